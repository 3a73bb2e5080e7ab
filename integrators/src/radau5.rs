//! The 3-stage Radau IIA method of order 5 for stiff problems, with the simplified Newton
//! iteration, embedded error estimate and step-size control of Hairer & Wanner's RADAU5
//! (Solving ODEs II, IV.8).
//!
//! The collocation system Z = h·(A⊗I)·F(Z) for the stage increments Z is solved in the
//! eigenbasis of A⁻¹ (one real eigenvalue, one complex pair), so each Newton iteration
//! needs one real and one complex N×N solve with the iteration matrices (γ/h)·I − J and
//! ((α+iβ)/h)·I − J. The Jacobian J is a forward difference (N evaluations, counted in
//! `n_rhs`), reused over steps while the Newton iteration converges quickly; the LU
//! factors are reused while the step size stays put.
//!
//! Co-simulation behaviour matches [`super::Dop853`]: warm restarts, every accepted step
//! projected by [`OdeSystem::project`], `integrate` steps past its target up to a limit,
//! and the collocation polynomial serves as dense output.

use super::linear::{Complex, Lu, Singular};
use super::{
    after_accepted, check_step_size, combine, first_step, plan_step, OdeSystem, Progress,
    SolverError, Statistics, Stepper, Tolerances,
};
use crate::bytes::{same_bits, FormatError, Reader, Writer};
use crate::put;

use super::radau5_tableau::{ALPHA_BETA, C, E, GAMMA, T, T_INV};

/// Newton iterations per attempt before the step is retried smaller.
const MAX_NEWTON: usize = 7;
/// Step-size factor bounds per step (Hairer's 1/facl = 0.2 and 1/facr = 8).
const FACTOR_MIN: f64 = 0.2;
const FACTOR_MAX: f64 = 8.0;
/// A factor in [1, KEEP_STEP) keeps the step size, and with it the LU factors.
const KEEP_STEP: f64 = 1.2;
/// The Jacobian is kept for the next step unless the last Newton iteration contracted more
/// slowly than this. Hairer's default is 0.001; here a Jacobian costs N evaluations against
/// 3 per Newton iteration, so reusing it more often pays (the stiff case of tests/stiff.rs
/// took fewest evaluations near this value).
const JACOBIAN_REUSE_RATE: f64 = 1e-2;
/// Power iterations for the spectral-radius estimate of J (the non-stiffness test).
const POWER_ITERATIONS: usize = 12;

/// The last accepted step: start, size, start state and the stage increments Z, the last
/// one replaced by the projected end state minus the start.
#[derive(Clone, Copy, Debug)]
struct LastStep<const N: usize> {
    t_old: f64,
    h: f64,
    y_old: [f64; N],
    z: [[f64; N]; 3],
}

impl<const N: usize> LastStep<N> {
    /// The collocation polynomial at s = (t − t_old)/h: through (0, y_old), (cᵢ, y_old + Zᵢ).
    fn at(&self, s: f64) -> [f64; N] {
        let weights: [f64; 3] = std::array::from_fn(|i| {
            let (others, ci) = (C.iter().enumerate().filter(|(j, _)| *j != i), C[i]);
            let (num, den) = others.fold((s, ci), |(num, den), (_, cj)| {
                (num * (s - cj), den * (ci - cj))
            });
            num / den
        });
        let increment = combine(&weights, &self.z);
        std::array::from_fn(|n| self.y_old[n] + increment[n])
    }
}

/// LU factors of (γ/h)·I − J and ((α+iβ)/h)·I − J for one Jacobian J and step size h.
#[derive(Clone, Copy, Debug)]
struct IterationMatrices<const N: usize> {
    real: Lu<f64, N>,
    complex: Lu<Complex, N>,
    h: f64,
}

