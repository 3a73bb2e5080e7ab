//! Work-precision harness. `bench <CyclicMechanism.fmu> <out.json> [--quick]`
//!
//! Runs each scenario × communication step H × tolerance through
//! - the packed FMU, loaded from the `.fmu` with libloading (fmi-sys's `Fmi2Binding`),
//!   driven by a master loop that reads every output after every step;
//! - the Rust crates ode_solvers (Dop853) and diffsol (tsit45, bdf, esdirk34) with the
//!   same right-hand side, stepped between the same communication points as a doStep
//!   would: ode_solvers restarted for each interval (its API integrates one span), diffsol
//!   kept alive and stopped at each point.
//!
//! Every method is timed by the same rule ([`TIMING`]): the fastest of at least 10 runs
//! and 0.2 s of repetitions (at least 3 runs for runs over a second). It also measures the
//! right-hand side alone (ns per evaluation). It records timings and the
//! states at 100 evenly spaced points; the Python driver computes the errors against the
//! reference and writes the table and plot.

mod compiled;
mod fmu;
mod peers;

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use cyclic_mechanism::model::{self, Inputs, Parameters, State};

/// A benchmark scenario: parameters by FMI name, whether the built-in torque laws apply
/// (`builtin_laws`), the stop time, and the FMU's `solver` (1 auto, 2 dop853, 3 implicit).
pub struct Scenario {
    pub name: &'static str,
    pub stop: f64,
    pub values: &'static [(&'static str, f64)],
    pub builtin_laws: bool,
    pub solver: i32,
}

pub const SCENARIOS: [Scenario; 2] = [
    Scenario {
        name: "case1",
        stop: 10.0,
        values: &[
            ("Mm_a0", 100.0),
            ("Mm_a1", -20.0),
            ("Mm_a2", -1.0),
            ("Mr_b0", 20.0),
            ("Mr_b1", -0.05),
        ],
        builtin_laws: true,
        solver: 1,
    },
    Scenario {
        name: "free",
        stop: 100.0,
        values: &[
            ("omega2_0", 6.0),
            ("twist12_0", 0.2),
            ("twist34_0", -0.1),
            ("omega4_0", -1.0),
        ],
        builtin_laws: false,
        solver: 1,
    },
];

/// Stiff, damped couplings: k12 = k34 = 1e7, d12 = d34 = 1e3, paper laws, 1 s.
const STIFF_VALUES: &[(&str, f64)] = &[
    ("Mm_a0", 100.0),
    ("Mm_a1", -20.0),
    ("Mm_a2", -1.0),
    ("Mr_b0", 20.0),
    ("Mr_b1", -0.05),
    ("k12", 1e7),
    ("k34", 1e7),
    ("d12", 1e3),
    ("d34", 1e3),
];

/// The stiff case with each `solver` choice, at H = 1e-2 and tolerance 1e-6.
fn stiff_study(fmu: &fmu::Fmu, out: &mut String) {
    let scenario = |name, solver| Scenario {
        name,
        stop: 1.0,
        values: STIFF_VALUES,
        builtin_laws: true,
        solver,
    };
    // The reference: DOP853 at 1e-12 (the implicit method's error is then independent).
    let Some(reference) = fmu.run(&scenario("reference", 2), 1e-2, 1e-12) else {
        eprintln!("stiff reference failed");
        return;
    };
    let exact = reference.states.last().copied().unwrap_or_default();
    out.push_str(", \"stiff\": [");
    for (i, (name, solver)) in [("auto", 1), ("dop853", 2), ("implicit", 3)]
        .iter()
        .enumerate()
    {
        let case = scenario(name, *solver);
        let run = || fmu.run(&case, 1e-2, 1e-6);
        let Some((seconds, runs, o)) = timed(&TIMING, run) else {
            eprintln!("stiff {name}: failed");
            continue;
        };
        let last = o.states.last().copied().unwrap_or_default();
        let error = last
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "stiff {name}: n_rhs {} error {error:e} {seconds:.4} s",
            o.n_rhs
        );
        write!(
            out,
            "{}{{\"solver\": \"{name}\", \"seconds\": {seconds:e}, \"runs\": {runs}, \"n_rhs\": {}, \"error\": {}}}",
            if i == 0 { "" } else { ", " },
            o.n_rhs,
            number(error)
        )
        .unwrap();
    }
    out.push(']');
}

