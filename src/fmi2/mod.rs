//! The FMI 2.0 C ABI, Co-Simulation and Model Exchange: every function of `fmi2Functions.h`, with the
//! official types of `fmi-sys`. This module holds the crate's only `unsafe` code: it turns
//! C pointers into safe calls on [`Instance`], enforces the state machine through
//! [`guarded`], and catches every panic so that none crosses the C boundary (a panic makes
//! the call return fmi2Fatal with a log message).

// The exported functions keep the argument names of fmi2Functions.h.
#![allow(non_snake_case)]

pub mod instance;
pub mod isa;
pub mod model_description;
pub mod state_machine;

use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr::null_mut;

use fmi_sys::fmi2::*;

use crate::simulation::Value;
use instance::{send_log, Category, Failure, FmuState, Instance, Outcome};
use model_description::guid;
use state_machine::{Call, Interface, State};

/// Run `body` on the instance behind `c` if the state machine allows `call` now; log and
/// map its failure to a status; turn a panic into fmi2Fatal.
fn guarded(
    c: fmi2Component,
    call: Call,
    function: &str,
    body: impl FnOnce(&mut Instance) -> Outcome,
) -> fmi2Status {
    // SAFETY: a non-null component is a pointer returned by fmi2Instantiate and not yet
    // freed (the master's obligation); instances are never shared between threads by FMI.
    let Some(instance) = (unsafe { c.cast::<Instance>().as_mut() }) else {
        return fmi2Status_fmi2Error;
    };
    if instance.log_enabled(Category::Calls) {
        instance.log(fmi2Status_fmi2OK, Category::Calls, function);
    }
    if let Some(interface) = call.interface() {
        if interface != instance.interface {
            let failure = Failure::error(format!(
                "a {} function, and this instance was instantiated for {}",
                interface.name(),
                instance.interface.name()
            ));
            instance.report(&failure, function);
            return failure.status;
        }
    }
    if !call.allowed_in(instance.state) {
        let failure = Failure::error(format!(
            "not allowed in state {}",
            instance.state.describe()
        ));
        instance.report(&failure, function);
        return failure.status;
    }
    match catch_unwind(AssertUnwindSafe(|| body(instance))) {
        Ok(Ok(())) => fmi2Status_fmi2OK,
        Ok(Err(failure)) => {
            instance.report(&failure, function);
            failure.status
        }
        Err(panic) => {
            instance.state = State::Fatal;
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let failure = Failure {
                status: fmi2Status_fmi2Fatal,
                message: format!("internal error: {what}"),
            };
            instance.report(&failure, function);
            fmi2Status_fmi2Fatal
        }
    }
}

/// A C array as a slice; `None` for a null pointer with a non-zero length.
///
/// # Safety
/// A non-null `ptr` must point to `n` valid elements that outlive the slice.
unsafe fn slice<'a, T>(ptr: *const T, n: usize) -> Option<&'a [T]> {
    match (n, ptr.is_null()) {
        (0, _) => Some(&[]),
        (_, true) => None,
        // SAFETY: guaranteed by the caller.
        _ => Some(unsafe { std::slice::from_raw_parts(ptr, n) }),
    }
}

/// A mutable C array as a slice; `None` for a null pointer with a non-zero length.
///
/// # Safety
/// A non-null `ptr` must point to `n` writable elements that outlive the slice.
unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize) -> Option<&'a mut [T]> {
    match (n, ptr.is_null()) {
        (0, _) => Some(&mut []),
        (_, true) => None,
        // SAFETY: guaranteed by the caller.
        _ => Some(unsafe { std::slice::from_raw_parts_mut(ptr, n) }),
    }
}

fn null_argument(name: &str, n: usize) -> Failure {
    Failure::error(format!("{name} is NULL with {n} elements requested"))
}

fn unknown_references(kind: &str, vrs: &[fmi2ValueReference]) -> Outcome {
    match vrs.first() {
        None => Ok(()),
        Some(vr) => Err(Failure::error(format!(
            "no {kind} variable has value reference {vr} (this FMU has no {kind} variables)"
        ))),
    }
}

