//! FMI 2.0: the binary's functions and one instance's calls, for co-simulation and for
//! Model Exchange (whose integration is the runner's, `crate::exchange`).

use std::ffi::CString;
use std::path::Path;
use std::rc::Rc;

use fmi_sys::fmi2::{
    self, fmi2CallbackFunctions, fmi2Component, fmi2EventInfo, fmi2FMUstate,
    fmi2Type_fmi2CoSimulation, fmi2Type_fmi2ModelExchange, Fmi2Binding,
};

use super::{require, resources, EventUpdate, Interface, Status};
use crate::description::Description;

pub struct Library {
    binding: Fmi2Binding,
    interface: Interface,
    guid: CString,
    resource_uri: CString,
}

impl Library {
    /// The binary at `path` of the FMU unpacked in `dir`.
    pub fn load(
        path: &Path,
        dir: &Path,
        description: &Description,
        interface: Interface,
    ) -> Result<Rc<Library>, String> {
        // SAFETY: loading a shared library runs its initialisers; the FMU is trusted as
        // far as its binary goes (a crash there ends only this runner process).
        let binding = unsafe { Fmi2Binding::new(path) }
            .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        require(path, &functions(&binding, interface))?;
        let uri = format!("file://{}/", resources(dir).display());
        Ok(Rc::new(Library {
            binding,
            interface,
            guid: CString::new(description.guid.as_str()).map_err(|e| e.to_string())?,
            resource_uri: CString::new(uri).map_err(|e| e.to_string())?,
        }))
    }
}

impl Library {
    /// Whether the binary exports fmi2GetRealOutputDerivatives, and
    /// fmi2SetRealInputDerivatives (whatever its description declares).
    pub fn exports_derivatives(&self) -> (bool, bool) {
        (
            self.binding.fmi2GetRealOutputDerivatives.is_ok(),
            self.binding.fmi2SetRealInputDerivatives.is_ok(),
        )
    }
}

impl Library {
    /// Whether the binary exports fmi2GetFMUstate, fmi2SetFMUstate and fmi2FreeFMUstate
    /// (whatever its description declares).
    pub fn exports_state(&self) -> bool {
        let b = &self.binding;
        b.fmi2GetFMUstate.is_ok() && b.fmi2SetFMUstate.is_ok() && b.fmi2FreeFMUstate.is_ok()
    }
}

/// The functions a run through `interface` calls, and whether the binary has each; the
/// others may be absent.
fn functions(b: &Fmi2Binding, interface: Interface) -> Vec<(&'static str, bool)> {
    let mut present = vec![
        ("fmi2Instantiate", b.fmi2Instantiate.is_ok()),
        ("fmi2FreeInstance", b.fmi2FreeInstance.is_ok()),
        ("fmi2SetupExperiment", b.fmi2SetupExperiment.is_ok()),
        (
            "fmi2EnterInitializationMode",
            b.fmi2EnterInitializationMode.is_ok(),
        ),
        (
            "fmi2ExitInitializationMode",
            b.fmi2ExitInitializationMode.is_ok(),
        ),
        ("fmi2Reset", b.fmi2Reset.is_ok()),
        ("fmi2SetReal", b.fmi2SetReal.is_ok()),
        ("fmi2SetInteger", b.fmi2SetInteger.is_ok()),
        ("fmi2SetBoolean", b.fmi2SetBoolean.is_ok()),
        ("fmi2GetReal", b.fmi2GetReal.is_ok()),
        ("fmi2GetInteger", b.fmi2GetInteger.is_ok()),
        ("fmi2GetBoolean", b.fmi2GetBoolean.is_ok()),
    ];
    match interface {
        Interface::CoSimulation => present.push(("fmi2DoStep", b.fmi2DoStep.is_ok())),
        Interface::ModelExchange => present.extend([
            ("fmi2SetTime", b.fmi2SetTime.is_ok()),
            ("fmi2SetContinuousStates", b.fmi2SetContinuousStates.is_ok()),
            ("fmi2GetContinuousStates", b.fmi2GetContinuousStates.is_ok()),
            ("fmi2GetDerivatives", b.fmi2GetDerivatives.is_ok()),
            ("fmi2GetEventIndicators", b.fmi2GetEventIndicators.is_ok()),
            (
                "fmi2GetNominalsOfContinuousStates",
                b.fmi2GetNominalsOfContinuousStates.is_ok(),
            ),
            ("fmi2EnterEventMode", b.fmi2EnterEventMode.is_ok()),
            ("fmi2NewDiscreteStates", b.fmi2NewDiscreteStates.is_ok()),
            (
                "fmi2EnterContinuousTimeMode",
                b.fmi2EnterContinuousTimeMode.is_ok(),
            ),
            (
                "fmi2CompletedIntegratorStep",
                b.fmi2CompletedIntegratorStep.is_ok(),
            ),
        ]),
    }
    present
}

