// Each test crate uses part of this module.
#![allow(dead_code)]

//! Shared by the integration tests that drive the exported C functions directly.

use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

use cyclic_mechanism::fmi2::fmi2Instantiate;
use cyclic_mechanism::fmi2::model_description::guid;
use fmi_sys::fmi2::{fmi2CallbackFunctions, fmi2Component, fmi2Type_fmi2CoSimulation};

/// A co-simulation instance without callbacks (no logger: nothing is formatted). The FMU
/// keeps only the logger and environment from `functions`, so a temporary struct is fine.
pub fn instantiate(name: &CStr) -> fmi2Component {
    instantiate_as(name, fmi2Type_fmi2CoSimulation)
}

/// An instance of either interface (`fmi2Type_fmi2ModelExchange` or `…CoSimulation`).
pub fn instantiate_as(name: &CStr, kind: fmi_sys::fmi2::fmi2Type) -> fmi2Component {
    let functions = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: null_mut(),
    };
    let guid = CString::new(guid()).expect("the GUID has no NUL");
    // SAFETY: valid C strings and callbacks for the duration of the call.
    let c =
        unsafe { fmi2Instantiate(name.as_ptr(), kind, guid.as_ptr(), null(), &functions, 0, 0) };
    assert!(!c.is_null(), "fmi2Instantiate failed");
    c
}

/// Set up (tolerance, optional stop time), set parameters by name, and leave
/// initialisation mode, asserting every status.
pub fn initialise(c: fmi2Component, tolerance: f64, stop: Option<f64>, parameters: &[(&str, f64)]) {
    use cyclic_mechanism::fmi2::{
        fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2SetReal, fmi2SetupExperiment,
    };
    use cyclic_mechanism::variables::value_reference;
    use fmi_sys::fmi2::fmi2Status_fmi2OK as OK;
    let refs: Vec<u32> = parameters
        .iter()
        .map(|(n, _)| value_reference(n).expect("a known name"))
        .collect();
    let values: Vec<f64> = parameters.iter().map(|(_, v)| *v).collect();
    let (stop_defined, stop_time) = (stop.is_some() as i32, stop.unwrap_or(0.0));
    // SAFETY: `c` is a live instance; the arrays hold `refs.len()` elements.
    unsafe {
        assert_eq!(
            fmi2SetupExperiment(c, 1, tolerance, 0.0, stop_defined, stop_time),
            OK
        );
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(
            fmi2SetReal(c, refs.as_ptr(), refs.len(), values.as_ptr()),
            OK
        );
        assert_eq!(fmi2ExitInitializationMode(c), OK);
    }
}

