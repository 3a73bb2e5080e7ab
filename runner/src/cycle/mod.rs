//! The steady cycle of a point, found directly instead of waited for: the periodic
//! steady state by shooting on the Model Exchange interface ([`shooting`], over legs of
//! the flow in [`flow`]) or through a co-simulation FMU's start values and its own
//! sensitivities ([`through_starts`]), its Floquet multipliers and the modes of the state
//! equations linearised along it ([`floquet`]), and metrics of outputs over one cycle
//! ([`measure`]).
//! docs/cycle.md explains the method.

mod continuation;
mod floquet;
mod flow;
mod measure;
mod shooting;
mod through_starts;

use integrators::Tolerances;
use serde::Serialize;

use crate::cycle_plan::{CyclePlan, LinearPlan};
use crate::fmi::Instance;
pub use continuation::Continuation;
pub use floquet::{Mode, Multiplier};
use flow::{leg, End, Problem};
pub use shooting::NoCycle;
use shooting::Shooting;
pub use shooting::Shot;
pub use through_starts::Restart;
use through_starts::ThroughStarts;

/// The local error held by the cycle's integration, as a fraction of the plan's
/// tolerance (the shooting converges to the tolerance itself, which the error of a whole
/// cycle must stay below).
const TOLERANCE_SAFETY: f64 = 1.0 / 30.0;

/// A point's steady cycle, as the runner replies it.
#[derive(Clone, Debug, Serialize)]
pub struct CycleRecord {
    pub period: f64,
    /// The state on the section, in Model Exchange's order, and the states' names.
    pub state: Vec<f64>,
    pub state_names: Vec<String>,
    /// The largest scaled component of x(T) − x0 − s.
    pub residual: f64,
    pub iterations: usize,
    pub runs: usize,
    /// Whether the shooting started from the previous point's cycle.
    pub continued: bool,
    pub multipliers: Vec<Multiplier>,
    pub largest_multiplier: f64,
    pub stability: &'static str,
    /// 1 − the largest multiplier's modulus.
    pub margin: f64,
    pub metrics: Vec<f64>,
    /// The modes at points along the cycle: the time into the cycle and the modes there.
    pub modes: Vec<(f64, Vec<Mode>)>,
    /// Where the plan asks, the whole linearisation at each of those points (its `t` the
    /// time into the cycle).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub linearisations: Vec<Linearisation>,
    /// The kept variables at the samples: the times into the cycle, then a row each
    /// (replied as a series).
    #[serde(skip)]
    pub kept: Vec<Vec<f64>>,
}

/// The instance a cycle is found on: a Model Exchange FMU in continuous-time mode at
/// `t`, its states `x`, nominals and event indicators.
pub struct Start<'a> {
    pub fmu: &'a mut Instance,
    pub t: f64,
    pub x: Vec<f64>,
    pub nominals: &'a [f64],
    pub indicators: usize,
}

/// The band around the unit circle within which a cycle is called marginal: what the
/// multipliers' own error allows at this tolerance.
fn marginal_band(tolerance: f64) -> f64 {
    (1e3 * tolerance).clamp(1e-9, 1e-3)
}

/// The record of a cycle found, its multipliers judged: a multiplier on the unit circle
/// (within what the tolerance can tell) is an undamped mode, not a steady cycle. The
/// metrics, modes and kept variables are the caller's to fill.
fn record_of(
    plan: &CyclePlan,
    shot: &Shot,
    state: Vec<f64>,
    continued: bool,
    multipliers: Vec<Multiplier>,
    tolerance: f64,
) -> Result<CycleRecord, NoCycle> {
    let (stability, margin) = floquet::stability(&multipliers, marginal_band(tolerance));
    if stability == "marginal" {
        let on = &multipliers[0];
        return Err(NoCycle::because(format!(
            "no steady cycle: a periodic motion was found, but a Floquet multiplier lies on \
             the unit circle (|μ| = {:.9}, mostly {}): an undamped mode, so transients do \
             not settle onto it and it is one of a family of motions, not a steady state",
            on.modulus,
            on.states.first().map_or("?", |s| s.0.as_str())
        )));
    }
    Ok(CycleRecord {
        period: shot.period,
        state,
        state_names: plan.state_names.clone(),
        residual: shot.residual,
        iterations: shot.iterations,
        runs: shot.runs,
        continued,
        largest_multiplier: multipliers.first().map_or(0.0, |m| m.modulus),
        multipliers,
        stability,
        margin,
        metrics: Vec::new(),
        modes: Vec::new(),
        linearisations: Vec::new(),
        kept: Vec::new(),
    })
}

