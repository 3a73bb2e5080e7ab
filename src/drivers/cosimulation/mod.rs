//! The co-simulation driver: the FMU integrates the plant between the master's
//! communication points.
//!
//! Two points in time are kept apart: the communication point (the plant's time and state:
//! what the outputs show) and the integrator's own point, which may lie ahead of it. While
//! the master changes nothing, the integrator steps at its own pace past communication
//! points and the state at each point comes from the dense output (then projected onto
//! the constraint). When the master changes a parameter or the state, or an input by
//! enough to matter at the tolerance ([`CoSimulation::input_change_is_negligible`]), the
//! integrator restarts from the communication point; a restarted communication step far
//! shorter than the integrator's natural step is taken by short RK4 steps that end on it
//! (a master coupling the FMU to another sets an input at every step).

mod serialize;

use crate::model::change_point::{self, Crossing};
use crate::model::{self, Inputs, ModelError, Parameters, Projected, State, STATE_SIZE};
use crate::plant::{check_inputs, Activity, InputDerivatives, Plant};
use integrators::bytes::{same_bits, FormatError, Reader, Writer};
use integrators::{Integrator, OdeSystem, SolverError, Statistics, Tolerances};

use super::sensitivity::Tracker;
use super::Experiment;

/// The step-size control holds local errors to this fraction of the master's tolerance,
/// and never above [`LOOSEST_INTERNAL_TOLERANCE`]: the promise is the tolerance at every
/// communication point, which the local error test does not see. Two effects escape it:
/// outputs between integration steps come from DOP853's dense output, whose error is
/// larger than that of the step points on this model, and over long undamped runs the
/// phase error accumulates. The fraction was chosen by the benchmark harness, which
/// measures the error at every communication point against an independent reference
/// (docs/benchmark.md).
pub const TOLERANCE_SAFETY: f64 = 1.0 / 30.0;
/// Above this internal tolerance DOP853's steps on the paper's mechanism grow so long that
/// its interpolant is no longer accurate to the master's tolerance between steps; looser
/// tolerances therefore cost what this one costs.
pub const LOOSEST_INTERNAL_TOLERANCE: f64 = 1.5e-6;

/// The drift an input change may cause before the integrator takes the new input, as a
/// fraction of its error scale ([`CoSimulation::input_change_is_negligible`]).
const NEGLIGIBLE_DRIFT: f64 = 0.1;

/// Relative input changes up to this many units of rounding are a master's rounding (an
/// interpolated held input flickers by an ulp), not a new input.
const ROUNDING_CHANGE: f64 = 4.0 * f64::EPSILON;

/// Whether some input moved by more than [`ROUNDING_CHANGE`] of its size: checked on the
/// inputs themselves, without evaluating the right-hand side.
fn beyond_rounding(new: &Inputs, old: &Inputs) -> bool {
    let moved = |a: f64, b: f64| (a - b).abs() > ROUNDING_CHANGE * a.abs().max(b.abs());
    moved(new.motor_torque, old.motor_torque) || moved(new.load_torque, old.load_torque)
}

/// The work one master's call may make the integrators do, in right-hand sides: the bound
/// that lets no call, whatever its arguments, run away; a call past it returns Discard.
/// Radau IIA's right-hand sides, with its Jacobians and factorisations, are the costliest;
/// the fuzzers time the longest call they make (`no_step_runs_away`, and the longest call
/// in their reports under `target/test-reports/`). Counted, not timed, so that a call ends
/// at the same point on every machine and under every load.
pub const CALL_WORK: u64 = 2_000_000;

/// What crossing a change point costs, counted against [`CALL_WORK`] as this many right-hand
/// sides (its Newton iterations and projections).
pub const CROSSING_WORK: u64 = 2_000;

/// A gap to the next communication point that the integrator does not resolve (it takes
/// no step below 16·ε·|t|; see `integrators::check_step_size`), with a margin.
const UNRESOLVED_STEP: f64 = 64.0 * f64::EPSILON;

/// The mechanism as the integrator sees it: parameters, and inputs as polynomials in time.
struct Driven<'a> {
    params: &'a Parameters,
    inputs: &'a Inputs,
    /// `None` while the inputs are held (no derivatives set): the right-hand side then
    /// skips the two polynomials.
    derivatives: Option<&'a InputDerivatives>,
    anchor: f64,
    /// The relative accuracy the projection needs of the gradient ([`model::project`]).
    projection_accuracy: f64,
}

