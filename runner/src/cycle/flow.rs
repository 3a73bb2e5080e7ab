//! One leg of a Model Exchange FMU's flow, integrated by DOP853 from a given state on the
//! runner's own right-hand side of the FMU ([`Scaled`]): for a given time, or until a
//! state reaches a value; with the flow's derivative with respect to the starting state
//! (the variational equations) when asked, and the states at given times on the way. An
//! event indicator that changes sign on the way ends the leg: a cycle through an event is
//! not one this analysis handles.

use integrators::{initial_step, Dop853, OdeSystem, Stepper, Tolerances};

use super::periodic::{check, NoCycle};
use crate::exchange::{at_size, AtSize, Scaled, Variational};
use crate::fmi::Instance;

/// What a leg runs on: the FMU in continuous-time mode, its states' nominals and value
/// references.
pub struct Problem<'a> {
    pub fmu: &'a mut Instance,
    pub nominals: &'a [f64],
    pub states: &'a [u32],
    pub derivatives: &'a [u32],
    pub indicators: usize,
    pub tolerances: Tolerances,
    /// The cyclic state, fixed on the section: its column of the flow's derivative is
    /// never read, so a variational leg does not integrate it.
    pub cyclic: usize,
}

/// Where a leg ends.
#[derive(Clone, Copy, Debug)]
pub enum End {
    /// After this long.
    After(f64),
    /// Where state `index` reaches `value` (from either side), within `within` of time.
    Reaching {
        index: usize,
        value: f64,
        within: f64,
    },
}

/// Where a leg ended.
pub struct Leg {
    /// Its duration.
    pub time: f64,
    pub x: Vec<f64>,
    /// The state's derivative at the end.
    pub f: Vec<f64>,
    /// ∂x(end)/∂x(start), row-major n × n (variational legs only), the cyclic state's
    /// column left 0.
    pub phi: Option<Vec<f64>>,
    /// The states at the times asked for, in order.
    pub sampled: Vec<Vec<f64>>,
}

/// Why a leg did not end as asked.
#[derive(Debug)]
pub enum Stopped {
    /// Event indicator `k` changed sign near time `t` after the leg's start.
    Event(usize, f64),
    /// The state did not reach its value in the time given; `moving` where it still
    /// moved toward it at the end.
    NotReached { moving: bool },
    /// The FMU or the integrator failed.
    Failed(NoCycle),
}

impl From<NoCycle> for Stopped {
    fn from(failed: NoCycle) -> Stopped {
        Stopped::Failed(failed)
    }
}

/// A leg at the size it is compiled for.
struct SizedLeg<'p, 'a, 'r> {
    problem: &'p mut Problem<'a>,
    t0: f64,
    x0: &'r [f64],
    end: End,
    variational: bool,
    at: &'r [f64],
}

impl AtSize for SizedLeg<'_, '_, '_> {
    type Made = Result<Leg, Stopped>;

    fn at<const N: usize>(self) -> Self::Made {
        sized_leg::<N>(self)
    }
}

/// Integrate from `x0` at time `t0` to `end`; the states at `at` (times after `t0`,
/// increasing) on the way.
pub fn leg(
    problem: &mut Problem,
    t0: f64,
    x0: &[f64],
    end: End,
    variational: bool,
    at: &[f64],
) -> Result<Leg, Stopped> {
    let n = x0.len();
    let size = if variational { Variational::size(n) } else { n };
    let sized = SizedLeg {
        problem,
        t0,
        x0,
        end,
        variational,
        at,
    };
    at_size(size, sized).unwrap_or_else(|| {
        Err(Stopped::Failed(NoCycle::because(format!(
            "{size} equations: the runner integrates a cycle's variational equations for at \
             most 11 states (ask for monodromy = \"differences\")"
        ))))
    })
}

