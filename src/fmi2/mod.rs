//! The FMI 2.0 C ABI, Co-Simulation and Model Exchange: every function of `fmi2Functions.h`,
//! with the official types of `fmi-sys`. This module and its three function files hold the
//! crate's only `unsafe` code: they turn C pointers into safe calls on [`Instance`].
//!
//! Every function that takes an instance is declared once with [`export!`]: its C name, its
//! arguments, the header's type it must match (checked at compile time) and its body. The C
//! name is also its [`Function`], whose states the standard allows are written once in
//! [`state_machine`]. [`guarded`] enforces them and catches every panic, so that none
//! crosses the C boundary (a panic makes the call return fmi2Fatal with a log message).
//!
//! - [`common`]: instantiation, set-up, values, FMU states, directional derivatives;
//! - [`cosimulation`]: input and output derivatives, the step and its status;
//! - [`model_exchange`]: event and continuous-time modes, states, derivatives, indicators.

// The exported functions keep the argument names of fmi2Functions.h.
#![allow(non_snake_case)]

pub mod common;
pub mod cosimulation;
pub mod fmu_state;
pub mod instance;
pub mod isa;
pub mod model_description;
pub mod model_exchange;
pub mod state_machine;

pub use common::*;
pub use cosimulation::*;
pub use model_exchange::*;

use std::panic::{catch_unwind, AssertUnwindSafe};

use fmi_sys::fmi2::*;

use instance::{Failure, Instance, Outcome};
use state_machine::{Belongs, Function, State};

/// Declare an exported function that takes an instance: `fn NAME(c, ARG: TYPE, ...):
/// HEADER_TYPE = |instance| BODY;`. The function runs `BODY` through [`guarded`] as the
/// [`Function`] of the same name, and the build fails unless its type is `HEADER_TYPE`.
macro_rules! export {
    ($(#[$attr:meta])* fn $name:ident($c:ident $(, $arg:ident: $ty:ty)* $(,)?): $check:ident = $body:expr;) => {
        $(#[$attr])*
        #[no_mangle]
        pub unsafe extern "C" fn $name($c: fmi2Component $(, $arg: $ty)*) -> fmi2Status {
            $crate::fmi2::guarded($c, $crate::fmi2::state_machine::Function::$name, $body)
        }

        const _: () = {
            let _: $check = Some($name);
        };
    };
}
pub(crate) use export;

/// Run `body` on the instance behind `c` if `function` belongs to its interface and the
/// state machine allows it now; log and map its failure to a status; turn a panic into
/// fmi2Fatal.
pub(crate) fn guarded(
    c: fmi2Component,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Outcome,
) -> fmi2Status {
    // SAFETY: a non-null component is a pointer returned by fmi2Instantiate and not yet
    // freed (the master's obligation); instances are never shared between threads by FMI.
    let Some(instance) = (unsafe { c.cast::<Instance>().as_mut() }) else {
        return fmi2Status_fmi2Error;
    };
    let name = function.name();
    if instance.log_enabled(instance::Category::Calls) {
        instance.log(fmi2Status_fmi2OK, instance::Category::Calls, name);
    }
    if let Err(failure) = admitted(instance, function) {
        instance.report(&failure, name);
        return failure.status;
    }
    match catch_unwind(AssertUnwindSafe(|| body(instance))) {
        Ok(Ok(())) => fmi2Status_fmi2OK,
        Ok(Err(failure)) => {
            instance.report(&failure, name);
            failure.status
        }
        Err(panic) => {
            instance.current.state = State::Fatal;
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let failure = Failure {
                status: fmi2Status_fmi2Fatal,
                message: format!("internal error: {what}"),
            };
            instance.report(&failure, name);
            fmi2Status_fmi2Fatal
        }
    }
}

/// Whether `function` may be called on `instance` now: its interface, then its state.
fn admitted(instance: &Instance, function: Function) -> Outcome {
    if let Belongs::Only(interface) = function.belongs() {
        if interface != instance.interface() {
            return Err(Failure::error(format!(
                "a {} function, and this instance was instantiated for {}",
                interface.name(),
                instance.interface().name()
            )));
        }
    }
    if !function.allowed().contains(instance.current.state) {
        return Err(Failure::error(format!(
            "not allowed in state {}",
            instance.current.state.describe()
        )));
    }
    Ok(())
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
