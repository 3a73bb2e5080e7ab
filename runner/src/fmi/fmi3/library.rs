//! An FMI 3.0 binary: its functions checked for what a run calls, what its instances
//! share (token, resource folder, event mode, the Int64 variables, the status categories
//! kept), and how an instance is made and heard from.

use std::ffi::{c_char, CStr, CString};
use std::path::Path;
use std::rc::Rc;

use fmi_sys::fmi3::{fmi3Instance, fmi3InstanceEnvironment, fmi3Status, Fmi3Binding};

use super::super::{require, resources, Interface, Status};
use crate::description::{BaseType, Description};

pub struct Library {
    pub(super) binding: Fmi3Binding,
    pub(super) interface: Interface,
    pub(super) token: CString,
    pub(super) resource_path: CString,
    /// Whether co-simulation instances use the FMU's event mode (its hasEventMode).
    pub(super) event_mode: bool,
    /// The tunable parameters, sorted: with event mode, set in event mode once stepping.
    pub(super) tunable: Vec<u32>,
    /// The value references of enumerations, which FMI 3.0 sets and gets as Int64 (Int32
    /// variables use the Int32 functions), sorted.
    pub(super) int64: Vec<u32>,
    /// The FMU's categories for warnings, discards, errors and fatal errors, the only
    /// messages the runner keeps (FMI 3.0 logs nothing at all while logging is off).
    pub(super) status_categories: Vec<CString>,
}

/// The standard's names of the categories of messages that come with a status above OK.
const STATUS_CATEGORIES: [&str; 4] = [
    "logStatusWarning",
    "logStatusDiscard",
    "logStatusError",
    "logStatusFatal",
];

impl Library {
    /// The binary at `path` of the FMU unpacked in `dir`.
    pub fn load(
        path: &Path,
        dir: &Path,
        description: &Description,
        interface: Interface,
    ) -> Result<Rc<Library>, String> {
        // SAFETY: loading a shared library runs its initialisers; the FMU is trusted as
        // far as its binary goes (a crash there ends only this runner process).
        let binding = unsafe { Fmi3Binding::new(path) }
            .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        let mut int64: Vec<u32> = description
            .variables
            .iter()
            .filter(|v| v.base_type == BaseType::Enumeration)
            .map(|v| v.value_reference)
            .collect();
        int64.sort_unstable();
        int64.dedup();
        let event_mode = interface == Interface::CoSimulation && description.has_event_mode;
        require(
            path,
            &functions(&binding, interface, event_mode, !int64.is_empty()),
        )?;
        // FMI 3.0 passes the resource folder as a path that ends in a separator.
        let mut folder = resources(dir).into_os_string();
        folder.push(std::path::MAIN_SEPARATOR_STR);
        Ok(Rc::new(Library {
            binding,
            interface,
            token: CString::new(description.guid.as_str()).map_err(|e| e.to_string())?,
            resource_path: CString::new(folder.to_string_lossy().into_owned())
                .map_err(|e| e.to_string())?,
            event_mode,
            tunable: description.tunable(),
            int64,
            status_categories: description
                .log_categories
                .iter()
                .filter(|c| STATUS_CATEGORIES.contains(&c.as_str()))
                .filter_map(|c| CString::new(c.as_str()).ok())
                .collect(),
        }))
    }

    pub fn exports_output_derivatives(&self) -> bool {
        self.binding.fmi3GetOutputDerivatives.is_ok()
    }

    /// Whether the binary exports fmi3GetFMUState, fmi3SetFMUState and fmi3FreeFMUState.
    pub fn exports_state(&self) -> bool {
        let b = &self.binding;
        b.fmi3GetFMUState.is_ok() && b.fmi3SetFMUState.is_ok() && b.fmi3FreeFMUState.is_ok()
    }
}

/// Each FMI 3.0 function named, with whether the binding has it.
macro_rules! present {
    ($b:expr; $($name:ident),* $(,)?) => {
        [$((stringify!($name), $b.$name.is_ok())),*]
    };
}

