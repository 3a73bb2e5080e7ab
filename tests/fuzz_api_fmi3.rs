//! Random FMI 3.0 call sequences with random, often invalid, arguments through the exported
//! fmi3 functions of both interfaces (Co-Simulation with and without event mode and early
//! return, Model Exchange; each also gets the other's calls), over geometries with change
//! points among others: never a crash, never fmi3Fatal (a caught panic, i.e. a bug), only
//! documented statuses, finite values whenever a read succeeds, a step's flags consistent
//! with its end, and exact FMU state round trips. Deterministic (a fixed seed), and run
//! under valgrind memcheck by `cargo xtask test`.

use std::ffi::CString;
use std::ptr::{null, null_mut};

mod common;

use common::Rng;

use cyclic_mechanism::fmi3::model_description::{instantiation_token, reference};
use cyclic_mechanism::fmi3::*;
use cyclic_mechanism::variables::{count, value_reference};
use fmi_sys::fmi3::*;

/// An FMI 3.0 value reference: mostly the FMU's (0 is `time`), some past them.
fn vr(rng: &mut Rng) -> u32 {
    if rng.chance(5) {
        rng.next() as u32
    } else {
        rng.below(count() as u64 + 4) as u32
    }
}

fn vr3(name: &str) -> u32 {
    reference(value_reference(name).expect("a known name"))
}

/// Statuses FMI 3.0 functions may return here: never Fatal.
fn documented(status: fmi3Status) -> bool {
    [
        fmi3Status_fmi3OK,
        fmi3Status_fmi3Warning,
        fmi3Status_fmi3Discard,
        fmi3Status_fmi3Error,
    ]
    .contains(&status)
}

struct Fuzz {
    rng: Rng,
    c: fmi3Instance,
    time: f64,
    states: Vec<fmi3FMUState>,
    calls: u64,
    round_trips: u64,
    early_returns: u64,
}

impl Fuzz {
    fn check(&mut self, status: fmi3Status, what: &str) -> fmi3Status {
        self.calls += 1;
        assert!(documented(status), "{what} returned status {status}");
        status
    }

    fn references(&mut self) -> Vec<u32> {
        let n = self.rng.below(4) as usize;
        (0..n).map(|_| vr(&mut self.rng)).collect()
    }

    /// A value count: mostly the references', sometimes another.
    fn count_for(&mut self, n: usize) -> usize {
        if self.rng.chance(10) {
            self.rng.below(5) as usize
        } else {
            n
        }
    }

