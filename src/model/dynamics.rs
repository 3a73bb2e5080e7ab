//! Equations of motion in the orthogonal-complement form (docs/model.md §2, [59], [72]–[78]),
//! with the paper's sign slips corrected (docs/model.md §5).

use super::kinematics::{constraint_terms, ConstraintTerms};
use super::{Inputs, Parameters, Scalar, State};

/// Motor and load torques: the inputs, plus the built-in laws while they are on
/// (docs/model.md §4, the paper's [79] and [80]).
#[inline(always)]
pub fn applied_torques<T: Scalar>(p: &Parameters, inputs: &Inputs<T>, omega1: T) -> (T, T) {
    if !p.builtin_laws {
        return (inputs.motor_torque, inputs.load_torque);
    }
    let motor = inputs.motor_torque + p.Mm_a0 + (omega1 * p.Mm_a2 + p.Mm_a1) * omega1;
    let load = inputs.load_torque + p.Mr_b0 + omega1 * p.Mr_b1;
    (motor, load)
}

/// Generalised forces Q1..Q4 (docs/model.md §2; the k12 spring sign corrected, docs/model.md §5).
#[inline(always)]
pub fn generalized_forces<T: Scalar>(p: &Parameters, inputs: &Inputs<T>, y: &[T; 8]) -> [T; 4] {
    let [phi1, phi2, phi3, phi4, w1, w2, w3, w4] = *y;
    let (motor, load) = applied_torques(p, inputs, w1);
    let spring12 = (phi2 - phi1) * p.k12 + (w2 - w1) * p.d12;
    let spring34 = (phi3 - phi4) * p.k34 + (w3 - w4) * p.d34;
    [
        motor + spring12,
        -spring12,
        -spring34,
        spring34 - load - w4 * p.c4,
    ]
}

/// Accelerations ω̇ with the terms they were computed from.
#[derive(Clone, Copy, Debug)]
pub struct Accelerations<T = f64> {
    pub omega_dot: [T; 4],
    pub forces: [T; 4],
    pub terms: ConstraintTerms<T>,
}

/// Solve the four orthogonal-complement equations for ω̇ (docs/model.md §2):
///
/// ```text
/// J1·ω̇1 = Q1
/// C1·J2·ω̇2 + B1·J3·ω̇3 = C1·Q2 + B1·Q3      (Lτᵀ(Jω̇ − Q) = 0, [72]–[78])
/// B1·ω̇2 − C1·ω̇3 = −(Ḃ1·ω2 − Ċ1·ω3)         (acceleration constraint, [49])
/// J4·ω̇4 = Q4
/// ```
///
/// The 2×2 block has determinant −(C1²·J2 + B1²·J3), zero only at a change point where
/// B1 = C1 = 0; there the result is not finite, which the caller detects.
#[inline(always)]
pub fn accelerations<T: Scalar>(
    p: &Parameters,
    inputs: &Inputs<T>,
    y: &[T; 8],
) -> Accelerations<T> {
    let forces = generalized_forces(p, inputs, y);
    let terms = constraint_terms(p, y[1], y[2], y[5], y[6]);
    let ConstraintTerms {
        b1,
        c1,
        b1_dot,
        c1_dot,
    } = terms;
    let r1 = c1 * forces[1] + b1 * forces[2];
    let r2 = -(b1_dot * y[5] - c1_dot * y[6]);
    let det = -(c1 * c1 * p.J2 + b1 * b1 * p.J3);
    let omega_dot = [
        forces[0] / p.J1,
        (-c1 * r1 - b1 * p.J3 * r2) / det,
        (c1 * p.J2 * r2 - b1 * r1) / det,
        forces[3] / p.J4,
    ];
    Accelerations {
        omega_dot,
        forces,
        terms,
    }
}

/// The state derivative ẏ = (ω, ω̇): the right-hand side integrated by the solver.
#[inline(always)]
pub fn state_derivative(p: &Parameters, inputs: &Inputs, y: &State, dy: &mut State) {
    let a = accelerations(p, inputs, y);
    dy[..4].copy_from_slice(&y[4..]);
    dy[4..].copy_from_slice(&a.omega_dot);
}

/// ẏ at the same (t, y) for inputs `to` instead of `from`, from ẏ = `dy` with `from`. The
/// inputs are torques on the crank and the rocker: they enter Q1 and Q4 alone, additively
/// (the built-in laws add to them, independent of the inputs), and ω̇1 = Q1/J1,
/// ω̇4 = Q4/J4; the constrained pair sees only Q2 and Q3. So ∂ẏ/∂M_m = 1/J1 on ω̇1 and
/// ∂ẏ/∂M_r = −1/J4 on ω̇4, whatever the state: the shift is exact up to rounding.
#[inline(always)]
pub fn shift_inputs(p: &Parameters, dy: &mut State, from: &Inputs, to: &Inputs) {
    dy[4] += (to.motor_torque - from.motor_torque) / p.J1;
    dy[7] -= (to.load_torque - from.load_torque) / p.J4;
}