impl<const N: usize> IterationMatrices<N> {
    fn factor(jacobian: &[[f64; N]; N], h: f64) -> Result<Self, Singular> {
        let (gamma_h, alpha_beta_h) = (GAMMA / h, ALPHA_BETA.scale(1.0 / h));
        let real = std::array::from_fn(|i| {
            std::array::from_fn(|j| if i == j { gamma_h } else { 0.0 } - jacobian[i][j])
        });
        let complex = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let diagonal = if i == j {
                    alpha_beta_h
                } else {
                    Complex::default()
                };
                diagonal - Complex::new(jacobian[i][j], 0.0)
            })
        });
        Ok(Self {
            real: Lu::factor(real)?,
            complex: Lu::factor(complex)?,
            h,
        })
    }
}

/// How one trial step ended.
enum Attempt {
    /// The Newton iteration converged; the scaled error norm, and the iterations used.
    Converged { error: f64, iterations: usize },
    /// The Newton iteration diverged, converged too slowly, or met a non-finite value.
    Diverged,
}

/// The Radau IIA (order 5) integrator for an `N`-dimensional system; all storage inline.
#[derive(Clone, Debug)]
pub struct Radau5<const N: usize> {
    progress: Progress,
    /// f(t, y) at the integrator's current point, valid when `f0_valid`.
    f0: [f64; N],
    f0_valid: bool,
    /// The Jacobian and where it was taken: `jacobian_valid` once any exists,
    /// `jacobian_current` if it belongs to the current point.
    jacobian: [[f64; N]; N],
    jacobian_valid: bool,
    jacobian_current: bool,
    /// |λ|max of the Jacobian (power-iteration estimate), for the non-stiffness test.
    spectral_radius: f64,
    /// The factored iteration matrices, for the current Jacobian and one step size.
    factors: Option<IterationMatrices<N>>,
    /// Hairer's faccon: the expected contraction factor θ/(1−θ) of the next iteration.
    contraction: f64,
    /// The previous accepted step's size and error, for the predictive controller.
    previous: Option<(f64, f64)>,
    last_step: Option<LastStep<N>>,
    /// Consecutive accepted steps with h·|λ|max below the explicit method's stability limit.
    non_stiff_steps: u32,
}

/// h·|λ|max below which the explicit method would not be limited by stability at this
/// step size (half DOP853's boundary of about 6, for a margin).
const NON_STIFF_LIMIT: f64 = 3.0;
/// Accepted steps in a row below that limit before the problem counts as non-stiff: a
/// stiff transient resolved with short steps is not the end of stiffness: with a shorter
/// run required, the stiff run of tests/no_allocation.rs (an input jump every tenth
/// communication step) changed method back and forth many times; with this one, only at
/// the start and once near the end.
const NON_STIFF_STEPS: u32 = 50;

impl<const N: usize> Radau5<N> {
    pub fn next_step(&self) -> Option<f64> {
        self.progress.next_step
    }

    /// Whether after each of the last `NON_STIFF_STEPS` accepted steps the proposed step was
    /// short enough for an explicit method to be stable: the problem no longer needs this one.
    pub fn is_non_stiff(&self) -> bool {
        self.non_stiff_steps >= NON_STIFF_STEPS
    }

