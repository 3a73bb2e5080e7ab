//! A value with its derivatives along `P` directions at once: the forward-mode number of
//! the parameter sensitivities ([`super::sensitivity`]), where one pass of the model gives
//! J·S for every column of S instead of one pass per column as with [`super::Dual`].

use std::ops::{Add, Div, Mul, Neg, Sub};

use super::Scalar;

/// v + Σ d[j]·ε_j, with ε_i·ε_j = 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualVector<const P: usize> {
    pub v: f64,
    pub d: [f64; P],
}

impl<const P: usize> DualVector<P> {
    #[inline(always)]
    pub fn new(v: f64, d: [f64; P]) -> Self {
        Self { v, d }
    }

    /// The value with derivatives `a·self.d + b·other.d`: the chain rule of a function of
    /// two arguments whose partials are a and b.
    #[inline(always)]
    fn chain(v: f64, a: f64, x: &Self, b: f64, y: &Self) -> Self {
        Self::new(v, std::array::from_fn(|j| a * x.d[j] + b * y.d[j]))
    }

    /// The value with derivatives `a·self.d`.
    #[inline(always)]
    fn scaled(v: f64, a: f64, x: &Self) -> Self {
        Self::new(v, std::array::from_fn(|j| a * x.d[j]))
    }
}

impl<const P: usize> Add for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.v + o.v, std::array::from_fn(|j| self.d[j] + o.d[j]))
    }
}

impl<const P: usize> Sub for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.v - o.v, std::array::from_fn(|j| self.d[j] - o.d[j]))
    }
}

impl<const P: usize> Mul for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self::chain(self.v * o.v, o.v, &self, self.v, &o)
    }
}

impl<const P: usize> Div for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let q = self.v / o.v;
        let inverse = 1.0 / o.v;
        Self::chain(q, inverse, &self, -q * inverse, &o)
    }
}

impl<const P: usize> Neg for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.v, self.d.map(|d| -d))
    }
}

impl<const P: usize> Add<f64> for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Self::new(self.v + o, self.d)
    }
}

impl<const P: usize> Sub<f64> for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Self::new(self.v - o, self.d)
    }
}

impl<const P: usize> Mul<f64> for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Self::new(self.v * o, self.d.map(|d| d * o))
    }
}

impl<const P: usize> Div<f64> for DualVector<P> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        Self::new(self.v / o, self.d.map(|d| d / o))
    }
}

impl<const P: usize> Scalar for DualVector<P> {
    #[inline(always)]
    fn constant(value: f64) -> Self {
        Self::new(value, [0.0; P])
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self.v
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = super::trig::sin_cos(self.v);
        (Self::scaled(s, c, &self), Self::scaled(c, -s, &self))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        Self::scaled(r, 0.5 / r, &self)
    }
    #[inline(always)]
    fn acos(self) -> Self {
        Self::scaled(self.v.acos(), -1.0 / (1.0 - self.v * self.v).sqrt(), &self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        let r2 = x.v * x.v + self.v * self.v;
        Self::chain(self.v.atan2(x.v), x.v / r2, &self, -self.v / r2, &x)
    }
    #[inline(always)]
    fn hypot(self, other: Self) -> Self {
        let h = self.v.hypot(other.v);
        Self::chain(h, self.v / h, &self, other.v / h, &other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Dual;

    /// Every operation's derivatives, direction by direction, are the one-direction
    /// [`Dual`]'s (itself checked against differences).
    #[test]
    fn each_direction_is_the_one_direction_dual() {
        let f = |x: &dyn Fn(f64, [f64; 2]) -> DualVector<2>, g: &dyn Fn(Dual) -> Dual| {
            let (v, d) = (0.37, [1.3, -0.4]);
            let many = x(v, d);
            for (j, &dj) in d.iter().enumerate() {
                let one = g(Dual::new(v, dj));
                assert_eq!(many.v, one.v);
                assert!(
                    (many.d[j] - one.d).abs() <= 1e-15 * one.d.abs().max(1.0),
                    "{j}"
                );
            }
        };
        let x = |v, d| DualVector::new(v, d);
        f(&|v, d| x(v, d).sin_cos().0, &|x| x.sin_cos().0);
        f(&|v, d| x(v, d).sin_cos().1, &|x| x.sin_cos().1);
        f(&|v, d| Scalar::sqrt(x(v, d)), &Scalar::sqrt);
        f(&|v, d| Scalar::acos(x(v, d)), &Scalar::acos);
        f(&|v, d| Scalar::atan2(x(v, d), x(v, d) * 2.0 - 1.5), &|x| {
            Scalar::atan2(x, x * 2.0 - 1.5)
        });
        f(
            &|v, d| Scalar::hypot(x(v, d), x(v, d) * x(v, d) + 0.5),
            &|x| Scalar::hypot(x, x * x + 0.5),
        );
        f(
            &|v, d| (x(v, d) * x(v, d) - 3.0) / (x(v, d) + 2.0) * 0.5 - -x(v, d) / 4.0,
            &|x| (x * x - 3.0) / (x + 2.0) * 0.5 - -x / 4.0,
        );
    }
}
