//! Model Exchange's operations on an instance: time, the continuous states and their
//! derivatives, the event indicator, nominals, and the chart's handover at events.

use super::fmu_state::Driver;
use super::{check_state_count, Category, Failure, Instance, Interface, Outcome, Status};
use crate::drivers::Exchange;
use crate::plant::Plant;

impl Instance {
    /// Model Exchange's states with the plant they describe, borrowed together (assembled
    /// first in initialization mode).
    fn exchange_and_plant(&mut self) -> Result<(&mut Exchange, &mut Plant), Failure> {
        self.assemble_if_needed()?;
        let fmu_state = &mut self.fmu_state;
        match &mut fmu_state.driver {
            Driver::ModelExchange(Some(exchange)) => Ok((exchange, &mut fmu_state.plant)),
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
        self.fmu_state.plant.set_time(time);
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

    /// fmi3UpdateDiscreteStates: in Model Exchange the chart's handover; in Co-Simulation
    /// nothing changes at an event. Returns whether the continuous states changed.
    pub fn update_discrete_states(&mut self) -> Result<bool, Failure> {
        match self.interface() {
            Interface::ModelExchange => self.new_discrete_states(),
            Interface::CoSimulation => Ok(false),
        }
    }

    /// NewDiscreteStates (FMI 2.0), UpdateDiscreteStates (3.0): the chart's handover, if its indicator has crossed. Returns
    /// whether the continuous states changed.
    pub fn new_discrete_states(&mut self) -> Result<bool, Failure> {
        let (exchange, plant) = self.exchange_and_plant()?;
        let changed = exchange
            .update(plant)
            .map_err(|e| Failure::error(e.to_string()))?;
        if changed && self.log_enabled(Category::Solver) {
            let plant = &self.fmu_state.plant;
            let message = format!(
                "t = {}: the loop's leading angle is now phi{}",
                plant.time(),
                plant.chart() as i32
            );
            self.log(Status::Ok, Category::Solver, &message);
        }
        Ok(changed)
    }

    /// CompletedIntegratorStep: asks for an event where the indicator has crossed (for
    /// masters that do not locate state events themselves).
    pub fn completed_integrator_step(&mut self) -> Result<bool, Failure> {
        Ok(Exchange::indicators(self.exchange_plant()?)[0] < 0.0)
    }
}