// ---------------------------------------------------------------------------------------
// Common functions

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    fmi2TypesPlatform.as_ptr().cast()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    fmi2Version.as_ptr().cast()
}

/// # Safety
/// `categories` must hold `nCategories` valid C strings (FMI 2.0 contract).
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    guarded(
        c,
        Call::SetDebugLogging,
        "fmi2SetDebugLogging",
        |instance| {
            // SAFETY: FMI contract on `categories`.
            let pointers = unsafe { slice(categories, nCategories) }
                .ok_or_else(|| null_argument("categories", nCategories))?;
            let mut names = Vec::with_capacity(pointers.len());
            for &pointer in pointers {
                if pointer.is_null() {
                    return Err(Failure::error("a category name is NULL"));
                }
                // SAFETY: non-null, NUL-terminated by the FMI contract.
                let name = unsafe { CStr::from_ptr(pointer) }
                    .to_str()
                    .map_err(|_| Failure::error("a category name is not UTF-8"))?;
                names.push(name);
            }
            instance.set_debug_logging(loggingOn != 0, &names)
        },
    )
}

/// # Safety
/// String arguments must be NULL or valid C strings; `functions` NULL or valid.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    _fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    // SAFETY: FMI contract on the arguments, checked for NULL inside.
    catch_unwind(|| unsafe {
        instantiate(instanceName, fmuType, fmuGUID, functions, loggingOn != 0)
    })
    .unwrap_or(null_mut())
}

/// # Safety
/// As [`fmi2Instantiate`].
unsafe fn instantiate(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    fmu_guid: fmi2String,
    functions: *const fmi2CallbackFunctions,
    logging_on: bool,
) -> fmi2Component {
    // SAFETY: NULL or valid, by the FMI contract.
    let functions = unsafe { functions.as_ref() };
    let logger = functions.and_then(|f| f.logger);
    let environment = functions.map_or(null_mut(), |f| f.componentEnvironment);
    let name = if instance_name.is_null() {
        CString::default()
    } else {
        // SAFETY: non-null C string by the FMI contract.
        unsafe { CStr::from_ptr(instance_name) }.to_owned()
    };
    let fail = |message: String| {
        if let Some(logger) = logger {
            send_log(
                logger,
                environment,
                &name,
                fmi2Status_fmi2Error,
                "logStatusError",
                &format!("fmi2Instantiate: {message}"),
            );
        }
        null_mut()
    };
    if functions.is_none() {
        return fail("functions is NULL".into());
    }
    if name.is_empty() {
        return fail("instanceName must be a non-empty string".into());
    }
    let interface = match fmu_type {
        t if t == fmi2Type_fmi2ModelExchange => Interface::ModelExchange,
        t if t == fmi2Type_fmi2CoSimulation => Interface::CoSimulation,
        _ => {
            return fail(format!(
                "fmuType = {fmu_type}: must be fmi2ModelExchange (0) or fmi2CoSimulation (1)"
            ))
        }
    };
    let expected = guid();
    // SAFETY: non-null C string by the FMI contract.
    let given = (!fmu_guid.is_null()).then(|| {
        unsafe { CStr::from_ptr(fmu_guid) }
            .to_string_lossy()
            .into_owned()
    });
    if given.as_deref() != Some(expected) {
        return fail(format!(
            "fmuGUID {} does not match this binary's {expected}: modelDescription.xml and binary are from different builds",
            given.as_deref().unwrap_or("NULL")
        ));
    }
    Box::into_raw(Box::new(Instance::new(
        interface,
        name,
        logger,
        environment,
        logging_on,
    )))
    .cast()
}

/// # Safety
/// `c` must be NULL or a pointer from fmi2Instantiate, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    if !c.is_null() {
        // SAFETY: created by Box::into_raw in fmi2Instantiate; the master frees it once.
        let _ = catch_unwind(|| drop(unsafe { Box::from_raw(c.cast::<Instance>()) }));
    }
}

