//! What both versions' model descriptions share, below both: the model's names and
//! version, its default experiment, event indicator count and log categories, the hash
//! that identifies the interface, and the writers of the XML elements and of the Markdown
//! table that FMI 2.0 and 3.0 write alike. `fmi2::model_description` and
//! `fmi3::model_description` add what each version writes its own way.

use quick_xml::Writer;
use std::io;

use crate::drivers::DEFAULT_TOLERANCE;
use crate::variables::{
    dependencies, value_reference, variables, Slot, Twin, Unknowns, VarType, Variable,
    SENSITIVITY_SLOTS, SOLVER_TYPE, STATE_REFERENCES, UNITS,
};

pub const MODEL_IDENTIFIER: &str = "CyclicMechanism";
pub const MODEL_NAME: &str = "CyclicMechanism";
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// DefaultExperiment: startTime, stopTime, stepSize (tolerance is DEFAULT_TOLERANCE).
pub const DEFAULT_EXPERIMENT: (f64, f64, f64) = (0.0, 10.0, 1e-3);

/// The number of event indicators: one, the chart's handover (docs/model.md §6).
pub const EVENT_INDICATORS: usize = 1;

/// maxOutputDerivativeOrder: the output derivatives of orders 1 and 2 are served.
pub const MAX_OUTPUT_DERIVATIVE_ORDER: u32 = 2;

/// Log categories, which either version's SetDebugLogging switches.
pub const LOG_CATEGORIES: &[(&str, &str)] = &[
    ("logStatusWarning", "Warnings"),
    (
        "logStatusDiscard",
        "Steps that could not be completed (a Discard)",
    ),
    (
        "logStatusError",
        "Errors: illegal calls and invalid arguments or values",
    ),
    (
        "logStatusFatal",
        "Internal errors; the instance cannot be used further",
    ),
    ("logCalls", "Every FMI function call, by name"),
    (
        "logSolver",
        "Integrator statistics after each communication step",
    ),
];

/// A UUID's text, "{8-4-4-4-12}", held without the heap: a master may unload the library
/// (dlclose) while it keeps static data, and a heap block only a static pointed to would then
/// be lost.
struct UuidText([u8; 38]);

impl UuidText {
    fn new(text: &str) -> Self {
        Self(
            text.as_bytes()
                .try_into()
                .expect("a UUID's text has 38 characters"),
        )
    }

    fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).expect("a UUID's text is ASCII")
    }
}

/// A 128-bit hash written as a UUID in braces, as FMI tools show GUIDs.
fn uuid_text(hash: u128) -> String {
    let hex = format!("{hash:032x}");
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &hex[..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..]
    )
}

fn fnv1a_128(bytes: &[u8]) -> u128 {
    const OFFSET: u128 = 0x6c62272e07bb014262b821756295c58d;
    const PRIME: u128 = 0x0000000001000000000000000000013B;
    bytes
        .iter()
        .fold(OFFSET, |hash, &b| (hash ^ b as u128).wrapping_mul(PRIME))
}

/// When this interface was last changed: fixed, so that the generated file is reproducible
/// (a timestamp of the build would make every build differ). Set with `version`.
const GENERATION_DATE: &str = "2026-11-23T00:00:00Z";

/// A unit's display unit for tools' dialogs: name and factor (display = factor · value).
pub fn display_unit(unit: &str) -> Option<(&'static str, f64)> {
    match unit {
        "rad" => Some(("deg", 180.0 / std::f64::consts::PI)),
        "rad/s" => Some(("rpm", 30.0 / std::f64::consts::PI)),
        _ => None,
    }
}

/// The attributes of `fmiModelDescription` that FMI 2.0 and 3.0 write alike, after the
/// version, the model's name and its identifying token.
pub const DESCRIPTION_ATTRIBUTES: [(&str, &str); 8] = [
    (
        "description",
        "Four-bar cyclic mechanism with two torsional springs (Tataru), orthogonal-complement method",
    ),
    ("version", VERSION),
    ("author", "the cyclic-mechanism developers"),
    ("copyright", "Copyright the cyclic-mechanism developers"),
    ("license", "MIT"),
    ("generationTool", "cyclic-mechanism (Rust)"),
    ("generationDateAndTime", GENERATION_DATE),
    ("variableNamingConvention", "flat"),
];

