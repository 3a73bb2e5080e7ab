//! One parameter point through one instance: reset, set up, initialise, step to the stop
//! time, measure. The instance is made once and reset between points; after an error it
//! is freed and made again (the library itself stays loaded).

use std::time::Instant;

mod cycle;

use crate::coupling::CouplingRecord;
use crate::cycle::{Continuation, CycleRecord};
use crate::description::Description;
use crate::fmi::Status;
use crate::messages;
use crate::plan::{type_group, ByType, Plan};
use crate::target::{Running, Target};
use crate::unit::Unit;

/// How a point ended, as the results table spells it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Ok,
    /// The FMU discarded a step (either version's Discard): it could not complete it.
    Discard,
    /// The FMU returned Error or Fatal, or broke a rule of the standard.
    Error,
    /// Over the per-point wall-time budget.
    Timeout,
    /// No steady cycle: none exists, or the shooting did not find it (the message says).
    NoCycle,
}

impl Outcome {
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Ok => "ok",
            Outcome::Discard => "discard",
            Outcome::Error => "error",
            Outcome::Timeout => "timeout",
            Outcome::NoCycle => "no_cycle",
        }
    }
}

pub struct PointResult {
    pub outcome: Outcome,
    pub message: String,
    pub metrics: Vec<Option<f64>>,
    /// The last communication point reached.
    pub t_end: f64,
    pub steps: u64,
    /// The events the FMU met (FMI 3.0 in event mode), each handled by the master.
    pub events: u64,
    pub wall_s: f64,
    /// Rows of (t, variables…), flattened.
    pub series: Vec<f64>,
    /// What the steps reported of the coupling (a system with a coupling tolerance).
    pub coupling: Option<CouplingRecord>,
    /// The steady cycle, when the plan asks for one.
    pub cycle: Option<CycleRecord>,
}

/// The values one request sets at every point, by type, with the point's own columns.
pub struct Assignments {
    vr: ByType,
    /// For each value reference in `vr` (reals, then integers, then booleans): the column
    /// of the point's row it takes, or the fixed value.
    sources: Vec<Source>,
    names: Vec<String>,
    real: Vec<f64>,
    integer: Vec<i32>,
    boolean: Vec<i32>,
}

#[derive(Clone, Copy)]
enum Source {
    Column(usize),
    Fixed(f64),
}

impl Assignments {
    /// The fixed settings of the plan, overridden by the point's columns `names`.
    pub fn new(description: &Description, plan: &Plan, names: &[String]) -> Result<Self, String> {
        let mut entries: Vec<(String, Source)> = plan
            .fixed
            .iter()
            .filter(|(name, _)| !names.contains(name))
            .map(|(name, value)| (name.clone(), Source::Fixed(*value)))
            .collect();
        entries.extend(
            names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), Source::Column(i))),
        );
        let mut groups: [Vec<(u32, Source, String)>; 3] = Default::default();
        for (name, source) in entries {
            let v = description.variable(&name)?;
            if !matches!(v.causality.as_str(), "parameter" | "input") {
                return Err(format!(
                    "{name} is a variable of causality {}, not a parameter or input",
                    v.causality
                ));
            }
            groups[type_group(v)?].push((v.value_reference, source, name));
        }
        let [real, integer, boolean] = groups;
        let vr = ByType {
            real: real.iter().map(|e| e.0).collect(),
            integer: integer.iter().map(|e| e.0).collect(),
            boolean: boolean.iter().map(|e| e.0).collect(),
        };
        let all = real.into_iter().chain(integer).chain(boolean);
        let (sources, names): (Vec<_>, Vec<_>) = all.map(|(_, s, n)| (s, n)).unzip();
        Ok(Assignments {
            real: vec![0.0; vr.real.len()],
            integer: vec![0; vr.integer.len()],
            boolean: vec![0; vr.boolean.len()],
            vr,
            sources,
            names,
        })
    }

    /// Fill the typed buffers from a row; an Integer or Boolean that is not a whole
    /// number (or 0/1) is refused by name.
    fn fill(&mut self, row: &[f64]) -> Result<(), String> {
        let (nr, ni) = (self.real.len(), self.integer.len());
        for (k, source) in self.sources.iter().enumerate() {
            let x = match *source {
                Source::Column(c) => row[c],
                Source::Fixed(x) => x,
            };
            if !x.is_finite() {
                return Err(format!("{} = {x} is not finite", self.names[k]));
            }
            if k < nr {
                self.real[k] = x;
            } else if k < nr + ni {
                if x.fract() != 0.0 || x.abs() > i32::MAX as f64 {
                    return Err(format!(
                        "{} = {x} is not a whole number (an Integer)",
                        self.names[k]
                    ));
                }
                self.integer[k - nr] = x as i32;
            } else {
                if x != 0.0 && x != 1.0 {
                    return Err(format!("{} = {x} is not 0 or 1 (a Boolean)", self.names[k]));
                }
                self.boolean[k - nr - ni] = x as i32;
            }
        }
        Ok(())
    }

    fn apply(&mut self, instance: &mut Running) -> Status {
        let s = instance.set_real(&self.vr.real, &self.real);
        if !s.proceeds() {
            return s;
        }
        let s = instance.set_integer(&self.vr.integer, &self.integer);
        if !s.proceeds() {
            return s;
        }
        instance.set_boolean(&self.vr.boolean, &self.boolean)
    }
}

