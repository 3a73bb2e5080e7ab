//! The FMI 3.0 C ABI, Co-Simulation and Model Exchange: every function of `fmi3Functions.h`,
//! with the official types of `fmi-sys`, over the same [`crate::instance::Instance`] as FMI
//! 2.0. Like `fmi2`, every function that takes an instance is declared once with
//! [`export!`] (C name, arguments, the header's type checked at compile time, body), and
//! its C name is its [`state_machine::Function`], with the states the standard allows.
//!
//! Value references are FMI 2.0's plus one, `time` being 0 ([`model_description`]); the
//! functions here translate them, check each variable's FMI 3.0 type, and refuse by name
//! what the FMU does not have (the other integer and float widths, strings, binaries,
//! clocks, structural parameters, scheduled execution).
//!
//! - [`common`]: instantiation, modes, values, FMU states, directional and adjoint
//!   derivatives, discrete states, the refused families;
//! - [`cosimulation`]: the step (with early return at change points), step mode, output
//!   derivatives;
//! - [`model_exchange`]: continuous-time mode, states, derivatives, indicators, nominals.

// The exported functions keep the argument names of fmi3Functions.h.
#![allow(non_snake_case)]

pub mod common;
pub mod cosimulation;
pub mod instantiation;
pub mod model_description;
pub mod model_exchange;
pub mod state_machine;

pub use common::*;
pub use cosimulation::*;
pub use instantiation::*;
pub use model_exchange::*;

use crate::abi::null_argument;
use crate::instance::Failure;
use crate::variables::{variable, VarType, Variable};

/// Declare an exported function that takes an instance: `fn NAME(instance, ARG: TYPE, ...):
/// HEADER_TYPE = |instance| BODY;`. The function runs `BODY` through [`crate::abi::guarded`]
/// as the [`state_machine::Function`] of the same name, and the build fails unless its type
/// is `HEADER_TYPE`.
macro_rules! export {
    ($(#[$attr:meta])* fn $name:ident($c:ident $(, $arg:ident: $ty:ty)* $(,)?): $check:ident = $body:expr;) => {
        $(#[$attr])*
        #[no_mangle]
        pub unsafe extern "C" fn $name($c: fmi_sys::fmi3::fmi3Instance $(, $arg: $ty)*)
            -> fmi_sys::fmi3::fmi3Status {
            $crate::abi::guarded($c, $crate::fmi3::state_machine::Function::$name, $body)
                as fmi_sys::fmi3::fmi3Status
        }

        const _: () = {
            let _: $check = Some($name);
        };
    };
}
pub(crate) use export;

/// The FMI 3.0 types of this FMU's variables, as the accessor functions name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accessor {
    Float64,
    Int32,
    /// Enumerations are read and written as Int64 in FMI 3.0.
    Int64,
    Boolean,
}

impl Accessor {
    fn of(v: &Variable) -> Accessor {
        match v.var_type() {
            VarType::Real => Accessor::Float64,
            VarType::Integer => Accessor::Int32,
            VarType::Enumeration => Accessor::Int64,
            VarType::Boolean => Accessor::Boolean,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Accessor::Float64 => "Float64",
            Accessor::Int32 => "Int32",
            Accessor::Int64 => "Int64",
            Accessor::Boolean => "Boolean",
        }
    }
}

/// The variable table's reference of FMI 3.0 reference `vr`, whose type must be
/// `accessor`'s; `None` for `time` (0), which only Float64 getters may name.
pub fn table_reference(vr: u32, accessor: Accessor) -> Result<Option<u32>, Failure> {
    let Some(table) = vr.checked_sub(1) else {
        return Ok(None);
    };
    let var = variable(table)
        .ok_or_else(|| Failure::error(format!("no variable has value reference {vr}")))?;
    let own = Accessor::of(var);
    if own != accessor {
        let what = if var.var_type() == VarType::Enumeration {
            "an Enumeration (read and written as Int64)".to_string()
        } else {
            format!("of type {}", own.name())
        };
        let (name, own) = (var.name, own.name());
        return Err(Failure::error(format!(
            "{name} (value reference {vr}) is {what}: use fmi3Get{own}/fmi3Set{own}"
        )));
    }
    Ok(Some(table))
}

/// The table references of `vrs` for a setter or any function but a Float64 getter, all
/// checked before the first is given (`time` is refused), and given without a buffer.
pub fn table_references(
    vrs: &[u32],
    accessor: Accessor,
) -> Result<impl Iterator<Item = u32> + Clone + '_, Failure> {
    for &vr in vrs {
        if table_reference(vr, accessor)?.is_none() {
            return Err(Failure::error(
                "time (value reference 0) is the independent variable: Model Exchange sets it \
                 with fmi3SetTime, Co-Simulation advances it with fmi3DoStep",
            ));
        }
    }
    // Checked above: none is 0.
    Ok(vrs.iter().map(|vr| vr - 1))
}

/// FMI 3.0 passes the number of values beside the number of value references; with no
/// array variables both must be equal.
fn check_value_count(nvr: usize, n_values: usize) -> Result<(), Failure> {
    if nvr != n_values {
        return Err(Failure::error(format!(
            "nValues = {n_values} must equal nValueReferences = {nvr}: this FMU has no array \
             variables"
        )));
    }
    Ok(())
}

/// A value-reference array as a slice.
///
/// # Safety
/// As [`crate::abi::slice`].
unsafe fn references<'a>(vr: *const u32, nvr: usize) -> Result<&'a [u32], Failure> {
    // SAFETY: guaranteed by the caller.
    unsafe { crate::abi::slice(vr, nvr) }.ok_or_else(|| null_argument("valueReferences", nvr))
}
