//! `cargo xtask tidy`, also the first step of `cargo xtask test`: the code is formatted,
//! clippy finds nothing, `unsafe` appears only in the FFI and loader files, no module of
//! `src/` imports from a layer above its own (ARCHITECTURE.md's table, `layers`), no
//! comment in `src/` carries a measured figure (figures live in the reports a command
//! writes), and `mypy --strict` passes on the Python package.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli::Parsed;
use crate::setup::Result;
use crate::setup::{cargo, ensure_venv, output_of, root, run, Packages};

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
    let architecture = fs::read_to_string(root().join("ARCHITECTURE.md"))
        .map_err(|e| format!("ARCHITECTURE.md: {e}"))?;
    let mut problems = layer_problems(&architecture)?;
    for dir in PRODUCT {
        for file in rust_files(&root().join(dir))? {
            let text = fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
            let name = relative(&file);
            problems.extend(unsafe_outside_ffi(&name, &text));
            problems.extend(crate::sizes::too_long(&name, &text));
            problems.extend(unknown_to_layer(&name, &text));
            if dir == "src" {
                problems.extend(figures_in_comments(&name, &text));
            }
        }
    }
    type_check()?;
    if problems.is_empty() {
        println!(
            "xtask: tidy: formatted, clippy clean, unsafe only where allowed, no arrow up and \
             no circle in any crate or in fmusweep, no file or function too long, no figures \
             in src/ comments, fmusweep typed (mypy --strict)"
        );
        Ok(())
    } else {
        Err(format!("tidy:\n{}", problems.join("\n")))
    }
}

/// The product's crates, whose files are held to the rules on `unsafe` and on length.
const PRODUCT: [&str; 5] = [
    "src",
    "integrators/src",
    "runner/src",
    "web/src",
    "fmi-description/src",
];

/// A file's path from the repository's root.
fn relative(file: &Path) -> String {
    file.strip_prefix(root())
        .unwrap_or(file)
        .to_string_lossy()
        .into_owned()
}

/// Arrows up and circles in every crate: the FMU's `src/` by ARCHITECTURE.md's layer
/// table, the runner, the integrators, the page's crate and xtask by the table of the
/// other crates' layers.
fn layer_problems(architecture: &str) -> Result<Vec<String>> {
    let mut crates = vec![(
        "src".to_string(),
        crate::layers::from_architecture(architecture)?,
    )];
    let mut problems = Vec::new();
    let mut folders = Vec::new();
    for (folder, layers) in crate::layers::other_crates(architecture)? {
        if folder.starts_with("python/") {
            problems.extend(package_shape(&folder, &layers)?);
        } else if crate::folders::is_folder(&folder) {
            folders.push(format!("{folder}/"));
            let code = |text: &str| code_lines(text).map(|(n, l)| (n, l.to_string())).collect();
            problems.extend(crate::folders::problems(&root(), &folder, &layers, code)?);
        } else {
            crates.push((format!("{folder}/src"), layers));
        }
    }
    for dir in PRODUCT {
        for folder in crate::folders::folders_below(&root(), dir)? {
            if !folders.contains(&folder) {
                problems.push(format!(
                    "{folder}: a folder of several modules without its row in \
                     ARCHITECTURE.md's table of layers"
                ));
            }
        }
    }
    for (dir, layers) in &crates {
        let mut graph = BTreeMap::new();
        for file in rust_files(&root().join(dir))? {
            let name = relative(&file);
            let Some(module) = crate::layers::module_of(&name) else {
                continue;
            };
            let text = fs::read_to_string(&file).map_err(|e| format!("{name}: {e}"))?;
            let code: Vec<(usize, String)> = code_lines(&text)
                .map(|(n, line)| match crate::layers::super_is_crate(&name) {
                    true => (n, line.replace("super::", "crate::")),
                    false => (n, line.to_string()),
                })
                .collect();
            let imported: &mut BTreeSet<String> = graph.entry(module.to_string()).or_default();
            for (_, line) in &code {
                imported.extend(
                    crate::layers::imported_modules(line)
                        .into_iter()
                        .filter(|m| m != module && layers.iter().flatten().any(|l| l == m)),
                );
            }
            problems.extend(crate::layers::arrows_up(
                layers,
                &name,
                module,
                code.into_iter(),
            ));
        }
        for circle in crate::layers::circles(&graph) {
            problems.push(format!(
                "{dir}: modules import each other round a circle: {}",
                circle.join(", ")
            ));
        }
    }
    Ok(problems)
}

