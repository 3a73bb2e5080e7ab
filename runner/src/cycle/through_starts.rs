//! The steady cycle through a Co-Simulation FMU's start values and its own sensitivities
//! to them. The unknowns are the start values q that set the state on the section (the
//! cyclic variable's own start stays the point's) and the period T; the equations are
//! y(T; q) − y(0; q) − s = 0 over the closing variables y, more of them than unknowns
//! where the state is constrained, consistent on the cycle and solved in least squares.
//! One run gives the residual and the whole Jacobian [S(T) − S(0) | ẏ(T)]: the FMU's
//! sensitivities S = ∂y/∂q at both ends and its output derivatives ẏ at the end, so that
//! every iteration is Newton's own.

use nalgebra::{DMatrix, DVector};

use super::floquet::{self, Multiplier};
use super::periodic::{self, check, norm, Budget, Found, NoCycle, Search, Settling, Shooter, Shot};
use crate::cycle_plan::{CyclePlan, StartsPlan};
use crate::fmi::Instance;
use crate::metrics::Sample;

/// The most Gauss-Newton steps that find the start values of the transient's state.
const MOST_INVERSIONS: usize = 12;
/// A singular value of the scaled Jacobian this small against the largest counts as 0.
const RANK_FLOOR: f64 = 1e-10;

/// What puts the FMU back at the point's start: the runner's part.
pub trait Restart {
    /// The instance reset and in initialisation mode, with the point's own values set.
    fn restart(&mut self) -> Result<&mut Instance, NoCycle>;
}

/// The closing variables where the FMU stands, and their sensitivities there (row-major,
/// a row per closing variable, a column per start value).
pub struct Reading {
    pub y: Vec<f64>,
    pub s: Vec<f64>,
}

/// What a run over the cycle read: the closing variables at its start and its end, and
/// their rates at the end.
pub struct Ends {
    pub start: Reading,
    pub end: Reading,
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
    transient: f64,
    /// The periodicity's tolerance, which the inversion of the transient's state aims at.
    tolerance: f64,
    budget: Budget,
    /// Runs over a cycle (the transient counts one per cycle it ran).
    pub runs: usize,
    direction: f64,
}

fn read(fmu: &mut Instance, vrs: &[u32], what: &str) -> Result<Vec<f64>, NoCycle> {
    let mut values = vec![0.0; vrs.len()];
    check(fmu.get_real(vrs, &mut values), what)?;
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(NoCycle::because(format!(
            "{what}: the FMU reported {v} with a successful status"
        ))),
        None => Ok(values),
    }
}

/// The closing variables and their sensitivities where the FMU stands.
fn reading(fmu: &mut Instance, starts: &StartsPlan) -> Result<Reading, NoCycle> {
    Ok(Reading {
        y: read(fmu, &starts.closing.vrs, "reading the closing variables")?,
        s: sensitivities(fmu, starts)?,
    })
}

/// S = ∂closing/∂q where the FMU stands, a row per closing variable.
fn sensitivities(fmu: &mut Instance, starts: &StartsPlan) -> Result<Vec<f64>, NoCycle> {
    let p = starts.columns.len();
    let mut s = vec![0.0; starts.closing.vrs.len() * p];
    for (j, column) in starts.columns.iter().enumerate() {
        let values = read(fmu, column, "reading the sensitivities")?;
        for (i, v) in values.into_iter().enumerate() {
            s[i * p + j] = v;
        }
    }
    Ok(s)
}

