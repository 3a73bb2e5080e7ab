//! The artefacts several jobs build and use, below the jobs that use them (none of which
//! imports another for them; `cargo xtask tidy` checks it): the compiled DC motor, flywheel
//! load and bouncing-ball FMUs, the sweep's wheel installed in the venv, and the FMI 2.0 and
//! 3.0 headers that C code here compiles against.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::setup::*;

/// Build and pack the motor; returns the archive.
pub(crate) fn build_motor() -> Result<PathBuf> {
    build_compiled_fmu("DcMotor", "examples/dc_motor/native", "dc_motor.c")
}

/// Build and pack the bouncing ball (FMI 3.0, events); returns the archive.
pub(crate) fn build_bouncing_ball() -> Result<PathBuf> {
    build_compiled_fmu3(
        "BouncingBall",
        "examples/bouncing_ball/native",
        "bouncing_ball.c",
    )
}

/// Build and pack the flywheel load; returns the archive.
pub(crate) fn build_flywheel_load() -> Result<PathBuf> {
    build_compiled_fmu(
        "FlywheelLoad",
        "examples/flywheel_load/native",
        "flywheel_load.c",
    )
}

/// The motor driving the mechanism as an SSP file, `target/fmu/MotorDrivenMechanism.ssp`:
/// `examples/dc_motor/ssp/`'s system structure and load parameters with the two packed
/// FMUs (the worked SSP sweep runs it).
pub(crate) fn build_motor_ssp(mechanism: &Path, motor: &Path) -> Result<PathBuf> {
    let source = root().join("examples/dc_motor/ssp");
    let ssp = root().join("target/fmu/MotorDrivenMechanism.ssp");
    crate::fmu::pack(
        &ssp,
        &[
            (
                "SystemStructure.ssd".to_string(),
                source.join("SystemStructure.ssd"),
            ),
            (
                "resources/CyclicMechanism.fmu".to_string(),
                mechanism.to_path_buf(),
            ),
            ("resources/DcMotor.fmu".to_string(), motor.to_path_buf()),
            ("resources/load.ssv".to_string(), source.join("load.ssv")),
        ],
    )?;
    Ok(ssp)
}

/// One model of `examples/` in C, linked with the co-simulation functions they share
/// (`examples/native/cosim.c`, FMI 2.0), packed as `target/fmu/{identifier}.fmu`.
fn build_compiled_fmu(identifier: &str, source: &str, model: &str) -> Result<PathBuf> {
    let shared = root().join("examples/native/cosim.c");
    let files = [model.into(), shared];
    compile_and_pack((identifier, identifier), source, &files, &fmi2_standard()?)
}

/// An FMI 3.0 model of `examples/` in C, all in one file, packed as
/// `target/fmu/{identifier}.fmu`.
fn build_compiled_fmu3(identifier: &str, source: &str, model: &str) -> Result<PathBuf> {
    compile_and_pack(
        (identifier, identifier),
        source,
        &[model.into()],
        &fmi3_standard()?,
    )
}

fn fmi2_standard() -> Result<Standard> {
    Ok(Standard {
        headers: fmi_headers("2")?,
        platform: "linux64",
    })
}

fn fmi3_standard() -> Result<Standard> {
    Ok(Standard {
        headers: fmi_headers("3")?,
        platform: "x86_64-linux",
    })
}

/// The bouncing ball's Model Exchange FMUs, FMI 2.0 and 3.0 (their masters integrate it):
/// `target/fmu/BouncingBallME.fmu` and `BouncingBallME-fmi3.fmu`.
pub(crate) fn build_bouncing_ball_me() -> Result<(PathBuf, PathBuf)> {
    let source = "examples/bouncing_ball/model_exchange";
    Ok((
        compile_and_pack(
            ("BouncingBallME", "BouncingBallME"),
            &format!("{source}/fmi2"),
            &["ball.c".into()],
            &fmi2_standard()?,
        )?,
        compile_and_pack(
            ("BouncingBallME", "BouncingBallME-fmi3"),
            &format!("{source}/fmi3"),
            &["ball.c".into(), "unsupported.c".into()],
            &fmi3_standard()?,
        )?,
    ))
}

