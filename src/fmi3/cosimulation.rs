//! Co-Simulation's own functions: step mode, output derivatives and the step, which in
//! FMI 3.0 can end early at a change point and ask the master to handle it as an event.

use fmi_sys::fmi3::*;

use super::{check_value_count, export, references, table_references, Accessor};
use crate::abi::{null_argument, slice, slice_mut};
use crate::instance::{Instance, StepEnd};

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3EnterStepMode(instance): fmi3EnterStepModeTYPE = Instance::enter_step_mode;
}

export! {
    /// # Safety
    /// `instance` is an instance; `valueReferences` and `orders` must hold
    /// `nValueReferences` elements, `values` `nValues` writable ones.
    fn fmi3GetOutputDerivatives(
        instance,
        valueReferences: *const fmi3ValueReference,
        nValueReferences: usize,
        orders: *const fmi3Int32,
        values: *mut fmi3Float64,
        nValues: usize,
    ): fmi3GetOutputDerivativesTYPE = |instance| {
        check_value_count(nValueReferences, nValues)?;
        // SAFETY: FMI contract on the arrays.
        let vrs = unsafe { references(valueReferences, nValueReferences) }?;
        // SAFETY: FMI contract on the arrays.
        let (orders, values) =
            unsafe { (slice(orders, nValueReferences), slice_mut(values, nValues)) };
        let orders = orders.ok_or_else(|| null_argument("orders", nValueReferences))?;
        let values = values.ok_or_else(|| null_argument("values", nValues))?;
        instance.get_output_derivatives(table_references(vrs, Accessor::Float64)?, orders, values)
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; the four flags and `lastSuccessfulTime` must be NULL or
    /// writable (a NULL one is not reported).
    fn fmi3DoStep(
        instance,
        currentCommunicationPoint: fmi3Float64,
        communicationStepSize: fmi3Float64,
        _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
        eventHandlingNeeded: *mut fmi3Boolean,
        terminateSimulation: *mut fmi3Boolean,
        earlyReturn: *mut fmi3Boolean,
        lastSuccessfulTime: *mut fmi3Float64,
    ): fmi3DoStepTYPE = |instance| {
        let outcome = instance.step_with_events(currentCommunicationPoint, communicationStepSize);
        let end = match &outcome {
            Ok(end) => *end,
            Err(_) => StepEnd::Complete,
        };
        // SAFETY: NULL or writable by the FMI contract.
        unsafe {
            let early = matches!(end, StepEnd::ChangePointEvent | StepEnd::OutOfWork);
            let event = matches!(end, StepEnd::ChangePointEvent | StepEnd::CompleteAfterEvent);
            for (pointer, value) in [
                (eventHandlingNeeded, event),
                (terminateSimulation, false),
                (earlyReturn, early),
            ] {
                if let Some(flag) = pointer.as_mut() {
                    *flag = value;
                }
            }
            if let Some(time) = lastSuccessfulTime.as_mut() {
                *time = instance.last_successful_time();
            }
        }
        outcome.map(|_| ())
    };
}