/// An interface element (`ModelExchange`, `CoSimulation`) with the model identifier, its
/// capability flags and then the attributes `more`.
pub fn write_interface(
    w: &mut Writer<Vec<u8>>,
    element: &str,
    flags: &[(&str, bool)],
    more: &[(&str, &str)],
) -> io::Result<()> {
    let mut interface = w
        .create_element(element)
        .with_attribute(("modelIdentifier", MODEL_IDENTIFIER));
    for (name, value) in flags {
        interface = interface.with_attribute((*name, if *value { "true" } else { "false" }));
    }
    interface
        .with_attributes(more.iter().copied())
        .write_empty()?;
    Ok(())
}

pub fn write_units(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("UnitDefinitions")
        .write_inner_content(|w| {
            for (name, exponents) in UNITS {
                w.create_element("Unit")
                    .with_attribute(("name", *name))
                    .write_inner_content(|w| {
                        let mut base = w.create_element("BaseUnit");
                        for (unit, exponent) in ["kg", "m", "s", "rad"].iter().zip(exponents) {
                            if *exponent != 0 {
                                base = base.with_attribute((*unit, exponent.to_string().as_str()));
                            }
                        }
                        base.write_empty()?;
                        if let Some((display, factor)) = display_unit(name) {
                            w.create_element("DisplayUnit")
                                .with_attributes([
                                    ("name", display),
                                    ("factor", factor.to_string().as_str()),
                                ])
                                .write_empty()?;
                        }
                        Ok(())
                    })?;
            }
            Ok(())
        })?;
    Ok(())
}

/// An enumeration's items: name, value, description.
pub type Items = [(&'static str, i32, &'static str)];

/// An enumeration's `Item` elements, as both FMI versions write them.
pub fn write_items(w: &mut Writer<Vec<u8>>, items: &Items) -> io::Result<()> {
    for (name, value, description) in items {
        w.create_element("Item")
            .with_attributes([
                ("name", *name),
                ("value", value.to_string().as_str()),
                ("description", *description),
            ])
            .write_empty()?;
    }
    Ok(())
}

pub fn write_log_categories(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("LogCategories").write_inner_content(|w| {
        for (name, description) in LOG_CATEGORIES {
            w.create_element("Category")
                .with_attributes([("name", *name), ("description", *description)])
                .write_empty()?;
        }
        Ok(())
    })?;
    Ok(())
}

pub fn write_default_experiment(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    let (start, stop, step) = DEFAULT_EXPERIMENT;
    w.create_element("DefaultExperiment")
        .with_attributes([
            ("startTime", start.to_string().as_str()),
            ("stopTime", stop.to_string().as_str()),
            ("tolerance", format!("{DEFAULT_TOLERANCE:e}").as_str()),
            ("stepSize", format!("{step:e}").as_str()),
        ])
        .write_empty()?;
    Ok(())
}

/// The attributes of a variable's type, which FMI 2.0 writes on its type element and FMI
/// 3.0 on the variable: unit and display unit, declared type, range, start, and for a state
/// derivative `derivative` (its state as the version numbers it).
pub fn type_attributes(v: &Variable, derivative: Option<u32>) -> Vec<(&'static str, String)> {
    let mut attributes = Vec::new();
    match v.var_type() {
        VarType::Real if !v.unit.is_empty() => {
            attributes.push(("unit", v.unit.to_string()));
            if let Some((display, _)) = display_unit(v.unit) {
                attributes.push(("displayUnit", display.to_string()));
            }
        }
        VarType::Enumeration => attributes.push((
            "declaredType",
            v.declared_type().unwrap_or(SOLVER_TYPE).to_string(),
        )),
        _ => {}
    }
    if let Some((low, high)) = v.range() {
        attributes.push(("min", low.to_string()));
        attributes.push(("max", high.to_string()));
    }
    attributes.extend(start_text(v).map(|start| ("start", start)));
    attributes.extend(derivative.map(|state| ("derivative", state.to_string())));
    attributes
}

