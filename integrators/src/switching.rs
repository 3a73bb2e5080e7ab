//! The integrator the co-simulation driver holds: DOP853, Radau IIA, or `auto`, which starts with
//! DOP853 and changes method between communication steps when the problem's stiffness
//! changes.
//!
//! The rule for `auto` (documented in the README):
//! - DOP853 → Radau IIA when the stiffness test (see [`Dop853::is_stiff`]) found, among the
//!   last 32 accepted steps, 10 whose h·|λ| exceeded DOP853's stability boundary 6.1: the
//!   step size is limited by stability, not accuracy.
//! - Radau IIA → DOP853 when, for 50 consecutive accepted steps, the controller's proposed
//!   step h satisfied h·ρ(J) < 3 (ρ from the Jacobian by power iteration): DOP853 would be
//!   stable at that step size with a margin of 2. The gap between 6.1 and 3, and the 50
//!   steps, are the hysteresis: a stiff transient being resolved with short steps (after an
//!   input jump, say) is not taken for the end of stiffness.
//! - Only when the communication step is more than 4 DOP853 steps long: Radau IIA ends a
//!   step on every communication point, so with shorter ones it cannot step further.
//! - A switch happens only at the start of a communication step, never within one. The
//!   new method restarts from the communication point with the old method's step size;
//!   the statistics continue.
//!
//! Besides, a communication step that starts afresh (new inputs, say) and is far shorter
//! than DOP853's natural step is taken by [`Rk4`] ([`Integrator::integrate_short`]): a
//! master that sets an input at every step restarts the integrator at every step, and
//! there four evaluations of RK4 do what twelve or more of DOP853 would.

use super::{
    Dop853, OdeSystem, Progress, Radau5, Rk4, SolverError, Statistics, Stepper, Tolerances,
};
use crate::bytes::{FormatError, Reader, Writer};
use crate::put;

/// Radau IIA ends a step on every communication point, so it can only beat a
/// stability-limited DOP853 when the communication step is several DOP853 steps long.
/// (Paper case 1 at a loose tolerance is stability-limited for DOP853 in places; with
/// short communication steps, switching there costs far more evaluations than DOP853
/// takes. tests/stiff.rs fails without this condition.)
const MIN_STEPS_PER_COMMUNICATION: f64 = 4.0;

/// Before RK4 has taken a short step, a communication step at most this fraction of
/// DOP853's natural step, starting afresh, goes to it first; from then on the cost of each
/// method decides ([`Integrator::suits_short_step`]).
const FIRST_SHORT_FRACTION: f64 = 0.25;
/// Evaluations per step: RK4 (three stages and the estimate's, its first stage the last
/// step's estimate or derived from it), and DOP853 (twelve stages), which starting afresh
/// and stepping past the communication point also evaluates f at the start and three
/// stages of its interpolant.
const RK4_STEP_COST: f64 = 4.0;
const DOP853_STEP_COST: f64 = 12.0;
const DOP853_FRESH_COST: f64 = 4.0;
/// RK4's estimate is held to this multiple of the integrator's tolerances. The estimate is
/// that of the embedded third-order solution while the fourth-order one goes on, and the
/// short steps end on communication points, so DOP853's interpolant (one of the reasons
/// for the integrator's tight tolerance) is not involved. Chosen with the coupled-step
/// benchmark (`cargo xtask bench-coupling`), which judges every output at every
/// communication point of a coupled run against the same run at tol 1e-12, at four
/// communication steps: a larger multiple let a run whose steps RK4 takes in two miss
/// the tolerance.
const SHORT_TOLERANCE_FACTOR: f64 = 2.0;

fn worth_landing<const N: usize>(explicit: &Dop853<N>, communication_step: f64) -> bool {
    explicit
        .next_step()
        .is_some_and(|h| communication_step > MIN_STEPS_PER_COMMUNICATION * h)
}

/// An integration method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Dop853,
    Radau5,
}

/// What the user chose: one method, or automatic switching.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    Auto,
    Fixed(Method),
}

