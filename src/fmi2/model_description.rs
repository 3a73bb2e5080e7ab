//! `modelDescription.xml`, generated with quick-xml from the variable table, the declared
//! capabilities and the log categories: the binary and the XML share one source.
//! The GUID is a hash of everything in the XML that defines the interface, so it changes
//! whenever the interface does.

use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::io;

use crate::drivers::DEFAULT_TOLERANCE;
use crate::model::LINKAGE_CLASSES;
use crate::variables::{
    dependencies, is_unknown, value_reference, variables, Causality, Unknowns, VarType, Variable,
    LINKAGE_TYPE, SOLVER_ITEMS, SOLVER_TYPE, STATE_REFERENCES, UNITS,
};
use crate::variables::{BRANCHES, BRANCH_TYPE};

pub const MODEL_IDENTIFIER: &str = "CyclicMechanism";
pub const MODEL_NAME: &str = "CyclicMechanism";
pub const FMI_VERSION: &str = "2.0";
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// DefaultExperiment: startTime, stopTime, stepSize (tolerance is DEFAULT_TOLERANCE).
pub const DEFAULT_EXPERIMENT: (f64, f64, f64) = (0.0, 10.0, 1e-3);

/// Model Exchange capability flags, as declared.
pub const EXCHANGE_CAPABILITIES: &[(&str, bool)] = &[
    ("needsExecutionTool", false),
    // Chart changes come from the event indicator, not from completed steps.
    ("completedIntegratorStepNotNeeded", true),
    ("canBeInstantiatedOnlyOncePerProcess", false),
    ("canNotUseMemoryManagementFunctions", true),
    ("canGetAndSetFMUstate", true),
    ("canSerializeFMUstate", true),
    ("providesDirectionalDerivative", true),
];

/// The number of event indicators: one, the chart's handover (docs/model.md §6).
pub const EVENT_INDICATORS: usize = 1;

/// Co-simulation capability flags, as declared; the FMI functions refuse what is false.
pub const CAPABILITIES: &[(&str, bool)] = &[
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

/// maxOutputDerivativeOrder: fmi2GetRealOutputDerivatives serves orders 1 and 2.
pub const MAX_OUTPUT_DERIVATIVE_ORDER: u32 = 2;

/// Log categories for fmi2SetDebugLogging.
pub const LOG_CATEGORIES: &[(&str, &str)] = &[
    ("logStatusWarning", "Warnings"),
    (
        "logStatusDiscard",
        "Steps that could not be completed (fmi2Discard)",
    ),
    (
        "logStatusError",
        "Errors: illegal calls and invalid arguments or values",
    ),
    (
        "logStatusFatal",
        "Internal errors; the instance cannot be used further",
    ),
    ("logCalls", "Every FMI function call with its arguments"),
    ("logSolver", "Integrator statistics after each fmi2DoStep"),
];

/// The GUID: a 128-bit FNV-1a hash of the interface, formatted as a UUID. Formed once per
/// process: every fmi2Instantiate and every serialized state checks it, and formatting the
/// whole variable table costs as much as a short simulation.
pub fn guid() -> &'static str {
    static GUID: std::sync::OnceLock<UuidText> = std::sync::OnceLock::new();
    GUID.get_or_init(|| UuidText::new(&interface_guid()))
        .as_str()
}

fn interface_guid() -> String {
    let mut text = format!("{MODEL_IDENTIFIER} {FMI_VERSION} {MAX_OUTPUT_DERIVATIVE_ORDER}");
    for (name, value) in CAPABILITIES.iter().chain(EXCHANGE_CAPABILITIES) {
        text += &format!(" {name}={value}");
    }
    text += &format!(" indicators={EVENT_INDICATORS} states={STATE_REFERENCES:?}");
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
    uuid_text(fnv1a_128(text.as_bytes()))
}

/// A 128-bit hash written as a UUID in braces, as FMI tools show GUIDs.
/// A UUID's text, "{8-4-4-4-12}", held without the heap: a master may unload the library
/// (dlclose) while it keeps static data, and a heap block only a static pointed to would then
/// be lost.
pub(crate) struct UuidText([u8; 38]);

