//! Parameter sensitivities S = ∂y/∂p along a trajectory (docs/sensitivities.md): their
//! differential equation Ṡ = ∂f/∂y·S + ∂f/∂p, the start S(0) = ∂y(0)/∂p, and the
//! projection of S onto the constraint's tangent space, the derivative of the state's own
//! projection. ∂f/∂y·S comes from one pass of the model in [`DualVector`] numbers, ∂f/∂p in
//! closed form: every parameter offered enters the accelerations through the generalised
//! forces (linearly) or the inertias, never through the constraint.

use super::dynamics::{accelerations, Accelerations};
use super::kinematics::constraint_terms;
use super::{initial_state, DualVector, Inputs, ModelError, Parameters, State, STATE_SIZE};

/// How many parameters one run carries sensitivities for: the FMU's
/// `sensitivity_1.parameter` … `sensitivity_5.parameter` slots.
pub const SLOTS: usize = 5;

macro_rules! items {
    ($($index:literal)*) => {
        /// The values of a `sensitivity_k.parameter` slot: none (0), or a parameter with a
        /// sensitivity, as its index in [`super::PARAMETERS`] plus one.
        pub const ITEMS: [(&str, i32, &str); 1 + [$($index,)*].len()] = [
            ("none", 0, "no parameter: the slot is unused"),
            $((super::PARAMETERS[$index].name, $index + 1, super::PARAMETERS[$index].description),)*
        ];
    };
}

// The inertias, springs and dampers, the start values but phi3_guess, the torque laws.
items!(0 1 2 3 4 5 6 7 8 13 15 16 17 18 19 20 21 22 23 24);

/// The parameter a slot's value names, where it is one of [`ITEMS`] other than none.
pub fn chosen(value: i32) -> Option<Option<(usize, Sensitive)>> {
    if value == 0 {
        return Some(None);
    }
    let index = usize::try_from(value - 1).ok()?;
    ITEMS.iter().any(|item| item.1 == value).then_some(())?;
    Some(Some((index, Sensitive::of(index)?)))
}

/// A parameter with a sensitivity, by how it enters the mechanism: the dynamics'
/// parameters through the accelerations alone (S(0) = 0), the start values through the
/// initial state alone (∂f/∂p = 0). The lengths and the rocker's assembly guess have none:
/// the lengths set the constraint and its projection, the guess is a discrete choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sensitive {
    /// An inertia J1…J4 (0-based body).
    Inertia(usize),
    K12,
    D12,
    K34,
    D34,
    C4,
    /// The built-in motor law's coefficient of ω1^n.
    Motor(i32),
    /// The built-in load law's coefficient of ω1^n.
    Load(i32),
    /// A start value: index into [`super::PARAMETERS`].
    Start(usize),
}

impl Sensitive {
    /// Parameter `index` of [`super::PARAMETERS`], where it has a sensitivity.
    pub fn of(index: usize) -> Option<Self> {
        Some(match super::PARAMETERS.get(index)?.name {
            "J1" => Self::Inertia(0),
            "J2" => Self::Inertia(1),
            "J3" => Self::Inertia(2),
            "J4" => Self::Inertia(3),
            "k12" => Self::K12,
            "d12" => Self::D12,
            "k34" => Self::K34,
            "d34" => Self::D34,
            "c4" => Self::C4,
            "Mm_a0" => Self::Motor(0),
            "Mm_a1" => Self::Motor(1),
            "Mm_a2" => Self::Motor(2),
            "Mr_b0" => Self::Load(0),
            "Mr_b1" => Self::Load(1),
            "phi2_0" | "twist12_0" | "twist34_0" | "omega1_0" | "omega2_0" | "omega4_0" => {
                Self::Start(index)
            }
            _ => return None,
        })
    }
}

/// ∂ω̇/∂p for parameter `which` at y, with `a` the accelerations there. Forces enter ω̇
/// linearly ([`force_response`]); an inertia divides its own row (J1, J4) or the
/// constrained pair's determinant (J2, J3); a start value does not enter.
#[inline]
pub fn acceleration_partials(
    p: &Parameters,
    y: &State,
    a: &Accelerations,
    which: Sensitive,
) -> [f64; 4] {
    let [phi1, phi2, phi3, phi4, w1, w2, w3, w4] = *y;
    let laws = if p.builtin_laws { 1.0 } else { 0.0 };
    let forces = |q: [f64; 4]| force_response(p, a, q);
    match which {
        Sensitive::K12 => forces([phi2 - phi1, phi1 - phi2, 0.0, 0.0]),
        Sensitive::D12 => forces([w2 - w1, w1 - w2, 0.0, 0.0]),
        Sensitive::K34 => forces([0.0, 0.0, phi4 - phi3, phi3 - phi4]),
        Sensitive::D34 => forces([0.0, 0.0, w4 - w3, w3 - w4]),
        Sensitive::C4 => forces([0.0, 0.0, 0.0, -w4]),
        Sensitive::Motor(n) => forces([laws * w1.powi(n), 0.0, 0.0, 0.0]),
        Sensitive::Load(n) => forces([0.0, 0.0, 0.0, -laws * w1.powi(n)]),
        Sensitive::Inertia(0) => [-a.omega_dot[0] / p.J1, 0.0, 0.0, 0.0],
        Sensitive::Inertia(3) => [0.0, 0.0, 0.0, -a.omega_dot[3] / p.J4],
        Sensitive::Inertia(body) => inertia_partials(p, y, a, body == 1),
        Sensitive::Start(_) => [0.0; 4],
    }
}

