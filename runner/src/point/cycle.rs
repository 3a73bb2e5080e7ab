//! A point's steady cycle, and its linearisation: the runner hands the cycle's search the
//! instance it initialised, Model Exchange's, or, through the start values, a way to start
//! the Co-Simulation instance again (and a Model Exchange instance for the modes).

use std::time::{Duration, Instant};

use super::{fresh_instance, set_up, Assignments, Outcome, PointResult, Runner, Stop};
use crate::cycle::{self, CycleRecord, Linearisation, Restart, Shot, Start};
use crate::cycle_plan::LinearPlan;
use crate::fmi::Instance;
use crate::messages;
use crate::plan::Plan;
use crate::target::Running;
use crate::unit::Unit;

/// The local error the FMU holds in a cycle's runs through its start values, as a
/// fraction of the plan's tolerance (as the runner's own integration of the cycle does).
const FMU_TOLERANCE: f64 = 1.0 / 30.0;

/// The point's start, again and again: what the shooting through start values restarts
/// the Co-Simulation instance with.
struct PointStart<'r> {
    runner: &'r mut Runner,
    plan: &'r Plan,
    assignments: &'r mut Assignments,
    tolerance: f64,
}

impl Restart for PointStart<'_> {
    fn restart(&mut self) -> Result<&mut Instance, String> {
        let runner = &mut *self.runner;
        let instance = fresh_instance(&runner.target, &mut runner.instance).map_err(|s| s.1)?;
        set_up(instance, self.plan, self.assignments, Some(self.tolerance)).map_err(|s| s.1)?;
        match instance {
            Running::Fmu(fmu) => Ok(fmu),
            _ => Err("a cycle through the start values runs the Co-Simulation interface".into()),
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
        let deadline = plan
            .timeout_s
            .map(|s| (started + Duration::from_secs_f64(s), s));
        let found = if cycle_plan.through.is_some() {
            self.through_starts(plan, assignments, row, tolerance, (guess, deadline))
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
            let budget = plan.stop - plan.start;
            cycle::analyse(
                start,
                cycle_plan,
                tolerance,
                budget,
                guess.as_ref(),
                deadline,
            )
            .map_err(|failure| (failure.timeout, failure.why))
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
                result.t_end = plan.start + shot.period;
                result.cycle = Some(record);
                self.continuation.record(row, shot);
                Ok(())
            }
            Err((timeout, why)) => {
                self.continuation.forget();
                let outcome = if timeout {
                    Outcome::Timeout
                } else {
                    Outcome::NoCycle
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
        (guess, deadline): (Option<Shot>, Option<(Instant, f64)>),
    ) -> Result<(CycleRecord, Shot), (bool, String)> {
        let cycle_plan = plan.cycle.as_ref().expect("a cycle plan");
        assignments.fill(row).map_err(|m| (false, m))?;
        let mut start = PointStart {
            runner: self,
            plan,
            assignments,
            tolerance: tolerance * FMU_TOLERANCE,
        };
        let run = (plan.start, plan.step, plan.stop - plan.start);
        let (mut record, shot, states) = cycle::analyse_through_starts(
            &mut start,
            cycle_plan,
            run,
            tolerance,
            guess.as_ref(),
            deadline,
        )
        .map_err(|failure| (failure.timeout, failure.why))?;
        if !states.is_empty() {
            (record.modes, record.linearisations) = self
                .modes_on_exchange(plan, assignments, &shot, &states)
                .map_err(|why| (false, format!("the modes along the cycle: {why}")))?;
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
    ) -> Result<cycle::Along, String> {
        let cycle_plan = plan.cycle.as_ref().expect("a cycle plan");
        let starts = cycle_plan.through.as_ref().expect("through start values");
        let target = self
            .exchange
            .as_ref()
            .ok_or("the FMU's Model Exchange interface was not loaded")?;
        let instance = fresh_instance(target, &mut self.exchange_instance).map_err(|s| s.1)?;
        set_up(instance, plan, assignments, plan.tolerance).map_err(|s| s.1)?;
        let mut s = instance.set_real(&starts.parameters, &shot.x0);
        if s.proceeds() {
            s = instance.exit_initialization_mode();
        }
        if !s.proceeds() {
            self.exchange_instance = None;
            return Err(format!(
                "initialising the Model Exchange instance returned {s:?}"
            ));
        }
        let Some(Running::Exchange(run)) = self.exchange_instance.as_mut() else {
            return Err("the modes are found on the Model Exchange interface".into());
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
        cycle::linearise(fmu, t, x, linear)
    }
}
