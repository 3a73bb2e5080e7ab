//! What a plan asks of a steady cycle: the cyclic variable and its advance over one cycle,
//! the others that advance with it, the metrics of outputs over one cycle, and which way
//! the cycle is found (shooting on Model Exchange, or through the Co-Simulation
//! interface's start values); names resolved against the description once. Every rule of
//! the `[cycle]` table lives here, and every mistake is refused at once, by its field.

use serde_json::Value;

use crate::description::{BaseType, Description};
use crate::fmi::Interface;
use crate::metrics::Extremes;
use crate::refusals::{nearest, shown, Fields, Refusals};

/// What a client sends of a steady cycle: the user's `[cycle]` table as written, the
/// metrics over one cycle (each with the field it is refused under), the start values'
/// variables where the cycle is found through them (the client reads them off the FMU's
/// offer of sensitivities), and whether each of the modes' points gets its whole
/// linearisation.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CycleSpec {
    pub table: Value,
    #[serde(default)]
    pub metrics: Vec<Value>,
    pub starts: Option<Value>,
    #[serde(default)]
    pub linearise: bool,
}

impl CycleSpec {
    /// Whether the spec asks for modes through the start values (which then need a Model
    /// Exchange instance beside the Co-Simulation one).
    pub fn modes_through_starts(&self) -> bool {
        let modes = self.table.get("modes").and_then(Value::as_u64).unwrap_or(0);
        self.starts.is_some() && modes > 0
    }
}

/// The metrics of an output over one cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

const CYCLE_KINDS: [(&str, CycleKind); 7] = [
    ("min", CycleKind::Min),
    ("max", CycleKind::Max),
    ("peak_abs", CycleKind::PeakAbs),
    ("peak_to_peak", CycleKind::PeakToPeak),
    ("mean", CycleKind::Mean),
    ("rms", CycleKind::Rms),
    ("harmonic", CycleKind::Harmonic),
];

/// How the monodromy matrix is found on Model Exchange.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Monodromy {
    Variational,
    Differences,
}

/// Which way the cycle is found, with what that way needs.
#[derive(Clone, Debug)]
pub enum Way {
    /// Shooting on the Model Exchange interface, the monodromy found as it says.
    Exchange(Monodromy),
    /// Newton's method on the Co-Simulation interface's runs from start values, with the
    /// FMU's own sensitivities to them.
    Starts(StartsPlan),
}

impl Way {
    /// The interface the cycle is found through.
    pub fn interface(&self) -> Interface {
        match self {
            Way::Exchange(_) => Interface::ModelExchange,
            Way::Starts(_) => Interface::CoSimulation,
        }
    }
}

/// A metric over one cycle: the slot of its variable among those read, its kind, its
/// harmonic's order (0 for the other kinds) and how its extremes are found.
#[derive(Clone, Copy, Debug)]
pub struct CycleMetric {
    pub slot: usize,
    pub kind: CycleKind,
    pub order: u32,
    pub extremes: Extremes,
}

/// Model Exchange's continuous states with their names, their derivatives, and whether
/// the FMU gives directional derivatives there.
#[derive(Clone, Debug, Default)]
pub struct ExchangeStates {
    pub states: Named,
    pub derivatives: Vec<u32>,
    pub directional: bool,
}

/// A cycle's plan with names resolved: positions among the variables the cycle closes on
/// (Model Exchange's states, or the closing variables through the start values), value
/// references of Real variables.
#[derive(Clone, Debug)]
pub struct CyclePlan {
    pub state: usize,
    pub advance: f64,
    pub shifted: Vec<usize>,
    pub way: Way,
    /// Model Exchange's states, where the modes are found (empty without the interface).
    pub exchange: ExchangeStates,
    pub metrics: Vec<CycleMetric>,
    /// The variables read at the samples: the metrics', then those kept.
    pub reads: Named,
    /// The slots of the kept variables among those read, in the order asked.
    pub kept: Vec<usize>,
    pub samples: usize,
    pub modes: usize,
    pub continuation: bool,
    /// What the whole linearisation at the modes' points reads (`None`: the modes alone).
    pub linear: Option<LinearPlan>,
}