/// The change of ω̇ for a change `q` of the generalised forces (the accelerations are
/// affine in Q: dynamics.rs's solve with the velocity terms left out).
fn force_response(p: &Parameters, a: &Accelerations, q: [f64; 4]) -> [f64; 4] {
    let (b1, c1) = (a.terms.b1, a.terms.c1);
    let r1 = c1 * q[1] + b1 * q[2];
    let det = -(c1 * c1 * p.J2 + b1 * b1 * p.J3);
    [q[0] / p.J1, -c1 * r1 / det, -b1 * r1 / det, q[3] / p.J4]
}

/// ∂ω̇/∂J2 (`crank`) or ∂ω̇/∂J3: the constrained pair's solve differentiated. With
/// r1 = C1·Q2 + B1·Q3, r2 the velocity term and det = −(C1²·J2 + B1²·J3):
/// ω̇2 = (−C1·r1 − B1·J3·r2)/det and ω̇3 = (C1·J2·r2 − B1·r1)/det.
fn inertia_partials(p: &Parameters, y: &State, a: &Accelerations, crank: bool) -> [f64; 4] {
    let t = &a.terms;
    let r2 = -(t.b1_dot * y[5] - t.c1_dot * y[6]);
    let det = -(t.c1 * t.c1 * p.J2 + t.b1 * t.b1 * p.J3);
    let [_, w2_dot, w3_dot, _] = a.omega_dot;
    if crank {
        let det_j = -t.c1 * t.c1;
        [
            0.0,
            -w2_dot * det_j / det,
            (t.c1 * r2 - w3_dot * det_j) / det,
            0.0,
        ]
    } else {
        let det_j = -t.b1 * t.b1;
        [
            0.0,
            (-t.b1 * r2 - w2_dot * det_j) / det,
            -w3_dot * det_j / det,
            0.0,
        ]
    }
}

/// The sensitivities' columns: S[i][j] = ∂y_i/∂p_j for the parameters `which`.
pub type Sensitivities<const P: usize> = [[f64; P]; STATE_SIZE];

/// ẏ and Ṡ = ∂f/∂y·S + ∂f/∂p at (inputs, y, s), for the parameters `which`.
#[inline]
pub fn derivative<const P: usize>(
    p: &Parameters,
    inputs: &Inputs,
    which: &[Sensitive; P],
    (y, s): (&State, &Sensitivities<P>),
    (dy, ds): (&mut State, &mut Sensitivities<P>),
) {
    let seeded: [DualVector<P>; STATE_SIZE] = std::array::from_fn(|i| DualVector::new(y[i], s[i]));
    let constant = |v: f64| DualVector::new(v, [0.0; P]);
    let dual_inputs = Inputs {
        motor_torque: constant(inputs.motor_torque),
        load_torque: constant(inputs.load_torque),
    };
    let dual = accelerations(p, &dual_inputs, &seeded);
    let values = Accelerations {
        omega_dot: dual.omega_dot.map(|w| w.v),
        forces: dual.forces.map(|q| q.v),
        terms: super::kinematics::ConstraintTerms {
            b1: dual.terms.b1.v,
            c1: dual.terms.c1.v,
            b1_dot: dual.terms.b1_dot.v,
            c1_dot: dual.terms.c1_dot.v,
        },
    };
    dy[..4].copy_from_slice(&y[4..]);
    ds[..4].copy_from_slice(&s[4..]);
    for k in 0..4 {
        dy[4 + k] = values.omega_dot[k];
        ds[4 + k] = dual.omega_dot[k].d;
    }
    for (j, &parameter) in which.iter().enumerate() {
        let partials = acceleration_partials(p, y, &values, parameter);
        for k in 0..4 {
            ds[4 + k][j] += partials[k];
        }
    }
}

