//! The runner's requests and replies: one JSON request per line on standard input; one
//! JSON reply per line on the protocol channel. A `run` request answers one line per
//! point (followed by its series as raw little-endian f64 when the plan records one).
//! Replies are flushed at least every `FLUSH_EVERY`, which keeps a wake-up of the caller
//! per point off the hot path; with `flush_each` every point's reply is flushed as soon
//! as the point ends, so that if the FMU kills the process, the caller knows exactly which
//! point did it: the first one without a reply. The caller reruns the unanswered points
//! of a batch that crashed that way. A plan's refusals come back all at once, each naming
//! its field.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use std::time::{Duration, Instant};

use serde::Deserialize;
use serde_json::{json, Value};

use crate::cycle_plan::LinearPlan;
use crate::description::Description;
use crate::exchange::{method_named, Shape};
use crate::fmi::{Interface, Library};
use crate::plan::{Plan, PlanSpec};
use crate::point::{Assignments, Runner};
use crate::refusals::Refusals;
use crate::system::{is_system, SystemLibrary};
use crate::target::Target;
use integrators::Method;

/// The longest a finished point's reply waits in the buffer.
const FLUSH_EVERY: Duration = Duration::from_millis(20);

#[derive(Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
enum Request {
    /// The model description as JSON.
    Describe,
    /// The plan for the following requests.
    Configure { plan: Box<PlanSpec> },
    /// Run each row: `names` are the columns (parameters or inputs set at the start).
    Run {
        names: Vec<String>,
        rows: Vec<Vec<f64>>,
        #[serde(default)]
        flush_each: bool,
        /// The lengths of the runs of rows that continue each other's steady cycles, in
        /// order; by default the request's rows are one.
        chains: Option<Vec<usize>>,
    },
    /// Set each row's values in initialisation mode only: what does the FMU refuse?
    Check {
        names: Vec<String>,
        rows: Vec<Vec<f64>>,
    },
    /// Linearise each row's point at its initial state (Model Exchange).
    Linearise {
        names: Vec<String>,
        rows: Vec<Vec<f64>>,
    },
    /// Time the plainest master loop over the rows.
    Bare {
        names: Vec<String>,
        rows: Vec<Vec<f64>>,
    },
}

pub struct Session {
    dir: PathBuf,
    description: Description,
    /// The interface a single FMU runs through (`None` for a system), and the method that
    /// integrates it under Model Exchange.
    interface: Option<Interface>,
    method: Method,
    runner: Runner,
    plan: Option<Plan>,
}

impl Session {
    /// Serve the FMU unpacked in `dir`, or the coupled system it holds.
    pub fn open(dir: &Path) -> Result<Self, String> {
        let (description, target, interface) = if is_system(dir) {
            let (description, system) = SystemLibrary::load(dir)?;
            (description, Target::System(system), None)
        } else {
            let description = Description::read(dir)?;
            let interface = Interface::default_for(&description);
            let target = fmu_target(dir, &description, interface, Method::Dop853)?;
            (description, target, Some(interface))
        };
        Ok(Session {
            dir: dir.to_path_buf(),
            description,
            interface,
            method: Method::Dop853,
            runner: Runner::new(target),
            plan: None,
        })
    }

    /// The plan a request sends, resolved against the description, with the FMU loaded
    /// through the interface and the method it runs with (a runner kept between studies
    /// may have run others); or every refusal of it.
    fn configure(&mut self, spec: PlanSpec) -> Result<Plan, Refusals> {
        let mut refusals = Refusals::default();
        let method = refusals.note(
            "scenario.integrator",
            method_named(spec.integrator.as_deref()),
        );
        let default = self
            .interface
            .map(|_| Interface::default_for(&self.description));
        let plan = Plan::resolve(spec, &self.description, default);
        let (plan, method) = match (plan, method) {
            (Ok(plan), Some(method)) => (plan, method),
            (Err(mut more), _) => {
                refusals.0.append(&mut more.0);
                return Err(refusals);
            }
            (Ok(_), None) => return Err(refusals),
        };
        match (self.interface, plan.interface) {
            (Some(current), Some(wanted)) if current != wanted || method != self.method => {
                match fmu_target(&self.dir, &self.description, wanted, method) {
                    Ok(target) => {
                        self.runner = Runner::new(target);
                        self.interface = Some(wanted);
                        self.method = method;
                    }
                    Err(e) => {
                        refusals.refuse("scenario.interface", e);
                        return Err(refusals);
                    }
                }
            }
            _ => {}
        }
        if let Err(e) = self.modes_through_exchange(&plan) {
            refusals.refuse("cycle.modes", e);
            return Err(refusals);
        }
        Ok(plan)
    }

