//! What both shootings share: the periodicity condition and its scales, Newton's method
//! on it with its line search, the point's time budget, the transient's settling, and why
//! no cycle was found. A shooting ([`Shooter`]) says what its unknowns are (the state on
//! the section, or the start values that set it), how a run over a cycle from them is
//! made and what Jacobian it gives; the search here is the same for both.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::cycle_plan::CyclePlan;
use crate::fmi::Status;

/// The most Newton iterations, and the most halvings of one Newton step; from a
/// neighbour's cycle, fewer of each before the point's own transient is tried instead.
const MOST: Patience = Patience {
    iterations: 30,
    halvings: 8,
};
const FROM_GUESS: Patience = Patience {
    iterations: 10,
    halvings: 2,
};
/// Revolutions of the transient before Newton starts, at least, and until the period
/// changes by less than this fraction from one to the next.
const LEAST_WARM_UP: usize = 2;
const WARM_UP_SETTLED: f64 = 1e-2;

/// How long Newton's method may try: iterations, and halvings of one step.
#[derive(Clone, Copy)]
pub(super) struct Patience {
    iterations: usize,
    halvings: usize,
}

/// What a search for a cycle found and spent: the cycle's period, the largest scaled
/// component of the periodicity residual there, the Newton iterations, and the runs over
/// a cycle or part of one (the transient's included).
#[derive(Clone, Debug, Serialize)]
pub struct Search {
    pub period: f64,
    pub residual: f64,
    pub iterations: usize,
    pub runs: usize,
}

/// A steady cycle found, as the next point's search may start from it: its time at the
/// section (where every run starts), its unknowns there (the state on the section, or the
/// start values that set it), on Model Exchange the monodromy at the solution (∂x(T)/∂x0
/// and f(x(T))), and the way the cyclic variable turns (+1 or −1).
#[derive(Clone, Debug)]
pub struct Shot {
    pub t0: f64,
    pub x0: Vec<f64>,
    pub search: Search,
    pub phi: Vec<f64>,
    pub f: Vec<f64>,
    pub direction: f64,
}

/// How a search without a cycle ends the point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Miss {
    /// No steady cycle: none exists, or the shooting did not find it.
    NoCycle,
    /// The point's wall-time budget ran out first.
    Timeout,
    /// A call of the FMU returned Error or Fatal: nothing more is asked of it.
    FmuError,
}

/// Why no cycle was found, and how that ends the point.
#[derive(Debug)]
pub struct NoCycle {
    pub why: String,
    pub miss: Miss,
}

impl NoCycle {
    pub fn because(why: String) -> NoCycle {
        NoCycle {
            why,
            miss: Miss::NoCycle,
        }
    }

    /// `what` returned `status`, which stops the search: an Error or Fatal ends the
    /// point as the FMU's error, a Discard as a search without a cycle.
    pub fn returned(what: &str, status: Status) -> NoCycle {
        NoCycle {
            why: format!("{what} returned {status:?}"),
            miss: if status > Status::Discard {
                Miss::FmuError
            } else {
                Miss::NoCycle
            },
        }
    }

    /// The same, said of `what` the search was doing (a timeout says it already).
    pub fn during(self, what: &str) -> NoCycle {
        if self.miss == Miss::Timeout {
            return self;
        }
        NoCycle {
            why: format!("{what}: {}", self.why),
            miss: self.miss,
        }
    }

    /// Whether the point ends here, without another way to its cycle being tried.
    fn ends_the_point(&self) -> bool {
        self.miss != Miss::NoCycle
    }
}

/// Go on where `status` lets the run go on, else stop with what returned it.
pub(super) fn check(status: Status, what: &str) -> Result<(), NoCycle> {
    if status.proceeds() {
        Ok(())
    } else {
        Err(NoCycle::returned(what, status))
    }
}

/// When the point's wall-time budget (in seconds) runs out, where it has one.
#[derive(Clone, Copy)]
pub struct Budget(pub Option<(Instant, f64)>);

impl Budget {
    /// Err where the budget is spent; `what` says what the search was about to do.
    pub(super) fn check(&self, what: &str) -> Result<(), NoCycle> {
        match self.0 {
            Some((at, seconds)) if Instant::now() > at => Err(NoCycle {
                why: format!("over the budget of {seconds} s per point ({what})"),
                miss: Miss::Timeout,
            }),
            _ => Ok(()),
        }
    }
}

/// The transient's period from one crossing of the section to the next, until it settles.
#[derive(Default)]
pub(super) struct Settling {
    crossings: usize,
    last: Option<f64>,
    previous: f64,
}

impl Settling {
    /// A crossing of the section at time `t`: the period since the last one, where it has
    /// settled.
    pub(super) fn crossed(&mut self, t: f64) -> Option<f64> {
        self.crossings += 1;
        let last = self.last.replace(t)?;
        let period = t - last;
        let settled = self.crossings > LEAST_WARM_UP
            && (period - self.previous).abs() <= WARM_UP_SETTLED * period;
        self.previous = period;
        settled.then_some(period)
    }