/// Number of evenly spaced sample points recorded per run (the last is the final time).
pub const SAMPLES: usize = 100;

impl Scenario {
    pub fn parameters(&self) -> Parameters {
        let mut p = Parameters {
            builtin_laws: self.builtin_laws,
            ..Parameters::default()
        };
        for (name, value) in self.values {
            p.set_by_name(name, *value)
                .expect("scenario parameters are valid");
        }
        p
    }

    pub fn initial_state(&self) -> State {
        model::initial_state(&self.parameters()).expect("scenario assembles")
    }
}

/// The independent reference (tests/python/reference.py at rtol 1e-13, written by
/// `bench.py reference`) at every point of the finest communication grid: a file of
/// little-endian f64, the grid step first, then 8 states per point from t = 0.
pub struct Reference {
    step: f64,
    points: Vec<State>,
    /// Each state's scale, max(1, max |y|) over the run: errors are measured in it.
    scale: State,
}

impl Reference {
    fn load(path: &std::path::Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let values: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        let (step, rows) = values.split_first().ok_or("empty reference")?;
        let points: Vec<State> = rows
            .chunks_exact(8)
            .map(|r| r.try_into().expect("8 states"))
            .collect();
        let mut scale = [1.0f64; 8];
        for y in &points {
            for (s, v) in scale.iter_mut().zip(y) {
                *s = s.max(v.abs());
            }
        }
        Ok(Self {
            step: *step,
            points,
            scale,
        })
    }
}

/// The worst error over every communication point and state, in units of each state's
/// scale: what a user who plots the outputs sees.
pub struct PointError<'a> {
    reference: Option<&'a Reference>,
    /// Reference points per communication step.
    stride: usize,
    worst: f64,
}

impl<'a> PointError<'a> {
    pub fn new(reference: Option<&'a Reference>, h: f64) -> Self {
        let stride = reference.map_or(0, |r| (h / r.step).round() as usize);
        Self {
            reference,
            stride,
            worst: 0.0,
        }
    }

    /// The state `y` at communication point `k` (time k·h).
    #[inline]
    pub fn record(&mut self, k: usize, y: &State) {
        let Some(reference) = self.reference else {
            return;
        };
        let expected = &reference.points[k * self.stride];
        for i in 0..8 {
            self.worst = self
                .worst
                .max((y[i] - expected[i]).abs() / reference.scale[i]);
        }
    }

    /// NaN when no reference was given.
    pub fn value(&self) -> f64 {
        if self.reference.is_some() {
            self.worst
        } else {
            f64::NAN
        }
    }
}

/// What one run of a method gives: the state at every communication point from t = 0, kept
/// as a master keeps its results, and the evaluations the run took. This is all a timed
/// run does besides the method's own work; [`Outcome::of`] analyses it afterwards.
pub struct Run {
    pub states: Vec<State>,
    pub n_rhs: u64,
}

impl Run {
    /// Room for every point of `scenario` at step `h`, zeroed but for `y0` at t = 0: every
    /// method pays the same for its storage (DOP853's and LSODA's wrappers write into it
    /// directly, the FMU's loop reads into it).
    pub fn start(scenario: &Scenario, h: f64, y0: &State) -> Self {
        let mut states = vec![[0.0; 8]; (scenario.stop / h).round() as usize + 1];
        states[0] = *y0;
        Self { states, n_rhs: 0 }
    }
}

