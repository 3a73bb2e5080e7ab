//! The layers of `src/`, as ARCHITECTURE.md's table gives them (top down), and the check
//! that no module imports from a layer above its own, and that the two C ABIs import
//! nothing from each other. The table is the one source: a module it does not place is
//! reported too.

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

/// The top module a file of `src/` belongs to (`src/instance/mod.rs` → `instance`);
/// `None` for the crate root and the binaries.
pub(crate) fn module_of(relative: &str) -> Option<&str> {
    let path = relative.strip_prefix("src/")?;
    let first = path.split('/').next()?;
    if first == "bin" || first == "lib.rs" {
        return None;
    }
    Some(first.strip_suffix(".rs").unwrap_or(first))
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
    let rank = |m: &str| layers.iter().position(|layer| layer.iter().any(|l| l == m));
    let Some(own) = rank(module) else {
        return vec![format!(
            "{name}: module `{module}` has no place in its layer table"
        )];
    };
    let mut found = Vec::new();
    for (number, line) in whole_groups(code) {
        for target in imported_modules(&line) {
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
fn imported_modules(line: &str) -> Vec<String> {
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
    }
}
