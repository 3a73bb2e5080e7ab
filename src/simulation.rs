//! A simulation of the mechanism: parameters, inputs, time, state and the integrator.
//! It knows the variable table but nothing of FMI's C interface or state machine, so a
//! Model Exchange or FMI 3.0 front end can drive the same object.
//!
//! Two points in time are kept apart: the communication point (`time`, `state`: what the
//! outputs show) and the integrator's own point, which may lie ahead of it. While the
//! master changes nothing, the integrator steps at its own pace past communication points
//! and the state at each point comes from the dense output (then projected onto the
//! constraint). When the master changes a parameter or the state, or an input by enough to
//! matter at the tolerance ([`Simulation::input_change_is_negligible`]), the integrator
//! restarts from the communication point.

use crate::model::chart::{handover_indicator, preferred_chart};
use crate::model::params::check_rule;
use crate::model::{
    self, Chart, Coordinates, Dual, Independent, Inputs, ModelError, Parameters, Projected, Scalar,
    State, STATE_SIZE,
};
use crate::snapshot::{same_bits, FormatError, Reader, Writer};
use crate::solver::{Choice, Integrator, Method, OdeSystem, SolverError, Statistics, Tolerances};
use crate::variables::{
    build_table, variable, Input, Local, Output, Slot, Statistic, VarType, Variable, SOLVER_ITEMS,
};

/// Relative tolerance when the master gives none (the DefaultExperiment's).
pub const DEFAULT_TOLERANCE: f64 = 1e-8;
/// Admissible relative tolerances.
pub const TOLERANCE_RANGE: (f64, f64) = (1e-13, 1e-1);
/// Time steps (s) of the central differences along the flow used for output derivatives
/// that have no closed form: about 1e-8 relative accuracy for one difference at the paper's
/// speeds, 1e-6 for the rod force's second derivative (a difference of a difference).
const DIFFERENCE_STEP: f64 = 1e-6;
const SECOND_DIFFERENCE_STEP: f64 = 1e-4;
/// The step-size control holds local errors to this fraction of the master's tolerance,
/// and never above [`LOOSEST_INTERNAL_TOLERANCE`]: the promise is the tolerance at every
/// communication point, which the local error test does not see. Two effects escape it:
/// outputs between integration steps come from DOP853's dense output, whose error is
/// 10-100x that of the step points on this model, and over long undamped runs the phase
/// error accumulates. Measured by the benchmark harness at every communication point
/// against an independent reference (error in units of each state's scale max(1, max|y|),
/// paper case 1 and the 100 s free run, H 1e-4…0.1, tol 1e-3…1e-10): with DOP853's
/// stabilised step-size control and a thirtieth, at most 6.8 x tol (the free run at
/// tol 1e-10); with the unstabilised control, 0.05 gave 15.3 x and 0.02 at most 6.3 x,
/// for 4-7 % more evaluations than the stabilised control at a thirtieth.
pub const TOLERANCE_SAFETY: f64 = 1.0 / 30.0;
/// Above this internal tolerance DOP853's steps on the paper's mechanism reach about
/// 0.1 s, where its interpolant is no longer accurate: with 2e-5 (tol 1e-3) ω1 between
/// steps was off by 10 x tol at case 1; with the stabilised control, 2e-6 gave 7.4 x tol
/// at tol 1e-4 (H = 1e-3) and 1.5e-6 at most 2.6 x. Looser tolerances therefore cost what
/// 1e-4 costs (case 1 at H = 0.01: 2150 evaluations).
pub const LOOSEST_INTERNAL_TOLERANCE: f64 = 1.5e-6;

/// A value of one of the FMI types used here (Enumerations travel as Integer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
}

/// The integration method chosen by the `solver` parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverKind {
    Auto = 1,
    Dop853 = 2,
    Implicit = 3,
}

impl SolverKind {
    fn choice(self) -> Choice {
        match self {
            SolverKind::Auto => Choice::Auto,
            SolverKind::Dop853 => Choice::Fixed(Method::Dop853),
            SolverKind::Implicit => Choice::Fixed(Method::Radau5),
        }
    }
}

/// First and second time derivatives of the inputs (fmi2SetRealInputDerivatives): within a
/// communication step starting at tc, an input is u(t) = u + u′·(t − tc) + u″·(t − tc)²/2,
/// u being the value the master set. They persist until the master changes them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InputDerivatives {
    pub motor_torque: [f64; 2],
    pub load_torque: [f64; 2],
}

impl InputDerivatives {
    fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// The inputs at time `t` of a step that started at `anchor` with values `base`.
    #[inline]
    fn at(&self, base: &Inputs, anchor: f64, t: f64) -> Inputs {
        let dt = t - anchor;
        let poly = |u: f64, [d1, d2]: [f64; 2]| u + dt * (d1 + 0.5 * dt * d2);
        Inputs {
            motor_torque: poly(base.motor_torque, self.motor_torque),
            load_torque: poly(base.load_torque, self.load_torque),
        }
    }
}

/// The mechanism as the integrator sees it: parameters, and inputs as polynomials in time.
struct Driven<'a> {
    params: &'a Parameters,
    inputs: &'a Inputs,
    /// `None` while the inputs are held (no derivatives set): the right-hand side then
    /// skips the two polynomials (about 12 instructions per evaluation; 1.6 % fewer
    /// instructions on paper case 1 at H = 0.01, tol 1e-6).
    derivatives: Option<&'a InputDerivatives>,
    anchor: f64,
    /// The relative accuracy the projection needs of the gradient ([`model::project`]).
    projection_accuracy: f64,
}

