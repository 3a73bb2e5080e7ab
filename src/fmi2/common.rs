//! The functions both interfaces share: version, instantiation and set-up, values, FMU
//! states and directional derivatives.

use std::ffi::{c_char, CStr, CString};
use std::panic::catch_unwind;
use std::ptr::null_mut;

use fmi_sys::fmi2::*;

use super::model_description::guid;
use super::{export, null_argument, slice, slice_mut};
use crate::abi;
use crate::instance::{Failure, Instance, Interface, Logger, Outcome, Status, Version};
use crate::plant::Value;

/// The FMU state functions' argument names, for the messages.
const STATE_NAMES: abi::StateNames = abi::StateNames {
    state: "FMUstate",
    size_function: "fmi2SerializedFMUstateSize",
};

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    fmi2TypesPlatform.as_ptr().cast()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    fmi2Version.as_ptr().cast()
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
    let environment = functions.map_or(null_mut(), |f| f.componentEnvironment);
    let logger = functions
        .and_then(|f| f.logger)
        .map(|callback| Logger::Fmi2 {
            callback,
            environment,
        });
    let name = if instance_name.is_null() {
        CString::default()
    } else {
        // SAFETY: non-null C string by the FMI contract.
        unsafe { CStr::from_ptr(instance_name) }.to_owned()
    };
    let fail = |message: String| {
        if let Some(logger) = logger {
            let message = format!("fmi2Instantiate: {message}");
            logger.send(&name, Status::Error, "logStatusError", &message);
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
        Version::Fmi2,
        name,
        logger,
        logging_on,
    )))
    .cast()
}

/// # Safety
/// `c` must be NULL or a pointer from fmi2Instantiate, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    // SAFETY: the master's obligation, as the function's.
    unsafe { abi::free_instance(c) }
}

const _: () = {
    let _: fmi2GetTypesPlatformTYPE = Some(fmi2GetTypesPlatform);
    let _: fmi2GetVersionTYPE = Some(fmi2GetVersion);
    let _: fmi2InstantiateTYPE = Some(fmi2Instantiate);
    let _: fmi2FreeInstanceTYPE = Some(fmi2FreeInstance);
};

export! {
    /// # Safety
    /// `c` is an instance; `categories` must hold `nCategories` valid C strings.
    fn fmi2SetDebugLogging(
        c,
        loggingOn: fmi2Boolean,
        nCategories: usize,
        categories: *const fmi2String,
    ): fmi2SetDebugLoggingTYPE = |instance| {
        // SAFETY: FMI contract on `categories`.
        let names = unsafe { abi::category_names(categories, nCategories) }?;
        instance.set_debug_logging(loggingOn != 0, &names)
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2SetupExperiment(
        c,
        toleranceDefined: fmi2Boolean,
        tolerance: fmi2Real,
        startTime: fmi2Real,
        stopTimeDefined: fmi2Boolean,
        stopTime: fmi2Real,
    ): fmi2SetupExperimentTYPE = |instance| {
        let tolerance = (toleranceDefined != 0).then_some(tolerance);
        let stop = (stopTimeDefined != 0).then_some(stopTime);
        instance.setup_experiment(tolerance, startTime, stop)
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2EnterInitializationMode(c): fmi2EnterInitializationModeTYPE =
        Instance::enter_initialization_mode;
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2ExitInitializationMode(c): fmi2ExitInitializationModeTYPE =
        Instance::exit_initialization_mode;
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2Terminate(c): fmi2TerminateTYPE = Instance::terminate;
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2Reset(c): fmi2ResetTYPE = Instance::reset;
}

/// A getter of `fmi2Functions.h`: reads the variables `vr` through `Instance::$read`.
macro_rules! getter {
    ($name:ident: $check:ident, $ctype:ty, $read:ident) => {
        export! {
            /// # Safety
            /// `c` is an instance; `vr` and `value` must hold `nvr` elements.
            fn $name(c, vr: *const fmi2ValueReference, nvr: usize, value: *mut $ctype): $check =
                |instance| {
                    // SAFETY: FMI contract on the arrays.
                    let vrs =
                        unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                    // SAFETY: FMI contract on the arrays.
                    let values = unsafe { slice_mut(value, nvr) }
                        .ok_or_else(|| null_argument("value", nvr))?;
                    instance.$read(vrs, values)
                };
        }
    };
}

/// A setter of `fmi2Functions.h`: each C value becomes a [`Value`] through `$value`.
macro_rules! setter {
    ($name:ident: $check:ident, $ctype:ty, $value:expr) => {
        export! {
            /// # Safety
            /// `c` is an instance; `vr` and `value` must hold `nvr` elements.
            fn $name(c, vr: *const fmi2ValueReference, nvr: usize, value: *const $ctype): $check =
                |instance| {
                    // SAFETY: FMI contract on the arrays.
                    let vrs =
                        unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                    // SAFETY: FMI contract on the arrays.
                    let values =
                        unsafe { slice(value, nvr) }.ok_or_else(|| null_argument("value", nvr))?;
                    instance.set_values(vrs.iter().copied().zip(values.iter().map(|v| $value(*v))))
                };
        }
    };
}

getter!(fmi2GetReal: fmi2GetRealTYPE, fmi2Real, get_real);
getter!(fmi2GetInteger: fmi2GetIntegerTYPE, fmi2Integer, get_integer);
getter!(fmi2GetBoolean: fmi2GetBooleanTYPE, fmi2Boolean, get_boolean);
setter!(fmi2SetReal: fmi2SetRealTYPE, fmi2Real, Value::Real);
setter!(fmi2SetInteger: fmi2SetIntegerTYPE, fmi2Integer, Value::Integer);
// C's convention, which fmi2True (1) and fmi2False (0) follow: any non-zero is true.
setter!(fmi2SetBoolean: fmi2SetBooleanTYPE, fmi2Boolean, |v: fmi2Boolean| {
    Value::Boolean(v != 0)
});

/// String accessors: this FMU has no String variables, so any value reference is
/// unknown; an empty request succeeds.
macro_rules! no_string_variables {
    ($name:ident: $check:ident, $ptr:ty) => {
        export! {
            /// # Safety
            /// `c` is an instance; `vr` must hold `nvr` elements.
            fn $name(c, vr: *const fmi2ValueReference, nvr: usize, _value: $ptr): $check =
                |_| {
                    // SAFETY: FMI contract on the array.
                    let vrs =
                        unsafe { slice(vr, nvr) }.ok_or_else(|| null_argument("vr", nvr))?;
                    unknown_string_references(vrs)
                };
        }
    };
}

no_string_variables!(fmi2GetString: fmi2GetStringTYPE, *mut fmi2String);
no_string_variables!(fmi2SetString: fmi2SetStringTYPE, *const fmi2String);

fn unknown_string_references(vrs: &[fmi2ValueReference]) -> Outcome {
    match vrs.first() {
        None => Ok(()),
        Some(vr) => Err(Failure::error(format!(
            "no String variable has value reference {vr} (this FMU has no String variables)"
        ))),
    }
}

export! {
    /// # Safety
    /// `c` is an instance; `FMUstate` must be NULL or point to a writable pointer (NULL, or
    /// a state of `c`).
    fn fmi2GetFMUstate(c, FMUstate: *mut fmi2FMUstate): fmi2GetFMUstateTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::get_fmu_state(instance, FMUstate, &STATE_NAMES) }
    };
}

