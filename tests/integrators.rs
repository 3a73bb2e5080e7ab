//! One conformance suite for every integration method behind the `Stepper` trait (DOP853 and
//! Radau IIA): accuracy on a problem with a known solution, exact landing on a target and
//! never passing a limit, dense output inside the last step and its convergence with the
//! tolerance, a restored method continuing bit for bit, and no allocation per step.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use integrators::bytes::{Reader, Writer};
use integrators::{Dop853, OdeSystem, Radau5, Rk4, Stepper, Tolerances};

/// Counts this thread's allocations while `COUNTING` is set.
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: every call is forwarded to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.with(|a| a.set(a.get() + 1));
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Harmonic oscillator y'' = −y: from (1, 0), exact solution (cos t, −sin t).
struct Oscillator;
impl OdeSystem<2> for Oscillator {
    fn rhs(&self, _t: f64, y: &[f64; 2], dy: &mut [f64; 2]) {
        *dy = [y[1], -y[0]];
    }
}

/// y' = y·cos t: exact solution exp(sin t); non-autonomous, so it checks the nodes.
struct Forced;
impl OdeSystem<1> for Forced {
    fn rhs(&self, t: f64, y: &[f64; 1], dy: &mut [f64; 1]) {
        dy[0] = y[0] * t.cos();
    }
}

fn tol(rtol: f64) -> Tolerances {
    Tolerances { rtol, atol: rtol }
}

fn oscillator_error(t: f64, y: &[f64; 2]) -> f64 {
    (y[0] - t.cos()).abs().max((y[1] + t.sin()).abs())
}

/// The error at t = 10 follows the tolerance: within 100 × rtol, and falling with it.
fn accuracy<S: Stepper<2>>() {
    let mut previous = f64::INFINITY;
    for rtol in [1e-4, 1e-7, 1e-10] {
        let mut method = S::new(tol(rtol));
        let (mut t, mut y) = (0.0, [1.0, 0.0]);
        method
            .integrate(&Oscillator, &mut t, &mut y, 10.0, 10.0)
            .unwrap();
        assert_eq!(t, 10.0);
        let error = oscillator_error(t, &y);
        assert!(error < 100.0 * rtol, "rtol {rtol}: error {error:e}");
        assert!(error < previous / 10.0, "rtol {rtol}: error {error:e}");
        previous = error;
    }
}

/// With the limit at the target the method ends exactly there, at every one of many
/// points; with the limit beyond, it may pass the target but never the limit.
fn exact_landing<S: Stepper<1>>() {
    let mut method = S::new(tol(1e-10));
    let (mut t, mut y) = (0.0, [1.0]);
    for k in 1..=1000 {
        let t_end = k as f64 * 7e-3;
        method
            .integrate(&Forced, &mut t, &mut y, t_end, t_end)
            .unwrap();
        assert_eq!(t, t_end);
    }
    assert!((y[0] - 7f64.sin().exp()).abs() < 1e-8, "{}", y[0]);
    let mut method = S::new(tol(1e-6));
    let (mut t, mut y) = (0.0, [1.0]);
    method
        .integrate(&Forced, &mut t, &mut y, 0.25, 0.3)
        .unwrap();
    assert!((0.25..=0.3).contains(&t), "{t}");
    method.integrate(&Forced, &mut t, &mut y, 0.3, 0.3).unwrap();
    assert_eq!(t, 0.3);
}

/// The largest error of the dense output at 99 points inside each last step, over
/// communication points every 0.25 s to t = 5.
fn dense_output_error<S: Stepper<2>>(rtol: f64) -> f64 {
    let mut method = S::new(tol(rtol));
    let (mut t, mut y) = (0.0, [1.0, 0.0]);
    let (mut worst, mut inside): (f64, usize) = (0.0, 0);
    for k in 1..=20 {
        let previous = t;
        let target = k as f64 * 0.25;
        method
            .integrate(&Oscillator, &mut t, &mut y, target, f64::INFINITY)
            .unwrap();
        assert!(t >= target);
        for j in 1..100 {
            let at_time = previous + j as f64 * 0.01 * (t - previous);
            if let Some(at) = method.dense_output(&Oscillator, at_time) {
                inside += 1;
                worst = worst.max(oscillator_error(at_time, &at));
            }
        }
    }
    assert!(inside >= 20, "{inside} points inside the last steps");
    let end = method.dense_output(&Oscillator, t).unwrap();
    assert!((end[0] - y[0]).abs() < 1e-14 && (end[1] - y[1]).abs() < 1e-14);
    assert!(method.dense_output(&Oscillator, t + 1.0).is_none());
    method.invalidate();
    assert!(method.dense_output(&Oscillator, t).is_none());
    worst
}

