//! The drivers over the [`Plant`](crate::plant::Plant): each moves the plant's time and
//! state in the way one kind of master expects, and none knows the C interface.
//!
//! - [`master_step`]: a master's step, assembled once for FMI 2.0, FMI 3.0 and the page
//!   (the experiment set up, the step's arguments, one call's work, the policy);
//! - [`cosimulation`]: the FMU integrates itself between communication points (integrator
//!   choice, restart rules, dense output, projection at communication points), with its
//!   copy of the step compiled for the processor in [`isa`];
//! - [`events`]: a co-simulation step in which a change point is an event;
//! - [`sensitivity`]: the parameter sensitivities integrated beside the state;
//! - [`model_exchange`]: the master integrates the loop's independent coordinates.
//!
//! All read the master's [`Experiment`]. Both FMI versions drive the plant through these.

pub mod cosimulation;
pub mod events;
pub mod isa;
pub mod master_step;
pub mod model_exchange;
pub mod sensitivity;

pub use cosimulation::CoSimulation;
pub use model_exchange::Exchange;

use crate::model::ModelError;
use crate::plant::{Activity, Plant, SolverKind};
use integrators::text::number;
use integrators::{Choice, Method, Statistics};

/// The integrators' choice for what the `solver` parameter names.
pub fn method_choice(kind: SolverKind) -> Choice {
    match kind {
        SolverKind::Auto => Choice::Auto,
        SolverKind::Dop853 => Choice::Fixed(Method::Dop853),
        SolverKind::Implicit => Choice::Fixed(Method::Radau5),
    }
}

/// The statistics outputs of an integrator that counted `statistics` and integrates with
/// `method` now.
pub fn activity(statistics: Statistics, method: Method) -> Activity {
    Activity {
        steps: statistics.n_steps,
        rejected: statistics.n_rejected,
        right_hand_sides: statistics.n_rhs,
        active: match method {
            Method::Dop853 => SolverKind::Dop853,
            Method::Radau5 => SolverKind::Implicit,
        },
    }
}

/// What the statistics outputs show: a started co-simulation `driver`'s work; without
/// one (before the start, or in Model Exchange) no work, and the method `solver` names
/// first.
pub fn activity_of(plant: &Plant, driver: Option<&CoSimulation>) -> Activity {
    match driver {
        Some(driver) => driver.activity(),
        None => activity(
            Statistics::default(),
            method_choice(plant.solver_kind()).first_method(),
        ),
    }
}

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
                number(tolerance)
            )));
        }
        Ok(())
    }

    /// The time no integrator steps past: the stop time, if defined.
    pub fn limit(&self) -> f64 {
        self.stop.unwrap_or(f64::INFINITY)
    }

    /// The end of a master's step of size `step` from its point `current`, the plant
    /// standing at `now`: the step finite and positive, `current` the plant's time up to
    /// the rounding of the sums that made each, the end not past the stop time (by more
    /// than that rounding). Each caller words the refusal in its own interface's names.
    #[inline(always)]
    pub fn step_target(&self, now: f64, current: f64, step: f64) -> Result<f64, StepRefusal> {
        // The larger of two numbers that are not NaN here: `f64::max` also handles NaN, in a
        // longer sequence of instructions on every step.
        let larger = |a: f64, b: f64| if a > b { a } else { b };
        // Finiteness as a comparison with f64::MAX rather than `is_finite`: with the latter
        // the compiler tested these checks on the bits, a longer sequence. NaN fails every
        // comparison.
        let step_is_valid = step > 0.0 && step <= f64::MAX;
        let current_is_finite = current.abs() <= f64::MAX;
        if !step_is_valid {
            return Err(StepRefusal::Step);
        }
        // Relative to the times' size, never to the step's.
        if !current_is_finite
            || (current - now).abs() > TIME_MATCH * larger(now.abs(), current.abs())
        {
            return Err(StepRefusal::Point);
        }
        let target = current + step;
        if let Some(stop) = self.stop {
            if target > stop + TIME_MATCH * larger(stop.abs(), current.abs()) {
                return Err(StepRefusal::PastStop { target, stop });
            }
        }
        Ok(target)
    }
}

/// Relative mismatch accepted between the master's communication point and the FMU's time.
const TIME_MATCH: f64 = 1e-12;

/// Why [`Experiment::step_target`] refuses a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepRefusal {
    /// The step size is not finite and positive.
    Step,
    /// The master's point is not the plant's time.
    Point,
    /// The step would end past the stop time.
    PastStop { target: f64, stop: f64 },
}
