//! Integrators, generic over a small trait and ignorant of the problem they solve.
//! Fixed-size state (`[f64; N]`), no heap allocation while stepping; what a method
//! remembers can be written to bytes and read back to continue bit for bit.

pub mod bytes;
pub mod dop853;
mod dop853_tableau;
mod linear;
pub mod radau5;
mod radau5_tableau;
pub mod rk4;
pub mod switching;
pub mod text;

pub use dop853::Dop853;
pub use radau5::Radau5;
pub use rk4::Rk4;
pub use switching::{Choice, Integrator, Method};

use crate::bytes::{FormatError, Reader, Writer};
use crate::text::number;

/// An ODE y' = f(t, y) on a manifold the system can project onto.
pub trait OdeSystem<const N: usize> {
    /// Evaluate f(t, y) into `dy`.
    fn rhs(&self, t: f64, y: &[f64; N], dy: &mut [f64; N]);

    /// Called on every accepted step's result `y` (the step started from `previous`): bring
    /// `y` back onto the manifold. Fails, saying why, when that is impossible or the step
    /// left the region where the solution is determined; the step is then an error.
    fn project(&self, _previous: &[f64; N], _y: &mut [f64; N]) -> Result<(), String> {
        Ok(())
    }

    /// How many of the N components are the problem's: the others are padding whose value
    /// and derivative stay zero (a problem whose size is known only at run time is solved
    /// in the next size the methods are compiled for). Error norms average over these
    /// alone and difference Jacobians skip the rest, so the padding changes no number.
    fn dimension(&self) -> usize {
        N
    }

    /// How many of the leading components DOP853's step-size control holds to the
    /// tolerances: all of the problem's, unless the others are quantities carried along
    /// that the steps should not depend on (a state's sensitivities, whose steps are then
    /// the state's own, so that the sensitivities are those of the state's numerical
    /// solution).
    fn controlled(&self) -> usize {
        self.dimension()
    }
}

/// One integration method, as the co-simulation driver uses it: DOP853, Radau IIA and the
/// short-step RK4 implement it, [`Integrator`] uses them through it, and one conformance
/// suite (`tests/integrators.rs`) runs for each.
pub trait Stepper<const N: usize>: Clone + Sized {
    /// A method with no memory, working to `tolerances`.
    fn new(tolerances: Tolerances) -> Self;

    /// What this method hands on when `auto` changes method.
    fn progress(&self) -> Progress;

    fn progress_mut(&mut self) -> &mut Progress;

    fn statistics(&self) -> Statistics {
        self.progress().stats
    }

    /// Continue where another method stopped: its counters go on, and its proposed step
    /// size is this one's first guess.
    fn resume(progress: Progress) -> Self {
        let mut method = Self::new(progress.tolerances);
        *method.progress_mut() = progress;
        method
    }

    /// The state or the right-hand side changed outside the integrator (new inputs, a
    /// restored state): what the method remembers of the last step no longer applies. The
    /// step size stays.
    fn invalidate(&mut self);

    /// Integrate from (`*t`, `*y`) until `*t >= target`, never stepping past `limit` (a
    /// step that would, lands on it exactly); `target == limit` lands exactly on the
    /// target. The solution in between comes from [`Stepper::dense_output`]. On error,
    /// `*t` and `*y` hold the last accepted (projected) step.
    fn integrate<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: &mut f64,
        y: &mut [f64; N],
        target: f64,
        limit: f64,
    ) -> Result<(), SolverError>;

    /// The solution at `t` within the last accepted step; `None` when no step is available
    /// (none taken since the last [`Stepper::invalidate`]) or `t` lies outside it.
    fn dense_output<S: OdeSystem<N>>(&mut self, system: &S, t: f64) -> Option<[f64; N]>;

    /// Check restored memory against `system` at the integrator's point (t, y): memory
    /// that its own steps would not give was altered after it was written.
    fn check_memory<S: OdeSystem<N>>(&self, system: &S, t: f64, y: &[f64; N])
        -> Result<(), String>;

    /// Everything the method remembers, as bytes: restoring it continues bit for bit.
    fn serialize_into(&self, w: &mut Writer);

    /// The method written by [`Stepper::serialize_into`].
    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError>;
}

/// The next step to try from `t` with proposed size `h`: its size and whether it lands on
/// `limit` (a step that would pass the limit, or leave less than a hundredth of a step
/// before it, is cut or stretched to end exactly there). Refused once the method's work
/// reaches its limit ([`Progress::work_limit`]).
fn plan_step(t: f64, h: f64, limit: f64, progress: &Progress) -> Result<(f64, bool), SolverError> {
    if progress.stats.n_rhs >= progress.work_limit {
        return Err(SolverError::WorkLimit { t });
    }
    let landing = t + 1.01 * h >= limit;
    let h_step = if landing { limit - t } else { h };
    if !landing {
        check_step_size(t, h_step)?;
    }
    Ok((h_step, landing))
}

