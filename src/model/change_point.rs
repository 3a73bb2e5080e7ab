//! Crossing a change point (docs/model.md §7): where crank, rod and rocker fall collinear
//! (B1 = C1 = 0) the constraint's gradient vanishes, the equations of motion do not
//! determine the motion, and two branches of the loop's configuration curve cross. The
//! integrator cannot step through that point; [`cross`] carries the state from just before
//! it to just after it along the branch [`Branch`] names, keeping the energy balance.

use super::dynamics::{accelerations, energy, power, state_derivative};
use super::kinematics::closure_with_gradient;
use super::projection::{conditioning, project, MIN_CONDITIONING};
use super::{Inputs, ModelError, Parameters, State};

/// Which branch the linkage takes at a change point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(i32)]
pub enum Branch {
    /// Along the branch it arrives on: at the change point the rod can transmit no
    /// impulse (the constraint's gradient is zero), so the velocity cannot jump.
    Straight = 1,
    /// Onto the other branch, with the kinetic energy of crank and rocker kept: the
    /// idealisation of a guide, a stop or a spring that steers the linkage over.
    Turn = 2,
}

/// The enumeration's items (name, value, description), for the model description.
pub const BRANCHES: [(&str, i32, &str); 2] = [
    (
        "straight",
        1,
        "continue along the branch the linkage arrives on",
    ),
    (
        "turn",
        2,
        "take the other branch, with the kinetic energy kept",
    ),
];

impl Branch {
    pub fn from_value(value: i32) -> Option<Branch> {
        match value {
            1 => Some(Branch::Straight),
            2 => Some(Branch::Turn),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        BRANCHES[self as usize - 1].0
    }
}

/// The state after a crossing, `duration` after the state it started from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    pub duration: f64,
    pub state: State,
    /// The change point crossed (φ2, φ3), and when it was passed, after the start.
    pub node: (f64, f64),
    pub time_to_node: f64,
    /// (ω2, ω3) at the change point: arriving along the approach, and leaving along the
    /// branch taken.
    pub arriving: [f64; 2],
    pub leaving: [f64; 2],
}

/// Hermite's cubic on [0, `span`] from value `a` with slope `da` to `b` with slope `db`:
/// its value and slope at `t`.
fn hermite((a, da): (f64, f64), (b, db): (f64, f64), span: f64, t: f64) -> (f64, f64) {
    let s = t / span;
    let (s2, s3) = (s * s, s * s * s);
    let value = (2.0 * s3 - 3.0 * s2 + 1.0) * a
        + (s3 - 2.0 * s2 + s) * span * da
        + (3.0 * s2 - 2.0 * s3) * b
        + (s3 - s2) * span * db;
    let slope = (6.0 * s2 - 6.0 * s) / span * (a - b)
        + (3.0 * s2 - 4.0 * s + 1.0) * da
        + (3.0 * s2 - 2.0 * s) * db;
    (value, slope)
}

impl Crossing {
    /// The state `t` after `from`, the state the crossing started from, while it is under
    /// way (0 < t < duration): a master stepping more finely than the crossing lasts sees
    /// the linkage on its way. Crank and rocker follow the crossing's own path, to the
    /// change point along the approach and away from it along the branch taken, each half
    /// a cubic in time between its ends' angles and speeds; bodies 1 and 4 a cubic between
    /// the ends' angles and speeds, and their speeds one between the ends' speeds and
    /// accelerations (`rates` holds f at `from` and at the end). Near the change point the
    /// loop's closure is not enforced: no projection is regular there. Crank and rocker
    /// then carry the energy the crossing's balance gives, linear in time between its ends'.
    pub fn along(&self, p: &Parameters, from: &State, rates: (&State, &State), t: f64) -> State {
        let end = &self.state;
        let mut y = *from;
        for (angle, speed) in [(0, 4), (3, 7)] {
            y[angle] = hermite(
                (from[angle], from[speed]),
                (end[angle], end[speed]),
                self.duration,
                t,
            )
            .0;
            y[speed] = hermite(
                (from[speed], rates.0[speed]),
                (end[speed], rates.1[speed]),
                self.duration,
                t,
            )
            .0;
        }
        let node = [self.node.0, self.node.1];
        for (k, (angle, speed)) in [(1, 5), (2, 6)].into_iter().enumerate() {
            let (value, slope) = if t <= self.time_to_node {
                hermite(
                    (from[angle], from[speed]),
                    (node[k], self.arriving[k]),
                    self.time_to_node,
                    t,
                )
            } else {
                hermite(
                    (node[k], self.leaving[k]),
                    (end[angle], end[speed]),
                    self.duration - self.time_to_node,
                    t - self.time_to_node,
                )
            };
            y[angle] = value;
            y[speed] = slope;
        }
        let (start, end) = (energy(p, from), energy(p, &self.state));
        let target = start + (end - start) * (t / self.duration);
        let rest = energy(p, &[y[0], y[1], y[2], y[3], y[4], 0.0, 0.0, y[7]]);
        let kinetic = 0.5 * (p.J2 * y[5] * y[5] + p.J3 * y[6] * y[6]);
        let factor = ((target - rest) / kinetic).sqrt();
        if factor.is_finite() {
            y[5] *= factor;
            y[6] *= factor;
        }
        y
    }
}

