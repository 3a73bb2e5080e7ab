//! The FMI 2.0 state machines of Co-Simulation (FMI 2.0.4, section 4.2.4) and Model
//! Exchange (section 3.2.3), in one place.
//!
//! Every exported function names its [`Call`]; [`Call::allowed_in`] is the standard's table
//! of which calls each state admits. An argument error leaves the state unchanged (the
//! instance keeps working, nothing having been applied); only a panic (a bug) moves the
//! instance to `Fatal`, where nothing but fmi2FreeInstance is allowed.

/// States of a co-simulation slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum State {
    Instantiated,
    InitializationMode,
    /// Initialised, the last doStep (if any) completed: the standard's "stepComplete".
    StepComplete,
    /// The last doStep returned fmi2Discard: outputs are at the last good point.
    StepFailed,
    Terminated,
    Fatal,
    /// Model Exchange: events are handled (after initialisation, or fmi2EnterEventMode).
    EventMode,
    /// Model Exchange: the master integrates.
    ContinuousTimeMode,
}

/// Which interface an instance was created for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Interface {
    ModelExchange = 0,
    CoSimulation = 1,
}

impl Interface {
    pub fn name(self) -> &'static str {
        match self {
            Interface::ModelExchange => "Model Exchange",
            Interface::CoSimulation => "Co-Simulation",
        }
    }
}

/// Calls that take an instance, grouped where the standard treats them alike.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Call {
    SetDebugLogging,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    /// fmi2GetReal, fmi2GetInteger, fmi2GetBoolean, fmi2GetString.
    Get,
    /// fmi2SetReal, fmi2SetInteger, fmi2SetBoolean, fmi2SetString.
    Set,
    /// fmi2SetRealInputDerivatives (Co-Simulation).
    SetInputDerivatives,
    /// fmi2GetRealOutputDerivatives (Co-Simulation).
    GetOutputDerivatives,
    DoStep,
    CancelStep,
    /// fmi2GetStatus and its typed variants.
    GetStatus,
    /// Getting, setting, freeing and (de)serializing FMU states.
    FmuState,
    DirectionalDerivative,
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    /// fmi2GetDerivatives, fmi2GetEventIndicators, fmi2GetContinuousStates,
    /// fmi2GetNominalsOfContinuousStates.
    GetContinuous,
}

impl Call {
    /// The interface a call belongs to, if only one.
    pub fn interface(self) -> Option<Interface> {
        match self {
            Call::SetInputDerivatives
            | Call::GetOutputDerivatives
            | Call::DoStep
            | Call::CancelStep
            | Call::GetStatus => Some(Interface::CoSimulation),
            Call::EnterEventMode
            | Call::NewDiscreteStates
            | Call::EnterContinuousTimeMode
            | Call::CompletedIntegratorStep
            | Call::SetTime
            | Call::SetContinuousStates
            | Call::GetContinuous => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    /// Whether the standard allows this call in `state` (the states of the two interfaces
    /// after initialisation are distinct, so one table serves both).
    pub fn allowed_in(self, state: State) -> bool {
        use State::*;
        let initialised = matches!(
            state,
            StepComplete | StepFailed | EventMode | ContinuousTimeMode
        );
        match self {
            Call::FreeInstance => true,
            _ if state == Fatal => false,
            Call::SetDebugLogging | Call::Reset => true,
            Call::SetupExperiment | Call::EnterInitializationMode => state == Instantiated,
            Call::ExitInitializationMode => state == InitializationMode,
            Call::Terminate => initialised,
            Call::Get | Call::DirectionalDerivative | Call::GetOutputDerivatives => {
                initialised || matches!(state, InitializationMode | Terminated)
            }
            Call::Set => matches!(
                state,
                Instantiated | InitializationMode | StepComplete | EventMode | ContinuousTimeMode
            ),
            Call::SetInputDerivatives => {
                matches!(state, Instantiated | InitializationMode | StepComplete)
            }
            Call::DoStep => state == StepComplete,
            Call::CancelStep => false,
            Call::GetStatus => matches!(state, StepComplete | StepFailed | Terminated),
            Call::FmuState => true,
            Call::EnterEventMode => matches!(state, EventMode | ContinuousTimeMode),
            Call::NewDiscreteStates | Call::EnterContinuousTimeMode => state == EventMode,
            Call::CompletedIntegratorStep | Call::SetContinuousStates => {
                state == ContinuousTimeMode
            }
            Call::SetTime => matches!(state, EventMode | ContinuousTimeMode),
            Call::GetContinuous => matches!(
                state,
                InitializationMode | EventMode | ContinuousTimeMode | Terminated
            ),
        }
    }
}

impl State {
    /// A byte for serialized FMU states.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The state with [`State::code`] `code`; Fatal is never restored.
    pub fn from_code(code: u8) -> Option<State> {
        use State::*;
        [
            Instantiated,
            InitializationMode,
            StepComplete,
            StepFailed,
            Terminated,
            EventMode,
            ContinuousTimeMode,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }

    /// Parameters of variability "fixed" may change only before initialisation ends.
    pub fn parameters_writable(self) -> bool {
        matches!(self, State::Instantiated | State::InitializationMode)
    }

    pub fn describe(self) -> &'static str {
        match self {
            State::Instantiated => "instantiated",
            State::InitializationMode => "initialization mode",
            State::StepComplete => "step complete",
            State::StepFailed => "step failed (after fmi2Discard)",
            State::Terminated => "terminated",
            State::Fatal => "fatal (after an internal error)",
            State::EventMode => "event mode",
            State::ContinuousTimeMode => "continuous-time mode",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_only_after_initialisation() {
        assert!(!Call::DoStep.allowed_in(State::Instantiated));
        assert!(!Call::DoStep.allowed_in(State::InitializationMode));
        assert!(Call::DoStep.allowed_in(State::StepComplete));
        assert!(!Call::DoStep.allowed_in(State::StepFailed));
        assert!(!Call::DoStep.allowed_in(State::Terminated));
    }

    #[test]
    fn fatal_admits_only_free() {
        assert!(Call::FreeInstance.allowed_in(State::Fatal));
        for call in [
            Call::Get,
            Call::Set,
            Call::Reset,
            Call::DoStep,
            Call::SetDebugLogging,
        ] {
            assert!(!call.allowed_in(State::Fatal), "{call:?}");
        }
    }

    #[test]
    fn inputs_settable_while_stepping_not_after_termination() {
        assert!(Call::Set.allowed_in(State::StepComplete));
        assert!(!Call::Set.allowed_in(State::Terminated));
        assert!(!State::StepComplete.parameters_writable());
        assert!(State::InitializationMode.parameters_writable());
    }
}