impl<'a> Driven<'a> {
    /// The plant's system with `inputs` (the plant's own, or those the integrator last
    /// stepped with), anchored at the communication point.
    fn new(plant: &'a Plant, inputs: &'a Inputs, tolerance: f64) -> Self {
        let derivatives = plant.input_derivatives();
        Self {
            params: plant.params(),
            inputs,
            derivatives: (!derivatives.is_zero()).then_some(derivatives),
            anchor: plant.time(),
            projection_accuracy: projection_accuracy(tolerance),
        }
    }

    #[inline]
    fn inputs_at(&self, t: f64) -> Inputs {
        match self.derivatives {
            None => *self.inputs,
            Some(derivatives) => derivatives.at(self.inputs, self.anchor, t),
        }
    }
}

impl OdeSystem<STATE_SIZE> for Driven<'_> {
    #[inline(always)]
    fn rhs(&self, t: f64, y: &State, dy: &mut State) {
        model::state_derivative(self.params, &self.inputs_at(t), y, dy);
    }

    #[inline(always)]
    fn project(&self, previous: &State, y: &mut State) -> Result<(), String> {
        let at =
            model::project(self.params, y, self.projection_accuracy).map_err(|e| e.to_string())?;
        model::check_passage(self.params, previous, y, &at).map_err(|e| e.to_string())
    }
}

/// f at the integrator's point after short steps that ended on the communication point,
/// with the inputs it was evaluated with. While nothing but the inputs changes, the next
/// short step starts from it, shifted to the new inputs ([`model::shift_inputs`]), and
/// evaluates no f of its own at the start. Kept only while it holds: the integrator stands
/// on the plant's communication point, no restart is pending from a failure, and the
/// parameters and state are the ones it was evaluated with (a change drops it, as does a
/// step taken otherwise).
#[derive(Clone, Copy, Debug)]
struct CarriedStage {
    f: State,
    inputs: Inputs,
}

#[derive(Clone, Debug)]
pub struct CoSimulation {
    /// The integrator's own point, at or ahead of the plant's communication point.
    integrator_time: f64,
    integrator_state: State,
    /// The inputs the integrator's memory (its last step, its stored first stage) was
    /// computed with; they differ from the plant's only by a change too small to matter,
    /// until the integrator steps again.
    integrator_inputs: Inputs,
    /// The integrator must start over from the communication point before its next step
    /// (it failed, or changed method).
    restart: bool,
    solver: Integrator<STATE_SIZE>,
    carried: Option<CarriedStage>,
    /// The plant stands just before a change point, located by an FMI 3.0 step that
    /// returned early there: the next step crosses it first ([`CoSimulation::cross`]).
    crossing_pending: bool,
    /// A crossing under way: a step ended before the crossing did, and the plant stands
    /// on its path ([`Crossing::along`]).
    in_flight: Option<InFlight>,
    /// The parameter sensitivities the plant's slots ask for, integrated alongside.
    sensitivities: Option<Tracker>,
}

/// A crossing of a change point under way: made from `from` at `start`, with the inputs
/// of that time.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    start: f64,
    from: State,
    inputs: Inputs,
    crossing: Crossing,
}

impl InFlight {
    /// The plant's state `at` (within the crossing) on the crossing's path.
    fn state_at(&self, params: &Parameters, at: f64) -> State {
        let (mut start, mut end) = ([0.0; STATE_SIZE], [0.0; STATE_SIZE]);
        model::state_derivative(params, &self.inputs, &self.from, &mut start);
        model::state_derivative(params, &self.inputs, &self.crossing.state, &mut end);
        self.crossing
            .along(params, &self.from, (&start, &end), at - self.start)
    }

    fn end(&self) -> f64 {
        self.start + self.crossing.duration
    }
}

impl CoSimulation {
    /// A driver for `plant` under `experiment`, starting at the plant's point with the
    /// method its `solver` parameter names.
    pub fn new(plant: &Plant, experiment: &Experiment) -> Self {
        Self {
            integrator_time: 0.0,
            integrator_state: [0.0; STATE_SIZE],
            integrator_inputs: Inputs::default(),
            restart: true,
            solver: Integrator::new(
                super::method_choice(plant.solver_kind()),
                tolerances(experiment.tolerance),
            ),
            carried: None,
            crossing_pending: false,
            in_flight: None,
            sensitivities: Tracker::start(plant, tolerances(experiment.tolerance)),
        }
    }