/// The farthest (rad, in φ2 + φ3) a state may stand from the change point it is to cross.
const NEAR: f64 = 1e-2;

/// Carry `y`, which approaches a change point, across it onto `branch`.
///
/// Crank and rocker move in (φ2, φ3) to the change point, along their velocity, and away
/// from it along the chosen branch's tangent by as far again, or farther until the
/// constraint is regular enough for the integrator (conditioning four times
/// [`MIN_CONDITIONING`]); the exit is projected onto the loop. The speed along the way
/// follows from the energy: at the change point from the work of the generalised forces
/// on crank and rocker over the approach, with the inertia along the tangent there (the
/// speed carries over onto the straight branch; onto the other, the kinetic energy does);
/// at the exit from the energy balance (E(y) plus the power at `y` times the duration).
/// Each half's duration is its length over the mean of the inverse speeds at its ends (the
/// trapezoidal rule), and the springs' bodies move with their accelerations at `y`: second
/// order in the (short) duration, including the change of inertia along the curved path.
pub fn cross(
    p: &Parameters,
    inputs: &Inputs,
    y: &State,
    branch: Branch,
) -> Result<Crossing, ModelError> {
    let node = locate_node(p, y[1], y[2])?;
    let v = [y[5], y[6]];
    let speed = v[0].hypot(v[1]);
    if speed == 0.0 {
        return Err(ModelError::new(
            "at the change point crank and rocker are at rest: no branch is taken",
        ));
    }
    let arrival = [v[0] / speed, v[1] / speed];
    let (arriving, chosen) = branch_tangents(p, node, (v, arrival), branch)?;
    let inertia = |d: [f64; 2]| p.J2 * d[0] * d[0] + p.J3 * d[1] * d[1];
    let offset = [node.0 - y[1], node.1 - y[2]];
    let distance = offset[0].hypot(offset[1]);
    if offset[0] * arrival[0] + offset[1] * arrival[1] <= 0.0 {
        return Err(ModelError::new(format!(
            "the state at phi2 = {}, phi3 = {} moves away from the change point at phi2 = {}, \
             phi3 = {}: nothing to cross",
            y[1], y[2], node.0, node.1
        )));
    }
    // The kinetic energy of crank and rocker at the change point: theirs at `y` and the
    // work of their generalised forces on the way.
    let forces = accelerations(p, inputs, y).forces;
    let kinetic =
        0.5 * inertia(arrival) * speed * speed + forces[1] * offset[0] + forces[2] * offset[1];
    if kinetic.is_nan() || kinetic <= 0.0 {
        return Err(ModelError::new(
            "crank and rocker stop before the change point: nothing to cross",
        ));
    }
    let speed_at_node = (2.0 * kinetic / inertia(arriving)).sqrt();
    let time_to_node = 0.5 * distance * (1.0 / speed + 1.0 / speed_at_node);
    let leaving_speed = (2.0 * kinetic / inertia(chosen)).sqrt();
    let mut reach = distance;
    for _ in 0..40 {
        let exit = [node.0 + chosen[0] * reach, node.1 + chosen[1] * reach];
        let velocity = [chosen[0] * leaving_speed, chosen[1] * leaving_speed];
        // A first estimate of the duration, for the springs' bodies; the exit's own speed
        // then gives the second half's duration.
        let estimate = time_to_node + reach / leaving_speed;
        let guess = leave(p, inputs, y, exit, velocity, estimate)?;
        let exit_speed = guess[5].hypot(guess[6]);
        let duration = time_to_node + 0.5 * reach * (1.0 / leaving_speed + 1.0 / exit_speed);
        let state = leave(p, inputs, y, exit, velocity, duration)?;
        let (_, b1, c1) = closure_with_gradient(p, state[1], state[2]);
        if conditioning(p, b1, c1) >= 4.0 * MIN_CONDITIONING {
            let speed_along = |d: [f64; 2], speed: f64| [d[0] * speed, d[1] * speed];
            return Ok(Crossing {
                duration,
                state,
                node,
                time_to_node,
                arriving: speed_along(arriving, speed_at_node),
                leaving: speed_along(chosen, leaving_speed),
            });
        }
        reach *= 1.5;
    }
    Err(ModelError::new(
        "the linkage does not leave the change point's neighbourhood along the chosen branch",
    ))
}

