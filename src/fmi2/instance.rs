//! One FMU instance: its restorable state ([`FmuState`], in `fmu_state.rs`), the master's
//! callbacks and the logging settings, and the operations of the FMI functions on them. Everything here
//! is safe Rust on slices; the function files turn C pointers into these calls.

use std::ffi::CString;

use fmi_sys::fmi2::{
    fmi2CallbackLogger, fmi2ComponentEnvironment, fmi2Status, fmi2Status_fmi2Discard,
    fmi2Status_fmi2Error, fmi2Status_fmi2Fatal, fmi2Status_fmi2OK, fmi2Status_fmi2Warning,
};

pub use super::fmu_state::{Driver, FmuState};
use super::model_description::LOG_CATEGORIES;
use super::state_machine::{Interface, State};
use crate::drivers::model_exchange::STATES;
use crate::drivers::{CoSimulation, Exchange, Experiment};
use crate::plant::{AccessError, Plant, Value};
use crate::solver::SolverError;
use crate::text::number;
use crate::variables::{variable, Input, Slot, VarType, STATE_REFERENCES};

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
    pub status: fmi2Status,
    pub message: String,
}

impl Failure {
    pub fn error(message: impl Into<String>) -> Self {
        Self {
            status: fmi2Status_fmi2Error,
            message: message.into(),
        }
    }

    pub fn discard(message: impl Into<String>) -> Self {
        Self {
            status: fmi2Status_fmi2Discard,
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
    logger: fmi2CallbackLogger,
    environment: fmi2ComponentEnvironment,
    /// fmi2SetDebugLogging's switch, and the debug categories it enabled.
    debug_logging: bool,
    enabled: [bool; LOG_CATEGORIES.len()],
    /// Everything fmi2SetFMUstate restores.
    pub current: FmuState,
    /// Addresses of the FMU states this instance has handed out and not yet freed.
    issued_states: Vec<usize>,
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
        name: CString,
        logger: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
        debug_logging: bool,
    ) -> Self {
        Self {
            name,
            logger,
            environment,
            debug_logging,
            enabled: [true; LOG_CATEGORIES.len()],
            current: FmuState::new(interface),
            issued_states: Vec::new(),
            warned_stability: false,
        }
    }

    /// Errors, discards, warnings and fatal errors are always reported; the debug
    /// categories (calls, solver) only while debug logging is on for them. Nothing is
    /// reported (or formatted) without a logger callback.
    pub fn log_enabled(&self, category: Category) -> bool {
        if self.logger.is_none() {
            return false;
        }
        match category {
            Category::Calls | Category::Solver => {
                self.debug_logging && self.enabled[category as usize]
            }
            _ => true,
        }
    }

    /// Send a message to the master's logger, if it gave one.
    pub fn log(&self, status: fmi2Status, category: Category, message: &str) {
        if let Some(logger) = self.logger {
            let category = LOG_CATEGORIES[category as usize].0;
            send_log(
                logger,
                self.environment,
                &self.name,
                status,
                category,
                message,
            );
        }
    }

    pub fn report(&self, failure: &Failure, function: &str) {
        let category = match failure.status {
            s if s == fmi2Status_fmi2Discard => Category::Discard,
            s if s == fmi2Status_fmi2Warning => Category::Warning,
            s if s == fmi2Status_fmi2Fatal => Category::Fatal,
            _ => Category::Error,
        };
        self.log(
            failure.status,
            category,
            &format!("{function}: {}", failure.message),
        );
    }

    /// FMI 2.0 semantics: no categories switches debug logging on or off altogether;
    /// with categories and `on`, exactly those are enabled; with `!on`, those are disabled.
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
        if categories.is_empty() {
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

    /// The interface the instance was created for.
    pub fn interface(&self) -> Interface {
        self.current.interface()
    }

    pub fn exit_initialization_mode(&mut self) -> Outcome {
        self.initialise_plant()?;
        self.current.state = match self.interface() {
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
            (fmi2Status_fmi2Warning, Category::Warning)
        } else {
            (fmi2Status_fmi2OK, Category::Solver)
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

    pub fn set_continuous_states(&mut self, x: &[f64]) -> Outcome {
        check_state_count("nx", x.len())?;
        let (exchange, plant) = self.exchange_and_plant()?;
        exchange
            .set_states(plant, x)
            .map_err(|e| Failure::error(e.to_string()))
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
        let expected = super::model_description::EVENT_INDICATORS;
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
        self.current.state = State::EventMode;
        Ok(())
    }

    pub fn enter_continuous_time_mode(&mut self) -> Outcome {
        self.current.state = State::ContinuousTimeMode;
        Ok(())
    }

    /// fmi2NewDiscreteStates: the chart's handover, if its indicator has crossed. Returns
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
            self.log(fmi2Status_fmi2OK, Category::Solver, &message);
        }
        Ok(changed)
    }

    /// fmi2GetDirectionalDerivative: the knowns are the inputs, and in Model Exchange the
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

    /// fmi2CompletedIntegratorStep: asks for an event where the indicator has crossed (for
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
        self.get_whole(vrs, values, VarType::Integer)
    }

    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [i32]) -> Outcome {
        self.get_whole(vrs, values, VarType::Boolean)
    }

