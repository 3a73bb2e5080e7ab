//! The classic fourth-order Runge–Kutta method with an embedded third-order estimate,
//! for steps far shorter than DOP853's natural step.
//!
//! A step costs three evaluations besides f at its start, and a fourth, f at its end, for
//! its error: with k5 = f(t + h, y_new), the weights (1/6, 1/3, 1/3, 0, 1/6) on (k1 … k5)
//! give a third-order solution, and the difference from the fourth-order one is
//! h/6·(k4 − k5). The end is projected onto the manifold before k5 is evaluated there, so
//! k5 is f at the point the next step starts from: the next step's k1 (first same as
//! last). The projection moves the end by about a local error, which changes the estimate
//! by h·L times that, an order higher than the estimate itself.
//!
//! When the right-hand side changes at every communication point (a coupled master sets
//! an input each step), a DOP853 step costs at least twelve evaluations where this one
//! costs four, and a step of a millisecond is far below what an eighth-order method needs
//! to be accurate. The caller may give the first step's k1 ([`Rk4::start_with`]): the
//! driver derives it from the last k5 when only inputs that enter the right-hand side
//! linearly changed.

use super::{
    after_accepted, check_step_size, first_step, plan_step, OdeSystem, Progress, SolverError,
    Stepper, Tolerances,
};
use crate::bytes::{same_bits, FormatError, Reader, Writer};
use crate::put;

const SAFETY: f64 = 0.9;
const FACTOR_MIN: f64 = 0.2;
const FACTOR_MAX: f64 = 5.0;

/// The last accepted step, for the dense output and the memory check.
#[derive(Clone, Copy, Debug)]
struct LastStep<const N: usize> {
    t_old: f64,
    h: f64,
    y_old: [f64; N],
    /// The step's end after projection.
    y_new: [f64; N],
    f_old: [f64; N],
    /// f at the projected end (the fifth stage).
    f_new: [f64; N],
}

/// The method for an `N`-dimensional system. All working storage is inline.
#[derive(Clone, Debug)]
pub struct Rk4<const N: usize> {
    progress: Progress,
    /// f(t, y) at the integrator's point, while valid.
    first: Option<[f64; N]>,
    last_step: Option<LastStep<N>>,
}

impl<const N: usize> Rk4<N> {
    #[inline(always)]
    fn eval<S: OdeSystem<N>>(&mut self, system: &S, t: f64, y: &[f64; N]) -> [f64; N] {
        let mut f = [0.0; N];
        system.rhs(t, y, &mut f);
        self.progress.stats.n_rhs += 1;
        f
    }

    /// Start the next call's first step with `k1` = f(t, y) at the point it starts from.
    pub fn start_with(&mut self, k1: [f64; N]) {
        self.first = Some(k1);
    }

    /// f(t, y) at the integrator's point, if known: after a step, f at its projected end.
    pub fn first_stage(&self) -> Option<[f64; N]> {
        self.first
    }

    /// One trial step of size `h` from (t, y) with f(t, y) = `k1`: the fourth-order end,
    /// projected, in `y_new`, f there in `f_new`, and the scaled error norm (NaN for a
    /// non-finite stage). Where the end cannot be projected, the error of the unprojected
    /// end decides: a step to be rejected anyway is rejected, an accepted one fails with
    /// the projection's reason.
    #[inline(always)]
    fn attempt<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        (t, y, k1): (f64, &[f64; N], &[f64; N]),
        h: f64,
        y_new: &mut [f64; N],
        f_new: &mut [f64; N],
    ) -> Result<f64, String> {
        let half = 0.5 * h;
        let k2 = self.eval(
            system,
            t + half,
            &std::array::from_fn(|n| y[n] + half * k1[n]),
        );
        let k3 = self.eval(
            system,
            t + half,
            &std::array::from_fn(|n| y[n] + half * k2[n]),
        );
        let k4 = self.eval(system, t + h, &std::array::from_fn(|n| y[n] + h * k3[n]));
        let sixth = h / 6.0;
        for n in 0..N {
            y_new[n] = y[n] + sixth * ((k1[n] + k4[n]) + 2.0 * (k2[n] + k3[n]));
        }
        let mut projected = *y_new;
        let projection = system.project(y, &mut projected);
        if projection.is_ok() {
            *y_new = projected;
        }
        *f_new = self.eval(system, t + h, y_new);
        let Tolerances { rtol, atol } = self.progress.tolerances;
        let mut sum = 0.0;
        for n in 0..N {
            let scale = atol + rtol * y[n].abs().max(y_new[n].abs());
            sum += (sixth * (k4[n] - f_new[n]) / scale).powi(2);
        }
        let error = (sum / system.dimension() as f64).sqrt();
        match projection {
            Err(reason) if error <= 1.0 => Err(reason),
            _ => Ok(error),
        }
    }
}