/// The first time derivatives of the Real variables `vrs` where the FMU stands.
fn rates(fmu: &mut Instance, vrs: &[u32]) -> Result<Vec<f64>, NoCycle> {
    let mut rates = vec![0.0; vrs.len()];
    for (&vr, rate) in vrs.iter().zip(rates.chunks_mut(1)) {
        check(
            fmu.get_output_derivatives(vr, rate),
            "reading an output's derivative",
        )?;
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
        starts.parameters.names.join(", ")
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

/// The transient's state where it crosses the section within a step of `h` ending at
/// (y1, dy1): the closing variables there, those that advance brought back by `shift`.
fn on_section(
    plan: &CyclePlan,
    (y, dy): (&[f64], &[f64]),
    (y1, dy1): (&[f64], &[f64]),
    (h, w, shift): (f64, f64, f64),
) -> Vec<f64> {
    (0..y.len())
        .map(|i| {
            let at = hermite(y[i], dy[i], y1[i], dy1[i], h, w);
            if periodic::advances(plan, i) {
                at - shift
            } else {
                at
            }
        })
        .collect()
}

impl<'a> ThroughStarts<'a> {
    pub fn new(
        plan: &'a CyclePlan,
        starts: &'a StartsPlan,
        restart: &'a mut dyn Restart,
        (t0, step, transient): (f64, f64, f64),
        (tolerance, budget): (f64, Budget),
    ) -> Self {
        ThroughStarts {
            plan,
            starts,
            restart,
            t0,
            step,
            transient,
            tolerance,
            budget,
            runs: 0,
            direction: 1.0,
        }
    }

    /// The instance initialised from the start values `q` (the point's own where `None`),
    /// its sensitivities computed or not.
    fn started(
        &mut self,
        q: Option<&[f64]>,
        with_sensitivities: bool,
    ) -> Result<&mut Instance, NoCycle> {
        let starts = self.starts;
        let fmu = self.restart.restart()?;
        if let Some(q) = q {
            check(
                fmu.set_real(&starts.parameters.vrs, q),
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

    fn ends(&mut self, q: &[f64], period: f64) -> Result<Ends, NoCycle> {
        let (starts, t0) = (self.starts, self.t0);
        let fmu = self.started(Some(q), true)?;
        let start = reading(fmu, starts)?;
        check(fmu.do_step(t0, period), "the step over the cycle")?;
        Ok(Ends {
            start,
            end: reading(fmu, starts)?,
            dy: rates(fmu, &starts.closing.vrs)?,
        })
    }

    /// The point's own transient, in communication steps, until the period from one
    /// crossing of the section to the next settles: the closing variables at the last
    /// crossing (those that advance brought back by whole advances), the last period, and
    /// the point's own start values.
    fn transient(&mut self) -> Result<(Vec<f64>, f64, Vec<f64>), NoCycle> {
        let (plan, starts) = (self.plan, self.starts);
        let (h, end, budget) = (self.step, self.t0 + self.transient, self.budget);
        let mut t = self.t0;
        let fmu = self.started(None, false)?;
        let own = read(fmu, &starts.parameters.vrs, "reading the start values")?;
        let k = plan.state;
        let mut y = read(fmu, &starts.closing.vrs, "reading the closing variables")?;
        let mut dy = rates(fmu, &starts.closing.vrs)?;
        let theta0 = y[k];
        let (mut direction, mut cycles, mut settling) = (0.0, 0.0, Settling::default());
        let (mut crossings, mut advanced_last) = (0, false);
        while t < end {
            budget.check("the transient before the shooting")?;
            let hh = h.min(end - t);
            check(fmu.do_step(t, hh), "a step of the transient")?;
            t += hh;
            let y1 = read(fmu, &starts.closing.vrs, "reading the closing variables")?;
            let dy1 = rates(fmu, &starts.closing.vrs)?;
            if direction == 0.0 && y1[k] != theta0 {
                direction = (y1[k] - theta0).signum();
            }
            let target = theta0 + direction * (cycles + 1.0) * plan.advance;
            if direction != 0.0 && (y1[k] - target) * direction >= 0.0 {
                if (y1[k] - target - direction * plan.advance) * direction >= 0.0 {
                    return Err(NoCycle::because(format!(
                        "the cyclic variable advanced by more than one cycle's advance in one \
                         communication step ({hh} s): take a shorter scenario step"
                    )));
                }
                let w = crossing(y[k], dy[k], y1[k], dy1[k], hh, target);
                cycles += 1.0;
                crossings += 1;
                if let Some(period) = settling.crossed(t - hh + w * hh) {
                    let shift = direction * cycles * plan.advance;
                    let section = on_section(plan, (&y, &dy), (&y1, &dy1), (hh, w, shift));
                    self.runs += crossings;
                    self.direction = direction;
                    return Ok((section, period, own));
                }
            }
            advanced_last = (y1[k] - y[k]) * direction > 0.0;
            (y, dy) = (y1, dy1);
        }
        self.runs += crossings;
        // Moving on at the end: by its rate, or (where the unit gives no rates) by its
        // last step.
        let moving = direction != 0.0 && (dy[k] * direction > 0.0 || advanced_last);
        Err(settling.unsettled(plan, self.transient, moving))
    }

    /// The start values whose initial state is `target`: Gauss-Newton on y(0; q) − target
    /// from the point's own, with the FMU's sensitivities at the start (no run over the
    /// cycle). The target, read off a transient, is only near the section's states; the
    /// shooting corrects what is left.
    fn invert(&mut self, target: &[f64], mut q: Vec<f64>) -> Result<Vec<f64>, NoCycle> {
        let scales = scales_of(self.plan, target);
        let starts = self.starts;
        let tolerance = self.tolerance;
        for _ in 0..MOST_INVERSIONS {
            let fmu = self.started(Some(&q), true)?;
            let y0 = read(fmu, &starts.closing.vrs, "reading the closing variables")?;
            let s0 = sensitivities(fmu, starts)?;
            let r: Vec<f64> = y0.iter().zip(target).map(|(a, b)| a - b).collect();
            if norm(&r, &scales) <= tolerance {
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
                .all(|(d, q)| d.abs() <= tolerance * q.abs().max(1.0))
            {
                break;
            }
        }
        Ok(q)
    }

    /// The cycle found, as the next point's guess: its start values and period.
    pub fn shot(&self, found: &Found<Ends>) -> Shot {
        Shot {
            t0: self.t0,
            x0: found.z.clone(),
            search: Search {
                period: found.period,
                residual: found.residual,
                iterations: found.iterations,
                runs: self.runs,
            },
            phi: Vec::new(),
            f: Vec::new(),
            direction: self.direction,
        }
    }

    /// A run from the cycle's start values `q` over its period, `vrs` read at `times` into
    /// it (ascending, from 0), with the rates of those `rated` (indices into `vrs`): a row
    /// of samples per time.
    pub fn along(
        &mut self,
        q: &[f64],
        times: &[f64],
        vrs: &[u32],
        rated: &[bool],
    ) -> Result<Vec<Vec<Sample>>, NoCycle> {
        let t0 = self.t0;
        let fmu = self.started(Some(q), false)?;
        let rated_vrs: Vec<u32> = vrs
            .iter()
            .zip(rated)
            .filter(|(_, &r)| r)
            .map(|(&v, _)| v)
            .collect();
        let mut rows = Vec::with_capacity(times.len());
        let mut now = 0.0;
        for &t in times {
            if t > now {
                check(fmu.do_step(t0 + now, t - now), "a step along the cycle")?;
                now = t;
            }
            let values = read(fmu, vrs, "reading along the cycle")?;
            let mut found = rates(fmu, &rated_vrs)?.into_iter();
            let row = values
                .into_iter()
                .zip(rated)
                .map(|(x, &r)| Sample {
                    t,
                    x,
                    rate: if r { found.next() } else { None },
                })
                .collect();
            rows.push(row);
        }
        Ok(rows)
    }
}

impl Shooter for ThroughStarts<'_> {
    type Run = Ends;

    /// A run over `period` from `q`, with the sensitivities (every run is exact).
    fn run(&mut self, q: &[f64], period: f64, _: bool) -> Result<Ends, NoCycle> {
        self.budget.check("a run over the cycle")?;
        self.runs += 1;
        self.ends(q, period)
            .map_err(|e| e.during("a run over the cycle"))
    }

    fn residual(&self, _: &[f64], ends: &Ends) -> Vec<f64> {
        periodic::residual(self.plan, self.direction, &ends.start.y, &ends.end.y)
    }

    fn scales(&self, _: &[f64], ends: &Ends) -> Vec<f64> {
        scales_of(self.plan, &ends.start.y)
    }

    /// [S(T) − S(0) | ẏ(T)], its rows over their scales.
    fn jacobian(&self, ends: &Ends, scales: &[f64]) -> Option<DMatrix<f64>> {
        let (m, p) = (ends.end.y.len(), self.starts.parameters.vrs.len());
        Some(DMatrix::from_fn(m, p + 1, |i, j| {
            let entry = if j < p {
                ends.end.s[i * p + j] - ends.start.s[i * p + j]
            } else {
                ends.dy[i]
            };
            entry / scales[i]
        }))
    }

    fn step(
        &self,
        jacobian: &DMatrix<f64>,
        r: &[f64],
        scales: &[f64],
    ) -> Result<Vec<f64>, NoCycle> {
        let b = DVector::from_iterator(r.len(), r.iter().zip(scales).map(|(r, s)| -r / s));
        least_squares(jacobian.clone(), b).ok_or_else(|| {
            periodic::singular(
                ", or the start values do not move the state on the section independently",
            )
        })
    }

    fn moved(&self, q: &[f64], step: &[f64], lambda: f64) -> Vec<f64> {
        q.iter().zip(step).map(|(q, d)| q + lambda * d).collect()
    }

    fn step_size(&self, q: &[f64], period: f64, step: &[f64], _: &[f64]) -> f64 {
        let p = q.len();
        let values = step[..p]
            .iter()
            .zip(q)
            .fold(0.0, |m: f64, (d, q)| m.max(d.abs() / q.abs().max(1.0)));
        values.max(step[p].abs() / period)
    }

    fn guessed(&mut self, guess: &Shot) -> ((Vec<f64>, f64), Option<DMatrix<f64>>) {
        self.direction = guess.direction;
        ((guess.x0.clone(), guess.search.period), None)
    }

    fn warm_up(&mut self) -> Result<(Vec<f64>, f64), NoCycle> {
        let (target, period, own) = self.transient()?;
        Ok((self.invert(&target, own)?, period))
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
    let (start, end, dy) = (&ends.start, &ends.end, &ends.dy);
    let (k, scales) = (plan.state, scales_of(plan, &start.y));
    let m = start.y.len();
    let p = start.s.len() / m.max(1);
    let s0 = DMatrix::from_fn(m, p, |i, j| start.s[i * p + j] / scales[i]);
    let moved = DMatrix::from_fn(m, p, |i, j| {
        (end.s[i * p + j] - dy[i] * end.s[k * p + j] / dy[k]) / scales[i]
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
        floquet::shares(plan.names().iter().map(String::as_str), &squares)
    }))
}

/// Each closing variable's residual scale: as on Model Exchange, with nominals of 1.
fn scales_of(plan: &CyclePlan, y0: &[f64]) -> Vec<f64> {
    periodic::scales(plan, y0, |_| 1.0)
}
