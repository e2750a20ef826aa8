//! Zeros in the closed right half-plane of a characteristic function
//! `Phi(s) = A(s) + B(s) e^(-s tau)`, `A` and `B` sums of powers of `s` (principal branch), by the
//! argument principle.
//!
//! For the loop `L = (N_c N_p / D_c D_p) e^(-s tau)` the closed loop's poles are the zeros of
//! `Phi = D_c D_p + N_c N_p e^(-s tau)`; the plant's own poles are the zeros of `D_p`. Unlike
//! `1 + L`, `Phi` has no poles: a lightly damped pole of the model, where `1 + L` turns a full
//! circle within a hair's breadth of frequency, is only a place where `D_p(j w)` passes near
//! zero along a nearly straight line, and `Phi` changes smoothly there. So the count needs no
//! knowledge of the open loop's unstable poles (an unstable model is counted as any other) and a
//! grid cannot step over a resonance: `Phi(j w)` turns fast only near one of its own zeros, where
//! the segments are subdivided until every step turns less than 0.2 rad and agrees with its two
//! halves.
//!
//! On the D contour (the imaginary axis from `-j inf` to `j inf`, indented around the origin on
//! the right, closed at infinity in the right half-plane, counter-clockwise), with `Phi ~ c_0 s^o0`
//! near the origin and `Phi ~ c_n s^on` at infinity (`B`'s highest order below `A`'s, so that
//! `e^(-s tau)` decays on the arc), the change of `arg Phi` is `-2 Delta + on pi - o0 pi`, where
//! `Delta` is its change along `j w` from `0+` to `+inf` (the lower half is the mirror image: the
//! coefficients are real). The number of zeros in the open right half-plane is that over `2 pi`.

use fracsim::{jw_pow, Term};
use num_complex::Complex64;
use std::f64::consts::{FRAC_PI_2, PI};

/// `A(s) + B(s) e^(-s tau)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Quasi {
    /// The terms without the delay.
    pub a: Vec<Term>,
    /// The terms with the delay.
    pub b: Vec<Term>,
    /// The delay, seconds.
    pub tau: f64,
}

/// `x * y`, like orders merged (within 1e-12), zero coefficients dropped, by decreasing order.
pub fn product(x: &[Term], y: &[Term]) -> Vec<Term> {
    let mut out: Vec<Term> = Vec::new();
    for p in x {
        for q in y {
            let (c, o) = (p.coef * q.coef, p.order + q.order);
            match out.iter_mut().find(|t| (t.order - o).abs() < 1e-12) {
                Some(t) => t.coef += c,
                None => out.push(Term::new(c, o)),
            }
        }
    }
    out.retain(|t| t.coef != 0.0);
    out.sort_by(|a, b| b.order.total_cmp(&a.order));
    out
}

/// The most evaluations of `Phi` one count makes (bounded work whatever the request).
const MAX_EVALS: usize = 4_000_000;
/// How much the dominant term must outweigh the others at the ends of the sweep.
const DOMINANCE: f64 = 50.0;
/// The largest turn of `arg Phi` accepted over one step, rad.
const MAX_TURN: f64 = 0.2;

/// Why a count could not be made.
#[derive(Debug, Clone, PartialEq)]
pub enum NoCount {
    /// A zero on the imaginary axis (at the origin when `omega` is 0), rad/s: marginal stability.
    OnAxis(f64),
    /// The delayed part is not of lower order than the rest (a loop that does not roll off).
    NotProper,
    /// The sweep would take more than the evaluations allowed (a delay turning the loop too many
    /// times over the band, or frequencies beyond the floating-point range).
    TooMuchWork(String),
}

impl std::fmt::Display for NoCount {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoCount::OnAxis(w) if *w == 0.0 => write!(f, "a closed-loop pole at s = 0"),
            NoCount::OnAxis(w) => {
                write!(
                    f,
                    "a closed-loop pole on the imaginary axis near {w:.4e} rad/s"
                )
            }
            NoCount::NotProper => write!(f, "the loop does not roll off at high frequency"),
            NoCount::TooMuchWork(why) => write!(f, "the stability count was abandoned: {why}"),
        }
    }
}

/// `sum |c_k| w^a_k` over the terms but those of order `skip` (none for `NaN`).
fn sum_abs(t: &[Term], w: f64, skip: f64) -> f64 {
    t.iter()
        .filter(|t| skip.is_nan() || (t.order - skip).abs() >= 1e-12)
        .map(|t| t.coef.abs() * w.powf(t.order))
        .sum()
}

