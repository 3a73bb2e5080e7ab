//! The periodic steady state by shooting: a state x0 on the section (the cyclic state at
//! a whole number of periods) and a period T such that the flow over T brings x0 back to
//! itself with the cyclic state (and those shifted with it) advanced by one period.
//! Newton's method on the n equations x(T; x0) − x0 − s = 0 in the n unknowns (x0 but its
//! cyclic state, fixed on the section, and T): the Jacobian's columns are the monodromy's
//! columns less the identity, and the state's derivative at the end for T.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use super::flow::{leg, End, Leg, Problem, Stopped};
use crate::cycle_plan::{CyclePlan, Monodromy};

/// The most Newton iterations, and the most halvings of one Newton step; from a
/// neighbour's cycle, fewer of each before the point's own transient is tried instead
/// (the shooting through start values keeps the same counts).
pub(super) const MOST_ITERATIONS: usize = 30;
pub(super) const MOST_HALVINGS: usize = 8;
pub(super) const GUESS_ITERATIONS: usize = 10;
pub(super) const GUESS_HALVINGS: usize = 2;
/// Revolutions of the transient before Newton starts, at least, and until the period
/// changes by less than this fraction from one to the next.
pub(super) const LEAST_WARM_UP: usize = 2;
pub(super) const WARM_UP_SETTLED: f64 = 1e-2;
/// A cyclic state at rest at the start: its way is read this fraction of the transient's
/// time budget later.
const START_PROBE: f64 = 1e-3;
/// A central difference's step, as a fraction of a state's scale.
const DIFFERENCE_STEP: f64 = 1e-5;

/// A steady cycle found.
#[derive(Clone, Debug)]
pub struct Shot {
    /// Its time at the section (where every run starts), its state there and its period.
    pub t0: f64,
    pub x0: Vec<f64>,
    pub period: f64,
    /// The largest scaled component of x(T) − x0 − s at the solution.
    pub residual: f64,
    /// ∂x(T)/∂x0 and f(x(T)) at the solution: the monodromy.
    pub phi: Vec<f64>,
    pub f: Vec<f64>,
    pub iterations: usize,
    /// Legs integrated (a leg is one run over a cycle or part of one), warm-up included.
    pub runs: usize,
    /// The way the cyclic state turns: +1 or −1.
    pub direction: f64,
}

/// Why no cycle was found; `timeout` when the point's wall-time budget ran out first.
pub struct NoCycle {
    pub why: String,
    pub timeout: bool,
}

impl NoCycle {
    pub fn because(why: String) -> NoCycle {
        NoCycle {
            why,
            timeout: false,
        }
    }
}

/// The shooting of one point: its plan, the FMU, and the work spent.
pub struct Shooting<'a, 'b> {
    pub plan: &'a CyclePlan,
    pub problem: &'a mut Problem<'b>,
    /// The direction in which the cyclic state advances: +1 or −1.
    direction: f64,
    /// The largest time the transient may take to complete a cycle.
    budget: f64,
    /// Convergence: the scaled residual the integration can reach.
    tolerance: f64,
    pub runs: usize,
    /// Whether the cycle was found from the guess.
    pub continued: bool,
    /// When the point's wall-time budget (in seconds) runs out.
    pub deadline: Option<(Instant, f64)>,
}

fn stopped(what: &str, e: Stopped, plan: &CyclePlan) -> NoCycle {
    let why = match e {
        Stopped::OverBudget(budget) => {
            return NoCycle {
                why: format!("over the budget of {budget} s per point ({what})"),
                timeout: true,
            }
        }
        Stopped::Event(k, t) => format!(
            "{what}: event indicator {k} changed sign {t:.6} s into the cycle (an event on the \
             way, such as a change point: the cycle is not smooth, and the shooting does not \
             cross events)"
        ),
        Stopped::NotReached => format!(
            "{what}: {} did not advance by its period ({}) in the time allowed: the motion is \
             not cyclic (it stopped or turned back)",
            plan.state_names[plan.state], plan.period
        ),
        Stopped::Failed(why) => format!("{what}: {why}"),
    };
    NoCycle::because(why)
}

