//! The steady cycle through a Co-Simulation FMU's start values and its own sensitivities
//! to them. The unknowns are the start values q that set the state on the section (the
//! cyclic variable's own start stays the point's) and the period T; the equations are
//! y(T; q) − y(0; q) − s = 0 over the closing variables y, more of them than unknowns
//! where the state is constrained, consistent on the cycle and solved in least squares.
//! One run gives the residual and the whole Jacobian [S(T) − S(0) | ẏ(T)]: the FMU's
//! sensitivities S = ∂y/∂q at both ends and its output derivatives ẏ at the end, so that
//! every iteration is Newton's own.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use super::floquet::{self, Multiplier};
use super::shooting::{
    advances, norm, residual, scales, NoCycle, Shot, GUESS_HALVINGS, GUESS_ITERATIONS,
    LEAST_WARM_UP, MOST_HALVINGS, MOST_ITERATIONS, WARM_UP_SETTLED,
};
use crate::cycle_plan::{CyclePlan, StartsPlan};
use crate::fmi::{Instance, Status};

/// The most Gauss-Newton steps that find the start values of the transient's state.
const MOST_INVERSIONS: usize = 12;
/// A singular value of the scaled Jacobian this small against the largest counts as 0.
const RANK_FLOOR: f64 = 1e-10;

/// What puts the FMU back at the point's start: the runner's part.
pub trait Restart {
    /// The instance reset and in initialisation mode, with the point's own values set.
    fn restart(&mut self) -> Result<&mut Instance, String>;
}

/// What a run over the cycle read: the closing variables at both ends, their
/// sensitivities there (row-major, a row per closing variable, a column per start value)
/// and their rates at the end.
pub struct Ends {
    pub y0: Vec<f64>,
    pub s0: Vec<f64>,
    pub y: Vec<f64>,
    pub s: Vec<f64>,
    pub dy: Vec<f64>,
}

/// The shooting of one point through its start values.
pub struct ThroughStarts<'a> {
    plan: &'a CyclePlan,
    starts: &'a StartsPlan,
    restart: &'a mut dyn Restart,
    /// The point's start time, the transient's communication step and the time it may
    /// take to settle.
    t0: f64,
    step: f64,
    budget: f64,
    tolerance: f64,
    pub deadline: Option<(Instant, f64)>,
    /// Runs over a cycle (the transient counts one per cycle it ran).
    pub runs: usize,
    pub continued: bool,
    direction: f64,
}

fn check(status: Status, what: &str) -> Result<(), String> {
    if status.proceeds() {
        Ok(())
    } else {
        Err(format!("{what} returned {status:?}"))
    }
}

fn read(fmu: &mut Instance, vrs: &[u32], what: &str) -> Result<Vec<f64>, String> {
    let mut values = vec![0.0; vrs.len()];
    check(fmu.get_real(vrs, &mut values), what)?;
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(format!(
            "{what}: the FMU reported {v} with a successful status"
        )),
        None => Ok(values),
    }
}

/// S = ∂closing/∂q where the FMU stands, a row per closing variable.
fn sensitivities(fmu: &mut Instance, starts: &StartsPlan) -> Result<Vec<f64>, String> {
    let p = starts.columns.len();
    let mut s = vec![0.0; starts.closing.len() * p];
    for (j, column) in starts.columns.iter().enumerate() {
        let values = read(fmu, column, "reading the sensitivities")?;
        for (i, v) in values.into_iter().enumerate() {
            s[i * p + j] = v;
        }
    }
    Ok(s)
}

/// The closing variables' first time derivatives where the FMU stands.
fn rates(fmu: &mut Instance, closing: &[u32]) -> Result<Vec<f64>, String> {
    let mut rates = Vec::with_capacity(closing.len());
    for &vr in closing {
        let mut rate = [0.0];
        check(
            fmu.get_output_derivatives(vr, &mut rate),
            "reading an output's derivative",
        )?;
        rates.push(rate[0]);
    }
    Ok(rates)
}

/// A's singular value decomposition where its columns are independent (its smallest
/// singular value above the floor), else `None`.
fn independent(a: DMatrix<f64>) -> Option<nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>> {
    let svd = a.svd(true, true);
    let largest = svd.singular_values.max();
    (largest > 0.0 && svd.singular_values.min() > RANK_FLOOR * largest).then_some(svd)
}

