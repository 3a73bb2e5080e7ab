//! The run plan that every point of a sweep shares: the time grid, the fixed settings,
//! the input signals, what to measure, and the interface it runs through. Names are
//! resolved against the model description once, so that the per-point loop works on value
//! references only; every mistake of a plan is refused at once, by its field.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::cycle_plan::{CyclePlan, CycleSpec};
use crate::description::{BaseType, Description, Variable};
use crate::fmi::Interface;
use crate::metrics::{Accumulator, Extremes, Kind, WINDOW_SLACK};
use crate::refusals::Refusals;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanSpec {
    pub start: f64,
    pub stop: f64,
    pub step: f64,
    pub tolerance: Option<f64>,
    #[serde(default)]
    pub fixed: BTreeMap<String, f64>,
    #[serde(default)]
    pub inputs: BTreeMap<String, TableSpec>,
    #[serde(default)]
    pub metrics: Vec<MetricSpec>,
    pub series: Option<SeriesSpec>,
    pub timeout_s: Option<f64>,
    /// `co_simulation` or `model_exchange`: the interface a single FMU runs through (by
    /// default its co-simulation one where it has both).
    pub interface: Option<String>,
    /// `dop853` (the default) or `radau5`: what integrates a Model Exchange FMU.
    pub integrator: Option<String>,
    /// The steady cycle: found instead of run to `stop` (which bounds the transient it
    /// starts from), its metrics over one cycle.
    pub cycle: Option<CycleSpec>,
}