impl<'a, 'b> Shooting<'a, 'b> {
    pub fn new(
        plan: &'a CyclePlan,
        problem: &'a mut Problem<'b>,
        budget: f64,
        tolerance: f64,
    ) -> Self {
        Shooting {
            plan,
            problem,
            direction: 1.0,
            budget,
            tolerance,
            runs: 0,
            continued: false,
            deadline: None,
        }
    }

    fn leg(&mut self, t0: f64, x0: &[f64], end: End, variational: bool) -> Result<Leg, Stopped> {
        if let Some((deadline, budget)) = self.deadline {
            if Instant::now() > deadline {
                return Err(Stopped::OverBudget(budget));
            }
        }
        self.runs += 1;
        leg(self.problem, t0, x0, end, variational, &[])
    }

    /// The cycle, from the point's initial state `(t, x)`, or first from `guess` (a
    /// neighbouring point's cycle: its state on the section and period) where given.
    pub fn solve(&mut self, t: f64, x: &[f64], guess: Option<&Shot>) -> Result<Shot, NoCycle> {
        if let Some(guess) = guess {
            self.direction = guess.direction;
            let patience = (GUESS_ITERATIONS, GUESS_HALVINGS);
            let start = (guess.t0, guess.x0.clone(), guess.period);
            if let Ok(shot) = self.newton(start.0, start.1, start.2, patience, Some(guess)) {
                self.continued = true;
                return Ok(shot);
            }
        }
        let (t, x) = self.set_direction(t, x)?;
        let (t0, x0, period) = self.warm_up(t, &x)?;
        self.newton(t0, x0, period, (MOST_ITERATIONS, MOST_HALVINGS), None)
    }

    /// The way the cyclic state turns, from its derivative at the start, or, starting at
    /// rest, a moment later (a mechanism may start backwards): where the transient goes on.
    fn set_direction(&mut self, t: f64, x: &[f64]) -> Result<(f64, Vec<f64>), NoCycle> {
        let k = self.plan.state;
        let (mut t, mut x) = (t, x.to_vec());
        let mut f = self.derivative(t, &x)?;
        if f[k] == 0.0 {
            let moment = START_PROBE * self.budget;
            let moved = self
                .leg(t, &x, End::After(moment), false)
                .map_err(|e| stopped("the start of the transient", e, self.plan))?;
            (t, x, f) = (t + moved.time, moved.x, moved.f);
        }
        self.direction = if f[k] < 0.0 { -1.0 } else { 1.0 };
        Ok((t, x))
    }

    fn derivative(&mut self, t: f64, x: &[f64]) -> Result<Vec<f64>, NoCycle> {
        let mut f = vec![0.0; x.len()];
        let fmu = &mut self.problem.fmu;
        let s = fmu
            .set_time(t)
            .max(fmu.set_continuous_states(x))
            .max(fmu.get_derivatives(&mut f));
        if !s.proceeds() {
            return Err(NoCycle::because(format!(
                "the state's derivative at the start: the FMU returned {s:?}"
            )));
        }
        Ok(f)
    }