#[no_mangle]
pub extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    guarded(
        c,
        Call::SetupExperiment,
        "fmi2SetupExperiment",
        |instance| {
            let tolerance = (toleranceDefined != 0).then_some(tolerance);
            let stop = (stopTimeDefined != 0).then_some(stopTime);
            instance.setup_experiment(tolerance, startTime, stop)
        },
    )
}

#[no_mangle]
pub extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    guarded(
        c,
        Call::EnterInitializationMode,
        "fmi2EnterInitializationMode",
        Instance::enter_initialization_mode,
    )
}

#[no_mangle]
pub extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    guarded(
        c,
        Call::ExitInitializationMode,
        "fmi2ExitInitializationMode",
        Instance::exit_initialization_mode,
    )
}

#[no_mangle]
pub extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    guarded(c, Call::Terminate, "fmi2Terminate", Instance::terminate)
}

#[no_mangle]
pub extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    guarded(c, Call::Reset, "fmi2Reset", Instance::reset)
}

// ---------------------------------------------------------------------------------------
// Getting and setting values

/// A getter of `fmi2Functions.h`: reads the variables `vr` through `Instance::$read`.
macro_rules! getter {
    ($name:ident, $ctype:ty, $read:ident) => {
        /// # Safety
        /// `vr` and `value` must hold `nvr` elements (FMI 2.0 contract).
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi2Component,
            vr: *const fmi2ValueReference,
            nvr: usize,
            value: *mut $ctype,
        ) -> fmi2Status {
            guarded(c, Call::Get, stringify!($name), |instance| {
                // SAFETY: FMI contract on the arrays.
                let vrs = unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                // SAFETY: FMI contract on the arrays.
                let values =
                    unsafe { slice_mut(value, nvr) }.ok_or_else(|| null_argument("value", nvr))?;
                instance.$read(vrs, values)
            })
        }
    };
}

/// A setter of `fmi2Functions.h`: each C value becomes a [`Value`] through `$value`.
macro_rules! setter {
    ($name:ident, $ctype:ty, $value:expr) => {
        /// # Safety
        /// `vr` and `value` must hold `nvr` elements (FMI 2.0 contract).
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi2Component,
            vr: *const fmi2ValueReference,
            nvr: usize,
            value: *const $ctype,
        ) -> fmi2Status {
            guarded(c, Call::Set, stringify!($name), |instance| {
                // SAFETY: FMI contract on the arrays.
                let vrs = unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                // SAFETY: FMI contract on the arrays.
                let values =
                    unsafe { slice(value, nvr) }.ok_or_else(|| null_argument("value", nvr))?;
                instance.set_values(vrs, values.iter().map(|v| $value(*v)))
            })
        }
    };
}

getter!(fmi2GetReal, fmi2Real, get_real);
getter!(fmi2GetInteger, fmi2Integer, get_integer);
getter!(fmi2GetBoolean, fmi2Boolean, get_boolean);
setter!(fmi2SetReal, fmi2Real, Value::Real);
setter!(fmi2SetInteger, fmi2Integer, Value::Integer);
// C's convention, which fmi2True (1) and fmi2False (0) follow: any non-zero is true.
setter!(
    fmi2SetBoolean,
    fmi2Boolean,
    |v: fmi2Boolean| Value::Boolean(v != 0)
);

/// String accessors: this FMU has no String variables, so any value reference is
/// unknown; an empty request succeeds.
macro_rules! no_variables_of_type {
    ($name:ident, $call:expr, $kind:literal, $ptr:ty) => {
        /// # Safety
        /// `vr` must hold `nvr` elements (FMI 2.0 contract).
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi2Component,
            vr: *const fmi2ValueReference,
            nvr: usize,
            _value: $ptr,
        ) -> fmi2Status {
            guarded(c, $call, stringify!($name), |_| {
                // SAFETY: FMI contract on the array.
                let vrs = unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                unknown_references($kind, vrs)
            })
        }
    };
}

