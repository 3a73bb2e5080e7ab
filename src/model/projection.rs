//! Projection back onto the constraint manifold after each accepted step (docs/model.md §2,
//! "Projection"), and the consistent initial state (docs/model.md §3).

use super::kinematics::{
    assemble_rocker, closure, closure_with_gradient_from, constraint_terms, rotate,
};
use super::trig::sin_cos_pair;
use super::{ModelError, Parameters, State};
use integrators::text::number;

/// The constraint's conditioning (B1²/J2 + C1²/J3, normalised by its largest possible
/// value) below which the configuration counts as singular: |G| at 1e-4 of its scale,
/// where the accelerations lose about four digits. Regular crank-rockers stay far above
/// (the default linkage: 0.64 at worst over a revolution).
pub const MIN_CONDITIONING: f64 = 1e-8;

/// The result of a projection: g and the gradient terms at the projected state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    pub closure: f64,
    pub b1: f64,
    pub c1: f64,
}

/// Newton iterations allowed for the position projection; two suffice after a step.
const MAX_POSITION_ITERATIONS: usize = 8;

/// Project onto the constraint manifold (docs/model.md §2, "Projection"): positions onto g(φ) = 0
/// with the mass-weighted minimum-norm correction Δφ = −J⁻¹Gᵀ·g/(G·J⁻¹·Gᵀ), iterated
/// (Newton along J⁻¹Gᵀ); then velocities onto B1·ω2 − C1·ω3 = 0 with the J-weighted
/// projection ω ← ω − J⁻¹Gᵀ(G·J⁻¹·Gᵀ)⁻¹·G·ω at the final positions. Only φ2, φ3, ω2, ω3
/// move. Returns g, B1 and C1 at the result; fails where G vanishes (a change point) or
/// Newton does not converge. One pair of sin_cos serves the whole projection: first
/// [`one_newton_step`], then, where that does not settle it, Newton's iteration.
///
/// `accuracy` is the relative error the gradient (B1, C1) at the result may have where
/// that saves work, never less than rounding: the velocity then meets its constraint to
/// that accuracy (and g = 0 is always met to rounding). Zero asks for rounding.
#[inline(always)]
pub fn project(p: &Parameters, y: &mut State, accuracy: f64) -> Result<Projected, ModelError> {
    let [sc2, sc3] = sin_cos_pair([y[1], y[2]]);
    match one_newton_step(p, y, sc2, sc3, accuracy) {
        Ok(at) => Ok(at),
        Err([sc2, sc3]) => iterate(p, y, sc2, sc3),
    }
}

/// The projection's common case, with the sines and cosines (`sc2`, `sc3`) of the angles in
/// `y`. A dense-output point or a step's end usually lies so near the manifold that one
/// Newton step moves the angles by 1e-12…1e-7 rad: then g, B1 and C1 at the new angles
/// follow from their values here by Taylor's formula (second order for g, first for B1
/// and C1) to within rounding or `accuracy`, which [`taylor_is_accurate`] checks before
/// they are used, and the velocity projected here gets a small correction for the moved
/// gradient. No second closure or division waits on the first, and this chain of
/// dependent operations sets much of the cost of a communication point, which is why a
/// second closure is avoided.
///
/// Where one step does not settle it, `Err` gives the sines and cosines of the angles `y`
/// now holds, for Newton's iteration to go on from: a small share of the projections at
/// the accuracy the driver asks for, a larger one when rounding is asked of the gradient
/// or the remainder bound of [`taylor_is_accurate`] is looser.
#[inline(always)]
fn one_newton_step(
    p: &Parameters,
    y: &mut State,
    sc2: (f64, f64),
    sc3: (f64, f64),
    accuracy: f64,
) -> Result<Projected, [(f64, f64); 2]> {
    let tolerance = closure_tolerance(p);
    let inverse_j = inverse_inertias(p);
    let here = Linearised::at(p, inverse_j, sc2, sc3);
    if here.g.abs() <= tolerance {
        here.project_velocity(y);
        return Ok(here.projected());
    }
    let scale = here.g * here.inverse_weight;
    if !scale.is_finite() {
        return Err([sc2, sc3]);
    }
    let delta = correct_positions(y, here.moves, scale);
    let moved = Curvature::at(p, sc2, sc3).moved((here.g, here.b1, here.c1), delta);
    if !(taylor_is_accurate(p, here.b1, here.c1, delta, accuracy)
        && moved.closure.abs() <= tolerance)
    {
        return Err([rotate(sc2, delta.0, y[1]), rotate(sc3, delta.1, y[2])]);
    }
    here.project_velocity(y);
    // G moved by O(Δφ): project what it left, with the new gradient (the weight's change
    // enters this tiny correction only to second order).
    let new_moves = (moved.b1 * inverse_j.0, moved.c1 * inverse_j.1);
    let left = (moved.b1 * y[5] - moved.c1 * y[6]) * here.inverse_weight;
    project_velocity(y, new_moves, left);
    Ok(moved)
}

