//! One FMU instance, whichever version of the standard created it: its restorable state
//! ([`FmuState`]), the master's logger and the logging settings, and the operations of the
//! FMI functions on them. Everything here is safe Rust on slices; the two C ABIs (`fmi2`,
//! `fmi3`) turn C pointers into these calls.

mod exchange;
pub mod fmu_state;
mod handles;
pub mod logger;
mod logging;
pub mod state;
mod state_frame;
mod status;
mod stepping;
mod values;

use std::ffi::CString;

pub use fmu_state::{Driver, FmuState};
use handles::StateHandles;
pub use logger::Logger;
pub use state::{Interface, State, Version};
pub use state_frame::{FORMAT_VERSION, HEADER as STATE_HEADER};
pub use status::{Category, Failure, Outcome, Status};

use crate::description::LOG_CATEGORIES;
use crate::drivers::events::EventHandling;
pub use crate::drivers::events::StepEnd;
use crate::drivers::model_exchange::CONTINUOUS_STATES;
use crate::drivers::{master_step, Exchange};

pub struct Instance {
    name: CString,
    logger: Option<Logger>,
    /// FMI 3.0 Co-Simulation: whether the master handles events in Event Mode, and whether
    /// a step may end before its end time.
    events: EventHandling,
    /// FMI 2.0: SetDebugLogging's switch for the debug categories, which `enabled` then
    /// selects. FMI 3.0: `enabled` alone says which categories are logged.
    debug_logging: bool,
    enabled: [bool; LOG_CATEGORIES.len()],
    /// What the settings above give: whether each category is logged now.
    logged: [bool; LOG_CATEGORIES.len()],
    /// Everything SetFMUState restores.
    fmu_state: FmuState,
    /// Addresses of the FMU states this instance has handed out and not yet freed.
    issued_states: StateHandles,
    /// Whether this run has warned that `solver = dop853` is limited by stability.
    warned_stability: bool,
}

/// The master's array length must be the number of continuous states.
fn check_state_count(name: &str, n: usize) -> Outcome {
    if n != CONTINUOUS_STATES {
        return Err(Failure::error(format!(
            "{name} = {n}: this FMU has {CONTINUOUS_STATES} continuous states"
        )));
    }
    Ok(())
}

impl Instance {
    /// The categories enabled at instantiation. FMI 2.0: all (debug logging decides the
    /// debug ones). FMI 3.0: the statuses' categories always, as the standard's own
    /// Reference-FMUs do, so that a master that has not asked for silence hears every
    /// refusal with its reason; the debug categories (calls, solver) as `loggingOn` says.
    /// `fmi3SetDebugLogging` switches any of them off by name, or all at once.
    fn enabled_at_first(version: Version, debug_logging: bool) -> [bool; LOG_CATEGORIES.len()] {
        std::array::from_fn(|i| {
            let debug = i == Category::Calls as usize || i == Category::Solver as usize;
            version == Version::Fmi2 || debug_logging || !debug
        })
    }

    pub fn new(
        interface: Interface,
        version: Version,
        name: CString,
        logger: Option<Logger>,
        debug_logging: bool,
    ) -> Self {
        let mut instance = Self {
            name,
            logger,
            events: EventHandling::default(),
            debug_logging,
            enabled: Self::enabled_at_first(version, debug_logging),
            logged: [false; LOG_CATEGORIES.len()],
            fmu_state: FmuState::new(interface, version),
            issued_states: StateHandles::default(),
            warned_stability: false,
        };
        instance.logging_changed();
        instance
    }

    pub fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Outcome {
        let fmu_state = &mut self.fmu_state;
        fmu_state.experiment =
            master_step::set_up(tolerance, start, stop, fmu_state.experiment.tolerance)
                .map_err(|e| Failure::error(e.to_string()))?;
        fmu_state.plant.set_time(start);
        Ok(())
    }

    pub fn enter_initialization_mode(&mut self) -> Outcome {
        self.fmu_state.state = State::InitializationMode;
        Ok(())
    }

    /// FMI 3.0 Co-Simulation: what the master said at instantiation it handles.
    pub fn handle_events(&mut self, events: EventHandling) {
        self.events = events;
    }

    /// The state of the instance, which decides what may be called.
    #[inline(always)]
    pub fn state(&self) -> State {
        self.fmu_state.state
    }

    /// A panic was caught in a call: the instance is unusable from now on.
    pub fn fail_fatally(&mut self) {
        self.fmu_state.state = State::Fatal;
    }

    /// The version of the standard the instance was created through.
    pub fn version(&self) -> Version {
        self.fmu_state.version
    }

    /// The interface the instance was created for.
    pub fn interface(&self) -> Interface {
        self.fmu_state.interface()
    }

    pub fn exit_initialization_mode(&mut self) -> Outcome {
        self.initialise_plant()?;
        self.fmu_state.state = match self.interface() {
            Interface::CoSimulation if self.events.event_mode => State::EventMode,
            Interface::CoSimulation => State::StepComplete,
            Interface::ModelExchange => State::EventMode,
        };
        self.warned_stability = false;
        self.log_linkage_class();
        Ok(())
    }

