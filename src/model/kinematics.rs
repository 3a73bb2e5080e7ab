//! Loop geometry (docs/model.md §1–§3): pin positions, the closure constraint g(φ), its gradient
//! G = [0, B1, −C1, 0] and time derivatives, and the assembly of a consistent start.

use super::trig::{sin_cos, sin_cos_pair};
use super::{ModelError, Parameters, Scalar};

/// Geometric terms of the constraint at one configuration (docs/model.md §2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstraintTerms<T = f64> {
    /// B1 = l2·(l·sin φ2 + l3·sin(φ2 − φ3)) = ∂g/∂φ2.
    pub b1: T,
    /// C1 = l3·(l2·sin(φ2 − φ3) + l·sin φ3) = −∂g/∂φ3.
    pub c1: T,
    /// Ḃ1 = l2·(l·cos φ2·ω2 + l3·cos(φ2 − φ3)·(ω2 − ω3)).
    pub b1_dot: T,
    /// Ċ1 = l3·(l2·cos(φ2 − φ3)·(ω2 − ω3) + l·cos φ3·ω3).
    pub c1_dot: T,
}

/// Evaluate B1, C1 (docs/model.md §2, [44]–[46]) and their time derivatives ([49]).
#[inline(always)]
pub fn constraint_terms<T: Scalar>(
    p: &Parameters,
    phi2: T,
    phi3: T,
    omega2: T,
    omega3: T,
) -> ConstraintTerms<T> {
    let [(s2, c2), (s3, c3)] = T::sin_cos_pair(phi2, phi3);
    // sin and cos of φ2 − φ3 from the two pairs above: saves a third sin_cos.
    let s23 = s2 * c3 - c2 * s3;
    let c23 = c2 * c3 + s2 * s3;
    let w23 = omega2 - omega3;
    ConstraintTerms {
        b1: (s2 * p.l + s23 * p.l3) * p.l2,
        c1: (s23 * p.l2 + s3 * p.l) * p.l3,
        b1_dot: (c2 * p.l * omega2 + c23 * p.l3 * w23) * p.l2,
        c1_dot: (c23 * p.l2 * w23 + c3 * p.l * omega3) * p.l3,
    }
}

/// The closure g(φ) = ½(|d|² − L²) with its gradient terms B1, C1, from one pair of
/// sin_cos (what the projection needs at every Newton iteration).
#[inline]
pub fn closure_with_gradient(p: &Parameters, phi2: f64, phi3: f64) -> (f64, f64, f64) {
    let [sc2, sc3] = sin_cos_pair([phi2, phi3]);
    closure_with_gradient_from(p, sc2, sc3)
}

/// [`closure_with_gradient`] from the sines and cosines of φ2 and φ3.
#[inline(always)]
pub fn closure_with_gradient_from(
    p: &Parameters,
    (s2, c2): (f64, f64),
    (s3, c3): (f64, f64),
) -> (f64, f64, f64) {
    let (dx, dy) = (p.l2 * c2 - (p.l + p.l3 * c3), p.l2 * s2 - p.l3 * s3);
    let s23 = s2 * c3 - c2 * s3;
    let g = 0.5 * (dx * dx + dy * dy - p.L * p.L);
    (
        g,
        p.l2 * (p.l * s2 + p.l3 * s23),
        p.l3 * (p.l2 * s23 + p.l * s3),
    )
}

/// (sin, cos) of `angle`, given (sin, cos) of `angle − delta`: a rotation by the small
/// `delta` with Taylor terms exact in double precision for |delta| < 1e-4 (the next terms
/// are below 1e-22); larger turns are evaluated directly.
#[inline(always)]
pub fn rotate((s, c): (f64, f64), delta: f64, angle: f64) -> (f64, f64) {
    if delta.abs() >= 1e-4 {
        return sin_cos(angle);
    }
    let d2 = delta * delta;
    // Multiplications by the reciprocals: these terms are below 1e-8 of the result, so
    // their last bits do not matter, and a division costs as much as the rest together.
    let (sd, cd) = (
        delta * (1.0 - d2 * (1.0 / 6.0)),
        1.0 - d2 * 0.5 + d2 * d2 * (1.0 / 24.0),
    );
    (s * cd + c * sd, c * cd - s * sd)
}