    /// Integer (and Enumeration) or Boolean values, which C passes alike (1 for true).
    fn get_whole(&mut self, vrs: &[u32], values: &mut [i32], accessor: VarType) -> Outcome {
        self.assemble_if_needed()?;
        let activity = self.current.activity();
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            *value = match self.current.plant.read(*vr, accessor, &activity)? {
                Value::Integer(v) => v,
                Value::Boolean(v) => i32::from(v),
                Value::Real(_) => unreachable!("read checks the accessor's type"),
            };
        }
        Ok(())
    }

    /// Validate every value first, then apply: a rejected batch changes nothing.
    pub fn set_values(
        &mut self,
        vrs: &[u32],
        values: impl Iterator<Item = Value> + Clone,
    ) -> Outcome {
        let current = &mut self.current;
        let writable = current.state.parameters_writable();
        for (vr, value) in vrs.iter().zip(values.clone()) {
            current.plant.check_set(*vr, value, writable)?;
        }
        for (vr, value) in vrs.iter().zip(values) {
            current.plant.set(*vr, value, writable)?;
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
        vrs: &[u32],
        orders: &[i32],
        values: &mut [f64],
    ) -> Outcome {
        self.assemble_if_needed()?;
        let plant = &self.current.plant;
        for ((vr, order), value) in vrs.iter().zip(orders).zip(values.iter_mut()) {
            *value = plant.output_derivative(*vr, *order)?;
            if !value.is_finite() {
                let name = variable(*vr).map_or("?", |v| v.name);
                let what = format!("the output derivative of order {order} of {name}");
                return Err(plant.not_finite(&what, *value).into());
            }
        }
        Ok(())
    }

    #[inline(always)]
    pub fn do_step(&mut self, current: f64, step: f64) -> Outcome {
        let now = self.current.plant.time();
        let target = self.step_target(now, current, step)?;
        let FmuState {
            plant,
            driver: Driver::CoSimulation(Some(driver)),
            experiment,
            ..
        } = &mut self.current
        else {
            return Err(Failure::error("the integrator starts at initialisation"));
        };
        if let Err(error) = super::isa::advance(driver, plant, target, experiment) {
            return Err(self.step_failed(now, target, error));
        }
        let stability_limited = !self.warned_stability && driver.dop853_is_stability_limited();
        self.report_step(target, stability_limited);
        Ok(())
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
        if !current_is_finite || (current - now).abs() > TIME_MATCH * larger(now.abs(), step) {
            return Err(Failure::error(format!(
                "currentCommunicationPoint = {} does not match the FMU's time {}",
                number(current),
                number(now)
            )));
        }
        let target = current + step;
        if let Some(stop) = self.current.experiment.stop {
            if target > stop + TIME_MATCH * larger(stop.abs(), step) {
                return Err(Failure::error(format!(
                    "a step to t = {target} would pass stopTime = {stop}"
                )));
            }
        }
        Ok(target)
    }

    /// A step the driver could not complete: the instance is in StepFailed, its outputs at
    /// the last good communication point, which the message gives.
    #[cold]
    fn step_failed(&mut self, now: f64, target: f64, error: SolverError) -> Failure {
        self.current.state = State::StepFailed;
        let y = self.current.plant.state();
        Failure::discard(format!(
            "step from t = {now} to {target} failed: {error}; state kept at t = {now} \
             (phi2 = {}, phi3 = {}, omega2 = {}, omega3 = {})",
            y[1], y[2], y[5], y[6]
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
                self.log(fmi2Status_fmi2Warning, Category::Warning, &message);
            }
        }
        if self.log_enabled(Category::Solver) {
            let s = self.current.activity().statistics;
            let message = format!(
                "t = {target}: {} steps, {} rejected, {} right-hand sides so far",
                s.n_steps, s.n_rejected, s.n_rhs
            );
            self.log(fmi2Status_fmi2OK, Category::Solver, &message);
        }
    }

    pub fn terminate(&mut self) -> Outcome {
        self.current.state = State::Terminated;
        Ok(())
    }

    /// Back to the state just after fmi2Instantiate, every variable at its start value.
    pub fn reset(&mut self) -> Outcome {
        self.current = FmuState::new(self.interface());
        Ok(())
    }

    pub fn last_successful_time(&self) -> f64 {
        self.current.plant.time()
    }

    pub fn save(&self) -> FmuState {
        self.current.clone()
    }

    pub fn restore(&mut self, saved: &FmuState) -> Outcome {
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

    /// Hand out `saved` as a new FMU state pointer.
    pub fn issue_state(&mut self, saved: FmuState) -> *mut FmuState {
        let pointer = Box::into_raw(Box::new(saved));
        self.issued_states.push(pointer as usize);
        pointer
    }

    /// The state behind `pointer`, if this instance issued it and has not freed it.
    pub fn issued_state(
        &mut self,
        pointer: *mut std::ffi::c_void,
    ) -> Result<&mut FmuState, Failure> {
        if pointer.is_null() {
            return Err(Failure::error("the FMU state is NULL"));
        }
        if !self.issued_states.contains(&(pointer as usize)) {
            return Err(Failure::error(
                "the FMU state was not created by this instance, or was freed already",
            ));
        }
        // SAFETY: the pointer came from Box::into_raw in issue_state and is still owned
        // by this instance (it is in the registry).
        Ok(unsafe { &mut *pointer.cast::<FmuState>() })
    }

    /// Free a state this instance issued.
    pub fn free_state(&mut self, pointer: *mut std::ffi::c_void) -> Outcome {
        self.issued_state(pointer)?;
        self.issued_states.retain(|p| *p != pointer as usize);
        // SAFETY: issued by issue_state (checked above) and now removed from the registry.
        drop(unsafe { Box::from_raw(pointer.cast::<FmuState>()) });
        Ok(())
    }
}

impl Drop for Instance {
    /// States the master did not free go with their instance.
    fn drop(&mut self) {
        for pointer in self.issued_states.drain(..) {
            // SAFETY: every registered address came from Box::into_raw and is freed once.
            drop(unsafe { Box::from_raw(pointer as *mut FmuState) });
        }
    }
}

/// Call the master's logger. The message is passed as the format string with `%` and
/// `#` escaped (FMI 2.0 gives both a meaning there), so masters that format it and
/// masters that print it as it is both show it readably.
pub(crate) fn send_log(
    logger: unsafe extern "C" fn(
        fmi2ComponentEnvironment,
        *const std::ffi::c_char,
        fmi2Status,
        *const std::ffi::c_char,
        *const std::ffi::c_char,
        ...
    ),
    environment: fmi2ComponentEnvironment,
    name: &CString,
    status: fmi2Status,
    category: &str,
    message: &str,
) {
    let escaped = message
        .replace('%', "%%")
        .replace('#', "##")
        .replace('\0', " ");
    let (Ok(category), Ok(text)) = (CString::new(category), CString::new(escaped)) else {
        return;
    };
    // SAFETY: the master supplied `logger` for this purpose; every pointer passed is a
    // valid NUL-terminated string that outlives the call, and no variadic arguments are
    // read because the escaped message contains no conversion specification.
    unsafe {
        logger(
            environment,
            name.as_ptr(),
            status,
            category.as_ptr(),
            text.as_ptr(),
        )
    };
}
