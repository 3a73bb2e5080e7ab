//! The FMU's shared library and its instances, for FMI 2.0 ([`fmi2`]) and FMI 3.0
//! ([`fmi3`]) alike, through either interface (co-simulation, or Model Exchange, which
//! `crate::exchange` integrates). With `stdio`, the only `unsafe` code of the runner: every
//! FMI call goes through a safe method of an instance that passes slices with their true
//! lengths and a component that instance created and frees. Above the two, [`Library`] and
//! [`Instance`] give one set of calls whichever version the FMU is, so that a point, a
//! system and its coupling do not know which they drive (a system may mix both).

mod fmi2;
mod fmi3;

use std::borrow::Cow;
use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use crate::description::Description;

/// An FMI status as the runner reports it (FMI 2.0 and 3.0 number them alike; Pending is
/// FMI 2.0's alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok,
    Warning,
    Discard,
    Error,
    Fatal,
    Pending,
}

impl Status {
    /// The status an FMU returned, by its number in either standard.
    fn from_code(code: u32) -> Status {
        match code {
            0 => Status::Ok,
            1 => Status::Warning,
            2 => Status::Discard,
            3 => Status::Error,
            4 => Status::Fatal,
            5 => Status::Pending,
            // A value outside the enumeration is the FMU's fault: treat it as fatal.
            _ => Status::Fatal,
        }
    }

    /// OK and Warning let the run go on.
    pub fn proceeds(self) -> bool {
        self <= Status::Warning
    }

    /// This status and the next call's, the worse of the two; the next call is made only
    /// where this one lets the run go on (a master calls nothing after an Error but what
    /// the standard allows then).
    #[inline]
    pub fn then(self, next: impl FnOnce() -> Status) -> Status {
        if self.proceeds() {
            self.max(next())
        } else {
            self
        }
    }
}

/// Which of an FMU's interfaces a library's instances use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interface {
    CoSimulation,
    ModelExchange,
}

impl Interface {
    /// The interface a plan names (`co_simulation` or `model_exchange`).
    pub fn from_name(name: &str) -> Result<Interface, String> {
        match name {
            "co_simulation" => Ok(Interface::CoSimulation),
            "model_exchange" => Ok(Interface::ModelExchange),
            other => Err(format!(
                "interface {other:?} is neither \"co_simulation\" nor \"model_exchange\""
            )),
        }
    }

    /// The interface's name as the standard writes it.
    pub fn name(self) -> &'static str {
        match self {
            Interface::CoSimulation => "Co-Simulation",
            Interface::ModelExchange => "Model Exchange",
        }
    }

    /// The interface an FMU is run through when the plan names none: co-simulation where
    /// the FMU has it, else Model Exchange.
    pub fn default_for(description: &Description) -> Interface {
        if description.model_identifier.is_none() && description.exchange_identifier.is_some() {
            Interface::ModelExchange
        } else {
            Interface::CoSimulation
        }
    }

    fn element(self) -> &'static str {
        match self {
            Interface::CoSimulation => "CoSimulation",
            Interface::ModelExchange => "ModelExchange",
        }
    }
}

/// What an FMU answered at the end of one event iteration (Model Exchange).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EventUpdate {
    /// Another iteration is needed.
    pub again: bool,
    pub terminate: bool,
    pub nominals_changed: bool,
    pub states_changed: bool,
    pub next_event_time: Option<f64>,
}

/// The platform folder of `binaries/` that this build of the runner loads from, as FMI 2.0
/// and FMI 3.0 name it.
pub const PLATFORM: &str = if cfg!(all(target_os = "linux", target_pointer_width = "64")) {
    "linux64"
} else if cfg!(all(target_os = "macos", target_pointer_width = "64")) {
    "darwin64"
} else if cfg!(all(target_os = "windows", target_pointer_width = "64")) {
    "win64"
} else {
    "unsupported"
};

