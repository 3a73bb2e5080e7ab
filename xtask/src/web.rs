//! `cargo xtask web` (the page in `target/web/`, built by [`crate::page`]) and
//! `cargo xtask bench-web` (the module against the native library, through the C master).

use std::fs;
use std::path::Path;
use std::process::Command;

use crate::cli::Parsed;
use crate::page::{build_page, build_wasm, ensure_node};
use crate::setup::{root, run, Result};

pub(crate) fn job(_: &Parsed) -> Result {
    let page = build_page()?;
    println!(
        "xtask: the page is in {}; open file://{} in a browser",
        page.parent()
            .map(Path::display)
            .map(|d| d.to_string())
            .unwrap_or_default(),
        page.display()
    );
    Ok(())
}

/// `cargo xtask bench-web`: paper case 1 stepped by the native library (the C master), by
/// the module under Node and in headless Chromium, the page's frame rate and pace, its
/// size and a screenshot, into `target/bench-web`.
pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    crate::setup::ensure_chromium()?;
    let page = build_page()?;
    let wasm = build_wasm()?;
    let node = ensure_node()?;
    let packed = crate::fmu::build_fmu(false)?;
    let out = root().join("target/bench-web");
    fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let description =
        crate::master::read_description(&root().join("target/fmu/assets/modelDescription.xml"))?;
    let master = crate::master::build_native_master(&out)?;
    let repeats = if parsed.has("quick") { 2 } else { 7 };
    let native = crate::master::paper_case_seconds(
        || Command::new(&master),
        &packed.linux64,
        &description,
        &out,
        repeats,
    )?;
    let script = root().join("web/node_master.mjs");
    let under_node = crate::master::paper_case_seconds(
        || {
            let mut command = Command::new(&node);
            command.arg(&script);
            command
        },
        &wasm,
        &description,
        &out,
        repeats,
    )?;
    let python = crate::builders::ensure_sweep_package()?;
    run(Command::new(python)
        .arg(root().join("bench/bench_web.py"))
        .arg(&page)
        .arg(&out)
        .args(["--native-seconds", &native.to_string()])
        .args(["--node-seconds", &under_node.to_string()])
        .args(parsed.flag_args()))
}
