//! What a plan asks of a steady cycle: the cyclic state and its period of angle, the other
//! states that advance with it, the metrics of outputs over one cycle, and how the
//! monodromy is found; names resolved against the description once, each refusal naming
//! its field.

use serde::Deserialize;

use crate::description::{BaseType, Description};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CycleSpec {
    /// The continuous state whose advance by `period` closes one cycle (a crank angle).
    pub state: String,
    /// The cyclic state's advance over one cycle (2π for a revolution), > 0.
    pub period: f64,
    /// Other states that advance by the same period over one cycle (angles of bodies that
    /// turn with the crank); every other state returns to its value.
    #[serde(default)]
    pub shifted: Vec<String>,
    #[serde(default)]
    pub metrics: Vec<CycleMetricSpec>,
    /// Points along the cycle, evenly spaced in time, at which the metrics' outputs are
    /// read (and the cycle is kept when `keep` asks).
    pub samples: Option<usize>,
    /// `variational` (the FMU's directional derivatives integrated with the states, the
    /// default where the FMU gives them) or `differences` (central differences of runs).
    pub monodromy: Option<String>,
    /// Points along the cycle, evenly spaced in time, at which the state equations are
    /// linearised for the modes (0: none).
    #[serde(default)]
    pub modes: usize,
    /// Variables whose values at the samples are returned with the cycle.
    #[serde(default)]
    pub keep: Vec<String>,
    /// Whether a point's shooting starts from the previous point's cycle (and from its
    /// own transient only if that fails); by default it does.
    pub continuation: Option<bool>,
    /// Whether each of the `modes` points along the cycle also gets its whole
    /// linearisation (A, B, C and D over the Real inputs and outputs).
    #[serde(default)]
    pub linearise: bool,
    /// The cycle through the Co-Simulation interface instead: the start values that set
    /// the state on the section, and the FMU's own sensitivities to them. `state` and
    /// `shifted` then name closing variables.
    pub starts: Option<StartsSpec>,
}

/// What the Co-Simulation path varies and reads: start values (parameters that set the
/// initial state), the value each one's sensitivity slot is set to, the closing variables
/// (outputs whose return after one cycle closes it) and, per start value, the variables
/// that hold ∂closing/∂it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartsSpec {
    pub parameters: Vec<String>,
    pub slots: Vec<(String, i32)>,
    pub closing: Vec<String>,
    pub columns: Vec<Vec<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CycleMetricSpec {
    pub variable: String,
    pub kind: CycleKind,
    /// The harmonic's order, a whole multiple of the cycle's frequency (`harmonic` only).
    pub order: Option<u32>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum CycleKind {
    Min,
    Max,
    PeakAbs,
    PeakToPeak,
    Mean,
    Rms,
    /// The amplitude of the output's component at `order` times the cycle's frequency.
    Harmonic,
}

/// How the monodromy matrix is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Monodromy {
    Variational,
    Differences,
}

/// A cycle's plan with names resolved: indices into Model Exchange's state vector, value
/// references of Real variables.
#[derive(Clone, Debug)]
pub struct CyclePlan {
    pub state: usize,
    pub period: f64,
    pub shifted: Vec<usize>,
    pub state_names: Vec<String>,
    pub states: Vec<u32>,
    pub derivatives: Vec<u32>,
    pub metrics: Vec<(usize, CycleKind, u32)>,
    /// The variables read at the samples: the metrics', then those kept.
    pub reads: Vec<u32>,
    pub read_names: Vec<String>,
    /// The slots of the kept variables among those read, in the order asked.
    pub kept: Vec<usize>,
    pub samples: usize,
    pub monodromy: Monodromy,
    pub modes: usize,
    pub continuation: bool,
    /// The Co-Simulation path's start values and sensitivities (`None`: Model Exchange).
    /// On it `state`, `shifted` and `state_names` are the closing variables', while
    /// `states` and `derivatives` stay Model Exchange's (for the modes, read along the
    /// cycle and linearised on a Model Exchange instance).
    pub through: Option<StartsPlan>,
    /// What the whole linearisation at the modes' points reads (`None`: the modes alone).
    pub linear: Option<LinearPlan>,
}

/// [`StartsSpec`] resolved to value references.
#[derive(Clone, Debug)]
pub struct StartsPlan {
    pub parameters: Vec<u32>,
    pub parameter_names: Vec<String>,
    pub slots: Vec<u32>,
    pub items: Vec<i32>,
    pub closing: Vec<u32>,
    /// Per start value, ∂closing/∂it, a variable per closing variable.
    pub columns: Vec<Vec<u32>>,
}