    /// Whether the next step starts by crossing a change point.
    pub fn crossing_pending(&self) -> bool {
        self.crossing_pending
    }

    /// The plant stands just before a change point: the next step crosses it first.
    pub fn expect_crossing(&mut self) {
        self.crossing_pending = true;
    }

    /// The crossing of the change point the plant stands before, onto its
    /// `change_point_branch` (docs/model.md §7); nothing changes yet.
    pub fn plan_crossing(&self, plant: &Plant) -> Result<Crossing, ModelError> {
        let inputs = plant.inputs_at(plant.time());
        change_point::cross(plant.params(), &inputs, plant.state(), plant.branch())
    }

    /// Make a planned crossing, as far as `target`: the whole of it where it ends by then
    /// (the plant moves past the change point, and the integrator starts afresh there),
    /// otherwise the plant placed on its way at `target` and the rest left for the next
    /// steps ([`CoSimulation::go_on_crossing`]). Returns whether the crossing is complete.
    /// A run carrying sensitivities is not crossed, nothing changed: the branch is a choice,
    /// not a differentiable function of the parameters.
    pub fn cross(
        &mut self,
        plant: &mut Plant,
        crossing: &Crossing,
        target: f64,
    ) -> Result<bool, String> {
        if self.sensitivities.is_some() {
            return Err(
                "sensitivities end at the change point: the motion's branch there is a choice, \
                 not a differentiable function of the parameters, so a run with sensitivity \
                 slots set does not cross it"
                    .into(),
            );
        }
        self.crossing_pending = false;
        self.in_flight = Some(InFlight {
            start: plant.time(),
            from: *plant.state(),
            inputs: plant.inputs_at(plant.time()),
            crossing: *crossing,
        });
        Ok(self.go_on_crossing(plant, target))
    }

    /// Whether a crossing is under way: the plant stands on its path.
    pub fn crossing_in_flight(&self) -> bool {
        self.in_flight.is_some()
    }

    /// The crossing under way taken on to `target`, as in [`CoSimulation::cross`]. Returns
    /// whether it is complete (as it is where none is under way).
    pub fn go_on_crossing(&mut self, plant: &mut Plant, target: f64) -> bool {
        let Some(flight) = self.in_flight else {
            return true;
        };
        self.restart = true;
        self.carried = None;
        if target >= flight.end() {
            plant.jump(flight.end(), flight.crossing.state);
            self.in_flight = None;
            true
        } else {
            plant.jump(target, flight.state_at(plant.params(), target));
            false
        }
    }

    pub fn statistics(&self) -> Statistics {
        self.solver.statistics()
    }

    /// Start a master's call: from now on the integrators may do `work` more right-hand
    /// sides in it ([`CALL_WORK`]).
    #[inline(always)]
    pub fn allow_work(&mut self, work: u64) {
        self.solver.allow_work(work);
    }

    /// Count `rhs` right-hand sides evaluated on the driver's behalf (on copies of it).
    pub fn count_work(&mut self, rhs: u64) {
        self.solver.count_work(rhs);
    }

    /// What is left of the work the call allows.
    pub fn work_left(&self) -> u64 {
        self.solver.work_left()
    }

    /// After a failed [`CoSimulation::advance`] towards `target`: the plant moved on to the
    /// integrator's last accepted step, where it got to, if that lies between the plant's
    /// point and `target` and its state is on the constraint. Returns whether it moved.
    pub fn accept_reached(
        &mut self,
        plant: &mut Plant,
        target: f64,
        experiment: &Experiment,
    ) -> bool {
        if !(self.integrator_time > plant.time() && self.integrator_time < target) {
            return false;
        }
        let mut y = self.integrator_state;
        let accuracy = projection_accuracy(experiment.tolerance);
        match model::project(plant.params(), &mut y, accuracy) {
            Ok(at) if all_finite(&y) => {
                let reached = (self.integrator_time, &y);
                let Ok(()) = self.follow_sensitivities(plant, reached, experiment, false) else {
                    return false;
                };
                plant.accept_point(self.integrator_time, y, &at);
                self.restart = true;
                self.carried = None;
                true
            }
            _ => false,
        }
    }

    /// What the statistics outputs show.
    pub fn activity(&self) -> Activity {
        super::activity(self.solver.statistics(), self.solver.method())
    }