fn sized_leg<const N: usize>(leg: SizedLeg) -> Result<Leg, Stopped> {
    let (problem, (t0, x0), end) = (leg.problem, (leg.t0, leg.x0), leg.end);
    let (variational, at) = (leg.variational, leg.at);
    let n = x0.len();
    let mut walk = Walk::<N> {
        method: Dop853::new(problem.tolerances),
        t: t0,
        y: [0.0; N],
        indicators: vec![0.0; problem.indicators],
        probe: vec![0.0; problem.indicators],
        x: x0.to_vec(),
        sampled: Vec::with_capacity(at.len()),
    };
    for (k, (x, nominal)) in x0.iter().zip(problem.nominals).enumerate() {
        walk.y[k] = x / nominal;
    }
    let columns = variational.then_some(Variational {
        states: problem.states,
        derivatives: problem.derivatives,
        skipped: problem.cyclic,
    });
    if let Some(columns) = &columns {
        for (c, j) in columns.columns() {
            walk.y[n + c * n + j] = 1.0;
        }
    }
    read_indicators(&mut *problem.fmu, t0, x0, &mut walk.indicators)?;
    let limit = t0
        + match end {
            End::After(time) => time,
            End::Reaching { within, .. } => within,
        };
    let flow = Scaled::new(&mut *problem.fmu, problem.nominals, columns);
    walk.size_first_step(&flow, limit, problem.tolerances);
    loop {
        if walk.t >= limit {
            if let End::Reaching { index, value, .. } = end {
                let x = unscaled(&walk.y[..n], flow.nominals);
                let f = derivative(&mut flow.fmu.borrow_mut(), walk.t, &x)?;
                let moving = f[index] * (value - x[index]) > 0.0;
                return Err(Stopped::NotReached { moving });
            }
            break;
        }
        if walk.step(&flow, (t0, limit), end, at)? {
            break;
        }
    }
    let Walk { t, y, sampled, .. } = walk;
    let columns = variational.then_some(problem.cyclic);
    let nominals = flow.nominals;
    finish(
        flow.fmu.into_inner(),
        nominals,
        (t0, t),
        &y,
        (n, columns),
        sampled,
    )
}

/// A leg on its way: the method, where it stands, the event indicators at its start and
/// the states sampled so far.
struct Walk<const N: usize> {
    method: Dop853<N>,
    t: f64,
    y: [f64; N],
    indicators: Vec<f64>,
    probe: Vec<f64>,
    x: Vec<f64>,
    sampled: Vec<Vec<f64>>,
}

impl<const N: usize> Walk<N> {
    /// A step is asked to end just past t, so the first one's size must come from the
    /// leg's span.
    fn size_first_step(&mut self, flow: &Scaled, limit: f64, tolerances: Tolerances) {
        let mut f0 = [0.0; N];
        flow.rhs(self.t, &self.y, &mut f0);
        let stats = &mut self.method.progress_mut().stats;
        stats.n_rhs += 1;
        let h = initial_step(
            flow,
            (self.t, &self.y, &f0),
            limit - self.t,
            tolerances,
            8,
            stats,
        );
        self.method.progress_mut().next_step = Some(h);
    }

    /// One accepted step: the samples within it taken, an event on it refused; whether
    /// it reached the state's value (`End::Reaching`), the walk then standing there.
    fn step(
        &mut self,
        flow: &Scaled,
        (t0, limit): (f64, f64),
        end: End,
        at: &[f64],
    ) -> Result<bool, Stopped> {
        let n = self.x.len();
        let before = (self.t, self.y);
        let target = self.t.next_up().min(limit);
        let result = self
            .method
            .integrate(flow, &mut self.t, &mut self.y, target, limit);
        if let Some(status) = flow.failure() {
            let at = format!("integrating the cycle at t = {}", self.t);
            return Err(NoCycle::returned(&at, status).into());
        }
        result.map_err(|e| NoCycle::because(format!("integrating the cycle: {e}")))?;
        let nominals = flow.nominals;
        for ((x, y), nominal) in self.x.iter_mut().zip(&self.y).zip(nominals) {
            *x = y * nominal;
        }
        read_indicators(&mut flow.fmu.borrow_mut(), self.t, &self.x, &mut self.probe)?;
        let (old, new) = (&self.indicators, &self.probe);
        if let Some(k) = (0..new.len()).find(|&k| (old[k] > 0.0) != (new[k] > 0.0)) {
            return Err(Stopped::Event(k, self.t - t0));
        }
        while let Some(&ts) = at.get(self.sampled.len()) {
            if t0 + ts > self.t {
                break;
            }
            let z = dense(&mut self.method, flow, t0 + ts, &self.y, self.t)?;
            self.sampled.push(unscaled(&z[..n], nominals));
        }
        let End::Reaching { index, value, .. } = end else {
            return Ok(false);
        };
        let (a, b) = (
            before.1[index] * nominals[index] - value,
            self.y[index] * nominals[index] - value,
        );
        if a == 0.0 || (a < 0.0) != (b < 0.0) {
            let bracket = ((before.0, a), (self.t, b));
            (self.t, self.y) = reach(&mut self.method, flow, bracket, index, value)?;
            return Ok(true);
        }
        Ok(false)
    }
}

