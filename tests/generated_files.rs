//! Files generated from the variable table and committed to the repository stay in sync
//! with it: `modelDescription/modelDescription.xml` and the README's variable table.
//! Regenerate with `cargo run --bin fmu-assets -- modelDescription` (and paste
//! `modelDescription/variables.md` into the README).

use cyclic_mechanism::fmi2::model_description::{variables_markdown, xml};

fn read(path: &str) -> String {
    let full = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{}: {e}", full.display()))
}

#[test]
fn committed_model_description_is_the_generated_one() {
    assert!(
        read("modelDescription/modelDescription.xml") == xml(),
        "modelDescription/modelDescription.xml is stale: run `cargo run --bin fmu-assets -- modelDescription`"
    );
}

#[test]
fn readme_shows_the_generated_variable_table() {
    assert!(
        read("README.md").contains(&variables_markdown()),
        "README.md's variable table differs from modelDescription/variables.md: paste the generated one"
    );
}
