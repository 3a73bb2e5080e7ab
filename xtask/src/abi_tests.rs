//! The FMU's binaries tested on the other platforms' ABIs, on this Linux machine: the
//! crate's Rust tests built for Windows and run under Wine, and one C master
//! (tests/platforms/master.c) built for linux64, win64 (MinGW, run under Wine) and aarch64
//! Linux (zig cc, run under QEMU) that drives each binary through the same scenarios and
//! records every output at every communication point; the page's WebAssembly module
//! (web/) runs the same scenarios under Node through web/node_master.mjs, which takes the
//! C master's command line and writes its output. The runs must agree with linux64's bit
//! for bit, or the test names the first value that differs and by how much.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::master::{
    build_native_master, compile_master, read_description, read_token, run_master, windows_path,
    Agreement, Description, SCENARIOS,
};
use crate::platforms::{self, Target, Zig, MINGW_GCC};
use crate::setup::Result;
use crate::setup::{root, run};

const WINE: &str = "/usr/lib/wine/wine64";
const QEMU: &str = "/usr/bin/qemu-aarch64-static";
/// Where libc6-arm64-cross puts aarch64's glibc and its loader.
const AARCH64_SYSROOT: &str = "/usr/aarch64-linux-gnu";

/// The crate's tests that need nothing but the library (no Python, no files of the
/// checkout), run as Windows programs. The golden outputs are not among them: they hold
/// linux64's bits, and under Wine the free run's differed from its first second on (the
/// C library's functions, which the model calls in places, differ in their last bits);
/// the C master below compares the platforms' runs instead.
const RUST_TESTS_ON_WINDOWS: &[&str] = &[
    "paper_cases",
    "fuzz_api",
    "state_validation",
    "state_round_trip",
    "parallel_instances",
    "tiny_steps",
    "stiff",
    "isa",
    "no_allocation",
    "integrators",
];

/// Where the tests' builds and runs go.
fn work_dir() -> PathBuf {
    root().join("target/platforms")
}

/// The C master for each platform: (native, win64, aarch64).
fn build_masters(zig: &Zig) -> Result<(PathBuf, PathBuf, PathBuf)> {
    let dir = work_dir();
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let native = build_native_master(&dir)?;
    let windows = dir.join("master.exe");
    compile_master(Command::new(MINGW_GCC).arg("-static"), &windows, &[])?;
    let aarch64 = dir.join("master-aarch64");
    compile_master(&mut zig.cc("aarch64-linux-gnu.2.17"), &aarch64, &["-ldl"])?;
    Ok((native, windows, aarch64))
}

/// Wine's settings: a prefix kept with the cross builds (its creation takes a while), no
/// debug output, and the folder of the `bcryptprimitives.dll` stand-in on its DLL path.
fn wine_env(command: &mut Command) -> Result<&mut Command> {
    let dlls = work_dir().join("wine-dlls");
    let standin = dlls.join("bcryptprimitives.dll");
    if !standin.exists() {
        fs::create_dir_all(&dlls).map_err(|e| e.to_string())?;
        run(Command::new(MINGW_GCC)
            .args(["-O2", "-shared", "-o"])
            .arg(&standin)
            .arg(root().join("tests/platforms/bcryptprimitives.c"))
            .arg("-ladvapi32"))?;
    }
    Ok(command
        .env(
            "WINEPREFIX",
            platforms::cross_target_dir().join("wineprefix"),
        )
        .env("WINEDEBUG", "-all")
        .env("WINEPATH", windows_path(&dlls)))
}

/// The differences between two recordings, as (values compared, values that differ, the
/// largest difference of a Real relative to max(1, |linux64's value|), the first
/// difference named). A line of either with the wrong number of values is an error.
fn compare(
    reference: &[String],
    other: &[String],
    description: &Description,
) -> Result<(usize, usize, f64, Option<String>)> {
    if reference.len() != other.len() {
        return Err(format!(
            "{} communication points against linux64's {}",
            other.len(),
            reference.len()
        ));
    }
    let (mut compared, mut differing, mut largest, mut first) = (0, 0, 0.0f64, None);
    for (a, b) in reference.iter().zip(other) {
        let (a, b) = (values(a, description)?, values(b, description)?);
        let time = a[0];
        for (k, name) in description.outputs.iter().enumerate() {
            let (x, y) = (a[k + 1], b[k + 1]);
            compared += 1;
            if x.to_bits() == y.to_bits() {
                continue;
            }
            differing += 1;
            if description.variables[name].kind == 'R' {
                largest = largest.max((x - y).abs() / x.abs().max(1.0));
            }
            first.get_or_insert_with(|| {
                format!(
                    "{name} at t = {time}: linux64 {x:e}, here {y:e} (difference {:e})",
                    y - x
                )
            });
        }
    }
    Ok((compared, differing, largest, first))
}

