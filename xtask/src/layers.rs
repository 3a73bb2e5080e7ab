//! The layers of every crate, as ARCHITECTURE.md's tables give them (top down): the FMU's
//! `src/` in its layer table, the other crates in the table of their layers. The checks:
//! no module imports from a layer above its own, the two C ABIs import nothing from each
//! other, and no modules import each other round a circle. The tables are the one source:
//! a module they do not place is reported too.

use std::collections::{BTreeMap, BTreeSet};

/// The modules named in the rows of ARCHITECTURE.md's layer table, top down; a row's
/// modules share a layer. The modules "beside them" (the paragraph after the table) share
/// the bottom row's.
pub(crate) fn from_architecture(text: &str) -> Result<Vec<Vec<String>>, String> {
    let rows = text
        .lines()
        .skip_while(|line| !line.starts_with("| layer | where |"))
        .skip(2)
        .take_while(|line| line.starts_with('|'));
    let mut layers: Vec<Vec<String>> = rows.map(|row| modules_in(cell(row, 2))).collect();
    let beside = text
        .split("\nBeside them:")
        .nth(1)
        .and_then(|rest| rest.split("\n\n").next())
        .ok_or("ARCHITECTURE.md: no paragraph \"Beside them:\" after the layer table")?;
    if layers.len() < 2 || layers.iter().any(Vec::is_empty) {
        return Err("ARCHITECTURE.md: the layer table names no modules in a row".into());
    }
    if let Some(bottom) = layers.last_mut() {
        bottom.extend(modules_in(beside));
    }
    Ok(layers)
}

/// The `n`-th cell (1-based) of a Markdown table row.
fn cell(row: &str, n: usize) -> &str {
    row.split('|').nth(n).unwrap_or_default()
}

/// The crate's top modules named as `src/NAME/` or `src/NAME.rs` in `text`.
fn modules_in(text: &str) -> Vec<String> {
    text.split('`')
        .filter_map(|quoted| quoted.strip_prefix("src/"))
        .filter_map(|path| {
            let first = path.split('/').next()?;
            let name = first.strip_suffix(".rs").unwrap_or(first);
            (!name.is_empty() && !name.contains(' ')).then(|| name.to_string())
        })
        .collect()
}

/// A crate's layers, top down: each a list of module names.
pub(crate) type Layers = Vec<Vec<String>>;

/// The other crates' layers: each row of the table headed `| crate | layers, top down |`
/// names a crate's folder and its layers, top down, separated by `›`.
pub(crate) fn other_crates(text: &str) -> Result<Vec<(String, Layers)>, String> {
    let rows: Vec<&str> = text
        .lines()
        .skip_while(|line| !line.starts_with("| crate | layers, top down |"))
        .skip(2)
        .take_while(|line| line.starts_with('|'))
        .collect();
    if rows.is_empty() {
        return Err("ARCHITECTURE.md: no table \"| crate | layers, top down |\"".into());
    }
    rows.iter()
        .map(|row| {
            let folder = cell(row, 1).trim().trim_matches('`').trim_end_matches('/');
            let layers: Vec<Vec<String>> = cell(row, 2)
                .split('›')
                .map(|layer| {
                    layer
                        .split('`')
                        .skip(1)
                        .step_by(2)
                        .map(str::to_string)
                        .collect()
                })
                .collect();
            if folder.is_empty() || layers.iter().any(Vec::is_empty) {
                return Err(format!(
                    "ARCHITECTURE.md: a crate's layers row is empty: {row}"
                ));
            }
            Ok((folder.to_string(), layers))
        })
        .collect()
}

/// The top module a file of a crate belongs to (`src/instance/mod.rs` → `instance`,
/// `runner/src/fmi/fmi2.rs` → `fmi`); `None` for the crate roots and the binaries.
pub(crate) fn module_of(relative: &str) -> Option<&str> {
    let (_, path) = relative.split_once("src/")?;
    let first = path.split('/').next()?;
    if ["bin", "lib.rs", "main.rs"].contains(&first) {
        return None;
    }
    Some(first.strip_suffix(".rs").unwrap_or(first))
}

