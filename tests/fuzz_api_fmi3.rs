//! Random FMI 3.0 call sequences with random, often invalid, arguments through the exported
//! fmi3 functions of both interfaces (Co-Simulation with and without event mode and early
//! return, Model Exchange; each also gets the other's calls), over geometries with change
//! points among others: never a crash, never fmi3Fatal (a caught panic, i.e. a bug), only
//! documented statuses, finite values whenever a read succeeds, a step's flags consistent
//! with its end, exact FMU state round trips, a Discarded step leaving the FMU as it was
//! and in Step Mode, no call of the logger with logging off or in a category switched off,
//! every `#` of a message escaped, and no call doing more work than one call may (the
//! longest call is reported). Deterministic (a fixed seed), and run under valgrind
//! memcheck by `cargo xtask test` (without the steps that spend a whole call's work).

use std::cell::RefCell;
use std::f64::consts::PI;
use std::ffi::{c_char, c_void, CStr, CString};
use std::ptr::{null, null_mut};
use std::time::{Duration, Instant};

mod common;

use common::{long_steps, Rng, RUNAWAY};

use cyclic_mechanism::drivers::cosimulation::CALL_WORK;
use cyclic_mechanism::fmi3::model_description::{instantiation_token, reference};
use cyclic_mechanism::fmi3::*;
use cyclic_mechanism::instance::{Instance, Interface, State};
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

/// The FMU's log categories, in the order of its model description.
const CATEGORIES: [&str; 6] = [
    "logStatusWarning",
    "logStatusDiscard",
    "logStatusError",
    "logStatusFatal",
    "logCalls",
    "logSolver",
];

/// What the logger saw, and which categories the master has enabled: the statuses' from
/// the start and the debug ones as `loggingOn` says, then as fmi3SetDebugLogging sets
/// them.
struct Log {
    enabled: [bool; 6],
    messages: u64,
    /// The last message of status Discard or worse.
    last_problem: String,
    /// Messages that broke a rule: the rule, and the message.
    broken: Vec<(&'static str, String)>,
}

impl Log {
    /// A fresh log for an instance whose `loggingOn` is `on`, boxed so that its address,
    /// the instance's environment, stays put.
    fn boxed(on: bool) -> Box<RefCell<Log>> {
        Box::new(RefCell::new(Log {
            enabled: [true, true, true, true, on, on],
            messages: 0,
            last_problem: String::new(),
            broken: Vec::new(),
        }))
    }
}

unsafe extern "C" fn log_message(
    environment: *mut c_void,
    status: fmi3Status,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: the environment is the fuzzer's `Log`; the strings are the FMU's, valid for
    // the call.
    let (log, category, message) = unsafe {
        (
            &*(environment as *const RefCell<Log>),
            CStr::from_ptr(category).to_string_lossy().into_owned(),
            CStr::from_ptr(message).to_string_lossy().into_owned(),
        )
    };
    let mut log = log.borrow_mut();
    log.messages += 1;
    if status >= fmi3Status_fmi3Discard {
        log.last_problem = message.clone();
    }
    let enabled = CATEGORIES
        .iter()
        .position(|c| *c == category)
        .is_some_and(|i| log.enabled[i]);
    if !enabled {
        let rule = "no log call with logging off or in a category switched off";
        log.broken.push((rule, format!("[{category}] {message}")));
    }
    if message.replace("##", "").contains('#') {
        log.broken.push(("every # of a message escaped", message));
    }
}

struct Fuzz {
    rng: Rng,
    c: fmi3Instance,
    log: Box<RefCell<Log>>,
    event_mode: bool,
    /// Whether steps that spend a whole call's work are tried.
    long_steps: bool,
    longest: (Duration, String),
    violations: std::collections::BTreeMap<&'static str, (u64, String)>,
    time: f64,
    states: Vec<fmi3FMUState>,
    calls: u64,
    round_trips: u64,
    early_returns: u64,
    discarded: u64,
    /// The logger's count of messages at the last call checked.
    said: u64,
}

impl Fuzz {
    fn check(&mut self, status: fmi3Status, what: &str) -> fmi3Status {
        self.calls += 1;
        assert!(documented(status), "{what} returned status {status}");
        self.judge_log(what);
        self.judge_said(status, what);
        status
    }