/// The loaded FMU (or system) and its one instance, kept across points and requests.
pub struct Runner {
    target: Target,
    instance: Option<Running>,
    reals: Vec<f64>,
    integers: Vec<i32>,
    booleans: Vec<i32>,
    read: Vec<f64>,
    /// The rated variables' rates at the communication point, and which were read there.
    rates: Vec<f64>,
    wanted: Vec<bool>,
    /// The last steady cycles found: the next point's shooting starts from them.
    continuation: Continuation,
    /// The FMU's Model Exchange interface beside its Co-Simulation one, where a cycle
    /// through the start values finds its modes, and its instance.
    exchange: Option<Target>,
    exchange_instance: Option<Running>,
}

/// A failed FMI call: the outcome it maps to and what the FMU said.
struct Stop(Outcome, String);

/// `call` (by its FMI 2.0 name, which `instance` names as its version does, with `at`
/// after it) returned `status`, which stops the point.
fn failed_in(instance: &Running, call: &str, at: &str, status: Status) -> Stop {
    failed(&format!("{}{at}", instance.call_name(call)), status)
}

fn failed(call: &str, status: Status) -> Stop {
    let outcome = if status == Status::Discard {
        Outcome::Discard
    } else {
        Outcome::Error
    };
    Stop(outcome, format!("{call} returned {status:?}"))
}

/// A fresh instance of `target` for a new point: the one kept in `slot` reset, or a new
/// one.
fn fresh_instance<'a>(
    target: &Target,
    slot: &'a mut Option<Running>,
) -> Result<&'a mut Running, Stop> {
    if slot.as_mut().is_some_and(|i| i.reset().proceeds()) {
        return Ok(slot.as_mut().expect("kept above"));
    }
    *slot = None;
    let instance = target.instantiate().map_err(|m| Stop(Outcome::Error, m))?;
    Ok(slot.insert(instance))
}

/// Set up the experiment at `tolerance`, enter initialisation and set the point's values
/// (filled) and inputs at the start.
fn set_up(
    instance: &mut Running,
    plan: &Plan,
    assignments: &mut Assignments,
    tolerance: Option<f64>,
) -> Result<(), Stop> {
    let s = instance.setup_experiment(tolerance, plan.start, plan.stop);
    if !s.proceeds() {
        return Err(failed_in(instance, "fmi2SetupExperiment", "", s));
    }
    let s = instance.enter_initialization_mode();
    if !s.proceeds() {
        return Err(failed_in(instance, "fmi2EnterInitializationMode", "", s));
    }
    let s = assignments.apply(instance);
    if !s.proceeds() {
        return Err(failed("setting the point's values", s));
    }
    for input in &plan.inputs {
        let s = instance.set_real(&[input.value_reference], &[input.at(plan.start)]);
        if !s.proceeds() {
            return Err(failed("setting an input", s));
        }
    }
    Ok(())
}

