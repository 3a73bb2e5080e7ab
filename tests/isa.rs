//! fmi2DoStep runs the step through a copy compiled with AVX where the processor has it
//! (src/drivers/isa.rs); `CoSimulation::advance` called from here is the baseline build. Both
//! must give the same bits at every communication point, with the same work.

use cyclic_mechanism::fmi2::{fmi2DoStep, fmi2FreeInstance, fmi2GetInteger, fmi2GetReal};
use cyclic_mechanism::variables::value_reference;
use fmi_sys::fmi2::fmi2Status_fmi2OK as OK;

mod common;

const STATES: [&str; 8] = [
    "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
];

/// Every communication point's state, as bits, and the evaluation count: through the C
/// ABI, and through the simulation directly.
fn both_ways(parameters: &[(&str, f64)], tolerance: f64, h: f64, t_end: f64) {
    let steps = (t_end / h).round() as usize;
    let refs: Vec<u32> = STATES.iter().map(|n| value_reference(n).unwrap()).collect();
    let c = common::instantiate(c"isa");
    common::initialise(c, tolerance, None, parameters);
    let mut sim = common::simulation(parameters, 1, tolerance);
    let mut values = [0.0; 8];
    for k in 0..steps {
        let t = k as f64 * h;
        // SAFETY: `c` is live; `refs` and `values` hold eight elements.
        unsafe {
            assert_eq!(fmi2DoStep(c, t, h, 1), OK);
            assert_eq!(fmi2GetReal(c, refs.as_ptr(), 8, values.as_mut_ptr()), OK);
        }
        // fmi2DoStep's target is t + h, which need not be (k + 1)·h.
        sim.advance(t + h).unwrap();
        for (i, (a, b)) in values.iter().zip(sim.state()).enumerate() {
            assert!(
                a.to_bits() == b.to_bits(),
                "{} at t = {}: {a:e} through fmi2DoStep, {b:e} directly",
                STATES[i],
                t + h
            );
        }
    }
    let mut n_rhs = 0;
    // SAFETY: `c` is live and freed once.
    unsafe {
        let vr = value_reference("n_rhs").unwrap();
        assert_eq!(fmi2GetInteger(c, &vr, 1, &mut n_rhs), OK);
        fmi2FreeInstance(c);
    }
    assert_eq!(n_rhs as u64, sim.statistics().n_rhs);
}

#[test]
fn the_vector_copy_gives_the_baseline_bits() {
    #[cfg(target_arch = "x86_64")]
    eprintln!("AVX: {}", std::arch::is_x86_feature_detected!("avx"));
    let case1 = common::paper_laws();
    for (tolerance, h) in [(1e-4, 0.1), (1e-6, 0.01), (1e-10, 0.01)] {
        both_ways(&case1, tolerance, h, 10.0);
    }
    // Stiff couplings: `auto` moves to the implicit method and back.
    let stiff: Vec<_> = case1
        .into_iter()
        .chain([("k12", 1e7), ("k34", 1e7), ("d12", 1e3), ("d34", 1e3)])
        .collect();
    both_ways(&stiff, 1e-6, 0.01, 1.0);
}
