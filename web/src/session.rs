//! One run of the mechanism as a page drives it: variables set by value reference, a
//! start, steps to the page's communication points, outputs read back. The experiment, the
//! start and the steps are the FMU's own, as the drivers assemble them for every master
//! ([`master_step`]): FMI 3.0 co-simulation steps with event mode and without early
//! return, so that a change point is crossed within the step and reported, never a stop.

use cyclic_mechanism::drivers::events::{EventHandling, Happening, StepEnd};
use cyclic_mechanism::drivers::master_step;
use cyclic_mechanism::drivers::{self, CoSimulation, Experiment, DEFAULT_TOLERANCE};
use cyclic_mechanism::model::linkage::LINKAGE_CLASSES;
use cyclic_mechanism::model::params::Rule;
use cyclic_mechanism::model::{self, PARAMETERS};
use cyclic_mechanism::plant::{Plant, Value};
use cyclic_mechanism::variables::{self, Causality, Slot, Twin, VarType, Variable};
use integrators::text::number;

/// How a completed step went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stepped {
    /// To its end, nothing met.
    Plain,
    /// To its end, over a change point (or more).
    OverChangePoint,
}

/// One run: the plant, and its driver once started.
#[derive(Clone, Debug, Default)]
pub struct Session {
    plant: Plant,
    driver: Option<CoSimulation>,
    experiment: Option<Experiment>,
    /// Change points crossed since the start.
    crossings: u32,
    /// The time of the last change point met, if any.
    last_crossing: Option<f64>,
}

/// Whether a parameter may change while the run goes on: one that moves neither the loop's
/// geometry (a length, which the current state would then no longer close) nor the start
/// (which has passed), nor the method (chosen when the driver starts).
pub fn is_live(variable: &Variable) -> bool {
    match variable.slot {
        Slot::Parameter(i) => {
            let name = PARAMETERS[i].name;
            let geometry = PARAMETERS[i].unit == "m";
            let start = name.ends_with("_0") || name.ends_with("_guess");
            !geometry && !start
        }
        Slot::BuiltinLaws | Slot::ChangePointBranch | Slot::Input(_) => true,
        Slot::Twin(Twin::ChangePointBranch) => true,
        _ => false,
    }
}

impl Session {
    pub fn new() -> Self {
        Self::default()
    }

    /// Set variable `vr` to `value`: a Real as it is, an Integer or Enumeration as a whole
    /// number, a Boolean as true when not 0. Before the start anything a master may set;
    /// after it, inputs and the parameters [`is_live`] admits.
    pub fn set(&mut self, vr: u32, value: f64) -> Result<(), String> {
        let variable = variables::variable(vr).ok_or(format!("no variable with reference {vr}"))?;
        let started = self.driver.is_some();
        if started && variable.causality() == Causality::Parameter && !is_live(variable) {
            return Err(format!(
                "{} fixes the loop's geometry, its start or its method: it takes effect from \
                 a new start",
                variable.name
            ));
        }
        let value = match variable.var_type() {
            VarType::Real => Value::Real(value),
            VarType::Boolean => Value::Boolean(value != 0.0),
            VarType::Integer | VarType::Enumeration => {
                if value.fract() != 0.0 || value.abs() > f64::from(i32::MAX) {
                    return Err(format!(
                        "{} = {value}: must be a whole number",
                        variable.name
                    ));
                }
                Value::Integer(value as i32)
            }
        };
        self.plant.set(vr, value, true).map_err(|e| e.to_string())
    }

    /// Start the run at `start` with relative `tolerance`, up to `stop` (none when it is
    /// not finite): the consistent start for the parameters set, or why there is none (a
    /// geometry that cannot close, for one).
    pub fn start(&mut self, tolerance: f64, start: f64, stop: f64) -> Result<(), String> {
        let stop = stop.is_finite().then_some(stop);
        let experiment = master_step::set_up(Some(tolerance), start, stop, DEFAULT_TOLERANCE)
            .map_err(|e| e.to_string())?;
        let driver = master_step::start(&mut self.plant, &experiment)
            .map_err(|e| format!("no start: {e}"))?;
        self.driver = Some(driver);
        self.experiment = Some(experiment);
        Ok(())
    }