    /// The transient, a cycle at a time, until its period settles: the state on the
    /// section, its time, and the last cycle's period.
    fn warm_up(&mut self, t: f64, x: &[f64]) -> Result<(f64, Vec<f64>, f64), NoCycle> {
        let (k, p) = (self.plan.state, self.plan.period);
        let next = |value: f64, direction: f64| {
            let cycles = value / p;
            p * if direction > 0.0 {
                cycles.floor() + 1.0
            } else {
                cycles.ceil() - 1.0
            }
        };
        let (mut t, mut x) = (t, x.to_vec());
        let (mut previous, mut cycles, mut started) = (f64::NAN, 0, None);
        let end_of_budget = t + self.budget;
        loop {
            let target = next(x[k], self.direction);
            let within = end_of_budget - t;
            let reached = self
                .leg(
                    t,
                    &x,
                    End::Reaching {
                        index: k,
                        value: target,
                        within,
                    },
                    false,
                )
                .map_err(|e| stopped("the transient before the shooting", e, self.plan))?;
            let mut x_next = reached.x;
            x_next[k] = target;
            t += reached.time;
            x = x_next;
            let Some(t_section) = started else {
                started = Some(t);
                continue;
            };
            let period = t - t_section;
            started = Some(t);
            cycles += 1;
            if cycles >= LEAST_WARM_UP && (period - previous).abs() <= WARM_UP_SETTLED * period {
                return Ok((t, x, period));
            }
            previous = period;
        }
    }

    fn scales(&self, x0: &[f64]) -> Vec<f64> {
        scales(self.plan, x0, |i| self.problem.nominals[i])
    }

    fn residual(&self, x0: &[f64], leg: &Leg) -> Vec<f64> {
        residual(self.plan, self.direction, x0, &leg.x)
    }

    /// One cycle's leg from (t0, x0) over `period`, with its monodromy.
    fn shoot(&mut self, t0: f64, x0: &[f64], period: f64) -> Result<Leg, NoCycle> {
        let what = "a run over the cycle";
        match self.plan.monodromy {
            Monodromy::Variational => self
                .leg(t0, x0, End::After(period), true)
                .map_err(|e| stopped(what, e, self.plan)),
            Monodromy::Differences => {
                let mut leg = self
                    .leg(t0, x0, End::After(period), false)
                    .map_err(|e| stopped(what, e, self.plan))?;
                leg.phi = Some(self.differences(t0, x0, period)?);
                Ok(leg)
            }
        }
    }

    /// ∂x(T)/∂x0 by central differences, a pair of runs per state but the cyclic one,
    /// whose column nothing reads (left 0).
    fn differences(&mut self, t0: f64, x0: &[f64], period: f64) -> Result<Vec<f64>, NoCycle> {
        let n = x0.len();
        let scales = self.scales(x0);
        let mut phi = vec![0.0; n * n];
        for j in (0..n).filter(|&j| j != self.plan.state) {
            let h = DIFFERENCE_STEP * scales[j];
            let mut ends = [Vec::new(), Vec::new()];
            for (side, sign) in [1.0, -1.0].into_iter().enumerate() {
                let mut x = x0.to_vec();
                x[j] += sign * h;
                ends[side] = self
                    .leg(t0, &x, End::After(period), false)
                    .map_err(|e| stopped("a run of the monodromy's differences", e, self.plan))?
                    .x;
            }
            for i in 0..n {
                phi[i * n + j] = (ends[0][i] - ends[1][i]) / (2.0 * h);
            }
        }
        Ok(phi)
    }