    /// Take the step: project the end state, remember the step for dense output and the
    /// next starting guess, move to the end and evaluate f there.
    fn accept<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: &mut f64,
        y: &mut [f64; N],
        t_new: f64,
        z: &[[f64; N]; 3],
    ) -> Result<(), SolverError> {
        let mut y_new: [f64; N] = std::array::from_fn(|n| y[n] + z[2][n]);
        if let Err(reason) = system.project(y, &mut y_new) {
            self.f0_valid = false;
            return Err(SolverError::ProjectionFailed { t: t_new, reason });
        }
        self.progress.stats.n_steps += 1;
        let mut z = *z;
        z[2] = std::array::from_fn(|n| y_new[n] - y[n]);
        self.last_step = Some(LastStep {
            t_old: *t,
            h: t_new - *t,
            y_old: *y,
            z,
        });
        *y = y_new;
        *t = t_new;
        self.f0 = evaluate(system, &mut self.progress.stats, *t, y);
        self.jacobian_current = false;
        self.contraction = self.contraction.max(f64::EPSILON).powf(0.8);
        Ok(())
    }

    /// Gustafsson's predictive controller (HNW II, IV.8 (8.25)) as in RADAU5.
    fn predicted_factor(&self, h: f64, error: f64) -> f64 {
        let mut factor = error.powf(-0.25);
        if let Some((h_old, error_old)) = self.previous {
            let predictive = h / h_old * (error_old / error).powf(0.25);
            factor *= predictive.min(1.0);
        }
        factor
    }

    /// Count accepted steps after which the proposed step `h` (not shortened to land on a
    /// communication point) is one an explicit method could also take stably.
    fn record_stiffness(&mut self, h: f64) {
        if h * self.spectral_radius < NON_STIFF_LIMIT {
            self.non_stiff_steps = self.non_stiff_steps.saturating_add(1);
        } else {
            self.non_stiff_steps = 0;
        }
    }

    /// One trial step of size `h` from (t, y): solve the collocation system by simplified
    /// Newton iteration, leave the stage increments in `z` and estimate the error.
    fn attempt<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: f64,
        y: &[f64; N],
        h: f64,
        after_rejection: bool,
        z: &mut [[f64; N]; 3],
    ) -> Attempt {
        let factors = match self.factors {
            Some(factors) if factors.h == h => factors,
            _ => match IterationMatrices::factor(&self.jacobian, h) {
                Ok(factors) => *self.factors.insert(factors),
                Err(Singular) => return Attempt::Diverged,
            },
        };
        let Tolerances { rtol, atol } = self.progress.tolerances;
        let scale: [f64; N] = std::array::from_fn(|n| atol + rtol * y[n].abs());
        self.starting_guess(y, h, z);
        let Some(iterations) = self.newton(system, (t, y, h), &factors, &scale, z) else {
            return Attempt::Diverged;
        };
        let error = self.error_estimate(system, (t, y, h), &factors.real, z, after_rejection);
        if error.is_finite() {
            Attempt::Converged { error, iterations }
        } else {
            Attempt::Diverged
        }
    }

    /// Z from the last step's collocation polynomial, extrapolated; zero after a restart.
    /// (The last step, while there is one, ends where this one starts: `invalidate` drops
    /// it whenever the point moves otherwise.)
    fn starting_guess(&self, y: &[f64; N], h: f64, z: &mut [[f64; N]; 3]) {
        match &self.last_step {
            Some(last) => {
                for (zi, ci) in z.iter_mut().zip(C) {
                    let u = last.at(1.0 + ci * h / last.h);
                    *zi = std::array::from_fn(|n| u[n] - y[n]);
                }
            }
            None => *z = [[0.0; N]; 3],
        }
    }

    /// The simplified Newton iteration in the transformed variables W = (T⁻¹⊗I)·Z.
    /// Returns the iterations used, or `None` if it does not converge.
    fn newton<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        (t, y, h): (f64, &[f64; N], f64),
        factors: &IterationMatrices<N>,
        scale: &[f64; N],
        z: &mut [[f64; N]; 3],
    ) -> Option<usize> {
        let tolerance = self.newton_tolerance();
        let mut w = transform(&T_INV, z);
        let mut previous_norm = f64::NAN;
        let (gamma_h, alpha_beta_h) = (GAMMA / h, ALPHA_BETA.scale(1.0 / h));
        for iteration in 0..MAX_NEWTON {
            let mut f = [[0.0; N]; 3];
            for i in 0..3 {
                let stage: [f64; N] = std::array::from_fn(|n| y[n] + z[i][n]);
                f[i] = evaluate(system, &mut self.progress.stats, t + C[i] * h, &stage);
            }
            if f.iter().flatten().any(|v| !v.is_finite()) {
                return None;
            }
            let g = transform(&T_INV, &f);
            let mut real: [f64; N] = std::array::from_fn(|n| g[0][n] - gamma_h * w[0][n]);
            let mut complex: [Complex; N] = std::array::from_fn(|n| {
                Complex::new(g[1][n], g[2][n]) - alpha_beta_h * Complex::new(w[1][n], w[2][n])
            });
            factors.real.solve(&mut real);
            factors.complex.solve(&mut complex);
            let norm = ((0..N)
                .map(|n| {
                    (real[n].powi(2) + complex[n].re.powi(2) + complex[n].im.powi(2))
                        / scale[n].powi(2)
                })
                .sum::<f64>()
                / (3 * system.dimension()) as f64)
                .sqrt();
            if iteration > 0 {
                let rate = norm / previous_norm;
                let remaining = (MAX_NEWTON - 1 - iteration) as i32;
                if rate.is_nan()
                    || rate >= 0.99
                    || rate.powi(remaining) / (1.0 - rate) * norm > tolerance
                {
                    return None;
                }
                self.contraction = rate / (1.0 - rate);
            }
            for n in 0..N {
                w[0][n] += real[n];
                w[1][n] += complex[n].re;
                w[2][n] += complex[n].im;
            }
            *z = transform(&T, &w);
            if self.contraction * norm <= tolerance || norm == 0.0 {
                return Some(iteration + 1);
            }
            previous_norm = norm;
        }
        None
    }

    /// Hairer's stopping tolerance for the Newton iteration, relative to the error scale.
    fn newton_tolerance(&self) -> f64 {
        let rtol = self.progress.tolerances.rtol;
        (10.0 * f64::EPSILON / rtol).max(0.03f64.min(rtol.sqrt()))
    }

    /// The embedded third-order error estimate, filtered through ((γ/h)·I − J)⁻¹ so that
    /// stiff components do not inflate it; after a rejection (or if it is large on a first
    /// step) refined once more as in RADAU5. Returns the scaled RMS norm.
    fn error_estimate<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        (t, y, h): (f64, &[f64; N], f64),
        lu_real: &Lu<f64, N>,
        z: &[[f64; N]; 3],
        after_rejection: bool,
    ) -> f64 {
        let Tolerances { rtol, atol } = self.progress.tolerances;
        let scale: [f64; N] =
            std::array::from_fn(|n| atol + rtol * y[n].abs().max((y[n] + z[2][n]).abs()));
        let ze = combine(&E, z).map(|v| v / h);
        let dimension = system.dimension() as f64;
        let norm = |e: &[f64; N]| {
            ((0..N).map(|n| (e[n] / scale[n]).powi(2)).sum::<f64>() / dimension)
                .sqrt()
                .max(1e-10)
        };
        let mut error: [f64; N] = std::array::from_fn(|n| self.f0[n] + ze[n]);
        lu_real.solve(&mut error);
        let mut size = norm(&error);
        if size > 1.0 && (after_rejection || self.previous.is_none()) {
            let shifted: [f64; N] = std::array::from_fn(|n| y[n] + error[n]);
            let f = evaluate(system, &mut self.progress.stats, t, &shifted);
            error = std::array::from_fn(|n| f[n] + ze[n]);
            lu_real.solve(&mut error);
            size = norm(&error);
        }
        size
    }

    /// The first-stage value and the Jacobian at (t, y) if missing, and the step size to
    /// try first: the one the last call proposed, else the starting step for the span to
    /// `target`.
    fn prepare<S: OdeSystem<N>>(&mut self, system: &S, t: f64, y: &[f64; N], target: f64) -> f64 {
        if !self.f0_valid {
            self.f0 = evaluate(system, &mut self.progress.stats, t, y);
            self.f0_valid = true;
        }
        if !self.jacobian_valid {
            self.update_jacobian(system, t, y);
        }
        first_step(&mut self.progress, system, (t, y, &self.f0), target, 5)
    }

    /// After an accepted step of `h_step` with scaled `error`, at its end (t, y): the
    /// Jacobian renewed when the Newton iteration said it was poor (it goes stale with the
    /// state), and the next step size, kept (with the LU factors) when the change would be
    /// small.
    fn next_step_size<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        (t, y): (f64, &[f64; N]),
        (h_step, error, safety): (f64, f64, f64),
        iterations: usize,
        after_rejection: bool,
    ) -> f64 {
        let renew = iterations > 1 && self.contraction > JACOBIAN_REUSE_RATE;
        if renew {
            self.update_jacobian(system, t, y);
        }
        let mut factor = (safety * self.predicted_factor(h_step, error)).min(FACTOR_MAX);
        if after_rejection {
            factor = factor.min(1.0);
        }
        self.previous = Some((h_step, error));
        if (1.0..KEEP_STEP).contains(&factor) && !renew {
            h_step
        } else {
            h_step * factor
        }
    }

    /// Forward-difference Jacobian at (t, y), with f(t, y) = `self.f0`: one evaluation per
    /// component of the problem ([`OdeSystem::dimension`]).
    fn update_jacobian<S: OdeSystem<N>>(&mut self, system: &S, t: f64, y: &[f64; N]) {
        let mut shifted = *y;
        for j in 0..system.dimension() {
            let delta = (f64::EPSILON * 1e-5f64.max(y[j].abs())).sqrt();
            shifted[j] = y[j] + delta;
            let f = evaluate(system, &mut self.progress.stats, t, &shifted);
            for (row, (fi, f0i)) in self.jacobian.iter_mut().zip(f.iter().zip(&self.f0)) {
                row[j] = (fi - f0i) / delta;
            }
            shifted[j] = y[j];
        }
        self.jacobian_valid = true;
        self.jacobian_current = true;
        self.factors = None;
        self.spectral_radius = spectral_radius(&self.jacobian);
    }
}

