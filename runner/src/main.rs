//! `fmu-runner serve DIR`: load the FMU (FMI 2.0 or 3.0, Co-Simulation or Model Exchange)
//! or the coupled system unpacked in DIR and answer
//! requests on standard input (see `protocol`). The sweep's workers start one runner per
//! FMU and keep it for their whole life, so the per-point work never passes through
//! Python; a crash of the FMU ends only this process.

use std::io::BufWriter;
use std::path::Path;

use fmu_runner::{fmi, messages, protocol, stdio};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = match args.as_slice() {
        [_, command, dir] if command == "serve" => dir,
        _ => {
            eprintln!("usage: fmu-runner serve <directory of an unpacked FMI 2.0 or 3.0 FMU, or of a system>");
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