    /// Newton's method from (x0, period), x0 on the section, with at most `patience`
    /// iterations and halvings of a step. Its Jacobian comes from a monodromy (the
    /// neighbour's, `hint`, or the first run's) and is kept up to date by Broyden's
    /// rank-one rule from the plain runs that follow, each a fraction of the cost of a run
    /// with the monodromy; where the residual is small enough, a run with the monodromy is
    /// made again, so that the multipliers are the solution's own.
    fn newton(
        &mut self,
        t0: f64,
        mut x0: Vec<f64>,
        mut period: f64,
        (most_iterations, most_halvings): (usize, usize),
        hint: Option<&Shot>,
    ) -> Result<Shot, NoCycle> {
        let k = self.plan.state;
        let scales = self.scales(&x0);
        let mut jacobian = hint.map(|h| jacobian_of(&h.phi, &h.f, k));
        let mut leg = self.run(t0, &x0, period, jacobian.is_none())?;
        let mut r = self.residual(&x0, &leg);
        let mut size = norm(&r, &scales);
        for iteration in 0..=most_iterations {
            if let Some(phi) = &leg.phi {
                jacobian = Some(jacobian_of(phi, &leg.f, k));
            }
            if size <= self.tolerance {
                if leg.phi.is_none() {
                    leg = self.run(t0, &x0, period, true)?;
                    r = self.residual(&x0, &leg);
                    size = norm(&r, &scales);
                }
                if size <= self.tolerance {
                    return Ok(self.shot(t0, x0, period, size, leg, iteration));
                }
                continue;
            }
            if iteration == most_iterations {
                break;
            }
            let matrix = jacobian.as_ref().expect("a Jacobian from a monodromy");
            let step = solve(matrix, &r).ok_or_else(|| {
                NoCycle::because(
                    "the shooting's Jacobian is singular: a Floquet multiplier other than the \
                     flow's own is 1 (an undamped mode, or a family of cycles), so the steady \
                     cycle is not isolated"
                        .into(),
                )
            })?;
            if Self::step_norm(&step, &scales, k, period) <= self.tolerance {
                // Newton can go no further than the integration's own error.
                if leg.phi.is_none() {
                    leg = self.run(t0, &x0, period, true)?;
                    size = norm(&self.residual(&x0, &leg), &scales);
                }
                return Ok(self.shot(t0, x0, period, size, leg, iteration));
            }
            match self.line_search(t0, (&x0, period, size), &step, &scales, most_halvings) {
                Some((x, p, trial, lambda)) => {
                    let r_trial = self.residual(&x, &trial);
                    let taken: Vec<f64> = step.iter().map(|s| lambda * s).collect();
                    let matrix = jacobian.as_mut().expect("a Jacobian");
                    broyden(matrix, &taken, &r, &r_trial);
                    size = norm(&r_trial, &scales);
                    (x0, period, leg, r) = (x, p, trial, r_trial);
                }
                // The Jacobian was the monodromy's own here: Newton is stuck.
                None if leg.phi.is_some() => break,
                // An approximate Jacobian led nowhere: the monodromy where Newton stands.
                None => {
                    leg = self.run(t0, &x0, period, true)?;
                    r = self.residual(&x0, &leg);
                    size = norm(&r, &scales);
                }
            }
        }
        Err(NoCycle::because(format!(
            "the shooting did not converge: after Newton's method the periodicity residual \
             is {size:.3e} (scaled), above the tolerance {:.3e}",
            self.tolerance
        )))
    }

    /// A run over the cycle, with its monodromy or without.
    fn run(&mut self, t0: f64, x0: &[f64], period: f64, monodromy: bool) -> Result<Leg, NoCycle> {
        if monodromy {
            return self.shoot(t0, x0, period);
        }
        self.leg(t0, x0, End::After(period), false)
            .map_err(|e| stopped("a run over the cycle", e, self.plan))
    }

    /// The first of the steps λ = 1, ½, ¼, … along `step` whose plain run lowers the
    /// residual's norm: its state, period, run and λ.
    fn line_search(
        &mut self,
        t0: f64,
        (x0, period, size): (&[f64], f64, f64),
        step: &[f64],
        scales: &[f64],
        most_halvings: usize,
    ) -> Option<(Vec<f64>, f64, Leg, f64)> {
        let (n, k) = (x0.len(), self.plan.state);
        let mut lambda = 1.0;
        for _ in 0..=most_halvings {
            let (mut x, p) = (x0.to_vec(), period + lambda * step[n - 1]);
            for (i, j) in (0..n).filter(|&i| i != k).enumerate() {
                x[j] += lambda * step[i];
            }
            if p > 0.0 {
                if let Ok(trial) = self.run(t0, &x, p, false) {
                    let trial_norm = norm(&self.residual(&x, &trial), scales);
                    if trial_norm < size {
                        return Some((x, p, trial, lambda));
                    }
                }
            }
            lambda *= 0.5;
        }
        None
    }