/// Why no cycle: the start values' columns of the sensitivities at the start are not
/// independent (one of them sets no part of the initial state, say).
fn dependent(starts: &StartsPlan) -> NoCycle {
    NoCycle::because(format!(
        "the start values ({}) do not move the state on the section independently: the \
         FMU's sensitivities to them have dependent columns",
        starts.parameter_names.join(", ")
    ))
}

/// The least-squares solution of A x = b; `None` when A's columns are not independent.
fn least_squares(a: DMatrix<f64>, b: DVector<f64>) -> Option<Vec<f64>> {
    let x = independent(a)?.solve(&b, 0.0).ok()?;
    x.iter()
        .all(|v| v.is_finite())
        .then(|| x.iter().copied().collect())
}

/// The value at w ∈ [0, 1] of the cubic Hermite interpolant over a step of
/// length h between (y0, d0) and (y1, d1).
fn hermite(y0: f64, d0: f64, y1: f64, d1: f64, h: f64, w: f64) -> f64 {
    let (w2, w3) = (w * w, w * w * w);
    (2.0 * w3 - 3.0 * w2 + 1.0) * y0
        + (w3 - 2.0 * w2 + w) * h * d0
        + (-2.0 * w3 + 3.0 * w2) * y1
        + (w3 - w2) * h * d1
}

/// Where in a step the interpolant of a variable reaches `target`: w ∈ [0, 1], by
/// Newton's method from the straight line's.
fn crossing(y0: f64, d0: f64, y1: f64, d1: f64, h: f64, target: f64) -> f64 {
    let mut w = ((target - y0) / (y1 - y0)).clamp(0.0, 1.0);
    for _ in 0..20 {
        let value = hermite(y0, d0, y1, d1, h, w) - target;
        let w2 = w * w;
        let slope = (6.0 * w2 - 6.0 * w) * (y0 - y1)
            + (3.0 * w2 - 4.0 * w + 1.0) * h * d0
            + (3.0 * w2 - 2.0 * w) * h * d1;
        if slope == 0.0 || !slope.is_finite() {
            break;
        }
        w = (w - value / slope).clamp(0.0, 1.0);
    }
    w
}

impl<'a> ThroughStarts<'a> {
    pub fn new(
        plan: &'a CyclePlan,
        starts: &'a StartsPlan,
        restart: &'a mut dyn Restart,
        (t0, step, budget): (f64, f64, f64),
        tolerance: f64,
    ) -> Self {
        ThroughStarts {
            plan,
            starts,
            restart,
            t0,
            step,
            budget,
            tolerance,
            deadline: None,
            runs: 0,
            continued: false,
            direction: 1.0,
        }
    }

    fn over_budget(deadline: Option<(Instant, f64)>) -> Result<(), NoCycle> {
        match deadline {
            Some((at, budget)) if Instant::now() > at => Err(NoCycle {
                why: format!("over the budget of {budget} s per point"),
                timeout: true,
            }),
            _ => Ok(()),
        }
    }

    /// The instance initialised from the start values `q` (the point's own where `None`),
    /// its sensitivities computed or not.
    fn started(
        &mut self,
        q: Option<&[f64]>,
        with_sensitivities: bool,
    ) -> Result<&mut Instance, String> {
        let starts = self.starts;
        let fmu = self.restart.restart()?;
        if let Some(q) = q {
            check(
                fmu.set_real(&starts.parameters, q),
                "setting the start values",
            )?;
        }
        if with_sensitivities {
            check(
                fmu.set_integer(&starts.slots, &starts.items),
                "setting the sensitivity slots",
            )?;
        }
        check(fmu.exit_initialization_mode(), "leaving initialisation")?;
        Ok(fmu)
    }

    /// A run over `period` from `q`, with the sensitivities.
    fn run(&mut self, q: &[f64], period: f64) -> Result<Ends, NoCycle> {
        Self::over_budget(self.deadline)?;
        self.runs += 1;
        self.ends(q, period)
            .map_err(|e| NoCycle::because(format!("a run over the cycle: {e}")))
    }

