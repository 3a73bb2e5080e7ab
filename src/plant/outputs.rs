//! The outputs computed from the state and inputs, their time derivatives (exact where a
//! formula exists, else along the flow) and their directional derivatives (exact, by
//! forward-mode differentiation).

use super::{AccessError, Plant};
use crate::model::chart::handover_indicator_at;
use crate::model::{
    self, Chart, Coordinates, Dual, Independent, Inputs, Parameters, Scalar, State, STATE_SIZE,
};
use crate::variables::{variable, Local, Output, Slot};

/// Time steps (s) of the central differences along the flow used for output derivatives
/// that have no closed form: about 1e-8 relative accuracy for one difference at the paper's
/// speeds, 1e-6 for the rod force's second derivative (a difference of a difference).
const DIFFERENCE_STEP: f64 = 1e-6;
const SECOND_DIFFERENCE_STEP: f64 = 1e-4;
impl Plant {
    /// The `order`-th time derivative (1 or 2) of output `vr` at the communication point.
    /// Exact where a formula exists (φ′ = ω, φ″ = ω′ = ω̇, energy′ = power of docs/model.md §2,
    /// residual′ = G·ω/|d|); otherwise a central difference along the flow.
    pub fn output_derivative(&self, vr: u32, order: i32) -> Result<f64, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let Slot::Output(output) = var.slot else {
            return Err(AccessError::NotAllowed(format!(
                "{} is not a Real output: it has no output derivatives",
                var.name
            )));
        };
        let (y, t) = (&self.state, self.time);
        match (order, output) {
            (1, _) => Ok(self.rate(output, y, t)),
            (2, Output::Angle(i)) => Ok(self.rate(Output::Speed(i), y, t)),
            // A difference of a difference: a wider outer step keeps rounding small. (A second
            // difference along the line y ± s·ẏ would miss the ∇F·ÿ term of d²F/dt².)
            (2, Output::RodForce) => Ok(self.central_difference(
                |ys, ts| self.rate(Output::RodForce, ys, ts),
                y,
                t,
                SECOND_DIFFERENCE_STEP,
            )),
            (2, _) => Ok(self.central_difference(
                |ys, ts| self.rate(output, ys, ts),
                y,
                t,
                DIFFERENCE_STEP,
            )),
            _ => Err(AccessError::NotAllowed(format!(
                "order = {order} for {}: must be 1 or 2",
                var.name
            ))),
        }
    }
    /// The first time derivative of `output` at (y, t) along the flow.
    fn rate(&self, output: Output, y: &State, t: f64) -> f64 {
        let inputs = self.inputs_at(t);
        match output {
            Output::Angle(i) => y[4 + i],
            Output::Speed(i) => model::accelerations(&self.params, &inputs, y).omega_dot[i],
            Output::Energy => model::power(&self.params, &inputs, y),
            Output::ConstraintResidual => {
                let (g, b1, c1) =
                    model::kinematics::closure_with_gradient(&self.params, y[1], y[2]);
                let length = (self.params.L * self.params.L + 2.0 * g).sqrt();
                (b1 * y[5] - c1 * y[6]) / length
            }
            Output::RodForce => self.central_difference(
                |ys, ts| model::rod_force(&self.params, &self.inputs_at(ts), ys),
                y,
                t,
                DIFFERENCE_STEP,
            ),
        }
    }
    /// (y + s·ẏ, t + s): a point along the flow, s small.
    fn along_flow(&self, y: &State, t: f64, s: f64) -> (State, f64) {
        let mut dy = [0.0; STATE_SIZE];
        self.rhs(t, y, &mut dy);
        (std::array::from_fn(|i| y[i] + s * dy[i]), t + s)
    }
    /// d/dt f(y(t), t) ≈ (f(y + hẏ, t + h) − f(y − hẏ, t − h))/(2h), exact to O(h²).
    fn central_difference(&self, f: impl Fn(&State, f64) -> f64, y: &State, t: f64, h: f64) -> f64 {
        let (ya, ta) = self.along_flow(y, t, h);
        let (yb, tb) = self.along_flow(y, t, -h);
        (f(&ya, ta) - f(&yb, tb)) / (2.0 * h)
    }
    /// The Model Exchange states' derivatives, `Local::Derivative(0..6)` in one call: the
    /// accelerations are computed once (each slot alone computes them all), the same
    /// numbers bit for bit.
    pub fn exchange_derivatives(&self) -> [f64; 6] {
        let (y, lead) = (&self.state, self.chart.leader());
        let a = model::accelerations(&self.params, &self.inputs, y).omega_dot;
        [y[4], y[lead + 4], y[7], a[0], a[lead], a[3]]
    }
    /// The event indicator of the leading angle's chart at the current configuration:
    /// positive while it determines the loop (docs/model.md §6).
    pub fn handover_indicator(&self) -> f64 {
        handover_indicator_at(&self.params, self.chart, &self.state)
    }
    /// The independent coordinates, their derivatives and the event indicator (docs/model.md
    /// §6).
    pub fn local(&self, local: Local) -> f64 {
        if local == Local::HandoverIndicator {
            return self.handover_indicator();
        }
        real_value(
            &self.params,
            &self.inputs,
            &self.state,
            self.chart,
            Slot::Local(local),
        )
        .expect("a Real slot")
    }
    /// An output, computed from the current state and inputs; diagnostics only on demand.
    #[inline]
    pub fn output(&self, output: Output) -> f64 {
        match output {
            // Kept from the projection: no second pair of sin_cos per communication point.
            Output::ConstraintResidual => self.residual,
            _ => real_value(
                &self.params,
                &self.inputs,
                &self.state,
                self.chart,
                Slot::Output(output),
            )
            .expect("a Real slot"),
        }
    }
    /// The derivatives of the Real `unknowns` along a direction of the knowns (GetDirectionalDerivative),
    /// exact by forward-mode differentiation: `input_seed` moves M_m and M_r; `states`, in
    /// Model Exchange, gives the independent coordinates with their seed. Without
    /// `states` the state is held (Co-Simulation's outputs at a communication point).
    pub fn directional_derivatives(
        &self,
        states: Option<(&Coordinates, &Independent, &[f64; 6])>,
        input_seed: [f64; 2],
        unknowns: &[u32],
        out: &mut [f64],
    ) -> Result<(), AccessError> {
        let inputs = Inputs {
            motor_torque: Dual::new(self.inputs.motor_torque, input_seed[0]),
            load_torque: Dual::new(self.inputs.load_torque, input_seed[1]),
        };
        let y: [Dual; STATE_SIZE] = match states {
            Some((at, x, seed)) => {
                let x: [Dual; 6] = std::array::from_fn(|i| Dual::new(x[i], seed[i]));
                model::chart::full_state(&self.params, at, &x).map_err(AccessError::Invalid)?
            }
            None => self.state.map(Dual::constant),
        };
        for (vr, value) in unknowns.iter().zip(out.iter_mut()) {
            let var = variable(*vr).ok_or(AccessError::UnknownReference(*vr))?;
            let derivative = real_value(&self.params, &inputs, &y, self.chart, var.slot)
                .ok_or_else(|| {
                    AccessError::NotAllowed(format!(
                        "{} is not an unknown: directional derivatives are of Real outputs and \
                         state derivatives",
                        var.name
                    ))
                })?
                .d;
            if !derivative.is_finite() {
                return Err(self.not_finite(&format!("the derivative of {}", var.name), derivative));
            }
            *value = derivative;
        }
        Ok(())
    }
}

