//! The steady cycle of a point, found directly instead of waited for: the periodic
//! steady state by Newton's method on the periodicity condition ([`periodic`]), shooting on
//! the Model Exchange interface ([`on_exchange`], over legs of the flow in [`flow`]) or
//! through a co-simulation FMU's start values and its own sensitivities
//! ([`through_starts`]), from the previous points' cycles ([`continuation`]); its Floquet
//! multipliers and the modes of the state equations linearised along it ([`floquet`]),
//! and metrics of outputs over one cycle ([`measure`]). docs/cycle.md explains the method.

mod continuation;
mod floquet;
mod flow;
mod measure;
mod on_exchange;
mod periodic;
mod through_starts;

use integrators::Tolerances;
use serde::Serialize;

use crate::cycle_plan::{CyclePlan, ExchangeStates, LinearPlan, Way};
use crate::exchange::TOLERANCE_SAFETY;
use crate::fmi::Instance;
use crate::metrics::Sample;
pub use continuation::Continuation;
pub use floquet::{Mode, Multiplier};
use flow::{derivative, leg, End, Problem};
use on_exchange::OnExchange;
use periodic::check;
pub use periodic::{Budget, Miss, NoCycle, Search, Shot};
pub use through_starts::Restart;
use through_starts::ThroughStarts;

/// A point's steady cycle, as the runner replies it.
#[derive(Clone, Debug, Serialize)]
pub struct CycleRecord {
    #[serde(flatten)]
    pub search: Search,
    /// The unknowns on the section (Model Exchange's states, or the closing variables
    /// through the start values), and their names.
    pub state: Vec<f64>,
    pub state_names: Vec<String>,
    /// Whether the shooting started from the previous point's cycle.
    pub continued: bool,
    pub multipliers: Vec<Multiplier>,
    pub largest_multiplier: f64,
    /// 1 − the largest multiplier's modulus: negative for an unstable cycle.
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
    (state, continued): (Vec<f64>, bool),
    multipliers: Vec<Multiplier>,
    tolerance: f64,
) -> Result<CycleRecord, NoCycle> {
    if floquet::marginal(&multipliers, marginal_band(tolerance)) {
        let on = &multipliers[0];
        return Err(NoCycle::because(format!(
            "no steady cycle: a periodic motion was found, but a Floquet multiplier lies on \
             the unit circle (|μ| = {:.9}, mostly {}): an undamped mode, so transients do \
             not settle onto it and it is one of a family of motions, not a steady state",
            on.modulus,
            on.states.first().map_or("?", |s| s.0.as_str())
        )));
    }
    let largest = multipliers.first().map_or(0.0, |m| m.modulus);
    Ok(CycleRecord {
        search: shot.search.clone(),
        state,
        state_names: plan.names().to_vec(),
        continued,
        largest_multiplier: largest,
        margin: 1.0 - largest,
        multipliers,
        metrics: Vec::new(),
        modes: Vec::new(),
        linearisations: Vec::new(),
        kept: Vec::new(),
    })
}

/// The steady cycle on Model Exchange from `start`: from `guess` (a neighbour's cycle)
/// first where given; the transient may take `transient` of time to settle.
pub fn analyse(
    start: Start,
    plan: &CyclePlan,
    tolerance: f64,
    (transient, budget): (f64, Budget),
    guess: Option<&Shot>,
) -> Result<(CycleRecord, Shot), NoCycle> {
    let internal = tolerance * TOLERANCE_SAFETY;
    let mut problem = Problem {
        fmu: start.fmu,
        nominals: start.nominals,
        states: &plan.exchange.states.vrs,
        derivatives: &plan.exchange.derivatives,
        indicators: start.indicators,
        tolerances: Tolerances {
            rtol: internal,
            atol: internal,
        },
        cyclic: plan.state,
    };
    let begin = (start.t, start.x);
    let mut shooting = OnExchange::new(plan, &mut problem, begin, transient, budget);
    let found = periodic::find(&mut shooting, guess, tolerance)?;
    let continued = found.continued;
    let shot = shooting.shot(found);
    let names = plan.names();
    let multipliers = floquet::multipliers(&shot.phi, &shot.f, plan.state, names, start.nominals);
    let state = (shot.x0.clone(), continued);
    let mut record = record_of(plan, &shot, state, multipliers, tolerance)?;
    (record.metrics, record.kept) = along(&mut problem, plan, &shot)?;
    (record.modes, record.linearisations) = modes_along(&mut problem, plan, &shot)?;
    Ok((record, shot))
}

/// The states at `count` evenly spaced times of the cycle (from its section).
fn states_along(
    problem: &mut Problem,
    plan: &CyclePlan,
    shot: &Shot,
    count: usize,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), NoCycle> {
    let times = times_along(shot.search.period, count);
    let after = End::After(shot.search.period);
    let run = leg(problem, shot.t0, &shot.x0, after, false, &times[1..])
        .map_err(|e| on_exchange::stopped("the cycle's samples", e, plan))?;
    let mut states = vec![shot.x0.clone()];
    states.extend(run.sampled);
    Ok((times, states))
}