const PLATFORM_FMI3: &str = if cfg!(all(target_os = "linux", target_arch = "x86_64")) {
    "x86_64-linux"
} else if cfg!(all(target_os = "linux", target_arch = "aarch64")) {
    "aarch64-linux"
} else if cfg!(all(target_os = "macos", target_arch = "x86_64")) {
    "x86_64-darwin"
} else if cfg!(all(target_os = "macos", target_arch = "aarch64")) {
    "aarch64-darwin"
} else if cfg!(all(target_os = "windows", target_arch = "x86_64")) {
    "x86_64-windows"
} else {
    "unsupported"
};

/// The binary of co-simulation model `identifier` for this platform, in the FMU unpacked
/// in `dir`, or why there is none.
fn binary_path(dir: &Path, platform: &str, identifier: &str) -> Result<PathBuf, String> {
    let path = dir
        .join("binaries")
        .join(platform)
        .join(format!("{identifier}{}", std::env::consts::DLL_SUFFIX));
    if path.is_file() {
        Ok(path)
    } else {
        Err(format!(
            "the FMU has no binary for this platform: {} is missing",
            path.display()
        ))
    }
}

/// The names in `present` whose function the binary lacks, or an error naming them.
fn require(path: &Path, present: &[(&'static str, bool)]) -> Result<(), String> {
    let missing: Vec<&str> = present
        .iter()
        .filter(|(_, ok)| !ok)
        .map(|(name, _)| *name)
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{} does not export {}",
            path.display(),
            missing.join(", ")
        ))
    }
}

/// A loaded FMU binary. It is never unloaded while the runner lives: some FMUs keep
/// process-wide state that does not survive `dlclose`.
pub enum Library {
    Fmi2(Rc<fmi2::Library>),
    Fmi3(Rc<fmi3::Library>),
}

impl Library {
    /// The binary of the FMU unpacked in `dir` for `interface`, for the version its
    /// description declares.
    pub fn load(
        dir: &Path,
        description: &Description,
        interface: Interface,
    ) -> Result<Rc<Library>, String> {
        let identifier = match interface {
            Interface::CoSimulation => description.model_identifier.as_deref(),
            Interface::ModelExchange => description.exchange_identifier.as_deref(),
        };
        let identifier = identifier
            .ok_or_else(|| format!("the FMU has no {} interface", interface.element()))?;
        let library = if description.fmi_version.starts_with("3.") {
            let path = binary_path(dir, PLATFORM_FMI3, identifier)?;
            Library::Fmi3(fmi3::Library::load(&path, dir, description, interface)?)
        } else {
            let path = binary_path(dir, PLATFORM, identifier)?;
            Library::Fmi2(fmi2::Library::load(&path, dir, description, interface)?)
        };
        Ok(Rc::new(library))
    }

    /// Whether the binary exports the output-derivative getter, and the input-derivative
    /// setter (whatever its description declares; FMI 3.0 has no such setter).
    pub fn exports_derivatives(&self) -> (bool, bool) {
        match self {
            Library::Fmi2(l) => l.exports_derivatives(),
            Library::Fmi3(l) => (l.exports_output_derivatives(), false),
        }
    }

    /// Whether the binary exports the functions that get, set and free an FMU state
    /// (whatever its description declares).
    pub fn exports_state(&self) -> bool {
        match self {
            Library::Fmi2(l) => l.exports_state(),
            Library::Fmi3(l) => l.exports_state(),
        }
    }
}

/// The resource folder of the FMU unpacked in `dir`, as a `file://` URI (FMI 2.0) or a
/// path ending in a separator (FMI 3.0).
fn resources(dir: &Path) -> PathBuf {
    let resources = dir.join("resources");
    resources.canonicalize().unwrap_or(resources)
}

/// FMI 3.0's name of the call FMI 2.0 names `fmi2_name`; for a call FMI 3.0 lacks, the
/// one that does its work there.
fn fmi3_name(fmi2_name: &str) -> String {
    let call = fmi2_name.strip_prefix("fmi2").unwrap_or(fmi2_name);
    let call = match call {
        "SetReal" => "SetFloat64",
        "GetReal" => "GetFloat64",
        "SetInteger" => "SetInt32",
        "GetInteger" => "GetInt32",
        "GetFMUstate" => "GetFMUState",
        "SetFMUstate" => "SetFMUState",
        "GetRealOutputDerivatives" => "GetOutputDerivatives",
        "SetupExperiment" => "EnterInitializationMode",
        other => other,
    };
    format!("fmi3{call}")
}

