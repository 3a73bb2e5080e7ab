//! A point's steady cycle, and its linearisation: the runner hands the cycle's search the
//! instance it initialised, Model Exchange's, or, through the start values, a way to start
//! the Co-Simulation instance again (and a Model Exchange instance for the modes).

use std::time::{Duration, Instant};

use super::{fresh_instance, set_up, Assignments, Outcome, PointResult, Runner, Stop};
use crate::cycle::{self, Budget, CycleRecord, Linearisation, Miss, NoCycle, Restart, Shot, Start};
use crate::cycle_plan::{LinearPlan, Way};
use crate::exchange::TOLERANCE_SAFETY;
use crate::fmi::Instance;
use crate::messages;
use crate::plan::Plan;
use crate::target::Running;
use crate::unit::Unit;

/// The point's start, again and again: what the shooting through start values restarts
/// the Co-Simulation instance with.
struct PointStart<'r> {
    runner: &'r mut Runner,
    plan: &'r Plan,
    assignments: &'r mut Assignments,
    tolerance: f64,
}

/// A point's stop, as a search without a cycle: an FMU's error stays one.
fn as_miss(Stop(outcome, why): Stop) -> NoCycle {
    NoCycle {
        why,
        miss: if outcome == Outcome::Error {
            Miss::FmuError
        } else {
            Miss::NoCycle
        },
    }
}

impl Restart for PointStart<'_> {
    fn restart(&mut self) -> Result<&mut Instance, NoCycle> {
        let runner = &mut *self.runner;
        let instance = fresh_instance(&runner.target, &mut runner.instance).map_err(as_miss)?;
        set_up(instance, self.plan, self.assignments, Some(self.tolerance)).map_err(as_miss)?;
        match instance {
            Running::Fmu(fmu) => Ok(fmu),
            _ => Err(NoCycle::because(
                "a cycle through the start values runs the Co-Simulation interface".into(),
            )),
        }
    }
}

impl Runner {
    /// The point's steady cycle, by shooting from its initial state (or from the last
    /// point's cycle): its metrics are the cycle's.
    pub(super) fn steady_cycle(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        row: &[f64],
        result: &mut PointResult,
        started: Instant,
    ) -> Result<(), Stop> {
        let cycle_plan = plan.cycle.as_ref().expect("a cycle plan");
        let tolerance = plan.tolerance.unwrap_or(crate::exchange::DEFAULT_TOLERANCE);
        let guess = cycle_plan
            .continuation
            .then(|| self.continuation.guess(row, cycle_plan))
            .flatten();
        let budget = Budget(
            plan.timeout_s
                .map(|s| (started + Duration::from_secs_f64(s), s)),
        );
        let found = if matches!(cycle_plan.way, Way::Starts(_)) {
            self.through_starts(plan, assignments, row, tolerance, (guess, budget))
        } else {
            self.prepare(plan, assignments, row, true)?;
            let Some(Running::Exchange(run)) = self.instance.as_mut() else {
                return Err(Stop(
                    Outcome::Error,
                    "a steady cycle is found through the Model Exchange interface".into(),
                ));
            };
            let (fmu, t, x, nominals, indicators) = run.parts();
            let start = Start {
                fmu,
                t,
                x,
                nominals,
                indicators,
            };
            let transient = plan.stop - plan.start;
            cycle::analyse(
                start,
                cycle_plan,
                tolerance,
                (transient, budget),
                guess.as_ref(),
            )
        };
        match found {
            Ok((mut record, shot)) => {
                result.metrics = record.metrics.iter().map(|&m| Some(m)).collect();
                // The kept variables travel as the series do: rows of (t, values…).
                let kept = std::mem::take(&mut record.kept);
                if let Some(times) = kept.first() {
                    for (j, t) in times.iter().enumerate() {
                        result.series.push(*t);
                        result
                            .series
                            .extend(kept[1..].iter().map(|column| column[j]));
                    }
                }
                result.t_end = plan.start + shot.search.period;
                result.cycle = Some(record);
                self.continuation.record(row, shot);
                Ok(())
            }
            Err(NoCycle { why, miss }) => {
                self.continuation.forget();
                let outcome = match miss {
                    Miss::Timeout => Outcome::Timeout,
                    Miss::NoCycle => Outcome::NoCycle,
                    Miss::FmuError => Outcome::Error,
                };
                Err(Stop(outcome, why))
            }
        }
    }

