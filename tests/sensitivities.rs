//! The FMU's parameter sensitivities (docs/sensitivities.md) through the FMI 2.0 C
//! interface, as a master reads them: against central differences of whole runs made at a
//! far tighter tolerance, at every communication point.

use std::ffi::CString;

use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::model::PARAMETERS;
use cyclic_mechanism::variables::value_reference;
use fmi_sys::fmi2::{fmi2Component, fmi2Status_fmi2OK as OK};

mod common;

const STATES: [&str; 8] = [
    "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
];

/// Paper case 1 with damping, so that the dampers have sensitivities.
fn case() -> Vec<(&'static str, f64)> {
    let mut p: Vec<_> = common::paper_laws().into();
    p.extend([("d12", 0.5), ("d34", 0.5), ("c4", 0.2), ("omega1_0", 1.0)]);
    p
}

fn vr(name: &str) -> u32 {
    value_reference(name).unwrap_or_else(|| panic!("{name}"))
}

/// Start an instance with `parameters` and sensitivity slots for `slots`.
fn start(parameters: &[(&str, f64)], slots: &[&str], tolerance: f64) -> fmi2Component {
    let name = CString::new("sensitivities").unwrap();
    let c = common::instantiate(&name);
    let refs: Vec<u32> = parameters.iter().map(|(n, _)| vr(n)).collect();
    let values: Vec<f64> = parameters.iter().map(|(_, v)| *v).collect();
    let slot_refs: Vec<u32> = (1..=slots.len())
        .map(|k| vr(&format!("sensitivity_{k}.parameter")))
        .collect();
    let items: Vec<i32> = slots
        .iter()
        .map(|s| 1 + PARAMETERS.iter().position(|p| p.name == *s).unwrap() as i32)
        .collect();
    // SAFETY: `c` is live; every array holds as many elements as passed.
    unsafe {
        assert_eq!(fmi2SetupExperiment(c, 1, tolerance, 0.0, 1, 10.0), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(
            fmi2SetReal(c, refs.as_ptr(), refs.len(), values.as_ptr()),
            OK
        );
        assert_eq!(
            fmi2SetInteger(c, slot_refs.as_ptr(), slot_refs.len(), items.as_ptr()),
            OK
        );
        assert_eq!(fmi2ExitInitializationMode(c), OK);
    }
    c
}

fn read(c: fmi2Component, names: &[String]) -> Vec<f64> {
    let refs: Vec<u32> = names.iter().map(|n| vr(n)).collect();
    let mut values = vec![0.0; refs.len()];
    // SAFETY: as above.
    assert_eq!(
        unsafe { fmi2GetReal(c, refs.as_ptr(), refs.len(), values.as_mut_ptr()) },
        OK
    );
    values
}

/// How a run moves: its communication step, and the motor torque input the master holds
/// over each step (from the step's start time), if it sets one.
#[derive(Clone, Copy)]
struct Drive {
    h: f64,
    motor_torque: Option<fn(f64) -> f64>,
}

const fn steps(h: f64) -> Drive {
    Drive {
        h,
        motor_torque: None,
    }
}

/// `names` at t = 0, h, 2h, … 10 s.
fn run(c: fmi2Component, names: &[String], drive: Drive) -> Vec<Vec<f64>> {
    let Drive { h, motor_torque } = drive;
    let n = (10.0 / h).round() as usize;
    let mut rows = vec![read(c, names)];
    let input = vr("M_m");
    for k in 0..n {
        let t = k as f64 * h;
        if let Some(torque) = motor_torque {
            // SAFETY: as above; one element.
            assert_eq!(unsafe { fmi2SetReal(c, &input, 1, &torque(t)) }, OK);
        }
        // SAFETY: as above.
        assert_eq!(unsafe { fmi2DoStep(c, t, h, 1) }, OK, "step {k}");
        rows.push(read(c, names));
    }
    // SAFETY: as above.
    unsafe { fmi2FreeInstance(c) };
    rows
}

fn states() -> Vec<String> {
    STATES.iter().map(|s| s.to_string()).collect()
}

/// The states along a run with `name` moved by `delta`, at tolerance 1e-13.
fn moved(name: &str, delta: f64, drive: Drive) -> Vec<Vec<f64>> {
    let mut parameters = case();
    match parameters.iter_mut().find(|(n, _)| *n == name) {
        Some(entry) => entry.1 += delta,
        None => {
            let default = PARAMETERS.iter().find(|p| p.name == name).unwrap().default;
            parameters.push((name, default + delta));
        }
    }
    run(start(&parameters, &[], 1e-13), &states(), drive)
}

/// ∂(states)/∂`name` by central differences of whole runs with steps δ and 2δ, combined
/// (Richardson) so that their truncation error, O(δ²), cancels: a plain central difference
/// is itself off by more than the sensitivities for some parameters (its error shrinks
/// with δ², which shows it is the difference's, not the sensitivities').
fn reference(name: &str, delta: f64, drive: Drive) -> Vec<Vec<f64>> {
    let central = |d: f64| -> Vec<Vec<f64>> {
        let (up, down) = (moved(name, d, drive), moved(name, -d, drive));
        up.iter()
            .zip(&down)
            .map(|(u, w)| u.iter().zip(w).map(|(a, b)| (a - b) / (2.0 * d)).collect())
            .collect()
    };
    let (fine, coarse) = (central(delta), central(2.0 * delta));
    fine.iter()
        .zip(&coarse)
        .map(|(f, c)| f.iter().zip(c).map(|(a, b)| (4.0 * a - b) / 3.0).collect())
        .collect()
}

#[test]
fn the_paper_fits_parameters_sensitivities_agree_with_central_differences() {
    agree_with_differences(&["k12", "k34", "d12", "d34", "J2"], steps(0.05));
}

#[test]
fn start_values_laws_and_other_inertias_agree_with_central_differences() {
    agree_with_differences(&["omega1_0", "phi2_0", "J1", "c4", "Mm_a1"], steps(0.05));
}

/// A master that changes an input at every communication point restarts the integration
/// there: the sensitivities go on from their value at that point.
#[test]
fn sensitivities_agree_with_central_differences_under_a_changing_input() {
    let drive = Drive {
        h: 0.05,
        motor_torque: Some(|t| 8.0 * (1.3 * t).sin()),
    };
    agree_with_differences(&["k12", "d34", "J2", "omega1_0"], drive);
}

/// At every communication point of 10 s driven by `drive`, tolerance 1e-10, every state's
/// sensitivity within 1e-6 of the largest difference quotient of that state.
fn agree_with_differences(slots: &[&str], drive: Drive) {
    let names: Vec<String> = (1..=slots.len())
        .flat_map(|k| STATES.iter().map(move |s| format!("sensitivity_{k}.{s}")))
        .collect();
    let sensitivities = run(start(&case(), slots, 1e-10), &names, drive);
    for (j, parameter) in slots.iter().enumerate() {
        let value = case()
            .iter()
            .find(|(n, _)| n == parameter)
            .map(|p| p.1)
            .unwrap_or_else(|| {
                PARAMETERS
                    .iter()
                    .find(|p| p.name == *parameter)
                    .unwrap()
                    .default
            });
        let delta = 1e-4 * value.abs().max(0.1);
        let differences = reference(parameter, delta, drive);
        let mut worst: f64 = 0.0;
        for i in 0..STATES.len() {
            let scale = differences
                .iter()
                .map(|row| row[i].abs())
                .fold(0.0, f64::max);
            for (row, fd) in sensitivities.iter().zip(&differences) {
                let error = (row[j * STATES.len() + i] - fd[i]).abs() / scale.max(1e-12);
                worst = worst.max(error);
            }
        }
        println!("{parameter}: worst |S - FD| / max|FD| = {worst:.2e}");
        assert!(worst <= 1e-6, "{parameter}: {worst:e}");
    }
}

/// Asking for sensitivities changes no output: they are integrated beside the run.
#[test]
fn the_states_are_the_same_bits_with_sensitivities_on() {
    let (plain, with) = (
        run(start(&case(), &[], 1e-10), &states(), steps(0.01)),
        run(
            start(&case(), &["k12", "J3"], 1e-10),
            &states(),
            steps(0.01),
        ),
    );
    assert_eq!(plain, with);
}

fn set_slot(c: fmi2Component, slot: usize, value: i32) -> fmi_sys::fmi2::fmi2Status {
    let r = vr(&format!("sensitivity_{slot}.parameter"));
    // SAFETY: `c` is live; one element.
    unsafe { fmi2SetInteger(c, &r, 1, &value) }
}

#[test]
fn a_slot_refuses_a_length_and_an_unknown_value_but_not_a_parameter_followed_twice() {
    let name = CString::new("refusals").unwrap();
    let c = common::instantiate(&name);
    // SAFETY: `c` is live.
    unsafe { assert_eq!(fmi2EnterInitializationMode(c), OK) };
    let index = |n: &str| 1 + PARAMETERS.iter().position(|p| p.name == n).unwrap() as i32;
    assert_ne!(set_slot(c, 1, index("L")), OK);
    assert_ne!(set_slot(c, 1, 99), OK);
    assert_eq!(set_slot(c, 1, index("k12")), OK);
    // Judged on its own value: two slots may follow one parameter, in any order.
    assert_eq!(set_slot(c, 2, index("k12")), OK);
    assert_eq!(set_slot(c, 2, index("k34")), OK);
    // SAFETY: as above.
    unsafe {
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        // Fixed: not after initialisation.
        assert_ne!(set_slot(c, 3, index("J1")), OK);
        fmi2FreeInstance(c);
    }
}

#[test]
fn model_exchange_refuses_a_slot_at_its_set_and_initialises() {
    let name = CString::new("exchange").unwrap();
    let c = common::instantiate_as(&name, fmi_sys::fmi2::fmi2Type_fmi2ModelExchange);
    // SAFETY: `c` is live.
    unsafe {
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_ne!(set_slot(c, 1, 5), OK);
        assert_eq!(set_slot(c, 1, 0), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        fmi2FreeInstance(c);
    }
}

/// A serialized FMU state holds the sensitivities' run: restored into a new instance, it
/// goes on bit for bit as the original.
#[test]
fn a_serialized_state_carries_the_sensitivities_on() {
    let names: Vec<String> = STATES
        .iter()
        .map(|s| format!("sensitivity_2.{s}"))
        .collect();
    let c = start(&case(), &["k12", "d34"], 1e-10);
    let step = |c: fmi2Component, from: f64| {
        // SAFETY: `c` is live.
        assert_eq!(unsafe { fmi2DoStep(c, from, 0.25, 1) }, OK);
    };
    for k in 0..4 {
        step(c, k as f64 * 0.25);
    }
    let mut bytes = Vec::new();
    // SAFETY: `c` is live; the buffers are sized by the FMU's answers.
    unsafe {
        let mut state = std::ptr::null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut state), OK);
        let mut size = 0;
        assert_eq!(fmi2SerializedFMUstateSize(c, state, &mut size), OK);
        bytes.resize(size, 0);
        assert_eq!(
            fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr().cast(), size),
            OK
        );
        assert_eq!(fmi2FreeFMUstate(c, &mut state), OK);
    }
    let copy = start(&case(), &["k12", "d34"], 1e-10);
    // SAFETY: as above.
    unsafe {
        let mut state = std::ptr::null_mut();
        assert_eq!(
            fmi2DeSerializeFMUstate(copy, bytes.as_ptr().cast(), bytes.len(), &mut state),
            OK
        );
        assert_eq!(fmi2SetFMUstate(copy, state), OK);
        assert_eq!(fmi2FreeFMUstate(copy, &mut state), OK);
    }
    for k in 4..8 {
        step(c, k as f64 * 0.25);
        step(copy, k as f64 * 0.25);
        assert_eq!(read(c, &names), read(copy, &names), "step {k}");
    }
    assert!(read(c, &names).iter().any(|v| *v != 0.0));
    // SAFETY: both live.
    unsafe {
        fmi2FreeInstance(c);
        fmi2FreeInstance(copy);
    }
}
