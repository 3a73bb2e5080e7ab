//! The FMI 3.0 state machines of Model Exchange (FMI 3.0.1, section 3.2) and Co-Simulation
//! (section 4.2), in one place: every exported function that takes an instance is a
//! [`Function`], with the states the standard allows it in.
//!
//! The FMU has no structural parameters, no clocks and no intermediate update, so
//! Configuration, Reconfiguration, Clock Activation and Intermediate Update modes are never
//! entered: fmi3EnterConfigurationMode is refused with that reason, and the functions made
//! for those modes (and for clocks) are listed with the states they could be called in and
//! refuse by name. As in FMI 2.0, a refused argument leaves the instance where it was (no
//! Error state); a panic moves it to Fatal, where nothing but fmi3FreeInstance is allowed.

use crate::instance::state::{functions, BOTH, CS, ME};
pub use crate::instance::state::{Belongs, Interface, Mask, State};

functions! {
    fmi3SetDebugLogging: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3EnterInitializationMode: BOTH => [Instantiated],
    fmi3ExitInitializationMode: BOTH => [InitializationMode],
    fmi3EnterEventMode: BOTH => [ContinuousTimeMode, StepMode],
    fmi3Terminate: BOTH => [EventMode, ContinuousTimeMode, StepMode],
    fmi3Reset: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetFloat32: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetFloat64: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetInt8: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetUInt8: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetInt16: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetUInt16: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetInt32: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetUInt32: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetInt64: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetUInt64: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetBoolean: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetString: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetBinary: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepMode,
        Terminated],
    fmi3GetClock: BOTH => [EventMode],
    fmi3SetFloat32: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode],
    fmi3SetFloat64: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode],
    fmi3SetInt8: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetUInt8: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetInt16: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetUInt16: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetInt32: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetUInt32: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetInt64: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetUInt64: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetBoolean: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetString: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetBinary: BOTH => [Instantiated, InitializationMode, EventMode, StepMode],
    fmi3SetClock: BOTH => [EventMode],
    fmi3GetNumberOfVariableDependencies: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepMode, Terminated],
    fmi3GetVariableDependencies: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepMode, Terminated],
    fmi3GetFMUState: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3SetFMUState: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3FreeFMUState: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3SerializedFMUStateSize: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepMode, Terminated],
    fmi3SerializeFMUState: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepMode, Terminated],
    fmi3DeserializeFMUState: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepMode, Terminated],
    fmi3GetDirectionalDerivative: BOTH => [InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3GetAdjointDerivative: BOTH => [InitializationMode, EventMode, ContinuousTimeMode,
        StepMode, Terminated],
    fmi3EnterConfigurationMode: BOTH => [Instantiated, EventMode, StepMode],
    fmi3ExitConfigurationMode: BOTH => [],
    fmi3GetIntervalDecimal: BOTH => [EventMode],
    fmi3GetIntervalFraction: BOTH => [EventMode],
    fmi3GetShiftDecimal: BOTH => [EventMode],
    fmi3GetShiftFraction: BOTH => [EventMode],
    fmi3SetIntervalDecimal: BOTH => [Instantiated, EventMode],
    fmi3SetIntervalFraction: BOTH => [Instantiated, EventMode],
    fmi3SetShiftDecimal: BOTH => [Instantiated],
    fmi3SetShiftFraction: BOTH => [Instantiated],
    fmi3EvaluateDiscreteStates: BOTH => [EventMode, ContinuousTimeMode, StepMode],
    fmi3UpdateDiscreteStates: BOTH => [EventMode],
    fmi3EnterContinuousTimeMode: ME => [EventMode],
    fmi3CompletedIntegratorStep: ME => [ContinuousTimeMode],
    fmi3SetTime: ME => [EventMode, ContinuousTimeMode],
    fmi3SetContinuousStates: ME => [ContinuousTimeMode],
    fmi3GetContinuousStateDerivatives: ME => [InitializationMode, EventMode, ContinuousTimeMode,
        Terminated],
    fmi3GetEventIndicators: ME => [InitializationMode, EventMode, ContinuousTimeMode, Terminated],
    fmi3GetContinuousStates: ME => [InitializationMode, EventMode, ContinuousTimeMode,
        Terminated],
    fmi3GetNominalsOfContinuousStates: ME => [InitializationMode, EventMode, ContinuousTimeMode,
        Terminated],
    fmi3GetNumberOfEventIndicators: ME => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, Terminated],
    fmi3GetNumberOfContinuousStates: ME => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, Terminated],
    fmi3EnterStepMode: CS => [EventMode],
    fmi3GetOutputDerivatives: CS => [EventMode, StepMode, Terminated],
    fmi3DoStep: CS => [StepMode],
    fmi3ActivateModelPartition: BOTH => [],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fatal_admits_nothing_that_takes_an_instance() {
        for function in Function::ALL {
            assert!(!function.allowed().contains(State::Fatal), "{function:?}");
        }
    }

    #[test]
    fn step_mode_is_fmi2s_step_complete() {
        assert!(Function::fmi3DoStep.allowed().contains(State::StepComplete));
        assert!(!Function::fmi3DoStep.allowed().contains(State::EventMode));
        assert!(Function::fmi3EnterStepMode
            .allowed()
            .contains(State::EventMode));
    }
}
