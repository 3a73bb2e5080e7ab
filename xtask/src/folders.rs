//! The layers inside the folders of a crate, as ARCHITECTURE.md's table of layers gives
//! them (a row per folder, `runner/src/cycle/` and the like): no file imports a sibling of
//! a layer above its own (`super::x`, `crate::cycle::x`), every file has a place, no
//! siblings import each other round a circle, and every folder of two or more modules
//! has its row. A folder's `mod.rs` is its face, declaring and re-exporting the others
//! and holding what they share: it has no layer, and an item of it is no sibling's.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

use crate::layers::{circles, imported_modules, imports_up, Layers};

/// Whether a row of the table names a folder inside a crate rather than a crate.
pub(crate) fn is_folder(path: &str) -> bool {
    path.starts_with("src/") || path.contains("/src/")
}

/// The module path of a folder below its crate's `src/`: `runner/src/fmi/fmi3` →
/// `fmi::fmi3`.
fn module_path(folder: &str) -> String {
    let below = folder.rsplit_once("src/").map_or(folder, |(_, b)| b);
    below.trim_end_matches('/').replace('/', "::")
}

/// The modules of a folder: its files' stems and its sub-folders' names, its `mod.rs` and
/// tests aside.
pub(crate) fn modules(dir: &Path) -> Result<Vec<String>, String> {
    let mut found = Vec::new();
    let entries = fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry.map_err(|e| e.to_string())?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if path.is_dir() && path.join("mod.rs").exists() {
            found.push(name);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            if stem != "tests" && stem != "mod" {
                found.push(stem.to_string());
            }
        }
    }
    found.sort();
    Ok(found)
}

/// The siblings a line of a file of the folder imports: `super::x` and `crate::PATH::x`,
/// each `x` a sibling module.
fn siblings_in(line: &str, path: &str, siblings: &[String]) -> Vec<String> {
    // Only the folder's own paths count: the crate's other modules are another table's.
    let own = format!("crate::{path}::");
    let line = line
        .replace(&own, "\u{1}")
        .replace("super::", "\u{1}")
        .replace("crate::", "\u{2}")
        .replace('\u{1}', "crate::");
    imported_modules(&line)
        .into_iter()
        .filter(|m| siblings.contains(m))
        .collect()
}

/// Arrows up, circles and unplaced files in the folder `folder` (from the repository's
/// root `root`), by `layers`; `code` gives a file's lines of code.
pub(crate) fn problems(
    root: &Path,
    folder: &str,
    layers: &Layers,
    code: impl Fn(&str) -> Vec<(usize, String)>,
) -> Result<Vec<String>, String> {
    let dir = root.join(folder.trim_end_matches('/'));
    let siblings = modules(&dir)?;
    let path = module_path(folder);
    let mut problems = Vec::new();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for module in &siblings {
        let file = match dir.join(format!("{module}.rs")) {
            f if f.exists() => f,
            _ => dir.join(module).join("mod.rs"),
        };
        let name = file
            .strip_prefix(root)
            .unwrap_or(&file)
            .to_string_lossy()
            .into_owned();
        let text = fs::read_to_string(&file).map_err(|e| format!("{name}: {e}"))?;
        let imports: Vec<(usize, String)> = code(&text)
            .into_iter()
            .flat_map(|(n, line)| {
                let used = siblings_in(&line, &path, &siblings);
                used.into_iter().map(move |m| (n, m))
            })
            .filter(|(_, m)| m != module)
            .collect();
        graph
            .entry(module.clone())
            .or_default()
            .extend(imports.iter().map(|(_, m)| m.clone()));
        problems.extend(imports_up(layers, &name, module, imports.into_iter()));
    }
    for circle in circles(&graph) {
        problems.push(format!(
            "{folder}: modules import each other round a circle: {}",
            circle.join(", ")
        ));
    }
    Ok(problems)
}

/// The folders below `crate_src` (a crate's `src/`, from `root`) that hold two or more
/// modules besides their `mod.rs`, by their paths from the root, each ending in `/`; the
/// binaries' folders (crates of their own) aside.
pub(crate) fn folders_below(root: &Path, crate_src: &str) -> Result<Vec<String>, String> {
    let mut found = Vec::new();
    let mut todo = vec![root.join(crate_src)];
    while let Some(dir) = todo.pop() {
        let entries = fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries {
            let path = entry.map_err(|e| e.to_string())?.path();
            if !path.is_dir() || path.ends_with("bin") {
                continue;
            }
            if modules(&path)?.len() >= 2 {
                let relative = path.strip_prefix(root).unwrap_or(&path);
                found.push(format!("{}/", relative.to_string_lossy()));
            }
            todo.push(path);
        }
    }
    found.sort();
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_siblings_import_is_read_from_super_and_from_the_crate() {
        let siblings: Vec<String> = ["flow", "periodic"].map(String::from).to_vec();
        let read = |line: &str| siblings_in(line, "cycle", &siblings);
        assert_eq!(read("use super::flow::{leg, End};"), ["flow"]);
        assert_eq!(
            read("use super::{periodic::Shot, flow};"),
            ["periodic", "flow"]
        );
        assert_eq!(read("use crate::cycle::periodic::x;"), ["periodic"]);
        assert!(read("use super::CycleRecord;").is_empty());
        assert!(read("use crate::fmi::Instance;").is_empty());
        assert_eq!(module_path("runner/src/fmi/fmi3/"), "fmi::fmi3");
        assert!(is_folder("runner/src/cycle/") && is_folder("src/model/"));
        assert!(!is_folder("runner/"));
    }
}