    fn ends(&mut self, q: &[f64], period: f64) -> Result<Ends, String> {
        let (starts, t0) = (self.starts, self.t0);
        let fmu = self.started(Some(q), true)?;
        let y0 = read(fmu, &starts.closing, "reading the closing variables")?;
        let s0 = sensitivities(fmu, starts)?;
        check(fmu.do_step(t0, period), "the step over the cycle")?;
        Ok(Ends {
            y0,
            s0,
            y: read(fmu, &starts.closing, "reading the closing variables")?,
            s: sensitivities(fmu, starts)?,
            dy: rates(fmu, &starts.closing)?,
        })
    }

    /// The cycle, first from `guess` (a neighbour's: its start values and period) where
    /// given, else from the point's own transient; with the last run's ends.
    pub fn solve(&mut self, guess: Option<&Shot>) -> Result<(Shot, Ends), NoCycle> {
        if let Some(guess) = guess {
            self.direction = guess.direction;
            let patience = (GUESS_ITERATIONS, GUESS_HALVINGS);
            if let Ok(found) = self.newton(guess.x0.clone(), guess.period, patience) {
                self.continued = true;
                return Ok(found);
            }
        }
        let (target, period, own) = self.warm_up()?;
        let q = self.invert(&target, own)?;
        self.newton(q, period, (MOST_ITERATIONS, MOST_HALVINGS))
    }

    fn not_cyclic(&self) -> NoCycle {
        NoCycle::because(format!(
            "the transient before the shooting: {} did not advance by its period ({}) in \
             the time allowed: the motion is not cyclic (it stopped or turned back)",
            self.plan.state_names[self.plan.state], self.plan.period
        ))
    }

    /// The point's own transient, in communication steps, until the period from one
    /// crossing of the section to the next settles: the closing variables at the last
    /// crossing (those that advance brought back by whole periods), the last period, and
    /// the point's own start values.
    fn warm_up(&mut self) -> Result<(Vec<f64>, f64, Vec<f64>), NoCycle> {
        let (plan, starts) = (self.plan, self.starts);
        let (h, end, deadline) = (self.step, self.t0 + self.budget, self.deadline);
        let failed =
            |e: String| NoCycle::because(format!("the transient before the shooting: {e}"));
        let mut t = self.t0;
        let fmu = self.started(None, false).map_err(failed)?;
        let own = read(fmu, &starts.parameters, "reading the start values").map_err(failed)?;
        let k = plan.state;
        let mut y = read(fmu, &starts.closing, "reading the closing variables").map_err(failed)?;
        let mut dy = rates(fmu, &starts.closing).map_err(failed)?;
        let theta0 = y[k];
        let (mut direction, mut cycles, mut last, mut previous) = (0.0, 0.0, None, f64::NAN);
        let mut runs = 0;
        while t < end {
            Self::over_budget(deadline)?;
            let hh = h.min(end - t);
            check(fmu.do_step(t, hh), "a step of the transient").map_err(failed)?;
            t += hh;
            let y1 = read(fmu, &starts.closing, "reading the closing variables").map_err(failed)?;
            let dy1 = rates(fmu, &starts.closing).map_err(failed)?;
            if direction == 0.0 && y1[k] != theta0 {
                direction = (y1[k] - theta0).signum();
            }
            let target = theta0 + direction * (cycles + 1.0) * plan.period;
            if direction != 0.0 && (y1[k] - target) * direction >= 0.0 {
                if (y1[k] - target - direction * plan.period) * direction >= 0.0 {
                    return Err(failed(format!(
                        "the cyclic variable advanced by more than its period in one \
                         communication step ({hh} s): take a shorter scenario step"
                    )));
                }
                let w = crossing(y[k], dy[k], y1[k], dy1[k], hh, target);
                let tc = t - hh + w * hh;
                cycles += 1.0;
                runs += 1;
                if let Some(before) = last {
                    let period: f64 = tc - before;
                    if runs > LEAST_WARM_UP && (period - previous).abs() <= WARM_UP_SETTLED * period
                    {
                        let shift = direction * cycles * plan.period;
                        let on_section: Vec<f64> = (0..y.len())
                            .map(|i| {
                                let at = hermite(y[i], dy[i], y1[i], dy1[i], hh, w);
                                if advances(plan, i) {
                                    at - shift
                                } else {
                                    at
                                }
                            })
                            .collect();
                        self.runs += runs;
                        self.direction = direction;
                        return Ok((on_section, period, own));
                    }
                    previous = period;
                }
                last = Some(tc);
            }
            (y, dy) = (y1, dy1);
        }
        self.runs += runs;
        Err(self.not_cyclic())
    }