/// A piecewise-linear signal, held beyond its ends; one point makes a constant.
#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    pub times: Vec<f64>,
    pub values: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricSpec {
    /// The field the metric's refusals name (the client's own).
    pub field: Option<String>,
    pub variable: String,
    pub kind: Kind,
    pub from: Option<f64>,
    pub to: Option<f64>,
    /// `refined` (the default) or `sampled`: how its extremes are found.
    pub extremes: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeriesSpec {
    pub variables: Vec<String>,
    /// Record every this many communication steps (the first point is always recorded).
    pub every: u64,
}

/// Value references grouped by the FMI setter or getter they need.
#[derive(Debug, Default, Clone)]
pub struct ByType {
    pub real: Vec<u32>,
    pub integer: Vec<u32>,
    pub boolean: Vec<u32>,
}

impl ByType {
    pub fn len(&self) -> usize {
        self.real.len() + self.integer.len() + self.boolean.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn push(&mut self, variable: &Variable) -> Result<(), String> {
        let list = match type_group(variable)? {
            0 => &mut self.real,
            1 => &mut self.integer,
            _ => &mut self.boolean,
        };
        list.push(variable.value_reference);
        Ok(())
    }
}

/// Which FMI accessor a variable needs: 0 Real, 1 Integer (and Enumeration), 2 Boolean.
/// Buffers that hold several types keep this order.
pub fn type_group(variable: &Variable) -> Result<usize, String> {
    match variable.base_type {
        BaseType::Real => Ok(0),
        BaseType::Integer | BaseType::Enumeration => Ok(1),
        BaseType::Boolean => Ok(2),
        BaseType::String | BaseType::Unsupported => Err(format!(
            "{}: {} variables are not supported",
            variable.name, variable.fmi_type
        )),
    }
}

pub struct Input {
    pub value_reference: u32,
    pub table: TableSpec,
}

impl Input {
    /// The slope of the signal just after t: its table segment's, 0 beyond the table.
    pub fn slope_after(&self, t: f64) -> f64 {
        let (times, values) = (&self.table.times, &self.table.values);
        let after = times.partition_point(|&ti| ti <= t);
        if after == 0 || after == times.len() {
            return 0.0;
        }
        (values[after] - values[after - 1]) / (times[after] - times[after - 1])
    }

    /// The table's times strictly between a and b, farther than `margin` from both.
    pub fn breakpoints_within(&self, a: f64, b: f64, margin: f64) -> &[f64] {
        let times = &self.table.times;
        let first = times.partition_point(|&ti| ti <= a + margin);
        let last = times.partition_point(|&ti| ti < b - margin);
        &times[first..last.max(first)]
    }

    /// The signal at t, linear between table points and held beyond them.
    pub fn at(&self, t: f64) -> f64 {
        let (times, values) = (&self.table.times, &self.table.values);
        let after = times.partition_point(|&ti| ti <= t);
        if after == 0 {
            return values[0];
        }
        if after == times.len() {
            return values[after - 1];
        }
        let (t0, t1) = (times[after - 1], times[after]);
        let (v0, v1) = (values[after - 1], values[after]);
        v0 + (v1 - v0) * ((t - t0) / (t1 - t0))
    }
}

pub struct Plan {
    pub start: f64,
    pub stop: f64,
    pub step: f64,
    pub n_steps: u64,
    pub tolerance: Option<f64>,
    pub fixed: Vec<(String, f64)>,
    pub inputs: Vec<Input>,
    /// The interface a single FMU runs through (`None` for a system).
    pub interface: Option<Interface>,
    /// Read at every communication point: the variables of the metrics and the series.
    pub reads: ByType,
    pub read_names: Vec<String>,
    /// The Real variables whose rates (first time derivatives) are read where a metric
    /// that refines its extremes is in its window: the FMU's output derivatives under
    /// co-simulation, its directional derivatives along the flow of these continuous
    /// states under Model Exchange.
    pub rated: Vec<u32>,
    pub rate_states: Vec<u32>,
    pub metrics: Vec<Metric>,
    pub series: Option<(Vec<usize>, u64)>,
    pub timeout_s: Option<f64>,
    pub cycle: Option<CyclePlan>,
}

/// A metric of a run: its position in the read buffer (reals, then integers, then
/// booleans), its variable's among those rated where its extremes are refined from rates,
/// and what it has gathered.
pub struct Metric {
    pub slot: usize,
    pub rate: Option<usize>,
    pub accumulator: Accumulator,
}

/// Start, stop, step and the number of communication steps, each checked.
fn time_grid(spec: &PlanSpec) -> Result<(f64, f64, f64, u64), String> {
    let (start, stop, step) = (
        finite("start", spec.start)?,
        finite("stop", spec.stop)?,
        finite("step", spec.step)?,
    );
    if step <= 0.0 || stop <= start {
        return Err(format!(
            "need step > 0 and stop > start, got start {start}, stop {stop}, step {step}"
        ));
    }
    let steps = (stop - start) / step;
    let n_steps = steps.round();
    if (steps - n_steps).abs() > 1e-6 || n_steps < 1.0 {
        return Err(format!(
            "stop − start = {} is not a whole number of communication steps of {step}",
            stop - start
        ));
    }
    Ok((start, stop, step, n_steps as u64))
}

/// What a plan reads at every communication point, and where the metrics and the
/// series find it in the read buffer.
struct Reads {
    by_type: ByType,
    names: Vec<String>,
    rated: Vec<u32>,
    metrics: Vec<Metric>,
    series: Option<(Vec<usize>, u64)>,
}

/// The variables read at every communication point, a slot each in first-use order.
struct Slots<'d> {
    description: &'d Description,
    by_type: ByType,
    variables: Vec<&'d Variable>,
}

impl Slots<'_> {
    /// The slot of variable `name`, a new one where it is not read yet.
    fn of(&mut self, name: &str) -> Result<usize, String> {
        let variable = self.description.variable(name)?;
        if let Some(i) = self.variables.iter().position(|v| v.name == name) {
            return Ok(i);
        }
        self.by_type.push(variable)?;
        self.variables.push(variable);
        Ok(self.variables.len() - 1)
    }
}

/// A metric of the plan (its refusals under its field, `metrics[k]` by default), its
/// window checked against the run's (start, stop); its variable's rate read where `rated`
/// holds it (a metric that refines its extremes, where the unit gives rates).
fn metric_of(
    (k, m): (usize, &MetricSpec),
    (start, stop, slack): (f64, f64, f64),
    slots: &mut Slots,
    rated: Option<&mut Vec<u32>>,
    refusals: &mut Refusals,
) -> Option<Metric> {
    let field = m.field.clone().unwrap_or_else(|| format!("metrics[{k}]"));
    let (from, to) = (m.from.unwrap_or(start), m.to.unwrap_or(stop));
    if !(from.is_finite() && to.is_finite() && from <= to) {
        let rule = format!("the window [{from}, {to}] is not an interval");
        refusals.refuse(format!("{field}.from"), rule);
    }
    let extremes = match &m.extremes {
        None => Some(Extremes::default()),
        Some(e) => refusals.note(&format!("{field}.extremes"), Extremes::named(e)),
    };
    let slot = refusals.note(&format!("{field}.variable"), slots.of(&m.variable))?;
    let accumulator = Accumulator::new(m.kind, extremes?, from, to, slack);
    let variable = slots.variables[slot];
    let rate = rated
        .filter(|_| accumulator.refines() && variable.base_type == BaseType::Real)
        .map(|rated| {
            let vr = variable.value_reference;
            rated.iter().position(|&r| r == vr).unwrap_or_else(|| {
                rated.push(vr);
                rated.len() - 1
            })
        });
    Some(Metric {
        slot,
        rate,
        accumulator,
    })
}

