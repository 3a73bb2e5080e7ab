//! The states of an instance, shared by FMI 2.0 and FMI 3.0, and the means for each version
//! to write its table of the states every function may be called in (`fmi2::state_machine`,
//! `fmi3::state_machine`).
//!
//! The two versions name some states differently: FMI 3.0's Step Mode is FMI 2.0's
//! "stepComplete", one state here with both names ([`State::StepMode`]). FMI 2.0's
//! "stepFailed" has no FMI 3.0 counterpart: after a Discard an FMI 3.0 instance is as
//! before the call. FMI 3.0's Configuration, Reconfiguration and Intermediate Update modes
//! never occur: the FMU has no structural parameters and provides no intermediate update.

/// The state of an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum State {
    Instantiated,
    InitializationMode,
    /// Co-Simulation, initialised, the last step (if any) completed.
    StepComplete,
    /// Co-Simulation: the last step returned Discard: outputs are at the last good point.
    StepFailed,
    Terminated,
    Fatal,
    /// Events are handled (Model Exchange; FMI 3.0 Co-Simulation with event mode).
    EventMode,
    /// Model Exchange: the master integrates.
    ContinuousTimeMode,
}

#[allow(non_upper_case_globals)]
impl State {
    /// FMI 3.0's name of [`State::StepComplete`].
    pub const StepMode: State = State::StepComplete;

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

    /// The state as the version's standard names it.
    pub fn describe(self, version: Version) -> &'static str {
        match (self, version) {
            (State::Instantiated, _) => "instantiated",
            (State::InitializationMode, _) => "initialization mode",
            (State::StepComplete, Version::Fmi2) => "step complete",
            (State::StepComplete, Version::Fmi3) => "step mode",
            (State::StepFailed, _) => "step failed (after fmi2Discard)",
            (State::Terminated, _) => "terminated",
            (State::Fatal, _) => "fatal (after an internal error)",
            (State::EventMode, _) => "event mode",
            (State::ContinuousTimeMode, _) => "continuous-time mode",
        }
    }
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

/// Which version of the standard an instance was created through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Version {
    Fmi2 = 2,
    Fmi3 = 3,
}

impl Version {
    pub fn name(self) -> &'static str {
        match self {
            Version::Fmi2 => "FMI 2.0",
            Version::Fmi3 => "FMI 3.0",
        }
    }
}

/// A set of [`State`]s, one bit per state code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mask(u16);

impl Mask {
    pub const fn of(states: &[State]) -> Mask {
        let mut bits = 0;
        let mut i = 0;
        while i < states.len() {
            bits |= 1 << states[i] as u16;
            i += 1;
        }
        Mask(bits)
    }

    pub const fn contains(self, state: State) -> bool {
        self.0 & (1 << state as u16) != 0
    }
}

/// Which interfaces a function belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Belongs {
    Both,
    Only(Interface),
}

pub const BOTH: Belongs = Belongs::Both;
pub const CS: Belongs = Belongs::Only(Interface::CoSimulation);
pub const ME: Belongs = Belongs::Only(Interface::ModelExchange);

/// A version's table of functions: `NAME: BELONGS => [STATE, ...],` for every function
/// that takes an instance, written once. It defines `Function`, whose variants are the C
/// names, with `ALL`, `name`, `belongs` and `allowed` (the states as a [`Mask`]).
macro_rules! functions {
    ($($name:ident: $belongs:expr => [$($state:ident),*],)*) => {
        /// One exported function that takes an instance; the variant is its C name.
        #[allow(non_camel_case_types)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum Function {
            $($name,)*
        }

        impl Function {
            pub const ALL: &'static [Function] = &[$(Function::$name,)*];

            pub const fn name(self) -> &'static str {
                match self {
                    $(Function::$name => stringify!($name),)*
                }
            }

            pub const fn belongs(self) -> $crate::instance::state::Belongs {
                match self {
                    $(Function::$name => $belongs,)*
                }
            }

            pub const fn allowed(self) -> $crate::instance::state::Mask {
                use $crate::instance::state::{Mask, State};
                match self {
                    $(Function::$name => Mask::of(&[$(State::$state),*]),)*
                }
            }
        }

        impl $crate::instance::state::Entry for Function {
            fn name(self) -> &'static str {
                Function::name(self)
            }
            fn belongs(self) -> $crate::instance::state::Belongs {
                Function::belongs(self)
            }
            fn allowed(self) -> $crate::instance::state::Mask {
                Function::allowed(self)
            }
        }
    };
}
pub(crate) use functions;

/// A function of either version's table, as the call guard sees it.
pub trait Entry: Copy {
    fn name(self) -> &'static str;
    fn belongs(self) -> Belongs;
    fn allowed(self) -> Mask;
}