/// A ModelStructure entry: `element`, naming the unknown `v` by the attribute `key`, with
/// the knowns it depends on in list `which` (each numbered by `number` from its value
/// reference) and how.
pub fn write_unknown(
    w: &mut Writer<Vec<u8>>,
    element: &str,
    (key, id): (&str, u32),
    v: &Variable,
    which: Unknowns,
    number: impl Fn(u32) -> u32,
) -> io::Result<()> {
    let pairs = dependencies(v, which);
    let known: Vec<String> = pairs
        .iter()
        .map(|(n, _)| number(value_reference(n).expect("known")).to_string())
        .collect();
    let kinds: Vec<&str> = pairs.iter().map(|(_, k)| k.as_str()).collect();
    let mut unknown = w.create_element(element).with_attributes([
        (key, id.to_string().as_str()),
        ("dependencies", known.join(" ").as_str()),
    ]);
    // An empty list says "depends on none"; its kinds would be an empty list too.
    if !known.is_empty() {
        unknown = unknown.with_attribute(("dependenciesKind", kinds.join(" ").as_str()));
    }
    unknown.write_empty()?;
    Ok(())
}

/// The start value as the XML writes it: a number, or `true`/`false` for a Boolean.
pub fn start_text(v: &Variable) -> Option<String> {
    v.start().map(|s| match v.var_type() {
        VarType::Boolean => (s != 0.0).to_string(),
        _ => s.to_string(),
    })
}

/// One row per variable: name, causality, unit, start, description (for the tables of the
/// README and of the FMU's `documentation/index.html`); the sensitivity slots, alike but
/// for their number, in two rows for all.
pub fn variable_rows() -> Vec<[String; 5]> {
    variables()
        .filter_map(|(_, v)| {
            let start = start_text(&v).unwrap_or_else(|| "calculated".to_string());
            let row = |name: &str, description: &str| {
                [name, v.causality().as_str(), v.unit, &start, description].map(str::to_string)
            };
            match v.slot {
                Slot::SensitivityParameter(0) => Some(row(
                    "sensitivity_<k>.parameter",
                    &format!(
                        "Slot k = 1…{SENSITIVITY_SLOTS}: the parameter whose sensitivities the \
                         slot's locals carry, none (0) or an inertia, spring, damper, start \
                         value or torque-law coefficient; Co-Simulation only \
                         (docs/sensitivities.md)"
                    ),
                )),
                Slot::Sensitivity { slot: 0, state: 0 } => Some(row(
                    "sensitivity_<k>.phi1 … .omega4",
                    "Derivatives of the eight states phi1…omega4 with respect to the parameter \
                     of slot k, along the run since initialisation",
                )),
                Slot::Twin(Twin::SensitivityParameter(0)) => Some(row(
                    "sensitivity_<k>.parameter_code",
                    "sensitivity_<k>.parameter as an Integer, for masters that cannot set \
                     Enumerations: 0 (the default) leaves the choice to the slot's \
                     Enumeration; an item's value decides instead of it",
                )),
                Slot::SensitivityParameter(_) | Slot::Sensitivity { .. } => None,
                Slot::Twin(Twin::SensitivityParameter(_)) => None,
                _ => Some(row(v.name, v.description)),
            }
        })
        .collect()
}

/// The variables as a Markdown table.
pub fn variables_markdown() -> String {
    let mut text = String::from(
        "| name | causality | unit | start | description |\n| --- | --- | --- | --- | --- |\n",
    );
    for [name, causality, unit, start, description] in variable_rows() {
        text += &format!("| `{name}` | {causality} | {unit} | {start} | {description} |\n");
    }
    text
}

/// Every variable with what defines it (reference, name, type, causality, variability,
/// unit, start, range), as text: what the interface's identity hashes with the rest.
fn variables_text() -> String {
    let mut text = String::new();
    for (vr, v) in variables() {
        text += &format!(
            " {vr}:{}:{}:{}:{}:{}:{:?}:{:?}",
            v.name,
            v.var_type().as_str(),
            v.causality().as_str(),
            v.variability(),
            v.unit,
            v.start(),
            v.range()
        );
    }
    text
}

