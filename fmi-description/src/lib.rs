//! Reads an FMI 2.0 or 3.0 `modelDescription.xml`, with quick-xml: the GUID (FMI 3.0's
//! instantiation token), the interfaces' model identifiers and capabilities, the states and
//! event indicators, and the variables with their Enumeration items. The project's one
//! reader of it in Rust: the runner loads FMUs with it, and xtask's jobs read the FMU's own
//! descriptions with it.

use std::collections::BTreeMap;
use std::path::Path;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use serde::Serialize;

/// The base type of a scalar variable, in FMI 2.0's words: FMI 3.0's Float64 is a Real and
/// its Int32 an Integer; its other types are [`BaseType::Unsupported`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseType {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
    /// A type the runner neither sets nor reads (FMI 3.0's Float32, Int64, Binary, …, and
    /// arrays); `fmi_type` names it.
    Unsupported,
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
    /// Its unit as declared on the variable (FMI 2.0's type element, FMI 3.0's variable).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    pub declared_type: Option<String>,
    pub description: Option<String>,
    /// The element that declares the type, as the standard names it (`Real`, `Float64`,
    /// `Int64`, …; an array's with `[]`).
    pub fmi_type: String,
    /// The state this variable is the time derivative of (its `derivative` attribute):
    /// FMI 2.0's 1-based variable index while reading, the state's value reference once
    /// read; FMI 3.0's value reference.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub derivative_of: Option<u32>,
    /// An Enumeration's items by name, from its declared type: what a spec may set it by.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub items: BTreeMap<String, i64>,
}

/// The Enumeration types of `<TypeDefinitions>` being read: FMI 2.0's
/// `<SimpleType name><Enumeration><Item name value/>…`, FMI 3.0's
/// `<EnumerationType name><Item name value/>…`.
#[derive(Default)]
struct EnumerationTypes {
    open: Option<String>,
    items: BTreeMap<String, BTreeMap<String, i64>>,
}