/// The samples along a cycle where none are asked for: enough that a peak found by a
/// parabola through its three nearest samples is good to about 1e-9 of the amplitude.
pub const DEFAULT_SAMPLES: usize = 2048;
/// The most samples and linearisation points along a cycle.
const MOST_SAMPLES: usize = 1 << 20;
const MOST_MODE_POINTS: usize = 4096;

impl CyclePlan {
    pub fn resolve(mut spec: CycleSpec, description: &Description) -> Result<CyclePlan, String> {
        // Through start values the cycle is closed by their closing variables, whose names
        // the plan's `state_names` then hold.
        let (through, closing) = match spec.starts.take() {
            Some(starts) => {
                let closing = starts.closing.clone();
                (
                    Some(StartsPlan::resolve(starts, description)?),
                    Some(closing),
                )
            }
            None => (None, None),
        };
        if through.is_none() && !description.has_model_exchange {
            return Err(
                "cycle: the steady cycle is found by integrating the FMU's Model \
                        Exchange interface, which this FMU does not have"
                    .into(),
            );
        }
        if description.has_model_exchange
            && description.states.len() != description.continuous_states
        {
            return Err(
                "cycle: the FMU's description does not say which variable each of its \
                        continuous states is (a derivative without its `derivative` attribute)"
                    .into(),
            );
        }
        let (state, shifted) = closed_by(&spec, description, closing.as_deref())?;
        let monodromy = monodromy_of(spec.monodromy.as_deref(), description, through.is_some())?;
        let samples = counts(&spec, description, through.is_some())?;
        let (states, derivatives, mut state_names) = states_of(description);
        if let Some(names) = closing {
            state_names = names;
        }
        let mut plan = CyclePlan {
            state,
            period: spec.period,
            shifted,
            state_names,
            states,
            derivatives,
            metrics: Vec::new(),
            reads: Vec::new(),
            read_names: Vec::new(),
            kept: Vec::new(),
            samples,
            monodromy,
            modes: spec.modes,
            continuation: spec.continuation.unwrap_or(true),
            through,
            linear: linear_of(&spec, description)?,
        };
        for (k, m) in spec.metrics.iter().enumerate() {
            let slot = plan.read(description, &m.variable, &format!("cycle.metrics[{k}]"))?;
            let order = order_of(m, k, samples)?;
            plan.metrics.push((slot, m.kind, order));
        }
        for (k, name) in spec.keep.iter().enumerate() {
            let slot = plan.read(description, name, &format!("cycle.keep[{k}]"))?;
            plan.kept.push(slot);
        }
        Ok(plan)
    }

    /// The slot of a Real variable among those read at the samples.
    fn read(
        &mut self,
        description: &Description,
        name: &str,
        field: &str,
    ) -> Result<usize, String> {
        let variable = description
            .variable(name)
            .map_err(|e| format!("{field}: {e}"))?;
        if variable.base_type != BaseType::Real {
            return Err(format!(
                "{field}: {name:?} is of type {}; a cycle's metrics and kept variables are Real",
                variable.fmi_type
            ));
        }
        if let Some(slot) = self.read_names.iter().position(|n| n == name) {
            return Ok(slot);
        }
        self.reads.push(variable.value_reference);
        self.read_names.push(name.to_string());
        Ok(self.reads.len() - 1)
    }
}

impl StartsPlan {
    /// The Co-Simulation path's variables, each refusal naming its field: the start values
    /// are Real parameters, the closing variables Real outputs, each slot's sensitivities
    /// Real variables, one per closing variable.
    fn resolve(starts: StartsSpec, description: &Description) -> Result<StartsPlan, String> {
        can_run_through(&starts, description)?;
        let n = starts.parameters.len();
        let mut plan = StartsPlan {
            parameters: Vec::with_capacity(n),
            parameter_names: starts.parameters.clone(),
            slots: Vec::with_capacity(n),
            items: Vec::with_capacity(n),
            closing: Vec::new(),
            columns: Vec::with_capacity(n),
        };
        for (k, name) in starts.parameters.iter().enumerate() {
            let field = format!("cycle.starts[{k}]");
            if starts.parameters[..k].contains(name) {
                return Err(format!("{field}: {name:?} is named twice"));
            }
            plan.parameters
                .push(real_variable(description, name, &field, Some("parameter"))?);
        }
        for (k, (name, item)) in starts.slots.iter().enumerate() {
            let v = description
                .variable(name)
                .map_err(|e| format!("cycle.starts[{k}]: its slot: {e}"))?;
            plan.slots.push(v.value_reference);
            plan.items.push(*item);
        }
        for (k, name) in starts.closing.iter().enumerate() {
            let field = format!("cycle.closing[{k}]");
            plan.closing
                .push(real_variable(description, name, &field, Some("output"))?);
        }
        for (k, column) in starts.columns.iter().enumerate() {
            let field = format!("cycle.starts[{k}]");
            if column.len() != starts.closing.len() {
                return Err(format!(
                    "{field}: {} sensitivities for {} closing variables",
                    column.len(),
                    starts.closing.len()
                ));
            }
            let vrs = column
                .iter()
                .map(|name| real_variable(description, name, &field, None))
                .collect::<Result<Vec<_>, _>>()?;
            plan.columns.push(vrs);
        }
        Ok(plan)
    }
}

