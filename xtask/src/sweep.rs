//! `cargo xtask sweep`, `wheel` and `bench-sweep`: the sweep package with its native runner,
//! a sweep of a spec, and the sweep benchmark.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli::{Flag, Parsed};
use crate::setup::*;
use crate::{fmu, Result};

/// The fmusweep wheel, built by maturin from `python/pyproject.toml`: the Python package
/// and the native runner, built with zig against glibc 2.17 (as the FMU) and tagged
/// manylinux_2_17, so that workers on older Linux install it too.
pub(crate) fn build_wheel() -> Result<PathBuf> {
    ensure_libclang()?;
    let python = ensure_venv(Packages::Tests)?;
    let out = root().join("target/wheels");
    // The wheel is made of the package, the runner's crate and the lock file: with the same
    // bytes of each, the wheel built from them last is the one.
    let mut inputs = files_below(&root().join("python"))?;
    inputs.extend(files_below(&root().join("runner"))?);
    inputs.push(root().join("Cargo.lock"));
    let key = fingerprint(&inputs)?;
    let stamp = root().join("target/wheels.fingerprint");
    if fs::read_to_string(&stamp).is_ok_and(|built| built == key) {
        if let Some(wheel) = wheel_in(&out) {
            return Ok(wheel);
        }
    }
    if out.exists() {
        fs::remove_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    let maturin = python.with_file_name("maturin");
    crate::setup::run(
        Command::new(&maturin)
            .current_dir(root().join("python"))
            .args(["build", "--release", "--quiet", "--zig", "--compatibility"])
            .arg(format!("manylinux{}", MANYLINUX_FOR_BASELINE))
            .arg("--out")
            .arg(&out)
            .env("PATH", path_with_venv(&python)?)
            // As for cargo-zigbuild: bindgen gets the C headers from here, not from zig.
            .env("BINDGEN_EXTRA_CLANG_ARGS", c_header_args()?),
    )?;
    check_glibc(&root().join("target/x86_64-unknown-linux-gnu/release/fmu-runner"))?;
    let wheel =
        wheel_in(&out).ok_or_else(|| format!("maturin wrote no wheel to {}", out.display()))?;
    fs::write(&stamp, key).map_err(|e| format!("{}: {e}", stamp.display()))?;
    Ok(wheel)
}

/// The wheel in `dir`, if there is one.
fn wheel_in(dir: &Path) -> Option<PathBuf> {
    fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|entry| entry.path())
        .find(|path| path.extension().is_some_and(|e| e == "whl"))
}

/// manylinux2014 is glibc 2.17, the baseline of every Linux binary here.
const MANYLINUX_FOR_BASELINE: &str = "2014";

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

/// `python -m fmusweep [SUBCOMMAND] OPERANDS FLAGS` with the packed FMU as the default FMU
/// (and the compiled DC motor packed beside it, in target/fmu).
pub(crate) fn run_fmusweep(subcommand: &[&str], parsed: &Parsed) -> Result {
    let fmu = fmu::build_fmu(false)?.fmu;
    // The compiled motor too: the worked coupled systems use it.
    crate::motor::build_motor()?;
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