impl EnumerationTypes {
    /// Reads the elements of a type definition; false for any other element.
    fn read(&mut self, e: &BytesStart, empty: bool) -> Result<bool, String> {
        match e.local_name().as_ref() {
            b"SimpleType" | b"EnumerationType" if !empty => self.open = attribute(e, "name")?,
            b"Item" => {
                let (Some(open), Some(name), Some(value)) = (
                    self.open.as_ref(),
                    attribute(e, "name")?,
                    attribute(e, "value")?,
                ) else {
                    return Ok(true);
                };
                let value = value
                    .trim()
                    .parse::<i64>()
                    .map_err(|_| format!("the item {name} of type {open} has value {value:?}"))?;
                self.items
                    .entry(open.clone())
                    .or_default()
                    .insert(name, value);
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    fn close(&mut self, tag: &[u8]) {
        if matches!(tag, b"SimpleType" | b"EnumerationType") {
            self.open = None;
        }
    }

    /// Each Enumeration variable's items, from its declared type.
    fn give_items(&self, variables: &mut [Variable]) {
        for v in variables
            .iter_mut()
            .filter(|v| v.base_type == BaseType::Enumeration)
        {
            if let Some(items) = v.declared_type.as_ref().and_then(|t| self.items.get(t)) {
                v.items = items.clone();
            }
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
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
    /// FMI 3.0: whether the FMU has an event mode its master may use (hasEventMode).
    pub has_event_mode: bool,
    /// The names of the FMU's log categories (`<LogCategories>`), in its order.
    pub log_categories: Vec<String>,
    /// Whether the FMU has a `<ModelExchange>` interface.
    pub has_model_exchange: bool,
    /// The Model Exchange interface's model identifier (`None` without one).
    pub exchange_identifier: Option<String>,
    /// The number of continuous states (the model structure's derivatives) and of event
    /// indicators, which a Model Exchange master integrates and watches.
    pub continuous_states: usize,
    pub event_indicators: usize,
    pub variables: Vec<Variable>,
    /// The tool that wrote the FMU (`generationTool`), if it says.
    pub generation_tool: Option<String>,
    /// The outputs of the model structure, each with the variables it depends on directly
    /// (`None`: on every input, as the standard says of an output without a list).
    pub output_dependencies: Vec<OutputDependencies>,
    /// The continuous states in the order Model Exchange's state vector has them (the
    /// model structure's derivatives), each with its derivative; shorter than
    /// `continuous_states` when a derivative does not name its state.
    pub states: Vec<ContinuousState>,
    /// Whether the Model Exchange interface gives directional derivatives
    /// (providesDirectionalDerivative, FMI 3.0's providesDirectionalDerivatives).
    pub exchange_directional_derivatives: bool,
}

/// A continuous state and its derivative, by value reference.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct ContinuousState {
    pub value_reference: u32,
    pub derivative: u32,
}

/// An output of the model structure and what it depends on directly, by value reference.
#[derive(Clone, Debug, Default, Serialize)]
pub struct OutputDependencies {
    pub value_reference: u32,
    pub dependencies: Option<Vec<u32>>,
}

impl Variable {
    /// A parameter the master may change after initialisation (in event mode where the
    /// FMU has one).
    pub fn is_tunable(&self) -> bool {
        self.causality == "parameter" && self.variability == "tunable"
    }
}

impl Description {
    /// The value references of the tunable parameters, sorted.
    pub fn tunable(&self) -> Vec<u32> {
        let mut found: Vec<u32> = self
            .variables
            .iter()
            .filter(|v| v.is_tunable())
            .map(|v| v.value_reference)
            .collect();
        found.sort_unstable();
        found.dedup();
        found
    }

    pub fn read(dir: &Path) -> Result<Self, String> {
        let path = dir.join("modelDescription.xml");
        let xml = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&xml).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn parse(xml: &str) -> Result<Self, String> {
        let mut reader = Reader::from_str(xml);
        let mut parse = Parse::default();
        loop {
            let event = reader.read_event().map_err(|e| e.to_string())?;
            match &event {
                Event::Start(e) => parse.start(e, false)?,
                Event::Empty(e) => parse.start(e, true)?,
                Event::End(e) => parse.end(e.local_name().as_ref()),
                Event::Eof => break,
                _ => {}
            }
        }
        let Parse {
            mut description,
            enumerations,
            fmi2_outputs,
            derivatives,
            ..
        } = parse;
        enumerations.give_items(&mut description.variables);
        description.resolve_fmi2_outputs(&fmi2_outputs)?;
        description.resolve_states(&derivatives);
        match description.fmi_version.as_str() {
            "2.0" => {}
            v if v.starts_with("3.") => description.refuse_clocks()?,
            v => {
                return Err(format!(
                    "an FMI {v} FMU (fmiVersion={v:?}); this runner loads FMI 2.0 and FMI 3.0 FMUs"
                ))
            }
        }
        Ok(description)
    }

    /// FMI 2.0's outputs and their dependencies, given by the 1-based index of each
    /// variable among the ScalarVariables, as value references.
    fn resolve_fmi2_outputs(
        &mut self,
        outputs: &[(usize, Option<Vec<usize>>)],
    ) -> Result<(), String> {
        let reference = |index: usize| {
            index
                .checked_sub(1)
                .and_then(|i| self.variables.get(i))
                .map(|v| v.value_reference)
                .ok_or_else(|| {
                    format!("ModelStructure names variable index {index}, which there is not")
                })
        };
        let mut resolved = Vec::new();
        for (index, dependencies) in outputs {
            resolved.push(OutputDependencies {
                value_reference: reference(*index)?,
                dependencies: match dependencies {
                    None => None,
                    Some(list) => Some(
                        list.iter()
                            .map(|&d| reference(d))
                            .collect::<Result<_, _>>()?,
                    ),
                },
            });
        }
        self.output_dependencies.extend(resolved);
        Ok(())
    }

    /// The states, from their derivatives (FMI 2.0: by 1-based variable index, FMI 3.0:
    /// by value reference), each derivative's `derivative` attribute naming its state.
    fn resolve_states(&mut self, derivatives: &[u32]) {
        let fmi2 = self.fmi_version == "2.0";
        if fmi2 {
            let variables = self.variables.clone();
            for variable in &mut self.variables {
                variable.derivative_of = variable
                    .derivative_of
                    .and_then(|i| variables.get((i as usize).checked_sub(1)?))
                    .map(|state| state.value_reference);
            }
        }
        for &derivative in derivatives {
            let found = if fmi2 {
                (derivative as usize)
                    .checked_sub(1)
                    .and_then(|i| self.variables.get(i))
            } else {
                self.variables
                    .iter()
                    .find(|v| v.value_reference == derivative)
            };
            let Some((derivative, Some(state))) =
                found.map(|v| (v.value_reference, v.derivative_of))
            else {
                break;
            };
            self.states.push(ContinuousState {
                value_reference: state,
                derivative,
            });
        }
    }

    fn read_root(&mut self, e: &BytesStart) -> Result<(), String> {
        self.fmi_version = attribute(e, "fmiVersion")?.unwrap_or_default();
        self.model_name = attribute(e, "modelName")?.unwrap_or_default();
        self.generation_tool = attribute(e, "generationTool")?;
        let token = if self.fmi_version.starts_with("3.") {
            "instantiationToken"
        } else {
            "guid"
        };
        self.guid = attribute(e, token)?.unwrap_or_default();
        if let Some(count) = attribute(e, "numberOfEventIndicators")? {
            self.event_indicators = count
                .parse()
                .map_err(|_| "numberOfEventIndicators is not a whole number")?;
        }
        Ok(())
    }

    fn read_co_simulation(&mut self, e: &BytesStart) -> Result<(), String> {
        let flag = |name: &str| -> Result<bool, String> {
            Ok(attribute(e, name)?.is_some_and(|v| v == "true"))
        };
        self.model_identifier = attribute(e, "modelIdentifier")?;
        self.can_handle_variable_step = flag("canHandleVariableCommunicationStepSize")?;
        self.can_interpolate_inputs = flag("canInterpolateInputs")?;
        // FMI 2.0 spells it FMUstate, FMI 3.0 FMUState.
        self.can_get_and_set_state = flag("canGetAndSetFMUstate")? || flag("canGetAndSetFMUState")?;
        self.has_event_mode = flag("hasEventMode")?;
        self.max_output_derivative_order = attribute(e, "maxOutputDerivativeOrder")?
            .map_or(Ok(0), |v| v.parse())
            .map_err(|_| "maxOutputDerivativeOrder is not a whole number")?;
        Ok(())
    }

    /// Clocks need a scheduling master the runner is not: an FMU with one is refused.
    fn refuse_clocks(&self) -> Result<(), String> {
        match self.variables.iter().find(|v| v.fmi_type == "Clock") {
            Some(clock) => Err(format!(
                "the FMU declares the clock {:?}; the runner does not run FMUs with clocks",
                clock.name
            )),
            None => Ok(()),
        }
    }

    pub fn variable(&self, name: &str) -> Result<&Variable, String> {
        self.variables
            .iter()
            .find(|v| v.name == name)
            .ok_or_else(|| format!("the FMU has no variable named {name:?}"))
    }
}

/// A variable's name, value reference, causality, variability and description, with the
/// type given (FMI 2.0 reads it from the child element next).
fn variable(e: &BytesStart, base_type: BaseType, fmi_type: &str) -> Result<Variable, String> {
    let name = attribute(e, "name")?.ok_or("a variable without a name")?;
    let value_reference = attribute(e, "valueReference")?
        .ok_or_else(|| format!("variable {name} has no valueReference"))?
        .parse()
        .map_err(|_| format!("variable {name}: valueReference is not an unsigned integer"))?;
    // Only floating-point variables default to continuous.
    let continuous = base_type == BaseType::Real || fmi_type == "Float32";
    Ok(Variable {
        value_reference,
        base_type,
        causality: attribute(e, "causality")?.unwrap_or_else(|| "local".into()),
        variability: attribute(e, "variability")?
            .unwrap_or_else(|| if continuous { "continuous" } else { "discrete" }.into()),
        start: None,
        min: None,
        max: None,
        unit: None,
        declared_type: None,
        description: attribute(e, "description")?,
        fmi_type: fmi_type.into(),
        derivative_of: None,
        items: BTreeMap::new(),
        name,
    })
}

fn fmi2_type(tag: &[u8]) -> BaseType {
    match tag {
        b"Real" => BaseType::Real,
        b"Integer" => BaseType::Integer,
        b"Boolean" => BaseType::Boolean,
        b"String" => BaseType::String,
        _ => BaseType::Enumeration,
    }
}

/// An FMI 3.0 variable: its element names its type, its attributes carry the rest.
fn fmi3_variable(e: &BytesStart, tag: &[u8]) -> Result<Variable, String> {
    let fmi_type = String::from_utf8_lossy(tag).into_owned();
    let base_type = match tag {
        b"Float64" => BaseType::Real,
        b"Int32" => BaseType::Integer,
        b"Boolean" => BaseType::Boolean,
        b"String" => BaseType::String,
        b"Enumeration" => BaseType::Enumeration,
        _ => BaseType::Unsupported,
    };
    let mut variable = variable(e, base_type, &fmi_type)?;
    variable.start = attribute(e, "start")?;
    variable.min = attribute(e, "min")?;
    variable.max = attribute(e, "max")?;
    variable.unit = attribute(e, "unit")?;
    variable.declared_type = attribute(e, "declaredType")?;
    variable.derivative_of = optional_number(e, "derivative")?;
    Ok(variable)
}

/// An attribute that, where present, must be a whole number ≥ 0.
fn optional_number(e: &BytesStart, name: &str) -> Result<Option<u32>, String> {
    attribute(e, name)?
        .map(|v| whole_number(Some(v), name))
        .transpose()
}

/// An attribute that must be a whole number ≥ 0 of type `T`.
fn whole_number<T: std::str::FromStr>(value: Option<String>, what: &str) -> Result<T, String> {
    value
        .as_deref()
        .and_then(|v| v.trim().parse().ok())
        .ok_or_else(|| format!("{what} must be a whole number ≥ 0, got {value:?}"))
}

/// A space-separated list of whole numbers (`dependencies`); `None` without the attribute.
fn whole_numbers<T: std::str::FromStr>(value: Option<String>) -> Result<Option<Vec<T>>, String> {
    value
        .map(|list| {
            list.split_whitespace()
                .map(|v| {
                    v.parse()
                        .map_err(|_| format!("dependencies {list:?}: {v:?} is not a whole number"))
                })
                .collect()
        })
        .transpose()
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

/// Where a reading of `modelDescription.xml` is: the description so far, and the
/// element it is inside.
#[derive(Default)]
struct Parse {
    description: Description,
    /// Inside FMI 2.0's <ModelStructure><Derivatives>, whose <Unknown>s are the states.
    in_derivatives: bool,
    /// Inside FMI 2.0's <ModelStructure><Outputs>, whose <Unknown>s name their variables
    /// (and dependencies) by index, resolved once every variable is read.
    in_outputs: bool,
    fmi2_outputs: Vec<(usize, Option<Vec<usize>>)>,
    /// The derivatives of the model structure: FMI 2.0's indices, FMI 3.0's value
    /// references.
    derivatives: Vec<u32>,
    /// The variable being read: an FMI 2.0 <ScalarVariable> takes its type from its child
    /// element; an FMI 3.0 one may have <Dimension> (an array) and <Alias> children.
    open: Option<Variable>,
    /// The element that closes an open FMI 3.0 variable.
    open_tag: Vec<u8>,
    in_variables: bool,
    enumerations: EnumerationTypes,
}

impl Parse {
    /// An element opens (`empty`: and closes at once).
    fn start(&mut self, e: &BytesStart, empty: bool) -> Result<(), String> {
        if !self.in_variables && self.enumerations.read(e, empty)? {
            return Ok(());
        }
        let tag = e.local_name();
        let fmi3 = self.description.fmi_version.starts_with("3.");
        let description = &mut self.description;
        match tag.as_ref() {
            b"fmiModelDescription" => description.read_root(e)?,
            b"CoSimulation" => description.read_co_simulation(e)?,
            b"ModelExchange" => {
                description.has_model_exchange = true;
                description.exchange_directional_derivatives = attribute(
                    e,
                    if fmi3 {
                        "providesDirectionalDerivatives"
                    } else {
                        "providesDirectionalDerivative"
                    },
                )?
                .is_some_and(|v| v == "true");
                description.exchange_identifier = attribute(e, "modelIdentifier")?;
            }
            b"Derivatives" if !fmi3 => self.in_derivatives = !empty,
            b"Outputs" if !fmi3 => self.in_outputs = !empty,
            b"Unknown" if self.in_derivatives => {
                description.continuous_states += 1;
                self.derivatives
                    .push(whole_number(attribute(e, "index")?, "Unknown index")?);
            }
            b"Unknown" if self.in_outputs => {
                let index = whole_number(attribute(e, "index")?, "Unknown index")?;
                let dependencies = whole_numbers(attribute(e, "dependencies")?)?;
                self.fmi2_outputs.push((index, dependencies));
            }
            b"Output" if fmi3 && !self.in_variables => {
                description.output_dependencies.push(OutputDependencies {
                    value_reference: whole_number(
                        attribute(e, "valueReference")?,
                        "Output valueReference",
                    )?,
                    dependencies: whole_numbers(attribute(e, "dependencies")?)?,
                });
            }
            b"ContinuousStateDerivative" if fmi3 && !self.in_variables => {
                description.continuous_states += 1;
                self.derivatives.push(whole_number(
                    attribute(e, "valueReference")?,
                    "ContinuousStateDerivative valueReference",
                )?);
            }
            b"EventIndicator" if fmi3 && !self.in_variables => {
                description.event_indicators += 1;
            }
            b"ModelVariables" => self.in_variables = !empty,
            b"Category" if !self.in_variables => {
                description.log_categories.extend(attribute(e, "name")?);
            }
            tag if fmi3 => self.start_fmi3_variable(e, tag, empty)?,
            tag => self.start_fmi2_variable(e, tag, empty)?,
        }
        Ok(())
    }

    /// FMI 2.0: a <ScalarVariable> and its type element.
    fn start_fmi2_variable(
        &mut self,
        e: &BytesStart,
        tag: &[u8],
        empty: bool,
    ) -> Result<(), String> {
        match tag {
            b"ScalarVariable" => {
                let variable = variable(e, BaseType::Real, "Real")?;
                if empty {
                    return Err(format!("variable {} has no type element", variable.name));
                }
                self.open = Some(variable);
            }
            b"Real" | b"Integer" | b"Boolean" | b"String" | b"Enumeration" => {
                if let Some(variable) = self.open.as_mut() {
                    variable.base_type = fmi2_type(tag);
                    variable.fmi_type = String::from_utf8_lossy(tag).into_owned();
                    variable.start = attribute(e, "start")?;
                    variable.min = attribute(e, "min")?;
                    variable.max = attribute(e, "max")?;
                    variable.unit = attribute(e, "unit")?;
                    variable.declared_type = attribute(e, "declaredType")?;
                    variable.derivative_of = optional_number(e, "derivative")?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// FMI 3.0: a variable element, and its <Dimension> and <Alias> children.
    fn start_fmi3_variable(
        &mut self,
        e: &BytesStart,
        tag: &[u8],
        empty: bool,
    ) -> Result<(), String> {
        match tag {
            b"Dimension" => {
                if let Some(variable) = self.open.as_mut() {
                    variable.base_type = BaseType::Unsupported;
                    if !variable.fmi_type.ends_with("[]") {
                        variable.fmi_type.push_str("[]");
                    }
                }
            }
            b"Alias" => {
                if let (Some(variable), Some(name)) = (self.open.as_ref(), attribute(e, "name")?) {
                    let alias = Variable {
                        name,
                        description: attribute(e, "description")?,
                        ..variable.clone()
                    };
                    self.description.variables.push(alias);
                }
            }
            tag if self.in_variables && self.open.is_none() => {
                let variable = fmi3_variable(e, tag)?;
                if empty {
                    self.description.variables.push(variable);
                } else {
                    self.open = Some(variable);
                    self.open_tag = tag.to_vec();
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// An element closes.
    fn end(&mut self, tag: &[u8]) {
        match tag {
            b"SimpleType" | b"EnumerationType" => self.enumerations.close(tag),
            b"ModelVariables" => self.in_variables = false,
            b"Derivatives" => self.in_derivatives = false,
            b"Outputs" => self.in_outputs = false,
            b"ScalarVariable" => self.description.variables.extend(self.open.take()),
            tag if self.open.is_some() && tag == self.open_tag.as_slice() => {
                self.description.variables.extend(self.open.take());
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{g}">
  <CoSimulation modelIdentifier="Mid" canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="true" maxOutputDerivativeOrder="2"/>
  <TypeDefinitions><SimpleType name="Way"><Enumeration><Item name="up" value="1"/>
    <Item name="down" value="-3"/></Enumeration></SimpleType></TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="3" causality="parameter" variability="fixed">
      <Real start="1.5" min="0"/>
    </ScalarVariable>
    <ScalarVariable name="n" valueReference="7" causality="output"><Integer/></ScalarVariable>
    <ScalarVariable name="a&amp;b" valueReference="8"><Boolean start="true"/></ScalarVariable>
    <ScalarVariable name="w" valueReference="9" causality="parameter" variability="fixed">
      <Enumeration declaredType="Way" start="1"/></ScalarVariable>
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
        let w = d.variable("w").unwrap();
        assert_eq!(
            (w.base_type, w.items.get("down")),
            (BaseType::Enumeration, Some(&-3))
        );
        assert!(d.variable("y").unwrap_err().contains("\"y\""));
    }

    /// The mechanism's own descriptions, both versions: the same six states in the same
    /// order, each with its derivative, and directional derivatives under Model Exchange.
    #[test]
    fn reads_the_states_and_their_derivatives() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../modelDescription");
        let names = |d: &Description| -> Vec<(String, String)> {
            let name = |vr: u32| {
                d.variables
                    .iter()
                    .find(|v| v.value_reference == vr)
                    .map(|v| v.name.clone())
                    .unwrap()
            };
            d.states
                .iter()
                .map(|s| (name(s.value_reference), name(s.derivative)))
                .collect()
        };
        let fmi2 = Description::read(&root).unwrap();
        let fmi3 = Description::read(&root.join("fmi3")).unwrap();
        let expected: Vec<(String, String)> = [
            "phi1",
            "loop_angle",
            "phi4",
            "omega1",
            "loop_speed",
            "omega4",
        ]
        .iter()
        .map(|s| (s.to_string(), format!("der({s})")))
        .collect();
        for d in [&fmi2, &fmi3] {
            assert_eq!(names(d), expected);
            assert_eq!(d.states.len(), d.continuous_states);
            assert!(d.exchange_directional_derivatives);
        }
    }

    #[test]
    fn refuses_other_fmi_versions() {
        let xml = XML.replace("fmiVersion=\"2.0\"", "fmiVersion=\"1.0\"");
        assert!(Description::parse(&xml)
            .unwrap_err()
            .contains("FMI 2.0 and FMI 3.0"));
    }

    const XML3: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="{t}">
  <CoSimulation modelIdentifier="Mid" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUState="true" hasEventMode="true" maxOutputDerivativeOrder="1"/>
  <TypeDefinitions><Float64Type name="Angle" unit="rad"/>
    <EnumerationType name="Way"><Item name="up" value="1"/><Item name="down" value="2"/>
    </EnumerationType></TypeDefinitions>
  <LogCategories><Category name="logStatusError"/><Category name="logEvents"/></LogCategories>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent"/>
    <Float64 name="x" valueReference="3" causality="parameter" variability="tunable"
      start="1.5" min="0" declaredType="Angle"/>
    <Int32 name="n" valueReference="7" causality="output"/>
    <Enumeration name="e" valueReference="8" causality="parameter" start="2"
      declaredType="Way">
      <Alias name="e_alias"/>
    </Enumeration>
    <Boolean name="b" valueReference="9" causality="input" start="true"/>
    <Float32 name="f" valueReference="10"/>
    <Float64 name="v" valueReference="11" start="0 0"><Dimension start="2"/></Float64>
  </ModelVariables>
</fmiModelDescription>"#;

    #[test]
    fn reads_an_fmi3_description() {
        let d = Description::parse(XML3).unwrap();
        assert_eq!((d.guid.as_str(), d.fmi_version.as_str()), ("{t}", "3.0"));
        assert!(d.can_handle_variable_step && d.can_get_and_set_state && d.has_event_mode);
        assert!(!d.can_interpolate_inputs);
        assert_eq!(d.max_output_derivative_order, 1);
        assert_eq!(d.log_categories, ["logStatusError", "logEvents"]);
        let x = d.variable("x").unwrap();
        assert_eq!((x.value_reference, x.base_type), (3, BaseType::Real));
        assert_eq!(
            (x.start.as_deref(), x.min.as_deref()),
            (Some("1.5"), Some("0"))
        );
        assert_eq!(
            (x.variability.as_str(), x.declared_type.as_deref()),
            ("tunable", Some("Angle"))
        );
        let n = d.variable("n").unwrap();
        assert_eq!(
            (n.base_type, n.variability.as_str()),
            (BaseType::Integer, "discrete")
        );
        assert_eq!(d.variable("e").unwrap().base_type, BaseType::Enumeration);
        assert_eq!(d.variable("e_alias").unwrap().value_reference, 8);
        let items: Vec<_> = d
            .variable("e_alias")
            .unwrap()
            .items
            .clone()
            .into_iter()
            .collect();
        assert_eq!(items, [("down".to_string(), 2), ("up".to_string(), 1)]);
        assert!(d.variable("n").unwrap().items.is_empty());
        assert_eq!(d.variable("b").unwrap().base_type, BaseType::Boolean);
        let f = d.variable("f").unwrap();
        assert_eq!(
            (f.base_type, f.fmi_type.as_str()),
            (BaseType::Unsupported, "Float32")
        );
        let v = d.variable("v").unwrap();
        assert_eq!(
            (v.base_type, v.fmi_type.as_str()),
            (BaseType::Unsupported, "Float64[]")
        );
        assert_eq!(d.variables.len(), 8);
    }

    #[test]
    fn refuses_an_fmi3_description_with_clocks() {
        let xml = XML3.replace(
            "<Float32 name=\"f\" valueReference=\"10\"/>",
            "<Clock name=\"tick\" valueReference=\"10\" causality=\"input\"/>",
        );
        let error = Description::parse(&xml).unwrap_err();
        assert!(
            error.contains("\"tick\"") && error.contains("clocks"),
            "{error}"
        );
    }

    #[test]
    fn outputs_name_what_they_depend_on_by_value_reference() {
        let fmi2 = XML.replace(
            "</ModelVariables>",
            "</ModelVariables><ModelStructure><Outputs><Unknown index=\"2\" dependencies=\"1 3\"/>\
             </Outputs></ModelStructure>",
        );
        let d = Description::parse(&fmi2).unwrap();
        assert_eq!(d.output_dependencies.len(), 1);
        let out = &d.output_dependencies[0];
        assert_eq!(
            (out.value_reference, out.dependencies.clone()),
            (7, Some(vec![3, 8]))
        );
        let fmi3 = r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="{t}"
            generationTool="a tool"><CoSimulation modelIdentifier="M"/><ModelVariables>
            <Float64 name="u" valueReference="1" causality="input" start="0"/>
            <Float64 name="y" valueReference="2" causality="output"/></ModelVariables>
            <ModelStructure><Output valueReference="2"/></ModelStructure></fmiModelDescription>"#;
        let d = Description::parse(fmi3).unwrap();
        assert_eq!(d.generation_tool.as_deref(), Some("a tool"));
        assert_eq!(d.output_dependencies[0].value_reference, 2);
        assert!(d.output_dependencies[0].dependencies.is_none());
        let beyond = fmi3.replace(
            "<Output valueReference=\"2\"",
            "<Output valueReference=\"4294967298\"",
        );
        assert!(Description::parse(&beyond)
            .unwrap_err()
            .contains("valueReference"));
        let wrong = fmi2.replace("index=\"2\"", "index=\"9\"");
        assert!(Description::parse(&wrong).unwrap_err().contains("index 9"));
    }
}
