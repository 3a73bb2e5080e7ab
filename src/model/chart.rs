//! Independent coordinates of the loop (docs/model.md §6): the form in which a master's own
//! integrator (Model Exchange) solves the mechanism without ever leaving the constraint.
//!
//! The loop has one degree of freedom. In the *crank chart* φ2 and ω2 are the independent
//! coordinates and the rocker follows in closed form, φ3 = θ(φ2) ± acos(c(φ2)), ω3 =
//! (B1/C1)·ω2; in the *rocker chart* φ3 and ω3 are, and the crank follows. A chart is
//! singular where its follower's pin lies on the line through the leader's pin and the
//! follower's pivot: the crank chart where C1 = 0 (a dead point of the crank), the rocker
//! chart where B1 = 0 (a dead point of the rocker). Each chart is left well before that,
//! when its pivot term falls below [`HANDOVER`] times the other chart's; both charts fail
//! only where B1 = C1 = 0, a change point, which the model refuses anyway.
//!
//! Within a chart the follower's angle is a smooth function of the leader's: θ is written
//! without a branch cut (see [`base_angle`]) and the assembly branch (the sign before the
//! acos) and the follower's whole turns are fixed when the chart is entered.

use integrators::text::number;
use std::f64::consts::{PI, TAU};

use super::kinematics::constraint_terms;
use super::{ModelError, Parameters, Scalar, State};

/// Which loop angle is the independent coordinate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chart {
    /// φ2 and ω2 lead; φ3 and ω3 follow.
    Crank = 2,
    /// φ3 and ω3 lead; φ2 and ω2 follow.
    Rocker = 3,
}

impl Chart {
    /// The state index of the leading angle (its speed is 4 more).
    pub fn leader(self) -> usize {
        self as usize - 1
    }

    /// The state index of the following angle.
    pub fn follower(self) -> usize {
        match self {
            Chart::Crank => 2,
            Chart::Rocker => 1,
        }
    }

    pub fn other(self) -> Chart {
        match self {
            Chart::Crank => Chart::Rocker,
            Chart::Rocker => Chart::Crank,
        }
    }

    pub fn from_code(code: i32) -> Option<Chart> {
        match code {
            2 => Some(Chart::Crank),
            3 => Some(Chart::Rocker),
            _ => None,
        }
    }
}

/// A chart is left when its pivot term falls below this fraction of the other chart's
/// (both normalised by their largest values). The other chart then starts at 1/HANDOVER
/// times its own threshold: no chattering between the two.
pub const HANDOVER: f64 = 0.5;

/// A chart with the follower's branch: follower = θ(leader) + branch·acos(c) + turns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coordinates {
    pub chart: Chart,
    /// +1 or −1: which of the two assemblies.
    pub branch: f64,
    /// The follower's whole turns, a multiple of 2π.
    pub turns: f64,
}

/// The independent state x = (φ1, q, φ4, ω1, q̇, ω4), q the chart's leading angle.
pub type Independent = [f64; 6];

/// The largest values of |B1| and |C1| for this geometry, their natural scales.
fn pivot_scales(p: &Parameters) -> (f64, f64) {
    (p.l2 * (p.l + p.l3), p.l3 * (p.l2 + p.l))
}

/// The chart to start in at a configuration with gradient terms B1, C1: the one whose
/// pivot term is larger relative to its scale.
pub fn preferred_chart(p: &Parameters, b1: f64, c1: f64) -> Chart {
    let (sb, sc) = pivot_scales(p);
    if (c1 / sc).abs() >= (b1 / sb).abs() {
        Chart::Crank
    } else {
        Chart::Rocker
    }
}

/// The event indicator of `chart`: positive while the chart is good, crossing zero where
/// it should be left (its pivot term at [`HANDOVER`] times the other's). Smooth in the
/// state, so a master's root finder locates it.
pub fn handover_indicator(p: &Parameters, chart: Chart, b1: f64, c1: f64) -> f64 {
    let (sb, sc) = pivot_scales(p);
    let (b, c) = (b1 / sb, c1 / sc);
    match chart {
        Chart::Crank => c * c - HANDOVER * HANDOVER * b * b,
        Chart::Rocker => b * b - HANDOVER * HANDOVER * c * c,
    }
}

