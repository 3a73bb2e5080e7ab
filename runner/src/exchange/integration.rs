//! The runner's integration of a Model Exchange FMU's continuous states, in the sizes the
//! methods are compiled for: the FMU's right-hand side scaled by its nominals (with the
//! variational equations of its flow where asked), one accepted step at a time, the dense
//! output between, and the retries of a step the FMU discards. The steady cycle's legs
//! ride on the same right-hand side and the same sizes.

use std::cell::{Cell, RefCell};

use integrators::{
    initial_step, Dop853, Method, OdeSystem, Radau5, SolverError, Stepper, Tolerances,
};

use crate::fmi::{Instance, Status};

/// The variational equations of the flow beside the states: the columns of
/// Ψ = D⁻¹ Φ D (D the nominals, Φ = ∂x(t)/∂x(t0)) but one, Ψ' = D⁻¹ J D Ψ with J from the
/// FMU's directional derivatives.
pub struct Variational<'a> {
    pub states: &'a [u32],
    pub derivatives: &'a [u32],
    /// The state whose column is not integrated (nothing reads it).
    pub skipped: usize,
}

impl Variational<'_> {
    /// The states whose columns are integrated, each with its place among the columns
    /// (which follow the state in the integrated vector).
    pub fn columns(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        let skipped = self.skipped;
        (0..self.states.len())
            .filter(move |&j| j != skipped)
            .enumerate()
    }

    /// The equations integrated for `n` states with the columns.
    pub fn size(n: usize) -> usize {
        n + n * n.saturating_sub(1)
    }
}

/// The FMU's right-hand side as the integrators see it: states divided by their nominals,
/// and with `variational` the columns of Ψ after them.
pub struct Scaled<'a> {
    pub fmu: RefCell<&'a mut Instance>,
    pub nominals: &'a [f64],
    variational: Option<Variational<'a>>,
    /// The worst status of a failed call (above Discard); once set, the FMU is not called
    /// again and every derivative is NaN, so that the integration stops.
    failure: Cell<Option<Status>>,
    /// Whether the last evaluation was discarded (the FMU refused the state: the
    /// integrator shortens the step).
    discarded: Cell<bool>,
}

impl<'a> Scaled<'a> {
    pub fn new(
        fmu: &'a mut Instance,
        nominals: &'a [f64],
        variational: Option<Variational<'a>>,
    ) -> Self {
        Scaled {
            fmu: RefCell::new(fmu),
            nominals,
            variational,
            failure: Cell::new(None),
            discarded: Cell::new(false),
        }
    }

    /// The status of the call that failed, where one did (Discard aside).
    pub fn failure(&self) -> Option<Status> {
        self.failure.get()
    }

    /// The states' derivatives at (t, x) (x as the FMU takes it), into `dx`, and the
    /// columns' derivatives from the columns `psi` (scaled) where variational; `seed` and
    /// `column` are scratch of the states' size.
    fn evaluate(
        &self,
        (t, x): (f64, &[f64]),
        dx: &mut [f64],
        psi: (&[f64], &mut [f64]),
        (seed, column): (&mut [f64], &mut [f64]),
    ) -> Status {
        let mut fmu = self.fmu.borrow_mut();
        let mut s = fmu.set_state(t, x).then(|| fmu.get_derivatives(dx));
        let Some(variational) = &self.variational else {
            return s;
        };
        let n = x.len();
        let (columns, rates) = psi;
        for (c, _) in variational.columns() {
            if !s.proceeds() {
                break;
            }
            for i in 0..n {
                seed[i] = columns[c * n + i] * self.nominals[i];
            }
            s = s.max(fmu.get_directional_derivative(
                variational.derivatives,
                variational.states,
                seed,
                column,
            ));
            for i in 0..n {
                rates[c * n + i] = column[i] / self.nominals[i];
            }
        }
        s
    }
}

