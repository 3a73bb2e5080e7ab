//! A simulation of the mechanism: parameters, inputs, time, state and the integrator.
//! It knows the variable table but nothing of FMI's C interface or state machine, so a
//! Model Exchange or FMI 3.0 front end can drive the same object.

use crate::model::params::check_rule;
use crate::model::{self, Inputs, Mechanism, ModelError, Parameters, State, STATE_SIZE};
use crate::solver::{Dop853, SolverError, Statistics, Tolerances};
use crate::variables::{variable, Input, Output, Slot};

/// Relative tolerance when the master gives none (the DefaultExperiment's).
pub const DEFAULT_TOLERANCE: f64 = 1e-8;
/// Admissible relative tolerances.
pub const TOLERANCE_RANGE: (f64, f64) = (1e-14, 1e-1);

/// Why a value cannot be read or written.
#[derive(Clone, Debug, PartialEq)]
pub enum AccessError {
    UnknownReference(u32),
    /// The variable exists but this operation does not apply to it now.
    NotAllowed(String),
    Invalid(ModelError),
}

impl std::fmt::Display for AccessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AccessError::UnknownReference(vr) => write!(f, "unknown value reference {vr}"),
            AccessError::NotAllowed(message) => f.write_str(message),
            AccessError::Invalid(error) => write!(f, "{error}"),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Simulation {
    params: Parameters,
    inputs: Inputs,
    tolerance: f64,
    time: f64,
    state: State,
    solver: Dop853<STATE_SIZE>,
}

impl Default for Simulation {
    fn default() -> Self {
        Self::new()
    }
}

impl Simulation {
    /// A simulation with every variable at its start value, not yet initialised.
    pub fn new() -> Self {
        Self {
            params: Parameters::default(),
            inputs: Inputs::default(),
            tolerance: DEFAULT_TOLERANCE,
            time: 0.0,
            state: [0.0; STATE_SIZE],
            solver: Dop853::new(tolerances(DEFAULT_TOLERANCE)),
        }
    }

    pub fn params(&self) -> &Parameters {
        &self.params
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn state(&self) -> &State {
        &self.state
    }

    pub fn statistics(&self) -> Statistics {
        self.solver.statistics()
    }

    /// Set the relative tolerance (before initialisation).
    pub fn set_tolerance(&mut self, tolerance: f64) -> Result<(), ModelError> {
        let (low, high) = TOLERANCE_RANGE;
        if !(low..=high).contains(&tolerance) {
            return Err(ModelError::new(format!(
                "tolerance = {tolerance} must lie in [{low:e}, {high:e}]"
            )));
        }
        self.tolerance = tolerance;
        Ok(())
    }

    /// The consistent initial state at `start_time` (SPEC §3); resets the solver.
    pub fn initialize(&mut self, start_time: f64) -> Result<(), ModelError> {
        self.state = model::initial_state(&self.params)?;
        self.time = start_time;
        self.solver = Dop853::new(tolerances(self.tolerance));
        Ok(())
    }

    /// Advance to `t_end`. On error the time and state stay as they were.
    pub fn advance(&mut self, t_end: f64) -> Result<(), SolverError> {
        let (mut t, mut y) = (self.time, self.state);
        let system = Mechanism {
            params: &self.params,
            inputs: &self.inputs,
        };
        match self.solver.integrate(&system, &mut t, &mut y, t_end) {
            Ok(()) if y.iter().all(|v| v.is_finite()) => {
                self.time = t;
                self.state = y;
                Ok(())
            }
            Ok(()) => {
                self.solver.invalidate();
                Err(SolverError::StepSizeTooSmall { t, h: 0.0 })
            }
            Err(error) => {
                self.solver.invalidate();
                Err(error)
            }
        }
    }

    /// The current value of variable `vr`.
    pub fn get(&self, vr: u32) -> Result<f64, AccessError> {
        let slot = variable(vr).ok_or(AccessError::UnknownReference(vr))?.slot;
        Ok(match slot {
            Slot::Input(Input::MotorTorque) => self.inputs.motor_torque,
            Slot::Input(Input::LoadTorque) => self.inputs.load_torque,
            Slot::Parameter(i) => self
                .params
                .get(i)
                .ok_or(AccessError::UnknownReference(vr))?,
            Slot::Output(output) => self.output(output),
        })
    }

    /// Set input or parameter `vr`; `parameters_writable` says whether parameters may
    /// change now. A rejected value changes nothing.
    pub fn set(
        &mut self,
        vr: u32,
        value: f64,
        parameters_writable: bool,
    ) -> Result<(), AccessError> {
        match self.check_set(vr, value, parameters_writable)? {
            Slot::Input(Input::MotorTorque) => self.inputs.motor_torque = value,
            Slot::Input(Input::LoadTorque) => self.inputs.load_torque = value,
            Slot::Parameter(i) => self.params.set(i, value).map_err(AccessError::Invalid)?,
            Slot::Output(_) => unreachable!("check_set refuses outputs"),
        }
        // The right-hand side changed: the solver's stored first stage is stale.
        self.solver.invalidate();
        Ok(())
    }

    /// Check that `value` may be written to `vr` now, without writing it: lets a
    /// caller validate a whole batch before applying any of it. Returns the slot.
    pub fn check_set(
        &self,
        vr: u32,
        value: f64,
        parameters_writable: bool,
    ) -> Result<Slot, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        if !value.is_finite() {
            return Err(AccessError::NotAllowed(format!(
                "{} = {value}: must be a finite number",
                var.name
            )));
        }
        match var.slot {
            Slot::Input(_) => {}
            Slot::Parameter(i) if parameters_writable => {
                check_rule(&model::PARAMETERS[i], value).map_err(AccessError::Invalid)?;
            }
            Slot::Parameter(_) => {
                return Err(AccessError::NotAllowed(format!(
                    "{} is a fixed parameter: it can only be set before fmi2ExitInitializationMode",
                    var.name
                )))
            }
            Slot::Output(_) => {
                return Err(AccessError::NotAllowed(format!(
                    "{} is an output and cannot be set",
                    var.name
                )))
            }
        }
        Ok(var.slot)
    }

    /// An output, computed from the current state and inputs; diagnostics only on demand.
    pub fn output(&self, output: Output) -> f64 {
        let (p, y) = (&self.params, &self.state);
        match output {
            Output::Angle(i) => y[i],
            Output::Speed(i) => y[4 + i],
            Output::RodForce => model::rod_force(p, &self.inputs, y),
            Output::ConstraintResidual => model::length_residual(p, y[1], y[2]),
            Output::Energy => model::energy(p, y),
        }
    }
}

/// Absolute tolerance equal to the relative one: the angles and speeds have unit scale.
fn tolerances(rtol: f64) -> Tolerances {
    Tolerances { rtol, atol: rtol }
}