/// f(t, y), counted. A function of the counters rather than a method, so that the solver's
/// other fields (the LU factors) stay borrowable meanwhile.
#[inline]
fn evaluate<S: OdeSystem<N>, const N: usize>(
    system: &S,
    stats: &mut Statistics,
    t: f64,
    y: &[f64; N],
) -> [f64; N] {
    let mut dy = [0.0; N];
    system.rhs(t, y, &mut dy);
    stats.n_rhs += 1;
    dy
}

/// (M⊗I)·X for a 3×3 matrix M and three stacked N-vectors X.
fn transform<const N: usize>(m: &[[f64; 3]; 3], x: &[[f64; N]; 3]) -> [[f64; N]; 3] {
    std::array::from_fn(|i| combine(&m[i], x))
}

/// An estimate of the spectral radius of `j` by power iteration: the geometric mean of
/// the growth factors (which also converges for a dominant complex pair).
fn spectral_radius<const N: usize>(j: &[[f64; N]; N]) -> f64 {
    let mut v = [1.0 / (N as f64).sqrt(); N];
    let mut log_growth = 0.0;
    let mut counted = 0;
    for iteration in 0..POWER_ITERATIONS {
        let next: [f64; N] = std::array::from_fn(|i| (0..N).map(|k| j[i][k] * v[k]).sum());
        let size = next.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(size > 0.0 && size.is_finite()) {
            return if size == 0.0 { 0.0 } else { f64::INFINITY };
        }
        // Skip the first iterations, dominated by the start vector.
        if iteration >= POWER_ITERATIONS / 2 {
            log_growth += size.ln();
            counted += 1;
        }
        v = next.map(|x| x / size);
    }
    (log_growth / counted as f64).exp()
}