/// |A2A3| − L from g = ½(|d|² − L²), without cancellation: 2g/(|d| + L). With ρ = g/L²
/// that is (g/L)·2/(1 + √(1 + 2ρ)) = (g/L)·(1 − ρ/2 + ρ²/2 − …); for |ρ| ≤ 1e-9 (every
/// projected state) the terms from ρ² on lie below 1e-18 relative, and (g/L)·(1 − ρ/2)
/// needs no square root and no division after g (1/L does not wait on it).
#[inline]
pub fn length_residual_from_closure(p: &Parameters, g: f64) -> f64 {
    let inverse_length = 1.0 / p.L;
    let ratio = g * inverse_length * inverse_length;
    if ratio.abs() <= 1e-9 {
        return g * inverse_length * (1.0 - 0.5 * ratio);
    }
    2.0 * g / ((p.L * p.L + 2.0 * g).max(0.0).sqrt() + p.L)
}

/// d = A2 − A3, the rod vector (docs/model.md §1).
#[inline]
pub fn rod_vector<T: Scalar>(p: &Parameters, phi2: T, phi3: T) -> [T; 2] {
    let [(s2, c2), (s3, c3)] = T::sin_cos_pair(phi2, phi3);
    [c2 * p.l2 - (c3 * p.l3 + p.l), s2 * p.l2 - s3 * p.l3]
}

/// The closure constraint g(φ) = ½(|d|² − L²) (docs/model.md §2).
#[inline]
pub fn closure(p: &Parameters, phi2: f64, phi3: f64) -> f64 {
    let [dx, dy] = rod_vector(p, phi2, phi3);
    0.5 * (dx * dx + dy * dy - p.L * p.L)
}

/// |A2A3| − L, the `constraint_residual` output (m).
pub fn length_residual<T: Scalar>(p: &Parameters, phi2: T, phi3: T) -> T {
    let [dx, dy] = rod_vector(p, phi2, phi3);
    dx.hypot(dy) - p.L
}

/// The rocker angle φ3 that closes the loop for crank angle φ2 (docs/model.md §3): of the two
/// assemblies, the one nearest `guess`, expressed in the 2π-branch nearest `guess`.
pub fn assemble_rocker(p: &Parameters, phi2: f64, guess: f64) -> Result<f64, ModelError> {
    // e = A2 − O3; A3 = O3 + l3·(cos φ3, sin φ3) must lie at distance L from A2:
    // |e|² − 2·l3·(e·u) + l3² = L², so cos(φ3 − θ) = (|e|² + l3² − L²)/(2·l3·|e|).
    let (s2, c2) = sin_cos(phi2);
    let (ex, ey) = (p.l2 * c2 - p.l, p.l2 * s2);
    let r = ex.hypot(ey);
    let cos_angle = (r * r + p.l3 * p.l3 - p.L * p.L) / (2.0 * p.l3 * r);
    if !(r > 0.0 && cos_angle.abs() <= 1.0) {
        return Err(ModelError::new(format!(
            "the loop cannot be assembled at phi2_0 = {phi2}: with l = {}, l2 = {}, l3 = {}, L = {} \
             the rod cannot reach the rocker (need |l3 - L| <= |O3 A2| <= l3 + L, |O3 A2| = {r})",
            p.l, p.l2, p.l3, p.L
        )));
    }
    let theta = ey.atan2(ex);
    let half = cos_angle.acos();
    let nearest = |candidate: f64| guess + wrap_angle(candidate - guess);
    let (a, b) = (nearest(theta + half), nearest(theta - half));
    Ok(if (a - guess).abs() <= (b - guess).abs() {
        a
    } else {
        b
    })
}

