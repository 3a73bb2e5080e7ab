//! The run plan that every point of a sweep shares: the time grid, the fixed settings,
//! the input signals, and what to measure. Names are resolved against the model
//! description once, so that the per-point loop works on value references only.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::cycle_plan::{CyclePlan, CycleSpec};
use crate::description::{BaseType, Description, Variable};
use crate::metrics::{Accumulator, Kind, WINDOW_SLACK};

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
    /// The steady cycle: found by shooting instead of run to `stop` (which bounds the
    /// transient it starts from), its metrics over one cycle.
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
    pub variable: String,
    pub kind: Kind,
    pub from: Option<f64>,
    pub to: Option<f64>,
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
    /// Read at every communication point: the variables of the metrics and the series.
    pub reads: ByType,
    pub read_names: Vec<String>,
    /// Per metric: its position in the read buffer (reals, then integers, then booleans).
    pub metrics: Vec<(usize, Accumulator)>,
    pub series: Option<(Vec<usize>, u64)>,
    pub timeout_s: Option<f64>,
    pub cycle: Option<CyclePlan>,
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
    metrics: Vec<(usize, Accumulator)>,
    series: Option<(Vec<usize>, u64)>,
}

impl Reads {
    /// One read slot per distinct variable of the metrics and the series, by type, the
    /// metrics' windows checked against the run's (start, stop, step).
    fn resolve(
        spec: &PlanSpec,
        description: &Description,
        (start, stop, step): (f64, f64, f64),
    ) -> Result<Self, String> {
        let mut by_type = ByType::default();
        let mut read_vars: Vec<&Variable> = Vec::new();
        let mut slot_of = |name: &str| -> Result<usize, String> {
            let variable = description.variable(name)?;
            if let Some(i) = read_vars.iter().position(|v| v.name == name) {
                return Ok(i);
            }
            by_type.push(variable)?;
            read_vars.push(variable);
            Ok(read_vars.len() - 1)
        };
        let slack = WINDOW_SLACK * step;
        let mut metrics = Vec::new();
        for m in &spec.metrics {
            let (from, to) = (m.from.unwrap_or(start), m.to.unwrap_or(stop));
            if !(from.is_finite() && to.is_finite() && from <= to) {
                return Err(format!(
                    "metric of {}: the window [{from}, {to}] is not an interval",
                    m.variable
                ));
            }
            metrics.push((
                slot_of(&m.variable)?,
                Accumulator::new(m.kind, from, to, slack),
            ));
        }
        let series = match &spec.series {
            None => None,
            Some(s) if s.every == 0 => return Err("series.every must be ≥ 1".into()),
            Some(s) => Some((
                s.variables
                    .iter()
                    .map(|n| slot_of(n))
                    .collect::<Result<Vec<_>, _>>()?,
                s.every,
            )),
        };
        // Slots were numbered in first-use order; the buffer is laid out by type.
        let layout = buffer_layout(&read_vars);
        let mut names = vec![String::new(); read_vars.len()];
        for (slot, v) in read_vars.iter().enumerate() {
            names[layout[slot]] = v.name.clone();
        }
        Ok(Reads {
            by_type,
            names,
            metrics: metrics
                .into_iter()
                .map(|(slot, acc)| (layout[slot], acc))
                .collect(),
            series: series
                .map(|(slots, every)| (slots.iter().map(|&s| layout[s]).collect(), every)),
        })
    }
}

fn finite(what: &str, x: f64) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{what} must be finite, got {x}"))
    }
}

impl Plan {
    pub fn resolve(mut spec: PlanSpec, description: &Description) -> Result<Plan, String> {
        let (start, stop, step, n_steps) = time_grid(&spec)?;
        if let Some(tol) = spec.tolerance {
            if !(tol.is_finite() && tol > 0.0) {
                return Err(format!("tolerance must be finite and > 0, got {tol}"));
            }
        }
        for (name, value) in &spec.fixed {
            description.variable(name)?;
            finite(name, *value)?;
        }
        let inputs = std::mem::take(&mut spec.inputs)
            .into_iter()
            .map(|(name, table)| resolve_input(description, &name, table))
            .collect::<Result<Vec<_>, _>>()?;
        let reads = Reads::resolve(&spec, description, (start, stop, step))?;
        let cycle = match spec.cycle.take() {
            None => None,
            Some(cycle) => {
                if let Some(input) = inputs.iter().find(|i| i.table.times.len() > 1) {
                    return Err(format!(
                        "cycle: a steady cycle needs constant inputs; input {:?} is a table \
                         of {} points",
                        description
                            .variables
                            .iter()
                            .find(|v| v.value_reference == input.value_reference)
                            .map_or("?", |v| v.name.as_str()),
                        input.table.times.len()
                    ));
                }
                Some(CyclePlan::resolve(cycle, description)?)
            }
        };
        Ok(Plan {
            start,
            stop,
            step,
            n_steps,
            tolerance: spec.tolerance,
            fixed: spec.fixed.into_iter().collect(),
            inputs,
            reads: reads.by_type,
            read_names: reads.names,
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
