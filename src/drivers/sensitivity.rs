//! Parameter sensitivities along a co-simulation run (docs/sensitivities.md): the run's state
//! with its sensitivities S = ∂y/∂p, integrated side by side with the driver's own
//! integration by DOP853 over the augmented system (y, S). The step-size control holds y
//! alone to the tolerance, so the steps are those of y's numerical solution and S is that
//! solution's derivative; each accepted step projects y onto the constraint and S onto its
//! tangent space, the projection's derivative.
//!
//! The driver's outputs do not depend on it: it integrates its own copy of the state,
//! taken from the plant whenever the driver starts over (new inputs, a master's change).
//! What it costs falls on runs that ask for sensitivities alone.

use crate::model::sensitivity::{self, Sensitive, Sensitivities, SLOTS};
use crate::model::{self, Inputs, Parameters, State, STATE_SIZE};
use crate::plant::{InputDerivatives, Plant};
use integrators::bytes::put;
use integrators::bytes::{FormatError, Reader, Writer};
use integrators::{Dop853, OdeSystem, SolverError, Stepper, Tolerances};

/// (y, S) as the integrator sees it: y first, then S row by row.
struct Augmented<'a, const P: usize> {
    params: &'a Parameters,
    inputs: &'a Inputs,
    derivatives: Option<&'a InputDerivatives>,
    anchor: f64,
    which: &'a [Sensitive; P],
    projection_accuracy: f64,
}

fn split<const P: usize, const N: usize>(point: &[f64; N]) -> (State, Sensitivities<P>) {
    let y = std::array::from_fn(|i| point[i]);
    let s = std::array::from_fn(|i| std::array::from_fn(|j| point[STATE_SIZE + i * P + j]));
    (y, s)
}

fn join<const P: usize, const N: usize>(y: &State, s: &Sensitivities<P>, point: &mut [f64; N]) {
    point[..STATE_SIZE].copy_from_slice(y);
    for (i, row) in s.iter().enumerate() {
        point[STATE_SIZE + i * P..STATE_SIZE + (i + 1) * P].copy_from_slice(row);
    }
}

impl<const P: usize, const N: usize> OdeSystem<N> for Augmented<'_, P> {
    fn rhs(&self, t: f64, point: &[f64; N], d: &mut [f64; N]) {
        let inputs = match self.derivatives {
            None => *self.inputs,
            Some(derivatives) => derivatives.at(self.inputs, self.anchor, t),
        };
        let (y, s) = split::<P, N>(point);
        let (mut dy, mut ds) = ([0.0; STATE_SIZE], [[0.0; P]; STATE_SIZE]);
        sensitivity::derivative(
            self.params,
            &inputs,
            self.which,
            (&y, &s),
            (&mut dy, &mut ds),
        );
        join(&dy, &ds, d);
    }

    fn project(&self, previous: &[f64; N], point: &mut [f64; N]) -> Result<(), String> {
        let (mut y, mut s) = split::<P, N>(point);
        let at = model::project(self.params, &mut y, self.projection_accuracy)
            .map_err(|e| e.to_string())?;
        let (before, _) = split::<P, N>(previous);
        model::check_passage(self.params, &before, &y, &at).map_err(|e| e.to_string())?;
        sensitivity::project(self.params, &y, &mut s);
        join(&y, &s, point);
        Ok(())
    }

    fn controlled(&self) -> usize {
        STATE_SIZE
    }
}

/// One width of the augmented run: `P` parameters, `N` = 8·(1 + P) components.
#[derive(Clone, Debug)]
struct Run<const P: usize, const N: usize> {
    which: [Sensitive; P],
    time: f64,
    point: [f64; N],
    solver: Dop853<N>,
    /// The next step starts from the plant's point (at the start, and after a failure).
    restart: bool,
}

