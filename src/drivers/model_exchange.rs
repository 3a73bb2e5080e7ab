//! Model Exchange: the mechanism as an ODE in the loop's independent coordinates
//! (docs/model.md §6), integrated by the master. The continuous states are
//! x = (φ1, q, φ4, ω1, q̇, ω4), q the leading loop angle; the follower's angle and speed are
//! computed in closed form from q and q̇, so the loop closes exactly whatever integrator
//! the master uses, and nothing drifts. One event indicator tells the master where the
//! leading angle should change (a dead point ahead); at that event the states change
//! meaning, and the master is told so.
//!
//! The [`Plant`] holds parameters, inputs, time and the full state, so every variable
//! reads as in Co-Simulation; this adapter keeps what Model Exchange adds: the chart with
//! its branch and turns, and the master's x.

use crate::model::chart::{coordinates_for, full_state, handover_indicator_at, independent};
use crate::model::{Chart, Coordinates, Independent, ModelError, State};
use crate::plant::Plant;
use crate::variables::STATES as STATE_NAMES;
use integrators::bytes::put;
use integrators::bytes::{same_bits, FormatError, Reader, Writer};

/// The number of continuous states.
pub const CONTINUOUS_STATES: usize = STATE_NAMES.len();

/// An indicator below this counts as crossed: a master's root finder may stop just before
/// the zero, and leaving a chart early is harmless (the other one is good there).
const CROSSED: f64 = 1e-9;

#[derive(Clone, Debug, PartialEq)]
pub struct Exchange {
    at: Coordinates,
    x: Independent,
}

impl Exchange {
    /// Model Exchange from the plant's (initialised) state, in its chart.
    pub fn start(plant: &mut Plant) -> Result<Self, ModelError> {
        let exchange = Self::enter(plant, plant.chart())?;
        exchange.place(plant, exchange.full_state(plant)?);
        Ok(exchange)
    }

    /// The chart `chart` entered at the plant's current configuration.
    fn enter(plant: &Plant, chart: Chart) -> Result<Self, ModelError> {
        let y = plant.state();
        Ok(Self {
            at: coordinates_for(plant.params(), y, chart)?,
            x: independent(y, chart),
        })
    }

    /// The full state of x.
    fn full_state(&self, plant: &Plant) -> Result<State, ModelError> {
        full_state(plant.params(), &self.at, &self.x)
    }

    /// Put `y`, the full state of x, into the plant. Callers compute `y` (and check
    /// what they need) first, so that a refusal leaves the plant as it was.
    fn place(&self, plant: &mut Plant, y: State) {
        plant.place(plant.time(), y, self.at.chart);
    }

    pub fn states(&self) -> &Independent {
        &self.x
    }

    pub fn coordinates(&self) -> &Coordinates {
        &self.at
    }