    /// The cycle through the FMU's Co-Simulation interface, its start values and its
    /// sensitivities; its modes on a Model Exchange instance at the states read along it.
    fn through_starts(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        row: &[f64],
        tolerance: f64,
        (guess, budget): (Option<Shot>, Budget),
    ) -> Result<(CycleRecord, Shot), NoCycle> {
        let cycle_plan = plan.cycle.as_ref().expect("a cycle plan");
        assignments.fill(row).map_err(NoCycle::because)?;
        let mut start = PointStart {
            runner: self,
            plan,
            assignments,
            tolerance: tolerance * TOLERANCE_SAFETY,
        };
        let run = (plan.start, plan.step, plan.stop - plan.start);
        let (mut record, shot, states) = cycle::analyse_through_starts(
            &mut start,
            cycle_plan,
            (run, tolerance),
            guess.as_ref(),
            budget,
        )?;
        if !states.is_empty() {
            (record.modes, record.linearisations) = self
                .modes_on_exchange(plan, assignments, &shot, &states)
                .map_err(|e| e.during("the modes along the cycle"))?;
        }
        Ok((record, shot))
    }

    /// The modes at Model Exchange states read along a cycle, on a Model Exchange instance
    /// initialised with the point's values and the cycle's start values.
    fn modes_on_exchange(
        &mut self,
        plan: &Plan,
        assignments: &mut Assignments,
        shot: &Shot,
        states: &[(f64, Vec<f64>)],
    ) -> Result<cycle::Along, NoCycle> {
        let cycle_plan = plan.cycle.as_ref().expect("a cycle plan");
        let Way::Starts(starts) = &cycle_plan.way else {
            return Err(NoCycle::because(
                "the cycle was not found through start values".into(),
            ));
        };
        let target = self.exchange.as_ref().ok_or_else(|| {
            NoCycle::because("the FMU's Model Exchange interface was not loaded".into())
        })?;
        let instance = fresh_instance(target, &mut self.exchange_instance).map_err(as_miss)?;
        set_up(instance, plan, assignments, plan.tolerance).map_err(as_miss)?;
        let s = instance
            .set_real(&starts.parameters.vrs, &shot.x0)
            .then(|| instance.exit_initialization_mode());
        if !s.proceeds() {
            self.exchange_instance = None;
            return Err(NoCycle::returned(
                "initialising the Model Exchange instance",
                s,
            ));
        }
        let Some(Running::Exchange(run)) = self.exchange_instance.as_mut() else {
            return Err(NoCycle::because(
                "the modes are found on the Model Exchange interface".into(),
            ));
        };
        let (fmu, t, _, _, _) = run.parts();
        cycle::modes_at(fmu, cycle_plan, t, states)
    }

    /// The point's state equations and outputs linearised at its initial state, on the
    /// Model Exchange interface.
    pub fn linearise_point(
        &mut self,
        plan: &Plan,
        linear: &LinearPlan,
        assignments: &mut Assignments,
        row: &[f64],
    ) -> Result<Linearisation, String> {
        messages::take();
        let prepared = self.prepare(plan, assignments, row, true);
        let said = messages::take();
        if let Err(Stop(_, what)) = prepared {
            self.instance = None;
            return Err(if said.is_empty() {
                what
            } else {
                format!("{what}: {said}")
            });
        }
        let Some(Running::Exchange(run)) = self.instance.as_mut() else {
            return Err("a linearisation reads the Model Exchange interface".into());
        };
        let (fmu, t, x, _, _) = run.parts();
        cycle::linearise(fmu, t, x, linear).map_err(|e| e.why)
    }
}