impl<const P: usize, const N: usize> Run<P, N> {
    fn new(which: [Sensitive; P], s: &Sensitivities<P>, tolerances: Tolerances) -> Self {
        let mut point = [0.0; N];
        join(&[0.0; STATE_SIZE], s, &mut point);
        Self {
            which,
            time: 0.0,
            point,
            solver: Dop853::new(tolerances),
            restart: true,
        }
    }

    /// S at `t_end`, the run taken there (or past it, never past `limit`); with `fresh`,
    /// from the plant's point: its state, and the sensitivities it holds there for
    /// `slots` (the run's own S belongs to the run's time, which may lie past that point).
    fn advance(
        &mut self,
        plant: &Plant,
        step: &Step,
        slots: &[(usize, Sensitive)],
    ) -> Result<Sensitivities<P>, SolverError> {
        if step.fresh || self.restart || self.time < plant.time() {
            self.restart = false;
            self.time = plant.time();
            join(plant.state(), &of_plant::<P>(slots, plant), &mut self.point);
            self.solver.invalidate();
        }
        let derivatives = plant.input_derivatives();
        let system = Augmented {
            params: plant.params(),
            inputs: &step.inputs,
            derivatives: (!derivatives.is_zero()).then_some(derivatives),
            anchor: plant.time(),
            which: &self.which,
            projection_accuracy: step.projection_accuracy,
        };
        let limit = step.limit.max(step.t_end);
        self.solver.progress_mut().work_limit =
            self.solver.statistics().n_rhs.saturating_add(step.work);
        if self.time < step.t_end {
            let result =
                self.solver
                    .integrate(&system, &mut self.time, &mut self.point, step.t_end, limit);
            if let Err(error) = result {
                self.restart = true;
                return Err(error);
            }
        }
        let refused = |reason: String| SolverError::ProjectionFailed {
            t: step.t_end,
            reason: format!("sensitivities: {reason}"),
        };
        let point = if self.time == step.t_end {
            self.point
        } else {
            self.solver
                .dense_output(&system, step.t_end)
                .ok_or_else(|| refused("no dense output covers this time".into()))?
        };
        // The state there is the driver's, projected and checked: S alone is projected,
        // onto the constraint's tangent space at that state.
        let (_, mut s) = split::<P, N>(&point);
        sensitivity::project(system.params, &step.y_end, &mut s);
        if s.iter().flatten().all(|v| v.is_finite()) {
            Ok(s)
        } else {
            Err(refused("not finite".into()))
        }
    }

    fn serialize_into(&self, w: &mut Writer) {
        put!(w.f64(self.time));
        put!(w.f64s(&self.point));
        put!(w.bool(self.restart));
        self.solver.serialize_into(w);
    }

    fn deserialize_from(r: &mut Reader, which: [Sensitive; P]) -> Result<Self, FormatError> {
        let time = r.f64()?;
        let point = r.f64s()?;
        let restart = r.bool()?;
        let solver = Dop853::deserialize_from(r)?;
        Ok(Self {
            which,
            time,
            point,
            solver,
            restart,
        })
    }
}

/// What one communication step gives the run.
struct Step {
    t_end: f64,
    /// The driver's state at `t_end`, projected.
    y_end: State,
    limit: f64,
    fresh: bool,
    inputs: Inputs,
    projection_accuracy: f64,
    work: u64,
}

