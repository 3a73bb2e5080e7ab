//! The drivers over the [`Plant`](crate::plant::Plant): each moves the plant's time and
//! state in the way one kind of master expects, and none knows the C interface.
//!
//! - [`cosimulation`]: the FMU integrates itself between communication points (integrator
//!   choice, restart rules, dense output, projection at communication points);
//! - [`model_exchange`]: the master integrates the loop's independent coordinates.
//!
//! Both read the master's [`Experiment`]. Both FMI versions drive the plant through these
//! same two.

pub mod cosimulation;
pub mod events;
pub mod isa;
pub mod model_exchange;
pub mod sensitivity;

pub use cosimulation::CoSimulation;
pub use model_exchange::Exchange;

use crate::model::{self, ModelError};

/// Relative tolerance when the master gives none (the DefaultExperiment's).
pub const DEFAULT_TOLERANCE: f64 = 1e-8;
/// Admissible relative tolerances.
pub const TOLERANCE_RANGE: (f64, f64) = (1e-13, 1e-1);

/// The master's set-up of a run: tolerance, start and stop time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Experiment {
    pub tolerance: f64,
    pub start: f64,
    pub stop: Option<f64>,
}

impl Experiment {
    /// The experiment before the master sets one up: `start` as the description's default.
    pub fn new(start: f64) -> Self {
        Self {
            tolerance: DEFAULT_TOLERANCE,
            start,
            stop: None,
        }
    }

    /// Check a tolerance against [`TOLERANCE_RANGE`].
    pub fn check_tolerance(tolerance: f64) -> Result<(), ModelError> {
        let (low, high) = TOLERANCE_RANGE;
        if !(low..=high).contains(&tolerance) {
            return Err(ModelError::new(format!(
                "tolerance = {} must lie in [{low:e}, {high:e}]",
                model::number(tolerance)
            )));
        }
        Ok(())
    }

    /// The time no integrator steps past: the stop time, if defined.
    pub fn limit(&self) -> f64 {
        self.stop.unwrap_or(f64::INFINITY)
    }
}
