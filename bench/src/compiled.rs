//! Compiled peers on the same equations with a compiled right-hand side (bench/compiled/
//! peers.c, the plain-C form of docs/model.md §2): Hairer's DOP853 and LSODA as the
//! numbalsoda package builds them (their shared libraries, called with the C function
//! directly: what a numba cfunc would hand them, without Python in between), GSL's rk8pd
//! and CVODE. Each reports the state at every communication point, as a doStep loop would
//! see it; DOP853 and LSODA interpolate there, GSL ends its steps there.

use std::ffi::{c_int, c_long, c_void};
use std::path::Path;

use libloading::Library;

use crate::{Run, Scenario};

pub const METHODS: [&str; 5] = [
    "hairer_dop853",
    "lsoda",
    "gsl_rk8pd",
    "cvode_adams",
    "cvode_bdf",
];

/// `mechanism` of peers.c, field for field.
#[repr(C)]
#[derive(Clone, Copy)]
struct Mechanism {
    inertias: [f64; 4],
    springs: [f64; 5],
    lengths: [f64; 3],
    laws: [f64; 5],
    n_rhs: c_long,
}

impl Mechanism {
    fn of(scenario: &Scenario) -> Self {
        let p = scenario.parameters();
        let on = if p.builtin_laws { 1.0 } else { 0.0 };
        Self {
            inertias: [p.J1, p.J2, p.J3, p.J4],
            springs: [p.k12, p.k34, p.d12, p.d34, p.c4],
            lengths: [p.l, p.l2, p.l3],
            laws: [p.Mm_a0, p.Mm_a1, p.Mm_a2, p.Mr_b0, p.Mr_b1].map(|c| c * on),
            n_rhs: 0,
        }
    }
}

type Rhs = unsafe extern "C" fn(f64, *mut f64, *mut f64, *mut c_void);
type RecordPoint = unsafe extern "C" fn(*mut c_void, c_long, *const f64);
type RhsNs = unsafe extern "C" fn(*mut Mechanism, *const f64, c_long) -> f64;
type GslRun = unsafe extern "C" fn(
    *mut Mechanism,
    *const f64,
    f64,
    c_long,
    f64,
    RecordPoint,
    *mut c_void,
) -> c_int;
type CvodeRun = unsafe extern "C" fn(
    *mut Mechanism,
    *const f64,
    f64,
    c_long,
    f64,
    c_int,
    RecordPoint,
    *mut c_void,
) -> c_int;
/// numbalsoda's `dop853_wrapper` and `lsoda_wrapper`: (rhs, neq, u0, data, nt, t_eval,
/// usol[nt][neq], rtol, atol, mxstep, success).
type Wrapper = unsafe extern "C" fn(
    Rhs,
    c_int,
    *const f64,
    *mut c_void,
    c_int,
    *const f64,
    *mut f64,
    f64,
    f64,
    c_int,
    *mut c_int,
);

pub struct Compiled {
    rhs: Rhs,
    rhs_ns: RhsNs,
    gsl: GslRun,
    cvode: CvodeRun,
    dop853: Wrapper,
    lsoda: Wrapper,
    _libraries: [Library; 3],
}

/// Load `name` from `library` (the library outlives the pointer: both live in [`Compiled`]).
unsafe fn symbol<T: Copy>(library: &Library, name: &str) -> Result<T, String> {
    // SAFETY: the caller names a symbol of type T.
    unsafe { library.get::<T>(name.as_bytes()) }
        .map(|s| *s)
        .map_err(|e| format!("{name}: {e}"))
}

impl Compiled {
    /// `peers`: target/bench/libpeers.so; `numbalsoda`: the installed package's directory.
    pub fn load(peers: &Path, numbalsoda: &Path) -> Result<Self, String> {
        let open = |path: &Path| {
            // SAFETY: loading runs only the libraries' constructors (none of ours).
            unsafe { Library::new(path) }.map_err(|e| format!("{}: {e}", path.display()))
        };
        let own = open(peers)?;
        let dop853 = open(&numbalsoda.join("libdop853.so"))?;
        let lsoda = open(&numbalsoda.join("liblsoda.so"))?;
        // SAFETY: the types are those of peers.c and of numbalsoda's wrappers.
        unsafe {
            Ok(Self {
                rhs: symbol(&own, "mechanism_rhs")?,
                rhs_ns: symbol(&own, "mechanism_rhs_ns")?,
                gsl: symbol(&own, "gsl_rk8pd_run")?,
                cvode: symbol(&own, "cvode_run")?,
                dop853: symbol(&dop853, "dop853_wrapper")?,
                lsoda: symbol(&lsoda, "lsoda_wrapper")?,
                _libraries: [own, dop853, lsoda],
            })
        }
    }

