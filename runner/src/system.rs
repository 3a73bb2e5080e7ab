//! A coupled system of FMI 2.0 and 3.0 co-simulation FMUs, stepped here as one unit: the
//! folder the runner serves holds `system.json` and the components' `.fmu` files,
//!
//! ```json
//! {"components": [{"name": "motor", "file": "motor.fmu"}, …],
//!  "connections": [{"from": "motor.torque", "to": "mechanism.M_m"}, …],
//!  "input_derivatives": 2}
//! ```
//!
//! Every variable of a component is `component.variable`, except the inputs that
//! connections feed. A communication step passes each connection's output at the step's
//! start to its input, in the order listed (the caller lists a connection after those
//! feeding the inputs its output depends on directly), then steps every component over
//! the same interval (Jacobi). With `input_derivatives` k > 0, a Real connection whose
//! source gives output derivatives and whose target interpolates inputs also passes the
//! derivatives of orders 1 to k (at most the source's maximum): the target then moves its
//! input along the source's Taylor polynomial over the step instead of holding it, which
//! raises the coupling's order of accuracy from 1 to k + 1.
//!
//! With `"coupling_tolerance": tol` the system chooses its communication steps itself
//! inside each step the master asks for ([`crate::coupling`]): every component must then
//! be able to save and restore its FMU state, so that a rejected step can be taken again.

use std::ffi::CString;
use std::path::Path;
use std::rc::Rc;

use serde::Deserialize;

use crate::archive::Unpacked;
use crate::coupling::{drift, Controller, CouplingReport, Verdict};
use crate::description::{Description, Variable};
use crate::fmi::{Instance, Interface, Library, Status};
use crate::plan::type_group;
use crate::unit::Unit;

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

struct Component {
    name: CString,
    library: Rc<Library>,
    /// Whether it moves its inputs along derivatives a master sets.
    interpolates: bool,
    // Removed when the system is dropped; the library stays loaded (see `Library`).
    _unpacked: Unpacked,
}

/// Where a variable of the system lives: its component, value reference there, and FMI
/// type group (0 Real, 1 Integer, 2 Boolean).
#[derive(Clone, Copy, Debug)]
struct Route {
    component: usize,
    vr: u32,
    group: usize,
}

/// A connection: the output `from` passed to the input `to`, with derivatives of orders 1
/// to `derivatives`.
#[derive(Clone, Copy, Debug)]
struct Link {
    from: Route,
    to: Route,
    derivatives: usize,
}

/// The system's components, loaded once; [`SystemInstance`]s step them.
pub struct SystemLibrary {
    components: Vec<Component>,
    /// By the system's value reference (the index).
    routes: Vec<Route>,
    links: Vec<Link>,
    /// Each link as "source → target", for messages.
    link_names: Vec<String>,
    coupling_tolerance: Option<f64>,
}

impl SystemLibrary {
    /// The route of the system's value reference `vr` if it has type group `group`.
    fn route(&self, vr: u32, group: usize) -> Option<Route> {
        self.routes
            .get(vr as usize)
            .copied()
            .filter(|r| r.group == group)
    }
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
        let mut components = Vec::new();
        let mut descriptions = Vec::new();
        for c in &file.components {
            // Inside the served folder, which the caller removes even if this process dies.
            let unpacked = Unpacked::within(&dir.join(&c.file), dir)?;
            let description = Description::read(unpacked.dir())
                .map_err(|e| format!("component {}: {e}", c.name))?;
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
        let names: Vec<&str> = file.components.iter().map(|c| c.name.as_str()).collect();
        let find = |end: &str| find_variable(end, &names, &descriptions);
        let mut links = Vec::new();
        let mut link_names = Vec::new();
        let mut fed = Vec::new();
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
                    ..v.clone()
                });
            }
        }
        let description = Description {
            fmi_version: "2.0".into(),
            model_name: "system".into(),
            guid: String::new(),
            model_identifier: Some("system".into()),
            can_handle_variable_step: descriptions.iter().all(|d| d.can_handle_variable_step),
            can_interpolate_inputs: false,
            max_output_derivative_order: 0,
            can_get_and_set_state: false,
            has_event_mode: false,
            log_categories: Vec::new(),
            has_model_exchange: false,
            exchange_identifier: None,
            continuous_states: 0,
            event_indicators: 0,
            variables,
        };
        if let Some(tolerance) = file.coupling_tolerance {
            check_rollback(tolerance, &components, &descriptions)?;
        }
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

