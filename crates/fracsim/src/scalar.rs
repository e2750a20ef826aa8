//! Scalars the simulation is generic over: `f64`, and forward-mode dual numbers [`Dual`] that carry
//! exact derivatives with respect to up to `N` parameters through every step of a discrete recursion
//! (used by `ident` for output sensitivities).

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar: `f64` or a [`Dual`] number.
///
/// The simulation code of this crate is written once over `T: Real`, so that running it with
/// `Dual<N>` gives the output and its exact derivatives (forward-mode differentiation).
pub trait Real:
    Copy
    + Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + From<f64>
    + Send
    + Sync
    + 'static
{
    /// The value (the real part of a dual number).
    fn re(self) -> f64;
    /// `e^x`.
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Tangent.
    fn tan(self) -> Self;
    /// Sine and cosine.
    fn sin_cos(self) -> (Self, Self);
    /// `self^e` for a positive base (computed as `exp(e ln self)`).
    fn powr(self, e: Self) -> Self {
        (e * self.ln()).exp()
    }
    /// `self^e` for a constant exponent.
    fn powf(self, e: f64) -> Self;
    /// One entry per derivative: `[V; 0]` for `f64`, `[V; N]` for `Dual<N>`. Lets code written
    /// over `Real` hold the parts of a scalar apart (the simulation kernels run a row of plain
    /// numbers per part).
    type Derivs<V: Copy>: Copy + AsRef<[V]> + AsMut<[V]>;
    /// Every derivative entry `v`.
    fn derivs_of<V: Copy>(v: V) -> Self::Derivs<V>;
    /// The derivatives (none for `f64`).
    fn derivs(self) -> Self::Derivs<f64>;
    /// The scalar of value `v` and derivatives `d`.
    fn from_parts(v: f64, d: Self::Derivs<f64>) -> Self;
    /// `y` as plain numbers, when the scalar is `f64`.
    fn as_plain(y: &mut [Self]) -> Option<&mut [f64]> {
        let _ = y;
        None
    }
    /// Absolute value.
    fn abs(self) -> Self {
        if self.re() < 0.0 {
            -self
        } else {
            self
        }
    }
}

impl Real for f64 {
    #[inline]
    fn re(self) -> f64 {
        self
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn tan(self) -> Self {
        f64::tan(self)
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }
    type Derivs<V: Copy> = [V; 0];
    #[inline(always)]
    fn derivs_of<V: Copy>(_: V) -> [V; 0] {
        []
    }
    #[inline(always)]
    fn derivs(self) -> [f64; 0] {
        []
    }
    #[inline(always)]
    fn from_parts(v: f64, _: [f64; 0]) -> Self {
        v
    }
    #[inline(always)]
    fn as_plain(y: &mut [Self]) -> Option<&mut [f64]> {
        Some(y)
    }
    #[inline]
    fn powr(self, e: Self) -> Self {
        f64::powf(self, e)
    }
    #[inline]
    fn powf(self, e: f64) -> Self {
        f64::powf(self, e)
    }
}

/// A forward-mode dual number `v + sum_i d_i eps_i` with `N` independent infinitesimals:
/// `d[i]` is the derivative of the value with respect to parameter `i`.
///
/// ```
/// use fracsim::{Dual, Real};
/// let x = Dual::<1>::var(2.0, 0);
/// let y = x * x + x.ln();
/// assert!((y.v - (4.0 + 2f64.ln())).abs() < 1e-15);
/// assert!((y.d[0] - (4.0 + 0.5)).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// The derivatives with respect to each parameter.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A constant (all derivatives zero).
    pub const fn cst(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }
    /// The independent variable number `i` with value `v` (derivative 1 with respect to itself).
    ///
    /// # Panics
    /// If `i >= N` (a programming error, not a data error).
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; N];
        d[i] = 1.0;
        Self { v, d }
    }
    #[inline]
    fn chain(self, v: f64, dv: f64) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x *= dv;
        }
        Self { v, d }
    }
}

impl<const N: usize> From<f64> for Dual<N> {
    fn from(v: f64) -> Self {
        Self::cst(v)
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.d[i] += o.d[i];
        }
        self
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for i in 0..N {
            self.d[i] -= o.d[i];
        }
        self
    }
}
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = self.d[i] * o.v + self.v * o.d[i];
        }
        Self { v: self.v * o.v, d }
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = (self.d[i] - v * o.d[i]) * inv;
        }
        Self { v, d }
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self.chain(-self.v, -1.0)
    }
}
impl<const N: usize> AddAssign for Dual<N> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<const N: usize> SubAssign for Dual<N> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<const N: usize> MulAssign for Dual<N> {
    #[inline]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}
impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: f64) -> Self {
        self.v += o;
        self
    }
}
impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: f64) -> Self {
        self.v -= o;
        self
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: f64) -> Self {
        self.chain(self.v * o, o)
    }
}
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: f64) -> Self {
        self.chain(self.v / o, 1.0 / o)
    }
}

impl<const N: usize> Real for Dual<N> {
    #[inline]
    fn re(self) -> f64 {
        self.v
    }
    type Derivs<V: Copy> = [V; N];
    #[inline(always)]
    fn derivs_of<V: Copy>(v: V) -> [V; N] {
        [v; N]
    }
    #[inline(always)]
    fn derivs(self) -> [f64; N] {
        self.d
    }
    #[inline(always)]
    fn from_parts(v: f64, d: [f64; N]) -> Self {
        Self { v, d }
    }
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s)
    }
    fn tan(self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    fn powf(self, e: f64) -> Self {
        let p = self.v.powf(e);
        self.chain(p, e * self.v.powf(e - 1.0))
    }
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dual_derivatives_match_finite_differences() {
        let f = |x: Dual<2>, y: Dual<2>| {
            (x * y).exp() / (y + 1.0) + x.powr(y) - y.sqrt().tan() * 3.0
                + (x * y).sin_cos().0 * (x - y).sin_cos().1
        };
        let (x0, y0) = (0.7, 1.3);
        let r = f(Dual::var(x0, 0), Dual::var(y0, 1));
        let h = 1e-6;
        let fx = |x: f64, y: f64| f(Dual::cst(x), Dual::cst(y)).v;
        let dx = (fx(x0 + h, y0) - fx(x0 - h, y0)) / (2.0 * h);
        let dy = (fx(x0, y0 + h) - fx(x0, y0 - h)) / (2.0 * h);
        // Central differences have O(h^2) ~ 1e-12 truncation and ~1e-10 rounding error here.
        assert!((r.d[0] - dx).abs() < 1e-8, "{} vs {}", r.d[0], dx);
        assert!((r.d[1] - dy).abs() < 1e-8, "{} vs {}", r.d[1], dy);
    }
}