    /// A step from `current` (the run's time, as the caller counts it) by `step`, as
    /// fmi3DoStep with event mode and no early return. A refused step leaves the run as
    /// it was, and says why.
    pub fn step(&mut self, current: f64, step: f64) -> Result<Stepped, String> {
        let (Some(driver), Some(experiment)) = (self.driver.as_mut(), self.experiment) else {
            return Err("the run has not started".into());
        };
        let mut happenings = Vec::new();
        let handling = EventHandling {
            event_mode: true,
            early_return: false,
        };
        let end = master_step::step_with_events(
            &mut self.plant,
            driver,
            &experiment,
            (current, step),
            handling,
            &mut happenings,
        )
        .map_err(|failure| failure.message().to_string())?;
        for happening in &happenings {
            if let Happening::Crossed { at, .. } = *happening {
                self.crossings += 1;
                self.last_crossing = Some(at);
            }
        }
        match end {
            StepEnd::Complete => Ok(Stepped::Plain),
            StepEnd::CompleteAfterEvent => Ok(Stepped::OverChangePoint),
            // Neither comes without early return; should one, the run is where it got to.
            StepEnd::ChangePointEvent | StepEnd::OutOfWork => {
                Err(format!("the step ended early at t = {}", self.plant.time()))
            }
        }
    }

    /// The value of variable `vr` now, as a number (a Boolean as 1 or 0).
    pub fn get(&self, vr: u32) -> Result<f64, String> {
        let activity = drivers::activity_of(&self.plant, self.driver.as_ref());
        match self.plant.get(vr, &activity).map_err(|e| e.to_string())? {
            Value::Real(x) => Ok(x),
            Value::Integer(n) => Ok(f64::from(n)),
            Value::Boolean(b) => Ok(f64::from(u8::from(b))),
        }
    }

    pub fn time(&self) -> f64 {
        self.plant.time()
    }

    pub fn started(&self) -> bool {
        self.driver.is_some()
    }

    /// Change points crossed since the start, and when the last was met.
    pub fn crossings(&self) -> (u32, Option<f64>) {
        (self.crossings, self.last_crossing)
    }

    /// |A2A3| − L now, for a page that wants to check the closure itself.
    pub fn residual(&self) -> f64 {
        self.plant.residual()
    }
}

/// Where the page offers a variable: the group its control stands in and, for a number,
/// the span its slider covers (the number field beside it takes anything the FMU admits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Control {
    pub group: &'static str,
    pub span: Option<(f64, f64)>,
}

/// The groups of controls (the page shows them in the order their first variable comes).
pub const GROUPS: [&str; 7] = [
    "Geometry (m)",
    "Springs and dampers",
    "Inertias (kg·m²)",
    "Input torques (N·m)",
    "Built-in laws",
    "Start",
    "Change points",
];

/// The control of a variable a user may set, if the page offers one: every parameter of
/// the mechanism, the inputs and the branch at a change point. The method, the
/// sensitivity slots and the built-in laws' switch (a check box of its own) have none.
pub fn control(v: &Variable) -> Option<Control> {
    let parameter = |i: usize| {
        let p = &PARAMETERS[i];
        let group = if p.name.starts_with("Mm_") || p.name.starts_with("Mr_") {
            GROUPS[4]
        } else if p.name.ends_with("_0") || p.name.ends_with("_guess") {
            GROUPS[5]
        } else if p.unit == "m" {
            GROUPS[0]
        } else if p.unit == "kg.m2" {
            GROUPS[2]
        } else {
            GROUPS[1]
        };
        Control {
            group,
            span: Some(slider_span(p.unit, p.rule)),
        }
    };
    match v.slot {
        Slot::Parameter(i) => Some(parameter(i)),
        Slot::Input(_) => Some(Control {
            group: GROUPS[3],
            span: Some(slider_span(v.unit, model::params::INPUT_RULE)),
        }),
        Slot::ChangePointBranch => Some(Control {
            group: GROUPS[6],
            span: None,
        }),
        _ => None,
    }
}

/// A slider's span: the size of the unit's quantities in a mechanism of this one's scale,
/// on the side of zero the rule admits (the number field reaches the rest of the range).
fn slider_span(unit: &str, rule: Rule) -> (f64, f64) {
    let size = match unit {
        "m" | "kg.m2" => 2.0,
        "N.m/rad" => 500.0,
        "N.m" => 200.0,
        "N.m.s/rad" | "rad/s" => 20.0,
        "N.m.s2/rad2" => 5.0,
        "rad" => std::f64::consts::PI,
        _ => 1.0,
    };
    match rule {
        Rule::Finite(_) => (-size, size),
        Rule::NonNegative(_) => (0.0, size),
        Rule::Positive(..) => (size / 100.0, size),
    }
}

