//! Project jobs: `cargo xtask <job> [--help]`, one module per job, each declaring its flags
//! in [`JOBS`].
//!
//! Each job installs what it needs on a fresh Debian machine: libclang for the FMI
//! bindings (bindgen), and a Python venv in `target/venv` with the pinned packages of
//! `tests/python/requirements.txt`. This crate deliberately does not depend on the FMU
//! crate: building that needs libclang, which this program installs first.

mod abi_tests;
mod accuracy;
mod bench;
mod builders;
mod cli;
mod demo;
mod fit;
mod fmu;
mod folders;
mod instructions;
mod layers;
mod master;
mod motor;
mod page;
mod platforms;
mod setup;
mod sizes;
mod sweep;
mod test;
mod tidy;
mod web;

use cli::{Flag, Job, QUICK};

const JOBS: &[Job] = &[
    Job {
        name: "fmu",
        operands: &[],
        about: "build and pack target/fmu/CyclicMechanism.fmu (linux64)",
        flags: &[Flag {
            name: "all-platforms",
            value: None,
            help: "win64 and darwin64 too, cross-built here (Debian's packages)",
        }],
        run: fmu::job,
    },
    Job {
        name: "demo",
        operands: &[],
        about: "run the paper's two cases through FMPy: CSV, plots and an animation in target/demo",
        flags: &[],
        run: demo::job,
    },
    Job {
        name: "test",
        operands: &[],
        about: "run every test: tidy, cargo test, the cross builds, then the FMPy and sweep tests",
        flags: &[],
        run: test::job,
    },
    Job {
        name: "test-platforms",
        operands: &[],
        about: "the win64, darwin64 and aarch64 builds and their tests alone (part of test)",
        flags: &[],
        run: test::job_platforms,
    },
    Job {
        name: "web",
        operands: &[],
        about: "build the page that runs the mechanism in a browser (wasm32) into target/web",
        flags: &[],
        run: web::job,
    },
    Job {
        name: "bench-web",
        operands: &[],
        about: "the page and its module against the native library: speed, frame rate, size, into target/bench-web",
        flags: &[QUICK],
        run: web::job_bench,
    },
    Job {
        name: "tidy",
        operands: &[],
        about: "formatting, clippy, unsafe only in the FFI and loader files, no figures in src/ comments",
        flags: &[],
        run: tidy::job,
    },
    Job {
        name: "motor",
        operands: &[],
        about: "build and pack target/fmu/DcMotor.fmu, FlywheelLoad.fmu and BouncingBall.fmu, the compiled FMUs of examples/",
        flags: &[],
        run: motor::job,
    },
    Job {
        name: "bench",
        operands: &[],
        about: "the work-precision benchmark into target/bench",
        flags: &[QUICK],
        run: bench::job,
    },
    Job {
        name: "sweep",
        operands: &["SPEC"],
        about: "run a sweep of SPEC.toml (the packed FMU unless the spec names another)",
        flags: sweep::FLAGS,
        run: sweep::job,
    },
    Job {
        name: "fit",
        operands: &["SPEC"],
        about: "fit parameters to measured data as SPEC.toml says (the packed FMU unless it names another)",
        flags: fit::FLAGS,
        run: fit::job,
    },
    Job {
        name: "wheel",
        operands: &[],
        about: "build the fmusweep wheel (the sweep package with its native runner) in target/wheels",
        flags: &[],
        run: sweep::job_wheel,
    },
    Job {
        name: "bench-sweep",
        operands: &[],
        about: "the sweep benchmark into target/bench-sweep",
        flags: &[QUICK],
        run: sweep::job_bench,
    },
    Job {
        name: "bench-coupling",
        operands: &[],
        about: "coupled runs (mechanism and motor): the cost of a step and the sweep engines, into target/bench-coupling",
        flags: motor::BENCH_FLAGS,
        run: motor::job_bench,
    },
    Job {
        name: "bench-engine",
        operands: &[],
        about: "each worked sweep serially, on a LocalCluster and as the engine choice runs it, and the disk estimate against what sweeps wrote, into target/bench-engine and docs/bench/engine.md",
        flags: &[QUICK],
        run: sweep::job_bench_engine,
    },
    Job {
        name: "bench-cycle",
        operands: &[],
        about: "steady cycles by shooting against transient runs on a lightly damped grid, 2 workers, into target/bench-cycle and docs/bench/cycle.md",
        flags: &[QUICK],
        run: sweep::job_bench_cycle,
    },
    Job {
        name: "bench-fit",
        operands: &[],
        about: "the fit benchmark into target/bench-fit",
        flags: &[QUICK],
        run: fit::job_bench,
    },
    Job {
        name: "bench-sensitivities",
        operands: &[],
        about: "the FMU's parameter sensitivities in a fit: a run's cost, a fit against differences, into target/bench-sensitivities",
        flags: &[QUICK],
        run: fit::job_bench_sensitivities,
    },
    Job {
        name: "bench-report",
        operands: &[],
        about: "the interactive reports in headless Chromium: size and time to open, into target/bench-report",
        flags: &[QUICK],
        run: sweep::job_bench_report,
    },
    Job {
        name: "accuracy",
        operands: &[],
        about: "the accuracy figures the tests measure, with the commit and machine, into docs/bench/accuracy.md",
        flags: &[],
        run: accuracy::job,
    },
    Job {
        name: "instructions",
        operands: &[],
        about: "instructions per communication point (callgrind) into docs/bench/instructions.md",
        flags: &[],
        run: instructions::job,
    },
];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((name, rest)) = args.split_first() else {
        eprint!("{}", cli::overview(JOBS));
        std::process::exit(2);
    };
    if name == "--help" || name == "-h" || name == "help" {
        print!("{}", cli::overview(JOBS));
        return;
    }
    let Some(job) = JOBS.iter().find(|job| job.name == name) else {
        eprint!("xtask: unknown job {name}\n\n{}", cli::overview(JOBS));
        std::process::exit(2);
    };
    let result = cli::parse(job, rest).and_then(|parsed| match parsed {
        Some(parsed) => (job.run)(&parsed),
        None => Ok(()),
    });
    if let Err(message) = result {
        eprintln!("xtask {name}: {message}");
        std::process::exit(1);
    }
}
