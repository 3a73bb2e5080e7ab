//! What the monodromy says of a cycle's stability, and what the state equations'
//! linearisation along it says of its modes.
//!
//! The monodromy Φ = ∂x(T)/∂x0 of an autonomous system's cycle has the eigenvalue 1 along
//! the flow (Φ f = f): the Floquet multipliers that decide stability are the other n − 1,
//! the eigenvalues of the section map's derivative P = (I − f e_kᵀ / f_k) Φ with row and
//! column k (the cyclic state, fixed on the section) left out.

use nalgebra::DMatrix;
use serde::Serialize;

/// A Floquet multiplier, with the states its eigenvector moves most.
#[derive(Clone, Debug, Serialize)]
pub struct Multiplier {
    pub re: f64,
    pub im: f64,
    pub modulus: f64,
    /// The states the multiplier's eigenvector moves most, largest first (each with its
    /// share of the vector's length, scaled by the states' nominals).
    pub states: Vec<(String, f64)>,
}

/// The multipliers of the section map, largest modulus first.
pub fn multipliers(
    phi: &[f64],
    f: &[f64],
    k: usize,
    names: &[String],
    nominals: &[f64],
) -> Vec<Multiplier> {
    let n = f.len();
    let others: Vec<usize> = (0..n).filter(|&i| i != k).collect();
    let m = others.len();
    let mut p = DMatrix::<f64>::zeros(m, m);
    for (a, &i) in others.iter().enumerate() {
        for (b, &j) in others.iter().enumerate() {
            // In the nominals' units, so that the eigenvectors compare states fairly.
            p[(a, b)] = (phi[i * n + j] - f[i] * phi[k * n + j] / f[k]) * nominals[j] / nominals[i];
        }
    }
    multipliers_of(&p, |u, v| {
        let squares: Vec<f64> = u.iter().zip(v).map(|(a, b)| a * a + b * b).collect();
        shares(others.iter().map(|&i| names[i].as_str()), &squares)
    })
}

/// The eigenvalues of a section map's derivative `p`, largest modulus first, each with
/// the states `named` says its eigenvector (real and imaginary parts) moves most.
pub fn multipliers_of(
    p: &DMatrix<f64>,
    named: impl Fn(&[f64], &[f64]) -> Vec<(String, f64)>,
) -> Vec<Multiplier> {
    let values = p.clone().complex_eigenvalues();
    let mut found: Vec<Multiplier> = values
        .iter()
        .map(|z| {
            let (u, v) = eigenvector(p, z.re, z.im);
            Multiplier {
                re: z.re,
                im: z.im,
                modulus: z.re.hypot(z.im),
                states: named(&u, &v),
            }
        })
        .collect();
    found.sort_by(|a, b| b.modulus.total_cmp(&a.modulus).then(b.im.total_cmp(&a.im)));
    found
}

/// The two largest of `squares` (an eigenvector's components' squared moduli, each
/// state's), with their shares of the total.
pub fn shares<'a>(names: impl Iterator<Item = &'a str>, squares: &[f64]) -> Vec<(String, f64)> {
    let total: f64 = squares.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let mut states: Vec<(String, f64)> = names
        .zip(squares)
        .map(|(name, &w)| (name.to_string(), w / total))
        .collect();
    states.sort_by(|a, b| b.1.total_cmp(&a.1));
    states.truncate(2);
    states
}

/// An eigenvector u + i·v of `p` for λ = re + i·im, by inverse iteration on (P − λ I) in
/// real form.
fn eigenvector(p: &DMatrix<f64>, re: f64, im: f64) -> (Vec<f64>, Vec<f64>) {
    let m = p.nrows();
    // [[P − re I, im I], [−im I, P − re I]] acting on (u, v), z = u + i v.
    let shift = 1e-10 * (1.0 + re.hypot(im));
    let mut big = DMatrix::<f64>::zeros(2 * m, 2 * m);
    for a in 0..m {
        for b in 0..m {
            big[(a, b)] = p[(a, b)];
            big[(m + a, m + b)] = p[(a, b)];
        }
        big[(a, a)] -= re + shift;
        big[(m + a, m + a)] -= re + shift;
        big[(a, m + a)] = im;
        big[(m + a, a)] = -im;
    }
    let lu = big.lu();
    let mut z = nalgebra::DVector::<f64>::from_element(2 * m, 1.0);
    for _ in 0..3 {
        match lu.solve(&z) {
            Some(next) if next.iter().all(|x| x.is_finite()) => {
                let norm = next.norm();
                if norm == 0.0 {
                    break;
                }
                z = next / norm;
            }
            _ => break,
        }
    }
    (
        (0..m).map(|a| z[a]).collect(),
        (0..m).map(|a| z[m + a]).collect(),
    )
}