/// The variables as a JSON array: name, value reference, causality, type, unit,
/// description, range and start where they have them, whether a running session takes a
/// change ([`is_live`]), and the page's control ([`control`]: its group and slider span).
pub fn variables_json() -> String {
    let items: Vec<String> = variables::variables()
        .map(|(vr, v)| {
            let mut fields = vec![
                format!("\"name\":{}", quoted(v.name)),
                format!("\"vr\":{vr}"),
                format!("\"causality\":{}", quoted(causality(v.causality()))),
                format!("\"type\":{}", quoted(v.var_type().as_str())),
                format!("\"unit\":{}", quoted(v.unit)),
                format!("\"description\":{}", quoted(v.description)),
                format!("\"live\":{}", is_live(&v)),
            ];
            if let Some((low, high)) = v.range() {
                fields.push(format!(
                    "\"min\":{},\"max\":{}",
                    json_number(low),
                    json_number(high)
                ));
            }
            if let Some(start) = v.start() {
                fields.push(format!("\"start\":{}", json_number(start)));
            }
            if let Some(control) = control(&v) {
                fields.push(format!("\"group\":{}", quoted(control.group)));
                if let Some((low, high)) = control.span {
                    fields.push(format!(
                        "\"span\":[{},{}]",
                        json_number(low),
                        json_number(high)
                    ));
                }
            }
            if let Some(items) = enumeration_items(&v) {
                let named: Vec<String> = items
                    .iter()
                    .map(|(name, value, _)| format!("\"{value}\":{}", quoted(name)))
                    .collect();
                fields.push(format!("\"items\":{{{}}}", named.join(",")));
            }
            format!("{{{}}}", fields.join(","))
        })
        .collect();
    format!("[{}]", items.join(","))
}

/// An Enumeration's items (name, value, description), as the model description lists them.
fn enumeration_items(v: &Variable) -> Option<&'static [(&'static str, i32, &'static str)]> {
    match v.declared_type()? {
        variables::SOLVER_TYPE => Some(&variables::SOLVER_ITEMS),
        variables::LINKAGE_TYPE => Some(&LINKAGE_CLASSES),
        variables::BRANCH_TYPE => Some(&variables::BRANCHES),
        _ => None,
    }
}

fn causality(c: Causality) -> &'static str {
    match c {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::Local => "local",
    }
}

/// A number as JSON has them: the infinite bounds of a range as the largest finite ones.
fn json_number(x: f64) -> String {
    if x.is_finite() {
        number(x)
    } else if x > 0.0 {
        format!("{:e}", f64::MAX)
    } else {
        format!("{:e}", f64::MIN)
    }
}

