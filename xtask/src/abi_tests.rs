//! The FMU's binaries tested on the other platforms' ABIs, on this Linux machine: the
//! crate's Rust tests built for Windows and run under Wine, and one C master
//! (tests/platforms/master.c) built for linux64, win64 (MinGW, run under Wine) and aarch64
//! Linux (zig cc, run under QEMU) that drives each binary through the same scenarios and
//! records every output at every communication point; the page's WebAssembly module
//! (web/) runs the same scenarios under Node through web/node_master.mjs, which takes the
//! C master's command line and writes its output. The runs must agree with linux64's bit
//! for bit, or the test names the first value that differs and by how much.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::platforms::{self, Target, Zig, MINGW_GCC};
use crate::setup::{root, run};
use crate::Result;

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

/// How a scenario's runs must agree with linux64's.
#[derive(Clone, Copy, PartialEq)]
enum Agreement {
    /// Bit for bit: the integrator and model use only IEEE-exact operations and their own
    /// sines and cosines.
    Bits,
    /// The Reals within twice the error the FMU promises (10 × tolerance × max(1, |y|)),
    /// as two runs each that close to the solution are: Radau IIA's step-size control
    /// takes powers from the C library, whose last bits differ between platforms, so its
    /// steps, and the step counts, may too.
    Tolerance,
}

struct Scenario {
    name: &'static str,
    tolerance: f64,
    step: f64,
    stop: f64,
    /// (variable, value) set in initialisation mode.
    settings: &'static [(&'static str, f64)],
    agreement: Agreement,
}

const SCENARIOS: &[Scenario] = &[
    Scenario {
        name: "paper case 1",
        tolerance: 1e-10,
        step: 0.01,
        stop: 10.0,
        settings: &[],
        agreement: Agreement::Bits,
    },
    Scenario {
        name: "free run",
        tolerance: 1e-8,
        step: 0.1,
        stop: 100.0,
        settings: &[
            ("builtin_laws", 0.0),
            ("omega2_0", 6.0),
            ("twist12_0", 0.2),
            ("twist34_0", -0.1),
            ("omega4_0", -1.0),
        ],
        agreement: Agreement::Bits,
    },
    Scenario {
        name: "paper case 2, implicit solver",
        tolerance: 1e-6,
        step: 0.01,
        stop: 10.0,
        settings: &[("k34", 40.0), ("solver", 3.0)],
        agreement: Agreement::Tolerance,
    },
];

/// A variable of the model description: value reference and type element.
#[derive(Clone)]
pub struct Variable {
    pub vr: u32,
    kind: char,
}

pub struct Description {
    pub guid: String,
    /// The FMI 3.0 description's instantiation token, when the master runs FMI 3.0 too.
    pub token: Option<String>,
    pub variables: BTreeMap<String, Variable>,
    /// The outputs, in the description's order.
    outputs: Vec<String>,
}

pub fn read_description(xml: &Path) -> Result<Description> {
    use quick_xml::events::Event;
    let text = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    let mut reader = quick_xml::Reader::from_str(&text);
    let mut description = Description {
        guid: String::new(),
        token: None,
        variables: BTreeMap::new(),
        outputs: Vec::new(),
    };
    let mut current: Option<(String, u32, bool)> = None;
    loop {
        let event = reader
            .read_event()
            .map_err(|e| format!("{}: {e}", xml.display()))?;
        let element = match &event {
            Event::Start(e) | Event::Empty(e) => e,
            Event::Eof => break,
            _ => continue,
        };
        let attribute = |name: &str| -> Option<String> {
            element
                .try_get_attribute(name)
                .ok()
                .flatten()
                .and_then(|a| a.unescape_value().ok().map(|v| v.into_owned()))
        };
        match element.name().as_ref() {
            b"fmiModelDescription" => description.guid = attribute("guid").unwrap_or_default(),
            b"ScalarVariable" => {
                let name = attribute("name").ok_or("a ScalarVariable without a name")?;
                let vr = attribute("valueReference")
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| format!("{name}: no valid valueReference"))?;
                let output = attribute("causality").as_deref() == Some("output");
                current = Some((name, vr, output));
            }
            tag @ (b"Real" | b"Integer" | b"Enumeration" | b"Boolean") => {
                if let Some((name, vr, output)) = current.take() {
                    let kind = match tag {
                        b"Real" => 'R',
                        b"Boolean" => 'B',
                        b"Enumeration" => 'E',
                        _ => 'I',
                    };
                    if output {
                        description.outputs.push(name.clone());
                    }
                    description.variables.insert(name, Variable { vr, kind });
                }
            }
            _ => {}
        }
    }
    if description.guid.is_empty() || description.outputs.is_empty() {
        return Err(format!("{}: no guid or no outputs", xml.display()));
    }
    Ok(description)
}

