//! The C master of every platform (tests/platforms/master.c): the model description it
//! reads, the scenarios it runs, building it for this machine and running it over a
//! library. The platform tests (`abi_tests`), the page's benchmark (`web`) and
//! `cargo xtask instructions` all drive the FMU through it.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::setup::{root, run, Result};
use fmi_description::BaseType;

/// How a scenario's runs must agree with linux64's.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Agreement {
    /// Bit for bit: the integrator and model use only IEEE-exact operations and their own
    /// sines and cosines.
    Bits,
    /// The Reals within twice the error the FMU promises (10 × tolerance × max(1, |y|)),
    /// as two runs each that close to the solution are: Radau IIA's step-size control
    /// takes powers from the C library, whose last bits differ between platforms, so its
    /// steps, and the step counts, may too.
    Tolerance,
}

pub(crate) struct Scenario {
    pub(crate) name: &'static str,
    pub(crate) tolerance: f64,
    pub(crate) step: f64,
    pub(crate) stop: f64,
    /// (variable, value) set in initialisation mode.
    pub(crate) settings: &'static [(&'static str, f64)],
    pub(crate) agreement: Agreement,
}

pub(crate) const SCENARIOS: &[Scenario] = &[
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
    pub(crate) kind: char,
}

pub struct Description {
    pub guid: String,
    /// The FMI 3.0 description's instantiation token, when the master runs FMI 3.0 too.
    pub token: Option<String>,
    pub variables: BTreeMap<String, Variable>,
    /// The outputs, in the description's order.
    pub(crate) outputs: Vec<String>,
    /// The Enumerations' items: (type name, item name) → value.
    pub items: BTreeMap<(String, String), i64>,
}

/// The model description at `xml`, by the project's one reader of it
/// (`fmi-description`): the scalar variables by name with their kind, the outputs in order,
/// and the Enumerations' items by their declared type.
pub fn read_description(xml: &Path) -> Result<Description> {
    let text = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    let read = fmi_description::Description::parse(&text)
        .map_err(|e| format!("{}: {e}", xml.display()))?;
    let mut description = Description {
        guid: read.guid.clone(),
        token: None,
        variables: BTreeMap::new(),
        outputs: Vec::new(),
        items: BTreeMap::new(),
    };
    for v in &read.variables {
        let kind = match v.base_type {
            BaseType::Real => 'R',
            BaseType::Boolean => 'B',
            BaseType::Enumeration => 'E',
            BaseType::Integer => 'I',
            BaseType::String | BaseType::Unsupported => continue,
        };
        if v.causality == "output" {
            description.outputs.push(v.name.clone());
        }
        let declared = v.declared_type.clone().unwrap_or_default();
        for (item, value) in &v.items {
            description
                .items
                .insert((declared.clone(), item.clone()), *value);
        }
        let vr = v.value_reference;
        description
            .variables
            .insert(v.name.clone(), Variable { vr, kind });
    }
    if description.guid.is_empty() || description.outputs.is_empty() {
        return Err(format!("{}: no guid or no outputs", xml.display()));
    }
    Ok(description)
}

/// The instantiation token of an FMI 3.0 model description.
pub(crate) fn read_token(xml: &Path) -> Result<String> {
    let text = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    fmi_description::Description::parse(&text)
        .map(|read| read.guid)
        .map_err(|e| format!("{}: {e}", xml.display()))
}

/// The C master for this machine, in `dir` (also what `cargo xtask instructions` runs).
pub fn build_native_master(dir: &Path) -> Result<PathBuf> {
    let native = dir.join("master");
    compile_master(&mut Command::new("cc"), &native, &["-ldl"])?;
    Ok(native)
}

/// Compile tests/platforms/master.c with `compiler` (its own options given) and the shared
/// flags into `output`, linking `libraries`.
pub(crate) fn compile_master(compiler: &mut Command, output: &Path, libraries: &[&str]) -> Result {
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

/// A Linux path as Wine's Z: drive sees it.
pub(crate) fn windows_path(path: &Path) -> String {
    format!("Z:{}", path.display()).replace('/', "\\")
}

/// One run of a master: the recorded points, as text lines, and the loop's time.
pub(crate) fn run_master(
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