impl Reads {
    /// One read slot per distinct variable of the metrics and the series, by type, the
    /// metrics' windows checked against the run's (start, stop, step); the rates of the
    /// refined metrics' variables read where `rates` says the unit gives them.
    fn resolve(
        spec: &PlanSpec,
        description: &Description,
        (start, stop, step): (f64, f64, f64),
        rates: bool,
        refusals: &mut Refusals,
    ) -> Reads {
        let mut slots = Slots {
            description,
            by_type: ByType::default(),
            variables: Vec::new(),
        };
        let window = (start, stop, WINDOW_SLACK * step);
        let mut rated: Vec<u32> = Vec::new();
        let mut metrics: Vec<Metric> = (spec.metrics.iter().enumerate())
            .filter_map(|m| {
                let rated = rates.then_some(&mut rated);
                metric_of(m, window, &mut slots, rated, refusals)
            })
            .collect();
        let series = match &spec.series {
            None => None,
            Some(s) if s.every == 0 => {
                refusals.refuse("series.every", "must be ≥ 1");
                None
            }
            Some(s) => {
                let found: Vec<Option<usize>> = (s.variables.iter())
                    .map(|n| refusals.note("series.variables", slots.of(n)))
                    .collect();
                let found: Option<Vec<usize>> = found.into_iter().collect();
                found.map(|v| (v, s.every))
            }
        };
        // Slots were numbered in first-use order; the buffer is laid out by type.
        let layout = buffer_layout(&slots.variables);
        let mut names = vec![String::new(); slots.variables.len()];
        for (slot, v) in slots.variables.iter().enumerate() {
            names[layout[slot]] = v.name.clone();
        }
        for metric in &mut metrics {
            metric.slot = layout[metric.slot];
        }
        Reads {
            by_type: slots.by_type,
            names,
            rated,
            metrics,
            series: series
                .map(|(slots, every)| (slots.iter().map(|&s| layout[s]).collect(), every)),
        }
    }
}

fn finite(what: &str, x: f64) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{what} must be finite, got {x}"))
    }
}

/// The interface a plan runs a single FMU through (`loaded`, the session's default, is
/// `None` for a system): a steady cycle's own, else the one asked, else the default; a
/// cycle's interface and the one asked must agree.
fn interface_of(
    asked: Option<&str>,
    cycle: Option<Interface>,
    loaded: Option<Interface>,
    refusals: &mut Refusals,
) -> Option<Interface> {
    let asked =
        asked.and_then(|name| refusals.note("scenario.interface", Interface::from_name(name)));
    let Some(default) = loaded else {
        if asked == Some(Interface::ModelExchange) {
            refusals.refuse(
                "scenario.interface",
                "a coupled system runs its components' co-simulation interfaces",
            );
        }
        return None;
    };
    let Some(wanted) = cycle else {
        return Some(asked.unwrap_or(default));
    };
    if asked.is_some_and(|a| a != wanted) {
        refusals.refuse(
            "scenario.interface",
            format!(
                "this steady cycle is found through the {} interface",
                wanted.name()
            ),
        );
    }
    Some(wanted)
}