/// Whether a cycle through start values can run on this FMU: it has Co-Simulation with
/// output derivatives (the closing variables' rates at the cycle's end), a slot and a
/// column of sensitivities for each start value, and as many start values as the state
/// on the section has free coordinates, where Model Exchange says how many that is.
fn can_run_through(starts: &StartsSpec, description: &Description) -> Result<(), String> {
    if description.model_identifier.is_none() {
        return Err(
            "cycle.starts: the cycle through the start values runs the FMU's \
                    Co-Simulation interface, which this FMU does not have"
                .into(),
        );
    }
    if description.max_output_derivative_order < 1 {
        return Err(
            "cycle.starts: the cycle through the start values reads the closing \
                    variables' rates at its end (fmi2GetRealOutputDerivatives), which this \
                    FMU does not give"
                .into(),
        );
    }
    let n = starts.parameters.len();
    if n == 0 || starts.slots.len() != n || starts.columns.len() != n {
        return Err(format!(
            "cycle.starts: {n} start values need as many sensitivity slots and columns, got \
             {} and {}",
            starts.slots.len(),
            starts.columns.len()
        ));
    }
    let states = description.states.len();
    if description.has_model_exchange && states != n + 1 {
        return Err(format!(
            "cycle.starts: the state on the section has {} free coordinates (the FMU's \
             {states} continuous states less the cyclic one), which {n} start values cannot \
             set",
            states.saturating_sub(1)
        ));
    }
    Ok(())
}

/// The value reference of the Real variable `name`, of `causality` where one is asked.
fn real_variable(
    description: &Description,
    name: &str,
    field: &str,
    causality: Option<&str>,
) -> Result<u32, String> {
    let v = description
        .variable(name)
        .map_err(|e| format!("{field}: {e}"))?;
    if v.base_type != BaseType::Real {
        return Err(format!(
            "{field}: {name:?} is of type {}, not Real",
            v.fmi_type
        ));
    }
    match causality {
        Some(c) if v.causality != c => Err(format!(
            "{field}: {name:?} has causality {}, not {c}",
            v.causality
        )),
        _ => Ok(v.value_reference),
    }
}

/// The position of `name` among the closing variables.
fn closing_index(
    description: &Description,
    names: &[String],
    name: &str,
    field: &str,
) -> Result<usize, String> {
    description
        .variable(name)
        .map_err(|e| format!("{field}: {e}"))?;
    names.iter().position(|n| n == name).ok_or_else(|| {
        format!(
            "{field}: {name:?} is not among the variables whose sensitivities to the start \
             values the FMU gives (those that close the cycle: {})",
            names.join(", ")
        )
    })
}

/// What the whole linearisation at the modes' points reads, where the spec asks for it.
fn linear_of(spec: &CycleSpec, description: &Description) -> Result<Option<LinearPlan>, String> {
    if !spec.linearise {
        return Ok(None);
    }
    if spec.modes == 0 {
        return Err(
            "cycle.linearise: the linearisations are made at the modes' points: ask \
                    for cycle.modes > 0"
                .into(),
        );
    }
    LinearPlan::of(description)
        .map(Some)
        .map_err(|e| format!("cycle.linearise: {e}"))
}