/// `fmi2Set…(vr, values)` for one type; nothing is called for an empty list.
macro_rules! setter {
    ($name:ident, $fmi:ident, $t:ty) => {
        pub fn $name(&mut self, vr: &[u32], values: &[$t]) -> Status {
            assert_eq!(vr.len(), values.len());
            if vr.is_empty() {
                return Status::Ok;
            }
            // SAFETY: both slices hold vr.len() elements; a live component.
            Status::from_code(unsafe {
                self.b()
                    .$fmi(self.component, vr.as_ptr(), vr.len(), values.as_ptr())
            })
        }
    };
}

/// `fmi2Get…(vr, values)` for one type; nothing is called for an empty list.
macro_rules! getter {
    ($name:ident, $fmi:ident, $t:ty) => {
        pub fn $name(&mut self, vr: &[u32], values: &mut [$t]) -> Status {
            assert_eq!(vr.len(), values.len());
            if vr.is_empty() {
                return Status::Ok;
            }
            // SAFETY: both slices hold vr.len() elements; a live component.
            Status::from_code(unsafe {
                self.b()
                    .$fmi(self.component, vr.as_ptr(), vr.len(), values.as_mut_ptr())
            })
        }
    };
}

/// One co-simulation instance; freed when dropped.
pub struct Instance {
    library: Rc<Library>,
    component: fmi2Component,
    /// The one FMU state this instance keeps (`save_state`), null until it is first taken;
    /// freed with the instance.
    saved: fmi2FMUstate,
    // The FMU may keep this pointer for its whole life (FMI 2.0 does not say it copies):
    // boxed so that its address is stable.
    _callbacks: Box<fmi2CallbackFunctions>,
}

impl Instance {
    /// An instance named `name` (the name the FMU's messages carry), of the library's
    /// interface.
    pub fn new(library: &Rc<Library>, name: &std::ffi::CStr) -> Result<Instance, String> {
        let kind = match library.interface {
            Interface::CoSimulation => fmi2Type_fmi2CoSimulation,
            Interface::ModelExchange => fmi2Type_fmi2ModelExchange,
        };
        let callbacks = Box::new(fmi2CallbackFunctions {
            logger: Some(fmi2::logger::callback_logger_handler),
            allocateMemory: Some(libc::calloc),
            freeMemory: Some(libc::free),
            stepFinished: None,
            componentEnvironment: std::ptr::null_mut(),
        });
        // SAFETY: every pointer is valid for the call; the callbacks outlive the instance.
        let component = unsafe {
            library.binding.fmi2Instantiate(
                name.as_ptr(),
                kind,
                library.guid.as_ptr(),
                library.resource_uri.as_ptr(),
                &*callbacks,
                0,
                0,
            )
        };
        if component.is_null() {
            return Err("fmi2Instantiate returned NULL".into());
        }
        Ok(Instance {
            library: Rc::clone(library),
            component,
            saved: std::ptr::null_mut(),
            _callbacks: callbacks,
        })
    }

    fn b(&self) -> &Fmi2Binding {
        &self.library.binding
    }

