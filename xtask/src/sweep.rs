//! `cargo xtask sweep`, `wheel`, `bench-sweep`, `bench-cycle` and `bench-report`: the sweep
//! package with its native runner, a sweep of a spec, and the sweep's, the steady cycles'
//! and the reports' benchmarks.

use std::fs;
use std::process::Command;

use crate::cli::{Flag, Parsed};
use crate::fmu;
use crate::setup::Result;
use crate::setup::*;

/// `cargo xtask sweep SPEC [options]`: the packed FMU is the default FMU of the spec.
pub(crate) fn job(parsed: &Parsed) -> Result {
    run_fmusweep(&[], parsed)
}

/// `python -m fmusweep [SUBCOMMAND] OPERANDS FLAGS` with the packed FMU as the default FMU
/// (and the compiled DC motor, flywheel load and the motor's SSP file beside it, in
/// target/fmu).
pub(crate) fn run_fmusweep(subcommand: &[&str], parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    // The compiled motor and load too, and the motor's system as an SSP file: the worked
    // coupled systems use them.
    let motor = crate::builders::build_motor()?;
    crate::builders::build_flywheel_load()?;
    crate::builders::build_motor_ssp(&fmu, &motor)?;
    let python = crate::builders::ensure_sweep_package()?;
    // Run where the user is: spec paths are theirs.
    crate::setup::run(
        Command::new(python)
            .args(["-m", "fmusweep"])
            .args(subcommand)
            .args(&parsed.operands)
            .args(parsed.flag_args())
            .env("FMUSWEEP_FMU", &fmu)
            // Killing this command ends the sweep too, which says what it kept.
            .env("FMUSWEEP_END_WITH_PARENT", "1"),
    )
}

pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    run_bench_script("bench/bench_sweep.py", "target/bench-sweep", parsed)
}

/// `cargo xtask bench-engine`: each worked sweep serially, on a LocalCluster and as the
/// engine choice runs it, and the disk estimate against what sweeps wrote
/// (docs/bench/engine.md).
pub(crate) fn job_bench_engine(parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    let motor = crate::builders::build_motor()?;
    crate::builders::build_flywheel_load()?;
    crate::builders::build_motor_ssp(&fmu, &motor)?;
    run_bench_script("bench/bench_engine.py", "target/bench-engine", parsed)
}

/// `cargo xtask bench-cycle`: steady cycles against transients (docs/bench/cycle.md).
pub(crate) fn job_bench_cycle(parsed: &Parsed) -> Result {
    run_bench_script("bench/bench_cycle.py", "target/bench-cycle", parsed)
}

/// `cargo xtask bench-report`: the reports opened in headless Chromium (installed if missing).
pub(crate) fn job_bench_report(parsed: &Parsed) -> Result {
    crate::setup::ensure_chromium()?;
    run_bench_script("bench/bench_report.py", "target/bench-report", parsed)
}

/// A Python benchmark of the sweep package: `python SCRIPT FMU OUT FLAGS`.
pub(crate) fn run_bench_script(script: &str, out: &str, parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    let python = crate::builders::ensure_sweep_package()?;
    let out = root().join(out);
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    crate::setup::run(
        Command::new(python)
            .arg(root().join(script))
            .arg(&fmu)
            .arg(&out)
            .args(parsed.flag_args()),
    )
}

/// `cargo xtask wheel`.
pub(crate) fn job_wheel(_: &Parsed) -> Result {
    let wheel = crate::builders::build_wheel()?;
    println!("wheel: {}", wheel.display());
    Ok(())
}

/// Where the runs go, for a sweep and a fit alike.
pub(crate) const WORKERS: Flag = Flag {
    name: "workers",
    value: Some("N"),
    help: "local Dask worker processes (default: every core)",
};
pub(crate) const SCHEDULER: Flag = Flag {
    name: "scheduler",
    value: Some("ADDRESS"),
    help: "an existing Dask scheduler, tcp://HOST:PORT",
};
pub(crate) const SERIAL: Flag = Flag {
    name: "serial",
    value: None,
    help: "no Dask: run in this process",
};

/// The flags of `cargo xtask sweep`, handed on to `python -m fmusweep`.
pub(crate) const FLAGS: &[Flag] = &[
    WORKERS,
    SCHEDULER,
    Flag {
        name: "out",
        value: Some("DIR"),
        help: "output directory (default: a new results/SPEC-DATE-TIME)",
    },
    Flag {
        name: "resume",
        value: None,
        help: "finish the sweep in --out (default: the newest of this spec in results/), redoing only missing points",
    },
    SERIAL,
    Flag {
        name: "batch-size",
        value: Some("N"),
        help: "points per task (default: about 0.5 s of work)",
    },
    Flag {
        name: "no-progress",
        value: None,
        help: "no progress bar",
    },
    Flag {
        name: "no-plots",
        value: None,
        help: "no plots or report (the sensitivity indices are still computed)",
    },
];