impl<'a> Driven<'a> {
    fn new(
        params: &'a Parameters,
        inputs: &'a Inputs,
        derivatives: &'a InputDerivatives,
        anchor: f64,
        tolerance: f64,
    ) -> Self {
        let derivatives = (!derivatives.is_zero()).then_some(derivatives);
        Self {
            params,
            inputs,
            derivatives,
            anchor,
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

/// Why a value cannot be read or written.
#[derive(Clone, Debug, PartialEq)]
pub enum AccessError {
    UnknownReference(u32),
    /// The variable exists but this operation does not apply to it now.
    NotAllowed(String),
    Invalid(ModelError),
}

impl std::fmt::Display for AccessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AccessError::UnknownReference(vr) => write!(f, "unknown value reference {vr}"),
            AccessError::NotAllowed(message) => f.write_str(message),
            AccessError::Invalid(error) => write!(f, "{error}"),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Simulation {
    params: Parameters,
    inputs: Inputs,
    input_derivatives: InputDerivatives,
    solver_kind: SolverKind,
    tolerance: f64,
    /// The last communication point and the state there (projected).
    time: f64,
    state: State,
    /// |A2A3| − L at `state`, from the projection's last closure evaluation: the
    /// `constraint_residual` output without another pair of sin_cos per step.
    residual: f64,
    /// The integrator's own point, at or ahead of `time`.
    integrator_time: f64,
    integrator_state: State,
    /// The inputs the integrator's memory (its last step, its stored first stage) was
    /// computed with; they differ from `inputs` only by a change too small to matter, until
    /// the integrator steps again.
    integrator_inputs: Inputs,
    /// The master changed something since the integrator last moved: restart it from the
    /// communication point before the next step.
    restart: bool,
    /// The integrator never steps past this (the experiment's stop time, if defined).
    limit: f64,
    /// Which loop angle leads (the `loop_*` variables; docs/model.md §6), switched with
    /// the same hysteresis as Model Exchange's charts.
    chart: Chart,
    solver: Integrator<STATE_SIZE>,
}

impl Default for Simulation {
    fn default() -> Self {
        Self::new()
    }
}

impl Simulation {
    /// A simulation with every variable at its start value, not yet initialised.
    pub fn new() -> Self {
        Self {
            params: Parameters::default(),
            inputs: Inputs::default(),
            input_derivatives: InputDerivatives::default(),
            solver_kind: SolverKind::Auto,
            tolerance: DEFAULT_TOLERANCE,
            time: 0.0,
            state: [0.0; STATE_SIZE],
            residual: 0.0,
            integrator_time: 0.0,
            integrator_state: [0.0; STATE_SIZE],
            integrator_inputs: Inputs::default(),
            restart: true,
            limit: f64::INFINITY,
            chart: Chart::Crank,
            solver: Integrator::new(Choice::Auto, tolerances(DEFAULT_TOLERANCE)),
        }
    }

    pub fn params(&self) -> &Parameters {
        &self.params
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn state(&self) -> &State {
        &self.state
    }

    pub fn inputs(&self) -> &Inputs {
        &self.inputs
    }

    pub fn chart(&self) -> Chart {
        self.chart
    }

    /// The master moves time: Model Exchange's fmi2SetTime, and before initialisation the
    /// experiment's start time, where [`Simulation::initialize`] will place the mechanism
    /// (a state saved before initialisation is checked against it on restore).
    pub fn set_time(&mut self, time: f64) {
        self.time = time;
        self.restart = true;
    }

    /// Model Exchange: the master moves time and state (`state` on the constraint, with
    /// `chart` leading). The integrator is not used; it restarts if Co-Simulation resumes.
    pub fn place(&mut self, time: f64, state: State, chart: Chart) {
        self.time = time;
        self.state = state;
        self.chart = chart;
        self.residual = model::length_residual(&self.params, state[1], state[2]);
        self.restart = true;
    }

    pub fn statistics(&self) -> Statistics {
        self.solver.statistics()
    }

    /// `solver = dop853` on a problem where DOP853 is limited by stability (see
    /// [`Integrator::fixed_dop853_is_stiff`]): worth a warning to the user.
    pub fn dop853_is_stability_limited(&self) -> bool {
        self.solver.fixed_dop853_is_stiff()
    }

    /// Set the relative tolerance (before initialisation).
    pub fn set_tolerance(&mut self, tolerance: f64) -> Result<(), ModelError> {
        let (low, high) = TOLERANCE_RANGE;
        if !(low..=high).contains(&tolerance) {
            return Err(ModelError::new(format!(
                "tolerance = {} must lie in [{low:e}, {high:e}]",
                model::number(tolerance)
            )));
        }
        self.tolerance = tolerance;
        Ok(())
    }

    /// The integrator will not step past `stop_time` (e.g. the experiment's stop time).
    pub fn set_stop_time(&mut self, stop_time: Option<f64>) {
        self.limit = stop_time.unwrap_or(f64::INFINITY);
    }

    /// The consistent initial state at `start_time` (docs/model.md §3); resets the solver.
    pub fn initialize(&mut self, start_time: f64) -> Result<(), ModelError> {
        self.state = model::initial_state(&self.params)?;
        self.residual = model::length_residual(&self.params, self.state[1], self.state[2]);
        let (_, b1, c1) =
            model::kinematics::closure_with_gradient(&self.params, self.state[1], self.state[2]);
        self.chart = preferred_chart(&self.params, b1, c1);
        self.time = start_time;
        self.restart = true;
        self.solver = Integrator::new(self.solver_kind.choice(), tolerances(self.tolerance));
        Ok(())
    }

    /// Advance the communication point to `t_end`. On error the time and state stay as
    /// they were.
    #[inline(always)]
    pub fn advance(&mut self, t_end: f64) -> Result<(), SolverError> {
        if self.solver.reconsider(t_end - self.time) {
            // `auto` changed method: the new one starts from the communication point.
            self.restart = true;
        }
        if !self.input_derivatives.is_zero() {
            // The input polynomials are anchored at this step's start: a new right-hand side.
            self.restart = true;
        }
        let inputs_changed = self.inputs != self.integrator_inputs;
        if inputs_changed && !self.input_change_is_negligible() {
            self.restart = true;
        }
        if self.restart {
            self.integrator_time = self.time;
            self.integrator_state = self.state;
            self.integrator_inputs = self.inputs;
            self.solver.invalidate();
            self.restart = false;
        } else if inputs_changed && self.integrator_time < t_end {
            // A negligible change: the next step takes the new inputs, from the integrator's
            // own point and with its step size.
            self.integrator_inputs = self.inputs;
            self.solver.invalidate();
        }
        // Disjoint borrows of the fields (self.integrator_system() would borrow all of self).
        let system = Driven::new(
            &self.params,
            &self.integrator_inputs,
            &self.input_derivatives,
            self.time,
            self.tolerance,
        );
        let limit = self.limit.max(t_end);
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
            } else {
                let (t, y) = (&mut self.integrator_time, &mut self.integrator_state);
                if let Err(error) = self.solver.integrate(&system, t, y, t_end, limit) {
                    self.restart = true;
                    return Err(error);
                }
            }
        }
        let integrator = (self.integrator_time, &self.integrator_state);
        let (y, at) = match at_communication_point(&mut self.solver, &system, integrator, t_end) {
            Ok(found) => found,
            Err(error) => {
                self.restart = true;
                return Err(error);
            }
        };
        self.time = t_end;
        self.state = y;
        self.residual = model::length_residual_from_closure(&self.params, at.closure);
        if handover_indicator(&self.params, self.chart, at.b1, at.c1) < 0.0 {
            self.chart = self.chart.other();
        }
        Ok(())
    }

    /// The current value of variable `vr`.
    pub fn get(&self, vr: u32) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        Ok(self.value_of(var.slot))
    }

    /// The current value of `vr` read through an accessor of type `accessor` (Real;
    /// Integer, for Integer and Enumeration variables; Boolean): one lookup, type checked.
    pub fn read(&self, vr: u32, accessor: VarType) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let probe = match accessor {
            VarType::Real => Value::Real(0.0),
            VarType::Integer | VarType::Enumeration => Value::Integer(0),
            VarType::Boolean => Value::Boolean(false),
        };
        check_type(var, probe)?;
        Ok(self.value_of(var.slot))
    }

