//! Co-Simulation's own functions: input and output derivatives, the step and its status.

use fmi_sys::fmi2::*;

use super::{export, null_argument, slice, slice_mut};
use crate::instance::Failure;

export! {
    /// # Safety
    /// `c` is an instance; `vr`, `order` and `value` must hold `nvr` elements.
    fn fmi2SetRealInputDerivatives(
        c,
        vr: *const fmi2ValueReference,
        nvr: usize,
        order: *const fmi2Integer,
        value: *const fmi2Real,
    ): fmi2SetRealInputDerivativesTYPE = |instance| {
        // SAFETY: FMI contract on the arrays.
        let (vrs, orders, values) =
            unsafe { (slice(vr, nvr), slice(order, nvr), slice(value, nvr)) };
        let vrs = vrs.ok_or_else(|| null_argument("vr", nvr))?;
        let orders = orders.ok_or_else(|| null_argument("order", nvr))?;
        let values = values.ok_or_else(|| null_argument("value", nvr))?;
        instance.set_input_derivatives(vrs, orders, values)
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `vr` and `order` must hold `nvr` elements, `value` `nvr`
    /// writable ones.
    fn fmi2GetRealOutputDerivatives(
        c,
        vr: *const fmi2ValueReference,
        nvr: usize,
        order: *const fmi2Integer,
        value: *mut fmi2Real,
    ): fmi2GetRealOutputDerivativesTYPE = |instance| {
        // SAFETY: FMI contract on the arrays.
        let (vrs, orders, values) =
            unsafe { (slice(vr, nvr), slice(order, nvr), slice_mut(value, nvr)) };
        let vrs = vrs.ok_or_else(|| null_argument("vr", nvr))?;
        let orders = orders.ok_or_else(|| null_argument("order", nvr))?;
        let values = values.ok_or_else(|| null_argument("value", nvr))?;
        instance.get_output_derivatives(vrs.iter().copied(), orders, values)
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2DoStep(
        c,
        currentCommunicationPoint: fmi2Real,
        communicationStepSize: fmi2Real,
        _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    ): fmi2DoStepTYPE = |instance| {
        instance.do_step(currentCommunicationPoint, communicationStepSize)
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2CancelStep(c): fmi2CancelStepTYPE = |_| Ok(());
}

export! {
    /// # Safety
    /// `c` is an instance; `value` must be NULL or writable.
    fn fmi2GetStatus(c, s: fmi2StatusKind, _value: *mut fmi2Status): fmi2GetStatusTYPE = |_| {
        Err(Failure::error(format!(
            "status kind {s}: this FMU never returns fmi2Pending, so no asynchronous step status exists"
        )))
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `value` must be NULL or writable.
    fn fmi2GetRealStatus(c, s: fmi2StatusKind, value: *mut fmi2Real): fmi2GetRealStatusTYPE =
        |instance| {
            if s != fmi2StatusKind_fmi2LastSuccessfulTime {
                return Err(Failure::error(format!(
                    "status kind {s} has no Real value; use fmi2LastSuccessfulTime (2)"
                )));
            }
            // SAFETY: NULL or writable by the FMI contract.
            let value = unsafe { value.as_mut() }.ok_or_else(|| null_argument("value", 1))?;
            *value = instance.last_successful_time();
            Ok(())
        };
}

export! {
    /// # Safety
    /// `c` is an instance; `value` must be NULL or writable.
    fn fmi2GetIntegerStatus(c, s: fmi2StatusKind, _value: *mut fmi2Integer):
        fmi2GetIntegerStatusTYPE = |_| {
        Err(Failure::error(format!("status kind {s} has no Integer value")))
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `value` must be NULL or writable.
    fn fmi2GetBooleanStatus(c, s: fmi2StatusKind, value: *mut fmi2Boolean):
        fmi2GetBooleanStatusTYPE = |_| {
        if s != fmi2StatusKind_fmi2Terminated {
            return Err(Failure::error(format!(
                "status kind {s} has no Boolean value; use fmi2Terminated (3)"
            )));
        }
        // SAFETY: NULL or writable by the FMI contract.
        let value = unsafe { value.as_mut() }.ok_or_else(|| null_argument("value", 1))?;
        // The FMU never asks the master to end the simulation.
        *value = fmi2False as fmi2Boolean;
        Ok(())
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `value` must be NULL or writable.
    fn fmi2GetStringStatus(c, s: fmi2StatusKind, _value: *mut fmi2String):
        fmi2GetStringStatusTYPE = |_| {
        Err(Failure::error(format!(
            "status kind {s}: this FMU never returns fmi2Pending, so there is no pending status"
        )))
    };
}