no_variables_of_type!(fmi2GetString, Call::Get, "String", *mut fmi2String);
no_variables_of_type!(fmi2SetString, Call::Set, "String", *const fmi2String);

// ---------------------------------------------------------------------------------------
// Optional capabilities: FMU state, directional derivatives, input and output derivatives.

/// # Safety
/// `FMUstate` must be NULL or point to a writable pointer (NULL, or a state of `c`).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    guarded(c, Call::FmuState, "fmi2GetFMUstate", |instance| {
        // SAFETY: NULL or writable by the FMI contract.
        let slot = unsafe { FMUstate.as_mut() }.ok_or_else(|| null_argument("FMUstate", 1))?;
        let saved = instance.save();
        if slot.is_null() {
            *slot = instance.issue_state(saved).cast();
        } else {
            // A non-NULL entry is a state to overwrite (FMI 2.0, 2.1.8).
            *instance.issued_state(*slot)? = saved;
        }
        Ok(())
    })
}

#[no_mangle]
pub extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    guarded(c, Call::FmuState, "fmi2SetFMUstate", |instance| {
        let saved = instance.issued_state(FMUstate)?.clone();
        instance.restore(&saved)
    })
}

/// # Safety
/// `FMUstate` must be NULL or point to a writable pointer.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    guarded(c, Call::FmuState, "fmi2FreeFMUstate", |instance| {
        // SAFETY: NULL or writable by the FMI contract.
        let Some(slot) = (unsafe { FMUstate.as_mut() }) else {
            return Ok(());
        };
        if !slot.is_null() {
            instance.free_state(*slot)?;
            *slot = null_mut();
        }
        Ok(())
    })
}

/// # Safety
/// `size` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    guarded(
        c,
        Call::FmuState,
        "fmi2SerializedFMUstateSize",
        |instance| {
            let length = instance.issued_state(FMUstate)?.serialize().len();
            // SAFETY: NULL or writable by the FMI contract.
            *unsafe { size.as_mut() }.ok_or_else(|| null_argument("size", 1))? = length;
            Ok(())
        },
    )
}

/// # Safety
/// `serializedState` must hold `size` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    guarded(c, Call::FmuState, "fmi2SerializeFMUstate", |instance| {
        let bytes = instance.issued_state(FMUstate)?.serialize();
        if size < bytes.len() {
            return Err(Failure::error(format!(
                "size = {size} is too small: the state needs {} bytes (fmi2SerializedFMUstateSize)",
                bytes.len()
            )));
        }
        // SAFETY: FMI contract on the buffer.
        let target = unsafe { slice_mut(serializedState.cast::<u8>(), size) }
            .ok_or_else(|| null_argument("serializedState", size))?;
        target[..bytes.len()].copy_from_slice(&bytes);
        Ok(())
    })
}

/// # Safety
/// `serializedState` must hold `size` readable bytes; `FMUstate` must be NULL or point to
/// a writable pointer (NULL, or a state of `c`).
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    guarded(c, Call::FmuState, "fmi2DeSerializeFMUstate", |instance| {
        // SAFETY: FMI contract on the buffer.
        let bytes = unsafe { slice(serializedState.cast::<u8>(), size) }
            .ok_or_else(|| null_argument("serializedState", size))?;
        let restored = FmuState::deserialize(bytes)?;
        // SAFETY: NULL or writable by the FMI contract.
        let slot = unsafe { FMUstate.as_mut() }.ok_or_else(|| null_argument("FMUstate", 1))?;
        if slot.is_null() {
            *slot = instance.issue_state(restored).cast();
        } else {
            *instance.issued_state(*slot)? = restored;
        }
        Ok(())
    })
}

