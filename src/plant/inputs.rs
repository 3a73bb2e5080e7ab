//! The inputs the master sets, with their first and second time derivatives, and the
//! rule every one of them keeps.

use super::{AccessError, Plant};
use crate::model::{self, Inputs};
use crate::variables::{variable, Input, Slot};
use integrators::text::number;

/// First and second time derivatives of the inputs (the master's input derivatives): within a
/// communication step starting at tc, an input is u(t) = u + u′·(t − tc) + u″·(t − tc)²/2,
/// u being its value at tc. At the step's end the inputs move on along them (value and
/// first derivative), so that the outputs there see the inputs the step ended with, and
/// the polynomial goes on until the master sets new values or derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InputDerivatives {
    pub motor_torque: [f64; 2],
    pub load_torque: [f64; 2],
}

impl InputDerivatives {
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// The inputs at time `t` of a step that started at `anchor` with values `base`.
    #[inline]
    pub fn at(&self, base: &Inputs, anchor: f64, t: f64) -> Inputs {
        let dt = t - anchor;
        let poly = |u: f64, [d1, d2]: [f64; 2]| u + dt * (d1 + 0.5 * dt * d2);
        Inputs {
            motor_torque: poly(base.motor_torque, self.motor_torque),
            load_torque: poly(base.load_torque, self.load_torque),
        }
    }
}

impl Plant {
    /// The inputs at time `t`: the values the master set, moved along their derivatives
    /// from the current time.
    #[inline(always)]
    pub fn inputs_at(&self, t: f64) -> Inputs {
        if self.input_derivatives.is_zero() {
            self.inputs
        } else {
            self.input_derivatives.at(&self.inputs, self.time, t)
        }
    }
    /// After a communication step from `start`: the inputs moved on along their derivatives
    /// to the plant's time, as the step integrated them. The outputs and their derivatives
    /// at the step's end then see the inputs there, and a next step without new values
    /// continues their polynomials.
    #[inline(always)]
    pub fn move_inputs_on(&mut self, start: f64) {
        if !self.input_derivatives.is_zero() {
            self.move_inputs_along(start);
        }
    }
    /// Out of line: held inputs, the common case, never come here.
    #[inline(never)]
    fn move_inputs_along(&mut self, start: f64) {
        let dt = self.time - start;
        let inputs = self.input_derivatives.at(&self.inputs, start, self.time);
        let mut derivatives = self.input_derivatives;
        for [d1, d2] in [&mut derivatives.motor_torque, &mut derivatives.load_torque] {
            *d1 += dt * *d2;
        }
        // Where they would leave what the model admits, they stay as the master set them.
        let admitted = |d: &[f64; 2]| d.iter().all(|v| v.abs() <= MAX_INPUT_DERIVATIVE);
        if check_inputs(&inputs, "").is_ok()
            && admitted(&derivatives.motor_torque)
            && admitted(&derivatives.load_torque)
        {
            self.inputs = inputs;
            self.input_derivatives = derivatives;
        }
    }
    /// Set the `order`-th time derivative (1 or 2) of input `vr` for the steps to come.
    pub fn set_input_derivative(
        &mut self,
        vr: u32,
        order: i32,
        value: f64,
    ) -> Result<(), AccessError> {
        let slot = self.check_input_derivative(vr, order, value)?;
        let derivatives = match slot {
            Slot::Input(Input::MotorTorque) => &mut self.input_derivatives.motor_torque,
            _ => &mut self.input_derivatives.load_torque,
        };
        if derivatives[order as usize - 1] != value {
            derivatives[order as usize - 1] = value;
            self.changed = true;
        }
        Ok(())
    }
    /// Check an input derivative without setting it (for validating a batch first).
    pub fn check_input_derivative(
        &self,
        vr: u32,
        order: i32,
        value: f64,
    ) -> Result<Slot, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        if !matches!(var.slot, Slot::Input(_)) {
            return Err(AccessError::NotAllowed(format!(
                "{} is not an input: it has no input derivatives",
                var.name
            )));
        }
        if !(1..=2).contains(&order) {
            return Err(AccessError::NotAllowed(format!(
                "order = {order} for {}: must be 1 or 2",
                var.name
            )));
        }
        if !value.is_finite() || value.abs() > MAX_INPUT_DERIVATIVE {
            return Err(AccessError::NotAllowed(format!(
                "derivative of {} = {}: must be finite, within ±{MAX_INPUT_DERIVATIVE:e}",
                var.name,
                number(value)
            )));
        }
        Ok(var.slot)
    }
}

/// Inputs within the rule the setters apply; `whose` names them in the message.
pub fn check_inputs(inputs: &Inputs, whose: &str) -> Result<(), String> {
    for (name, u) in [("M_m", inputs.motor_torque), ("M_r", inputs.load_torque)] {
        model::params::INPUT_RULE
            .check(u)
            .map_err(|rule| format!("input {name}{whose} = {} {rule}", number(u)))?;
    }
    Ok(())
}

/// Input derivatives beyond this (N·m/s, N·m/s²) would carry the inputs past any torque
/// the model admits within a second.
pub(super) const MAX_INPUT_DERIVATIVE: f64 = 1e15;
