//! Integrators, generic over a small trait and ignorant of the problem they solve.
//! Fixed-size state (`[f64; N]`), no heap allocation while stepping.

pub mod dop853;
mod dop853_tableau;

pub use dop853::Dop853;

/// An ODE y' = f(t, y) on a manifold the system can project onto.
pub trait OdeSystem<const N: usize> {
    /// Evaluate f(t, y) into `dy`.
    fn rhs(&self, t: f64, y: &[f64; N], dy: &mut [f64; N]);

    /// Called on every accepted step's result `y` (the step started from `previous`): bring
    /// `y` back onto the manifold. Fails, saying why, when that is impossible or the step
    /// left the region where the solution is determined; the step is then an error.
    fn project(&self, _previous: &[f64; N], _y: &mut [f64; N]) -> Result<(), String> {
        Ok(())
    }
}

/// Error-control settings: a component's error is scaled by atol + rtol·|y_i|.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    pub rtol: f64,
    pub atol: f64,
}

/// Cumulative work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Statistics {
    /// Accepted steps.
    pub n_steps: u64,
    /// Rejected steps (error too large, or a non-finite stage).
    pub n_rejected: u64,
    /// Right-hand-side evaluations.
    pub n_rhs: u64,
}

/// Why an integration stopped short of its end time. The caller's state is left at the
/// last accepted step that succeeded.
#[derive(Clone, Debug, PartialEq)]
pub enum SolverError {
    /// The step size fell below what t's precision resolves.
    StepSizeTooSmall { t: f64, h: f64 },
    /// The system refused an accepted state (could not project it, or it is singular).
    ProjectionFailed { t: f64, reason: String },
    /// Too many steps in one call (a runaway).
    TooManySteps { t: f64, limit: u64 },
}

impl std::fmt::Display for SolverError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolverError::StepSizeTooSmall { t, h } => {
                write!(
                    f,
                    "step size {h:e} too small at t = {t} (stiff, singular or non-finite dynamics)"
                )
            }
            SolverError::ProjectionFailed { t, reason } => write!(f, "at t = {t}: {reason}"),
            SolverError::TooManySteps { t, limit } => {
                write!(f, "more than {limit} steps in one call, stopped at t = {t}")
            }
        }
    }
}

impl std::error::Error for SolverError {}