/// # Safety
/// `vUnknown_ref` and `dvUnknown` must hold `nUnknown` elements, `vKnown_ref` and
/// `dvKnown` `nKnown` (FMI 2.0 contract).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    guarded(
        c,
        Call::DirectionalDerivative,
        "fmi2GetDirectionalDerivative",
        |instance| {
            // SAFETY: FMI contract on the arrays.
            let (unknowns, knowns, seed, sensitivity) = unsafe {
                (
                    slice(vUnknown_ref, nUnknown),
                    slice(vKnown_ref, nKnown),
                    slice(dvKnown, nKnown),
                    slice_mut(dvUnknown, nUnknown),
                )
            };
            let unknowns = unknowns.ok_or_else(|| null_argument("vUnknown_ref", nUnknown))?;
            let knowns = knowns.ok_or_else(|| null_argument("vKnown_ref", nKnown))?;
            let seed = seed.ok_or_else(|| null_argument("dvKnown", nKnown))?;
            let sensitivity = sensitivity.ok_or_else(|| null_argument("dvUnknown", nUnknown))?;
            instance.directional_derivative(unknowns, knowns, seed, sensitivity)
        },
    )
}

/// # Safety
/// `vr`, `order` and `value` must hold `nvr` elements (FMI 2.0 contract).
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    guarded(
        c,
        Call::SetInputDerivatives,
        "fmi2SetRealInputDerivatives",
        |instance| {
            // SAFETY: FMI contract on the arrays.
            let (vrs, orders, values) =
                unsafe { (slice(vr, nvr), slice(order, nvr), slice(value, nvr)) };
            let vrs = vrs.ok_or_else(|| null_argument("vr", nvr))?;
            let orders = orders.ok_or_else(|| null_argument("order", nvr))?;
            let values = values.ok_or_else(|| null_argument("value", nvr))?;
            instance.set_input_derivatives(vrs, orders, values)
        },
    )
}

/// # Safety
/// `vr` and `order` must hold `nvr` elements, `value` `nvr` writable ones.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    guarded(
        c,
        Call::GetOutputDerivatives,
        "fmi2GetRealOutputDerivatives",
        |instance| {
            // SAFETY: FMI contract on the arrays.
            let (vrs, orders, values) =
                unsafe { (slice(vr, nvr), slice(order, nvr), slice_mut(value, nvr)) };
            let vrs = vrs.ok_or_else(|| null_argument("vr", nvr))?;
            let orders = orders.ok_or_else(|| null_argument("order", nvr))?;
            let values = values.ok_or_else(|| null_argument("value", nvr))?;
            instance.get_output_derivatives(vrs, orders, values)
        },
    )
}

// ---------------------------------------------------------------------------------------
// Co-simulation stepping and status

#[no_mangle]
pub extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    guarded(c, Call::DoStep, "fmi2DoStep", |instance| {
        instance.do_step(currentCommunicationPoint, communicationStepSize)
    })
}

#[no_mangle]
pub extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    guarded(c, Call::CancelStep, "fmi2CancelStep", |_| Ok(()))
}

/// # Safety
/// `value` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2Status,
) -> fmi2Status {
    guarded(c, Call::GetStatus, "fmi2GetStatus", |_| {
        Err(Failure::error(format!(
            "status kind {s}: this FMU never returns fmi2Pending, so no asynchronous step status exists"
        )))
    })
}

/// # Safety
/// `value` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    guarded(c, Call::GetStatus, "fmi2GetRealStatus", |instance| {
        if s != fmi2StatusKind_fmi2LastSuccessfulTime {
            return Err(Failure::error(format!(
                "status kind {s} has no Real value; use fmi2LastSuccessfulTime (2)"
            )));
        }
        // SAFETY: NULL or writable by the FMI contract.
        let value = unsafe { value.as_mut() }.ok_or_else(|| null_argument("value", 1))?;
        *value = instance.last_successful_time();
        Ok(())
    })
}

/// # Safety
/// `value` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2Integer,
) -> fmi2Status {
    guarded(c, Call::GetStatus, "fmi2GetIntegerStatus", |_| {
        Err(Failure::error(format!(
            "status kind {s} has no Integer value"
        )))
    })
}