/// The tangents at `node` that the motion with velocity `v` (ω2, ω3; `arrival` its unit
/// direction) arrives along and leaves along on `branch`, each pointing forward: at an
/// acute angle with `v` in the kinetic metric.
fn branch_tangents(
    p: &Parameters,
    node: (f64, f64),
    (v, arrival): ([f64; 2], [f64; 2]),
    branch: Branch,
) -> Result<([f64; 2], [f64; 2]), ModelError> {
    let (first, second) = tangents(p, node)?;
    // The tangent the motion arrives along is the one nearest the velocity.
    let along = |d: [f64; 2]| (d[0] * arrival[0] + d[1] * arrival[1]).abs();
    let (arriving, other) = if along(first) >= along(second) {
        (first, second)
    } else {
        (second, first)
    };
    let forward = |d: [f64; 2]| {
        let sign = if p.J2 * d[0] * v[0] + p.J3 * d[1] * v[1] >= 0.0 {
            1.0
        } else {
            -1.0
        };
        [d[0] * sign, d[1] * sign]
    };
    let chosen = match branch {
        Branch::Straight => forward(arriving),
        Branch::Turn => forward(other),
    };
    Ok((forward(arriving), chosen))
}

/// The state `dt` after `y`, crank and rocker at `exit` with (ω2, ω3) = `velocity`;
/// projected, its energy balanced. The springs' bodies 1 and 4 move with accelerations
/// taken linear in time between `y` and the result (their spring forces change with the
/// crank's and rocker's travel, by about the crossing's length), and the energy balance
/// takes the power by the trapezoidal rule likewise: a first pass with the accelerations
/// and power at `y` gives the end's.
fn leave(
    p: &Parameters,
    inputs: &Inputs,
    y: &State,
    exit: [f64; 2],
    velocity: [f64; 2],
    dt: f64,
) -> Result<State, ModelError> {
    let mut start = [0.0; 8];
    state_derivative(p, inputs, y, &mut start);
    let first = balanced(p, inputs, y, (exit, velocity), (&start, &start), dt, None)?;
    let mut end = [0.0; 8];
    state_derivative(p, inputs, &first, &mut end);
    let power_end = power(p, inputs, &first);
    balanced(
        p,
        inputs,
        y,
        (exit, velocity),
        (&start, &end),
        dt,
        Some(power_end),
    )
}

/// One pass of [`leave`]: bodies 1 and 4 moved with accelerations linear in time from
/// `rates.0`'s to `rates.1`'s, crank and rocker placed at the exit and projected, their
/// speeds scaled to the energy E(y) plus the power (at `y`, and `power_end` at the end if
/// known) over `dt`.
fn balanced(
    p: &Parameters,
    inputs: &Inputs,
    y: &State,
    (exit, velocity): ([f64; 2], [f64; 2]),
    rates: (&State, &State),
    dt: f64,
    power_end: Option<f64>,
) -> Result<State, ModelError> {
    let mut z = *y;
    for (angle, speed) in [(0, 4), (3, 7)] {
        let (a0, a1) = (rates.0[speed], rates.1[speed]);
        z[angle] += y[speed] * dt + (a0 / 3.0 + a1 / 6.0) * dt * dt;
        z[speed] += 0.5 * (a0 + a1) * dt;
    }
    z[1] = exit[0];
    z[2] = exit[1];
    z[5] = velocity[0];
    z[6] = velocity[1];
    project(p, &mut z, 0.0)?;
    // Crank and rocker carry what the balance leaves them.
    let power_start = power(p, inputs, y);
    let work = 0.5 * (power_start + power_end.unwrap_or(power_start)) * dt;
    let target = energy(p, y) + work;
    let rest = energy(p, &[z[0], z[1], z[2], z[3], z[4], 0.0, 0.0, z[7]]);
    let kinetic = 0.5 * (p.J2 * z[5] * z[5] + p.J3 * z[6] * z[6]);
    let left = target - rest;
    if left.is_nan() || left <= 0.0 || kinetic <= 0.0 {
        return Err(ModelError::new(
            "the energy balance leaves crank and rocker no motion past the change point",
        ));
    }
    let factor = (left / kinetic).sqrt();
    z[5] *= factor;
    z[6] *= factor;
    Ok(z)
}

