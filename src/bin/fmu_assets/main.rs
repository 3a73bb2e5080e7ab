//! Writes the FMU's generated files: `fmu-assets <dir>` writes
//! `<dir>/modelDescription.xml`, `<dir>/fmi3/modelDescription.xml` (FMI 3.0's) and
//! `<dir>/variables.md` (the table as the README shows it), all from the variable table,
//! `<dir>/reference/` (the default experiment's result and its fmi-ls-ref manifest), and
//! `<dir>/index.html`, the documentation inside the
//! FMU, from the repository's own documents: docs/fmu.md, the README's section on using
//! the FMU, docs/model.md and the variable table. Copies are committed under
//! `modelDescription/`, and `tests/generated_files.rs` fails when one is out of date.

mod markdown;
mod reference;

use cyclic_mechanism::description::{variable_rows, variables_markdown};
use cyclic_mechanism::fmi2::model_description::xml;
use std::path::PathBuf;

const GUIDE: &str = include_str!("../../../docs/fmu.md");
const README: &str = include_str!("../../../README.md");
const MODEL: &str = include_str!("../../../docs/model.md");
/// The README's section that the FMU's documentation shows too.
const README_SECTION: &str = "## Using the FMU from FMPy";

fn main() {
    let Some(dir) = std::env::args().nth(1).map(PathBuf::from) else {
        eprintln!("usage: fmu-assets <output directory>");
        std::process::exit(2);
    };
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        let folder = path.parent().unwrap_or(&dir).to_path_buf();
        if let Err(error) =
            std::fs::create_dir_all(folder).and_then(|()| std::fs::write(&path, text))
        {
            eprintln!(
                "fmu-assets: cannot write {}: {error}",
                dir.join(name).display()
            );
            std::process::exit(1);
        }
    };
    write("modelDescription.xml", xml());
    write(
        "fmi3/modelDescription.xml",
        cyclic_mechanism::fmi3::model_description::xml(),
    );
    write("variables.md", variables_markdown());
    write("index.html", documentation());
    write(
        &format!("reference/{}", reference::RESULT),
        reference::result().unwrap_or_else(|e| {
            eprintln!("fmu-assets: the default experiment failed: {e}");
            std::process::exit(1);
        }),
    );
    write("reference/fmi-ls-manifest.xml", reference::manifest());
}

/// The FMU's documentation page.
fn documentation() -> String {
    let mut html = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>CyclicMechanism FMU</title>\n<style>\n\
         body { font-family: sans-serif; max-width: 60em; margin: 2em auto; line-height: 1.45; }\n\
         table { border-collapse: collapse; } td, th { border: 1px solid #bbb; padding: 0.2em 0.5em; text-align: left; }\n\
         code, pre { background: #f4f4f4; }\n</style>\n</head>\n<body>\n",
    );
    html += &markdown::to_html(GUIDE, 0);
    html += &markdown::to_html(readme_section(), 0);
    html += &markdown::to_html(MODEL, 1);
    html += "<h2>Variables</h2>\n";
    html += &variables_html();
    html + "\n</body>\n</html>\n"
}

/// [`README_SECTION`] of the README, up to the next section.
fn readme_section() -> &'static str {
    let Some(start) = README.find(README_SECTION) else {
        panic!("README.md has no section {README_SECTION:?}");
    };
    let rest = &README[start..];
    let end = rest[README_SECTION.len()..]
        .find("\n## ")
        .map_or(rest.len(), |e| e + README_SECTION.len() + 1);
    &rest[..end]
}

fn variables_html() -> String {
    let escape = markdown::escape;
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
