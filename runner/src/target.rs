//! What the runner loaded and runs, whichever it is: one FMU, or a coupled system of FMUs.
//! Above both [`crate::unit`] (the calls) and [`crate::system`] (a system's
//! implementation of them), which import nothing from here.

use std::rc::Rc;

use crate::coupling::CouplingRecord;
use crate::exchange::{ExchangeRun, Shape};
use crate::fmi::each_call;
use crate::fmi::{Instance, Library, Status};
use crate::system::{SystemInstance, SystemLibrary};
use crate::unit::Unit;

/// What the runner loaded: one FMU's library (co-simulation, or Model Exchange that the
/// runner integrates), or a system's.
#[derive(Clone)]
pub enum Target {
    Fmu(Rc<Library>),
    Exchange(Rc<Library>, Shape),
    System(Rc<SystemLibrary>),
}

impl Target {
    /// A new instance of the target.
    pub fn instantiate(&self) -> Result<Running, String> {
        Ok(match self {
            Target::Fmu(library) => Running::Fmu(Instance::new(library, c"sweep")?),
            Target::Exchange(library, shape) => Running::Exchange(ExchangeRun::new(
                Instance::new(library, c"sweep")?,
                shape.clone(),
            )),
            Target::System(system) => Running::System(SystemInstance::new(system)?),
        })
    }
}

/// An instance of a [`Target`]. Dispatched by a match, not a virtual call: a single FMU's
/// calls on the runner's per-step path stay direct (and inlinable), as without systems.
pub enum Running {
    Fmu(Instance),
    Exchange(ExchangeRun),
    System(SystemInstance),
}

/// Each call goes to the variant's method of the same name.
macro_rules! dispatch {
    ($($name:ident($($arg:ident: $t:ty),*)),* $(,)?) => {
        $(#[inline]
        fn $name(&mut self, $($arg: $t),*) -> Status {
            match self {
                Running::Fmu(unit) => Unit::$name(unit, $($arg),*),
                Running::Exchange(unit) => Unit::$name(unit, $($arg),*),
                Running::System(unit) => Unit::$name(unit, $($arg),*),
            }
        })*
    };
}

impl Running {
    /// What FMI 2.0 calls `fmi2_name`, as the running unit names it (a system, which may
    /// mix versions, names its components' calls in its own messages).
    pub fn call_name<'a>(&self, fmi2_name: &'a str) -> std::borrow::Cow<'a, str> {
        match self {
            Running::Fmu(instance) => instance.call_name(fmi2_name),
            Running::Exchange(unit) => unit.call_name(fmi2_name),
            // Its step is the system's own, over every component.
            Running::System(_) if fmi2_name == "fmi2DoStep" => {
                std::borrow::Cow::Borrowed("the coupled system's step")
            }
            Running::System(_) => std::borrow::Cow::Borrowed(fmi2_name),
        }
    }
}

impl Running {
    /// The first time derivatives of the outputs `vrs` into `rates`: a single FMU's
    /// output derivatives under co-simulation, or its directional derivatives along the
    /// flow under Model Exchange (`states` its continuous states); a system gives none
    /// (the plan asks for none there).
    pub fn get_rates(&mut self, vrs: &[u32], states: &[u32], rates: &mut [f64]) -> Status {
        match self {
            Running::Fmu(instance) => {
                for (vr, rate) in vrs.iter().zip(rates.chunks_mut(1)) {
                    let s = instance.get_output_derivatives(*vr, rate);
                    if !s.proceeds() {
                        return s;
                    }
                }
                Status::Ok
            }
            Running::Exchange(run) => run.rates(vrs, states, rates),
            Running::System(_) => Status::Error,
        }
    }
}

impl Unit for Running {
    each_call!(dispatch);

    fn events(&self) -> u64 {
        match self {
            Running::Fmu(unit) => unit.events(),
            Running::Exchange(unit) => unit.events(),
            Running::System(unit) => unit.events(),
        }
    }

    fn coupling(&self) -> Option<CouplingRecord> {
        match self {
            Running::Fmu(unit) => unit.coupling(),
            Running::Exchange(unit) => unit.coupling(),
            Running::System(unit) => unit.coupling(),
        }
    }

    fn set_input_slope(&mut self, vr: u32, slope: f64) -> Status {
        match self {
            Running::Fmu(unit) => unit.set_input_slope(vr, slope),
            Running::Exchange(unit) => unit.set_input_slope(vr, slope),
            Running::System(unit) => unit.set_input_slope(vr, slope),
        }
    }
}
