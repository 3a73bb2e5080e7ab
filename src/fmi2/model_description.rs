//! `modelDescription.xml`, generated with quick-xml from the variable table, the declared
//! capabilities and the log categories: the binary and the XML share one source.
//! The GUID is the interface's identity, a hash of everything either version's XML says
//! that defines the interface, so it changes whenever the interface does.

use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::io;

use crate::description::{
    identity_text, type_attributes, write_default_experiment, write_interface, write_items,
    write_log_categories, write_units, write_unknown, Items, DESCRIPTION_ATTRIBUTES,
    EVENT_INDICATORS, FMI2_CO_SIMULATION, FMI2_MODEL_EXCHANGE, MAX_OUTPUT_DERIVATIVE_ORDER,
    MODEL_NAME,
};
use crate::model::LINKAGE_CLASSES;
use crate::variables::{
    is_unknown, variables, Causality, Unknowns, Variable, LINKAGE_TYPE, SOLVER_ITEMS, SOLVER_TYPE,
};
use crate::variables::{BRANCHES, BRANCH_TYPE, SENSITIVITY_ITEMS, SENSITIVITY_TYPE};

pub const FMI_VERSION: &str = "2.0";

/// The GUID: the interface's identity ([`identity_text`]), which FMI 3.0's instantiation
/// token and every serialized state share.
pub fn guid() -> &'static str {
    identity_text()
}

/// The complete `modelDescription.xml`.
pub fn xml() -> String {
    let mut writer = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_model_description(&mut writer).expect("writing to a Vec cannot fail");
    let mut text = String::from_utf8(writer.into_inner()).expect("quick-xml writes UTF-8");
    text.push('\n');
    text
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
            write_interface(w, "ModelExchange", FMI2_MODEL_EXCHANGE, &[])?;
            write_interface(
                w,
                "CoSimulation",
                FMI2_CO_SIMULATION,
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
