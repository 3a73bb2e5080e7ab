//! `cargo xtask bench [--quick]`: the work-precision study (the Rust harness, the compiled
//! peers, the Python driver) into target/bench.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli::Parsed;
use crate::fmu;
use crate::setup::Result;
use crate::setup::*;

/// The benchmark harness, built in a target directory of its own: its peer crates unify
/// features of the build dependencies (fmi-sys's bindgen) differently, and in the shared
/// `target/release` that would rebuild the FMU's library and every test binary on the next
/// `cargo test`, changed or not.
pub(crate) fn build_bench_harness() -> Result<PathBuf> {
    let target = root().join("target/bench-build");
    run(cargo()
        .args(["build", "--release", "--package", "bench"])
        .env("CARGO_TARGET_DIR", &target))?;
    Ok(target.join("release/bench"))
}

/// The harness for the tests' smoke run, which judges no timing: built as a test build
/// ([`as_test_build`]) in a folder of its own.
pub(crate) fn build_bench_harness_for_tests() -> Result<PathBuf> {
    let target = root().join("target/bench-smoke");
    run(as_test_build(&mut cargo())
        .args(["build", "--release", "--quiet", "--package", "bench"])
        .env("CARGO_TARGET_DIR", &target))?;
    Ok(target.join("release/bench"))
}

/// The compiled peers: bench/compiled/peers.c (the C right-hand side, GSL's rk8pd and
/// CVODE) built against Debian's libgsl-dev and libsundials-dev into
/// target/bench/libpeers.so, and numbalsoda's DOP853 and LSODA libraries (built from
/// PyPI's source with gfortran, without numba). Returns the library and numbalsoda's
/// directory.
pub(crate) fn build_compiled_peers(python: &Path) -> Result<(PathBuf, PathBuf)> {
    let headers = [
        "/usr/include/gsl/gsl_odeiv2.h",
        "/usr/include/cvode/cvode.h",
    ];
    if !headers.iter().all(|h| Path::new(h).exists())
        || Command::new("gfortran").arg("--version").output().is_err()
    {
        println!("xtask: installing gfortran, libgsl-dev and libsundials-dev (the compiled peers)");
        apt_install(&["gfortran", "libgsl-dev", "libsundials-dev"])?;
    }
    let site = python_path(
        python,
        "import sysconfig; print(sysconfig.get_paths()['platlib'])",
    )?
    .join("numbalsoda");
    let pins = root().join("bench/requirements.txt");
    let stamp = site.join("requirements.installed");
    let wanted = fs::read_to_string(&pins).map_err(|e| format!("{}: {e}", pins.display()))?;
    if fs::read_to_string(&stamp).ok().as_deref() != Some(wanted.as_str()) {
        println!("xtask: building numbalsoda's DOP853 and LSODA (bench/requirements.txt)");
        run(Command::new(python)
            .args(["-m", "pip", "install", "--quiet", "--no-deps", "-r"])
            .arg(&pins))?;
        fs::write(&stamp, &wanted).map_err(|e| e.to_string())?;
    }
    let library = root().join("target/bench/libpeers.so");
    run(Command::new("cc")
        .args([
            "-O3", "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror", "-o",
        ])
        .arg(&library)
        .arg(root().join("bench/compiled/peers.c"))
        .args([
            "-lgsl",
            "-lgslcblas",
            "-lsundials_cvode",
            "-lsundials_nvecserial",
        ])
        .args(["-lsundials_sunlinsoldense", "-lsundials_sunmatrixdense"])
        .args(["-lsundials_sunnonlinsolfixedpoint", "-lm"]))?;
    Ok((library, site))
}

/// The work-precision study: the Rust harness (FMU through its C ABI, Rust crates, ns per
/// right-hand side), then the Python driver (reference, scipy, FMPy, table and plot).
pub(crate) fn job(parsed: &Parsed) -> Result {
    let quick = parsed.has("quick");
    let fmu = fmu::build_fmu(false)?.fmu;
    let python = ensure_venv(Packages::Tests)?;
    let program = build_bench_harness()?;
    let out = root().join("target/bench");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    let harness = out.join("harness.json");
    let quick_flag: &[&str] = if quick { &["--quick"] } else { &[] };
    // The reference at every communication point first: the harness measures against it.
    run(Command::new(&python)
        .arg(root().join("bench/bench.py"))
        .arg("reference")
        .arg(&out)
        .args(quick_flag))?;
    let (peers, numbalsoda) = build_compiled_peers(&python)?;
    let mut command = Command::new(&program);
    command
        .arg(&fmu)
        .arg(&harness)
        .arg("--reference")
        .arg(&out)
        .arg("--compiled")
        .arg(&peers)
        .arg("--numbalsoda")
        .arg(&numbalsoda)
        .args(quick_flag);
    run(&mut command)?;
    let mut driver = Command::new(python);
    driver
        .arg(root().join("bench/bench.py"))
        .arg(&harness)
        .arg(&fmu)
        .arg(&out);
    if quick {
        driver.arg("--quick");
    }
    run(&mut driver)
}