/// The step to try after an accepted step whose control proposed `proposed`, `planned`
/// having been the size planned for it: a step cut short to land on the limit says nothing
/// against the longer step, so the planned size stays if larger.
#[inline(always)]
fn after_accepted(proposed: f64, planned: f64, landing: bool) -> f64 {
    if landing {
        proposed.max(planned)
    } else {
        proposed
    }
}

/// A step size must stay resolvable in t's precision.
fn check_step_size(t: f64, h: f64) -> Result<(), SolverError> {
    if h <= 16.0 * f64::EPSILON * t.abs().max(1.0) {
        return Err(SolverError::StepSizeTooSmall { t, h });
    }
    Ok(())
}

/// Error-control settings: a component's error is scaled by atol + rtol·|y_i|.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    pub rtol: f64,
    pub atol: f64,
}

/// Cumulative work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Statistics {
    /// Accepted steps.
    pub n_steps: u64,
    /// Rejected steps (error too large, or a non-finite stage).
    pub n_rejected: u64,
    /// Right-hand-side evaluations.
    pub n_rhs: u64,
}

impl Statistics {
    /// Count `other`'s work in these counters too.
    pub fn add(&mut self, other: &Statistics) {
        self.n_steps += other.n_steps;
        self.n_rejected += other.n_rejected;
        self.n_rhs += other.n_rhs;
    }

    fn serialize_into(&self, w: &mut Writer) {
        put!(w.u64(self.n_steps));
        put!(w.u64(self.n_rejected));
        put!(w.u64(self.n_rhs));
    }

    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        Ok(Self {
            n_steps: r.u64()?,
            n_rejected: r.u64()?,
            n_rhs: r.u64()?,
        })
    }
}

/// What each integrator carries from one call to the next, and hands on when `auto`
/// changes method: its tolerances, the step size to try next, and the work counters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    pub tolerances: Tolerances,
    /// Proposed size of the next step; `None` until the first step is chosen.
    pub next_step: Option<f64>,
    pub stats: Statistics,
    /// The count of right-hand sides (`stats.n_rhs`) at which stepping stops with
    /// [`SolverError::WorkLimit`]: the caller's bound on one call's work, counted
    /// deterministically rather than by a clock. Not part of the serialized state: each
    /// call sets its own ([`NO_WORK_LIMIT`] until then).
    pub work_limit: u64,
}

/// No bound on the work of a call.
pub const NO_WORK_LIMIT: u64 = u64::MAX;

impl Progress {
    pub fn new(tolerances: Tolerances) -> Self {
        Self {
            tolerances,
            next_step: None,
            stats: Statistics::default(),
            work_limit: NO_WORK_LIMIT,
        }
    }

    /// Where every integrator's serialized form begins.
    fn serialize_into(&self, w: &mut Writer) {
        put!(w.f64s(&[self.tolerances.rtol, self.tolerances.atol]));
        put!(w.bool(self.next_step.is_some()));
        put!(w.f64(self.next_step.unwrap_or(0.0)));
        self.stats.serialize_into(w);
    }

    /// What [`Progress::serialize_into`] wrote. A stored step size that is not finite and
    /// positive is dropped (the integrator then chooses its first step afresh).
    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let [rtol, atol] = r.f64s()?;
        let has_step = r.bool()?;
        let step = r.f64()?;
        Ok(Self {
            tolerances: Tolerances { rtol, atol },
            next_step: has_step
                .then_some(step)
                .filter(|h| h.is_finite() && *h > 0.0),
            stats: Statistics::deserialize_from(r)?,
            work_limit: NO_WORK_LIMIT,
        })
    }
}

/// Why an integration stopped short of its end time. The caller's state is left at the
/// last accepted step that succeeded.
#[derive(Clone, Debug, PartialEq)]
pub enum SolverError {
    /// The step size fell below what t's precision resolves.
    StepSizeTooSmall { t: f64, h: f64 },
    /// The system refused an accepted state (could not project it, or it is singular).
    ProjectionFailed { t: f64, reason: String },
    /// The work limit of the call was reached ([`Progress::work_limit`]): the state is
    /// good up to `t`, and the call asked for more work than it allows.
    WorkLimit { t: f64 },
}

impl std::fmt::Display for SolverError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolverError::StepSizeTooSmall { t, h } => {
                write!(
                    f,
                    "step size {h:e} too small at t = {} (stiff, singular or non-finite dynamics)",
                    number(*t)
                )
            }
            SolverError::ProjectionFailed { t, reason } => {
                write!(f, "at t = {}: {reason}", number(*t))
            }
            SolverError::WorkLimit { t } => {
                write!(
                    f,
                    "the work one call may do was spent at t = {}",
                    number(*t)
                )
            }
        }
    }
}

impl std::error::Error for SolverError {}

/// Σ_j weights[j]·vectors[j], component by component: one accumulator per component, so
/// the sums run side by side instead of as one long dependent chain per component (in
/// DOP853 the stage combinations were the largest cost outside the right-hand side), and
/// zero weights (a tableau's zero entries) are skipped.
#[inline(always)]
fn combine<const N: usize>(weights: &[f64], vectors: &[[f64; N]]) -> [f64; N] {
    let mut sum = [0.0; N];
    for (w, vector) in weights.iter().zip(vectors) {
        if *w != 0.0 {
            for (s, k) in sum.iter_mut().zip(vector) {
                *s += w * k;
            }
        }
    }
    sum
}

