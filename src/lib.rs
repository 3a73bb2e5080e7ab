//! An FMI 2.0 unit (Co-Simulation and Model Exchange) for the cyclic mechanism of `docs/model.md`.
//!
//! - [`model`]: the mechanism alone (physics, constraint, projection, energy);
//! - [`solver`]: integrators that know nothing of the mechanism;
//! - [`variables`]: the one table of FMI variables, from which both the value-reference
//!   dispatch and `modelDescription.xml` are derived;
//! - [`simulation`]: a model instance with its solver, independent of the FMI interface;
//! - [`exchange`]: the same instance in independent coordinates, for a master's integrator;
//! - [`fmi2`]: the C ABI, the only `unsafe` code in the crate.

pub mod exchange;
pub mod fmi2;
pub mod model;
pub mod simulation;
pub mod snapshot;
pub mod solver;
pub mod text;
pub mod variables;
