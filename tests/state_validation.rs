//! A serialized FMU state is checked by value, not only by its checksum: a buffer whose
//! numbers were changed and whose checksum was recomputed restores only if every value is
//! one the FMU could have reached (finite, within the rules, on the constraint), and then
//! every output stays finite.

use std::ffi::c_char;
use std::ptr::null_mut;

mod common;

use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::variables::{value_reference, variables, Causality, VarType};
use fmi_sys::fmi2::*;
use integrators::bytes::fnv1a_64;

const HEADER: usize = cyclic_mechanism::instance::STATE_HEADER;

/// Paper case 1 run to t = 1 s; its serialized state.
fn running_instance() -> (fmi2Component, Vec<u8>) {
    let c = common::instantiate(c"state");
    common::initialise(c, 1e-8, None, &common::paper_laws());
    let mut t = 0.0;
    // SAFETY: a live instance; the state and buffers are this test's own.
    unsafe {
        for _ in 0..100 {
            assert_eq!(fmi2DoStep(c, t, 0.01, 1), fmi2Status_fmi2OK);
            t += 0.01;
        }
    }
    (c, serialized(c))
}

/// The instance's state, serialized.
fn serialized(c: fmi2Component) -> Vec<u8> {
    // SAFETY: a live instance; the state and buffer are this test's own.
    unsafe {
        let mut state: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut state), fmi2Status_fmi2OK);
        let mut size = 0;
        assert_eq!(
            fmi2SerializedFMUstateSize(c, state, &mut size),
            fmi2Status_fmi2OK
        );
        let mut bytes = vec![0 as c_char; size];
        assert_eq!(
            fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr(), size),
            fmi2Status_fmi2OK
        );
        fmi2FreeFMUstate(c, &mut state);
        bytes.iter().map(|b| *b as u8).collect()
    }
}

/// Deserialize `bytes` and set the instance to it; false when refused.
fn set_state(c: fmi2Component, bytes: &[u8]) -> bool {
    // SAFETY: a live instance; the buffer and state are this test's own.
    unsafe {
        let mut state: fmi2FMUstate = null_mut();
        let chars: Vec<c_char> = bytes.iter().map(|b| *b as c_char).collect();
        if fmi2DeSerializeFMUstate(c, chars.as_ptr(), chars.len(), &mut state) != fmi2Status_fmi2OK
        {
            return false;
        }
        assert_eq!(fmi2SetFMUstate(c, state), fmi2Status_fmi2OK);
        fmi2FreeFMUstate(c, &mut state);
        true
    }
}

fn with_checksum(mut bytes: Vec<u8>) -> Vec<u8> {
    let end = bytes.len() - 8;
    let sum = fnv1a_64(&bytes[HEADER..end]);
    bytes[end..].copy_from_slice(&sum.to_le_bytes());
    bytes
}

/// Restore `bytes` into `c`: None when refused, else every Real output after the
/// restore and after one more step.
fn restore(c: fmi2Component, bytes: &[u8]) -> Option<Vec<f64>> {
    let real: Vec<u32> = variables()
        .filter(|(_, v)| v.var_type() == VarType::Real && v.causality() == Causality::Output)
        .map(|(vr, _)| vr)
        .collect();
    let mut values = vec![0.0; real.len()];
    if !set_state(c, bytes) {
        return None;
    }
    // SAFETY: a live instance, buffers of the stated sizes.
    unsafe {
        let mut seen = Vec::new();
        let mut read = |values: &mut Vec<f64>| {
            let s = fmi2GetReal(c, real.as_ptr(), real.len(), values.as_mut_ptr());
            // A refused read shows as NaN, which no comparison below accepts.
            seen.extend(
                values
                    .iter()
                    .map(|v| if s == fmi2Status_fmi2OK { *v } else { f64::NAN }),
            );
        };
        read(&mut values);
        let mut t = 0.0;
        fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut t);
        if fmi2DoStep(c, t, 0.01, 1) == fmi2Status_fmi2OK {
            read(&mut values);
        } else {
            seen.push(f64::NAN);
        }
        Some(seen)
    }
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn a_forged_state_restores_only_if_it_runs_like_the_original() {
    let (c, bytes) = running_instance();
    let original = restore(c, &bytes).expect("the untouched state restores");
    let (mut restored, mut identical) = (0, 0);
    for at in HEADER..bytes.len() - 16 {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut forged = bytes.clone();
            forged[at..at + 8].copy_from_slice(&bad.to_le_bytes());
            if let Some(values) = restore(c, &with_checksum(forged)) {
                // What restores is a state the FMU could have reached: here, changes that
                // cannot alter the run (step counters, scratch stages recomputed before
                // use, start values already used) or that alter it below the tolerance (a
                // subnormal damper or input derivative, which restarts the integrator).
                let worst = values
                    .iter()
                    .zip(&original)
                    .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
                    .fold(0.0, f64::max);
                assert!(
                    worst <= 1e-7,
                    "offset {at}: a forgery restored and moved the run by {worst:e}"
                );
                identical += (bits(&values) == bits(&original)) as usize;
                restored += 1;
            }
        }
    }
    let forgeries = 3 * (bytes.len() - 16 - HEADER);
    eprintln!("{restored} of {forgeries} forgeries restored, {identical} of them with the original's results bit for bit");
    assert!(restored * 5 < forgeries);
    unsafe { fmi2FreeInstance(c) };
}

/// The payload offset of the first f64 equal to `value`.
fn offset_of(bytes: &[u8], value: f64) -> usize {
    let pattern = value.to_le_bytes();
    (HEADER..bytes.len() - 8)
        .find(|&at| bytes[at..at + 8] == pattern)
        .expect("the value is in the state")
}

