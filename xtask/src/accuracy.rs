//! `cargo xtask accuracy`: the accuracy figures the documents quote, measured by the tests
//! that hold them (each against a bound of its own) and tabled with the commit and machine
//! into `docs/bench/accuracy.md`, so that a document quotes a row a command wrote.

use std::fs;
use std::process::Command;

use crate::setup::Result;
use crate::setup::{root, run};
use crate::{builders, fmu};

/// The test files whose figures the report holds.
const MEASURING: [&str; 11] = [
    "test_physics.py",
    "test_stability.py",
    "test_stiff.py",
    "test_tolerance.py",
    "test_fmi_api.py",
    "test_model_exchange.py",
    "test_linkages.py",
    "test_fmi3.py",
    "test_coupling.py",
    "test_sensitivities.py",
    "test_libcosim.py",
];

pub(crate) fn job(_: &crate::cli::Parsed) -> Result {
    let packed = fmu::build_fmu(false)?;
    let python = builders::ensure_sweep_package()?;
    let motor = builders::build_motor()?;
    let out = root().join("target/accuracy");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    let measurements = out.join("measurements.json");
    run(Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(format!("--basetemp={}", out.join("pytest").display()))
        .args(MEASURING.map(|f| root().join("tests/python").join(f)))
        .env("CYCLIC_MECHANISM_FMU", &packed.fmu)
        .env("CYCLIC_MECHANISM_FMU3", &packed.fmu3)
        .env("DC_MOTOR_FMU", &motor)
        .env("MEASUREMENTS", &measurements)
        .current_dir(root()))?;
    let report = root().join("docs/bench/accuracy.md");
    run(Command::new(&python)
        .arg(root().join("bench/accuracy_report.py"))
        .arg(&measurements)
        .arg(&report)
        .args(MEASURING))?;
    println!("xtask: {}", report.display());
    Ok(())
}