/// The instantiation token of an FMI 3.0 model description.
fn read_token(xml: &Path) -> Result<String> {
    let text = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    text.split("instantiationToken=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .map(str::to_string)
        .ok_or_else(|| format!("{}: no instantiationToken", xml.display()))
}

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

/// The C master for this machine, in `dir` (also what `cargo xtask instructions` runs).
pub fn build_native_master(dir: &Path) -> Result<PathBuf> {
    let native = dir.join("master");
    compile_master(&mut Command::new("cc"), &native, &["-ldl"])?;
    Ok(native)
}

/// Compile tests/platforms/master.c with `compiler` (its own options given) and the shared
/// flags into `output`, linking `libraries`.
fn compile_master(compiler: &mut Command, output: &Path, libraries: &[&str]) -> Result {
    let fmi2 = crate::builders::fmi_headers("2")?;
    let fmi3 = fmi2
        .parent()
        .and_then(Path::parent)
        .map(|fmi_sys| fmi_sys.join("fmi-standard3/headers"))
        .ok_or("no folder above fmi-sys's FMI 2.0 headers")?;
    run(compiler
        .args(["-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(fmi2)
        .arg("-I")
        .arg(fmi3)
        .arg("-o")
        .arg(output)
        .arg(root().join("tests/platforms/master.c"))
        .args(libraries))
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

/// A Linux path as Wine's Z: drive sees it.
fn windows_path(path: &Path) -> String {
    format!("Z:{}", path.display()).replace('/', "\\")
}

/// One run of a master: the recorded points, as text lines, and the loop's time.
fn run_master(
    how: &mut Command,
    library: &Path,
    output: &Path,
    scenario: &Scenario,
    description: &Description,
    (windows, fmi3): (bool, bool),
) -> Result<(Vec<String>, f64)> {
    let path = |p: &Path| {
        if windows {
            windows_path(p)
        } else {
            p.display().to_string()
        }
    };
    let instance_key = match (&description.token, fmi3) {
        (Some(token), true) => format!("fmi3:{token}"),
        (None, true) => return Err("an FMI 3.0 run without an instantiation token".into()),
        (_, false) => description.guid.clone(),
    };
    how.arg(path(library))
        .arg(instance_key)
        .arg(format!("{:e}", scenario.tolerance))
        .arg(format!("{}", scenario.step))
        .arg(format!("{}", scenario.stop))
        .arg(path(output));
    for (name, value) in scenario.settings {
        let v = &description.variables[*name];
        let value = if v.kind == 'R' {
            format!("{value:e}")
        } else {
            format!("{}", *value as i64)
        };
        how.arg(format!("{}:{}={value}", v.kind, v.vr));
    }
    how.arg("--");
    for name in &description.outputs {
        let v = &description.variables[name];
        how.arg(format!("{}:{}", v.kind, v.vr));
    }
    let shown = format!("{how:?}");
    let result = how
        .output()
        .map_err(|e| format!("cannot run {shown}: {e}"))?;
    let stderr = String::from_utf8_lossy(&result.stderr);
    if !result.status.success() {
        return Err(format!("{shown} failed ({}): {stderr}", result.status));
    }
    let seconds = stderr
        .lines()
        .find_map(|l| l.strip_prefix("loop_seconds="))
        .and_then(|s| s.trim().parse().ok())
        .ok_or_else(|| format!("{shown}: no loop time in {stderr}"))?;
    let text = fs::read_to_string(output).map_err(|e| format!("{}: {e}", output.display()))?;
    Ok((text.lines().map(str::to_string).collect(), seconds))
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
    let node_program = crate::web::ensure_node()?;
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

/// The stepping loop's seconds of paper case 1 (the first scenario) run by `how` over
/// `library`, the fastest of `repeats` runs, for the benchmarks; the recording in `dir`.
pub fn paper_case_seconds(
    how: impl Fn() -> Command,
    library: &Path,
    description: &Description,
    dir: &Path,
    repeats: usize,
) -> Result<f64> {
    let scenario = &SCENARIOS[0];
    let output = dir.join("paper-case-1.txt");
    let mut fastest = f64::INFINITY;
    for _ in 0..repeats {
        let mut command = how();
        let (_, seconds) = run_master(
            &mut command,
            library,
            &output,
            scenario,
            description,
            (false, false),
        )?;
        fastest = fastest.min(seconds);
    }
    Ok(fastest)
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
    let win64 = binaries.join(format!("win64/{}.dll", crate::MODEL_IDENTIFIER));
    let aarch64 = binaries.join(format!("aarch64-linux/{}.so", crate::MODEL_IDENTIFIER));
    rust_tests_under_wine(zig)?;
    let wasm32 = crate::web::build_wasm()?;
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
    use super::*;

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