/// Newton's iteration for what [`one_newton_step`] does not settle, from the angles in `y`
/// with their sines and cosines: each iteration rotates them by the change of the stored
/// angles ([`rotate`]); the velocity is projected at the final positions.
#[inline(never)]
fn iterate(
    p: &Parameters,
    y: &mut State,
    mut sc2: (f64, f64),
    mut sc3: (f64, f64),
) -> Result<Projected, ModelError> {
    let tolerance = closure_tolerance(p);
    let inverse_j = inverse_inertias(p);
    for iteration in 0..=MAX_POSITION_ITERATIONS {
        let at = Linearised::at(p, inverse_j, sc2, sc3);
        let converged = at.g.abs() <= tolerance
            || iteration == MAX_POSITION_ITERATIONS && at.g.abs() <= 1e3 * tolerance;
        if converged {
            at.project_velocity(y);
            return Ok(at.projected());
        }
        let scale = at.g * at.inverse_weight;
        if !scale.is_finite() {
            break;
        }
        let (delta2, delta3) = correct_positions(y, at.moves, scale);
        sc2 = rotate(sc2, delta2, y[1]);
        sc3 = rotate(sc3, delta3, y[2]);
    }
    let g = closure(p, y[1], y[2]);
    Err(ModelError::new(format!(
        "position projection failed at phi2 = {}, phi3 = {}: closure residual {g:e}",
        y[1], y[2]
    )))
}

/// How close to g = 0 the projection goes: a few roundings of g's evaluation.
#[inline(always)]
fn closure_tolerance(p: &Parameters) -> f64 {
    4.0 * f64::EPSILON * p.L * p.L
}

/// (1/J2, 1/J3): two divisions per projection rather than per Newton iteration.
#[inline(always)]
fn inverse_inertias(p: &Parameters) -> (f64, f64) {
    (1.0 / p.J2, 1.0 / p.J3)
}

/// g, B1 and C1 at one configuration, with what a Newton step and the velocity projection
/// there need: `moves` = J⁻¹Gᵀ's two entries (B1/J2, C1/J3) and 1/(G·J⁻¹·Gᵀ).
struct Linearised {
    g: f64,
    b1: f64,
    c1: f64,
    moves: (f64, f64),
    inverse_weight: f64,
}

impl Linearised {
    #[inline(always)]
    fn at(p: &Parameters, inverse_j: (f64, f64), sc2: (f64, f64), sc3: (f64, f64)) -> Self {
        let (g, b1, c1) = closure_with_gradient_from(p, sc2, sc3);
        let moves = (b1 * inverse_j.0, c1 * inverse_j.1);
        let inverse_weight = 1.0 / (b1 * moves.0 + c1 * moves.1);
        Self {
            g,
            b1,
            c1,
            moves,
            inverse_weight,
        }
    }

    /// The velocity projected onto B1·ω2 − C1·ω3 = 0 with this gradient.
    #[inline(always)]
    fn project_velocity(&self, y: &mut State) {
        let scale = (self.b1 * y[5] - self.c1 * y[6]) * self.inverse_weight;
        project_velocity(y, self.moves, scale);
    }

