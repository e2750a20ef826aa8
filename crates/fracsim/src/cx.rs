//! Complex numbers over any [`Real`] scalar, so that poles, residues and their discretisation carry
//! exact derivatives when the scalar is a [`crate::Dual`] number.

use crate::scalar::Real;
use num_complex::Complex64;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// `re + j im` with real and imaginary parts of type `T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cx<T> {
    /// Real part.
    pub re: T,
    /// Imaginary part.
    pub im: T,
}

/// `1/k!` for `k = 1..=17`, the Taylor coefficients of [`Cx::phi1`] (`k!` is exact in `f64`
/// up to `18!`, each quotient rounded once).
const PHI1_COEF: [f64; 17] = {
    let mut c = [0.0; 17];
    let mut fact = 1.0;
    let mut k = 1;
    while k <= 17 {
        fact *= k as f64;
        c[k - 1] = 1.0 / fact;
        k += 1;
    }
    c
};

impl<T: Real> Cx<T> {
    /// `re + j im`.
    #[inline]
    pub fn new(re: T, im: T) -> Self {
        Self { re, im }
    }

    /// A real number.
    #[inline]
    pub fn real(re: T) -> Self {
        Self {
            re,
            im: T::from(0.0),
        }
    }

    /// A constant (no derivatives) from a `Complex64`.
    #[inline]
    pub fn cst(c: Complex64) -> Self {
        Self {
            re: T::from(c.re),
            im: T::from(c.im),
        }
    }

    /// The value, without derivatives.
    #[inline]
    pub fn val(self) -> Complex64 {
        Complex64::new(self.re.re(), self.im.re())
    }

    /// `|z|^2`.
    #[inline]
    pub fn norm_sqr(self) -> T {
        self.re * self.re + self.im * self.im
    }

    /// `1 / z`.
    #[inline]
    pub fn recip(self) -> Self {
        let d = self.norm_sqr();
        Self {
            re: self.re / d,
            im: -self.im / d,
        }
    }

    /// `z * k` for a real `k`.
    #[inline]
    pub fn scale(self, k: T) -> Self {
        Self {
            re: self.re * k,
            im: self.im * k,
        }
    }

    /// `e^z`.
    #[inline]
    pub fn exp(self) -> Self {
        let e = self.re.exp();
        let (s, c) = self.im.sin_cos();
        Self {
            re: e * c,
            im: e * s,
        }
    }

    /// `(e^z - 1)/z`, accurate near `z = 0` (its Taylor series `sum z^k/(k+1)!` below
    /// `|z| = 0.5`, to the term `z^16/17!`, whose size is below 1e-19), `1` at `z = 0`.
    pub fn phi1(self) -> Self {
        if self.val().norm() < 0.5 {
            let mut acc = Self::real(T::from(0.0));
            for &c in PHI1_COEF.iter().rev() {
                acc = acc * self + Self::real(T::from(c));
            }
            acc
        } else {
            let e = self.exp();
            (e - Self::real(T::from(1.0))) / self
        }
    }
}

impl<T: Real> Add for Cx<T> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self {
            re: self.re + o.re,
            im: self.im + o.im,
        }
    }
}

impl<T: Real> AddAssign for Cx<T> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<T: Real> Sub for Cx<T> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }
}

impl<T: Real> Neg for Cx<T> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self {
            re: -self.re,
            im: -self.im,
        }
    }
}

impl<T: Real> Mul for Cx<T> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        Self {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }
}

impl<T: Real> Div for Cx<T> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let d = o.norm_sqr();
        Self {
            re: (self.re * o.re + self.im * o.im) / d,
            im: (self.im * o.re - self.re * o.im) / d,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dual;

    #[test]
    fn arithmetic_matches_complex64() {
        let (a, b) = (Complex64::new(0.3, -1.7), Complex64::new(-2.1, 0.4));
        let (x, y) = (Cx::<f64>::cst(a), Cx::<f64>::cst(b));
        for (got, want) in [
            ((x * y).val(), a * b),
            ((x / y).val(), a / b),
            ((x - y).val(), a - b),
            (x.exp().val(), a.exp()),
            (x.phi1().val(), (a.exp() - 1.0) / a),
        ] {
            assert!((got - want).norm() < 1e-14 * want.norm(), "{got} {want}");
        }
        // phi1 on both sides of the series threshold agrees with a long-precision series.
        for z in [Complex64::new(3e-3, 4e-3), Complex64::new(-2e-2, 1e-3)] {
            let exact: Complex64 = (0..30)
                .scan(Complex64::new(1.0, 0.0), |t, k| {
                    let out = *t;
                    *t = *t * z / (k as f64 + 2.0);
                    Some(out)
                })
                .sum();
            assert!((Cx::<f64>::cst(z).phi1().val() - exact).norm() < 1e-15);
        }
    }

    #[test]
    fn derivatives_of_exp_match_finite_differences() {
        let f = |t: Dual<1>| {
            let z = Cx::new(t * 0.5 - 1.0, t * t);
            (z.exp() * z.phi1()).re
        };
        let t0 = 0.8;
        let h = 1e-6;
        let fd = (f(Dual::cst(t0 + h)).v - f(Dual::cst(t0 - h)).v) / (2.0 * h);
        let d = f(Dual::var(t0, 0)).d[0];
        assert!((d - fd).abs() < 1e-8, "{d} {fd}");
    }
}