/// Where the cycle is closed: the cyclic state and those shifted with it, as positions in
/// Model Exchange's states, or among the `closing` variables through start values.
fn closed_by(
    spec: &CycleSpec,
    description: &Description,
    closing: Option<&[String]>,
) -> Result<(usize, Vec<usize>), String> {
    let locate = |name: &str, field: &str| match closing {
        Some(names) => closing_index(description, names, name, field),
        None => state_index(description, name, field),
    };
    let state = locate(&spec.state, "cycle.state")?;
    if !(spec.period.is_finite() && spec.period > 0.0) {
        return Err(format!(
            "cycle.period: must be a finite number > 0 (the cyclic state's advance over \
             one cycle), got {}",
            spec.period
        ));
    }
    let mut shifted = Vec::new();
    for (k, name) in spec.shifted.iter().enumerate() {
        let index = locate(name, &format!("cycle.shifted[{k}]"))?;
        if index == state || shifted.contains(&index) {
            return Err(format!("cycle.shifted[{k}]: {name:?} is named twice"));
        }
        shifted.push(index);
    }
    Ok((state, shifted))
}

/// The samples along the cycle, and the bounds of the samples and the modes' points.
fn counts(spec: &CycleSpec, description: &Description, through: bool) -> Result<usize, String> {
    let samples = spec.samples.unwrap_or(DEFAULT_SAMPLES);
    if !(8..=MOST_SAMPLES).contains(&samples) {
        return Err(format!(
            "cycle.samples: must be between 8 and {MOST_SAMPLES}, got {samples}"
        ));
    }
    if spec.modes > MOST_MODE_POINTS {
        return Err(format!(
            "cycle.modes: at most {MOST_MODE_POINTS} points along the cycle, got {}",
            spec.modes
        ));
    }
    if through
        && spec.modes > 0
        && !(description.has_model_exchange && description.exchange_directional_derivatives)
    {
        return Err(
            "cycle.modes: the modes along the cycle linearise the state equations \
                        on the FMU's Model Exchange interface, whose directional derivatives \
                        this FMU does not give"
                .into(),
        );
    }
    Ok(samples)
}

/// How the monodromy is found: as asked, or by the variational equations where the FMU
/// gives directional derivatives; `through` start values, from the sensitivities (the
/// value is then unread).
fn monodromy_of(
    asked: Option<&str>,
    description: &Description,
    through: bool,
) -> Result<Monodromy, String> {
    let exact = description.exchange_directional_derivatives;
    if through {
        return match asked {
            None => Ok(Monodromy::Differences),
            Some(_) => Err(
                "cycle.monodromy: through the start values the monodromy comes \
                            from the FMU's own sensitivities"
                    .into(),
            ),
        };
    }
    match asked {
        None if exact => Ok(Monodromy::Variational),
        None | Some("differences") => Ok(Monodromy::Differences),
        Some("variational") if exact => Ok(Monodromy::Variational),
        Some("variational") => Err("cycle.monodromy: \"variational\" needs the FMU's \
                                    directional derivatives under Model Exchange, which it \
                                    does not give"
            .into()),
        Some(other) => Err(format!(
            "cycle.monodromy: must be \"variational\" or \"differences\", got {other:?}"
        )),
    }
}

/// A metric's harmonic order: a harmonic's, between 1 and half the samples; 0 for the
/// other kinds, which take none.
fn order_of(metric: &CycleMetricSpec, k: usize, samples: usize) -> Result<u32, String> {
    match (metric.kind, metric.order) {
        (CycleKind::Harmonic, Some(order)) if order >= 1 && 2 * order as usize <= samples => {
            Ok(order)
        }
        (CycleKind::Harmonic, order) => Err(format!(
            "cycle.metrics[{k}].order: a harmonic needs a whole order between 1 and half the \
             samples ({}), got {order:?}",
            samples / 2
        )),
        (_, None) => Ok(0),
        (_, Some(_)) => Err(format!(
            "cycle.metrics[{k}].order: only a harmonic has an order"
        )),
    }
}

/// The position of the continuous state `name` in Model Exchange's state vector.
fn state_index(description: &Description, name: &str, field: &str) -> Result<usize, String> {
    let variable = description
        .variable(name)
        .map_err(|e| format!("{field}: {e}"))?;
    description
        .states
        .iter()
        .position(|s| s.value_reference == variable.value_reference)
        .ok_or_else(|| {
            let names: Vec<String> = description
                .states
                .iter()
                .map(|s| name_of(description, s.value_reference))
                .collect();
            format!(
                "{field}: {name:?} is not a continuous state of the FMU (its states: {})",
                names.join(", ")
            )
        })
}

