//! FMI 3.0: the binary's functions and one instance's calls, for co-simulation and for
//! Model Exchange (whose integration is the runner's, `crate::exchange`). In co-simulation
//! the instance is its own master for what FMI 3.0 adds: it uses the FMU's event mode when the FMU has
//! one, so that a step that meets an event ends early, the event is handled
//! (`fmi3EnterEventMode`, `fmi3UpdateDiscreteStates` until the FMU needs no further
//! iteration, `fmi3EnterStepMode`) and the step goes on from where it ended; a caller
//! asks for a step as under FMI 2.0 and learns how many events it met.

use std::ffi::CStr;
use std::rc::Rc;

use fmi_sys::fmi3::{fmi3FMUState, fmi3Instance, Fmi3Binding};

use super::{EventUpdate, Interface, Status};

/// The most early returns one communication step may take, and the most event iterations
/// one event: an FMU past either is looping, and the point fails with that reason rather
/// than run on.
const MAX_EARLY_RETURNS: u32 = 100_000;
const MAX_EVENT_ITERATIONS: u32 = 1_000;

mod library;

pub use library::Library;
use library::{instantiate_co_simulation, instantiate_model_exchange, keep_status_messages};

/// One instance; freed when dropped.
pub struct Instance {
    library: Rc<Library>,
    instance: fmi3Instance,
    /// The one FMU state this instance keeps (`save_state`), null until it is first taken.
    saved: fmi3FMUState,
    /// What `setup_experiment` was told, passed on at `fmi3EnterInitializationMode` (FMI 3.0
    /// has no separate set-up call).
    experiment: (Option<f64>, f64, f64),
    /// Events handled since the instance was made or last reset.
    events: u64,
    /// Initialised and in step mode (until reset): a tunable parameter is set in event mode.
    stepping: bool,
    /// Booleans as FMI 3.0 passes them (one byte each), for the callers' 0/1 integers.
    booleans: Vec<bool>,
}

impl Instance {
    /// An instance named `name` (the name the FMU's messages carry), of the library's
    /// interface.
    pub fn new(library: &Rc<Library>, name: &CStr) -> Result<Instance, String> {
        let instance = match library.interface {
            Interface::CoSimulation => instantiate_co_simulation(library, name),
            Interface::ModelExchange => instantiate_model_exchange(library, name),
        };
        if instance.is_null() {
            return Err(format!(
                "fmi3Instantiate{} returned NULL",
                match library.interface {
                    Interface::CoSimulation => "CoSimulation",
                    Interface::ModelExchange => "ModelExchange",
                }
            ));
        }
        keep_status_messages(library, instance);
        Ok(Instance {
            library: Rc::clone(library),
            instance,
            saved: std::ptr::null_mut(),
            experiment: (None, 0.0, 0.0),
            events: 0,
            stepping: false,
            booleans: Vec::new(),
        })
    }

    fn b(&self) -> &Fmi3Binding {
        &self.library.binding
    }

    pub fn events(&self) -> u64 {
        self.events
    }

    pub fn reset(&mut self) -> Status {
        self.events = 0;
        self.stepping = false;
        // SAFETY: a live instance of this binding.
        Status::from_code(unsafe { self.b().fmi3Reset(self.instance) })
    }

    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Status {
        self.experiment = (tolerance, start, stop);
        Status::Ok
    }

    pub fn enter_initialization_mode(&mut self) -> Status {
        let (tolerance, start, stop) = self.experiment;
        // SAFETY: a live instance; plain values.
        Status::from_code(unsafe {
            self.b().fmi3EnterInitializationMode(
                self.instance,
                tolerance.is_some(),
                tolerance.unwrap_or(0.0),
                start,
                true,
                stop,
            )
        })
    }

    /// Leave initialisation; with event mode used, the FMU is then in event mode, and its
    /// initial event is handled here, so that the instance is ready to step.
    pub fn exit_initialization_mode(&mut self) -> Status {
        // SAFETY: a live instance.
        let s = Status::from_code(unsafe { self.b().fmi3ExitInitializationMode(self.instance) });
        if !s.proceeds() || !self.library.event_mode {
            self.stepping = s.proceeds();
            return s;
        }
        let s = s.max(self.settle_and_step());
        self.stepping = s.proceeds();
        s
    }

    /// Float64 values; once stepping with event mode, a tunable parameter among them is
    /// set in event mode (entered for it, its discrete states settled, back to step mode),
    /// as FMI 3.0 allows it there only.
    pub fn set_real(&mut self, vr: &[u32], values: &[f64]) -> Status {
        let tunable = |r: &u32| self.library.tunable.binary_search(r).is_ok();
        if self.stepping && self.library.event_mode && vr.iter().any(tunable) {
            // SAFETY: a live instance in step mode.
            let s = Status::from_code(unsafe { self.b().fmi3EnterEventMode(self.instance) });
            if !s.proceeds() {
                return s;
            }
            let s = s.max(self.set_float64(vr, values));
            if !s.proceeds() {
                return s;
            }
            return s.max(self.settle_and_step());
        }
        self.set_float64(vr, values)
    }

