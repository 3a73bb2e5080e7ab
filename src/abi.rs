//! What the two C ABIs (`fmi2`, `fmi3`) share: the guard every function that takes an
//! instance runs through, and C arrays as slices.

use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::instance::state::{Belongs, Entry};
use crate::instance::{Failure, Instance, Outcome, State, Status};

/// Run `body` on the instance behind `c` if `function` belongs to its interface and the
/// state machine allows it now; log and map its failure to a status; turn a panic into
/// Fatal (no panic crosses the C boundary).
pub(crate) fn guarded(
    c: *mut c_void,
    function: impl Entry,
    body: impl FnOnce(&mut Instance) -> Outcome,
) -> Status {
    // SAFETY: a non-null instance is a pointer returned by this FMU's instantiation and
    // not yet freed (the master's obligation); FMI never shares instances between threads.
    let Some(instance) = (unsafe { c.cast::<Instance>().as_mut() }) else {
        return Status::Error;
    };
    let name = function.name();
    if instance.log_enabled(crate::instance::Category::Calls) {
        instance.log(Status::Ok, crate::instance::Category::Calls, name);
    }
    if let Err(failure) = admitted(instance, function) {
        instance.report(&failure, name);
        return failure.status;
    }
    match catch_unwind(AssertUnwindSafe(|| body(instance))) {
        Ok(Ok(())) => Status::Ok,
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
                status: Status::Fatal,
                message: format!("internal error: {what}"),
            };
            instance.report(&failure, name);
            Status::Fatal
        }
    }
}

/// Whether `function` may be called on `instance` now: its interface, then its state.
fn admitted(instance: &Instance, function: impl Entry) -> Outcome {
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
            instance.current.state.describe(instance.version())
        )));
    }
    Ok(())
}

/// A C array as a slice; `None` for a null pointer with a non-zero length.
///
/// # Safety
/// A non-null `ptr` must point to `n` valid elements that outlive the slice.
pub(crate) unsafe fn slice<'a, T>(ptr: *const T, n: usize) -> Option<&'a [T]> {
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
pub(crate) unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize) -> Option<&'a mut [T]> {
    match (n, ptr.is_null()) {
        (0, _) => Some(&mut []),
        (_, true) => None,
        // SAFETY: guaranteed by the caller.
        _ => Some(unsafe { std::slice::from_raw_parts_mut(ptr, n) }),
    }
}

pub(crate) fn null_argument(name: &str, n: usize) -> Failure {
    Failure::error(format!("{name} is NULL with {n} elements requested"))
}
