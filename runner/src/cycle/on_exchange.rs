//! The steady cycle by shooting on the Model Exchange interface: the unknowns are the
//! state x0 on the section (the cyclic state at a whole number of advances, fixed) and the
//! period T; the equations x(T; x0) − x0 − s = 0. Newton's Jacobian is [Φ − I without the
//! cyclic state's column | f(x(T))], Φ the monodromy, from the variational equations or
//! from central differences of runs.

use nalgebra::{DMatrix, DVector};

use super::flow::{derivative, leg, End, Leg, Problem, Stopped};
use super::periodic::{self, Budget, NoCycle, Search, Settling, Shooter, Shot};
use crate::cycle_plan::{CyclePlan, Monodromy};

/// A cyclic state at rest at the start: its way is read this fraction of the transient's
/// time budget later.
const START_PROBE: f64 = 1e-3;
/// A central difference's step, as a fraction of a state's scale.
const DIFFERENCE_STEP: f64 = 1e-5;

/// The shooting of one point on Model Exchange: its plan, the FMU, and the work spent.
pub(super) struct OnExchange<'p, 'a> {
    plan: &'p CyclePlan,
    monodromy: Monodromy,
    pub problem: &'p mut Problem<'a>,
    /// The section's time, where every run starts; and the point's initial time and state.
    t0: f64,
    start: (f64, Vec<f64>),
    /// The direction in which the cyclic state advances: +1 or −1.
    direction: f64,
    /// The longest the transient may take to settle.
    transient: f64,
    budget: Budget,
    pub runs: usize,
}

/// What a stopped leg says, as a reason for no cycle.
pub(super) fn stopped(what: &str, e: Stopped, plan: &CyclePlan) -> NoCycle {
    match e {
        Stopped::Event(k, t) => NoCycle::because(format!(
            "{what}: event indicator {k} changed sign {t:.6} s into the cycle (an event on the \
             way, such as a change point: the cycle is not smooth, and the shooting does not \
             cross events)"
        )),
        Stopped::NotReached { moving } => NoCycle::because(format!(
            "{what}: {} did not advance by one cycle's advance ({}) in the time of a cycle{}",
            plan.names()[plan.state],
            plan.advance,
            if moving {
                ""
            } else {
                ": it stopped or turned back"
            }
        )),
        Stopped::Failed(failed) => failed.during(what),
    }
}

impl<'p, 'a> OnExchange<'p, 'a> {
    /// The shooting from the point's initial state (t, x), its transient taking at most
    /// `transient` of time.
    pub fn new(
        plan: &'p CyclePlan,
        problem: &'p mut Problem<'a>,
        (t, x): (f64, Vec<f64>),
        transient: f64,
        budget: Budget,
    ) -> Self {
        let monodromy = match plan.way {
            crate::cycle_plan::Way::Exchange(monodromy) => monodromy,
            crate::cycle_plan::Way::Starts(_) => Monodromy::Differences,
        };
        OnExchange {
            plan,
            monodromy,
            problem,
            t0: t,
            start: (t, x),
            direction: 1.0,
            transient,
            budget,
            runs: 0,
        }
    }

    fn leg(&mut self, x0: &[f64], end: End, variational: bool) -> Result<Leg, Stopped> {
        self.budget.check("a run over the cycle")?;
        self.runs += 1;
        leg(self.problem, self.t0, x0, end, variational, &[])
    }

    /// The way the cyclic state turns, from its derivative at the start, or, starting at
    /// rest, a moment later (a mechanism may start backwards): where the transient goes on.
    fn set_direction(&mut self) -> Result<Vec<f64>, NoCycle> {
        let k = self.plan.state;
        let mut x = self.start.1.clone();
        self.t0 = self.start.0;
        let mut f = derivative(self.problem.fmu, self.t0, &x)?;
        if f[k] == 0.0 {
            let moment = START_PROBE * self.transient;
            let moved = self
                .leg(&x, End::After(moment), false)
                .map_err(|e| stopped("the start of the transient", e, self.plan))?;
            (self.t0, x, f) = (self.t0 + moved.time, moved.x, moved.f);
        }
        self.direction = if f[k] < 0.0 { -1.0 } else { 1.0 };
        Ok(x)
    }

    /// One cycle's run from x0 over `period`, with its monodromy.
    fn with_monodromy(&mut self, x0: &[f64], period: f64) -> Result<Leg, NoCycle> {
        let what = "a run over the cycle";
        match self.monodromy {
            Monodromy::Variational => self
                .leg(x0, End::After(period), true)
                .map_err(|e| stopped(what, e, self.plan)),
            Monodromy::Differences => {
                let mut leg = self
                    .leg(x0, End::After(period), false)
                    .map_err(|e| stopped(what, e, self.plan))?;
                leg.phi = Some(self.differences(x0, period)?);
                Ok(leg)
            }
        }
    }