impl Runner {
    pub fn new(target: Target) -> Self {
        Runner {
            target,
            instance: None,
            reals: Vec::new(),
            integers: Vec::new(),
            booleans: Vec::new(),
            read: Vec::new(),
            rates: Vec::new(),
            wanted: Vec::new(),
            continuation: Continuation::default(),
            exchange: None,
            exchange_instance: None,
        }
    }

    pub fn has_exchange(&self) -> bool {
        self.exchange.is_some()
    }

    /// The Model Exchange target a cycle through start values finds its modes on.
    pub fn set_exchange(&mut self, target: Option<Target>) {
        self.exchange = target;
        self.exchange_instance = None;
    }

    /// A new plan: no cycle of the last one guides the next point's shooting.
    pub fn forget_cycle(&mut self) {
        self.continuation.forget();
    }

    /// Reset, set up, set the point's values and inputs at the start; with `initialise`,
    /// also leave initialisation mode.
    fn prepare(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        row: &[f64],
        initialise: bool,
    ) -> Result<(), Stop> {
        assignments.fill(row).map_err(|m| Stop(Outcome::Error, m))?;
        let instance = fresh_instance(&self.target, &mut self.instance)?;
        set_up(instance, plan, assignments, plan.tolerance)?;
        if initialise {
            let s = instance.exit_initialization_mode();
            if !s.proceeds() {
                return Err(failed_in(instance, "fmi2ExitInitializationMode", "", s));
            }
        }
        Ok(())
    }

    /// Size the read buffers for the plan (once per point, not per step).
    fn size_buffers(&mut self, plan: &Plan) {
        let r = &plan.reads;
        self.reals.resize(r.real.len(), 0.0);
        self.integers.resize(r.integer.len(), 0);
        self.booleans.resize(r.boolean.len(), 0);
        self.read.resize(r.len(), 0.0);
        self.rates.resize(plan.rated.len(), 0.0);
        self.wanted.resize(plan.rated.len(), false);
    }

