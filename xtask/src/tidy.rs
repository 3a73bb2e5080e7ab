//! `cargo xtask tidy`, also the first step of `cargo xtask test`: the code is formatted,
//! clippy finds nothing, `unsafe` appears only in the FFI and loader files, no module of
//! `src/` imports from a layer above its own (ARCHITECTURE.md's table, `layers`), no
//! comment in `src/` carries a measured figure (figures live in the reports a command
//! writes), and `mypy --strict` passes on the Python package.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli::Parsed;
use crate::setup::Result;
use crate::setup::{cargo, ensure_venv, root, run, Packages};

/// The files allowed to hold `unsafe`: the FMI 2 and 3 C ABIs and what they share (the
/// call guard, the master's logger, the FMU state pointers), the AVX copy of the step, the
/// runner's loader, and the tests' and harnesses' own masters, allocators and checks.
const UNSAFE_ALLOWED: &[&str] = &[
    "src/fmi2/",
    "src/fmi3/",
    "src/abi.rs",
    "src/instance/handles.rs",
    "src/instance/logger.rs",
    "src/drivers/isa.rs",
    "runner/src/fmi/",
    "runner/src/stdio.rs",
    "tests/",
    "bench/src/",
    "xtask/src/",
];

pub(crate) fn job(_: &Parsed) -> Result {
    check()
}

/// `mypy` on `python/fmusweep` with the package's own settings (strict, in its
/// pyproject.toml), its cache in target/ so that a re-run with nothing changed is quick.
fn type_check() -> Result {
    let python = ensure_venv(Packages::Tests)?;
    let package = root().join("python");
    run(Command::new(python)
        .current_dir(&package)
        .args(["-m", "mypy", "--no-error-summary", "--cache-dir"])
        .arg(root().join("target/mypy"))
        .arg("fmusweep"))
}

pub(crate) fn check() -> Result {
    run(cargo().args(["fmt", "--all", "--check"]))?;
    crate::setup::ensure_libclang()?;
    run(cargo().args([
        "clippy",
        "--quiet",
        "--workspace",
        "--exclude",
        "bench",
        "--all-targets",
        "--",
        "-D",
        "warnings",
    ]))?;
    let mut problems = Vec::new();
    let architecture = fs::read_to_string(root().join("ARCHITECTURE.md"))
        .map_err(|e| format!("ARCHITECTURE.md: {e}"))?;
    let layers = crate::layers::from_architecture(&architecture)?;
    for dir in ["src", "runner/src", "integrators/src", "web/src"] {
        for file in rust_files(&root().join(dir))? {
            let text = fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
            let name = file
                .strip_prefix(root())
                .unwrap_or(&file)
                .to_string_lossy()
                .into_owned();
            problems.extend(unsafe_outside_ffi(&name, &text));
            if dir == "src" {
                problems.extend(figures_in_comments(&name, &text));
                if let Some(module) = crate::layers::module_of(&name) {
                    let code = code_lines(&text).map(|(n, line)| (n, line.to_string()));
                    problems.extend(crate::layers::arrows_up(&layers, &name, module, code));
                }
            }
        }
    }
    problems.extend(xtask_arrows_up()?);
    type_check()?;
    if problems.is_empty() {
        println!(
            "xtask: tidy: formatted, clippy clean, unsafe only where allowed, no arrow up in \
             src/ or xtask/, no figures in src/ comments, fmusweep typed (mypy --strict)"
        );
        Ok(())
    } else {
        Err(format!("tidy:\n{}", problems.join("\n")))
    }
}

/// xtask's own layers, top down: the job that runs the others, the jobs, the builders
/// below them, and what every module uses. A module of xtask/src/ not placed here is
/// reported; `main.rs` (the job table) is above them all.
const XTASK_LAYERS: &[&[&str]] = &[
    &["test"],
    &[
        "abi_tests",
        "accuracy",
        "bench",
        "demo",
        "fit",
        "instructions",
        "motor",
        "sweep",
        "tidy",
        "web",
    ],
    &["builders", "fmu", "layers", "master", "page", "platforms"],
    &["cli", "setup"],
];

/// Imports from a layer above in xtask itself (builders below the jobs).
fn xtask_arrows_up() -> Result<Vec<String>> {
    let layers: Vec<Vec<String>> = XTASK_LAYERS
        .iter()
        .map(|layer| layer.iter().map(|m| m.to_string()).collect())
        .collect();
    let mut problems = Vec::new();
    for file in rust_files(&root().join("xtask/src"))? {
        let Some(module) = file.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if module == "main" {
            continue;
        }
        let text = fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        let name = format!("xtask/src/{module}.rs");
        let code = code_lines(&text).map(|(n, line)| (n, line.to_string()));
        problems.extend(crate::layers::arrows_up(&layers, &name, module, code));
    }
    Ok(problems)
}