impl Plan {
    /// The plan of `spec` against `description`, run through the interface it asks for
    /// or the one `loaded` (a single FMU's default; `None` for a system); or every
    /// mistake of it.
    pub fn resolve(
        mut spec: PlanSpec,
        description: &Description,
        loaded: Option<Interface>,
    ) -> Result<Plan, Refusals> {
        let mut refusals = Refusals::default();
        let grid = refusals.note("scenario", time_grid(&spec));
        if let Some(tol) = spec.tolerance {
            if !(tol.is_finite() && tol > 0.0) {
                let rule = format!("must be finite and > 0, got {tol}");
                refusals.refuse("scenario.tolerance", rule);
            }
        }
        for (name, value) in &spec.fixed {
            let field = format!("scenario.parameters.{name}");
            let checked = description
                .variable(name)
                .and_then(|_| finite(name, *value));
            refusals.note(&field, checked);
        }
        let inputs: Vec<Input> = std::mem::take(&mut spec.inputs)
            .into_iter()
            .filter_map(|(name, table)| {
                let field = format!("scenario.inputs.{name}");
                refusals.note(&field, resolve_input(description, &name, table))
            })
            .collect();
        // The way a cycle is found fixes its interface, checked even where the cycle's own
        // table has mistakes.
        let cycle_interface = spec.cycle.as_ref().map(|c| match c.starts {
            Some(_) => Interface::CoSimulation,
            None => Interface::ModelExchange,
        });
        let cycle = cycle_of(&mut spec, description, (&inputs, loaded), &mut refusals);
        let interface = interface_of(
            spec.interface.as_deref(),
            cycle_interface,
            loaded,
            &mut refusals,
        );
        let (rates, rate_states) = rates_of(interface, description);
        let (start, stop, step, n_steps) = grid.unwrap_or((0.0, 1.0, 1.0, 1));
        let reads = Reads::resolve(
            &spec,
            description,
            (start, stop, step),
            rates,
            &mut refusals,
        );
        if !refusals.is_empty() {
            return Err(refusals);
        }
        Ok(Plan {
            start,
            stop,
            step,
            n_steps,
            tolerance: spec.tolerance,
            fixed: spec.fixed.into_iter().collect(),
            inputs,
            interface,
            reads: reads.by_type,
            read_names: reads.names,
            rated: reads.rated,
            rate_states,
            metrics: reads.metrics,
            series: reads.series,
            timeout_s: spec.timeout_s,
            cycle,
        })
    }

    /// How many metrics a point's result holds: the cycle's where the plan has one.
    pub fn metric_count(&self) -> usize {
        self.cycle
            .as_ref()
            .map_or(self.metrics.len(), |c| c.metrics.len())
    }

    /// The numbers in a row of a point's series (t and the variables), 0 without one: the
    /// series' variables, or the cycle's kept ones.
    pub fn series_width(&self) -> usize {
        match (&self.series, &self.cycle) {
            (Some((slots, _)), _) => slots.len() + 1,
            (None, Some(cycle)) if !cycle.kept.is_empty() => cycle.kept.len() + 1,
            _ => 0,
        }
    }

    /// The communication point k: start + k·step, and exactly `stop` for the last.
    #[inline]
    pub fn time(&self, k: u64) -> f64 {
        if k >= self.n_steps {
            self.stop
        } else {
            self.start + k as f64 * self.step
        }
    }
}

/// The plan's steady cycle, where it asks for one: found on one FMU (`loaded` is its
/// default interface; `None` for a system), with constant inputs, on Model Exchange by
/// DOP853 (which integrates its variational equations).
fn cycle_of(
    spec: &mut PlanSpec,
    description: &Description,
    (inputs, loaded): (&[Input], Option<Interface>),
    refusals: &mut Refusals,
) -> Option<CyclePlan> {
    let asked = spec.cycle.take()?;
    constant_inputs(inputs, description, refusals);
    if loaded.is_none() {
        refusals.refuse(
            "cycle",
            "a coupled system has no Model Exchange interface: a steady cycle is found on \
             one FMU",
        );
        return None;
    }
    let cycle = CyclePlan::resolve(&asked, description, refusals)?;
    let on_exchange = cycle.way.interface() == Interface::ModelExchange;
    if on_exchange && spec.integrator.as_deref() == Some("radau5") {
        refusals.refuse(
            "scenario.integrator",
            "a steady cycle on Model Exchange is integrated with its variational equations \
             by DOP853",
        );
    }
    Some(cycle)
}

