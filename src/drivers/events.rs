//! A co-simulation step in which a change point is an event (FMI 3.0; docs/model.md §7):
//! where a change-point linkage fails a step, the step is bisected to the last time it
//! passes; with early return it ends there, and the next step crosses the change point onto
//! the branch `change_point_branch` names; with event mode alone it crosses at once and
//! goes on; without event mode the step is refused. A step that would need more work than
//! one call may do ends early where it got to, where early return is allowed, and is
//! refused otherwise. A refused step leaves plant and driver as they were.
//!
//! The policy is the driver's; the instance maps the outcome to its interface's states and
//! statuses and logs what [`Happening`]s the step reports.

use super::cosimulation::{CoSimulation, CALL_WORK, CROSSING_WORK};
use super::{isa, Experiment};
use crate::model::change_point::{locate_node, Crossing};
use crate::model::{classify, LinkageClass};
use crate::plant::Plant;
use integrators::text::number;
use integrators::SolverError;

/// What the master handles: FMI 3.0's `eventModeUsed` and `earlyReturnAllowed`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EventHandling {
    pub event_mode: bool,
    pub early_return: bool,
}

/// How a step ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepEnd {
    /// At the step's end time, with nothing to handle.
    Complete,
    /// At the step's end time, a change point crossed on the way (early return not
    /// allowed): the master may handle the event.
    CompleteAfterEvent,
    /// Early, just before a change point, for the master to handle in event mode.
    ChangePointEvent,
    /// Early, where the work one call may do ran out: no event, the master steps on.
    OutOfWork,
}

/// What happened within a step, for the instance's log.
#[derive(Clone, Copy, Debug)]
pub enum Happening {
    /// The linkage stands just before a change point at `at`, (φ2, φ3) there.
    Located { at: f64, phi2: f64, phi3: f64 },
    /// The change point crossed from `at`, all of it (`complete`) or as far as the step's
    /// end.
    Crossed {
        at: f64,
        crossing: Crossing,
        complete: bool,
    },
}

/// Why a step stopped short of its end.
enum ShortOfEnd {
    /// The call's work is spent, at this time.
    OutOfWork(f64),
    /// The step cannot go on: refused, for this reason.
    Refused(String),
}

/// Where a failed step of a change-point linkage stopped.
enum Located {
    /// Not at a change point: the failure is the step's.
    NotAChangePoint,
    /// Just before a change point, at this time.
    At(f64),
    /// The call's work ran out at this time before the change point was located.
    OutOfWork(f64),
    /// The failure lay past the step's end (the integrator had stepped ahead of it), and
    /// the step, landing on its end, passed: the plant stands there.
    Reached,
}

/// One step of the plant to `target` under `handling`, within the work the driver was
/// allowed ([`super::master_step`] allows one call's): how it ended, or why it was refused
/// (plant and driver then as before the call); what happened on the way is pushed onto
/// `happenings`.
#[inline(always)]
pub fn step(
    plant: &mut Plant,
    driver: &mut CoSimulation,
    experiment: &Experiment,
    target: f64,
    handling: EventHandling,
    happenings: &mut Vec<Happening>,
) -> Result<StepEnd, String> {
    // The common case, a step that neither starts at nor meets a change point.
    let error = if driver.crossing_pending() || driver.crossing_in_flight() {
        None
    } else {
        match isa::advance(driver, plant, target, experiment) {
            Ok(()) => return Ok(StepEnd::Complete),
            Err(error) => Some(error),
        }
    };
    // The plant stands where the step began (a failed advance leaves it there): what a
    // refusal puts back.
    let before = (plant.clone(), driver.clone());
    StepWithEvents {
        plant,
        driver,
        experiment,
        handling,
        happenings,
    }
    .finish(before, target, error)
}

/// The rest of a step, where it meets or starts at a change point, or fails.
struct StepWithEvents<'a> {
    plant: &'a mut Plant,
    driver: &'a mut CoSimulation,
    experiment: &'a Experiment,
    handling: EventHandling,
    happenings: &'a mut Vec<Happening>,
}

