//! Dormand & Prince's explicit Runge–Kutta method of order 8 with the 5(3) error estimator
//! and step-size control of Hairer's DOP853 (Hairer, Nørsett & Wanner, Solving ODEs I,
//! II.4 and II.10).
//!
//! Differences from the textbook driver, for co-simulation:
//! - the step size carries over from one `integrate` call to the next (warm restart), so
//!   the initial-step heuristic runs once, and a step shortened only to land on a limit
//!   does not shrink the next call's step;
//! - the first stage of a step is reused from the previous step's end (after projection)
//!   unless [`Dop853::invalidate`] says the state or the problem changed;
//! - every accepted step is projected by [`OdeSystem::project`];
//! - `integrate` may step past its target (up to a limit) and the caller reads the solution
//!   at the target from the 7th-order dense output of the last step, whose three extra
//!   stages are evaluated only when asked for.

use super::dop853_tableau::{A, A_DENSE, B, C, C_DENSE, D, E3, E5};
use super::{
    after_accepted, check_step_size, first_step, plan_step, OdeSystem, Progress, SolverError,
    Stepper, Tolerances,
};
use crate::bytes::{same_bits, FormatError, Reader, Writer};
use crate::put;

const STAGES: usize = 12;
/// Stage slots: the twelve stages, f(t + h, y_new) (the next step's first stage), and the
/// three extra stages of the dense output.
const SLOTS: usize = 16;
const NEXT_FIRST: usize = 12;
/// Step-size factor bounds per step (Hairer's fac1 = 0.333, fac2 = 6) and safety factor.
const FACTOR_MIN: f64 = 0.333;
const FACTOR_MAX: f64 = 6.0;
const SAFETY: f64 = 0.9;
/// Lund stabilisation of the step-size control (HNW II, IV.2; dop853.f's `beta`, which
/// Hairer allows up to 0.04): the new step size also depends on the last accepted step's
/// error, h_new = h·SAFETY·err^(−1/8)·(err^0.2·err_old)^β. On the paper's cases it
/// rejects far fewer steps than β = 0 and takes no more evaluations at equal worst error
/// over all communication points ([`step_factor`] approximates the powers).
const BETA: f64 = 0.04;
/// Hairer's floor on the remembered error (his `facold`), and its starting value; its
/// log₂ is what the control stores.
const SMALLEST_REMEMBERED_ERROR: f64 = 1e-4;
const LOG2_SMALLEST_REMEMBERED_ERROR: f64 = rough_log2(SMALLEST_REMEMBERED_ERROR);

/// The last accepted step: start time, size, and the states at both ends (the end as
/// projected).
#[derive(Clone, Copy, Debug)]
struct LastStep<const N: usize> {
    t_old: f64,
    h: f64,
    /// 1/h: the dense output's x = (t − t_old)/h by a multiplication rather than a
    /// division, at the start of each communication point's chain of dependent operations.
    inverse_h: f64,
    y_old: [f64; N],
    y_new: [f64; N],
}

/// The DOP853 integrator for an `N`-dimensional system. All working storage is inline.
#[derive(Clone, Debug)]
pub struct Dop853<const N: usize> {
    progress: Progress,
    /// Stages of the last step (slots 0..12), f at its end (slot 12) and the dense
    /// output's extra stages (13..16).
    stages: [[f64; N]; SLOTS],
    /// Whether slot 12 holds f(t, y) for the current (t, y).
    first_stage_valid: bool,
    /// The last accepted step, while its stages are intact.
    last_step: Option<LastStep<N>>,
    /// Dense-output coefficients of the last step, computed on first use.
    dense: Option<[[f64; N]; 7]>,
    /// Hairer's stiffness test over the last accepted steps (a few flops per step).
    stiffness: StiffnessTest,
    /// log₂ of the last accepted step's scaled error, at least
    /// [`SMALLEST_REMEMBERED_ERROR`]: the memory of the stabilised step-size control.
    log2_last_error: f64,
}

