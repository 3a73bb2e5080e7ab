//! The restorable state of an instance, in one place: the FMI state and version, the
//! experiment, the plant and its driver. GetFMUState clones it, SetFMUState puts a clone
//! back, Reset starts a new one (in either version), and serialization writes and reads its
//! fields in one order, each part checking its values again on reading.

use super::state::{Interface, State, Version};
use super::state_frame;
use super::status::Failure;
use crate::description::DEFAULT_EXPERIMENT;
use crate::drivers::{self, CoSimulation, Exchange, Experiment};
use crate::plant::{Activity, Plant};
use integrators::bytes::put;
use integrators::bytes::{FormatError, Writer};

/// The driver of an instance, by interface; each exists once initialisation (or, in
/// initialization mode, a read) has assembled the plant, so that in initialization mode a
/// started driver says the assembly is current.
// One per instance and saved state, never moved on the step's path: boxing the larger
// variant would add an indirection to every step for no saving that matters.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Driver {
    CoSimulation(Option<CoSimulation>),
    ModelExchange(Option<Exchange>),
}

impl Driver {
    pub(super) fn new(interface: Interface) -> Self {
        match interface {
            Interface::CoSimulation => Driver::CoSimulation(None),
            Interface::ModelExchange => Driver::ModelExchange(None),
        }
    }

    fn interface(&self) -> Interface {
        match self {
            Driver::CoSimulation(_) => Interface::CoSimulation,
            Driver::ModelExchange(_) => Interface::ModelExchange,
        }
    }

    pub(super) fn is_started(&self) -> bool {
        match self {
            Driver::CoSimulation(driver) => driver.is_some(),
            Driver::ModelExchange(exchange) => exchange.is_some(),
        }
    }

    /// Back to not started: the plant's assembly it was made from is stale.
    pub(super) fn stop(&mut self) {
        *self = Driver::new(self.interface());
    }
}

/// The restorable state of an instance, in one place: what GetFMUState saves,
/// SetFMUState restores, SerializeFMUState writes and Reset starts again from.
/// The logging settings belong to the instance, not here.
#[derive(Clone, Debug)]
pub struct FmuState {
    pub state: State,
    /// The version of the standard whose functions drive this instance.
    pub version: Version,
    pub(super) experiment: Experiment,
    pub(super) plant: Plant,
    pub(super) driver: Driver,
}

impl FmuState {
    /// Just after instantiation: every variable at its start value.
    pub(super) fn new(interface: Interface, version: Version) -> Self {
        let mut plant = Plant::new();
        plant.set_time(DEFAULT_EXPERIMENT.0);
        Self {
            state: State::Instantiated,
            version,
            experiment: Experiment::new(DEFAULT_EXPERIMENT.0),
            plant,
            driver: Driver::new(interface),
        }
    }

    pub(super) fn interface(&self) -> Interface {
        self.driver.interface()
    }

    /// What the statistics outputs show ([`drivers::activity_of`]).
    pub(super) fn activity(&self) -> Activity {
        let driver = match &self.driver {
            Driver::CoSimulation(Some(driver)) => Some(driver),
            _ => None,
        };
        drivers::activity_of(&self.plant, driver)
    }

    /// The versioned, position-independent byte form (framed by [`state_frame`]).
    pub fn serialize(&self) -> Vec<u8> {
        state_frame::frame(&self.write().into_bytes())
    }

    /// The layout of this state's serialized payload: the kinds of its fields, in order,
    /// without their values (see [`Writer::layout`]).
    pub fn layout(&self) -> u64 {
        self.write().layout()
    }

    fn write(&self) -> Writer {
        let mut w = Writer::default();
        put!(w.u8(self.interface() as u8));
        put!(w.u8(self.version as u8));
        put!(w.u8(self.state.code()));
        let e = &self.experiment;
        put!(w.f64s(&[e.tolerance, e.start]));
        put!(w.bool(e.stop.is_some()));
        put!(w.f64(e.stop.unwrap_or(e.start)));
        self.plant.serialize_into(&mut w);
        put!(w.bool(self.driver.is_started()));
        match &self.driver {
            Driver::CoSimulation(Some(driver)) => driver.serialize_into(&mut w),
            Driver::ModelExchange(Some(exchange)) => exchange.serialize_into(&mut w),
            _ => {}
        }
        w
    }

