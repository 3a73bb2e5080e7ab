//! Loading a system: `system.json` read, each component's FMU unpacked, described and
//! loaded, each connection checked against both ends, and the system's variables
//! described as one FMU's.

use std::ffi::CString;
use std::path::Path;
use std::rc::Rc;

use serde::Deserialize;

use super::{Component, Link, Route, SystemLibrary};
use crate::archive::Unpacked;
use crate::coupling;
use crate::description::{Description, Variable};
use crate::fmi::{Interface, Library};
use crate::plan::type_group;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SystemFile {
    components: Vec<ComponentFile>,
    connections: Vec<ConnectionFile>,
    #[serde(default)]
    input_derivatives: usize,
    #[serde(default)]
    coupling_tolerance: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentFile {
    name: String,
    file: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ConnectionFile {
    from: String,
    to: String,
}

/// Whether `dir` holds a system rather than an unpacked FMU.
pub fn is_system(dir: &Path) -> bool {
    dir.join("system.json").is_file()
}

impl SystemLibrary {
    /// Load the system in `dir`, with the description of its variables as one FMU's.
    pub fn load(dir: &Path) -> Result<(Description, Rc<SystemLibrary>), String> {
        let path = dir.join("system.json");
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let file: SystemFile =
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        let (components, descriptions) = load_components(dir, &file.components)?;
        if let Some(tolerance) = file.coupling_tolerance {
            check_rollback(tolerance, &components, &descriptions)?;
        }
        let names: Vec<&str> = file.components.iter().map(|c| c.name.as_str()).collect();
        let (links, link_names, fed) = connect(&file, &names, &components, &descriptions)?;
        let (routes, variables) = routes(&names, &descriptions, &fed);
        let description = Description {
            fmi_version: "2.0".into(),
            model_name: "system".into(),
            model_identifier: Some("system".into()),
            can_handle_variable_step: descriptions.iter().all(|d| d.can_handle_variable_step),
            variables,
            ..Description::default()
        };
        let system = SystemLibrary {
            components,
            routes,
            links,
            link_names,
            coupling_tolerance: file.coupling_tolerance,
        };
        Ok((description, Rc::new(system)))
    }
}

/// Each component unpacked (inside the served folder, which the caller removes even if
/// this process dies), described and loaded.
fn load_components(
    dir: &Path,
    files: &[ComponentFile],
) -> Result<(Vec<Component>, Vec<Description>), String> {
    let mut components = Vec::new();
    let mut descriptions = Vec::new();
    for c in files {
        let unpacked = Unpacked::within(&dir.join(&c.file), dir)?;
        let description =
            Description::read(unpacked.dir()).map_err(|e| format!("component {}: {e}", c.name))?;
        let library = Library::load(unpacked.dir(), &description, Interface::CoSimulation)
            .map_err(|e| format!("component {}: {e}", c.name))?;
        components.push(Component {
            name: CString::new(c.name.as_str()).map_err(|e| e.to_string())?,
            interpolates: description.can_interpolate_inputs && library.exports_derivatives().1,
            library,
            _unpacked: unpacked,
        });
        descriptions.push(description);
    }
    Ok((components, descriptions))
}

/// Links, their names for messages, and the inputs they feed (component, value
/// reference).
type Connected = (Vec<Link>, Vec<String>, Vec<(usize, u32)>);

/// The connections of `file`, checked against both ends.
fn connect(
    file: &SystemFile,
    names: &[&str],
    components: &[Component],
    descriptions: &[Description],
) -> Result<Connected, String> {
    let find = |end: &str| find_variable(end, names, descriptions);
    let (mut links, mut link_names, mut fed) = (Vec::new(), Vec::new(), Vec::new());
    for c in &file.connections {
        let (from, output) = find(&c.from)?;
        let (to, input) = find(&c.to)?;
        let mut link = link(
            (from, output, &descriptions[from]),
            (to, input, &descriptions[to]),
            file.input_derivatives,
        )?;
        // A description may promise derivatives its binary does not export.
        if !(components[from].library.exports_derivatives().0 && components[to].interpolates) {
            link.derivatives = 0;
        }
        links.push(link);
        link_names.push(format!("{} → {}", c.from, c.to));
        fed.push((to, input.value_reference));
    }
    Ok((links, link_names, fed))
}

/// The system's variables, `component.variable` for each of its components' but the
/// inputs a connection feeds, and where each lives (the system's value reference is its
/// index).
fn routes(
    names: &[&str],
    descriptions: &[Description],
    fed: &[(usize, u32)],
) -> (Vec<Route>, Vec<Variable>) {
    let mut variables = Vec::new();
    let mut routes = Vec::new();
    for (component, description) in descriptions.iter().enumerate() {
        for v in &description.variables {
            let connected = fed.contains(&(component, v.value_reference));
            if (v.causality == "input" && connected) || v.causality == "independent" {
                continue;
            }
            let Ok(group) = type_group(v) else { continue };
            routes.push(Route {
                component,
                vr: v.value_reference,
                group,
            });
            variables.push(Variable {
                name: format!("{}.{}", names[component], v.name),
                value_reference: (routes.len() - 1) as u32,
                // A component's state is not one of the system's, which has no Model
                // Exchange interface.
                derivative_of: None,
                ..v.clone()
            });
        }
    }
    (routes, variables)
}

/// A coupling tolerance needs a positive tolerance and components that can roll back (the
/// refusal names the field, `system.coupling_tolerance: rule` or the component's
/// `system.components.NAME: rule`, which the client reports by it).
fn check_rollback(
    tolerance: f64,
    components: &[Component],
    descriptions: &[Description],
) -> Result<(), String> {
    coupling::check_tolerance(tolerance)?;
    for (c, d) in components.iter().zip(descriptions) {
        if !(d.can_get_and_set_state && c.library.exports_state()) {
            return Err(format!(
                "system.components.{}: cannot save its FMU state (canGetAndSetFMUstate), \
                 which system.coupling_tolerance needs: a step is taken again from every \
                 component's saved state",
                c.name.to_string_lossy()
            ));
        }
    }
    Ok(())
}

/// The component and variable that `end` ("component.variable") names.
fn find_variable<'a>(
    end: &str,
    names: &[&str],
    descriptions: &'a [Description],
) -> Result<(usize, &'a Variable), String> {
    let (component, variable) = end
        .split_once('.')
        .ok_or_else(|| format!("connection end {end:?} is not component.variable"))?;
    let index = names
        .iter()
        .position(|n| *n == component)
        .ok_or_else(|| format!("connection end {end:?}: no component {component:?}"))?;
    let v = descriptions[index]
        .variable(variable)
        .map_err(|e| format!("connection end {end:?}: {e}"))?;
    Ok((index, v))
}

/// The link from output `from` to input `to`, checked, with the derivative orders both
/// ends support up to `wanted`.
fn link(
    (source, output, source_description): (usize, &Variable, &Description),
    (target, input, target_description): (usize, &Variable, &Description),
    wanted: usize,
) -> Result<Link, String> {
    let what = format!("connection {} → {}", output.name, input.name);
    if output.causality != "output" || input.causality != "input" {
        return Err(format!(
            "{what}: a connection goes from an output to an input (these are {} and {})",
            output.causality, input.causality
        ));
    }
    if output.base_type != input.base_type {
        return Err(format!("{what}: the two ends have different types"));
    }
    let group = type_group(output)?;
    let derivatives = if group == 0 && target_description.can_interpolate_inputs {
        wanted.min(source_description.max_output_derivative_order as usize)
    } else {
        0
    };
    Ok(Link {
        from: Route {
            component: source,
            vr: output.value_reference,
            group,
        },
        to: Route {
            component: target,
            vr: input.value_reference,
            group,
        },
        derivatives: derivatives.min(2),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn description(can_interpolate: bool, max_order: u32, variables: &str) -> Description {
        Description::parse(&format!(
            r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{{g}}">
  <CoSimulation modelIdentifier="m" canInterpolateInputs="{can_interpolate}"
    maxOutputDerivativeOrder="{max_order}"/>
  <ModelVariables>{variables}</ModelVariables>
</fmiModelDescription>"#
        ))
        .unwrap()
    }

    const MOTOR: &str = r#"
    <ScalarVariable name="omega" valueReference="4" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="torque" valueReference="6" causality="output"><Real/></ScalarVariable>
    <ScalarVariable name="mode" valueReference="7" causality="output"><Integer/></ScalarVariable>"#;
    const MECHANISM: &str = r#"
    <ScalarVariable name="M_m" valueReference="1" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="omega1" valueReference="9" causality="output"><Real/></ScalarVariable>"#;

    fn pair(wanted: usize, interpolates: bool) -> Result<Link, String> {
        let motor = description(true, 1, MOTOR);
        let mechanism = description(interpolates, 2, MECHANISM);
        let descriptions = [motor, mechanism];
        let names = ["motor", "mechanism"];
        let (from, output) = find_variable("motor.torque", &names, &descriptions)?;
        let (to, input) = find_variable("mechanism.M_m", &names, &descriptions)?;
        link(
            (from, output, &descriptions[from]),
            (to, input, &descriptions[to]),
            wanted,
        )
    }

    /// Derivatives up to what was asked, what the source gives and what the target takes.
    #[test]
    fn a_link_passes_the_derivatives_both_ends_support() {
        let orders = |wanted, interpolates| pair(wanted, interpolates).unwrap().derivatives;
        assert_eq!(orders(2, true), 1); // the motor gives only the first
        assert_eq!(orders(0, true), 0);
        assert_eq!(orders(2, false), 0); // the mechanism would not take them
        let link = pair(2, true).unwrap();
        assert_eq!((link.from.vr, link.to.vr, link.from.group), (6, 1, 0));
    }

    #[test]
    fn a_wrong_connection_is_refused_with_its_ends_named() {
        let descriptions = [description(true, 1, MOTOR), description(true, 2, MECHANISM)];
        let names = ["motor", "mechanism"];
        let refusal = |from: &str, to: &str| {
            let (a, output) = find_variable(from, &names, &descriptions)?;
            let (b, input) = find_variable(to, &names, &descriptions)?;
            link(
                (a, output, &descriptions[a]),
                (b, input, &descriptions[b]),
                2,
            )
            .map(|_| ())
        };
        let said = refusal("motor.omega", "mechanism.M_m").unwrap_err();
        assert!(said.contains("from an output to an input"), "{said}");
        let said = refusal("motor.mode", "mechanism.M_m").unwrap_err();
        assert!(said.contains("different types"), "{said}");
        let said = refusal("pump.torque", "mechanism.M_m").unwrap_err();
        assert!(said.contains("no component \"pump\""), "{said}");
        let said = refusal("motor.speed", "mechanism.M_m").unwrap_err();
        assert!(said.contains("\"speed\""), "{said}");
        let said = refusal("torque", "mechanism.M_m").unwrap_err();
        assert!(said.contains("not component.variable"), "{said}");
    }
}
