//! Values on an instance: the getters and setters of every type, input and output
//! derivatives, and directional and adjoint derivatives.

use super::fmu_state::Driver;
use super::{Failure, Instance, Interface, Outcome, State};
use crate::drivers::model_exchange::CONTINUOUS_STATES;
use crate::plant::{AccessError, Value};
use crate::variables::{variable, Input, Slot, Twin, VarType, STATE_REFERENCES};

impl Instance {
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
        let (mut input_seed, mut state_seed) = ([0.0; 2], [0.0; CONTINUOUS_STATES]);
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
        let states = match &self.fmu_state.driver {
            Driver::ModelExchange(Some(e)) => Some((e.coordinates(), e.states(), &state_seed)),
            _ => None,
        };
        self.fmu_state
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

    /// Inlined into fmi2GetReal, as `do_step` into fmi2DoStep: left to itself, the compiler
    /// kept both as calls of their own in the cdylib, a cost paid at every communication
    /// point.
    #[inline(always)]
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Outcome {
        self.assemble_if_needed()?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            *value = self.fmu_state.plant.read_real(*vr)?;
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
        let activity = self.fmu_state.activity();
        for (i, vr) in vrs.enumerate() {
            put(
                i,
                match self.fmu_state.plant.read(vr, accessor, &activity)? {
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
        let exchange = self.fmu_state.interface() == Interface::ModelExchange;
        let fmu_state = &mut self.fmu_state;
        let writable = fmu_state.state.parameters_writable();
        for (vr, value) in values.clone() {
            fmu_state.plant.check_set(vr, value, writable)?;
            if exchange {
                refuse_sensitivity_slot(vr, value)?;
            }
        }
        for (vr, value) in values {
            fmu_state.plant.set(vr, value, writable)?;
        }
        if fmu_state.state == State::InitializationMode {
            // The assembly, and the driver started on it, are stale: the next read makes
            // them again.
            fmu_state.driver.stop();
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
        let plant = &mut self.fmu_state.plant;
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
        let plant = &self.fmu_state.plant;
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
}

/// Model Exchange has no sensitivities (the master integrates, and the FMU sees only the
/// points it is given): a slot's parameter other than 0 is refused at its set, rather
/// than left at zero or failing later calls.
fn refuse_sensitivity_slot(vr: u32, value: Value) -> Outcome {
    let slot = variable(vr).map(|v| (v.slot, v.name));
    match (slot, value) {
        (
            Some((Slot::SensitivityParameter(_) | Slot::Twin(Twin::SensitivityParameter(_)), name)),
            Value::Integer(v),
        ) if v != 0 => Err(Failure::error(format!(
            "{name} = {v}: sensitivities come from the FMU's own integration, in \
                 Co-Simulation; in Model Exchange the master integrates, and every slot \
                 stays 0"
        ))),
        _ => Ok(()),
    }
}
