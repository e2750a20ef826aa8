//! Recursive discrete filters: each rational approximation of `s^nu` becomes a cascade of
//! first-order sections (never one multiplied-out polynomial, which is ill-conditioned), and
//! [`Simulator`] combines the operators of a fractional transfer function implicitly, sample by
//! sample.
//!
//! With every operator written `D^a x_k = d_a x_k + h_a(k)` (feed-through `d_a`, history `h_a`),
//! the model `sum_j a_j D^(alpha_j) y = sum_i b_i D^(beta_i) u` gives at each step
//! `y_k = (sum_i b_i D^(beta_i) u_k - sum_j a_j h_(alpha_j)(k)) / sum_j a_j d_(alpha_j)`.

use crate::approx::{approximate, ApproxSpec, Discretization, Rational};
use crate::error::{finite, invalid, Error, Result};
use crate::scalar::Real;
use crate::tf::FracTf;

/// A first-order section `y = (b0 + b1 z^-1)/(1 + a1 z^-1) x` in transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section<T> {
    /// Feed-through coefficient.
    pub b0: T,
    /// Delayed input coefficient.
    pub b1: T,
    /// Delayed output coefficient (pole at `z = -a1`).
    pub a1: T,
}

/// The discrete version of one fractional operator: `gain * s_1 * s_2 * ...` with state.
///
/// The cascade of sections defines the operator ([`Operator::sections`]). When its poles are
/// distinct (bilinear discretisation, at most one integer differentiator or integrator), it runs
/// in the equivalent modal (partial-fraction) form instead: the cascade's recursion is a serial
/// chain through every section, twice per sample, while the modes update independently of each
/// other, which is several times faster; see [`Modes`].
#[derive(Debug, Clone)]
pub struct Operator<T> {
    gain: T,
    sections: Vec<Section<T>>,
    state: Vec<T>,
    /// Total feed-through `gain * prod b0`.
    feed: T,
    /// The modal form, when the poles allow it.
    modes: Option<Modes<T>>,
}

/// The modal (diagonal state-space) form of a cascade with distinct poles `lambda_i`:
/// `H(z) = feed + sum_i r_i / (z - lambda_i)`, run as `m_i(k+1) = lambda_i m_i(k) + x_k`,
/// `out_k = feed x_k + sum_i r_i m_i(k)`.
///
/// The residues come from the continuous cells, not from the discrete coefficients: the bilinear
/// map is a substitution `s = c (z - 1)/(z + 1)`, so a section evaluated at the discrete pole
/// `lambda_i` equals its continuous cell at the continuous pole `-p_i`, and
/// `r_i = gain (b0_i lambda_i + b1_i) prod_(j != i) (z_j - p_i)/(p_j - p_i)` with
/// `b0_i lambda_i + b1_i = 2c (z_i - p_i)/(c + p_i)^2`. This avoids the cancellation of
/// `1 + a1_j/a1_i` between discrete poles crowded near `z = 1` (every pole far below Nyquist),
/// so the residues are accurate to a few ulps. The vectors are padded to a multiple of 4 with
/// `lambda = r = 0` so the update runs in independent lanes.
#[derive(Debug, Clone)]
struct Modes<T> {
    /// The modes in blocks of four lanes (contiguous, so the update vectorises).
    blocks: Vec<Block<T>>,
    /// `sum_i r_i`.
    res_sum: T,
    /// `sum_i r_i m_i` for the current state (the operator's history).
    hist: T,
}

/// Four modes: poles, `r_i lambda_i` and states.
///
/// `res_lam`: the history after an update is `sum_i r_i lambda_i m_i + (sum_i r_i) x`, whose
/// first part does not wait for the input `x` (the output just solved for).
#[derive(Debug, Clone, Copy)]
struct Block<T> {
    lam: [T; 4],
    res_lam: [T; 4],
    m: [T; 4],
}

/// One factor of a rational approximation, for the modal form.
#[derive(Clone, Copy)]
enum Factor<T> {
    /// `(s + z)/(s + p)`.
    Cell(T, T),
    /// `s` (bilinear differentiator, discrete pole `-1`).
    Diff,
    /// `1/s` (bilinear integrator, discrete pole `1`).
    Integ,
}