    pub fn reset(&mut self) -> Status {
        // SAFETY: a live component of this binding.
        Status::from_code(unsafe { self.b().fmi2Reset(self.component) })
    }

    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Status {
        let (defined, tol) = (tolerance.is_some() as i32, tolerance.unwrap_or(0.0));
        // SAFETY: a live component; plain values.
        Status::from_code(unsafe {
            self.b()
                .fmi2SetupExperiment(self.component, defined, tol, start, 1, stop)
        })
    }

    pub fn enter_initialization_mode(&mut self) -> Status {
        // SAFETY: a live component.
        Status::from_code(unsafe { self.b().fmi2EnterInitializationMode(self.component) })
    }

    pub fn exit_initialization_mode(&mut self) -> Status {
        // SAFETY: a live component.
        Status::from_code(unsafe { self.b().fmi2ExitInitializationMode(self.component) })
    }

    setter!(set_real, fmi2SetReal, f64);
    setter!(set_integer, fmi2SetInteger, i32);
    setter!(set_boolean, fmi2SetBoolean, i32);
    getter!(get_real, fmi2GetReal, f64);
    getter!(get_integer, fmi2GetInteger, i32);
    getter!(get_boolean, fmi2GetBoolean, i32);

    /// fmi2GetRealOutputDerivatives of output `vr`, orders 1 to `values.len()` (at most 2);
    /// Error when the FMU does not export the function.
    pub fn get_output_derivatives(&mut self, vr: u32, values: &mut [f64]) -> Status {
        let Ok(get) = self.b().fmi2GetRealOutputDerivatives.as_ref() else {
            return Status::Error;
        };
        let n = values.len().min(2);
        // SAFETY: the arrays hold n ≤ 2 elements; a live component of this binding.
        Status::from_code(unsafe {
            get(
                self.component,
                [vr; 2].as_ptr(),
                n,
                [1, 2].as_ptr(),
                values.as_mut_ptr(),
            )
        })
    }

    /// fmi2GetDirectionalDerivative: `sensitivity` = ∂unknowns/∂knowns · `seed`; Error
    /// when the FMU does not export the function.
    pub fn get_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Status {
        assert!(knowns.len() == seed.len() && unknowns.len() == sensitivity.len());
        let Ok(get) = self.b().fmi2GetDirectionalDerivative.as_ref() else {
            return Status::Error;
        };
        // SAFETY: each array holds the length passed with it; a live component.
        Status::from_code(unsafe {
            get(
                self.component,
                unknowns.as_ptr(),
                unknowns.len(),
                knowns.as_ptr(),
                knowns.len(),
                seed.as_ptr(),
                sensitivity.as_mut_ptr(),
            )
        })
    }

    /// fmi2SetRealInputDerivatives of input `vr`, orders 1 to `values.len()` (at most 2);
    /// Error when the FMU does not export the function.
    pub fn set_input_derivatives(&mut self, vr: u32, values: &[f64]) -> Status {
        let Ok(set) = self.b().fmi2SetRealInputDerivatives.as_ref() else {
            return Status::Error;
        };
        let n = values.len().min(2);
        // SAFETY: the arrays hold n ≤ 2 elements; a live component of this binding.
        Status::from_code(unsafe {
            set(
                self.component,
                [vr; 2].as_ptr(),
                n,
                [1, 2].as_ptr(),
                values.as_ptr(),
            )
        })
    }

    /// Take the FMU's state now into the instance's one saved state (the FMU overwrites
    /// the state it gave before, as FMI 2.0 lets a master ask); Error when the FMU does not
    /// export the function.
    pub fn save_state(&mut self) -> Status {
        let Ok(get) = self.b().fmi2GetFMUstate.as_ref() else {
            return Status::Error;
        };
        // SAFETY: a live component; `saved` is null or a state this component gave.
        Status::from_code(unsafe { get(self.component, &mut self.saved) })
    }

