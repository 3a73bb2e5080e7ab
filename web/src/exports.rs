//! The module's functions, for JavaScript: numbers in, numbers out, and text (the variables'
//! JSON, the last error) left in the module's memory for the page to read by pointer and
//! length. A status of 0 is success; 1 is a refusal, whose reason [`mechanism_message`]
//! points at.
//!
//! One session per module: a page that wants two instantiates the module twice.

use std::cell::RefCell;

use crate::session::{self, Session, Stepped};

thread_local! {
    static SESSION: RefCell<Session> = RefCell::new(Session::new());
    /// The text a caller reads next: the variables' JSON, or the last refusal's reason.
    static MESSAGE: RefCell<String> = const { RefCell::new(String::new()) };
}

fn status(result: Result<(), String>) -> i32 {
    match result {
        Ok(()) => 0,
        Err(reason) => {
            MESSAGE.with_borrow_mut(|m| *m = reason);
            1
        }
    }
}

/// A new session: every variable at its start value, not started.
#[no_mangle]
pub extern "C" fn mechanism_reset() {
    SESSION.with_borrow_mut(|s| *s = Session::new());
}

/// Set variable `vr` ([`Session::set`]).
#[no_mangle]
pub extern "C" fn mechanism_set(vr: u32, value: f64) -> i32 {
    status(SESSION.with_borrow_mut(|s| s.set(vr, value)))
}

/// Start the run ([`Session::start`]); a `stop` that is not finite sets none.
#[no_mangle]
pub extern "C" fn mechanism_start(tolerance: f64, start: f64, stop: f64) -> i32 {
    status(SESSION.with_borrow_mut(|s| s.start(tolerance, start, stop)))
}

/// One step ([`Session::step`]): 0 plain, 2 over a change point, 1 refused.
#[no_mangle]
pub extern "C" fn mechanism_step(current: f64, step: f64) -> i32 {
    match SESSION.with_borrow_mut(|s| s.step(current, step)) {
        Ok(Stepped::Plain) => 0,
        Ok(Stepped::OverChangePoint) => 2,
        Err(reason) => status(Err(reason)),
    }
}

/// The value of variable `vr`; for a reference the table does not have, 0 with the reason
/// in the message and a status of 1 from [`mechanism_get_status`].
#[no_mangle]
pub extern "C" fn mechanism_get(vr: u32) -> f64 {
    match SESSION.with_borrow(|s| s.get(vr)) {
        Ok(x) => {
            LAST_GET.set(0);
            x
        }
        Err(reason) => {
            LAST_GET.set(status(Err(reason)));
            0.0
        }
    }
}

thread_local! {
    static LAST_GET: std::cell::Cell<i32> = const { std::cell::Cell::new(0) };
}

/// The status of the last [`mechanism_get`].
#[no_mangle]
pub extern "C" fn mechanism_get_status() -> i32 {
    LAST_GET.get()
}

/// The run's time.
#[no_mangle]
pub extern "C" fn mechanism_time() -> f64 {
    SESSION.with_borrow(Session::time)
}

/// Change points crossed since the start.
#[no_mangle]
pub extern "C" fn mechanism_crossings() -> u32 {
    SESSION.with_borrow(|s| s.crossings().0)
}

/// When the last change point was met; not a number when none was.
#[no_mangle]
pub extern "C" fn mechanism_last_crossing() -> f64 {
    SESSION.with_borrow(|s| s.crossings().1.unwrap_or(f64::NAN))
}

/// Put the variables' JSON ([`session::variables_json`]) in the message.
#[no_mangle]
pub extern "C" fn mechanism_describe() {
    MESSAGE.with_borrow_mut(|m| *m = session::variables_json());
}

/// Where the message's UTF-8 bytes start in the module's memory; valid until the next call.
#[no_mangle]
pub extern "C" fn mechanism_message() -> *const u8 {
    MESSAGE.with_borrow(|m| m.as_ptr())
}

/// The message's length in bytes.
#[no_mangle]
pub extern "C" fn mechanism_message_length() -> usize {
    MESSAGE.with_borrow(String::len)
}
