// Each test crate uses part of this module.
#![allow(dead_code)]

//! Shared by the integration tests that drive the exported C functions directly.

use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

use cyclic_mechanism::fmi2::fmi2Instantiate;
use cyclic_mechanism::fmi2::model_description::guid;
use fmi_sys::fmi2::{fmi2CallbackFunctions, fmi2Component, fmi2Type_fmi2CoSimulation};

/// A co-simulation instance without callbacks (no logger: nothing is formatted). The FMU
/// keeps only the logger and environment from `functions`, so a temporary struct is fine.
pub fn instantiate(name: &CStr) -> fmi2Component {
    instantiate_as(name, fmi2Type_fmi2CoSimulation)
}

/// An instance of either interface (`fmi2Type_fmi2ModelExchange` or `…CoSimulation`).
pub fn instantiate_as(name: &CStr, kind: fmi_sys::fmi2::fmi2Type) -> fmi2Component {
    let functions = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: null_mut(),
    };
    let guid = CString::new(guid()).expect("the GUID has no NUL");
    // SAFETY: valid C strings and callbacks for the duration of the call.
    let c =
        unsafe { fmi2Instantiate(name.as_ptr(), kind, guid.as_ptr(), null(), &functions, 0, 0) };
    assert!(!c.is_null(), "fmi2Instantiate failed");
    c
}

/// Set up (tolerance, optional stop time), set parameters by name, and leave
/// initialisation mode, asserting every status.
pub fn initialise(c: fmi2Component, tolerance: f64, stop: Option<f64>, parameters: &[(&str, f64)]) {
    use cyclic_mechanism::fmi2::{
        fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2SetReal, fmi2SetupExperiment,
    };
    use cyclic_mechanism::variables::value_reference;
    use fmi_sys::fmi2::fmi2Status_fmi2OK as OK;
    let refs: Vec<u32> = parameters
        .iter()
        .map(|(n, _)| value_reference(n).expect("a known name"))
        .collect();
    let values: Vec<f64> = parameters.iter().map(|(_, v)| *v).collect();
    let (stop_defined, stop_time) = (stop.is_some() as i32, stop.unwrap_or(0.0));
    // SAFETY: `c` is a live instance; the arrays hold `refs.len()` elements.
    unsafe {
        assert_eq!(
            fmi2SetupExperiment(c, 1, tolerance, 0.0, stop_defined, stop_time),
            OK
        );
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(
            fmi2SetReal(c, refs.as_ptr(), refs.len(), values.as_ptr()),
            OK
        );
        assert_eq!(fmi2ExitInitializationMode(c), OK);
    }
}

/// The paper's built-in motor and load laws, [79] and [80] (docs/model.md §4), as (FMI
/// name, value) pairs: the published figures, set explicitly so that a test of case 1
/// does not depend on the defaults (which are these too).
pub fn paper_laws() -> [(&'static str, f64); 5] {
    [
        ("Mm_a0", 100.0),
        ("Mm_a1", -20.0),
        ("Mm_a2", -1.0),
        ("Mr_b0", 20.0),
        ("Mr_b1", -0.05),
    ]
}

/// A simulation without the FMI layer: `parameters` set by name, `solver` (1 auto,
/// 2 dop853, 3 implicit) and `tolerance`, initialised at t = 0.
pub fn simulation(
    parameters: &[(&str, f64)],
    solver: i32,
    tolerance: f64,
) -> cyclic_mechanism::simulation::Simulation {
    use cyclic_mechanism::simulation::{Simulation, Value};
    use cyclic_mechanism::variables::value_reference;
    let mut sim = Simulation::new();
    for (name, value) in parameters {
        sim.set(value_reference(name).unwrap(), Value::Real(*value), true)
            .unwrap();
    }
    sim.set(
        value_reference("solver").unwrap(),
        Value::Integer(solver),
        true,
    )
    .unwrap();
    sim.set_tolerance(tolerance).unwrap();
    sim.initialize(0.0).unwrap();
    sim
}

/// Advance `sim` from t = 0 to `t_end` in communication steps of `h`.
pub fn advance(sim: &mut cyclic_mechanism::simulation::Simulation, t_end: f64, h: f64) {
    for k in 1..=(t_end / h).round() as usize {
        sim.advance(k as f64 * h).unwrap();
    }
}
