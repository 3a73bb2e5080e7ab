//! Reading and writing the variables by value reference: the type of the accessor, and
//! every rule a written value must keep, checked before anything changes.

use super::{solver_kind, Activity, Plant};
use crate::model::params::check_rule;
use crate::model::sensitivity;
use crate::model::{self, ModelError, STATE_SIZE};
use crate::variables::{
    build_table, variable, Branch, Input, Output, Slot, Statistic, Twin, VarType, Variable,
};
use integrators::text::number;

/// A value of one of the FMI types used here (Enumerations travel as Integer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
}

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

impl Plant {
    /// The current value of variable `vr`, the statistics as `activity` reports them.
    pub fn get(&self, vr: u32, activity: &Activity) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        Ok(self.value_of(var.slot, activity))
    }
    /// The current value of `vr` read through an accessor of type `accessor` (Real;
    /// Integer, for Integer and Enumeration variables; Boolean): one lookup, type checked.
    pub fn read(
        &self,
        vr: u32,
        accessor: VarType,
        activity: &Activity,
    ) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let probe = match accessor {
            VarType::Real => Value::Real(0.0),
            VarType::Integer | VarType::Enumeration => Value::Integer(0),
            VarType::Boolean => Value::Boolean(false),
        };
        check_type(var, probe)?;
        Ok(self.value_of(var.slot, activity))
    }
    /// A Real variable's value: the hot path of the Real getters. φ and ω take one subtraction
    /// and one comparison, and need no check (`advance` keeps the state finite; inputs and
    /// parameters are checked when set). The computed outputs are checked: none leaves the
    /// FMU non-finite. Inlined into both versions' getters: with two callers the compiler
    /// kept it out of line, a call per value read.
    #[inline(always)]
    pub fn read_real(&self, vr: u32) -> Result<f64, AccessError> {
        if let Some(y) = self.state.get(vr.wrapping_sub(FIRST_STATE_VR) as usize) {
            return Ok(*y);
        }
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let value = self
            .real_of(var.slot)
            .ok_or_else(|| check_type(var, Value::Real(0.0)).unwrap_err())?;
        if !value.is_finite() {
            return Err(self.not_finite(var.name, value));
        }
        Ok(value)
    }
    /// The refusal of a value that would leave the FMU non-finite: the last guard.
    pub fn not_finite(&self, name: &str, value: f64) -> AccessError {
        let y = &self.state;
        AccessError::NotAllowed(format!(
            "{name} = {value} at t = {} is not finite: the model left its valid range \
             (state: phi2 = {}, phi3 = {}, omega2 = {}, omega3 = {})",
            self.time, y[1], y[2], y[5], y[6]
        ))
    }
    /// The value in a Real slot; `None` for the Integer and Enumeration slots.
    #[inline]
    fn real_of(&self, slot: Slot) -> Option<f64> {
        match slot {
            Slot::Output(output) => Some(self.output(output)),
            Slot::Input(Input::MotorTorque) => Some(self.inputs_set.motor_torque),
            Slot::Input(Input::LoadTorque) => Some(self.inputs_set.load_torque),
            Slot::Parameter(i) => Some(self.params.get(i).unwrap_or(f64::NAN)),
            Slot::Local(local) => Some(self.local(local)),
            Slot::Sensitivity { slot, state } => Some(self.sensitivities[state][slot]),
            Slot::Statistic(_)
            | Slot::SensitivityParameter(_)
            | Slot::SolverChoice
            | Slot::LinkageClass
            | Slot::LoopChart
            | Slot::BuiltinLaws
            | Slot::ChangePointBranch
            | Slot::Twin(_) => None,
        }
    }
    fn value_of(&self, slot: Slot, activity: &Activity) -> Value {
        if let Some(value) = self.real_of(slot) {
            return Value::Real(value);
        }
        let statistic = |count: u64| Value::Integer(count.min(i32::MAX as u64) as i32);
        match slot {
            Slot::Statistic(Statistic::Steps) => statistic(activity.steps),
            Slot::Statistic(Statistic::Rejected) => statistic(activity.rejected),
            Slot::Statistic(Statistic::RightHandSides) => statistic(activity.right_hand_sides),
            Slot::Statistic(Statistic::ActiveSolver) => Value::Integer(activity.active as i32),
            Slot::SolverChoice => Value::Integer(self.solver_kind as i32),
            Slot::LinkageClass => Value::Integer(model::classify(&self.params) as i32),
            Slot::LoopChart => Value::Integer(self.chart as i32),
            Slot::BuiltinLaws => Value::Boolean(self.params.builtin_laws),
            Slot::ChangePointBranch => Value::Integer(self.branch as i32),
            Slot::SensitivityParameter(k) => Value::Integer(self.sensitivity_choice[k]),
            Slot::Twin(Twin::Solver) => Value::Integer(self.codes.solver),
            Slot::Twin(Twin::ChangePointBranch) => Value::Integer(self.codes.branch),
            Slot::Twin(Twin::SensitivityParameter(k)) => Value::Integer(self.codes.sensitivity[k]),
            Slot::Output(_)
            | Slot::Input(_)
            | Slot::Parameter(_)
            | Slot::Local(_)
            | Slot::Sensitivity { .. } => {
                unreachable!("Real slots")
            }
        }
    }
    /// Set input or parameter `vr`; `parameters_writable` says whether parameters may
    /// change now. A rejected value changes nothing; an unchanged value restarts nothing.
    pub fn set(
        &mut self,
        vr: u32,
        value: Value,
        parameters_writable: bool,
    ) -> Result<(), AccessError> {
        let slot = self.check_set(vr, value, parameters_writable)?;
        // An input is compared with what the plant integrates with, which may have moved on
        // from what was set.
        let now = match slot {
            Slot::Input(Input::MotorTorque) => Value::Real(self.inputs.motor_torque),
            Slot::Input(Input::LoadTorque) => Value::Real(self.inputs.load_torque),
            _ => self.get(vr, &Activity::idle())?,
        };
        if let Slot::Input(input) = slot {
            let Value::Real(v) = value else {
                unreachable!("checked: an input is Real")
            };
            match input {
                Input::MotorTorque => self.inputs_set.motor_torque = v,
                Input::LoadTorque => self.inputs_set.load_torque = v,
            }
        }
        if now == value {
            return Ok(());
        }
        match (slot, value) {
            (Slot::Input(Input::MotorTorque), Value::Real(v)) => self.inputs.motor_torque = v,
            (Slot::Input(Input::LoadTorque), Value::Real(v)) => self.inputs.load_torque = v,
            (Slot::Parameter(i), Value::Real(v)) => {
                self.params.set(i, v).map_err(AccessError::Invalid)?
            }
            (Slot::SolverChoice, Value::Integer(v)) => {
                self.solver_kind = solver_kind(v).expect("checked")
            }
            (Slot::BuiltinLaws, Value::Boolean(on)) => self.params.builtin_laws = on,
            (Slot::ChangePointBranch, Value::Integer(v)) => {
                self.branch = Branch::from_value(v).expect("checked")
            }
            (Slot::SensitivityParameter(k), Value::Integer(v)) => self.sensitivity_choice[k] = v,
            (Slot::Twin(Twin::Solver), Value::Integer(v)) => self.codes.solver = v,
            (Slot::Twin(Twin::ChangePointBranch), Value::Integer(v)) => self.codes.branch = v,
            (Slot::Twin(Twin::SensitivityParameter(k)), Value::Integer(v)) => {
                self.codes.sensitivity[k] = v
            }
            _ => unreachable!("check_set admits only writable slots of the right type"),
        }
        // The right-hand side changed. (An input is left to the driver: whether a change
        // matters depends on how far its integrator has gone; the branch matters only at a
        // change point.)
        if !matches!(
            slot,
            Slot::Input(_) | Slot::ChangePointBranch | Slot::Twin(Twin::ChangePointBranch)
        ) {
            self.changed = true;
        }
        Ok(())
    }
    /// Check that `value` may be written to `vr` now, without writing it: lets a caller
    /// validate a whole batch before applying any of it. Returns the slot.
    pub fn check_set(
        &self,
        vr: u32,
        value: Value,
        parameters_writable: bool,
    ) -> Result<Slot, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        check_type(var, value)?;
        if let Value::Real(v) = value {
            if !v.is_finite() {
                return Err(AccessError::NotAllowed(format!(
                    "{} = {v}: must be a finite number",
                    var.name
                )));
            }
        }
        let fixed = matches!(
            var.slot,
            Slot::Parameter(_)
                | Slot::SolverChoice
                | Slot::BuiltinLaws
                | Slot::SensitivityParameter(_)
                | Slot::Twin(Twin::Solver | Twin::SensitivityParameter(_))
        );
        if fixed && !parameters_writable {
            return Err(AccessError::NotAllowed(format!(
                "{} is a fixed parameter: it can only be set before initialisation ends (ExitInitializationMode)",
                var.name
            )));
        }
        self.check_rule_of(var, value)?;
        Ok(var.slot)
    }

    /// The rule of a writable variable on its new value (of the variable's type); the
    /// refusal of a variable that cannot be written.
    fn check_rule_of(&self, var: &Variable, value: Value) -> Result<(), AccessError> {
        let refuse = |v: i32, rule: &str| {
            Err(AccessError::NotAllowed(format!(
                "{} = {v}: must be {rule}",
                var.name
            )))
        };
        match (var.slot, value) {
            (Slot::Input(_), Value::Real(v)) => {
                model::params::INPUT_RULE.check(v).map_err(|rule| {
                    AccessError::NotAllowed(format!("{} = {} {rule}", var.name, number(v)))
                })
            }
            (Slot::Parameter(i), Value::Real(v)) => {
                check_rule(&model::PARAMETERS[i], v).map_err(AccessError::Invalid)
            }
            (Slot::BuiltinLaws, Value::Boolean(_)) | (Slot::Twin(_), Value::Integer(0)) => Ok(()),
            (
                Slot::SensitivityParameter(_) | Slot::Twin(Twin::SensitivityParameter(_)),
                Value::Integer(v),
            ) => self.check_sensitivity_choice(var.name, v),
            (Slot::SolverChoice, Value::Integer(v)) if solver_kind(v).is_none() => {
                refuse(v, "1 (auto), 2 (dop853) or 3 (implicit)")
            }
            (Slot::Twin(Twin::Solver), Value::Integer(v)) if solver_kind(v).is_none() => refuse(
                v,
                "0 (as solver says), 1 (auto), 2 (dop853) or 3 (implicit)",
            ),
            (Slot::ChangePointBranch, Value::Integer(v)) if Branch::from_value(v).is_none() => {
                refuse(v, "1 (straight) or 2 (turn)")
            }
            (Slot::Twin(Twin::ChangePointBranch), Value::Integer(v))
                if Branch::from_value(v).is_none() =>
            {
                refuse(
                    v,
                    "0 (as change_point_branch says), 1 (straight) or 2 (turn)",
                )
            }
            (
                Slot::SolverChoice
                | Slot::ChangePointBranch
                | Slot::Twin(Twin::Solver | Twin::ChangePointBranch),
                Value::Integer(_),
            ) => Ok(()),
            _ => {
                let what = if var.causality() == crate::variables::Causality::Local {
                    "a Model Exchange state or derivative, set through SetContinuousStates"
                } else {
                    "an output"
                };
                Err(AccessError::NotAllowed(format!(
                    "{} is {what} and cannot be set",
                    var.name
                )))
            }
        }
    }

    /// A slot's new value: one of the items. Two slots may follow the same parameter (each
    /// computes its own column, the same numbers): a set is judged on its own value,
    /// whatever the other slots hold or the order a master sets them in.
    fn check_sensitivity_choice(&self, name: &str, v: i32) -> Result<(), AccessError> {
        let refuse = |rule: String| AccessError::NotAllowed(format!("{name} = {v}: {rule}"));
        sensitivity::chosen(v).ok_or_else(|| {
            let index = usize::try_from(v - 1)
                .ok()
                .filter(|&i| i < model::PARAMETERS.len());
            refuse(match index {
                Some(index) => sensitivity::not_offered(index).to_string(),
                None => "must be 0 (none) or a parameter of the SensitivityParameter items".into(),
            })
        })?;
        Ok(())
    }
}