/// Where a factor's pole sits in the continuous domain.
#[derive(Clone, Copy)]
enum At<T> {
    /// `s = -p`.
    Minus(T),
    /// `s = infinity` (the differentiator's pole).
    Infinity,
    /// `s = 0` (the integrator's pole).
    Zero,
}

impl<T: Real> Factor<T> {
    fn pole(self) -> At<T> {
        match self {
            Factor::Cell(_, p) => At::Minus(p),
            Factor::Diff => At::Infinity,
            Factor::Integ => At::Zero,
        }
    }
    /// The factor's value at another factor's pole.
    fn at(self, s: At<T>) -> T {
        match (self, s) {
            (Factor::Cell(z, p), At::Minus(q)) => (z - q) / (p - q),
            (Factor::Cell(..), At::Infinity) => T::from(1.0),
            (Factor::Cell(z, p), At::Zero) => z / p,
            (Factor::Diff, At::Minus(q)) => -q,
            (Factor::Integ, At::Minus(q)) => -(T::from(1.0) / q),
            (Factor::Diff, _) | (Factor::Integ, _) => T::from(0.0),
        }
    }
    /// `b0 lambda + b1` of its own bilinear section (`c = 2/dt`).
    fn own(self, c: f64) -> T {
        match self {
            Factor::Cell(z, p) => {
                let d = p + c;
                (z - p) * (2.0 * c) / (d * d)
            }
            Factor::Diff => T::from(-2.0 * c),
            Factor::Integ => T::from(2.0 / c),
        }
    }
}

impl<T: Real> Modes<T> {
    /// The modal form of `gain * prod factors`, whose discrete poles are `lam` (in the same
    /// order), or `None` when two poles are too close for a partial-fraction expansion.
    fn new(gain: T, factors: &[Factor<T>], lam: &[T], c: f64) -> Option<Self> {
        let n = factors.len();
        for i in 0..n {
            for j in 0..i {
                let (a, b) = (lam[i].re(), lam[j].re());
                if (a - b).abs() <= 1e-9 {
                    return None;
                }
                if let (Factor::Cell(_, p), Factor::Cell(_, q)) = (factors[i], factors[j]) {
                    let (p, q) = (p.re(), q.re());
                    if (p - q).abs() <= 1e-9 * p.abs().max(q.abs()) {
                        return None;
                    }
                }
            }
            if let Factor::Cell(_, p) = factors[i] {
                if p.re().is_nan() || p.re() <= 0.0 {
                    return None;
                }
            }
        }
        let mut res = Vec::with_capacity(n.next_multiple_of(4));
        for (i, f) in factors.iter().enumerate() {
            let s = f.pole();
            let mut r = gain * f.own(c);
            for (j, g) in factors.iter().enumerate() {
                if j != i {
                    r *= g.at(s);
                }
            }
            if !r.re().is_finite() {
                return None;
            }
            res.push(r);
        }
        let mut lam = lam.to_vec();
        let padded = n.next_multiple_of(4);
        lam.resize(padded, T::from(0.0));
        res.resize(padded, T::from(0.0));
        let mut res_sum = T::from(0.0);
        for &r in &res {
            res_sum += r;
        }
        let zero = T::from(0.0);
        let blocks = lam
            .chunks_exact(4)
            .zip(res.chunks_exact(4))
            .map(|(l, r)| Block {
                lam: [l[0], l[1], l[2], l[3]],
                res_lam: [r[0] * l[0], r[1] * l[1], r[2] * l[2], r[3] * l[3]],
                m: [zero; 4],
            })
            .collect();
        Some(Self {
            blocks,
            res_sum,
            hist: zero,
        })
    }