/// [`handover_indicator`] of `chart` at the configuration of state `y`.
pub fn handover_indicator_at(p: &Parameters, chart: Chart, y: &[f64; 8]) -> f64 {
    let (_, b1, c1) = super::kinematics::closure_with_gradient(p, y[1], y[2]);
    handover_indicator(p, chart, b1, c1)
}

/// The leader's pin seen from the follower's pivot, as (θ, r): its direction, continuous
/// in the leader's angle q (no branch cut), and its distance. The leader's pin lies at
/// `a`·(cos q, sin q) from its own pivot, the pivots `l` apart, `sign` = −1 when the
/// follower's pivot is O3 (crank chart) and +1 when it is O2 (rocker chart).
fn base_angle<T: Scalar>(a: f64, l: f64, sign: f64, q: T) -> (T, T) {
    let (s, c) = q.sin_cos();
    let (x, y) = (c * a + sign * l, s * a);
    let r = x.hypot(y);
    let theta = if a >= l {
        // The pin circles the pivot: θ = q plus a turn that stays within ±π/2
        // (the vector rotated back by q has the positive x part a + sign·l·cos q).
        q + (s * (-sign * l)).atan2(c * (sign * l) + a)
    } else if sign > 0.0 {
        // The pin stays on the side x > 0 of the pivot.
        y.atan2(x)
    } else {
        // ... or on the side x < 0: the angle from the negative x axis, turned by π.
        (-y).atan2(-x) + PI
    };
    (theta, r)
}

/// The follower's angle for leader angle `q` without its branch and turns: (θ, acos(c)),
/// or an error where the loop cannot be closed (the chart was not left in time).
fn follower_terms<T: Scalar>(p: &Parameters, chart: Chart, q: T) -> Result<(T, T), ModelError> {
    let (a, b, sign) = match chart {
        Chart::Crank => (p.l2, p.l3, -1.0),
        Chart::Rocker => (p.l3, p.l2, 1.0),
    };
    let (theta, r) = base_angle(a, p.l, sign, q);
    let cosine = (r * r + b * b - p.L * p.L) / (r * (2.0 * b));
    if cosine.value().abs().is_nan() || cosine.value().abs() > 1.0 {
        let name = ["phi2", "phi3"][chart.leader() - 1];
        return Err(ModelError::new(format!(
            "{name} = {}: the loop cannot be closed there (the follower's angle has no \
             solution; cos = {}); the chart should have been left at its event \
             indicator's zero crossing",
            q.value(),
            cosine.value()
        )));
    }
    Ok((theta, cosine.acos()))
}

/// The full state y from the independent state `x` in `coordinates`: the follower's angle
/// in closed form and its speed from the velocity constraint B1·ω2 = C1·ω3.
pub fn full_state<T: Scalar>(
    p: &Parameters,
    at: &Coordinates,
    x: &[T; 6],
) -> Result<[T; 8], ModelError> {
    let chart = at.chart;
    let (q, speed) = (x[1], x[4]);
    let (theta, half) = follower_terms(p, chart, q)?;
    let follower = theta + half * at.branch + at.turns;
    let zero = T::constant(0.0);
    let mut y = [x[0], zero, zero, x[2], x[3], zero, zero, x[5]];
    y[chart.leader()] = q;
    y[chart.follower()] = follower;
    let t = constraint_terms(p, y[1], y[2], zero, zero);
    let (w2, w3) = match chart {
        Chart::Crank => (speed, t.b1 / t.c1 * speed),
        Chart::Rocker => (t.c1 / t.b1 * speed, speed),
    };
    if !(w2.value().is_finite() && w3.value().is_finite()) {
        return Err(ModelError::new(format!(
            "the loop's speeds are undetermined at phi2 = {}, phi3 = {} (B1 = {}, C1 = {})",
            y[1].value(),
            y[2].value(),
            number(t.b1.value()),
            number(t.c1.value())
        )));
    }
    y[5] = w2;
    y[6] = w3;
    Ok(y)
}

/// The independent state of `y` in `chart`.
pub fn independent(y: &State, chart: Chart) -> Independent {
    let lead = chart.leader();
    [y[0], y[lead], y[3], y[4], y[lead + 4], y[7]]
}