/// The state component a variable reads: φ_i is y[i], ω_i is y[4 + i] (docs/model.md §2's order),
/// as in [`Plant::output`]; `real_reads_agree_with_the_variable_table` checks the two agree.
const fn state_component(slot: Slot) -> Option<usize> {
    match slot {
        Slot::Output(Output::Angle(i)) => Some(i),
        Slot::Output(Output::Speed(i)) => Some(4 + i),
        _ => None,
    }
}

/// The value reference of φ1, which φ2…ω4 follow in state order (the table is built that
/// way, and this checks it when compiling): the Real getter serves a state with one
/// subtraction and one comparison, cheaper than a table lookup per value on the path of
/// every read.
const FIRST_STATE_VR: u32 = {
    let table = build_table();
    let mut first = 0;
    while !matches!(state_component(table[first].slot), Some(0)) {
        first += 1;
    }
    let mut i = 0;
    while i < STATE_SIZE {
        assert!(
            matches!(state_component(table[first + i].slot), Some(c) if c == i),
            "the states' value references are consecutive, in state order"
        );
        i += 1;
    }
    first as u32
};

/// The FMI accessor must match the variable's type.
fn check_type(var: &Variable, value: Value) -> Result<(), AccessError> {
    let matches = matches!(
        (var.var_type(), value),
        (VarType::Real, Value::Real(_))
            | (VarType::Integer | VarType::Enumeration, Value::Integer(_))
            | (VarType::Boolean, Value::Boolean(_))
    );
    if matches {
        return Ok(());
    }
    // The FMI function names the accessor; the plant names the types.
    let asked = match value {
        Value::Real(_) => "Real",
        Value::Integer(_) => "Integer",
        Value::Boolean(_) => "Boolean",
    };
    let own = match var.var_type() {
        VarType::Real => "Real",
        VarType::Integer | VarType::Enumeration => "Integer",
        VarType::Boolean => "Boolean",
    };
    Err(AccessError::NotAllowed(format!(
        "{} is of type {}: read and write it as {own}, not {asked}",
        var.name,
        var.var_type().as_str()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variables::{variables, COUNT};

    /// The Real getter's fast path for φ and ω (by value reference range) gives what the
    /// general path gives, and every other Real variable still reads through the general
    /// path.
    #[test]
    fn real_reads_agree_with_the_variable_table() {
        let mut plant = Plant::new();
        plant
            .set(
                crate::variables::value_reference("omega2_0").unwrap(),
                Value::Real(3.0),
                true,
            )
            .unwrap();
        plant.initialize(0.0).unwrap();
        let mut state_reads = 0;
        for (vr, var) in variables() {
            match plant.real_of(var.slot) {
                Some(expected) => {
                    assert_eq!(
                        plant.read_real(vr).unwrap().to_bits(),
                        expected.to_bits(),
                        "{}",
                        var.name
                    );
                    state_reads += usize::from(state_component(var.slot).is_some());
                }
                None => assert!(plant.read_real(vr).is_err(), "{}", var.name),
            }
        }
        assert_eq!(state_reads, STATE_SIZE);
        for i in 0..4 {
            let phi = crate::variables::value_reference(&format!("phi{}", i + 1)).unwrap();
            let omega = crate::variables::value_reference(&format!("omega{}", i + 1)).unwrap();
            assert_eq!(plant.read_real(phi).unwrap(), plant.state()[i]);
            assert_eq!(plant.read_real(omega).unwrap(), plant.state()[4 + i]);
        }
        assert!(plant.read_real(COUNT as u32).is_err());
    }
}