    /// `solver = dop853` on a problem where DOP853 is limited by stability (see
    /// [`Integrator::fixed_dop853_is_stiff`]): worth a warning to the user.
    pub fn dop853_is_stability_limited(&self) -> bool {
        self.solver.fixed_dop853_is_stiff()
    }

    /// Advance the plant's communication point to `t_end`. On error the plant's time and
    /// state stay as they were.
    #[inline(always)]
    pub fn advance(
        &mut self,
        plant: &mut Plant,
        t_end: f64,
        experiment: &Experiment,
    ) -> Result<(), SolverError> {
        if plant.take_changed() {
            self.restart = true;
            // f at the integrator's point no longer holds for the new parameters or state.
            self.carried = None;
        }
        if self.solver.reconsider(t_end - plant.time()) {
            // `auto` changed method: the new one starts from the communication point.
            self.restart = true;
        }
        if !plant.input_derivatives().is_zero() {
            // The input polynomials are anchored at this step's start: a new right-hand side.
            self.restart = true;
        }
        let inputs_changed = *plant.inputs() != self.integrator_inputs;
        if inputs_changed && !self.input_change_is_negligible(plant, experiment) {
            self.restart = true;
        }
        // Whether the integrator starts this step afresh from the communication point.
        let fresh = if self.restart {
            // With a carried stage the integrator stands on the communication point already
            // (see `CarriedStage`), and starts from its own state there.
            if self.carried.is_none() {
                self.integrator_time = plant.time();
                self.integrator_state = *plant.state();
            }
            self.integrator_inputs = *plant.inputs();
            self.solver.invalidate();
            self.restart = false;
            true
        } else if inputs_changed && self.integrator_time < t_end {
            // A negligible change: the next step takes the new inputs, from the integrator's
            // own point and with its step size. From the communication point itself that is
            // a fresh start, unless the inputs moved by rounding only (a master
            // interpolating a held input).
            let fresh = self.integrator_time == plant.time()
                && beyond_rounding(plant.inputs(), &self.integrator_inputs);
            self.integrator_inputs = *plant.inputs();
            self.solver.invalidate();
            fresh
        } else {
            false
        };
        let short = fresh && self.solver.suits_short_step(t_end - plant.time());
        if !short && self.carried.is_some() {
            self.carried = None;
        }
        let start = plant.time();
        let (y, at) = self.integrate_to(plant, t_end, experiment, short)?;
        self.follow_sensitivities(plant, (t_end, &y), experiment, fresh)
            .inspect_err(|_| self.restart = true)?;
        plant.accept_point(t_end, y, &at);
        plant.move_inputs_on(start);
        Ok(())
    }

    /// The sensitivities, where the plant asks for them, taken from the plant's point to
    /// `t_end` (with `fresh`, from the plant's state) and handed to the plant; the plant
    /// itself has not moved yet, `y` being its projected state at `t_end`.
    fn follow_sensitivities(
        &mut self,
        plant: &mut Plant,
        (t_end, y): (f64, &State),
        experiment: &Experiment,
        fresh: bool,
    ) -> Result<(), SolverError> {
        let Some(tracker) = &mut self.sensitivities else {
            return Ok(());
        };
        let work = self.solver.work_left();
        let values = tracker.advance(
            plant,
            (t_end, y),
            (experiment.limit(), fresh, self.integrator_inputs),
            (projection_accuracy(experiment.tolerance), work),
        )?;
        plant.set_sensitivities(values);
        Ok(())
    }

    /// The integrator taken to (or past) `t_end`, and the state there, projected; with
    /// `short`, by short steps that end on `t_end` ([`Integrator::integrate_short`]), the
    /// first from the carried stage if one is kept.
    #[inline(always)]
    fn integrate_to(
        &mut self,
        plant: &Plant,
        t_end: f64,
        experiment: &Experiment,
        short: bool,
    ) -> Result<(State, Projected), SolverError> {
        let system = Driven::new(plant, &self.integrator_inputs, experiment.tolerance);
        let limit = experiment.limit().max(t_end);
        if self.integrator_time < t_end {
            let gap = t_end - self.integrator_time;
            if gap <= UNRESOLVED_STEP * self.integrator_time.abs().max(1.0) {
                // Shorter than any step the integrator takes: one Taylor step, y + h·f(t, y),
                // whose error h²·|ÿ|/2 lies far below the rounding of y. The integrator
                // continues from there (with its step size).
                let mut f = [0.0; STATE_SIZE];
                system.rhs(self.integrator_time, &self.integrator_state, &mut f);
                for (y, dy) in self.integrator_state.iter_mut().zip(f) {
                    *y += gap * dy;
                }
                self.integrator_time = t_end;
                self.solver.invalidate();
                self.carried = None;
            } else {
                let stepped = if short {
                    let point = (&mut self.integrator_time, &mut self.integrator_state);
                    step_short(&mut self.solver, &mut self.carried, point, &system, t_end)
                } else {
                    let (t, y) = (&mut self.integrator_time, &mut self.integrator_state);
                    self.solver.integrate(&system, t, y, t_end, limit)
                };
                if let Err(error) = stepped {
                    self.restart = true;
                    return Err(error);
                }
            }
        }
        let integrator = (self.integrator_time, &self.integrator_state);
        at_communication_point(&mut self.solver, &system, integrator, t_end).inspect_err(|_| {
            self.restart = true;
            self.carried = None;
        })
    }

