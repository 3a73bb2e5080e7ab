//! Co-Simulation's step on an instance, either version's: the arguments checked against the
//! FMU's time and the experiment, the driver's step (with events, in FMI 3.0), and its
//! outcome as statuses, flags and log messages.

use super::fmu_state::{Driver, FmuState};
use super::{Category, Failure, Instance, Outcome, State, Status, StepEnd};
use crate::drivers::cosimulation::CALL_WORK;
use crate::drivers::events::{self, Happening};
use crate::drivers::{isa, CoSimulation, Experiment, StepRefusal};
use crate::plant::Plant;
use integrators::text::number;
use integrators::SolverError;

impl Instance {
    /// fmi3DoStep: as fmi2DoStep, but a change point is an event, and a step is bounded
    /// in work, as the driver's step with events has it ([`events::step`]); a step it
    /// refuses is FMI 3.0's Discard, the FMU as before the call.
    pub fn step_with_events(&mut self, current: f64, step: f64) -> Result<StepEnd, Failure> {
        let now = self.fmu_state.plant.time();
        let target = self.step_target(now, current, step)?;
        let handling = self.events;
        // Empty, and so without an allocation, unless a change point is met.
        let mut happenings = Vec::new();
        let warned = self.warned_stability;
        let (plant, driver, experiment) = self.cosimulation()?;
        let experiment = *experiment;
        let outcome = events::step(
            plant,
            driver,
            &experiment,
            target,
            handling,
            &mut happenings,
        );
        let stability_limited = !warned && driver.dop853_is_stability_limited();
        if !happenings.is_empty() {
            self.log_happenings(&happenings);
        }
        match outcome {
            Ok(end) => {
                self.report_step(self.fmu_state.plant.time(), stability_limited);
                Ok(end)
            }
            Err(message) => Err(Failure::discard(format!(
                "{message}; the FMU is as before the call, at t = {}",
                number(now)
            ))),
        }
    }

    /// What a step with events met, in the solver's log.
    #[cold]
    fn log_happenings(&self, happenings: &[Happening]) {
        if !self.log_enabled(Category::Solver) {
            return;
        }
        let branch = self.fmu_state.plant.branch().name();
        for happening in happenings {
            let message = match *happening {
                Happening::Located { at, phi2, phi3 } => format!(
                    "t = {}: the linkage reaches a change point (phi2 = {phi2}, phi3 = {phi3}): \
                     an event; the next step crosses it onto change_point_branch = {branch}",
                    number(at)
                ),
                Happening::Crossed {
                    at,
                    crossing,
                    complete,
                } => format!(
                    "t = {}: the change point at phi2 = {}, phi3 = {} crossed onto the branch \
                     {branch} in {} s{}",
                    number(at),
                    crossing.node.0,
                    crossing.node.1,
                    crossing.duration,
                    if complete {
                        ""
                    } else {
                        ", on its way over the next steps"
                    }
                ),
            };
            self.log(Status::Ok, Category::Solver, &message);
        }
    }

    /// The co-simulation plant, driver and experiment, once initialised.
    #[inline(always)]
    fn cosimulation(&mut self) -> Result<(&mut Plant, &mut CoSimulation, &Experiment), Failure> {
        let FmuState {
            plant,
            driver: Driver::CoSimulation(Some(driver)),
            experiment,
            ..
        } = &mut self.fmu_state
        else {
            return Err(Failure::error("the integrator starts at initialisation"));
        };
        Ok((plant, driver, experiment))
    }

    #[inline(always)]
    pub fn do_step(&mut self, current: f64, step: f64) -> Outcome {
        let now = self.fmu_state.plant.time();
        let target = self.step_target(now, current, step)?;
        if let Err(error) = self.advance_to(target)? {
            return Err(self.step_failed(now, target, error));
        }
        Ok(())
    }

    /// The plant advanced to `target` by the co-simulation driver, within one call's
    /// work, and the step reported; the outer error when there is no driver yet, the inner
    /// the solver's (the plant then stays where it was).
    #[inline(always)]
    fn advance_to(&mut self, target: f64) -> Result<Result<(), SolverError>, Failure> {
        let warned = self.warned_stability;
        let (plant, driver, experiment) = self.cosimulation()?;
        driver.allow_work(CALL_WORK);
        if let Err(error) = isa::advance(driver, plant, target, experiment) {
            return Ok(Err(error));
        }
        let stability_limited = !warned && driver.dop853_is_stability_limited();
        self.report_step(target, stability_limited);
        Ok(Ok(()))
    }

    /// The step's end, once its arguments are checked against the FMU's time `now` and the
    /// experiment's stop time.
    #[inline(always)]
    fn step_target(&self, now: f64, current: f64, step: f64) -> Result<f64, Failure> {
        let experiment = &self.fmu_state.experiment;
        experiment
            .step_target(now, current, step)
            .map_err(|refusal| {
                Failure::error(match refusal {
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
                })
            })
    }

    /// An FMI 2.0 step the driver could not complete: the instance is in StepFailed, its
    /// outputs at the last communication point, which fmi2LastSuccessfulTime reports ("the
    /// end time of the last successfully completed communication step") and the message
    /// gives.
    #[cold]
    fn step_failed(&mut self, now: f64, target: f64, error: SolverError) -> Failure {
        self.fmu_state.state = State::StepFailed;
        let y = self.fmu_state.plant.state();
        let advice = match error {
            SolverError::WorkLimit { .. } => {
                format!(" (one call may do {CALL_WORK} right-hand sides): take shorter steps")
            }
            _ => String::new(),
        };
        Failure::discard(format!(
            "step from t = {} to {} failed: {error}{advice}; state kept at t = {} (phi2 = {}, \
             phi3 = {}, omega2 = {}, omega3 = {})",
            number(now),
            number(target),
            number(now),
            y[1],
            y[2],
            y[5],
            y[6]
        ))
    }

    /// After a step: warn once when a fixed DOP853 is limited by stability, and log the
    /// integrator's work when asked.
    #[inline(always)]
    fn report_step(&mut self, target: f64, stability_limited: bool) {
        if stability_limited {
            self.warned_stability = true;
            if self.log_enabled(Category::Warning) {
                let message = format!(
                    "t = {target}: with solver = dop853 the step size is limited by stability, \
                     not accuracy: fast modes may carry errors above the tolerance that the error \
                     estimate does not see; on stiff problems solver = auto (1) or implicit (3) \
                     is accurate with far fewer evaluations (logged once)"
                );
                self.log(Status::Warning, Category::Warning, &message);
            }
        }
        if self.log_enabled(Category::Solver) {
            let s = self.fmu_state.activity();
            let message = format!(
                "t = {target}: {} steps, {} rejected, {} right-hand sides so far",
                s.steps, s.rejected, s.right_hand_sides
            );
            self.log(Status::Ok, Category::Solver, &message);
        }
    }

    pub fn last_successful_time(&self) -> f64 {
        self.fmu_state.plant.time()
    }
}
