//! The simulation (without the FMI layer) against docs/model.md §4's published values.

use common::Run as Simulation;
use cyclic_mechanism::model::energy;
use cyclic_mechanism::plant::Value;
use cyclic_mechanism::variables::value_reference;

mod common;

fn set(sim: &mut Simulation, name: &str, value: f64) {
    sim.set(value_reference(name).unwrap(), Value::Real(value), true)
        .unwrap();
}

fn paper_case(k34: f64, tolerance: f64, step: f64) -> Simulation {
    let parameters: Vec<_> = common::paper_laws()
        .into_iter()
        .chain([("k34", k34)])
        .collect();
    let mut sim = common::simulation(&parameters, 1, tolerance);
    common::advance(&mut sim, 10.0, step);
    sim
}

#[test]
fn case_1_matches_spec_reference_at_ten_seconds() {
    // docs/model.md §4: independent solution at tolerance 1e-12, 8 decimals.
    let expected = [41.24994319, 41.25007318, 1.71429998, 1.60546713];
    let sim = paper_case(100.0, 1e-10, 1e-2);
    let y = sim.state();
    for i in 0..4 {
        assert!(
            (y[i] - expected[i]).abs() < 1e-7,
            "phi{}: {} vs {}",
            i + 1,
            y[i],
            expected[i]
        );
    }
    assert!((y[4] - 4.12779271).abs() < 1e-7, "omega1: {}", y[4]);
    assert_eq!(sim.time(), 10.0);
}

#[test]
fn communication_step_does_not_change_the_answer() {
    let coarse = paper_case(40.0, 1e-10, 0.5);
    let fine = paper_case(40.0, 1e-10, 1e-3);
    for (a, b) in coarse.state().iter().zip(fine.state()) {
        assert!((a - b).abs() < 1e-7, "{a} vs {b}");
    }
}

#[test]
fn free_run_conserves_energy() {
    let mut sim = Simulation::new();
    // No torques: the built-in laws off, the inputs at 0.
    let laws = value_reference("builtin_laws").unwrap();
    sim.set(laws, Value::Boolean(false), true).unwrap();
    set(&mut sim, "omega2_0", 6.0);
    set(&mut sim, "twist12_0", 0.2);
    set(&mut sim, "twist34_0", -0.1);
    sim.set_tolerance(1e-10);
    sim.initialize(0.0);
    let e0 = energy(sim.params(), sim.state());
    let mut worst: f64 = 0.0;
    for k in 1..=1000 {
        sim.advance(k as f64 * 0.1).unwrap();
        worst = worst.max((energy(sim.params(), sim.state()) - e0).abs() / e0);
    }
    assert!(worst < 1e-8, "relative energy drift {worst:e}");
}

#[test]
fn unchanged_inputs_cost_about_the_same_at_any_communication_step() {
    // with nothing changed between steps, outputs come from dense output.
    let fine = paper_case(100.0, 1e-8, 1e-3).statistics();
    let coarse = paper_case(100.0, 1e-8, 0.1).statistics();
    let ratio = fine.n_rhs as f64 / coarse.n_rhs as f64;
    assert!(
        ratio <= 1.5,
        "H = 1e-3 needs {ratio:.2} x the evaluations of H = 0.1: {fine:?} vs {coarse:?}"
    );
}

#[test]
fn only_an_input_change_that_matters_restarts_the_integrator() {
    // The motor's torque: the law's constant `law` plus the input M_m.
    let run_with = |law: f64, torque: &dyn Fn(usize) -> f64| {
        let mut sim = Simulation::new();
        set(&mut sim, "Mm_a0", law);
        sim.initialize(0.0);
        for k in 1..=1000 {
            sim.set(
                value_reference("M_m").unwrap(),
                Value::Real(torque(k)),
                false,
            )
            .unwrap();
            sim.advance(k as f64 * 1e-3).unwrap();
        }
        (sim.statistics().n_rhs, sim.state()[4])
    };
    let run = |torque: &dyn Fn(usize) -> f64| run_with(100.0, torque);
    let (held, omega_held) = run(&|_| 0.0);
    let (varying, _) = run(&|k| if k % 2 == 0 { 0.0 } else { 1e-3 });
    // Restarting on every doStep forces at least one step per doStep (at these short steps
    // RK4's: three stages and the error estimate's, the first stage carried over from the
    // last step's end); held inputs let the integrator take far fewer, longer steps.
    assert!(
        varying >= 4 * 1000,
        "a change that matters must restart: {varying} evaluations"
    );
    assert!(
        3 * held < varying,
        "held inputs must not restart: {held} vs {varying}"
    );
    // A master interpolating a held input: it flickers by an ulp around its value. The
    // law's constant is 0, so that the ulp is not lost in the sum of law and input.
    let flicker = |k: usize| match k % 3 {
        0 => 100.0,
        1 => f64::from_bits(100f64.to_bits() + 1),
        _ => f64::from_bits(100f64.to_bits() - 1),
    };
    let (steady, omega_steady) = run_with(0.0, &|_| 100.0);
    let (flickering, omega_flickering) = run_with(0.0, &flicker);
    assert!(
        flickering <= steady + steady / 10,
        "an ulp's change must not restart: {flickering} evaluations against {steady}"
    );
    // The default tolerance, 1e-8, in units of max(1, |omega1|).
    let scale = omega_steady.abs().max(1.0);
    assert!(
        (omega_flickering - omega_steady).abs() <= 1e-8 * scale,
        "omega1 {omega_flickering} against {omega_steady}"
    );
    let (baseline, omega_baseline) = {
        let mut sim = Simulation::new();
        set(&mut sim, "Mm_a0", 100.0);
        sim.initialize(0.0);
        for k in 1..=1000 {
            sim.advance(k as f64 * 1e-3).unwrap();
        }
        (sim.statistics().n_rhs, sim.state()[4])
    };
    assert_eq!(
        held, baseline,
        "setting an input to its current value must not restart"
    );
    assert_eq!(omega_held, omega_baseline);
}
