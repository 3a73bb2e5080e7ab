//! Writes the FMU's generated files, all derived from the variable table:
//! `fmu-assets <dir>` writes `<dir>/modelDescription.xml`, `<dir>/index.html` (the
//! documentation, `documentation/index.html` with the variable table filled in) and
//! `<dir>/variables.md` (the table as the README shows it).

use cyclic_mechanism::fmi2::model_description::{variable_rows, variables_markdown, xml};
use std::path::PathBuf;

const DOCUMENTATION: &str = include_str!("../../documentation/index.html");
const PLACEHOLDER: &str = "<!-- VARIABLES -->";

fn main() {
    let Some(dir) = std::env::args().nth(1).map(PathBuf::from) else {
        eprintln!("usage: fmu-assets <output directory>");
        std::process::exit(2);
    };
    let write = |name: &str, text: String| {
        if let Err(error) =
            std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(dir.join(name), text))
        {
            eprintln!(
                "fmu-assets: cannot write {}: {error}",
                dir.join(name).display()
            );
            std::process::exit(1);
        }
    };
    write("modelDescription.xml", xml());
    write("variables.md", variables_markdown());
    write(
        "index.html",
        DOCUMENTATION.replace(PLACEHOLDER, &variables_html()),
    );
}

fn variables_html() -> String {
    let escape = |s: &str| {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    };
    let mut html = String::from(
        "<table>\n<tr><th>name</th><th>causality</th><th>unit</th><th>start</th><th>description</th></tr>\n",
    );
    for row in variable_rows() {
        html += "<tr>";
        for cell in row {
            html += &format!("<td>{}</td>", escape(&cell));
        }
        html += "</tr>\n";
    }
    html + "</table>"
}