/// The state's derivative at (t, x).
pub fn derivative(fmu: &mut Instance, t: f64, x: &[f64]) -> Result<Vec<f64>, NoCycle> {
    let mut f = vec![0.0; x.len()];
    let s = fmu.set_state(t, x).then(|| fmu.get_derivatives(&mut f));
    check(s, &format!("the state's derivative at t = {t}"))?;
    Ok(f)
}

/// The leg's end: the state and its derivative there, and the flow's derivative from
/// the variational part of `y` (Ψ, back in the states' own units) where `columns` names
/// the state whose column was skipped.
fn finish(
    fmu: &mut Instance,
    nominals: &[f64],
    (t0, t): (f64, f64),
    y: &[f64],
    (n, columns): (usize, Option<usize>),
    sampled: Vec<Vec<f64>>,
) -> Result<Leg, Stopped> {
    let x = unscaled(&y[..n], nominals);
    let f = derivative(fmu, t, &x)?;
    let phi = columns.map(|skipped| {
        let mut phi = vec![0.0; n * n];
        for (c, j) in (0..n).filter(|&j| j != skipped).enumerate() {
            for i in 0..n {
                phi[i * n + j] = nominals[i] * y[n + c * n + i] / nominals[j];
            }
        }
        phi
    });
    Ok(Leg {
        time: t - t0,
        x,
        f,
        phi,
        sampled,
    })
}

fn unscaled(y: &[f64], nominals: &[f64]) -> Vec<f64> {
    y.iter().zip(nominals).map(|(y, n)| y * n).collect()
}

/// The solution at `t` within the last step (ending at `end`, where it is `y`).
fn dense<const N: usize>(
    method: &mut Dop853<N>,
    flow: &Scaled,
    t: f64,
    y: &[f64; N],
    end: f64,
) -> Result<[f64; N], NoCycle> {
    if t == end {
        return Ok(*y);
    }
    dense_at(method, flow, t)
}

/// The solution at `t` within the last step, from its dense output.
fn dense_at<const N: usize>(
    method: &mut Dop853<N>,
    flow: &Scaled,
    t: f64,
) -> Result<[f64; N], NoCycle> {
    method
        .dense_output(flow, t)
        .ok_or_else(|| NoCycle::because(format!("no dense output at t = {t}")))
}

/// Where, within the last step, state `index` reaches `value`: the secant method on the
/// step's dense output, kept inside the bracket by bisection, to a few ulps of time.
fn reach<const N: usize>(
    method: &mut Dop853<N>,
    flow: &Scaled,
    ((mut ta, mut a), (mut tb, mut b)): ((f64, f64), (f64, f64)),
    index: usize,
    value: f64,
) -> Result<(f64, [f64; N]), NoCycle> {
    let nominal = flow.nominals[index];
    let mut best = (tb, b.abs());
    for _ in 0..200 {
        if a == 0.0 {
            best = (ta, 0.0);
            break;
        }
        if tb - ta <= 4.0 * f64::EPSILON * tb.abs().max(1.0) {
            break;
        }
        let secant = tb - b * (tb - ta) / (b - a);
        let t = if secant > ta && secant < tb {
            secant
        } else {
            0.5 * (ta + tb)
        };
        let g = dense_at(method, flow, t)?[index] * nominal - value;
        if g.abs() < best.1 {
            best = (t, g.abs());
        }
        if g == 0.0 {
            break;
        }
        if (g < 0.0) == (a < 0.0) {
            (ta, a) = (t, g);
        } else {
            (tb, b) = (t, g);
        }
    }
    let y = dense_at(method, flow, best.0)?;
    Ok((best.0, y))
}

/// The event indicators at (t, x), into `into`.
fn read_indicators(fmu: &mut Instance, t: f64, x: &[f64], into: &mut [f64]) -> Result<(), NoCycle> {
    if into.is_empty() {
        return Ok(());
    }
    let s = fmu.set_state(t, x).then(|| fmu.get_event_indicators(into));
    check(s, &format!("reading the event indicators at t = {t}"))
}