/// Whether `super::` in the file means the crate: a top module's own file.
pub(crate) fn super_is_crate(relative: &str) -> bool {
    relative
        .split_once("src/")
        .is_some_and(|(_, path)| !path.contains('/') || path.ends_with("/mod.rs"))
}

/// Modules that import each other round a circle: the strongly connected parts of
/// `graph` (module → the modules it imports) with more than one module.
pub(crate) fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let reaches = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.to_string()];
        while let Some(m) = todo.pop() {
            for next in graph.get(&m).into_iter().flatten() {
                if seen.insert(next.clone()) {
                    todo.push(next.clone());
                }
            }
        }
        seen
    };
    let reach: BTreeMap<&String, BTreeSet<String>> =
        graph.keys().map(|m| (m, reaches(m))).collect();
    let mut found: Vec<Vec<String>> = Vec::new();
    for (m, from_m) in &reach {
        let circle: Vec<String> = from_m
            .iter()
            .filter(|other| reach.get(other).is_some_and(|r| r.contains(*m)))
            .cloned()
            .collect();
        if circle.len() > 1 && !found.contains(&circle) {
            found.push(circle);
        }
    }
    found
}

/// Violations in `code` (the lines of code of the file `name`, in module `module`): each
/// `crate::X`, or `X` of a grouped `crate::{X, Y::z}` (over several lines too), with X in a
/// layer above the module's, or the other C ABI.
pub(crate) fn arrows_up(
    layers: &[Vec<String>],
    name: &str,
    module: &str,
    code: impl Iterator<Item = (usize, String)>,
) -> Vec<String> {
    let imports = whole_groups(code).into_iter().flat_map(|(number, line)| {
        imported_modules(&line)
            .into_iter()
            .map(move |target| (number, target))
    });
    imports_up(layers, name, module, imports)
}

/// Violations among `imports` ((line, imported module) of the file `name`, in module
/// `module`): a module above the file's own, or the other C ABI; a module the table does
/// not place is one too.
pub(crate) fn imports_up(
    layers: &[Vec<String>],
    name: &str,
    module: &str,
    imports: impl Iterator<Item = (usize, String)>,
) -> Vec<String> {
    let rank = |m: &str| layers.iter().position(|layer| layer.iter().any(|l| l == m));
    let Some(own) = rank(module) else {
        return vec![format!(
            "{name}: module `{module}` has no place in its layer table"
        )];
    };
    let mut found = Vec::new();
    for (number, target) in imports {
        if target == module {
            continue;
        }
        let peers = matches!(
            (module, target.as_str()),
            ("fmi2", "fmi3") | ("fmi3", "fmi2")
        );
        match rank(&target) {
            Some(r) if r < own => found.push(format!(
                "{name}:{number}: `{module}` imports from `{target}`, a layer above it"
            )),
            _ if peers => found.push(format!(
                "{name}:{number}: `{module}` imports from `{target}`: the two C ABIs are peers"
            )),
            _ => {}
        }
    }
    found
}

/// The lines of `code`, a `crate::{` group that spans lines joined onto its first line.
fn whole_groups(code: impl Iterator<Item = (usize, String)>) -> Vec<(usize, String)> {
    let mut lines = Vec::new();
    let mut open: Option<(usize, String)> = None;
    for (number, line) in code {
        let (number, line) = match open.take() {
            Some((first, mut joined)) => {
                joined.push(' ');
                joined.push_str(&line);
                (first, joined)
            }
            None => (number, line),
        };
        let unclosed = line
            .find("crate::{")
            .is_some_and(|at| line[at..].matches('{').count() > line[at..].matches('}').count());
        if unclosed {
            open = Some((number, line));
        } else {
            lines.push((number, line));
        }
    }
    lines.extend(open);
    lines
}

