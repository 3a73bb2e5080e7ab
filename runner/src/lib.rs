//! The one place in the project that loads an FMI 2.0 or 3.0 FMU: unpack
//! the archive ([`archive`]), read its description with quick-xml ([`description`]), load
//! its binary and own its instances, freed on drop, FMI 3.0's events handled on the way
//! ([`fmi`]); a Model Exchange FMU is integrated by the project's own DOP853 or Radau IIA and run as a
//! co-simulation unit ([`exchange`]); a coupled system of such FMUs
//! is stepped as one unit ([`system`], [`unit`]), its communication steps chosen by an
//! error estimate when it has a coupling tolerance ([`coupling`]). A point may ask instead
//! for its steady cycle, found by shooting on a Model Exchange instance or through a
//! co-simulation FMU's start values and its own sensitivities, with its Floquet
//! multipliers and modes ([`cycle`], planned by [`cycle_plan`]). The `fmu-runner` binary
//! serves sweep points over it ([`protocol`], [`plan`], [`point`], [`metrics`]); the
//! benchmark harness drives the packed FMU through the same types.

pub mod archive;
pub mod coupling;
pub mod cycle;
pub mod cycle_plan;
pub mod description;
pub mod exchange;
pub mod fmi;
pub mod messages;
pub mod metrics;
pub mod plan;
pub mod point;
pub mod protocol;
pub mod refusals;
pub mod stdio;
pub mod system;
pub mod target;
pub mod unit;