    /// Whether the integrator may go on past the master's new inputs without a restart.
    ///
    /// The integrator's last step, computed with the old inputs, may reach past the
    /// communication point by `lag`; the dense output there, and its stored first stage,
    /// carry the old inputs, and its next step takes the new ones. Over the lag the state
    /// then drifts from the true one by about Δf·lag, Δf being the change of the right-hand
    /// side at the communication point. The change is negligible when that drift is within
    /// a tenth of the integrator's error scale (atol + rtol·|y_i|) in every component: a
    /// tenth of what one step may add, at most once per step. An input moved by a few ulps
    /// (a master interpolating a constant input) is negligible at every tolerance above
    /// about 1e-12; a change that matters restarts the integrator as before.
    fn input_change_is_negligible(&self, plant: &Plant, experiment: &Experiment) -> bool {
        let lag = self.integrator_time - plant.time();
        if lag <= 0.0 {
            return true;
        }
        let (mut new, mut old) = ([0.0; STATE_SIZE], [0.0; STATE_SIZE]);
        let (time, state) = (plant.time(), plant.state());
        Driven::new(plant, plant.inputs(), experiment.tolerance).rhs(time, state, &mut new);
        Driven::new(plant, &self.integrator_inputs, experiment.tolerance)
            .rhs(time, state, &mut old);
        let Tolerances { rtol, atol } = self.solver.tolerances();
        (0..STATE_SIZE).all(|i| {
            (new[i] - old[i]).abs() * lag <= NEGLIGIBLE_DRIFT * (atol + rtol * state[i].abs())
        })
    }

    /// Whether the integrator starts over before its next step, for whatever reason.
    pub(super) fn restarts(&self, plant: &Plant) -> bool {
        self.restart || plant.is_changed()
    }
}

/// Short steps from the integrator's point to `t_end` ([`Integrator::integrate_short`]),
/// the first from the `carried` stage if one is kept, keeping f at the end for the next.
/// Out of line: a run without input changes never comes here, and its communication
/// points stay lean.
#[inline(never)]
fn step_short(
    solver: &mut Integrator<STATE_SIZE>,
    carried: &mut Option<CarriedStage>,
    (t, y): (&mut f64, &mut State),
    system: &Driven,
    t_end: f64,
) -> Result<(), SolverError> {
    let first = carried.take().map(|stage| {
        let mut f = stage.f;
        model::shift_inputs(system.params, &mut f, &stage.inputs, &system.inputs_at(*t));
        f
    });
    let end = solver.integrate_short(system, (t, y), t_end, first)?;
    *carried = end.map(|f| CarriedStage {
        f,
        inputs: system.inputs_at(t_end),
    });
    Ok(())
}

/// The state at communication point `t_end` from the integrator (at `time` with `state`,
/// or its dense output inside the last step), projected onto the constraint; with the
/// closure g and the gradient terms there. `system` is the one the integrator's memory
/// belongs to.
#[inline(always)]
fn at_communication_point(
    solver: &mut Integrator<STATE_SIZE>,
    system: &Driven,
    (time, state): (f64, &State),
    t_end: f64,
) -> Result<(State, Projected), SolverError> {
    let refused = |reason: String| SolverError::ProjectionFailed { t: t_end, reason };
    let mut y = if time == t_end {
        *state
    } else {
        solver
            .dense_output(system, t_end)
            .ok_or_else(|| refused("no dense output covers this time".into()))?
    };
    match model::project(system.params, &mut y, system.projection_accuracy) {
        Ok(at) if all_finite(&y) => Ok((y, at)),
        Ok(_) => Err(refused("the interpolated state is not finite".into())),
        Err(error) => Err(refused(error.to_string())),
    }
}