/// Angle wrapped into (−π, π].
pub fn wrap_angle(x: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = x.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_assembly_matches_spec() {
        let p = Parameters::default();
        let phi3 = assemble_rocker(&p, 0.0, std::f64::consts::FRAC_PI_2).unwrap();
        assert!((phi3 - 1.4873662401842818).abs() < 1e-15, "{phi3}");
        assert!(closure(&p, 0.0, phi3).abs() < 1e-15);
        // The other assembly, below the ground line.
        let other = assemble_rocker(&p, 0.0, -std::f64::consts::FRAC_PI_2).unwrap();
        assert!((other - phi3).abs() > 1.0, "{other}");
        assert!(closure(&p, 0.0, other).abs() < 1e-15);
    }

    #[test]
    fn impossible_geometry_names_parameters() {
        let p = Parameters {
            L: 2.0,
            ..Parameters::default()
        };
        let err = assemble_rocker(&p, 0.0, 1.5).unwrap_err().to_string();
        assert!(
            err.contains("L = 2") && err.contains("l3") && err.contains("phi2_0"),
            "{err}"
        );
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let p = Parameters::default();
        let (phi2, phi3) = (0.7, 1.6);
        let t = constraint_terms(&p, phi2, phi3, 0.0, 0.0);
        let h = 1e-6;
        let dg2 = (closure(&p, phi2 + h, phi3) - closure(&p, phi2 - h, phi3)) / (2.0 * h);
        let dg3 = (closure(&p, phi2, phi3 + h) - closure(&p, phi2, phi3 - h)) / (2.0 * h);
        assert!((dg2 - t.b1).abs() < 1e-9, "{dg2} {}", t.b1);
        assert!((dg3 + t.c1).abs() < 1e-9, "{dg3} {}", t.c1);
    }

    #[test]
    fn gradient_rates_match_finite_differences() {
        let p = Parameters::default();
        let (phi2, phi3, w2, w3) = (0.7, 1.6, 3.0, -0.4);
        let t = constraint_terms(&p, phi2, phi3, w2, w3);
        let h = 1e-6;
        let fwd = constraint_terms(&p, phi2 + h * w2, phi3 + h * w3, w2, w3);
        let bwd = constraint_terms(&p, phi2 - h * w2, phi3 - h * w3, w2, w3);
        assert!(((fwd.b1 - bwd.b1) / (2.0 * h) - t.b1_dot).abs() < 1e-8);
        assert!(((fwd.c1 - bwd.c1) / (2.0 * h) - t.c1_dot).abs() < 1e-8);
    }

    #[test]
    fn closure_with_gradient_agrees_with_the_separate_functions() {
        let p = Parameters::default();
        let (g, b1, c1) = closure_with_gradient(&p, 0.4, 1.7);
        let t = constraint_terms(&p, 0.4, 1.7, 0.0, 0.0);
        assert!((g - closure(&p, 0.4, 1.7)).abs() < 1e-16);
        assert!((b1 - t.b1).abs() < 1e-16 && (c1 - t.c1).abs() < 1e-16);
        let direct = length_residual(&p, 0.4, 1.7);
        assert!(
            (length_residual_from_closure(&p, g) - direct).abs() < 1e-15,
            "{direct}"
        );
    }

    #[test]
    fn residual_of_a_tiny_closure_matches_the_exact_formula() {
        // The series' branch (|g| ≤ 1e-9·L²) against 2g/(|d| + L), up to its limit, where
        // leaving out its −ρ/2 term would be off by 5e-10 relative.
        let p = Parameters::default();
        let limit = 1e-9 * p.L * p.L;
        for g in [1e-25, 4e-16, 3e-13, 1e-11, 0.999 * limit] {
            for g in [g, -g] {
                let exact = 2.0 * g / ((p.L * p.L + 2.0 * g).sqrt() + p.L);
                let series = length_residual_from_closure(&p, g);
                assert!(
                    (series - exact).abs() <= 2.0 * f64::EPSILON * exact.abs(),
                    "{g:e}"
                );
            }
        }
    }

    #[test]
    fn small_rotations_match_direct_evaluation() {
        for (angle, delta) in [
            (41.25f64, 3e-9f64),
            (1.487, -7e-6),
            (-2.0, 9.9e-5),
            (0.3, 2e-3),
        ] {
            // As in the projection: the difference of two stored angles, exact.
            let start = angle - delta;
            let (s, c) = rotate(sin_cos(start), angle - start, angle);
            let (s0, c0) = sin_cos(angle);
            assert!(
                (s - s0).abs() < 4e-16 && (c - c0).abs() < 4e-16,
                "{angle} {delta}"
            );
        }
    }

    #[test]
    fn wrap_angle_range() {
        use std::f64::consts::PI;
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
        assert!((wrap_angle(7.0) - (7.0 - 2.0 * PI)).abs() < 1e-15);
    }
}