    fn set_float64(&mut self, vr: &[u32], values: &[f64]) -> Status {
        assert_eq!(vr.len(), values.len());
        if vr.is_empty() {
            return Status::Ok;
        }
        // SAFETY: both slices hold vr.len() elements; a live instance.
        Status::from_code(unsafe {
            self.b().fmi3SetFloat64(
                self.instance,
                vr.as_ptr(),
                vr.len(),
                values.as_ptr(),
                values.len(),
            )
        })
    }

    pub fn get_real(&mut self, vr: &[u32], values: &mut [f64]) -> Status {
        assert_eq!(vr.len(), values.len());
        if vr.is_empty() {
            return Status::Ok;
        }
        // SAFETY: both slices hold vr.len() elements; a live instance.
        Status::from_code(unsafe {
            self.b().fmi3GetFloat64(
                self.instance,
                vr.as_ptr(),
                vr.len(),
                values.as_mut_ptr(),
                values.len(),
            )
        })
    }

    /// Int32 variables through fmi3SetInt32, enumerations through fmi3SetInt64: one call
    /// for them all where none is an enumeration (the common case), else one per value.
    pub fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> Status {
        assert_eq!(vr.len(), values.len());
        if !vr.iter().any(|&r| self.is_int64(r)) {
            if vr.is_empty() {
                return Status::Ok;
            }
            // SAFETY: both slices hold vr.len() elements; a live instance.
            return Status::from_code(unsafe {
                self.b().fmi3SetInt32(
                    self.instance,
                    vr.as_ptr(),
                    vr.len(),
                    values.as_ptr(),
                    values.len(),
                )
            });
        }
        let mut worst = Status::Ok;
        for (&r, &x) in vr.iter().zip(values) {
            // SAFETY: one value for one reference; a live instance.
            let s = Status::from_code(unsafe {
                if self.is_int64(r) {
                    self.b()
                        .fmi3SetInt64(self.instance, &r, 1, &i64::from(x), 1)
                } else {
                    self.b().fmi3SetInt32(self.instance, &r, 1, &x, 1)
                }
            });
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
        worst
    }

    /// Int32 variables through fmi3GetInt32, enumerations through fmi3GetInt64, as
    /// `set_integer` sets them (a value beyond 32 bits is an error: the runner's integers
    /// are 32-bit).
    pub fn get_integer(&mut self, vr: &[u32], values: &mut [i32]) -> Status {
        assert_eq!(vr.len(), values.len());
        if !vr.iter().any(|&r| self.is_int64(r)) {
            if vr.is_empty() {
                return Status::Ok;
            }
            // SAFETY: both slices hold vr.len() elements; a live instance.
            return Status::from_code(unsafe {
                self.b().fmi3GetInt32(
                    self.instance,
                    vr.as_ptr(),
                    vr.len(),
                    values.as_mut_ptr(),
                    values.len(),
                )
            });
        }
        let mut worst = Status::Ok;
        for (&r, slot) in vr.iter().zip(values.iter_mut()) {
            let s = if self.is_int64(r) {
                let mut wide = 0_i64;
                // SAFETY: one value for one reference; a live instance.
                let s = Status::from_code(unsafe {
                    self.b().fmi3GetInt64(self.instance, &r, 1, &mut wide, 1)
                });
                let Ok(x) = i32::try_from(wide) else {
                    log::error!("value reference {r} = {wide} does not fit 32 bits");
                    return Status::Error;
                };
                *slot = x;
                s
            } else {
                // SAFETY: one value for one reference; a live instance.
                Status::from_code(unsafe { self.b().fmi3GetInt32(self.instance, &r, 1, slot, 1) })
            };
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
        }
        worst
    }

    fn is_int64(&self, vr: u32) -> bool {
        self.library.int64.binary_search(&vr).is_ok()
    }

    pub fn set_boolean(&mut self, vr: &[u32], values: &[i32]) -> Status {
        assert_eq!(vr.len(), values.len());
        if vr.is_empty() {
            return Status::Ok;
        }
        self.booleans.clear();
        self.booleans.extend(values.iter().map(|&b| b != 0));
        // SAFETY: both arrays hold vr.len() elements; a live instance.
        Status::from_code(unsafe {
            self.b().fmi3SetBoolean(
                self.instance,
                vr.as_ptr(),
                vr.len(),
                self.booleans.as_ptr(),
                vr.len(),
            )
        })
    }

    pub fn get_boolean(&mut self, vr: &[u32], values: &mut [i32]) -> Status {
        assert_eq!(vr.len(), values.len());
        if vr.is_empty() {
            return Status::Ok;
        }
        self.booleans.clear();
        self.booleans.resize(vr.len(), false);
        let read = self.booleans.as_mut_ptr();
        // SAFETY: both arrays hold vr.len() elements; a live instance.
        let s = Status::from_code(unsafe {
            self.b()
                .fmi3GetBoolean(self.instance, vr.as_ptr(), vr.len(), read, vr.len())
        });
        for (slot, &b) in values.iter_mut().zip(&self.booleans) {
            *slot = i32::from(b);
        }
        s
    }

    /// fmi3GetOutputDerivatives of output `vr`, orders 1 to `values.len()` (at most 2);
    /// Error when the FMU does not export the function.
    pub fn get_output_derivatives(&mut self, vr: u32, values: &mut [f64]) -> Status {
        let Ok(get) = self.b().fmi3GetOutputDerivatives.as_ref() else {
            return Status::Error;
        };
        let n = values.len().min(2);
        // SAFETY: the arrays hold n ≤ 2 elements; a live instance of this binding.
        Status::from_code(unsafe {
            get(
                self.instance,
                [vr; 2].as_ptr(),
                n,
                [1, 2].as_ptr(),
                values.as_mut_ptr(),
                n,
            )
        })
    }

    /// fmi3GetDirectionalDerivative: `sensitivity` = ∂unknowns/∂knowns · `seed` (scalar
    /// variables only); Error when the FMU does not export the function.
    pub fn get_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Status {
        assert!(knowns.len() == seed.len() && unknowns.len() == sensitivity.len());
        let Ok(get) = self.b().fmi3GetDirectionalDerivative.as_ref() else {
            return Status::Error;
        };
        // SAFETY: each array holds the length passed with it; a live instance.
        Status::from_code(unsafe {
            get(
                self.instance,
                unknowns.as_ptr(),
                unknowns.len(),
                knowns.as_ptr(),
                knowns.len(),
                seed.as_ptr(),
                seed.len(),
                sensitivity.as_mut_ptr(),
                sensitivity.len(),
            )
        })
    }

    /// FMI 3.0 has no input derivatives: always Error (a system never asks, as its
    /// library says it has none).
    pub fn set_input_derivatives(&mut self, _vr: u32, _values: &[f64]) -> Status {
        Status::Error
    }

    /// Take the FMU's state now into the instance's one saved state (overwritten in
    /// place, as FMI 3.0 lets a master ask); Error when the FMU does not export it.
    pub fn save_state(&mut self) -> Status {
        let Ok(get) = self.b().fmi3GetFMUState.as_ref() else {
            return Status::Error;
        };
        // SAFETY: a live instance; `saved` is null or a state this instance gave.
        Status::from_code(unsafe { get(self.instance, &mut self.saved) })
    }

    /// Put the FMU back into the state last saved; Error when none was saved.
    pub fn restore_state(&mut self) -> Status {
        let Ok(set) = self.b().fmi3SetFMUState.as_ref() else {
            return Status::Error;
        };
        if self.saved.is_null() {
            return Status::Error;
        }
        // SAFETY: a live instance and a state it gave.
        Status::from_code(unsafe { set(self.instance, self.saved) })
    }

    /// One communication step from `time` to `time + step`, through every early return
    /// and event on the way: after an early return the step goes on from the FMU's
    /// lastSuccessfulTime. An FMU that asks to terminate ends the point with Discard and
    /// a message that says when.
    pub fn do_step(&mut self, time: f64, step: f64) -> Status {
        let end = time + step;
        let mut now = time;
        let mut worst = Status::Ok;
        for _ in 0..MAX_EARLY_RETURNS {
            let (mut event, mut terminate, mut early, mut last) = (false, false, false, now);
            // SAFETY: a live instance; the four flags and the time are writable locals.
            let s = Status::from_code(unsafe {
                self.b().fmi3DoStep(
                    self.instance,
                    now,
                    end - now,
                    false,
                    &mut event,
                    &mut terminate,
                    &mut early,
                    &mut last,
                )
            });
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
            if terminate {
                log::trace!("the FMU asked to terminate the simulation at t = {last}");
                return Status::Discard;
            }
            if event {
                let s = self.handle_event();
                if !s.proceeds() {
                    return s;
                }
                worst = worst.max(s);
            }
            if !early || last >= end {
                return worst;
            }
            if !last.is_finite() || (last <= now && !event) {
                log::error!(
                    "fmi3DoStep returned early at t = {now} without advancing \
                     (lastSuccessfulTime = {last})"
                );
                return Status::Error;
            }
            now = last;
        }
        log::error!(
            "fmi3DoStep returned early more than {MAX_EARLY_RETURNS} times in the step from t = {time}"
        );
        Status::Error
    }

    /// The event the FMU asked for: event mode, its discrete states settled, step mode.
    fn handle_event(&mut self) -> Status {
        self.events += 1;
        // SAFETY: a live instance in step mode.
        let s = Status::from_code(unsafe { self.b().fmi3EnterEventMode(self.instance) });
        if !s.proceeds() {
            return s;
        }
        s.max(self.settle_and_step())
    }

    /// In event mode: fmi3UpdateDiscreteStates until the FMU needs no further iteration,
    /// then fmi3EnterStepMode.
    fn settle_and_step(&mut self) -> Status {
        let mut worst = Status::Ok;
        let mut update = EventUpdate::default();
        for _ in 0..MAX_EVENT_ITERATIONS {
            let s = self.update_discrete_states(&mut update);
            if !s.proceeds() {
                return s;
            }
            worst = worst.max(s);
            if update.terminate {
                log::trace!("the FMU asked to terminate the simulation in event mode");
                return Status::Discard;
            }
            if !update.again {
                // SAFETY: a live instance in event mode.
                let s = Status::from_code(unsafe { self.b().fmi3EnterStepMode(self.instance) });
                return worst.max(s);
            }
        }
        log::error!(
            "the FMU's discrete states did not settle in {MAX_EVENT_ITERATIONS} event iterations"
        );
        Status::Error
    }
}

/// `fmi3…(instance, array, length)` for one array call of Model Exchange.
macro_rules! array_call {
    ($name:ident, $fmi:ident, $ptr:ident, $t:ty) => {
        pub fn $name(&mut self, values: $t) -> Status {
            if values.is_empty() {
                return Status::Ok;
            }
            // SAFETY: the slice holds values.len() elements; a live instance.
            Status::from_code(unsafe { self.b().$fmi(self.instance, values.$ptr(), values.len()) })
        }
    };
}

/// Model Exchange: the calls of the runner's integration (`crate::exchange`).
impl Instance {
    pub fn set_time(&mut self, time: f64) -> Status {
        // SAFETY: a live instance; a plain value.
        Status::from_code(unsafe { self.b().fmi3SetTime(self.instance, time) })
    }

