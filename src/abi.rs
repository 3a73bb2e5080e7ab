//! What the two C ABIs (`fmi2`, `fmi3`) share: the guard every function that takes an
//! instance runs through, and C arrays as slices.

use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::instance::state::{Belongs, Entry};
use crate::instance::{Failure, Instance, Outcome, Status};

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
            instance.fail_fatally();
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
/// Inlined into each export, where `function` is a constant and both checks fold to a test
/// of one mask; left to itself the compiler called it on every step and read.
#[inline(always)]
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
    if !function.allowed().contains(instance.state()) {
        return Err(Failure::error(format!(
            "not allowed in state {}",
            instance.state().describe(instance.version())
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

/// SetDebugLogging's category names, checked: none NULL, all UTF-8.
///
/// # Safety
/// `categories` must hold `n` pointers, each NULL or a NUL-terminated string.
pub(crate) unsafe fn category_names<'a>(
    categories: *const *const std::ffi::c_char,
    n: usize,
) -> Result<Vec<&'a str>, Failure> {
    // SAFETY: guaranteed by the caller.
    let pointers = unsafe { slice(categories, n) }.ok_or_else(|| null_argument("categories", n))?;
    pointers
        .iter()
        .map(|&pointer| {
            if pointer.is_null() {
                return Err(Failure::error("a category name is NULL"));
            }
            // SAFETY: non-null, NUL-terminated by the caller's guarantee.
            unsafe { std::ffi::CStr::from_ptr(pointer) }
                .to_str()
                .map_err(|_| Failure::error("a category name is not UTF-8"))
        })
        .collect()
}

/// FreeInstance of either version: NULL is no instance; a panic in a drop stays here.
///
/// # Safety
/// `instance` must be NULL or a pointer an instantiation function returned, not used
/// afterwards.
pub(crate) unsafe fn free_instance(instance: *mut c_void) {
    if !instance.is_null() {
        // SAFETY: created by Box::into_raw at instantiation; the master frees it once.
        let _ = catch_unwind(|| drop(unsafe { Box::from_raw(instance.cast::<Instance>()) }));
    }
}

pub(crate) fn null_argument(name: &str, n: usize) -> Failure {
    Failure::error(format!("{name} is NULL with {n} elements requested"))
}

/// The names one version gives the FMU state functions' arguments, for the messages.
pub(crate) struct StateNames {
    pub state: &'static str,
    pub size_function: &'static str,
}

/// GetFMUState: a new state in `*slot`, or the state `*slot` names overwritten.
///
/// # Safety
/// `slot` must be NULL or point to a writable pointer (NULL, or a state of `instance`).
pub(crate) unsafe fn get_fmu_state(
    instance: &mut Instance,
    slot: *mut *mut c_void,
    names: &StateNames,
) -> Outcome {
    // SAFETY: NULL or writable by the FMI contract.
    let slot = unsafe { slot.as_mut() }.ok_or_else(|| null_argument(names.state, 1))?;
    let saved = instance.save();
    if slot.is_null() {
        *slot = instance.issue_state(saved).cast();
    } else {
        // A non-NULL entry is a state to overwrite.
        *instance.issued_state(*slot)? = saved;
    }
    Ok(())
}

/// FreeFMUState: the state `*slot` names freed and `*slot` set to NULL; NULL is no state.
///
/// # Safety
/// `slot` must be NULL or point to a writable pointer.
pub(crate) unsafe fn free_fmu_state(instance: &mut Instance, slot: *mut *mut c_void) -> Outcome {
    // SAFETY: NULL or writable by the FMI contract.
    let Some(slot) = (unsafe { slot.as_mut() }) else {
        return Ok(());
    };
    if !slot.is_null() {
        instance.free_state(*slot)?;
        *slot = std::ptr::null_mut();
    }
    Ok(())
}

/// SerializedFMUStateSize.
///
/// # Safety
/// `size` must be NULL or writable.
pub(crate) unsafe fn serialized_size(
    instance: &mut Instance,
    state: *mut c_void,
    size: *mut usize,
) -> Outcome {
    let length = instance.issued_state(state)?.serialize().len();
    // SAFETY: NULL or writable by the FMI contract.
    *unsafe { size.as_mut() }.ok_or_else(|| null_argument("size", 1))? = length;
    Ok(())
}

/// SerializeFMUState into `buffer` of `size` bytes.
///
/// # Safety
/// `buffer` must hold `size` writable bytes.
pub(crate) unsafe fn serialize(
    instance: &mut Instance,
    state: *mut c_void,
    buffer: *mut u8,
    size: usize,
    names: &StateNames,
) -> Outcome {
    let bytes = instance.issued_state(state)?.serialize();
    if size < bytes.len() {
        return Err(Failure::error(format!(
            "size = {size} is too small: the state needs {} bytes ({})",
            bytes.len(),
            names.size_function
        )));
    }
    // SAFETY: FMI contract on the buffer.
    let target =
        unsafe { slice_mut(buffer, size) }.ok_or_else(|| null_argument("serializedState", size))?;
    target[..bytes.len()].copy_from_slice(&bytes);
    Ok(())
}

/// DeserializeFMUState from `buffer` into a new state in `*slot`, or the state `*slot`
/// names.
///
/// # Safety
/// `buffer` must hold `size` readable bytes; `slot` must be NULL or point to a writable
/// pointer (NULL, or a state of `instance`).
pub(crate) unsafe fn deserialize(
    instance: &mut Instance,
    buffer: *const u8,
    size: usize,
    slot: *mut *mut c_void,
    names: &StateNames,
) -> Outcome {
    // SAFETY: FMI contract on the buffer.
    let bytes =
        unsafe { slice(buffer, size) }.ok_or_else(|| null_argument("serializedState", size))?;
    let restored = crate::instance::FmuState::deserialize(bytes)?;
    // SAFETY: NULL or writable by the FMI contract.
    let slot = unsafe { slot.as_mut() }.ok_or_else(|| null_argument(names.state, 1))?;
    if slot.is_null() {
        *slot = instance.issue_state(restored).cast();
    } else {
        *instance.issued_state(*slot)? = restored;
    }
    Ok(())
}