/// The continuous states' and their derivatives' value references, and the states' names.
fn states_of(description: &Description) -> (Vec<u32>, Vec<u32>, Vec<String>) {
    let states = &description.states;
    (
        states.iter().map(|s| s.value_reference).collect(),
        states.iter().map(|s| s.derivative).collect(),
        states
            .iter()
            .map(|s| name_of(description, s.value_reference))
            .collect(),
    )
}

fn name_of(description: &Description, value_reference: u32) -> String {
    description
        .variables
        .iter()
        .find(|v| v.value_reference == value_reference)
        .map_or_else(|| format!("#{value_reference}"), |v| v.name.clone())
}

/// What a linearisation reads: the states and their derivatives, the Real inputs and the
/// Real outputs, by value reference, with their names.
#[derive(Clone, Debug)]
pub struct LinearPlan {
    pub states: Vec<u32>,
    pub derivatives: Vec<u32>,
    pub inputs: Vec<u32>,
    pub outputs: Vec<u32>,
    pub state_names: Vec<String>,
    pub input_names: Vec<String>,
    pub output_names: Vec<String>,
}

impl LinearPlan {
    pub fn of(description: &Description) -> Result<LinearPlan, String> {
        if !description.has_model_exchange || !description.exchange_directional_derivatives {
            return Err(
                "a linearisation reads the FMU's directional derivatives under Model \
                        Exchange, which this FMU does not give"
                    .into(),
            );
        }
        if description.states.len() != description.continuous_states {
            return Err(
                "the FMU's description does not say which variable each of its \
                        continuous states is"
                    .into(),
            );
        }
        let real = |causality: &str| -> (Vec<u32>, Vec<String>) {
            description
                .variables
                .iter()
                .filter(|v| v.causality == causality && v.base_type == BaseType::Real)
                .map(|v| (v.value_reference, v.name.clone()))
                .unzip()
        };
        let (inputs, input_names) = real("input");
        let (outputs, output_names) = real("output");
        let (states, derivatives, state_names) = states_of(description);
        Ok(LinearPlan {
            states,
            derivatives,
            state_names,
            inputs,
            outputs,
            input_names,
            output_names,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn mechanism() -> Description {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../modelDescription");
        Description::read(&root).unwrap()
    }

    fn spec(json: &str) -> CycleSpec {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn resolves_the_states_and_reads() {
        let plan = CyclePlan::resolve(
            spec(
                r#"{"state": "loop_angle", "period": 6.283185307179586, "shifted": ["phi1"],
                    "metrics": [{"variable": "rod_force", "kind": "harmonic", "order": 2},
                                {"variable": "omega2", "kind": "mean"}],
                    "keep": ["omega2", "phi3"]}"#,
            ),
            &mechanism(),
        )
        .unwrap();
        assert_eq!((plan.state, plan.shifted.as_slice()), (1, &[0][..]));
        assert_eq!(plan.monodromy, Monodromy::Variational);
        assert_eq!(plan.read_names, ["rod_force", "omega2", "phi3"]);
        // A kept variable read for a metric too is kept from the metric's slot.
        assert_eq!(plan.kept, [1, 2]);
        assert_eq!(plan.metrics[0].2, 2);
    }

    #[test]
    fn refuses_each_mistake_by_its_field() {
        let d = mechanism();
        let refused = |json: &str| CyclePlan::resolve(spec(json), &d).unwrap_err();
        let cases = [
            (
                r#"{"state": "phi2", "period": 1.0}"#,
                "cycle.state: \"phi2\" is not a continuous state",
            ),
            (
                r#"{"state": "nothing", "period": 1.0}"#,
                "cycle.state: the FMU has no variable",
            ),
            (
                r#"{"state": "loop_angle", "period": 0.0}"#,
                "cycle.period: must be a finite number > 0",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "shifted": ["loop_angle"]}"#,
                "cycle.shifted[0]: \"loop_angle\" is named twice",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "monodromy": "exact"}"#,
                "cycle.monodromy: must be",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "samples": 4}"#,
                "cycle.samples: must be between 8",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "metrics": [{"variable": "rod_force", "kind": "harmonic"}]}"#,
                "cycle.metrics[0].order: a harmonic needs",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "metrics": [{"variable": "rod_force", "kind": "max", "order": 1}]}"#,
                "cycle.metrics[0].order: only a harmonic",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "keep": ["linkage_class"]}"#,
                "cycle.keep[0]: \"linkage_class\" is of type Enumeration",
            ),
            (
                r#"{"state": "loop_angle", "period": 1.0, "linearise": true}"#,
                "cycle.linearise: the linearisations are made at the modes' points",
            ),
        ];
        for (json, said) in cases {
            let message = refused(json);
            assert!(message.starts_with(said), "{json}: {message}");
        }
        let mut without = d.clone();
        without.has_model_exchange = false;
        let message =
            CyclePlan::resolve(spec(r#"{"state": "loop_angle", "period": 1.0}"#), &without)
                .unwrap_err();
        assert!(message.contains("Model Exchange"), "{message}");
        without = d.clone();
        without.exchange_directional_derivatives = false;
        let plan = CyclePlan::resolve(spec(r#"{"state": "loop_angle", "period": 1.0}"#), &without)
            .unwrap();
        assert_eq!(plan.monodromy, Monodromy::Differences);
    }

    /// The Co-Simulation path's spec, as fmusweep writes it from the FMU's offer.
    fn through(starts: &[&str], extra: &str) -> CycleSpec {
        let closing = [
            "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
        ];
        let slots: Vec<String> = (1..=starts.len())
            .map(|k| format!(r#"["sensitivity_{k}.parameter", 7]"#))
            .collect();
        let columns: Vec<String> = (1..=starts.len())
            .map(|k| {
                let names: Vec<String> = closing
                    .iter()
                    .map(|c| format!(r#""sensitivity_{k}.{c}""#))
                    .collect();
                format!("[{}]", names.join(", "))
            })
            .collect();
        spec(&format!(
            r#"{{"state": "phi2", "period": 6.283185307179586, "shifted": ["phi1"], {extra}
                "starts": {{"parameters": {starts:?}, "slots": [{}], "closing": {closing:?},
                            "columns": [{}]}}}}"#,
            slots.join(", "),
            columns.join(", ")
        ))
    }

    const STARTS: [&str; 5] = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"];

    #[test]
    fn resolves_the_start_values_and_the_closing_variables() {
        let d = mechanism();
        let plan = CyclePlan::resolve(through(&STARTS, r#""modes": 4,"#), &d).unwrap();
        let starts = plan.through.as_ref().unwrap();
        assert_eq!((plan.state, plan.shifted.as_slice()), (1, &[0][..]));
        assert_eq!(plan.state_names[1], "phi2");
        let vr = |name: &str| d.variable(name).unwrap().value_reference;
        assert_eq!(starts.parameters[0], vr("twist12_0"));
        assert_eq!(starts.closing[7], vr("omega4"));
        assert_eq!(starts.columns[4][1], vr("sensitivity_5.phi2"));
        assert_eq!(starts.slots[2], vr("sensitivity_3.parameter"));
        // The modes are Model Exchange's, read along the cycle.
        assert_eq!(plan.states.len(), 6);
    }

    #[test]
    fn refuses_each_mistake_of_the_start_values_by_its_field() {
        let d = mechanism();
        let refused = |spec: CycleSpec| CyclePlan::resolve(spec, &d).unwrap_err();
        let message = refused(through(&STARTS[..4], ""));
        assert!(
            message.starts_with("cycle.starts: the state on the section has 5 free"),
            "{message}"
        );
        let message = refused(through(&STARTS, r#""monodromy": "variational","#));
        assert!(
            message.starts_with("cycle.monodromy: through the start values"),
            "{message}"
        );
        let message = refused(through(
            &["twist12_0", "twist34_0", "J9", "omega2_0", "omega4_0"],
            "",
        ));
        assert!(
            message.starts_with("cycle.starts[2]: the FMU has no variable"),
            "{message}"
        );
        let message = refused(through(
            &["twist12_0", "twist12_0", "omega1_0", "omega2_0", "omega4_0"],
            "",
        ));
        assert!(
            message.starts_with("cycle.starts[1]: \"twist12_0\" is named twice"),
            "{message}"
        );
        let mut wrong = through(&STARTS, "");
        wrong.state = "loop_angle".into();
        let message = refused(wrong);
        assert!(
            message.starts_with("cycle.state: \"loop_angle\" is not among the variables"),
            "{message}"
        );
        let mut without = d.clone();
        without.model_identifier = None;
        let message = CyclePlan::resolve(through(&STARTS, ""), &without).unwrap_err();
        assert!(
            message.starts_with("cycle.starts: the cycle through the start values runs"),
            "{message}"
        );
        without = d.clone();
        without.exchange_directional_derivatives = false;
        let message = CyclePlan::resolve(through(&STARTS, r#""modes": 2,"#), &without).unwrap_err();
        assert!(
            message.starts_with("cycle.modes: the modes along the cycle"),
            "{message}"
        );
    }
}
