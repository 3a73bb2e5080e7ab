//! The packed FMU through its C ABI: unpack, load with libloading, run a master loop.

use std::ffi::CString;
use std::io::Read;
use std::path::Path;
use std::ptr::{null, null_mut};

use fmi_sys::fmi2::{
    fmi2CallbackFunctions, fmi2Component, fmi2Status_fmi2OK, fmi2Type_fmi2CoSimulation, Fmi2Binding,
};

use crate::{Run, Scenario};

pub struct Fmu {
    binding: Fmi2Binding,
    guid: CString,
    /// Value references by name, read from the packed modelDescription.xml.
    references: Vec<(String, u32)>,
    _unpacked: tempdir::Dir,
}

mod tempdir {
    /// A directory removed when dropped.
    pub struct Dir(pub std::path::PathBuf);
    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// `name="…"` and `valueReference="…"` pairs, and the GUID, from the model description.
fn parse_description(xml: &str) -> (String, Vec<(String, u32)>) {
    let attribute = |text: &str, name: &str| -> Option<String> {
        let start = text.find(&format!("{name}=\""))? + name.len() + 2;
        Some(text[start..start + text[start..].find('"')?].to_string())
    };
    let guid = attribute(xml, "guid").unwrap_or_default();
    let references = xml
        .split("<ScalarVariable")
        .skip(1)
        .filter_map(|v| {
            Some((
                attribute(v, "name")?,
                attribute(v, "valueReference")?.parse().ok()?,
            ))
        })
        .collect();
    (guid, references)
}

fn check(status: u32, what: &str) -> Option<()> {
    (status == fmi2Status_fmi2OK).then_some(()).or_else(|| {
        eprintln!("{what} returned status {status}");
        None
    })
}

impl Fmu {
    pub fn load(path: &Path) -> Result<Self, String> {
        let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
        let mut archive = zip::ZipArchive::new(file).map_err(|e| e.to_string())?;
        let mut xml = String::new();
        archive
            .by_name("modelDescription.xml")
            .map_err(|e| e.to_string())?
            .read_to_string(&mut xml)
            .map_err(|e| e.to_string())?;
        let (guid, references) = parse_description(&xml);
        let dir = std::env::temp_dir().join(format!("cyclic-bench-{}", std::process::id()));
        archive.extract(&dir).map_err(|e| e.to_string())?;
        let library = dir.join("binaries/linux64/CyclicMechanism.so");
        // SAFETY: loading the FMU's own library, whose initialisers are Rust's defaults.
        let binding = unsafe { Fmi2Binding::new(&library) }.map_err(|e| e.to_string())?;
        Ok(Self {
            binding,
            guid: CString::new(guid).map_err(|e| e.to_string())?,
            references,
            _unpacked: tempdir::Dir(dir),
        })
    }

    fn vr(&self, name: &str) -> u32 {
        self.references
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, vr)| *vr)
            .expect("variable in the description")
    }

    /// One simulation: instantiate, initialise, step with H to the stop time reading the
    /// eight states after every step and keeping them, as a master does.
    pub fn run(&self, scenario: &Scenario, h: f64, tol: f64) -> Option<Run> {
        let functions = fmi2CallbackFunctions {
            logger: None,
            allocateMemory: None,
            freeMemory: None,
            stepFinished: None,
            componentEnvironment: null_mut(),
        };
        let b = &self.binding;
        // SAFETY: FMI calls with valid arguments, on an instance created and freed here.
        unsafe {
            let c: fmi2Component = b.fmi2Instantiate(
                c"bench".as_ptr(),
                fmi2Type_fmi2CoSimulation,
                self.guid.as_ptr(),
                null(),
                &functions,
                0,
                0,
            );
            if c.is_null() {
                eprintln!("fmi2Instantiate failed");
                return None;
            }
            let outcome = self.simulate(c, scenario, h, tol);
            b.fmi2FreeInstance(c);
            outcome
        }
    }

    /// # Safety
    /// `c` must be a live instance of this binding.
    unsafe fn simulate(
        &self,
        c: fmi2Component,
        scenario: &Scenario,
        h: f64,
        tol: f64,
    ) -> Option<Run> {
        let b = &self.binding;
        let outputs: Vec<u32> = [
            "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
        ]
        .iter()
        .map(|n| self.vr(n))
        .collect();
        // t = 0 as the FMU reads it, below.
        let mut run = Run::start(scenario, h, &[0.0; 8]);
        unsafe {
            check(
                b.fmi2SetupExperiment(c, 1, tol, 0.0, 1, scenario.stop),
                "fmi2SetupExperiment",
            )?;
            check(
                b.fmi2EnterInitializationMode(c),
                "fmi2EnterInitializationMode",
            )?;
            for (name, value) in scenario.values {
                check(b.fmi2SetReal(c, &self.vr(name), 1, value), "fmi2SetReal")?;
            }
            check(
                b.fmi2SetInteger(c, &self.vr("solver"), 1, &scenario.solver),
                "fmi2SetInteger",
            )?;
            let laws = i32::from(scenario.builtin_laws);
            check(
                b.fmi2SetBoolean(c, &self.vr("builtin_laws"), 1, &laws),
                "fmi2SetBoolean",
            )?;
            check(
                b.fmi2ExitInitializationMode(c),
                "fmi2ExitInitializationMode",
            )?;
            check(
                b.fmi2GetReal(c, outputs.as_ptr(), 8, run.states[0].as_mut_ptr()),
                "fmi2GetReal",
            )?;
            for (k, y) in run.states.iter_mut().skip(1).enumerate() {
                check(b.fmi2DoStep(c, k as f64 * h, h, 1), "fmi2DoStep")?;
                check(
                    b.fmi2GetReal(c, outputs.as_ptr(), 8, y.as_mut_ptr()),
                    "fmi2GetReal",
                )?;
            }
        }
        let mut rhs = 0;
        unsafe {
            check(
                b.fmi2GetInteger(c, &self.vr("n_rhs"), 1, &mut rhs),
                "fmi2GetInteger",
            )?
        };
        run.n_rhs = rhs as u64;
        Some(run)
    }
}