    fn projected(&self) -> Projected {
        Projected {
            closure: self.g,
            b1: self.b1,
            c1: self.c1,
        }
    }
}

/// φ ← φ − J⁻¹Gᵀ·scale on φ2 and φ3; returns the changes of the stored angles, which are
/// exact (what the rotation of the sines and Taylor's formula need).
#[inline(always)]
fn correct_positions(y: &mut State, (move2, move3): (f64, f64), scale: f64) -> (f64, f64) {
    let (old2, old3) = (y[1], y[2]);
    y[1] -= move2 * scale;
    y[2] += move3 * scale;
    (y[1] - old2, y[2] - old3)
}

/// ω ← ω − J⁻¹Gᵀ·scale, with `moves` = J⁻¹Gᵀ's two entries and `scale` = G·ω/(G·J⁻¹·Gᵀ);
/// skipped when the scale is not finite (G vanishes: the caller's passage check reports it).
#[inline(always)]
fn project_velocity(y: &mut State, (move2, move3): (f64, f64), scale: f64) {
    if scale.is_finite() {
        y[5] -= move2 * scale;
        y[6] += move3 * scale;
    }
}

/// The second derivatives of g (docs/model.md §2) at one configuration: with B1 = ∂g/∂φ2 and
/// C1 = −∂g/∂φ3, g_22 = ∂B1/∂φ2 = l2·(l·cos φ2 + l3·cos(φ2 − φ3)), g_23 = ∂B1/∂φ3 =
/// −l2·l3·cos(φ2 − φ3), g_33 = −∂C1/∂φ3 = l3·(l2·cos(φ2 − φ3) − l·cos φ3).
struct Curvature {
    g22: f64,
    g23: f64,
    g33: f64,
}

impl Curvature {
    #[inline(always)]
    fn at(p: &Parameters, (s2, c2): (f64, f64), (s3, c3): (f64, f64)) -> Self {
        let c23 = c2 * c3 + s2 * s3;
        Self {
            g22: p.l2 * (p.l * c2 + p.l3 * c23),
            g23: -(p.l2 * p.l3 * c23),
            g33: p.l3 * (p.l2 * c23 - p.l * c3),
        }
    }

    /// g (to second order), B1 and C1 (to first) after the angles moved by `delta`.
    #[inline(always)]
    fn moved(&self, (g, b1, c1): (f64, f64, f64), (d2, d3): (f64, f64)) -> Projected {
        let quadratic = self.g22 * d2 * d2 + 2.0 * self.g23 * d2 * d3 + self.g33 * d3 * d3;
        Projected {
            closure: g + (b1 * d2 - c1 * d3) + 0.5 * quadratic,
            b1: b1 + self.g22 * d2 + self.g23 * d3,
            c1: c1 - (self.g23 * d2 + self.g33 * d3),
        }
    }
}

/// Whether Taylor's formula in [`Curvature::moved`] is accurate for a move of `delta`: to
/// rounding for g, and for B1 and C1 to rounding or the relative `accuracy`, whichever is
/// larger. Along the move φ + s·Δφ every term of g, B1 and C1 is a sine or cosine of φ2,
/// φ3 or φ2 − φ3 times a product of two lengths, whose n-th derivative in s is at most that
/// product times |Δφ|ⁿ, |Δφ| = |Δφ2| + |Δφ3|. So the remainders of B1 and C1 are at most
/// ½·M·|Δφ|², g's at most M·|Δφ|³/6, with M = l2·l3 + l·(l2 + l3).
#[inline(always)]
fn taylor_is_accurate(
    p: &Parameters,
    b1: f64,
    c1: f64,
    (d2, d3): (f64, f64),
    accuracy: f64,
) -> bool {
    let bound = p.l2 * p.l3 + p.l * (p.l2 + p.l3);
    let size = d2.abs() + d3.abs();
    let gradient = 4.0 * accuracy.max(f64::EPSILON) * (b1.abs() + c1.abs());
    bound * size * size <= gradient && bound * size * size * size <= 6.0 * f64::EPSILON * p.L * p.L
}