    /// `m_i <- lambda_i m_i + x` and the new history `sum_i r_i m_i`, computed as
    /// `sum_i (r_i lambda_i) m_i(old) + (sum_i r_i) x` in four independent lanes, so that only
    /// one multiply-add waits for `x`.
    #[inline]
    fn advance(&mut self, x: T) {
        let zero = T::from(0.0);
        let mut acc = [zero; 4];
        for b in &mut self.blocks {
            for k in 0..4 {
                acc[k] += b.res_lam[k] * b.m[k];
                b.m[k] = b.lam[k] * b.m[k] + x;
            }
        }
        self.hist = (acc[0] + acc[1]) + (acc[2] + acc[3]) + self.res_sum * x;
    }

    fn reset(&mut self) {
        for b in &mut self.blocks {
            b.m = [T::from(0.0); 4];
        }
        self.hist = T::from(0.0);
    }
}

fn prewarp(w: f64, dt: f64) -> f64 {
    let cap = 0.9 * std::f64::consts::FRAC_PI_2;
    (2.0 / dt) * (0.5 * w * dt).min(cap).tan()
}

fn prewarp_t<T: Real>(w: T, dt: f64) -> T {
    let cap = 0.9 * std::f64::consts::FRAC_PI_2;
    if 0.5 * w.re() * dt >= cap {
        T::from(prewarp(w.re(), dt))
    } else {
        (w * (0.5 * dt)).tan() * (2.0 / dt)
    }
}

impl<T: Real> Operator<T> {
    /// The identity operator (order 0).
    pub fn identity() -> Self {
        Self {
            gain: T::from(1.0),
            sections: vec![],
            state: vec![],
            feed: T::from(1.0),
            modes: None,
        }
    }

    /// Discretise a rational approximation with step `dt` (seconds).
    ///
    /// Cells `(s + z)/(s + p)`: bilinear `c = 2/dt`: `b0 = (c+z)/(c+p)`, `b1 = -(c-z)/(c+p)`,
    /// `a1 = -(c-p)/(c+p)` (corners prewarped when asked); ZOH: `b0 = 1`, `a1 = -e^(-p dt)`,
    /// `b1 = (z-p)(1-e^(-p dt))/p - e^(-p dt)`. Integer powers `s^n`: `n` bilinear differentiators
    /// `c (1 - z^-1)/(1 + z^-1)`; `s^-1`: the bilinear integrator.
    ///
    /// # Errors
    /// A non-positive step, an integer order below -1.
    pub fn from_rational(r: &Rational<T>, dt: f64, disc: Discretization) -> Result<Self> {
        finite("dt", dt)?;
        if dt <= 0.0 {
            return invalid("dt", format!("{dt} s must be positive"));
        }
        let c = 2.0 / dt;
        let mut sections = Vec::with_capacity(r.zeros.len() + r.int_order.unsigned_abs() as usize);
        // The continuous factors behind the sections (bilinear only), for the modal form.
        let mut factors = Vec::with_capacity(sections.capacity());
        for (&z, &p) in r.zeros.iter().zip(&r.poles) {
            sections.push(match disc {
                Discretization::Zoh => {
                    let e = (-p * dt).exp();
                    let g = (z - p) * (-e + 1.0) / p;
                    Section {
                        b0: T::from(1.0),
                        b1: g - e,
                        a1: -e,
                    }
                }
                Discretization::Bilinear | Discretization::BilinearPrewarp => {
                    let (z, p) = if disc == Discretization::BilinearPrewarp {
                        (prewarp_t(z, dt), prewarp_t(p, dt))
                    } else {
                        (z, p)
                    };
                    factors.push(Factor::Cell(z, p));
                    let den = p + c;
                    Section {
                        b0: (z + c) / den,
                        b1: -(-z + c) / den,
                        a1: -(-p + c) / den,
                    }
                }
            });
        }
        match r.int_order {
            n if n >= 0 => {
                for _ in 0..n {
                    factors.push(Factor::Diff);
                    sections.push(Section {
                        b0: T::from(c),
                        b1: T::from(-c),
                        a1: T::from(1.0),
                    });
                }
            }
            -1 => {
                factors.push(Factor::Integ);
                sections.push(Section {
                    b0: T::from(1.0 / c),
                    b1: T::from(1.0 / c),
                    a1: T::from(-1.0),
                })
            }
            n => return invalid("order", format!("integer part {n} below -1")),
        }
        let mut feed = r.gain;
        for s in &sections {
            feed *= s.b0;
        }
        let modes = if disc == Discretization::Zoh || r.int_order.abs() > 1 {
            None
        } else {
            let lam: Vec<T> = sections.iter().map(|s| -s.a1).collect();
            Modes::new(r.gain, &factors, &lam, c)
        };
        Ok(Self {
            gain: r.gain,
            state: vec![T::from(0.0); sections.len()],
            sections,
            feed,
            modes,
        })
    }

