//! Markdown to HTML for the FMU's documentation: the subset the repository's documents use
//! (headings, paragraphs, one-level lists, tables, fenced and indented code, code spans,
//! emphasis, links). Links to files of the repository become plain text, since the FMU
//! does not carry them.

/// `text` as an HTML fragment; headings are shifted down by `demote` levels.
pub fn to_html(text: &str, demote: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let mut html = String::new();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        let (consumed, block) = if line.trim().is_empty() {
            (1, String::new())
        } else if line.starts_with("```") {
            fenced_code(&lines[i..])
        } else if line.starts_with("    ") {
            indented_code(&lines[i..])
        } else if let Some(heading) = heading(line, demote) {
            (1, heading)
        } else if is_table(&lines[i..]) {
            table(&lines[i..])
        } else if line.starts_with("- ") {
            list(&lines[i..])
        } else {
            paragraph(&lines[i..])
        };
        html += &block;
        i += consumed;
    }
    html
}

fn heading(line: &str, demote: usize) -> Option<String> {
    let level = line.chars().take_while(|&c| c == '#').count();
    let title = line.get(level..)?.strip_prefix(' ')?;
    if level == 0 {
        return None;
    }
    let n = (level + demote).min(6);
    Some(format!("<h{n}>{}</h{n}>\n", inline(title)))
}

fn fenced_code(lines: &[&str]) -> (usize, String) {
    let end = lines[1..]
        .iter()
        .position(|l| l.starts_with("```"))
        .map_or(lines.len(), |p| p + 1);
    let body: Vec<String> = lines[1..end].iter().map(|l| escape(l)).collect();
    let consumed = (end + 1).min(lines.len());
    (
        consumed,
        format!("<pre><code>{}</code></pre>\n", body.join("\n")),
    )
}

fn indented_code(lines: &[&str]) -> (usize, String) {
    let mut end = 0;
    while end < lines.len() && (lines[end].starts_with("    ") || lines[end].trim().is_empty()) {
        end += 1;
    }
    while end > 0 && lines[end - 1].trim().is_empty() {
        end -= 1;
    }
    let body: Vec<String> = lines[..end]
        .iter()
        .map(|l| escape(l.get(4..).unwrap_or("")))
        .collect();
    (end, format!("<pre>{}</pre>\n", body.join("\n")))
}

fn is_table(lines: &[&str]) -> bool {
    lines.len() > 1 && lines[0].starts_with('|') && lines[1].starts_with("| ---")
}

fn table(lines: &[&str]) -> (usize, String) {
    let end = lines
        .iter()
        .position(|l| !l.starts_with('|'))
        .unwrap_or(lines.len());
    let mut html = String::from("<table>\n");
    for (row, line) in lines[..end].iter().enumerate() {
        if row == 1 {
            continue;
        }
        let tag = if row == 0 { "th" } else { "td" };
        html += "<tr>";
        for cell in cells(line) {
            html += &format!("<{tag}>{}</{tag}>", inline(cell.trim()));
        }
        html += "</tr>\n";
    }
    (end, html + "</table>\n")
}

/// A table row's cells; `\|` is a literal bar.
fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    let mut cells = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                cells.last_mut().expect("one cell").push('|');
            }
            '|' => cells.push(String::new()),
            _ => cells.last_mut().expect("one cell").push(c),
        }
    }
    cells
}

/// Items start with "- "; their continuation lines are indented.
fn list(lines: &[&str]) -> (usize, String) {
    let mut items: Vec<String> = Vec::new();
    let mut end = 0;
    while end < lines.len() {
        let line = lines[end];
        if let Some(first) = line.strip_prefix("- ") {
            items.push(first.to_string());
        } else if line.starts_with("  ") && !line.trim().is_empty() {
            let item = items.last_mut().expect("a continuation follows an item");
            item.push(' ');
            item.push_str(line.trim());
        } else {
            break;
        }
        end += 1;
    }
    let body: String = items
        .iter()
        .map(|item| format!("<li>{}</li>\n", inline(item)))
        .collect();
    (end, format!("<ul>\n{body}</ul>\n"))
}

