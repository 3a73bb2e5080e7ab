//! Projection back onto the constraint manifold after each accepted step (SPEC §2,
//! "Projection"), and the consistent initial state (SPEC §3).

use super::kinematics::{
    assemble_rocker, closure, closure_with_gradient_from, constraint_terms, rotate,
};
use super::{ModelError, Parameters, State};

/// Newton iterations allowed for the position projection; two suffice after a step.
const MAX_POSITION_ITERATIONS: usize = 8;

/// Project onto the constraint manifold (SPEC §2, "Projection"): positions onto g(φ) = 0
/// with the mass-weighted minimum-norm correction Δφ = −J⁻¹Gᵀ·g/(G·J⁻¹·Gᵀ), iterated
/// (Newton along J⁻¹Gᵀ); then velocities onto B1·ω2 − C1·ω3 = 0 with the J-weighted
/// projection ω ← ω − J⁻¹Gᵀ(G·J⁻¹·Gᵀ)⁻¹·G·ω at the final positions. Only φ2, φ3, ω2, ω3
/// move. One pair of sin_cos serves the whole projection: Newton's corrections are tiny,
/// so each iteration rotates the previous sines and cosines by the change of the stored
/// angles ([`rotate`]). Returns g at the result; fails where G vanishes (a change point)
/// or Newton does not converge.
pub fn project(p: &Parameters, y: &mut State) -> Result<f64, ModelError> {
    let tolerance = 4.0 * f64::EPSILON * p.L * p.L;
    let (mut sc2, mut sc3) = (y[1].sin_cos(), y[2].sin_cos());
    for iteration in 0..=MAX_POSITION_ITERATIONS {
        let (g, b1, c1) = closure_with_gradient_from(p, sc2, sc3);
        let weight = b1 * b1 / p.J2 + c1 * c1 / p.J3;
        let converged = g.abs() <= tolerance
            || iteration == MAX_POSITION_ITERATIONS && g.abs() <= 1e3 * tolerance;
        if converged {
            let scale = (b1 * y[5] - c1 * y[6]) / weight;
            if scale.is_finite() {
                y[5] -= b1 / p.J2 * scale;
                y[6] += c1 / p.J3 * scale;
            }
            return Ok(g);
        }
        let scale = g / weight;
        if !scale.is_finite() {
            break;
        }
        let (old2, old3) = (y[1], y[2]);
        y[1] -= b1 / p.J2 * scale;
        y[2] += c1 / p.J3 * scale;
        // The differences of the stored angles are exact: the sines and cosines match them.
        sc2 = rotate(sc2, y[1] - old2, y[1]);
        sc3 = rotate(sc3, y[2] - old3, y[2]);
    }
    let g = closure(p, y[1], y[2]);
    Err(ModelError::new(format!(
        "position projection failed at phi2 = {}, phi3 = {}: closure residual {g:e}",
        y[1], y[2]
    )))
}

/// The consistent initial state of SPEC §3: φ3 from the assembly nearest `phi3_guess`,
/// the springs' initial twists, and ω3 = (B1/C1)·ω2.
pub fn initial_state(p: &Parameters) -> Result<State, ModelError> {
    p.validate()?;
    let phi2 = p.phi2_0;
    let phi3 = assemble_rocker(p, phi2, p.phi3_guess)?;
    let t = constraint_terms(p, phi2, phi3, 0.0, 0.0);
    // C1 tiny relative to its scale l3·(l2 + l) means rod and rocker are aligned.
    if t.c1.abs() <= 1e-9 * p.l3 * (p.l2 + p.l) {
        return Err(ModelError::new(format!(
            "the assembly at phi2_0 = {phi2} has C1 = {:e} (rod and rocker aligned): omega3(0) \
             is undetermined; change phi2_0, phi3_guess or the lengths l, l2, l3, L",
            t.c1
        )));
    }
    let omega3 = t.b1 / t.c1 * p.omega2_0;
    Ok([
        phi2 + p.twist12_0,
        phi2,
        phi3,
        phi3 - p.twist34_0,
        p.omega1_0,
        p.omega2_0,
        omega3,
        p.omega4_0,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn initial_state_defaults() {
        let y = initial_state(&Parameters::default()).unwrap();
        assert_eq!(y[0], 0.0);
        assert!((y[2] - 1.4873662401842818).abs() < 1e-15);
        assert_eq!(y[3], y[2]);
        assert_eq!(&y[4..], &[0.0; 4]);
    }

    #[test]
    fn initial_velocities_are_consistent() {
        let p = Parameters {
            phi2_0: 1.0,
            omega2_0: 3.0,
            twist12_0: 0.2,
            ..Parameters::default()
        };
        let y = initial_state(&p).unwrap();
        let t = constraint_terms(&p, y[1], y[2], 0.0, 0.0);
        assert!((t.b1 * y[5] - t.c1 * y[6]).abs() < 1e-15);
        assert_eq!(y[0], 1.2);
    }

    #[test]
    fn projection_restores_both_constraints() {
        let p = Parameters {
            omega2_0: 4.0,
            ..Parameters::default()
        };
        let mut y = initial_state(&p).unwrap();
        y[1] += 1e-5;
        y[2] -= 2e-5;
        y[5] += 1e-4;
        let before = y;
        project(&p, &mut y).unwrap();
        assert!(closure(&p, y[1], y[2]).abs() < 1e-15);
        let t = constraint_terms(&p, y[1], y[2], 0.0, 0.0);
        assert!((t.b1 * y[5] - t.c1 * y[6]).abs() < 1e-14);
        // Bodies 1 and 4 are not touched.
        assert_eq!(
            (y[0], y[3], y[4], y[7]),
            (before[0], before[3], before[4], before[7])
        );
    }

    #[test]
    fn bad_parameters_fail_initialisation_by_name() {
        let p = Parameters {
            J1: 0.0,
            ..Parameters::default()
        };
        assert!(initial_state(&p).unwrap_err().to_string().contains("J1"));
    }
}