    /// Why the transient did not give a start: it ran out of the scenario's time while
    /// the cyclic variable still turned (`moving`), or the motion stopped or turned back.
    pub(super) fn unsettled(&self, plan: &CyclePlan, time: f64, moving: bool) -> NoCycle {
        let name = &plan.names()[plan.state];
        NoCycle::because(if moving && self.crossings > 0 {
            format!(
                "the transient before the shooting: its period did not settle (to 1 % from \
                 one cycle to the next) within the scenario's time, stop − start = {time} s: \
                 give scenario.stop more time"
            )
        } else if moving {
            format!(
                "the transient before the shooting: {name} did not advance by one cycle's \
                 advance ({}) within the scenario's time, stop − start = {time} s, though it \
                 still turns: give scenario.stop more time",
                plan.advance
            )
        } else {
            format!(
                "the transient before the shooting: {name} did not advance by one cycle's \
                 advance ({}) within the scenario's time, stop − start = {time} s, and at \
                 its end it was not moving on (it stopped or turned back): if the motion \
                 is cyclic once started, give scenario.stop more time",
                plan.advance
            )
        })
    }
}

/// One way of shooting: its unknowns z (the state on the section, or the start values
/// that set it), its runs over a cycle from them, and the Jacobian a run gives.
pub(super) trait Shooter {
    /// What a run over the cycle read.
    type Run;

    /// A run over `period` from `z`; with `exact`, one that gives Newton's Jacobian too.
    fn run(&mut self, z: &[f64], period: f64, exact: bool) -> Result<Self::Run, NoCycle>;
    /// The periodicity residual of a run from `z`.
    fn residual(&self, z: &[f64], run: &Self::Run) -> Vec<f64>;
    /// Each residual's scale, from where the search starts.
    fn scales(&self, z: &[f64], run: &Self::Run) -> Vec<f64>;
    /// Newton's Jacobian (a column per unknown, then the period's), where the run gives it.
    fn jacobian(&self, run: &Self::Run, scales: &[f64]) -> Option<DMatrix<f64>>;
    /// Newton's step (Δz, ΔT) from the Jacobian and the residual.
    fn step(&self, jacobian: &DMatrix<f64>, r: &[f64], scales: &[f64])
        -> Result<Vec<f64>, NoCycle>;
    /// `z` moved by λ·Δz.
    fn moved(&self, z: &[f64], step: &[f64], lambda: f64) -> Vec<f64>;
    /// The step's size against the unknowns', comparable with the tolerance.
    fn step_size(&self, z: &[f64], period: f64, step: &[f64], scales: &[f64]) -> f64;
    /// Where the search starts from a neighbour's cycle, and the Jacobian it brings.
    fn guessed(&mut self, guess: &Shot) -> ((Vec<f64>, f64), Option<DMatrix<f64>>);
    /// Where the search starts from the point's own transient.
    fn warm_up(&mut self) -> Result<(Vec<f64>, f64), NoCycle>;
}

/// What Newton's method found: the unknowns, the period, the residual's scaled size, the
/// last run (an exact one), the iterations spent, and whether it started from a guess.
pub(super) struct Found<R> {
    pub z: Vec<f64>,
    pub period: f64,
    pub residual: f64,
    pub run: R,
    pub iterations: usize,
    pub continued: bool,
}

/// The cycle, first from `guess` (a neighbour's) where given, else from the point's own
/// transient.
pub(super) fn find<S: Shooter>(
    shooter: &mut S,
    guess: Option<&Shot>,
    tolerance: f64,
) -> Result<Found<S::Run>, NoCycle> {
    if let Some(guess) = guess {
        let (start, hint) = shooter.guessed(guess);
        match newton(shooter, start, FROM_GUESS, hint, tolerance) {
            Ok(found) => {
                return Ok(Found {
                    continued: true,
                    ..found
                })
            }
            Err(e) if e.ends_the_point() => return Err(e),
            Err(_) => {}
        }
    }
    let start = shooter.warm_up()?;
    newton(shooter, start, MOST, None, tolerance)
}