fn poly(t: &[Term], w: f64) -> Complex64 {
    t.iter().map(|t| jw_pow(w, t.order) * t.coef).sum()
}

impl Quasi {
    /// `Phi(j w)`.
    pub fn eval(&self, w: f64) -> Complex64 {
        let a = poly(&self.a, w);
        if self.b.is_empty() {
            return a;
        }
        a + poly(&self.b, w) * Complex64::from_polar(1.0, -w * self.tau)
    }

    /// The sizes of the two parts at `w`: `sum |a_k| w^a_k`, `sum |b_k| w^b_k`.
    fn sizes(&self, w: f64) -> (f64, f64) {
        (sum_abs(&self.a, w, f64::NAN), sum_abs(&self.b, w, f64::NAN))
    }

    /// The lowest order of its terms and the sum of their coefficients there (`Phi ~ c s^o` as
    /// `s -> 0`): `o > 0` is a zero at the origin.
    pub fn lowest(&self) -> (f64, f64) {
        let o = self
            .a
            .iter()
            .chain(&self.b)
            .map(|t| t.order)
            .fold(f64::INFINITY, f64::min);
        let c = self
            .a
            .iter()
            .chain(&self.b)
            .filter(|t| (t.order - o).abs() < 1e-12)
            .map(|t| t.coef)
            .sum();
        (o, c)
    }
}

/// The number of zeros of `phi` in the open right half-plane (principal sheet), sweeping `j w`
/// around `hint` rad/s (where the sweep starts looking for its ends) with `extra` frequencies
/// added to the grid (the places where the caller knows something narrow happens).
///
/// # Errors
/// [`NoCount`]: a zero on the imaginary axis, a delayed part of the highest order, too much work.
pub fn rhp_zeros(phi: &Quasi, hint: f64, extra: &[f64]) -> Result<u32, NoCount> {
    let (o_lo, c_lo) = phi.lowest();
    let scale_lo: f64 = phi
        .a
        .iter()
        .chain(&phi.b)
        .filter(|t| (t.order - o_lo).abs() < 1e-12)
        .map(|t| t.coef.abs())
        .sum();
    if !(c_lo.abs() > 1e-12 * scale_lo) {
        return Err(NoCount::OnAxis(0.0));
    }
    let top_a = phi
        .a
        .iter()
        .map(|t| t.order)
        .fold(f64::NEG_INFINITY, f64::max);
    let top_b = phi
        .b
        .iter()
        .map(|t| t.order)
        .fold(f64::NEG_INFINITY, f64::max);
    // A delayed part of the same highest order (a loop with a feed-through, `|L(j inf)| = r`):
    // without a delay it merges with the rest; with one, `Phi / (c s^n) = 1 + r e^(-j w tau)`
    // stays in the right half-plane for r < 1 (the change past the sweep is then within
    // +-pi/2), and the count is refused for r near or above 1 (a neutral loop).
    let c_b_top: f64 = phi
        .b
        .iter()
        .filter(|t| (t.order - top_a).abs() < 1e-12)
        .map(|t| t.coef)
        .sum();
    let c_a_top: f64 = phi
        .a
        .iter()
        .filter(|t| (t.order - top_a).abs() < 1e-12)
        .map(|t| t.coef)
        .sum();
    let (c_top, r_top) = if top_b > top_a + 1e-12 {
        return Err(NoCount::NotProper);
    } else if top_b < top_a - 1e-12 {
        (c_a_top, 0.0)
    } else if phi.tau == 0.0 {
        (c_a_top + c_b_top, 0.0)
    } else {
        (c_a_top, (c_b_top / c_a_top).abs())
    };
    if !(c_top != 0.0 && r_top < 0.9) {
        return Err(NoCount::NotProper);
    }
    let (w_lo, w_hi) = sweep_ends(phi, hint, (o_lo, c_lo), (top_a, c_top, r_top))?;
    let grid = sweep_grid(phi, w_lo, w_hi, extra)?;
    let mut budget = MAX_EVALS.saturating_sub(grid.len());
    let vals: Vec<Complex64> = grid.iter().map(|&w| phi.eval(w)).collect();
    let tiny = |w: f64, v: Complex64| {
        let (sa, sb) = phi.sizes(w);
        v.norm() <= 1e-13 * (sa + sb)
    };
    let start = o_lo * FRAC_PI_2 + if c_lo < 0.0 { PI } else { 0.0 };
    let end = top_a * FRAC_PI_2 + if c_top < 0.0 { PI } else { 0.0 };
    let wrap = |d: f64| (Complex64::from_polar(1.0, d)).arg();
    let mut delta = wrap(vals[0].arg() - start);
    for i in 1..grid.len() {
        if tiny(grid[i], vals[i]) {
            return Err(NoCount::OnAxis(grid[i]));
        }
        delta += turn(
            phi,
            (grid[i - 1], vals[i - 1]),
            (grid[i], vals[i]),
            0,
            &mut budget,
        )?;
    }
    delta += wrap(end - vals[vals.len() - 1].arg());
    let z = (top_a * PI - o_lo * PI - 2.0 * delta) / (2.0 * PI);
    let r = z.round();
    if (z - r).abs() > 0.1 || r < 0.0 {
        return Err(NoCount::TooMuchWork(format!(
            "the winding number {z:.3} is not an integer"
        )));
    }
    Ok(r as u32)
}