/// A JSON string: quotes, backslashes and control characters escaped.
fn quoted(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vr(name: &str) -> u32 {
        variables::value_reference(name).expect("a variable of the table")
    }

    #[test]
    fn a_run_steps_and_reports_its_outputs() {
        let mut s = Session::new();
        s.start(1e-8, 0.0, f64::INFINITY).unwrap();
        let mut t = 0.0;
        for k in 1..=100 {
            let next = f64::from(k) * 0.01;
            assert_eq!(s.step(t, next - t), Ok(Stepped::Plain));
            t = next;
        }
        assert!(
            s.get(vr("omega2")).unwrap() > 0.5,
            "the built-in motor turns the crank"
        );
        assert!(s.get(vr("n_steps")).unwrap() > 0.0);
        assert!(s.residual().abs() < 1e-9);
    }

    #[test]
    fn a_geometry_that_cannot_close_is_refused_with_its_reason() {
        let mut s = Session::new();
        s.set(vr("L"), 2.0).unwrap();
        let error = s.start(1e-8, 0.0, f64::INFINITY).unwrap_err();
        assert!(error.starts_with("no start: "), "{error}");
        assert!(!s.started());
        assert!(s.step(0.0, 0.01).is_err());
    }

    #[test]
    fn a_running_session_takes_springs_and_torques_but_not_lengths() {
        let mut s = Session::new();
        s.start(1e-8, 0.0, f64::INFINITY).unwrap();
        s.step(0.0, 0.1).unwrap();
        let before = s.clone();
        s.set(vr("k34"), 10.0).unwrap();
        s.set(vr("M_r"), 5.0).unwrap();
        s.set(vr("builtin_laws"), 0.0).unwrap();
        let error = s.set(vr("L"), 0.6).unwrap_err();
        assert!(error.contains("L fixes the loop's geometry"), "{error}");
        let mut unchanged = before.clone();
        unchanged.step(0.1, 0.1).unwrap();
        s.step(0.1, 0.1).unwrap();
        assert_ne!(s.get(vr("phi4")), unchanged.get(vr("phi4")));
    }

    #[test]
    fn a_change_point_linkage_is_crossed_and_counted() {
        // A parallelogram: a change-point linkage (docs/model.md §6), turning freely.
        let mut s = Session::new();
        let parallelogram = [("l", 0.5), ("l2", 0.5), ("l3", 0.5), ("L", 0.5)];
        let start = [("phi2_0", 1.0), ("omega2_0", 3.0), ("builtin_laws", 0.0)];
        for (name, value) in parallelogram.into_iter().chain(start) {
            s.set(vr(name), value).unwrap();
        }
        s.start(1e-8, 0.0, f64::INFINITY).unwrap();
        let mut t = 0.0;
        let mut over = 0;
        for k in 1..=500 {
            let next = f64::from(k) * 0.01;
            if s.step(t, next - t).unwrap() == Stepped::OverChangePoint {
                over += 1;
            }
            t = next;
        }
        let (crossed, last) = s.crossings();
        assert!(
            over > 0 && crossed > 0,
            "no change point met: {over}, {crossed}"
        );
        assert!(last.is_some_and(|at| at > 0.0 && at < t));
    }

    #[test]
    fn bad_steps_are_refused_by_rule() {
        let mut s = Session::new();
        s.start(1e-8, 0.0, 1.0).unwrap();
        assert!(s
            .step(0.0, f64::NAN)
            .unwrap_err()
            .contains("finite and > 0"));
        assert!(s.step(0.5, 0.1).unwrap_err().contains("does not match"));
        assert!(s
            .step(0.0, 2.0)
            .unwrap_err()
            .contains("would pass stopTime"));
        assert!(s.set(vr("solver"), 1.5).is_err());
    }

    #[test]
    fn the_variables_are_json_with_every_name() {
        let json = variables_json();
        for (vr, v) in variables::variables() {
            assert!(json.contains(&format!("\"name\":\"{}\",\"vr\":{vr}", v.name)));
        }
        assert!(!json.contains("inf") && !json.contains("NaN"));
        assert!(
            json.contains("\"items\":{\"1\":\"auto\",\"2\":\"dop853\""),
            "{json}"
        );
    }

    #[test]
    fn every_parameter_input_and_the_branch_has_a_control_holding_its_start() {
        let mut offered = Vec::new();
        for (_, v) in variables::variables() {
            let settable = matches!(
                v.slot,
                Slot::Parameter(_) | Slot::Input(_) | Slot::ChangePointBranch
            );
            let Some(c) = control(&v) else {
                assert!(!settable, "{} has no control", v.name);
                continue;
            };
            assert!(settable, "{} is not the user's to set", v.name);
            assert!(GROUPS.contains(&c.group));
            if let Some((low, high)) = c.span {
                let start = v.start().unwrap_or(0.0);
                let (min, max) = v.range().unwrap();
                assert!(low < high && low <= start && start <= high, "{}", v.name);
                assert!(min <= low && high <= max, "{}", v.name);
            }
            offered.push(v.name);
        }
        for name in ["Mm_a2", "Mr_b1", "change_point_branch", "twist12_0", "M_r"] {
            assert!(offered.contains(&name), "{name}");
        }
        let json = variables_json();
        assert!(json.contains("\"name\":\"Mm_a2\""));
        assert!(
            json.contains("\"group\":\"Built-in laws\",\"span\":[-5,5]"),
            "{json}"
        );
    }

    /// The statistics read as the FMU's do: before the start the method `solver` names.
    #[test]
    fn the_active_solver_before_the_start_is_the_one_chosen() {
        let mut s = Session::new();
        s.set(vr("solver"), 3.0).unwrap();
        assert_eq!(s.get(vr("active_solver")).unwrap(), 3.0);
        assert_eq!(s.get(vr("n_steps")).unwrap(), 0.0);
    }
}