impl<const N: usize> Stepper<N> for Radau5<N> {
    fn new(tolerances: Tolerances) -> Self {
        Self {
            progress: Progress::new(tolerances),
            f0: [0.0; N],
            f0_valid: false,
            jacobian: [[0.0; N]; N],
            jacobian_valid: false,
            jacobian_current: false,
            spectral_radius: 0.0,
            factors: None,
            contraction: 1.0,
            previous: None,
            last_step: None,
            non_stiff_steps: 0,
        }
    }

    fn progress(&self) -> Progress {
        self.progress
    }

    fn progress_mut(&mut self) -> &mut Progress {
        &mut self.progress
    }

    /// The state or the right-hand side changed outside the integrator: f(t, y), the
    /// Jacobian's currency and the last step no longer apply. The Jacobian itself and
    /// the step size are kept as good first guesses.
    fn invalidate(&mut self) {
        self.f0_valid = false;
        self.jacobian_current = false;
        self.last_step = None;
        self.previous = None;
    }

    /// Integrate from (`*t`, `*y`) to `target` exactly. Unlike [`super::Dop853`], Radau IIA
    /// never steps past its target (so `limit` only bounds it like the target does): its
    /// collocation polynomial is only third order between the nodes, while DOP853's dense
    /// output is seventh order: on a stiff problem, stepping past the target and
    /// interpolating back misses the tolerance by orders of magnitude, landing does not.
    fn integrate<S: OdeSystem<N>>(
        &mut self,
        system: &S,
        t: &mut f64,
        y: &mut [f64; N],
        target: f64,
        limit: f64,
    ) -> Result<(), SolverError> {
        debug_assert!(target <= limit);
        let limit = target;
        if *t >= target {
            return Ok(());
        }
        let mut h = self.prepare(system, *t, y, target);
        let mut rejected = false;
        let mut z = [[0.0; N]; 3];
        while *t < target {
            let (h_step, landing) = plan_step(*t, h, limit, &self.progress)?;
            let (error, iterations) = match self.attempt(system, *t, y, h_step, rejected, &mut z) {
                Attempt::Converged { error, iterations } => (error, iterations),
                Attempt::Diverged => {
                    self.progress.stats.n_rejected += 1;
                    if self.jacobian_current {
                        h = h_step * 0.5;
                    } else {
                        // A stale Jacobian may be all that is wrong: renew it, same step.
                        self.update_jacobian(system, *t, y);
                        h = h_step;
                    }
                    rejected = true;
                    check_step_size(*t, h)?;
                    continue;
                }
            };
            let safety = 0.9 * (2 * MAX_NEWTON + 1) as f64 / (2 * MAX_NEWTON + iterations) as f64;
            if error > 1.0 {
                self.progress.stats.n_rejected += 1;
                let factor = safety * self.predicted_factor(h_step, error);
                h = h_step * factor.max(FACTOR_MIN);
                rejected = true;
                continue;
            }
            let t_new = if landing { limit } else { *t + h_step };
            self.accept(system, t, y, t_new, &z)?;
            let h_new = self.next_step_size(
                system,
                (*t, y),
                (h_step, error, safety),
                iterations,
                rejected,
            );
            h = after_accepted(h_new, h, landing);
            self.record_stiffness(h);
            rejected = false;
        }
        self.progress.next_step = Some(h);
        Ok(())
    }