/// A recorded line's time and values: Reals from their IEEE bits, Integers as written.
fn values(line: &str, description: &Description) -> Result<Vec<f64>> {
    let fields: Vec<&str> = line.split(' ').collect();
    if fields.len() != description.outputs.len() + 1 {
        return Err(format!(
            "a recorded point has {} values, not {}: {line:?}",
            fields.len(),
            description.outputs.len() + 1
        ));
    }
    let kinds = std::iter::once('R').chain(
        description
            .outputs
            .iter()
            .map(|name| description.variables[name].kind),
    );
    fields
        .iter()
        .zip(kinds)
        .map(|(field, kind)| {
            let parsed = if kind == 'R' {
                u64::from_str_radix(field, 16).map(f64::from_bits).ok()
            } else {
                field.parse::<i64>().map(|n| n as f64).ok()
            };
            parsed.ok_or_else(|| format!("{field:?} in a recorded point is not a value"))
        })
        .collect()
}

/// Run every scenario through the linux64, win64 and aarch64 binaries and compare them
/// with linux64's. Returns the report's lines.
fn compare_platforms(
    description: &Description,
    linux64: &Path,
    (win64, aarch64, wasm32): (&Path, &Path, &Path),
    zig: &Zig,
) -> Result<Vec<String>> {
    let (native, windows, arm) = build_masters(zig)?;
    let node_program = crate::page::ensure_node()?;
    let dir = work_dir();
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for (index, scenario) in SCENARIOS.iter().enumerate() {
        let out = |platform: &str| dir.join(format!("scenario{index}-{platform}.txt"));
        let (reference, linux_seconds) = run_master(
            &mut Command::new(&native),
            linux64,
            &out("linux64"),
            scenario,
            description,
            (false, false),
        )?;
        let wine = || -> Result<Command> {
            let mut wine = Command::new(WINE);
            wine_env(&mut wine)?.arg(windows_path(&windows));
            Ok(wine)
        };
        let qemu = || {
            let mut qemu = Command::new(QEMU);
            qemu.args(["-L", AARCH64_SYSROOT]).arg(&arm);
            qemu
        };
        let mut node = Command::new(&node_program);
        node.arg(root().join("web/node_master.mjs"));
        // Each binary through FMI 2.0 and FMI 3.0, all against linux64's FMI 2.0 run.
        let runs = [
            ("win64 under Wine", wine()?, win64, (true, false)),
            ("aarch64 under QEMU", qemu(), aarch64, (false, false)),
            (
                "linux64, FMI 3.0",
                Command::new(&native),
                linux64,
                (false, true),
            ),
            ("win64 under Wine, FMI 3.0", wine()?, win64, (true, true)),
            (
                "aarch64 under QEMU, FMI 3.0",
                qemu(),
                aarch64,
                (false, true),
            ),
            // The page's module: the plant and driver the FMU steps, without FMI.
            ("wasm32 under Node", node, wasm32, (false, false)),
        ];
        for (platform, mut command, library, version) in runs {
            let file = out(&platform.replace([' ', ','], "-"));
            let (recorded, seconds) =
                run_master(&mut command, library, &file, scenario, description, version)?;
            let (compared, differing, largest, first) = compare(&reference, &recorded, description)
                .map_err(|e| format!("{} on {platform}: {e}", scenario.name))?;
            report.push(format!(
                "{}, {platform}: {compared} values at {} points compared with linux64's, \
                 {differing} differ (largest relative difference of a Real {largest:e}); stepping \
                 loop {:.3} ms against linux64's {:.3} ms",
                scenario.name,
                reference.len(),
                seconds * 1e3,
                linux_seconds * 1e3
            ));
            let bound = 20.0 * scenario.tolerance;
            let failed = match scenario.agreement {
                Agreement::Bits => differing > 0,
                Agreement::Tolerance => largest > bound,
            };
            if failed {
                failures.push(format!(
                    "{} on {platform}: {differing} of {compared} values differ from linux64's \
                     (allowed: {}); first: {}",
                    scenario.name,
                    if scenario.agreement == Agreement::Bits {
                        "none".to_string()
                    } else {
                        format!("relative differences up to {bound:e}")
                    },
                    first.unwrap_or_default()
                ));
            }
        }
    }
    if !failures.is_empty() {
        return Err(failures.join("\n"));
    }
    Ok(report)
}

