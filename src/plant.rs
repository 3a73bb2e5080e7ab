//! The plant: the mechanism as a master sees it, whichever interface or integrator drives
//! it. Parameters, inputs (with their time derivatives), time, the full state on the
//! constraint with the leading loop angle, and from these every output, derivative and
//! event indicator, with every check on the values a master writes. It holds no integrator:
//! the drivers ([`crate::drivers`]) move its time and state, the co-simulation driver by
//! integrating, the Model Exchange adapter from the master's continuous states.
//!
//! A write that changes the right-hand side or moves the state (a parameter, the time, an
//! input derivative, a new state) marks the plant as changed; a driver that remembers the
//! trajectory (the co-simulation integrator) takes that mark and starts over.

use crate::model::chart::{handover_indicator, handover_indicator_at, preferred_chart};
use crate::model::params::check_rule;
use crate::model::sensitivity::{self, Sensitive};
use crate::model::{
    self, Chart, Coordinates, Dual, Independent, Inputs, ModelError, Parameters, Projected, Scalar,
    State, STATE_SIZE,
};
use crate::variables::{
    build_table, variable, Branch, Input, Local, Output, Slot, Statistic, Twin, VarType, Variable,
    SENSITIVITY_SLOTS, SOLVER_ITEMS,
};
use integrators::snapshot::{FormatError, Reader, Writer};
use integrators::{Choice, Method, Statistics};

/// Time steps (s) of the central differences along the flow used for output derivatives
/// that have no closed form: about 1e-8 relative accuracy for one difference at the paper's
/// speeds, 1e-6 for the rod force's second derivative (a difference of a difference).
const DIFFERENCE_STEP: f64 = 1e-6;
const SECOND_DIFFERENCE_STEP: f64 = 1e-4;
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
    /// The integrator's method choice.
    pub fn choice(self) -> Choice {
        match self {
            SolverKind::Auto => Choice::Auto,
            SolverKind::Dop853 => Choice::Fixed(Method::Dop853),
            SolverKind::Implicit => Choice::Fixed(Method::Radau5),
        }
    }
}

/// First and second time derivatives of the inputs (the master's input derivatives): within a
/// communication step starting at tc, an input is u(t) = u + u′·(t − tc) + u″·(t − tc)²/2,
/// u being its value at tc. At the step's end the inputs move on along them (value and
/// first derivative), so that the outputs there see the inputs the step ended with, and
/// the polynomial goes on until the master sets new values or derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InputDerivatives {
    pub motor_torque: [f64; 2],
    pub load_torque: [f64; 2],
}