/// FMI 2.0's Co-Simulation capability flags, as declared; the FMI functions refuse what is
/// false.
pub const FMI2_CO_SIMULATION: &[(&str, bool)] = &[
    ("needsExecutionTool", false),
    ("canHandleVariableCommunicationStepSize", true),
    ("canInterpolateInputs", true),
    ("canRunAsynchronuously", false),
    ("canBeInstantiatedOnlyOncePerProcess", false),
    ("canNotUseMemoryManagementFunctions", true),
    ("canGetAndSetFMUstate", true),
    ("canSerializeFMUstate", true),
    ("providesDirectionalDerivative", true),
];

/// FMI 2.0's Model Exchange capability flags, as declared.
pub const FMI2_MODEL_EXCHANGE: &[(&str, bool)] = &[
    ("needsExecutionTool", false),
    // Chart changes come from the event indicator, not from completed steps.
    ("completedIntegratorStepNotNeeded", true),
    ("canBeInstantiatedOnlyOncePerProcess", false),
    ("canNotUseMemoryManagementFunctions", true),
    ("canGetAndSetFMUstate", true),
    ("canSerializeFMUstate", true),
    ("providesDirectionalDerivative", true),
];

/// FMI 3.0's Co-Simulation capabilities, as declared (the output derivatives' order is written
/// beside them): as for Model Exchange, with event mode, and a step that may return early
/// (at a change point, docs/model.md §7); no intermediate update.
pub const FMI3_CO_SIMULATION: &[(&str, bool)] = &[
    ("needsExecutionTool", false),
    ("canBeInstantiatedOnlyOncePerProcess", false),
    ("canGetAndSetFMUState", true),
    ("canSerializeFMUState", true),
    ("providesDirectionalDerivatives", true),
    ("providesAdjointDerivatives", true),
    ("canHandleVariableCommunicationStepSize", true),
    ("mightReturnEarlyFromDoStep", true),
    ("hasEventMode", true),
];

/// FMI 3.0's Model Exchange capabilities, as declared: FMU states and their serialization,
/// directional and adjoint derivatives; no per-element dependencies and no evaluation of
/// clocked discrete states.
pub const FMI3_MODEL_EXCHANGE: &[(&str, bool)] = &[
    ("needsExecutionTool", false),
    ("canBeInstantiatedOnlyOncePerProcess", false),
    ("canGetAndSetFMUState", true),
    ("canSerializeFMUState", true),
    ("providesDirectionalDerivatives", true),
    ("providesAdjointDerivatives", true),
    ("needsCompletedIntegratorStep", false),
];

/// The interface's identity: a hash of what defines it in either version's model
/// description (the variable table, the states, the event indicators, the output
/// derivatives, each version's capabilities). FMI 2.0's GUID and FMI 3.0's instantiation
/// token are its text ([`identity_text`]), and it stamps serialized FMU states, so that a
/// state is restored only by a binary with the same interface. Formed once per process:
/// formatting the whole variable table costs as much as a short simulation.
pub fn identity() -> u128 {
    static HASH: std::sync::OnceLock<u128> = std::sync::OnceLock::new();
    *HASH.get_or_init(|| {
        let mut text = format!(
            "{MODEL_IDENTIFIER} {MAX_OUTPUT_DERIVATIVE_ORDER} indicators={EVENT_INDICATORS} \
             states={STATE_REFERENCES:?}"
        );
        let capabilities = [
            ("fmi2 cs", FMI2_CO_SIMULATION),
            ("fmi2 me", FMI2_MODEL_EXCHANGE),
            ("fmi3 cs", FMI3_CO_SIMULATION),
            ("fmi3 me", FMI3_MODEL_EXCHANGE),
        ];
        for (interface, flags) in capabilities {
            text += &format!(" {interface}:");
            for (name, value) in flags {
                text += &format!(" {name}={value}");
            }
        }
        text += &variables_text();
        fnv1a_128(text.as_bytes())
    })
}

/// The identity as a UUID's text, as FMI tools show GUIDs and tokens; formed once per
/// process, held without the heap ([`UuidText`]).
pub fn identity_text() -> &'static str {
    static TEXT: std::sync::OnceLock<UuidText> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| UuidText::new(&uuid_text(identity())))
        .as_str()
}
