//! fmi2DoStep, fmi2SetReal of inputs and fmi2GetReal of outputs do not allocate: counted
//! by a global allocator around calls through the exported C functions, on the calling
//! thread only (the test harness's other threads may allocate meanwhile).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

mod common;

use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::variables::{value_reference, variables, Causality, VarType};
use fmi_sys::fmi2::*;

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn vr(name: &str) -> u32 {
    value_reference(name).unwrap()
}

const DOP853: usize = 2;
const IMPLICIT: usize = 3;

#[test]
fn stepping_and_exchanging_values_does_not_allocate() {
    let used = run_counting(&common::paper_laws(), 1e-3);
    assert!(
        used[DOP853] && !used[IMPLICIT],
        "DOP853 throughout: {used:?}"
    );
}

#[test]
fn the_implicit_method_and_the_auto_switch_do_not_allocate() {
    let stiff = [("k12", 1e7), ("k34", 1e7), ("d12", 1e3), ("d34", 1e3)];
    let parameters: Vec<_> = common::paper_laws().into_iter().chain(stiff).collect();
    let used = run_counting(&parameters, 1e-2);
    assert!(
        used[DOP853] && used[IMPLICIT],
        "auto switched between the methods: {used:?}"
    );
}

/// Run 1999 steps of `h` with `parameters`, counting allocations; returns which values
/// `active_solver` took after those steps (indexed by value).
fn run_counting(parameters: &[(&str, f64)], h: f64) -> [bool; 4] {
    let c = common::instantiate(c"probe");
    let outputs: Vec<u32> = variables()
        .filter(|(_, v)| v.causality() == Causality::Output && v.var_type() == VarType::Real)
        .map(|(r, _)| r)
        .collect();
    let mut read = vec![0.0; outputs.len()];
    common::initialise(c, 1e-8, None, parameters);
    // SAFETY: `c` is a live instance.
    assert_eq!(unsafe { fmi2DoStep(c, 0.0, h, 1) }, fmi2Status_fmi2OK);
    let torque = vr("M_m");
    let active_vr = vr("active_solver");
    let mut used = [false; 4];
    COUNTING.with(|c| c.set(true));
    for k in 1..2000 {
        let t = k as f64 * h;
        // A new input every tenth step (restart), held otherwise (dense output).
        let input = [0.5 * ((k / 10) as f64).sin()];
        unsafe {
            assert_eq!(
                fmi2SetReal(c, &torque, 1, input.as_ptr()),
                fmi2Status_fmi2OK
            );
            assert_eq!(fmi2DoStep(c, t, h, 1), fmi2Status_fmi2OK);
            assert_eq!(
                fmi2GetReal(c, outputs.as_ptr(), outputs.len(), read.as_mut_ptr()),
                fmi2Status_fmi2OK
            );
            let mut active = 0;
            assert_eq!(
                fmi2GetInteger(c, &active_vr, 1, &mut active),
                fmi2Status_fmi2OK
            );
            used[active as usize] = true;
        }
    }
    COUNTING.with(|c| c.set(false));
    let allocations = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(
        read.iter().all(|v| v.is_finite()) && read[0] > 1.0,
        "the run moved: {read:?}"
    );
    assert_eq!(allocations, 0, "allocations during 1999 steps");
    // SAFETY: `c` came from fmi2Instantiate and is freed once.
    unsafe { fmi2FreeInstance(c) };
    used
}
