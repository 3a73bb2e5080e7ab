//! The instance's logging: which categories are enabled, by each version's rules, and the
//! messages sent to the master's logger.

use super::{Category, Failure, Instance, Outcome, Status, Version};
use crate::description::LOG_CATEGORIES;

impl Instance {
    /// Whether a message of `category` goes to the master now: one load, as the guard of
    /// every call asks it (see [`Instance::logging_changed`]).
    #[inline(always)]
    pub fn log_enabled(&self, category: Category) -> bool {
        self.logged[category as usize]
    }

    /// Which categories are logged, from the settings: FMI 2.0 reports errors, discards,
    /// warnings and fatal errors always (its logger decides what to show when logging is
    /// off), the debug categories (calls, solver) only while debug logging is on for them.
    /// FMI 3.0 the categories enabled now (the statuses' from the start, the debug ones as
    /// `loggingOn` and `fmi3SetDebugLogging` say). Nothing is reported (or formatted)
    /// without a logger callback.
    pub(super) fn logging_changed(&mut self) {
        let version = self.version();
        for (i, logged) in self.logged.iter_mut().enumerate() {
            let debug = i == Category::Calls as usize || i == Category::Solver as usize;
            let on = match (version, debug) {
                (Version::Fmi3, _) => self.enabled[i],
                (Version::Fmi2, true) => self.debug_logging && self.enabled[i],
                (Version::Fmi2, false) => true,
            };
            *logged = self.logger.is_some() && on;
        }
    }

    /// Send a message to the master's logger, if it gave one and the category is enabled.
    pub fn log(&self, status: Status, category: Category, message: &str) {
        if !self.log_enabled(category) {
            return;
        }
        if let Some(logger) = &self.logger {
            let category = LOG_CATEGORIES[category as usize].0;
            logger.send(&self.name, status, category, message);
        }
    }

    pub fn report(&self, failure: &Failure, function: &str) {
        let category = match failure.status {
            Status::Discard => Category::Discard,
            Status::Warning => Category::Warning,
            Status::Fatal => Category::Fatal,
            Status::Ok | Status::Error => Category::Error,
        };
        if self.log_enabled(category) {
            self.log(
                failure.status,
                category,
                &format!("{function}: {}", failure.message),
            );
        }
    }

    /// FMI 2.0: no categories switches debug logging on or off altogether; with
    /// categories and `on`, exactly those are enabled; with `!on`, those are disabled.
    /// FMI 3.0: `on` applies to the categories listed, or to all where none is ("If
    /// nCategories = 0, loggingOn applies to all log categories").
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Outcome {
        let mut listed = [false; LOG_CATEGORIES.len()];
        for name in categories {
            let index = LOG_CATEGORIES
                .iter()
                .position(|(c, _)| c == name)
                .ok_or_else(|| {
                    let known: Vec<_> = LOG_CATEGORIES.iter().map(|(c, _)| *c).collect();
                    Failure::error(format!(
                        "unknown log category \"{name}\"; known: {}",
                        known.join(", ")
                    ))
                })?;
            listed[index] = true;
        }
        if self.version() == Version::Fmi3 {
            let all = categories.is_empty();
            for (enabled, this) in self.enabled.iter_mut().zip(listed) {
                if all || this {
                    *enabled = on;
                }
            }
        } else if categories.is_empty() {
            self.enabled = [true; LOG_CATEGORIES.len()];
            self.debug_logging = on;
        } else if on {
            self.enabled = listed;
            self.debug_logging = true;
        } else {
            for (enabled, off) in self.enabled.iter_mut().zip(listed) {
                *enabled &= !off;
            }
        }
        self.logging_changed();
        Ok(())
    }
}