    /// ∂x(T)/∂x0 by central differences, a pair of runs per state but the cyclic one,
    /// whose column nothing reads (left 0).
    fn differences(&mut self, x0: &[f64], period: f64) -> Result<Vec<f64>, NoCycle> {
        let n = x0.len();
        let scales = periodic::scales(self.plan, x0, |i| self.problem.nominals[i]);
        let mut phi = vec![0.0; n * n];
        for j in (0..n).filter(|&j| j != self.plan.state) {
            let h = DIFFERENCE_STEP * scales[j];
            let mut ends = [Vec::new(), Vec::new()];
            for (side, sign) in [1.0, -1.0].into_iter().enumerate() {
                let mut x = x0.to_vec();
                x[j] += sign * h;
                ends[side] = self
                    .leg(&x, End::After(period), false)
                    .map_err(|e| stopped("a run of the monodromy's differences", e, self.plan))?
                    .x;
            }
            for i in 0..n {
                phi[i * n + j] = (ends[0][i] - ends[1][i]) / (2.0 * h);
            }
        }
        Ok(phi)
    }

    /// The cycle found, as the next point's guess: its state on the section, period and
    /// monodromy.
    pub fn shot(&self, found: periodic::Found<Leg>) -> Shot {
        Shot {
            t0: self.t0,
            x0: found.z,
            search: Search {
                period: found.period,
                residual: found.residual,
                iterations: found.iterations,
                runs: self.runs,
            },
            phi: found.run.phi.unwrap_or_default(),
            f: found.run.f,
            direction: self.direction,
        }
    }
}

impl Shooter for OnExchange<'_, '_> {
    type Run = Leg;

    fn run(&mut self, x0: &[f64], period: f64, exact: bool) -> Result<Leg, NoCycle> {
        if exact {
            return self.with_monodromy(x0, period);
        }
        self.leg(x0, End::After(period), false)
            .map_err(|e| stopped("a run over the cycle", e, self.plan))
    }

    fn residual(&self, x0: &[f64], run: &Leg) -> Vec<f64> {
        periodic::residual(self.plan, self.direction, x0, &run.x)
    }

    fn scales(&self, x0: &[f64], _: &Leg) -> Vec<f64> {
        periodic::scales(self.plan, x0, |i| self.problem.nominals[i])
    }

    fn jacobian(&self, run: &Leg, _: &[f64]) -> Option<DMatrix<f64>> {
        run.phi
            .as_ref()
            .map(|phi| jacobian_of(phi, &run.f, self.plan.state))
    }

    fn step(&self, jacobian: &DMatrix<f64>, r: &[f64], _: &[f64]) -> Result<Vec<f64>, NoCycle> {
        let rhs = DVector::from_iterator(r.len(), r.iter().map(|r| -r));
        let step = jacobian.clone().lu().solve(&rhs);
        step.filter(|s| s.iter().all(|v| v.is_finite()))
            .map(|s| s.iter().copied().collect())
            .ok_or_else(|| periodic::singular(""))
    }

    fn moved(&self, x0: &[f64], step: &[f64], lambda: f64) -> Vec<f64> {
        let mut x = x0.to_vec();
        let others = (0..x.len()).filter(|&i| i != self.plan.state);
        for (i, j) in others.enumerate() {
            x[j] += lambda * step[i];
        }
        x
    }

    fn step_size(&self, _: &[f64], period: f64, step: &[f64], scales: &[f64]) -> f64 {
        let last = step.len() - 1;
        let others = (0..scales.len()).filter(|&i| i != self.plan.state);
        let states = others
            .zip(step)
            .fold(0.0, |m: f64, (j, d)| m.max(d.abs() / scales[j]));
        states.max(step[last].abs() / period)
    }

    fn guessed(&mut self, guess: &Shot) -> ((Vec<f64>, f64), Option<DMatrix<f64>>) {
        self.t0 = guess.t0;
        self.direction = guess.direction;
        let hint =
            (!guess.phi.is_empty()).then(|| jacobian_of(&guess.phi, &guess.f, self.plan.state));
        ((guess.x0.clone(), guess.search.period), hint)
    }

    /// The transient, a cycle at a time, until its period settles: the state on the
    /// section and the last cycle's period (the section's time kept as `t0`).
    fn warm_up(&mut self) -> Result<(Vec<f64>, f64), NoCycle> {
        let (k, advance) = (self.plan.state, self.plan.advance);
        let mut x = self.set_direction()?;
        let next = |value: f64, direction: f64| {
            let cycles = value / advance;
            advance
                * if direction > 0.0 {
                    cycles.floor() + 1.0
                } else {
                    cycles.ceil() - 1.0
                }
        };
        let end_of_transient = self.t0 + self.transient;
        let mut settling = Settling::default();
        // Each crossing's target a whole advance on from the last one's: read off the
        // state, a value that rounding left a hair short of a crossing would be crossed
        // again at once.
        let mut target = next(x[k], self.direction);
        loop {
            let within = end_of_transient - self.t0;
            let reaching = End::Reaching {
                index: k,
                value: target,
                within,
            };
            let reached = match self.leg(&x, reaching, false) {
                Ok(reached) => reached,
                Err(Stopped::NotReached { moving }) => {
                    return Err(settling.unsettled(self.plan, self.transient, moving))
                }
                Err(e) => return Err(stopped("the transient before the shooting", e, self.plan)),
            };
            self.t0 += reached.time;
            x = reached.x;
            x[k] = target;
            if let Some(period) = settling.crossed(self.t0) {
                return Ok((x, period));
            }
            target += self.direction * advance;
        }
    }
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