/// The step from `previous` to `y` (projected, with `at` its projection) stayed where the
/// motion is determined (docs/model.md §2: the 2×2 block is singular only where B1 = C1 = 0, a
/// change point, possible only when two sums of link lengths are equal).
///
/// B1 = 0 alone is a dead point of the rocker (ω3 = 0, it reverses) and C1 = 0 alone one
/// of the crank (ω2 = 0: rod and rocker aligned, the crank stops and swings back, as in
/// every non-Grashof linkage): both are regular motion, and C1 changes sign through the
/// latter. So a step is refused only where the constraint is singular at its end, or
/// where C1 changed sign with B1 also near zero at the crossing (a change point passed
/// within the step): there the linkage may continue on either of two branches and the
/// equations do not say which.
#[inline(always)]
pub fn check_passage(
    p: &Parameters,
    previous: &State,
    y: &State,
    at: &Projected,
) -> Result<(), ModelError> {
    let singular = |what: &str, b1: f64, c1: f64| {
        ModelError::new(format!(
            "{what} at phi2 = {}, phi3 = {} (B1 = {}, C1 = {}): crank, rod and rocker are \
             collinear, a change point, where the motion is not determined; this geometry has \
             one because {}",
            y[1],
            y[2],
            number(b1),
            number(c1),
            equal_sums(p)
        ))
    };
    let measure = conditioning(p, at.b1, at.c1);
    if measure.is_nan() || measure < MIN_CONDITIONING {
        return Err(singular("singular configuration", at.b1, at.c1));
    }
    // C1 moves at most l3·(l2 + l) per radian of φ2 and φ3: only a C1 that small can have
    // changed sign during the step, so only then is the start's C1 worth computing.
    let reach = p.l3 * (p.l2 + p.l) * ((y[1] - previous[1]).abs() + (y[2] - previous[2]).abs());
    if at.c1.abs() <= 1.01 * reach {
        let before = constraint_terms(p, previous[1], previous[2], 0.0, 0.0);
        if before.c1 * at.c1 < 0.0 {
            // Where C1 crossed zero (linear in the step), what was B1?
            let s = before.c1 / (before.c1 - at.c1);
            let b1 = before.b1 + s * (at.b1 - before.b1);
            if conditioning(p, b1, 0.0) < MIN_CONDITIONING {
                return Err(singular("a change point passed during the step", b1, 0.0));
            }
        }
    }
    Ok(())
}

/// Which sums of link lengths are (nearly) equal, in words: what makes a change point.
pub fn equal_sums(p: &Parameters) -> String {
    let pairs = [
        ("l2 + L", p.l2 + p.L, "l + l3", p.l + p.l3),
        ("l2 + l", p.l2 + p.l, "l3 + L", p.l3 + p.L),
        ("l2 + l3", p.l2 + p.l3, "l + L", p.l + p.L),
    ];
    let (a, x, b, z) = pairs
        .iter()
        .copied()
        .min_by(|u, v| (u.1 - u.3).abs().total_cmp(&(v.1 - v.3).abs()))
        .expect("three pairs");
    format!(
        "{a} = {x} and {b} = {z} are (nearly) equal (l = {}, l2 = {}, l3 = {}, L = {})",
        p.l, p.l2, p.l3, p.L
    )
}

/// How far the constraint is from singular: (B1²/J2 + C1²/J3), normalised by its scale
/// for this geometry; zero only where B1 = C1 = 0 (crank, rod and rocker collinear).
pub fn conditioning(p: &Parameters, b1: f64, c1: f64) -> f64 {
    let scale = (p.l2 * (p.l + p.l3)).powi(2) / p.J2 + (p.l3 * (p.l2 + p.l)).powi(2) / p.J3;
    (b1 * b1 / p.J2 + c1 * c1 / p.J3) / scale
}