impl UuidText {
    pub(crate) fn new(text: &str) -> Self {
        Self(
            text.as_bytes()
                .try_into()
                .expect("a UUID's text has 38 characters"),
        )
    }

    pub(crate) fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).expect("a UUID's text is ASCII")
    }
}

pub(crate) fn uuid_text(hash: u128) -> String {
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

pub(crate) fn fnv1a_128(bytes: &[u8]) -> u128 {
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
pub(crate) fn display_unit(unit: &str) -> Option<(&'static str, f64)> {
    match unit {
        "rad" => Some(("deg", 180.0 / std::f64::consts::PI)),
        "rad/s" => Some(("rpm", 30.0 / std::f64::consts::PI)),
        _ => None,
    }
}

/// The complete `modelDescription.xml`.
pub fn xml() -> String {
    let mut writer = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_model_description(&mut writer).expect("writing to a Vec cannot fail");
    let mut text = String::from_utf8(writer.into_inner()).expect("quick-xml writes UTF-8");
    text.push('\n');
    text
}

/// The attributes of `fmiModelDescription` that FMI 2.0 and 3.0 write alike, after the
/// version, the model's name and its identifying token.
pub(crate) const DESCRIPTION_ATTRIBUTES: [(&str, &str); 8] = [
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
pub(crate) fn write_interface(
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

fn write_model_description(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let indicators = EVENT_INDICATORS.to_string();
    let order = MAX_OUTPUT_DERIVATIVE_ORDER.to_string();
    w.create_element("fmiModelDescription")
        .with_attributes([
            ("fmiVersion", FMI_VERSION),
            ("modelName", MODEL_NAME),
            ("guid", guid()),
        ])
        .with_attributes(DESCRIPTION_ATTRIBUTES)
        .with_attribute(("numberOfEventIndicators", indicators.as_str()))
        .write_inner_content(|w| {
            write_interface(w, "ModelExchange", EXCHANGE_CAPABILITIES, &[])?;
            write_interface(
                w,
                "CoSimulation",
                CAPABILITIES,
                &[("maxOutputDerivativeOrder", order.as_str())],
            )?;
            write_units(w)?;
            write_types(w)?;
            write_log_categories(w)?;
            write_default_experiment(w)?;
            write_variables(w)?;
            write_structure(w)
        })?;
    Ok(())
}

pub(crate) fn write_units(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
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
pub(crate) type Items = [(&'static str, i32, &'static str)];

fn write_types(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    let types: [(&str, &Items); 3] = [
        (SOLVER_TYPE, &SOLVER_ITEMS),
        (LINKAGE_TYPE, &LINKAGE_CLASSES),
        (BRANCH_TYPE, &BRANCHES),
    ];
    w.create_element("TypeDefinitions")
        .write_inner_content(|w| {
            for (type_name, items) in types {
                w.create_element("SimpleType")
                    .with_attribute(("name", type_name))
                    .write_inner_content(|w| {
                        w.create_element("Enumeration")
                            .write_inner_content(|w| write_items(w, items))?;
                        Ok(())
                    })?;
            }
            Ok(())
        })?;
    Ok(())
}

/// An enumeration's `Item` elements, as both FMI versions write them.
pub(crate) fn write_items(w: &mut Writer<Vec<u8>>, items: &Items) -> io::Result<()> {
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

pub(crate) fn write_log_categories(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
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

pub(crate) fn write_default_experiment(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
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

fn write_variables(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("ModelVariables")
        .write_inner_content(|w| {
            for (vr, v) in variables() {
                write_variable(w, vr, &v)?;
            }
            Ok(())
        })?;
    Ok(())
}

fn write_variable(w: &mut Writer<Vec<u8>>, vr: u32, v: &Variable) -> io::Result<()> {
    let vr = vr.to_string();
    let mut element = w.create_element("ScalarVariable").with_attributes([
        ("name", v.name),
        ("valueReference", vr.as_str()),
        ("description", v.description),
        ("causality", v.causality().as_str()),
        ("variability", v.variability()),
    ]);
    if let Some(initial) = v.initial() {
        element = element.with_attribute(("initial", initial));
    }
    // FMI 2.0 names a state by its 1-based index into ModelVariables.
    let attributes = type_attributes(v, v.derivative_of().map(|state| state + 1));
    element.write_inner_content(|w| {
        w.create_element(v.var_type().as_str())
            .with_attributes(attributes.iter().map(|(k, v)| (*k, v.as_str())))
            .write_empty()?;
        Ok(())
    })?;
    Ok(())
}

/// The attributes of a variable's type, which FMI 2.0 writes on its type element and FMI
/// 3.0 on the variable: unit and display unit, declared type, range, start, and for a state
/// derivative `derivative` (its state as the version numbers it).
pub(crate) fn type_attributes(
    v: &Variable,
    derivative: Option<u32>,
) -> Vec<(&'static str, String)> {
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

/// Outputs, state derivatives and initial unknowns, by 1-based index into ModelVariables,
/// each with the knowns it depends on and how (see [`dependencies`]).
fn write_structure(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    let listed = |keep: &dyn Fn(&Variable) -> bool| -> Vec<(usize, Variable)> {
        variables()
            .filter(|(_, v)| keep(v))
            .map(|(vr, v)| (vr as usize + 1, v))
            .collect()
    };
    let outputs = listed(&|v| v.causality() == Causality::Output);
    let derivatives = listed(&|v| v.derivative_of().is_some());
    let initial = listed(&|v| is_unknown(v, Unknowns::Initial));
    let unknowns = |w: &mut Writer<Vec<u8>>,
                    list: &str,
                    members: &[(usize, Variable)],
                    which: Unknowns|
     -> io::Result<()> {
        w.create_element(list).write_inner_content(|w| {
            for (index, v) in members {
                write_unknown(w, "Unknown", ("index", *index as u32), v, which, |vr| {
                    vr + 1
                })?;
            }
            Ok(())
        })?;
        Ok(())
    };
    w.create_element("ModelStructure")
        .write_inner_content(|w| {
            unknowns(w, "Outputs", &outputs, Unknowns::Running)?;
            // Their order is the order of the continuous states (FMI 2.0).
            unknowns(w, "Derivatives", &derivatives, Unknowns::Running)?;
            unknowns(w, "InitialUnknowns", &initial, Unknowns::Initial)
        })?;
    Ok(())
}

/// A ModelStructure entry: `element`, naming the unknown `v` by the attribute `key`, with
/// the knowns it depends on in list `which` (each numbered by `number` from its value
/// reference) and how.
pub(crate) fn write_unknown(
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
pub(crate) fn start_text(v: &Variable) -> Option<String> {
    v.start().map(|s| match v.var_type() {
        VarType::Boolean => (s != 0.0).to_string(),
        _ => s.to_string(),
    })
}

/// One row per variable: name, causality, unit, start, description (for the tables of the
/// README and of the FMU's `documentation/index.html`).
pub fn variable_rows() -> Vec<[String; 5]> {
    variables()
        .map(|(_, v)| {
            let start = start_text(&v).unwrap_or_else(|| "calculated".to_string());
            [
                v.name,
                v.causality().as_str(),
                v.unit,
                &start,
                v.description,
            ]
            .map(str::to_string)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guid_is_stable_and_well_formed() {
        let g = guid();
        assert_eq!(g, guid());
        assert_eq!(g.len(), 38);
        assert!(g.starts_with('{') && g.ends_with('}'));
    }

    #[test]
    fn xml_lists_every_variable_once() {
        let text = xml();
        for (vr, v) in variables() {
            let needle = format!("name=\"{}\" valueReference=\"{vr}\"", v.name);
            assert_eq!(text.matches(&needle).count(), 1, "{needle}");
        }
        assert!(text.contains(guid()));
    }
}