fn rust_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let files = crate::setup::files_below(dir)?;
    Ok(files
        .into_iter()
        .filter(|path| path.extension().is_some_and(|e| e == "rs"))
        .collect())
}

/// Lines of `text` (the file `name`) that use `unsafe` outside the allowed files.
fn unsafe_outside_ffi(name: &str, text: &str) -> Vec<String> {
    if UNSAFE_ALLOWED
        .iter()
        .any(|allowed| name.starts_with(allowed))
    {
        return Vec::new();
    }
    code_lines(text)
        .filter(|(_, code)| {
            code.split(|c: char| !c.is_alphanumeric() && c != '_')
                .any(|word| word == "unsafe")
        })
        .map(|(number, _)| format!("{name}:{number}: unsafe outside the FFI and loader files"))
        .collect()
}

/// (line number, the line without its comment), for the lines of code.
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.split("//").next().unwrap_or_default()))
}

/// Words that mark a comment as reporting a measurement.
const MEASURED: &[&str] = &[
    "valgrind",
    "callgrind",
    "measured",
    "median",
    "alternating rounds",
    "instructions per",
    "more instructions",
    "fewer instructions",
    "the time of",
];

/// Comment lines of `text` (the file `name`) that carry a measured figure: a percentage, a
/// multiple of a time, a duration, or a word that reports a measurement.
fn figures_in_comments(name: &str, text: &str) -> Vec<String> {
    text.lines()
        .enumerate()
        .filter_map(|(i, line)| {
            let comment = line.split_once("//")?.1.to_lowercase();
            let reason = if has_percentage(&comment) {
                "a percentage"
            } else if has_time_multiple(&comment) {
                "a multiple of a time"
            } else if has_duration(&comment) {
                "a duration"
            } else {
                MEASURED.iter().copied().find(|w| comment.contains(w))?
            };
            Some(format!(
                "{name}:{}: a comment reports a measurement ({reason}); it belongs in a report",
                i + 1
            ))
        })
        .collect()
}

/// A number followed by `%`.
fn has_percentage(comment: &str) -> bool {
    comment.match_indices('%').any(|(at, _)| {
        comment[..at]
            .trim_end()
            .chars()
            .next_back()
            .is_some_and(|c| c.is_ascii_digit())
    })
}

/// A number followed by `×` or `x` and then `the`, `faster`, `slower`, `more` or `fewer`.
fn has_time_multiple(comment: &str) -> bool {
    let words: Vec<&str> = comment.split_whitespace().collect();
    words.windows(3).any(|w| {
        let number = w[0]
            .trim_end_matches(['×', 'x'])
            .trim_start_matches('(')
            .parse::<f64>()
            .is_ok();
        let times = w[0].ends_with('×') || w[1] == "×" || w[1] == "x";
        let compared = ["the", "faster", "slower", "more", "fewer"];
        number && times && (compared.contains(&w[1]) || compared.contains(&w[2]))
    })
}

/// A number followed by a unit of time below a second.
fn has_duration(comment: &str) -> bool {
    let words: Vec<&str> = comment.split_whitespace().collect();
    words.windows(2).any(|w| {
        w[0].parse::<f64>().is_ok()
            && ["ns", "µs", "us", "ms"].contains(&w[1].trim_end_matches([',', '.', ';', ')']))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_figures_in_comments_are_found() {
        let text = "\
/// The 2×2 block is singular where B1 = C1 = 0.
/// It took 1.8 % more time.
// 0.98 × the time of the Taylor polynomials
/// 57 ns per evaluation
// counted by valgrind
let x = 3; // a hundredth of a step
";
        let found = figures_in_comments("f.rs", text);
        assert_eq!(found.len(), 4, "{found:?}");
        assert!(found[0].starts_with("f.rs:2:") && found[0].contains("percentage"));
        assert!(found[1].contains("multiple of a time"));
        assert!(found[2].contains("duration"));
        assert!(found[3].contains("valgrind"));
    }

    #[test]
    fn unsafe_is_found_outside_the_allowed_files_only() {
        let text = "// unsafe in a comment\nlet y = unsafe { f() };\nfn unsafe_name() {}\n";
        let found = unsafe_outside_ffi("src/plant.rs", text);
        assert_eq!(
            found,
            ["src/plant.rs:2: unsafe outside the FFI and loader files"]
        );
        assert!(unsafe_outside_ffi("src/fmi2/common.rs", text).is_empty());
    }
}