fn read(c: fmi2Component, name: &str) -> f64 {
    let vr = value_reference(name).unwrap();
    let mut v = 0.0;
    unsafe { assert_eq!(fmi2GetReal(c, &vr, 1, &mut v), fmi2Status_fmi2OK) };
    v
}

#[test]
fn a_state_off_the_constraint_or_out_of_range_is_refused() {
    let (c, bytes) = running_instance();
    let forge = |value: f64, new: f64| {
        let mut forged = bytes.clone();
        let at = offset_of(&bytes, value);
        forged[at..at + 8].copy_from_slice(&new.to_le_bytes());
        restore(c, &with_checksum(forged))
    };
    let (phi2, omega3) = (read(c, "phi2"), read(c, "omega3"));
    assert_eq!(
        forge(phi2, phi2 + 0.1),
        None,
        "positions that do not close the loop"
    );
    assert_eq!(
        forge(omega3, omega3 * 1.5 + 1.0),
        None,
        "velocities that break the constraint"
    );
    assert_eq!(forge(0.5, -0.5), None, "J1 < 0");
    assert_eq!(forge(0.5, 1e300), None, "J1 beyond its range");
    assert_eq!(
        forge(100.0, 1e300),
        None,
        "a law coefficient beyond its range"
    );
    // A parameter within its rules, but not the one the stored steps were taken with.
    assert_eq!(
        forge(20.0, 25.0),
        None,
        "the load law changed under the integrator's memory"
    );
    unsafe { fmi2FreeInstance(c) };
}

/// A master that sets M_m before every step of 1 ms, as a coupled one does: the FMU takes
/// short steps, each starting from the last one's f shifted to the new torque (the
/// carried stage, part of the state). Restored, the run goes on bit for bit, at four
/// evaluations for some steps (a step without the carried stage costs five); with any f64
/// of the payload forged (NaN, ±inf), the state is refused or runs like the original.
#[test]
fn a_state_mid_coupled_run_round_trips_and_refuses_forgeries() {
    let c = common::instantiate(c"coupled");
    // The DC-motor example's mechanism: the motor (here a torque signal) replaces the law.
    let example = [
        ("Mm_a0", 0.0),
        ("Mm_a1", 0.0),
        ("Mm_a2", 0.0),
        ("Mr_b0", 20.0),
        ("Mr_b1", -0.05),
        ("c4", 0.5),
        ("d34", 1.0),
    ];
    common::initialise(c, 1e-8, None, &example);
    let torque = value_reference("M_m").unwrap();
    let reals: Vec<u32> = ["phi1", "phi2", "omega1", "omega3", "rod_force"]
        .iter()
        .map(|n| value_reference(n).unwrap())
        .collect();
    let rhs = value_reference("n_rhs").unwrap();
    // Steps k0..k1, each after a new torque: every Real read and the evaluations per
    // step, as bits; None when a step fails.
    let run = |c: fmi2Component, (k0, k1): (usize, usize)| -> Option<(Vec<u64>, Vec<i32>)> {
        let (mut seen, mut costs, mut values, mut count) =
            (Vec::new(), Vec::new(), vec![0.0; 5], 0);
        // SAFETY: a live instance, buffers of the stated sizes.
        unsafe {
            fmi2GetInteger(c, &rhs, 1, &mut count);
            for k in k0..k1 {
                let m = 40.0 + 5.0 * (k as f64 * 0.37).sin();
                if fmi2SetReal(c, &torque, 1, &m) != fmi2Status_fmi2OK
                    || fmi2DoStep(c, k as f64 * 1e-3, 1e-3, 1) != fmi2Status_fmi2OK
                    || fmi2GetReal(c, reals.as_ptr(), 5, values.as_mut_ptr()) != fmi2Status_fmi2OK
                {
                    return None;
                }
                seen.extend(bits(&values));
                let before = count;
                fmi2GetInteger(c, &rhs, 1, &mut count);
                costs.push(count - before);
            }
        }
        Some((seen, costs))
    };
    run(c, (0, 100)).expect("the coupled run");
    let bytes = serialized(c);
    let (original, costs) = run(c, (100, 110)).unwrap();
    assert!(
        costs.contains(&4),
        "no step started from a carried stage: {costs:?}"
    );
    assert!(set_state(c, &bytes));
    assert_eq!(run(c, (100, 110)), Some((original.clone(), costs)));
    for at in HEADER..bytes.len() - 16 {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut forged = bytes.clone();
            forged[at..at + 8].copy_from_slice(&bad.to_le_bytes());
            if !set_state(c, &with_checksum(forged)) {
                continue;
            }
            let (values, _) = run(c, (100, 110)).expect("a restored forgery runs");
            let worst = values
                .iter()
                .zip(&original)
                .map(|(a, b)| {
                    let (a, b) = (f64::from_bits(*a), f64::from_bits(*b));
                    (a - b).abs() / b.abs().max(1.0)
                })
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-7,
                "offset {at}: a forgery restored and moved the run by {worst:e}"
            );
        }
    }
    // The carried stage ends the payload: f (8 numbers), then the inputs it was evaluated
    // with (2), before the checksum. Any finite change to one of them is refused.
    let carried = bytes.len() - 8 - 10 * 8;
    for slot in 0..10 {
        let at = carried + 8 * slot;
        let value = f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        let mut forged = bytes.clone();
        forged[at..at + 8].copy_from_slice(&(value * (1.0 + 1e-12) + 1e-9).to_le_bytes());
        assert!(
            !set_state(c, &with_checksum(forged)),
            "a carried stage changed in slot {slot} was restored"
        );
    }
    unsafe { fmi2FreeInstance(c) };
}