    /// The system the integrator solves, anchored at the current communication point.
    fn system(&self) -> Driven<'_> {
        Driven::new(
            &self.params,
            &self.inputs,
            &self.input_derivatives,
            self.time,
            self.tolerance,
        )
    }

    /// The system the integrator's memory belongs to: as [`Simulation::system`], with the
    /// inputs the integrator last stepped with.
    fn integrator_system(&self) -> Driven<'_> {
        Driven {
            inputs: &self.integrator_inputs,
            ..self.system()
        }
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
    fn input_change_is_negligible(&self) -> bool {
        let lag = self.integrator_time - self.time;
        if lag <= 0.0 {
            return true;
        }
        let (mut new, mut old) = ([0.0; STATE_SIZE], [0.0; STATE_SIZE]);
        self.system().rhs(self.time, &self.state, &mut new);
        self.integrator_system()
            .rhs(self.time, &self.state, &mut old);
        let Tolerances { rtol, atol } = self.solver.tolerances();
        (0..STATE_SIZE).all(|i| {
            (new[i] - old[i]).abs() * lag <= NEGLIGIBLE_DRIFT * (atol + rtol * self.state[i].abs())
        })
    }

    /// Set the `order`-th time derivative (1 or 2) of input `vr` for the steps to come.
    pub fn set_input_derivative(
        &mut self,
        vr: u32,
        order: i32,
        value: f64,
    ) -> Result<(), AccessError> {
        let slot = self.check_input_derivative(vr, order, value)?;
        let derivatives = match slot {
            Slot::Input(Input::MotorTorque) => &mut self.input_derivatives.motor_torque,
            _ => &mut self.input_derivatives.load_torque,
        };
        if derivatives[order as usize - 1] != value {
            derivatives[order as usize - 1] = value;
            self.restart = true;
        }
        Ok(())
    }

    /// Check an input derivative without setting it (for validating a batch first).
    pub fn check_input_derivative(
        &self,
        vr: u32,
        order: i32,
        value: f64,
    ) -> Result<Slot, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        if !matches!(var.slot, Slot::Input(_)) {
            return Err(AccessError::NotAllowed(format!(
                "{} is not an input: it has no input derivatives",
                var.name
            )));
        }
        if !(1..=2).contains(&order) {
            return Err(AccessError::NotAllowed(format!(
                "order = {order} for {}: must be 1 or 2",
                var.name
            )));
        }
        if !value.is_finite() || value.abs() > MAX_INPUT_DERIVATIVE {
            return Err(AccessError::NotAllowed(format!(
                "derivative of {} = {}: must be finite, within ±{MAX_INPUT_DERIVATIVE:e}",
                var.name,
                model::number(value)
            )));
        }
        Ok(var.slot)
    }

    /// The `order`-th time derivative (1 or 2) of output `vr` at the communication point.
    /// Exact where a formula exists (φ′ = ω, φ″ = ω′ = ω̇, energy′ = power of docs/model.md §2,
    /// residual′ = G·ω/|d|); otherwise a central difference along the flow.
    pub fn output_derivative(&self, vr: u32, order: i32) -> Result<f64, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let Slot::Output(output) = var.slot else {
            return Err(AccessError::NotAllowed(format!(
                "{} is not a Real output: it has no output derivatives",
                var.name
            )));
        };
        let (y, t) = (&self.state, self.time);
        match (order, output) {
            (1, _) => Ok(self.rate(output, y, t)),
            (2, Output::Angle(i)) => Ok(self.rate(Output::Speed(i), y, t)),
            // A difference of a difference: a wider outer step keeps rounding small. (A second
            // difference along the line y ± s·ẏ would miss the ∇F·ÿ term of d²F/dt².)
            (2, Output::RodForce) => Ok(self.central_difference(
                |ys, ts| self.rate(Output::RodForce, ys, ts),
                y,
                t,
                SECOND_DIFFERENCE_STEP,
            )),
            (2, _) => Ok(self.central_difference(
                |ys, ts| self.rate(output, ys, ts),
                y,
                t,
                DIFFERENCE_STEP,
            )),
            _ => Err(AccessError::NotAllowed(format!(
                "order = {order} for {}: must be 1 or 2",
                var.name
            ))),
        }
    }

    /// The first time derivative of `output` at (y, t) along the flow.
    fn rate(&self, output: Output, y: &State, t: f64) -> f64 {
        let inputs = self.system().inputs_at(t);
        match output {
            Output::Angle(i) => y[4 + i],
            Output::Speed(i) => model::accelerations(&self.params, &inputs, y).omega_dot[i],
            Output::Energy => model::power(&self.params, &inputs, y),
            Output::ConstraintResidual => {
                let (g, b1, c1) =
                    model::kinematics::closure_with_gradient(&self.params, y[1], y[2]);
                let length = (self.params.L * self.params.L + 2.0 * g).sqrt();
                (b1 * y[5] - c1 * y[6]) / length
            }
            Output::RodForce => self.central_difference(
                |ys, ts| model::rod_force(&self.params, &self.system().inputs_at(ts), ys),
                y,
                t,
                DIFFERENCE_STEP,
            ),
        }
    }

    /// (y + s·ẏ, t + s): a point along the flow, s small.
    fn along_flow(&self, y: &State, t: f64, s: f64) -> (State, f64) {
        let mut dy = [0.0; STATE_SIZE];
        self.system().rhs(t, y, &mut dy);
        (std::array::from_fn(|i| y[i] + s * dy[i]), t + s)
    }

    /// d/dt f(y(t), t) ≈ (f(y + hẏ, t + h) − f(y − hẏ, t − h))/(2h), exact to O(h²).
    fn central_difference(&self, f: impl Fn(&State, f64) -> f64, y: &State, t: f64, h: f64) -> f64 {
        let (ya, ta) = self.along_flow(y, t, h);
        let (yb, tb) = self.along_flow(y, t, -h);
        (f(&ya, ta) - f(&yb, tb)) / (2.0 * h)
    }

    /// A Real variable's value: the hot path of fmi2GetReal. φ and ω take one subtraction
    /// and one comparison, and need no check (`advance` keeps the state finite; inputs and
    /// parameters are checked when set). The computed outputs are checked: none leaves the
    /// FMU non-finite.
    #[inline]
    pub fn read_real(&self, vr: u32) -> Result<f64, AccessError> {
        if let Some(y) = self.state.get(vr.wrapping_sub(FIRST_STATE_VR) as usize) {
            return Ok(*y);
        }
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let value = self
            .real_of(var.slot)
            .ok_or_else(|| check_type(var, Value::Real(0.0)).unwrap_err())?;
        if !value.is_finite() {
            return Err(self.not_finite(var.name, value));
        }
        Ok(value)
    }

    /// The refusal of a value that would leave the FMU non-finite: the last guard.
    pub fn not_finite(&self, name: &str, value: f64) -> AccessError {
        let y = &self.state;
        AccessError::NotAllowed(format!(
            "{name} = {value} at t = {} is not finite: the model left its valid range \
             (state: phi2 = {}, phi3 = {}, omega2 = {}, omega3 = {})",
            self.time, y[1], y[2], y[5], y[6]
        ))
    }

    /// The value in a Real slot; `None` for the Integer and Enumeration slots.
    #[inline]
    fn real_of(&self, slot: Slot) -> Option<f64> {
        match slot {
            Slot::Output(output) => Some(self.output(output)),
            Slot::Input(Input::MotorTorque) => Some(self.inputs.motor_torque),
            Slot::Input(Input::LoadTorque) => Some(self.inputs.load_torque),
            Slot::Parameter(i) => Some(self.params.get(i).unwrap_or(f64::NAN)),
            Slot::Local(local) => Some(self.local(local)),
            Slot::Statistic(_)
            | Slot::SolverChoice
            | Slot::LinkageClass
            | Slot::LoopChart
            | Slot::BuiltinLaws => None,
        }
    }

    fn value_of(&self, slot: Slot) -> Value {
        if let Some(value) = self.real_of(slot) {
            return Value::Real(value);
        }
        let statistic = |count: u64| Value::Integer(count.min(i32::MAX as u64) as i32);
        match slot {
            Slot::Statistic(Statistic::Steps) => statistic(self.solver.statistics().n_steps),
            Slot::Statistic(Statistic::Rejected) => statistic(self.solver.statistics().n_rejected),
            Slot::Statistic(Statistic::RightHandSides) => statistic(self.solver.statistics().n_rhs),
            Slot::Statistic(Statistic::ActiveSolver) => {
                Value::Integer(match self.solver.method() {
                    Method::Dop853 => SolverKind::Dop853 as i32,
                    Method::Radau5 => SolverKind::Implicit as i32,
                })
            }
            Slot::SolverChoice => Value::Integer(self.solver_kind as i32),
            Slot::LinkageClass => Value::Integer(model::classify(&self.params) as i32),
            Slot::LoopChart => Value::Integer(self.chart as i32),
            Slot::BuiltinLaws => Value::Boolean(self.params.builtin_laws),
            Slot::Output(_) | Slot::Input(_) | Slot::Parameter(_) | Slot::Local(_) => {
                unreachable!("Real slots")
            }
        }
    }

    /// Set input or parameter `vr`; `parameters_writable` says whether parameters may
    /// change now. A rejected value changes nothing; an unchanged value restarts nothing.
    pub fn set(
        &mut self,
        vr: u32,
        value: Value,
        parameters_writable: bool,
    ) -> Result<(), AccessError> {
        let slot = self.check_set(vr, value, parameters_writable)?;
        if self.get(vr)? == value {
            return Ok(());
        }
        match (slot, value) {
            (Slot::Input(Input::MotorTorque), Value::Real(v)) => self.inputs.motor_torque = v,
            (Slot::Input(Input::LoadTorque), Value::Real(v)) => self.inputs.load_torque = v,
            (Slot::Parameter(i), Value::Real(v)) => {
                self.params.set(i, v).map_err(AccessError::Invalid)?
            }
            (Slot::SolverChoice, Value::Integer(v)) => {
                self.solver_kind = solver_kind(v).expect("checked")
            }
            (Slot::BuiltinLaws, Value::Boolean(on)) => self.params.builtin_laws = on,
            _ => unreachable!("check_set admits only writable slots of the right type"),
        }
        // The right-hand side changed: restart the integrator from the communication point
        // (for an input, only if the change matters; see `advance`).
        if !matches!(slot, Slot::Input(_)) {
            self.restart = true;
        }
        Ok(())
    }

    /// Check that `value` may be written to `vr` now, without writing it: lets a caller
    /// validate a whole batch before applying any of it. Returns the slot.
    pub fn check_set(
        &self,
        vr: u32,
        value: Value,
        parameters_writable: bool,
    ) -> Result<Slot, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        check_type(var, value)?;
        if let Value::Real(v) = value {
            if !v.is_finite() {
                return Err(AccessError::NotAllowed(format!(
                    "{} = {v}: must be a finite number",
                    var.name
                )));
            }
        }
        let fixed = || {
            AccessError::NotAllowed(format!(
                "{} is a fixed parameter: it can only be set before fmi2ExitInitializationMode",
                var.name
            ))
        };
        match (var.slot, value) {
            (Slot::Input(_), Value::Real(v)) => {
                model::params::INPUT_RULE.check(v).map_err(|rule| {
                    AccessError::NotAllowed(format!("{} = {} {rule}", var.name, model::number(v)))
                })?
            }
            (Slot::Parameter(_) | Slot::SolverChoice | Slot::BuiltinLaws, _)
                if !parameters_writable =>
            {
                return Err(fixed())
            }
            (Slot::Parameter(i), Value::Real(v)) => {
                check_rule(&model::PARAMETERS[i], v).map_err(AccessError::Invalid)?
            }
            (Slot::SolverChoice, Value::Integer(v)) => {
                if solver_kind(v).is_none() {
                    return Err(AccessError::NotAllowed(format!(
                        "solver = {v}: must be 1 (auto), 2 (dop853) or 3 (implicit)"
                    )));
                }
            }
            (Slot::BuiltinLaws, Value::Boolean(_)) => {}
            _ => {
                let what = if var.causality() == crate::variables::Causality::Local {
                    "a Model Exchange state or derivative, set through fmi2SetContinuousStates"
                } else {
                    "an output"
                };
                return Err(AccessError::NotAllowed(format!(
                    "{} is {what} and cannot be set",
                    var.name
                )));
            }
        }
        Ok(var.slot)
    }

    /// The independent coordinates and their derivatives (docs/model.md §6).
    pub fn local(&self, local: Local) -> f64 {
        real_value(
            &self.params,
            &self.inputs,
            &self.state,
            self.chart,
            Slot::Local(local),
        )
        .expect("a Real slot")
    }

    /// An output, computed from the current state and inputs; diagnostics only on demand.
    #[inline]
    pub fn output(&self, output: Output) -> f64 {
        match output {
            // Kept from the projection: no second pair of sin_cos per communication point.
            Output::ConstraintResidual => self.residual,
            _ => real_value(
                &self.params,
                &self.inputs,
                &self.state,
                self.chart,
                Slot::Output(output),
            )
            .expect("a Real slot"),
        }
    }

    /// The derivatives of the Real `unknowns` along a direction of the knowns (fmi2GetDirectionalDerivative),
    /// exact by forward-mode differentiation: `input_seed` moves M_m and M_r; `states`, in
    /// Model Exchange, gives the independent coordinates with their seed. Without
    /// `states` the state is held (Co-Simulation's outputs at a communication point).
    pub fn directional_derivatives(
        &self,
        states: Option<(&Coordinates, &Independent, &[f64; 6])>,
        input_seed: [f64; 2],
        unknowns: &[u32],
        out: &mut [f64],
    ) -> Result<(), AccessError> {
        let inputs = Inputs {
            motor_torque: Dual::new(self.inputs.motor_torque, input_seed[0]),
            load_torque: Dual::new(self.inputs.load_torque, input_seed[1]),
        };
        let y: [Dual; STATE_SIZE] = match states {
            Some((at, x, seed)) => {
                let x: [Dual; 6] = std::array::from_fn(|i| Dual::new(x[i], seed[i]));
                model::chart::full_state(&self.params, at, &x).map_err(AccessError::Invalid)?
            }
            None => self.state.map(Dual::constant),
        };
        for (vr, value) in unknowns.iter().zip(out.iter_mut()) {
            let var = variable(*vr).ok_or(AccessError::UnknownReference(*vr))?;
            let derivative = real_value(&self.params, &inputs, &y, self.chart, var.slot)
                .ok_or_else(|| {
                    AccessError::NotAllowed(format!(
                        "{} is not an unknown: directional derivatives are of Real outputs and \
                         state derivatives",
                        var.name
                    ))
                })?
                .d;
            if !derivative.is_finite() {
                return Err(self.not_finite(&format!("the derivative of {}", var.name), derivative));
            }
            *value = derivative;
        }
        Ok(())
    }
}