/// The metrics over the cycle, and the kept variables at its samples.
fn along(
    problem: &mut Problem,
    plan: &CyclePlan,
    shot: &Shot,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), NoCycle> {
    if plan.reads.vrs.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }
    let (times, states) = states_along(problem, plan, shot, plan.samples)?;
    let mut columns = vec![Vec::with_capacity(times.len()); plan.reads.vrs.len()];
    let mut row = vec![0.0; plan.reads.vrs.len()];
    for (&t, x) in times.iter().zip(&states) {
        let fmu = &mut problem.fmu;
        let s = fmu
            .set_state(shot.t0 + t, x)
            .then(|| fmu.get_real(&plan.reads.vrs, &mut row));
        check(s, "reading the outputs along the cycle")?;
        if let Some(i) = row.iter().position(|v| !v.is_finite()) {
            return Err(NoCycle::because(format!(
                "the FMU reported {} = {} on the cycle with a successful status",
                plan.reads.names[i], row[i]
            )));
        }
        for (column, &x) in columns.iter_mut().zip(&row) {
            column.push(Sample { t, x, rate: None });
        }
    }
    if plan.exchange.directional {
        rates_at_extremes(problem, plan, (shot.t0, &states), &mut columns)?;
    }
    Ok(measured(plan, (times, shot.search.period), &columns))
}

/// Where a metric refines its extremes, the rates of its variable at the samples around
/// them: dy/dt = ∂y/∂x · f, from the FMU's directional derivatives.
fn rates_at_extremes(
    problem: &mut Problem,
    plan: &CyclePlan,
    (t0, states): (f64, &[Vec<f64>]),
    columns: &mut [Vec<Sample>],
) -> Result<(), NoCycle> {
    let refining = plan
        .metrics
        .iter()
        .filter(|m| m.extremes == crate::metrics::Extremes::Refined);
    for metric in refining {
        for &sign in measure::signs(metric.kind) {
            for j in measure::around(&columns[metric.slot], sign) {
                let sample = &mut columns[metric.slot][j];
                if sample.rate.is_some() {
                    continue;
                }
                let fmu = &mut *problem.fmu;
                let f = derivative(fmu, t0 + sample.t, &states[j])?;
                let mut rate = [0.0];
                let vr = [plan.reads.vrs[metric.slot]];
                let s =
                    fmu.get_directional_derivative(&vr, &plan.exchange.states.vrs, &f, &mut rate);
                check(s, "an output's rate along the cycle")?;
                sample.rate = rate[0].is_finite().then_some(rate[0]);
            }
        }
    }
    Ok(())
}

