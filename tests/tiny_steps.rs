//! Legal communication steps shorter than the integrator can resolve (down to 1e-300 s)
//! advance time and return fmi2OK, at the start and in the middle of a run, with and
//! without a stop time; the outputs after them stay on the trajectory.

mod common;

use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::variables::value_reference;
use fmi_sys::fmi2::*;

const TINY: [f64; 5] = [1e-300, 1e-20, 1e-15, 8.88e-16, 5e-324];

fn time(c: fmi2Component) -> f64 {
    let mut t = 0.0;
    unsafe { fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut t) };
    t
}

fn omega1(c: fmi2Component) -> f64 {
    let vr = value_reference("omega1").unwrap();
    let mut v = 0.0;
    unsafe { assert_eq!(fmi2GetReal(c, &vr, 1, &mut v), fmi2Status_fmi2OK) };
    v
}

/// Tiny steps at t = `at`, then on to 2 s: every step OK, the result that of a run
/// without them to within the tolerance.
fn run(at: f64, stop: Option<f64>) {
    let c = common::instantiate(c"tiny");
    let plain = common::instantiate(c"plain");
    for instance in [c, plain] {
        common::initialise(instance, 1e-10, stop, &common::paper_laws());
    }
    unsafe {
        let mut t = 0.0;
        while t < at - 1e-12 {
            assert_eq!(fmi2DoStep(c, t, 0.25, 1), fmi2Status_fmi2OK);
            t += 0.25;
        }
        for h in TINY {
            let before = time(c);
            assert_eq!(
                fmi2DoStep(c, before, h, 1),
                fmi2Status_fmi2OK,
                "h = {h:e} at t = {before}"
            );
            assert_eq!(time(c), before + h, "h = {h:e}: time advances by the step");
            assert!(omega1(c).is_finite());
        }
        let t = time(c);
        assert_eq!(fmi2DoStep(c, t, 2.0 - t, 1), fmi2Status_fmi2OK);
        assert_eq!(fmi2DoStep(plain, 0.0, 2.0, 1), fmi2Status_fmi2OK);
        let (a, b) = (omega1(c), omega1(plain));
        assert!((a - b).abs() <= 1e-7 * b.abs(), "omega1 {a} against {b}");
        fmi2FreeInstance(c);
        fmi2FreeInstance(plain);
    }
}

#[test]
fn tiny_steps_at_the_start() {
    run(0.0, None);
    run(0.0, Some(2.0));
}

#[test]
fn tiny_steps_in_the_middle() {
    run(1.0, None);
    run(1.0, Some(2.0));
}

/// A geometry at the very limit of assembly (L = l3 + |O3 A2| with the defaults: l2 + L =
/// l + l3, a change-point geometry starting at its change point), and one ulp short of
/// it, is refused at initialisation with the reason, not at the first step.
#[test]
fn the_limit_of_assembly_is_refused_at_initialisation() {
    use cyclic_mechanism::model::{initial_state, Parameters};
    let at_limit: f64 = 0.5 + (0.5 - 0.05);
    for length in [at_limit, f64::from_bits(at_limit.to_bits() - 1)] {
        let p = Parameters {
            L: length,
            ..Default::default()
        };
        let error = initial_state(&p)
            .expect_err("refused at initialisation")
            .to_string();
        assert!(
            error.contains("change point") && error.contains("l2 + L"),
            "{error}"
        );
    }
}
