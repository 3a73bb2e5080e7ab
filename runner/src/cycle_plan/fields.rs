//! The `[cycle]` table's fields and a cycle's metrics' fields as the runner declares them:
//! what the docs' field tables show (`fmu-runner fields`), kept beside the reader that holds
//! their rules; a test holds the two to the same names.

use serde::Serialize;

use super::{DEFAULT_SAMPLES, MOST_MODE_POINTS, MOST_SAMPLES};

/// One field: its name, the type of its value, its default, its range and what it means.
#[derive(Debug, Serialize)]
pub struct FieldDoc {
    pub name: &'static str,
    #[serde(rename = "type")]
    pub kind: &'static str,
    pub default: String,
    pub range: String,
    pub meaning: &'static str,
}

/// A table's fields, with its heading and what it is.
#[derive(Debug, Serialize)]
pub struct TableDoc {
    pub table: &'static str,
    pub about: &'static str,
    pub fields: Vec<FieldDoc>,
}

fn field(
    name: &'static str,
    kind: &'static str,
    default: impl Into<String>,
    range: impl Into<String>,
    meaning: &'static str,
) -> FieldDoc {
    FieldDoc {
        name,
        kind,
        default: default.into(),
        range: range.into(),
        meaning,
    }
}

/// The `[cycle]` table the runner reads (the client reads `starts` itself).
pub fn cycle_table() -> TableDoc {
    TableDoc {
        table: "[cycle]",
        about: "each point's steady cycle instead of its transient; the runner's rules",
        fields: vec![
            field(
                "state",
                "name",
                "required",
                "",
                "the variable whose advance closes a cycle (a continuous state, or through \
                 the start values an output they give sensitivities of)",
            ),
            field(
                "advance",
                "number",
                "required",
                "> 0, in the state's unit",
                "the state's advance over one cycle (2π = 6.283185307179586 for a revolution)",
            ),
            field(
                "shifted",
                "list of names",
                "none",
                "",
                "other states that advance by the same amount",
            ),
            field(
                "samples",
                "whole number",
                DEFAULT_SAMPLES.to_string(),
                format!("[8, {MOST_SAMPLES}]"),
                "points along the cycle the metrics are read at",
            ),
            field(
                "monodromy",
                "variational | differences",
                "variational where the FMU gives directional derivatives",
                "",
                "how the monodromy matrix is found on Model Exchange",
            ),
            field(
                "modes",
                "whole number",
                "0",
                format!("[0, {MOST_MODE_POINTS}]"),
                "points along the cycle its modes are found at",
            ),
            field(
                "keep",
                "list of names",
                "none",
                "",
                "Real variables kept over one cycle (series/, the pictures)",
            ),
            field(
                "continuation",
                "true/false",
                "true",
                "",
                "start each point's search from its neighbours' cycles",
            ),
        ],
    }
}

/// A metric over one cycle, as `[outputs.metrics.NAME]` gives it beside a `[cycle]`.
pub fn cycle_metric() -> TableDoc {
    TableDoc {
        table: "[outputs.metrics.NAME] beside a [cycle]",
        about: "a metric over one cycle; the runner's rules",
        fields: vec![
            field(
                "variable",
                "name",
                "required",
                "",
                "the Real variable measured",
            ),
            field(
                "kind",
                "min | max | peak_abs | peak_to_peak | mean | rms | harmonic",
                "required",
                "",
                "what is measured over the cycle",
            ),
            field(
                "order",
                "whole number",
                "—",
                "[1, samples / 2]",
                "a harmonic's order: its amplitude at order times the cycle's frequency",
            ),
            field(
                "extremes",
                "refined | sampled",
                "\"refined\"",
                "",
                "min, max, peak_abs, peak_to_peak: found between the samples, or the largest \
                 sample",
            ),
        ],
    }
}

/// Every table declared here, as `fmu-runner fields` prints them.
pub fn declared() -> Vec<TableDoc> {
    vec![cycle_table(), cycle_metric()]
}
