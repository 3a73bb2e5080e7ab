//! The FMI 2.0 Co-Simulation state machine (FMI 2.0.4, section 4.2.4), in one place.
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
    /// FMU state, directional derivatives, input and output derivatives: optional
    /// capabilities, refused with a message in every state while not declared.
    Capability,
    DoStep,
    CancelStep,
    /// fmi2GetStatus and its typed variants.
    GetStatus,
    /// Model Exchange functions: never allowed in a co-simulation FMU.
    ModelExchange,
    /// Getting, setting, freeing and (de)serializing FMU states.
    FmuState,
}

impl Call {
    /// Whether the standard allows this call in `state`.
    pub fn allowed_in(self, state: State) -> bool {
        use State::*;
        match self {
            Call::FreeInstance => true,
            _ if state == Fatal => false,
            Call::SetDebugLogging | Call::Reset => true,
            Call::SetupExperiment | Call::EnterInitializationMode => state == Instantiated,
            Call::ExitInitializationMode => state == InitializationMode,
            Call::Terminate => matches!(state, StepComplete | StepFailed),
            Call::Get => matches!(
                state,
                InitializationMode | StepComplete | StepFailed | Terminated
            ),
            Call::Set => matches!(state, Instantiated | InitializationMode | StepComplete),
            Call::Capability => true,
            Call::DoStep => state == StepComplete,
            Call::CancelStep => false,
            Call::GetStatus => matches!(state, StepComplete | StepFailed | Terminated),
            Call::ModelExchange => false,
            Call::FmuState => true,
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