    fn step_norm(step: &[f64], scales: &[f64], k: usize, period: f64) -> f64 {
        let n = scales.len();
        let states = (0..n)
            .filter(|&i| i != k)
            .zip(step)
            .fold(0.0, |m: f64, (j, d)| m.max(d.abs() / scales[j]));
        states.max(step[n - 1].abs() / period)
    }

    fn shot(
        &self,
        t0: f64,
        x0: Vec<f64>,
        period: f64,
        residual: f64,
        leg: Leg,
        iterations: usize,
    ) -> Shot {
        Shot {
            t0,
            x0,
            period,
            residual,
            phi: leg.phi.unwrap_or_default(),
            f: leg.f,
            iterations,
            runs: self.runs,
            direction: self.direction,
        }
    }
}

/// Whether state `i` advances by a period over the cycle: the cyclic state and those
/// shifted with it.
pub(super) fn advances(plan: &CyclePlan, i: usize) -> bool {
    i == plan.state || plan.shifted.contains(&i)
}

/// The scale of each state's residual: its nominal, or its size on the cycle (a period
/// for the states that advance), whichever is larger.
pub(super) fn scales(plan: &CyclePlan, x0: &[f64], nominal: impl Fn(usize) -> f64) -> Vec<f64> {
    (0..x0.len())
        .map(|i| {
            let size = if advances(plan, i) {
                plan.period
            } else {
                x0[i].abs()
            };
            nominal(i).max(size)
        })
        .collect()
}

/// x(T) − x0 − s: the states that advance brought back by a period the way the cyclic
/// state turns (`direction`).
pub(super) fn residual(plan: &CyclePlan, direction: f64, x0: &[f64], end: &[f64]) -> Vec<f64> {
    let shift = direction * plan.period;
    (0..x0.len())
        .map(|i| end[i] - x0[i] - if advances(plan, i) { shift } else { 0.0 })
        .collect()
}

/// The largest component of `r` over its scale.
pub(super) fn norm(r: &[f64], scales: &[f64]) -> f64 {
    r.iter()
        .zip(scales)
        .fold(0.0, |m, (r, s)| m.max(r.abs() / s))
}

/// The shooting's Jacobian [Φ − I without column k | f(x(T))], from a monodromy.
fn jacobian_of(phi: &[f64], f: &[f64], k: usize) -> DMatrix<f64> {
    let n = f.len();
    let mut jacobian = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for (c, j) in (0..n).filter(|&j| j != k).enumerate() {
            jacobian[(i, c)] = phi[i * n + j] - if i == j { 1.0 } else { 0.0 };
        }
        jacobian[(i, n - 1)] = f[i];
    }
    jacobian
}

/// The Newton step (Δx0 without the cyclic state, ΔT) solving J Δ = −r; `None` when J is
/// singular.
fn solve(jacobian: &DMatrix<f64>, r: &[f64]) -> Option<Vec<f64>> {
    let rhs = DVector::from_iterator(r.len(), r.iter().map(|r| -r));
    let step = jacobian.clone().lu().solve(&rhs)?;
    step.iter()
        .all(|s| s.is_finite())
        .then(|| step.iter().copied().collect())
}

/// Broyden's update of J after the step `taken` changed the residual from `before` to
/// `after`: J + (Δr − J Δz) Δzᵀ / Δzᵀ Δz, the least change that makes J Δz = Δr.
fn broyden(jacobian: &mut DMatrix<f64>, taken: &[f64], before: &[f64], after: &[f64]) {
    let dz = DVector::from_column_slice(taken);
    let dr = DVector::from_iterator(after.len(), after.iter().zip(before).map(|(a, b)| a - b));
    let size = dz.norm_squared();
    if size > 0.0 {
        let miss = dr - &*jacobian * &dz;
        *jacobian += miss * dz.transpose() / size;
    }
}