/// Whether every component of `y` is finite: x·0 is ±0 for a finite x and NaN for an
/// infinite or NaN one, and so is their sum. Vector multiplications and additions rather
/// than a test and a branch per component, on the path of every communication point.
#[inline(always)]
fn all_finite(y: &State) -> bool {
    let z = y.map(|v| v * 0.0);
    ((z[0] + z[4]) + (z[1] + z[5])) + ((z[2] + z[6]) + (z[3] + z[7])) == 0.0
}

/// The relative accuracy the projection needs of the gradient for the master's relative
/// tolerance `rtol` ([`model::project`]): a millionth of the integrator's tolerance (at
/// most 1.5e-12), below which an error of the velocity constraint cannot matter; rounding
/// where that is larger. Asking rounding of the gradient sent many more projections on to
/// Newton's iteration for no gain in accuracy.
fn projection_accuracy(rtol: f64) -> f64 {
    tolerances(rtol).rtol * 1e-6
}

/// The integrator's tolerances for the master's relative tolerance `rtol` (see
/// [`TOLERANCE_SAFETY`]); the absolute tolerance equals the relative one, as the angles
/// and speeds have unit scale.
fn tolerances(rtol: f64) -> Tolerances {
    let internal = (rtol * TOLERANCE_SAFETY).min(LOOSEST_INTERNAL_TOLERANCE);
    Tolerances {
        rtol: internal,
        atol: internal,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::Value;
    use crate::variables::value_reference;

    #[test]
    fn all_finite_finds_every_non_finite_component() {
        let finite = [0.0, -0.0, 1e308, -1e308, 5e-324, 1.0, -3.5, 2.0];
        assert!(all_finite(&finite));
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            for i in 0..STATE_SIZE {
                let mut y = finite;
                y[i] = bad;
                assert!(!all_finite(&y), "{bad} at {i}");
            }
        }
    }

    /// An input moved by an ulp while the integrator is ahead of the communication point:
    /// no restart, and a state saved then restores (its memory checked against the inputs
    /// it was computed with) and runs on exactly as the original.
    #[test]
    fn a_deferred_input_change_survives_a_saved_state() {
        let motor = value_reference("M_m").unwrap();
        let experiment = Experiment::new(0.0);
        let mut plant = Plant::new();
        plant.initialize(0.0).unwrap();
        let mut driver = CoSimulation::new(&plant, &experiment);
        driver.advance(&mut plant, 0.5, &experiment).unwrap();
        let steps = driver.statistics().n_steps;
        let nudged = f64::from_bits(1f64.to_bits() + 1);
        // A communication step longer than DOP853's steps after the change, so that its
        // last step reaches past the communication point (a short one ends on it).
        plant.set(motor, Value::Real(1.0), false).unwrap();
        driver.advance(&mut plant, 0.6, &experiment).unwrap();
        plant.set(motor, Value::Real(nudged), false).unwrap();
        // A communication point inside the integrator's last step.
        let inside = 0.5 * (0.6 + driver.integrator_time);
        assert!(inside > 0.6, "the integrator is not ahead");
        driver.advance(&mut plant, inside, &experiment).unwrap();
        assert!(
            driver.integrator_time > plant.time(),
            "the integrator is not ahead"
        );
        assert_ne!(
            *plant.inputs(),
            driver.integrator_inputs,
            "the change was not deferred"
        );
        let mut w = Writer::default();
        plant.serialize_into(&mut w);
        driver.serialize_into(&mut w);
        let bytes = w.into_bytes();
        let mut r = Reader::new(&bytes);
        let mut plant_2 = Plant::deserialize_from(&mut r).unwrap();
        let mut driver_2 = CoSimulation::deserialize_from(&mut r, &plant_2, &experiment)
            .expect("a deferred input change restores");
        driver_2.check_initialised(&plant_2, &experiment).unwrap();
        driver.advance(&mut plant, 1.0, &experiment).unwrap();
        driver_2.advance(&mut plant_2, 1.0, &experiment).unwrap();
        assert!(same_bits(plant.state(), plant_2.state()));
        assert!(driver.statistics().n_steps - steps < 40);
    }
}