/// The steady cycle from `start`: from `guess` (a neighbour's cycle) first where given;
/// the transient may take `budget` of time to complete a cycle.
pub fn analyse(
    start: Start,
    plan: &CyclePlan,
    tolerance: f64,
    budget: f64,
    guess: Option<&Shot>,
    deadline: Option<(std::time::Instant, f64)>,
) -> Result<(CycleRecord, Shot), NoCycle> {
    let internal = tolerance * TOLERANCE_SAFETY;
    let mut problem = Problem {
        fmu: start.fmu,
        nominals: start.nominals,
        states: &plan.states,
        derivatives: &plan.derivatives,
        indicators: start.indicators,
        tolerances: Tolerances {
            rtol: internal,
            atol: internal,
        },
        cyclic: plan.state,
    };
    let mut shooting = Shooting::new(plan, &mut problem, budget, tolerance);
    shooting.deadline = deadline;
    let shot = shooting.solve(start.t, &start.x, guess)?;
    let continued = shooting.continued;
    let multipliers = floquet::multipliers(
        &shot.phi,
        &shot.f,
        plan.state,
        &plan.state_names,
        start.nominals,
    );
    let mut record = record_of(
        plan,
        &shot,
        shot.x0.clone(),
        continued,
        multipliers,
        tolerance,
    )?;
    (record.metrics, record.kept) = along(&mut problem, plan, &shot).map_err(NoCycle::because)?;
    (record.modes, record.linearisations) =
        modes_along(&mut problem, plan, &shot).map_err(NoCycle::because)?;
    Ok((record, shot))
}

/// The states at `count` evenly spaced times of the cycle (from its section).
fn states_along(
    problem: &mut Problem,
    shot: &Shot,
    count: usize,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    let times = times_along(shot.period, count);
    let later: Vec<f64> = times[1..].to_vec();
    let run = leg(
        problem,
        shot.t0,
        &shot.x0,
        End::After(shot.period),
        false,
        &later,
    )
    .map_err(|e| format!("the cycle's samples: {e:?}"))?;
    let mut states = vec![shot.x0.clone()];
    states.extend(run.sampled);
    Ok((times, states))
}

/// The metrics over the cycle, and the kept variables at its samples.
fn along(
    problem: &mut Problem,
    plan: &CyclePlan,
    shot: &Shot,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    if plan.reads.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }
    let (times, states) = states_along(problem, shot, plan.samples)?;
    let mut rows = Vec::with_capacity(times.len());
    let mut row = vec![0.0; plan.reads.len()];
    for (t, x) in times.iter().zip(&states) {
        let fmu = &mut problem.fmu;
        let s = fmu
            .set_time(shot.t0 + t)
            .max(fmu.set_continuous_states(x))
            .max(fmu.get_real(&plan.reads, &mut row));
        if !s.proceeds() {
            return Err(format!(
                "reading the outputs along the cycle returned {s:?}"
            ));
        }
        if let Some(i) = row.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "the FMU reported {} = {} on the cycle with a successful status",
                plan.read_names[i], row[i]
            ));
        }
        rows.push(row.clone());
    }
    Ok(measured(plan, times, &rows))
}

