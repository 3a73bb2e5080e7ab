//! `cargo xtask instructions`: the instructions one communication point costs, counted by
//! valgrind's callgrind (a count, not a time: the same for the same binary and inputs,
//! whatever else the machine runs). The C master of the platform tests runs paper case 1
//! for 10 s at H = 1 ms reading ten Real outputs at every point; only the instructions
//! inside fmi2DoStep and fmi2GetReal (and what they call) are counted, and divided by the
//! number of points. Each build is counted with no sensitivity slot set, and with two and
//! with five slots carrying parameter sensitivities, so that what the slots cost, and that
//! a run without them pays nothing, is measured. The report goes to
//! `docs/bench/instructions.md`.

use std::fs;
use std::path::Path;
use std::process::Command;

use crate::master::{read_description, Description};
use crate::setup::Result;
use crate::setup::{apt_install, output_of, root};

const OUTPUTS: [&str; 10] = [
    "phi1",
    "phi2",
    "phi3",
    "phi4",
    "omega1",
    "omega2",
    "omega3",
    "omega4",
    "rod_force",
    "energy",
];
const STEP: f64 = 1e-3;
const STOP: f64 = 10.0;
const TOLERANCE: f64 = 1e-8;
/// The slot sets counted: none, the worked fit's two parameters, and all five slots.
const SLOT_SETS: [&[&str]; 3] = [&[], &["k34", "d34"], &["J1", "k12", "k34", "d12", "d34"]];

/// The master's settings that put `parameters` into sensitivity slots 1, 2, …: each slot's
/// Enumeration set to the item's value.
fn slot_settings(description: &Description, parameters: &[&str]) -> Result<Vec<String>> {
    parameters
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let item = ("SensitivityParameter".to_string(), name.to_string());
            let value = description
                .items
                .get(&item)
                .ok_or_else(|| format!("the description has no sensitivity item {name}"))?;
            Ok(format!(
                "E:{}={value}",
                vr_of(description, &format!("sensitivity_{}.parameter", i + 1))?
            ))
        })
        .collect()
}

/// The description's GUID and the value references of [`OUTPUTS`].
fn references(description: &Description) -> Result<Vec<u32>> {
    OUTPUTS
        .iter()
        .map(|name| vr_of(description, name))
        .collect()
}

/// The value reference of the variable `name`.
fn vr_of(description: &Description, name: &str) -> Result<u32> {
    description
        .variables
        .get(name)
        .map(|v| v.vr)
        .ok_or_else(|| format!("the description has no variable {name}"))
}