impl InputDerivatives {
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// The inputs at time `t` of a step that started at `anchor` with values `base`.
    #[inline]
    pub fn at(&self, base: &Inputs, anchor: f64, t: f64) -> Inputs {
        let dt = t - anchor;
        let poly = |u: f64, [d1, d2]: [f64; 2]| u + dt * (d1 + 0.5 * dt * d2);
        Inputs {
            motor_torque: poly(base.motor_torque, self.motor_torque),
            load_torque: poly(base.load_torque, self.load_torque),
        }
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

/// What the integrator driving the plant reports through the statistics outputs
/// (`n_steps`, `n_rejected`, `n_rhs`, `active_solver`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Activity {
    pub statistics: Statistics,
    pub method: Method,
}

impl Activity {
    /// No integrator has run: no work counted, and the explicit method shown.
    pub fn idle() -> Self {
        Self {
            statistics: Statistics::default(),
            method: Method::Dop853,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Plant {
    params: Parameters,
    /// The inputs the plant integrates with at its time: as the master set them, moved on
    /// along their derivatives at each step's end.
    inputs: Inputs,
    /// The inputs as the master last set them, which their getters return: a master that
    /// logs or checks its inputs reads back what it set.
    inputs_set: Inputs,
    input_derivatives: InputDerivatives,
    /// The `solver` parameter: which integrator the co-simulation driver runs.
    solver_kind: SolverKind,
    /// The `change_point_branch` parameter: where a change-point linkage goes on.
    branch: Branch,
    time: f64,
    /// The full state, on the constraint.
    state: State,
    /// |A2A3| − L at `state`, from the projection's last closure evaluation: the
    /// `constraint_residual` output without another pair of sin_cos per step.
    residual: f64,
    /// Which loop angle leads (the `loop_*` variables; docs/model.md §6).
    chart: Chart,
    /// The master changed the right-hand side or moved the state since a driver last took
    /// this mark ([`Plant::take_changed`]).
    changed: bool,
    /// The `sensitivity_k.parameter` slots: the value each holds (0: none), and the
    /// sensitivities ∂y/∂p by state and slot at the plant's point, which the co-simulation
    /// driver computes (docs/sensitivities.md).
    sensitivity_choice: [i32; SENSITIVITY_SLOTS],
    sensitivities: [[f64; SENSITIVITY_SLOTS]; STATE_SIZE],
    /// The Integer twins of `solver`, `change_point_branch` and the slots' parameters
    /// ([`Twin`]): 0 leaves the choice to the Enumeration, an item's value decides.
    codes: Codes,
}

/// The values of the Integer twins, 0 where the Enumeration decides.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Codes {
    solver: i32,
    branch: i32,
    sensitivity: [i32; SENSITIVITY_SLOTS],
}

impl Default for Plant {
    fn default() -> Self {
        Self::new()
    }
}

impl Plant {
    /// A plant with every variable at its start value, not yet initialised.
    pub fn new() -> Self {
        Self {
            params: Parameters::default(),
            inputs: Inputs::default(),
            inputs_set: Inputs::default(),
            input_derivatives: InputDerivatives::default(),
            solver_kind: SolverKind::Auto,
            branch: Branch::Straight,
            time: 0.0,
            state: [0.0; STATE_SIZE],
            residual: 0.0,
            chart: Chart::Crank,
            changed: true,
            sensitivity_choice: [0; SENSITIVITY_SLOTS],
            codes: Codes::default(),
            sensitivities: [[0.0; SENSITIVITY_SLOTS]; STATE_SIZE],
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

    pub fn input_derivatives(&self) -> &InputDerivatives {
        &self.input_derivatives
    }

    /// The branch taken at a change point: the twin's where it holds one, else the
    /// Enumeration's.
    pub fn branch(&self) -> Branch {
        Branch::from_value(self.codes.branch).unwrap_or(self.branch)
    }

    /// The method chosen: the twin's where it holds one, else the Enumeration's.
    pub fn solver_kind(&self) -> SolverKind {
        solver_kind(self.codes.solver).unwrap_or(self.solver_kind)
    }

    /// Slot k's parameter (an item's value, 0 for none): the twin's where it holds one,
    /// else the Enumeration's.
    fn slot_choice(&self, k: usize) -> i32 {
        match self.codes.sensitivity[k] {
            0 => self.sensitivity_choice[k],
            code => code,
        }
    }

    /// Whether the master changed the right-hand side or moved the state since the last
    /// call; clears the mark.
    #[inline(always)]
    pub fn take_changed(&mut self) -> bool {
        std::mem::replace(&mut self.changed, false)
    }

    /// The mark [`Plant::take_changed`] clears, without clearing it.
    pub fn is_changed(&self) -> bool {
        self.changed
    }

    /// The inputs at time `t`: the values the master set, moved along their derivatives
    /// from the current time.
    #[inline(always)]
    pub fn inputs_at(&self, t: f64) -> Inputs {
        if self.input_derivatives.is_zero() {
            self.inputs
        } else {
            self.input_derivatives.at(&self.inputs, self.time, t)
        }
    }

    /// After a communication step from `start`: the inputs moved on along their derivatives
    /// to the plant's time, as the step integrated them. The outputs and their derivatives
    /// at the step's end then see the inputs there, and a next step without new values
    /// continues their polynomials.
    #[inline(always)]
    pub fn move_inputs_on(&mut self, start: f64) {
        if !self.input_derivatives.is_zero() {
            self.move_inputs_along(start);
        }
    }

    /// Out of line: held inputs, the common case, never come here.
    #[inline(never)]
    fn move_inputs_along(&mut self, start: f64) {
        let dt = self.time - start;
        let inputs = self.input_derivatives.at(&self.inputs, start, self.time);
        let mut derivatives = self.input_derivatives;
        for [d1, d2] in [&mut derivatives.motor_torque, &mut derivatives.load_torque] {
            *d1 += dt * *d2;
        }
        // Where they would leave what the model admits, they stay as the master set them.
        let admitted = |d: &[f64; 2]| d.iter().all(|v| v.abs() <= MAX_INPUT_DERIVATIVE);
        if check_inputs(&inputs, "").is_ok()
            && admitted(&derivatives.motor_torque)
            && admitted(&derivatives.load_torque)
        {
            self.inputs = inputs;
            self.input_derivatives = derivatives;
        }
    }

    /// The state's time derivative at (t, y), the inputs moved to t.
    pub fn rhs(&self, t: f64, y: &State, dy: &mut State) {
        model::state_derivative(&self.params, &self.inputs_at(t), y, dy);
    }

    /// A driver's new point: the state `y` at time `t`, projected, `at` the projection's
    /// closure terms. The leading loop angle hands over where its indicator has crossed.
    #[inline(always)]
    pub fn accept_point(&mut self, t: f64, y: State, at: &Projected) {
        self.time = t;
        self.state = y;
        self.residual = model::length_residual_from_closure(&self.params, at.closure);
        if handover_indicator(&self.params, self.chart, at.b1, at.c1) < 0.0 {
            self.chart = self.chart.other();
        }
    }

    /// The master moves time: Model Exchange's SetTime, and before initialisation the
    /// experiment's start time, where [`Plant::initialize`] will place the mechanism
    /// (a state saved before initialisation is checked against it on restore).
    pub fn set_time(&mut self, time: f64) {
        self.time = time;
        self.changed = true;
    }

    /// Model Exchange: the master moves time and state (`state` on the constraint, with
    /// `chart` leading).
    pub fn place(&mut self, time: f64, state: State, chart: Chart) {
        self.time = time;
        self.state = state;
        self.chart = chart;
        self.residual = model::length_residual(&self.params, state[1], state[2]);
        self.changed = true;
    }

    /// A new point that no integrator step led to (the initial state, the end of a crossing
    /// of a change point, docs/model.md §7): `state` is on the constraint, and the loop angle
    /// whose chart is regular there leads.
    pub fn jump(&mut self, time: f64, state: State) {
        self.time = time;
        self.state = state;
        self.residual = model::length_residual(&self.params, state[1], state[2]);
        let (_, b1, c1) =
            model::kinematics::closure_with_gradient(&self.params, state[1], state[2]);
        self.chart = preferred_chart(&self.params, b1, c1);
        self.changed = true;
    }

    /// The consistent initial state at `start_time` (docs/model.md §3), with its
    /// sensitivities to the chosen parameters.
    pub fn initialize(&mut self, start_time: f64) -> Result<(), ModelError> {
        let state = model::initial_state(&self.params)?;
        let slots = self.sensitivity_slots();
        let which: Vec<Sensitive> = slots.iter().map(|&(_, s)| s).collect();
        let initial = sensitivity::initial_by_slot(&self.params, &which)
            .map_err(|e| ModelError::new(format!("sensitivities at the start: {e}")))?;
        self.jump(start_time, state);
        self.sensitivities = [[0.0; SENSITIVITY_SLOTS]; STATE_SIZE];
        for (j, &(slot, _)) in slots.iter().enumerate() {
            for (row, values) in self.sensitivities.iter_mut().zip(&initial) {
                row[slot] = values[j];
            }
        }
        Ok(())
    }

    /// The sensitivity slots in use, in order, with their parameters.
    pub fn sensitivity_slots(&self) -> Vec<(usize, Sensitive)> {
        let mut slots = Vec::new();
        for slot in 0..SENSITIVITY_SLOTS {
            if let Some(Some((_, which))) = sensitivity::chosen(self.slot_choice(slot)) {
                slots.push((slot, which));
            }
        }
        slots
    }

    /// The sensitivities by state and slot at the plant's point.
    pub fn sensitivities(&self) -> &[[f64; SENSITIVITY_SLOTS]; STATE_SIZE] {
        &self.sensitivities
    }

    /// A driver's sensitivities at the plant's new point.
    pub fn set_sensitivities(&mut self, values: [[f64; SENSITIVITY_SLOTS]; STATE_SIZE]) {
        self.sensitivities = values;
    }

    /// The current value of variable `vr`, the statistics as `activity` reports them.
    pub fn get(&self, vr: u32, activity: &Activity) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        Ok(self.value_of(var.slot, activity))
    }

    /// The current value of `vr` read through an accessor of type `accessor` (Real;
    /// Integer, for Integer and Enumeration variables; Boolean): one lookup, type checked.
    pub fn read(
        &self,
        vr: u32,
        accessor: VarType,
        activity: &Activity,
    ) -> Result<Value, AccessError> {
        let var = variable(vr).ok_or(AccessError::UnknownReference(vr))?;
        let probe = match accessor {
            VarType::Real => Value::Real(0.0),
            VarType::Integer | VarType::Enumeration => Value::Integer(0),
            VarType::Boolean => Value::Boolean(false),
        };
        check_type(var, probe)?;
        Ok(self.value_of(var.slot, activity))
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
            self.changed = true;
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
        let inputs = self.inputs_at(t);
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
                |ys, ts| model::rod_force(&self.params, &self.inputs_at(ts), ys),
                y,
                t,
                DIFFERENCE_STEP,
            ),
        }
    }

    /// (y + s·ẏ, t + s): a point along the flow, s small.
    fn along_flow(&self, y: &State, t: f64, s: f64) -> (State, f64) {
        let mut dy = [0.0; STATE_SIZE];
        self.rhs(t, y, &mut dy);
        (std::array::from_fn(|i| y[i] + s * dy[i]), t + s)
    }

    /// d/dt f(y(t), t) ≈ (f(y + hẏ, t + h) − f(y − hẏ, t − h))/(2h), exact to O(h²).
    fn central_difference(&self, f: impl Fn(&State, f64) -> f64, y: &State, t: f64, h: f64) -> f64 {
        let (ya, ta) = self.along_flow(y, t, h);
        let (yb, tb) = self.along_flow(y, t, -h);
        (f(&ya, ta) - f(&yb, tb)) / (2.0 * h)
    }

    /// A Real variable's value: the hot path of the Real getters. φ and ω take one subtraction
    /// and one comparison, and need no check (`advance` keeps the state finite; inputs and
    /// parameters are checked when set). The computed outputs are checked: none leaves the
    /// FMU non-finite. Inlined into both versions' getters: with two callers the compiler
    /// kept it out of line, a call per value read.
    #[inline(always)]
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
            Slot::Input(Input::MotorTorque) => Some(self.inputs_set.motor_torque),
            Slot::Input(Input::LoadTorque) => Some(self.inputs_set.load_torque),
            Slot::Parameter(i) => Some(self.params.get(i).unwrap_or(f64::NAN)),
            Slot::Local(local) => Some(self.local(local)),
            Slot::Sensitivity { slot, state } => Some(self.sensitivities[state][slot]),
            Slot::Statistic(_)
            | Slot::SensitivityParameter(_)
            | Slot::SolverChoice
            | Slot::LinkageClass
            | Slot::LoopChart
            | Slot::BuiltinLaws
            | Slot::ChangePointBranch
            | Slot::Twin(_) => None,
        }
    }

