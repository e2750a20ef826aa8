//! The controller as a rational system: the fractional operators approximated (refined Oustaloup
//! by default, as `fracid sim` and `export` do) and discretised exactly for a held input
//! (`fracsim::export::discrete`), the realisation a drive runs.
//!
//! See [`discrete`] for how each part of `C(s)` is realised.

use crate::controller::Controller;
use crate::error::Result;
use fracsim::approx::approximate;
use fracsim::export::StateSpace;
use fracsim::ApproxSpec;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// The modal form of the controller's approximation: `d + c1/s + c2/s^2 + sum r_k/(s - p_k)`.
#[derive(Debug, Clone, Default)]
struct Modes {
    d: f64,
    /// The coefficients of `1/s` and `1/s^2` (the integrator's poles at the origin).
    origin: [f64; 2],
    /// Real poles (negative, distinct) and their residues.
    real: Vec<(f64, f64)>,
}

/// Add `gain * prod (s - zeros) / (s^m prod (s - poles))` (roots as values of `s`: real, nonzero
/// and distinct poles, `m <= 2`, no more zeros than poles) to `out` in partial fractions: at the
/// origin `F(0)/s^m` and, for `m = 2`, `F'(0)/s` with `F = s^m G`, `F'/F = sum 1/(s - z) - sum
/// 1/(s - p)`; elsewhere `r_k = F(p_k) / p_k^m`.
fn add_part(out: &mut Modes, gain: f64, zeros: &[f64], poles: &[f64], m: usize) -> Result<()> {
    let repeated = poles.iter().enumerate().any(|(i, a)| {
        poles[..i]
            .iter()
            .any(|b| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()))
    });
    if repeated || m > 2 || poles.contains(&0.0) {
        return Err(fracsim::Error::Numerical(
            "the controller's approximation has repeated poles".into(),
        )
        .into());
    }
    if zeros.len() == poles.len() + m {
        out.d += gain;
    }
    let f = |s: f64, skip: Option<usize>| {
        let mut v = gain;
        for z in zeros {
            v *= s - z;
        }
        for (j, q) in poles.iter().enumerate() {
            if Some(j) != skip {
                v /= s - q;
            }
        }
        v
    };
    if m > 0 {
        let f0 = f(0.0, None);
        out.origin[m - 1] += f0;
        if m == 2 {
            let dlog: f64 = zeros.iter().map(|z| -1.0 / z).sum::<f64>()
                - poles.iter().map(|p| -1.0 / p).sum::<f64>();
            out.origin[0] += f0 * dlog;
        }
    }
    for (k, &p) in poles.iter().enumerate() {
        out.real.push((p, f(p, Some(k)) / p.powi(m as i32)));
    }
    Ok(())
}

/// Split roots given as corner frequencies (`s + w`) into those at the origin and the others.
fn roots(corners: &[f64]) -> (usize, Vec<f64>) {
    let at0 = corners.iter().filter(|w| **w == 0.0).count();
    (
        at0,
        corners.iter().filter(|w| **w != 0.0).map(|w| -w).collect(),
    )
}

/// The modes of `1/s^nu` (`0 <= nu < 2`), `s^nu` approximated as `g s^m prod (s + z)/(s + p)`
/// and inverted.
fn integrator_modes(nu: f64, band: (f64, f64), spec: &ApproxSpec) -> Result<Modes> {
    let mut out = Modes::default();
    let r = approximate(nu, band, spec)?;
    let (z0, poles) = roots(&r.zeros);
    let (p0, zeros) = roots(&r.poles);
    let m = r.int_order + z0 as i32 - p0 as i32;
    if !(0..=2).contains(&m) || p0 > 0 {
        return Err(fracsim::Error::Invalid {
            what: "order",
            msg: format!("{nu}: the integrator's approximation is not realisable"),
        }
        .into());
    }
    add_part(&mut out, 1.0 / r.gain, &zeros, &poles, m as usize)?;
    Ok(out)
}

/// The exact held-input discretisation of `modes` (see [`discrete`]).
fn modal_ss(md: &Modes, dt: f64) -> DMats {
    let n = 2 + md.real.len();
    let mut s = DMats {
        a: DMatrix::zeros(n, n),
        b: DMatrix::zeros(n, 1),
        c: DMatrix::zeros(1, n),
        d: md.d,
    };
    s.a[(0, 0)] = 1.0;
    s.a[(1, 1)] = 1.0;
    s.a[(1, 0)] = dt;
    s.b[(0, 0)] = dt;
    s.b[(1, 0)] = dt * dt / 2.0;
    s.c[(0, 0)] = md.origin[0];
    s.c[(0, 1)] = md.origin[1];
    for (k, &(p, r)) in md.real.iter().enumerate() {
        let e = (p * dt).exp();
        s.a[(k + 2, k + 2)] = e;
        s.b[(k + 2, 0)] = (e - 1.0) / p;
        s.c[(0, k + 2)] = r;
    }
    s
}

/// `(A, B, C, D)` of a single-input single-output discrete system.
#[derive(Debug, Clone)]
struct DMats {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: f64,
}

impl DMats {
    fn order(&self) -> usize {
        self.a.nrows()
    }

