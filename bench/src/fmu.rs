//! The packed FMU through its C ABI, loaded by the runner's library (the project's one FMU
//! loader): a master loop as FMPy's would run it.

use std::path::Path;
use std::rc::Rc;

use fmu_runner::archive::Unpacked;
use fmu_runner::description::Description;
use fmu_runner::fmi::{Instance, Interface, Library, Status};

use crate::{Run, Scenario};

pub struct Fmu {
    library: Rc<Library>,
    description: Description,
    _unpacked: Unpacked,
}

fn check(status: Status, what: &str) -> Option<()> {
    (status == Status::Ok).then_some(()).or_else(|| {
        eprintln!("{what} returned status {status:?}");
        None
    })
}

impl Fmu {
    pub fn load(path: &Path) -> Result<Self, String> {
        let unpacked = Unpacked::new(path)?;
        let description = Description::read(unpacked.dir())?;
        let library = Library::load(unpacked.dir(), &description, Interface::CoSimulation)?;
        Ok(Self {
            library,
            description,
            _unpacked: unpacked,
        })
    }

    fn vr(&self, name: &str) -> u32 {
        self.description
            .variables
            .iter()
            .find(|v| v.name == name)
            .map(|v| v.value_reference)
            .expect("variable in the description")
    }

    /// One simulation: instantiate, initialise, step with H to the stop time reading the
    /// eight states after every step and keeping them, as a master does.
    pub fn run(&self, scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
        let mut instance = Instance::new(&self.library, c"bench")
            .map_err(|e| eprintln!("{e}"))
            .ok()?;
        let outputs: Vec<u32> = [
            "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
        ]
        .iter()
        .map(|n| self.vr(n))
        .collect();
        // t = 0 as the FMU reads it, below.
        let mut run = Run::start(scenario, h, &[0.0; 8]);
        let c = &mut instance;
        check(
            c.setup_experiment(Some(tol), 0.0, scenario.stop),
            "fmi2SetupExperiment",
        )?;
        check(c.enter_initialization_mode(), "fmi2EnterInitializationMode")?;
        for (name, value) in scenario.values {
            check(c.set_real(&[self.vr(name)], &[*value]), "fmi2SetReal")?;
        }
        check(
            c.set_integer(&[self.vr("solver")], &[scenario.solver]),
            "fmi2SetInteger",
        )?;
        let laws = i32::from(scenario.builtin_laws);
        check(
            c.set_boolean(&[self.vr("builtin_laws")], &[laws]),
            "fmi2SetBoolean",
        )?;
        check(c.exit_initialization_mode(), "fmi2ExitInitializationMode")?;
        check(c.get_real(&outputs, &mut run.states[0]), "fmi2GetReal")?;
        for (k, y) in run.states.iter_mut().skip(1).enumerate() {
            check(c.do_step(k as f64 * h, h), "fmi2DoStep")?;
            check(c.get_real(&outputs, y), "fmi2GetReal")?;
        }
        let mut rhs = [0];
        check(
            c.get_integer(&[self.vr("n_rhs")], &mut rhs),
            "fmi2GetInteger",
        )?;
        run.n_rhs = rhs[0] as u64;
        Some(run)
    }
}
