//! What a sweep point drives: one FMU's instance, or a coupled system of instances
//! ([`crate::system`]), through the same calls. The point's master loop, metrics and
//! series do not tell them apart.

use std::rc::Rc;

use crate::fmi::{Instance, Library, Status};
use crate::system::{SystemInstance, SystemLibrary};

/// The FMI 2.0 co-simulation calls of a point's master loop.
pub trait Unit {
    fn reset(&mut self) -> Status;
    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Status;
    fn enter_initialization_mode(&mut self) -> Status;
    fn exit_initialization_mode(&mut self) -> Status;
    fn set_real(&mut self, vr: &[u32], values: &[f64]) -> Status;
    fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> Status;
    fn set_boolean(&mut self, vr: &[u32], values: &[i32]) -> Status;
    fn get_real(&mut self, vr: &[u32], values: &mut [f64]) -> Status;
    fn get_integer(&mut self, vr: &[u32], values: &mut [i32]) -> Status;
    fn get_boolean(&mut self, vr: &[u32], values: &mut [i32]) -> Status;
    fn do_step(&mut self, time: f64, step: f64) -> Status;
}

/// `$implement!` over every call of [`Unit`], written once here.
macro_rules! each_call {
    ($implement:ident) => {
        $implement!(
            reset(),
            setup_experiment(tolerance: Option<f64>, start: f64, stop: f64),
            enter_initialization_mode(),
            exit_initialization_mode(),
            set_real(vr: &[u32], values: &[f64]),
            set_integer(vr: &[u32], values: &[i32]),
            set_boolean(vr: &[u32], values: &[i32]),
            get_real(vr: &[u32], values: &mut [f64]),
            get_integer(vr: &[u32], values: &mut [i32]),
            get_boolean(vr: &[u32], values: &mut [i32]),
            do_step(time: f64, step: f64),
        );
    };
}

/// Each call goes to the instance's method of the same name.
macro_rules! delegate {
    ($($name:ident($($arg:ident: $t:ty),*)),* $(,)?) => {
        $(fn $name(&mut self, $($arg: $t),*) -> Status {
            Instance::$name(self, $($arg),*)
        })*
    };
}

impl Unit for Instance {
    each_call!(delegate);
}

/// What the runner loaded: one FMU's library, or a system's.
#[derive(Clone)]
pub enum Target {
    Fmu(Rc<Library>),
    System(Rc<SystemLibrary>),
}

impl Target {
    /// A new instance of the target.
    pub fn instantiate(&self) -> Result<Running, String> {
        Ok(match self {
            Target::Fmu(library) => Running::Fmu(Instance::new(library, c"sweep")?),
            Target::System(system) => Running::System(SystemInstance::new(system)?),
        })
    }
}

/// An instance of a [`Target`]. Dispatched by a match, not a virtual call: a single FMU's
/// calls on the runner's per-step path stay direct (and inlinable), as without systems.
pub enum Running {
    Fmu(Instance),
    System(SystemInstance),
}

/// Each call goes to the variant's method of the same name.
macro_rules! dispatch {
    ($($name:ident($($arg:ident: $t:ty),*)),* $(,)?) => {
        $(#[inline]
        fn $name(&mut self, $($arg: $t),*) -> Status {
            match self {
                Running::Fmu(unit) => Unit::$name(unit, $($arg),*),
                Running::System(unit) => Unit::$name(unit, $($arg),*),
            }
        })*
    };
}

impl Unit for Running {
    each_call!(dispatch);
}
