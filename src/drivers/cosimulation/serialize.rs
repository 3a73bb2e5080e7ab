//! The co-simulation driver in the bytes of a serialized FMU state, and the checks a
//! restored driver passes: its inputs within their rules, its point not behind the
//! communication point, its memory what its own steps on this system give.

use super::*;
use integrators::bytes::put;

impl InFlight {
    /// What [`CoSimulation::serialize_into`] wrote of a crossing under way.
    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let [start, motor_torque, load_torque] = r.f64s()?;
        let from = r.f64s()?;
        let [duration, node_phi2, node_phi3, time_to_node] = r.f64s()?;
        let state = r.f64s()?;
        let [a2, a3, l2, l3] = r.f64s()?;
        Ok(Self {
            start,
            from,
            inputs: Inputs {
                motor_torque,
                load_torque,
            },
            crossing: Crossing {
                duration,
                state,
                node: (node_phi2, node_phi3),
                time_to_node,
                arriving: [a2, a3],
                leaving: [l2, l3],
            },
        })
    }
}

impl CoSimulation {
    /// Everything that determines the integrator's future, for a serialized FMU state.
    pub fn serialize_into(&self, w: &mut Writer) {
        put!(w.f64(self.integrator_time));
        put!(w.f64s(&self.integrator_state));
        put!(w.f64s(&[
            self.integrator_inputs.motor_torque,
            self.integrator_inputs.load_torque,
        ]));
        put!(w.bool(self.restart));
        self.solver.serialize_into(w);
        put!(w.bool(self.carried.is_some()));
        let carried = self.carried.unwrap_or(CarriedStage {
            f: [0.0; STATE_SIZE],
            inputs: Inputs::default(),
        });
        put!(w.f64s(&carried.f));
        put!(w.f64s(&[carried.inputs.motor_torque, carried.inputs.load_torque]));
        put!(w.bool(self.crossing_pending));
        // A crossing under way, only where there is one: no unused numbers to check.
        put!(w.bool(self.in_flight.is_some()));
        if let Some(flight) = &self.in_flight {
            let c = &flight.crossing;
            put!(w.f64s(&[
                flight.start,
                flight.inputs.motor_torque,
                flight.inputs.load_torque,
            ]));
            put!(w.f64s(&flight.from));
            put!(w.f64s(&[c.duration, c.node.0, c.node.1, c.time_to_node]));
            put!(w.f64s(&c.state));
            put!(w.f64s(&[c.arriving[0], c.arriving[1], c.leaving[0], c.leaving[1]]));
        }
        if let Some(tracker) = &self.sensitivities {
            tracker.serialize_into(w);
        }
    }

    /// The driver written by [`CoSimulation::serialize_into`], checked against the plant
    /// restored with it.
    pub fn deserialize_from(
        r: &mut Reader,
        plant: &Plant,
        experiment: &Experiment,
    ) -> Result<Self, FormatError> {
        let integrator_time = r.f64()?;
        let integrator_state = r.f64s()?;
        let [motor_torque, load_torque] = r.f64s()?;
        let restart = r.bool()?;
        let solver = Integrator::deserialize_from(r)?;
        let has_carried = r.bool()?;
        let f = r.f64s()?;
        let [motor_torque_then, load_torque_then] = r.f64s()?;
        let crossing_pending = r.bool()?;
        let in_flight = if r.bool()? {
            Some(InFlight::deserialize_from(r)?)
        } else {
            None
        };
        // Present exactly where the restored plant's slots ask for sensitivities.
        let sensitivities = Tracker::deserialize_from(r, plant)?;
        let carried = has_carried.then_some(CarriedStage {
            f,
            inputs: Inputs {
                motor_torque: motor_torque_then,
                load_torque: load_torque_then,
            },
        });
        let driver = Self {
            integrator_time,
            integrator_state,
            integrator_inputs: Inputs {
                motor_torque,
                load_torque,
            },
            restart,
            solver,
            carried,
            crossing_pending,
            in_flight,
            sensitivities,
        };
        driver
            .check_restored(plant, experiment)
            .map_err(|e| FormatError(format!("invalid serialized state: {e}")))?;
        Ok(driver)
    }

