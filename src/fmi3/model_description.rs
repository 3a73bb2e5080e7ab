//! The FMI 3.0 `modelDescription.xml`, from the same variable table, units, types and log
//! categories as FMI 2.0's. Value references: `time`, the independent variable FMI 3.0
//! requires, is 0, and every other variable has its FMI 2.0 reference plus one, so that
//! both stay positional and append-only. State derivatives name their state's value
//! reference, and the event indicator is a variable (`handover_indicator`).

use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::io;

use crate::description::{
    identity_text, type_attributes, write_default_experiment, write_interface, write_items,
    write_log_categories, write_units, write_unknown, Items, DESCRIPTION_ATTRIBUTES,
    FMI3_CO_SIMULATION, FMI3_MODEL_EXCHANGE, MAX_OUTPUT_DERIVATIVE_ORDER, MODEL_NAME,
};
use crate::model::LINKAGE_CLASSES;
use crate::variables::{
    is_unknown, variables, Causality, Local, Slot, Unknowns, VarType, Variable, LINKAGE_TYPE,
    SOLVER_ITEMS, SOLVER_TYPE,
};
use crate::variables::{BRANCHES, BRANCH_TYPE, SENSITIVITY_ITEMS, SENSITIVITY_TYPE};

pub const FMI_VERSION: &str = "3.0";

/// The value reference of the independent variable `time`.
pub const TIME_REFERENCE: u32 = 0;

/// A variable's FMI 3.0 value reference.
pub fn reference(fmi2_reference: u32) -> u32 {
    fmi2_reference + 1
}

/// The instantiation token: the interface's identity ([`identity_text`]), as FMI 2.0's
/// GUID.
pub fn instantiation_token() -> &'static str {
    identity_text()
}

/// The complete FMI 3.0 `modelDescription.xml`.
pub fn xml() -> String {
    document(instantiation_token())
}

fn document(token: &str) -> String {
    let mut writer = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_model_description(&mut writer, token).expect("writing to a Vec cannot fail");
    let mut text = String::from_utf8(writer.into_inner()).expect("quick-xml writes UTF-8");
    text.push('\n');
    text
}