/// The metrics over the cycle from the variables read at its samples (a row per sample
/// time), and the kept variables (the times first).
fn measured(plan: &CyclePlan, times: Vec<f64>, rows: &[Vec<f64>]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let columns: Vec<Vec<f64>> = (0..plan.reads.len())
        .map(|j| rows.iter().map(|row| row[j]).collect())
        .collect();
    let metrics = plan
        .metrics
        .iter()
        .map(|&(slot, kind, order)| measure::metric(&columns[slot], kind, order))
        .collect();
    let mut kept = Vec::new();
    if !plan.kept.is_empty() {
        kept.push(times);
        kept.extend(plan.kept.iter().map(|&slot| columns[slot].clone()));
    }
    (metrics, kept)
}

/// The times of `count` evenly spaced points of a cycle of `period`, from its section.
fn times_along(period: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|j| period * j as f64 / count as f64)
        .collect()
}

/// The modes of A = ∂f/∂x (the FMU's directional derivatives) at `plan.modes` evenly
/// spaced times of the cycle.
fn modes_along(problem: &mut Problem, plan: &CyclePlan, shot: &Shot) -> Result<Along, String> {
    if plan.modes == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let (times, states) = states_along(problem, shot, plan.modes)?;
    let points: Vec<(f64, Vec<f64>)> = times.into_iter().zip(states).collect();
    modes_at(problem.fmu, plan, shot.t0, &points)
}

/// A = ∂f/∂x at (t, x), row-major, a column per directional derivative.
fn jacobian_at(
    fmu: &mut Instance,
    (states, derivatives): (&[u32], &[u32]),
    t: f64,
    x: &[f64],
) -> Result<Vec<f64>, String> {
    let s = fmu.set_time(t).max(fmu.set_continuous_states(x));
    if !s.proceeds() {
        return Err(format!("setting the state along the cycle returned {s:?}"));
    }
    block(fmu, derivatives, states).map_err(|e| format!("along the cycle: {e}"))
}

/// What the state equations linearised along a cycle give: each point's time into the
/// cycle and modes, and, where the plan asks, each point's whole linearisation.
pub type Along = (Vec<(f64, Vec<Mode>)>, Vec<Linearisation>);

/// The modes at Model Exchange states read along a cycle (each with its time into the
/// cycle, which starts at `t0`), on a Model Exchange instance in continuous-time mode;
/// with the plan's `linear`, A, B, C and D there too.
pub fn modes_at(
    fmu: &mut Instance,
    plan: &CyclePlan,
    t0: f64,
    points: &[(f64, Vec<f64>)],
) -> Result<Along, String> {
    let (mut modes, mut whole) = (Vec::with_capacity(points.len()), Vec::new());
    for (t, x) in points {
        if let Some(linear) = &plan.linear {
            let mut found = linearise(fmu, t0 + t, x.clone(), linear)
                .map_err(|e| format!("along the cycle: {e}"))?;
            found.t = *t;
            modes.push((*t, found.modes.clone()));
            whole.push(found);
        } else {
            let a = jacobian_at(fmu, (&plan.states, &plan.derivatives), t0 + t, x)?;
            modes.push((*t, floquet::modes(&a, x.len())));
        }
    }
    Ok((modes, whole))
}

/// Model Exchange's states at times into a cycle.
pub type StatesAlong = Vec<(f64, Vec<f64>)>;