    /// The values of a restored driver: its inputs within their rules, its point not
    /// behind the communication point, and its memory what its own steps on this system
    /// give (that memory is used only while nothing restarts it).
    fn check_restored(&self, plant: &Plant, experiment: &Experiment) -> Result<(), String> {
        check_inputs(&self.integrator_inputs, " (integrator's)")?;
        if self.crossing_pending {
            let y = plant.state();
            change_point::locate_node(plant.params(), y[1], y[2])
                .map_err(|e| format!("a change point to cross: {e}"))?;
        }
        if let Some(flight) = &self.in_flight {
            self.check_flight(flight, plant)?;
        }
        if self.carried.is_some() {
            if self.restart {
                return Err("a carried first stage with a restart pending".into());
            }
            if self.integrator_time != plant.time() {
                return Err("a carried first stage off the communication point".into());
            }
        }
        if self.restarts(plant) {
            return Ok(());
        }
        // Used only while nothing restarts the integrator.
        if let Some(stage) = &self.carried {
            check_inputs(&stage.inputs, " (carried stage's)")?;
            let mut f = [0.0; STATE_SIZE];
            model::state_derivative(
                plant.params(),
                &stage.inputs,
                &self.integrator_state,
                &mut f,
            );
            if !same_bits(&f, &stage.f) {
                return Err("the carried first stage is not f at the integrator's point".into());
            }
        }
        if self.integrator_time < plant.time() {
            return Err("the integrator is behind the communication point".into());
        }
        // The time may lie past the stop time: Co-Simulation's last step may end past it
        // by a rounding margin. A further step is refused there, not the state.
        if plant.input_derivatives().is_zero() {
            let system = Driven::new(plant, &self.integrator_inputs, experiment.tolerance);
            self.solver
                .check_memory(&system, self.integrator_time, &self.integrator_state)?;
        }
        Ok(())
    }

    /// A restored crossing under way: its values finite and in order, the plant within
    /// it, and the plant's state what the crossing's path gives there, bit for bit.
    fn check_flight(&self, flight: &InFlight, plant: &Plant) -> Result<(), String> {
        if self.crossing_pending || !self.restart || self.carried.is_some() {
            return Err("a crossing under way with the integrator not waiting for it".into());
        }
        check_inputs(&flight.inputs, " (crossing's)")?;
        let c = &flight.crossing;
        let numbers = [flight.start, c.duration, c.node.0, c.node.1, c.time_to_node];
        let finite = numbers
            .iter()
            .chain(&flight.from)
            .chain(&c.state)
            .chain(&c.arriving)
            .chain(&c.leaving)
            .all(|v| v.is_finite());
        if !(finite && c.time_to_node > 0.0 && c.time_to_node < c.duration) {
            return Err("a crossing under way with values out of order".into());
        }
        if !(flight.start < plant.time() && plant.time() < flight.end()) {
            return Err("the plant's time is not within the crossing under way".into());
        }
        let p = plant.params();
        let size = p.l + p.l2 + p.l3 + p.L;
        if model::length_residual(p, c.state[1], c.state[2]).abs() > 1e-8 * size {
            return Err("the crossing under way does not end on the loop".into());
        }
        let y = plant.state();
        let on_path = same_bits(y, &flight.state_at(p, plant.time()));
        let residual = model::length_residual(p, y[1], y[2]);
        if !on_path || residual.to_bits() != plant.residual().to_bits() {
            return Err("the plant's state is not on the crossing's path".into());
        }
        Ok(())
    }

    /// For a state restored after initialisation: the integrator works to the experiment's
    /// tolerance, and without a pending restart the plant's state is what the integrator
    /// gives at the communication point, projected: recomputed, it must agree bit for bit
    /// (it did when the state was written).
    pub fn check_initialised(&self, plant: &Plant, experiment: &Experiment) -> Result<(), String> {
        if self.solver.tolerances() != tolerances(experiment.tolerance) {
            return Err("the integrator's tolerances do not match the tolerance".into());
        }
        if self.restarts(plant) || !plant.input_derivatives().is_zero() {
            return Ok(());
        }
        // On a copy of the integrator: its dense output may form its coefficients.
        let integrator = (self.integrator_time, &self.integrator_state);
        let system = Driven::new(plant, &self.integrator_inputs, experiment.tolerance);
        let (y, at) =
            at_communication_point(&mut self.solver.clone(), &system, integrator, plant.time())
                .map_err(|e| e.to_string())?;
        let residual = model::length_residual_from_closure(plant.params(), at.closure);
        if !same_bits(&y, plant.state()) || residual.to_bits() != plant.residual().to_bits() {
            return Err("the state at the communication point is not the integrator's".into());
        }
        Ok(())
    }
}