    /// The feed-through `d`: the output is `d x_k + history`.
    #[inline]
    pub fn feed(&self) -> T {
        self.feed
    }

    /// The part of the next output that does not depend on the next input.
    #[inline]
    pub fn history(&self) -> T {
        if let Some(md) = &self.modes {
            return md.hist;
        }
        let mut h = T::from(0.0);
        for (s, &st) in self.sections.iter().zip(&self.state) {
            h = s.b0 * h + st;
        }
        h * self.gain
    }

    /// Apply to the next input, advance the state, return the output.
    #[inline]
    pub fn step(&mut self, x: T) -> T {
        if let Some(md) = &mut self.modes {
            let out = self.feed * x + md.hist;
            md.advance(x);
            return out;
        }
        let mut v = x;
        for (s, st) in self.sections.iter().zip(self.state.iter_mut()) {
            let y = s.b0 * v + *st;
            *st = s.b1 * v - s.a1 * y;
            v = y;
        }
        v * self.gain
    }

    /// Zero the state.
    pub fn reset(&mut self) {
        for s in &mut self.state {
            *s = T::from(0.0);
        }
        if let Some(md) = &mut self.modes {
            md.reset();
        }
    }

    /// The sections of the cascade.
    pub fn sections(&self) -> &[Section<T>] {
        &self.sections
    }
}

/// Runs a fractional transfer function on a sampled input, one sample at a time, through the
/// recursive discrete filters of its fractional operators (implicit in the output).
///
/// Generic over [`Real`]: with [`crate::Dual`] coefficients, orders and delay it returns the exact
/// derivatives of the discrete simulation (forward-mode sensitivities).
///
/// The input is taken as held constant over each step (as a drive's PWM holds it): `u_k` acts on
/// `[t_k, t_(k+1))` and `y_k` is the output at `t_k`. The bilinear map treats samples as a
/// piecewise-linear signal, which would advance a held input by half a step, so bilinear
/// simulations delay the input by `dt/2` to compensate (this cuts the error at the first samples of
/// a step tenfold). The input delay `tau` (plus that half step) is `m + phi` samples (`m` whole,
/// `0 <= phi < 1`); the delayed input is interpolated linearly, `(1 - phi) u_(k-m) + phi u_(k-m-1)`,
/// which keeps it differentiable in `tau`.
///
/// ```
/// use fracsim::{ApproxSpec, FracTf, Simulator};
/// let g: FracTf = "6.77/(0.0064 s^0.89 + 1)".parse().unwrap();
/// let mut sim = Simulator::<f64>::new(&g, 1e-4, &ApproxSpec::default()).unwrap();
/// let y = sim.simulate(&vec![1.0; 301]);
/// // Mittag-Leffler oracle: y(0.03) = 6.615241
/// assert!((y[300] - 6.615241).abs() < 1e-3 * 6.615241);
/// ```
#[derive(Debug, Clone)]
pub struct Simulator<T> {
    num: Vec<(T, Operator<T>)>,
    den: Vec<(T, Operator<T>)>,
    /// `1 / sum_j a_j d_j`, the inverse of the denominator's feed-through (a multiply instead of a divide on the critical path of every step).
    den_feed_inv: T,
    delay_whole: usize,
    delay_frac: T,
    /// Ring buffer of past inputs for the delay.
    hist: Vec<T>,
    pos: usize,
}