    /// A cycle through start values finds its modes on the FMU's Model Exchange
    /// interface: loaded beside the Co-Simulation one where the plan asks for modes.
    fn modes_through_exchange(&mut self, plan: &Plan) -> Result<(), String> {
        let wanted = plan
            .cycle
            .as_ref()
            .is_some_and(|c| matches!(c.way, crate::cycle_plan::Way::Starts(_)) && c.modes > 0)
            && self.description.has_model_exchange;
        if !wanted {
            self.runner.set_exchange(None);
            return Ok(());
        }
        if !self.runner.has_exchange() {
            let target = fmu_target(
                &self.dir,
                &self.description,
                Interface::ModelExchange,
                Method::Dop853,
            )?;
            self.runner.set_exchange(Some(target));
        }
        Ok(())
    }

    /// Serve requests until standard input closes.
    pub fn serve(&mut self, input: impl BufRead, out: &mut impl Write) -> std::io::Result<()> {
        for line in input.lines() {
            let line = line?;
            if line.trim().is_empty() {
                continue;
            }
            match serde_json::from_str::<Request>(&line) {
                Ok(request) => self.answer(request, out)?,
                Err(e) => reply(out, &json!({"error": format!("malformed request: {e}")}))?,
            }
            out.flush()?;
        }
        Ok(())
    }

    fn answer(&mut self, request: Request, out: &mut impl Write) -> std::io::Result<()> {
        match request {
            Request::Describe => reply(out, &json!({"description": self.description})),
            Request::Configure { plan } => match self.configure(*plan) {
                Ok(plan) => {
                    let answer = json!({"configured": true, "reads": plan.read_names,
                                        "series_width": plan.series_width()});
                    self.plan = Some(plan);
                    reply(out, &answer)
                }
                Err(refusals) => {
                    self.plan = None;
                    reply(
                        out,
                        &json!({"error": refusals.said(), "refusals": refusals.0}),
                    )
                }
            },
            Request::Run {
                names,
                rows,
                flush_each,
                chains,
            } => self.run(&names, &rows, (flush_each, chains), out),
            Request::Check { names, rows } => self.check(&names, &rows, out),
            Request::Linearise { names, rows } => self.linearise(&names, &rows, out),
            Request::Bare { names, rows } => {
                let answer = self
                    .prepared(&names, &rows)
                    .and_then(|(plan, runner, mut a)| runner.bare(plan, &mut a, &rows));
                match answer {
                    Ok(seconds) => reply(out, &json!({"seconds": seconds, "points": rows.len()})),
                    Err(e) => reply(out, &json!({"error": e})),
                }
            }
        }
    }

    /// The plan, the runner and the request's assignments, borrowed apart.
    fn prepared(
        &mut self,
        names: &[String],
        rows: &[Vec<f64>],
    ) -> Result<(&mut Plan, &mut Runner, Assignments), String> {
        let plan = self
            .plan
            .as_mut()
            .ok_or("no plan: send a configure request first")?;
        if let Some(row) = rows.iter().find(|r| r.len() != names.len()) {
            return Err(format!(
                "a row has {} values for {} names",
                row.len(),
                names.len()
            ));
        }
        let assignments = Assignments::new(&self.description, plan, names)?;
        Ok((plan, &mut self.runner, assignments))
    }