/// What one method did on one configuration.
pub struct Outcome {
    pub seconds: f64,
    pub runs: usize,
    /// State at each sample point, in order.
    pub samples: Vec<State>,
    /// |A2A3| − L, the largest over every point.
    pub max_residual: f64,
    pub max_energy_drift: f64,
    /// [`PointError`]'s value.
    pub max_point_error: f64,
    pub n_rhs: u64,
}

impl Outcome {
    /// The analysis of `run`, after its timing: the same for every method, from the states
    /// it gave (the FMU's `constraint_residual` and `energy` outputs are not read, so the
    /// FMU is timed reading what the peers give, the eight states).
    pub fn of(
        scenario: &Scenario,
        h: f64,
        run: Run,
        reference: Option<&Reference>,
        (seconds, runs): (f64, usize),
    ) -> Self {
        let p = scenario.parameters();
        let energy0 = model::energy(&p, &run.states[0]);
        let every = ((run.states.len() - 1) / SAMPLES).max(1);
        let mut errors = PointError::new(reference, h);
        let (mut max_residual, mut max_drift) = (0.0f64, 0.0f64);
        for (k, y) in run.states.iter().enumerate().skip(1) {
            max_residual = max_residual.max(model::length_residual(&p, y[1], y[2]).abs());
            let drift = (model::energy(&p, y) - energy0).abs() / energy0.abs().max(1e-300);
            max_drift = max_drift.max(drift);
            errors.record(k, y);
        }
        Self {
            seconds,
            runs,
            samples: run
                .states
                .iter()
                .skip(every)
                .step_by(every)
                .copied()
                .collect(),
            max_residual,
            max_energy_drift: max_drift,
            max_point_error: errors.value(),
            n_rhs: run.n_rhs,
        }
    }
}

/// How long one configuration is timed, the same rule for the FMU and every peer.
pub struct Timing {
    /// Repeat until at least this many runs …
    pub min_runs: usize,
    /// … and at least this much time spent: sub-millisecond runs are repeated hundreds of
    /// times, so that their minimum is not one cold start on a shared machine.
    pub min_total: Duration,
    /// Stop after this much time once `slow_runs` runs are done (slow peers at small H).
    pub slow_total: Duration,
    pub slow_runs: usize,
}

/// One run longer than this (s) ends a method's sweep toward tighter tolerances.
const TOO_SLOW: f64 = 10.0;

pub const TIMING: Timing = Timing {
    min_runs: 10,
    min_total: Duration::from_millis(200),
    slow_total: Duration::from_secs(4),
    slow_runs: 3,
};

/// Time `run` repeatedly under `timing` and return the fastest run with its result.
pub fn timed<T>(timing: &Timing, mut run: impl FnMut() -> Option<T>) -> Option<(f64, usize, T)> {
    let mut best = f64::INFINITY;
    let started = Instant::now();
    let mut runs = 0;
    loop {
        let start = Instant::now();
        let outcome = run()?;
        best = best.min(start.elapsed().as_secs_f64());
        runs += 1;
        let spent = started.elapsed();
        let enough = runs >= timing.min_runs && spent >= timing.min_total;
        let slow = runs >= timing.slow_runs && spent >= timing.slow_total;
        if enough || slow {
            return Some((best, runs, outcome));
        }
    }
}

fn ns_per_rhs() -> f64 {
    let scenario = &SCENARIOS[0];
    let p = scenario.parameters();
    let inputs = Inputs::default();
    let mut y = scenario.initial_state();
    y[5] = 3.0;
    let mut dy = [0.0; 8];
    let n = 20_000_000u64;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        for k in 0..n {
            // Vary the angles so nothing is hoisted out of the loop.
            y[1] = (k % 1000) as f64 * 6.283e-3;
            model::state_derivative(&p, &inputs, std::hint::black_box(&y), &mut dy);
            std::hint::black_box(&dy);
        }
        best = best.min(start.elapsed().as_secs_f64() * 1e9 / n as f64);
    }
    best
}