/// The metrics over the cycle from the variables sampled along it (a column per variable
/// read), and the kept variables (the times first).
fn measured(
    plan: &CyclePlan,
    (times, period): (Vec<f64>, f64),
    columns: &[Vec<Sample>],
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let metrics = plan
        .metrics
        .iter()
        .map(|metric| measure::metric(&columns[metric.slot], period, metric))
        .collect();
    let mut kept = Vec::new();
    if !plan.kept.is_empty() {
        kept.push(times);
        kept.extend(
            plan.kept
                .iter()
                .map(|&slot| columns[slot].iter().map(|s| s.x).collect()),
        );
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
fn modes_along(problem: &mut Problem, plan: &CyclePlan, shot: &Shot) -> Result<Along, NoCycle> {
    if plan.modes == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let (times, states) = states_along(problem, plan, shot, plan.modes)?;
    let points: Vec<(f64, Vec<f64>)> = times.into_iter().zip(states).collect();
    modes_at(problem.fmu, plan, shot.t0, &points)
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
) -> Result<Along, NoCycle> {
    let (mut modes, mut whole) = (Vec::with_capacity(points.len()), Vec::new());
    for (t, x) in points {
        if let Some(linear) = &plan.linear {
            let mut found = linearise(fmu, t0 + t, x.clone(), linear)
                .map_err(|e| e.during("along the cycle"))?;
            found.t = *t;
            modes.push((*t, found.modes.clone()));
            whole.push(found);
        } else {
            let a = jacobian_at(fmu, &plan.exchange, t0 + t, x)?;
            modes.push((*t, floquet::modes(&a, x.len())));
        }
    }
    Ok((modes, whole))
}

/// A = ∂f/∂x at (t, x), row-major, a column per directional derivative.
fn jacobian_at(
    fmu: &mut Instance,
    exchange: &ExchangeStates,
    t: f64,
    x: &[f64],
) -> Result<Vec<f64>, NoCycle> {
    check(fmu.set_state(t, x), "setting the state along the cycle")?;
    block(fmu, &exchange.derivatives, &exchange.states.vrs).map_err(|e| e.during("along the cycle"))
}

/// Model Exchange's states at times into a cycle.
pub type StatesAlong = Vec<(f64, Vec<f64>)>;

/// The steady cycle through the FMU's Co-Simulation interface, its start values and its
/// sensitivities: the record (its modes still to find), the shot for the next point, and
/// Model Exchange's states read at the modes' points along the cycle.
pub fn analyse_through_starts(
    restart: &mut dyn Restart,
    plan: &CyclePlan,
    (run, tolerance): ((f64, f64, f64), f64),
    guess: Option<&Shot>,
    budget: Budget,
) -> Result<(CycleRecord, Shot, StatesAlong), NoCycle> {
    let Way::Starts(starts) = &plan.way else {
        return Err(NoCycle::because(
            "a cycle through start values has none".into(),
        ));
    };
    let mut shooting = ThroughStarts::new(plan, starts, restart, run, (tolerance, budget));
    let found = periodic::find(&mut shooting, guess, tolerance)?;
    let shot = shooting.shot(&found);
    let multipliers = through_starts::multipliers(&found.run, plan, starts)?;
    let state = (found.run.start.y.clone(), found.continued);
    let mut record = record_of(plan, &shot, state, multipliers, tolerance)?;
    if !plan.reads.vrs.is_empty() {
        let times = times_along(shot.search.period, plan.samples);
        let rated: Vec<bool> = (0..plan.reads.vrs.len())
            .map(|slot| {
                plan.metrics.iter().any(|m| {
                    m.slot == slot
                        && m.extremes == crate::metrics::Extremes::Refined
                        && !measure::signs(m.kind).is_empty()
                })
            })
            .collect();
        let rows = shooting.along(&shot.x0, &times, &plan.reads.vrs, &rated)?;
        let columns: Vec<Vec<Sample>> = (0..plan.reads.vrs.len())
            .map(|j| rows.iter().map(|row| row[j]).collect())
            .collect();
        (record.metrics, record.kept) = measured(plan, (times, shot.search.period), &columns);
    }
    let mode_states = if plan.modes == 0 {
        Vec::new()
    } else {
        let times = times_along(shot.search.period, plan.modes);
        let states = &plan.exchange.states.vrs;
        let rows = shooting.along(&shot.x0, &times, states, &vec![false; states.len()])?;
        let values = rows
            .into_iter()
            .map(|row| row.iter().map(|s| s.x).collect());
        times.into_iter().zip(values).collect()
    };
    Ok((record, shot, mode_states))
}

/// ∂unknowns/∂knowns where the FMU stands, row-major, a column per directional
/// derivative.
fn block(fmu: &mut Instance, unknowns: &[u32], knowns: &[u32]) -> Result<Vec<f64>, NoCycle> {
    let (rows, columns) = (unknowns.len(), knowns.len());
    let mut matrix = vec![0.0; rows * columns];
    let (mut seed, mut column) = (vec![0.0; columns], vec![0.0; rows]);
    for j in 0..columns {
        seed.fill(0.0);
        seed[j] = 1.0;
        let s = fmu.get_directional_derivative(unknowns, knowns, &seed, &mut column);
        check(
            s,
            &format!("the directional derivative along the {j}th known"),
        )?;
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
    #[serde(flatten)]
    pub matrices: Matrices,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub modes: Vec<Mode>,
}

/// A linearisation's matrices, each row-major.
#[derive(Clone, Debug, Serialize)]
pub struct Matrices {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub c: Vec<f64>,
    pub d: Vec<f64>,
}

pub fn linearise(
    fmu: &mut Instance,
    t: f64,
    x: Vec<f64>,
    plan: &LinearPlan,
) -> Result<Linearisation, NoCycle> {
    check(fmu.set_state(t, &x), "setting the state")?;
    let (states, derivatives) = (&plan.exchange.states.vrs, &plan.exchange.derivatives);
    let a = block(fmu, derivatives, states).map_err(|e| e.during("A"))?;
    let (inputs, outputs) = (&plan.inputs.vrs, &plan.outputs.vrs);
    let b = block(fmu, derivatives, inputs).map_err(|e| e.during("B"))?;
    let c = block(fmu, outputs, states).map_err(|e| e.during("C"))?;
    let d = block(fmu, outputs, inputs).map_err(|e| e.during("D"))?;
    if let Some(v) = [&a, &b, &c, &d]
        .iter()
        .flat_map(|m| m.iter())
        .find(|v| !v.is_finite())
    {
        return Err(NoCycle::because(format!(
            "the FMU's directional derivatives hold {v}"
        )));
    }
    let modes = floquet::modes(&a, x.len());
    Ok(Linearisation {
        t,
        x,
        states: plan.exchange.states.names.clone(),
        matrices: Matrices { a, b, c, d },
        inputs: plan.inputs.names.clone(),
        outputs: plan.outputs.names.clone(),
        modes,
    })
}