/// The steady cycle through the FMU's Co-Simulation interface, its start values and its
/// sensitivities (`plan.through`): the record (its modes still to find), the shot for
/// the next point, and Model Exchange's states read at the modes' points along the cycle.
pub fn analyse_through_starts(
    restart: &mut dyn Restart,
    plan: &CyclePlan,
    run: (f64, f64, f64),
    tolerance: f64,
    guess: Option<&Shot>,
    deadline: Option<(std::time::Instant, f64)>,
) -> Result<(CycleRecord, Shot, StatesAlong), NoCycle> {
    let starts = plan.through.as_ref().expect("a cycle through start values");
    let mut shooting = ThroughStarts::new(plan, starts, restart, run, tolerance);
    shooting.deadline = deadline;
    let (shot, ends) = shooting.solve(guess)?;
    let multipliers = through_starts::multipliers(&ends, plan, starts)?;
    let mut record = record_of(
        plan,
        &shot,
        ends.y0,
        shooting.continued,
        multipliers,
        tolerance,
    )?;
    if !plan.reads.is_empty() {
        let times = times_along(shot.period, plan.samples);
        let rows = shooting
            .along(&shot.x0, &times, &plan.reads)
            .map_err(NoCycle::because)?;
        (record.metrics, record.kept) = measured(plan, times, &rows);
    }
    let mode_states = if plan.modes == 0 {
        Vec::new()
    } else {
        let times = times_along(shot.period, plan.modes);
        let rows = shooting
            .along(&shot.x0, &times, &plan.states)
            .map_err(NoCycle::because)?;
        times.into_iter().zip(rows).collect()
    };
    Ok((record, shot, mode_states))
}

/// ∂unknowns/∂knowns where the FMU stands, row-major, a column per directional
/// derivative.
fn block(fmu: &mut Instance, unknowns: &[u32], knowns: &[u32]) -> Result<Vec<f64>, String> {
    let (rows, columns) = (unknowns.len(), knowns.len());
    let mut matrix = vec![0.0; rows * columns];
    let (mut seed, mut column) = (vec![0.0; columns], vec![0.0; rows]);
    for j in 0..columns {
        seed.fill(0.0);
        seed[j] = 1.0;
        let s = fmu.get_directional_derivative(unknowns, knowns, &seed, &mut column);
        if !s.proceeds() {
            return Err(format!(
                "the directional derivative along the {j}th known returned {s:?}"
            ));
        }
        for i in 0..rows {
            matrix[i * columns + j] = column[i];
        }
    }
    Ok(matrix)
}

/// The state equations and outputs linearised where the FMU stands, at (t, x):
/// x' ≈ A x + B u, y ≈ C x + D u (u the Real inputs, y the Real outputs), each matrix
/// row-major; and the modes of A.
#[derive(Clone, Debug, Serialize)]
pub struct Linearisation {
    pub t: f64,
    pub x: Vec<f64>,
    pub states: Vec<String>,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub c: Vec<f64>,
    pub d: Vec<f64>,
    pub modes: Vec<Mode>,
}

pub fn linearise(
    fmu: &mut Instance,
    t: f64,
    x: Vec<f64>,
    plan: &LinearPlan,
) -> Result<Linearisation, String> {
    let s = fmu.set_time(t).max(fmu.set_continuous_states(&x));
    if !s.proceeds() {
        return Err(format!("setting the state returned {s:?}"));
    }
    let a = block(fmu, &plan.derivatives, &plan.states).map_err(|e| format!("A: {e}"))?;
    let b = block(fmu, &plan.derivatives, &plan.inputs).map_err(|e| format!("B: {e}"))?;
    let c = block(fmu, &plan.outputs, &plan.states).map_err(|e| format!("C: {e}"))?;
    let d = block(fmu, &plan.outputs, &plan.inputs).map_err(|e| format!("D: {e}"))?;
    if let Some(v) = [&a, &b, &c, &d]
        .iter()
        .flat_map(|m| m.iter())
        .find(|v| !v.is_finite())
    {
        return Err(format!("the FMU's directional derivatives hold {v}"));
    }
    let modes = floquet::modes(&a, x.len());
    Ok(Linearisation {
        t,
        x,
        states: plan.state_names.clone(),
        inputs: plan.input_names.clone(),
        outputs: plan.output_names.clone(),
        a,
        b,
        c,
        d,
        modes,
    })
}