/// Lines up to the next block; the first always belongs to the paragraph (a line such as
/// "#5" is text, and must not stop the paragraph before it starts).
fn paragraph(lines: &[&str]) -> (usize, String) {
    let end = 1 + lines[1..]
        .iter()
        .position(|l| {
            l.trim().is_empty() || l.starts_with('#') || l.starts_with("- ") || l.starts_with("```")
        })
        .unwrap_or(lines.len() - 1);
    let text: Vec<&str> = lines[..end].iter().map(|l| l.trim()).collect();
    (end, format!("<p>{}</p>\n", inline(&text.join(" "))))
}

/// Code spans, **strong**, *emphasis*, [links](target) and ![images](target) (as their
/// text) in one line of text.
fn inline(text: &str) -> String {
    let mut html = String::new();
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if let Some((consumed, piece)) = code_span(rest)
            .or_else(|| delimited(rest, "**", "strong"))
            .or_else(|| delimited(rest, "*", "em"))
            .or_else(|| link(rest))
        {
            html += &piece;
            rest = &rest[consumed..];
        } else {
            html += &escape(&c.to_string());
            rest = &rest[c.len_utf8()..];
        }
    }
    html
}

fn code_span(text: &str) -> Option<(usize, String)> {
    let body = text.strip_prefix('`')?;
    let end = body.find('`')?;
    Some((end + 2, format!("<code>{}</code>", escape(&body[..end]))))
}

/// `marker`…`marker` around text that neither starts nor ends with a space.
fn delimited(text: &str, marker: &str, tag: &str) -> Option<(usize, String)> {
    let body = text.strip_prefix(marker)?;
    let end = body.find(marker)?;
    let inner = &body[..end];
    if inner.is_empty() || inner.starts_with(' ') || inner.ends_with(' ') {
        return None;
    }
    Some((
        end + 2 * marker.len(),
        format!("<{tag}>{}</{tag}>", inline(inner)),
    ))
}

/// A link to the web stays a link; one to a file of the repository (which the FMU does
/// not carry) becomes its text.
fn link(text: &str) -> Option<(usize, String)> {
    let image = text.starts_with("![");
    let body = text.strip_prefix(if image { "![" } else { "[" })?;
    let close = body.find("](")?;
    let label = &body[..close];
    let target_end = body[close + 2..].find(')')?;
    let target = &body[close + 2..close + 2 + target_end];
    let consumed = text.len() - body.len() + close + 2 + target_end + 1;
    let piece = if target.starts_with("https://") && !image {
        format!("<a href=\"{}\">{}</a>", escape(target), inline(label))
    } else {
        inline(label)
    };
    Some((consumed, piece))
}

pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_the_subset_the_documents_use() {
        let text = "# Title\n\nA *b* **c** `d<e` [f](docs/x.md) [g](https://e.org).\n\n\
                    - one\n  two\n- three\n\n    code <x>\n\n| a | b \\| c |\n| --- | --- |\n| 1 | 2 |\n";
        assert_eq!(
            to_html(text, 1),
            "<h2>Title</h2>\n<p>A <em>b</em> <strong>c</strong> <code>d&lt;e</code> f \
             <a href=\"https://e.org\">g</a>.</p>\n<ul>\n<li>one two</li>\n<li>three</li>\n</ul>\n\
             <pre>code &lt;x&gt;</pre>\n<table>\n<tr><th>a</th><th>b | c</th></tr>\n\
             <tr><td>1</td><td>2</td></tr>\n</table>\n"
        );
    }

    #[test]
    fn a_hash_without_a_space_is_text() {
        assert_eq!(to_html("#5 is a number\n", 0), "<p>#5 is a number</p>\n");
    }
}
