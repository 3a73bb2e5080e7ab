//! One FMU instance, whichever version of the standard created it: its restorable state
//! ([`FmuState`]), the master's logger and the logging settings, and the operations of the
//! FMI functions on them. Everything here is safe Rust on slices; the two C ABIs (`fmi2`,
//! `fmi3`) turn C pointers into these calls.

pub mod fmu_state;
mod handles;
pub mod logger;
pub mod state;

use std::ffi::CString;

pub use fmu_state::{Driver, FmuState};
use handles::StateHandles;
pub use logger::Logger;
pub use state::{Interface, State, Version};

use crate::description::LOG_CATEGORIES;
use crate::drivers::cosimulation::CALL_WORK;
pub use crate::drivers::events::StepEnd;
use crate::drivers::events::{self, EventHandling, Happening};
use crate::drivers::isa;
use crate::drivers::model_exchange::STATES;
use crate::drivers::{CoSimulation, Exchange, Experiment};
use crate::plant::{AccessError, Plant, Value};
use crate::solver::SolverError;
use crate::text::number;
use crate::variables::{variable, Input, Slot, VarType, STATE_REFERENCES};

/// A function's status, with the numbers FMI 2.0 and 3.0 both give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

/// Log categories, by their position in [`LOG_CATEGORIES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    Warning = 0,
    Discard = 1,
    Error = 2,
    Fatal = 3,
    Calls = 4,
    Solver = 5,
}

/// Why a call failed: the status to return and the message to log.
#[derive(Debug)]
pub struct Failure {
    pub status: Status,
    pub message: String,
}

impl Failure {
    pub fn error(message: impl Into<String>) -> Self {
        Self {
            status: Status::Error,
            message: message.into(),
        }
    }

    pub fn discard(message: impl Into<String>) -> Self {
        Self {
            status: Status::Discard,
            message: message.into(),
        }
    }
}

impl From<AccessError> for Failure {
    fn from(error: AccessError) -> Self {
        Failure::error(error.to_string())
    }
}

pub type Outcome = Result<(), Failure>;

/// Relative mismatch accepted between the master's communication point and the FMU's time.
const TIME_MATCH: f64 = 1e-12;

pub struct Instance {
    name: CString,
    logger: Option<Logger>,
    /// FMI 3.0 Co-Simulation: whether the master handles events in Event Mode, and whether
    /// a step may end before its end time.
    pub event_mode_used: bool,
    pub early_return_allowed: bool,
    /// FMI 2.0: SetDebugLogging's switch for the debug categories, which `enabled` then
    /// selects. FMI 3.0: `enabled` alone says which categories are logged.
    debug_logging: bool,
    enabled: [bool; LOG_CATEGORIES.len()],
    /// Everything SetFMUState restores.
    pub current: FmuState,
    /// Addresses of the FMU states this instance has handed out and not yet freed.
    issued_states: StateHandles,
    /// Whether this run has warned that `solver = dop853` is limited by stability.
    warned_stability: bool,
}

/// The master's array length must be the number of continuous states.
fn check_state_count(name: &str, n: usize) -> Outcome {
    if n != STATES {
        return Err(Failure::error(format!(
            "{name} = {n}: this FMU has {STATES} continuous states"
        )));
    }
    Ok(())
}

impl Instance {
    pub fn new(
        interface: Interface,
        version: Version,
        name: CString,
        logger: Option<Logger>,
        debug_logging: bool,
    ) -> Self {
        Self {
            name,
            logger,
            event_mode_used: false,
            early_return_allowed: false,
            debug_logging,
            // FMI 3.0's categories are each on or off, all as `loggingOn` says at first.
            enabled: [version == Version::Fmi2 || debug_logging; LOG_CATEGORIES.len()],
            current: FmuState::new(interface, version),
            issued_states: StateHandles::default(),
            warned_stability: false,
        }
    }