/// S projected onto the tangent space of the constraint at `y` (on the constraint): the
/// derivative of [`super::project`], which moves φ2, φ3 along J⁻¹Gᵀ onto g = 0 and then
/// ω2, ω3 along J⁻¹Gᵀ onto B1·ω2 − C1·ω3 = 0. A column is corrected so that G·∂φ = 0 and
/// the velocity constraint's derivative (which moves with the angles' change through B1
/// and C1) vanishes.
pub fn project<const P: usize>(p: &Parameters, y: &State, s: &mut Sensitivities<P>) {
    let t = constraint_terms(p, y[1], y[2], y[5], y[6]);
    let moves = (t.b1 / p.J2, t.c1 / p.J3);
    let inverse_weight = 1.0 / (t.b1 * moves.0 + t.c1 * moves.1);
    if !inverse_weight.is_finite() {
        return; // a change point: the passage check refuses the step
    }
    let [_, phi2, phi3, ..] = s;
    for (d2, d3) in phi2.iter_mut().zip(phi3.iter_mut()) {
        let scale = (t.b1 * *d2 - t.c1 * *d3) * inverse_weight;
        *d2 -= moves.0 * scale;
        *d3 += moves.1 * scale;
    }
    let angle = |i: usize| DualVector::new(y[i], s[i]);
    let moved = constraint_terms(p, angle(1), angle(2), angle(5), angle(6));
    let [.., omega2, omega3, _] = s;
    for (j, (d2, d3)) in omega2.iter_mut().zip(omega3.iter_mut()).enumerate() {
        let velocity = t.b1 * *d2 - t.c1 * *d3 + moved.b1.d[j] * y[5] - moved.c1.d[j] * y[6];
        let scale = velocity * inverse_weight;
        *d2 -= moves.0 * scale;
        *d3 += moves.1 * scale;
    }
}

/// S(0) = ∂y(0)/∂p: zero for the dynamics' parameters (the initial state does not depend
/// on them); for a start value, central differences of the initial state (docs/model.md
/// §3), exact for the speeds and twists, in which it is linear, and to the differences'
/// truncation for phi2_0, through the assembly (tests/sensitivities.rs checks it).
pub fn initial<const P: usize>(
    p: &Parameters,
    which: &[Sensitive; P],
) -> Result<Sensitivities<P>, ModelError> {
    let mut s = [[0.0; P]; STATE_SIZE];
    for (j, &parameter) in which.iter().enumerate() {
        if let Sensitive::Start(index) = parameter {
            let value = p.get(index).unwrap_or(0.0);
            let h = 1e-6 * value.abs().max(1.0);
            let moved = |delta: f64| -> Result<State, ModelError> {
                let mut q = *p;
                q.set(index, value + delta)?;
                initial_state(&q)
            };
            let (up, down) = (moved(h)?, moved(-h)?);
            for (row, (u, d)) in s.iter_mut().zip(up.iter().zip(&down)) {
                row[j] = (u - d) / (2.0 * h);
            }
        }
    }
    Ok(s)
}

/// [`initial`] for as many parameters as `which` holds (up to [`SLOTS`]): by state, the
/// columns in `which`'s order.
pub fn initial_by_slot(
    p: &Parameters,
    which: &[Sensitive],
) -> Result<Sensitivities<SLOTS>, ModelError> {
    let padded: [Sensitive; SLOTS] =
        std::array::from_fn(|j| which.get(j).copied().unwrap_or(Sensitive::K12));
    let mut s = initial(p, &padded)?;
    for row in s.iter_mut() {
        row[which.len()..].fill(0.0);
    }
    Ok(s)
}

