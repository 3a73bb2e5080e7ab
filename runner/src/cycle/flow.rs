//! One leg of a Model Exchange FMU's flow, integrated by DOP853 from a given state: for a
//! given time, or until a state reaches a value; with the flow's derivative with respect
//! to the starting state (the variational equations, from the FMU's directional
//! derivatives) when asked, and the states at given times on the way. An event indicator
//! that changes sign on the way ends the leg: a cycle through an event is not one this
//! analysis handles.

use std::cell::{Cell, RefCell};

use integrators::{initial_step, Dop853, OdeSystem, Stepper, Tolerances};

use crate::fmi::{Instance, Status};

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
    /// The state did not reach its value in the time given.
    NotReached,
    /// The FMU or the integrator failed, saying why.
    Failed(String),
    /// The point's wall-time budget (seconds) ran out before the leg began.
    OverBudget(f64),
}

/// The FMU's right-hand side, states over their nominals; with `variational`, the
/// columns of Ψ = D⁻¹ Φ D after the state (D the nominals), Ψ' = D⁻¹ J D Ψ, but the
/// cyclic state's.
struct Flow<'a, 'b> {
    problem: RefCell<&'a mut Problem<'b>>,
    n: usize,
    variational: bool,
    failure: Cell<Option<Status>>,
}

/// The states whose columns of Ψ a variational leg integrates, in the order they follow
/// the state in its vector: all but the cyclic one.
fn columns(n: usize, cyclic: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..n).filter(move |&j| j != cyclic).enumerate()
}

impl<const N: usize> OdeSystem<N> for Flow<'_, '_> {
    fn rhs(&self, t: f64, y: &[f64; N], dy: &mut [f64; N]) {
        *dy = [0.0; N];
        if self.failure.get().is_some() {
            dy.fill(f64::NAN);
            return;
        }
        let n = self.n;
        let mut p = self.problem.borrow_mut();
        let p = &mut **p;
        let mut x = [0.0; N];
        for k in 0..n {
            x[k] = y[k] * p.nominals[k];
        }
        let mut s = p.fmu.set_time(t).max(p.fmu.set_continuous_states(&x[..n]));
        if s.proceeds() {
            s = s.max(p.fmu.get_derivatives(&mut dy[..n]));
        }
        if s.proceeds() && self.variational {
            let (mut seed, mut column) = ([0.0; N], [0.0; N]);
            for (c, _) in columns(n, p.cyclic) {
                for i in 0..n {
                    seed[i] = y[n + c * n + i] * p.nominals[i];
                }
                s = s.max(p.fmu.get_directional_derivative(
                    p.derivatives,
                    p.states,
                    &seed[..n],
                    &mut column[..n],
                ));
                for i in 0..n {
                    dy[n + c * n + i] = column[i] / p.nominals[i];
                }
            }
        }
        if !s.proceeds() {
            self.failure.set(Some(s));
            dy.fill(f64::NAN);
            return;
        }
        for (dy, nominal) in dy[..n].iter_mut().zip(p.nominals) {
            *dy /= nominal;
        }
    }

    fn dimension(&self) -> usize {
        size(self.n, self.variational)
    }

    /// The steps are the state's own: the derivative is that of the numerical flow.
    fn controlled(&self) -> usize {
        self.n
    }
}

/// The equations of a leg of `n` states: with `variational`, n − 1 columns of Ψ too.
fn size(n: usize, variational: bool) -> usize {
    n + if variational { n * (n - 1) } else { 0 }
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
    let size = size(x0.len(), variational);
    macro_rules! sized {
        ($($size:literal)*) => {
            $(if size <= $size {
                return sized_leg::<$size>(problem, t0, x0, end, variational, at);
            })*
        };
    }
    sized!(2 4 6 8 12 16 24 30 36 48 64 96 128);
    Err(Stopped::Failed(format!(
        "{size} equations: the runner integrates a cycle's variational equations for at most \
         11 states (ask for monodromy = \"differences\")"
    )))
}