/// The consistent initial state of docs/model.md §3: φ3 from the assembly nearest `phi3_guess`,
/// the springs' initial twists, and ω3 = (B1/C1)·ω2.
pub fn initial_state(p: &Parameters) -> Result<State, ModelError> {
    p.validate()?;
    let phi2 = p.phi2_0;
    let phi3 = assemble_rocker(p, phi2, p.phi3_guess)?;
    let t = constraint_terms(p, phi2, phi3, 0.0, 0.0);
    let measure = conditioning(p, t.b1, t.c1);
    if measure.is_nan() || measure < MIN_CONDITIONING {
        return Err(ModelError::new(format!(
            "the assembly at phi2_0 = {phi2} is a change point (B1 = {}, C1 = {}: crank, rod \
             and rocker collinear), where the motion is not determined; this geometry has one \
             because {}; change phi2_0 or the lengths",
            number(t.b1),
            number(t.c1),
            equal_sums(p)
        )));
    }
    // C1 tiny relative to its scale l3·(l2 + l): rod and rocker aligned, a dead point of
    // the crank, which cannot move there (B1·ω2 = C1·ω3 = 0) while ω3 is free: the crank
    // must start at rest, and ω3(0) = 0.
    let omega3 = if t.c1.abs() <= 1e-9 * p.l3 * (p.l2 + p.l) {
        if p.omega2_0 != 0.0 {
            return Err(ModelError::new(format!(
                "the assembly at phi2_0 = {phi2} is a dead point of the crank (C1 = {}: rod \
                 and rocker aligned), where the crank cannot move: omega2_0 = {} is not a \
                 possible initial speed there (the initial velocity is undetermined by \
                 omega2_0); set omega2_0 = 0 to start at rest, or change phi2_0",
                number(t.c1),
                p.omega2_0
            )));
        }
        0.0
    } else {
        t.b1 / t.c1 * p.omega2_0
    };
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
    use crate::model::kinematics::closure_with_gradient;

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
        let at = project(&p, &mut y, 0.0).unwrap();
        assert!(closure(&p, y[1], y[2]).abs() < 1e-15);
        assert!((at.closure - closure(&p, y[1], y[2])).abs() < 1e-16);
        check_passage(&p, &before, &y, &at).unwrap();
        let t = constraint_terms(&p, y[1], y[2], 0.0, 0.0);
        assert!((t.b1 * y[5] - t.c1 * y[6]).abs() < 1e-14);
        // Bodies 1 and 4 are not touched.
        assert_eq!(
            (y[0], y[3], y[4], y[7]),
            (before[0], before[3], before[4], before[7])
        );
    }

    #[test]
    fn taylor_values_match_a_direct_evaluation() {
        // A wrong derivative shows as an error of order δ; the formulas leave δ² for B1
        // and C1 and δ³ for g.
        let p = Parameters::default();
        let y = initial_state(&p).unwrap();
        for (phi2, phi3) in [(y[1], y[2]), (2.5, 1.1), (-1.0, 0.4)] {
            let [sc2, sc3] = sin_cos_pair([phi2, phi3]);
            let here = closure_with_gradient_from(&p, sc2, sc3);
            for delta in [(1e-4, -3e-4), (-2e-5, 1e-5), (1e-6, 2e-6)] {
                let moved = Curvature::at(&p, sc2, sc3).moved(here, delta);
                let (g, b1, c1) = closure_with_gradient(&p, phi2 + delta.0, phi3 + delta.1);
                let size = delta.0.abs() + delta.1.abs();
                assert!(
                    (moved.closure - g).abs() <= 1.0 * size.powi(3) + 1e-16,
                    "{delta:?}"
                );
                assert!(
                    (moved.b1 - b1).abs() <= 1.0 * size.powi(2) + 1e-16,
                    "{delta:?}"
                );
                assert!(
                    (moved.c1 - c1).abs() <= 1.0 * size.powi(2) + 1e-16,
                    "{delta:?}"
                );
            }
        }
    }

    /// The paper's linkage moving, with φ2 moved by `turns` and both angles and ω2 moved off
    /// the constraint in proportion to `departure`.
    fn departed(turns: f64, departure: f64) -> (Parameters, State) {
        let p = Parameters {
            omega2_0: 4.0,
            ..Parameters::default()
        };
        let mut y = initial_state(&p).unwrap();
        y[1] += turns * std::f64::consts::TAU + departure;
        y[2] -= 0.3 * departure;
        y[5] += 1e3 * departure;
        (p, y)
    }

    /// `y` projected (`at` what the projection returned) keeps g = 0 to rounding and the
    /// velocity constraint to `accuracy`; the g, B1, C1 returned are those at `y`; and `y`
    /// agrees with `by_iteration`, Newton's iteration from the same start, in the angles
    /// to rounding and in the speeds to `accuracy`.
    fn assert_settled(
        p: &Parameters,
        (y, at): (&State, &Projected),
        by_iteration: &State,
        accuracy: f64,
        what: &str,
    ) {
        let (g, b1, c1) = closure_with_gradient(p, y[1], y[2]);
        let gradient = b1.abs() + c1.abs();
        let tolerance = closure_tolerance(p);
        assert!(g.abs() <= 2.0 * tolerance, "{what}: g = {g:e}");
        assert!((at.closure - g).abs() <= tolerance, "{what}");
        assert!((at.b1 - b1).abs() <= accuracy * gradient, "{what}");
        assert!((at.c1 - c1).abs() <= accuracy * gradient, "{what}");
        let speed = y[5].abs() + y[6].abs();
        let velocity = b1 * y[5] - c1 * y[6];
        assert!(
            velocity.abs() <= accuracy * gradient * speed,
            "{what}: velocity constraint {velocity:e}"
        );
        for (i, scale) in [(1, 1e-15), (2, 1e-15), (5, accuracy), (6, accuracy)] {
            let scale = scale * (1.0 + by_iteration[i].abs());
            assert!((y[i] - by_iteration[i]).abs() <= scale, "{what}: y[{i}]");
        }
    }

    #[test]
    fn one_newton_step_gives_what_newtons_iteration_gives() {
        // Departures as a dense output leaves them (1e-12…1e-8), at small and large angles:
        // one step settles them (up to a few turns; at a hundred turns, where an ulp of φ2
        // is 1e-13 rad, Newton's iteration may go on), the result agrees with Newton's
        // iteration to rounding and keeps both constraints, and the g, B1, C1 returned are
        // those at the result.
        for turns in [0.0, 3.0, 100.0] {
            for departure in [1e-12, 1e-10, 1e-8] {
                let (p, mut y) = departed(turns, departure);
                let what = format!("{turns} turns, departure {departure:e}");
                let mut by_iteration = y;
                let [sc2, sc3] = sin_cos_pair([y[1], y[2]]);
                let at = if turns < 10.0 {
                    let settled = one_newton_step(&p, &mut y, sc2, sc3, 0.0);
                    assert!(settled.is_ok(), "{what}: one step did not settle it");
                    settled.unwrap()
                } else {
                    project(&p, &mut y, 0.0).unwrap()
                };
                iterate(&p, &mut by_iteration, sc2, sc3).unwrap();
                assert_settled(&p, (&y, &at), &by_iteration, 1e-15, &what);
            }
        }
    }

    #[test]
    fn a_looser_gradient_accuracy_settles_larger_departures_in_one_step() {
        // Departures that Newton's step corrects by 6e-8 and 2e-7 rad (as after a dense
        // output at tol 1e-4): with rounding asked of the gradient the iteration goes on;
        // with 2e-12 one step settles them, g still to rounding and the velocity
        // constraint to that accuracy.
        let accuracy = 2e-12;
        for turns in [0.0, 3.0] {
            for departure in [3e-7, 1e-6] {
                let (p, mut y) = departed(turns, departure);
                let what = format!("{turns} turns, departure {departure:e}");
                let [sc2, sc3] = sin_cos_pair([y[1], y[2]]);
                let strict = one_newton_step(&p, &mut y.clone(), sc2, sc3, 0.0);
                assert!(strict.is_err(), "{what}");
                let mut by_iteration = y;
                let at = one_newton_step(&p, &mut y, sc2, sc3, accuracy);
                assert!(at.is_ok(), "{what}: one step did not settle it");
                iterate(&p, &mut by_iteration, sc2, sc3).unwrap();
                assert_settled(&p, (&y, &at.unwrap()), &by_iteration, accuracy, &what);
            }
        }
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