    /// Two sensitivity slots set at once to offered parameters (k12 or k34, the same one
    /// at times): legal in Co-Simulation before initialisation ends, whatever the slots
    /// held, so accepted; refused at the set in Model Exchange.
    unsafe fn set_two_slots(&mut self) {
        let slots = [
            vr3("sensitivity_1.parameter"),
            vr3("sensitivity_2.parameter"),
        ];
        let values = [5 + self.rng.below(2) as i64, 5 + self.rng.below(2) as i64];
        // SAFETY: the handle is the instance this fuzzer made and has not freed.
        let (interface, state) = unsafe {
            let instance = &*(self.c as *const Instance);
            (instance.interface(), instance.state())
        };
        let status = unsafe { fmi3SetInt64(self.c, slots.as_ptr(), 2, values.as_ptr(), 2) };
        self.check(status, "SetInt64 of two slots");
        let before_end = matches!(state, State::Instantiated | State::InitializationMode);
        let detail = format!("{values:?} in {state:?} returned {status}");
        if interface == Interface::CoSimulation && before_end && status != fmi3Status_fmi3OK {
            self.violated(
                "a slot's legal set is accepted whatever the others hold",
                detail,
            );
        } else if interface == Interface::ModelExchange && status == fmi3Status_fmi3OK {
            self.violated("Model Exchange refuses a slot at its set", detail);
        }
    }

    /// A Discard or worse, its status's category enabled, comes with a message.
    fn judge_said(&mut self, status: fmi3Status, what: &str) {
        let (messages, enabled) = {
            let log = self.log.borrow();
            // The categories of Discard, Error and Fatal: 1, 2 and 3.
            let category = if status == fmi3Status_fmi3Discard {
                1
            } else if status == fmi3Status_fmi3Error {
                2
            } else {
                3
            };
            (log.messages, log.enabled[category])
        };
        if status >= fmi3Status_fmi3Discard && enabled && messages == self.said {
            let rule = "every Discard or Error said with its reason";
            self.violated(rule, format!("{what} returned {status} without a message"));
        }
        self.said = messages;
    }

    /// The messages logged since the last judgement, against the logging rules.
    fn judge_log(&mut self, what: &str) {
        let broken = std::mem::take(&mut self.log.borrow_mut().broken);
        for (rule, message) in broken {
            self.violated(rule, format!("after {what}: {message}"));
        }
    }

    /// An oracle broken: counted, with its first instance, and failed at the end.
    fn violated(&mut self, rule: &'static str, detail: String) {
        let entry = self.violations.entry(rule).or_insert((0, detail));
        entry.0 += 1;
    }

    /// Time a call, keeping the longest.
    fn timed<T>(&mut self, what: &str, call: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let result = call();
        let took = start.elapsed();
        if took > self.longest.0 {
            self.longest = (took, what.to_string());
        }
        result
    }

    /// Every Float64 value the FMU reads out now (time, states, outputs), `None` where a
    /// read is refused.
    unsafe fn values(&mut self) -> Vec<Option<u64>> {
        (0..=count() as u32)
            .map(|vr| {
                let mut v = [0.0];
                let s = unsafe { fmi3GetFloat64(self.c, [vr].as_ptr(), 1, v.as_mut_ptr(), 1) };
                (s == fmi3Status_fmi3OK).then_some(v[0].to_bits())
            })
            .collect()
    }