/// A number for JSON: non-finite values (e.g. a relative energy drift from zero energy)
/// become null.
fn number(value: f64) -> String {
    if value.is_finite() {
        format!("{value:e}")
    } else {
        "null".to_string()
    }
}

fn json_states(samples: &[State]) -> String {
    let rows: Vec<String> = samples
        .iter()
        .map(|y| {
            format!(
                "[{}]",
                y.iter().map(|v| number(*v)).collect::<Vec<_>>().join(",")
            )
        })
        .collect();
    format!("[{}]", rows.join(","))
}

/// The path after `flag`, if given.
fn path_after(args: &[String], flag: &str) -> Option<std::path::PathBuf> {
    let at = args.iter().position(|a| a == flag)?;
    args.get(at + 1).map(std::path::PathBuf::from)
}

/// The compiled peers (`--compiled target/bench/libpeers.so --numbalsoda DIR`), checked to
/// solve the model's equations; `None` without the flags. Exits on a load failure.
fn load_compiled(args: &[String]) -> Option<compiled::Compiled> {
    let library = path_after(args, "--compiled")?;
    let numbalsoda = path_after(args, "--numbalsoda").unwrap_or_else(|| {
        eprintln!("bench: --compiled needs --numbalsoda DIR (the package's shared libraries)");
        std::process::exit(2);
    });
    let peers = compiled::Compiled::load(&library, &numbalsoda).unwrap_or_else(|e| {
        eprintln!("bench: {e}");
        std::process::exit(1);
    });
    for scenario in &SCENARIOS {
        let difference = peers.rhs_difference(scenario);
        if difference > 1e-12 {
            eprintln!(
                "bench: the C right-hand side differs from the model's by {difference:e} ({})",
                scenario.name
            );
            std::process::exit(1);
        }
    }
    Some(peers)
}

