//! `cargo xtask demo`: the paper's two cases through FMPy, with plots and an animation, and
//! a change-point linkage through FMI 3.0's event mode.

use std::process::Command;

use crate::cli::Parsed;
use crate::setup::Result;
use crate::setup::*;

pub(crate) fn job(_: &Parsed) -> Result {
    let packed = crate::fmu::build_fmu(false)?;
    let python = ensure_venv(Packages::Demo)?;
    let out = root().join("target/demo");
    run(Command::new(python)
        .arg(root().join("examples/demo.py"))
        .arg(&packed.fmu)
        .arg(&out)
        .arg(&packed.fmu3))
}