    fn value_of(&self, slot: Slot, activity: &Activity) -> Value {
        if let Some(value) = self.real_of(slot) {
            return Value::Real(value);
        }
        let statistic = |count: u64| Value::Integer(count.min(i32::MAX as u64) as i32);
        match slot {
            Slot::Statistic(Statistic::Steps) => statistic(activity.statistics.n_steps),
            Slot::Statistic(Statistic::Rejected) => statistic(activity.statistics.n_rejected),
            Slot::Statistic(Statistic::RightHandSides) => statistic(activity.statistics.n_rhs),
            Slot::Statistic(Statistic::ActiveSolver) => Value::Integer(match activity.method {
                Method::Dop853 => SolverKind::Dop853 as i32,
                Method::Radau5 => SolverKind::Implicit as i32,
            }),
            Slot::SolverChoice => Value::Integer(self.solver_kind as i32),
            Slot::LinkageClass => Value::Integer(model::classify(&self.params) as i32),
            Slot::LoopChart => Value::Integer(self.chart as i32),
            Slot::BuiltinLaws => Value::Boolean(self.params.builtin_laws),
            Slot::ChangePointBranch => Value::Integer(self.branch as i32),
            Slot::SensitivityParameter(k) => Value::Integer(self.sensitivity_choice[k]),
            Slot::Twin(Twin::Solver) => Value::Integer(self.codes.solver),
            Slot::Twin(Twin::ChangePointBranch) => Value::Integer(self.codes.branch),
            Slot::Twin(Twin::SensitivityParameter(k)) => Value::Integer(self.codes.sensitivity[k]),
            Slot::Output(_)
            | Slot::Input(_)
            | Slot::Parameter(_)
            | Slot::Local(_)
            | Slot::Sensitivity { .. } => {
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
        // An input is compared with what the plant integrates with, which may have moved on
        // from what was set.
        let now = match slot {
            Slot::Input(Input::MotorTorque) => Value::Real(self.inputs.motor_torque),
            Slot::Input(Input::LoadTorque) => Value::Real(self.inputs.load_torque),
            _ => self.get(vr, &Activity::idle())?,
        };
        if let Slot::Input(input) = slot {
            let Value::Real(v) = value else {
                unreachable!("checked: an input is Real")
            };
            match input {
                Input::MotorTorque => self.inputs_set.motor_torque = v,
                Input::LoadTorque => self.inputs_set.load_torque = v,
            }
        }
        if now == value {
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
            (Slot::ChangePointBranch, Value::Integer(v)) => {
                self.branch = Branch::from_value(v).expect("checked")
            }
            (Slot::SensitivityParameter(k), Value::Integer(v)) => self.sensitivity_choice[k] = v,
            (Slot::Twin(Twin::Solver), Value::Integer(v)) => self.codes.solver = v,
            (Slot::Twin(Twin::ChangePointBranch), Value::Integer(v)) => self.codes.branch = v,
            (Slot::Twin(Twin::SensitivityParameter(k)), Value::Integer(v)) => {
                self.codes.sensitivity[k] = v
            }
            _ => unreachable!("check_set admits only writable slots of the right type"),
        }
        // The right-hand side changed. (An input is left to the driver: whether a change
        // matters depends on how far its integrator has gone; the branch matters only at a
        // change point.)
        if !matches!(
            slot,
            Slot::Input(_) | Slot::ChangePointBranch | Slot::Twin(Twin::ChangePointBranch)
        ) {
            self.changed = true;
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
                "{} is a fixed parameter: it can only be set before initialisation ends (ExitInitializationMode)",
                var.name
            ))
        };
        match (var.slot, value) {
            (Slot::Input(_), Value::Real(v)) => {
                model::params::INPUT_RULE.check(v).map_err(|rule| {
                    AccessError::NotAllowed(format!("{} = {} {rule}", var.name, model::number(v)))
                })?
            }
            (
                Slot::Parameter(_)
                | Slot::SolverChoice
                | Slot::BuiltinLaws
                | Slot::SensitivityParameter(_)
                | Slot::Twin(Twin::Solver | Twin::SensitivityParameter(_)),
                _,
            ) if !parameters_writable => return Err(fixed()),
            (Slot::Twin(_), Value::Integer(0)) => {}
            (Slot::Twin(Twin::Solver), Value::Integer(v)) => {
                if solver_kind(v).is_none() {
                    return Err(AccessError::NotAllowed(format!(
                        "{} = {v}: must be 0 (as solver says), 1 (auto), 2 (dop853) or 3 (implicit)",
                        var.name
                    )));
                }
            }
            (Slot::Twin(Twin::ChangePointBranch), Value::Integer(v)) => {
                if Branch::from_value(v).is_none() {
                    return Err(AccessError::NotAllowed(format!(
                        "{} = {v}: must be 0 (as change_point_branch says), 1 (straight) or 2 (turn)",
                        var.name
                    )));
                }
            }
            (Slot::Twin(Twin::SensitivityParameter(_)), Value::Integer(v)) => {
                self.check_sensitivity_choice(var.name, v)?
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
            (Slot::SensitivityParameter(_), Value::Integer(v)) => {
                self.check_sensitivity_choice(var.name, v)?
            }
            (Slot::ChangePointBranch, Value::Integer(v)) => {
                if Branch::from_value(v).is_none() {
                    return Err(AccessError::NotAllowed(format!(
                        "change_point_branch = {v}: must be 1 (straight) or 2 (turn)"
                    )));
                }
            }
            _ => {
                let what = if var.causality() == crate::variables::Causality::Local {
                    "a Model Exchange state or derivative, set through SetContinuousStates"
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

    /// A slot's new value: one of the items. Two slots may follow the same parameter (each
    /// computes its own column, the same numbers): a set is judged on its own value,
    /// whatever the other slots hold or the order a master sets them in.
    fn check_sensitivity_choice(&self, name: &str, v: i32) -> Result<(), AccessError> {
        let refuse = |rule: String| AccessError::NotAllowed(format!("{name} = {v}: {rule}"));
        sensitivity::chosen(v).ok_or_else(|| {
            let index = usize::try_from(v - 1)
                .ok()
                .filter(|&i| i < model::PARAMETERS.len());
            refuse(match index {
                Some(index) => sensitivity::not_offered(index).to_string(),
                None => "must be 0 (none) or a parameter of the SensitivityParameter items".into(),
            })
        })?;
        Ok(())
    }

    /// The Model Exchange states' derivatives, `Local::Derivative(0..6)` in one call: the
    /// accelerations are computed once (each slot alone computes them all), the same
    /// numbers bit for bit.
    pub fn exchange_derivatives(&self) -> [f64; 6] {
        let (y, lead) = (&self.state, self.chart.leader());
        let a = model::accelerations(&self.params, &self.inputs, y).omega_dot;
        [y[4], y[lead + 4], y[7], a[0], a[lead], a[3]]
    }

    /// The event indicator of the leading angle's chart at the current configuration:
    /// positive while it determines the loop (docs/model.md §6).
    pub fn handover_indicator(&self) -> f64 {
        handover_indicator_at(&self.params, self.chart, &self.state)
    }

    /// The independent coordinates, their derivatives and the event indicator (docs/model.md
    /// §6).
    pub fn local(&self, local: Local) -> f64 {
        if local == Local::HandoverIndicator {
            return self.handover_indicator();
        }
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

    /// The derivatives of the Real `unknowns` along a direction of the knowns (GetDirectionalDerivative),
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
/// slots that are not computed from the state. Inlined: in the Real getter's path the match
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
/// as in [`Plant::output`]; `real_reads_agree_with_the_variable_table` checks the two agree.
const fn state_component(slot: Slot) -> Option<usize> {
    match slot {
        Slot::Output(Output::Angle(i)) => Some(i),
        Slot::Output(Output::Speed(i)) => Some(4 + i),
        _ => None,
    }
}

/// The value reference of φ1, which φ2…ω4 follow in state order (the table is built that
/// way, and this checks it when compiling): the Real getter serves a state with one
/// subtraction and one comparison, cheaper than a table lookup per value on the path of
/// every read.
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

impl Plant {
    /// Everything that determines the plant's future, for a serialized FMU state.
    pub fn serialize_into(&self, w: &mut Writer) {
        for i in 0..model::PARAMETERS.len() {
            w.f64(self.params.get(i).unwrap_or(f64::NAN));
        }
        w.f64s(&[self.inputs.motor_torque, self.inputs.load_torque]);
        w.f64s(&[self.inputs_set.motor_torque, self.inputs_set.load_torque]);
        w.f64s(&self.input_derivatives.motor_torque);
        w.f64s(&self.input_derivatives.load_torque);
        w.bool(self.params.builtin_laws);
        w.u8(self.solver_kind as u8);
        w.u8(self.branch as u8);
        w.u8(self.codes.solver as u8);
        w.u8(self.codes.branch as u8);
        w.f64(self.time);
        w.f64s(&self.state);
        w.f64(self.residual);
        w.u8(self.chart as u8);
        w.bool(self.changed);
        // The values of the slots in use alone: an unused slot's are zero.
        for k in 0..SENSITIVITY_SLOTS {
            w.u8(self.sensitivity_choice[k] as u8);
            w.u8(self.codes.sensitivity[k] as u8);
            if self.slot_choice(k) != 0 {
                for row in &self.sensitivities {
                    w.f64(row[k]);
                }
            }
        }
    }

    /// The plant written by [`Plant::serialize_into`]; every value is checked again by the
    /// rule that admitted it.
    pub fn deserialize_from(r: &mut Reader) -> Result<Self, FormatError> {
        let invalid = |e: String| FormatError(format!("invalid serialized state: {e}"));
        let mut params = Parameters::default();
        for i in 0..model::PARAMETERS.len() {
            params
                .set(i, r.f64()?)
                .map_err(|e| invalid(e.to_string()))?;
        }
        let [motor_torque, load_torque] = r.f64s()?;
        let [motor_torque_set, load_torque_set] = r.f64s()?;
        let input_derivatives = InputDerivatives {
            motor_torque: r.f64s()?,
            load_torque: r.f64s()?,
        };
        params.builtin_laws = r.bool()?;
        let kind = r.u8()?;
        let solver_kind =
            solver_kind(kind as i32).ok_or_else(|| invalid(format!("solver = {kind}")))?;
        let code = r.u8()?;
        let branch = Branch::from_value(code as i32)
            .ok_or_else(|| invalid(format!("change_point_branch = {code}")))?;
        let mut codes = Codes {
            solver: i32::from(r.u8()?),
            branch: i32::from(r.u8()?),
            sensitivity: [0; SENSITIVITY_SLOTS],
        };
        if codes.solver != 0 && self::solver_kind(codes.solver).is_none() {
            return Err(invalid(format!("solver_code = {}", codes.solver)));
        }
        if codes.branch != 0 && Branch::from_value(codes.branch).is_none() {
            let branch = codes.branch;
            return Err(invalid(format!("change_point_branch_code = {branch}")));
        }
        let time = r.f64()?;
        let state = r.f64s()?;
        let residual = r.f64()?;
        let code = r.u8()?;
        let chart =
            Chart::from_code(code as i32).ok_or_else(|| invalid(format!("loop chart {code}")))?;
        let changed = r.bool()?;
        let mut sensitivity_choice = [0; SENSITIVITY_SLOTS];
        let mut sensitivities = [[0.0; SENSITIVITY_SLOTS]; STATE_SIZE];
        for k in 0..SENSITIVITY_SLOTS {
            for value in [&mut sensitivity_choice[k], &mut codes.sensitivity[k]] {
                *value = i32::from(r.u8()?);
                if sensitivity::chosen(*value).is_none() {
                    return Err(invalid(format!("sensitivity slot {} = {value}", k + 1)));
                }
            }
            if codes.sensitivity[k] != 0 || sensitivity_choice[k] != 0 {
                for row in sensitivities.iter_mut() {
                    row[k] = r.f64()?;
                }
            }
        }
        let plant = Self {
            params,
            inputs: Inputs {
                motor_torque,
                load_torque,
            },
            inputs_set: Inputs {
                motor_torque: motor_torque_set,
                load_torque: load_torque_set,
            },
            input_derivatives,
            solver_kind,
            branch,
            time,
            state,
            residual,
            chart,
            changed,
            sensitivity_choice,
            sensitivities,
            codes,
        };
        plant.check_restored().map_err(invalid)?;
        Ok(plant)
    }

    /// The inputs and their derivatives of a restored plant, each within its rule (a
    /// checksum protects only against accidents).
    fn check_restored(&self) -> Result<(), String> {
        check_inputs(&self.inputs, "")?;
        check_inputs(&self.inputs_set, "")?;
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
        Ok(())
    }

    /// For a state restored after initialisation: the positions close the loop and the
    /// velocities satisfy B1·ω2 = C1·ω3, to well within what the projection leaves.
    pub fn check_consistent(&self) -> Result<(), String> {
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

    /// The stored residual, bit for bit (a restored driver's recomputation is compared).
    pub fn residual(&self) -> f64 {
        self.residual
    }
}

/// Inputs within the rule the setters apply; `whose` names them in the message.
pub fn check_inputs(inputs: &Inputs, whose: &str) -> Result<(), String> {
    for (name, u) in [("M_m", inputs.motor_torque), ("M_r", inputs.load_torque)] {
        model::params::INPUT_RULE
            .check(u)
            .map_err(|rule| format!("input {name}{whose} = {} {rule}", model::number(u)))?;
    }
    Ok(())
}

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
    // The FMI function names the accessor; the plant names the types.
    let asked = match value {
        Value::Real(_) => "Real",
        Value::Integer(_) => "Integer",
        Value::Boolean(_) => "Boolean",
    };
    let own = match var.var_type() {
        VarType::Real => "Real",
        VarType::Integer | VarType::Enumeration => "Integer",
        VarType::Boolean => "Boolean",
    };
    Err(AccessError::NotAllowed(format!(
        "{} is of type {}: read and write it as {own}, not {asked}",
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variables::{variables, COUNT};

    /// The Real getter's fast path for φ and ω (by value reference range) gives what the
    /// general path gives, and every other Real variable still reads through the general
    /// path.
    #[test]
    fn real_reads_agree_with_the_variable_table() {
        let mut plant = Plant::new();
        plant
            .set(
                crate::variables::value_reference("omega2_0").unwrap(),
                Value::Real(3.0),
                true,
            )
            .unwrap();
        plant.initialize(0.0).unwrap();
        let mut state_reads = 0;
        for (vr, var) in variables() {
            match plant.real_of(var.slot) {
                Some(expected) => {
                    assert_eq!(
                        plant.read_real(vr).unwrap().to_bits(),
                        expected.to_bits(),
                        "{}",
                        var.name
                    );
                    state_reads += usize::from(state_component(var.slot).is_some());
                }
                None => assert!(plant.read_real(vr).is_err(), "{}", var.name),
            }
        }
        assert_eq!(state_reads, STATE_SIZE);
        for i in 0..4 {
            let phi = crate::variables::value_reference(&format!("phi{}", i + 1)).unwrap();
            let omega = crate::variables::value_reference(&format!("omega{}", i + 1)).unwrap();
            assert_eq!(plant.read_real(phi).unwrap(), plant.state()[i]);
            assert_eq!(plant.read_real(omega).unwrap(), plant.state()[4 + i]);
        }
        assert!(plant.read_real(COUNT as u32).is_err());
    }
}