impl<const N: usize> OdeSystem<N> for Scaled<'_> {
    fn rhs(&self, t: f64, y: &[f64; N], dy: &mut [f64; N]) {
        *dy = [0.0; N];
        let n = self.nominals.len();
        if self.failure.get().is_some() {
            dy.fill(f64::NAN);
            return;
        }
        let mut x = [0.0; N];
        for ((x, y), nominal) in x.iter_mut().zip(y).zip(self.nominals) {
            *x = y * nominal;
        }
        let (mut seed, mut column) = ([0.0; N], [0.0; N]);
        let (states, columns) = dy.split_at_mut(n);
        let s = self.evaluate(
            (t, &x[..n]),
            states,
            (&y[n..], columns),
            (&mut seed[..n], &mut column[..n]),
        );
        self.discarded.set(s == Status::Discard);
        if !s.proceeds() {
            if s > Status::Discard {
                self.failure.set(Some(s));
            }
            dy.fill(f64::NAN);
            return;
        }
        for (dy, nominal) in dy.iter_mut().zip(self.nominals) {
            *dy /= nominal;
        }
    }

    fn dimension(&self) -> usize {
        let n = self.nominals.len();
        match self.variational {
            Some(_) => Variational::size(n),
            None => n,
        }
    }

    /// The steps are the states' own: a variational leg's derivative is then that of the
    /// numerical flow.
    fn controlled(&self) -> usize {
        self.nominals.len()
    }
}

/// What is made at one of the sizes the integrations are compiled for.
pub trait AtSize {
    type Made;
    fn at<const N: usize>(self) -> Self::Made;
}

/// `job` at the smallest compiled size that holds `size` equations (padded with components
/// that stay zero and that the norms and Jacobians leave out); `None` above the largest.
pub fn at_size<J: AtSize>(size: usize, job: J) -> Option<J::Made> {
    macro_rules! ladder {
        ($($n:literal)*) => {
            $(if size <= $n {
                return Some(job.at::<$n>());
            })*
        };
    }
    ladder!(1 2 3 4 6 8 12 16 24 32 36 48 64 96 128);
    None
}

/// Why the integration stopped.
pub(super) enum Failure {
    /// A call of the FMU failed with this status.
    Fmu(Status),
    /// The integrator gave up (with the FMU discarding, or not).
    Solver(SolverError, bool),
}

/// One integration in a state size the methods are compiled for.
pub(super) trait Integration {
    /// Start afresh from (t, x) (x as the FMU gives it).
    fn restart(&mut self, t: f64, x: &[f64], nominals: &[f64]);
    /// Where the integration stands: its time, and the state into `x`.
    fn now(&self, x: &mut [f64], nominals: &[f64]) -> f64;
    /// One accepted step from where it stands, landing on `limit` if it would pass it.
    /// Returns the step's start.
    fn step(&mut self, fmu: &mut Instance, nominals: &[f64], limit: f64) -> Result<f64, Failure>;
    /// The state at `t` within the last accepted step, into `x`; false when there is none.
    fn state_at(&mut self, fmu: &mut Instance, nominals: &[f64], t: f64, x: &mut [f64]) -> bool;
    /// Whether the method's last evaluation in a step is f at the step's end, so that the
    /// FMU holds the end's time and state after it.
    fn evaluates_at_end(&self) -> bool;
}

/// What the integration needs of a method beyond [`Stepper`].
trait Stepping<const N: usize>: Stepper<N> {
    /// The order in Hairer's starting-step formula.
    const ORDER: i32;
    /// Whether it steps past its target (DOP853, whose last evaluation of a step is f at
    /// its end, the next step's first stage) rather than land on it (Radau IIA).
    const STEPS_PAST_TARGET: bool;
}

impl<const N: usize> Stepping<N> for Dop853<N> {
    const ORDER: i32 = 8;
    const STEPS_PAST_TARGET: bool = true;
}

impl<const N: usize> Stepping<N> for Radau5<N> {
    const ORDER: i32 = 5;
    const STEPS_PAST_TARGET: bool = false;
}

/// The most times a landing method's call is retried shorter when a rejection made it
/// take several steps (an event is located within one step).
const MAX_RETRIES: u32 = 8;

/// A method on `N` (padded) states.
struct SizedIntegration<const N: usize, M> {
    method: M,
    t: f64,
    y: [f64; N],
    tolerances: Tolerances,
}