    /// The rates at `t` of the rated variables that a metric wants at this sample (marked
    /// in `self.wanted`).
    fn read_rates(&mut self, plan: &Plan, t: f64) -> Result<(), Stop> {
        self.wanted.fill(false);
        for m in &plan.metrics {
            if let Some(r) = m.rate {
                self.wanted[r] |= m.accumulator.wants_rate(t, self.read[m.slot]);
            }
        }
        let instance = self.instance.as_mut().expect("prepared");
        for (r, vr) in plan.rated.iter().enumerate() {
            if !self.wanted[r] {
                continue;
            }
            let rate = &mut self.rates[r..=r];
            let s = instance.get_rates(&[*vr], &plan.rate_states, rate);
            if !s.proceeds() {
                let call = match plan.rate_states.is_empty() {
                    true => "fmi2GetRealOutputDerivatives",
                    false => "fmi2GetDirectionalDerivative",
                };
                return Err(failed_in(instance, call, "", s));
            }
            if !rate[0].is_finite() {
                return Err(Stop(
                    Outcome::Error,
                    format!(
                        "the FMU reported a rate of {} at t = {t} with a successful status",
                        rate[0]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Read every metric and series variable into `self.read` (buffers sized).
    fn read(&mut self, plan: &Plan) -> Result<(), Stop> {
        let r = &plan.reads;
        let instance = self.instance.as_mut().expect("prepared");
        for (s, call) in [
            (instance.get_real(&r.real, &mut self.reals), "fmi2GetReal"),
            (
                instance.get_integer(&r.integer, &mut self.integers),
                "fmi2GetInteger",
            ),
            (
                instance.get_boolean(&r.boolean, &mut self.booleans),
                "fmi2GetBoolean",
            ),
        ] {
            if !s.proceeds() {
                return Err(failed_in(instance, call, "", s));
            }
        }
        let values = self
            .reals
            .iter()
            .copied()
            .chain(self.integers.iter().map(|&i| i as f64))
            .chain(
                self.booleans
                    .iter()
                    .map(|&b| if b != 0 { 1.0 } else { 0.0 }),
            );
        for (slot, x) in self.read.iter_mut().zip(values) {
            *slot = x;
        }
        Ok(())
    }

    fn record(&mut self, plan: &mut Plan, k: u64, result: &mut PointResult) -> Result<(), Stop> {
        self.read(plan)?;
        let t = plan.time(k);
        if let Some(i) = self.read.iter().position(|x| !x.is_finite()) {
            return Err(Stop(
                Outcome::Error,
                format!(
                    "the FMU reported {} = {} at t = {t} with a successful status",
                    plan.read_names[i], self.read[i]
                ),
            ));
        }
        self.read_rates(plan, t)?;
        for m in plan.metrics.iter_mut() {
            let rate = m.rate.filter(|&r| self.wanted[r]).map(|r| self.rates[r]);
            m.accumulator.push(t, self.read[m.slot], rate);
        }
        if let Some((slots, every)) = &plan.series {
            if k.is_multiple_of(*every) || k == plan.n_steps {
                result.series.push(t);
                result.series.extend(slots.iter().map(|&s| self.read[s]));
            }
        }
        result.t_end = t;
        Ok(())
    }

    fn simulate(
        &mut self,
        plan: &mut Plan,
        assignments: &mut Assignments,
        row: &[f64],
        result: &mut PointResult,
        started: Instant,
    ) -> Result<(), Stop> {
        self.prepare(plan, assignments, row, true)?;
        self.size_buffers(plan);
        self.record(plan, 0, result)?;
        let mut inputs_now: Vec<(f64, f64)> = plan
            .inputs
            .iter()
            .map(|i| (i.at(plan.start), 0.0))
            .collect();
        // A system with a coupling tolerance takes the tables as they are: each input moves
        // along its segment's slope, and its steps end on every breakpoint. Anything else
        // has each input set at a step's start and held over the step.
        let along = self
            .instance
            .as_ref()
            .is_some_and(|i| i.coupling().is_some());
        let mut ends = Vec::new();
        for k in 0..plan.n_steps {
            let (t, t_next) = (plan.time(k), plan.time(k + 1));
            ends.clear();
            if along {
                let margin = 1e-9 * plan.step;
                for input in &plan.inputs {
                    ends.extend_from_slice(input.breakpoints_within(t, t_next, margin));
                }
                ends.sort_by(f64::total_cmp);
                ends.dedup();
            }
            ends.push(t_next);
            let mut a = t;
            for &b in &ends {
                let instance = self.instance.as_mut().expect("prepared");
                set_inputs(instance, plan, a, along, &mut inputs_now)?;
                let s = instance.do_step(a, b - a);
                if !s.proceeds() {
                    let at = format!(" at t = {a}");
                    return Err(failed_in(instance, "fmi2DoStep", &at, s));
                }
                a = b;
            }
            result.steps = k + 1;
            self.record(plan, k + 1, result)?;
            if let Some(budget) = plan.timeout_s {
                if started.elapsed().as_secs_f64() > budget {
                    return Err(Stop(
                        Outcome::Timeout,
                        format!("over the budget of {budget} s per point at t = {t_next}"),
                    ));
                }
            }
        }
        Ok(())
    }

    pub fn run_point(
        &mut self,
        plan: &mut Plan,
        assignments: &mut Assignments,
        row: &[f64],
    ) -> PointResult {
        let started = Instant::now();
        messages::take();
        for m in plan.metrics.iter_mut() {
            m.accumulator.clear();
        }
        let mut result = PointResult {
            outcome: Outcome::Ok,
            message: String::new(),
            metrics: Vec::new(),
            t_end: plan.start,
            steps: 0,
            events: 0,
            wall_s: 0.0,
            series: Vec::new(),
            coupling: None,
            cycle: None,
        };
        let ended = if plan.cycle.is_some() {
            self.steady_cycle(plan, assignments, row, &mut result, started)
        } else {
            self.simulate(plan, assignments, row, &mut result, started)
        };
        result.coupling = self.instance.as_ref().and_then(Unit::coupling);
        result.events = self.instance.as_ref().map_or(0, Unit::events);
        let said = messages::take();
        match ended {
            Ok(()) if plan.cycle.is_some() => result.message = said,
            Ok(()) => {
                result.metrics = plan.metrics.iter().map(|m| m.accumulator.value()).collect();
                result.message = said;
            }
            Err(Stop(outcome, what)) => {
                result.outcome = outcome;
                result.message = if said.is_empty() {
                    what
                } else {
                    format!("{what}: {said}")
                };
                result.metrics = vec![None; plan.metric_count()];
                // An instance that failed may be unusable; make a new one next time.
                if outcome == Outcome::Error {
                    self.instance = None;
                }
            }
        }
        result.wall_s = started.elapsed().as_secs_f64();
        result
    }

    /// Set the point's values in initialisation mode and report what the FMU says,
    /// without running: the sweep's check of a design against the FMU's own rules.
    pub fn check_point(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        row: &[f64],
    ) -> (Outcome, String) {
        messages::take();
        let checked = self.prepare(plan, assignments, row, false);
        let said = messages::take();
        match checked {
            Ok(()) => (Outcome::Ok, String::new()),
            Err(Stop(outcome, what)) => {
                self.instance = None;
                (
                    outcome,
                    if said.is_empty() {
                        what
                    } else {
                        format!("{what}: {said}")
                    },
                )
            }
        }
    }

    /// The plainest master loop over the same points, for the benchmark: reset,
    /// initialise, then fmi2DoStep and one read of the same variables per step; no
    /// metrics, no checks beyond the status. Returns the seconds it took.
    pub fn bare(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        rows: &[Vec<f64>],
    ) -> Result<f64, String> {
        let started = Instant::now();
        for row in rows {
            self.prepare(plan, assignments, row, true)
                .map_err(|Stop(_, m)| m)?;
            self.size_buffers(plan);
            let instance = self.instance.as_mut().expect("prepared");
            for k in 0..plan.n_steps {
                let (t, t_next) = (plan.time(k), plan.time(k + 1));
                if !instance.do_step(t, t_next - t).proceeds() {
                    return Err(format!("fmi2DoStep failed at t = {t}"));
                }
                instance.get_real(&plan.reads.real, &mut self.reals);
                instance.get_integer(&plan.reads.integer, &mut self.integers);
            }
        }
        Ok(started.elapsed().as_secs_f64())
    }
}

/// Each input at `t`, set where its value changed (a set restarts many FMUs' integrators);
/// with `along`, its slope after `t` too, where that changed. `now` holds what was set.
fn set_inputs(
    instance: &mut Running,
    plan: &Plan,
    t: f64,
    along: bool,
    now: &mut [(f64, f64)],
) -> Result<(), Stop> {
    for (input, (value, slope)) in plan.inputs.iter().zip(now.iter_mut()) {
        let u = input.at(t);
        if u.to_bits() != value.to_bits() {
            let s = instance.set_real(&[input.value_reference], &[u]);
            if !s.proceeds() {
                return Err(failed("setting an input", s));
            }
            *value = u;
        }
        if !along {
            continue;
        }
        let du = input.slope_after(t);
        if du.to_bits() != slope.to_bits() {
            let s = instance.set_input_slope(input.value_reference, du);
            if !s.proceeds() {
                return Err(failed("setting an input's slope", s));
            }
            *slope = du;
        }
    }
    Ok(())
}
