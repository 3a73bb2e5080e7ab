//! The master's logger, as either version hands it over: FMI 2.0's takes the instance name
//! and a format string, FMI 3.0's the message as it is.

use std::ffi::{c_void, CString};

use super::status::Status;

type Fmi2Callback = unsafe extern "C" fn(
    *mut c_void,
    *const std::ffi::c_char,
    fmi_sys::fmi2::fmi2Status,
    *const std::ffi::c_char,
    *const std::ffi::c_char,
    ...
);

type Fmi3Callback = unsafe extern "C" fn(
    *mut c_void,
    fmi_sys::fmi3::fmi3Status,
    *const std::ffi::c_char,
    *const std::ffi::c_char,
);

/// A master's logger callback with the environment pointer it wants back.
#[derive(Clone, Copy)]
pub enum Logger {
    Fmi2 {
        callback: Fmi2Callback,
        environment: *mut c_void,
    },
    Fmi3 {
        callback: Fmi3Callback,
        environment: *mut c_void,
    },
}

// The statuses are passed as numbers both standards define alike.
const _: () = {
    assert!(Status::Discard as u32 == fmi_sys::fmi2::fmi2Status_fmi2Discard);
    assert!(Status::Fatal as u32 == fmi_sys::fmi2::fmi2Status_fmi2Fatal);
    assert!(Status::Discard as u32 == fmi_sys::fmi3::fmi3Status_fmi3Discard);
    assert!(Status::Fatal as u32 == fmi_sys::fmi3::fmi3Status_fmi3Fatal);
};

impl Logger {
    /// Send one message. FMI 2.0's callback takes it as a format string: `%` and `#` are
    /// escaped there (FMI 2.0 gives both a meaning), so masters that format it and masters
    /// that print it as it is both show it readably. FMI 3.0 gives `#` alone a meaning (a
    /// value reference between two, a literal one written `##`).
    pub fn send(&self, name: &CString, status: Status, category: &str, message: &str) {
        let text = match self {
            Logger::Fmi2 { .. } => message.replace('%', "%%").replace('#', "##"),
            Logger::Fmi3 { .. } => message.replace('#', "##"),
        };
        let (Ok(category), Ok(text)) = (
            CString::new(category),
            CString::new(text.replace('\0', " ")),
        ) else {
            return;
        };
        match *self {
            // SAFETY: the master supplied `callback` for this purpose; every pointer passed
            // is a valid NUL-terminated string that outlives the call, and no variadic
            // arguments are read because the escaped message has no conversion
            // specification.
            Logger::Fmi2 {
                callback,
                environment,
            } => unsafe {
                callback(
                    environment,
                    name.as_ptr(),
                    status as u32,
                    category.as_ptr(),
                    text.as_ptr(),
                )
            },
            // SAFETY: as above; FMI 3.0's callback takes the message as it is.
            Logger::Fmi3 {
                callback,
                environment,
            } => unsafe { callback(environment, status as u32, category.as_ptr(), text.as_ptr()) },
        }
    }
}
