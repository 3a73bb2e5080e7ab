//! Dense LU factorisation with partial pivoting for small fixed-size systems, in real and
//! complex arithmetic: what an implicit method needs for its Newton iterations, with all
//! storage inline (no heap).

use std::ops::{Add, Mul, Sub};

/// A complex number, just enough arithmetic for Gaussian elimination.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Complex {
    pub re: f64,
    pub im: f64,
}

impl Complex {
    pub const fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }

    fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    fn recip(self) -> Self {
        let d = self.norm_sqr();
        Self::new(self.re / d, -self.im / d)
    }

    pub fn scale(self, s: f64) -> Self {
        Self::new(self.re * s, self.im * s)
    }
}

impl Add for Complex {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.re + o.re, self.im + o.im)
    }
}

impl Sub for Complex {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.re - o.re, self.im - o.im)
    }
}

impl Mul for Complex {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

/// What Gaussian elimination needs of a scalar.
pub trait Scalar: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    fn magnitude(self) -> f64;
    fn recip(self) -> Self;
}

impl Scalar for f64 {
    fn magnitude(self) -> f64 {
        self.abs()
    }
    fn recip(self) -> Self {
        1.0 / self
    }
}

impl Scalar for Complex {
    fn magnitude(self) -> f64 {
        self.re.abs() + self.im.abs()
    }
    fn recip(self) -> Self {
        Complex::recip(self)
    }
}

/// The factors L·U = P·M of a square matrix M, stored in place (L below the diagonal with
/// unit diagonal implied, U on and above it; the diagonal holds U's reciprocals).
#[derive(Clone, Copy, Debug)]
pub struct Lu<T: Scalar, const N: usize> {
    factors: [[T; N]; N],
    pivots: [usize; N],
}

/// The matrix is singular (or not finite) to working precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Singular;

impl<T: Scalar, const N: usize> Lu<T, N> {
    /// Factor `matrix` (row-major). Fails on a zero or non-finite pivot.
    pub fn factor(matrix: [[T; N]; N]) -> Result<Self, Singular> {
        let mut a = matrix;
        let mut pivots = [0; N];
        for k in 0..N {
            let p = (k..N)
                .max_by(|&i, &j| a[i][k].magnitude().total_cmp(&a[j][k].magnitude()))
                .unwrap_or(k);
            let size = a[p][k].magnitude();
            if size == 0.0 || !size.is_finite() {
                return Err(Singular);
            }
            a.swap(k, p);
            pivots[k] = p;
            let inverse = a[k][k].recip();
            a[k][k] = inverse;
            let pivot_row = a[k];
            for row in a.iter_mut().skip(k + 1) {
                let m = row[k] * inverse;
                row[k] = m;
                for (x, p) in row.iter_mut().zip(&pivot_row).skip(k + 1) {
                    *x = *x - m * *p;
                }
            }
        }
        Ok(Self { factors: a, pivots })
    }

    /// Solve M·x = b in place.
    pub fn solve(&self, b: &mut [T; N]) {
        let a = &self.factors;
        for k in 0..N {
            b.swap(k, self.pivots[k]);
        }
        for i in 1..N {
            let mut sum = b[i];
            for j in 0..i {
                sum = sum - a[i][j] * b[j];
            }
            b[i] = sum;
        }
        for i in (0..N).rev() {
            let mut sum = b[i];
            for j in i + 1..N {
                sum = sum - a[i][j] * b[j];
            }
            b[i] = sum * a[i][i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_solve_recovers_a_known_solution() {
        let m = [[0.0, 2.0, 1.0], [1.0, -1.0, 4.0], [3.0, 1.0, 1.0]];
        let x = [1.0, -2.0, 0.5];
        let mut b: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| m[i][j] * x[j]).sum());
        Lu::factor(m).unwrap().solve(&mut b);
        for (bi, xi) in b.iter().zip(x) {
            assert!((bi - xi).abs() < 1e-14, "{b:?}");
        }
    }

    #[test]
    fn complex_solve_recovers_a_known_solution() {
        let c = Complex::new;
        let m = [[c(1.0, 2.0), c(0.0, -1.0)], [c(3.0, 0.0), c(-2.0, 0.5)]];
        let x = [c(0.5, -1.0), c(2.0, 3.0)];
        let mut b = [
            m[0][0] * x[0] + m[0][1] * x[1],
            m[1][0] * x[0] + m[1][1] * x[1],
        ];
        Lu::factor(m).unwrap().solve(&mut b);
        for (bi, xi) in b.iter().zip(x) {
            assert!((*bi - xi).magnitude() < 1e-14, "{b:?}");
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_are_refused() {
        assert_eq!(Lu::factor([[1.0, 2.0], [2.0, 4.0]]).err(), Some(Singular));
        assert_eq!(
            Lu::factor([[f64::NAN, 0.0], [0.0, 1.0]]).err(),
            Some(Singular)
        );
    }
}
