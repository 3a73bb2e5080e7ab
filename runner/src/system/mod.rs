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
use std::rc::Rc;

use crate::archive::Unpacked;
use crate::coupling::{Connection, Controller, CouplingRecord, Verdict};
use crate::fmi::{Instance, Library, Status};
use crate::unit::Unit;

mod load;

pub use load::is_system;

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

/// One instance of each component.
pub struct SystemInstance {
    system: Rc<SystemLibrary>,
    instances: Vec<Instance>,
    /// With a coupling tolerance: the step-size controller, and per connection the value
    /// and derivatives its target was given at the step's start.
    controller: Option<Controller>,
    given: Vec<[f64; 3]>,
    /// What the connections give at a controlled step's end, before it is accepted.
    given_next: Vec<[f64; 3]>,
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
        let connections = system
            .links
            .iter()
            .map(|l| Connection {
                real: l.from.group == 0,
                derivatives: l.derivatives,
            })
            .collect();
        Ok(Self {
            system: Rc::clone(system),
            instances,
            controller: system
                .coupling_tolerance
                .map(|tol| Controller::new(tol, connections)),
            given: vec![[0.0; 3]; system.links.len()],
            given_next: vec![[0.0; 3]; system.links.len()],
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

    fn coupling(&self) -> Option<CouplingRecord> {
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
                _ => self.controller().estimate(&self.given, next, h),
            };
            match self.controller_mut().judge(h, estimate, grid) {
                Verdict::Accept => {
                    worst = worst.max(stepped).max(saved);
                    std::mem::swap(&mut self.given, next);
                    if let Some(controller) = self.controller.as_mut() {
                        controller.widen_scales(&self.given);
                    }
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
        let needed = controller.step_needed(h, estimate, derivatives);
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
