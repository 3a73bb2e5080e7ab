//! Shared by the integration tests that drive the exported C functions directly.

use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

use cyclic_mechanism::fmi2::fmi2Instantiate;
use cyclic_mechanism::fmi2::model_description::guid;
use fmi_sys::fmi2::{fmi2CallbackFunctions, fmi2Component, fmi2Type_fmi2CoSimulation};

/// A co-simulation instance without callbacks (no logger: nothing is formatted). The FMU
/// keeps only the logger and environment from `functions`, so a temporary struct is fine.
pub fn instantiate(name: &CStr) -> fmi2Component {
    let functions = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: null_mut(),
    };
    let guid = CString::new(guid()).expect("the GUID has no NUL");
    // SAFETY: valid C strings and callbacks for the duration of the call.
    let c = unsafe {
        fmi2Instantiate(
            name.as_ptr(),
            fmi2Type_fmi2CoSimulation,
            guid.as_ptr(),
            null(),
            &functions,
            0,
            0,
        )
    };
    assert!(!c.is_null(), "fmi2Instantiate failed");
    c
}
