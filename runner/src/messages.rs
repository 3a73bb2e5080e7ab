//! The FMU's log messages, gathered per point. fmi-sys hands every message of the FMI
//! logger callback to the `log` crate; this logger keeps those at warning level and above
//! so that a failed point's row can say what the FMU said.

use std::sync::Mutex;

use log::{Level, Log, Metadata, Record};

static MESSAGES: Mutex<Vec<String>> = Mutex::new(Vec::new());
static CAPTURE: Capture = Capture;

/// Most of one point's messages kept; a chatty FMU cannot grow a row without bound.
const MAX_CHARS: usize = 2000;

struct Capture;

impl Log for Capture {
    fn enabled(&self, _: &Metadata) -> bool {
        true
    }

    fn log(&self, record: &Record) {
        // fmi-sys maps fmi2Warning to Warn, fmi2Discard to Trace, fmi2Error and
        // fmi2Fatal to Error, fmi2OK to Info (not kept: logging is off in the runner).
        let kind = match record.level() {
            Level::Error => "error",
            Level::Warn => "warning",
            Level::Trace => "discard",
            _ => return,
        };
        let mut messages = MESSAGES.lock().unwrap_or_else(|e| e.into_inner());
        if messages.iter().map(String::len).sum::<usize>() < MAX_CHARS {
            messages.push(format!("{kind}: {}", record.args()));
        }
    }

    fn flush(&self) {}
}

pub fn install() {
    // Only the first call installs; a second is harmless.
    if log::set_logger(&CAPTURE).is_ok() {
        log::set_max_level(log::LevelFilter::Trace);
    }
}

/// The messages since the last call, joined, and forgotten.
pub fn take() -> String {
    let mut messages = MESSAGES.lock().unwrap_or_else(|e| e.into_inner());
    let joined = messages.join(" | ");
    messages.clear();
    joined
}