/// The ends of the sweep: `w_lo` where the lowest-order term (`o_lo`, `c_lo`) outweighs the rest
/// [`DOMINANCE`] times and the delay has not yet turned the delayed part, `w_hi` where the
/// highest-order one does (`r_top > 0`: a delayed part of that order, left out).
fn sweep_ends(
    phi: &Quasi,
    hint: f64,
    (o_lo, c_lo): (f64, f64),
    (top_a, c_top, r_top): (f64, f64, f64),
) -> Result<(f64, f64), NoCount> {
    let hint = if hint.is_finite() && hint > 0.0 {
        hint
    } else {
        1.0
    };
    // the low end: the lowest term dominates, the delay has not turned the delayed part yet
    let b_lo: f64 = phi
        .b
        .iter()
        .filter(|t| (t.order - o_lo).abs() < 1e-12)
        .map(|t| t.coef.abs())
        .sum();
    let low_ok = |w: f64| {
        let rest = sum_abs(&phi.a, w, o_lo) + sum_abs(&phi.b, w, o_lo);
        c_lo.abs() * w.powf(o_lo) >= DOMINANCE * rest
            && b_lo * w * phi.tau * DOMINANCE <= c_lo.abs()
    };
    let mut w_lo = hint;
    while !low_ok(w_lo) {
        w_lo /= 10.0;
        if w_lo < 1e-250 {
            return Err(NoCount::TooMuchWork(
                "no frequency low enough where the lowest-order term dominates".into(),
            ));
        }
    }
    let high_ok = |w: f64| {
        let b_rest = if phi.tau == 0.0 || r_top > 0.0 {
            sum_abs(&phi.b, w, top_a)
        } else {
            sum_abs(&phi.b, w, f64::NAN)
        };
        let rest = sum_abs(&phi.a, w, top_a) + b_rest;
        c_top.abs() * w.powf(top_a) >= DOMINANCE * rest
    };
    let mut w_hi = hint.max(w_lo * 10.0);
    while !high_ok(w_hi) {
        w_hi *= 10.0;
        if w_hi > 1e250 {
            return Err(NoCount::TooMuchWork(
                "no frequency high enough where the highest-order term dominates".into(),
            ));
        }
    }
    Ok((w_lo, w_hi))
}

/// The sweep's frequencies: 50 a decade over `[w_lo, w_hi]`, closer where the delayed part
/// matters so that the delay turns it at most 0.5 rad a step, with `extra` merged in.
fn sweep_grid(phi: &Quasi, w_lo: f64, w_hi: f64, extra: &[f64]) -> Result<Vec<f64>, NoCount> {
    let ratio = 10f64.powf(1.0 / 50.0);
    let mut g = vec![w_lo];
    let mut w = w_lo;
    while w < w_hi {
        let mut next = w * ratio;
        if phi.tau > 0.0 {
            let (sa, sb) = phi.sizes(w);
            if sb * DOMINANCE > sa {
                next = next.min(w + 0.5 / phi.tau);
            }
        }
        w = next.min(w_hi);
        g.push(w);
        if g.len() > MAX_EVALS / 4 {
            return Err(NoCount::TooMuchWork(format!(
                "the delay of {} s turns the loop more than {} times below {w_hi:.3e} rad/s",
                phi.tau,
                MAX_EVALS / 4
            )));
        }
    }
    g.extend(extra.iter().copied().filter(|&x| x > w_lo && x < w_hi));
    g.sort_by(f64::total_cmp);
    g.dedup();
    Ok(g)
}

