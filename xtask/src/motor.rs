//! `cargo xtask motor`: the compiled DC motor of `examples/dc_motor/native` (C, FMI 2.0
//! Co-Simulation) built against glibc 2.17 with zig, checked and packed as
//! `target/fmu/DcMotor.fmu`, for coupling and sweeping the mechanism at native speed; and
//! `cargo xtask bench-coupling`, which measures a coupled step with it.

use std::path::PathBuf;

use crate::cli::{Flag, Parsed};
use crate::setup::{check_glibc, ensure_venv, root, run, Packages};
use crate::Result;

pub(crate) fn job(_: &Parsed) -> Result {
    println!("FMU: {}", build_motor()?.display());
    Ok(())
}

/// Build and pack the motor; returns the archive.
pub(crate) fn build_motor() -> Result<PathBuf> {
    let source = root().join("examples/dc_motor/native");
    let zig = crate::platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
    let dir = root().join("target/motor");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let library = dir.join("DcMotor.so");
    run(zig
        .cc("x86_64-linux-gnu.2.17")
        .args(["-O2", "-std=c99", "-shared", "-fPIC", "-fvisibility=hidden"])
        .args(["-Wall", "-Wextra", "-Wno-unused-parameter", "-Werror", "-I"])
        .arg(crate::abi_tests::fmi2_headers()?)
        .arg("-o")
        .arg(&library)
        .arg(source.join("dc_motor.c"))
        .arg("-lm"))?;
    check_glibc(&library)?;
    let fmu = root().join("target/fmu/DcMotor.fmu");
    crate::fmu::pack(
        &fmu,
        &[
            (
                "modelDescription.xml".to_string(),
                source.join("modelDescription.xml"),
            ),
            ("binaries/linux64/DcMotor.so".to_string(), library),
        ],
    )?;
    Ok(fmu)
}

/// `cargo xtask bench-coupling [--before FMU] [--quick]`: into target/bench-coupling, the
/// cost and accuracy of a coupled communication step (`step/`; with `--before`, another
/// build of the mechanism measured beside this one) and the coupled sweep's engines and
/// coupling error (`sweep/`).
pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    let mechanism = crate::fmu::build_fmu(false)?.fmu;
    let motor = build_motor()?;
    let python = crate::sweep::ensure_sweep_package()?;
    let out = root().join("target/bench-coupling");
    for (script, part, flags) in [
        (
            "bench/bench_coupled_step.py",
            "step",
            parsed.flag_args_except(&["quick"]),
        ),
        (
            "bench/bench_coupled_sweep.py",
            "sweep",
            parsed.flag_args_except(&["before"]),
        ),
    ] {
        run(std::process::Command::new(&python)
            .arg(root().join(script))
            .arg(&mechanism)
            .arg(&motor)
            .arg(out.join(part))
            .args(flags))?;
    }
    Ok(())
}

pub(crate) const BENCH_FLAGS: &[Flag] = &[
    Flag {
        name: "before",
        value: Some("FMU"),
        help: "another build of CyclicMechanism.fmu, its coupled step measured beside this one",
    },
    crate::QUICK,
];