/// Hairer's stiffness test for DOP853 (HNW II, IV.2; dop853.f): after each accepted step
/// |hλ| ≈ h·|f(y_new) − f(y₁₂)| / |y_new − y₁₂|, y₁₂ being the last stage's argument (both at
/// t + h). Above the stability boundary the step size is limited by stability, not accuracy.
///
/// The estimate sees λ only along one direction, so in a stability-limited run (steps
/// hovering at the boundary) only about half of the steps show it on a stiff coupling,
/// while the paper's non-stiff cases exceed it in a few steps at loose tolerances only.
/// Hence a window rather than Hairer's run of 15: the problem counts as stiff when
/// `STIFF_STEPS` of the last 32 accepted steps exceeded the boundary.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct StiffnessTest {
    /// One bit per accepted step, newest lowest: whether |hλ| exceeded the boundary.
    history: u32,
}

/// DOP853's stability boundary along the negative real axis (dop853.f uses 6.1).
const STABILITY_BOUNDARY: f64 = 6.1;
const STIFF_STEPS: u32 = 10;

impl StiffnessTest {
    fn record(&mut self, h_lambda: f64) {
        self.history = (self.history << 1) | u32::from(h_lambda > STABILITY_BOUNDARY);
    }

    fn is_stiff(&self) -> bool {
        self.history.count_ones() >= STIFF_STEPS
    }
}

impl<const N: usize> Dop853<N> {
    /// Whether the stiffness test says the step size is limited by stability: an
    /// implicit method would take far fewer evaluations, and DOP853's fast modes may carry
    /// noise its error estimate does not see.
    pub fn is_stiff(&self) -> bool {
        self.stiffness.is_stiff()
    }

    /// The step size the next call will try first, once chosen.
    pub fn next_step(&self) -> Option<f64> {
        self.progress.next_step
    }

    /// Evaluate the extra stages and form the interpolant's seven coefficient vectors in
    /// `self.dense`, and return them. Formed in place: returned by value, the 448 bytes
    /// were copied twice on their way into the field.
    #[inline(always)]
    fn dense_coefficients<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        step: &LastStep<N>,
    ) -> &[[f64; N]; 7] {
        let LastStep {
            t_old,
            h,
            y_old,
            y_new,
            ..
        } = *step;
        for (extra, c) in C_DENSE.into_iter().enumerate() {
            let slot = NEXT_FIRST + 1 + extra;
            let increment = dense_stage_increment(extra, &self.stages);
            let y_stage: [f64; N] = std::array::from_fn(|n| y_old[n] + h * increment[n]);
            self.eval(system, t_old + c * h, &y_stage, slot);
        }
        let (f_old, f_new) = (self.stages[0], self.stages[NEXT_FIRST]);
        let coefficients = self.dense.insert([[0.0; N]; 7]);
        for row in 0..D.len() {
            let sum = dense_coefficient_sum(row, &self.stages);
            coefficients[3 + row] = std::array::from_fn(|n| h * sum[n]);
        }
        for n in 0..N {
            let delta = y_new[n] - y_old[n];
            coefficients[0][n] = delta;
            coefficients[1][n] = h * f_old[n] - delta;
            coefficients[2][n] = 2.0 * delta - h * (f_new[n] + f_old[n]);
        }
        coefficients
    }

    /// One trial step of size `h` from (t, y), with f(t, y) in slot 12 (the previous
    /// step's end, or a fresh evaluation).
    /// Writes the 8th-order result to `y_new`, leaves the last stage's argument (at t + h)
    /// in `y_stage` for the stiffness test, and returns the scaled error norm.
    #[inline(always)]
    fn attempt<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: f64,
        y: &[f64; N],
        h: f64,
        y_new: &mut [f64; N],
        y_stage: &mut [f64; N],
    ) -> f64 {
        self.stages[0] = self.stages[NEXT_FIRST];
        for (i, &c) in C.iter().enumerate().skip(1) {
            let increment = stage_increment(i, &self.stages);
            for n in 0..N {
                y_stage[n] = y[n] + h * increment[n];
            }
            self.eval(system, t + c * h, y_stage, i);
        }
        let [increment, e5, e3] = step_sums(&self.stages);
        let Tolerances { rtol, atol } = self.progress.tolerances;
        let (mut err5, mut err3) = (0.0, 0.0);
        for n in 0..N {
            y_new[n] = y[n] + h * increment[n];
        }
        for n in 0..system.controlled() {
            let scale = atol + rtol * y[n].abs().max(y_new[n].abs());
            err5 += (e5[n] / scale).powi(2);
            err3 += (e3[n] / scale).powi(2);
        }
        if err5 == 0.0 && err3 == 0.0 {
            return 0.0;
        }
        // Hairer's combination of the 5th- and 3rd-order estimates (dop853.f).
        h.abs() * err5 / ((err5 + 0.01 * err3) * system.controlled() as f64).sqrt()
    }

    /// |hλ| along the last step: f at its end `y_end` (slot 12) against f at its last stage
    /// (slot 11, argument `y_stage`), over the distance between the two points.
    #[inline(always)]
    fn stiffness_estimate(&self, h: f64, y_end: &[f64; N], y_stage: &[f64; N]) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        let (f_end, f_stage) = (&self.stages[NEXT_FIRST], &self.stages[STAGES - 1]);
        for n in 0..N {
            num += (f_end[n] - f_stage[n]).powi(2);
        }
        for (end, stage) in y_end.iter().zip(y_stage) {
            den += (end - stage).powi(2);
        }
        if den > 0.0 {
            h * (num / den).sqrt()
        } else {
            0.0
        }
    }

    #[inline(always)]
    fn eval<S: OdeSystem<N>>(&mut self, system: &S, t: f64, y: &[f64; N], stage: usize) {
        system.rhs(t, y, &mut self.stages[stage]);
        self.progress.stats.n_rhs += 1;
    }
}