/// The Python package in `folder`, judged as the crates are: arrows up by `layers`,
/// circles, and its files' and functions' lengths. `xtask/python/package_shape.py` reads
/// the facts (every import counted, wherever it stands).
fn package_shape(folder: &str, layers: &[Vec<String>]) -> Result<Vec<String>> {
    let python = ensure_venv(Packages::Tests)?;
    let facts = output_of(
        Command::new(python)
            .current_dir(root())
            .arg("xtask/python/package_shape.py")
            .arg(folder.trim_end_matches('/')),
    )?;
    let mut problems = Vec::new();
    let mut files = BTreeMap::new();
    let mut imports: BTreeMap<String, Vec<(usize, String)>> = BTreeMap::new();
    for line in facts.lines() {
        let fact: Vec<&str> = line.split('\t').collect();
        let number = |k: usize| fact.get(k).and_then(|v| v.parse::<usize>().ok());
        match (fact.as_slice(), number(2), number(3), number(4)) {
            (["module", name, path, _], _, Some(lines), _) => {
                files.insert(name.to_string(), path.to_string());
                imports.entry(name.to_string()).or_default();
                problems.extend(crate::sizes::file_too_long(path, lines));
            }
            (["import", name, _, target], Some(at), _, _) => imports
                .entry(name.to_string())
                .or_default()
                .push((at, target.to_string())),
            (["function", path, _, function, _], Some(at), _, Some(length)) => {
                problems.extend(crate::sizes::function_too_long(path, at, function, length))
            }
            _ => {
                return Err(format!(
                    "package_shape.py: a fact tidy cannot read: {line:?}"
                ))
            }
        }
    }
    let mut graph = BTreeMap::new();
    for (module, found) in &imports {
        let file = files.get(module).map_or(module.as_str(), String::as_str);
        problems.extend(crate::layers::imports_up(
            layers,
            file,
            module,
            found.iter().cloned(),
        ));
        graph.insert(
            module.clone(),
            found.iter().map(|(_, target)| target.clone()).collect(),
        );
    }
    for circle in crate::layers::circles(&graph) {
        problems.push(format!(
            "{folder}: modules import each other round a circle: {}",
            circle.join(", ")
        ));
    }
    Ok(problems)
}

/// What a part of the product does not know, as ARCHITECTURE.md says, by the paths its
/// `use` lines name: (files, a path named, what of it is allowed). The model and the plant
/// know no integrator (of that crate only how a message prints a number, and for the plant
/// its byte form); the variable table and the description none of it; the runner's
/// coupling controller nothing of the runner (no FMU).
const UNKNOWN: &[(&str, &str, &[&str])] = &[
    ("src/model/", "integrators::", &["integrators::text::"]),
    (
        "src/plant/",
        "integrators::",
        &["integrators::text::", "integrators::bytes::"],
    ),
    ("src/variables.rs", "integrators::", &[]),
    ("src/description.rs", "integrators::", &[]),
    ("runner/src/coupling.rs", "crate::", &[]),
];

/// Below the instance, none of these: the C interface's types.
const C_TYPES: &[&str] = &["fmi_sys", "std::ffi", "std::os::raw", "libc::"];
const BELOW_INSTANCE: &[&str] = &[
    "src/drivers/",
    "src/plant/",
    "src/model/",
    "src/description.rs",
    "src/variables.rs",
];

/// Words the integrators' crate does not say, in its code, comments or bytes: it knows
/// nothing of the FMU, the mechanism or FMI.
const NOT_INTEGRATORS: &[&str] = &["fmu", "fmi", "mechanism", "crank", "plant"];

/// Lines of the file `name` that name what its part does not know.
fn unknown_to_layer(name: &str, text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (number, line) in code_lines(text) {
        for (files, path, allowed) in UNKNOWN {
            let named = line.contains(path) && !allowed.iter().any(|a| line.contains(a));
            if name.starts_with(files) && named {
                found.push(format!(
                    "{name}:{number}: names `{path}`, which ARCHITECTURE.md says it does not know"
                ));
            }
        }
        let below = BELOW_INSTANCE.iter().any(|b| name.starts_with(b));
        if below && C_TYPES.iter().any(|c| line.contains(c)) {
            found.push(format!(
                "{name}:{number}: names a C type, below the instance"
            ));
        }
    }
    if name.starts_with("integrators/") {
        for (i, line) in text.lines().enumerate() {
            let words = line.to_lowercase();
            let said = words
                .split(|c: char| !c.is_alphanumeric())
                .find(|w| NOT_INTEGRATORS.contains(w));
            if let Some(word) = said {
                found.push(format!(
                    "{name}:{}: says \"{word}\": the integrators know nothing of the FMU",
                    i + 1
                ));
            }
        }
    }
    found
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

    #[test]
    fn what_a_part_does_not_know_is_found_in_its_use_lines() {
        let text = "use integrators::bytes::Writer;\nuse integrators::{Method, Statistics};\n";
        let found = unknown_to_layer("src/plant/access.rs", text);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].starts_with("src/plant/access.rs:2:"));
        assert_eq!(
            unknown_to_layer("src/drivers/mod.rs", text),
            Vec::<String>::new()
        );
        let found = unknown_to_layer("src/drivers/isa.rs", "use std::ffi::c_void;\n");
        assert!(found[0].contains("C type"), "{found:?}");
        let found = unknown_to_layer("runner/src/coupling.rs", "use crate::fmi::Status;\n");
        assert_eq!(found.len(), 1, "{found:?}");
        let found = unknown_to_layer("integrators/src/lib.rs", "//! Steps the FMU's plant.\n");
        assert_eq!(found.len(), 1, "{found:?}");
    }
}