    /// The start values whose initial state is `target`: Gauss-Newton on y(0; q) − target
    /// from the point's own, with the FMU's sensitivities at the start (no run over the
    /// cycle). The target, read off a transient, is only near the section's states; the
    /// shooting corrects what is left.
    fn invert(&mut self, target: &[f64], mut q: Vec<f64>) -> Result<Vec<f64>, NoCycle> {
        let scales = self.scales(target);
        let starts = self.starts;
        let failed =
            |e: String| NoCycle::because(format!("the start values of the transient's state: {e}"));
        for _ in 0..MOST_INVERSIONS {
            let fmu = self.started(Some(&q), true).map_err(failed)?;
            let y0 = read(fmu, &starts.closing, "reading the closing variables").map_err(failed)?;
            let s0 = sensitivities(fmu, starts).map_err(failed)?;
            let r: Vec<f64> = y0.iter().zip(target).map(|(a, b)| a - b).collect();
            if norm(&r, &scales) <= self.tolerance {
                break;
            }
            let p = q.len();
            let a = DMatrix::from_fn(r.len(), p, |i, j| s0[i * p + j] / scales[i]);
            let b = DVector::from_iterator(r.len(), r.iter().zip(&scales).map(|(r, s)| -r / s));
            let step = least_squares(a, b).ok_or_else(|| dependent(starts))?;
            for (q, d) in q.iter_mut().zip(&step) {
                *q += d;
            }
            if step
                .iter()
                .zip(&q)
                .all(|(d, q)| d.abs() <= self.tolerance * q.abs().max(1.0))
            {
                break;
            }
        }
        Ok(q)
    }

    fn scales(&self, y0: &[f64]) -> Vec<f64> {
        scales_of(self.plan, y0)
    }

    fn residual(&self, ends: &Ends) -> Vec<f64> {
        residual(self.plan, self.direction, &ends.y0, &ends.y)
    }

    /// Newton's step (Δq, ΔT) from one run's ends, in least squares.
    fn newton_step(&self, ends: &Ends, r: &[f64], scales: &[f64]) -> Result<Vec<f64>, NoCycle> {
        let (m, p) = (r.len(), self.starts.parameters.len());
        let a = DMatrix::from_fn(m, p + 1, |i, j| {
            let entry = if j < p {
                ends.s[i * p + j] - ends.s0[i * p + j]
            } else {
                ends.dy[i]
            };
            entry / scales[i]
        });
        let b = DVector::from_iterator(m, r.iter().zip(scales).map(|(r, s)| -r / s));
        least_squares(a, b).ok_or_else(|| {
            NoCycle::because(
                "the shooting's Jacobian is singular: a Floquet multiplier other than the \
                 flow's own is 1 (an undamped mode, or a family of cycles), or the start \
                 values do not move the state on the section independently"
                    .into(),
            )
        })
    }