/// Rod axial force, tension positive: −λ·L (docs/model.md §2), with λ from whichever of
/// λ = (J2·ω̇2 − Q2)/B1 = −(J3·ω̇3 − Q3)/C1 has the larger denominator.
pub fn rod_force<T: Scalar>(p: &Parameters, inputs: &Inputs<T>, y: &[T; 8]) -> T {
    let Accelerations {
        omega_dot,
        forces,
        terms,
    } = accelerations(p, inputs, y);
    let lambda = if terms.b1.value().abs() >= terms.c1.value().abs() {
        (omega_dot[1] * p.J2 - forces[1]) / terms.b1
    } else {
        -(omega_dot[2] * p.J3 - forces[2]) / terms.c1
    };
    -lambda * p.L
}

/// Mechanical energy E = ½ΣJi·ωi² + ½k12(φ1 − φ2)² + ½k34(φ3 − φ4)² (docs/model.md §2).
pub fn energy<T: Scalar>(p: &Parameters, y: &[T; 8]) -> T {
    let [phi1, phi2, phi3, phi4, w1, w2, w3, w4] = *y;
    let (twist12, twist34) = (phi1 - phi2, phi3 - phi4);
    (w1 * p.J1 * w1 + w2 * p.J2 * w2 + w3 * p.J3 * w3 + w4 * p.J4 * w4) * 0.5
        + twist12 * twist12 * (0.5 * p.k12)
        + twist34 * twist34 * (0.5 * p.k34)
}

