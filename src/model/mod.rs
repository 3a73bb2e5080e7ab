//! The mechanism alone (docs/model.md): parameters, state, right-hand side, constraint,
//! projection, assembly and energy. Pure Rust; it knows nothing of FMI or of the solver
//! that drives it.

pub mod change_point;
pub mod chart;
pub mod dual_vector;
pub mod dynamics;
pub mod kinematics;
pub mod linkage;
pub mod params;
pub mod projection;
pub mod scalar;
pub mod sensitivity;
pub mod trig;

pub use chart::{Chart, Coordinates, Independent};
pub use dual_vector::DualVector;
pub use dynamics::{accelerations, energy, power, rod_force, shift_inputs, state_derivative};
pub use kinematics::{length_residual, length_residual_from_closure};
pub use linkage::{classify, LinkageClass, LINKAGE_CLASSES};
pub use params::{Parameters, PARAMETERS};
pub use projection::{check_passage, initial_state, project, Projected};
pub use scalar::{Dual, Scalar};

/// The state vector y = (φ1, φ2, φ3, φ4, ω1, ω2, ω3, ω4).
pub type State = [f64; 8];

/// Number of state components.
pub const STATE_SIZE: usize = 8;

/// The external torques: the FMU inputs M_m and M_r (N·m), held over a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs<T = f64> {
    pub motor_torque: T,
    pub load_torque: T,
}

/// A model error: the message says which variable and which rule.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelError(String);

impl ModelError {
    pub fn new(message: impl Into<String>) -> Self {
        Self(message.into())
    }
}

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ModelError {}
