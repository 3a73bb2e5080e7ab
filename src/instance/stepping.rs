//! Co-Simulation's step on an instance, either version's: the step as the drivers
//! assemble it for every master ([`master_step`]), and its outcome as the interfaces'
//! states, statuses, flags and log messages.

use super::fmu_state::{Driver, FmuState};
use super::{Category, Failure, Instance, Outcome, State, Status, StepEnd};
use crate::drivers::events::Happening;
use crate::drivers::master_step::{self, StepFailure};
use crate::drivers::{CoSimulation, Experiment};
use crate::plant::Plant;
use integrators::text::number;

impl Instance {
    /// fmi3DoStep: as fmi2DoStep, but a change point is an event, handled as the master
    /// said at instantiation; a step refused is FMI 3.0's Discard, the FMU as before the
    /// call.
    pub fn step_with_events(&mut self, current: f64, step: f64) -> Result<StepEnd, Failure> {
        let handling = self.events;
        let warned = self.warned_stability;
        // Empty, and so without an allocation, unless a change point is met.
        let mut happenings = Vec::new();
        let (plant, driver, experiment) = self.cosimulation()?;
        let experiment = *experiment;
        let outcome = master_step::step_with_events(
            plant,
            driver,
            &experiment,
            (current, step),
            handling,
            &mut happenings,
        );
        let stability_limited = !warned && driver.dop853_is_stability_limited();
        if !happenings.is_empty() {
            self.log_happenings(&happenings);
        }
        let end = outcome.map_err(|failure| self.step_failed(failure))?;
        self.after_step(self.fmu_state.plant.time(), stability_limited);
        Ok(end)
    }

    /// fmi2DoStep; a step the integrator cannot finish leaves the instance in StepFailed.
    #[inline(always)]
    pub fn do_step(&mut self, current: f64, step: f64) -> Outcome {
        let warned = self.warned_stability;
        let (plant, driver, experiment) = self.cosimulation()?;
        if let Err(failure) = master_step::fmi2_step(plant, driver, experiment, (current, step)) {
            return Err(self.step_failed(failure));
        }
        let stability_limited = !warned && driver.dop853_is_stability_limited();
        self.after_step(self.fmu_state.plant.time(), stability_limited);
        Ok(())
    }

    /// A step that did not complete, as the interfaces have it: arguments refused are an
    /// Error; an FMI 2.0 step the integrator could not finish leaves the instance in
    /// StepFailed, its outputs at the last communication point, which
    /// fmi2LastSuccessfulTime reports; a step refused with events is a Discard.
    #[cold]
    fn step_failed(&mut self, failure: StepFailure) -> Failure {
        match failure {
            StepFailure::Arguments(message) => Failure::error(message),
            StepFailure::Failed(message) => {
                self.fmu_state.state = State::StepFailed;
                Failure::discard(message)
            }
            StepFailure::Refused(message) => Failure::discard(message),
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

    /// After a step: warn once when a fixed DOP853 is limited by stability, and log the
    /// integrator's work when asked.
    #[inline(always)]
    fn after_step(&mut self, target: f64, stability_limited: bool) {
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