    /// Put the FMU back into the state last saved; Error when none was saved.
    pub fn restore_state(&mut self) -> Status {
        let Ok(set) = self.b().fmi2SetFMUstate.as_ref() else {
            return Status::Error;
        };
        if self.saved.is_null() {
            return Status::Error;
        }
        // SAFETY: a live component and a state it gave.
        Status::from_code(unsafe { set(self.component, self.saved) })
    }

    pub fn do_step(&mut self, time: f64, step: f64) -> Status {
        // SAFETY: a live component; plain values.
        Status::from_code(unsafe { self.b().fmi2DoStep(self.component, time, step, 1) })
    }
}

/// `fmi2…(component, array, length)` for one array call of Model Exchange.
macro_rules! array_call {
    ($name:ident, $fmi:ident, $ptr:ident, $t:ty) => {
        pub fn $name(&mut self, values: $t) -> Status {
            if values.is_empty() {
                return Status::Ok;
            }
            // SAFETY: the slice holds values.len() elements; a live component.
            Status::from_code(unsafe { self.b().$fmi(self.component, values.$ptr(), values.len()) })
        }
    };
}

/// Model Exchange: the calls of the runner's integration (`crate::exchange`).
impl Instance {
    pub fn set_time(&mut self, time: f64) -> Status {
        // SAFETY: a live component; a plain value.
        Status::from_code(unsafe { self.b().fmi2SetTime(self.component, time) })
    }

    array_call!(
        set_continuous_states,
        fmi2SetContinuousStates,
        as_ptr,
        &[f64]
    );
    array_call!(
        get_continuous_states,
        fmi2GetContinuousStates,
        as_mut_ptr,
        &mut [f64]
    );
    array_call!(get_derivatives, fmi2GetDerivatives, as_mut_ptr, &mut [f64]);
    array_call!(
        get_event_indicators,
        fmi2GetEventIndicators,
        as_mut_ptr,
        &mut [f64]
    );
    array_call!(
        get_nominals,
        fmi2GetNominalsOfContinuousStates,
        as_mut_ptr,
        &mut [f64]
    );

    pub fn enter_event_mode(&mut self) -> Status {
        // SAFETY: a live component.
        Status::from_code(unsafe { self.b().fmi2EnterEventMode(self.component) })
    }

    pub fn update_discrete_states(&mut self, update: &mut EventUpdate) -> Status {
        let mut info = fmi2EventInfo::default();
        // SAFETY: a live component; a writable event info.
        let s =
            Status::from_code(unsafe { self.b().fmi2NewDiscreteStates(self.component, &mut info) });
        *update = EventUpdate {
            again: info.newDiscreteStatesNeeded != 0,
            terminate: info.terminateSimulation != 0,
            nominals_changed: info.nominalsOfContinuousStatesChanged != 0,
            states_changed: info.valuesOfContinuousStatesChanged != 0,
            next_event_time: (info.nextEventTimeDefined != 0).then_some(info.nextEventTime),
        };
        s
    }

    pub fn enter_continuous_time_mode(&mut self) -> Status {
        // SAFETY: a live component.
        Status::from_code(unsafe { self.b().fmi2EnterContinuousTimeMode(self.component) })
    }

    /// fmi2CompletedIntegratorStep: whether the FMU asks for event mode, and to terminate.
    pub fn completed_integrator_step(&mut self, asks: &mut (bool, bool)) -> Status {
        let (mut event, mut terminate) = (0, 0);
        // SAFETY: a live component; writable locals.
        let s = Status::from_code(unsafe {
            self.b()
                .fmi2CompletedIntegratorStep(self.component, 1, &mut event, &mut terminate)
        });
        *asks = (event != 0, terminate != 0);
        s
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if let (false, Ok(free)) = (self.saved.is_null(), self.b().fmi2FreeFMUstate.as_ref()) {
            // SAFETY: a state this live component gave, freed once, before the component.
            unsafe { free(self.component, &mut self.saved) };
        }
        // SAFETY: the component was created by this binding and is freed exactly once.
        unsafe { self.b().fmi2FreeInstance(self.component) }
    }
}