/// What a compiled FMU's version decides: the headers it is built against and the folder
/// of `binaries/` its library goes in.
struct Standard {
    headers: PathBuf,
    platform: &'static str,
}

/// The C files `files` (relative to `source`, or absolute) built against glibc 2.17 with
/// zig and packed with `source`'s `modelDescription.xml` as `target/fmu/{archive}.fmu`, the
/// library named for the model's `identifier`.
fn compile_and_pack(
    (identifier, archive): (&str, &str),
    source: &str,
    files: &[PathBuf],
    standard: &Standard,
) -> Result<PathBuf> {
    let source = root().join(source);
    let dir = root().join("target/compiled-fmus");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let fmu = root().join(format!("target/fmu/{archive}.fmu"));
    // The same sources and description pack the same archive: a later call reuses it.
    let mut inputs: Vec<PathBuf> = files.iter().map(|f| source.join(f)).collect();
    inputs.push(source.join("modelDescription.xml"));
    inputs.extend(files_below(&root().join("examples/native"))?);
    let key = fingerprint(&inputs)?;
    let stamp = dir.join(format!("{archive}.fingerprint"));
    if fmu.exists() && fs::read_to_string(&stamp).is_ok_and(|built| built == key) {
        return Ok(fmu);
    }
    let zig = crate::platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
    let library = dir.join(format!("{archive}.so"));
    run(zig
        .cc("x86_64-linux-gnu.2.17")
        .args(["-O2", "-std=c99", "-shared", "-fPIC", "-fvisibility=hidden"])
        .args(["-Wall", "-Wextra", "-Wno-unused-parameter", "-Werror", "-I"])
        .arg(&standard.headers)
        .arg("-I")
        .arg(root().join("examples/native"))
        .arg("-o")
        .arg(&library)
        .args(files.iter().map(|f| source.join(f)))
        .arg("-lm"))?;
    check_glibc(&library)?;
    crate::fmu::pack(
        &fmu,
        &[
            (
                "modelDescription.xml".to_string(),
                source.join("modelDescription.xml"),
            ),
            (
                format!("binaries/{}/{identifier}.so", standard.platform),
                library,
            ),
        ],
    )?;
    fs::write(&stamp, key).map_err(|e| format!("{}: {e}", stamp.display()))?;
    Ok(fmu)
}

/// The fmusweep wheel, built by maturin from `python/pyproject.toml`: the Python package
/// and the native runner, built with zig against glibc 2.17 (as the FMU) and tagged
/// manylinux_2_17, so that workers on older Linux install it too.
pub(crate) fn build_wheel() -> Result<PathBuf> {
    ensure_libclang()?;
    let python = ensure_venv(Packages::Tests)?;
    let out = root().join("target/wheels");
    let key = fingerprint(&wheel_inputs(&root())?)?;
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
    // A folder of its own: the FMU's portable build writes the same target triple with
    // other flags, and sharing one folder rebuilt every dependency of each, by turns.
    let build = root().join("target/wheel-build");
    println!("xtask: building the fmusweep wheel (maturin, the runner against glibc 2.17)");
    crate::setup::run(
        Command::new(&maturin)
            .current_dir(root().join("python"))
            .args(["build", "--release", "--zig", "--compatibility"])
            .arg(format!("manylinux{}", MANYLINUX_FOR_BASELINE))
            .arg("--out")
            .arg(&out)
            .env("PATH", path_with_venv(&python)?)
            .env("CARGO_TARGET_DIR", &build)
            // As for cargo-zigbuild: bindgen gets the C headers from here, not from zig.
            .env("BINDGEN_EXTRA_CLANG_ARGS", c_header_args()?),
    )?;
    check_glibc(&build.join("x86_64-unknown-linux-gnu/release/fmu-runner"))?;
    let wheel =
        wheel_in(&out).ok_or_else(|| format!("maturin wrote no wheel to {}", out.display()))?;
    fs::write(&stamp, key).map_err(|e| format!("{}: {e}", stamp.display()))?;
    Ok(wheel)
}

