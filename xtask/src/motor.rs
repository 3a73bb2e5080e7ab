//! `cargo xtask motor`: the compiled FMUs of `examples/` (C), built against glibc 2.17 with
//! zig, checked and packed into `target/fmu`: the DC motor and the flywheel load (FMI 2.0
//! Co-Simulation), for coupling and sweeping the mechanism at native speed, and the
//! bouncing ball, a subject with known solutions (FMI 3.0 Co-Simulation with events, and
//! Model Exchange for FMI 2.0 and 3.0); and `cargo xtask bench-coupling`, which measures
//! coupled steps and sweeps with them.

use crate::cli::{Flag, Parsed};
use crate::setup::Result;
use crate::setup::{root, run};

pub(crate) fn job(_: &Parsed) -> Result {
    println!("FMU: {}", crate::builders::build_motor()?.display());
    println!("FMU: {}", crate::builders::build_flywheel_load()?.display());
    println!("FMU: {}", crate::builders::build_bouncing_ball()?.display());
    let (me2, me3) = crate::builders::build_bouncing_ball_me()?;
    println!("FMU: {}\nFMU: {}", me2.display(), me3.display());
    Ok(())
}

/// `cargo xtask bench-coupling [--before FMU] [--quick]`: into target/bench-coupling, the
/// cost and accuracy of a coupled communication step (`step/`; with `--before`, another
/// build of the mechanism measured beside this one) and the coupled sweep's engines and
/// coupling error (`sweep/`).
pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    let mechanism = crate::fmu::build_fmu(false)?.fmu;
    let motor = crate::builders::build_motor()?;
    let load = crate::builders::build_flywheel_load()?;
    let python = crate::builders::ensure_sweep_package()?;
    let out = root().join("target/bench-coupling");
    for (script, part, flags, components) in [
        (
            "bench/bench_coupled_step.py",
            "step",
            parsed.flag_args_except(&["quick"]),
            vec![&motor],
        ),
        (
            "bench/bench_coupled_sweep.py",
            "sweep",
            parsed.flag_args_except(&["before"]),
            vec![&motor, &load],
        ),
    ] {
        run(std::process::Command::new(&python)
            .arg(root().join(script))
            .arg(&mechanism)
            .args(components)
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
    crate::cli::QUICK,
];
