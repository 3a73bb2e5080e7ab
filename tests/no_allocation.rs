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

/// FMI 3.0's step, input setter, Float64 and Int64 getters and output derivatives do not
/// allocate either: its value references are translated without a buffer.
#[test]
fn fmi3_stepping_and_exchanging_values_does_not_allocate() {
    use cyclic_mechanism::fmi3::model_description::{instantiation_token, reference};
    use cyclic_mechanism::fmi3::*;
    let token = std::ffi::CString::new(instantiation_token()).unwrap();
    let null = std::ptr::null();
    // SAFETY: valid strings for the call; no callbacks.
    let c = unsafe {
        fmi3InstantiateCoSimulation(
            c"probe".as_ptr(),
            token.as_ptr(),
            null,
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            None,
            None,
        )
    };
    assert!(!c.is_null());
    let outputs: Vec<u32> = variables()
        .filter(|(_, v)| v.causality() == Causality::Output && v.var_type() == VarType::Real)
        .map(|(r, _)| reference(r))
        .chain([0])
        .collect();
    let mut read = vec![0.0; outputs.len()];
    let (torque, active) = (reference(vr("M_m")), reference(vr("active_solver")));
    let omega1 = [reference(vr("omega1")); 2];
    let h = 1e-3;
    // SAFETY: `c` is a live instance; every array holds the count given.
    unsafe {
        assert_eq!(
            fmi3EnterInitializationMode(c, true, 1e-8, 0.0, false, 0.0),
            0
        );
        assert_eq!(fmi3ExitInitializationMode(c), 0);
        COUNTING.with(|c| c.set(true));
        for k in 0..1999 {
            let t = k as f64 * h;
            let input = [0.5 * ((k / 10) as f64).sin()];
            assert_eq!(fmi3SetFloat64(c, &torque, 1, input.as_ptr(), 1), 0);
            let (mut event, mut stop, mut early, mut last) = (false, false, false, 0.0);
            let s = fmi3DoStep(c, t, h, true, &mut event, &mut stop, &mut early, &mut last);
            assert_eq!(s, 0);
            let n = outputs.len();
            assert_eq!(
                fmi3GetFloat64(c, outputs.as_ptr(), n, read.as_mut_ptr(), n),
                0
            );
            let mut method = [0i64];
            assert_eq!(fmi3GetInt64(c, &active, 1, method.as_mut_ptr(), 1), 0);
            let mut derivatives = [0.0; 2];
            let orders = [1, 2];
            let s = fmi3GetOutputDerivatives(
                c,
                omega1.as_ptr(),
                2,
                orders.as_ptr(),
                derivatives.as_mut_ptr(),
                2,
            );
            assert_eq!(s, 0);
        }
        COUNTING.with(|c| c.set(false));
        fmi3FreeInstance(c);
    }
    assert!(
        read.iter().all(|v| v.is_finite()) && read[0] > 1.0,
        "the run moved: {read:?}"
    );
    assert_eq!(
        ALLOCATIONS.load(Ordering::SeqCst),
        0,
        "allocations during 1999 steps"
    );
}