    /// The C right-hand side against the model's own at a few states: the peers must solve
    /// the same equations. The largest relative difference.
    pub fn rhs_difference(&self, scenario: &Scenario) -> f64 {
        let p = scenario.parameters();
        let mut m = Mechanism::of(scenario);
        let mut worst: f64 = 0.0;
        for k in 0..5 {
            let mut y = scenario.initial_state();
            y[0] += 0.01 * k as f64;
            y[4] = 1.0 + k as f64;
            y[5] = 3.0 - k as f64;
            y[7] = -0.5;
            let mut expected = [0.0; 8];
            cyclic_mechanism::model::state_derivative(&p, &Default::default(), &y, &mut expected);
            let mut got = [0.0; 8];
            // SAFETY: 8 states, 8 rates and the struct peers.c expects.
            unsafe { (self.rhs)(0.0, y.as_mut_ptr(), got.as_mut_ptr(), (&raw mut m).cast()) };
            for (a, b) in got.iter().zip(&expected) {
                worst = worst.max((a - b).abs() / b.abs().max(1.0));
            }
        }
        worst
    }

    /// Nanoseconds per call of the bare compiled right-hand side (the floor).
    pub fn ns_per_rhs(&self, scenario: &Scenario) -> f64 {
        let mut m = Mechanism::of(scenario);
        let mut y = scenario.initial_state();
        y[5] = 3.0;
        // SAFETY: the struct and 8 states.
        unsafe { (self.rhs_ns)(&mut m, y.as_ptr(), 20_000_000) }
    }

    pub fn run(&self, method: &str, scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
        let y0 = scenario.initial_state();
        let mut m = Mechanism::of(scenario);
        let mut run = Run::start(scenario, h, &y0);
        let n = (scenario.stop / h).round() as usize;
        let context = (&raw mut run).cast::<c_void>();
        // SAFETY: the drivers call `record_point` with `context` (the run, alive
        // across the call) and 8 states; the buffers hold what the wrappers write.
        let ok = unsafe {
            match method {
                "gsl_rk8pd" => {
                    (self.gsl)(
                        &mut m,
                        y0.as_ptr(),
                        h,
                        n as c_long,
                        tol,
                        record_point,
                        context,
                    ) == 0
                }
                "cvode_adams" | "cvode_bdf" => {
                    let bdf = c_int::from(method == "cvode_bdf");
                    (self.cvode)(
                        &mut m,
                        y0.as_ptr(),
                        h,
                        n as c_long,
                        tol,
                        bdf,
                        record_point,
                        context,
                    ) == 0
                }
                "hairer_dop853" | "lsoda" => {
                    let wrapper = if method == "lsoda" {
                        self.lsoda
                    } else {
                        self.dop853
                    };
                    // A sentinel past the end: the DOP853 wrapper's output loop reads one
                    // element beyond the grid before it checks the bound.
                    let times: Vec<f64> = (0..=n)
                        .map(|k| k as f64 * h)
                        .chain([f64::INFINITY])
                        .collect();
                    let mut success: c_int = 0;
                    wrapper(
                        self.rhs,
                        8,
                        y0.as_ptr(),
                        (&raw mut m).cast(),
                        (n + 1) as c_int,
                        times.as_ptr(),
                        run.states.as_mut_ptr().cast(),
                        tol,
                        tol,
                        c_int::MAX,
                        &mut success,
                    );
                    success == 1
                }
                _ => false,
            }
        };
        if !ok {
            eprintln!("{method} failed");
            return None;
        }
        run.n_rhs = m.n_rhs as u64;
        Some(run)
    }
}

/// The drivers' callback: the state at communication point `k`, kept.
unsafe extern "C" fn record_point(context: *mut c_void, k: c_long, y: *const f64) {
    // SAFETY: `context` is the run of `Compiled::run` and `y` holds 8 states.
    let (run, y) = unsafe { (&mut *context.cast::<Run>(), &*y.cast::<[f64; 8]>()) };
    run.states[k as usize] = *y;
}
