//! What a sweep point drives, as its master loop sees it: the calls of [`Unit`], which one
//! FMU's instance implements here and a coupled system ([`crate::system`]) beside it. The
//! point's master loop, metrics and series do not tell them apart ([`crate::target`]).

use crate::coupling::CouplingRecord;
use crate::fmi::{each_call, Instance, Status};

/// The co-simulation calls of a point's master loop, in FMI 2.0's words (an FMI 3.0
/// instance maps them onto its own calls).
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
    /// The events met since the unit was made or last reset (FMI 3.0 components in event
    /// mode; 0 for anything else).
    fn events(&self) -> u64;
    /// What a point's steps reported of the coupling, for a system with a coupling
    /// tolerance; None for anything else.
    fn coupling(&self) -> Option<CouplingRecord> {
        None
    }
    /// For a system with a coupling tolerance: an input that moves on from its value along
    /// `slope` over the steps to come, where its component interpolates inputs (held
    /// otherwise). Not called on anything else.
    fn set_input_slope(&mut self, _vr: u32, _slope: f64) -> Status {
        Status::Ok
    }
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

    fn events(&self) -> u64 {
        Instance::events(self)
    }
}