/// The top modules a line uses through `crate::`: `crate::a::b` gives `a`, and
/// `crate::{a, b::{c, d}, e}` gives `a`, `b` and `e`.
pub(crate) fn imported_modules(line: &str) -> Vec<String> {
    let name = |text: &str| -> String {
        text.trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut found = Vec::new();
    for used in line.split("crate::").skip(1) {
        let Some(group) = used.strip_prefix('{') else {
            found.push(name(used));
            continue;
        };
        let (mut depth, mut start) = (0usize, 0usize);
        for (at, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    found.push(name(&group[start..at]));
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    found.push(name(&group[start..at]));
                    start = at + 1;
                }
                _ => {}
            }
        }
    }
    found.retain(|n| !n.is_empty());
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE: &str = "\n| layer | where | what it knows |\n| --- | --- | --- |\n\
        | C ABIs | `src/fmi2/`, `src/fmi3/`, `src/abi.rs` | x |\n\
        | instance | `src/instance/` | y |\n| model | `src/model/` | z |\n\n\
        Beside them: `src/variables.rs` is the table.\n\nMore.\n";

    #[test]
    fn a_grouped_import_names_each_of_its_modules_over_several_lines_too() {
        assert_eq!(
            imported_modules("use crate::{a, b::{c, d}, e};"),
            ["a", "b", "e"]
        );
        assert_eq!(imported_modules("crate::x::y(crate::z)"), ["x", "z"]);
        let layers = vec![vec!["top".to_string()], vec!["low".to_string()]];
        let lines = ["use crate::{", "    other,", "    top::Thing,", "};"];
        let code = lines
            .iter()
            .enumerate()
            .map(|(n, l)| (n + 1, l.to_string()));
        let found = arrows_up(&layers, "f.rs", "low", code);
        assert_eq!(
            found,
            ["f.rs:1: `low` imports from `top`, a layer above it"]
        );
    }

    #[test]
    fn an_import_from_above_or_from_the_peer_is_found() {
        let layers = from_architecture(TABLE).unwrap();
        assert_eq!(layers[0], ["fmi2", "fmi3", "abi"]);
        assert_eq!(layers[2], ["model", "variables"]);
        let code = |s: &str| vec![(1, s.to_string())].into_iter();
        assert!(arrows_up(&layers, "a", "model", code("use crate::model::x;")).is_empty());
        assert!(arrows_up(&layers, "a", "instance", code("use crate::model::x;")).is_empty());
        assert_eq!(
            arrows_up(&layers, "a", "model", code("crate::instance::f()")).len(),
            1
        );
        assert_eq!(
            arrows_up(&layers, "a", "fmi3", code("crate::fmi2::x")).len(),
            1
        );
        assert_eq!(arrows_up(&layers, "a", "plant", code("")).len(), 1);
        assert_eq!(module_of("src/instance/mod.rs"), Some("instance"));
        assert_eq!(module_of("src/plant.rs"), Some("plant"));
        assert_eq!(module_of("src/lib.rs"), None);
        assert_eq!(module_of("runner/src/fmi/fmi2.rs"), Some("fmi"));
        assert_eq!(module_of("runner/src/main.rs"), None);
        assert!(super_is_crate("runner/src/fmi/mod.rs") && super_is_crate("web/src/a.rs"));
        assert!(!super_is_crate("runner/src/fmi/fmi2.rs"));
    }

    #[test]
    fn the_other_crates_layers_and_their_circles_are_read() {
        let text = "| crate | layers, top down |\n| --- | --- |\n\
            | `web/` | `exports` › `session`, `page` |\n";
        let crates = other_crates(text).unwrap();
        assert_eq!(crates[0].0, "web");
        assert_eq!(crates[0].1, [vec!["exports"], vec!["session", "page"]]);
        let graph: BTreeMap<String, BTreeSet<String>> = [
            ("a", &["b"][..]),
            ("b", &["c"]),
            ("c", &["a"]),
            ("d", &["a"]),
        ]
        .iter()
        .map(|(m, to)| (m.to_string(), to.iter().map(|t| t.to_string()).collect()))
        .collect();
        assert_eq!(circles(&graph), [vec!["a", "b", "c"]]);
    }
}