/// The factor a rejected step's size shrinks by: Hairer's, the accepted steps' formula
/// without the memory; a tenth after a non-finite stage.
#[inline(always)]
fn rejection_factor(error: f64) -> f64 {
    if error.is_finite() {
        step_factor(error, rough_log2(error), 0.0, false)
    } else {
        0.1
    }
}

/// error^(−1/8) by three square roots (a few instructions each) instead of a C library
/// call of `powf` on every step; the two differ by at most 2 ulp over 1e-14…1e3 (tested
/// below), far below what the step-size control can resolve.
#[inline(always)]
fn inverse_eighth_root(error: f64) -> f64 {
    1.0 / error.sqrt().sqrt().sqrt()
}

/// log₂ x to within 0.009 for a positive x (below the smallest normal number, as for
/// it): the exponent, and log₂ m of the significand m ∈ [1, 2) as t·(1.3465 − 0.3465·t),
/// t = m − 1. Enough for the stabilisation's small powers (an error of 0.009 moves the
/// step-size factor by less than 3e-4 of itself), without a division or a library call,
/// and in parallel with [`inverse_eighth_root`]'s square roots.
#[inline(always)]
const fn rough_log2(x: f64) -> f64 {
    let bits = x.max(f64::MIN_POSITIVE).to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as f64 - 1023.0;
    let t = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52)) - 1.0;
    exponent + t * (1.3465 - 0.3465 * t)
}

/// 2ᵘ for u clamped to [−1, ½], to within 3e-4: e^(u·ln 2) by Taylor's series to the
/// fifth power.
#[inline(always)]
fn rough_exp2(u: f64) -> f64 {
    let y = u.clamp(-1.0, 0.5) * std::f64::consts::LN_2;
    1.0 + y * (1.0 + y * (0.5 + y * (1.0 / 6.0 + y * (1.0 / 24.0 + y * (1.0 / 120.0)))))
}