/// The refusal of a sensitivity to a parameter that has none here.
pub fn not_offered(index: usize) -> ModelError {
    let name = super::PARAMETERS.get(index).map_or("?", |info| info.name);
    ModelError::new(format!(
        "no sensitivity to {name}: it sets the linkage's geometry, which the constraint and \
         its projection depend on; sensitivities are offered for the inertias, springs, \
         dampers, torque laws and start values"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{self, PARAMETERS};

    fn damped() -> Parameters {
        Parameters {
            d12: 0.3,
            d34: 0.2,
            c4: 0.1,
            omega1_0: 2.0,
            omega2_0: 1.5,
            twist12_0: 0.05,
            ..Parameters::default()
        }
    }

    /// A state on the constraint, moving.
    fn moving(p: &Parameters) -> State {
        let mut y = model::initial_state(p).unwrap();
        y[0] += 0.02;
        y[7] = -0.7;
        y
    }

    fn offered() -> Vec<(usize, Sensitive)> {
        (0..PARAMETERS.len())
            .filter_map(|i| Some((i, Sensitive::of(i)?)))
            .collect()
    }

    #[test]
    fn the_geometry_has_no_sensitivity_and_everything_else_has() {
        let none: Vec<_> = (0..PARAMETERS.len())
            .filter(|&i| Sensitive::of(i).is_none())
            .map(|i| PARAMETERS[i].name)
            .collect();
        assert_eq!(none, ["l", "l2", "l3", "L", "phi3_guess"]);
        assert!(not_offered(12).to_string().contains("no sensitivity to L"));
        // The slots' items are exactly the parameters with a sensitivity.
        let items: Vec<_> = ITEMS[1..].iter().map(|item| item.0).collect();
        let offered: Vec<_> = offered().iter().map(|&(i, _)| PARAMETERS[i].name).collect();
        assert_eq!(items, offered);
        assert_eq!(chosen(0), Some(None));
        assert_eq!(chosen(5), Some(Some((4, Sensitive::K12))));
        assert_eq!(chosen(13), None, "L");
        assert_eq!(chosen(99), None);
    }

    /// Each closed-form ∂ω̇/∂p against central differences of the accelerations.
    #[test]
    fn acceleration_partials_are_the_accelerations_derivatives() {
        let p = damped();
        let y = moving(&p);
        let inputs = Inputs {
            motor_torque: 0.4,
            load_torque: -0.3,
        };
        let a = accelerations(&p, &inputs, &y);
        for (index, which) in offered() {
            let exact = acceleration_partials(&p, &y, &a, which);
            let value = p.get(index).unwrap();
            let h = 1e-6 * value.abs().max(1.0);
            let at = |delta: f64| {
                let mut q = p;
                q.set(index, value + delta).unwrap();
                accelerations(&q, &inputs, &y).omega_dot
            };
            let (up, down) = (at(h), at(-h));
            for k in 0..4 {
                let estimate = (up[k] - down[k]) / (2.0 * h);
                let scale = estimate.abs().max(1e-3);
                assert!(
                    (exact[k] - estimate).abs() <= 1e-7 * scale,
                    "{}: d omega_dot{}: {} against {estimate}",
                    PARAMETERS[index].name,
                    k + 1,
                    exact[k]
                );
            }
        }
    }

    /// The projected columns are the derivative of the state's projection: projecting
    /// y ± h·column and differencing gives them.
    #[test]
    fn projected_sensitivities_are_the_projections_derivative() {
        let p = damped();
        let y = moving(&p);
        let columns = [
            [0.3, -0.2, 0.5, 0.1, 1.0, -0.4, 0.7, 0.2],
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 1.0, 0.0],
        ];
        let mut s: Sensitivities<3> = std::array::from_fn(|i| columns.map(|c| c[i]));
        project(&p, &y, &mut s);
        let h = 1e-6;
        for (j, column) in columns.iter().enumerate() {
            let projected = |sign: f64| {
                let mut z: State = std::array::from_fn(|i| y[i] + sign * h * column[i]);
                model::project(&p, &mut z, 0.0).unwrap();
                z
            };
            let (up, down) = (projected(1.0), projected(-1.0));
            for i in 0..STATE_SIZE {
                let estimate = (up[i] - down[i]) / (2.0 * h);
                assert!(
                    (s[i][j] - estimate).abs() <= 1e-7 * estimate.abs().max(1.0),
                    "column {j}, component {i}: {} against {estimate}",
                    s[i][j]
                );
            }
        }
    }

    #[test]
    fn a_start_value_moves_the_initial_state_and_a_dynamics_parameter_does_not() {
        let p = damped();
        let index = |name| model::Parameters::index_of(name).unwrap();
        let which = [
            Sensitive::of(index("omega1_0")).unwrap(),
            Sensitive::of(index("k12")).unwrap(),
            Sensitive::of(index("omega2_0")).unwrap(),
        ];
        let s = initial(&p, &which).unwrap();
        let column = |j: usize| s.map(|row| row[j]);
        let unit = |i: usize| std::array::from_fn::<f64, 8, _>(|k| f64::from(u8::from(k == i)));
        assert!(column(0)
            .iter()
            .zip(unit(4))
            .all(|(a, b)| (a - b).abs() < 1e-9));
        assert_eq!(column(1), [0.0; 8]);
        // omega3(0) follows omega2_0 through the constraint: B1·ω2 = C1·ω3.
        let y = model::initial_state(&p).unwrap();
        let t = constraint_terms(&p, y[1], y[2], 0.0, 0.0);
        assert!((column(2)[5] - 1.0).abs() < 1e-9);
        assert!((column(2)[6] - t.b1 / t.c1).abs() < 1e-8);
    }
}