/// What the wheel is made of, in the repository at `root`: the package, the runner's crate
/// with every crate of the repository it depends on, and the lock file. With the same
/// bytes of each, the wheel built from them last is the one.
pub(crate) fn wheel_inputs(root: &Path) -> Result<Vec<PathBuf>> {
    let mut inputs = files_below(&root.join("python"))?;
    for krate in local_crates(&root.join("runner"))? {
        inputs.extend(files_below(&krate)?);
    }
    inputs.push(root.join("Cargo.lock"));
    Ok(inputs)
}

/// `krate` and every crate of this repository it depends on, directly or not: the
/// `path = "…"` dependencies of their manifests.
pub(crate) fn local_crates(krate: &Path) -> Result<Vec<PathBuf>> {
    let mut found = vec![krate.to_path_buf()];
    let mut next = 0;
    while next < found.len() {
        let manifest = found[next].join("Cargo.toml");
        let text =
            fs::read_to_string(&manifest).map_err(|e| format!("{}: {e}", manifest.display()))?;
        for line in text.lines().filter(|l| !l.trim_start().starts_with('#')) {
            // A dependency's inline table, `name = { path = "…", … }` (a `[lib]` or
            // `[[bin]]` table's `path` names a file, not a crate).
            let Some(rest) = line
                .split_once('{')
                .and_then(|(_, table)| table.split("path = \"").nth(1))
            else {
                continue;
            };
            let relative = rest.split('"').next().unwrap_or_default();
            let dependency = found[next]
                .join(relative)
                .canonicalize()
                .map_err(|e| format!("{}: {relative}: {e}", manifest.display()))?;
            if !found.contains(&dependency) {
                found.push(dependency);
            }
        }
        next += 1;
    }
    Ok(found)
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

/// The FMI headers of `version` ("2" or "3") that fmi-sys ships (fetched into cargo's
/// registry by the build).
pub(crate) fn fmi_headers(version: &str) -> Result<PathBuf> {
    let home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")))
        .ok_or("neither CARGO_HOME nor HOME is set")?;
    fs::read_dir(home.join("registry/src"))
        .into_iter()
        .flat_map(|d| d.flatten())
        .map(|index| {
            index
                .path()
                .join(format!("fmi-sys-0.6.0/fmi-standard{version}/headers"))
        })
        .find(|headers| headers.join(format!("fmi{version}Functions.h")).exists())
        .ok_or_else(|| {
            format!("fmi-sys 0.6.0's FMI {version}.0 headers not found in cargo's registry")
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Copy what the wheel may be made of into `scratch`: the package and the crates.
    fn copy_tree(from: &Path, to: &Path) {
        for file in files_below(from).expect("a readable tree") {
            let target = to.join(file.strip_prefix(from).expect("below"));
            fs::create_dir_all(target.parent().expect("a folder")).expect("writable");
            fs::copy(&file, &target).expect("copied");
        }
    }

    #[test]
    fn a_change_to_any_crate_the_runner_is_built_from_rebuilds_the_wheel() {
        let scratch = std::env::temp_dir().join(format!("wheel-inputs-{}", std::process::id()));
        for folder in ["python", "runner", "integrators", "fmi-description"] {
            copy_tree(&root().join(folder), &scratch.join(folder));
        }
        fs::copy(root().join("Cargo.lock"), scratch.join("Cargo.lock")).expect("copied");
        fs::create_dir_all(scratch.join("docs")).expect("writable");
        let key = || fingerprint(&wheel_inputs(&scratch).expect("inputs")).expect("read");
        let before = key();
        // A document is not part of the wheel.
        fs::write(scratch.join("docs/notes.md"), "a note").expect("writable");
        assert_eq!(key(), before);
        // A source of the integrators, which the runner depends on, is.
        let source = files_below(&scratch.join("integrators/src")).expect("sources")[0].clone();
        let mut text = fs::read(&source).expect("readable");
        text.extend_from_slice(b"\n// changed\n");
        fs::write(&source, text).expect("writable");
        let after = key();
        fs::remove_dir_all(&scratch).expect("removed");
        assert_ne!(
            after,
            before,
            "{} changed and the wheel would be kept",
            source.display()
        );
    }
}
