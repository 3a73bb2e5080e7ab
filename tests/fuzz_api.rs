//! Random FMI call sequences with random, often invalid, arguments through the exported C
//! functions of both interfaces (every other sequence is a Model Exchange instance, which
//! also gets the Co-Simulation calls, and the reverse): never a crash, never fmi2Fatal (a caught panic, i.e. a bug),
//! only documented statuses, finite values whenever a read succeeds, no step from a
//! communication point other than the FMU's time, and no step doing more work than one
//! call may (the longest is reported). Deterministic (a fixed seed), and run under
//! valgrind memcheck by `cargo xtask test` (without the steps that spend a whole call's
//! work).

use std::collections::BTreeMap;
use std::ffi::c_char;
use std::ptr::{null, null_mut};
use std::time::{Duration, Instant};

mod common;

use common::{long_steps, Rng, RUNAWAY};

use cyclic_mechanism::drivers::cosimulation::CALL_WORK;
use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::instance::{FmuState, State, Version};
use cyclic_mechanism::variables::{count, variable, VarType};
use fmi_sys::fmi2::*;
use integrators::bytes::fnv1a_64;

/// A value reference: mostly the FMU's, some past them, some anything.
fn vr(rng: &mut Rng) -> u32 {
    if rng.chance(10) {
        rng.next() as u32
    } else {
        rng.below(count() as u64 + 3) as u32
    }
}

struct Fuzz {
    rng: Rng,
    c: fmi2Component,
    /// A Model Exchange instance (else Co-Simulation).
    exchange: bool,
    time: f64,
    states: Vec<fmi2FMUstate>,
    calls: u64,
    /// Exact round trips checked, by the code of the FMI state they were taken in.
    round_trips: BTreeMap<u8, u64>,
    /// Whether steps that spend a whole call's work are tried.
    long_steps: bool,
    longest: (Duration, String),
    /// Oracles broken: how often, and the first instance.
    violations: BTreeMap<&'static str, (u64, String)>,
    /// The value last set to each input (M_m, M_r) by an accepted fmi2SetReal, where the
    /// fuzzer knows it: what a getter of the input must return, steps and input
    /// derivatives notwithstanding.
    inputs_set: [Option<f64>; 2],
}

/// The inputs' value references, in the order of [`Fuzz::inputs_set`].
fn input_vrs() -> [u32; 2] {
    ["M_m", "M_r"].map(|n| cyclic_mechanism::variables::value_reference(n).expect("an input"))
}

/// The serialized state's header; the interface's byte follows it, then the version's,
/// then the FMI state's code.
const HEADER: usize = cyclic_mechanism::instance::STATE_HEADER;
const STATE_CODE: usize = HEADER + 2;

/// Why the FMU refuses `bytes`, with the interface and FMI state they describe.
fn refusal(bytes: &[c_char]) -> String {
    let raw: Vec<u8> = bytes.iter().map(|b| *b as u8).collect();
    let why = FmuState::deserialize(&raw).err().map(|f| f.message);
    format!(
        "interface {}, state {}: {why:?}",
        raw[HEADER], raw[STATE_CODE]
    )
}

fn documented(status: fmi2Status) -> bool {
    [
        fmi2Status_fmi2OK,
        fmi2Status_fmi2Warning,
        fmi2Status_fmi2Discard,
        fmi2Status_fmi2Error,
    ]
    .contains(&status)
}

impl Fuzz {
    fn check(&mut self, status: fmi2Status, what: &str) -> fmi2Status {
        self.calls += 1;
        assert!(
            documented(status),
            "{what} returned status {status} (never fmi2Fatal or undocumented)"
        );
        status
    }

    /// An oracle broken: counted, with its first instance, and failed at the end.
    fn violated(&mut self, rule: &'static str, detail: String) {
        self.violations.entry(rule).or_insert((0, detail)).0 += 1;
    }

    /// The right-hand sides counted so far, if the FMU reads them out now.
    unsafe fn work(&mut self) -> Option<i64> {
        let vr = [cyclic_mechanism::variables::value_reference("n_rhs").expect("n_rhs")];
        let mut n = [0];
        let s = unsafe { fmi2GetInteger(self.c, vr.as_ptr(), 1, n.as_mut_ptr()) };
        (s == fmi2Status_fmi2OK).then_some(i64::from(n[0]))
    }