impl<const N: usize, M: Stepping<N>> Integration for SizedIntegration<N, M> {
    fn restart(&mut self, t: f64, x: &[f64], nominals: &[f64]) {
        self.t = t;
        self.y = [0.0; N];
        for (k, (x, nominal)) in x.iter().zip(nominals).enumerate() {
            self.y[k] = x / nominal;
        }
        self.method.invalidate();
    }

    fn now(&self, x: &mut [f64], nominals: &[f64]) -> f64 {
        for (k, (x, nominal)) in x.iter_mut().zip(nominals).enumerate() {
            *x = self.y[k] * nominal;
        }
        self.t
    }

    fn step(&mut self, fmu: &mut Instance, nominals: &[f64], limit: f64) -> Result<f64, Failure> {
        let system = Scaled::new(fmu, nominals, None);
        if self.method.progress().next_step.is_none() {
            let mut f0 = [0.0; N];
            system.rhs(self.t, &self.y, &mut f0);
            let stats = &mut self.method.progress_mut().stats;
            stats.n_rhs += 1;
            let h = initial_step(
                &system,
                (self.t, &self.y, &f0),
                limit - self.t,
                self.tolerances,
                M::ORDER,
                stats,
            );
            self.method.progress_mut().next_step = Some(h);
        }
        let (start, y0) = (self.t, self.y);
        for _ in 0..MAX_RETRIES {
            // DOP853 with a target just past t takes exactly one accepted step; Radau IIA
            // lands on its target, so the target is its proposed step's end.
            let target = if M::STEPS_PAST_TARGET {
                self.t.next_up()
            } else {
                self.t + self.method.progress().next_step.unwrap_or(limit - self.t)
            }
            .min(limit);
            let steps = self.method.statistics().n_steps;
            let result = self
                .method
                .integrate(&system, &mut self.t, &mut self.y, target, limit);
            if let Some(status) = system.failure() {
                return Err(Failure::Fmu(status));
            }
            if let Err(e) = result {
                return Err(Failure::Solver(e, system.discarded.get()));
            }
            let taken = self.method.statistics().n_steps - steps;
            if taken <= 1 {
                return Ok(start);
            }
            // A rejection shortened the first step and the call went on in more: again
            // from the start, the first step as long as the steps taken were on average.
            let shorter = (self.t - start) / taken as f64;
            (self.t, self.y) = (start, y0);
            self.method.invalidate();
            self.method.progress_mut().next_step = Some(shorter);
        }
        Ok(start)
    }

    fn evaluates_at_end(&self) -> bool {
        M::STEPS_PAST_TARGET
    }

    fn state_at(&mut self, fmu: &mut Instance, nominals: &[f64], t: f64, x: &mut [f64]) -> bool {
        if t == self.t {
            self.now(x, nominals);
            return true;
        }
        let system = Scaled::new(fmu, nominals, None);
        let Some(y) = self.method.dense_output(&system, t) else {
            return false;
        };
        for (k, (x, nominal)) in x.iter_mut().zip(nominals).enumerate() {
            *x = y[k] * nominal;
        }
        true
    }
}

/// The integration a method makes at a compiled size.
struct Driver {
    method: Method,
    tolerances: Tolerances,
}

impl AtSize for Driver {
    type Made = Box<dyn Integration>;

    fn at<const N: usize>(self) -> Box<dyn Integration> {
        let (t, y, tolerances) = (0.0, [0.0; N], self.tolerances);
        match self.method {
            Method::Dop853 => Box::new(SizedIntegration {
                method: Dop853::<N>::new(tolerances),
                t,
                y,
                tolerances,
            }),
            Method::Radau5 => Box::new(SizedIntegration {
                method: Radau5::<N>::new(tolerances),
                t,
                y,
                tolerances,
            }),
        }
    }
}

/// An integration for `states` states (at most `MAX_STATES`, which `Shape::check` holds).
pub(super) fn integration(
    states: usize,
    method: Method,
    tolerances: Tolerances,
) -> Box<dyn Integration> {
    at_size(states, Driver { method, tolerances })
        .expect("Shape::check refuses more than MAX_STATES states")
}