    /// `self` followed by `next`.
    fn then(&self, next: &DMats) -> DMats {
        let (n1, n2) = (self.order(), next.order());
        let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, n1), (n2, n2)).copy_from(&next.a);
        a.view_mut((n1, 0), (n2, n1))
            .copy_from(&(&next.b * &self.c));
        let mut b = DMatrix::zeros(n1 + n2, 1);
        b.view_mut((0, 0), (n1, 1)).copy_from(&self.b);
        b.view_mut((n1, 0), (n2, 1)).copy_from(&(&next.b * self.d));
        let mut c = DMatrix::zeros(1, n1 + n2);
        c.view_mut((0, 0), (1, n1)).copy_from(&(&self.c * next.d));
        c.view_mut((0, n1), (1, n2)).copy_from(&next.c);
        DMats {
            a,
            b,
            c,
            d: self.d * next.d,
        }
    }

    /// `k1 self + k2 other`, side by side.
    fn plus(&self, k1: f64, other: &DMats, k2: f64) -> DMats {
        let (n1, n2) = (self.order(), other.order());
        let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, n1), (n2, n2)).copy_from(&other.a);
        let mut b = DMatrix::zeros(n1 + n2, 1);
        b.view_mut((0, 0), (n1, 1)).copy_from(&self.b);
        b.view_mut((n1, 0), (n2, 1)).copy_from(&other.b);
        let mut c = DMatrix::zeros(1, n1 + n2);
        c.view_mut((0, 0), (1, n1)).copy_from(&(&self.c * k1));
        c.view_mut((0, n1), (1, n2)).copy_from(&(&other.c * k2));
        DMats {
            a,
            b,
            c,
            d: k1 * self.d + k2 * other.d,
        }
    }

    /// The backward difference `(u_k - u_(k-1)) / dt`.
    fn backward_difference(dt: f64) -> DMats {
        DMats {
            a: DMatrix::zeros(1, 1),
            b: DMatrix::from_element(1, 1, 1.0),
            c: DMatrix::from_element(1, 1, -1.0 / dt),
            d: 1.0 / dt,
        }
    }
}

/// The discrete realisation of the controller for a sampled input (period `dt` seconds), its
/// fractional operators approximated as `spec` says over `spec.band_for(dt)`:
///
/// - `kp`, a feed-through;
/// - `ki / s^lambda`: the approximation of `s^-lambda` in modal form, each mode discretised
///   exactly for a held input (as `fracid export` and `sim` do). A real pole `p`:
///   `x_(k+1) = e^(p dt) x_k + (e^(p dt) - 1)/p u_k`, output `r x_k`; the origin (one or two
///   integrators, `c1/s + c2/s^2`): `x1_(k+1) = x1_k + dt u_k`, `x2_(k+1) = x2_k + dt x1_k +
///   dt^2/2 u_k`;
/// - `kd s^mu`, written `s^n s^-(n - mu)` with `n = ceil(mu)`: the fractional integrator of order
///   `n - mu` as above followed by `n` backward differences `(1 - z^-1)/dt`. A held-input
///   discretisation of a differentiator would sample its impulse (its gain wrong by the
///   roll-off's `w_f dt / (1 - e^(-w_f dt))`); the backward difference is `j w e^(-j w dt/2)`
///   to `O((w dt)^2)`, the same half-sample lag as the held integrator.
///
/// # Errors
/// A bad step or band, an order outside the approximation's range, repeated poles.
pub fn discrete(c: &Controller, dt: f64, spec: &ApproxSpec) -> Result<StateSpace> {
    let band = spec.band_for(dt)?;
    let one = DMats {
        a: DMatrix::zeros(0, 0),
        b: DMatrix::zeros(0, 1),
        c: DMatrix::zeros(1, 0),
        d: 1.0,
    };
    let mut all = if c.ki != 0.0 {
        let integ = modal_ss(&integrator_modes(c.lambda, band, spec)?, dt);
        one.plus(c.kp, &integ, c.ki)
    } else {
        DMats {
            d: c.kp,
            ..one.clone()
        }
    };
    if c.kd != 0.0 {
        let n = c.mu.ceil().max(1.0);
        let rest = n - c.mu;
        let mut d = if rest > 0.0 {
            modal_ss(&integrator_modes(rest, band, spec)?, dt)
        } else {
            one.clone()
        };
        for _ in 0..n as usize {
            d = d.then(&DMats::backward_difference(dt));
        }
        all = all.plus(1.0, &d, c.kd);
    }
    Ok(StateSpace {
        a: all.a,
        b: all.b,
        c: all.c,
        d: all.d,
        dt: Some(dt),
        input_delay: 0.0,
        delay_states: 0,
        band,
        spec: *spec,
    })
}

/// The frequency response of a discrete state space at omega rad/s, `C (z I - A)^-1 B + D` with
/// `z = e^(j omega dt)`.
pub fn discrete_response(ss: &StateSpace, omega: f64) -> Complex64 {
    let dt = ss.dt.unwrap_or(1.0);
    let z = Complex64::from_polar(1.0, omega * dt);
    let n = ss.order();
    let m = DMatrix::from_fn(n, n, |i, j| {
        let a = Complex64::new(ss.a[(i, j)], 0.0);
        if i == j {
            z - a
        } else {
            -a
        }
    });
    let b = DMatrix::from_fn(n, 1, |i, _| Complex64::new(ss.b[(i, 0)], 0.0));
    let x = m.lu().solve(&b).unwrap_or_else(|| DMatrix::zeros(n, 1));
    (0..n).fold(Complex64::new(ss.d, 0.0), |acc, k| {
        acc + x[(k, 0)] * ss.c[(0, k)]
    })
}
