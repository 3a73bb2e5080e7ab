//! Model Exchange's own functions (docs/model.md §6): event and continuous-time modes, the
//! continuous states, their derivatives and nominals, the event indicator.

use fmi_sys::fmi2::*;

use super::{export, null_argument, slice, slice_mut};
use crate::instance::Instance;

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2EnterEventMode(c): fmi2EnterEventModeTYPE = Instance::enter_event_mode;
}

export! {
    /// # Safety
    /// `c` is an instance; `eventInfo` must be NULL or writable.
    fn fmi2NewDiscreteStates(c, eventInfo: *mut fmi2EventInfo): fmi2NewDiscreteStatesTYPE =
        |instance| {
            // SAFETY: NULL or writable by the FMI contract.
            let info =
                unsafe { eventInfo.as_mut() }.ok_or_else(|| null_argument("eventInfo", 1))?;
            let changed = instance.new_discrete_states()?;
            *info = fmi2EventInfo {
                newDiscreteStatesNeeded: fmi2False as fmi2Boolean,
                terminateSimulation: fmi2False as fmi2Boolean,
                nominalsOfContinuousStatesChanged: fmi2False as fmi2Boolean,
                valuesOfContinuousStatesChanged: fmi2Boolean::from(changed),
                nextEventTimeDefined: fmi2False as fmi2Boolean,
                nextEventTime: 0.0,
            };
            Ok(())
        };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2EnterContinuousTimeMode(c): fmi2EnterContinuousTimeModeTYPE =
        Instance::enter_continuous_time_mode;
}

export! {
    /// # Safety
    /// `c` is an instance; `enterEventMode` and `terminateSimulation` must be NULL or
    /// writable.
    fn fmi2CompletedIntegratorStep(
        c,
        _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
        enterEventMode: *mut fmi2Boolean,
        terminateSimulation: *mut fmi2Boolean,
    ): fmi2CompletedIntegratorStepTYPE = |instance| {
        // SAFETY: NULL or writable by the FMI contract.
        let (event, terminate) =
            unsafe { (enterEventMode.as_mut(), terminateSimulation.as_mut()) };
        let event = event.ok_or_else(|| null_argument("enterEventMode", 1))?;
        let terminate = terminate.ok_or_else(|| null_argument("terminateSimulation", 1))?;
        *event = fmi2Boolean::from(instance.completed_integrator_step()?);
        *terminate = fmi2False as fmi2Boolean;
        Ok(())
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2SetTime(c, time: fmi2Real): fmi2SetTimeTYPE = |instance| instance.set_time(time);
}

export! {
    /// # Safety
    /// `c` is an instance; `x` must hold `nx` elements.
    fn fmi2SetContinuousStates(c, x: *const fmi2Real, nx: usize): fmi2SetContinuousStatesTYPE =
        |instance| {
            // SAFETY: FMI contract on the array.
            let x = unsafe { slice(x, nx) }.ok_or_else(|| null_argument("x", nx))?;
            instance.set_continuous_states(x)
        };
}

/// The four functions that fill an array of continuous-time values.
macro_rules! continuous_values {
    ($name:ident: $check:ident, $array:literal, $method:ident) => {
        export! {
            /// # Safety
            /// `c` is an instance; the array must hold `n` writable elements.
            fn $name(c, values: *mut fmi2Real, n: usize): $check = |instance| {
                // SAFETY: FMI contract on the array.
                let values =
                    unsafe { slice_mut(values, n) }.ok_or_else(|| null_argument($array, n))?;
                instance.$method(values)
            };
        }
    };
}

continuous_values!(fmi2GetDerivatives: fmi2GetDerivativesTYPE, "derivatives", get_derivatives);
continuous_values!(
    fmi2GetEventIndicators: fmi2GetEventIndicatorsTYPE,
    "eventIndicators",
    get_event_indicators
);
continuous_values!(fmi2GetContinuousStates: fmi2GetContinuousStatesTYPE, "x", get_continuous_states);
continuous_values!(
    fmi2GetNominalsOfContinuousStates: fmi2GetNominalsOfContinuousStatesTYPE,
    "x_nominal",
    get_nominals
);