fn sized_leg<const N: usize>(
    problem: &mut Problem,
    t0: f64,
    x0: &[f64],
    end: End,
    variational: bool,
    at: &[f64],
) -> Result<Leg, Stopped> {
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
    if variational {
        for (c, j) in columns(n, problem.cyclic) {
            walk.y[n + c * n + j] = 1.0;
        }
    }
    read_indicators(problem, t0, x0, &mut walk.indicators)?;
    let limit = t0
        + match end {
            End::After(time) => time,
            End::Reaching { within, .. } => within,
        };
    let flow = Flow {
        problem: RefCell::new(problem),
        n,
        variational,
        failure: Cell::new(None),
    };
    walk.size_first_step(&flow, limit);
    loop {
        if walk.t >= limit {
            match end {
                End::After(_) => break,
                End::Reaching { .. } => return Err(Stopped::NotReached),
            }
        }
        if walk.step(&flow, (t0, limit), end, at)? {
            break;
        }
    }
    let Walk { t, y, sampled, .. } = walk;
    finish(
        flow.problem.into_inner(),
        (t0, t),
        &y[..],
        n,
        variational,
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
    fn size_first_step(&mut self, flow: &Flow, limit: f64) {
        let mut f0 = [0.0; N];
        flow.rhs(self.t, &self.y, &mut f0);
        let tolerances = flow.problem.borrow().tolerances;
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
        flow: &Flow,
        (t0, limit): (f64, f64),
        end: End,
        at: &[f64],
    ) -> Result<bool, Stopped> {
        let n = flow.n;
        let before = (self.t, self.y);
        let target = self.t.next_up().min(limit);
        let result = self
            .method
            .integrate(flow, &mut self.t, &mut self.y, target, limit);
        if let Some(status) = flow.failure.get() {
            return Err(Stopped::Failed(format!(
                "the FMU returned {status:?} on the way, at t = {}",
                self.t
            )));
        }
        result.map_err(|e| Stopped::Failed(format!("integrating the cycle: {e}")))?;
        let nominals = flow.problem.borrow().nominals;
        for ((x, y), nominal) in self.x.iter_mut().zip(&self.y).zip(nominals) {
            *x = y * nominal;
        }
        read_indicators(
            &mut flow.problem.borrow_mut(),
            self.t,
            &self.x,
            &mut self.probe,
        )?;
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

/// The leg's end: the state and its derivative there, and the flow's derivative from
/// the variational part of `y` (Ψ, back in the states' own units).
fn finish(
    problem: &mut Problem,
    (t0, t): (f64, f64),
    y: &[f64],
    n: usize,
    variational: bool,
    sampled: Vec<Vec<f64>>,
) -> Result<Leg, Stopped> {
    let x = unscaled(&y[..n], problem.nominals);
    let mut f = vec![0.0; n];
    let s = problem
        .fmu
        .set_time(t)
        .max(problem.fmu.set_continuous_states(&x))
        .max(problem.fmu.get_derivatives(&mut f));
    if !s.proceeds() {
        return Err(Stopped::Failed(format!(
            "fmi2GetDerivatives returned {s:?} at the leg's end"
        )));
    }
    let phi = variational.then(|| {
        let nom = problem.nominals;
        let mut phi = vec![0.0; n * n];
        for (c, j) in columns(n, problem.cyclic) {
            for i in 0..n {
                phi[i * n + j] = nom[i] * y[n + c * n + i] / nom[j];
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
    flow: &Flow,
    t: f64,
    y: &[f64; N],
    end: f64,
) -> Result<[f64; N], Stopped> {
    if t == end {
        return Ok(*y);
    }
    method
        .dense_output(flow, t)
        .ok_or_else(|| Stopped::Failed(format!("no dense output at t = {t}")))
}

/// Where, within the last step, state `index` reaches `value`: the secant method on the
/// step's dense output, kept inside the bracket by bisection, to a few ulps of time.
fn reach<const N: usize>(
    method: &mut Dop853<N>,
    flow: &Flow,
    ((mut ta, mut a), (mut tb, mut b)): ((f64, f64), (f64, f64)),
    index: usize,
    value: f64,
) -> Result<(f64, [f64; N]), Stopped> {
    let nominal = flow.problem.borrow().nominals[index];
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
        let g = method
            .dense_output(flow, t)
            .ok_or_else(|| Stopped::Failed(format!("no dense output at t = {t}")))?[index]
            * nominal
            - value;
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
    let y = method
        .dense_output(flow, best.0)
        .ok_or_else(|| Stopped::Failed(format!("no dense output at t = {}", best.0)))?;
    Ok((best.0, y))
}

fn read_indicators(
    problem: &mut Problem,
    t: f64,
    x: &[f64],
    into: &mut [f64],
) -> Result<(), Stopped> {
    if into.is_empty() {
        return Ok(());
    }
    let s = problem
        .fmu
        .set_time(t)
        .max(problem.fmu.set_continuous_states(x))
        .max(problem.fmu.get_event_indicators(into));
    if s.proceeds() {
        Ok(())
    } else {
        Err(Stopped::Failed(format!(
            "reading the event indicators returned {s:?} at t = {t}"
        )))
    }
}