/// A Real output or Model Exchange variable of state `y` under `inputs` with `chart` leading,
/// generic so that one definition serves values and exact derivatives; `None` for the
/// slots that are not computed from the state. Inlined: in fmi2GetReal's path the match
/// on the slot then folds into the caller's.
#[inline(always)]
fn real_value<T: Scalar>(
    p: &Parameters,
    inputs: &Inputs<T>,
    y: &[T; STATE_SIZE],
    chart: Chart,
    slot: Slot,
) -> Option<T> {
    let lead = chart.leader();
    Some(match slot {
        Slot::Output(Output::Angle(i)) => y[i],
        Slot::Output(Output::Speed(i)) => y[4 + i],
        Slot::Output(Output::RodForce) => model::rod_force(p, inputs, y),
        Slot::Output(Output::ConstraintResidual) => model::length_residual(p, y[1], y[2]),
        Slot::Output(Output::Energy) => model::energy(p, y),
        Slot::Local(Local::LoopAngle) => y[lead],
        Slot::Local(Local::LoopSpeed) => y[lead + 4],
        Slot::Local(Local::Derivative(i)) if i < 3 => [y[4], y[lead + 4], y[7]][i],
        Slot::Local(Local::Derivative(i)) => {
            let a = model::accelerations(p, inputs, y).omega_dot;
            [a[0], a[lead], a[3]][i - 3]
        }
        _ => return None,
    })
}