    /// The solution at `t` within the last accepted step, from its collocation polynomial
    /// (order 3 between the nodes). `None` when there is no step or `t` lies outside it.
    fn dense_output<S: OdeSystem<N>>(&mut self, _system: &S, t: f64) -> Option<[f64; N]> {
        let step = self.last_step.as_ref()?;
        let s = (t - step.t_old) / step.h;
        // At s = 1 the interpolant is exactly the (projected) end state.
        (-1e-12..=1.0 + 1e-12).contains(&s).then(|| step.at(s))
    }

    /// Check restored memory against `system` at the integrator's point (t, y): the stored
    /// f(t, y) must be the system's bit for bit, and the last step must end at (t, y). (The
    /// Jacobian and the inner stages only steer Newton's iteration and the interpolant
    /// between nodes, which communication points never use: a step ends on each.)
    fn check_memory<S: OdeSystem<N>>(
        &self,
        system: &S,
        t: f64,
        y: &[f64; N],
    ) -> Result<(), String> {
        if self.f0_valid {
            let mut stats = Statistics::default();
            let f = evaluate(system, &mut stats, t, y);
            if !same_bits(&f, &self.f0) {
                return Err("the stored f(t, y) is not the system's".into());
            }
        }
        if let Some(step) = &self.last_step {
            let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * (a.abs() + b.abs());
            let ends_here = (0..N).all(|n| close(step.y_old[n] + step.z[2][n], y[n]));
            if !close(step.t_old + step.h, t) || !ends_here {
                return Err("the last step does not end at the integrator's state".into());
            }
        }
        Ok(())
    }