/// The change of `arg Phi` from `a` to `b`, subdivided (at the geometric middle) until each part
/// turns less than [`MAX_TURN`] and agrees with its two halves.
fn turn(
    phi: &Quasi,
    a: (f64, Complex64),
    b: (f64, Complex64),
    depth: u32,
    budget: &mut usize,
) -> Result<f64, NoCount> {
    let m = (a.0 * b.0).sqrt();
    if *budget == 0 {
        return Err(NoCount::TooMuchWork(format!(
            "more than {MAX_EVALS} evaluations"
        )));
    }
    *budget -= 1;
    let fm = phi.eval(m);
    let (sa, sb) = phi.sizes(m);
    if fm.norm() <= 1e-13 * (sa + sb) {
        return Err(NoCount::OnAxis(m));
    }
    let whole = (b.1 / a.1).arg();
    let (d1, d2) = ((fm / a.1).arg(), (b.1 / fm).arg());
    let agree = (d1 + d2 - whole).abs() < 1e-9;
    if (d1.abs() < MAX_TURN && d2.abs() < MAX_TURN && agree) || b.0 / a.0 - 1.0 < 1e-14 {
        if b.0 / a.0 - 1.0 < 1e-14 && !(d1.abs() < MAX_TURN && d2.abs() < MAX_TURN) {
            // a zero closer to the axis than floating point resolves
            return Err(NoCount::OnAxis(m));
        }
        return Ok(d1 + d2);
    }
    let _ = depth;
    Ok(turn(phi, a, (m, fm), depth + 1, budget)? + turn(phi, (m, fm), b, depth + 1, budget)?)
}