export! {
    /// # Safety
    /// `c` is an instance.
    fn fmi2SetFMUstate(c, FMUstate: fmi2FMUstate): fmi2SetFMUstateTYPE = |instance| {
        instance.restore_issued(FMUstate)
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `FMUstate` must be NULL or point to a writable pointer.
    fn fmi2FreeFMUstate(c, FMUstate: *mut fmi2FMUstate): fmi2FreeFMUstateTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::free_fmu_state(instance, FMUstate) }
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `size` must be NULL or writable.
    fn fmi2SerializedFMUstateSize(c, FMUstate: fmi2FMUstate, size: *mut usize):
        fmi2SerializedFMUstateSizeTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::serialized_size(instance, FMUstate, size) }
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `serializedState` must hold `size` writable bytes.
    fn fmi2SerializeFMUstate(
        c,
        FMUstate: fmi2FMUstate,
        serializedState: *mut fmi2Byte,
        size: usize,
    ): fmi2SerializeFMUstateTYPE = |instance| {
        // SAFETY: FMI contract on the buffer.
        unsafe { abi::serialize(instance, FMUstate, serializedState.cast(), size, &STATE_NAMES) }
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `serializedState` must hold `size` readable bytes; `FMUstate`
    /// must be NULL or point to a writable pointer (NULL, or a state of `c`).
    fn fmi2DeSerializeFMUstate(
        c,
        serializedState: *const fmi2Byte,
        size: usize,
        FMUstate: *mut fmi2FMUstate,
    ): fmi2DeSerializeFMUstateTYPE = |instance| {
        // SAFETY: FMI contract on the buffer and the pointer.
        unsafe {
            abi::deserialize(instance, serializedState.cast(), size, FMUstate, &STATE_NAMES)
        }
    };
}

export! {
    /// # Safety
    /// `c` is an instance; `vUnknown_ref` and `dvUnknown` must hold `nUnknown` elements,
    /// `vKnown_ref` and `dvKnown` `nKnown`.
    fn fmi2GetDirectionalDerivative(
        c,
        vUnknown_ref: *const fmi2ValueReference,
        nUnknown: usize,
        vKnown_ref: *const fmi2ValueReference,
        nKnown: usize,
        dvKnown: *const fmi2Real,
        dvUnknown: *mut fmi2Real,
    ): fmi2GetDirectionalDerivativeTYPE = |instance| {
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
    };
}