/// One instance; freed when dropped.
pub enum Instance {
    Fmi2(fmi2::Instance),
    Fmi3(fmi3::Instance),
}

/// `$implement!` over every call of a point's master loop (the calls of
/// [`crate::unit::Unit`]), written once here.
macro_rules! each_call {
    ($implement:ident) => {
        $implement!(
            reset(),
            setup_experiment(tolerance: Option<f64>, start: f64, stop: f64),
            enter_initialization_mode(),
            exit_initialization_mode(),
            set_real(vr: &[u32], values: &[f64]),
            set_integer(vr: &[u32], values: &[i32]),
            set_boolean(vr: &[u32], values: &[i32]),
            get_real(vr: &[u32], values: &mut [f64]),
            get_integer(vr: &[u32], values: &mut [i32]),
            get_boolean(vr: &[u32], values: &mut [i32]),
            do_step(time: f64, step: f64),
        );
    };
}
pub(crate) use each_call;

/// Each call goes to the version's method of the same name.
macro_rules! each_version {
    ($($name:ident($($arg:ident: $t:ty),*)),* $(,)?) => {
        $(#[inline]
        pub fn $name(&mut self, $($arg: $t),*) -> Status {
            match self {
                Instance::Fmi2(i) => i.$name($($arg),*),
                Instance::Fmi3(i) => i.$name($($arg),*),
            }
        })*
    };
}

impl Instance {
    /// An instance named `name` (the name the FMU's messages carry).
    pub fn new(library: &Rc<Library>, name: &CStr) -> Result<Instance, String> {
        Ok(match &**library {
            Library::Fmi2(library) => Instance::Fmi2(fmi2::Instance::new(library, name)?),
            Library::Fmi3(library) => Instance::Fmi3(fmi3::Instance::new(library, name)?),
        })
    }

    each_call!(each_version);
    each_version!(
        get_output_derivatives(vr: u32, values: &mut [f64]),
        get_directional_derivative(
            unknowns: &[u32],
            knowns: &[u32],
            seed: &[f64],
            sensitivity: &mut [f64]
        ),
        set_input_derivatives(vr: u32, values: &[f64]),
        save_state(),
        restore_state(),
    );
    // Model Exchange.
    each_version!(
        set_time(time: f64),
        set_continuous_states(values: &[f64]),
        get_continuous_states(values: &mut [f64]),
        get_derivatives(values: &mut [f64]),
        get_event_indicators(values: &mut [f64]),
        get_nominals(values: &mut [f64]),
        enter_event_mode(),
        update_discrete_states(update: &mut EventUpdate),
        enter_continuous_time_mode(),
        completed_integrator_step(asks: &mut (bool, bool)),
    );

    /// Model Exchange's time and continuous states, the states set only where the time
    /// was.
    pub fn set_state(&mut self, time: f64, states: &[f64]) -> Status {
        self.set_time(time)
            .then(|| self.set_continuous_states(states))
    }

    /// What FMI 2.0 calls `fmi2_name` (such as `fmi2SetReal`), as this instance's version
    /// names it, for messages.
    pub fn call_name<'a>(&self, fmi2_name: &'a str) -> Cow<'a, str> {
        match self {
            Instance::Fmi2(_) => Cow::Borrowed(fmi2_name),
            Instance::Fmi3(_) => Cow::Owned(fmi3_name(fmi2_name)),
        }
    }

    /// The events the master handled for this instance since it was made or last reset
    /// (always 0 under FMI 2.0, whose co-simulation has none).
    pub fn events(&self) -> u64 {
        match self {
            Instance::Fmi2(_) => 0,
            Instance::Fmi3(i) => i.events(),
        }
    }
}
