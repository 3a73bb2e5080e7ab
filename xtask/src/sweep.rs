//! `cargo xtask sweep`, `wheel` and `bench-sweep`: the sweep package with its native runner,
//! a sweep of a spec, and the sweep benchmark.

use std::fs;
use std::path::PathBuf;
use std::process::Command;

use crate::cli::{Flag, Parsed};
use crate::setup::*;
use crate::{fmu, Result};

/// The fmusweep wheel: the native runner, built against glibc 2.17 like the FMU, packed
/// with the Python package by `python/build_wheel.py` (standard library only) as a
/// manylinux_2_17 wheel: workers on older Linux install it too.
pub(crate) fn build_wheel() -> Result<PathBuf> {
    ensure_libclang()?;
    let python = ensure_venv(Packages::Tests)?;
    let runner = build_portable(
        &["--package", "fmu-runner", "--bin", "fmu-runner"],
        "fmu-runner",
    )?;
    check_glibc(&runner)?;
    let wheel = output_of(
        Command::new(&python)
            .arg(root().join("python/build_wheel.py"))
            .arg(&runner)
            .arg(root().join("target/wheels"))
            .arg(format!(
                "manylinux_{}_{}_x86_64",
                GLIBC_BASELINE.0, GLIBC_BASELINE.1
            )),
    )?;
    Ok(PathBuf::from(wheel.trim()))
}

/// Build the wheel and install it in the venv, unless that very wheel is installed.
pub(crate) fn ensure_sweep_package() -> Result<PathBuf> {
    let wheel = build_wheel()?;
    let python = ensure_venv(Packages::Tests)?;
    let stamp = root().join("target/venv/fmusweep.installed.whl");
    let bytes = fs::read(&wheel).map_err(|e| format!("{}: {e}", wheel.display()))?;
    if fs::read(&stamp).is_ok_and(|installed| installed == bytes) {
        return Ok(python);
    }
    println!("xtask: installing {} in the venv", wheel.display());
    run(pip_install(&python)
        .args(["--no-deps", "--force-reinstall"])
        .arg(&wheel))?;
    fs::write(&stamp, bytes).map_err(|e| e.to_string())?;
    Ok(python)
}

/// `cargo xtask sweep SPEC [options]`: the packed FMU is the default FMU of the spec.
pub(crate) fn job(parsed: &Parsed) -> Result {
    run_fmusweep(&[], parsed)
}

/// `python -m fmusweep [SUBCOMMAND] OPERANDS FLAGS` with the packed FMU as the default FMU.
pub(crate) fn run_fmusweep(subcommand: &[&str], parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    let python = ensure_sweep_package()?;
    // Run where the user is: spec paths are theirs.
    crate::setup::run(
        Command::new(python)
            .args(["-m", "fmusweep"])
            .args(subcommand)
            .args(&parsed.operands)
            .args(parsed.flag_args())
            .env("FMUSWEEP_FMU", &fmu),
    )
}

pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    run_bench_script("bench/bench_sweep.py", "target/bench-sweep", parsed)
}

/// A Python benchmark of the sweep package: `python SCRIPT FMU OUT FLAGS`.
pub(crate) fn run_bench_script(script: &str, out: &str, parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    let python = ensure_sweep_package()?;
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
    let wheel = build_wheel()?;
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
        help: "output directory (default: sweep-<spec digest>)",
    },
    Flag {
        name: "resume",
        value: None,
        help: "finish the sweep in --out, redoing only missing points",
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
        help: "no plots or sensitivity indices",
    },
];