    /// An fmi2SetReal of `values` to `vrs` returned `status`: accepted, its inputs' values
    /// are known; refused, they are not (the fuzzer does not model which part applied).
    fn note_inputs_set(&mut self, vrs: &[u32], values: &[f64], status: fmi2Status) {
        let accepted = status == fmi2Status_fmi2OK || status == fmi2Status_fmi2Warning;
        for (vr, value) in vrs.iter().zip(values) {
            if let Some(k) = input_vrs().iter().position(|i| i == vr) {
                self.inputs_set[k] = accepted.then_some(*value);
            }
        }
    }

    /// Each input read returns the value last set to it, where that is known.
    fn judge_inputs_read(&mut self, vrs: &[u32], values: &[f64]) {
        for (vr, value) in vrs.iter().zip(values) {
            let Some(k) = input_vrs().iter().position(|i| i == vr) else {
                continue;
            };
            if let Some(set) = self.inputs_set[k] {
                if set.to_bits() != value.to_bits() {
                    let detail = format!("input {vr} set to {set}, read {value}");
                    self.violated("an input reads back the value last set", detail);
                }
            }
        }
    }

    fn arrays(&mut self) -> (Vec<u32>, usize) {
        let n = self.rng.below(5) as usize;
        ((0..n).map(|_| vr(&mut self.rng)).collect(), n)
    }