/// The paper's built-in motor and load laws, [79] and [80] (docs/model.md §4), as (FMI
/// name, value) pairs: the published figures, set explicitly so that a test of case 1
/// does not depend on the defaults (which are these too).
pub fn paper_laws() -> [(&'static str, f64); 5] {
    [
        ("Mm_a0", 100.0),
        ("Mm_a1", -20.0),
        ("Mm_a2", -1.0),
        ("Mr_b0", 20.0),
        ("Mr_b1", -0.05),
    ]
}

/// The plant under the co-simulation driver without the FMI layer, as the tests that look
/// inside use it.
pub struct Run {
    pub plant: cyclic_mechanism::plant::Plant,
    pub driver: Option<cyclic_mechanism::drivers::CoSimulation>,
    pub experiment: cyclic_mechanism::drivers::Experiment,
}

impl Run {
    pub fn new() -> Self {
        Self {
            plant: cyclic_mechanism::plant::Plant::new(),
            driver: None,
            experiment: cyclic_mechanism::drivers::Experiment::new(0.0),
        }
    }

    pub fn set(
        &mut self,
        vr: u32,
        value: cyclic_mechanism::plant::Value,
        parameters_writable: bool,
    ) -> Result<(), cyclic_mechanism::plant::AccessError> {
        self.plant.set(vr, value, parameters_writable)
    }

    pub fn set_tolerance(&mut self, tolerance: f64) {
        self.experiment.tolerance = tolerance;
    }

    pub fn initialize(&mut self, start: f64) {
        self.experiment.start = start;
        self.plant.initialize(start).unwrap();
        self.driver = Some(cyclic_mechanism::drivers::CoSimulation::new(
            &self.plant,
            &self.experiment,
        ));
    }

    pub fn advance(&mut self, t: f64) -> Result<(), integrators::SolverError> {
        let driver = self.driver.as_mut().expect("initialised");
        driver.advance(&mut self.plant, t, &self.experiment)
    }

    pub fn state(&self) -> &[f64; 8] {
        self.plant.state()
    }

    pub fn time(&self) -> f64 {
        self.plant.time()
    }

    pub fn params(&self) -> &cyclic_mechanism::model::Parameters {
        self.plant.params()
    }

    /// A variable's value, the statistics from the driver.
    pub fn get(
        &self,
        vr: u32,
    ) -> Result<cyclic_mechanism::plant::Value, cyclic_mechanism::plant::AccessError> {
        let activity = self.driver.as_ref().expect("initialised").activity();
        self.plant.get(vr, &activity)
    }

    pub fn statistics(&self) -> integrators::Statistics {
        self.driver.as_ref().expect("initialised").statistics()
    }
}

/// A run without the FMI layer: `parameters` set by name, `solver` (1 auto, 2 dop853,
/// 3 implicit) and `tolerance`, initialised at t = 0.
pub fn simulation(parameters: &[(&str, f64)], solver: i32, tolerance: f64) -> Run {
    use cyclic_mechanism::plant::Value;
    use cyclic_mechanism::variables::value_reference;
    let mut run = Run::new();
    for (name, value) in parameters {
        run.set(value_reference(name).unwrap(), Value::Real(*value), true)
            .unwrap();
    }
    run.set(
        value_reference("solver").unwrap(),
        Value::Integer(solver),
        true,
    )
    .unwrap();
    run.set_tolerance(tolerance);
    run.initialize(0.0);
    run
}

/// Advance `run` from t = 0 to `t_end` in communication steps of `h`.
pub fn advance(run: &mut Run, t_end: f64, h: f64) {
    for k in 1..=(t_end / h).round() as usize {
        run.advance(k as f64 * h).unwrap();
    }
}

/// xorshift64*: a small deterministic generator, enough for fuzzing.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    pub fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
    pub fn real(&mut self) -> f64 {
        match self.below(12) {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => -1.0,
            3 => 0.0,
            4 => 1e9,
            5 => self.extreme(),
            _ => (self.below(2000) as f64 - 500.0) / 100.0,
        }
    }
    /// Finite but extreme: huge, tiny, subnormal, of either sign.
    pub fn extreme(&mut self) -> f64 {
        const EXTREMES: [f64; 8] = [1e300, 1e200, 1e155, 1e-300, 5e-324, 2.2e-308, 1e100, 1e-20];
        let x = EXTREMES[self.below(EXTREMES.len() as u64) as usize];
        if self.chance(50) {
            -x
        } else {
            x
        }
    }
}

/// Far above the longest call the work bound allows on a loaded machine, far below the
/// minutes a call ran before it.
pub const RUNAWAY: std::time::Duration = std::time::Duration::from_secs(20);

/// Whether the fuzzers try steps that spend a whole call's work (not under valgrind, where
/// each would take minutes).
pub fn long_steps() -> bool {
    std::env::var("FUZZ_LONG_STEPS").map_or(true, |v| v != "0")
}

/// The longest call seen, and which: a hang guard, not a speed target (see [`RUNAWAY`]).
pub fn assert_no_runaway(longest: &(std::time::Duration, String)) {
    assert!(
        longest.0 < RUNAWAY,
        "a call took {:.1} s: {}",
        longest.0.as_secs_f64(),
        longest.1
    );
}