    unsafe fn call(&mut self) {
        let c = self.c;
        unsafe {
            match self.rng.below(24) {
                0 => {
                    let start = if self.rng.chance(70) {
                        0.0
                    } else {
                        self.rng.real()
                    };
                    let tolerance = self.rng.real().abs() * 1e-9;
                    let stop = self.rng.real();
                    let (tol_on, stop_on) = (self.rng.chance(50), self.rng.chance(30));
                    let s = fmi3EnterInitializationMode(c, tol_on, tolerance, start, stop_on, stop);
                    if self.check(s, "fmi3EnterInitializationMode") == fmi3Status_fmi3OK {
                        self.time = start;
                    }
                }
                1 => {
                    self.check(fmi3ExitInitializationMode(c), "fmi3ExitInitializationMode");
                }
                2 => {
                    let vrs = self.references();
                    let n = self.count_for(vrs.len());
                    let values: Vec<f64> = (0..n.max(vrs.len())).map(|_| self.rng.real()).collect();
                    let s = fmi3SetFloat64(c, vrs.as_ptr(), vrs.len(), values.as_ptr(), n);
                    self.check(s, "fmi3SetFloat64");
                }
                3 => {
                    let vrs = self.references();
                    let n = self.count_for(vrs.len());
                    let mut values = vec![0.0; n.max(vrs.len())];
                    let s = fmi3GetFloat64(c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr(), n);
                    if self.check(s, "fmi3GetFloat64") == fmi3Status_fmi3OK {
                        assert!(values.iter().all(|v| v.is_finite()), "{vrs:?}: {values:?}");
                    }
                }
                4 => {
                    let vrs = self.references();
                    let mut ints = vec![0i32; vrs.len()];
                    let mut longs = vec![0i64; vrs.len()];
                    let mut bools = vec![false; vrs.len()];
                    let n = vrs.len();
                    self.check(
                        fmi3GetInt32(c, vrs.as_ptr(), n, ints.as_mut_ptr(), n),
                        "GetInt32",
                    );
                    self.check(
                        fmi3GetInt64(c, vrs.as_ptr(), n, longs.as_mut_ptr(), n),
                        "GetInt64",
                    );
                    self.check(
                        fmi3GetBoolean(c, vrs.as_ptr(), n, bools.as_mut_ptr(), n),
                        "GetBool",
                    );
                }
                5 => {
                    let branch = [vr3("change_point_branch")];
                    let value =
                        [self.rng.below(4) as i64 - 1 + (self.rng.chance(5) as i64) * (1 << 40)];
                    self.check(
                        fmi3SetInt64(c, branch.as_ptr(), 1, value.as_ptr(), 1),
                        "SetInt64",
                    );
                    let vrs = self.references();
                    let values = vec![self.rng.chance(50); vrs.len()];
                    let s = fmi3SetBoolean(c, vrs.as_ptr(), vrs.len(), values.as_ptr(), vrs.len());
                    self.check(s, "fmi3SetBoolean");
                    let ints = vec![self.rng.below(5) as i32; vrs.len()];
                    let s = fmi3SetInt32(c, vrs.as_ptr(), vrs.len(), ints.as_ptr(), vrs.len());
                    self.check(s, "fmi3SetInt32");
                }
                6..=8 => self.step(),
                9 => {
                    self.check(fmi3EnterEventMode(c), "fmi3EnterEventMode");
                }
                10 => {
                    self.check(fmi3EnterStepMode(c), "fmi3EnterStepMode");
                }
                11 => {
                    let mut flags = [false; 5];
                    let mut next = 0.0;
                    let [a, b, d, e, f] = &mut flags;
                    let s = fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next);
                    self.check(s, "fmi3UpdateDiscreteStates");
                }
                12 => {
                    let s = if self.rng.chance(50) {
                        fmi3Terminate(c)
                    } else {
                        fmi3Reset(c)
                    };
                    if self.check(s, "fmi3Terminate/Reset") == fmi3Status_fmi3OK {
                        self.time = 0.0;
                    }
                }
                13 => {
                    let mut state: fmi3FMUState = null_mut();
                    if self.check(fmi3GetFMUState(c, &mut state), "GetFMUState")
                        == fmi3Status_fmi3OK
                    {
                        self.states.push(state);
                    }
                }
                14 => {
                    if let Some(&state) = self.states.last() {
                        self.check(fmi3SetFMUState(c, state), "fmi3SetFMUState");
                        let mut t = [0.0];
                        fmi3GetFloat64(c, [0].as_ptr(), 1, t.as_mut_ptr(), 1);
                        self.time = t[0];
                    }
                    let forged = 0x1000 as fmi3FMUState;
                    self.check(fmi3SetFMUState(c, forged), "fmi3SetFMUState (forged)");
                }
                15 => self.round_trip(),
                16 => self.derivatives(),
                17 => {
                    let s = fmi3SetTime(c, self.rng.real());
                    self.check(s, "fmi3SetTime");
                    let mut x = [0.0; 6];
                    if self.check(fmi3GetContinuousStates(c, x.as_mut_ptr(), 6), "GetX")
                        == fmi3Status_fmi3OK
                    {
                        assert!(x.iter().all(|v| v.is_finite()));
                    }
                    if self.rng.chance(30) {
                        let i = self.rng.below(6) as usize;
                        x[i] = self.rng.real();
                    }
                    let n = if self.rng.chance(10) { 5 } else { 6 };
                    self.check(fmi3SetContinuousStates(c, x.as_ptr(), n), "SetX");
                }
                18 => {
                    let mut dx = [0.0; 6];
                    let s = fmi3GetContinuousStateDerivatives(c, dx.as_mut_ptr(), 6);
                    if self.check(s, "fmi3GetContinuousStateDerivatives") == fmi3Status_fmi3OK {
                        assert!(dx.iter().all(|v| v.is_finite()), "{dx:?}");
                    }
                    let mut z = [0.0];
                    self.check(fmi3GetEventIndicators(c, z.as_mut_ptr(), 1), "GetZ");
                    let mut nominal = [0.0; 6];
                    self.check(
                        fmi3GetNominalsOfContinuousStates(c, nominal.as_mut_ptr(), 6),
                        "Nom",
                    );
                    let mut n = 0usize;
                    self.check(fmi3GetNumberOfContinuousStates(c, &mut n), "NX");
                }
                19 => {
                    self.check(
                        fmi3EnterContinuousTimeMode(c),
                        "fmi3EnterContinuousTimeMode",
                    );
                    let (mut event, mut stop) = (false, false);
                    let s = fmi3CompletedIntegratorStep(c, true, &mut event, &mut stop);
                    self.check(s, "fmi3CompletedIntegratorStep");
                }
                20 => {
                    // Types and features the FMU does not have: refused by name, or empty.
                    let vrs = self.references();
                    let n = vrs.len();
                    let mut f32s = vec![0f32; n];
                    self.check(
                        fmi3GetFloat32(c, vrs.as_ptr(), n, f32s.as_mut_ptr(), n),
                        "GetF32",
                    );
                    let mut strings = vec![null(); n];
                    self.check(
                        fmi3GetString(c, vrs.as_ptr(), n, strings.as_mut_ptr(), n),
                        "GetStr",
                    );
                    let ptr = if self.rng.chance(50) {
                        null()
                    } else {
                        vrs.as_ptr()
                    };
                    self.check(fmi3GetClock(c, ptr, n, null_mut()), "fmi3GetClock");
                    self.check(fmi3EnterConfigurationMode(c), "fmi3EnterConfigurationMode");
                    self.check(fmi3EvaluateDiscreteStates(c), "fmi3EvaluateDiscreteStates");
                    self.check(
                        fmi3ActivateModelPartition(c, 0, 0.0),
                        "ActivateModelPartition",
                    );
                }
                21 => {
                    let vrs = self.references();
                    let orders: Vec<i32> = vrs.iter().map(|_| self.rng.below(4) as i32).collect();
                    let mut values = vec![0.0; vrs.len()];
                    let n = vrs.len();
                    let s = fmi3GetOutputDerivatives(
                        c,
                        vrs.as_ptr(),
                        n,
                        orders.as_ptr(),
                        values.as_mut_ptr(),
                        n,
                    );
                    if self.check(s, "fmi3GetOutputDerivatives") == fmi3Status_fmi3OK {
                        assert!(values.iter().all(|v| v.is_finite()));
                    }
                }
                22 => {
                    let names = [c"logSolver".as_ptr(), c"nonsense".as_ptr()];
                    let n = self.rng.below(3) as usize;
                    let s = fmi3SetDebugLogging(c, self.rng.chance(50), n, names.as_ptr());
                    self.check(s, "fmi3SetDebugLogging");
                }
                _ => {
                    let mut freed = self.states.pop().unwrap_or(null_mut());
                    self.check(fmi3FreeFMUState(c, &mut freed), "fmi3FreeFMUState");
                }
            }
        }
    }

    /// A step of a random length from the FMU's time (or a wrong one); its flags must agree
    /// with where it ended, and with event handling needed the master handles it.
    unsafe fn step(&mut self) {
        let c = self.c;
        let h = [1e-3, 0.01, 0.1, 0.5, 2.0, -1.0, f64::NAN][self.rng.below(7) as usize];
        let from = if self.rng.chance(90) {
            self.time
        } else {
            self.rng.real()
        };
        let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
        unsafe {
            let s = fmi3DoStep(
                c, from, h, true, &mut event, &mut stop, &mut early, &mut last,
            );
            let status = self.check(s, "fmi3DoStep");
            if status == fmi3Status_fmi3OK {
                assert!(!stop);
                assert!(last.is_finite());
                if early {
                    assert!(
                        event && last < from + h,
                        "early at {last}, step {from} + {h}"
                    );
                    self.early_returns += 1;
                } else {
                    assert!((last - (from + h)).abs() <= 1e-9 * (1.0 + last.abs()));
                }
                self.time = last;
                if event && self.rng.chance(70) {
                    self.check(fmi3EnterEventMode(c), "fmi3EnterEventMode");
                    let value = [1 + self.rng.below(2) as i64];
                    let branch = [vr3("change_point_branch")];
                    self.check(
                        fmi3SetInt64(c, branch.as_ptr(), 1, value.as_ptr(), 1),
                        "branch",
                    );
                    let mut flags = [false; 5];
                    let mut next = 0.0;
                    let [a, b, d, e, f] = &mut flags;
                    self.check(
                        fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next),
                        "Update",
                    );
                    self.check(fmi3EnterStepMode(c), "fmi3EnterStepMode");
                }
            } else if status == fmi3Status_fmi3Discard && last.is_finite() {
                self.time = last;
            }
        }
    }

    /// Get, serialize, deserialize, set: a buffer the FMU wrote restores, and serializes
    /// to the same bytes again; a damaged one is refused or restores a valid state.
    unsafe fn round_trip(&mut self) {
        let c = self.c;
        unsafe {
            let mut taken: fmi3FMUState = null_mut();
            if self.check(fmi3GetFMUState(c, &mut taken), "GetFMUState") != fmi3Status_fmi3OK {
                return;
            }
            let bytes = serialized(c, taken);
            let mut restored: fmi3FMUState = null_mut();
            let s = fmi3DeserializeFMUState(c, bytes.as_ptr(), bytes.len(), &mut restored);
            assert_eq!(s, fmi3Status_fmi3OK, "a buffer the FMU wrote was refused");
            assert_eq!(fmi3SetFMUState(c, restored), fmi3Status_fmi3OK);
            let mut again: fmi3FMUState = null_mut();
            assert_eq!(fmi3GetFMUState(c, &mut again), fmi3Status_fmi3OK);
            assert!(
                serialized(c, again) == bytes,
                "the restored state serializes differently"
            );
            self.round_trips += 1;
            let mut damaged = bytes.clone();
            let i = self.rng.below(damaged.len() as u64) as usize;
            damaged[i] ^= 1 << self.rng.below(8);
            let mut other: fmi3FMUState = null_mut();
            let s = fmi3DeserializeFMUState(c, damaged.as_ptr(), damaged.len(), &mut other);
            if self.check(s, "fmi3DeserializeFMUState (damaged)") == fmi3Status_fmi3OK {
                self.states.push(other);
            }
            for mut state in [taken, restored, again] {
                self.check(fmi3FreeFMUState(c, &mut state), "fmi3FreeFMUState");
            }
        }
    }

    /// Directional and adjoint derivatives with random references, seeds and lengths.
    unsafe fn derivatives(&mut self) {
        let c = self.c;
        let unknowns = self.references();
        let knowns = self.references();
        let seed: Vec<f64> = (0..4).map(|_| self.rng.real()).collect();
        let mut out = vec![0.0; 4];
        let (nu, nk) = (unknowns.len(), knowns.len());
        let (n_seed, n_out) = (self.count_for(nk), self.count_for(nu));
        unsafe {
            let s = fmi3GetDirectionalDerivative(
                c,
                unknowns.as_ptr(),
                nu,
                knowns.as_ptr(),
                nk,
                seed.as_ptr(),
                n_seed,
                out.as_mut_ptr(),
                n_out,
            );
            if self.check(s, "fmi3GetDirectionalDerivative") == fmi3Status_fmi3OK {
                assert!(out[..nu].iter().all(|v| v.is_finite()), "{out:?}");
            }
            let (n_seed, n_out) = (self.count_for(nu), self.count_for(nk));
            let s = fmi3GetAdjointDerivative(
                c,
                unknowns.as_ptr(),
                nu,
                knowns.as_ptr(),
                nk,
                seed.as_ptr(),
                n_seed,
                out.as_mut_ptr(),
                n_out,
            );
            if self.check(s, "fmi3GetAdjointDerivative") == fmi3Status_fmi3OK {
                assert!(out[..nk].iter().all(|v| v.is_finite()), "{out:?}");
            }
        }
    }
}