/// Whether the unit gives its outputs' rates, and where they come from Model Exchange's
/// directional derivatives, the continuous states they are taken along.
fn rates_of(interface: Option<Interface>, description: &Description) -> (bool, Vec<u32>) {
    match interface {
        Some(Interface::CoSimulation) => (description.max_output_derivative_order >= 1, vec![]),
        Some(Interface::ModelExchange)
            if description.exchange_directional_derivatives
                && description.states.len() == description.continuous_states =>
        {
            let states = description
                .states
                .iter()
                .map(|s| s.value_reference)
                .collect();
            (true, states)
        }
        _ => (false, Vec::new()),
    }
}

/// A steady cycle needs constant inputs: a table of several points is refused.
fn constant_inputs(inputs: &[Input], description: &Description, refusals: &mut Refusals) {
    for input in inputs.iter().filter(|i| i.table.times.len() > 1) {
        let name = description
            .variables
            .iter()
            .find(|v| v.value_reference == input.value_reference)
            .map_or("?", |v| v.name.as_str());
        refusals.refuse(
            format!("scenario.inputs.{name}"),
            format!(
                "a steady cycle needs constant inputs; this is a table of {} points",
                input.table.times.len()
            ),
        );
    }
}

/// Where each first-use slot lands in a buffer of reals, then integers, then booleans.
fn buffer_layout(vars: &[&Variable]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..vars.len()).collect();
    // Stable: first-use order within a type. (Strings were refused when the slot was made.)
    order.sort_by_key(|&i| type_group(vars[i]).unwrap_or(2));
    let mut layout = vec![0; vars.len()];
    for (position, &slot) in order.iter().enumerate() {
        layout[slot] = position;
    }
    layout
}

fn resolve_input(description: &Description, name: &str, table: TableSpec) -> Result<Input, String> {
    let variable = description.variable(name)?;
    if !(variable.causality == "input" || variable.is_tunable())
        || variable.base_type != BaseType::Real
    {
        return Err(format!(
            "{name} is neither a Real input nor a tunable Real parameter of the FMU"
        ));
    }
    if table.times.is_empty() || table.times.len() != table.values.len() {
        return Err(format!(
            "input {name}: times and values must be non-empty and of equal length"
        ));
    }
    if table
        .times
        .iter()
        .chain(&table.values)
        .any(|x| !x.is_finite())
        || table.times.windows(2).any(|w| w[1] <= w[0])
    {
        return Err(format!(
            "input {name}: values must be finite and times strictly increasing"
        ));
    }
    Ok(Input {
        value_reference: variable.value_reference,
        table,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn input_tables_interpolate_and_hold() {
        let input = Input {
            value_reference: 0,
            table: TableSpec {
                times: vec![1.0, 3.0],
                values: vec![10.0, 20.0],
            },
        };
        assert_eq!(input.at(0.0), 10.0);
        assert_eq!(input.at(2.0), 15.0);
        assert_eq!(input.at(3.0), 20.0);
        assert_eq!(input.at(9.0), 20.0);
        // The slope just after a time, and the breakpoints within a step.
        assert_eq!((input.slope_after(0.0), input.slope_after(1.0)), (0.0, 5.0));
        assert_eq!((input.slope_after(2.9), input.slope_after(3.0)), (5.0, 0.0));
        let within = |a, b| input.breakpoints_within(a, b, 1e-9).to_vec();
        assert_eq!(within(0.5, 3.5), vec![1.0, 3.0]);
        assert_eq!(within(1.0, 3.0), Vec::<f64>::new());
        assert_eq!(within(3.5, 9.0), Vec::<f64>::new());
    }

    #[test]
    fn buffer_layout_puts_reals_first() {
        let v = |t| Variable {
            name: String::new(),
            value_reference: 0,
            base_type: t,
            causality: "output".into(),
            variability: "continuous".into(),
            start: None,
            min: None,
            max: None,
            unit: None,
            declared_type: None,
            description: None,
            fmi_type: String::new(),
            derivative_of: None,
            items: Default::default(),
        };
        let (i, r1, b, r2) = (
            v(BaseType::Integer),
            v(BaseType::Real),
            v(BaseType::Boolean),
            v(BaseType::Real),
        );
        assert_eq!(buffer_layout(&[&i, &r1, &b, &r2]), vec![2, 0, 3, 1]);
    }
}