/// `scenario`'s reference from `dir`, checked to cover its whole run.
fn load_reference(dir: &std::path::Path, scenario: &Scenario) -> Result<Reference, String> {
    let path = dir.join(format!("reference_{}.f64", scenario.name));
    let reference = Reference::load(&path)?;
    let points = (scenario.stop / reference.step).round() as usize + 1;
    if reference.points.len() != points {
        return Err(format!(
            "{}: {} points, expected {points} (t = 0…{} every {})",
            path.display(),
            reference.points.len(),
            scenario.stop,
            reference.step
        ));
    }
    Ok(reference)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!(
            "usage: bench <CyclicMechanism.fmu> <out.json> [--quick] [--fmu-only] [--reference DIR] \
             [--compiled LIBPEERS --numbalsoda DIR] [--steps H,H] [--only METHOD,METHOD]"
        );
        std::process::exit(2);
    }
    let quick = args.iter().any(|a| a == "--quick");
    let fmu_only = args.iter().any(|a| a == "--fmu-only");
    let fmu = match fmu::Fmu::load(std::path::Path::new(&args[1])) {
        Ok(fmu) => fmu,
        Err(e) => {
            eprintln!("bench: cannot load {}: {e}", args[1]);
            std::process::exit(1);
        }
    };
    let references: Vec<Option<Reference>> = match path_after(&args, "--reference") {
        None => SCENARIOS.iter().map(|_| None).collect(),
        Some(dir) => match SCENARIOS
            .iter()
            .map(|s| load_reference(&dir, s).map(Some))
            .collect()
        {
            Ok(references) => references,
            Err(e) => {
                eprintln!("bench: {e}");
                std::process::exit(1);
            }
        },
    };
    let tolerances: Vec<f64> = if quick {
        vec![1e-4, 1e-8]
    } else {
        (3..=12).map(|e| 10f64.powi(-e)).collect()
    };
    let steps: Vec<f64> = match path_after(&args, "--steps") {
        // A focused run: `--steps 0.01,0.1`.
        Some(list) => list
            .to_string_lossy()
            .split(',')
            .filter_map(|h| h.parse().ok())
            .collect(),
        None if quick => vec![1e-3, 1e-1],
        None => vec![1e-4, 1e-3, 1e-2, 1e-1],
    };
    // `--only fmu,hairer_dop853`: these methods alone.
    let only: Option<Vec<String>> = path_after(&args, "--only").map(|list| {
        list.to_string_lossy()
            .split(',')
            .map(str::to_string)
            .collect()
    });
    let wanted = |method: &str| only.as_ref().is_none_or(|o| o.iter().any(|m| m == method));
    let rhs_ns = if fmu_only { f64::NAN } else { ns_per_rhs() };
    if !fmu_only {
        eprintln!("right-hand side: {rhs_ns:.1} ns per evaluation");
    }
    let compiled = load_compiled(&args);
    let c_rhs_ns = compiled
        .as_ref()
        .map_or(f64::NAN, |c| c.ns_per_rhs(&SCENARIOS[0]));
    if compiled.is_some() {
        eprintln!("bare C right-hand side: {c_rhs_ns:.1} ns per evaluation");
    }
    let mut out = String::new();
    write!(
        out,
        "{{\"ns_per_rhs\": {}, \"c_ns_per_rhs\": {}, \"samples\": {SAMPLES}, \"results\": [",
        // Not measured: null, not NaN (which is not JSON).
        number(rhs_ns),
        number(c_rhs_ns)
    )
    .unwrap();
    let mut first = true;
    for (scenario, reference) in SCENARIOS.iter().zip(&references) {
        let reference = reference.as_ref();
        for &h in &steps {
            let compiled_methods = compiled.iter().flat_map(|_| compiled::METHODS);
            let methods = peers::METHODS
                .iter()
                .copied()
                .chain(compiled_methods)
                .filter(|_| !fmu_only)
                .map(|m| m.to_string());
            for method in std::iter::once("fmu".to_string())
                .chain(methods)
                .filter(|m| wanted(m))
            {
                let mut too_slow = false;
                for &tol in &tolerances {
                    if too_slow {
                        continue;
                    }
                    let run = || {
                        if method == "fmu" {
                            fmu.run(scenario, h, tol)
                        } else if compiled::METHODS.contains(&method.as_str()) {
                            compiled.as_ref()?.run(&method, scenario, h, tol)
                        } else {
                            peers::run(&method, scenario, h, tol)
                        }
                    };
                    let Some((seconds, runs, timed_run)) = timed(&TIMING, run) else {
                        eprintln!("{method} {} H={h:e} tol={tol:e}: failed", scenario.name);
                        continue;
                    };
                    // Tighter tolerances would only be slower still.
                    too_slow = seconds > TOO_SLOW;
                    eprintln!(
                        "{method:>10} {:>5} H={h:e} tol={tol:e}: {seconds:.4} s ({runs} runs)",
                        scenario.name
                    );
                    let o = Outcome::of(scenario, h, timed_run, reference, (seconds, runs));
                    write!(
                        out,
                        "{}\n{{\"method\": \"{method}\", \"scenario\": \"{}\", \"H\": {h:e}, \"tol\": {tol:e}, \
                         \"seconds\": {:e}, \"runs\": {}, \"n_rhs\": {}, \"max_residual\": {}, \
                         \"max_energy_drift\": {}, \"max_point_error\": {}, \"states\": {}}}",
                        if first { "" } else { "," },
                        scenario.name,
                        o.seconds,
                        o.runs,
                        o.n_rhs,
                        number(o.max_residual),
                        number(o.max_energy_drift),
                        number(o.max_point_error),
                        json_states(&o.samples)
                    )
                    .unwrap();
                    first = false;
                }
            }
        }
    }
    out.push_str("\n]");
    stiff_study(&fmu, &mut out);
    out.push_str("}\n");
    if let Err(e) = std::fs::write(&args[2], out) {
        eprintln!("bench: cannot write {}: {e}", args[2]);
        std::process::exit(1);
    }
}
