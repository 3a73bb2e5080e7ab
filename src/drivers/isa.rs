//! Run the co-simulation step with the widest vector instructions the processor has, in a
//! binary built for the x86-64 baseline (SSE2) so that it loads on any x86-64 machine.
//!
//! [`advance`] calls a second copy of [`CoSimulation::advance`] compiled with AVX and POPCNT
//! (it and what is marked `#[inline(always)]` beneath it: the integrator's stages, the
//! right-hand side, the dense output and the projection) when the processor supports both.
//! Only the instruction encoding and the vector width change: Rust never fuses a
//! multiplication and an addition on its own, so both copies round alike and give the same
//! bits (tests/isa.rs compares them).

use super::{CoSimulation, Experiment};
use crate::plant::Plant;
use integrators::SolverError;

/// [`CoSimulation::advance`], through the AVX copy where the processor has AVX and POPCNT
/// (the stiffness test then counts the bits of its window in one instruction; both are
/// checked at run time). Inlined into its caller, so that a step enters only the copy it
/// runs.
#[inline]
pub fn advance(
    driver: &mut CoSimulation,
    plant: &mut Plant,
    t_end: f64,
    experiment: &Experiment,
) -> Result<(), SolverError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") && std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the processor supports AVX and POPCNT, the features `advance_avx` enables.
        return unsafe { advance_avx(driver, plant, t_end, experiment) };
    }
    advance_baseline(driver, plant, t_end, experiment)
}

/// The baseline copy behind a call of its own: inlined into [`advance`], its large frame
/// would be set up on every step, also where the AVX copy runs.
#[inline(never)]
fn advance_baseline(
    driver: &mut CoSimulation,
    plant: &mut Plant,
    t_end: f64,
    experiment: &Experiment,
) -> Result<(), SolverError> {
    driver.advance(plant, t_end, experiment)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,popcnt")]
fn advance_avx(
    driver: &mut CoSimulation,
    plant: &mut Plant,
    t_end: f64,
    experiment: &Experiment,
) -> Result<(), SolverError> {
    driver.advance(plant, t_end, experiment)
}
