//! Stiff springs and dampers: k12 = k34 = 1e7 N·m/rad, d12 = d34 = 1e3
//! N·m·s/rad with the paper's laws, 1 s at H = 1e-2, tolerance 1e-6. The implicit method
//! and `auto` against DOP853. Evaluation counts are deterministic, so the work ratio is a
//! test here, not a benchmark.

use common::Run as Simulation;
use cyclic_mechanism::plant::Value;
use cyclic_mechanism::variables::value_reference;

mod common;

const AUTO: i32 = 1;
const DOP853: i32 = 2;
const IMPLICIT: i32 = 3;
/// Stiff, damped couplings, and paper case 1's (undamped).
const STIFF: (f64, f64) = (1e7, 1e3);
const PAPER: (f64, f64) = (100.0, 0.0);

fn integer(sim: &Simulation, name: &str) -> i32 {
    match sim.get(value_reference(name).unwrap()).unwrap() {
        Value::Integer(v) => v,
        other => panic!("{name}: {other:?}"),
    }
}

/// Paper case 1's laws with `solver` = `kind`, stiffness `k` and damping `d` in both
/// couplings, run to `t_end` at communication step `h`.
fn run(kind: i32, (k, d): (f64, f64), tolerance: f64, t_end: f64, h: f64) -> Simulation {
    let couplings = [("k12", k), ("k34", k), ("d12", d), ("d34", d)];
    let parameters: Vec<_> = common::paper_laws().into_iter().chain(couplings).collect();
    let mut sim = common::simulation(&parameters, kind, tolerance);
    common::advance(&mut sim, t_end, h);
    sim
}

fn max_difference(a: &Simulation, b: &Simulation) -> f64 {
    let pairs = a.state().iter().zip(b.state());
    pairs.map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn auto_is_accurate_and_about_ten_times_cheaper_than_dop853_on_stiff_springs() {
    // The reference: DOP853 at 1e-12, a different method from the implicit one.
    let reference = run(DOP853, STIFF, 1e-12, 1.0, 1e-2);
    let explicit = run(DOP853, STIFF, 1e-6, 1.0, 1e-2);
    let auto = run(AUTO, STIFF, 1e-6, 1.0, 1e-2);
    let implicit = run(IMPLICIT, STIFF, 1e-6, 1.0, 1e-2);
    let work = |sim: &Simulation| integer(sim, "n_rhs");
    eprintln!(
        "n_rhs: dop853 {}, auto {}, implicit {}; errors {:e}, {:e}, {:e}",
        work(&explicit),
        work(&auto),
        work(&implicit),
        max_difference(&explicit, &reference),
        max_difference(&auto, &reference),
        max_difference(&implicit, &reference)
    );
    for sim in [&auto, &implicit] {
        assert!(max_difference(sim, &reference) <= 1e-8);
    }
    // DOP853 at its stability limit takes ten times the work, which is why `auto` switches.
    // Its error there is noise in the stiff modes that its error estimate does not see and
    // depends on the last bits of the arithmetic (1.7e-10 and 1.1e-7 from the 1e-12 run,
    // measured with two builds that differ only there), hence the loose bound.
    assert!(max_difference(&explicit, &reference) <= 1e-5);
    for sim in [&explicit, &auto, &implicit] {
        assert!(sim.state().iter().all(|v| v.is_finite()));
    }
    // Measured: 18 833 evaluations for DOP853, 1825 for auto, 1992 for the implicit method.
    assert!(10 * work(&auto) <= work(&explicit));
    assert!(9 * work(&implicit) <= work(&explicit));
    assert_eq!(integer(&auto, "active_solver"), IMPLICIT);
    assert_eq!(integer(&explicit, "active_solver"), DOP853);
}

#[test]
fn auto_keeps_dop853_on_the_paper_case_bit_for_bit() {
    // Not stiff: auto never leaves DOP853, so it is DOP853 exactly. At tolerance 1e-2
    // DOP853 is limited by stability in places, but at H = 1e-4 Radau IIA could not step
    // further than it: without the landing condition `auto` switches there (within the
    // 10 s; 204 229 evaluations against 1722 when measured).
    for (tolerance, h) in [(1e-8, 1e-2), (1e-2, 1e-4), (1e-2, 1e-2), (1e-2, 0.1)] {
        let auto = run(AUTO, PAPER, tolerance, 10.0, h);
        let explicit = run(DOP853, PAPER, tolerance, 10.0, h);
        assert_eq!(integer(&auto, "active_solver"), DOP853, "{tolerance} {h}");
        assert_eq!(auto.state(), explicit.state());
        assert_eq!(auto.statistics(), explicit.statistics());
    }
}

#[test]
fn implicit_method_matches_the_paper_case() {
    let reference = run(DOP853, PAPER, 1e-11, 2.0, 1e-2);
    let implicit = run(IMPLICIT, PAPER, 1e-8, 2.0, 1e-2);
    let error = max_difference(&implicit, &reference);
    assert!(error < 1e-6, "{error:e}");
    assert!(implicit.state().iter().all(|v| v.is_finite()));
}
