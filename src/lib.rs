//! An FMI 2.0 and 3.0 unit (Co-Simulation and Model Exchange) for the cyclic mechanism of
//! `docs/model.md`.
//! ARCHITECTURE.md at the repository's root tells how the parts fit; from the top down:
//!
//! - [`fmi2`]: the FMI 2.0 C ABI; with `fmi3` and `abi` the crate's `unsafe` code, with
//!   two files of the instance (the master's logger, FMU state handles) and the drivers' AVX copy;
//! - [`fmi3`]: the FMI 3.0 C ABI over the same instance, and its model description;
//! - [`instance`]: one instance of either version: its restorable state, states and logger;
//! - [`description`]: what both versions' model descriptions share (names, log categories,
//!   the interface's hash, the XML writers);
//! - [`drivers`]: the co-simulation driver (the FMU's own integrator) and the Model Exchange
//!   adapter (the master's integrator), each over the plant;
//! - [`plant`]: the mechanism as a master sees it: variables, checks, outputs, derivatives;
//! - [`variables`]: the one table of FMI variables, from which both the value-reference
//!   dispatch and `modelDescription.xml` are derived;
//! - [`model`]: the mechanism alone (physics, constraint, projection, energy).
//!
//! The integrators, which know nothing of the mechanism, are the crate `integrators`
//! (`integrators/` at the repository's root), which the sweep's runner uses too.

#[cfg(feature = "fmi")]
mod abi;
pub mod description;
pub mod drivers;
#[cfg(feature = "fmi")]
pub mod fmi2;
#[cfg(feature = "fmi")]
pub mod fmi3;
#[cfg(feature = "fmi")]
pub mod instance;
pub mod model;
pub mod plant;
pub mod variables;