unsafe fn serialized(c: fmi3Instance, state: fmi3FMUState) -> Vec<u8> {
    let mut size = 0usize;
    unsafe {
        assert_eq!(
            fmi3SerializedFMUStateSize(c, state, &mut size),
            fmi3Status_fmi3OK
        );
        let mut bytes = vec![0u8; size];
        assert_eq!(
            fmi3SerializeFMUState(c, state, bytes.as_mut_ptr(), size),
            fmi3Status_fmi3OK
        );
        bytes
    }
}

/// A fresh instance of kind `kind` (0: Model Exchange; 1: Co-Simulation; 2: with event
/// mode; 3: with event mode and early return), its geometry a change-point one or not.
unsafe fn instantiate(kind: u64, change_point: bool) -> fmi3Instance {
    let token = CString::new(instantiation_token()).expect("no NUL");
    let name = c"fuzz3";
    let c = unsafe {
        if kind == 0 {
            fmi3InstantiateModelExchange(
                name.as_ptr(),
                token.as_ptr(),
                null(),
                false,
                false,
                null_mut(),
                None,
            )
        } else {
            fmi3InstantiateCoSimulation(
                name.as_ptr(),
                token.as_ptr(),
                null(),
                false,
                false,
                kind >= 2,
                kind == 3,
                null(),
                0,
                null_mut(),
                None,
                None,
            )
        }
    };
    assert!(!c.is_null());
    if change_point {
        let vrs = [vr3("L"), vr3("phi2_0"), vr3("omega2_0")];
        let values = [0.95, 6.0, 20.0];
        let laws = [vr3("builtin_laws")];
        unsafe {
            assert_eq!(
                fmi3SetFloat64(c, vrs.as_ptr(), 3, values.as_ptr(), 3),
                fmi3Status_fmi3OK
            );
            assert_eq!(
                fmi3SetBoolean(c, laws.as_ptr(), 1, [false].as_ptr(), 1),
                fmi3Status_fmi3OK
            );
        }
    }
    c
}