/// Newton's method from (z, period) on the periodicity condition. Its Jacobian comes from
/// an exact run (or `hint`, a neighbour's) and, after a plain run, from Broyden's rank-one
/// update; where the residual is small enough, a run is made exact again, so that the
/// multipliers are the solution's own.
fn newton<S: Shooter>(
    shooter: &mut S,
    (mut z, mut period): (Vec<f64>, f64),
    patience: Patience,
    hint: Option<DMatrix<f64>>,
    tolerance: f64,
) -> Result<Found<S::Run>, NoCycle> {
    let mut jacobian = hint;
    let mut run = shooter.run(&z, period, jacobian.is_none())?;
    let scales = shooter.scales(&z, &run);
    let mut r = shooter.residual(&z, &run);
    let mut size = norm(&r, &scales);
    for iteration in 0..=patience.iterations {
        let exact = shooter.jacobian(&run, &scales);
        let was_exact = exact.is_some();
        if exact.is_some() {
            jacobian = exact;
        }
        let small = size <= tolerance;
        let step = if small || iteration == patience.iterations {
            None
        } else {
            let matrix = jacobian.as_ref().expect("a Jacobian from an exact run");
            Some(shooter.step(matrix, &r, &scales)?)
        };
        // Newton can go no further than the integration's own error.
        let stalled = step
            .as_ref()
            .is_some_and(|s| shooter.step_size(&z, period, s, &scales) <= tolerance);
        if small || stalled {
            if !was_exact {
                run = shooter.run(&z, period, true)?;
                r = shooter.residual(&z, &run);
                size = norm(&r, &scales);
            }
            if size <= tolerance || stalled {
                return Ok(Found {
                    z,
                    period,
                    residual: size,
                    run,
                    iterations: iteration,
                    continued: false,
                });
            }
            continue;
        }
        let Some(step) = step else { break };
        match line_search(shooter, (&z, period, size), &step, &scales, patience)? {
            Some((moved, trial, lambda)) => {
                let r_trial = shooter.residual(&moved.0, &trial);
                if shooter.jacobian(&trial, &scales).is_none() {
                    let taken: Vec<f64> = step.iter().map(|s| lambda * s).collect();
                    let matrix = jacobian.as_mut().expect("a Jacobian");
                    broyden(matrix, &taken, &r, &r_trial);
                }
                size = norm(&r_trial, &scales);
                ((z, period), run, r) = (moved, trial, r_trial);
            }
            // The Jacobian was an exact run's: Newton is stuck.
            None if was_exact => break,
            // An updated Jacobian led nowhere: an exact run where Newton stands.
            None => {
                run = shooter.run(&z, period, true)?;
                r = shooter.residual(&z, &run);
                size = norm(&r, &scales);
            }
        }
    }
    Err(NoCycle::because(format!(
        "the shooting did not converge: after Newton's method the periodicity residual is \
         {size:.3e} (scaled), above the tolerance {tolerance:.3e}"
    )))
}

/// A step taken by the line search: the unknowns and period it reached, its run, and λ.
type Taken<R> = ((Vec<f64>, f64), R, f64);

/// The first of the steps λ = 1, ½, ¼, … along `step` whose plain run lowers the
/// residual's norm. A run that fails tries the next λ, unless it ends the point.
fn line_search<S: Shooter>(
    shooter: &mut S,
    (z, period, size): (&[f64], f64, f64),
    step: &[f64],
    scales: &[f64],
    patience: Patience,
) -> Result<Option<Taken<S::Run>>, NoCycle> {
    let last = step.len() - 1;
    let mut lambda = 1.0;
    for _ in 0..=patience.halvings {
        let p = period + lambda * step[last];
        if p > 0.0 {
            let moved = shooter.moved(z, &step[..last], lambda);
            match shooter.run(&moved, p, false) {
                Ok(trial) => {
                    if norm(&shooter.residual(&moved, &trial), scales) < size {
                        return Ok(Some(((moved, p), trial, lambda)));
                    }
                }
                Err(e) if e.ends_the_point() => return Err(e),
                Err(_) => {}
            }
        }
        lambda *= 0.5;
    }
    Ok(None)
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

/// Why Newton cannot step: its Jacobian is singular.
pub(super) fn singular(also: &str) -> NoCycle {
    NoCycle::because(format!(
        "the shooting's Jacobian is singular: a Floquet multiplier other than the flow's own \
         is 1 (an undamped mode, or a family of cycles){also}"
    ))
}

/// Whether variable `i` of those the cycle closes on advances by the plan's advance over
/// a cycle: the cyclic one and those shifted with it.
pub(super) fn advances(plan: &CyclePlan, i: usize) -> bool {
    i == plan.state || plan.shifted.contains(&i)
}

/// The scale of each variable's residual: its nominal, or its size on the cycle (the
/// advance for those that advance), whichever is larger.
pub(super) fn scales(plan: &CyclePlan, x0: &[f64], nominal: impl Fn(usize) -> f64) -> Vec<f64> {
    (0..x0.len())
        .map(|i| {
            let size = if advances(plan, i) {
                plan.advance
            } else {
                x0[i].abs()
            };
            nominal(i).max(size)
        })
        .collect()
}

/// x(T) − x0 − s: the variables that advance brought back by the advance the way the
/// cyclic variable turns (`direction`).
pub(super) fn residual(plan: &CyclePlan, direction: f64, x0: &[f64], end: &[f64]) -> Vec<f64> {
    let shift = direction * plan.advance;
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
