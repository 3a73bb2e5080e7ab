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
//!
//! By job: the state and how the drivers move it (here), the inputs and their derivatives
//! (`inputs.rs`), reading and writing variables with every check on a written value
//! (`access.rs`), outputs and their time and directional derivatives (`outputs.rs`), and
//! the serialized form with its checks on restore (`serialize.rs`).

mod access;
mod inputs;
mod outputs;
mod serialize;

pub use access::{AccessError, Value};
pub use inputs::{check_inputs, InputDerivatives};

use crate::model::chart::{handover_indicator, preferred_chart};
use crate::model::sensitivity::{self, Sensitive};
use crate::model::{self, Chart, Inputs, ModelError, Parameters, Projected, State, STATE_SIZE};
use crate::variables::{Branch, SENSITIVITY_SLOTS, SOLVER_ITEMS};

/// The integration method chosen by the `solver` parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverKind {
    Auto = 1,
    Dop853 = 2,
    Implicit = 3,
}

/// What the integrator driving the plant reports through the statistics outputs
/// (`n_steps`, `n_rejected`, `n_rhs`, `active_solver`), in the plant's own terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Activity {
    pub steps: u64,
    pub rejected: u64,
    pub right_hand_sides: u64,
    /// The method integrating now: [`SolverKind::Dop853`] or [`SolverKind::Implicit`].
    pub active: SolverKind,
}

impl Activity {
    /// No integrator has run: no work counted, and the explicit method shown.
    pub fn idle() -> Self {
        Self {
            steps: 0,
            rejected: 0,
            right_hand_sides: 0,
            active: SolverKind::Dop853,
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
