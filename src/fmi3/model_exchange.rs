//! Model Exchange's own functions (docs/model.md §6): continuous-time mode, the continuous
//! states, their derivatives and nominals, the event indicator and the counts.

use fmi_sys::fmi3::*;

use super::export;
use crate::abi::{null_argument, slice, slice_mut};
use crate::description::EVENT_INDICATORS;
use crate::drivers::model_exchange::CONTINUOUS_STATES;
use crate::instance::Instance;

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3EnterContinuousTimeMode(instance): fmi3EnterContinuousTimeModeTYPE =
        Instance::enter_continuous_time_mode;
}

export! {
    /// # Safety
    /// `instance` is an instance; `enterEventMode` and `terminateSimulation` must be NULL or
    /// writable.
    fn fmi3CompletedIntegratorStep(
        instance,
        _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
        enterEventMode: *mut fmi3Boolean,
        terminateSimulation: *mut fmi3Boolean,
    ): fmi3CompletedIntegratorStepTYPE = |instance| {
        // SAFETY: NULL or writable by the FMI contract.
        let (event, terminate) =
            unsafe { (enterEventMode.as_mut(), terminateSimulation.as_mut()) };
        let event = event.ok_or_else(|| null_argument("enterEventMode", 1))?;
        let terminate = terminate.ok_or_else(|| null_argument("terminateSimulation", 1))?;
        *event = instance.completed_integrator_step()?;
        *terminate = false;
        Ok(())
    };
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3SetTime(instance, time: fmi3Float64): fmi3SetTimeTYPE =
        |instance| instance.set_time(time);
}

export! {
    /// # Safety
    /// `instance` is an instance; `continuousStates` must hold `nContinuousStates` elements.
    fn fmi3SetContinuousStates(
        instance,
        continuousStates: *const fmi3Float64,
        nContinuousStates: usize,
    ): fmi3SetContinuousStatesTYPE = |instance| {
        // SAFETY: FMI contract on the array.
        let x = unsafe { slice(continuousStates, nContinuousStates) }
            .ok_or_else(|| null_argument("continuousStates", nContinuousStates))?;
        instance.set_continuous_states(x)
    };
}

/// The four functions that fill an array of continuous-time values.
macro_rules! continuous_values {
    ($name:ident: $check:ident, $array:literal, $method:ident) => {
        export! {
            /// # Safety
            /// `instance` is an instance; the array must hold `n` writable elements.
            fn $name(instance, values: *mut fmi3Float64, n: usize): $check = |instance| {
                // SAFETY: FMI contract on the array.
                let values =
                    unsafe { slice_mut(values, n) }.ok_or_else(|| null_argument($array, n))?;
                instance.$method(values)
            };
        }
    };
}

continuous_values!(
    fmi3GetContinuousStateDerivatives: fmi3GetContinuousStateDerivativesTYPE,
    "derivatives",
    get_derivatives
);
continuous_values!(
    fmi3GetEventIndicators: fmi3GetEventIndicatorsTYPE,
    "eventIndicators",
    get_event_indicators
);
continuous_values!(
    fmi3GetContinuousStates: fmi3GetContinuousStatesTYPE,
    "continuousStates",
    get_continuous_states
);
continuous_values!(
    fmi3GetNominalsOfContinuousStates: fmi3GetNominalsOfContinuousStatesTYPE,
    "nominals",
    get_nominals
);

/// The two counts, which without structural parameters are those of the model
/// description.
macro_rules! count {
    ($name:ident: $check:ident, $what:literal, $value:expr) => {
        export! {
            /// # Safety
            /// `instance` is an instance; the count must be NULL or writable.
            fn $name(instance, n: *mut usize): $check = |_| {
                // SAFETY: NULL or writable by the FMI contract.
                *unsafe { n.as_mut() }.ok_or_else(|| null_argument($what, 1))? = $value;
                Ok(())
            };
        }
    };
}

count!(fmi3GetNumberOfEventIndicators: fmi3GetNumberOfEventIndicatorsTYPE,
    "nEventIndicators", EVENT_INDICATORS);
count!(fmi3GetNumberOfContinuousStates: fmi3GetNumberOfContinuousStatesTYPE,
    "nContinuousStates", CONTINUOUS_STATES);