fn write_model_description(w: &mut Writer<Vec<u8>>, token: &str) -> io::Result<()> {
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let order = MAX_OUTPUT_DERIVATIVE_ORDER.to_string();
    w.create_element("fmiModelDescription")
        .with_attributes([
            ("fmiVersion", FMI_VERSION),
            ("modelName", MODEL_NAME),
            ("instantiationToken", token),
        ])
        .with_attributes(DESCRIPTION_ATTRIBUTES)
        .write_inner_content(|w| {
            write_interface(w, "ModelExchange", FMI3_MODEL_EXCHANGE, &[])?;
            write_interface(
                w,
                "CoSimulation",
                FMI3_CO_SIMULATION,
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

fn write_types(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    let types: [(&str, &Items); 4] = [
        (SOLVER_TYPE, &SOLVER_ITEMS),
        (LINKAGE_TYPE, &LINKAGE_CLASSES),
        (BRANCH_TYPE, &BRANCHES),
        (SENSITIVITY_TYPE, &SENSITIVITY_ITEMS),
    ];
    w.create_element("TypeDefinitions")
        .write_inner_content(|w| {
            for (type_name, items) in types {
                w.create_element("EnumerationType")
                    .with_attribute(("name", type_name))
                    .write_inner_content(|w| write_items(w, items))?;
            }
            Ok(())
        })?;
    Ok(())
}

fn write_variables(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    w.create_element("ModelVariables")
        .write_inner_content(|w| {
            w.create_element("Float64")
                .with_attributes([
                    ("name", "time"),
                    ("valueReference", TIME_REFERENCE.to_string().as_str()),
                    ("description", "Simulation time"),
                    ("causality", "independent"),
                    ("variability", "continuous"),
                    ("unit", "s"),
                ])
                .write_empty()?;
            for (vr, v) in variables() {
                write_variable(w, reference(vr), &v)?;
            }
            Ok(())
        })?;
    Ok(())
}

/// The element of a variable's type in FMI 3.0.
fn element_name(var_type: VarType) -> &'static str {
    match var_type {
        VarType::Real => "Float64",
        VarType::Integer => "Int32",
        VarType::Boolean => "Boolean",
        VarType::Enumeration => "Enumeration",
    }
}

fn write_variable(w: &mut Writer<Vec<u8>>, vr: u32, v: &Variable) -> io::Result<()> {
    let vr = vr.to_string();
    let mut element = w
        .create_element(element_name(v.var_type()))
        .with_attributes([
            ("name", v.name),
            ("valueReference", vr.as_str()),
            ("description", v.description),
            ("causality", v.causality().as_str()),
            ("variability", v.variability()),
        ]);
    if let Some(initial) = v.initial() {
        element = element.with_attribute(("initial", initial));
    }
    // FMI 3.0 names a state by its value reference.
    let attributes = type_attributes(v, v.derivative_of().map(reference));
    element
        .with_attributes(attributes.iter().map(|(k, v)| (*k, v.as_str())))
        .write_empty()?;
    Ok(())
}

/// Outputs, state derivatives (in the order of the continuous states), initial unknowns
/// and the event indicator, each by value reference with the knowns it depends on and how.
fn write_structure(w: &mut Writer<Vec<u8>>) -> io::Result<()> {
    let listed = |keep: &dyn Fn(&Variable) -> bool| -> Vec<(u32, Variable)> {
        variables()
            .filter(|(_, v)| keep(v))
            .map(|(vr, v)| (reference(vr), v))
            .collect()
    };
    let outputs = listed(&|v| v.causality() == Causality::Output);
    let derivatives = listed(&|v| v.derivative_of().is_some());
    let initial = listed(&|v| is_unknown(v, Unknowns::Initial));
    let indicators = listed(&|v| v.slot == Slot::Local(Local::HandoverIndicator));
    w.create_element("ModelStructure")
        .write_inner_content(|w| {
            write_unknowns(w, "Output", &outputs, Unknowns::Running)?;
            write_unknowns(
                w,
                "ContinuousStateDerivative",
                &derivatives,
                Unknowns::Running,
            )?;
            write_unknowns(w, "InitialUnknown", &initial, Unknowns::Initial)?;
            write_unknowns(w, "EventIndicator", &indicators, Unknowns::Running)
        })?;
    Ok(())
}

fn write_unknowns(
    w: &mut Writer<Vec<u8>>,
    element: &str,
    members: &[(u32, Variable)],
    which: Unknowns,
) -> io::Result<()> {
    for (vr, v) in members {
        write_unknown(w, element, ("valueReference", *vr), v, which, reference)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variables::value_reference;

    #[test]
    fn every_variable_once_after_time_and_the_token_is_stable() {
        let text = xml();
        assert!(text.contains(
            "name=\"time\" valueReference=\"0\" description=\"Simulation time\" causality=\"independent\""
        ));
        for (vr, v) in variables() {
            let needle = format!("name=\"{}\" valueReference=\"{}\"", v.name, vr + 1);
            assert_eq!(text.matches(&needle).count(), 1, "{needle}");
        }
        assert_eq!(instantiation_token(), instantiation_token());
        assert!(text.contains(instantiation_token()));
        assert_eq!(instantiation_token(), crate::description::identity_text());
    }

    #[test]
    fn derivatives_name_their_states_and_the_indicator_is_listed() {
        let text = xml();
        let vr = |name: &str| reference(value_reference(name).unwrap());
        let needle = format!("name=\"der(phi1)\" valueReference=\"{}\"", vr("der(phi1)"));
        let line = text.lines().find(|l| l.contains(&needle)).unwrap();
        assert!(
            line.contains(&format!("derivative=\"{}\"", vr("phi1"))),
            "{line}"
        );
        assert!(text.contains(&format!(
            "<EventIndicator valueReference=\"{}\" dependencies=\"{}\"",
            vr("handover_indicator"),
            vr("loop_angle")
        )));
    }
}