    /// Everything the integrator remembers, in the byte form of [`crate::bytes`].
    fn serialize_into(&self, w: &mut Writer) {
        self.progress.serialize_into(w);
        put!(w.f64s(&self.f0));
        put!(w.bool(self.f0_valid));
        self.jacobian.iter().for_each(|row| w.f64s(row));
        put!(w.bool(self.jacobian_valid));
        put!(w.bool(self.jacobian_current));
        // The LU factors and the spectral radius are recomputed from the Jacobian on
        // restore (bit-identical: both are deterministic), so only the step size is stored.
        put!(w.bool(self.factors.is_some()));
        put!(w.f64(self.factors.map_or(0.0, |factors| factors.h)));
        put!(w.f64(self.contraction));
        put!(w.bool(self.previous.is_some()));
        let (h_old, error_old) = self.previous.unwrap_or((0.0, 0.0));
        put!(w.f64s(&[h_old, error_old]));
        put!(w.bool(self.last_step.is_some()));
        if let Some(step) = &self.last_step {
            put!(w.f64s(&[step.t_old, step.h]));
            put!(w.f64s(&step.y_old));
            step.z.iter().for_each(|zi| w.f64s(zi));
        }
        put!(w.u64(self.non_stiff_steps as u64));
    }

    /// The integrator written by [`Radau5::serialize_into`].
    fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let mut solver = Self::resume(Progress::deserialize_from(r)?);
        solver.f0 = r.f64s()?;
        solver.f0_valid = r.bool()?;
        for row in solver.jacobian.iter_mut() {
            *row = r.f64s()?;
        }
        solver.jacobian_valid = r.bool()?;
        solver.jacobian_current = r.bool()?;
        if solver.jacobian_valid {
            solver.spectral_radius = spectral_radius(&solver.jacobian);
        }
        let factored = r.bool()?;
        let h = r.f64()?;
        if factored {
            let factors = IterationMatrices::factor(&solver.jacobian, h).map_err(|_| {
                FormatError("invalid serialized state: singular iteration matrix".into())
            })?;
            solver.factors = Some(factors);
        }
        solver.contraction = r.f64()?;
        let has_previous = r.bool()?;
        let [h_old, error_old] = r.f64s()?;
        solver.previous = has_previous.then_some((h_old, error_old));
        if r.bool()? {
            let [t_old, h] = r.f64s()?;
            solver.last_step = Some(LastStep {
                t_old,
                h,
                y_old: r.f64s()?,
                z: [r.f64s()?, r.f64s()?, r.f64s()?],
            });
        }
        solver.non_stiff_steps = r.u64()?.min(u32::MAX as u64) as u32;
        Ok(solver)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radau5_tableau::SQRT6;
    use crate::test_problems::tol;
    use crate::Dop853;

    /// The Radau IIA (order 5) coefficient matrix, from its closed form.
    fn radau_matrix() -> [[f64; 3]; 3] {
        let s = SQRT6;
        [
            [
                (88.0 - 7.0 * s) / 360.0,
                (296.0 - 169.0 * s) / 1800.0,
                (-2.0 + 3.0 * s) / 225.0,
            ],
            [
                (296.0 + 169.0 * s) / 1800.0,
                (88.0 + 7.0 * s) / 360.0,
                (-2.0 - 3.0 * s) / 225.0,
            ],
            [(16.0 - s) / 36.0, (16.0 + s) / 36.0, 1.0 / 9.0],
        ]
    }