/// Frequencies where `t(j w)` passes close to zero within `[lo, hi]` rad/s (a lightly damped pole
/// or zero of the model): each as `(w0, width)`, `w0` where `|t|` is least and `width =
/// |t(w0)| / |dt/dw(w0)|` the half-width of the feature it makes in `1/t`. Found as the local
/// minima, on 100 points a decade, of `|t|` relative to the sum of its terms' sizes (a sum of
/// powers varies slowly: near a zero it is nearly linear, so its least value is within a step of
/// a grid minimum), then golden-section search.
pub fn near_zeros(t: &[Term], lo: f64, hi: f64) -> Vec<(f64, f64)> {
    if t.len() < 2 || !(lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let n = ((hi / lo).log10() * 100.0).ceil().min(1e5) as usize;
    let w: Vec<f64> = (0..=n)
        .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
        .collect();
    let rel = |w: f64| poly(t, w).norm() / sum_abs(t, w, f64::NAN);
    let r: Vec<f64> = w.iter().map(|&x| rel(x)).collect();
    let mut out = Vec::new();
    for i in 1..n {
        if r[i] <= r[i - 1] && r[i] <= r[i + 1] && r[i] < 0.5 {
            let (mut a, mut b) = (w[i - 1].ln(), w[i + 1].ln());
            let g = (5f64.sqrt() - 1.0) / 2.0;
            let f = |x: f64| poly(t, x.exp()).norm();
            let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
            let (mut f1, mut f2) = (f(x1), f(x2));
            for _ in 0..200 {
                if b - a < 1e-15 {
                    break;
                }
                if f1 < f2 {
                    b = x2;
                    (x2, f2) = (x1, f1);
                    x1 = b - g * (b - a);
                    f1 = f(x1);
                } else {
                    a = x1;
                    (x1, f1) = (x2, f2);
                    x2 = a + g * (b - a);
                    f2 = f(x2);
                }
            }
            let w0 = (0.5 * (a + b)).exp();
            let d: Complex64 = t
                .iter()
                .map(|t| jw_pow(w0, t.order) * (t.coef * t.order / w0))
                .sum();
            let width = poly(t, w0).norm() / d.norm();
            if width.is_finite() {
                out.push((w0, width));
            }
        }
    }
    out
}

/// Frequencies to add to a grid around each feature of `near_zeros`: `w0` and `w0 +- width g` for
/// `g` from 1e-2 to 1e3 (12 points a decade), kept positive; only for features narrower than 3%
/// of their frequency (the others a grid of 100 a decade resolves).
pub fn refine_around(features: &[(f64, f64)]) -> Vec<f64> {
    let mut out = Vec::new();
    for &(w0, width) in features {
        if width >= 0.03 * w0 {
            continue;
        }
        out.push(w0);
        for k in 0..=60 {
            let g = 10f64.powf(-2.0 + k as f64 / 12.0);
            for s in [-1.0, 1.0] {
                let x = w0 + s * width * g;
                if x > 0.0 {
                    out.push(x);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(a: &[(f64, f64)], b: &[(f64, f64)], tau: f64) -> Quasi {
        let t = |v: &[(f64, f64)]| v.iter().map(|&(c, o)| Term::new(c, o)).collect();
        Quasi {
            a: t(a),
            b: t(b),
            tau,
        }
    }

    #[test]
    fn counts_known_zeros() {
        // s + 1: none; s - 1: one; s^0.5 - 1: one (s = 1); s^0.5 + 1: none on the principal sheet
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 1.0), (1.0, 0.0)], &[], 0.0), 1.0, &[]),
            Ok(0)
        );
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 1.0), (-1.0, 0.0)], &[], 0.0), 1.0, &[]),
            Ok(1)
        );
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 0.5), (-1.0, 0.0)], &[], 0.0), 1.0, &[]),
            Ok(1)
        );
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 0.5), (1.0, 0.0)], &[], 0.0), 1.0, &[]),
            Ok(0)
        );
        // (s - 1)(s^2 - 0.2 s + 100): three, the pair lightly unstable
        let p = product(
            &[Term::new(1.0, 1.0), Term::new(-1.0, 0.0)],
            &[
                Term::new(1.0, 2.0),
                Term::new(-0.2, 1.0),
                Term::new(100.0, 0.0),
            ],
        );
        assert_eq!(
            rhp_zeros(
                &Quasi {
                    a: p,
                    b: vec![],
                    tau: 0.0
                },
                1.0,
                &[]
            ),
            Ok(3)
        );
        // s + 1 + 3 e^(-s): the delayed loop 3 e^(-s)/(s + 1) is unstable (|L| > 1 at -180 deg)
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 1.0), (1.0, 0.0)], &[(3.0, 0.0)], 1.0), 1.0, &[]),
            Ok(2)
        );
        // s + 1 + (0.5 s + 3) e^(-s): a feed-through of 0.5, unstable like the one above; without
        // the delay, 1.5 s + 4: stable
        assert_eq!(
            rhp_zeros(
                &q(&[(1.0, 1.0), (1.0, 0.0)], &[(0.5, 1.0), (3.0, 0.0)], 1.0),
                1.0,
                &[]
            ),
            Ok(2)
        );
        assert_eq!(
            rhp_zeros(
                &q(&[(1.0, 1.0), (1.0, 0.0)], &[(0.5, 1.0), (3.0, 0.0)], 0.0),
                1.0,
                &[]
            ),
            Ok(0)
        );
        // s + 1 + 0.5 e^(-s): stable
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 1.0), (1.0, 0.0)], &[(0.5, 0.0)], 1.0), 1.0, &[]),
            Ok(0)
        );
        // s^2 + 1: on the axis; s (s + 1): the zero at the origin is left out, s (s - 1) has one
        assert!(matches!(
            rhp_zeros(&q(&[(1.0, 2.0), (1.0, 0.0)], &[], 0.0), 0.3, &[]),
            Err(NoCount::OnAxis(_))
        ));
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 2.0), (1.0, 1.0)], &[], 0.0), 1.0, &[]),
            Ok(0)
        );
        assert_eq!(
            rhp_zeros(&q(&[(1.0, 2.0), (-1.0, 1.0)], &[], 0.0), 1.0, &[]),
            Ok(1)
        );
    }

    #[test]
    fn a_narrow_resonance_is_located() {
        let t = [
            Term::new(1.0, 2.0),
            Term::new(0.001, 1.0),
            Term::new(1e4, 0.0),
        ];
        let f = near_zeros(&t, 1.0, 1e4);
        assert_eq!(f.len(), 1, "{f:?}");
        assert!((f[0].0 - 100.0).abs() < 1e-6, "{f:?}");
        assert!((f[0].1 - 0.0005).abs() < 1e-6, "{f:?}");
    }
}