/// # Safety
/// `value` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    guarded(c, Call::GetStatus, "fmi2GetBooleanStatus", |_| {
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
    })
}

/// # Safety
/// `value` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2String,
) -> fmi2Status {
    guarded(c, Call::GetStatus, "fmi2GetStringStatus", |_| {
        Err(Failure::error(format!(
            "status kind {s}: this FMU never returns fmi2Pending, so there is no pending status"
        )))
    })
}

// ---------------------------------------------------------------------------------------
// Model Exchange (docs/model.md §6)

#[no_mangle]
pub extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
    guarded(
        c,
        Call::EnterEventMode,
        "fmi2EnterEventMode",
        Instance::enter_event_mode,
    )
}

/// # Safety
/// `eventInfo` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2NewDiscreteStates(
    c: fmi2Component,
    eventInfo: *mut fmi2EventInfo,
) -> fmi2Status {
    guarded(
        c,
        Call::NewDiscreteStates,
        "fmi2NewDiscreteStates",
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
        },
    )
}

#[no_mangle]
pub extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
    guarded(
        c,
        Call::EnterContinuousTimeMode,
        "fmi2EnterContinuousTimeMode",
        Instance::enter_continuous_time_mode,
    )
}

/// # Safety
/// `enterEventMode` and `terminateSimulation` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
    c: fmi2Component,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    enterEventMode: *mut fmi2Boolean,
    terminateSimulation: *mut fmi2Boolean,
) -> fmi2Status {
    guarded(
        c,
        Call::CompletedIntegratorStep,
        "fmi2CompletedIntegratorStep",
        |instance| {
            // SAFETY: NULL or writable by the FMI contract.
            let (event, terminate) =
                unsafe { (enterEventMode.as_mut(), terminateSimulation.as_mut()) };
            let event = event.ok_or_else(|| null_argument("enterEventMode", 1))?;
            let terminate = terminate.ok_or_else(|| null_argument("terminateSimulation", 1))?;
            *event = fmi2Boolean::from(instance.completed_integrator_step()?);
            *terminate = fmi2False as fmi2Boolean;
            Ok(())
        },
    )
}

#[no_mangle]
pub extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    guarded(c, Call::SetTime, "fmi2SetTime", |instance| {
        instance.set_time(time)
    })
}

/// # Safety
/// `x` must hold `nx` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetContinuousStates(
    c: fmi2Component,
    x: *const fmi2Real,
    nx: usize,
) -> fmi2Status {
    guarded(
        c,
        Call::SetContinuousStates,
        "fmi2SetContinuousStates",
        |instance| {
            // SAFETY: FMI contract on the array.
            let x = unsafe { slice(x, nx) }.ok_or_else(|| null_argument("x", nx))?;
            instance.set_continuous_states(x)
        },
    )
}

/// The four functions that fill an array of continuous-time values.
macro_rules! continuous_values {
    ($name:ident, $array:literal, $method:ident) => {
        /// # Safety
        /// The array must hold `n` writable elements.
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi2Component,
            values: *mut fmi2Real,
            n: usize,
        ) -> fmi2Status {
            guarded(c, Call::GetContinuous, stringify!($name), |instance| {
                // SAFETY: FMI contract on the array.
                let values =
                    unsafe { slice_mut(values, n) }.ok_or_else(|| null_argument($array, n))?;
                instance.$method(values)
            })
        }
    };
}

continuous_values!(fmi2GetDerivatives, "derivatives", get_derivatives);
continuous_values!(
    fmi2GetEventIndicators,
    "eventIndicators",
    get_event_indicators
);
continuous_values!(fmi2GetContinuousStates, "x", get_continuous_states);
continuous_values!(fmi2GetNominalsOfContinuousStates, "x_nominal", get_nominals);

