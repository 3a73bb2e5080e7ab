//! `cargo xtask demo`: the paper's two cases through FMPy, with plots and an animation.

use std::process::Command;

use crate::cli::Parsed;
use crate::setup::*;
use crate::Result;

pub(crate) fn job(_: &Parsed) -> Result {
    let fmu = crate::fmu::build_fmu(false)?.fmu;
    let python = ensure_venv(Packages::Demo)?;
    let out = root().join("target/demo");
    run(Command::new(python)
        .arg(root().join("examples/demo.py"))
        .arg(&fmu)
        .arg(&out))
}