    fn run(
        &mut self,
        names: &[String],
        rows: &[Vec<f64>],
        (flush_each, chains): (bool, Option<Vec<usize>>),
        out: &mut impl Write,
    ) -> std::io::Result<()> {
        let chains = chains.unwrap_or_else(|| vec![rows.len()]);
        if chains.iter().sum::<usize>() != rows.len() {
            let e = format!(
                "chains of {} rows for {} rows",
                chains.iter().sum::<usize>(),
                rows.len()
            );
            return reply(out, &json!({"error": e}));
        }
        let (plan, runner, mut assignments) = match self.prepared(names, rows) {
            Ok(p) => p,
            Err(e) => return reply(out, &json!({"error": e})),
        };
        // A chain's points continue each other's steady cycles, and nothing before them:
        // the same chains give the same answers however a sweep deals them out.
        let starts: Vec<usize> = chains
            .iter()
            .scan(0, |at, length| {
                let start = *at;
                *at += length;
                Some(start)
            })
            .collect();
        let mut flushed = Instant::now();
        for (i, row) in rows.iter().enumerate() {
            if starts.contains(&i) {
                runner.forget_cycle();
            }
            let r = runner.run_point(plan, &mut assignments, row);
            let width = plan.series_width();
            reply(
                out,
                &json!({
                    "i": i,
                    "status": r.outcome.name(),
                    "message": r.message,
                    "metrics": r.metrics,
                    "t_end": r.t_end,
                    "steps": r.steps,
                    "events": r.events,
                    "wall_s": r.wall_s,
                    "series_rows": r.series.len().checked_div(width).unwrap_or(0),
                    "coupling": r.coupling,
                    "cycle": r.cycle,
                }),
            )?;
            if !r.series.is_empty() {
                let bytes: Vec<u8> = r.series.iter().flat_map(|x| x.to_le_bytes()).collect();
                out.write_all(&bytes)?;
            }
            if flush_each || flushed.elapsed() >= FLUSH_EVERY {
                out.flush()?;
                flushed = Instant::now();
            }
        }
        reply(out, &json!({"done": rows.len()}))
    }

    fn linearise(
        &mut self,
        names: &[String],
        rows: &[Vec<f64>],
        out: &mut impl Write,
    ) -> std::io::Result<()> {
        if self.interface != Some(Interface::ModelExchange) {
            return reply(
                out,
                &json!({"error": "a linearisation needs a plan with interface \"model_exchange\""}),
            );
        }
        let linear = match LinearPlan::of(&self.description) {
            Ok(linear) => linear,
            Err(e) => return reply(out, &json!({ "error": e })),
        };
        let (plan, runner, mut assignments) = match self.prepared(names, rows) {
            Ok(p) => p,
            Err(e) => return reply(out, &json!({ "error": e })),
        };
        let results: Vec<Value> = rows
            .iter()
            .map(
                |row| match runner.linearise_point(plan, &linear, &mut assignments, row) {
                    Ok(l) => json!({"status": "ok", "linearisation": l}),
                    Err(e) => json!({"status": "error", "message": e}),
                },
            )
            .collect();
        reply(out, &json!({ "linearised": results }))
    }

    fn check(
        &mut self,
        names: &[String],
        rows: &[Vec<f64>],
        out: &mut impl Write,
    ) -> std::io::Result<()> {
        let (plan, runner, mut assignments) = match self.prepared(names, rows) {
            Ok(p) => p,
            Err(e) => return reply(out, &json!({"error": e})),
        };
        let results: Vec<Value> = rows
            .iter()
            .map(|row| {
                let (outcome, message) = runner.check_point(plan, &mut assignments, row);
                json!({"status": outcome.name(), "message": message})
            })
            .collect();
        reply(out, &json!({"checked": results}))
    }
}

/// What runs the FMU unpacked in `dir` through `interface`: its co-simulation instances,
/// or its Model Exchange instances integrated by the runner.
fn fmu_target(
    dir: &Path,
    description: &Description,
    interface: Interface,
    method: Method,
) -> Result<Target, String> {
    let library = Library::load(dir, description, interface)?;
    Ok(match interface {
        Interface::CoSimulation => Target::Fmu(library),
        Interface::ModelExchange => {
            let shape = Shape {
                states: description.continuous_states,
                indicators: description.event_indicators,
                method,
                tunable: description.tunable(),
            };
            shape.check()?;
            Target::Exchange(library, shape)
        }
    })
}

fn reply(out: &mut impl Write, value: &Value) -> std::io::Result<()> {
    serde_json::to_writer(&mut *out, value)?;
    out.write_all(b"\n")
}
