//! Lengths a reader can hold: no file of the product longer than `MAX_FILE_LINES` before
//! its tests, no function longer than `MAX_FUNCTION_LINES` (the variable table, one row
//! per variable, aside); Rust's measured here, Python's by `xtask/python/package_shape.py`.

/// Lines of a file before its `#[cfg(test)]` module.
const MAX_FILE_LINES: usize = 700;
/// Lines of a function, from its signature to its closing brace.
const MAX_FUNCTION_LINES: usize = 80;
/// The one file allowed to be long: a row per variable.
const LONG_BY_NATURE: &[&str] = &["src/variables.rs"];

/// The file `name` (text `text`) or its functions, where longer than allowed.
pub(crate) fn too_long(name: &str, text: &str) -> Vec<String> {
    let lines: Vec<&str> = text
        .lines()
        .take_while(|line| !line.starts_with("#[cfg(test)]"))
        .collect();
    let mut found: Vec<String> = file_too_long(name, lines.len()).into_iter().collect();
    found.extend(
        functions(&lines)
            .into_iter()
            .filter_map(|(start, function, length)| {
                function_too_long(name, start, &function, length)
            }),
    );
    found
}

/// The file `name` of `lines` lines (before its tests), if longer than allowed.
pub(crate) fn file_too_long(name: &str, lines: usize) -> Option<String> {
    (lines > MAX_FILE_LINES && !LONG_BY_NATURE.contains(&name))
        .then(|| format!("{name}: {lines} lines before its tests, more than {MAX_FILE_LINES}"))
}

/// The function `function` of `name`, from line `start` and `length` lines long, if longer
/// than allowed.
pub(crate) fn function_too_long(
    name: &str,
    start: usize,
    function: &str,
    length: usize,
) -> Option<String> {
    (length > MAX_FUNCTION_LINES).then(|| {
        format!("{name}:{start}: fn {function} is {length} lines, more than {MAX_FUNCTION_LINES}")
    })
}

/// (first line, name, lines) of each function with a body in `lines`: from the line of
/// `fn` to the one closing its body, counting braces outside comments.
fn functions(lines: &[&str]) -> Vec<(usize, String, usize)> {
    let code = |line: &str| line.split("//").next().unwrap_or_default().to_string();
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(name) = function_name(&code(line)) else {
            continue;
        };
        let mut depth = 0i64;
        for (j, later) in lines.iter().enumerate().skip(i) {
            let later = code(later);
            depth += later.matches('{').count() as i64 - later.matches('}').count() as i64;
            let opened = lines[i..=j].iter().any(|l| code(l).contains('{'));
            if !opened && later.trim_end().ends_with(';') {
                break;
            }
            if opened && depth <= 0 {
                found.push((i + 1, name, j - i + 1));
                break;
            }
        }
    }
    found
}

/// The name of the function a line declares, if it does.
fn function_name(line: &str) -> Option<String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "fn")?;
    let before_ok = words[..at].iter().all(|w| {
        ["pub", "const", "unsafe", "extern", "\"C\"", "async"].contains(w) || w.starts_with("pub(")
    });
    let name: String = words
        .get(at + 1)?
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (before_ok && !name.is_empty()).then_some(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_functions_and_files_are_found() {
        let body = "    x();\n".repeat(MAX_FUNCTION_LINES);
        let text = format!(
            "pub(crate) fn short() {{\n}}\nfn long() {{\n{body}}}\nfn declared();\n\
             #[cfg(test)]\nfn in_tests() {{\n{body}}}\n"
        );
        let found = too_long("f.rs", &text);
        assert_eq!(
            found,
            [format!(
                "f.rs:3: fn long is {} lines, more than {MAX_FUNCTION_LINES}",
                MAX_FUNCTION_LINES + 2
            )]
        );
        let long_file = "let a = 1;\n".repeat(MAX_FILE_LINES + 1);
        assert_eq!(too_long("g.rs", &long_file).len(), 1);
        assert!(too_long("src/variables.rs", &long_file).is_empty());
    }
}