impl Choice {
    /// The method a run starts with: `auto` starts explicit.
    pub fn first_method(self) -> Method {
        match self {
            Choice::Fixed(method) => method,
            Choice::Auto => Method::Dop853,
        }
    }
}

#[derive(Clone, Debug)]
enum Active<const N: usize> {
    Explicit(Dop853<N>),
    Implicit(Radau5<N>),
}

/// `$body` on the active method, bound to `$s`: the one place that tells the methods apart
/// (each arm calls the same [`Stepper`] method).
macro_rules! on_active {
    ($active:expr, $s:ident => $body:expr) => {
        match $active {
            Active::Explicit($s) => $body,
            Active::Implicit($s) => $body,
        }
    };
}

/// One integrator with a method choice; the same calls whichever method is active.
#[derive(Clone, Debug)]
pub struct Integrator<const N: usize> {
    choice: Choice,
    active: Active<N>,
    /// The step RK4 proposed at the end of its last short steps, if it took any.
    short_step: Option<f64>,
}

impl<const N: usize> Integrator<N> {
    pub fn new(choice: Choice, tolerances: Tolerances) -> Self {
        let active = match choice.first_method() {
            Method::Radau5 => Active::Implicit(Radau5::new(tolerances)),
            Method::Dop853 => Active::Explicit(Dop853::new(tolerances)),
        };
        Self {
            choice,
            active,
            short_step: None,
        }
    }

    pub fn method(&self) -> Method {
        match self.active {
            Active::Explicit(_) => Method::Dop853,
            Active::Implicit(_) => Method::Radau5,
        }
    }

    /// See [`Stepper::check_memory`].
    pub fn check_memory<S: OdeSystem<N>>(
        &self,
        system: &S,
        t: f64,
        y: &[f64; N],
    ) -> Result<(), String> {
        on_active!(&self.active, s => s.check_memory(system, t, y))
    }

    /// The tolerances the active method controls its steps to.
    pub fn tolerances(&self) -> Tolerances {
        on_active!(&self.active, s => s.progress().tolerances)
    }

    pub fn statistics(&self) -> Statistics {
        on_active!(&self.active, s => s.statistics())
    }

    pub fn invalidate(&mut self) {
        on_active!(&mut self.active, s => s.invalidate())
    }

    /// Count `rhs` right-hand sides evaluated elsewhere (by copies of this integrator) in
    /// the statistics.
    pub fn count_work(&mut self, rhs: u64) {
        on_active!(&mut self.active, s => s.progress_mut().stats.n_rhs += rhs)
    }

    /// What is left of the work allowed by [`Integrator::allow_work`].
    pub fn work_left(&self) -> u64 {
        on_active!(&self.active, s => {
            let progress = s.progress();
            progress.work_limit.saturating_sub(progress.stats.n_rhs)
        })
    }

    /// Allow `work` more right-hand sides from now on, and no more, until set again: a
    /// method that `auto` switches to keeps the same limit.
    #[inline(always)]
    pub fn allow_work(&mut self, work: u64) {
        on_active!(&mut self.active, s => {
            let progress = s.progress_mut();
            progress.work_limit = progress.stats.n_rhs.saturating_add(work);
        })
    }