    array_call!(
        set_continuous_states,
        fmi3SetContinuousStates,
        as_ptr,
        &[f64]
    );
    array_call!(
        get_continuous_states,
        fmi3GetContinuousStates,
        as_mut_ptr,
        &mut [f64]
    );
    array_call!(
        get_derivatives,
        fmi3GetContinuousStateDerivatives,
        as_mut_ptr,
        &mut [f64]
    );
    array_call!(
        get_event_indicators,
        fmi3GetEventIndicators,
        as_mut_ptr,
        &mut [f64]
    );
    array_call!(
        get_nominals,
        fmi3GetNominalsOfContinuousStates,
        as_mut_ptr,
        &mut [f64]
    );

    pub fn enter_event_mode(&mut self) -> Status {
        // SAFETY: a live instance.
        Status::from_code(unsafe { self.b().fmi3EnterEventMode(self.instance) })
    }

    pub fn update_discrete_states(&mut self, update: &mut EventUpdate) -> Status {
        let mut flags = [false; 5];
        let mut next_event_time = 0.0;
        let [again, terminate, nominals, values, next_defined] = &mut flags;
        // SAFETY: a live instance in event mode; writable locals.
        let s = Status::from_code(unsafe {
            self.b().fmi3UpdateDiscreteStates(
                self.instance,
                again,
                terminate,
                nominals,
                values,
                next_defined,
                &mut next_event_time,
            )
        });
        *update = EventUpdate {
            again: *again,
            terminate: *terminate,
            nominals_changed: *nominals,
            states_changed: *values,
            next_event_time: next_defined.then_some(next_event_time),
        };
        s
    }

    pub fn enter_continuous_time_mode(&mut self) -> Status {
        // SAFETY: a live instance.
        Status::from_code(unsafe { self.b().fmi3EnterContinuousTimeMode(self.instance) })
    }

    /// fmi3CompletedIntegratorStep: whether the FMU asks for event mode, and to terminate.
    pub fn completed_integrator_step(&mut self, asks: &mut (bool, bool)) -> Status {
        let (mut event, mut terminate) = (false, false);
        // SAFETY: a live instance; writable locals.
        let s = Status::from_code(unsafe {
            self.b()
                .fmi3CompletedIntegratorStep(self.instance, true, &mut event, &mut terminate)
        });
        *asks = (event, terminate);
        s
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if let (false, Ok(free)) = (self.saved.is_null(), self.b().fmi3FreeFMUState.as_ref()) {
            // SAFETY: a state this live instance gave, freed once, before the instance.
            unsafe { free(self.instance, &mut self.saved) };
        }
        // SAFETY: the instance was created by this binding and is freed exactly once.
        unsafe { self.b().fmi3FreeInstance(self.instance) }
    }
}
