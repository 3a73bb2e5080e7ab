//! The start values' variables of a cycle found through them, resolved and checked.

use serde_json::Value;

use super::{Named, StartsPlan};
use crate::description::{BaseType, Description};
use crate::refusals::{shown, Fields, Refusals};

impl StartsPlan {
    /// The Co-Simulation way's variables, each refusal naming its field: the start values
    /// are Real parameters, the closing variables Real outputs, each slot's sensitivities
    /// Real variables, one per closing variable. What was refused is left out, so that
    /// the rest of the table is still checked against what was not.
    pub(super) fn resolve(
        starts: &Value,
        description: &Description,
        refusals: &mut Refusals,
    ) -> StartsPlan {
        let empty = Value::Object(Default::default());
        let table = if starts.is_object() { starts } else { &empty };
        if !starts.is_object() {
            refusals.refuse(
                "cycle.starts",
                format!("must be a table, got {}", shown(starts)),
            );
        }
        let mut fields = Fields::of(table, "cycle.starts", refusals).expect("a table");
        let parameters = fields.names("parameters").unwrap_or_default();
        let closing = fields.names("closing").unwrap_or_default();
        let slots = fields.items("slots");
        let columns = fields.items("columns");
        fields.finish(&[]);
        can_run_through(
            parameters.len(),
            (slots.len(), columns.len()),
            description,
            refusals,
        );
        let named = |names: &[String]| Named {
            vrs: Vec::new(),
            names: names.to_vec(),
        };
        let mut plan = StartsPlan {
            parameters: named(&parameters),
            slots: Vec::new(),
            items: Vec::new(),
            closing: named(&closing),
            columns: Vec::new(),
        };
        for (k, name) in parameters.iter().enumerate() {
            let field = format!("cycle.starts[{k}]");
            if parameters[..k].contains(name) {
                refusals.refuse(&field, format!("{name:?} is named twice"));
            }
            let found = real_variable(description, name, Some("parameter"));
            plan.parameters.vrs.extend(refusals.note(&field, found));
        }
        for (field, slot) in slots {
            let found = slot_of(slot, description);
            if let Some((vr, item)) = refusals.note(&field, found) {
                plan.slots.push(vr);
                plan.items.push(item);
            }
        }
        for (k, name) in closing.iter().enumerate() {
            let found = real_variable(description, name, Some("output"));
            let field = format!("cycle.closing[{k}]");
            plan.closing.vrs.extend(refusals.note(&field, found));
        }
        for (field, column) in columns {
            let found = column_of(column, closing.len(), description);
            plan.columns.extend(refusals.note(&field, found));
        }
        plan
    }
}

/// A sensitivity slot as the client sends it: the slot's variable and the value it is set to.
fn slot_of(slot: &Value, description: &Description) -> Result<(u32, i32), String> {
    let pair = slot.as_array().filter(|p| p.len() == 2);
    let (name, item) = match pair.map(|p| (p[0].as_str(), p[1].as_i64())) {
        Some((Some(name), Some(item))) => (name, item),
        _ => return Err(format!("must be [slot, value], got {}", shown(slot))),
    };
    let item = i32::try_from(item).map_err(|_| format!("{item} is not a slot's value"))?;
    Ok((description.variable(name)?.value_reference, item))
}

/// A start value's column of sensitivities: a Real variable per closing variable.
fn column_of(
    column: &Value,
    closing: usize,
    description: &Description,
) -> Result<Vec<u32>, String> {
    let names: Option<Vec<&str>> = column
        .as_array()
        .and_then(|names| names.iter().map(Value::as_str).collect());
    let names = names.ok_or_else(|| format!("must be a list of names, got {}", shown(column)))?;
    if names.len() != closing {
        return Err(format!(
            "{} sensitivities for {closing} closing variables",
            names.len()
        ));
    }
    names
        .iter()
        .map(|name| real_variable(description, name, None))
        .collect()
}

/// Whether a cycle through start values can run on this FMU: it has Co-Simulation with
/// output derivatives (the closing variables' rates at the cycle's end), a slot and a
/// column of sensitivities for each start value, and as many start values as the state
/// on the section has free coordinates, where Model Exchange says how many that is.
fn can_run_through(
    n: usize,
    (slots, columns): (usize, usize),
    description: &Description,
    refusals: &mut Refusals,
) {
    if description.model_identifier.is_none() {
        refusals.refuse(
            "cycle.starts",
            "the cycle through the start values runs the FMU's Co-Simulation interface, which \
             this FMU does not have",
        );
    }
    if description.max_output_derivative_order < 1 {
        refusals.refuse(
            "cycle.starts",
            "the cycle through the start values reads the closing variables' rates at its end \
             (output derivatives), which this FMU does not give",
        );
    }
    if n == 0 || slots != n || columns != n {
        refusals.refuse(
            "cycle.starts",
            format!("{n} start values need as many sensitivity slots and columns, got {slots} and {columns}"),
        );
    }
    let states = description.states.len();
    if description.has_model_exchange && states != n + 1 {
        refusals.refuse(
            "cycle.starts",
            format!(
                "the state on the section has {} free coordinates (the FMU's {states} \
                 continuous states less the cyclic one): name as many start values, not {n}",
                states.saturating_sub(1)
            ),
        );
    }
}

/// The value reference of the Real variable `name`, of `causality` where one is asked.
fn real_variable(
    description: &Description,
    name: &str,
    causality: Option<&str>,
) -> Result<u32, String> {
    let v = description.variable(name)?;
    if v.base_type != BaseType::Real {
        return Err(format!("{name:?} is of type {}, not Real", v.fmi_type));
    }
    match causality {
        Some(c) if v.causality != c => {
            Err(format!("{name:?} has causality {}, not {c}", v.causality))
        }
        _ => Ok(v.value_reference),
    }
}
