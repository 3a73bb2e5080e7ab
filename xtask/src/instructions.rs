//! `cargo xtask instructions`: the instructions one communication point costs, counted by
//! valgrind's callgrind (a count, not a time: the same for the same binary and inputs,
//! whatever else the machine runs). The C master of the platform tests runs paper case 1
//! for 10 s at H = 1 ms reading ten Real outputs at every point; only the instructions
//! inside fmi2DoStep and fmi2GetReal (and what they call) are counted, and divided by the
//! number of points. The report goes to `docs/bench/instructions.md`.

use std::fs;
use std::path::Path;
use std::process::Command;

use crate::setup::{apt_install, output_of, root};
use crate::Result;

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

/// The description's GUID and the value references of [`OUTPUTS`].
fn references(xml: &Path) -> Result<(String, Vec<u32>)> {
    let description = crate::abi_tests::read_description(xml)?;
    let refs = OUTPUTS
        .iter()
        .map(|name| {
            description
                .variables
                .get(*name)
                .map(|v| v.vr)
                .ok_or_else(|| format!("no variable {name} in {}", xml.display()))
        })
        .collect::<Result<Vec<u32>>>()?;
    Ok((description.guid, refs))
}

/// Instructions counted inside the stepping and reading functions.
fn count(master: &Path, library: &Path, guid: &str, refs: &[u32], dir: &Path) -> Result<u64> {
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
    let (guid, refs) = references(&root().join("target/fmu/assets/modelDescription.xml"))?;
    let master = crate::abi_tests::build_native_master(&dir)?;
    let total = count(&master, &packed.linux64, &guid, &refs, &dir)?;
    let points = (STOP / STEP).round() as u64;
    let commit = build_label();
    let path = root().join("docs/bench/instructions.md");
    let row = format!(
        "| {} | {total} | {:.1} |",
        commit.trim(),
        total as f64 / points as f64
    );
    let report = with_row(&fs::read_to_string(&path).unwrap_or_default(), &row);
    fs::write(&path, &report).map_err(|e| format!("{}: {e}", path.display()))?;
    print!("{report}");
    Ok(())
}

/// The commit the FMU was built from, marked `-modified` when the library's sources differ
/// from it (the report itself, or other files, do not count).
fn build_label() -> String {
    let git = |args: &[&str]| {
        output_of(Command::new("git").arg("-C").arg(root()).args(args)).unwrap_or_default()
    };
    let commit = git(&["rev-parse", "--short", "HEAD"]);
    let changed = git(&[
        "status",
        "--porcelain",
        "--",
        "src",
        "build.rs",
        "Cargo.toml",
        "Cargo.lock",
    ]);
    let modified = if changed.trim().is_empty() {
        ""
    } else {
        "-modified"
    };
    format!("{}{modified}", commit.trim())
}

/// The report with `row` as its last row: the rows of other builds kept in their order, an
/// earlier row of the same build replaced.
fn with_row(previous: &str, row: &str) -> String {
    let build = |line: &str| line.split('|').nth(1).map(str::trim).map(str::to_string);
    let mut rows: Vec<&str> = data_rows(previous)
        .filter(|l| build(l) != build(row))
        .collect();
    rows.push(row);
    format!(
        "# Instructions per communication point\n\n\
         Written by `cargo xtask instructions` (valgrind's callgrind; a count, the same on every \
         run of the same build), one row per build measured, the latest last. Paper case 1, \
         tolerance {TOLERANCE:e}, H = {STEP} s for {STOP} s ({} points), ten Real outputs read \
         at each ({}); counted inside fmi2DoStep and fmi2GetReal only.\n\n\
         | build | instructions | per point |\n| --- | --- | --- |\n{}\n",
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
        let first = with_row("", "| abc | 100 | 0.0 |");
        let second = with_row(&first, "| def | 200 | 0.0 |");
        let again = with_row(&second, "| abc | 150 | 0.0 |");
        let rows: Vec<&str> = data_rows(&again).collect();
        assert_eq!(rows, ["| def | 200 | 0.0 |", "| abc | 150 | 0.0 |"]);
    }
}