/// The state component a variable reads: φ_i is y[i], ω_i is y[4 + i] (docs/model.md §2's order),
/// as in [`Simulation::output`]; `real_reads_agree_with_the_variable_table` checks the two agree.
const fn state_component(slot: Slot) -> Option<usize> {
    match slot {
        Slot::Output(Output::Angle(i)) => Some(i),
        Slot::Output(Output::Speed(i)) => Some(4 + i),
        _ => None,
    }
}

/// The value reference of φ1, which φ2…ω4 follow in state order (the table is built that
/// way, and this checks it when compiling): fmi2GetReal serves a state with one
/// subtraction and one comparison. A table lookup per value (itself in place of two nested
/// matches, which perf had put at a tenth of a doStep-and-read cycle at H = 1 ms) took 18
/// instructions more per communication point with the eight states read (valgrind, paper
/// case 1 at H = 0.001).
const FIRST_STATE_VR: u32 = {
    let table = build_table();
    let mut first = 0;
    while !matches!(state_component(table[first].slot), Some(0)) {
        first += 1;
    }
    let mut i = 0;
    while i < STATE_SIZE {
        assert!(
            matches!(state_component(table[first + i].slot), Some(c) if c == i),
            "the states' value references are consecutive, in state order"
        );
        i += 1;
    }
    first as u32
};