    /// See [`Stepper::integrate`] (Radau IIA ends on `target`).
    #[inline(always)]
    pub fn integrate<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: &mut f64,
        y: &mut [f64; N],
        target: f64,
        limit: f64,
    ) -> Result<(), SolverError> {
        on_active!(&mut self.active, s => s.integrate(system, t, y, target, limit))
    }

    /// The solution at `t` within the last accepted step, if any.
    #[inline(always)]
    pub fn dense_output<S: OdeSystem<N>>(&mut self, system: &S, t: f64) -> Option<[f64; N]> {
        on_active!(&mut self.active, s => s.dense_output(system, t))
    }

    /// Whether a communication step of `communication_step` that starts afresh costs less
    /// by [`Integrator::integrate_short`] than by DOP853, the active method: RK4's steps at
    /// the size it last proposed against DOP853's at its natural step, each method's
    /// evaluations per step counted; before RK4's first short steps, when the step is a
    /// small fraction of DOP853's ([`FIRST_SHORT_FRACTION`]).
    pub fn suits_short_step(&self, communication_step: f64) -> bool {
        let Active::Explicit(explicit) = &self.active else {
            return false;
        };
        let Some(natural) = explicit.next_step() else {
            return false;
        };
        match self.short_step {
            None => communication_step <= FIRST_SHORT_FRACTION * natural,
            Some(short) => {
                let short_cost = RK4_STEP_COST * (communication_step / short).ceil();
                let explicit_cost =
                    DOP853_STEP_COST * (communication_step / natural).ceil() + DOP853_FRESH_COST;
                short_cost < explicit_cost
            }
        }
    }

    /// Integrate from (`*t`, `*y`) to exactly `t_end` with [`Rk4`], starting with one
    /// step of the whole span or the step it last proposed, whichever is shorter, and with
    /// `first` as f(t, y) if given; its work counts in the statistics. Returns f at the
    /// end (the system's, at the state reached). The active method's memory no longer
    /// applies afterwards; its step size stays for when it goes on.
    pub fn integrate_short<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        (t, y): (&mut f64, &mut [f64; N]),
        t_end: f64,
        first: Option<[f64; N]>,
    ) -> Result<Option<[f64; N]>, SolverError> {
        let Tolerances { rtol, atol } = self.tolerances();
        let mut short = Rk4::<N>::new(Tolerances {
            rtol: rtol * SHORT_TOLERANCE_FACTOR,
            atol: atol * SHORT_TOLERANCE_FACTOR,
        });
        if let Some(k1) = first {
            short.start_with(k1);
        }
        let Progress {
            stats, work_limit, ..
        } = on_active!(&self.active, s => s.progress());
        short.progress_mut().work_limit = work_limit.saturating_sub(stats.n_rhs);
        let span = t_end - *t;
        short.progress_mut().next_step = Some(self.short_step.map_or(span, |h| h.min(span)));
        let result = short.integrate(system, t, y, t_end, t_end);
        self.short_step = short.progress().next_step.filter(|_| result.is_ok());
        let work = short.statistics();
        on_active!(&mut self.active, s => {
            s.progress_mut().stats.add(&work);
            s.invalidate();
        });
        result.map(|()| short.first_stage())
    }

    /// Whether the user fixed DOP853 and its stiffness test finds the step size limited by
    /// stability: the fast modes may carry noise above the tolerance on stiff damped
    /// couplings, which the error estimate does not see and Radau IIA would not leave.
    pub fn fixed_dop853_is_stiff(&self) -> bool {
        self.choice == Choice::Fixed(Method::Dop853)
            && matches!(&self.active, Active::Explicit(s) if s.is_stiff())
    }

    /// Under `auto`, change method if the stiffness tests say so, before a communication
    /// step of size `communication_step`. Call only between communication steps; returns
    /// whether the method changed, in which case the integrator must restart from the
    /// communication point.
    ///
    /// The tests inlined into the step, the change of method out of line: called on its
    /// own, the whole of it (with the new method's frame) cost a call with a large stack
    /// frame at every communication point.
    #[inline(always)]
    pub fn reconsider(&mut self, communication_step: f64) -> bool {
        if self.choice != Choice::Auto {
            return false;
        }
        let change = match &self.active {
            Active::Explicit(s) => s.is_stiff() && worth_landing(s, communication_step),
            Active::Implicit(s) => s.is_non_stiff(),
        };
        if change {
            self.change_method();
        }
        change
    }

    /// `auto`'s change of method: the other one goes on with this one's progress.
    #[cold]
    #[inline(never)]
    fn change_method(&mut self) {
        self.active = match &self.active {
            Active::Explicit(s) => Active::Implicit(Radau5::resume(s.progress())),
            Active::Implicit(s) => Active::Explicit(Dop853::resume(s.progress())),
        };
    }

    /// Everything the integrator remembers, in the byte form of [`crate::bytes`].
    pub fn serialize_into(&self, w: &mut Writer) {
        put!(w.u8(match self.choice {
            Choice::Auto => 0,
            Choice::Fixed(Method::Dop853) => 1,
            Choice::Fixed(Method::Radau5) => 2,
        }));
        put!(w.u8(match self.method() {
            Method::Dop853 => 1,
            Method::Radau5 => 2,
        }));
        on_active!(&self.active, s => s.serialize_into(w));
        put!(w.bool(self.short_step.is_some()));
        put!(w.f64(self.short_step.unwrap_or(0.0)));
    }

    /// The integrator written by [`Integrator::serialize_into`].
    pub fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let choice = match r.u8()? {
            0 => Choice::Auto,
            1 => Choice::Fixed(Method::Dop853),
            2 => Choice::Fixed(Method::Radau5),
            other => return Err(FormatError(format!("invalid method choice {other}"))),
        };
        let active = match r.u8()? {
            1 => Active::Explicit(Dop853::deserialize_from(r)?),
            2 => Active::Implicit(Radau5::deserialize_from(r)?),
            other => return Err(FormatError(format!("invalid active method {other}"))),
        };
        // Like the methods' own step sizes, one that is not finite and positive is dropped.
        let has_short = r.bool()?;
        let short = r.f64()?;
        let short_step = has_short
            .then_some(short)
            .filter(|h| h.is_finite() && *h > 0.0);
        Ok(Self {
            choice,
            active,
            short_step,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Prothero–Robinson with a stiffness that ends: λ = 1e5 before t = 1, λ = 1 after:
    /// `auto` switches to Radau IIA within the first steps and back some time after t = 1.
    struct StiffThenNot;
    impl OdeSystem<1> for StiffThenNot {
        fn rhs(&self, t: f64, y: &[f64; 1], dy: &mut [f64; 1]) {
            let lambda = if t < 1.0 { 1e5 } else { 1.0 };
            dy[0] = -lambda * (y[0] - t.cos()) - t.sin();
        }
    }

    /// Communication steps of 0.01 s as a master would make them; the method in use at
    /// each step's end.
    fn run(choice: Choice) -> (Vec<Method>, Integrator<1>, f64) {
        let mut integrator = Integrator::new(
            choice,
            Tolerances {
                rtol: 1e-8,
                atol: 1e-8,
            },
        );
        let (mut t_comm, mut y_comm) = (0.0, [1.0]);
        let (mut t, mut y) = (t_comm, y_comm);
        let mut methods = Vec::new();
        for k in 1..=300 {
            if integrator.reconsider(0.01) {
                (t, y) = (t_comm, y_comm);
                integrator.invalidate();
            }
            let target = k as f64 * 0.01;
            integrator
                .integrate(&StiffThenNot, &mut t, &mut y, target, f64::INFINITY)
                .unwrap();
            y_comm = integrator.dense_output(&StiffThenNot, target).unwrap();
            t_comm = target;
            methods.push(integrator.method());
        }
        let error = (y_comm[0] - t_comm.cos()).abs();
        (methods, integrator, error)
    }

    #[test]
    fn auto_switches_to_the_implicit_method_and_back() {
        let (methods, auto, error) = run(Choice::Auto);
        assert!(error < 1e-6, "{error}");
        // Stiff within the first steps, non-stiff soon after t = 1.
        let first_implicit = methods.iter().position(|m| *m == Method::Radau5).unwrap();
        assert!(first_implicit <= 2, "{first_implicit}");
        let back = methods[first_implicit..]
            .iter()
            .position(|m| *m == Method::Dop853)
            .unwrap()
            + first_implicit;
        assert!((100..=170).contains(&back), "switched back at step {back}");
        assert!(methods[back..].iter().all(|m| *m == Method::Dop853));
        let (_, explicit, _) = run(Choice::Fixed(Method::Dop853));
        let (auto_work, explicit_work) = (auto.statistics().n_rhs, explicit.statistics().n_rhs);
        assert!(
            auto_work * 20 < explicit_work,
            "{auto_work} vs {explicit_work}"
        );
    }

    #[test]
    fn fixed_choices_never_switch() {
        for method in [Method::Dop853, Method::Radau5] {
            let (methods, _, error) = run(Choice::Fixed(method));
            assert!(methods.iter().all(|m| *m == method));
            assert!(error < 1e-6, "{method:?}: {error}");
        }
    }
}