impl CyclePlan {
    /// The names of the variables the cycle closes on, in the order `state` and `shifted`
    /// count them.
    pub fn names(&self) -> &[String] {
        match &self.way {
            Way::Exchange(_) => &self.exchange.states.names,
            Way::Starts(starts) => &starts.closing.names,
        }
    }
}

/// The start values' variables, resolved: the parameters, the slot each one's sensitivity
/// is set in and the value it is set to, the closing variables (outputs whose return after
/// one cycle closes it) and, per start value, the variables that hold ∂closing/∂it.
#[derive(Clone, Debug)]
pub struct StartsPlan {
    pub parameters: Named,
    pub slots: Vec<u32>,
    pub items: Vec<i32>,
    pub closing: Named,
    pub columns: Vec<Vec<u32>>,
}

/// The samples along a cycle where none are asked for: enough that a peak found by a
/// parabola through its three nearest samples is good to about 1e-9 of the amplitude.
pub const DEFAULT_SAMPLES: usize = 2048;
/// The most samples and linearisation points along a cycle.
const MOST_SAMPLES: usize = 1 << 20;
const MOST_MODE_POINTS: usize = 4096;

/// The `[cycle]` table's own fields, each read and checked.
struct Table {
    state: Option<String>,
    advance: Option<f64>,
    shifted: Vec<String>,
    samples: usize,
    monodromy: Option<String>,
    modes: usize,
    keep: Vec<String>,
    continuation: bool,
}

impl Table {
    fn read(value: &Value, refusals: &mut Refusals) -> Option<Table> {
        let mut fields = Fields::of(value, "cycle", refusals)?;
        let state = fields.text("state");
        let state = fields.required("state", "the variable whose advance closes a cycle", state);
        let mut advance = fields.number("advance");
        // A table that still says `period` hears of the new name alone.
        match fields.get("period") {
            Some(period) => {
                let rule = renamed_period(period.as_f64());
                fields.refuse("period", rule);
            }
            None => {
                let what = "the cyclic variable's advance over one cycle (2π for a revolution)";
                advance = fields.required("advance", what, advance);
            }
        }
        if let Some(a) = advance.filter(|a| *a <= 0.0) {
            fields.refuse(
                "advance",
                format!("must be > 0 (the cyclic variable's advance over one cycle), got {a}"),
            );
        }
        let table = Table {
            state,
            advance: advance.filter(|a| *a > 0.0),
            shifted: fields.names("shifted").unwrap_or_default(),
            samples: fields
                .whole("samples", 8, MOST_SAMPLES)
                .unwrap_or(DEFAULT_SAMPLES),
            monodromy: fields.text("monodromy"),
            modes: fields.whole("modes", 0, MOST_MODE_POINTS).unwrap_or(0),
            keep: fields.names("keep").unwrap_or_default(),
            continuation: fields.boolean("continuation").unwrap_or(true),
        };
        if let Some(m) = &table.monodromy {
            if !["variational", "differences"].contains(&m.as_str()) {
                fields.refuse(
                    "monodromy",
                    format!("must be \"variational\" or \"differences\", got {m:?}"),
                );
            }
        }
        fields.finish(&[]);
        Some(table)
    }
}

/// What a table that still says `period` is told: the new name, and that it is in the
/// state's unit where its value looks like degrees.
fn renamed_period(value: Option<f64>) -> String {
    let said = "unknown field: it is called advance now, the state's advance over one cycle in \
                its own unit (2π = 6.283185307179586 for a revolution in rad)";
    match value.filter(|v| looks_like_degrees(*v)) {
        Some(v) => format!("{said}; {v} looks like degrees"),
        None => said.to_string(),
    }
}

/// A whole number of right angles, in degrees: 90, 180, 360, 720, …
fn looks_like_degrees(value: f64) -> bool {
    value >= 90.0 && value % 90.0 == 0.0
}

