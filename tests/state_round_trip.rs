//! A buffer the FMU serialized itself always deserializes, and restoring it gives back
//! exactly the state it was taken from: here the sequences where that once failed (a state
//! taken before initialisation after a start time other than 0); the fuzzer
//! (tests/fuzz_api.rs) checks the same round trip at random points of random sequences.

use std::ffi::c_char;
use std::ptr::null_mut;

mod common;

use cyclic_mechanism::fmi2::*;
use fmi_sys::fmi2::*;

const OK: fmi2Status = fmi2Status_fmi2OK;

/// The serialized form of the instance's current state.
unsafe fn serialized(c: fmi2Component) -> Vec<c_char> {
    let mut state: fmi2FMUstate = null_mut();
    let mut size = 0;
    unsafe {
        assert_eq!(fmi2GetFMUstate(c, &mut state), OK);
        assert_eq!(fmi2SerializedFMUstateSize(c, state, &mut size), OK);
        let mut bytes = vec![0 as c_char; size];
        assert_eq!(
            fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr(), size),
            OK
        );
        assert_eq!(fmi2FreeFMUstate(c, &mut state), OK);
        bytes
    }
}

/// Deserialize `bytes`, which must succeed, set the state, and check that it serializes
/// to the same bytes again.
unsafe fn restore(c: fmi2Component, bytes: &[c_char]) {
    let mut state: fmi2FMUstate = null_mut();
    unsafe {
        let status = fmi2DeSerializeFMUstate(c, bytes.as_ptr(), bytes.len(), &mut state);
        assert_eq!(status, OK, "a buffer the FMU wrote was refused");
        assert_eq!(fmi2SetFMUstate(c, state), OK);
        assert_eq!(fmi2FreeFMUstate(c, &mut state), OK);
        assert!(serialized(c) == bytes, "the restored state differs");
    }
}

#[test]
fn a_state_before_initialisation_at_any_start_time_round_trips() {
    for start in [1.0, -5.0, 1e300, -1e300, 5e-324] {
        for kind in [fmi2Type_fmi2CoSimulation, fmi2Type_fmi2ModelExchange] {
            let c = common::instantiate_as(c"start", kind);
            // SAFETY: a live instance; buffers and states are this test's own.
            unsafe {
                assert_eq!(fmi2SetupExperiment(c, 0, 0.0, start, 0, 0.0), OK);
                let instantiated = serialized(c);
                restore(c, &instantiated);
                assert_eq!(fmi2EnterInitializationMode(c), OK);
                let initialising = serialized(c);
                restore(c, &initialising);
                restore(c, &instantiated);
                assert_eq!(fmi2EnterInitializationMode(c), OK);
                assert_eq!(fmi2ExitInitializationMode(c), OK);
                let mut t = 0.0;
                assert_eq!(
                    fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut t),
                    if kind == fmi2Type_fmi2CoSimulation {
                        OK
                    } else {
                        fmi2Status_fmi2Error
                    }
                );
                if kind == fmi2Type_fmi2CoSimulation {
                    assert_eq!(t, start, "initialised at the start time");
                }
                fmi2FreeInstance(c);
            }
        }
    }
}

/// The sequence an outside harness found: set-ups ending at start 1e300, a state taken
/// in Instantiated, runs, terminations and restores of it, then its buffer deserialized.
#[test]
fn the_sequence_found_by_the_outside_harness_round_trips() {
    let c = common::instantiate(c"found");
    // SAFETY: a live instance; buffers and states are this test's own.
    unsafe {
        assert_eq!(fmi2SetupExperiment(c, 1, 1e-4, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2SetupExperiment(c, 1, 1e-6, 0.0, 1, 100.0), OK);
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 1e300, 1, 1e300), OK);
        let mut a: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut a), OK);
        let mut size = 0;
        assert_eq!(fmi2SerializedFMUstateSize(c, a, &mut size), OK);
        let mut buffer = vec![0 as c_char; size];
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 1e300, 0.01, 1), OK);
        assert_eq!(fmi2SerializeFMUstate(c, a, buffer.as_mut_ptr(), size), OK);
        assert_eq!(fmi2DoStep(c, 1e300, 0.1, 1), OK);
        assert_eq!(fmi2Terminate(c), OK);
        assert_eq!(fmi2SetFMUstate(c, a), OK);
        assert_eq!(fmi2SetupExperiment(c, 1, 1e-6, 0.0, 1, 1.0), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 0.0, 0.5, 1), OK);
        assert_eq!(fmi2Terminate(c), OK);
        assert_eq!(fmi2SetFMUstate(c, a), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 1e300, 0.01, 1), OK);
        restore(c, &buffer);
        assert_eq!(fmi2FreeFMUstate(c, &mut a), OK);
        fmi2FreeInstance(c);
    }
}
