// Coefficients of the three-stage Radau IIA method of order 5 (Hairer & Wanner, Solving
// ODEs II, section IV.8): its nodes, the weights of its embedded error estimate, the
// eigenvalues of the inverse of its coefficient matrix and the transformation that
// diagonalises it.

use super::linear::Complex;

pub const SQRT6: f64 = 2.449_489_742_783_178;
/// Nodes c of Radau IIA (order 5).
pub const C: [f64; 3] = [(4.0 - SQRT6) / 10.0, (4.0 + SQRT6) / 10.0, 1.0];
/// Weights of the embedded error estimate: err = ((γ/h)·I − J)⁻¹·(f(y₀) + Σ Eᵢ·Zᵢ/h).
pub const E: [f64; 3] = [
    (-13.0 - 7.0 * SQRT6) / 3.0,
    (-13.0 + 7.0 * SQRT6) / 3.0,
    -1.0 / 3.0,
];
/// Eigenvalues of A⁻¹: γ = 3 + 3^(2/3) − 3^(1/3) and α + iβ = 3 + (3^(1/3) − 3^(2/3))/2
/// − i·(3^(5/6) + 3^(7/6))/2 (and its conjugate).
pub const GAMMA: f64 = 3.637_834_252_744_496;
pub const ALPHA_BETA: Complex = Complex::new(2.681_082_873_627_752_3, -3.050_430_199_247_411);
/// T with T⁻¹·A⁻¹·T = diag(γ, [[α, −β], [β, α]]), and its inverse (HNW II, IV.8; the
/// values as published with scipy's Radau). Checked by a unit test.
#[allow(clippy::excessive_precision)] // the published digits
pub const T: [[f64; 3]; 3] = [
    [
        0.094_438_762_488_975_24,
        -0.141_255_295_020_954_21,
        0.030_029_194_105_147_42,
    ],
    [
        0.250_213_122_965_333_32,
        0.204_129_352_293_799_94,
        -0.382_942_112_757_261_92,
    ],
    [1.0, 1.0, 0.0],
];
#[allow(clippy::excessive_precision)]
pub const T_INV: [[f64; 3]; 3] = [
    [
        4.178_718_591_551_904_28,
        0.327_682_820_761_062_37,
        0.523_376_445_499_449_51,
    ],
    [
        -4.178_718_591_551_904_28,
        -0.327_682_820_761_062_37,
        0.476_623_554_500_550_44,
    ],
    [
        0.502_872_634_945_786_82,
        -2.571_926_949_855_605_22,
        0.596_039_204_828_224_92,
    ],
];