    fn product(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
    }

    #[test]
    fn transformation_diagonalises_the_inverse_coefficient_matrix() {
        let identity = product(&T, &T_INV);
        // T⁻¹·A⁻¹·T = Λ  ⟺  A·T·Λ = T.
        let (a, b) = (ALPHA_BETA.re, ALPHA_BETA.im);
        let lambda = [[GAMMA, 0.0, 0.0], [0.0, a, -b], [0.0, b, a]];
        let back = product(&product(&radau_matrix(), &T), &lambda);
        for i in 0..3 {
            for j in 0..3 {
                let unit = if i == j { 1.0 } else { 0.0 };
                assert!((identity[i][j] - unit).abs() < 1e-14, "T·T⁻¹ {identity:?}");
                assert!((back[i][j] - T[i][j]).abs() < 1e-14, "A·T·Λ {back:?}");
            }
        }
        // Row sums of A are the nodes; the last row is the weights (stiffly accurate).
        for (row, c) in radau_matrix().iter().zip(C) {
            assert!((row.iter().sum::<f64>() - c).abs() < 1e-15);
        }
    }

    /// Prothero–Robinson: y' = −λ·(y − cos t) − sin t, exact solution cos t, very stiff.
    struct ProtheroRobinson(f64);
    impl OdeSystem<1> for ProtheroRobinson {
        fn rhs(&self, t: f64, y: &[f64; 1], dy: &mut [f64; 1]) {
            dy[0] = -self.0 * (y[0] - t.cos()) - t.sin();
        }
    }

    /// Van der Pol in Hairer's scaled form with ε = 1e-6 (HNW II, IV.10 "VDPOL"): very
    /// stiff, nonlinear, relaxation oscillations of period about 0.8.
    struct VanDerPol;
    impl OdeSystem<2> for VanDerPol {
        fn rhs(&self, _t: f64, y: &[f64; 2], dy: &mut [f64; 2]) {
            *dy = [y[1], ((1.0 - y[0] * y[0]) * y[1] - y[0]) / 1e-6];
        }
    }

    #[test]
    fn stiff_linear_problem_takes_few_steps_where_dop853_takes_many() {
        let system = ProtheroRobinson(1e5);
        let mut radau = Radau5::new(tol(1e-8));
        let (mut t, mut y) = (0.0, [1.0]);
        radau
            .integrate(&system, &mut t, &mut y, 10.0, 10.0)
            .unwrap();
        assert!((y[0] - 10f64.cos()).abs() < 1e-7, "{}", y[0]);
        let radau_work = radau.statistics().n_rhs;
        let mut dop = Dop853::new(tol(1e-8));
        let (mut t, mut y) = (0.0, [1.0]);
        dop.integrate(&system, &mut t, &mut y, 10.0, 10.0).unwrap();
        let dop_work = dop.statistics().n_rhs;
        assert!(dop.is_stiff(), "the stiffness test must fire");
        assert!(
            radau_work * 100 < dop_work,
            "radau {radau_work}, dop853 {dop_work} evaluations"
        );
    }

    #[test]
    fn van_der_pol_relaxation_oscillation() {
        let mut solver = Radau5::new(tol(1e-6));
        let (mut t, mut y) = (0.0, [2.0, -0.66]);
        solver
            .integrate(&VanDerPol, &mut t, &mut y, 2.0, 2.0)
            .unwrap();
        let stats = solver.statistics();
        // Two relaxation jumps; y₁(2) = 1.70616773217 (the test set's reference value).
        assert!((y[0] - 1.706_167_732_170_483).abs() < 1e-4, "{y:?}");
        assert!(stats.n_steps < 1000, "{stats:?}");
        assert!(!solver.is_non_stiff(), "{stats:?}");
    }
}