/// Step-size factor after a step with scaled error `error` (log₂ of it in `log2_error`),
/// given log₂ of the previous accepted step's ([`BETA`]; 0 leaves the memory out, as
/// after a rejection): no growth right after a rejection (HNW I, II.4). An error of zero
/// gives the largest factor.
fn step_factor(error: f64, log2_error: f64, log2_last_error: f64, after_rejection: bool) -> f64 {
    let stabilisation = rough_exp2(BETA * (0.2 * log2_error + log2_last_error));
    let factor =
        (SAFETY * inverse_eighth_root(error) * stabilisation).clamp(FACTOR_MIN, FACTOR_MAX);
    if after_rejection {
        factor.min(1.0)
    } else {
        factor
    }
}

/// `$body` with `$index` bound to a literal in one arm per listed value, so that the
/// compiler sees the tableau row it selects; any other value takes the same `$body` with
/// the index read at run time.
macro_rules! with_known_index {
    ($index:expr, |$k:ident| $body:expr, $($value:literal)*) => {
        match $index {
            $($value => {
                let $k: usize = $value;
                $body
            })*
            $k => $body,
        }
    };
}

/// Σ_j weights[j]·k_j over the stage slots listed, as [`combine`] sums them (same order,
/// same bits), but with every slot a literal: where `weights` is a row known to the
/// compiler, each zero entry is dropped at compile time and the sum is straight-line code.
/// [`combine`] over such a row stayed a loop that tested each weight for zero at run time
/// (rows of 11 to 16 entries were not unrolled).
macro_rules! tableau_sum {
    ($weights:expr, $stages:expr, $($j:literal)*) => {{
        let (weights, stages) = (&$weights, $stages);
        let mut sum = [0.0; N];
        $(
            if $j < weights.len() && weights[$j] != 0.0 {
                for (s, k) in sum.iter_mut().zip(&stages[$j]) {
                    *s += weights[$j] * k;
                }
            }
        )*
        sum
    }};
}

/// Σ_j A[i][j]·k_j for stage `i` of a step, with the row known to the compiler: the zero
/// entries cost nothing and the sums are straight-line code. The general form, one loop
/// over `i` with the row read at run time, tested every weight for zero, as many
/// instructions as the multiply-adds themselves; it stays as the last arm, which the
/// steps never reach.
#[inline(always)]
fn stage_increment<const N: usize>(i: usize, stages: &[[f64; N]; SLOTS]) -> [f64; N] {
    with_known_index!(
        i,
        |row| tableau_sum!(A[row][..row], stages, 0 1 2 3 4 5 6 7 8 9 10),
        1 2 3 4 5 6 7 8 9 10 11
    )
}

/// Σ_j A_DENSE[extra][j]·k_j for the interpolant's extra stage `extra` (slot 13 + extra),
/// with the row known to the compiler as in [`stage_increment`].
#[inline(always)]
fn dense_stage_increment<const N: usize>(extra: usize, stages: &[[f64; N]; SLOTS]) -> [f64; N] {
    with_known_index!(
        extra,
        |row| tableau_sum!(
            A_DENSE[row][..NEXT_FIRST + 1 + row],
            stages,
            0 1 2 3 4 5 6 7 8 9 10 11 12 13 14
        ),
        0 1 2
    )
}

/// Σ_j D[row][j]·k_j, the interpolant's coefficient `row` (before the factor h).
#[inline(always)]
fn dense_coefficient_sum<const N: usize>(row: usize, stages: &[[f64; N]; SLOTS]) -> [f64; N] {
    with_known_index!(
        row,
        |row| tableau_sum!(D[row], stages, 0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15),
        0 1 2 3
    )
}

/// The step's three sums over its twelve stages: the 8th-order increment (B) and the 5th-
/// and 3rd-order error estimates (E5, E3).
#[inline(always)]
fn step_sums<const N: usize>(stages: &[[f64; N]; SLOTS]) -> [[f64; N]; 3] {
    [
        tableau_sum!(B, stages, 0 1 2 3 4 5 6 7 8 9 10 11),
        tableau_sum!(E5, stages, 0 1 2 3 4 5 6 7 8 9 10 11),
        tableau_sum!(E3, stages, 0 1 2 3 4 5 6 7 8 9 10 11),
    ]
}