impl<T: Real> Simulator<T> {
    /// Build from a [`FracTf`].
    ///
    /// # Errors
    /// As [`Simulator::from_terms`].
    pub fn new(tf: &FracTf, dt: f64, spec: &ApproxSpec) -> Result<Self> {
        let conv = |t: &[crate::Term]| -> Vec<(T, T)> {
            t.iter()
                .map(|t| (T::from(t.coef), T::from(t.order)))
                .collect()
        };
        Self::from_terms(&conv(&tf.num), &conv(&tf.den), T::from(tf.delay), dt, spec)
    }

    /// Build from `(coef, order)` terms of numerator and denominator and a delay in seconds.
    ///
    /// # Errors
    /// Non-finite values, negative orders or delay, a bad band or step, a denominator whose
    /// discrete feed-through vanishes (the implicit step would divide by zero).
    pub fn from_terms(
        num: &[(T, T)],
        den: &[(T, T)],
        delay: T,
        dt: f64,
        spec: &ApproxSpec,
    ) -> Result<Self> {
        let band = spec.band_for(dt)?;
        let build = |terms: &[(T, T)], what: &'static str| -> Result<Vec<(T, Operator<T>)>> {
            terms
                .iter()
                .map(|&(c, o)| {
                    finite(what, c.re())?;
                    let op = if o.re() == 0.0 {
                        Operator::identity()
                    } else {
                        Operator::from_rational(
                            &approximate(o, band, spec)?,
                            dt,
                            spec.discretization,
                        )?
                    };
                    Ok((c, op))
                })
                .collect()
        };
        let num = build(num, "numerator coefficient")?;
        let den = build(den, "denominator coefficient")?;
        if den.iter().all(|(c, _)| c.re() == 0.0) {
            return Err(Error::ZeroDenominator);
        }
        let mut den_feed = T::from(0.0);
        for (a, op) in &den {
            den_feed += *a * op.feed();
        }
        let df = den_feed.re();
        if !df.is_finite() || df.abs() < 1e-300 {
            return Err(Error::Numerical(format!(
                "the discrete denominator has feed-through {df}: the implicit step is singular"
            )));
        }
        let d = finite("delay", delay.re())?;
        if d < 0.0 {
            return invalid("delay", format!("{d} s is negative"));
        }
        let hold = match spec.discretization {
            crate::Discretization::Zoh => 0.0,
            _ => 0.5,
        };
        let samples = delay / dt + hold;
        let whole = samples.re().floor();
        if whole > 1e8 {
            return invalid("delay", format!("{d} s is more than 1e8 samples"));
        }
        Ok(Self {
            num,
            den,
            den_feed_inv: T::from(1.0) / den_feed,
            delay_whole: whole as usize,
            delay_frac: samples - whole,
            hist: vec![T::from(0.0); whole as usize + 2],
            pos: 0,
        })
    }

    /// Advance one sample with input `u`, return the output.
    #[inline]
    pub fn step(&mut self, u: T) -> T {
        let x = if self.hist.len() == 2 && self.delay_frac == T::from(0.0) {
            u
        } else {
            let n = self.hist.len();
            // Ring buffer indices without integer division (`delay_whole <= n - 2`).
            let wrap = |i: usize| if i >= n { i - n } else { i };
            self.pos = wrap(self.pos + 1);
            self.hist[self.pos] = u;
            let a = self.hist[wrap(self.pos + n - self.delay_whole)];
            let b = self.hist[wrap(self.pos + n - self.delay_whole - 1)];
            a + (b - a) * self.delay_frac
        };
        let mut rhs = T::from(0.0);
        for (b, op) in &mut self.num {
            rhs += *b * op.step(x);
        }
        for (a, op) in &self.den {
            rhs -= *a * op.history();
        }
        let y = rhs * self.den_feed_inv;
        for (_, op) in &mut self.den {
            op.step(y);
        }
        y
    }

    /// Run on a whole input sequence (from rest).
    pub fn simulate(&mut self, u: &[f64]) -> Vec<T> {
        self.reset();
        u.iter().map(|&x| self.step(T::from(x))).collect()
    }

    /// Back to rest: all states and the delay line zeroed.
    pub fn reset(&mut self) {
        for (_, op) in self.num.iter_mut().chain(self.den.iter_mut()) {
            op.reset();
        }
        for h in &mut self.hist {
            *h = T::from(0.0);
        }
        self.pos = 0;
    }
}