    /// SetContinuousStates: a rejected x changes nothing.
    pub fn set_states(&mut self, plant: &mut Plant, x: &[f64]) -> Result<(), ModelError> {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::new(format!(
                "continuous state {} ({}) = {}: must be finite",
                i, STATE_NAMES[i], x[i]
            )));
        }
        let next = Self {
            at: self.at,
            x: std::array::from_fn(|i| x[i]),
        };
        let y = next.full_state(plant)?;
        next.place(plant, y);
        *self = next;
        Ok(())
    }

    /// ẋ at the current time, state and inputs.
    pub fn derivatives(plant: &Plant) -> [f64; CONTINUOUS_STATES] {
        plant.exchange_derivatives()
    }

    /// The event indicator: the current chart's handover function.
    pub fn indicators(plant: &Plant) -> [f64; 1] {
        [plant.handover_indicator()]
    }

    /// NewDiscreteStates (FMI 3.0's UpdateDiscreteStates): hand over to the other chart if the indicator has crossed.
    /// Returns whether the continuous states changed (their meaning did). A refusal (a
    /// change point, where neither chart holds) changes nothing.
    pub fn update(&mut self, plant: &mut Plant) -> Result<bool, ModelError> {
        if Self::indicators(plant)[0] >= CROSSED {
            return Ok(false);
        }
        let next = Self::enter(plant, plant.chart().other())?;
        let y = next.full_state(plant)?;
        if handover_indicator_at(plant.params(), next.at.chart, &y) < CROSSED {
            return Err(ModelError::new(format!(
                "neither loop angle determines the motion at phi2 = {}, phi3 = {}: crank, rod \
                 and rocker are collinear, a change point; {}",
                y[1],
                y[2],
                crate::model::projection::equal_sums(plant.params())
            )));
        }
        next.place(plant, y);
        *self = next;
        Ok(true)
    }

    pub fn serialize_into(&self, w: &mut Writer) {
        put!(w.u8(self.at.chart as u8));
        put!(w.f64s(&[self.at.branch, self.at.turns]));
        put!(w.f64s(&self.x));
    }

    /// The exchange written by [`Exchange::serialize_into`], checked against the plant
    /// restored with it: x must give exactly its state.
    pub fn deserialize_from(r: &mut Reader, plant: &Plant) -> Result<Self, FormatError> {
        let invalid = |what: String| FormatError(format!("invalid serialized state: {what}"));
        let code = r.u8()?;
        let chart =
            Chart::from_code(code as i32).ok_or_else(|| invalid(format!("chart {code}")))?;
        let [branch, turns] = r.f64s()?;
        let x: Independent = r.f64s()?;
        // Turns are formed as round(·)·2π (coordinates_for): the same product must return.
        let whole = (turns / std::f64::consts::TAU).round() * std::f64::consts::TAU;
        if branch.abs() != 1.0 || whole.to_bits() != turns.to_bits() {
            return Err(invalid("the follower's branch or turns".into()));
        }
        let exchange = Self {
            at: Coordinates {
                chart,
                branch,
                turns,
            },
            x,
        };
        let y = full_state(plant.params(), &exchange.at, &x).map_err(|e| invalid(e.to_string()))?;
        if chart != plant.chart() || !same_bits(&y, plant.state()) {
            return Err(invalid(
                "the continuous states do not give the plant's state".into(),
            ));
        }
        Ok(exchange)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::Value;
    use crate::variables::value_reference;
    use crate::variables::Local;

    fn plant_with(values: &[(&str, f64)]) -> Plant {
        let mut plant = Plant::new();
        for (name, value) in values {
            plant
                .set(value_reference(name).unwrap(), Value::Real(*value), true)
                .unwrap();
        }
        plant.initialize(0.0).unwrap();
        plant
    }

    #[test]
    fn derivatives_are_the_constrained_dynamics() {
        let mut plant = plant_with(&[("omega2_0", 3.0), ("twist12_0", 0.1), ("Mm_a0", 10.0)]);
        let y0 = *plant.state();
        let exchange = Exchange::start(&mut plant).unwrap();
        for (a, b) in plant.state().iter().zip(&y0) {
            assert!((a - b).abs() < 1e-14, "{a} {b}");
        }
        let dx = Exchange::derivatives(&plant);
        let a =
            crate::model::accelerations(plant.params(), plant.inputs(), plant.state()).omega_dot;
        assert_eq!(dx, [y0[4], y0[5], y0[7], a[0], a[1], a[3]]);
        // The same bits as the derivative variables, each read alone.
        let each: [f64; CONTINUOUS_STATES] =
            std::array::from_fn(|i| plant.local(Local::Derivative(i)));
        assert_eq!(dx.map(f64::to_bits), each.map(f64::to_bits));
        assert_eq!(exchange.states()[1], y0[1]);
    }

    #[test]
    fn a_crossed_indicator_hands_over_and_keeps_the_configuration() {
        // A non-Grashof linkage swinging into a dead point of the crank.
        let mut plant = plant_with(&[
            ("l", 0.5),
            ("l2", 0.4),
            ("l3", 0.45),
            ("L", 0.42),
            ("phi2_0", 1.0),
            ("omega2_0", 1.0),
        ]);
        let mut exchange = Exchange::start(&mut plant).unwrap();
        assert!(!exchange.update(&mut plant).unwrap());
        // Walk q until the indicator crosses, as a master's integrator would.
        let mut x = *exchange.states();
        let mut crossed = false;
        for _ in 0..2000 {
            x[1] += 1e-3 * x[4].signum();
            if exchange.set_states(&mut plant, &x).is_err() {
                break;
            }
            if Exchange::indicators(&plant)[0] < 0.0 {
                crossed = true;
                break;
            }
        }
        assert!(crossed, "no handover on the way to the dead point");
        let (before, chart) = (*plant.state(), plant.chart());
        assert!(exchange.update(&mut plant).unwrap());
        assert_ne!(plant.chart(), chart);
        for (a, b) in plant.state().iter().zip(&before) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        assert!(Exchange::indicators(&plant)[0] > 0.0);
    }
}