/// The step size a call tries first: the one the last call proposed, else Hairer's starting
/// step for a method of order `order` over the span to `target` ([`initial_step`]).
pub(crate) fn first_step<S: OdeSystem<N>, const N: usize>(
    progress: &mut Progress,
    system: &S,
    (t, y, f0): (f64, &[f64; N], &[f64; N]),
    target: f64,
    order: i32,
) -> f64 {
    match progress.next_step {
        Some(h) => h,
        None => initial_step(
            system,
            (t, y, f0),
            target - t,
            progress.tolerances,
            order,
            &mut progress.stats,
        ),
    }
}

/// Hairer's starting step size (HNW I, II.4) for a method of order `order` at (t, y) with
/// f(t, y) = `f0`, bounded by the span to integrate. Costs one evaluation. Public for a
/// caller that steps one accepted step at a time (its target just past t would bound the
/// first step to nothing): it proposes the first step with this.
pub fn initial_step<S: OdeSystem<N>, const N: usize>(
    system: &S,
    (t, y, f0): (f64, &[f64; N], &[f64; N]),
    span: f64,
    tolerances: Tolerances,
    order: i32,
    stats: &mut Statistics,
) -> f64 {
    let Tolerances { rtol, atol } = tolerances;
    let scale = |n: usize| atol + rtol * y[n].abs();
    let norm_f: f64 = (0..N).map(|n| (f0[n] / scale(n)).powi(2)).sum();
    let norm_y: f64 = (0..N).map(|n| (y[n] / scale(n)).powi(2)).sum();
    let mut h = if norm_f <= 1e-10 || norm_y <= 1e-10 {
        1e-6
    } else {
        0.01 * (norm_y / norm_f).sqrt()
    };
    h = h.min(span);
    let y1: [f64; N] = std::array::from_fn(|n| y[n] + h * f0[n]);
    let mut f1 = [0.0; N];
    system.rhs(t + h, &y1, &mut f1);
    stats.n_rhs += 1;
    let second: f64 = (0..N)
        .map(|n| ((f1[n] - f0[n]) / scale(n)).powi(2))
        .sum::<f64>()
        .sqrt()
        / h;
    let largest = second.max(norm_f.sqrt());
    let h1 = if largest <= 1e-15 {
        (h * 1e-3).max(1e-6)
    } else {
        (0.01 / largest).powf(1.0 / order as f64)
    };
    (100.0 * h).min(h1).min(span)
}

/// Test problems shared by the integrators' unit tests.
#[cfg(test)]
pub(crate) mod test_problems {
    use super::{OdeSystem, Tolerances};

    /// Harmonic oscillator y'' = −y: from (1, 0), exact solution (cos t, −sin t).
    pub struct Oscillator;
    impl OdeSystem<2> for Oscillator {
        fn rhs(&self, _t: f64, y: &[f64; 2], dy: &mut [f64; 2]) {
            *dy = [y[1], -y[0]];
        }
    }

    pub fn tol(rtol: f64) -> Tolerances {
        Tolerances { rtol, atol: rtol }
    }
}

#[cfg(test)]
mod padding {
    use super::test_problems::{tol, Oscillator};
    use super::*;

    /// A damped, driven oscillator (so that both components and time matter), in the first
    /// two of `N` components; the rest are padding.
    struct Padded<const N: usize>;
    impl<const N: usize> OdeSystem<N> for Padded<N> {
        fn rhs(&self, t: f64, y: &[f64; N], dy: &mut [f64; N]) {
            *dy = [0.0; N];
            dy[0] = y[1];
            dy[1] = -y[0] - 0.1 * y[1] + t.sin();
        }
        fn dimension(&self) -> usize {
            2
        }
    }

    /// The first two components at each of ten points, stepped by `M` on `N` components.
    fn run<const N: usize, M: Stepper<N>>() -> Vec<[u64; 2]> {
        let mut method = M::new(tol(1e-9));
        let (mut t, mut y) = (0.0, [0.0; N]);
        y[0] = 1.0;
        let mut out = Vec::new();
        for k in 1..=10 {
            let target = 0.7 * k as f64;
            method
                .integrate(&Padded::<N>, &mut t, &mut y, target, target)
                .unwrap();
            out.push([y[0].to_bits(), y[1].to_bits()]);
        }
        assert!(y[2..].iter().all(|&p| p == 0.0), "the padding stays zero");
        out
    }

    #[test]
    fn padding_a_problem_changes_no_number() {
        assert_eq!(run::<2, Dop853<2>>(), run::<5, Dop853<5>>());
        assert_eq!(run::<2, Radau5<2>>(), run::<7, Radau5<7>>());
        assert_eq!(run::<2, Rk4<2>>(), run::<3, Rk4<3>>());
        // The oscillator's own dimension is its size.
        assert_eq!(OdeSystem::<2>::dimension(&Oscillator), 2);
    }
}