impl Simulation {
    /// Everything that determines the simulation's future, for a serialized FMU state.
    pub fn serialize_into(&self, w: &mut Writer) {
        for i in 0..model::PARAMETERS.len() {
            w.f64(self.params.get(i).unwrap_or(f64::NAN));
        }
        w.f64s(&[self.inputs.motor_torque, self.inputs.load_torque]);
        w.f64s(&self.input_derivatives.motor_torque);
        w.f64s(&self.input_derivatives.load_torque);
        w.bool(self.params.builtin_laws);
        w.u8(self.solver_kind as u8);
        w.f64s(&[self.tolerance, self.time]);
        w.f64s(&self.state);
        w.f64s(&[self.residual, self.integrator_time]);
        w.f64s(&self.integrator_state);
        w.f64s(&[
            self.integrator_inputs.motor_torque,
            self.integrator_inputs.load_torque,
        ]);
        w.bool(self.restart);
        w.bool(self.limit.is_finite());
        w.f64(if self.limit.is_finite() {
            self.limit
        } else {
            0.0
        });
        w.u8(self.chart as u8);
        self.solver.serialize_into(w);
    }

    /// The simulation written by [`Simulation::serialize_into`]; parameters are checked again.
    pub fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let invalid = |e: ModelError| FormatError(format!("invalid serialized state: {e}"));
        let mut params = Parameters::default();
        for i in 0..model::PARAMETERS.len() {
            params.set(i, r.f64()?).map_err(invalid)?;
        }
        let [motor_torque, load_torque] = r.f64s()?;
        let input_derivatives = InputDerivatives {
            motor_torque: r.f64s()?,
            load_torque: r.f64s()?,
        };
        params.builtin_laws = r.bool()?;
        let kind = r.u8()?;
        let solver_kind = solver_kind(kind as i32)
            .ok_or_else(|| FormatError(format!("invalid serialized state: solver = {kind}")))?;
        let [tolerance, time] = r.f64s()?;
        let state = r.f64s()?;
        let [residual, integrator_time] = r.f64s()?;
        let integrator_state = r.f64s()?;
        let [integrator_motor_torque, integrator_load_torque] = r.f64s()?;
        let restart = r.bool()?;
        let has_limit = r.bool()?;
        let stored_limit = r.f64()?;
        let limit = if has_limit {
            stored_limit
        } else {
            f64::INFINITY
        };
        let code = r.u8()?;
        let chart = Chart::from_code(code as i32)
            .ok_or_else(|| FormatError(format!("invalid serialized state: loop chart {code}")))?;
        let solver = Integrator::deserialize_from(r)?;
        let simulation = Self {
            params,
            inputs: Inputs {
                motor_torque,
                load_torque,
            },
            input_derivatives,
            solver_kind,
            tolerance,
            time,
            state,
            residual,
            integrator_time,
            integrator_state,
            integrator_inputs: Inputs {
                motor_torque: integrator_motor_torque,
                load_torque: integrator_load_torque,
            },
            restart,
            limit,
            chart,
            solver,
        };
        simulation
            .check_restored()
            .map_err(|e| FormatError(format!("invalid serialized state: {e}")))?;
        Ok(simulation)
    }

    /// The values of a restored simulation, checked one by one (a checksum protects only
    /// against accidents): inputs within their rules, the tolerance in its range and the
    /// integrator's consistent with it, the integrator not behind the communication point.
    fn check_restored(&self) -> Result<(), String> {
        for (name, u) in [
            ("M_m", self.inputs.motor_torque),
            ("M_r", self.inputs.load_torque),
            ("M_m (integrator's)", self.integrator_inputs.motor_torque),
            ("M_r (integrator's)", self.integrator_inputs.load_torque),
        ] {
            model::params::INPUT_RULE
                .check(u)
                .map_err(|rule| format!("input {name} = {} {rule}", model::number(u)))?;
        }
        let derivatives = self
            .input_derivatives
            .motor_torque
            .iter()
            .chain(&self.input_derivatives.load_torque);
        if derivatives
            .into_iter()
            .any(|d| d.abs() > MAX_INPUT_DERIVATIVE)
        {
            return Err("an input derivative is out of range".into());
        }
        let (low, high) = TOLERANCE_RANGE;
        if !(low..=high).contains(&self.tolerance) {
            return Err(format!(
                "tolerance = {} is out of range",
                model::number(self.tolerance)
            ));
        }
        if !self.restart && self.integrator_time < self.time {
            return Err("the integrator is behind the communication point".into());
        }
        // The time may lie past the stop time: Model Exchange's master sets it (its
        // integrator may step beyond the end and interpolate back), and Co-Simulation's last
        // step may end past it by a rounding margin. A further step is refused there, not
        // the state.
        // The integrator's memory is used only while nothing restarts it; then it must be
        // what its own steps on this system give.
        if !self.restart && self.input_derivatives.is_zero() {
            self.solver.check_memory(
                &self.integrator_system(),
                self.integrator_time,
                &self.integrator_state,
            )?;
        }
        Ok(())
    }

    /// After initialisation, without a pending restart, the state at the communication
    /// point is what the integrator gives there, projected: recomputed, it must agree bit
    /// for bit (it did when the state was written).
    fn check_communication_point(&self) -> Result<(), String> {
        if self.restart || !self.input_derivatives.is_zero() {
            return Ok(());
        }
        // On a copy of the integrator: its dense output may form its coefficients.
        let integrator = (self.integrator_time, &self.integrator_state);
        let system = self.integrator_system();
        let (y, at) =
            at_communication_point(&mut self.solver.clone(), &system, integrator, self.time)
                .map_err(|e| e.to_string())?;
        let g = at.closure;
        if !same_bits(&y, &self.state)
            || model::length_residual_from_closure(&self.params, g).to_bits()
                != self.residual.to_bits()
        {
            return Err("the state at the communication point is not the integrator's".into());
        }
        Ok(())
    }

    /// For a state restored after initialisation: the integrator works to the tolerance,
    /// the positions close the loop and the velocities satisfy B1·ω2 = C1·ω3, to well
    /// within what the projection leaves.
    pub fn check_initialised(&self) -> Result<(), String> {
        if self.solver.tolerances() != tolerances(self.tolerance) {
            return Err("the integrator's tolerances do not match the tolerance".into());
        }
        self.check_communication_point()?;
        let (p, y) = (&self.params, &self.state);
        let residual = model::length_residual(p, y[1], y[2]);
        let size = p.l + p.l2 + p.l3 + p.L;
        if residual.is_nan() || residual.abs() > 1e-8 * size {
            return Err(format!(
                "the positions do not close the loop (|A2A3| - L = {})",
                model::number(residual)
            ));
        }
        let (_, b1, c1) = model::kinematics::closure_with_gradient(p, y[1], y[2]);
        let (along, across) = (b1 * y[5], c1 * y[6]);
        let allowed = 1e-8 * (along.abs() + across.abs()) + 1e-12 * size * size;
        if (along - across).is_nan() || (along - across).abs() > allowed {
            return Err(format!(
                "the velocities break the constraint (B1·omega2 - C1·omega3 = {})",
                model::number(along - across)
            ));
        }
        if (residual - self.residual).abs() > 1e-12 * size {
            return Err("the stored constraint residual is not the state's".into());
        }
        Ok(())
    }
}

