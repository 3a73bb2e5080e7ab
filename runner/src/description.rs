//! What the runner needs from `modelDescription.xml`: the GUID, the co-simulation model
//! identifier and the scalar variables, read with quick-xml.

use std::path::Path;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use serde::Serialize;

/// The FMI 2.0 base type of a scalar variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseType {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
}

#[derive(Clone, Debug, Serialize)]
pub struct Variable {
    pub name: String,
    pub value_reference: u32,
    #[serde(rename = "type")]
    pub base_type: BaseType,
    pub causality: String,
    pub variability: String,
    pub start: Option<String>,
    pub min: Option<String>,
    pub max: Option<String>,
    pub declared_type: Option<String>,
    pub description: Option<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Description {
    pub fmi_version: String,
    pub model_name: String,
    pub guid: String,
    /// `None` when the FMU has no `<CoSimulation>` element.
    pub model_identifier: Option<String>,
    pub can_handle_variable_step: bool,
    /// Whether the FMU takes input derivatives (fmi2SetRealInputDerivatives).
    pub can_interpolate_inputs: bool,
    /// The highest order of fmi2GetRealOutputDerivatives (0: none).
    pub max_output_derivative_order: u32,
    /// Whether the FMU can save and restore its state (canGetAndSetFMUstate).
    pub can_get_and_set_state: bool,
    pub variables: Vec<Variable>,
}

impl Description {
    pub fn read(dir: &Path) -> Result<Self, String> {
        let path = dir.join("modelDescription.xml");
        let xml = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&xml).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn parse(xml: &str) -> Result<Self, String> {
        let mut reader = Reader::from_str(xml);
        let mut description = Description {
            fmi_version: String::new(),
            model_name: String::new(),
            guid: String::new(),
            model_identifier: None,
            can_handle_variable_step: false,
            can_interpolate_inputs: false,
            max_output_derivative_order: 0,
            can_get_and_set_state: false,
            variables: Vec::new(),
        };
        // The <ScalarVariable> being read: its type comes from the child element.
        let mut open: Option<Variable> = None;
        loop {
            let event = reader.read_event().map_err(|e| e.to_string())?;
            match &event {
                Event::Start(e) | Event::Empty(e) => {
                    let empty = matches!(event, Event::Empty(_));
                    match e.local_name().as_ref() {
                        b"fmiModelDescription" => {
                            description.fmi_version =
                                attribute(e, "fmiVersion")?.unwrap_or_default();
                            description.model_name = attribute(e, "modelName")?.unwrap_or_default();
                            description.guid = attribute(e, "guid")?.unwrap_or_default();
                        }
                        b"CoSimulation" => {
                            description.model_identifier = attribute(e, "modelIdentifier")?;
                            description.can_handle_variable_step =
                                attribute(e, "canHandleVariableCommunicationStepSize")?
                                    .is_some_and(|v| v == "true");
                            description.can_interpolate_inputs =
                                attribute(e, "canInterpolateInputs")?.is_some_and(|v| v == "true");
                            description.can_get_and_set_state =
                                attribute(e, "canGetAndSetFMUstate")?.is_some_and(|v| v == "true");
                            description.max_output_derivative_order =
                                attribute(e, "maxOutputDerivativeOrder")?
                                    .map_or(Ok(0), |v| v.parse())
                                    .map_err(|_| {
                                        "maxOutputDerivativeOrder is not a whole number"
                                    })?;
                        }
                        b"ScalarVariable" => {
                            let variable = scalar_variable(e)?;
                            if empty {
                                return Err(format!(
                                    "variable {} has no type element",
                                    variable.name
                                ));
                            }
                            open = Some(variable);
                        }
                        tag @ (b"Real" | b"Integer" | b"Boolean" | b"String" | b"Enumeration") => {
                            if let Some(variable) = open.as_mut() {
                                variable.base_type = match tag {
                                    b"Real" => BaseType::Real,
                                    b"Integer" => BaseType::Integer,
                                    b"Boolean" => BaseType::Boolean,
                                    b"String" => BaseType::String,
                                    _ => BaseType::Enumeration,
                                };
                                variable.start = attribute(e, "start")?;
                                variable.min = attribute(e, "min")?;
                                variable.max = attribute(e, "max")?;
                                variable.declared_type = attribute(e, "declaredType")?;
                            }
                        }
                        _ => {}
                    }
                }
                Event::End(e) if e.local_name().as_ref() == b"ScalarVariable" => {
                    description.variables.extend(open.take());
                }
                Event::Eof => break,
                _ => {}
            }
        }
        if description.fmi_version != "2.0" {
            return Err(format!(
                "fmiVersion is {:?}; this runner loads FMI 2.0 FMUs",
                description.fmi_version
            ));
        }
        Ok(description)
    }

