//! The version and the three instantiation functions, what they share (the instance's
//! name and the instantiation token checked, the logger kept, why an instance cannot be
//! made said to the logger), and freeing an instance.

use std::ffi::{c_char, CStr, CString};
use std::panic::catch_unwind;
use std::ptr::null_mut;

use fmi_sys::fmi3::*;

use super::model_description::instantiation_token;
use crate::abi;
use crate::drivers::events::EventHandling;
use crate::instance::{Instance, Interface, Logger, Status, Version};

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    fmi3Version.as_ptr().cast()
}

/// What the three instantiation functions share: the name and token checked, the logger
/// kept. `None` (after logging why) when the instance cannot be made: also when
/// `interface` is the reason the FMU does not provide what is asked for.
///
/// # Safety
/// `instance_name` and `token` must be NULL or valid C strings.
unsafe fn new_instance(
    function: &str,
    interface: Result<Interface, String>,
    instance_name: fmi3String,
    token: fmi3String,
    environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
    logging_on: bool,
) -> Option<Instance> {
    let logger = log_message.map(|callback| Logger::Fmi3 {
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
        // Said whatever `loggingOn`: "If a null pointer is returned, then instantiation
        // failed. In that case, logMessage is called with detailed information about the
        // reason."
        if let Some(logger) = logger {
            let message = format!("{function}: {message}");
            logger.send(&name, Status::Error, "logStatusError", &message);
        }
        None
    };
    let interface = match interface {
        Ok(interface) => interface,
        Err(reason) => return fail(reason),
    };
    if name.as_bytes().iter().all(u8::is_ascii_whitespace) {
        return fail("instanceName must be a non-empty string".into());
    }
    let expected = instantiation_token();
    // SAFETY: non-null C string by the FMI contract.
    let given = (!token.is_null()).then(|| {
        unsafe { CStr::from_ptr(token) }
            .to_string_lossy()
            .into_owned()
    });
    if given.as_deref() != Some(expected) {
        return fail(format!(
            "instantiationToken {} does not match this binary's {expected}: modelDescription.xml \
             and binary are from different builds",
            given.as_deref().map_or("NULL".into(), shown_token)
        ));
    }
    Some(Instance::new(
        interface,
        Version::Fmi3,
        name,
        logger,
        logging_on,
    ))
}

/// A token as a message shows it: quoted, and cut short when it is longer than any token.
fn shown_token(token: &str) -> String {
    const SHOWN: usize = 80;
    match token.char_indices().nth(SHOWN) {
        None => format!("{token:?}"),
        Some((cut, _)) => format!("{:?}… ({} bytes)", &token[..cut], token.len()),
    }
}

fn into_handle(instance: Option<Instance>) -> fmi3Instance {
    instance.map_or(null_mut(), |i| Box::into_raw(Box::new(i)).cast())
}

/// # Safety
/// String arguments must be NULL or valid C strings.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    // SAFETY: FMI contract on the arguments, checked for NULL inside.
    catch_unwind(|| unsafe {
        into_handle(new_instance(
            "fmi3InstantiateModelExchange",
            Ok(Interface::ModelExchange),
            instanceName,
            instantiationToken,
            instanceEnvironment,
            logMessage,
            loggingOn,
        ))
    })
    .unwrap_or(null_mut())
}

/// # Safety
/// String arguments must be NULL or valid C strings; `requiredIntermediateVariables` must
/// hold `nRequiredIntermediateVariables` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    earlyReturnAllowed: fmi3Boolean,
    _requiredIntermediateVariables: *const fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    // SAFETY: FMI contract on the arguments, checked for NULL inside.
    catch_unwind(|| unsafe {
        let interface = match nRequiredIntermediateVariables {
            0 => Ok(Interface::CoSimulation),
            n => Err(format!(
                "nRequiredIntermediateVariables = {n}: this FMU provides no intermediate update \
                 (providesIntermediateUpdate is false)"
            )),
        };
        let mut instance = new_instance(
            "fmi3InstantiateCoSimulation",
            interface,
            instanceName,
            instantiationToken,
            instanceEnvironment,
            logMessage,
            loggingOn,
        );
        if let Some(instance) = instance.as_mut() {
            instance.handle_events(EventHandling {
                event_mode: eventModeUsed,
                early_return: earlyReturnAllowed,
            });
        }
        into_handle(instance)
    })
    .unwrap_or(null_mut())
}

/// # Safety
/// String arguments must be NULL or valid C strings.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _clockUpdate: fmi3ClockUpdateCallback,
    _lockPreemption: fmi3LockPreemptionCallback,
    _unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    // SAFETY: FMI contract on the arguments, checked for NULL inside.
    catch_unwind(|| unsafe {
        into_handle(new_instance(
            "fmi3InstantiateScheduledExecution",
            Err(
                "this FMU provides Model Exchange and Co-Simulation, not Scheduled Execution"
                    .into(),
            ),
            instanceName,
            instantiationToken,
            instanceEnvironment,
            logMessage,
            loggingOn,
        ))
    })
    .unwrap_or(null_mut())
}

/// # Safety
/// `instance` must be NULL or a pointer from an fmi3Instantiate function, not used
/// afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    // SAFETY: the master's obligation, as the function's.
    unsafe { abi::free_instance(instance) }
}

const _: () = {
    let _: fmi3GetVersionTYPE = Some(fmi3GetVersion);
    let _: fmi3InstantiateModelExchangeTYPE = Some(fmi3InstantiateModelExchange);
    let _: fmi3InstantiateCoSimulationTYPE = Some(fmi3InstantiateCoSimulation);
    let _: fmi3InstantiateScheduledExecutionTYPE = Some(fmi3InstantiateScheduledExecution);
    let _: fmi3FreeInstanceTYPE = Some(fmi3FreeInstance);
};