#[test]
fn random_fmi3_call_sequences_never_crash_and_return_only_documented_statuses() {
    let sequences = std::env::var("FUZZ_SEQUENCES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3000u64);
    let mut rng = Rng(0xD1B54A32D192ED03);
    let (mut calls, mut round_trips, mut early_returns) = (0, 0, 0);
    for sequence in 0..sequences {
        let c = unsafe { instantiate(sequence % 4, rng.chance(50)) };
        let mut fuzz = Fuzz {
            rng: Rng(rng.next() | 1),
            c,
            time: 0.0,
            states: Vec::new(),
            calls: 0,
            round_trips: 0,
            early_returns: 0,
        };
        let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            // Mostly a proper start, so that the later calls reach the running states.
            if fuzz.rng.chance(80) {
                unsafe {
                    fuzz.check(
                        fmi3EnterInitializationMode(c, true, 1e-8, 0.0, false, 0.0),
                        "init",
                    );
                    fuzz.check(fmi3ExitInitializationMode(c), "exit");
                    if sequence % 4 >= 2 {
                        fuzz.check(fmi3EnterStepMode(c), "step mode");
                    }
                }
            }
            for _ in 0..40 {
                unsafe { fuzz.call() };
            }
        }));
        if let Err(panic) = run {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            panic!("sequence {sequence} (of {sequences}) found: {what}");
        }
        calls += fuzz.calls;
        round_trips += fuzz.round_trips;
        early_returns += fuzz.early_returns;
        unsafe { fmi3FreeInstance(c) };
    }
    eprintln!(
        "fuzzed {sequences} FMI 3.0 sequences, {calls} calls, {round_trips} exact round trips, \
         {early_returns} early returns at change points"
    );
    // `cargo xtask test` asks for the counts in its reports, which the docs quote.
    if let Some(report) = std::env::var_os("FUZZ_REPORT_FMI3") {
        let json = format!(
            "{{\"sequences\": {sequences}, \"calls\": {calls}, \"round_trips\": {round_trips}, \
             \"early_returns\": {early_returns}}}\n"
        );
        std::fs::write(&report, json).expect("the fuzzer's report is writable");
    }
    assert!(calls > sequences * 30);
    assert!(round_trips > 0, "no round trip was checked");
    assert!(
        early_returns > 0,
        "no step returned early at a change point"
    );
}
