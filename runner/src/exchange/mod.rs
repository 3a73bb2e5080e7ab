//! A Model Exchange FMU run as a co-simulation unit: the runner integrates its continuous
//! states with the project's own DOP853 or Radau IIA (the crate `integrators`, which the
//! FMU's own co-simulation uses too), so that a point's master loop, metrics and series
//! treat it like any other [`Unit`].
//!
//! Between communication points the integrator steps freely, one accepted step at a time:
//! DOP853 past a communication point where no event intervenes (the state there comes
//! from the step's dense output), Radau IIA (whose collocation polynomial is only third
//! order between its nodes) landing on each; both land exactly on the FMU's next time
//! event and on the stop time. After each accepted step:
//! - the event indicators at its end are compared with those at its start; where one
//!   changed sign (the domain z > 0 was left or entered), the crossing is located on the
//!   step's dense output by bisection to a few ulps of t, on the side where the sign has
//!   changed;
//! - otherwise the FMU hears `CompletedIntegratorStep`, which may ask for an event (a step
//!   event);
//! - an event is handled where it lies: the FMU is set to the state there, enters event
//!   mode, updates its discrete states until it needs no further iteration, and returns
//!   to continuous time; its states (if it changed them), nominals and next time event
//!   are read, and the integrator restarts from there.
//!
//! The error norm sees the states divided by the FMU's nominals (a state of nominal 1e-3
//! gets an absolute tolerance of 1e-3·atol), as the standard intends them. The integrators
//! are compiled for fixed state sizes; an FMU's states are padded to the next such size
//! with components that stay zero and that the norms and Jacobians leave out
//! ([`OdeSystem::dimension`]), so the padding changes no number.

use integrators::{Method, Tolerances};

use crate::fmi::{EventUpdate, Instance, Status};
use crate::unit::Unit;

/// The most continuous states the runner integrates (the largest size it is compiled
/// for).
pub const MAX_STATES: usize = 64;
/// The tolerance where the plan gives none.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// The integrator holds local errors (relative and absolute, on the states over their
/// nominals) to this fraction of the plan's tolerance: the promise is the tolerance at
/// every communication point, where the global error that local errors add up to, and the
/// dense output's error, show. On this project's mechanism, local errors held to the
/// tolerance itself left errors far above it at the communication points
/// (tests/python/test_sweep_model_exchange.py holds them to ten times it); the fraction is
/// the one the FMU's own co-simulation uses for the same reason, and the one a steady
/// cycle's runs hold, whoever integrates them.
pub const TOLERANCE_SAFETY: f64 = 1.0 / 30.0;
/// The most iterations one event may take, and the most events one communication step may
/// handle without time advancing: an FMU past either is looping.
const MAX_EVENT_ITERATIONS: u32 = 1_000;
const MAX_EVENTS_AT_ONE_TIME: u32 = 1_000;
/// Bisection on an event indicator stops when the bracket is this many ulps of t wide.
const EVENT_ULPS: f64 = 4.0;

/// The method a plan names to integrate a Model Exchange run (`dop853` or `radau5`;
/// DOP853 when it names none).
pub fn method_named(name: Option<&str>) -> Result<Method, String> {
    match name {
        None | Some("dop853") => Ok(Method::Dop853),
        Some("radau5") => Ok(Method::Radau5),
        Some(other) => Err(format!(
            "integrator {other:?} is neither \"dop853\" nor \"radau5\""
        )),
    }
}

/// What a Model Exchange run needs to know of the FMU beyond its instance.
#[derive(Clone, Debug)]
pub struct Shape {
    pub states: usize,
    pub indicators: usize,
    pub method: Method,
    /// The tunable parameters, sorted: set in event mode once integrating.
    pub tunable: Vec<u32>,
}

impl Shape {
    /// Refuse an FMU with more states than the runner is compiled for.
    pub fn check(&self) -> Result<(), String> {
        if self.states > MAX_STATES {
            return Err(format!(
                "the FMU has {} continuous states; the runner integrates Model Exchange FMUs \
                 of at most {MAX_STATES} (run its CoSimulation interface instead)",
                self.states
            ));
        }
        Ok(())
    }
}

mod integration;

pub(crate) use integration::{at_size, AtSize, Scaled, Variational};
use integration::{integration, Failure, Integration};

/// A Model Exchange instance and the runner's integration of it.
pub struct ExchangeRun {
    fmu: Instance,
    shape: Shape,
    tolerance: f64,
    stop: f64,
    nominals: Vec<f64>,
    /// The event indicators at the integration's current point, and scratch for others.
    indicators: Vec<f64>,
    probe: Vec<f64>,
    /// States as the FMU takes them, and their derivatives (scratch).
    x: Vec<f64>,
    probe_states: Vec<f64>,
    integration: Option<Box<dyn Integration>>,
    next_time_event: Option<f64>,
    /// An event located (or due) at this time, not handled yet; the integration's last
    /// step still covers the time before it.
    pending: Option<f64>,
    /// The last communication point, where the FMU's state was left.
    now: f64,
    /// The master set values since the last step: the integration restarts from `now`.
    inputs_changed: bool,
    events: u64,
}

