//! The reference result inside the archives (the FMI layered standard fmi-ls-ref): the
//! default experiment (the paper's case 1) run through the FMU's own instance as an FMI
//! 2.0 co-simulation master runs it, every Real output written as CSV, and the manifest
//! that names the file.

use cyclic_mechanism::description::DEFAULT_EXPERIMENT;
use cyclic_mechanism::instance::{Instance, Interface, Version};
use cyclic_mechanism::variables::{variables, Causality, VarType};
use std::ffi::CString;
use std::fmt::Write;

/// The CSV's name, beside the manifest (the archive's
/// `extra/org.fmi-standard.fmi-ls-ref/`).
pub const RESULT: &str = "CyclicMechanism_out.csv";
/// Every this many communication steps a row: the CSV stays small, and each row is a
/// communication point of the default experiment.
const STEPS_PER_ROW: u32 = 50;

/// The manifest of the layered standard, naming the result.
pub fn manifest() -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <fmiReferences\n    \
         xmlns:fmi-ls=\"http://fmi-standard.org/fmi-ls-manifest\"\n    \
         fmi-ls:fmi-ls-name=\"org.fmi-standard.fmi-ls-ref\"\n    \
         fmi-ls:fmi-ls-version=\"1.0.0-alpha.1\"\n    \
         fmi-ls:fmi-ls-description=\"Reference results of the CyclicMechanism FMU\">\n    \
         <Related type=\"text/csv\" source=\"{RESULT}\" role=\"result\" \
         description=\"Every Real output of the default experiment (the paper's case 1: \
         start values, no input), co-simulation with a communication step of {step} s and the \
         default tolerance, every {every} s\"/>\n\
         </fmiReferences>\n",
        step = DEFAULT_EXPERIMENT.2,
        every = DEFAULT_EXPERIMENT.2 * f64::from(STEPS_PER_ROW),
    )
}

/// The default experiment's Real outputs, a row every [`STEPS_PER_ROW`] communication
/// steps, as CSV with quoted names.
pub fn result() -> Result<String, String> {
    let (start, stop, step) = DEFAULT_EXPERIMENT;
    let outputs: Vec<(u32, &str)> = variables()
        .filter(|(_, v)| v.causality() == Causality::Output && v.var_type() == VarType::Real)
        .map(|(vr, v)| (vr, v.name))
        .collect();
    let vrs: Vec<u32> = outputs.iter().map(|&(vr, _)| vr).collect();
    let name = CString::new("reference").map_err(|e| e.to_string())?;
    let mut fmu = Instance::new(Interface::CoSimulation, Version::Fmi2, name, None, false);
    let failed =
        |what: &str, e: cyclic_mechanism::instance::Failure| format!("{what}: {}", e.message);
    fmu.setup_experiment(None, start, Some(stop))
        .map_err(|e| failed("setup", e))?;
    fmu.enter_initialization_mode()
        .map_err(|e| failed("initialisation", e))?;
    fmu.exit_initialization_mode()
        .map_err(|e| failed("initialisation", e))?;
    let mut csv = String::from("\"time\"");
    for (_, name) in &outputs {
        write!(csv, ",\"{name}\"").map_err(|e| e.to_string())?;
    }
    let steps = ((stop - start) / step).round() as u32;
    let mut values = vec![0.0; vrs.len()];
    for k in 0..=steps {
        let t = start + f64::from(k) * step;
        if k > 0 {
            let from = start + f64::from(k - 1) * step;
            fmu.do_step(from, t - from)
                .map_err(|e| failed(&format!("the step to t = {t}"), e))?;
        }
        if k % STEPS_PER_ROW == 0 {
            fmu.get_real(&vrs, &mut values)
                .map_err(|e| failed("reading the outputs", e))?;
            write!(csv, "\n{t}").map_err(|e| e.to_string())?;
            for value in &values {
                write!(csv, ",{value:e}").map_err(|e| e.to_string())?;
            }
        }
    }
    csv.push('\n');
    Ok(csv)
}
