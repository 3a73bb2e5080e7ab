//! sin and cos together, of one angle or of two at once, without a call into the C library.
//!
//! The right-hand side needs (sin, cos) of φ2 and φ3 at every evaluation, and the C
//! library's `sincos` spends much of its time saving and restoring the rounding mode; two
//! calls cannot share a vector register either. Here the angle is reduced to
//! r ∈ [−π/4, π/4] by the nearest multiple q of π/2, with π/2 in three parts (Cody and
//! Waite's reduction) so that the first two products q·(π/2)ᵢ are exact, and r is carried
//! as a sum r_hi + r_lo. sin r and cos r are then polynomials in r² of degree 5 after their
//! leading terms: minimax fits for the relative error on |r| ≤ π/4, which
//! tests/python/test_trig_coefficients.py derives (Remez's exchange algorithm) and checks
//! against the constants here. As doubles they err by less than 2⁻⁵⁶·⁵ of sin r and 2⁻⁵⁹·⁵
//! of cos r, below 0.03 ulp; Taylor's polynomials needed two more terms each for that.
//! They are evaluated by Estrin's scheme (short dependency chains). Only plain
//! multiplications and additions are used, so the result is the same on every machine; it
//! stays within 2 ulp of the C library's (tested below over a million angles in each of
//! |x| < 0.8, 10 and 1000).
//! Beyond |x| = 2²⁰, at zero and for non-finite x, the C library is called.
//!
//! [`sin_cos_pair`] computes φ2's and φ3's lane by lane, without branches, so that both
//! run in one vector register: cheaper per evaluation than two calls of the C library's
//! `sincos`, and the same on every platform.

/// π/2 in three parts: 33 significant bits, the next 33, and the next 53 (what is left
/// is below 1.1e-37). With |q| < 2²⁰ the products q·P1 and q·P2 are exact.
const PIO2_1: f64 = 1.570_796_326_734_125_6;
const PIO2_2: f64 = 6.077_100_506_303_966e-11;
const PIO2_3: f64 = 2.022_266_248_795_950_6e-21;

/// Largest |x| reduced here: q stays below 2²⁰, where q·P1 and q·P2 are exact.
const LIMIT: f64 = 1_048_576.0;

/// sin r = r + r·z·(S0 + S1·z + … + S5·z⁵), z = r²: the minimax fit (module comment), two
/// terms shorter than Taylor's polynomial for the same accuracy.
const S: [f64; 6] = [
    -0.16666666666666666,
    0.00833333333332881,
    -0.000198412698339783,
    2.755731492392363e-06,
    -2.5050927241591773e-08,
    1.5905569606946147e-10,
];

/// cos r = 1 − z/2 + z²·(C0 + C1·z + … + C5·z⁵): the minimax fit (module comment).
const C: [f64; 6] = [
    0.041666666666666595,
    -0.0013888888888873056,
    2.4801587288851704e-05,
    -2.755731417929674e-07,
    2.087570084197473e-09,
    -1.1358536521387682e-11,
];

/// Rounds x·2/π to the nearest integer when added and removed: `round()` is a C library
/// call on baseline x86-64.
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// Whether x is reduced here: finite, below [`LIMIT`], and not zero (the C library gives
/// sin(−0) its sign).
#[inline(always)]
fn reduced_here(x: f64) -> bool {
    (x.abs() < LIMIT) & (x != 0.0)
}

