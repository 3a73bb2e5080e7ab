//! The plant in the bytes of a serialized FMU state, and the checks a restored plant
//! passes: every value by the rule that admitted it, the state on the constraint.

use super::inputs::MAX_INPUT_DERIVATIVE;
use super::{check_inputs, solver_kind, Codes, InputDerivatives, Plant};
use crate::model::sensitivity;
use crate::model::{self, Chart, Inputs, Parameters, STATE_SIZE};
use crate::variables::{Branch, SENSITIVITY_SLOTS};
use integrators::bytes::put;
use integrators::bytes::{FormatError, Reader, Writer};
use integrators::text::number;

impl Plant {
    /// Everything that determines the plant's future, for a serialized FMU state.
    pub fn serialize_into(&self, w: &mut Writer) {
        for i in 0..model::PARAMETERS.len() {
            put!(w.f64(self.params.get(i).unwrap_or(f64::NAN)));
        }
        put!(w.f64s(&[self.inputs.motor_torque, self.inputs.load_torque]));
        put!(w.f64s(&[self.inputs_set.motor_torque, self.inputs_set.load_torque]));
        put!(w.f64s(&self.input_derivatives.motor_torque));
        put!(w.f64s(&self.input_derivatives.load_torque));
        put!(w.bool(self.params.builtin_laws));
        put!(w.u8(self.solver_kind as u8));
        put!(w.u8(self.branch as u8));
        put!(w.u8(self.codes.solver as u8));
        put!(w.u8(self.codes.branch as u8));
        put!(w.f64(self.time));
        put!(w.f64s(&self.state));
        put!(w.f64(self.residual));
        put!(w.u8(self.chart as u8));
        put!(w.bool(self.changed));
        // The values of the slots in use alone: an unused slot's are zero.
        for k in 0..SENSITIVITY_SLOTS {
            put!(w.u8(self.sensitivity_choice[k] as u8));
            put!(w.u8(self.codes.sensitivity[k] as u8));
            if self.slot_choice(k) != 0 {
                for row in &self.sensitivities {
                    put!(w.f64(row[k]));
                }
            }
        }
    }

    /// The plant written by [`Plant::serialize_into`]; every value is checked again by the
    /// rule that admitted it.
    pub fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let invalid = |e: String| FormatError(format!("invalid serialized state: {e}"));
        let mut params = Parameters::default();
        for i in 0..model::PARAMETERS.len() {
            params
                .set(i, r.f64()?)
                .map_err(|e| invalid(e.to_string()))?;
        }
        let [motor_torque, load_torque] = r.f64s()?;
        let [motor_torque_set, load_torque_set] = r.f64s()?;
        let input_derivatives = InputDerivatives {
            motor_torque: r.f64s()?,
            load_torque: r.f64s()?,
        };
        params.builtin_laws = r.bool()?;
        let kind = r.u8()?;
        let solver_kind =
            solver_kind(kind as i32).ok_or_else(|| invalid(format!("solver = {kind}")))?;
        let code = r.u8()?;
        let branch = Branch::from_value(code as i32)
            .ok_or_else(|| invalid(format!("change_point_branch = {code}")))?;
        let mut codes = Codes {
            solver: i32::from(r.u8()?),
            branch: i32::from(r.u8()?),
            sensitivity: [0; SENSITIVITY_SLOTS],
        };
        if codes.solver != 0 && self::solver_kind(codes.solver).is_none() {
            return Err(invalid(format!("solver_code = {}", codes.solver)));
        }
        if codes.branch != 0 && Branch::from_value(codes.branch).is_none() {
            let branch = codes.branch;
            return Err(invalid(format!("change_point_branch_code = {branch}")));
        }
        let time = r.f64()?;
        let state = r.f64s()?;
        let residual = r.f64()?;
        let code = r.u8()?;
        let chart =
            Chart::from_code(code as i32).ok_or_else(|| invalid(format!("loop chart {code}")))?;
        let changed = r.bool()?;
        let mut sensitivity_choice = [0; SENSITIVITY_SLOTS];
        let mut sensitivities = [[0.0; SENSITIVITY_SLOTS]; STATE_SIZE];
        for k in 0..SENSITIVITY_SLOTS {
            for value in [&mut sensitivity_choice[k], &mut codes.sensitivity[k]] {
                *value = i32::from(r.u8()?);
                if sensitivity::chosen(*value).is_none() {
                    return Err(invalid(format!("sensitivity slot {} = {value}", k + 1)));
                }
            }
            if codes.sensitivity[k] != 0 || sensitivity_choice[k] != 0 {
                for row in sensitivities.iter_mut() {
                    row[k] = r.f64()?;
                }
            }
        }
        let plant = Self {
            params,
            inputs: Inputs {
                motor_torque,
                load_torque,
            },
            inputs_set: Inputs {
                motor_torque: motor_torque_set,
                load_torque: load_torque_set,
            },
            input_derivatives,
            solver_kind,
            branch,
            time,
            state,
            residual,
            chart,
            changed,
            sensitivity_choice,
            sensitivities,
            codes,
        };
        plant.check_restored().map_err(invalid)?;
        Ok(plant)
    }

    /// The inputs and their derivatives of a restored plant, each within its rule (a
    /// checksum protects only against accidents).
    fn check_restored(&self) -> Result<(), String> {
        check_inputs(&self.inputs, "")?;
        check_inputs(&self.inputs_set, "")?;
        let derivatives = self
            .input_derivatives
            .motor_torque
            .iter()
            .chain(&self.input_derivatives.load_torque);
        if derivatives
            .into_iter()
            .any(|d| d.abs() > MAX_INPUT_DERIVATIVE)
        {
            return Err("an input derivative is out of range".into());
        }
        Ok(())
    }

    /// For a state restored after initialisation: the positions close the loop and the
    /// velocities satisfy B1·ω2 = C1·ω3, to well within what the projection leaves.
    pub fn check_consistent(&self) -> Result<(), String> {
        let (p, y) = (&self.params, &self.state);
        let residual = model::length_residual(p, y[1], y[2]);
        let size = p.l + p.l2 + p.l3 + p.L;
        if residual.is_nan() || residual.abs() > 1e-8 * size {
            return Err(format!(
                "the positions do not close the loop (|A2A3| - L = {})",
                number(residual)
            ));
        }
        let (_, b1, c1) = model::kinematics::closure_with_gradient(p, y[1], y[2]);
        let (along, across) = (b1 * y[5], c1 * y[6]);
        let allowed = 1e-8 * (along.abs() + across.abs()) + 1e-12 * size * size;
        if (along - across).is_nan() || (along - across).abs() > allowed {
            return Err(format!(
                "the velocities break the constraint (B1·omega2 - C1·omega3 = {})",
                number(along - across)
            ));
        }
        if (residual - self.residual).abs() > 1e-12 * size {
            return Err("the stored constraint residual is not the state's".into());
        }
        Ok(())
    }

    /// The stored residual, bit for bit (a restored driver's recomputation is compared).
    pub fn residual(&self) -> f64 {
        self.residual
    }
}
