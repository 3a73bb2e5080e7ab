//! `cargo xtask instructions`: the instructions one communication point costs, counted by
//! valgrind's callgrind (a count, not a time: the same for the same binary and inputs,
//! whatever else the machine runs). The C master of the platform tests runs paper case 1
//! for 10 s at H = 1 ms reading ten Real outputs at every point; only the instructions
//! inside fmi2DoStep and fmi2GetReal (and what they call) are counted, and divided by the
//! number of points. The report goes to `docs/bench/instructions.md`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::{output_of, root, run, Result};

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

fn build_master(dir: &Path) -> Result<PathBuf> {
    let master = dir.join("master");
    run(Command::new("cc")
        .args(["-O2", "-std=c99"])
        .arg("-I")
        .arg(crate::abi_tests::fmi2_headers()?)
        .arg("-o")
        .arg(&master)
        .arg(root().join("tests/platforms/master.c"))
        .arg("-ldl"))?;
    Ok(master)
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

pub fn measure() -> Result {
    crate::apt_install(&["valgrind"])?;
    let packed = crate::build_fmu(false)?;
    let dir = root().join("target/instructions");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let (guid, refs) = references(&root().join("target/fmu/assets/modelDescription.xml"))?;
    let master = build_master(&dir)?;
    let total = count(&master, &packed.linux64, &guid, &refs, &dir)?;
    let points = (STOP / STEP).round() as u64;
    let commit = output_of(
        Command::new("git")
            .args(["-C"])
            .arg(root())
            .args(["describe", "--always", "--dirty"]),
    )
    .unwrap_or_default();
    let report = format!(
        "# Instructions per communication point\n\n\
         Written by `cargo xtask instructions` (valgrind's callgrind; a count, the same on every \
         run of the same build). Paper case 1, tolerance {TOLERANCE:e}, H = {STEP} s for {STOP} s \
         ({points} points), ten Real outputs read at each ({}); counted inside fmi2DoStep and \
         fmi2GetReal only.\n\n\
         | build | instructions | per point |\n| --- | --- | --- |\n| {} | {total} | {:.1} |\n",
        OUTPUTS.join(", "),
        commit.trim(),
        total as f64 / points as f64
    );
    let path = root().join("docs/bench/instructions.md");
    fs::write(&path, &report).map_err(|e| format!("{}: {e}", path.display()))?;
    print!("{report}");
    Ok(())
}