macro_rules! widths {
    ($($variant:ident: $p:literal, $n:literal;)*) => {
        /// The augmented run for as many parameters as the master chose.
        #[derive(Clone, Debug)]
        enum Width {
            $($variant(Box<Run<$p, $n>>),)*
        }

        impl Width {
            /// From the plant's sensitivities for `slots` (1 to [`SLOTS`] of them).
            fn new(slots: &[(usize, Sensitive)], plant: &Plant, tolerances: Tolerances) -> Self {
                match slots.len() {
                    $($p => Self::$variant(Box::new(Run::new(
                        std::array::from_fn(|j| slots[j].1),
                        &of_plant(slots, plant),
                        tolerances,
                    ))),)*
                    n => unreachable!("{n} sensitivities: the slots hold 1 to {SLOTS}"),
                }
            }

            /// S at the step's end, by slot.
            fn advance(
                &mut self,
                plant: &Plant,
                step: &Step,
                slots: &[(usize, Sensitive)],
            ) -> Result<[[f64; SLOTS]; STATE_SIZE], SolverError> {
                match self {
                    $(Self::$variant(run) => Ok(by_slot(slots, &run.advance(plant, step, slots)?)),)*
                }
            }

            fn serialize_into(&self, w: &mut Writer) {
                match self {
                    $(Self::$variant(run) => run.serialize_into(w),)*
                }
            }

            fn deserialize_from(r: &mut Reader, slots: &[(usize, Sensitive)]) -> Result<Self, FormatError> {
                Ok(match slots.len() {
                    $($p => Self::$variant(Box::new(Run::deserialize_from(r, std::array::from_fn(|j| slots[j].1))?)),)*
                    n => return Err(FormatError(format!("{n} sensitivities: the slots hold 1 to {SLOTS}"))),
                })
            }
        }
    };
}

widths! {
    One: 1, 16;
    Two: 2, 24;
    Three: 3, 32;
    Four: 4, 40;
    Five: 5, 48;
}

/// The plant's sensitivities at its point for `slots` (P of them), column j for `slots[j]`.
fn of_plant<const P: usize>(slots: &[(usize, Sensitive)], plant: &Plant) -> Sensitivities<P> {
    plant
        .sensitivities()
        .map(|row| std::array::from_fn(|j| row[slots[j].0]))
}

/// `s` as the plant holds it, by slot: column j in slot `slots[j]`.
fn by_slot<const P: usize>(
    slots: &[(usize, Sensitive)],
    s: &Sensitivities<P>,
) -> [[f64; SLOTS]; STATE_SIZE] {
    let mut out = [[0.0; SLOTS]; STATE_SIZE];
    for (row, values) in out.iter_mut().zip(s) {
        for (&(slot, _), &value) in slots.iter().zip(values) {
            row[slot] = value;
        }
    }
    out
}

/// The sensitivities a co-simulation run carries, for the parameters the plant's
/// `sensitivity_*.parameter` slots name.
#[derive(Clone, Debug)]
pub struct Tracker {
    /// The slots in use, in order, and their parameters.
    slots: Vec<(usize, Sensitive)>,
    width: Width,
}

impl Tracker {
    /// The run for `plant`'s chosen parameters, from S at its initial state; `None` when
    /// it chose none.
    pub fn start(plant: &Plant, tolerances: Tolerances) -> Option<Self> {
        let slots = plant.sensitivity_slots();
        if slots.is_empty() {
            return None;
        }
        Some(Self {
            width: Width::new(&slots, plant, tolerances),
            slots,
        })
    }

    /// S at the plant's new point `t_end`, by slot: the driver has just moved its state
    /// there, from the plant's time, to `y_end` (projected), and the plant takes both next.
    pub fn advance(
        &mut self,
        plant: &Plant,
        (t_end, y_end): (f64, &State),
        (limit, fresh, inputs): (f64, bool, Inputs),
        (projection_accuracy, work): (f64, u64),
    ) -> Result<[[f64; SLOTS]; STATE_SIZE], SolverError> {
        let step = Step {
            t_end,
            y_end: *y_end,
            limit,
            fresh,
            inputs,
            projection_accuracy,
            work,
        };
        self.width.advance(plant, &step, &self.slots)
    }

    /// The run's sensitivities and their integration's memory.
    pub fn serialize_into(&self, w: &mut Writer) {
        self.width.serialize_into(w);
    }

    /// The run written by [`Tracker::serialize_into`] for `plant`'s choice.
    pub fn deserialize_from(r: &mut Reader, plant: &Plant) -> Result<Option<Self>, FormatError> {
        let slots = plant.sensitivity_slots();
        if slots.is_empty() {
            return Ok(None);
        }
        Ok(Some(Self {
            width: Width::deserialize_from(r, &slots)?,
            slots,
        }))
    }
}