impl<const N: usize> Stepper<N> for Dop853<N> {
    fn new(tolerances: Tolerances) -> Self {
        Self {
            progress: Progress::new(tolerances),
            stages: [[0.0; N]; SLOTS],
            first_stage_valid: false,
            last_step: None,
            dense: None,
            stiffness: StiffnessTest::default(),
            log2_last_error: LOG2_SMALLEST_REMEMBERED_ERROR,
        }
    }

    fn progress(&self) -> Progress {
        self.progress
    }

    fn progress_mut(&mut self) -> &mut Progress {
        &mut self.progress
    }

    /// The state or the right-hand side changed outside the integrator (new inputs, a
    /// restored state): the stored first stage no longer applies. The step size stays.
    fn invalidate(&mut self) {
        self.first_stage_valid = false;
        self.last_step = None;
    }

    /// Integrate from (`*t`, `*y`) until `*t >= target`, never stepping past `limit`
    /// (a step that would, lands on it exactly); `target == limit` lands exactly on the
    /// target. The solution in between comes from [`Dop853::dense_output`]. On error,
    /// `*t` and `*y` hold the last accepted (projected) step.
    #[inline(always)]
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
        if !self.first_stage_valid {
            self.eval(system, *t, y, NEXT_FIRST);
            self.first_stage_valid = true;
        }
        let first = (*t, &*y, &self.stages[NEXT_FIRST]);
        let mut h = first_step(&mut self.progress, system, first, target, 8);
        let mut last_rejected = false;
        let (mut y_new, mut last_stage) = ([0.0; N], [0.0; N]);
        while *t < target {
            let (h_step, landing) = plan_step(*t, h, limit, &self.progress)?;
            self.last_step = None;
            self.dense = None;
            let error = self.attempt(system, *t, y, h_step, &mut y_new, &mut last_stage);
            if error.is_nan() || error > 1.0 {
                // Rejected, or a non-finite stage (error is NaN or infinite).
                self.progress.stats.n_rejected += 1;
                h = h_step * rejection_factor(error);
                last_rejected = true;
                check_step_size(*t, h)?;
                continue;
            }
            if let Err(reason) = system.project(y, &mut y_new) {
                self.first_stage_valid = false;
                return Err(SolverError::ProjectionFailed {
                    t: *t + h_step,
                    reason,
                });
            }
            self.progress.stats.n_steps += 1;
            self.last_step = Some(LastStep {
                t_old: *t,
                h: h_step,
                inverse_h: 1.0 / h_step,
                y_old: *y,
                y_new,
            });
            *y = y_new;
            *t = if landing { limit } else { *t + h_step };
            self.eval(system, *t, y, NEXT_FIRST);
            let h_lambda = self.stiffness_estimate(h_step, y, &last_stage);
            self.stiffness.record(h_lambda);
            let log2_error = rough_log2(error);
            let factor = step_factor(error, log2_error, self.log2_last_error, last_rejected);
            self.log2_last_error = log2_error.max(LOG2_SMALLEST_REMEMBERED_ERROR);
            h = after_accepted(h_step * factor, h, landing);
            last_rejected = false;
        }
        self.progress.next_step = Some(h);
        Ok(())
    }

    /// The solution at `t` within the last accepted step, from the 7th-order continuous
    /// extension of DOP853 (HNW I, II.6). Its three extra stages are evaluated on the
    /// first request after a step. `None` when no step is available (none taken since the
    /// last [`Dop853::invalidate`]) or `t` lies outside it.
    #[inline(always)]
    fn dense_output<S: OdeSystem<N>>(&mut self, system: &S, t: f64) -> Option<[f64; N]> {
        let step = self.last_step.as_ref()?;
        let x = (t - step.t_old) * step.inverse_h;
        if !(-1e-12..=1.0 + 1e-12).contains(&x) {
            return None;
        }
        if self.dense.is_none() {
            let step = *step;
            self.dense_coefficients(system, &step);
        }
        let (step, coefficients) = (self.last_step.as_ref()?, self.dense.as_ref()?);
        // The interpolant x·(d0 + u·d2 + u²·d4 + u³·d6) + u·(d1 + u·d3 + u²·d5), u = x·(1 − x):
        // Hairer's seven nested levels in x and 1 − x regrouped into two independent sums,
        // each split at u² (Estrin's scheme), for a short chain of dependent operations on
        // the path of every communication point.
        let [d0, d1, d2, d3, d4, d5, d6] = coefficients;
        let u = x * (1.0 - x);
        let uu = u * u;
        let x_part: [f64; N] =
            std::array::from_fn(|n| (d0[n] + u * d2[n]) + uu * (d4[n] + u * d6[n]));
        let u_part: [f64; N] = std::array::from_fn(|n| (d1[n] + u * d3[n]) + uu * d5[n]);
        let y: [f64; N] = std::array::from_fn(|n| step.y_old[n] + (x * x_part[n] + u * u_part[n]));
        Some(y)
    }

    /// Check restored memory against `system` at the integrator's point (t, y): a step is
    /// deterministic, so the last step is taken again from its stored start, and its
    /// stages, its (projected) end, the interpolant and f(t, y) must come out bit for bit
    /// as stored. Memory that differs was altered after it was written.
    fn check_memory<S: OdeSystem<N>>(
        &self,
        system: &S,
        t: f64,
        y: &[f64; N],
    ) -> Result<(), String> {
        let same = |a: &[f64; N], b: &[f64; N]| same_bits(a, b);
        let mut copy = self.clone();
        if self.first_stage_valid {
            copy.eval(system, t, y, NEXT_FIRST);
            if !same(&copy.stages[NEXT_FIRST], &self.stages[NEXT_FIRST]) {
                return Err("the stored f(t, y) is not the system's".into());
            }
        }
        let Some(step) = self.last_step else {
            return Ok(());
        };
        if !same(&step.y_new, y) || !self.first_stage_valid {
            return Err("the last step does not end at the integrator's state".into());
        }
        copy.eval(system, step.t_old, &step.y_old, NEXT_FIRST);
        let (mut y_new, mut y_stage) = ([0.0; N], [0.0; N]);
        copy.attempt(
            system,
            step.t_old,
            &step.y_old,
            step.h,
            &mut y_new,
            &mut y_stage,
        );
        system.project(&step.y_old, &mut y_new)?;
        let stages_agree = (0..STAGES).all(|i| same(&copy.stages[i], &self.stages[i]));
        if !stages_agree || !same(&y_new, &step.y_new) {
            return Err("the last step's stages or end do not follow from its start".into());
        }
        if let Some(dense) = &self.dense {
            // The interpolant also uses f at the step's end, checked above.
            copy.stages[NEXT_FIRST] = self.stages[NEXT_FIRST];
            let again = copy.dense_coefficients(system, &step);
            if !(0..7).all(|i| same(&again[i], &dense[i])) {
                return Err("the stored interpolant is not the last step's".into());
            }
        }
        Ok(())
    }

    /// Everything the integrator remembers (step size, stages, dense output, counters),
    /// as bytes: restoring it continues bit for bit.
    fn serialize_into(&self, w: &mut Writer) {
        self.progress.serialize_into(w);
        self.stages.iter().for_each(|stage| w.f64s(stage));
        put!(w.bool(self.first_stage_valid));
        put!(w.bool(self.last_step.is_some()));
        if let Some(step) = &self.last_step {
            put!(w.f64s(&[step.t_old, step.h]));
            put!(w.f64s(&step.y_old));
            put!(w.f64s(&step.y_new));
        }
        put!(w.bool(self.dense.is_some()));
        if let Some(dense) = &self.dense {
            dense.iter().for_each(|row| w.f64s(row));
        }
        put!(w.u64(self.stiffness.history as u64));
        put!(w.f64(self.log2_last_error));
    }

    /// The integrator written by [`Dop853::serialize_into`].
    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let mut solver = Self::resume(Progress::deserialize_from(r)?);
        for stage in solver.stages.iter_mut() {
            *stage = r.f64s()?;
        }
        solver.first_stage_valid = r.bool()?;
        if r.bool()? {
            let [t_old, h] = r.f64s()?;
            solver.last_step = Some(LastStep {
                t_old,
                inverse_h: 1.0 / h,
                h,
                y_old: r.f64s()?,
                y_new: r.f64s()?,
            });
        }
        if r.bool()? {
            let mut dense = [[0.0; N]; 7];
            for row in dense.iter_mut() {
                *row = r.f64s()?;
            }
            solver.dense = Some(dense);
        }
        solver.stiffness = StiffnessTest {
            history: r.u64()? as u32,
        };
        // Like a stored step size, a remembered error outside what the control stores (a
        // changed buffer) is dropped: the control starts from Hairer's initial value.
        let remembered = r.f64()?;
        solver.log2_last_error = if (LOG2_SMALLEST_REMEMBERED_ERROR..=0.0).contains(&remembered) {
            remembered
        } else {
            LOG2_SMALLEST_REMEMBERED_ERROR
        };
        Ok(solver)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::combine;
    use crate::test_problems::{tol, Oscillator};

    #[test]
    fn step_size_carries_over_between_calls() {
        let mut solver = Dop853::new(tol(1e-8));
        let (mut t, mut y) = (0.0, [1.0, 0.0]);
        solver
            .integrate(&Oscillator, &mut t, &mut y, 1.0, 1.0)
            .unwrap();
        let h = solver.next_step().unwrap();
        let evaluations = solver.statistics().n_rhs;
        // Many short calls: one step each, 12 evaluations each, no restart heuristic.
        for k in 1..=100 {
            let t_end = 1.0 + k as f64 * 1e-4;
            solver
                .integrate(&Oscillator, &mut t, &mut y, t_end, t_end)
                .unwrap();
        }
        assert_eq!(solver.statistics().n_rhs - evaluations, 100 * 12);
        assert!(solver.next_step().unwrap() >= h * 0.999);
    }

    /// A right-hand side that turns NaN: the solver must stop with an error, not loop.
    struct Blowup;
    impl OdeSystem<1> for Blowup {
        fn rhs(&self, t: f64, _y: &[f64; 1], dy: &mut [f64; 1]) {
            dy[0] = if t > 0.5 { f64::NAN } else { 1.0 };
        }
    }

    #[test]
    fn non_finite_right_hand_side_is_an_error_and_state_stays_finite() {
        let mut solver = Dop853::new(tol(1e-8));
        let (mut t, mut y) = (0.0, [0.0]);
        let result = solver.integrate(&Blowup, &mut t, &mut y, 1.0, 1.0);
        assert!(
            matches!(result, Err(SolverError::StepSizeTooSmall { .. })),
            "{result:?}"
        );
        assert!(t <= 0.5 && y[0].is_finite() && (y[0] - t).abs() < 1e-12);
    }

    #[test]
    fn spelled_out_stage_sums_equal_the_tableau_rows() {
        // Stage vectors with no zero and no pattern, so that any wrong weight or slice shows.
        let stages: [[f64; 3]; SLOTS] =
            std::array::from_fn(|j| std::array::from_fn(|n| ((j * 7 + n * 3 + 1) as f64).sin()));
        let same =
            |a: [f64; 3], b: [f64; 3]| a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits());
        for i in 1..STAGES {
            assert!(
                same(stage_increment(i, &stages), combine(&A[i][..i], &stages)),
                "stage {i}"
            );
        }
        for extra in 0..3 {
            let row = combine(&A_DENSE[extra][..NEXT_FIRST + 1 + extra], &stages);
            assert!(
                same(dense_stage_increment(extra, &stages), row),
                "extra stage {extra}"
            );
        }
        for (row, d) in D.iter().enumerate() {
            let sum = combine(d, &stages);
            assert!(
                same(dense_coefficient_sum(row, &stages), sum),
                "D row {row}"
            );
        }
        let [increment, e5, e3] = step_sums(&stages);
        for (sum, weights, name) in [(increment, B, "B"), (e5, E5, "E5"), (e3, E3, "E3")] {
            assert!(same(sum, combine(&weights, &stages[..STAGES])), "{name}");
        }
    }

    #[test]
    fn the_step_factors_root_is_powf_to_two_ulp() {
        let ulps = |a: f64, b: f64| (a - b).abs() / (b.next_up() - b);
        let mut worst: f64 = 0.0;
        for k in 0..=170_000 {
            let error = 10f64.powf(-14.0 + k as f64 * 1e-4);
            worst = worst.max(ulps(inverse_eighth_root(error), error.powf(-1.0 / 8.0)));
        }
        assert!(worst <= 2.0, "{worst} ulp");
    }

    #[test]
    fn the_step_factor_is_the_stabilised_formula() {
        let mut worst: f64 = 0.0;
        for k in 0..=1000 {
            let error = 10f64.powf(-10.0 + k as f64 * 1e-2);
            for last in [1e-4, 3e-3, 0.5, 1.0f64] {
                let exact = (SAFETY * error.powf(-0.125) * (error.powf(0.2) * last).powf(BETA))
                    .clamp(FACTOR_MIN, FACTOR_MAX);
                let factor = step_factor(error, rough_log2(error), rough_log2(last), false);
                worst = worst.max((factor - exact).abs() / exact);
            }
        }
        // Rejected steps (error above 1): the memory left out.
        for k in 1..=600 {
            let error = 10f64.powf(k as f64 * 1e-2);
            let exact = (SAFETY * error.powf(-0.125 + 0.2 * BETA)).clamp(FACTOR_MIN, FACTOR_MAX);
            let factor = step_factor(error, rough_log2(error), 0.0, false);
            worst = worst.max((factor - exact).abs() / exact);
        }
        assert!(worst <= 3e-4, "{worst}");
        let floor = LOG2_SMALLEST_REMEMBERED_ERROR;
        assert_eq!(step_factor(0.0, rough_log2(0.0), floor, false), FACTOR_MAX);
        assert_eq!(step_factor(1e-9, rough_log2(1e-9), floor, true), 1.0);
        // A step at the tolerance after a nearly exact one grows less than after one at it.
        let half = rough_log2(0.5);
        assert!(step_factor(0.5, half, floor, false) < step_factor(0.5, half, 0.0, false));
    }

    /// The remembered error of the step-size control goes with a serialized state: out of
    /// the control's range it is dropped on reading, and a non-finite one is refused.
    #[test]
    fn the_remembered_error_is_checked_on_restore() {
        let mut solver = Dop853::new(tol(1e-8));
        let (mut t, mut y) = (0.0, [1.0, 0.0]);
        solver
            .integrate(&Oscillator, &mut t, &mut y, 3.0, f64::INFINITY)
            .unwrap();
        assert!(solver.log2_last_error > LOG2_SMALLEST_REMEMBERED_ERROR);
        let copy_of = |solver: &Dop853<2>| {
            let mut w = Writer::default();
            solver.serialize_into(&mut w);
            let bytes = w.into_bytes();
            let mut reader = Reader::new(&bytes);
            Dop853::<2>::deserialize_from(&mut reader)
        };
        let copy = copy_of(&solver).unwrap();
        assert_eq!(copy.log2_last_error, solver.log2_last_error);
        for bad in [1.0, -100.0] {
            solver.log2_last_error = bad;
            let copy = copy_of(&solver).unwrap();
            assert_eq!(copy.log2_last_error, LOG2_SMALLEST_REMEMBERED_ERROR);
        }
        solver.log2_last_error = f64::NAN;
        assert!(copy_of(&solver).is_err());
    }

    #[test]
    fn the_rough_logarithm_and_power_are_within_their_bounds() {
        let mut x = 1e-300;
        while x < 1e300 {
            assert!((rough_log2(x) - x.log2()).abs() <= 0.009, "{x}");
            x *= 1.37;
        }
        let mut u = -1.0;
        while u <= 0.5 {
            assert!((rough_exp2(u) - u.exp2()).abs() <= 3e-4 * u.exp2(), "{u}");
            u += 1e-3;
        }
    }
}