    /// One random call.
    unsafe fn call(&mut self) {
        let c = self.c;
        let r = &mut self.rng;
        let choice = r.below(26);
        unsafe {
            match choice {
                0 => {
                    // Start times other than 0 too, up to the extremes of the doubles.
                    let start = if r.chance(60) { 0.0 } else { r.real() };
                    let s = fmi2SetupExperiment(
                        c,
                        r.below(2) as i32,
                        r.real().abs() * 1e-9,
                        start,
                        r.below(2) as i32,
                        if r.chance(30) { start } else { r.real() },
                    );
                    if self.check(s, "fmi2SetupExperiment") == fmi2Status_fmi2OK {
                        self.time = start;
                    }
                }
                1 => {
                    let s = fmi2EnterInitializationMode(c);
                    self.check(s, "fmi2EnterInitializationMode");
                }
                2 => {
                    let s = fmi2ExitInitializationMode(c);
                    self.check(s, "fmi2ExitInitializationMode");
                }
                3..=5 => {
                    // Short steps: random parameters can make the model very stiff, and the
                    // point here is the API, not long integrations (tested elsewhere).
                    let h = match r.below(8) {
                        0 => r.real().min(0.05),
                        1 => 0.05,
                        2 => 1e-9,
                        // Legal steps shorter than the integrator resolves.
                        3 => [1e-300, 1e-20, 1e-15, 8.88e-16][r.below(4) as usize],
                        // Now and then a step longer than one call's work.
                        4 if self.long_steps && r.chance(5) => {
                            [1e6, 1e12, 1e300][r.below(3) as usize]
                        }
                        _ => 0.01,
                    };
                    let t = if r.chance(85) { self.time } else { r.real() };
                    let work_before = self.work();
                    let start = Instant::now();
                    let s = fmi2DoStep(c, t, h, 1);
                    let took = start.elapsed();
                    let what = format!("fmi2DoStep({t:e}, {h:e})");
                    if took > self.longest.0 {
                        self.longest = (took, what.clone());
                    }
                    if let (Some(a), Some(b)) = (work_before, self.work()) {
                        if b - a > CALL_WORK as i64 + 1000 {
                            let detail = format!("{what}: {} right-hand sides", b - a);
                            self.violated("no call does more work than one call may", detail);
                        }
                    }
                    if self.check(s, "fmi2DoStep") == fmi2Status_fmi2OK {
                        if (t - self.time).abs() > 1e-12 * t.abs().max(self.time.abs()) {
                            let detail = format!("{what} accepted at the FMU's time {}", self.time);
                            self.violated("a step starts at the FMU's time", detail);
                        }
                        self.time = t + h;
                    }
                }
                6..=7 => {
                    let (vrs, n) = self.arrays();
                    let mut values = vec![0.0; n];
                    let pointer = if self.rng.chance(5) {
                        null_mut()
                    } else {
                        values.as_mut_ptr()
                    };
                    let s = fmi2GetReal(c, vrs.as_ptr(), n, pointer);
                    if self.check(s, "fmi2GetReal") == fmi2Status_fmi2OK {
                        assert!(
                            values.iter().all(|v| v.is_finite()),
                            "non-finite output {values:?}"
                        );
                        self.judge_inputs_read(&vrs, &values);
                    }
                }
                8..=9 => {
                    let (vrs, n) = self.arrays();
                    let values: Vec<f64> = (0..n).map(|_| self.rng.real()).collect();
                    let s = fmi2SetReal(c, vrs.as_ptr(), n, values.as_ptr());
                    let s = self.check(s, "fmi2SetReal");
                    self.note_inputs_set(&vrs, &values, s);
                }
                10 => {
                    let (vrs, n) = self.arrays();
                    let values: Vec<i32> = (0..n).map(|_| self.rng.below(5) as i32 - 1).collect();
                    let mut read = vec![0; n];
                    // Integers and Booleans (builtin_laws) share the C type.
                    if self.rng.chance(50) {
                        let s = fmi2SetInteger(c, vrs.as_ptr(), n, values.as_ptr());
                        self.check(s, "fmi2SetInteger");
                        let s = fmi2GetInteger(c, vrs.as_ptr(), n, read.as_mut_ptr());
                        self.check(s, "fmi2GetInteger");
                    } else {
                        let s = fmi2SetBoolean(c, vrs.as_ptr(), n, values.as_ptr());
                        self.check(s, "fmi2SetBoolean");
                        let s = fmi2GetBoolean(c, vrs.as_ptr(), n, read.as_mut_ptr());
                        if self.check(s, "fmi2GetBoolean") == fmi2Status_fmi2OK {
                            assert!(read.iter().all(|v| *v == 0 || *v == 1), "{read:?}");
                        }
                    }
                }
                11 => {
                    let mut state: fmi2FMUstate = null_mut();
                    if self.check(fmi2GetFMUstate(c, &mut state), "fmi2GetFMUstate")
                        == fmi2Status_fmi2OK
                    {
                        self.states.push(state);
                    }
                }
                12 => {
                    let state = self.pick_state();
                    let s = fmi2SetFMUstate(c, state);
                    self.inputs_set = [None; 2];
                    if self.check(s, "fmi2SetFMUstate") == fmi2Status_fmi2OK {
                        let mut t = 0.0;
                        fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut t);
                        self.time = t;
                    }
                }
                13 => {
                    if !self.states.is_empty() {
                        let i = self.rng.below(self.states.len() as u64) as usize;
                        let mut state = self.states.swap_remove(i);
                        self.check(fmi2FreeFMUstate(c, &mut state), "fmi2FreeFMUstate");
                    }
                }
                14 => self.round_trip_serialized(),
                19 => self.round_trip_exact(),
                15 => {
                    let names = [
                        c"logCalls".as_ptr(),
                        c"logSolver".as_ptr(),
                        c"nonsense".as_ptr(),
                        null(),
                    ];
                    let n = self.rng.below(3) as usize;
                    let chosen: Vec<*const c_char> =
                        (0..n).map(|_| names[self.rng.below(4) as usize]).collect();
                    let s = fmi2SetDebugLogging(c, self.rng.below(2) as i32, n, chosen.as_ptr());
                    self.check(s, "fmi2SetDebugLogging");
                }
                16 => {
                    let (vrs, n) = self.arrays();
                    let orders: Vec<i32> = (0..n).map(|_| self.rng.below(4) as i32).collect();
                    let mut values = vec![0.0; n];
                    let s = fmi2GetRealOutputDerivatives(
                        c,
                        vrs.as_ptr(),
                        n,
                        orders.as_ptr(),
                        values.as_mut_ptr(),
                    );
                    if self.check(s, "fmi2GetRealOutputDerivatives") == fmi2Status_fmi2OK {
                        assert!(
                            values.iter().all(|v| v.is_finite()),
                            "non-finite derivative {values:?}"
                        );
                    }
                    let values: Vec<f64> = (0..n).map(|_| self.rng.real()).collect();
                    let s = fmi2SetRealInputDerivatives(
                        c,
                        vrs.as_ptr(),
                        n,
                        orders.as_ptr(),
                        values.as_ptr(),
                    );
                    self.check(s, "fmi2SetRealInputDerivatives");
                }
                17 => {
                    let s = fmi2Terminate(c);
                    self.check(s, "fmi2Terminate");
                }
                18 => {
                    if self.rng.chance(30) {
                        self.check(fmi2Reset(c), "fmi2Reset");
                        self.inputs_set = [None; 2];
                        self.time = 0.0;
                    }
                }
                20..=24 => self.model_exchange_call(),
                _ => {
                    let mut flag = 0;
                    self.check(
                        fmi2GetBooleanStatus(c, fmi2StatusKind_fmi2Terminated, &mut flag),
                        "fmi2GetBooleanStatus",
                    );
                    self.check(fmi2CancelStep(c), "fmi2CancelStep");
                    self.check(fmi2GetDerivatives(c, null_mut(), 0), "fmi2GetDerivatives");
                }
            }
        }
    }

    /// One random Model Exchange call (refused with a message by a Co-Simulation
    /// instance): states moved near the current ones or anywhere, time, events, Jacobians.
    unsafe fn model_exchange_call(&mut self) {
        let c = self.c;
        let n = if self.rng.chance(90) {
            6
        } else {
            self.rng.below(8) as usize
        };
        let mut x = vec![0.0; n.max(6)];
        unsafe {
            match self.rng.below(7) {
                0 => {
                    let s = fmi2SetTime(c, self.time + self.rng.real().min(0.1));
                    self.check(s, "fmi2SetTime");
                }
                1 => {
                    if fmi2GetContinuousStates(c, x.as_mut_ptr(), 6) == fmi2Status_fmi2OK {
                        for v in x.iter_mut() {
                            if self.rng.chance(30) {
                                *v += if self.rng.chance(80) {
                                    0.01
                                } else {
                                    self.rng.real()
                                };
                            }
                        }
                    }
                    let s = fmi2SetContinuousStates(c, x.as_ptr(), n);
                    self.check(s, "fmi2SetContinuousStates");
                }
                2 => {
                    let s = fmi2GetDerivatives(c, x.as_mut_ptr(), n);
                    if self.check(s, "fmi2GetDerivatives") == fmi2Status_fmi2OK {
                        assert!(
                            x.iter().all(|v| v.is_finite()),
                            "non-finite derivative {x:?}"
                        );
                    }
                    let mut z = [0.0; 2];
                    let s = fmi2GetEventIndicators(c, z.as_mut_ptr(), self.rng.below(3) as usize);
                    if self.check(s, "fmi2GetEventIndicators") == fmi2Status_fmi2OK {
                        assert!(z[0].is_finite(), "non-finite indicator {z:?}");
                    }
                }
                3 => {
                    let s = fmi2EnterEventMode(c);
                    self.check(s, "fmi2EnterEventMode");
                    let mut info = std::mem::zeroed::<fmi2EventInfo>();
                    let s = fmi2NewDiscreteStates(c, &mut info);
                    self.check(s, "fmi2NewDiscreteStates");
                }
                4 => {
                    let s = fmi2EnterContinuousTimeMode(c);
                    self.check(s, "fmi2EnterContinuousTimeMode");
                    let (mut event, mut stop) = (0, 0);
                    let s = fmi2CompletedIntegratorStep(c, 1, &mut event, &mut stop);
                    self.check(s, "fmi2CompletedIntegratorStep");
                }
                5 => {
                    let (unknowns, nu) = self.arrays();
                    let (knowns, nk) = self.arrays();
                    let seed: Vec<f64> = (0..nk).map(|_| self.rng.real()).collect();
                    let mut out = vec![0.0; nu];
                    let s = fmi2GetDirectionalDerivative(
                        c,
                        unknowns.as_ptr(),
                        nu,
                        knowns.as_ptr(),
                        nk,
                        seed.as_ptr(),
                        out.as_mut_ptr(),
                    );
                    if self.check(s, "fmi2GetDirectionalDerivative") == fmi2Status_fmi2OK {
                        assert!(out.iter().all(|v| v.is_finite()), "non-finite {out:?}");
                    }
                }
                _ => {
                    let s = fmi2GetNominalsOfContinuousStates(c, x.as_mut_ptr(), n);
                    self.check(s, "fmi2GetNominalsOfContinuousStates");
                }
            }
        }
    }

    fn pick_state(&mut self) -> fmi2FMUstate {
        if self.states.is_empty() || self.rng.chance(10) {
            // A pointer this instance never issued: must be refused, not dereferenced.
            return 0x1000 as fmi2FMUstate;
        }
        self.states[self.rng.below(self.states.len() as u64) as usize]
    }

    /// Write a wrong number over the payload and recompute the checksum, as an attacker
    /// (or a buggy tool) would: only a check of the values themselves can refuse it.
    fn forge(&mut self, bytes: &mut [c_char]) {
        if bytes.len() < HEADER + 16 {
            return;
        }
        let payload_end = bytes.len() - 8;
        let at = HEADER + self.rng.below((payload_end - HEADER - 8) as u64) as usize;
        let value = match self.rng.below(4) {
            0 => f64::NAN,
            1 => f64::INFINITY,
            _ => self.rng.extreme(),
        };
        for (k, b) in value.to_le_bytes().iter().enumerate() {
            bytes[at + k] = *b as c_char;
        }
        let payload: Vec<u8> = bytes[HEADER..payload_end]
            .iter()
            .map(|b| *b as u8)
            .collect();
        for (k, b) in fnv1a_64(&payload).to_le_bytes().iter().enumerate() {
            bytes[payload_end + k] = *b as c_char;
        }
    }

    /// The instance's serialized state (which must be obtainable wherever a state is).
    unsafe fn serialized(&mut self, state: fmi2FMUstate) -> Vec<c_char> {
        let c = self.c;
        let mut size = 0usize;
        unsafe {
            let s = fmi2SerializedFMUstateSize(c, state, &mut size);
            assert_eq!(s, fmi2Status_fmi2OK, "fmi2SerializedFMUstateSize");
            let mut bytes = vec![0 as c_char; size];
            let s = fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr(), size);
            assert_eq!(s, fmi2Status_fmi2OK, "fmi2SerializeFMUstate");
            self.calls += 2;
            bytes
        }
    }

    /// Every variable's value, read one at a time by its type, with the call's status: what
    /// a master can observe of the instance.
    unsafe fn observe(&mut self) -> Vec<(fmi2Status, u64)> {
        let c = self.c;
        (0..count() as u32)
            .map(|vr| unsafe {
                let (status, bits) = match variable(vr).map(|v| v.var_type()) {
                    Some(VarType::Real) => {
                        let mut x = 0.0;
                        (fmi2GetReal(c, &vr, 1, &mut x), x.to_bits())
                    }
                    Some(VarType::Boolean) => {
                        let mut x = 0;
                        (fmi2GetBoolean(c, &vr, 1, &mut x), x as u64)
                    }
                    _ => {
                        let mut x = 0;
                        (fmi2GetInteger(c, &vr, 1, &mut x), x as u64)
                    }
                };
                self.calls += 1;
                // A refused read leaves the output as it was: only the status counts.
                (status, if status == fmi2Status_fmi2OK { bits } else { 0 })
            })
            .collect()
    }

    /// The next call a master would make, with everything it returns: a step of 0.01 for
    /// Co-Simulation (then every variable), the derivatives, event indicators and states
    /// for Model Exchange.
    unsafe fn continuation(&mut self) -> Vec<(fmi2Status, u64)> {
        let c = self.c;
        let mut seen = Vec::new();
        unsafe {
            if self.exchange {
                let mut x = [0.0; 6];
                let mut z = [0.0; 1];
                let statuses = [
                    fmi2GetDerivatives(c, x.as_mut_ptr(), 6),
                    fmi2GetEventIndicators(c, z.as_mut_ptr(), 1),
                ];
                seen.extend(statuses.iter().map(|s| (*s, 0)));
                seen.extend(x.iter().chain(&z).map(|v| (0, v.to_bits())));
                let s = fmi2GetContinuousStates(c, x.as_mut_ptr(), 6);
                seen.push((s, 0));
                seen.extend(x.iter().map(|v| (0, v.to_bits())));
            } else {
                seen.push((fmi2DoStep(c, self.time, 0.01, 1), 0));
            }
        }
        self.calls += seen.len() as u64;
        seen.extend(unsafe { self.observe() });
        seen
    }

    /// Get the state, serialize it, deserialize the bytes and set the result: a buffer the
    /// FMU wrote always deserializes, and the instance is then exactly what it was: the
    /// same bytes when serialized again, the same value of every variable, and the same
    /// results of the next call. Counted by the FMI state the round trip was taken in.
    unsafe fn round_trip_exact(&mut self) {
        let c = self.c;
        let mut taken: fmi2FMUstate = null_mut();
        unsafe {
            if self.check(fmi2GetFMUstate(c, &mut taken), "fmi2GetFMUstate") != fmi2Status_fmi2OK {
                return;
            }
            let bytes = self.serialized(taken);
            let before = self.observe();
            let next = self.continuation();
            let mut restored: fmi2FMUstate = null_mut();
            let s = fmi2DeSerializeFMUstate(c, bytes.as_ptr(), bytes.len(), &mut restored);
            if s != fmi2Status_fmi2OK {
                panic!("a buffer the FMU wrote was refused: {}", refusal(&bytes));
            }
            assert_eq!(
                fmi2SetFMUstate(c, restored),
                fmi2Status_fmi2OK,
                "fmi2SetFMUstate"
            );
            let mut again: fmi2FMUstate = null_mut();
            assert_eq!(fmi2GetFMUstate(c, &mut again), fmi2Status_fmi2OK);
            assert!(
                self.serialized(again) == bytes,
                "the restored state serializes differently"
            );
            assert!(
                self.observe() == before,
                "a variable differs after the restore"
            );
            assert!(
                self.continuation() == next,
                "the next call differs after the restore"
            );
            for mut state in [taken, restored, again] {
                self.check(fmi2FreeFMUstate(c, &mut state), "fmi2FreeFMUstate");
            }
            *self.round_trips.entry(bytes[STATE_CODE] as u8).or_default() += 1;
        }
    }

    /// Serialize a state, damage the bytes sometimes, and deserialize.
    unsafe fn round_trip_serialized(&mut self) {
        let state = self.pick_state();
        let c = self.c;
        let mut size = 0usize;
        unsafe {
            if self.check(
                fmi2SerializedFMUstateSize(c, state, &mut size),
                "fmi2SerializedFMUstateSize",
            ) != fmi2Status_fmi2OK
            {
                return;
            }
            let mut bytes = vec![0 as c_char; size];
            let given = if self.rng.chance(10) { size / 2 } else { size };
            if self.check(
                fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr(), given),
                "fmi2SerializeFMUstate",
            ) != fmi2Status_fmi2OK
            {
                return;
            }
            let damage = self.rng.below(5);
            match damage {
                0 => bytes.truncate(self.rng.below(size as u64 + 1) as usize),
                1 => {
                    let i = self.rng.below(size as u64) as usize;
                    bytes[i] ^= 1 << self.rng.below(8);
                }
                2 => self.forge(&mut bytes),
                _ => {}
            }
            let mut restored: fmi2FMUstate = null_mut();
            let s = fmi2DeSerializeFMUstate(c, bytes.as_ptr(), bytes.len(), &mut restored);
            let status = self.check(s, "fmi2DeSerializeFMUstate");
            if damage > 2 && status != fmi2Status_fmi2OK {
                panic!("an unmodified buffer was refused: {}", refusal(&bytes));
            }
            if status == fmi2Status_fmi2OK {
                self.states.push(restored);
            }
        }
    }
}