/// The factor the next step's size changes by after a step with scaled error `error`
/// (the estimate is of order 3, hence the fourth root); no growth after a rejection.
fn step_factor(error: f64, after_rejection: bool) -> f64 {
    if !error.is_finite() {
        return 0.1;
    }
    let factor = if error == 0.0 {
        FACTOR_MAX
    } else {
        (SAFETY / error.sqrt().sqrt()).clamp(FACTOR_MIN, FACTOR_MAX)
    };
    if after_rejection {
        factor.min(1.0)
    } else {
        factor
    }
}

impl<const N: usize> Stepper<N> for Rk4<N> {
    fn new(tolerances: Tolerances) -> Self {
        Self {
            progress: Progress::new(tolerances),
            first: None,
            last_step: None,
        }
    }

    fn progress(&self) -> Progress {
        self.progress
    }

    fn progress_mut(&mut self) -> &mut Progress {
        &mut self.progress
    }

    fn invalidate(&mut self) {
        self.first = None;
        self.last_step = None;
    }

    fn integrate<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: &mut f64,
        y: &mut [f64; N],
        target: f64,
        limit: f64,
    ) -> Result<(), SolverError> {
        debug_assert!(target <= limit);
        if *t >= target {
            return Ok(());
        }
        let mut k1 = match self.first {
            Some(first) => first,
            None => self.eval(system, *t, y),
        };
        let mut h = first_step(&mut self.progress, system, (*t, &*y, &k1), target, 4);
        let mut last_rejected = false;
        let (mut y_new, mut f_new) = ([0.0; N], [0.0; N]);
        while *t < target {
            let (h_step, landing) = plan_step(*t, h, limit, &self.progress)?;
            let attempted = self.attempt(system, (*t, y, &k1), h_step, &mut y_new, &mut f_new);
            let error = match attempted {
                Ok(error) => error,
                Err(reason) => {
                    self.first = None;
                    self.last_step = None;
                    return Err(SolverError::ProjectionFailed {
                        t: *t + h_step,
                        reason,
                    });
                }
            };
            if error.is_nan() || error > 1.0 {
                self.progress.stats.n_rejected += 1;
                h = h_step * step_factor(error, true).min(0.5);
                last_rejected = true;
                check_step_size(*t, h)?;
                continue;
            }
            self.progress.stats.n_steps += 1;
            self.last_step = Some(LastStep {
                t_old: *t,
                h: h_step,
                y_old: *y,
                y_new,
                f_old: k1,
                f_new,
            });
            *y = y_new;
            *t = if landing { limit } else { *t + h_step };
            k1 = f_new;
            self.first = Some(k1);
            h = after_accepted(h_step * step_factor(error, last_rejected), h, landing);
            last_rejected = false;
        }
        self.progress.next_step = Some(h);
        Ok(())
    }

    /// The cubic Hermite interpolant of the last step: its ends and f there (order 3).
    fn dense_output<S: OdeSystem<N>>(&mut self, _system: &S, t: f64) -> Option<[f64; N]> {
        let step = self.last_step.as_ref()?;
        let x = (t - step.t_old) / step.h;
        if !(-1e-12..=1.0 + 1e-12).contains(&x) {
            return None;
        }
        let h = step.h;
        Some(std::array::from_fn(|n| {
            let delta = step.y_new[n] - step.y_old[n];
            let a = h * step.f_old[n] - delta;
            let b = 2.0 * delta - h * (step.f_new[n] + step.f_old[n]);
            step.y_old[n] + x * (delta + (1.0 - x) * (a + x * b))
        }))
    }

    /// The last step taken again from its stored start must give its stored end and
    /// slopes bit for bit, and a stored f(t, y) must be the system's.
    fn check_memory<S: OdeSystem<N>>(
        &self,
        system: &S,
        t: f64,
        y: &[f64; N],
    ) -> Result<(), String> {
        let mut copy = self.clone();
        if let Some(first) = self.first {
            if !same_bits(&copy.eval(system, t, y), &first) {
                return Err("the stored f(t, y) is not the system's".into());
            }
        }
        let Some(step) = self.last_step else {
            return Ok(());
        };
        if !same_bits(&step.y_new, y) {
            return Err("the last step does not end at the integrator's state".into());
        }
        let f_old = copy.eval(system, step.t_old, &step.y_old);
        let (mut y_new, mut f_new) = ([0.0; N], [0.0; N]);
        copy.attempt(
            system,
            (step.t_old, &step.y_old, &f_old),
            step.h,
            &mut y_new,
            &mut f_new,
        )?;
        let agree = same_bits(&f_old, &step.f_old)
            && same_bits(&f_new, &step.f_new)
            && same_bits(&y_new, &step.y_new);
        if !agree {
            return Err("the last step's slopes or end do not follow from its start".into());
        }
        Ok(())
    }

    fn serialize_into(&self, w: &mut Writer) {
        self.progress.serialize_into(w);
        put!(w.bool(self.first.is_some()));
        put!(w.f64s(&self.first.unwrap_or([0.0; N])));
        put!(w.bool(self.last_step.is_some()));
        if let Some(step) = &self.last_step {
            put!(w.f64s(&[step.t_old, step.h]));
            for vector in [&step.y_old, &step.y_new, &step.f_old, &step.f_new] {
                put!(w.f64s(vector));
            }
        }
    }

    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let mut method = Self::resume(Progress::deserialize_from(r)?);
        let has_first = r.bool()?;
        let first = r.f64s()?;
        method.first = has_first.then_some(first);
        if r.bool()? {
            let [t_old, h] = r.f64s()?;
            method.last_step = Some(LastStep {
                t_old,
                h,
                y_old: r.f64s()?,
                y_new: r.f64s()?,
                f_old: r.f64s()?,
                f_new: r.f64s()?,
            });
        }
        Ok(method)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_problems::{tol, Oscillator};

    /// The estimate h/6·(k4 − k5) falls as h⁴ (a third-order solution against a
    /// fourth-order one), and the fourth-order end's own error as h⁵.
    #[test]
    fn the_estimate_and_the_step_have_their_orders() {
        let errors = |h: f64| {
            let mut method = Rk4::<2>::new(tol(1.0));
            let (y, mut k1) = ([1.0, 0.0], [0.0; 2]);
            Oscillator.rhs(0.0, &y, &mut k1);
            let (mut y_new, mut f_new) = ([0.0; 2], [0.0; 2]);
            let estimate = method
                .attempt(&Oscillator, (0.0, &y, &k1), h, &mut y_new, &mut f_new)
                .unwrap();
            let true_error = (y_new[0] - h.cos()).abs().max((y_new[1] + h.sin()).abs());
            (estimate, true_error)
        };
        let (e1, t1) = errors(0.02);
        let (e2, t2) = errors(0.01);
        assert!(
            (14.0..18.0).contains(&(e1 / e2)),
            "estimate ratio {}",
            e1 / e2
        );
        assert!((28.0..36.0).contains(&(t1 / t2)), "error ratio {}", t1 / t2);
        assert!(
            t1 < e1,
            "the estimate {e1:e} does not bound the error {t1:e}"
        );
    }

    /// A step that lands on the limit costs five evaluations when f at the start is not
    /// known (the four stages and the estimate's), four when it is given, and the next
    /// step starts from the estimate's f at the projected end.
    #[test]
    fn a_landing_step_costs_five_evaluations_or_four_given_its_first_stage() {
        let run = |first: Option<[f64; 2]>| {
            let mut method = Rk4::<2>::new(tol(1e-8));
            method.progress_mut().next_step = Some(1e-3);
            if let Some(k1) = first {
                method.start_with(k1);
            }
            let (mut t, mut y) = (0.0, [1.0, 0.0]);
            method
                .integrate(&Oscillator, &mut t, &mut y, 1e-3, 1e-3)
                .unwrap();
            assert_eq!(t, 1e-3);
            let mut f_end = [0.0; 2];
            Oscillator.rhs(t, &y, &mut f_end);
            assert_eq!(method.first_stage(), Some(f_end));
            let stats = method.statistics();
            (stats.n_steps, stats.n_rhs, stats.n_rejected, y)
        };
        let (steps, rhs, rejected, cold) = run(None);
        assert_eq!((steps, rhs, rejected), (1, 5, 0));
        let (steps, rhs, rejected, given) = run(Some([0.0, -1.0]));
        assert_eq!((steps, rhs, rejected), (1, 4, 0));
        assert_eq!(cold, given);
    }
}