/// The drift an input change may cause before the integrator takes the new input, as a
/// fraction of its error scale ([`Simulation::input_change_is_negligible`]).
const NEGLIGIBLE_DRIFT: f64 = 0.1;

/// A gap to the next communication point that the integrator does not resolve (it takes
/// no step below 16·ε·|t|; see `solver::check_step_size`), with a margin.
const UNRESOLVED_STEP: f64 = 64.0 * f64::EPSILON;

/// Input derivatives beyond this (N·m/s, N·m/s²) would carry the inputs past any torque
/// the model admits within a second.
const MAX_INPUT_DERIVATIVE: f64 = 1e15;

/// The FMI accessor must match the variable's type.
fn check_type(var: &Variable, value: Value) -> Result<(), AccessError> {
    let matches = matches!(
        (var.var_type(), value),
        (VarType::Real, Value::Real(_))
            | (VarType::Integer | VarType::Enumeration, Value::Integer(_))
            | (VarType::Boolean, Value::Boolean(_))
    );
    if matches {
        return Ok(());
    }
    let accessor = match var.var_type() {
        VarType::Real => "Real",
        VarType::Integer | VarType::Enumeration => "Integer",
        VarType::Boolean => "Boolean",
    };
    Err(AccessError::NotAllowed(format!(
        "{} is of type {}: use fmi2Get{accessor}/fmi2Set{accessor}",
        var.name,
        var.var_type().as_str()
    )))
}