/// dE/dt = M_m·ω1 − (M_r + c4·ω4)·ω4 − d12·(ω2 − ω1)² − d34·(ω3 − ω4)² (docs/model.md §2),
/// with M_m and M_r the totals including the built-in laws.
pub fn power(p: &Parameters, inputs: &Inputs, y: &State) -> f64 {
    let [_, _, _, _, w1, w2, w3, w4] = *y;
    let (motor, load) = applied_torques(p, inputs, w1);
    motor * w1 - (load + p.c4 * w4) * w4 - p.d12 * (w2 - w1).powi(2) - p.d34 * (w3 - w4).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::kinematics::closure;

    fn sample_state(p: &Parameters) -> State {
        let phi2 = 0.9;
        let phi3 = crate::model::kinematics::assemble_rocker(p, phi2, 1.5).unwrap();
        let t = constraint_terms(p, phi2, phi3, 0.0, 0.0);
        let w2 = 2.5;
        [
            phi2 + 0.1,
            phi2,
            phi3,
            phi3 - 0.05,
            3.0,
            w2,
            t.b1 / t.c1 * w2,
            -1.0,
        ]
    }

    #[test]
    fn accelerations_satisfy_the_constrained_equations() {
        let p = Parameters {
            d12: 0.3,
            d34: 0.2,
            c4: 0.1,
            ..Parameters::default()
        };
        let inputs = Inputs {
            motor_torque: 1.5,
            load_torque: -0.5,
        };
        let y = sample_state(&p);
        let a = accelerations(&p, &inputs, &y);
        let t = a.terms;
        // Acceleration constraint [49].
        let acc = t.b1 * a.omega_dot[1] - t.c1 * a.omega_dot[2] + t.b1_dot * y[5] - t.c1_dot * y[6];
        assert!(acc.abs() < 1e-12, "{acc}");
        // J·ω̇ − Q lies along Gᵀ = (0, B1, −C1, 0): one multiplier explains both rows.
        let l2 = (p.J2 * a.omega_dot[1] - a.forces[1]) / t.b1;
        let l3 = -(p.J3 * a.omega_dot[2] - a.forces[2]) / t.c1;
        assert!((l2 - l3).abs() < 1e-10 * l2.abs().max(1.0), "{l2} {l3}");
        assert!((p.J1 * a.omega_dot[0] - a.forces[0]).abs() < 1e-12);
        assert!((p.J4 * a.omega_dot[3] - a.forces[3]).abs() < 1e-12);
    }

    #[test]
    fn builtin_laws_add_to_the_inputs_and_switch_off() {
        let inputs = Inputs {
            motor_torque: 3.0,
            load_torque: -2.0,
        };
        // The paper's laws by default: at omega1 = 2, 100 - 40 - 4 and 20 - 0.1.
        let on = applied_torques(&Parameters::default(), &inputs, 2.0);
        assert_eq!(on, (3.0 + 56.0, -2.0 + 19.9));
        let off = applied_torques(&Parameters::default().without_builtin_laws(), &inputs, 2.0);
        assert_eq!(off, (3.0, -2.0));
    }

    #[test]
    fn restoring_springs_with_corrected_sign() {
        let p = Parameters::default().without_builtin_laws();
        // Body 2 ahead of body 1: the k12 spring pulls body 1 forward (docs/model.md §5).
        let y = [0.0, 0.1, 1.48, 1.48, 0.0, 0.0, 0.0, 0.0];
        let q = generalized_forces(&p, &Inputs::default(), &y);
        assert!(q[0] > 0.0 && q[1] < 0.0);
        let y = [0.0, 0.0, 1.5, 1.4, 0.0, 0.0, 0.0, 0.0];
        let q = generalized_forces(&p, &Inputs::default(), &y);
        assert!(q[2] < 0.0 && q[3] > 0.0);
    }

    #[test]
    fn power_is_the_energy_rate() {
        let p = Parameters {
            d12: 0.4,
            d34: 0.7,
            c4: 0.2,
            ..Parameters::default()
        };
        let inputs = Inputs {
            motor_torque: 2.0,
            load_torque: 1.0,
        };
        let y = sample_state(&p);
        let mut dy = [0.0; 8];
        state_derivative(&p, &inputs, &y, &mut dy);
        let h = 1e-6;
        let step = |s: f64| -> State { std::array::from_fn(|i| y[i] + s * h * dy[i]) };
        let rate = (energy(&p, &step(1.0)) - energy(&p, &step(-1.0))) / (2.0 * h);
        assert!(
            (rate - power(&p, &inputs, &y)).abs() < 1e-6,
            "{rate} {}",
            power(&p, &inputs, &y)
        );
        assert!(closure(&p, y[1], y[2]).abs() < 1e-14);
    }

    #[test]
    fn rod_force_is_the_tension_that_turns_the_rocker() {
        // Independent of λ: a tension T pulls pin A3 towards A2 with force T·d/|d|; its
        // moment about O3 must be the rocker's J3·ω̇3 − Q3, and likewise for the crank.
        let p = Parameters {
            d34: 0.3,
            ..Parameters::default()
        };
        let inputs = Inputs {
            motor_torque: 3.0,
            load_torque: 0.0,
        };
        let y = sample_state(&p);
        let tension = rod_force(&p, &inputs, &y);
        let a = accelerations(&p, &inputs, &y);
        let [dx, dy] = crate::model::kinematics::rod_vector(&p, y[1], y[2]);
        let (ux, uy) = (dx / p.L, dy / p.L);
        let (s3, c3) = y[2].sin_cos();
        let rocker_moment = p.l3 * (c3 * tension * uy - s3 * tension * ux);
        assert!(
            (rocker_moment - (p.J3 * a.omega_dot[2] - a.forces[2])).abs() < 1e-9,
            "{rocker_moment}"
        );
        let (s2, c2) = y[1].sin_cos();
        let crank_moment = p.l2 * (c2 * -tension * uy - s2 * -tension * ux);
        assert!(
            (crank_moment - (p.J2 * a.omega_dot[1] - a.forces[1])).abs() < 1e-9,
            "{crank_moment}"
        );
        assert!(
            tension.abs() > 1.0,
            "a loaded linkage carries rod force: {tension}"
        );
    }

    /// The input shift equals evaluating afresh with the other inputs, to rounding of the
    /// terms, on states and inputs across their ranges, built-in laws on and off.
    #[test]
    fn shifting_the_inputs_equals_evaluating_with_them() {
        for builtin_laws in [false, true] {
            let p = Parameters {
                builtin_laws,
                d12: 0.3,
                d34: 0.2,
                ..Parameters::default()
            };
            let y = sample_state(&p);
            for (k, (m, r)) in [(0.0, 0.0), (150.0, -20.0), (-3e3, 7.5), (1e-9, 1e5)]
                .into_iter()
                .enumerate()
            {
                let from = Inputs {
                    motor_torque: 10.0 * k as f64 - 5.0,
                    load_torque: 2.0 - k as f64,
                };
                let to = Inputs {
                    motor_torque: m,
                    load_torque: r,
                };
                let (mut shifted, mut fresh) = ([0.0; 8], [0.0; 8]);
                state_derivative(&p, &from, &y, &mut shifted);
                shift_inputs(&p, &mut shifted, &from, &to);
                state_derivative(&p, &to, &y, &mut fresh);
                for i in 0..8 {
                    let size = fresh[i].abs() + (m.abs() + r.abs() + 1e3) / p.J1.min(p.J4);
                    assert!(
                        (shifted[i] - fresh[i]).abs() <= 8.0 * f64::EPSILON * size,
                        "component {i}: {} against {}",
                        shifted[i],
                        fresh[i]
                    );
                }
            }
        }
    }
}