#[test]
fn random_call_sequences_never_crash_and_return_only_documented_statuses() {
    let sequences = std::env::var("FUZZ_SEQUENCES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5000u64);
    let mut rng = Rng(0x9E3779B97F4A7C15);
    let mut total_calls = 0;
    let mut round_trips = BTreeMap::new();
    let mut longest = (Duration::ZERO, String::new());
    let mut violations: BTreeMap<&str, (u64, String)> = BTreeMap::new();
    for sequence in 0..sequences {
        let kind = if sequence % 2 == 0 {
            fmi2Type_fmi2CoSimulation
        } else {
            fmi2Type_fmi2ModelExchange
        };
        let c = common::instantiate_as(c"fuzz", kind);
        let mut fuzz = Fuzz {
            rng: Rng(rng.next() | 1),
            c,
            exchange: kind == fmi2Type_fmi2ModelExchange,
            time: 0.0,
            states: Vec::new(),
            calls: 0,
            round_trips: BTreeMap::new(),
            long_steps: long_steps(),
            longest: (Duration::ZERO, String::new()),
            inputs_set: [None; 2],
            violations: BTreeMap::new(),
        };
        let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
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
        // Free some states explicitly; the rest go with the instance.
        for mut state in fuzz.states.drain(..).step_by(2) {
            unsafe { fmi2FreeFMUstate(c, &mut state) };
        }
        total_calls += fuzz.calls;
        if fuzz.longest.0 > longest.0 {
            longest = (
                fuzz.longest.0,
                format!("sequence {sequence}: {}", fuzz.longest.1),
            );
        }
        for (rule, (n, first)) in std::mem::take(&mut fuzz.violations) {
            let entry = violations
                .entry(rule)
                .or_insert((0, format!("sequence {sequence}: {first}")));
            entry.0 += n;
        }
        for (state, n) in &fuzz.round_trips {
            *round_trips.entry(*state).or_insert(0u64) += n;
        }
        unsafe { fmi2FreeInstance(c) };
    }
    eprintln!(
        "fuzzed {sequences} sequences, {total_calls} calls; longest call {:.3} s ({})",
        longest.0.as_secs_f64(),
        longest.1
    );
    for (rule, (n, first)) in &violations {
        eprintln!("broken {n} times: {rule}; first: {first}");
    }
    eprintln!("exact round trips by FMI state code: {round_trips:?}");
    // `cargo xtask test` asks for the counts in its reports, which the docs quote.
    if let Some(report) = std::env::var_os("FUZZ_REPORT") {
        let states: Vec<String> = round_trips
            .iter()
            .map(|(code, n)| {
                let name = State::from_code(*code).map_or("?", |s| s.describe(Version::Fmi2));
                format!("\"{name}\": {n}")
            })
            .collect();
        let json = format!(
            "{{\"sequences\": {sequences}, \"calls\": {total_calls}, \
             \"round_trips_by_state\": {{{}}}, \"longest_call_s\": {:.3}, \"broken\": {}}}\n",
            states.join(", "),
            longest.0.as_secs_f64(),
            violations.values().map(|(n, _)| n).sum::<u64>()
        );
        std::fs::write(&report, json).expect("the fuzzer's report is writable");
    }
    assert!(violations.is_empty(), "oracles broken: {violations:?}");
    assert!(total_calls > sequences * 30);
    assert!(!round_trips.is_empty(), "no round trip was checked");
    common::assert_no_runaway(&longest);
}

/// A step longer than one call's work ends with Discard within that work, the FMU kept at
/// its last communication point, which fmi2LastSuccessfulTime reports ("the end time of
/// the last successfully completed communication step"); a step from another time than
/// the FMU's is refused, however long.
#[test]
fn no_step_runs_away() {
    let inputs = [
        cyclic_mechanism::variables::value_reference("M_m").expect("M_m"),
        cyclic_mechanism::variables::value_reference("M_r").expect("M_r"),
    ];
    for (name, h, torques) in [
        ("paper case 1", 1e300, [0.0, 0.0]),
        ("driven hard", 1e6, [17.0, -27.0]),
    ] {
        let c = common::instantiate(c"long");
        common::initialise(c, 1e-8, None, &[]);
        unsafe {
            assert_eq!(fmi2DoStep(c, 0.0, 0.102, 1), fmi2Status_fmi2OK);
            assert_eq!(
                fmi2SetReal(c, inputs.as_ptr(), 2, torques.as_ptr()),
                fmi2Status_fmi2OK
            );
            // The wrong communication point is refused before any work, however long the
            // step.
            assert_eq!(
                fmi2DoStep(c, -0.001, 1e12, 1),
                fmi2Status_fmi2Error,
                "{name}"
            );
            let start = Instant::now();
            let status = fmi2DoStep(c, 0.102, h, 1);
            let took = start.elapsed();
            let mut reached = f64::NAN;
            let kind = fmi2StatusKind_fmi2LastSuccessfulTime;
            assert_eq!(fmi2GetRealStatus(c, kind, &mut reached), fmi2Status_fmi2OK);
            eprintln!(
                "{name}: fmi2DoStep(0.102, {h:e}) -> status {status}, last successful time \
                 {reached}, {:.3} s",
                took.as_secs_f64()
            );
            assert_eq!(status, fmi2Status_fmi2Discard, "{name}");
            assert_eq!(reached, 0.102, "{name}");
            assert!(took < RUNAWAY, "{name}: {took:?}");
            fmi2FreeInstance(c);
        }
    }
}
