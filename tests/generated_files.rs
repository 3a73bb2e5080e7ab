//! Generated files committed to the repository stay in sync with their sources:
//! `modelDescription/modelDescription.xml`, FMI 3.0's `modelDescription/fmi3/modelDescription.xml`
//! and the README's variable table (from the variable table), and `modelDescription/index.html`, the FMU's documentation (from
//! docs/fmu.md, the README and docs/model.md). Regenerate with
//! `cargo run --release --bin fmu-assets -- modelDescription` (and paste
//! `modelDescription/variables.md` into the README).

use cyclic_mechanism::description::variables_markdown;
use cyclic_mechanism::fmi2::model_description::xml;

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
fn committed_fmi3_model_description_is_the_generated_one() {
    assert!(
        read("modelDescription/fmi3/modelDescription.xml")
            == cyclic_mechanism::fmi3::model_description::xml(),
        "modelDescription/fmi3/modelDescription.xml is stale: run `cargo run --bin fmu-assets -- modelDescription`"
    );
}

#[test]
fn readme_shows_the_generated_variable_table() {
    assert!(
        read("README.md").contains(&variables_markdown()),
        "README.md's variable table differs from modelDescription/variables.md: paste the generated one"
    );
}

#[test]
fn committed_documentation_is_the_generated_one() {
    let dir = std::env::temp_dir().join(format!("fmu-assets-{}", std::process::id()));
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_fmu-assets"))
        .arg(&dir)
        .status()
        .expect("fmu-assets runs");
    assert!(status.success());
    let generated = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
    // The reference result too: a change of the default experiment's numbers shows here.
    let files = [
        "index.html",
        "reference/fmi-ls-manifest.xml",
        "reference/CyclicMechanism_out.csv",
    ];
    let stale: Vec<&str> = files
        .into_iter()
        .filter(|name| read(&format!("modelDescription/{name}")) != generated(name))
        .collect();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        stale.is_empty(),
        "modelDescription/{stale:?} stale: run `cargo run --release --bin fmu-assets -- modelDescription`"
    );
}