impl ExchangeRun {
    pub fn new(fmu: Instance, shape: Shape) -> ExchangeRun {
        ExchangeRun {
            fmu,
            tolerance: DEFAULT_TOLERANCE,
            stop: f64::INFINITY,
            nominals: vec![1.0; shape.states],
            indicators: vec![0.0; shape.indicators],
            probe: vec![0.0; shape.indicators],
            x: vec![0.0; shape.states],
            probe_states: vec![0.0; shape.states],
            shape,
            integration: None,
            next_time_event: None,
            pending: None,
            now: 0.0,
            inputs_changed: false,
            events: 0,
        }
    }

    pub fn call_name<'a>(&self, fmi2_name: &'a str) -> std::borrow::Cow<'a, str> {
        // A step of Model Exchange is the runner's own integration, not a call of the FMU.
        if fmi2_name == "fmi2DoStep" {
            return std::borrow::Cow::Borrowed("the runner's integration of the FMU's states");
        }
        self.fmu.call_name(fmi2_name)
    }

    /// In event mode: update the discrete states until the FMU needs no further
    /// iteration, return to continuous time, and read what the event changed; the
    /// integration restarts at `t`.
    fn settle(&mut self, t: f64) -> Status {
        let mut worst = Status::Ok;
        let mut update = EventUpdate::default();
        let mut changed = (false, false);
        let mut iterations = 0;
        loop {
            let s = self.fmu.update_discrete_states(&mut update);
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
            if update.terminate {
                log::trace!("the FMU asked to terminate the simulation at t = {t}");
                return Status::Discard;
            }
            changed.0 |= update.states_changed;
            changed.1 |= update.nominals_changed;
            iterations += 1;
            if !update.again {
                break;
            }
            if iterations >= MAX_EVENT_ITERATIONS {
                log::error!(
                    "the FMU's discrete states did not settle in {MAX_EVENT_ITERATIONS} \
                     event iterations at t = {t}"
                );
                return Status::Error;
            }
        }
        self.next_time_event = update.next_event_time;
        let s = self.fmu.enter_continuous_time_mode();
        if !s.proceeds() {
            return s;
        }
        worst = worst.max(s).max(self.read_after_event(t, changed));
        worst
    }

    /// After an event at `t` (or initialisation): the states if the FMU changed them (else
    /// those it was set to, in `self.x`), the nominals if they changed, the indicators,
    /// and a restarted integration.
    fn read_after_event(
        &mut self,
        t: f64,
        (states_changed, nominals_changed): (bool, bool),
    ) -> Status {
        let mut worst = Status::Ok;
        if states_changed {
            let s = self.fmu.get_continuous_states(&mut self.x);
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
        if nominals_changed {
            let s = self.read_nominals();
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
        let s = self.fmu.set_state(t, &self.x);
        if !s.proceeds() {
            return s;
        }
        let s = s.max(self.fmu.get_event_indicators(&mut self.indicators));
        if !s.proceeds() {
            return s;
        }
        if let Some(integration) = self.integration.as_mut() {
            integration.restart(t, &self.x, &self.nominals);
        }
        self.pending = None;
        worst.max(s)
    }

    /// The FMU's nominals; one where a nominal is not finite and positive (the standard
    /// asks for positive ones).
    fn read_nominals(&mut self) -> Status {
        let s = self.fmu.get_nominals(&mut self.nominals);
        for nominal in &mut self.nominals {
            if !(nominal.is_finite() && *nominal > 0.0) {
                *nominal = 1.0;
            }
        }
        s
    }

    /// Handle the event at `t`: the FMU set to the state there, event mode, settled.
    fn handle_event(&mut self, t: f64) -> Status {
        let integration = self.integration.as_mut().expect("integrating");
        if !integration.state_at(&mut self.fmu, &self.nominals, t, &mut self.x) {
            integration.now(&mut self.x, &self.nominals);
        }
        self.events += 1;
        let s = self.fmu.set_state(t, &self.x);
        if !s.proceeds() {
            return s;
        }
        let s = s.max(self.fmu.enter_event_mode());
        if !s.proceeds() {
            return s;
        }
        s.max(self.settle(t))
    }

    /// The master changed values at the communication point `now`: the integration
    /// restarts there, and an indicator whose sign the change flipped is an event there.
    fn restart_at_communication_point(&mut self) -> Status {
        self.inputs_changed = false;
        let integration = self.integration.as_mut().expect("integrating");
        integration.restart(self.now, &self.x, &self.nominals);
        self.pending = None;
        let s = self.fmu.get_event_indicators(&mut self.probe);
        if !s.proceeds() {
            return s;
        }
        if crossed(&self.indicators, &self.probe) {
            return s.max(self.handle_event(self.now));
        }
        self.indicators.copy_from_slice(&self.probe);
        s
    }

    /// After an accepted step from `start`: an indicator that changed sign is an event
    /// where it crossed; else the FMU hears the step completed and may ask for one.
    fn after_step(&mut self, start: f64) -> Status {
        let integration = self.integration.as_mut().expect("integrating");
        let end = integration.now(&mut self.x, &self.nominals);
        let mut s = Status::Ok;
        if !integration.evaluates_at_end() {
            s = self.fmu.set_state(end, &self.x);
            if !s.proceeds() {
                return s;
            }
        }
        let s = s.max(self.fmu.get_event_indicators(&mut self.probe));
        if !s.proceeds() {
            return s;
        }
        if crossed(&self.indicators, &self.probe) {
            let at = self.locate(start, end);
            self.pending = Some(at);
            return s;
        }
        self.indicators.copy_from_slice(&self.probe);
        let mut asks = (false, false);
        let s = s.max(self.fmu.completed_integrator_step(&mut asks));
        if !s.proceeds() {
            return s;
        }
        if asks.1 {
            log::trace!("the FMU asked to terminate the simulation at t = {end}");
            return Status::Discard;
        }
        if asks.0 || self.next_time_event.is_some_and(|te| end >= te) {
            self.pending = Some(end);
        }
        s
    }

    /// The first time in (start, end] where an indicator has changed sign since `start`,
    /// to a few ulps, on the side where it has: bisection on the step's dense output.
    fn locate(&mut self, start: f64, end: f64) -> f64 {
        let (mut before, mut after) = (start, end);
        let integration = self.integration.as_mut().expect("integrating");
        while after - before > EVENT_ULPS * f64::EPSILON * after.abs().max(1.0) {
            let middle = 0.5 * (before + after);
            if middle <= before || middle >= after {
                break;
            }
            let crossed_by_middle =
                integration.state_at(&mut self.fmu, &self.nominals, middle, &mut self.x)
                    && self.fmu.set_state(middle, &self.x).proceeds()
                    && self.fmu.get_event_indicators(&mut self.probe).proceeds()
                    && crossed(&self.indicators, &self.probe);
            if crossed_by_middle {
                after = middle;
            } else {
                before = middle;
            }
        }
        after
    }

    /// Leave the FMU at the communication point `end` (within the last step, before any
    /// pending event), for the master's reads.
    fn settle_at(&mut self, end: f64) -> Status {
        let integration = self.integration.as_mut().expect("integrating");
        if !integration.state_at(&mut self.fmu, &self.nominals, end, &mut self.x) {
            log::error!("no dense output at the communication point t = {end}");
            return Status::Error;
        }
        self.now = end;
        self.fmu.set_state(end, &self.x)
    }

    /// Integrate to `end`, handling every event on the way.
    fn advance(&mut self, end: f64) -> Status {
        let mut worst = Status::Ok;
        if self.inputs_changed {
            let s = self.restart_at_communication_point();
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
        let mut events_here = 0;
        loop {
            if let Some(at) = self.pending {
                // An event on the communication point is handled before it: the master
                // reads the values after it, as from a co-simulation FMU in event mode.
                if end < at {
                    return worst.max(self.settle_at(end));
                }
                events_here += 1;
                if events_here > MAX_EVENTS_AT_ONE_TIME {
                    log::error!("more than {MAX_EVENTS_AT_ONE_TIME} events in a row at t = {at}");
                    return Status::Error;
                }
                let s = self.handle_event(at);
                if !s.proceeds() {
                    return s;
                }
                worst = worst.max(s);
                continue;
            }
            let integration = self.integration.as_mut().expect("integrating");
            let t = integration.now(&mut self.x, &self.nominals);
            if end <= t {
                return worst.max(self.settle_at(end));
            }
            if self.next_time_event.is_some_and(|te| te <= t) {
                self.pending = Some(t);
                continue;
            }
            let limit = self
                .next_time_event
                .unwrap_or(f64::INFINITY)
                .min(self.stop.max(end));
            let start = match integration.step(&mut self.fmu, &self.nominals, limit) {
                Ok(start) => start,
                Err(failure) => return self.report(failure),
            };
            events_here = 0;
            let s = self.after_step(start);
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
    }

    fn report(&self, failure: Failure) -> Status {
        match failure {
            Failure::Fmu(status) => status,
            Failure::Solver(e, discarded) => {
                log::error!("integrating the FMU's states: {e}");
                if discarded {
                    Status::Discard
                } else {
                    Status::Error
                }
            }
        }
    }
}

/// Whether an indicator left or entered the domain z > 0 between `before` and `after`.
fn crossed(before: &[f64], after: &[f64]) -> bool {
    before
        .iter()
        .zip(after)
        .any(|(b, a)| (*b > 0.0) != (*a > 0.0))
}

/// Each call goes to the instance's method of the same name; a value set once the
/// integration runs restarts it at the communication point.
macro_rules! to_instance {
    ($($name:ident($($arg:ident: $t:ty),*) $(=> $changes:expr)?),* $(,)?) => {
        $(fn $name(&mut self, $($arg: $t),*) -> Status {
            $(if self.integration.is_some() { self.inputs_changed = $changes; })?
            self.fmu.$name($($arg),*)
        })*
    };
}

impl Unit for ExchangeRun {
    to_instance!(
        enter_initialization_mode(),
        set_integer(vr: &[u32], values: &[i32]) => true,
        set_boolean(vr: &[u32], values: &[i32]) => true,
        get_real(vr: &[u32], values: &mut [f64]),
        get_integer(vr: &[u32], values: &mut [i32]),
        get_boolean(vr: &[u32], values: &mut [i32]),
    );

    /// Real values; once integrating, a tunable parameter among them is set in event
    /// mode at the communication point (the only mode that takes it), and the
    /// integration restarts there.
    fn set_real(&mut self, vr: &[u32], values: &[f64]) -> Status {
        let tunable = |r: &u32| self.shape.tunable.binary_search(r).is_ok();
        if self.integration.is_none() || !vr.iter().any(tunable) {
            if self.integration.is_some() {
                self.inputs_changed = true;
            }
            return self.fmu.set_real(vr, values);
        }
        let s = self.fmu.enter_event_mode();
        if !s.proceeds() {
            return s;
        }
        let s = s.max(self.fmu.set_real(vr, values));
        if !s.proceeds() {
            return s;
        }
        self.inputs_changed = false;
        s.max(self.settle(self.now))
    }

    fn reset(&mut self) -> Status {
        self.integration = None;
        self.pending = None;
        self.next_time_event = None;
        self.inputs_changed = false;
        self.events = 0;
        self.fmu.reset()
    }

    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Status {
        self.tolerance = tolerance.unwrap_or(DEFAULT_TOLERANCE);
        self.stop = stop;
        self.now = start;
        self.fmu.setup_experiment(tolerance, start, stop)
    }

    /// Leave initialisation (the FMU is then in event mode), settle the initial event and
    /// start the integration.
    fn exit_initialization_mode(&mut self) -> Status {
        let s = self.fmu.exit_initialization_mode();
        if !s.proceeds() {
            return s;
        }
        let s = s.max(self.read_nominals());
        if !s.proceeds() {
            return s;
        }
        let internal = self.tolerance * TOLERANCE_SAFETY;
        let tolerances = Tolerances {
            rtol: internal,
            atol: internal,
        };
        self.integration = Some(integration(
            self.shape.states,
            self.shape.method,
            tolerances,
        ));
        s.max(self.settle_initial())
    }

    fn do_step(&mut self, time: f64, step: f64) -> Status {
        if self.integration.is_none() {
            log::error!("a step before initialisation ended");
            return Status::Error;
        }
        self.now = time;
        self.advance(time + step)
    }

    fn events(&self) -> u64 {
        self.events
    }
}

impl ExchangeRun {
    /// The instance as initialised, in continuous-time mode, for an analysis of its own:
    /// the instance, its time and states now, the states' nominals and how many event
    /// indicators it has.
    pub fn parts(&mut self) -> (&mut Instance, f64, Vec<f64>, &[f64], usize) {
        (
            &mut self.fmu,
            self.now,
            self.x.clone(),
            &self.nominals,
            self.shape.indicators,
        )
    }

    /// The first time derivatives of the outputs `vrs` where the integration left the FMU
    /// (a communication point), into `rates`: ∂y/∂x · f from its directional derivatives,
    /// `states` the continuous states' value references (the inputs are held over a step).
    pub fn rates(&mut self, vrs: &[u32], states: &[u32], rates: &mut [f64]) -> Status {
        let s = self.fmu.get_derivatives(&mut self.probe_states);
        for (vr, rate) in vrs.iter().zip(rates.chunks_mut(1)) {
            if !s.proceeds() {
                return s;
            }
            let seed = &self.probe_states;
            let s = self
                .fmu
                .get_directional_derivative(&[*vr], states, seed, rate);
            if !s.proceeds() {
                return s;
            }
        }
        s
    }

    /// The initial event iteration: the states as initialised.
    fn settle_initial(&mut self) -> Status {
        let s = self.fmu.get_continuous_states(&mut self.x);
        if !s.proceeds() {
            return s;
        }
        s.max(self.settle(self.now))
    }
}