/// Dense output inside the step is accurate to the tolerance's order and converges with
/// it: a thousand times tighter gives at least a hundred times smaller errors.
fn dense_output<S: Stepper<2>>() {
    let loose = dense_output_error::<S>(1e-6);
    let tight = dense_output_error::<S>(1e-9);
    assert!(loose < 1e-4, "dense output error {loose:e} at rtol 1e-6");
    assert!(tight < loose / 100.0, "{tight:e} at 1e-9 against {loose:e}");
}

/// A method serialized mid-run and read back passes its own memory check and continues
/// exactly as the original, with the same statistics.
fn restore_bit_for_bit<S: Stepper<2>>() {
    let mut method = S::new(tol(1e-8));
    let (mut t, mut y) = (0.0, [1.0, 0.0]);
    method
        .integrate(&Oscillator, &mut t, &mut y, 3.0, f64::INFINITY)
        .unwrap();
    let mut w = Writer::default();
    method.serialize_into(&mut w);
    let bytes = w.into_bytes();
    let mut reader = Reader::new(&bytes);
    let mut copy = S::deserialize_from(&mut reader).unwrap();
    reader.finish().unwrap();
    copy.check_memory(&Oscillator, t, &y).unwrap();
    let (mut t2, mut y2) = (t, y);
    method
        .integrate(&Oscillator, &mut t, &mut y, 10.0, f64::INFINITY)
        .unwrap();
    copy.integrate(&Oscillator, &mut t2, &mut y2, 10.0, f64::INFINITY)
        .unwrap();
    assert_eq!(t.to_bits(), t2.to_bits());
    assert_eq!(y.map(f64::to_bits), y2.map(f64::to_bits));
    assert_eq!(method.statistics(), copy.statistics());
}

/// After the first call, stepping and dense output allocate nothing.
fn no_allocation<S: Stepper<2>>() {
    let mut method = S::new(tol(1e-11));
    let (mut t, mut y) = (0.0, [1.0, 0.0]);
    method
        .integrate(&Oscillator, &mut t, &mut y, 0.01, f64::INFINITY)
        .unwrap();
    ALLOCATIONS.with(|a| a.set(0));
    COUNTING.with(|c| c.set(true));
    for k in 2..=2000 {
        let target = k as f64 * 0.01;
        method
            .integrate(&Oscillator, &mut t, &mut y, target, f64::INFINITY)
            .unwrap();
        let _ = method.dense_output(&Oscillator, target);
    }
    COUNTING.with(|c| c.set(false));
    assert!(
        method.statistics().n_steps > 50,
        "{:?}",
        method.statistics()
    );
    assert_eq!(ALLOCATIONS.with(Cell::get), 0);
}

macro_rules! conformance {
    ($name:ident, $method:ident) => {
        mod $name {
            use super::*;

            #[test]
            fn accuracy_on_a_known_solution() {
                accuracy::<$method<2>>();
            }

            #[test]
            fn exact_landing_and_the_limit() {
                exact_landing::<$method<1>>();
            }

            #[test]
            fn dense_output_inside_the_step() {
                dense_output::<$method<2>>();
            }

            #[test]
            fn restore_bit_for_bit() {
                super::restore_bit_for_bit::<$method<2>>();
            }

            #[test]
            fn no_allocation_per_step() {
                no_allocation::<$method<2>>();
            }
        }
    };
}

conformance!(dop853, Dop853);
conformance!(radau_iia, Radau5);
conformance!(rk4, Rk4);