/// An advance in degrees where the state is an angle in rad: refused with the radians.
fn refuse_degrees(table: &Table, description: &Description, refusals: &mut Refusals) {
    let (Some(advance), Some(state)) = (table.advance, table.state.as_deref()) else {
        return;
    };
    let in_rad = description
        .variable(state)
        .is_ok_and(|v| v.unit.as_deref() == Some("rad"));
    if in_rad && looks_like_degrees(advance) {
        refusals.refuse(
            "cycle.advance",
            format!(
                "{advance} rad is {:.3} revolutions of {state}: the advance is in its unit, rad \
                 (2π = 6.283185307179586 for one revolution); {advance} looks like degrees",
                advance / std::f64::consts::TAU
            ),
        );
    }
}

impl CyclePlan {
    /// The plan of `spec` against `description`, or every mistake of it.
    pub fn resolve(
        spec: &CycleSpec,
        description: &Description,
        refusals: &mut Refusals,
    ) -> Option<CyclePlan> {
        let before = refusals.0.len();
        let table = Table::read(&spec.table, refusals);
        let way = way_of(spec, table.as_ref(), description, refusals);
        let exchange = exchange_states(description);
        let (Some(table), Some(way)) = (table, way) else {
            return None;
        };
        let closing: &[String] = match &way {
            Way::Exchange(_) => &exchange.states.names,
            Way::Starts(starts) => &starts.closing.names,
        };
        let (state, shifted) = closed_by(&table, closing, &way, description, refusals);
        refuse_degrees(&table, description, refusals);
        check_modes(&table, &way, description, refusals);
        let linear = linear_of(spec.linearise, table.modes, description, refusals);
        let mut plan = CyclePlan {
            state: state.unwrap_or(0),
            advance: table.advance.unwrap_or(1.0),
            shifted,
            way,
            exchange,
            metrics: Vec::new(),
            reads: Named::default(),
            kept: Vec::new(),
            samples: table.samples,
            modes: table.modes,
            continuation: table.continuation,
            linear,
        };
        for (k, metric) in spec.metrics.iter().enumerate() {
            plan.metric(metric, k, description, refusals);
        }
        for (k, name) in table.keep.iter().enumerate() {
            let field = format!("cycle.keep[{k}]");
            if let Some(slot) = refusals.note(&field, plan.read(description, name)) {
                plan.kept.push(slot);
            }
        }
        (refusals.0.len() == before && state.is_some() && table.advance.is_some()).then_some(plan)
    }

    /// A metric over one cycle, as the client sends it: its field, variable, kind, order
    /// and extremes.
    fn metric(
        &mut self,
        value: &Value,
        k: usize,
        description: &Description,
        refusals: &mut Refusals,
    ) {
        let field = value
            .get("field")
            .and_then(Value::as_str)
            .map_or_else(|| format!("cycle.metrics[{k}]"), str::to_string);
        let Some(mut fields) = Fields::of(value, &field, refusals) else {
            return;
        };
        fields.get("field");
        let variable = fields.text("variable");
        let variable = fields.required("variable", "the variable measured", variable);
        let kind = fields.text("kind").and_then(|kind| {
            let found = CYCLE_KINDS.iter().find(|(name, _)| *name == kind);
            if found.is_none() {
                let names: Vec<&str> = CYCLE_KINDS.iter().map(|(n, _)| *n).collect();
                fields.refuse(
                    "kind",
                    format!(
                        "must be one of {} over a steady cycle, got {kind:?}",
                        names.join(", ")
                    ),
                );
            }
            found.map(|(_, kind)| *kind)
        });
        let kind = fields.required("kind", "what is measured over the cycle", kind);
        let order = fields.get("order").cloned();
        let extremes = fields
            .text("extremes")
            .and_then(|e: String| {
                let field = format!("{field}.extremes");
                fields.refusals().note(&field, Extremes::named(&e))
            })
            .unwrap_or_default();
        for window in ["from", "to"] {
            if fields.get(window).is_some() {
                fields.refuse(
                    window,
                    "a steady cycle's metrics are taken over one cycle: no window",
                );
            }
        }
        fields.finish(&[]);
        let order = kind.and_then(|kind| {
            refusals.note(
                &format!("{field}.order"),
                order_of(kind, order, self.samples),
            )
        });
        let slot = variable.and_then(|name: String| {
            let field = format!("{field}.variable");
            refusals.note(&field, self.read(description, &name))
        });
        if let (Some(slot), Some(kind), Some(order)) = (slot, kind, order) {
            self.metrics.push(CycleMetric {
                slot,
                kind,
                order,
                extremes,
            });
        }
    }