/// A Real output or Model Exchange variable of state `y` under `inputs` with `chart` leading,
/// generic so that one definition serves values and exact derivatives; `None` for the
/// slots that are not computed from the state. Inlined: in the Real getter's path the match
/// on the slot then folds into the caller's.
#[inline(always)]
fn real_value<T: Scalar>(
    p: &Parameters,
    inputs: &Inputs<T>,
    y: &[T; STATE_SIZE],
    chart: Chart,
    slot: Slot,
) -> Option<T> {
    let lead = chart.leader();
    Some(match slot {
        Slot::Output(Output::Angle(i)) => y[i],
        Slot::Output(Output::Speed(i)) => y[4 + i],
        Slot::Output(Output::RodForce) => model::rod_force(p, inputs, y),
        Slot::Output(Output::ConstraintResidual) => model::length_residual(p, y[1], y[2]),
        Slot::Output(Output::Energy) => model::energy(p, y),
        Slot::Local(Local::LoopAngle) => y[lead],
        Slot::Local(Local::LoopSpeed) => y[lead + 4],
        Slot::Local(Local::Derivative(i)) if i < 3 => [y[4], y[lead + 4], y[7]][i],
        Slot::Local(Local::Derivative(i)) => {
            let a = model::accelerations(p, inputs, y).omega_dot;
            [a[0], a[lead], a[3]][i - 3]
        }
        _ => return None,
    })
}
