//! The numbers the model computes with: `f64`, or a [`Dual`] number that carries one
//! directional derivative along (forward-mode automatic differentiation). The model's
//! functions are written once, generic over [`Scalar`]; with `f64` they compile to the
//! plain arithmetic, with `Dual` they give exact Jacobian-vector products (the FMU's
//! directional derivatives), not finite differences.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// What the model needs of a number. Parameters stay `f64`: they multiply from the right
/// (`x * p.l2`), as the operators with `f64` are defined for the scalar on the left.
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    fn constant(value: f64) -> Self;
    /// The value without its derivative.
    fn value(self) -> f64;
    fn sin_cos(self) -> (Self, Self);
    /// (sin, cos) of two numbers.
    #[inline(always)]
    fn sin_cos_pair(a: Self, b: Self) -> [(Self, Self); 2] {
        [a.sin_cos(), b.sin_cos()]
    }
    fn sqrt(self) -> Self;
    fn acos(self) -> Self;
    /// atan2(self, x): the angle of (x, self).
    fn atan2(self, x: Self) -> Self;
    fn hypot(self, other: Self) -> Self;
}

impl Scalar for f64 {
    #[inline(always)]
    fn constant(value: f64) -> Self {
        value
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        super::trig::sin_cos(self)
    }
    #[inline(always)]
    fn sin_cos_pair(a: Self, b: Self) -> [(Self, Self); 2] {
        super::trig::sin_cos_pair([a, b])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn acos(self) -> Self {
        f64::acos(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
    #[inline(always)]
    fn hypot(self, other: Self) -> Self {
        f64::hypot(self, other)
    }
}

/// A value with its derivative along one direction: v + d·ε, ε² = 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dual {
    pub v: f64,
    pub d: f64,
}

impl Dual {
    pub fn new(v: f64, d: f64) -> Self {
        Self { v, d }
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        Dual::new(self.v + o.v, self.d + o.d)
    }
}

impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        Dual::new(self.v - o.v, self.d - o.d)
    }
}

impl Mul for Dual {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        Dual::new(self.v * o.v, self.d * o.v + self.v * o.d)
    }
}

impl Div for Dual {
    type Output = Dual;
    fn div(self, o: Dual) -> Dual {
        let q = self.v / o.v;
        Dual::new(q, (self.d - q * o.d) / o.v)
    }
}

impl Neg for Dual {
    type Output = Dual;
    fn neg(self) -> Dual {
        Dual::new(-self.v, -self.d)
    }
}

impl Add<f64> for Dual {
    type Output = Dual;
    fn add(self, o: f64) -> Dual {
        Dual::new(self.v + o, self.d)
    }
}

impl Sub<f64> for Dual {
    type Output = Dual;
    fn sub(self, o: f64) -> Dual {
        Dual::new(self.v - o, self.d)
    }
}

impl Mul<f64> for Dual {
    type Output = Dual;
    fn mul(self, o: f64) -> Dual {
        Dual::new(self.v * o, self.d * o)
    }
}

impl Div<f64> for Dual {
    type Output = Dual;
    fn div(self, o: f64) -> Dual {
        Dual::new(self.v / o, self.d / o)
    }
}

impl Scalar for Dual {
    fn constant(value: f64) -> Self {
        Dual::new(value, 0.0)
    }
    fn value(self) -> f64 {
        self.v
    }
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = super::trig::sin_cos(self.v);
        (Dual::new(s, c * self.d), Dual::new(c, -s * self.d))
    }
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        Dual::new(r, self.d / (2.0 * r))
    }
    fn acos(self) -> Self {
        Dual::new(self.v.acos(), -self.d / (1.0 - self.v * self.v).sqrt())
    }
    fn atan2(self, x: Self) -> Self {
        let (y, x) = (self, x);
        Dual::new(
            y.v.atan2(x.v),
            (x.v * y.d - y.v * x.d) / (x.v * x.v + y.v * y.v),
        )
    }
    fn hypot(self, other: Self) -> Self {
        let h = self.v.hypot(other.v);
        Dual::new(h, (self.v * self.d + other.v * other.d) / h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each rule against a central difference of the f64 function.
    #[test]
    fn derivatives_of_the_elementary_functions() {
        let h = 1e-6;
        let check = |f: &dyn Fn(Dual) -> Dual, g: &dyn Fn(f64) -> f64, x: f64| {
            let exact = f(Dual::new(x, 1.0));
            let estimate = (g(x + h) - g(x - h)) / (2.0 * h);
            assert_eq!(exact.v, g(x));
            assert!(
                (exact.d - estimate).abs() < 1e-8 * estimate.abs().max(1.0),
                "{x}"
            );
        };
        use crate::model::trig::sin_cos;
        check(&|x| x.sin_cos().0, &|x| sin_cos(x).0, 0.7);
        check(&|x| x.sin_cos().1, &|x| sin_cos(x).1, 0.7);
        check(&|x| Scalar::sqrt(x), &f64::sqrt, 2.5);
        check(&|x| Scalar::acos(x), &f64::acos, 0.3);
        check(
            &|x| Scalar::atan2(x, Dual::new(-0.4, 0.0)),
            &|x| x.atan2(-0.4),
            0.9,
        );
        check(
            &|x| Scalar::atan2(Dual::new(0.9, 0.0), x),
            &|x| 0.9f64.atan2(x),
            -0.4,
        );
        check(
            &|x| Scalar::hypot(x, Dual::new(2.0, 0.0)),
            &|x| x.hypot(2.0),
            -1.5,
        );
        check(
            &|x| x * x / (x - 3.0) + 2.0,
            &|x| x * x / (x - 3.0) + 2.0,
            1.1,
        );
    }
}