/// ∂(B1, C1)/∂(φ2, φ3) as rows (B1's, C1's): docs/model.md §2's B1 and C1 differentiated.
fn gradient_jacobian(p: &Parameters, phi2: f64, phi3: f64) -> [[f64; 2]; 2] {
    let c23 = (phi2 - phi3).cos();
    [
        [p.l2 * (p.l * phi2.cos() + p.l3 * c23), -p.l2 * p.l3 * c23],
        [p.l3 * p.l2 * c23, p.l3 * (-p.l2 * c23 + p.l * phi3.cos())],
    ]
}

/// The change point near (φ2, φ3): Newton's iteration on B1 = C1 = 0, checked to lie on
/// the loop (g = 0).
pub fn locate_node(p: &Parameters, phi2: f64, phi3: f64) -> Result<(f64, f64), ModelError> {
    let (mut a, mut b) = (phi2, phi3);
    let scale = p.l2 * (p.l + p.l3) + p.l3 * (p.l2 + p.l);
    for _ in 0..30 {
        let (_, b1, c1) = closure_with_gradient(p, a, b);
        let [[j11, j12], [j21, j22]] = gradient_jacobian(p, a, b);
        let det = j11 * j22 - j12 * j21;
        if det == 0.0 || !det.is_finite() {
            break;
        }
        let da = (b1 * j22 - c1 * j12) / det;
        let db = (j11 * c1 - j21 * b1) / det;
        a -= da;
        b -= db;
        if da.abs() + db.abs() <= 4.0 * f64::EPSILON * (1.0 + a.abs() + b.abs()) {
            break;
        }
    }
    let (g, b1, c1) = closure_with_gradient(p, a, b);
    let near = (a - phi2).abs() + (b - phi3).abs() <= NEAR;
    let on_loop = g.abs() <= 1e-9 * p.L * p.L;
    let singular = b1.abs() + c1.abs() <= 1e-12 * scale;
    if !(near && on_loop && singular) {
        return Err(ModelError::new(format!(
            "no change point near phi2 = {phi2}, phi3 = {phi3} (nearest candidate phi2 = {a}, \
             phi3 = {b}, g = {g:e}): the linkage is not at a change point"
        )));
    }
    Ok((a, b))
}