    /// Newton's method from (q, period) with at most `patience` iterations and halvings.
    fn newton(
        &mut self,
        mut q: Vec<f64>,
        mut period: f64,
        (most_iterations, most_halvings): (usize, usize),
    ) -> Result<(Shot, Ends), NoCycle> {
        let mut ends = self.run(&q, period)?;
        let scales = self.scales(&ends.y0);
        let mut r = self.residual(&ends);
        let mut size = norm(&r, &scales);
        for iteration in 0..=most_iterations {
            if size <= self.tolerance {
                return Ok((self.shot(q, period, size, iteration), ends));
            }
            if iteration == most_iterations {
                break;
            }
            let step = self.newton_step(&ends, &r, &scales)?;
            let p = q.len();
            let small = step[..p]
                .iter()
                .zip(&q)
                .all(|(d, q)| d.abs() <= self.tolerance * q.abs().max(1.0))
                && step[p].abs() <= self.tolerance * period;
            if small {
                // Newton can go no further than the integration's own error.
                return Ok((self.shot(q, period, size, iteration), ends));
            }
            let mut lambda = 1.0;
            let mut taken = None;
            for _ in 0..=most_halvings {
                let trial_period = period + lambda * step[p];
                let trial: Vec<f64> = q.iter().zip(&step).map(|(q, d)| q + lambda * d).collect();
                if trial_period > 0.0 {
                    if let Ok(trial_ends) = self.run(&trial, trial_period) {
                        let trial_r = self.residual(&trial_ends);
                        let trial_size = norm(&trial_r, &scales);
                        if trial_size < size {
                            taken = Some((trial, trial_period, trial_ends, trial_r, trial_size));
                            break;
                        }
                    }
                }
                lambda *= 0.5;
            }
            let Some(next) = taken else { break };
            (q, period, ends, r, size) = next;
        }
        Err(NoCycle::because(format!(
            "the shooting did not converge: after Newton's method the periodicity residual \
             is {size:.3e} (scaled), above the tolerance {:.3e}",
            self.tolerance
        )))
    }

    fn shot(&self, q: Vec<f64>, period: f64, residual: f64, iterations: usize) -> Shot {
        Shot {
            t0: self.t0,
            x0: q,
            period,
            residual,
            phi: Vec::new(),
            f: Vec::new(),
            iterations,
            runs: self.runs,
            direction: self.direction,
        }
    }

    /// A run from the cycle's start values `q` over its period, `vrs` read at `times` into
    /// it (ascending, from 0): a row per time.
    pub fn along(
        &mut self,
        q: &[f64],
        times: &[f64],
        vrs: &[u32],
    ) -> Result<Vec<Vec<f64>>, String> {
        let t0 = self.t0;
        let fmu = self.started(Some(q), false)?;
        let mut rows = Vec::with_capacity(times.len());
        let mut now = 0.0;
        for &t in times {
            if t > now {
                check(fmu.do_step(t0 + now, t - now), "a step along the cycle")?;
                now = t;
            }
            rows.push(read(fmu, vrs, "reading along the cycle")?);
        }
        Ok(rows)
    }
}

/// The Floquet multipliers from a run over the cycle through the start values: the
/// eigenvalues of the section map's derivative in the start values,
/// M = S(0)⁺ (I − ẏ e_kᵀ / ẏ_k) S(T) (k the cyclic variable, whose start is fixed), each
/// with the closing variables its eigenvector moves most (S(0) maps it to them).
pub fn multipliers(
    ends: &Ends,
    plan: &CyclePlan,
    starts: &StartsPlan,
) -> Result<Vec<Multiplier>, NoCycle> {
    let (k, scales) = (plan.state, scales_of(plan, &ends.y0));
    let m = ends.y0.len();
    let p = ends.s0.len() / m.max(1);
    let s0 = DMatrix::from_fn(m, p, |i, j| ends.s0[i * p + j] / scales[i]);
    let moved = DMatrix::from_fn(m, p, |i, j| {
        (ends.s[i * p + j] - ends.dy[i] * ends.s[k * p + j] / ends.dy[k]) / scales[i]
    });
    let map = independent(s0.clone())
        .and_then(|svd| svd.solve(&moved, 0.0).ok())
        .filter(|map| map.iter().all(|v| v.is_finite()))
        .ok_or_else(|| dependent(starts))?;
    Ok(floquet::multipliers_of(&map, |u, v| {
        let (a, b) = (
            &s0 * DVector::from_column_slice(u),
            &s0 * DVector::from_column_slice(v),
        );
        let squares: Vec<f64> = a.iter().zip(b.iter()).map(|(a, b)| a * a + b * b).collect();
        floquet::shares(plan.state_names.iter().map(String::as_str), &squares)
    }))
}

/// Each closing variable's residual scale: as on Model Exchange, with nominals of 1.
fn scales_of(plan: &CyclePlan, y0: &[f64]) -> Vec<f64> {
    scales(plan, y0, |_| 1.0)
}