fn solver_kind(value: i32) -> Option<SolverKind> {
    SOLVER_ITEMS
        .iter()
        .find(|(_, v, _)| *v == value)
        .map(|(_, v, _)| match v {
            1 => SolverKind::Auto,
            2 => SolverKind::Dop853,
            _ => SolverKind::Implicit,
        })
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
/// than a test and a branch per component: about 20 fewer instructions per communication
/// point (valgrind).
#[inline(always)]
fn all_finite(y: &State) -> bool {
    let z = y.map(|v| v * 0.0);
    ((z[0] + z[4]) + (z[1] + z[5])) + ((z[2] + z[6]) + (z[3] + z[7])) == 0.0
}

/// The relative accuracy the projection needs of the gradient for the master's relative
/// tolerance `rtol` ([`model::project`]): a millionth of the integrator's tolerance (at
/// most 1.5e-12), below which an error of the velocity constraint cannot matter; rounding
/// where that is larger. On paper case 1 at H = 0.01 and tol 1e-4 (with the integrator's
/// tolerance at 2e-6, before its step-size control was stabilised), 22 of the 1114
/// projections that move the angles then went on to Newton's iteration (310 with rounding
/// asked of the gradient), and the run took 0.95–0.98 × the time (0.96–0.97 at
/// H = 0.001; two series of 9–11 alternating rounds through the C ABI).
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
    use crate::variables::{variables, COUNT};

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

    /// fmi2GetReal's fast path for φ and ω (by value reference range) gives what the
    /// general path gives, and every other Real variable still reads through the general
    /// path.
    #[test]
    fn real_reads_agree_with_the_variable_table() {
        let mut sim = Simulation::new();
        sim.set(
            crate::variables::value_reference("omega2_0").unwrap(),
            Value::Real(3.0),
            true,
        )
        .unwrap();
        sim.initialize(0.0).unwrap();
        sim.advance(0.05).unwrap();
        let mut state_reads = 0;
        for (vr, var) in variables() {
            match sim.real_of(var.slot) {
                Some(expected) => {
                    assert_eq!(
                        sim.read_real(vr).unwrap().to_bits(),
                        expected.to_bits(),
                        "{}",
                        var.name
                    );
                    state_reads += usize::from(state_component(var.slot).is_some());
                }
                None => assert!(sim.read_real(vr).is_err(), "{}", var.name),
            }
        }
        assert_eq!(state_reads, STATE_SIZE);
        for i in 0..4 {
            let phi = crate::variables::value_reference(&format!("phi{}", i + 1)).unwrap();
            let omega = crate::variables::value_reference(&format!("omega{}", i + 1)).unwrap();
            assert_eq!(sim.read_real(phi).unwrap(), sim.state()[i]);
            assert_eq!(sim.read_real(omega).unwrap(), sim.state()[4 + i]);
        }
        assert!(sim.read_real(COUNT as u32).is_err());
    }

    /// An input moved by an ulp while the integrator is ahead of the communication point:
    /// no restart, and a state saved then restores (its memory checked against the inputs
    /// it was computed with) and runs on exactly as the original.
    #[test]
    fn a_deferred_input_change_survives_a_saved_state() {
        let motor = crate::variables::value_reference("M_m").unwrap();
        let mut sim = Simulation::new();
        sim.initialize(0.0).unwrap();
        sim.advance(0.5).unwrap();
        let steps = sim.statistics().n_steps;
        let nudged = f64::from_bits(1f64.to_bits() + 1);
        sim.set(motor, Value::Real(1.0), false).unwrap();
        sim.advance(0.501).unwrap();
        sim.set(motor, Value::Real(nudged), false).unwrap();
        sim.advance(0.502).unwrap();
        assert!(
            sim.integrator_time > sim.time,
            "the integrator is not ahead"
        );
        assert_ne!(
            sim.inputs, sim.integrator_inputs,
            "the change was not deferred"
        );
        let mut w = Writer::default();
        sim.serialize_into(&mut w);
        let bytes = w.finish(7);
        let mut restored = Simulation::deserialize_from(&mut Reader::open(&bytes, 7).unwrap())
            .expect("a deferred input change restores");
        restored.check_initialised().unwrap();
        for sim in [&mut sim, &mut restored] {
            sim.advance(1.0).unwrap();
        }
        assert!(same_bits(sim.state(), restored.state()));
        assert!(sim.statistics().n_steps - steps < 40);
    }
}