/// The two branches' tangents (in (φ2, φ3)) at the change point `node`: the directions d
/// with dᵀ·H·d = 0, H the Hessian of g, which is indefinite where two branches cross.
fn tangents(p: &Parameters, node: (f64, f64)) -> Result<([f64; 2], [f64; 2]), ModelError> {
    // ∇g = (B1, −C1), so H's rows are B1's gradient and minus C1's.
    let [[h11, h12], [h21, h22]] = gradient_jacobian(p, node.0, node.1);
    let (a, b, c) = (h11, 0.5 * (h12 - h21), -h22);
    let discriminant = b * b - a * c;
    if discriminant.is_nan() || discriminant <= 0.0 {
        return Err(ModelError::new(
            "the change point is not a crossing of two branches (the closure's Hessian is \
             not indefinite there)",
        ));
    }
    let root = discriminant.sqrt();
    // a·u² + 2b·u·w + c·w² = 0: with q = −b − sign(b)·√(b² − ac), never 0 here, the two
    // directions are (q, a) and (c, q), each without a cancellation or a division, also
    // where a or c (or both, the axes themselves: a rhombus folding onto its frame) vanish.
    let q = -b - b.signum() * root;
    let pair = ([q, a], [c, q]);
    let unit = |d: [f64; 2]| {
        let n = d[0].hypot(d[1]);
        [d[0] / n, d[1] / n]
    };
    Ok((unit(pair.0), unit(pair.1)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::kinematics::constraint_terms;

    /// The change-point geometry l2 + L = l + l3, collinear at φ2 = φ3 = 0; no torque law.
    fn geometry() -> Parameters {
        Parameters {
            L: 0.95,
            builtin_laws: false,
            ..Parameters::default()
        }
    }

    /// A state on the branch of slope `m` (dφ3/dφ2) at distance `s` in φ2 before the
    /// change point, moving towards it at ω2 = 3, with the springs twisted.
    fn approaching(p: &Parameters, m: f64, s: f64) -> State {
        let mut y = [0.1, -s, -m * s, -m * s - 0.05, 2.0, 3.0, 3.0 * m, 1.0];
        project(p, &mut y, 0.0).unwrap();
        y
    }

    fn slopes(p: &Parameters) -> [f64; 2] {
        let (d1, d2) = tangents(p, (0.0, 0.0)).unwrap();
        [d1[1] / d1[0], d2[1] / d2[0]]
    }

    #[test]
    fn the_node_and_its_two_branches() {
        let p = geometry();
        let node = locate_node(&p, 1e-3, -2e-3).unwrap();
        assert!(node.0.abs() < 1e-12 && node.1.abs() < 1e-12, "{node:?}");
        // By hand from g's second-order terms: a + 2b·m + c·m² = 0 with a = L·l2 + l2²,
        // b = −l2·l3, c = l3² − L·l3.
        let (a, b, c) = (
            p.L * p.l2 + p.l2 * p.l2,
            -p.l2 * p.l3,
            p.l3 * p.l3 - p.L * p.l3,
        );
        for m in slopes(&p) {
            assert!((a + 2.0 * b * m + c * m * m).abs() < 1e-12, "{m}");
        }
        assert!(locate_node(&Parameters::default(), 0.3, 1.4).is_err());
    }

    #[test]
    fn a_rhombus_folding_onto_its_frame_has_the_axes_for_tangents() {
        // All four lengths equal: at φ2 = 0, φ3 = π the rod lies on the frame, and the
        // branches are the crank turning alone (φ3 = π) and the rocker alone (φ2 = 0):
        // the closure's Hessian has no diagonal there.
        let p = Parameters {
            l: 0.5,
            l2: 0.5,
            l3: 0.5,
            L: 0.5,
            ..geometry()
        };
        let node = locate_node(&p, 1e-4, std::f64::consts::PI - 1e-4).unwrap();
        let (d1, d2) = tangents(&p, node).unwrap();
        let axis = |d: [f64; 2]| d[0].abs().max(d[1].abs());
        assert!(d1.iter().chain(&d2).all(|x| x.is_finite()), "{d1:?} {d2:?}");
        assert!(
            axis(d1) > 1.0 - 1e-12 && axis(d2) > 1.0 - 1e-12,
            "{d1:?} {d2:?}"
        );
        assert!((d1[0] * d2[0] + d1[1] * d2[1]).abs() < 1e-12);
    }

    #[test]
    fn straight_keeps_the_arrival_tangent_turn_takes_the_other_and_both_keep_the_energy() {
        let p = geometry();
        let inputs = Inputs::default();
        for (i, m) in slopes(&p).into_iter().enumerate() {
            let y = approaching(&p, m, 2e-4);
            for branch in [Branch::Straight, Branch::Turn] {
                let c = cross(&p, &inputs, &y, branch).unwrap();
                let z = c.state;
                let slope = z[6] / z[5];
                let expected = if branch == Branch::Straight {
                    m
                } else {
                    slopes(&p)[1 - i]
                };
                assert!(
                    (slope - expected).abs() < 2e-3,
                    "{branch:?}: {slope} vs {expected}"
                );
                assert!(z[5] > 0.0, "the crank keeps turning forwards");
                assert!(z[1] > 0.0, "past the change point");
                // No torque, no damper: the energy is kept.
                assert!((energy(&p, &z) - energy(&p, &y)).abs() <= 1e-12 * energy(&p, &y));
                let t = constraint_terms(&p, z[1], z[2], z[5], z[6]);
                assert!(
                    (t.b1 * z[5] - t.c1 * z[6]).abs() < 1e-13,
                    "velocity constraint"
                );
                let (g, b1, c1) = closure_with_gradient(&p, z[1], z[2]);
                assert!(g.abs() < 1e-15, "on the loop");
                assert!(conditioning(&p, b1, c1) >= 4.0 * MIN_CONDITIONING);
            }
        }
    }

    #[test]
    fn a_state_moving_away_is_not_crossed() {
        let p = geometry();
        let m = slopes(&p)[0];
        let mut y = approaching(&p, m, 2e-4);
        y[5] = -y[5];
        y[6] = -y[6];
        let error = cross(&p, &Inputs::default(), &y, Branch::Straight).unwrap_err();
        assert!(error.to_string().contains("moves away"), "{error}");
    }
}