    /// FMI 2.0: errors, discards, warnings and fatal errors are always reported (its
    /// logger decides what to show when logging is off); the debug categories (calls,
    /// solver) only while debug logging is on for them. FMI 3.0: only the categories
    /// enabled now, none while logging is off ("If loggingOn = fmi3False, then any
    /// logging is disabled"). Nothing is reported (or formatted) without a logger callback.
    #[inline(always)]
    pub fn log_enabled(&self, category: Category) -> bool {
        if self.logger.is_none() {
            return false;
        }
        match (self.version(), category) {
            (Version::Fmi3, _) => self.enabled[category as usize],
            (_, Category::Calls | Category::Solver) => {
                self.debug_logging && self.enabled[category as usize]
            }
            _ => true,
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
        Ok(())
    }

    pub fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Outcome {
        if !start.is_finite() {
            return Err(Failure::error(format!(
                "startTime = {start} must be finite"
            )));
        }
        if let Some(stop) = stop {
            if !(stop.is_finite() && stop >= start) {
                return Err(Failure::error(format!(
                    "stopTime = {} must be finite and >= startTime = {}",
                    number(stop),
                    number(start)
                )));
            }
        }
        if let Some(tolerance) = tolerance {
            Experiment::check_tolerance(tolerance).map_err(|e| Failure::error(e.to_string()))?;
        }
        let current = &mut self.current;
        current.experiment = Experiment {
            tolerance: tolerance.unwrap_or(current.experiment.tolerance),
            start,
            stop,
        };
        current.plant.set_time(start);
        Ok(())
    }

    pub fn enter_initialization_mode(&mut self) -> Outcome {
        self.current.state = State::InitializationMode;
        Ok(())
    }

    /// The version of the standard the instance was created through.
    pub fn version(&self) -> Version {
        self.current.version
    }

    /// The interface the instance was created for.
    pub fn interface(&self) -> Interface {
        self.current.interface()
    }

    pub fn exit_initialization_mode(&mut self) -> Outcome {
        self.initialise_plant()?;
        self.current.state = match self.interface() {
            Interface::CoSimulation if self.event_mode_used => State::EventMode,
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
        let class = crate::model::classify(self.current.plant.params());
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
        let current = &mut self.current;
        current
            .plant
            .initialize(current.experiment.start)
            .map_err(failed)?;
        current.driver = match interface {
            Interface::CoSimulation => {
                Driver::CoSimulation(Some(CoSimulation::new(&current.plant, &current.experiment)))
            }
            Interface::ModelExchange => {
                Driver::ModelExchange(Some(Exchange::start(&mut current.plant).map_err(failed)?))
            }
        };
        Ok(())
    }

    /// Outputs in initialization mode reflect the parameters set so far: the plant is
    /// assembled, and its driver started, on the first read after a change.
    fn assemble_if_needed(&mut self) -> Outcome {
        if self.current.state == State::InitializationMode && !self.current.driver.is_started() {
            self.initialise_plant()?;
        }
        Ok(())
    }

    /// Model Exchange's states with the plant they describe, borrowed together (assembled
    /// first in initialization mode).
    fn exchange_and_plant(&mut self) -> Result<(&mut Exchange, &mut Plant), Failure> {
        self.assemble_if_needed()?;
        let current = &mut self.current;
        match &mut current.driver {
            Driver::ModelExchange(Some(exchange)) => Ok((exchange, &mut current.plant)),
            _ => Err(Failure::error(
                "the continuous states exist from initialisation on",
            )),
        }
    }

    /// The plant, once Model Exchange's states exist.
    fn exchange_plant(&mut self) -> Result<&Plant, Failure> {
        self.exchange_and_plant().map(|(_, plant)| &*plant)
    }

    pub fn set_time(&mut self, time: f64) -> Outcome {
        if !time.is_finite() {
            return Err(Failure::error(format!("time = {time} must be finite")));
        }
        self.current.plant.set_time(time);
        Ok(())
    }

    /// A refused x changes nothing. Finite states the loop cannot close (the master's
    /// integrator stepped too far) are a Discard, which both standards recommend there so
    /// that the master retries with a smaller step; a non-finite one is an Error.
    pub fn set_continuous_states(&mut self, x: &[f64]) -> Outcome {
        check_state_count("nx", x.len())?;
        let finite = x.iter().all(|v| v.is_finite());
        let (exchange, plant) = self.exchange_and_plant()?;
        exchange.set_states(plant, x).map_err(|e| {
            if finite {
                Failure::discard(format!(
                    "{e}; the states are as before the call: retry with a smaller step"
                ))
            } else {
                Failure::error(e.to_string())
            }
        })
    }

    pub fn get_continuous_states(&mut self, x: &mut [f64]) -> Outcome {
        check_state_count("nx", x.len())?;
        x.copy_from_slice(self.exchange_and_plant()?.0.states());
        Ok(())
    }

    pub fn get_derivatives(&mut self, dx: &mut [f64]) -> Outcome {
        check_state_count("nx", dx.len())?;
        let plant = self.exchange_plant()?;
        dx.copy_from_slice(&Exchange::derivatives(plant));
        if let Some(i) = dx.iter().position(|v| !v.is_finite()) {
            let name = crate::variables::STATES[i];
            return Err(plant.not_finite(&format!("der({name})"), dx[i]).into());
        }
        Ok(())
    }

    pub fn get_event_indicators(&mut self, z: &mut [f64]) -> Outcome {
        let expected = crate::description::EVENT_INDICATORS;
        if z.len() != expected {
            return Err(Failure::error(format!(
                "ni = {}: this FMU has {expected} event indicator",
                z.len()
            )));
        }
        z.copy_from_slice(&Exchange::indicators(self.exchange_plant()?));
        Ok(())
    }

    pub fn get_nominals(&mut self, nominals: &mut [f64]) -> Outcome {
        check_state_count("nx", nominals.len())?;
        // Angles and speeds of order one: the solver's absolute tolerance applies as is.
        nominals.fill(1.0);
        Ok(())
    }

    pub fn enter_event_mode(&mut self) -> Outcome {
        if self.interface() == Interface::CoSimulation && !self.event_mode_used {
            return Err(Failure::error(
                "eventModeUsed was false at instantiation: this Co-Simulation instance has no \
                 event mode",
            ));
        }
        self.current.state = State::EventMode;
        Ok(())
    }

    /// FMI 3.0 Co-Simulation: from event mode back to stepping.
    pub fn enter_step_mode(&mut self) -> Outcome {
        self.current.state = State::StepMode;
        Ok(())
    }

    /// fmi3UpdateDiscreteStates: in Model Exchange the chart's handover; in Co-Simulation
    /// nothing changes at an event. Returns whether the continuous states changed.
    pub fn update_discrete_states(&mut self) -> Result<bool, Failure> {
        match self.interface() {
            Interface::ModelExchange => self.new_discrete_states(),
            Interface::CoSimulation => Ok(false),
        }
    }

    pub fn enter_continuous_time_mode(&mut self) -> Outcome {
        self.current.state = State::ContinuousTimeMode;
        Ok(())
    }

    /// NewDiscreteStates (FMI 2.0), UpdateDiscreteStates (3.0): the chart's handover, if its indicator has crossed. Returns
    /// whether the continuous states changed.
    pub fn new_discrete_states(&mut self) -> Result<bool, Failure> {
        let (exchange, plant) = self.exchange_and_plant()?;
        let changed = exchange
            .update(plant)
            .map_err(|e| Failure::error(e.to_string()))?;
        if changed && self.log_enabled(Category::Solver) {
            let plant = &self.current.plant;
            let message = format!(
                "t = {}: the loop's leading angle is now phi{}",
                plant.time(),
                plant.chart() as i32
            );
            self.log(Status::Ok, Category::Solver, &message);
        }
        Ok(changed)
    }

    /// GetDirectionalDerivative: the knowns are the inputs, and in Model Exchange the
    /// continuous states; the unknowns any Real outputs and state derivatives.
    pub fn directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Outcome {
        self.assemble_if_needed()?;
        let (mut input_seed, mut state_seed) = ([0.0; 2], [0.0; STATES]);
        let exchange = self.interface() == Interface::ModelExchange;
        for (vr, s) in knowns.iter().zip(seed) {
            let var = variable(*vr).ok_or(AccessError::UnknownReference(*vr))?;
            if !s.is_finite() {
                return Err(Failure::error(format!(
                    "the seed of {} = {s}: must be finite",
                    var.name
                )));
            }
            let state = STATE_REFERENCES.iter().position(|r| r == vr);
            match (var.slot, state) {
                (Slot::Input(Input::MotorTorque), _) => input_seed[0] += s,
                (Slot::Input(Input::LoadTorque), _) => input_seed[1] += s,
                (_, Some(i)) if exchange => state_seed[i] += s,
                _ => {
                    let knowns = if exchange {
                        "the inputs and the continuous states"
                    } else {
                        "the inputs (in Co-Simulation)"
                    };
                    return Err(Failure::error(format!(
                        "{} is not a known: the knowns are {knowns}",
                        var.name
                    )));
                }
            }
        }
        let states = match &self.current.driver {
            Driver::ModelExchange(Some(e)) => Some((e.coordinates(), e.states(), &state_seed)),
            _ => None,
        };
        self.current
            .plant
            .directional_derivatives(states, input_seed, unknowns, sensitivity)
            .map_err(Failure::from)
    }

    /// fmi3GetAdjointDerivative: `sensitivity` = Jᵀ·`seed`, J being the Jacobian of the
    /// unknowns by the knowns, column by column from the directional derivative.
    pub fn adjoint_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Outcome {
        if let Some(s) = seed.iter().find(|s| !s.is_finite()) {
            return Err(Failure::error(format!("a seed of {s}: must be finite")));
        }
        let mut column = vec![0.0; unknowns.len()];
        for (known, out) in knowns.iter().zip(sensitivity.iter_mut()) {
            self.directional_derivative(
                unknowns,
                std::slice::from_ref(known),
                &[1.0],
                &mut column,
            )?;
            *out = column.iter().zip(seed).map(|(j, s)| j * s).sum();
        }
        Ok(())
    }

    /// CompletedIntegratorStep: asks for an event where the indicator has crossed (for
    /// masters that do not locate state events themselves).
    pub fn completed_integrator_step(&mut self) -> Result<bool, Failure> {
        Ok(Exchange::indicators(self.exchange_plant()?)[0] < 0.0)
    }

    /// Inlined into fmi2GetReal, as `do_step` into fmi2DoStep: left to itself, the compiler
    /// kept both as calls of their own in the cdylib, a cost paid at every communication
    /// point.
    #[inline(always)]
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Outcome {
        self.assemble_if_needed()?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            *value = self.current.plant.read_real(*vr)?;
        }
        Ok(())
    }

    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32]) -> Outcome {
        self.get_whole(vrs.iter().copied(), VarType::Integer, |i, v| values[i] = v)
    }

    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [i32]) -> Outcome {
        self.get_whole(vrs.iter().copied(), VarType::Boolean, |i, v| values[i] = v)
    }

    /// Integer (and Enumeration) or Boolean values, which C passes alike (1 for true): the
    /// i-th of `vrs` handed to `put` as (i, value), so that each version writes its own C
    /// type without a buffer.
    pub fn get_whole(
        &mut self,
        vrs: impl Iterator<Item = u32>,
        accessor: VarType,
        mut put: impl FnMut(usize, i32),
    ) -> Outcome {
        self.assemble_if_needed()?;
        let activity = self.current.activity();
        for (i, vr) in vrs.enumerate() {
            put(
                i,
                match self.current.plant.read(vr, accessor, &activity)? {
                    Value::Integer(v) => v,
                    Value::Boolean(v) => i32::from(v),
                    Value::Real(_) => unreachable!("read checks the accessor's type"),
                },
            );
        }
        Ok(())
    }

    /// Validate every (value reference, value) first, then apply: a rejected batch changes
    /// nothing.
    pub fn set_values(&mut self, values: impl Iterator<Item = (u32, Value)> + Clone) -> Outcome {
        let current = &mut self.current;
        let writable = current.state.parameters_writable();
        for (vr, value) in values.clone() {
            current.plant.check_set(vr, value, writable)?;
        }
        for (vr, value) in values {
            current.plant.set(vr, value, writable)?;
        }
        if current.state == State::InitializationMode {
            // The assembly, and the driver started on it, are stale: the next read makes
            // them again.
            current.driver.stop();
        }
        Ok(())
    }

    /// Validate every derivative first, then apply: a rejected batch changes nothing.
    pub fn set_input_derivatives(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        values: &[f64],
    ) -> Outcome {
        let plant = &mut self.current.plant;
        for ((vr, order), value) in vrs.iter().zip(orders).zip(values) {
            plant.check_input_derivative(*vr, *order, *value)?;
        }
        for ((vr, order), value) in vrs.iter().zip(orders).zip(values) {
            plant.set_input_derivative(*vr, *order, *value)?;
        }
        Ok(())
    }

    pub fn get_output_derivatives(
        &mut self,
        vrs: impl Iterator<Item = u32>,
        orders: &[i32],
        values: &mut [f64],
    ) -> Outcome {
        self.assemble_if_needed()?;
        let plant = &self.current.plant;
        for ((vr, order), value) in vrs.zip(orders).zip(values.iter_mut()) {
            *value = plant.output_derivative(vr, *order)?;
            if !value.is_finite() {
                let name = variable(vr).map_or("?", |v| v.name);
                let what = format!("the output derivative of order {order} of {name}");
                return Err(plant.not_finite(&what, *value).into());
            }
        }
        Ok(())
    }

    /// fmi3DoStep: as fmi2DoStep, but a change point is an event, and a step is bounded
    /// in work, as the driver's step with events has it ([`events::step`]); a step it
    /// refuses is FMI 3.0's Discard, the FMU as before the call.
    pub fn do_step_fmi3(&mut self, current: f64, step: f64) -> Result<StepEnd, Failure> {
        let now = self.current.plant.time();
        let target = self.step_target(now, current, step)?;
        let handling = EventHandling {
            event_mode: self.event_mode_used,
            early_return: self.early_return_allowed,
        };
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
                self.report_step(self.current.plant.time(), stability_limited);
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
        let branch = self.current.plant.branch().name();
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
        } = &mut self.current
        else {
            return Err(Failure::error("the integrator starts at initialisation"));
        };
        Ok((plant, driver, experiment))
    }

    #[inline(always)]
    pub fn do_step(&mut self, current: f64, step: f64) -> Outcome {
        let now = self.current.plant.time();
        let target = self.step_target(now, current, step)?;
        self.cosimulation()?.1.allow_work(CALL_WORK);
        if let Err(error) = self.advance_to(target)? {
            return Err(self.step_failed(now, target, error));
        }
        Ok(())
    }

    /// The plant advanced to `target` by the co-simulation driver and the step reported;
    /// the outer error when there is no driver yet, the inner the solver's (the plant then
    /// stays where it was).
    #[inline(always)]
    fn advance_to(&mut self, target: f64) -> Result<Result<(), SolverError>, Failure> {
        let warned = self.warned_stability;
        let (plant, driver, experiment) = self.cosimulation()?;
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
        // The larger of two numbers that are not NaN here: `f64::max` also handles NaN, in a
        // longer sequence of instructions on every step.
        let larger = |a: f64, b: f64| if a > b { a } else { b };
        // Finiteness as a comparison with f64::MAX rather than `is_finite`: with the latter
        // the compiler tested these checks on the bits, a longer sequence. NaN fails every
        // comparison.
        let step_is_valid = step > 0.0 && step <= f64::MAX;
        let current_is_finite = current.abs() <= f64::MAX;
        if !step_is_valid {
            return Err(Failure::error(format!(
                "communicationStepSize = {} must be finite and > 0",
                number(step)
            )));
        }
        // The master's point and the FMU's time agree up to the rounding of the sum that
        // made each: relative to their size, never to the step's.
        if !current_is_finite
            || (current - now).abs() > TIME_MATCH * larger(now.abs(), current.abs())
        {
            return Err(Failure::error(format!(
                "currentCommunicationPoint = {} does not match the FMU's time {}",
                number(current),
                number(now)
            )));
        }
        let target = current + step;
        if let Some(stop) = self.current.experiment.stop {
            if target > stop + TIME_MATCH * larger(stop.abs(), current.abs()) {
                return Err(Failure::error(format!(
                    "a step to t = {target} would pass stopTime = {stop}"
                )));
            }
        }
        Ok(target)
    }

    /// An FMI 2.0 step the driver could not complete: the instance is in StepFailed, its
    /// outputs at the last communication point, which fmi2LastSuccessfulTime reports ("the
    /// end time of the last successfully completed communication step") and the message
    /// gives.
    #[cold]
    fn step_failed(&mut self, now: f64, target: f64, error: SolverError) -> Failure {
        self.current.state = State::StepFailed;
        let y = self.current.plant.state();
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
            let s = self.current.activity().statistics;
            let message = format!(
                "t = {target}: {} steps, {} rejected, {} right-hand sides so far",
                s.n_steps, s.n_rejected, s.n_rhs
            );
            self.log(Status::Ok, Category::Solver, &message);
        }
    }

    pub fn terminate(&mut self) -> Outcome {
        self.current.state = State::Terminated;
        Ok(())
    }

    /// Back to the state just after instantiation, every variable at its start value.
    pub fn reset(&mut self) -> Outcome {
        self.current = FmuState::new(self.interface(), self.version());
        Ok(())
    }

    pub fn last_successful_time(&self) -> f64 {
        self.current.plant.time()
    }

    pub fn save(&self) -> FmuState {
        self.current.clone()
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
        self.current = saved.clone();
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