/// Whether the largest multiplier lies on the unit circle, to within `band`: an undamped
/// mode, not a steady cycle.
pub fn marginal(multipliers: &[Multiplier], band: f64) -> bool {
    let largest = multipliers.first().map_or(0.0, |m| m.modulus);
    (1.0 - largest).abs() <= band
}

/// A mode of the state equations linearised at one point: an eigenvalue of A.
#[derive(Clone, Debug, Serialize)]
pub struct Mode {
    /// Its frequency, |Im λ| / 2π (Hz), and damping ratio, −Re λ / |λ|.
    pub frequency: f64,
    pub damping: f64,
    pub re: f64,
    pub im: f64,
}

/// Eigenvalues this much smaller than A's largest are rigid-body motion (a free angle's
/// double zero, split by rounding), not a mode.
const RIGID: f64 = 1e-6;

/// The oscillating modes of A (row-major, n × n): one per complex pair, by frequency.
pub fn modes(a: &[f64], n: usize) -> Vec<Mode> {
    let matrix = DMatrix::from_row_slice(n, n, a);
    let values = matrix.complex_eigenvalues();
    let largest = values.iter().fold(0.0f64, |m, z| m.max(z.norm()));
    let mut found: Vec<Mode> = values
        .iter()
        .filter(|z| z.im > 0.0 && z.norm() > RIGID * largest)
        .map(|z| {
            let modulus = z.re.hypot(z.im);
            Mode {
                frequency: z.im / std::f64::consts::TAU,
                damping: -z.re / modulus,
                re: z.re,
                im: z.im,
            }
        })
        .collect();
    found.sort_by(|a, b| a.frequency.total_cmp(&b.frequency));
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped oscillator's flow over T, with a trivial cyclic state beside it: the
    /// multipliers are e^{λT} of the oscillator's eigenvalues.
    #[test]
    fn multipliers_of_a_known_flow() {
        let (zeta, omega, t): (f64, f64, f64) = (0.1, 2.0, 0.7);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -omega * omega, -2.0 * zeta * omega]);
        let e = (a * t).exp();
        // State 0 is the cyclic one (θ' = 1, independent of the rest).
        let mut phi = vec![0.0; 9];
        phi[0] = 1.0;
        for i in 0..2 {
            for j in 0..2 {
                phi[(i + 1) * 3 + j + 1] = e[(i, j)];
            }
        }
        let names: Vec<String> = ["theta", "x", "v"].iter().map(|s| s.to_string()).collect();
        let found = multipliers(&phi, &[1.0, 0.3, -0.2], 0, &names, &[1.0; 3]);
        let decay = (-zeta * omega * t).exp();
        let turn = omega * (1.0 - zeta * zeta).sqrt() * t;
        assert_eq!(found.len(), 2);
        for m in &found {
            assert!((m.modulus - decay).abs() < 1e-12, "{m:?}");
            assert!((m.im.abs() - decay * turn.sin()).abs() < 1e-12);
        }
        assert!(!marginal(&found, 1e-6) && marginal(&found, 1.0 - decay + 1e-9));
        let modes = modes(&[0.0, 1.0, -omega * omega, -2.0 * zeta * omega], 2);
        assert_eq!(modes.len(), 1);
        let expected = omega * (1.0 - zeta * zeta).sqrt() / std::f64::consts::TAU;
        assert!((modes[0].frequency - expected).abs() < 1e-12);
        assert!((modes[0].damping - zeta).abs() < 1e-12);
    }
}
