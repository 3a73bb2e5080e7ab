//! `fmu-runner serve DIR`: load the FMU (FMI 2.0 or 3.0, Co-Simulation or Model Exchange)
//! or the coupled system unpacked in DIR and answer requests on standard input (see
//! `protocol`). The sweep's workers start one runner per FMU and keep it for their whole
//! life, so the per-point work never passes through Python; a crash of the FMU ends only
//! this process.
//!
//! `fmu-runner describe DIR`: print the description of the FMU unpacked in DIR as JSON,
//! read by the one reader of it (`fmi-description`) without loading its binary: what
//! fmusweep checks a system's components against before anything runs.
//!
//! `fmu-runner fields`: print, as JSON, the fields of the tables whose rules the runner
//! holds (a steady cycle's), for the docs' field tables.

use std::io::BufWriter;
use std::path::Path;

use fmu_runner::{fmi, messages, protocol, stdio};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = match args.as_slice() {
        [_, command, dir] if command == "serve" => dir,
        [_, command, dir] if command == "describe" => describe(Path::new(dir)),
        [_, command] if command == "fields" => {
            println!(
                "{}",
                serde_json::json!(fmu_runner::cycle_plan::declared_fields())
            );
            std::process::exit(0)
        }
        _ => {
            eprintln!(
                "usage: fmu-runner serve|describe <directory of an unpacked FMI 2.0 or 3.0 FMU, \
                 or of a system (serve)>, or fmu-runner fields"
            );
            std::process::exit(2);
        }
    };
    let protocol = match stdio::take_protocol_output() {
        Ok(file) => file,
        Err(e) => {
            eprintln!("fmu-runner: {e}");
            std::process::exit(1);
        }
    };
    let mut out = BufWriter::with_capacity(1 << 20, protocol);
    messages::install();
    let mut session = match protocol::Session::open(Path::new(dir)) {
        Ok(session) => session,
        Err(e) => {
            // The caller reads the reason from the protocol channel, then the exit code.
            use std::io::Write;
            let _ = writeln!(out, "{}", serde_json::json!({ "error": e }));
            let _ = out.flush();
            std::process::exit(1);
        }
    };
    {
        use std::io::Write;
        let _ = writeln!(out, "{}", serde_json::json!({ "ready": fmi::PLATFORM }));
        let _ = out.flush();
    }
    let stdin = std::io::stdin();
    if let Err(e) = session.serve(stdin.lock(), &mut out) {
        eprintln!("fmu-runner: {e}");
        std::process::exit(1);
    }
}

/// The description of the FMU unpacked in `dir`, as JSON on standard output; the reason it
/// cannot be read on standard error, and exit code 1.
fn describe(dir: &Path) -> ! {
    match fmu_runner::description::Description::read(dir) {
        Ok(description) => {
            println!("{}", serde_json::json!({ "description": description }));
            std::process::exit(0)
        }
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1)
        }
    }
}