/// A coupling tolerance needs a positive tolerance and components that can roll back.
fn check_rollback(
    tolerance: f64,
    components: &[Component],
    descriptions: &[Description],
) -> Result<(), String> {
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(format!(
            "coupling_tolerance must be a finite number > 0, got {tolerance}"
        ));
    }
    for (c, d) in components.iter().zip(descriptions) {
        if !(d.can_get_and_set_state && c.library.exports_state()) {
            return Err(format!(
                "component {}: a coupling tolerance needs components that can save and \
                 restore their FMU state (canGetAndSetFMUstate), and this one cannot",
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

/// One instance of each component.
pub struct SystemInstance {
    system: Rc<SystemLibrary>,
    instances: Vec<Instance>,
    /// With a coupling tolerance: the step-size controller, and per connection the value
    /// and derivatives its target was given at the step's start and its scale.
    controller: Option<Controller>,
    given: Vec<[f64; 3]>,
    /// What the connections give at a controlled step's end, before it is accepted.
    given_next: Vec<[f64; 3]>,
    scales: Vec<f64>,
    /// Whether the last controlled step's end passed every connection and nothing was set
    /// since: the next step starts from those values.
    passed: bool,
}

/// The first status that stops a run, else the worst; `calls` run in order until one stops.
fn in_turn(calls: impl IntoIterator<Item = Status>) -> Status {
    let mut worst = Status::Ok;
    for status in calls {
        if !status.proceeds() {
            return status;
        }
        worst = worst.max(status);
    }
    worst
}

impl SystemInstance {
    pub fn new(system: &Rc<SystemLibrary>) -> Result<Self, String> {
        let instances = system
            .components
            .iter()
            .map(|c| {
                Instance::new(&c.library, &c.name)
                    .map_err(|e| format!("component {}: {e}", c.name.to_string_lossy()))
            })
            .collect::<Result<_, _>>()?;
        let fewest = system
            .links
            .iter()
            .map(|l| l.derivatives)
            .min()
            .unwrap_or(0);
        Ok(Self {
            system: Rc::clone(system),
            instances,
            controller: system
                .coupling_tolerance
                .map(|tol| Controller::new(tol, fewest)),
            given: vec![[0.0; 3]; system.links.len()],
            given_next: vec![[0.0; 3]; system.links.len()],
            scales: vec![1.0; system.links.len()],
            passed: false,
        })
    }

    /// `call` for each of the first `n` references in `vr` in turn, with its instance, its
    /// value reference there and its index; an unknown reference is an error.
    fn each_routed(
        &mut self,
        (vr, n, group): (&[u32], usize, usize),
        name: &str,
        mut call: impl FnMut(&mut Instance, u32, usize) -> Status,
    ) -> Status {
        let system = Rc::clone(&self.system);
        in_turn(
            vr[..n]
                .iter()
                .enumerate()
                .map(|(k, &v)| match system.route(v, group) {
                    Some(r) => {
                        let instance = &mut self.instances[r.component];
                        let status = call(instance, r.vr, k);
                        blame(&system, r.component, instance, name, status)
                    }
                    None => Status::Error,
                }),
        )
    }

    /// One value per call, each to its component.
    fn set<T: Copy>(
        &mut self,
        (vr, values, group): (&[u32], &[T], usize),
        call: fn(&mut Instance, &[u32], &[T]) -> Status,
    ) -> Status {
        let n = vr.len().min(values.len());
        let name = ["fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean"][group];
        self.each_routed((vr, n, group), name, |instance, r, k| {
            call(instance, &[r], &values[k..=k])
        })
    }

    fn get<T: Copy>(
        &mut self,
        (vr, values, group): (&[u32], &mut [T], usize),
        call: fn(&mut Instance, &[u32], &mut [T]) -> Status,
    ) -> Status {
        let n = vr.len().min(values.len());
        let name = ["fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean"][group];
        self.each_routed((vr, n, group), name, |instance, r, k| {
            call(instance, &[r], &mut values[k..=k])
        })
    }

    /// Pass the value (and derivatives) of one connection's output to its input; `given`
    /// receives the value and derivatives passed.
    fn pass(&mut self, link: Link, given: &mut [f64; 3]) -> Status {
        let (from, to) = (link.from, link.to);
        let (mut real, mut whole) = ([0.0], [0]);
        let source = &mut self.instances[from.component];
        let (read, call) = match from.group {
            0 => (source.get_real(&[from.vr], &mut real), "fmi2GetReal"),
            1 => (source.get_integer(&[from.vr], &mut whole), "fmi2GetInteger"),
            _ => (source.get_boolean(&[from.vr], &mut whole), "fmi2GetBoolean"),
        };
        let read = self.blame(from.component, call, read);
        if !read.proceeds() {
            return read;
        }
        let target = &mut self.instances[to.component];
        let (written, call) = match to.group {
            0 => (target.set_real(&[to.vr], &real), "fmi2SetReal"),
            1 => (target.set_integer(&[to.vr], &whole), "fmi2SetInteger"),
            _ => (target.set_boolean(&[to.vr], &whole), "fmi2SetBoolean"),
        };
        let written = self.blame(to.component, call, written);
        given[0] = real[0];
        if !written.proceeds() || link.derivatives == 0 {
            return in_turn([read, written]);
        }
        let mut rates = [0.0; 2];
        let rates = &mut rates[..link.derivatives];
        let got = self.instances[from.component].get_output_derivatives(from.vr, rates);
        let got = self.blame(from.component, "fmi2GetRealOutputDerivatives", got);
        if !got.proceeds() {
            return got;
        }
        given[1..=rates.len()].copy_from_slice(rates);
        let set = self.instances[to.component].set_input_derivatives(to.vr, rates);
        let set = self.blame(to.component, "fmi2SetRealInputDerivatives", set);
        in_turn([read, written, got, set])
    }

    /// `call` on every component in turn, until one stops the run.
    fn each(&mut self, name: &str, mut call: impl FnMut(&mut Instance) -> Status) -> Status {
        let system = &self.system;
        in_turn(
            self.instances
                .iter_mut()
                .enumerate()
                .map(|(component, instance)| {
                    let status = call(instance);
                    blame(system, component, instance, name, status)
                }),
        )
    }

    fn blame(&self, component: usize, call: &str, status: Status) -> Status {
        blame(
            &self.system,
            component,
            &self.instances[component],
            call,
            status,
        )
    }
}

/// `status`, which `call` (by its FMI 2.0 name) of `component` returned; when it stops the
/// run, a message names the component (the FMU's own message does not) and the call as
/// the component's FMI version names it.
fn blame(
    system: &SystemLibrary,
    component: usize,
    instance: &Instance,
    call: &str,
    status: Status,
) -> Status {
    if !status.proceeds() {
        let name = system.components[component].name.to_string_lossy();
        let level = if status == Status::Discard {
            log::Level::Trace
        } else {
            log::Level::Error
        };
        let call = instance.call_name(call);
        log::log!(level, "component {name}: {call} returned {status:?}");
    }
    status
}

impl Unit for SystemInstance {
    fn reset(&mut self) -> Status {
        if let Some(controller) = self.controller.as_mut() {
            controller.restart();
        }
        self.scales.iter_mut().for_each(|s| *s = 1.0);
        self.passed = false;
        self.each("fmi2Reset", Instance::reset)
    }

    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Status {
        self.each("fmi2SetupExperiment", |i| {
            i.setup_experiment(tolerance, start, stop)
        })
    }

    fn enter_initialization_mode(&mut self) -> Status {
        self.each(
            "fmi2EnterInitializationMode",
            Instance::enter_initialization_mode,
        )
    }

    fn exit_initialization_mode(&mut self) -> Status {
        self.each(
            "fmi2ExitInitializationMode",
            Instance::exit_initialization_mode,
        )
    }

    fn set_real(&mut self, vr: &[u32], values: &[f64]) -> Status {
        self.passed = false;
        self.set((vr, values, 0), Instance::set_real)
    }

    fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> Status {
        self.passed = false;
        self.set((vr, values, 1), Instance::set_integer)
    }

    fn set_boolean(&mut self, vr: &[u32], values: &[i32]) -> Status {
        self.passed = false;
        self.set((vr, values, 2), Instance::set_boolean)
    }

    fn get_real(&mut self, vr: &[u32], values: &mut [f64]) -> Status {
        self.get((vr, values, 0), Instance::get_real)
    }

    fn get_integer(&mut self, vr: &[u32], values: &mut [i32]) -> Status {
        self.get((vr, values, 1), Instance::get_integer)
    }

    fn get_boolean(&mut self, vr: &[u32], values: &mut [i32]) -> Status {
        self.get((vr, values, 2), Instance::get_boolean)
    }

    /// Without a coupling tolerance: pass every connection at `time`, then step every
    /// component to `time + step`. With one: as many controlled steps as it takes to reach
    /// `time + step`.
    fn do_step(&mut self, time: f64, step: f64) -> Status {
        if self.controller.is_some() {
            return self.controlled_steps(time, step);
        }
        self.jacobi_step(time, step)
    }

    fn events(&self) -> u64 {
        self.instances.iter().map(Instance::events).sum()
    }

    fn coupling(&self) -> Option<CouplingReport> {
        self.controller.as_ref().map(Controller::report)
    }

    fn set_input_slope(&mut self, vr: u32, slope: f64) -> Status {
        let Some(route) = self.system.route(vr, 0) else {
            return Status::Error;
        };
        if !self.system.components[route.component].interpolates {
            return Status::Ok;
        }
        self.passed = false;
        let set = self.instances[route.component].set_input_derivatives(route.vr, &[slope]);
        self.blame(route.component, "fmi2SetRealInputDerivatives", set)
    }
}

impl SystemInstance {
    /// Pass every connection at `time` (each link's given values kept), then step every
    /// component to `time + step`.
    fn jacobi_step(&mut self, time: f64, step: f64) -> Status {
        let passed = self.jacobi_pass();
        if !passed.proceeds() {
            return passed;
        }
        in_turn([passed, self.step_all(time, step)])
    }

    /// Pass every connection, in the system's order, the values and derivatives passed
    /// into `given`.
    fn pass_all(&mut self, given: &mut [[f64; 3]]) -> Status {
        let system = Rc::clone(&self.system);
        in_turn(
            system
                .links
                .iter()
                .zip(given.iter_mut())
                .map(|(&link, g)| self.pass(link, g)),
        )
    }

    fn step_all(&mut self, time: f64, step: f64) -> Status {
        self.each("fmi2DoStep", |i| i.do_step(time, step))
    }

    /// Steps chosen by the controller from `time` to exactly `time + grid`. Each is taken
    /// from saved FMU states with the connections passed at its start, and ends by passing
    /// them at its end: what the targets are then given, against what they were given, is
    /// the estimate. A step whose estimate is too large is taken again, shorter, from the
    /// saved states (which hold the inputs passed at its start).
    fn controlled_steps(&mut self, time: f64, grid: f64) -> Status {
        // The scratch values go back whatever the way out.
        let mut next = std::mem::take(&mut self.given_next);
        let status = self.controlled_steps_with(time, grid, &mut next);
        self.given_next = next;
        status
    }

    fn controlled_steps_with(&mut self, time: f64, grid: f64, next: &mut Vec<[f64; 3]>) -> Status {
        let end = time + grid;
        let mut worst = Status::Ok;
        if !self.passed {
            worst = self.jacobi_pass();
            if !worst.proceeds() {
                return worst;
            }
        }
        let mut t = time;
        while t < end {
            let h = self.controller().next_step(t, end, grid);
            let lands = h == end - t;
            let saved = self.each("fmi2GetFMUstate", Instance::save_state);
            if !saved.proceeds() {
                return saved;
            }
            let stepped = match self.step_all(t, h) {
                Status::Discard => Status::Discard,
                s if !s.proceeds() => return s,
                s => s.max(self.pass_all(next)),
            };
            let (estimate, worst_link) = match stepped {
                Status::Discard => (f64::INFINITY, None),
                s if !s.proceeds() => return s,
                _ => self.largest_drift(next, h),
            };
            match self.controller_mut().judge(h, estimate, grid) {
                Verdict::Accept => {
                    worst = worst.max(stepped).max(saved);
                    std::mem::swap(&mut self.given, next);
                    self.widen_scales();
                    t = if lands { end } else { t + h };
                    self.passed = true;
                }
                Verdict::Reject => {
                    let restored = self.each("fmi2SetFMUstate", Instance::restore_state);
                    if !restored.proceeds() {
                        return restored;
                    }
                }
                Verdict::GiveUp => return self.give_up(t, h, estimate, worst_link),
            }
        }
        worst
    }

    /// Pass every connection now, into the values given.
    fn jacobi_pass(&mut self) -> Status {
        let mut given = std::mem::take(&mut self.given);
        let passed = self.pass_all(&mut given);
        self.given = given;
        passed
    }

    /// The largest drift of a Real connection over a step of `h`: what its target is given
    /// now (`now`) against the polynomial it was given at the step's start, in its scale;
    /// and the connection that drifted most.
    fn largest_drift(&self, now: &[[f64; 3]], h: f64) -> (f64, Option<usize>) {
        let mut largest = (0.0_f64, None);
        for (k, link) in self.system.links.iter().enumerate() {
            if link.from.group == 0 {
                let d = drift(&self.given[k], link.derivatives, h, now[k][0]);
                let relative = d / self.scales[k].max(now[k][0].abs());
                if largest.1.is_none() || relative > largest.0 {
                    largest = (relative, Some(k));
                }
            }
        }
        largest
    }

    /// Each connection's scale grows to the largest |value| passed so far.
    fn widen_scales(&mut self) {
        for (scale, given) in self.scales.iter_mut().zip(&self.given) {
            *scale = scale.max(given[0].abs());
        }
    }

    /// The point cannot meet the tolerance: say where, over what step, on which connection,
    /// and what the order of its estimate asks for.
    fn give_up(&self, t: f64, h: f64, estimate: f64, link: Option<usize>) -> Status {
        let controller = self.controller();
        let tolerance = controller.tolerance();
        let Some(k) = link.filter(|_| estimate.is_finite()) else {
            log::error!(
                "the coupling error cannot be held to the tolerance {tolerance:e}: at t = {t} \
                 a component discards even the smallest communication step ({h:.3e} s)"
            );
            return Status::Error;
        };
        let derivatives = self.system.links[k].derivatives;
        let held = match derivatives {
            0 => "its input is held over a step (no input derivatives passed), so its \
                  error falls only in proportion to the step"
                .to_string(),
            d => format!(
                "its input moves along {d} derivative(s), so its error falls as the step to \
                 the power {}",
                d + 1
            ),
        };
        let needed = h * (tolerance / estimate).powf(1.0 / (1.0 + derivatives as f64));
        log::error!(
            "the coupling error cannot be held to the tolerance {tolerance:e}: at t = {t}, \
             over the smallest communication step ({h:.3e} s), the connection {} drifts \
             {estimate:.3e} of its scale max(1, its largest |value|); {held}, and a step of \
             about {needed:.1e} s would be needed. Raise coupling_tolerance, pass \
             input_derivatives (to a component that interpolates its inputs), or make the \
             output grid's step shorter (the smallest step is {:e} of it)",
            self.system.link_names[k],
            crate::coupling::MIN_STEP_FRACTION
        );
        Status::Error
    }

    fn controller(&self) -> &Controller {
        self.controller.as_ref().expect("a controlled system")
    }

    fn controller_mut(&mut self) -> &mut Controller {
        self.controller.as_mut().expect("a controlled system")
    }
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