impl StepWithEvents<'_> {
    /// From a failure (`error`), or from a change point the plant stands at: each change
    /// point located and crossed as the handling says, then on, until the step's end, an
    /// early return, or a refusal, which puts `before` back.
    #[cold]
    fn finish(
        &mut self,
        before: (Plant, CoSimulation),
        target: f64,
        mut error: Option<SolverError>,
    ) -> Result<StepEnd, String> {
        let now = before.0.time();
        let mut met = StepEnd::Complete;
        loop {
            if let Some(failed) = error.take() {
                match self.after_failure(target, failed) {
                    // A step that reached its end keeps an event met on the way.
                    Ok(Some(StepEnd::Complete)) => return Ok(met),
                    Ok(Some(end)) => return Ok(end),
                    Ok(None) => met = StepEnd::CompleteAfterEvent,
                    Err(refusal) => return self.refused(before, now, target, refusal),
                }
            }
            if self.driver.crossing_in_flight() {
                if !self.driver.go_on_crossing(self.plant, target) {
                    // The step ends on the crossing's way.
                    return Ok(met);
                }
            } else if self.driver.crossing_pending() {
                match self.cross(target) {
                    Ok(true) => {}
                    Ok(false) => return Ok(met),
                    Err(refusal) => return self.refused(before, now, target, refusal),
                }
            }
            match isa::advance(self.driver, self.plant, target, self.experiment) {
                Ok(()) => return Ok(met),
                Err(failed) => error = Some(failed),
            }
        }
    }

    /// A step that stopped short: out of work, early where it got to if early return is
    /// allowed and it got past its start; otherwise refused, `before` put back.
    #[cold]
    fn refused(
        &mut self,
        before: (Plant, CoSimulation),
        now: f64,
        target: f64,
        refusal: ShortOfEnd,
    ) -> Result<StepEnd, String> {
        let message = match refusal {
            ShortOfEnd::OutOfWork(at) => {
                if self.handling.early_return
                    && (self
                        .driver
                        .accept_reached(self.plant, target, self.experiment)
                        || self.plant.time() > now)
                {
                    return Ok(StepEnd::OutOfWork);
                }
                format!(
                    "the step from t = {} to {} needs more work than one call may do \
                     ({CALL_WORK} right-hand sides); it got to t = {}: take shorter steps{}",
                    number(now),
                    number(target),
                    number(at),
                    if self.handling.early_return {
                        ""
                    } else {
                        ", or allow early return"
                    }
                )
            }
            ShortOfEnd::Refused(message) => message,
        };
        (*self.plant, *self.driver) = before;
        Err(message)
    }

    /// A step that failed from the plant's time towards `target`: `None` where it
    /// stopped before a change point and is to cross it at once (event mode without early
    /// return); otherwise how it ends.
    #[cold]
    fn after_failure(
        &mut self,
        target: f64,
        error: SolverError,
    ) -> Result<Option<StepEnd>, ShortOfEnd> {
        if let SolverError::WorkLimit { t } = error {
            return Err(ShortOfEnd::OutOfWork(t));
        }
        let start = self.plant.time();
        let located = match self.locate_change_point(target, &error) {
            Located::NotAChangePoint => {
                return Err(ShortOfEnd::Refused(format!(
                    "step from t = {} to {} failed: {error}",
                    number(start),
                    number(target)
                )))
            }
            Located::OutOfWork(t) => return Err(ShortOfEnd::OutOfWork(t)),
            Located::Reached => return Ok(Some(StepEnd::Complete)),
            Located::At(located) => located,
        };
        if !self.handling.event_mode {
            let (start, target, located) = (number(start), number(target), number(located));
            return Err(ShortOfEnd::Refused(format!(
                "the step from t = {start} to {target} meets a change point at t = {located} \
                 ({error}); without event mode the FMU does not choose a branch: instantiate \
                 with eventModeUsed = true to go on (docs/model.md §7), or step to t = \
                 {located} at most"
            )));
        }
        self.driver.expect_crossing();
        let y = self.plant.state();
        self.happenings.push(Happening::Located {
            at: located,
            phi2: y[1],
            phi3: y[2],
        });
        Ok(self
            .handling
            .early_return
            .then_some(StepEnd::ChangePointEvent))
    }

    /// Cross the change point the plant stands before, within a step to `target`: whole,
    /// or as far as `target` where the crossing lasts longer than the step (the next steps
    /// go on with it). Returns whether it is complete.
    #[cold]
    fn cross(&mut self, target: f64) -> Result<bool, ShortOfEnd> {
        let start = self.plant.time();
        let left = self.driver.work_left();
        if left < CROSSING_WORK {
            return Err(ShortOfEnd::OutOfWork(start));
        }
        self.driver.allow_work(left - CROSSING_WORK);
        let crossing = self
            .driver
            .plan_crossing(self.plant)
            .map_err(|e| ShortOfEnd::Refused(format!("at t = {}: {e}", number(start))))?;
        let complete = self
            .driver
            .cross(self.plant, &crossing, target)
            .map_err(|reason| ShortOfEnd::Refused(format!("at t = {}: {reason}", number(start))))?;
        self.happenings.push(Happening::Crossed {
            at: start,
            crossing,
            complete,
        });
        Ok(complete)
    }

    /// After a step that failed from the plant's time towards `target` with `error`: for
    /// a change-point linkage, the last time before the change point to the tolerance,
    /// found by bisection (the plant and driver left there), where the state stands next
    /// to a change point. The bisection starts from the bracket the failure gives (the end
    /// of the step that failed), each try lands on its time (an integrator step reaching
    /// past it could pass the change point and fail a try that stops before it), and its
    /// work counts against the call's.
    #[cold]
    fn locate_change_point(&mut self, target: f64, error: &SolverError) -> Located {
        if classify(self.plant.params()) != LinkageClass::ChangePoint {
            return Located::NotAChangePoint;
        }
        let (plant, driver, experiment) = (&mut *self.plant, &mut *self.driver, self.experiment);
        let start = plant.time();
        let resolution = experiment.tolerance * start.abs().max(1.0);
        let failed_by = match *error {
            SolverError::ProjectionFailed { t, .. } | SolverError::StepSizeTooSmall { t, .. } => {
                t.clamp(start, target)
            }
            SolverError::WorkLimit { .. } => target,
        };
        // The first try is the failure's bracket; past it, the whole step.
        let mut tries = [failed_by, target].into_iter();
        let (mut lo, mut hi) = (start, tries.next().unwrap_or(target));
        let (allowed, done_before) = (driver.work_left(), driver.statistics().n_rhs);
        let mut spent = 0;
        let mut reached: Option<(Plant, CoSimulation)> = None;
        let mut probe = Some(hi);
        while hi - lo > resolution || probe.is_some() {
            let mid = probe.take().unwrap_or(0.5 * (lo + hi));
            let (mut p, mut d) = reached
                .clone()
                .unwrap_or_else(|| (plant.clone(), driver.clone()));
            d.allow_work(allowed.saturating_sub(spent));
            let done = d.statistics().n_rhs;
            let landing = Experiment {
                stop: Some(mid),
                ..*experiment
            };
            let result = isa::advance(&mut d, &mut p, mid, &landing);
            spent += d.statistics().n_rhs - done;
            match result {
                Ok(()) => {
                    lo = mid;
                    reached = Some((p, d));
                    if lo >= hi {
                        // The bracket held no failure: the whole step's is next.
                        match tries.next() {
                            Some(next) if next > lo => {
                                hi = next;
                                probe = Some(hi);
                            }
                            _ => break,
                        }
                    }
                }
                Err(SolverError::WorkLimit { .. }) => return Located::OutOfWork(lo),
                Err(_) => hi = mid,
            }
        }
        let (p, mut d) = reached.unwrap_or_else(|| (plant.clone(), driver.clone()));
        let y = p.state();
        let at_end = lo >= target;
        if !at_end && locate_node(p.params(), y[1], y[2]).is_err() {
            return Located::NotAChangePoint;
        }
        // The statistics count every right-hand side the bisection evaluated, also on the
        // tries it dropped; the call's allowance goes on from what is left.
        d.count_work(done_before + spent - d.statistics().n_rhs);
        d.allow_work(allowed.saturating_sub(spent));
        *plant = p;
        *driver = d;
        if at_end {
            Located::Reached
        } else {
            Located::At(lo)
        }
    }
}
