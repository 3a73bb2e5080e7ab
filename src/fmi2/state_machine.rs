//! The FMI 2.0 state machines of Co-Simulation (FMI 2.0.4, section 4.2.4) and Model
//! Exchange (section 3.2.3), in one place.
//!
//! Every exported function that takes an instance is a [`Function`], and
//! [`Function::allowed`] is the standard's table of the states it may be called in. An
//! argument error leaves the state unchanged (the instance keeps working, nothing having been
//! applied); only a panic (a bug) moves the instance to `Fatal`, where nothing but
//! fmi2FreeInstance is allowed.

use crate::instance::state::{functions, BOTH, CS, ME};
pub use crate::instance::state::{Belongs, Interface, Mask, State};

// The functions that take an instance, each with the states the FMI 2.0.4 tables allow it
// in (Model Exchange section 3.2.3, Co-Simulation section 4.2.4), written once here. The
// standard's StepInProgress and StepCanceled never occur (this FMU never returns
// fmi2Pending), and neither does its Error state: a refused argument leaves the instance
// where it was, nothing having been applied. A cell that holds only such states is empty.
functions! {
    fmi2SetDebugLogging: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2SetupExperiment: BOTH => [Instantiated],
    fmi2EnterInitializationMode: BOTH => [Instantiated],
    fmi2ExitInitializationMode: BOTH => [InitializationMode],
    fmi2Terminate: BOTH => [EventMode, ContinuousTimeMode, StepComplete, StepFailed],
    fmi2Reset: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2GetReal: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepComplete,
        StepFailed, Terminated],
    fmi2GetInteger: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepComplete,
        StepFailed, Terminated],
    fmi2GetBoolean: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepComplete,
        StepFailed, Terminated],
    fmi2GetString: BOTH => [InitializationMode, EventMode, ContinuousTimeMode, StepComplete,
        StepFailed, Terminated],
    fmi2SetReal: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete],
    fmi2SetInteger: BOTH => [Instantiated, InitializationMode, EventMode, StepComplete],
    fmi2SetBoolean: BOTH => [Instantiated, InitializationMode, EventMode, StepComplete],
    fmi2SetString: BOTH => [Instantiated, InitializationMode, EventMode, StepComplete],
    fmi2GetFMUstate: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2SetFMUstate: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2FreeFMUstate: BOTH => [Instantiated, InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2SerializedFMUstateSize: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepComplete, StepFailed, Terminated],
    fmi2SerializeFMUstate: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepComplete, StepFailed, Terminated],
    fmi2DeSerializeFMUstate: BOTH => [Instantiated, InitializationMode, EventMode,
        ContinuousTimeMode, StepComplete, StepFailed, Terminated],
    fmi2GetDirectionalDerivative: BOTH => [InitializationMode, EventMode, ContinuousTimeMode,
        StepComplete, StepFailed, Terminated],
    fmi2EnterEventMode: ME => [EventMode, ContinuousTimeMode],
    fmi2NewDiscreteStates: ME => [EventMode],
    fmi2EnterContinuousTimeMode: ME => [EventMode],
    fmi2CompletedIntegratorStep: ME => [ContinuousTimeMode],
    fmi2SetTime: ME => [EventMode, ContinuousTimeMode],
    fmi2SetContinuousStates: ME => [ContinuousTimeMode],
    fmi2GetEventIndicators: ME => [InitializationMode, EventMode, ContinuousTimeMode, Terminated],
    fmi2GetContinuousStates: ME => [InitializationMode, EventMode, ContinuousTimeMode,
        Terminated],
    fmi2GetDerivatives: ME => [EventMode, ContinuousTimeMode, Terminated],
    fmi2GetNominalsOfContinuousStates: ME => [Instantiated, EventMode, ContinuousTimeMode,
        Terminated],
    fmi2SetRealInputDerivatives: CS => [Instantiated, InitializationMode, StepComplete],
    fmi2GetRealOutputDerivatives: CS => [StepComplete, StepFailed, Terminated],
    fmi2DoStep: CS => [StepComplete],
    fmi2CancelStep: CS => [],
    fmi2GetStatus: CS => [StepComplete, StepFailed, Terminated],
    fmi2GetRealStatus: CS => [StepComplete, StepFailed, Terminated],
    fmi2GetIntegerStatus: CS => [StepComplete, StepFailed, Terminated],
    fmi2GetBooleanStatus: CS => [StepComplete, StepFailed, Terminated],
    fmi2GetStringStatus: CS => [StepComplete, StepFailed, Terminated],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_only_after_initialisation() {
        let allowed = Function::fmi2DoStep.allowed();
        assert!(!allowed.contains(State::Instantiated));
        assert!(!allowed.contains(State::InitializationMode));
        assert!(allowed.contains(State::StepComplete));
        assert!(!allowed.contains(State::StepFailed));
        assert!(!allowed.contains(State::Terminated));
    }

    #[test]
    fn fatal_admits_nothing_that_takes_an_instance() {
        for function in Function::ALL {
            assert!(!function.allowed().contains(State::Fatal), "{function:?}");
        }
    }

    #[test]
    fn inputs_settable_while_stepping_not_after_termination() {
        assert!(Function::fmi2SetReal
            .allowed()
            .contains(State::StepComplete));
        assert!(!Function::fmi2SetReal.allowed().contains(State::Terminated));
        assert!(!State::StepComplete.parameters_writable());
        assert!(State::InitializationMode.parameters_writable());
    }
}
