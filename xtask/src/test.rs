//! `cargo xtask test`: every test, as CI runs it: the Rust tests, the fuzzer under
//! valgrind, the cross builds and their tests on other ABIs (the page's wasm32 module among
//! them), the benchmark harness's smoke run, the FMPy, libcosim, sweep and browser tests,
//! and memcheck of the FMPy suite.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::cli::Parsed;
use crate::setup::*;
use crate::setup::{Result, MODEL_IDENTIFIER};
use crate::{abi_tests, fmu, platforms};

/// Each stage's wall time, said as the run goes and again at its end: where a suite's time
/// goes, in every log.
struct Stages {
    started: Instant,
    last: Instant,
    done: Vec<(&'static str, f64)>,
}

impl Stages {
    fn new() -> Self {
        let now = Instant::now();
        Self {
            started: now,
            last: now,
            done: Vec::new(),
        }
    }

    fn done(&mut self, stage: &'static str) {
        let now = Instant::now();
        let seconds = (now - self.last).as_secs_f64();
        println!("xtask test: {stage} took {seconds:.0} s");
        self.done.push((stage, seconds));
        self.last = now;
    }

    fn summary(&self) -> String {
        let parts: Vec<String> = self
            .done
            .iter()
            .map(|(stage, s)| format!("{stage} {s:.0} s"))
            .collect();
        format!(
            "xtask test: all passed in {:.0} s ({})",
            self.started.elapsed().as_secs_f64(),
            parts.join(", ")
        )
    }
}

pub(crate) fn job(_: &Parsed) -> Result {
    let mut stages = Stages::new();
    crate::tidy::check()?;
    stages.done("tidy");
    ensure_libclang()?;
    let reports = root().join("target/test-reports");
    fs::create_dir_all(&reports).map_err(|e| e.to_string())?;
    run(as_test_build(&mut cargo())
        .args(["test", "--release"])
        .env("FUZZ_REPORT", reports.join("fuzz_api.json"))
        .env("FUZZ_REPORT_FMI3", reports.join("fuzz_api_fmi3.json")))?;
    stages.done("cargo test");
    fuzz_under_valgrind()?;
    stages.done("fuzzers under valgrind");
    // The archive with every platform: the FMPy tests check it as a master would.
    let (fmu, fmu3) = test_platforms()?;
    stages.done("cross builds and other platforms");
    // The benchmark harness builds and drives the packed FMU (a smoke run, no timings
    // judged), so that `cargo xtask bench` keeps working from a fresh clone.
    let harness = crate::bench::build_bench_harness_for_tests()?;
    let smoke = root().join("target/bench/smoke.json");
    fs::create_dir_all(root().join("target/bench")).map_err(|e| e.to_string())?;
    run(Command::new(&harness)
        .arg(&fmu)
        .arg(&smoke)
        .args(["--quick", "--fmu-only"]))?;
    stages.done("benchmark harness");
    let python = crate::builders::ensure_sweep_package()?;
    let motor = crate::builders::build_motor()?;
    let load = crate::builders::build_flywheel_load()?;
    let ball = crate::builders::build_bouncing_ball()?;
    let (ball_me, ball_me3) = crate::builders::build_bouncing_ball_me()?;
    ensure_chromium()?;
    let page = crate::page::build_page()?;
    stages.done("the package, examples and page");
    // Memcheck of the FMPy suite runs beside the Python suite, at the lowest priority: it
    // takes the core time the suite leaves idle (much of the suite is one process waiting
    // on another), and the suite itself is scheduled as if alone. Its outcome is decided
    // by the packed FMU, the test files, the installed packages and the selection and
    // options in `fmpy_under_valgrind` (in this file) alone: a re-run skips it.
    let mut inputs = vec![
        fmu.clone(),
        fmu3.clone(),
        root().join("target/venv/requirements.installed"),
        root().join("xtask/src/test.rs"),
    ];
    inputs.extend(files_with_extension(&root().join("tests/python"), "py")?);
    let mut suite = Command::new(&python);
    suite
        .args([
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "--durations=25",
        ])
        .arg(root().join("tests/python"))
        .env("CYCLIC_MECHANISM_FMU", &fmu)
        .env("CYCLIC_MECHANISM_FMU3", &fmu3)
        .env("DC_MOTOR_FMU", &motor)
        .env("FLYWHEEL_LOAD_FMU", &load)
        .env("BOUNCING_BALL_FMU", &ball)
        .env("BOUNCING_BALL_ME_FMU", &ball_me)
        .env("BOUNCING_BALL_ME_FMU3", &ball_me3)
        .env("MECHANISM_WEB_PAGE", &page)
        .current_dir(root());
    let (suite, memcheck) = std::thread::scope(|scope| {
        let memcheck = scope.spawn(|| {
            unless_passed_before("valgrind memcheck of the FMPy suite", &inputs, || {
                fmpy_under_valgrind(&python, &fmu, &fmu3)
            })
        });
        let suite = run(&mut suite);
        let memcheck = memcheck
            .join()
            .unwrap_or_else(|_| Err("the memcheck's thread panicked".into()));
        (suite, memcheck)
    });
    suite?;
    stages.done("Python suite, with the memcheck of the FMPy suite beside it");
    memcheck?;
    println!("{}", stages.summary());
    Ok(())
}

/// Build the FMU for every platform and run the other platforms' binaries on their ABIs
/// (tests/platforms, xtask/src/abi_tests.rs). Returns the archive.
/// `cargo xtask test-platforms`.
pub(crate) fn job_platforms(_: &Parsed) -> Result {
    test_platforms().map(drop)
}

/// Returns the FMI 2.0 and FMI 3.0 archives.
pub(crate) fn test_platforms() -> Result<(PathBuf, PathBuf)> {
    ensure_libclang()?;
    let packed = fmu::build_fmu(true)?;
    let zig = platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
    abi_tests::test(
        &root().join("target/fmu/assets/modelDescription.xml"),
        &packed.linux64,
        &root().join(fmu::PLATFORM_BINARIES),
        &packed.report,
        &zig,
    )?;
    Ok((packed.fmu, packed.fmu3))
}

/// The FMPy tests of the C API (argument checks, state machine, FMU state, discards) under
/// valgrind memcheck. Python and numpy have valgrind reports of their own, so
/// only errors with a frame in the FMU's library count, including definite leaks allocated
/// there. A positive control first shows that an overrun inside the library is caught and
/// attributed (tests/python/valgrind_probe.py). At the lowest priority, as it runs beside
/// the Python suite; its output goes to target/valgrind/fmpy_suite.log.
pub(crate) fn fmpy_under_valgrind(python: &Path, fmu: &Path, fmu3: &Path) -> Result {
    let out = root().join("target/valgrind");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    let log = out.join("fmpy_suite.log");
    let log_file = fs::File::create(&log).map_err(|e| format!("{}: {e}", log.display()))?;
    let memcheck = |xml: &Path| -> Result<Command> {
        let to_log = || {
            log_file
                .try_clone()
                .map_err(|e| format!("{}: {e}", log.display()))
        };
        let mut command = Command::new("nice");
        command
            .args(["-n", "19", "valgrind"])
            .args([
                "--leak-check=full",
                "--show-leak-kinds=definite",
                "--error-limit=no",
            ])
            .args(["--xml=yes", &format!("--xml-file={}", xml.display())])
            .arg(python)
            .env("PYTHONMALLOC", "malloc")
            .env("CYCLIC_MECHANISM_FMU", fmu)
            .env("CYCLIC_MECHANISM_FMU3", fmu3)
            .env("MEASUREMENTS", out.join("measurements.json"))
            .current_dir(root())
            .stdout(to_log()?)
            .stderr(to_log()?);
        Ok(command)
    };
    let logged =
        |result: Result| result.map_err(|e| format!("{e}; its output in {}", log.display()));
    let probe = out.join("probe.xml");
    logged(run(memcheck(&probe)?
        .arg(root().join("tests/python/valgrind_probe.py"))
        .arg(fmu)))?;
    if errors_in_fmu(&probe)?.is_empty() {
        return Err(
            "valgrind check: the deliberate overrun in valgrind_probe.py was not \
                    attributed to the FMU; the check below would prove nothing"
                .into(),
        );
    }
    let suite = out.join("fmpy_suite.xml");
    let files = [
        "test_fmi_api.py",
        "test_fmu_state.py",
        "test_discard.py",
        // Model Exchange: the state machine, FMU states, Jacobians, and CVODE through the
        // handovers at dead points (the tests against the Python reference are left out:
        // its scipy integration under valgrind takes minutes and exercises no FMU code).
        "test_model_exchange.py::test_bad_states_and_wrong_calls_are_refused_and_change_nothing",
        "test_model_exchange.py::test_fmu_state_restores_model_exchange_exactly",
        "test_model_exchange.py::test_derivatives_match_the_variables_and_states_round_trip",
        "test_model_exchange.py::test_directional_derivatives_are_exact",
        "test_model_exchange.py::test_cvode_hands_over_at_every_dead_point",
        // FMI 3.0: the state machine, FMU states, early return at change points and the
        // adjoint derivatives (not the runs against the reference, as above).
        "test_fmi3_conformance.py::test_every_function_in_every_state",
        "test_fmi3.py::test_fmu_state_round_trips_bit_for_bit",
        "test_fmi3.py::test_change_point_returns_early_and_goes_on_on_the_chosen_branch",
        "test_fmi3.py::test_adjoint_is_the_transpose_of_the_directional_derivative",
    ];
    logged(run(memcheck(&suite)?
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(format!("--basetemp={}", out.join("pytest").display()))
        .args(files.map(|f| root().join("tests/python").join(f)))))?;
    let errors = errors_in_fmu(&suite)?;
    if !errors.is_empty() {
        return Err(format!(
            "valgrind: {} error(s) in the FMU under the FMPy suite (see {}):\n{}",
            errors.len(),
            suite.display(),
            errors.join("\n")
        ));
    }
    println!(
        "xtask: valgrind memcheck of the FMPy suite ({}): no error in the FMU",
        files.join(", ")
    );
    Ok(())
}

/// The kinds and first functions of the errors in valgrind's XML report that have a frame
/// in the FMU's library.
pub(crate) fn errors_in_fmu(xml: &Path) -> Result<Vec<String>> {
    let report = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    let tag = |block: &str, name: &str| -> Vec<String> {
        let (open, close) = (format!("<{name}>"), format!("</{name}>"));
        block
            .split(&open)
            .skip(1)
            .filter_map(|rest| rest.split(&close).next().map(str::to_string))
            .collect()
    };
    Ok(report
        .split("<error>")
        .skip(1)
        .filter_map(|rest| rest.split("</error>").next())
        .filter(|block| block.contains(&format!("{MODEL_IDENTIFIER}.so")))
        .map(|block| format!("{:?} in {:?}", tag(block, "kind"), tag(block, "fn").first()))
        .collect())
}

/// The fuzzed FMI 2.0 and 3.0 call sequences again, under valgrind memcheck: no invalid access, no
/// use of uninitialised memory, no definite leak.
pub(crate) fn fuzz_under_valgrind() -> Result {
    if Command::new("valgrind").arg("--version").output().is_err() {
        println!("xtask: installing valgrind");
        apt_install(&["valgrind"])?;
    }
    let runner = "valgrind --error-exitcode=9 --leak-check=full --errors-for-leak-kinds=definite \
                  --show-leak-kinds=definite --quiet";
    run(as_test_build(&mut cargo())
        .args(["test", "--release", "--quiet", "--test", "fuzz_api"])
        .args(["--test", "fuzz_api_fmi3"])
        // Each of its steps spends a whole call's work: minutes under valgrind.
        .args(["--", "--skip", "no_step_runs_away"])
        .env("CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER", runner)
        .env("CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER", runner)
        .env("FUZZ_SEQUENCES", "300")
        .env("FUZZ_LONG_STEPS", "0"))
}