    pub fn deserialize(bytes: &[u8]) -> Result<Self, Failure> {
        Self::read(bytes).map_err(|e| Failure::error(e.to_string()))
    }

    fn read(bytes: &[u8]) -> Result<Self, FormatError> {
        let invalid = |what: String| FormatError(format!("invalid serialized state: {what}"));
        let mut r = state_frame::open(bytes)?;
        let interface = match r.u8()? {
            0 => Interface::ModelExchange,
            1 => Interface::CoSimulation,
            other => return Err(invalid(format!("interface {other}"))),
        };
        let version = match r.u8()? {
            2 => Version::Fmi2,
            3 => Version::Fmi3,
            other => return Err(invalid(format!("FMI version {other}"))),
        };
        let code = r.u8()?;
        let state =
            State::from_code(code).ok_or_else(|| invalid(format!("FMI state code {code}")))?;
        let [tolerance, start] = r.f64s()?;
        Experiment::check_tolerance(tolerance).map_err(|e| invalid(e.to_string()))?;
        let has_stop = r.bool()?;
        let stop = r.f64()?;
        let experiment = Experiment {
            tolerance,
            start,
            stop: has_stop.then_some(stop),
        };
        let plant = Plant::deserialize_from(&mut r)?;
        let started = r.bool()?;
        let driver = match (interface, started) {
            (_, false) => Driver::new(interface),
            (Interface::CoSimulation, true) => Driver::CoSimulation(Some(
                CoSimulation::deserialize_from(&mut r, &plant, &experiment)?,
            )),
            (Interface::ModelExchange, true) => {
                Driver::ModelExchange(Some(Exchange::deserialize_from(&mut r, &plant)?))
            }
        };
        r.finish()?;
        let restored = Self {
            state,
            version,
            experiment,
            plant,
            driver,
        };
        restored.check().map_err(invalid)?;
        Ok(restored)
    }

    /// The parts of a restored state agree with each other and with its FMI state.
    fn check(&self) -> Result<(), String> {
        let state = self.state;
        // FMI 3.0 Co-Simulation has an event mode too.
        let exchange_states = match (self.interface(), self.version) {
            (Interface::CoSimulation, Version::Fmi3) => state == State::ContinuousTimeMode,
            _ => matches!(state, State::EventMode | State::ContinuousTimeMode),
        };
        let cs_states = matches!(state, State::StepComplete | State::StepFailed);
        let initialised = !matches!(state, State::Instantiated | State::InitializationMode);
        let started = self.driver.is_started();
        let consistent = match self.interface() {
            Interface::ModelExchange => !cs_states && (started || !exchange_states),
            Interface::CoSimulation => {
                !exchange_states && (started || !(cs_states || state == State::EventMode))
            }
        };
        if !consistent {
            return Err(format!(
                "{} in a {} instance",
                state.describe(self.version),
                self.interface().name()
            ));
        }
        let steps = self.activity().steps;
        if !initialised && (self.plant.time() != self.experiment.start || steps != 0) {
            return Err("an instance before initialisation has not moved".into());
        }
        if started && state == State::Instantiated {
            return Err("a started driver before initialization mode".into());
        }
        if started || initialised {
            // On a crossing's path the loop's closure is not enforced: the driver checks
            // the state against the path instead.
            let in_flight = matches!(
                &self.driver,
                Driver::CoSimulation(Some(driver)) if driver.crossing_in_flight()
            );
            if !in_flight {
                self.plant.check_consistent()?;
            }
            if let Driver::CoSimulation(Some(driver)) = &self.driver {
                driver.check_initialised(&self.plant, &self.experiment)?;
            }
        }
        if self
            .experiment
            .stop
            .is_some_and(|stop| stop < self.experiment.start)
        {
            return Err("the stop time is before the start time".into());
        }
        Ok(())
    }
}