    /// The slot of a Real variable among those read at the samples.
    fn read(&mut self, description: &Description, name: &str) -> Result<usize, String> {
        let variable = description.variable(name)?;
        if variable.base_type != BaseType::Real {
            return Err(format!(
                "{name:?} is of type {}; a cycle's metrics and kept variables are Real",
                variable.fmi_type
            ));
        }
        if let Some(slot) = self.reads.names.iter().position(|n| n == name) {
            return Ok(slot);
        }
        self.reads.vrs.push(variable.value_reference);
        self.reads.names.push(name.to_string());
        Ok(self.reads.vrs.len() - 1)
    }
}

/// The way the cycle is found: through the start values where the client sends them (the
/// table's `starts`), else shooting on Model Exchange, each with what it needs of the FMU.
fn way_of(
    spec: &CycleSpec,
    table: Option<&Table>,
    description: &Description,
    refusals: &mut Refusals,
) -> Option<Way> {
    if description.has_model_exchange && description.states.len() != description.continuous_states {
        refusals.refuse(
            "cycle",
            "the FMU's description does not say which variable each of its continuous states \
             is (a derivative without its `derivative` attribute)",
        );
        return None;
    }
    let asked = table.and_then(|t| t.monodromy.as_deref());
    match &spec.starts {
        Some(starts) => {
            if asked.is_some() {
                refusals.refuse(
                    "cycle.monodromy",
                    "through the start values the monodromy comes from the FMU's own \
                     sensitivities",
                );
            }
            Some(Way::Starts(StartsPlan::resolve(
                starts,
                description,
                refusals,
            )))
        }
        None if !description.has_model_exchange => {
            refusals.refuse(
                "cycle",
                "the steady cycle is found by integrating the FMU's Model Exchange \
                 interface, which this FMU does not have",
            );
            None
        }
        None => monodromy_of(asked, description, refusals).map(Way::Exchange),
    }
}

/// How the monodromy is found: as asked, or by the variational equations where the FMU
/// gives directional derivatives.
fn monodromy_of(
    asked: Option<&str>,
    description: &Description,
    refusals: &mut Refusals,
) -> Option<Monodromy> {
    let exact = description.exchange_directional_derivatives;
    match asked {
        None if exact => Some(Monodromy::Variational),
        None | Some("differences") => Some(Monodromy::Differences),
        Some("variational") if exact => Some(Monodromy::Variational),
        Some("variational") => {
            refusals.refuse(
                "cycle.monodromy",
                "\"variational\" needs the FMU's directional derivatives under Model \
                 Exchange, which it does not give",
            );
            Some(Monodromy::Differences)
        }
        // Refused with the table's fields.
        Some(_) => Some(Monodromy::Differences),
    }
}

/// Where the cycle is closed: the cyclic variable and those shifted with it, as positions
/// among `closing` (Model Exchange's states, or the closing variables).
fn closed_by(
    table: &Table,
    closing: &[String],
    way: &Way,
    description: &Description,
    refusals: &mut Refusals,
) -> (Option<usize>, Vec<usize>) {
    let locate = |name: &str, field: &str, refusals: &mut Refusals| {
        let found = description.variable(name).and_then(|_| {
            closing
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| match way {
                    Way::Exchange(_) => format!(
                        "{name:?} is not a continuous state of the FMU (its states: {})",
                        closing.join(", ")
                    ),
                    Way::Starts(_) => format!(
                    "{name:?} is not among the outputs whose sensitivities to the start values \
                     the FMU gives (those that close the cycle: {})",
                    closing.join(", ")
                ),
                })
        });
        refusals.note(field, found.map_err(|e| with_nearest(e, name, closing)))
    };
    let state = table
        .state
        .as_deref()
        .and_then(|s| locate(s, "cycle.state", refusals));
    let mut shifted = Vec::new();
    for (k, name) in table.shifted.iter().enumerate() {
        let field = format!("cycle.shifted[{k}]");
        let Some(index) = locate(name, &field, refusals) else {
            continue;
        };
        if Some(index) == state || shifted.contains(&index) {
            refusals.refuse(field, format!("{name:?} is named twice"));
        } else {
            shifted.push(index);
        }
    }
    (state, shifted)
}