/// The functions a run through `interface` calls, and whether the binary has each: in
/// co-simulation the event functions when the FMU has an event mode, and Int64 access
/// when it has enumerations.
fn functions(
    b: &Fmi3Binding,
    interface: Interface,
    events: bool,
    int64: bool,
) -> Vec<(&'static str, bool)> {
    let mut present = match interface {
        Interface::CoSimulation => present!(b; fmi3InstantiateCoSimulation, fmi3DoStep).to_vec(),
        Interface::ModelExchange => present!(b;
            fmi3InstantiateModelExchange,
            fmi3SetTime,
            fmi3SetContinuousStates,
            fmi3GetContinuousStates,
            fmi3GetContinuousStateDerivatives,
            fmi3GetEventIndicators,
            fmi3GetNominalsOfContinuousStates,
            fmi3EnterEventMode,
            fmi3UpdateDiscreteStates,
            fmi3EnterContinuousTimeMode,
            fmi3CompletedIntegratorStep,
        )
        .to_vec(),
    };
    present.extend(present!(b;
        fmi3FreeInstance,
        fmi3EnterInitializationMode,
        fmi3ExitInitializationMode,
        fmi3Reset,
        fmi3SetFloat64,
        fmi3SetInt32,
        fmi3SetBoolean,
        fmi3GetFloat64,
        fmi3GetInt32,
        fmi3GetBoolean,
    ));
    if events {
        present
            .extend(present!(b; fmi3EnterEventMode, fmi3UpdateDiscreteStates, fmi3EnterStepMode));
    }
    if int64 {
        present.extend(present!(b; fmi3SetInt64, fmi3GetInt64));
    }
    present
}

/// The FMU's log messages go to the `log` crate, as fmi-sys does for FMI 2.0, at the
/// level of their status (OK and Pending are not kept: the runner keeps no debug log).
unsafe extern "C" fn log_message(
    _environment: fmi3InstanceEnvironment,
    status: fmi3Status,
    category: *const c_char,
    message: *const c_char,
) {
    let level = match Status::from_code(status) {
        Status::Warning => log::Level::Warn,
        Status::Discard => log::Level::Trace,
        Status::Error | Status::Fatal => log::Level::Error,
        // An FMU without the standard's categories may report every step at OK: nothing
        // is copied for what is not kept.
        Status::Ok | Status::Pending => return,
    };
    let text = |p: *const c_char| {
        if p.is_null() {
            std::borrow::Cow::Borrowed("")
        } else {
            // SAFETY: a non-null C string the FMU passes for the call's duration.
            unsafe { CStr::from_ptr(p) }.to_string_lossy()
        }
    };
    log::log!(level, "[{}] {}", text(category), text(message));
}

/// Logging is on from instantiation (else an FMU says nothing, not even why it failed):
/// where the FMU names the standard's status categories, only those stay enabled, so that
/// it does not format debug messages the runner drops.
pub(super) fn keep_status_messages(library: &Library, instance: fmi3Instance) {
    let Ok(set) = library.binding.fmi3SetDebugLogging.as_ref() else {
        return;
    };
    if library.status_categories.is_empty() {
        return;
    }
    let names: Vec<*const c_char> = library
        .status_categories
        .iter()
        .map(|c| c.as_ptr())
        .collect();
    // SAFETY: a live instance; `names` holds names.len() C strings that outlive the calls.
    unsafe {
        set(instance, false, 0, std::ptr::null());
        set(instance, true, names.len(), names.as_ptr());
    }
}

/// fmi3InstantiateCoSimulation with the library's event mode and early return allowed;
/// null when the FMU refuses.
pub(super) fn instantiate_co_simulation(library: &Library, name: &CStr) -> fmi3Instance {
    // SAFETY: every pointer is valid for the call; the FMU copies the strings.
    unsafe {
        library.binding.fmi3InstantiateCoSimulation(
            name.as_ptr(),
            library.token.as_ptr(),
            library.resource_path.as_ptr(),
            false,
            true,
            library.event_mode,
            true,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            Some(log_message),
            None,
        )
    }
}

/// fmi3InstantiateModelExchange; null when the FMU refuses.
pub(super) fn instantiate_model_exchange(library: &Library, name: &CStr) -> fmi3Instance {
    // SAFETY: every pointer is valid for the call; the FMU copies the strings.
    unsafe {
        library.binding.fmi3InstantiateModelExchange(
            name.as_ptr(),
            library.token.as_ptr(),
            library.resource_path.as_ptr(),
            false,
            true,
            std::ptr::null_mut(),
            Some(log_message),
        )
    }
}
