//! The small dense systems of an implicit method's Newton iterations, real and complex, on
//! nalgebra's fixed-size matrices, whose storage is inline (no heap): LU factorisation with
//! partial pivoting by nalgebra's pivot search and Gaussian elimination steps, and its
//! permutation and triangular solves. (nalgebra's `LU` type itself needs its dimension as a
//! typenum, which a size generic over `const N` cannot name; the steps it is made of do
//! not, and are the same.)

use nalgebra::linalg::{gauss_step, gauss_step_swap, PermutationSequence};
use nalgebra::{ComplexField, Const, SMatrix, SVector};

/// A complex number (nalgebra's, from num-complex).
pub type Complex = nalgebra::Complex<f64>;

/// The factors L·U = P·M of a square matrix M, in nalgebra's packed form (L below the
/// diagonal with its unit diagonal implied, U on and above it).
#[derive(Clone, Copy, Debug)]
pub struct Lu<T: ComplexField + Copy, const N: usize> {
    factors: SMatrix<T, N, N>,
    permutation: PermutationSequence<Const<N>>,
}

/// The matrix is singular (or not finite) to working precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Singular;

impl<T: ComplexField + Copy, const N: usize> Lu<T, N> {
    /// Factor `matrix` (row by row). Fails on a non-finite entry or a zero pivot.
    pub fn factor(matrix: [[T; N]; N]) -> Result<Self, Singular> {
        if !matrix.iter().flatten().all(|x| x.is_finite()) {
            return Err(Singular);
        }
        let mut factors = SMatrix::<T, N, N>::from_fn(|i, j| matrix[i][j]);
        let mut permutation = PermutationSequence::identity_generic(Const::<N>);
        for i in 0..N {
            let pivot = factors.view_range(i.., i).icamax() + i;
            let diagonal = factors[(pivot, i)];
            if diagonal.is_zero() {
                return Err(Singular);
            }
            if pivot == i {
                gauss_step(&mut factors, diagonal, i);
            } else {
                permutation.append_permutation(i, pivot);
                factors.columns_range_mut(..i).swap_rows(i, pivot);
                gauss_step_swap(&mut factors, diagonal, i, pivot);
            }
        }
        Ok(Self {
            factors,
            permutation,
        })
    }

    /// Solve M·x = b in place.
    #[inline]
    pub fn solve(&self, b: &mut [T; N]) {
        let mut x = SVector::<T, N>::from(*b);
        self.permutation.permute_rows(&mut x);
        self.factors
            .solve_lower_triangular_with_diag_mut(&mut x, T::one());
        self.factors.solve_upper_triangular_mut(&mut x);
        *b = x.into();
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
            assert!((*bi - xi).norm() < 1e-14, "{b:?}");
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_are_refused() {
        assert_eq!(Lu::factor([[1.0, 2.0], [2.0, 4.0]]).err(), Some(Singular));
        assert_eq!(
            Lu::factor([[f64::NAN, 0.0], [0.0, 1.0]]).err(),
            Some(Singular)
        );
        assert_eq!(
            Lu::factor([[f64::INFINITY, 0.0], [0.0, 1.0]]).err(),
            Some(Singular)
        );
    }
}
