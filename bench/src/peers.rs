//! Rust ODE crates on the same equations (docs/model.md §2's right-hand side, the model crate's
//! `state_derivative`), stepped between the same communication points as a doStep would.
//! No projection: these are what a Rust user would put inside a doStep.

use std::cell::Cell;
use std::rc::Rc;

use cyclic_mechanism::model::{state_derivative, Inputs, Parameters, State};
use diffsol::{NalgebraLU, NalgebraMat, OdeBuilder, OdeSolverMethod, OdeSolverStopReason};
use ode_solvers::{SVector, System};

use crate::{Run, Scenario};

pub const METHODS: [&str; 4] = [
    "ode_solvers_dop853",
    "diffsol_tsit45",
    "diffsol_bdf",
    "diffsol_esdirk34",
];

pub fn run(method: &str, scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
    match method {
        "ode_solvers_dop853" => ode_solvers_dop853(scenario, h, tol),
        _ => diffsol_run(method, scenario, h, tol),
    }
}

#[derive(Clone, Copy)]
struct Mechanism<'a> {
    params: Parameters,
    counter: &'a Cell<u64>,
}

impl System<f64, SVector<f64, 8>> for Mechanism<'_> {
    fn system(&self, _t: f64, y: &SVector<f64, 8>, dy: &mut SVector<f64, 8>) {
        let state: State = (*y).into();
        let mut rate = [0.0; 8];
        state_derivative(&self.params, &Inputs::default(), &state, &mut rate);
        *dy = SVector::from(rate);
        self.counter.set(self.counter.get() + 1);
    }
}

/// ode_solvers' Dop853 integrates one span per solver: a new one for every interval.
fn ode_solvers_dop853(scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
    let counter = Cell::new(0);
    let system = Mechanism {
        params: scenario.parameters(),
        counter: &counter,
    };
    let mut y = scenario.initial_state();
    let mut run = Run::start(scenario, h, &y);
    let n = (scenario.stop / h).round() as usize;
    for k in 1..=n {
        let t = (k - 1) as f64 * h;
        let mut solver = ode_solvers::Dop853::new(system, t, t + h, h, SVector::from(y), tol, tol);
        if let Err(e) = solver.integrate() {
            eprintln!("ode_solvers: {e:?} at t = {t}");
            return None;
        }
        y = (*solver.y_out().last()?).into();
        run.states[k] = y;
    }
    run.n_rhs = counter.get();
    Some(run)
}

/// Stop a diffsol solver at every communication point and record the state there
/// (a macro: the solvers' types involve the closures' unnameable types).
macro_rules! step_through {
    ($solver:expr, $scenario:expr, $h:expr, $y0:expr) => {{
        let mut solver = $solver;
        let mut run = Run::start($scenario, $h, $y0);
        let n = ($scenario.stop / $h).round() as usize;
        let mut ok = true;
        for k in 1..=n {
            if solver.set_stop_time(k as f64 * $h).is_err() {
                ok = false;
                break;
            }
            loop {
                match solver.step() {
                    Ok(OdeSolverStopReason::TstopReached) => break,
                    Ok(_) => {}
                    Err(_) => {
                        ok = false;
                        break;
                    }
                }
            }
            if !ok {
                break;
            }
            let y: State = std::array::from_fn(|i| solver.state().y[i]);
            run.states[k] = y;
        }
        ok.then_some(run)
    }};
}

/// diffsol's solvers are kept alive and stopped at each communication point.
fn diffsol_run(method: &str, scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
    let counter = Rc::new(Cell::new(0u64));
    let (params, y0) = (scenario.parameters(), scenario.initial_state());
    let rhs_counter = counter.clone();
    let rhs = move |x: &[f64], _p: &[f64], _t: f64, dy: &mut [f64]| {
        let state: State = x.try_into().expect("8 states");
        let mut rate = [0.0; 8];
        state_derivative(&params, &Inputs::default(), &state, &mut rate);
        dy.copy_from_slice(&rate);
        rhs_counter.set(rhs_counter.get() + 1);
    };
    let jac_counter = counter.clone();
    // Jacobian-vector product by a forward difference (counted as one evaluation).
    let jacobian = move |x: &[f64], _p: &[f64], _t: f64, v: &[f64], jv: &mut [f64]| {
        let state: State = x.try_into().expect("8 states");
        let norm = v.iter().map(|e| e * e).sum::<f64>().sqrt();
        if norm == 0.0 {
            jv.fill(0.0);
            return;
        }
        let eps = 1e-7 * (1.0 + state.iter().map(|e| e.abs()).fold(0.0, f64::max)) / norm;
        let shifted: State = std::array::from_fn(|i| state[i] + eps * v[i]);
        let (mut f0, mut f1) = ([0.0; 8], [0.0; 8]);
        state_derivative(&params, &Inputs::default(), &state, &mut f0);
        state_derivative(&params, &Inputs::default(), &shifted, &mut f1);
        for i in 0..8 {
            jv[i] = (f1[i] - f0[i]) / eps;
        }
        jac_counter.set(jac_counter.get() + 2);
    };
    let problem = OdeBuilder::<NalgebraMat<f64>>::new()
        .rtol(tol)
        .atol([tol])
        .rhs_implicit(rhs, jacobian)
        .init(move |_p, _t, y: &mut [f64]| y.copy_from_slice(&y0), 8)
        .build()
        .ok()?;
    let mut run = match method {
        "diffsol_tsit45" => step_through!(problem.tsit45().ok()?, scenario, h, &y0),
        "diffsol_bdf" => step_through!(problem.bdf::<NalgebraLU<f64>>().ok()?, scenario, h, &y0),
        "diffsol_esdirk34" => step_through!(
            problem.esdirk34::<NalgebraLU<f64>>().ok()?,
            scenario,
            h,
            &y0
        ),
        _ => None,
    }?;
    run.n_rhs = counter.get();
    Some(run)
}