/// The branch and turns that reproduce `y`'s follower angle in `chart`: what a chart
/// needs when it is entered at configuration `y`.
pub fn coordinates_for(p: &Parameters, y: &State, chart: Chart) -> Result<Coordinates, ModelError> {
    let (theta, half) = follower_terms(p, chart, y[chart.leader()])?;
    let offset = y[chart.follower()] - theta;
    let fit = |branch: f64| {
        let rest = offset - branch * half;
        let turns = (rest / TAU).round() * TAU;
        (branch, turns, (rest - turns).abs())
    };
    let (plus, minus) = (fit(1.0), fit(-1.0));
    let (branch, turns, _) = if plus.2 <= minus.2 { plus } else { minus };
    Ok(Coordinates {
        chart,
        branch,
        turns,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::kinematics::{assemble_rocker, length_residual};

    /// A crank-rocker (the default), a double crank and a non-Grashof triple rocker.
    fn geometries() -> Vec<Parameters> {
        let base = Parameters::default();
        vec![
            base,
            Parameters {
                l: 0.05,
                l2: 0.5,
                l3: 0.6,
                L: 0.4,
                ..base
            },
            Parameters {
                l: 0.5,
                l2: 0.4,
                l3: 0.45,
                L: 0.3,
                ..base
            },
        ]
    }

    #[test]
    fn charts_reproduce_every_assembled_configuration() {
        for p in geometries() {
            for k in -40..40 {
                let phi2 = 0.37 * k as f64;
                for guess in [1.5, -1.5] {
                    let Ok(phi3) = assemble_rocker(&p, phi2, guess + phi2) else {
                        continue;
                    };
                    let t = constraint_terms(&p, phi2, phi3, 0.0, 0.0);
                    let w2 = 1.3;
                    let w3 = t.b1 / t.c1 * w2;
                    let y = [phi2 + 0.1, phi2, phi3, phi3 - 0.2, 2.0, w2, w3, -1.0];
                    let chart = preferred_chart(&p, t.b1, t.c1);
                    let at = coordinates_for(&p, &y, chart).unwrap();
                    let back = full_state(&p, &at, &independent(&y, chart)).unwrap();
                    for i in 0..8 {
                        let scale = y[i].abs().max(1.0);
                        assert!((back[i] - y[i]).abs() < 1e-12 * scale, "{i} {back:?} {y:?}");
                    }
                    assert!(length_residual(&p, back[1], back[2]).abs() < 1e-15);
                    assert!(handover_indicator(&p, chart, t.b1, t.c1) > 0.0);
                }
            }
        }
    }

    #[test]
    fn follower_is_continuous_over_whole_turns() {
        // A double crank: both φ2 and φ3 turn fully, the follower's angle must wind with
        // the leader's without a jump.
        let p = &geometries()[1];
        let phi3 = assemble_rocker(p, 0.0, 0.0).unwrap();
        let y = [0.0, 0.0, phi3, 0.0, 0.0, 0.0, 0.0, 0.0];
        let at = coordinates_for(p, &y, Chart::Crank).unwrap();
        let mut previous = phi3;
        for k in 1..=2000 {
            let q = k as f64 * 0.01;
            let x = [0.0, q, 0.0, 0.0, 0.0, 0.0];
            let follower = full_state(p, &at, &x).unwrap()[2];
            assert!((follower - previous).abs() < 0.05, "jump at q = {q}");
            previous = follower;
        }
        assert!(
            previous > 15.0,
            "the rocker turned with the crank: {previous}"
        );
    }

    #[test]
    fn handover_is_hysteretic() {
        let p = Parameters::default();
        // Where the crank chart's indicator crosses zero, the rocker chart's is
        // (1 − HANDOVER⁴)·(B1/B̄)² = 15/16 of its term (docs/model.md §6).
        let (sb, sc) = pivot_scales(&p);
        let (b1, c1) = (0.8 * sb, HANDOVER * 0.8 * sc);
        assert!(handover_indicator(&p, Chart::Crank, b1, c1).abs() < 1e-15);
        let rocker = handover_indicator(&p, Chart::Rocker, b1, c1);
        assert!((rocker - 15.0 / 16.0 * 0.64).abs() < 1e-15, "{rocker}");
    }
}
