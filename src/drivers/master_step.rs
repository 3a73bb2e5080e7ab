//! A master's step, put together in this one place for every master of the co-simulation
//! driver: FMI 2.0's fmi2DoStep, FMI 3.0's fmi3DoStep and the page. The experiment a master
//! sets up is checked here, and the driver started on it; a step's arguments are checked
//! against the plant's time and the experiment ([`Experiment::step_target`]), one call's
//! work is allowed ([`CALL_WORK`]), and the step is taken by the master's policy: FMI
//! 2.0's, where a step the integrator cannot finish fails and the plant stays at its
//! start, or with events ([`events::step`]), where a change point is an event and a
//! refused step leaves plant and driver as before the call. The callers only map the
//! outcome to their interface's states, statuses and log.

use super::cosimulation::{CoSimulation, CALL_WORK};
use super::events::{self, EventHandling, Happening, StepEnd};
use super::{isa, Experiment, StepRefusal};
use crate::model::ModelError;
use crate::plant::Plant;
use integrators::text::number;
use integrators::SolverError;

/// Why a master's step did not complete.
#[derive(Clone, Debug, PartialEq)]
pub enum StepFailure {
    /// Its arguments do not fit the plant's time or the experiment: nothing moved.
    Arguments(String),
    /// FMI 2.0's step: the integrator could not finish; the plant stands at the step's
    /// start, where the message says.
    Failed(String),
    /// A step with events: refused; plant and driver are as before the call.
    Refused(String),
}

impl StepFailure {
    pub fn message(&self) -> &str {
        match self {
            StepFailure::Arguments(m) | StepFailure::Failed(m) | StepFailure::Refused(m) => m,
        }
    }
}

/// The experiment a master sets up: the start finite, the stop (if any) finite and not
/// before it, the tolerance (if given) in [`super::TOLERANCE_RANGE`], else `tolerance_before`.
pub fn set_up(
    tolerance: Option<f64>,
    start: f64,
    stop: Option<f64>,
    tolerance_before: f64,
) -> Result<Experiment, ModelError> {
    if !start.is_finite() {
        return Err(ModelError::new(format!(
            "startTime = {start} must be finite"
        )));
    }
    if let Some(stop) = stop {
        if !(stop.is_finite() && stop >= start) {
            return Err(ModelError::new(format!(
                "stopTime = {} must be finite and >= startTime = {}",
                number(stop),
                number(start)
            )));
        }
    }
    if let Some(tolerance) = tolerance {
        Experiment::check_tolerance(tolerance)?;
    }
    Ok(Experiment {
        tolerance: tolerance.unwrap_or(tolerance_before),
        start,
        stop,
    })
}

/// The plant at its consistent start for `experiment`, and the co-simulation driver
/// started on it.
pub fn start(plant: &mut Plant, experiment: &Experiment) -> Result<CoSimulation, ModelError> {
    plant.initialize(experiment.start)?;
    Ok(CoSimulation::new(plant, experiment))
}

/// FMI 2.0's step of size `step` from the master's point `current`, within one call's
/// work: a step the integrator cannot finish fails.
#[inline(always)]
pub fn fmi2_step(
    plant: &mut Plant,
    driver: &mut CoSimulation,
    experiment: &Experiment,
    (current, step): (f64, f64),
) -> Result<(), StepFailure> {
    let target = begin(plant, driver, experiment, (current, step))?;
    isa::advance(driver, plant, target, experiment)
        .map_err(|error| StepFailure::Failed(failed(plant, target, error)))
}

/// A step with events (FMI 3.0's, the page's) of size `step` from the master's point
/// `current`, within one call's work, a change point handled as `handling` says: how it
/// ended; what happened on the way is pushed onto `happenings`.
pub fn step_with_events(
    plant: &mut Plant,
    driver: &mut CoSimulation,
    experiment: &Experiment,
    (current, step): (f64, f64),
    handling: EventHandling,
    happenings: &mut Vec<Happening>,
) -> Result<StepEnd, StepFailure> {
    let now = plant.time();
    let target = begin(plant, driver, experiment, (current, step))?;
    events::step(plant, driver, experiment, target, handling, happenings).map_err(|message| {
        StepFailure::Refused(format!(
            "{message}; the FMU is as before the call, at t = {}",
            number(now)
        ))
    })
}

/// What every master's step begins with: its arguments checked against the plant's time
/// and the experiment, giving the step's end, and one call's work allowed.
#[inline(always)]
fn begin(
    plant: &Plant,
    driver: &mut CoSimulation,
    experiment: &Experiment,
    (current, step): (f64, f64),
) -> Result<f64, StepFailure> {
    let now = plant.time();
    let target = experiment
        .step_target(now, current, step)
        .map_err(|refusal| {
            StepFailure::Arguments(refused_arguments(refusal, now, current, step))
        })?;
    driver.allow_work(CALL_WORK);
    Ok(target)
}

/// Why a step's arguments are refused, in the FMI functions' names for them.
#[cold]
fn refused_arguments(refusal: StepRefusal, now: f64, current: f64, step: f64) -> String {
    match refusal {
        StepRefusal::Step => format!(
            "communicationStepSize = {} must be finite and > 0",
            number(step)
        ),
        StepRefusal::Point => format!(
            "currentCommunicationPoint = {} does not match the FMU's time {}",
            number(current),
            number(now)
        ),
        StepRefusal::PastStop { target, stop } => {
            format!("a step to t = {target} would pass stopTime = {stop}")
        }
    }
}

/// An FMI 2.0 step the integrator could not finish, the plant at its start: where, why,
/// and what to do about a step past one call's work.
#[cold]
fn failed(plant: &Plant, target: f64, error: SolverError) -> String {
    let (now, y) = (plant.time(), plant.state());
    let advice = match error {
        SolverError::WorkLimit { .. } => {
            format!(" (one call may do {CALL_WORK} right-hand sides): take shorter steps")
        }
        _ => String::new(),
    };
    format!(
        "step from t = {} to {} failed: {error}{advice}; state kept at t = {} (phi2 = {}, \
         phi3 = {}, omega2 = {}, omega3 = {})",
        number(now),
        number(target),
        number(now),
        y[1],
        y[2],
        y[5],
        y[6]
    )
}
