//! The Integer twins of the Enumeration parameters, for masters that cannot set
//! Enumerations: 0 leaves the choice to the Enumeration, any item's value decides,
//! whichever of the two was set last.

use std::ffi::CString;

use cyclic_mechanism::drivers::events::EventHandling;
use cyclic_mechanism::instance::{Instance, Interface, Version};
use cyclic_mechanism::plant::Value;
use cyclic_mechanism::variables::value_reference;

fn vr(name: &str) -> u32 {
    value_reference(name).unwrap_or_else(|| panic!("no variable {name}"))
}

/// An initialised FMI 3.0 Co-Simulation instance, with event mode and without early
/// return (a change point is crossed within the step, onto the branch chosen), `settings`
/// set in that order before initialisation.
fn initialised(settings: &[(&str, Value)]) -> Instance {
    let name = CString::new("twins").expect("no NUL");
    let mut fmu = Instance::new(Interface::CoSimulation, Version::Fmi3, name, None, false);
    fmu.handle_events(EventHandling {
        event_mode: true,
        early_return: false,
    });
    fmu.setup_experiment(None, 0.0, None).expect("a start");
    for &(name, value) in settings {
        fmu.set_values([(vr(name), value)].into_iter())
            .unwrap_or_else(|e| panic!("{name}: {}", e.message));
    }
    fmu.enter_initialization_mode().expect("initialisation");
    fmu.exit_initialization_mode().expect("initialised");
    fmu
}

/// A run of 6 s in steps of 0.01 s; the values of `read` at its end.
fn run(settings: &[(&str, Value)], read: &[&str]) -> Vec<f64> {
    let mut fmu = initialised(settings);
    for k in 0..600 {
        fmu.step_with_events(f64::from(k) * 0.01, 0.01)
            .expect("a step");
    }
    let vrs: Vec<u32> = read.iter().map(|n| vr(n)).collect();
    let mut values = vec![0.0; vrs.len()];
    fmu.get_real(&vrs, &mut values).expect("outputs");
    values
}

/// The method integrating after a step of 0.1 s.
fn active_solver(settings: &[(&str, Value)]) -> i32 {
    let mut fmu = initialised(settings);
    fmu.step_with_events(0.0, 0.1).expect("a step");
    let mut active = [0];
    fmu.get_integer(&[vr("active_solver")], &mut active)
        .expect("read");
    active[0]
}

const DOP853: Value = Value::Integer(2);
const IMPLICIT: Value = Value::Integer(3);
const NONE: Value = Value::Integer(0);

#[test]
fn a_twin_other_than_zero_chooses_the_method_whatever_the_order() {
    assert_eq!(active_solver(&[("solver", DOP853)]), 2);
    assert_eq!(active_solver(&[("solver_code", IMPLICIT)]), 3);
    assert_eq!(
        active_solver(&[("solver", DOP853), ("solver_code", IMPLICIT)]),
        3
    );
    assert_eq!(
        active_solver(&[("solver_code", IMPLICIT), ("solver", DOP853)]),
        3
    );
    // 0, a master setting every start value: the Enumeration decides.
    assert_eq!(
        active_solver(&[("solver", IMPLICIT), ("solver_code", NONE)]),
        3
    );
    assert_eq!(
        active_solver(&[("solver", DOP853), ("solver_code", NONE)]),
        2
    );
}

#[test]
fn the_branch_twin_turns_a_change_point_linkage_as_the_enumeration_does() {
    let parallelogram = [
        ("l", Value::Real(0.5)),
        ("l2", Value::Real(0.5)),
        ("l3", Value::Real(0.5)),
        ("L", Value::Real(0.5)),
        ("phi2_0", Value::Real(1.0)),
        ("omega2_0", Value::Real(3.0)),
        ("builtin_laws", Value::Boolean(false)),
    ];
    let read = ["phi2", "phi3", "omega3"];
    let with = |extra: &[(&str, Value)]| {
        let settings: Vec<(&str, Value)> = parallelogram.iter().chain(extra).copied().collect();
        run(&settings, &read)
    };
    let turn = with(&[("change_point_branch", Value::Integer(2))]);
    let straight = with(&[]);
    assert_ne!(turn, straight, "the branch changes nothing here");
    let by_twin = with(&[
        ("change_point_branch_code", Value::Integer(2)),
        ("change_point_branch", Value::Integer(1)),
    ]);
    assert_eq!(by_twin, turn);
}

#[test]
fn a_slot_twin_follows_its_parameter_as_the_slot_does() {
    let read = ["sensitivity_1.phi3", "sensitivity_1.omega2"];
    let by_slot = run(&[("sensitivity_1.parameter", Value::Integer(6))], &read);
    let by_twin = run(
        &[("sensitivity_1.parameter_code", Value::Integer(6))],
        &read,
    );
    assert!(by_slot[0] != 0.0);
    assert_eq!(by_twin, by_slot);
}

#[test]
fn a_twin_out_of_its_items_and_a_slot_twin_in_model_exchange_are_refused_by_name() {
    let name = CString::new("twins").expect("no NUL");
    let mut fmu = Instance::new(Interface::CoSimulation, Version::Fmi2, name, None, false);
    for (twin, bad) in [
        ("solver_code", 4),
        ("change_point_branch_code", 3),
        ("sensitivity_2.parameter_code", 10),
    ] {
        let refused = fmu.set_values([(vr(twin), Value::Integer(bad))].into_iter());
        let message = refused.expect_err("refused").message;
        assert!(message.starts_with(&format!("{twin} = {bad}")), "{message}");
    }
    let name = CString::new("exchange").expect("no NUL");
    let mut me = Instance::new(Interface::ModelExchange, Version::Fmi2, name, None, false);
    let refused =
        me.set_values([(vr("sensitivity_1.parameter_code"), Value::Integer(6))].into_iter());
    assert!(refused
        .expect_err("refused")
        .message
        .contains("Model Exchange"));
}