    /// The right-hand sides counted so far, if the FMU reads them out now.
    unsafe fn work(&mut self) -> Option<i64> {
        let mut n = [0i32];
        let s = unsafe { fmi3GetInt32(self.c, [vr3("n_rhs")].as_ptr(), 1, n.as_mut_ptr(), 1) };
        (s == fmi3Status_fmi3OK).then_some(i64::from(n[0]))
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
                    self.set_two_slots();
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
                    let names = [
                        c"logSolver".as_ptr(),
                        c"logStatusError".as_ptr(),
                        c"non#sense#".as_ptr(),
                    ];
                    let n = self.rng.below(4) as usize;
                    let first = self.rng.below(3) as usize;
                    let names = &names[first.min(3 - n)..];
                    let on = self.rng.chance(50);
                    let s = fmi3SetDebugLogging(c, on, n, names.as_ptr());
                    if s == fmi3Status_fmi3OK {
                        let listed: Vec<String> = names[..n]
                            .iter()
                            .map(|p| CStr::from_ptr(*p).to_string_lossy().into_owned())
                            .collect();
                        let mut log = self.log.borrow_mut();
                        for (category, enabled) in CATEGORIES.iter().zip(&mut log.enabled) {
                            if n == 0 || listed.iter().any(|l| l == category) {
                                *enabled = on;
                            }
                        }
                    }
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
    /// with where it ended, a Discard must leave the FMU as it was and in Step Mode, and
    /// no step may do more work than one call may. With event handling needed the master
    /// handles it.
    unsafe fn step(&mut self) {
        let c = self.c;
        let lengths = [1e-3, 0.01, 0.1, 0.5, 2.0, -1.0, f64::NAN, 1e6, 1e300];
        let kinds = if self.long_steps { 9 } else { 7 };
        let mut h = lengths[self.rng.below(kinds) as usize];
        if h > 2.0 && !self.rng.chance(10) {
            h = 0.1;
        }
        let from = if self.rng.chance(90) {
            self.time
        } else {
            self.rng.real()
        };
        let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
        unsafe {
            let (before, work_before) = (self.values(), self.work());
            let s = self.timed(&format!("fmi3DoStep({from}, {h})"), || {
                fmi3DoStep(
                    c, from, h, true, &mut event, &mut stop, &mut early, &mut last,
                )
            });
            let status = self.check(s, "fmi3DoStep");
            if let (Some(a), Some(b)) = (work_before, self.work()) {
                if b - a > CALL_WORK as i64 + 1000 {
                    let detail = format!("fmi3DoStep({from}, {h}): {} right-hand sides", b - a);
                    self.violated("no call does more work than one call may", detail);
                }
            }
            if status == fmi3Status_fmi3OK {
                assert!(!stop);
                assert!(last.is_finite());
                if early {
                    assert!(last < from + h, "early at {last}, step {from} + {h}");
                    if event {
                        self.early_returns += 1;
                    }
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
            } else if status == fmi3Status_fmi3Discard {
                self.discarded += 1;
                // "fmi3Discard: the call was not successful and the FMU is in the same state
                // as before the call": the same values, and Step Mode's calls allowed.
                let same = "a Discard leaves the FMU as before the call";
                if self.values() != before {
                    self.violated(same, format!("fmi3DoStep({from}, {h}) moved the values"));
                }
                let time_before = before[0].map(f64::from_bits);
                if Some(last) != time_before {
                    let detail = format!("fmi3DoStep({from}, {h}): lastSuccessfulTime {last}");
                    self.violated(same, detail);
                }
                let legal = "Step Mode's calls allowed after a Discard";
                let input = [vr3("M_m")];
                let mut value = [0.0];
                fmi3GetFloat64(c, input.as_ptr(), 1, value.as_mut_ptr(), 1);
                if fmi3SetFloat64(c, input.as_ptr(), 1, value.as_ptr(), 1) != fmi3Status_fmi3OK {
                    self.violated(
                        legal,
                        format!("fmi3SetFloat64 after fmi3DoStep({from}, {h})"),
                    );
                }
                if self.event_mode {
                    if fmi3EnterEventMode(c) == fmi3Status_fmi3OK {
                        self.check(fmi3EnterStepMode(c), "fmi3EnterStepMode");
                    } else {
                        let detail = format!("fmi3EnterEventMode after fmi3DoStep({from}, {h})");
                        self.violated(legal, detail);
                    }
                }
                self.judge_log("the calls after a Discard");
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
/// mode; 3: with event mode and early return), its geometry a change-point one or not, its
/// messages going to `log`; `#` in its name, which no message may leave unescaped.
unsafe fn instantiate(
    kind: u64,
    change_point: bool,
    logging_on: bool,
    log: &RefCell<Log>,
) -> fmi3Instance {
    let token = CString::new(instantiation_token()).expect("no NUL");
    let name = c"fuzz#3#";
    let environment = log as *const RefCell<Log> as *mut c_void;
    let c = unsafe {
        if kind == 0 {
            fmi3InstantiateModelExchange(
                name.as_ptr(),
                token.as_ptr(),
                null(),
                false,
                logging_on,
                environment,
                Some(log_message),
            )
        } else {
            fmi3InstantiateCoSimulation(
                name.as_ptr(),
                token.as_ptr(),
                null(),
                false,
                logging_on,
                kind >= 2,
                kind == 3,
                null(),
                0,
                environment,
                Some(log_message),
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

/// An instantiation the FMU cannot make (a wrong token, a blank or missing name): NULL,
/// with a message whatever `loggingOn`. The oracle broken, if one is.
unsafe fn refused_instantiation(
    rng: &mut Rng,
    logging_on: bool,
    log: &RefCell<Log>,
) -> Option<(&'static str, String)> {
    let good = instantiation_token();
    let tokens = [
        String::new(),
        format!(" {good}"),
        format!("{good}\t"),
        good[1..].to_string(),
        "{".repeat(3000),
    ];
    let token = CString::new(tokens[rng.below(tokens.len() as u64) as usize].clone()).ok()?;
    let good = CString::new(good).ok()?;
    let names = [c"".as_ptr(), c"  ".as_ptr(), null()];
    let (name, token) = if rng.chance(50) {
        (names[rng.below(3) as usize], good.as_ptr())
    } else {
        (c"bad".as_ptr(), token.as_ptr())
    };
    let before = log.borrow().messages;
    let environment = log as *const RefCell<Log> as *mut c_void;
    let c = unsafe {
        fmi3InstantiateModelExchange(
            name,
            token,
            null(),
            false,
            logging_on,
            environment,
            Some(log_message),
        )
    };
    if !c.is_null() {
        unsafe { fmi3FreeInstance(c) };
        return Some(("an impossible instantiation returns NULL", String::new()));
    }
    (log.borrow().messages == before).then(|| {
        let rule = "a NULL instantiation says why";
        (rule, format!("loggingOn = {logging_on}"))
    })
}

#[test]
fn random_fmi3_call_sequences_never_crash_and_return_only_documented_statuses() {
    let sequences = std::env::var("FUZZ_SEQUENCES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3000u64);
    let mut rng = Rng(0xD1B54A32D192ED03);
    let (mut calls, mut round_trips, mut early_returns, mut discarded) = (0, 0, 0, 0);
    let mut messages = 0;
    let mut longest = (Duration::ZERO, String::new());
    let mut violations: std::collections::BTreeMap<&str, (u64, String)> = Default::default();
    for sequence in 0..sequences {
        let logging_on = rng.chance(50);
        let log = Log::boxed(logging_on);
        if rng.chance(10) {
            // SAFETY: the arguments are valid C strings or NULL.
            if let Some(broken) = unsafe { refused_instantiation(&mut rng, logging_on, &log) } {
                let entry = violations.entry(broken.0).or_insert((0, broken.1));
                entry.0 += 1;
            }
        }
        let kind = sequence % 4;
        let c = unsafe { instantiate(kind, rng.chance(50), logging_on, &log) };
        let mut fuzz = Fuzz {
            rng: Rng(rng.next() | 1),
            c,
            log,
            event_mode: kind >= 2,
            long_steps: long_steps(),
            longest: (Duration::ZERO, String::new()),
            violations: Default::default(),
            time: 0.0,
            states: Vec::new(),
            calls: 0,
            round_trips: 0,
            early_returns: 0,
            discarded: 0,
            said: 0,
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
        discarded += fuzz.discarded;
        messages += fuzz.log.borrow().messages;
        for (rule, (n, first)) in std::mem::take(&mut fuzz.violations) {
            let entry = violations
                .entry(rule)
                .or_insert((0, format!("sequence {sequence}: {first}")));
            entry.0 += n;
        }
        if fuzz.longest.0 > longest.0 {
            longest = (
                fuzz.longest.0,
                format!("sequence {sequence}: {}", fuzz.longest.1),
            );
        }
        unsafe { fmi3FreeInstance(c) };
    }
    eprintln!(
        "fuzzed {sequences} FMI 3.0 sequences, {calls} calls, {round_trips} exact round trips, \
         {early_returns} early returns at change points, {discarded} Discards, {messages} \
         messages logged; longest call {:.3} s ({})",
        longest.0.as_secs_f64(),
        longest.1
    );
    // `cargo xtask test` asks for the counts in its reports, which the docs quote.
    if let Some(report) = std::env::var_os("FUZZ_REPORT_FMI3") {
        let json = format!(
            "{{\"sequences\": {sequences}, \"calls\": {calls}, \"round_trips\": {round_trips}, \
             \"early_returns\": {early_returns}, \"discards\": {discarded}, \
             \"messages\": {messages}, \"longest_call_s\": {:.3}, \"broken\": {}}}\n",
            longest.0.as_secs_f64(),
            violations.values().map(|(n, _)| n).sum::<u64>()
        );
        std::fs::write(&report, json).expect("the fuzzer's report is writable");
    }
    for (rule, (n, first)) in &violations {
        eprintln!("broken {n} times: {rule}; first: {first}");
    }
    assert!(violations.is_empty(), "oracles broken: {violations:?}");
    assert!(calls > sequences * 30);
    assert!(round_trips > 0, "no round trip was checked");
    assert!(discarded > 0, "no step was discarded");
    assert!(messages > 0, "nothing was logged");
    assert!(
        early_returns > 0,
        "no step returned early at a change point"
    );
    common::assert_no_runaway(&longest);
}

/// A Co-Simulation instance with the given flags, logging on into `log`, initialised with
/// `parameters` (by name; `builtin_laws` as 0 or 1), in Step Mode.
unsafe fn started(
    event_mode: bool,
    early_return: bool,
    parameters: &[(&str, f64)],
    log: &RefCell<Log>,
) -> fmi3Instance {
    let kind = 1 + u64::from(event_mode) + u64::from(early_return);
    let c = unsafe { instantiate(kind, false, true, log) };
    unsafe {
        assert_eq!(
            fmi3EnterInitializationMode(c, true, 1e-8, 0.0, false, 0.0),
            fmi3Status_fmi3OK
        );
        for (name, value) in parameters {
            let vr = [vr3(name)];
            let status = if *name == "builtin_laws" {
                fmi3SetBoolean(c, vr.as_ptr(), 1, [*value != 0.0].as_ptr(), 1)
            } else if *name == "solver" {
                fmi3SetInt64(c, vr.as_ptr(), 1, [*value as i64].as_ptr(), 1)
            } else {
                fmi3SetFloat64(c, vr.as_ptr(), 1, [*value].as_ptr(), 1)
            };
            assert_eq!(status, fmi3Status_fmi3OK, "{name}");
        }
        assert_eq!(fmi3ExitInitializationMode(c), fmi3Status_fmi3OK);
        if event_mode {
            assert_eq!(fmi3EnterStepMode(c), fmi3Status_fmi3OK);
        }
    }
    c
}

/// The change-point linkage whose one step crossed about 800 change points for a minute.
const WANDERING: [(&str, f64); 3] = [("L", 0.95), ("phi2_0", 1.0742), ("omega2_0", -5.4821)];

/// A run's name, its parameters, and whether event mode and early return are used.
type Case<'a> = (&'a str, &'a [(&'a str, f64)], bool, bool);

/// Steps of any length end within the work one call may do: where early return is
/// allowed, early and OK where they got to, the run going on from there; otherwise a
/// Discard that leaves the FMU as it was. Each call is timed (reported, and held far below
/// the minutes they once took).
#[test]
fn no_step_runs_away() {
    let cases: [Case; 5] = [
        // Radau IIA's steps, the costliest per right-hand side.
        (
            "implicit, stiff springs",
            &[("solver", 3.0), ("k12", 1e7), ("k34", 1e7)],
            false,
            false,
        ),
        ("change points, event mode", &WANDERING, true, false),
        ("change points, early return", &WANDERING, true, true),
        ("paper case 1, plain", &[], false, false),
        ("paper case 1, early return", &[], true, true),
    ];
    for (name, parameters, event_mode, early_return) in cases {
        let log = Log::boxed(true);
        let c = unsafe { started(event_mode, early_return, parameters, &log) };
        let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
        let start = Instant::now();
        let status = unsafe {
            fmi3DoStep(
                c, 0.0, 1e300, true, &mut event, &mut stop, &mut early, &mut last,
            )
        };
        let took = start.elapsed();
        eprintln!(
            "{name}: fmi3DoStep(0, 1e300) -> status {status}, early {early}, event {event}, \
             lastSuccessfulTime {last}, {:.3} s {}",
            took.as_secs_f64(),
            log.borrow().last_problem
        );
        assert!(took < RUNAWAY, "{name}: {took:?}");
        assert!(log.borrow().broken.is_empty(), "{:?}", log.borrow().broken);
        if early_return {
            assert_eq!(status, fmi3Status_fmi3OK, "{name}");
            assert!(early && last > 0.0, "{name}: early {early} at {last}");
            // The run goes on from where the step got to.
            let mut again = (false, false, false, f64::NAN);
            let status = unsafe {
                fmi3DoStep(
                    c,
                    last,
                    0.01,
                    true,
                    &mut again.0,
                    &mut again.1,
                    &mut again.2,
                    &mut again.3,
                )
            };
            assert!(
                status == fmi3Status_fmi3OK || event,
                "{name}: the next step: {status}"
            );
        } else {
            assert_eq!(status, fmi3Status_fmi3Discard, "{name}");
            assert_eq!(last, 0.0, "{name}: a Discard leaves the FMU at its time");
            let mut t = [f64::NAN];
            unsafe { fmi3GetFloat64(c, [0].as_ptr(), 1, t.as_mut_ptr(), 1) };
            assert_eq!(t[0], 0.0, "{name}");
        }
        unsafe { fmi3FreeInstance(c) };
    }
}

/// A change point's event, as a master handles it: event mode, the discrete states
/// updated, back to step mode, each call answered OK.
unsafe fn handle_event(c: fmi3Instance) {
    let mut flags = [false; 5];
    let mut next = 0.0;
    let [a, b, d, e, f] = &mut flags;
    assert_eq!(fmi3EnterEventMode(c), fmi3Status_fmi3OK);
    let s = fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next);
    assert_eq!(s, fmi3Status_fmi3OK);
    assert_eq!(fmi3EnterStepMode(c), fmi3Status_fmi3OK);
}

/// The parallelogram and the kite, whose change points the integrator can step over (on
/// their parallelogram branch the constraint stays regular up to the node): with event
/// mode and early return every change point is an early return, and a run goes on through
/// all of them to its end.
#[test]
fn special_change_point_linkages_return_early_at_each_change_point() {
    let lengths = |l, l2, l3, big_l| {
        [
            ("l", l),
            ("l2", l2),
            ("l3", l3),
            ("L", big_l),
            ("phi2_0", 1.0),
            ("omega2_0", 3.0),
            ("builtin_laws", 0.0),
        ]
    };
    for (name, parameters) in [
        ("parallelogram", lengths(0.5, 0.5, 0.5, 0.5)),
        ("kite", lengths(0.5, 0.3, 0.5, 0.3)),
    ] {
        let log = Log::boxed(true);
        let c = unsafe { started(true, true, &parameters, &log) };
        // Steps of 10 ms, so that the crank's angle is seen often enough to count, apart
        // from the FMU's events, each passage of the crank through the frame's line (φ2 a
        // multiple of π), where crank, rod and rocker of these linkages fall collinear.
        let (mut t, mut events, mut passages) = (0.0, 0, 0);
        let mut half_turns = unsafe { (states(c)[1] / PI).floor() };
        while t < 5.0 && events < 100 {
            let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
            let status = unsafe {
                fmi3DoStep(
                    c,
                    t,
                    (5.0 - t).min(0.01),
                    true,
                    &mut event,
                    &mut stop,
                    &mut early,
                    &mut last,
                )
            };
            let problem = log.borrow().last_problem.clone();
            assert_eq!(status, fmi3Status_fmi3OK, "{name} at t = {t}: {problem}");
            assert_eq!(early, event, "{name}: an early return is a change point's");
            t = last;
            if event {
                events += 1;
                unsafe { handle_event(c) };
            }
            let now = unsafe { (states(c)[1] / PI).floor() };
            passages += (now - half_turns).abs() as usize;
            half_turns = now;
        }
        eprintln!("{name}: {events} change points, {passages} passages to t = 5");
        assert_eq!(t, 5.0, "{name}");
        assert!(events > 0, "{name}: no change point met");
        assert_eq!(
            events, passages,
            "{name}: a change point without its event, or one twice"
        );
        unsafe { fmi3FreeInstance(c) };
    }
}

/// The states (φ1..φ4, ω1..ω4) read out now.
unsafe fn states(c: fmi3Instance) -> [f64; 8] {
    let names = [
        "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
    ];
    let vrs: Vec<u32> = names.iter().map(|n| vr3(n)).collect();
    let mut y = [f64::NAN; 8];
    let status = unsafe { fmi3GetFloat64(c, vrs.as_ptr(), 8, y.as_mut_ptr(), 8) };
    assert_eq!(status, fmi3Status_fmi3OK);
    y
}

/// Steps of `h` from `t` to `until` (the last one shorter), every one OK; the time reached.
unsafe fn step_to(c: fmi3Instance, mut t: f64, h: f64, until: f64) -> f64 {
    while t < until {
        let step = h.min(until - t);
        let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
        let status = unsafe {
            fmi3DoStep(
                c, t, step, true, &mut event, &mut stop, &mut early, &mut last,
            )
        };
        assert_eq!(status, fmi3Status_fmi3OK, "the step from {t} of {step}");
        assert!(!early, "an early return at {last} on the way from {t}");
        t = last;
    }
    t
}

/// A master on a fine grid passes a change point: the crossing (about 2.5e-4 s) spans its
/// steps, the linkage shown on its way, and after it the run agrees with one whose step
/// held the whole crossing; an FMU state saved on the way restores and goes on bit for
/// bit.
/// A communication step that ends just before a change point the integrator has already
/// stepped past (its steps run ahead of the communication points) is completed, not
/// refused: with and without early return, a parallelogram on a grid of 0.01 s runs
/// through its change points to its end.
#[test]
fn a_change_point_past_the_step_end_does_not_refuse_the_step() {
    let parameters = [
        ("l", 0.5),
        ("l2", 0.5),
        ("l3", 0.5),
        ("L", 0.5),
        ("phi2_0", 1.0),
        ("omega2_0", 3.0),
        ("builtin_laws", 0.0),
    ];
    for early_return in [false, true] {
        let log = Log::boxed(true);
        let c = unsafe { started(true, early_return, &parameters, &log) };
        let (mut t, mut events) = (0.0, 0);
        for k in 1..=500 {
            let next = f64::from(k) * 0.01;
            while t < next {
                let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
                let status = unsafe {
                    fmi3DoStep(
                        c,
                        t,
                        next - t,
                        true,
                        &mut event,
                        &mut stop,
                        &mut early,
                        &mut last,
                    )
                };
                let problem = log.borrow().last_problem.clone();
                assert_eq!(status, fmi3Status_fmi3OK, "at t = {t}: {problem}");
                t = if early { last } else { next };
                if event {
                    events += 1;
                    unsafe { handle_event(c) };
                }
            }
        }
        assert!(
            events > 0,
            "early return {early_return}: no change point met"
        );
        unsafe { fmi3FreeInstance(c) };
    }
}

#[test]
fn a_fine_grid_passes_a_change_point() {
    let parameters = [
        ("L", 0.95),
        ("phi2_0", std::f64::consts::FRAC_PI_2),
        ("omega2_0", 4.0),
        ("builtin_laws", 0.0),
    ];
    for branch in [1i64, 2] {
        let log = Log::boxed(true);
        let c = unsafe { started(true, true, &parameters, &log) };
        let mut t = 0.0;
        unsafe {
            loop {
                let (mut event, mut stop, mut early, mut last) = (false, false, false, f64::NAN);
                let status = fmi3DoStep(
                    c, t, 1e-3, true, &mut event, &mut stop, &mut early, &mut last,
                );
                assert_eq!(status, fmi3Status_fmi3OK);
                t = last;
                if early {
                    break;
                }
                assert!(t < 6.0, "no change point met");
            }
            assert_eq!(fmi3EnterEventMode(c), fmi3Status_fmi3OK);
            let vr = [vr3("change_point_branch")];
            assert_eq!(
                fmi3SetInt64(c, vr.as_ptr(), 1, [branch].as_ptr(), 1),
                fmi3Status_fmi3OK
            );
            let mut flags = [false; 5];
            let mut next = 0.0;
            let [a, b, d, e, f] = &mut flags;
            assert_eq!(
                fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next),
                fmi3Status_fmi3OK
            );
            assert_eq!(fmi3EnterStepMode(c), fmi3Status_fmi3OK);
            let mut at_event: fmi3FMUState = null_mut();
            assert_eq!(fmi3GetFMUState(c, &mut at_event), fmi3Status_fmi3OK);
            let mut energy_at_event = f64::NAN;
            fmi3GetFloat64(c, [vr3("energy")].as_ptr(), 1, &mut energy_at_event, 1);
            // A state saved on the way restores, and the run goes on bit for bit.
            let on_the_way = step_to(c, t, 1e-5, t + 5e-5);
            let mut saved: fmi3FMUState = null_mut();
            assert_eq!(fmi3GetFMUState(c, &mut saved), fmi3Status_fmi3OK);
            let bytes = serialized(c, saved);
            step_to(c, on_the_way, 1e-4, t + 0.01);
            let straight_on = states(c);
            let mut restored: fmi3FMUState = null_mut();
            let s = fmi3DeserializeFMUState(c, bytes.as_ptr(), bytes.len(), &mut restored);
            assert_eq!(
                s, fmi3Status_fmi3OK,
                "a state on a crossing's way was refused"
            );
            assert_eq!(fmi3SetFMUState(c, restored), fmi3Status_fmi3OK);
            step_to(c, on_the_way, 1e-4, t + 0.01);
            assert!(states(c) == straight_on, "the restored run differs");
            for mut state in [saved, restored] {
                fmi3FreeFMUState(c, &mut state);
            }
            assert_eq!(fmi3SetFMUState(c, at_event), fmi3Status_fmi3OK);
            let until = t + 0.01;
            // The reference: the whole crossing within one step.
            step_to(c, t, 1e-3, until);
            let whole = states(c);
            for h in [1e-4, 1e-5, 1e-9] {
                assert_eq!(fmi3SetFMUState(c, at_event), fmi3Status_fmi3OK);
                // The finest grid only through the crossing, then on at 1e-4.
                let through = if h < 1e-6 { t + 1e-6 } else { t };
                let reached = step_to(c, t, h, through);
                step_to(c, reached, h.max(1e-4), t + 1e-4);
                // On the way: all outputs readable and finite.
                let on_the_way = states(c);
                assert!(on_the_way.iter().all(|v| v.is_finite()));
                let mut out = [f64::NAN; 3];
                let vrs = [vr3("energy"), vr3("rod_force"), vr3("constraint_residual")];
                let status = fmi3GetFloat64(c, vrs.as_ptr(), 3, out.as_mut_ptr(), 3);
                assert_eq!(status, fmi3Status_fmi3OK);
                // No torques: the crossing's path keeps the energy, and the loop closed.
                let drift = (out[0] - energy_at_event) / energy_at_event;
                assert!(drift.abs() < 1e-9 && out[2].abs() < 1e-12, "{out:?}");
                step_to(c, t + 1e-4, h.max(1e-4), until);
                let fine = states(c);
                let worst = whole
                    .iter()
                    .zip(&fine)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                eprintln!("branch {branch}, h = {h:e}: worst difference at t0 + 0.01 {worst:e}");
                assert!(worst < 1e-9, "branch {branch}, h = {h}: {worst}");
            }
            let mut at = at_event;
            fmi3FreeFMUState(c, &mut at);
            fmi3FreeInstance(c);
        }
    }
}