/// The crate's Rust tests built for Windows and run under Wine as cargo's runner.
fn rust_tests_under_wine(zig: &Zig) -> Result {
    let mut command = platforms::cross_cargo(Target::Win64, "test", zig)?;
    crate::setup::as_test_build(&mut command);
    command.args(["--package", "cyclic-mechanism", "--lib"]);
    for test in RUST_TESTS_ON_WINDOWS {
        command.args(["--test", test]);
    }
    command.env("CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUNNER", WINE);
    wine_env(&mut command)?;
    println!("xtask: the Rust tests built for Windows, run under Wine");
    run(&mut command)
}

/// Everything above: the report goes to `target/test-reports/platforms.md` with the build
/// lines of `builds`.
pub fn test(
    description_xml: &Path,
    linux64: &Path,
    binaries: &Path,
    builds: &[String],
    zig: &Zig,
) -> Result {
    platforms::ensure_packages(platforms::RUN_PACKAGES)?;
    let mut description = read_description(description_xml)?;
    let fmi3_xml = description_xml
        .with_file_name("fmi3")
        .join("modelDescription.xml");
    description.token = Some(read_token(&fmi3_xml)?);
    let win64 = binaries.join(format!("win64/{}.dll", crate::setup::MODEL_IDENTIFIER));
    let aarch64 = binaries.join(format!(
        "aarch64-linux/{}.so",
        crate::setup::MODEL_IDENTIFIER
    ));
    rust_tests_under_wine(zig)?;
    let wasm32 = crate::page::build_wasm()?;
    let comparisons = compare_platforms(&description, linux64, (&win64, &aarch64, &wasm32), zig)?;
    let reports = root().join("target/test-reports");
    fs::create_dir_all(&reports).map_err(|e| e.to_string())?;
    let mut text = String::from(
        "# Platforms: the binaries' checks and the runs compared with linux64\n\n\
         Written by `cargo xtask test`.\n\n## Binaries\n\n",
    );
    for line in builds {
        text += &format!("- {line}\n");
    }
    text += "\n## The C master's runs\n\n";
    for line in &comparisons {
        println!("xtask: {line}");
        text += &format!("- {line}\n");
    }
    let file = reports.join("platforms.md");
    fs::write(&file, text).map_err(|e| format!("{}: {e}", file.display()))?;
    println!("xtask: platform report in {}", file.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::master::Variable;

    fn description() -> Description {
        let variables = BTreeMap::from([
            ("x".to_string(), Variable { vr: 1, kind: 'R' }),
            ("n".to_string(), Variable { vr: 2, kind: 'I' }),
        ]);
        Description {
            guid: "{g}".into(),
            token: None,
            variables,
            outputs: vec!["x".into(), "n".into()],
            items: BTreeMap::new(),
        }
    }

    fn line(t: f64, x: f64, n: i32) -> String {
        format!("{:016x} {:016x} {n}", t.to_bits(), x.to_bits())
    }

    /// Equal recordings agree; a Real one ulp off and an Integer off are both counted,
    /// the Real's relative difference measured; a malformed line is an error, not a match.
    #[test]
    fn recordings_are_compared_value_by_value() {
        let d = description();
        let reference = [line(0.0, 1.5, 3), line(0.1, 2.0, 4)];
        let (compared, differing, largest, first) = compare(&reference, &reference, &d).unwrap();
        assert_eq!((compared, differing, largest, first), (4, 0, 0.0, None));
        let off = [
            line(0.0, 1.5, 3),
            line(0.1, f64::from_bits(2f64.to_bits() + 1), 5),
        ];
        let (_, differing, largest, first) = compare(&reference, &off, &d).unwrap();
        assert_eq!(differing, 2);
        assert_eq!(largest, f64::EPSILON);
        assert!(first.unwrap().starts_with("x at t = 0.1"));
        let short = [
            line(0.0, 1.5, 3),
            "3fb999999999999a 4000000000000000".to_string(),
        ];
        assert!(compare(&reference, &short, &d).is_err());
        assert!(compare(&reference, &reference[..1], &d).is_err());
    }
}
