//! The FMI 2.0 C ABI, Co-Simulation and Model Exchange: every function of `fmi2Functions.h`,
//! with the official types of `fmi-sys`. Its `unsafe` code turns C pointers into safe calls
//! on [`crate::instance::Instance`] (the crate's other `unsafe` is in `fmi3`, `abi` and the
//! instance's logger and FMU state handles and the drivers' AVX copy, as ARCHITECTURE.md lists).
//!
//! Every function that takes an instance is declared once with [`export!`]: its C name, its
//! arguments, the header's type it must match (checked at compile time) and its body. The C
//! name is also its [`state_machine::Function`], whose states the standard allows are written once in
//! [`state_machine`]. [`crate::abi::guarded`] enforces them and catches every panic, so that none
//! crosses the C boundary (a panic makes the call return fmi2Fatal with a log message).
//!
//! - [`common`]: instantiation, set-up, values, FMU states, directional derivatives;
//! - [`cosimulation`]: input and output derivatives, the step and its status;
//! - [`model_exchange`]: event and continuous-time modes, states, derivatives, indicators.

// The exported functions keep the argument names of fmi2Functions.h.
#![allow(non_snake_case)]

pub mod common;
pub mod cosimulation;
pub mod model_description;
pub mod model_exchange;
pub mod state_machine;

pub use common::*;
pub use cosimulation::*;
pub use model_exchange::*;

pub(crate) use crate::abi::{null_argument, slice, slice_mut};

/// Declare an exported function that takes an instance: `fn NAME(c, ARG: TYPE, ...):
/// HEADER_TYPE = |instance| BODY;`. The function runs `BODY` through [`crate::abi::guarded`] as the
/// [`state_machine::Function`] of the same name, and the build fails unless its type is `HEADER_TYPE`.
macro_rules! export {
    ($(#[$attr:meta])* fn $name:ident($c:ident $(, $arg:ident: $ty:ty)* $(,)?): $check:ident = $body:expr;) => {
        $(#[$attr])*
        #[no_mangle]
        pub unsafe extern "C" fn $name($c: fmi_sys::fmi2::fmi2Component $(, $arg: $ty)*)
            -> fmi_sys::fmi2::fmi2Status {
            $crate::abi::guarded($c, $crate::fmi2::state_machine::Function::$name, $body)
                as fmi_sys::fmi2::fmi2Status
        }

        const _: () = {
            let _: $check = Some($name);
        };
    };
}
pub(crate) use export;