    pub fn variable(&self, name: &str) -> Result<&Variable, String> {
        self.variables
            .iter()
            .find(|v| v.name == name)
            .ok_or_else(|| format!("the FMU has no variable named {name:?}"))
    }
}

fn scalar_variable(e: &BytesStart) -> Result<Variable, String> {
    let name = attribute(e, "name")?.ok_or("a ScalarVariable without a name")?;
    let value_reference = attribute(e, "valueReference")?
        .ok_or_else(|| format!("variable {name} has no valueReference"))?
        .parse()
        .map_err(|_| format!("variable {name}: valueReference is not an unsigned integer"))?;
    Ok(Variable {
        value_reference,
        base_type: BaseType::Real,
        causality: attribute(e, "causality")?.unwrap_or_else(|| "local".into()),
        variability: attribute(e, "variability")?.unwrap_or_else(|| "continuous".into()),
        start: None,
        min: None,
        max: None,
        declared_type: None,
        description: attribute(e, "description")?,
        name,
    })
}

fn attribute(e: &BytesStart, name: &str) -> Result<Option<String>, String> {
    for attr in e.attributes() {
        let attr = attr.map_err(|err| err.to_string())?;
        if attr.key.as_ref() == name.as_bytes() {
            let value = attr.unescape_value().map_err(|err| err.to_string())?;
            return Ok(Some(value.into_owned()));
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{g}">
  <CoSimulation modelIdentifier="Mid" canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="true" maxOutputDerivativeOrder="2"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="3" causality="parameter" variability="fixed">
      <Real start="1.5" min="0"/>
    </ScalarVariable>
    <ScalarVariable name="n" valueReference="7" causality="output"><Integer/></ScalarVariable>
    <ScalarVariable name="a&amp;b" valueReference="8"><Boolean start="true"/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"#;

    #[test]
    fn reads_identity_and_variables() {
        let d = Description::parse(XML).unwrap();
        assert_eq!(
            (d.guid.as_str(), d.model_identifier.as_deref()),
            ("{g}", Some("Mid"))
        );
        assert!(d.can_handle_variable_step && d.can_interpolate_inputs);
        assert_eq!(d.max_output_derivative_order, 2);
        let x = d.variable("x").unwrap();
        assert_eq!((x.value_reference, x.base_type), (3, BaseType::Real));
        assert_eq!(
            (x.start.as_deref(), x.min.as_deref(), x.max.as_deref()),
            (Some("1.5"), Some("0"), None)
        );
        assert_eq!(d.variable("n").unwrap().base_type, BaseType::Integer);
        assert_eq!(d.variable("n").unwrap().causality, "output");
        assert_eq!(d.variable("a&b").unwrap().base_type, BaseType::Boolean);
        assert_eq!(d.variable("a&b").unwrap().causality, "local");
        assert!(d.variable("y").unwrap_err().contains("\"y\""));
    }

    #[test]
    fn refuses_other_fmi_versions() {
        let xml = XML.replace("fmiVersion=\"2.0\"", "fmiVersion=\"3.0\"");
        assert!(Description::parse(&xml).unwrap_err().contains("FMI 2.0"));
    }
}