    /// The linkage's class and the motions it allows; a warning for a change-point
    /// geometry, whose run stops where crank, rod and rocker fall collinear.
    fn log_linkage_class(&self) {
        let class = crate::model::classify(self.fmu_state.plant.params());
        let (status, category) = if class == crate::model::LinkageClass::ChangePoint {
            (Status::Warning, Category::Warning)
        } else {
            (Status::Ok, Category::Solver)
        };
        if self.log_enabled(category) {
            let message = format!("the linkage is a {}: {}", class.name(), class.description());
            self.log(status, category, &message);
        }
    }

    /// The consistent start for the current parameters, and the driver started on it.
    fn initialise_plant(&mut self) -> Outcome {
        let failed =
            |e: crate::model::ModelError| Failure::error(format!("initialisation failed: {e}"));
        let interface = self.interface();
        let fmu_state = &mut self.fmu_state;
        fmu_state.driver = match interface {
            Interface::CoSimulation => Driver::CoSimulation(Some(
                master_step::start(&mut fmu_state.plant, &fmu_state.experiment).map_err(failed)?,
            )),
            Interface::ModelExchange => {
                fmu_state
                    .plant
                    .initialize(fmu_state.experiment.start)
                    .map_err(failed)?;
                refuse_sensitivities(&fmu_state.plant)?;
                Driver::ModelExchange(Some(Exchange::start(&mut fmu_state.plant).map_err(failed)?))
            }
        };
        Ok(())
    }

    /// Outputs in initialization mode reflect the parameters set so far: the plant is
    /// assembled, and its driver started, on the first read after a change.
    fn assemble_if_needed(&mut self) -> Outcome {
        if self.fmu_state.state == State::InitializationMode && !self.fmu_state.driver.is_started()
        {
            self.initialise_plant()?;
        }
        Ok(())
    }

    pub fn enter_event_mode(&mut self) -> Outcome {
        if self.interface() == Interface::CoSimulation && !self.events.event_mode {
            return Err(Failure::error(
                "eventModeUsed was false at instantiation: this Co-Simulation instance has no \
                 event mode",
            ));
        }
        self.fmu_state.state = State::EventMode;
        Ok(())
    }

    /// FMI 3.0 Co-Simulation: from event mode back to stepping.
    pub fn enter_step_mode(&mut self) -> Outcome {
        self.fmu_state.state = State::StepMode;
        Ok(())
    }

    pub fn enter_continuous_time_mode(&mut self) -> Outcome {
        self.fmu_state.state = State::ContinuousTimeMode;
        Ok(())
    }

    pub fn terminate(&mut self) -> Outcome {
        self.fmu_state.state = State::Terminated;
        Ok(())
    }

    /// Back to the state just after instantiation, every variable at its start value.
    pub fn reset(&mut self) -> Outcome {
        self.fmu_state = FmuState::new(self.interface(), self.version());
        Ok(())
    }

    pub fn save(&self) -> FmuState {
        self.fmu_state.clone()
    }

    pub fn restore(&mut self, saved: &FmuState) -> Outcome {
        if saved.version != self.version() {
            return Err(Failure::error(format!(
                "the FMU state was saved by an {} instance; this one is {}",
                saved.version.name(),
                self.version().name()
            )));
        }
        if saved.interface() != self.interface() {
            return Err(Failure::error(format!(
                "the FMU state was saved by a {} instance; this one is {}",
                saved.interface().name(),
                self.interface().name()
            )));
        }
        self.fmu_state = saved.clone();
        Ok(())
    }

    /// SetFMUState: the state behind `pointer`, which this instance issued, put back.
    pub fn restore_issued(&mut self, pointer: *mut std::ffi::c_void) -> Outcome {
        let saved = self.issued_state(pointer)?.clone();
        self.restore(&saved)
    }

    /// Hand out `saved` as a new FMU state pointer.
    pub fn issue_state(&mut self, saved: FmuState) -> *mut FmuState {
        self.issued_states.issue(saved)
    }

    /// The state behind `pointer`, if this instance issued it and has not freed it.
    pub fn issued_state(
        &mut self,
        pointer: *mut std::ffi::c_void,
    ) -> Result<&mut FmuState, Failure> {
        self.issued_states.get(pointer)
    }

    /// Free a state this instance issued.
    pub fn free_state(&mut self, pointer: *mut std::ffi::c_void) -> Outcome {
        self.issued_states.free(pointer)
    }
}

/// Model Exchange has no sensitivities: the master integrates, and the FMU sees only the
/// points it is given. A slot set anyway is refused rather than left at zero.
fn refuse_sensitivities(plant: &crate::plant::Plant) -> Outcome {
    match plant.sensitivity_slots().first() {
        None => Ok(()),
        Some(&(slot, _)) => Err(Failure::error(format!(
            "sensitivity_{}.parameter is set: sensitivities come from the FMU's own \
             integration, in Co-Simulation; in Model Exchange the master integrates",
            slot + 1
        ))),
    }
}