/// Every export has exactly the type the official header declares: the build fails if not.
const _: () = {
    let _: fmi2GetTypesPlatformTYPE = Some(fmi2GetTypesPlatform);
    let _: fmi2GetVersionTYPE = Some(fmi2GetVersion);
    let _: fmi2SetDebugLoggingTYPE = Some(fmi2SetDebugLogging);
    let _: fmi2InstantiateTYPE = Some(fmi2Instantiate);
    let _: fmi2FreeInstanceTYPE = Some(fmi2FreeInstance);
    let _: fmi2SetupExperimentTYPE = Some(fmi2SetupExperiment);
    let _: fmi2EnterInitializationModeTYPE = Some(fmi2EnterInitializationMode);
    let _: fmi2ExitInitializationModeTYPE = Some(fmi2ExitInitializationMode);
    let _: fmi2TerminateTYPE = Some(fmi2Terminate);
    let _: fmi2ResetTYPE = Some(fmi2Reset);
    let _: fmi2GetRealTYPE = Some(fmi2GetReal);
    let _: fmi2GetIntegerTYPE = Some(fmi2GetInteger);
    let _: fmi2GetBooleanTYPE = Some(fmi2GetBoolean);
    let _: fmi2GetStringTYPE = Some(fmi2GetString);
    let _: fmi2SetRealTYPE = Some(fmi2SetReal);
    let _: fmi2SetIntegerTYPE = Some(fmi2SetInteger);
    let _: fmi2SetBooleanTYPE = Some(fmi2SetBoolean);
    let _: fmi2SetStringTYPE = Some(fmi2SetString);
    let _: fmi2GetFMUstateTYPE = Some(fmi2GetFMUstate);
    let _: fmi2SetFMUstateTYPE = Some(fmi2SetFMUstate);
    let _: fmi2FreeFMUstateTYPE = Some(fmi2FreeFMUstate);
    let _: fmi2SerializedFMUstateSizeTYPE = Some(fmi2SerializedFMUstateSize);
    let _: fmi2SerializeFMUstateTYPE = Some(fmi2SerializeFMUstate);
    let _: fmi2DeSerializeFMUstateTYPE = Some(fmi2DeSerializeFMUstate);
    let _: fmi2GetDirectionalDerivativeTYPE = Some(fmi2GetDirectionalDerivative);
    let _: fmi2EnterEventModeTYPE = Some(fmi2EnterEventMode);
    let _: fmi2NewDiscreteStatesTYPE = Some(fmi2NewDiscreteStates);
    let _: fmi2EnterContinuousTimeModeTYPE = Some(fmi2EnterContinuousTimeMode);
    let _: fmi2CompletedIntegratorStepTYPE = Some(fmi2CompletedIntegratorStep);
    let _: fmi2SetTimeTYPE = Some(fmi2SetTime);
    let _: fmi2SetContinuousStatesTYPE = Some(fmi2SetContinuousStates);
    let _: fmi2GetDerivativesTYPE = Some(fmi2GetDerivatives);
    let _: fmi2GetEventIndicatorsTYPE = Some(fmi2GetEventIndicators);
    let _: fmi2GetContinuousStatesTYPE = Some(fmi2GetContinuousStates);
    let _: fmi2GetNominalsOfContinuousStatesTYPE = Some(fmi2GetNominalsOfContinuousStates);
    let _: fmi2SetRealInputDerivativesTYPE = Some(fmi2SetRealInputDerivatives);
    let _: fmi2GetRealOutputDerivativesTYPE = Some(fmi2GetRealOutputDerivatives);
    let _: fmi2DoStepTYPE = Some(fmi2DoStep);
    let _: fmi2CancelStepTYPE = Some(fmi2CancelStep);
    let _: fmi2GetStatusTYPE = Some(fmi2GetStatus);
    let _: fmi2GetRealStatusTYPE = Some(fmi2GetRealStatus);
    let _: fmi2GetIntegerStatusTYPE = Some(fmi2GetIntegerStatus);
    let _: fmi2GetBooleanStatusTYPE = Some(fmi2GetBooleanStatus);
    let _: fmi2GetStringStatusTYPE = Some(fmi2GetStringStatus);
};