/// Simulate `tf` on input `u` sampled every `dt` seconds, from rest.
///
/// ```
/// use fracsim::{lsim, ApproxSpec, FracTf};
/// let g: FracTf = "1/(0.1 s + 1)".parse().unwrap();
/// let y = lsim(&g, &vec![1.0; 2000], 1e-3, &ApproxSpec::default()).unwrap();
/// assert!((y[1999] - 1.0).abs() < 1e-6);
/// ```
///
/// # Errors
/// As [`Simulator::from_terms`]; non-finite input samples; a non-finite output.
pub fn lsim(tf: &FracTf, u: &[f64], dt: f64, spec: &ApproxSpec) -> Result<Vec<f64>> {
    if let Some(i) = u.iter().position(|x| !x.is_finite()) {
        return invalid("input", format!("sample {i} is {}", u[i]));
    }
    let mut sim = Simulator::<f64>::new(tf, dt, spec)?;
    let y = sim.simulate(u);
    if let Some(i) = y.iter().position(|x| !x.is_finite()) {
        return Err(Error::Numerical(format!(
            "the output is not finite at sample {i}"
        )));
    }
    Ok(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::Method;
    use crate::scalar::Dual;

    /// The modal form runs the same filter as the cascade it is expanded from.
    #[test]
    fn modal_form_matches_the_cascade() {
        let dt = 1e-4;
        let u: Vec<f64> = (0..20_000)
            .map(|k| if (k / 37) % 3 == 0 { 1.0 } else { -0.5 })
            .collect();
        for method in [Method::Oustaloup, Method::Refined, Method::Trigeassou] {
            for disc in [Discretization::Bilinear, Discretization::BilinearPrewarp] {
                for nu in [0.3f64, 0.92, 1.7452] {
                    let spec = ApproxSpec {
                        method,
                        discretization: disc,
                        band: if disc == Discretization::Bilinear {
                            None
                        } else {
                            Some((1e-2, 1e4))
                        },
                        ..ApproxSpec::default()
                    };
                    let nu = if method == Method::Trigeassou {
                        nu.min(1.0)
                    } else {
                        nu
                    };
                    let band = spec.band_for(dt).unwrap();
                    let r = approximate(nu, band, &spec).unwrap();
                    let mut modal = Operator::from_rational(&r, dt, disc).unwrap();
                    assert!(modal.modes.is_some(), "{method:?} {disc:?} {nu}");
                    let mut cascade = modal.clone();
                    cascade.modes = None;
                    let (mut worst, mut scale) = (0.0f64, 0.0f64);
                    for &x in &u {
                        let (h1, h2) = (modal.history(), cascade.history());
                        let (a, b) = (modal.step(x), cascade.step(x));
                        worst = worst.max((a - b).abs()).max((h1 - h2).abs());
                        scale = scale.max(b.abs());
                    }
                    assert!(
                        worst <= 1e-9 * scale,
                        "{method:?} {disc:?} {nu}: {worst} of {scale}"
                    );
                }
            }
        }
    }

    /// The derivatives through the modal form equal those through the cascade.
    #[test]
    fn modal_form_derivatives_match_the_cascade() {
        let dt = 1e-4;
        let spec = ApproxSpec::default();
        let band = spec.band_for(dt).unwrap();
        let r = approximate(Dual::<1>::var(0.92, 0), band, &spec).unwrap();
        let mut modal = Operator::from_rational(&r, dt, spec.discretization).unwrap();
        let mut cascade = modal.clone();
        cascade.modes = None;
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        for k in 0..5000 {
            let x = Dual::cst(if (k / 30) % 2 == 0 { 1.0 } else { -1.0 });
            let (a, b) = (modal.step(x), cascade.step(x));
            worst = worst.max((a.d[0] - b.d[0]).abs());
            scale = scale.max(b.d[0].abs());
        }
        assert!(worst <= 1e-9 * scale, "{worst} of {scale}");
    }
}