/// Instructions counted inside the stepping and reading functions.
fn count(
    master: &Path,
    library: &Path,
    guid: &str,
    (settings, refs): (&[String], &[u32]),
    dir: &Path,
) -> Result<u64> {
    let out = dir.join("callgrind.out");
    let mut command = Command::new("valgrind");
    command
        .args(["--tool=callgrind", "--collect-atstart=no"])
        .arg("--toggle-collect=fmi2DoStep")
        .arg("--toggle-collect=fmi2GetReal")
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg(master)
        .arg(library)
        .arg(guid)
        .arg(format!("{TOLERANCE:e}"))
        .arg(format!("{STEP}"))
        .arg(format!("{STOP}"))
        .arg(dir.join("points.txt"))
        .args(settings)
        .arg("--")
        .args(refs.iter().map(|vr| format!("R:{vr}")));
    output_of(&mut command)?;
    let profile = fs::read_to_string(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    profile
        .lines()
        .find_map(|l| l.strip_prefix("totals: "))
        .or_else(|| profile.lines().find_map(|l| l.strip_prefix("summary: ")))
        .and_then(|v| v.trim().parse().ok())
        .ok_or_else(|| format!("{}: no totals line", out.display()))
}

pub(crate) fn job(_: &crate::cli::Parsed) -> Result {
    apt_install(&["valgrind"])?;
    let packed = crate::fmu::build_fmu(false)?;
    let dir = root().join("target/instructions");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let description = read_description(&root().join("target/fmu/assets/modelDescription.xml"))?;
    let refs = references(&description)?;
    let master = crate::master::build_native_master(&dir)?;
    let points = (STOP / STEP).round() as u64;
    let commit = build_label();
    let path = root().join("docs/bench/instructions.md");
    let mut report = fs::read_to_string(&path).unwrap_or_default();
    for parameters in SLOT_SETS {
        let settings = slot_settings(&description, parameters)?;
        let total = count(
            &master,
            &packed.linux64,
            &description.guid,
            (&settings, &refs),
            &dir,
        )?;
        let slots = match parameters {
            [] => "none".to_string(),
            names => names.join(", "),
        };
        let row = format!(
            "| {} | {slots} | {total} | {:.1} |",
            commit.trim(),
            total as f64 / points as f64
        );
        report = with_row(&report, &row);
    }
    fs::write(&path, &report).map_err(|e| format!("{}: {e}", path.display()))?;
    print!("{report}");
    Ok(())
}

/// The build: the last commit that changed the library's sources (its crate and the
/// integrators), marked `-modified` when the working tree's differ from it; a commit of
/// other files alone measures the same build and adds no row.
fn build_label() -> String {
    let git = |args: &[&str]| {
        output_of(Command::new("git").arg("-C").arg(root()).args(args)).unwrap_or_default()
    };
    let sources = ["src", "integrators", "build.rs", "Cargo.toml", "Cargo.lock"];
    let commit = git(&[&["log", "-1", "--format=%h", "--"][..], &sources].concat());
    let changed = git(&[&["status", "--porcelain", "--"][..], &sources].concat());
    let modified = if changed.trim().is_empty() {
        ""
    } else {
        "-modified"
    };
    format!("{}{modified}", commit.trim())
}

/// The report with `row` as its last row: the rows of other builds and slot sets kept in
/// their order, an earlier row of the same build and slots replaced. A row of the older
/// three-column form (before slots were counted) is read as one without slots.
fn with_row(previous: &str, row: &str) -> String {
    let widened = |line: &str| {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        match cells.len() {
            5 => format!("| {} | none | {} | {} |", cells[1], cells[2], cells[3]),
            _ => line.to_string(),
        }
    };
    let key = |line: &str| {
        line.split('|')
            .take(3)
            .map(str::trim)
            .collect::<Vec<_>>()
            .join("|")
    };
    let mut rows: Vec<String> = data_rows(previous)
        .map(widened)
        .filter(|l| key(l) != key(row))
        .collect();
    rows.push(row.to_string());
    format!(
        "# Instructions per communication point\n\n\
         Written by `cargo xtask instructions` (valgrind's callgrind; a count, the same on every \
         run of the same build), one row per build measured, the latest last. Paper case 1, \
         tolerance {TOLERANCE:e}, H = {STEP} s for {STOP} s ({} points), ten Real outputs read \
         at each ({}); counted inside fmi2DoStep and fmi2GetReal only. Slots: the parameters \
         whose sensitivities the run carries (none before the slots existed).\n\n\
         | build | slots | instructions | per point |\n| --- | --- | --- | --- |\n{}\n",
        (STOP / STEP).round(),
        OUTPUTS.join(", "),
        rows.join("\n")
    )
}

/// The table's rows of measurements (not its header or separator).
fn data_rows(report: &str) -> impl Iterator<Item = &str> {
    report
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| build") && !l.starts_with("| ---"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_new_build_adds_a_row_and_the_same_build_replaces_its_own() {
        let first = with_row("", "| abc | none | 100 | 0.0 |");
        let second = with_row(&first, "| def | none | 200 | 0.0 |");
        let slots = with_row(&second, "| def | k34 | 300 | 0.0 |");
        let again = with_row(&slots, "| abc | none | 150 | 0.0 |");
        let rows: Vec<&str> = data_rows(&again).collect();
        assert_eq!(
            rows,
            [
                "| def | none | 200 | 0.0 |",
                "| def | k34 | 300 | 0.0 |",
                "| abc | none | 150 | 0.0 |"
            ]
        );
    }

    #[test]
    fn a_row_of_the_older_form_is_read_as_one_without_slots() {
        let old =
            "| build | instructions | per point |\n| --- | --- | --- |\n| xyz | 100 | 0.0 |\n";
        let report = with_row(old, "| abc | none | 150 | 0.0 |");
        let rows: Vec<&str> = data_rows(&report).collect();
        assert_eq!(
            rows,
            ["| xyz | none | 100 | 0.0 |", "| abc | none | 150 | 0.0 |"]
        );
    }
}