/// (sin x, cos x).
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if !reduced_here(x) {
        return x.sin_cos();
    }
    let q = (x * std::f64::consts::FRAC_2_PI + SHIFT) - SHIFT;
    // x − q·P1 is exact (the two are within a factor of two, or q = 0); the subtraction
    // of q·P2 is made exact as a sum hi + lo (Knuth's two-sum).
    let a = x - q * PIO2_1;
    let b = -(q * PIO2_2);
    let hi = a + b;
    let b_virtual = hi - a;
    let lo = ((a - (hi - b_virtual)) + (b - b_virtual)) - q * PIO2_3;
    let (s, c) = kernel(hi, lo);
    match (q as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// [`sin_cos`] of two angles at once, written lane by lane (no branch on the quadrant) so
/// that the compiler can run the two in one vector register. It repeats [`sin_cos`]'s
/// arithmetic on purpose, step for step (a test checks the bits): the shared forms were
/// slower. One lane function mapped over the pair is not vectorised by the compiler, and
/// [`sin_cos`] computed as the first lane of a pair pays for the second.
#[inline(always)]
pub fn sin_cos_pair(x: [f64; 2]) -> [(f64, f64); 2] {
    // `&`, not `&&`: both tests at once, without a branch between them.
    if !(reduced_here(x[0]) & reduced_here(x[1])) {
        return [sin_cos(x[0]), sin_cos(x[1])];
    }
    let shifted = x.map(|x| x * std::f64::consts::FRAC_2_PI + SHIFT);
    let q = shifted.map(|t| t - SHIFT);
    let a: [f64; 2] = std::array::from_fn(|i| x[i] - q[i] * PIO2_1);
    let b: [f64; 2] = std::array::from_fn(|i| -(q[i] * PIO2_2));
    let hi: [f64; 2] = std::array::from_fn(|i| a[i] + b[i]);
    let b_virtual: [f64; 2] = std::array::from_fn(|i| hi[i] - a[i]);
    let lo: [f64; 2] = std::array::from_fn(|i| {
        ((a[i] - (hi[i] - b_virtual[i])) + (b[i] - b_virtual[i])) - q[i] * PIO2_3
    });
    let z: [f64; 2] = std::array::from_fn(|i| hi[i] * hi[i]);
    let z2: [f64; 2] = std::array::from_fn(|i| z[i] * z[i]);
    let z4: [f64; 2] = std::array::from_fn(|i| z2[i] * z2[i]);
    let sin_poly: [f64; 2] = std::array::from_fn(|i| {
        (S[0] + S[1] * z[i]) + z2[i] * (S[2] + S[3] * z[i]) + z4[i] * (S[4] + S[5] * z[i])
    });
    let cos_poly: [f64; 2] = std::array::from_fn(|i| {
        (C[0] + C[1] * z[i]) + z2[i] * (C[2] + C[3] * z[i]) + z4[i] * (C[4] + C[5] * z[i])
    });
    let s: [f64; 2] =
        std::array::from_fn(|i| hi[i] + (hi[i] * z[i] * sin_poly[i] + lo[i] * (1.0 - 0.5 * z[i])));
    let c: [f64; 2] =
        std::array::from_fn(|i| 1.0 - 0.5 * z[i] + (z2[i] * cos_poly[i] - hi[i] * lo[i]));
    // Quadrant n: odd swaps sin and cos; sin is negative for n = 2, 3, cos for n = 1, 2.
    // n's low bits are those of `shifted`'s mantissa (SHIFT = 1.5·2⁵² puts q there), so
    // the fix-up is bit arithmetic on the two lanes. With `q as i32` (a saturating
    // conversion) the compiler paired each angle's sin with its cos instead of the two
    // angles, mostly in scalar instructions.
    let n = shifted.map(f64::to_bits);
    let swap = n.map(|n| (n & 1).wrapping_neg());
    let (s, c) = (s.map(f64::to_bits), c.map(f64::to_bits));
    std::array::from_fn(|i| {
        let sin_sign = (n[i] & 2) << 62;
        let cos_sign = (n[i].wrapping_add(1) & 2) << 62;
        let sin = ((c[i] & swap[i]) | (s[i] & !swap[i])) ^ sin_sign;
        let cos = ((s[i] & swap[i]) | (c[i] & !swap[i])) ^ cos_sign;
        (f64::from_bits(sin), f64::from_bits(cos))
    })
}

/// sin and cos of r + lo for |r| ≤ π/4 and |lo| ≪ ulp(r): the tail enters to first order.
#[inline(always)]
fn kernel(r: f64, lo: f64) -> (f64, f64) {
    let z = r * r;
    let z2 = z * z;
    let z4 = z2 * z2;
    let sin_poly = (S[0] + S[1] * z) + z2 * (S[2] + S[3] * z) + z4 * (S[4] + S[5] * z);
    let cos_poly = (C[0] + C[1] * z) + z2 * (C[2] + C[3] * z) + z4 * (C[4] + C[5] * z);
    // sin(r + lo) ≈ sin r + lo·cos r, with cos r ≈ 1 − z/2 at this order.
    let s = r + (r * z * sin_poly + lo * (1.0 - 0.5 * z));
    let c = 1.0 - 0.5 * z + (z2 * cos_poly - r * lo);
    (s, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    // The tests against the C library's sines are ignored on Windows, whose C library
    // (msvcrt, and Wine's where the tests run) is not correctly rounded; the FMU's own
    // polynomials are compared across platforms bit for bit by tests/platforms instead.

    /// Distance in units in the last place of `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        let ulp = f64::from_bits(b.abs().to_bits() + 1) - b.abs();
        if b == 0.0 {
            return a.abs() / f64::MIN_POSITIVE;
        }
        (a - b).abs() / ulp
    }

    /// A reproducible stream of numbers in [0, 1).
    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    fn worst_over(xs: impl Iterator<Item = f64>) -> f64 {
        let mut worst: f64 = 0.0;
        for x in xs {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            worst = worst.max(ulps(s, s0)).max(ulps(c, c0));
        }
        worst
    }

    #[test]
    #[cfg_attr(windows, ignore = "the C library's sines are the reference")]
    fn within_two_ulp_of_the_c_library() {
        let mut seed = 7;
        for range in [0.8, 10.0, 1e3, 1e6] {
            let worst = worst_over((0..200_000).map(|_| (2.0 * uniform(&mut seed) - 1.0) * range));
            assert!(worst <= 2.0, "|x| < {range}: {worst} ulp");
        }
    }

    #[test]
    #[cfg_attr(windows, ignore = "the C library's sines are the reference")]
    fn within_two_ulp_next_to_multiples_of_a_quarter_turn() {
        // Where r is tiny and the reduction's cancellation is worst.
        let mut seed = 11;
        let worst = worst_over((1..20_000).flat_map(|k| {
            let centre = k as f64 * std::f64::consts::FRAC_PI_2;
            let near = (uniform(&mut seed) - 0.5) * 1e-6;
            [
                centre,
                -centre,
                centre + near,
                centre.next_up(),
                centre.next_down(),
            ]
        }));
        assert!(worst <= 2.0, "{worst} ulp");
    }

    #[test]
    fn a_pair_gives_the_bits_of_two_singles() {
        let mut seed = 3;
        let special = [0.0, -0.0, LIMIT, -LIMIT, 1e300, f64::INFINITY, f64::NAN];
        let mut pairs: Vec<[f64; 2]> = (0..20_000)
            .map(|_| [0, 1].map(|_| (2.0 * uniform(&mut seed) - 1.0) * 100.0))
            .collect();
        pairs.extend(special.map(|x| [x, 0.3]));
        pairs.extend(special.map(|x| [-2.0, x]));
        for pair in pairs {
            for ((s, c), x) in sin_cos_pair(pair).into_iter().zip(pair) {
                let (s0, c0) = sin_cos(x);
                assert!(
                    s.to_bits() == s0.to_bits() && c.to_bits() == c0.to_bits(),
                    "{x}"
                );
            }
        }
    }

    #[test]
    #[cfg_attr(windows, ignore = "the C library's sines are the reference")]
    fn the_c_library_beyond_the_reduced_range() {
        for x in [LIMIT, -2e7, 1e300, f64::INFINITY, f64::NAN, 0.0, -0.0] {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            assert!(
                s.to_bits() == s0.to_bits() && c.to_bits() == c0.to_bits(),
                "{x}"
            );
        }
    }
}