/// A refusal of a name that is not among `names`, with the nearest of them.
fn with_nearest(rule: String, name: &str, names: &[String]) -> String {
    match nearest(name, names.iter().map(String::as_str)) {
        Some(near) if !rule.contains("(its states") => format!("{rule}: did you mean {near}?"),
        _ => rule,
    }
}

/// The modes along a cycle through start values are found on the Model Exchange
/// interface, which must give directional derivatives.
fn check_modes(table: &Table, way: &Way, description: &Description, refusals: &mut Refusals) {
    if matches!(way, Way::Starts(_))
        && table.modes > 0
        && !(description.has_model_exchange && description.exchange_directional_derivatives)
    {
        refusals.refuse(
            "cycle.modes",
            "the modes along the cycle linearise the state equations on the FMU's Model \
             Exchange interface, whose directional derivatives this FMU does not give",
        );
    }
}

/// What the whole linearisation at the modes' points reads, where it is asked for.
fn linear_of(
    asked: bool,
    modes: usize,
    description: &Description,
    refusals: &mut Refusals,
) -> Option<LinearPlan> {
    if !asked {
        return None;
    }
    if modes == 0 {
        refusals.refuse(
            "cycle.modes",
            "the linearisations are made at the modes' points: ask for at least one",
        );
        return None;
    }
    refusals.note("cycle", LinearPlan::of(description))
}

/// A metric's harmonic order: a harmonic's, between 1 and half the samples; 0 for the
/// other kinds, which take none.
fn order_of(kind: CycleKind, order: Option<Value>, samples: usize) -> Result<u32, String> {
    let given = order.as_ref().filter(|v| !v.is_null());
    let whole = given.and_then(Value::as_u64);
    match (kind, given) {
        (CycleKind::Harmonic, Some(_))
            if whole.is_some_and(|o| o >= 1 && 2 * o <= samples as u64) =>
        {
            Ok(whole.unwrap_or(0) as u32)
        }
        (CycleKind::Harmonic, _) => Err(format!(
            "a harmonic needs a whole order between 1 and half the samples ({}), got {}",
            samples / 2,
            given.map_or("none".into(), shown)
        )),
        (_, None) => Ok(0),
        (_, Some(_)) => Err("only a harmonic has an order".into()),
    }
}

/// Model Exchange's states, their derivatives and names (empty without the interface).
fn exchange_states(description: &Description) -> ExchangeStates {
    let states = &description.states;
    let vrs: Vec<u32> = states.iter().map(|s| s.value_reference).collect();
    let names = vrs.iter().map(|&vr| name_of(description, vr)).collect();
    ExchangeStates {
        states: Named { vrs, names },
        derivatives: states.iter().map(|s| s.derivative).collect(),
        directional: description.has_model_exchange && description.exchange_directional_derivatives,
    }
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
    pub exchange: ExchangeStates,
    pub inputs: Named,
    pub outputs: Named,
}

/// Variables by value reference, with their names.
#[derive(Clone, Debug, Default)]
pub struct Named {
    pub vrs: Vec<u32>,
    pub names: Vec<String>,
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
        let real = |causality: &str| -> Named {
            let (vrs, names) = (description.variables.iter())
                .filter(|v| v.causality == causality && v.base_type == BaseType::Real)
                .map(|v| (v.value_reference, v.name.clone()))
                .unzip();
            Named { vrs, names }
        };
        Ok(LinearPlan {
            exchange: exchange_states(description),
            inputs: real("input"),
            outputs: real("output"),
        })
    }
}

mod fields;
mod starts;
#[cfg(test)]
mod tests;

pub use fields::declared as declared_fields;
