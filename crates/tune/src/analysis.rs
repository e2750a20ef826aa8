//! The loop `L(s) = C(s) P(s)` analysed: crossovers, margins, the sensitivity peak, and the
//! Nyquist criterion (the argument principle on the D contour, indented around the origin).

use crate::controller::Controller;
use crate::plant::Plant;
use num_complex::Complex64;
use serde::Serialize;
use std::f64::consts::PI;

/// What a designed loop achieves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopMetrics {
    /// The gain crossover in rad/s (`|L(j wc)| = 1`; the lowest one when there are several).
    pub wc: f64,
    /// The phase margin at `wc` in degrees, `180 + arg L(j wc)`.
    pub pm_deg: f64,
    /// How many times `|L|` crosses 1.
    pub crossovers: usize,
    /// The smallest phase margin over every gain crossover, degrees.
    pub pm_min_deg: f64,
    /// The gain margin in dB at the phase crossovers (`arg L = -180 deg`); `None` (infinite) when
    /// `L` never crosses the negative real axis where it matters.
    pub gm_db: Option<f64>,
    /// The sensitivity peak `Ms = max |1/(1+L(j w))|`.
    pub ms: f64,
    /// The frequency of the sensitivity peak, rad/s.
    pub ms_omega: f64,
    /// The phase slope at `wc`, `d arg L / d ln omega` (rad): 0 for a flat phase.
    pub phase_slope: f64,
    /// The number of closed-loop poles in the right half-plane by the Nyquist criterion (0:
    /// stable), assuming a stable model.
    pub unstable_poles: i64,
}

/// `L(j omega)`.
pub fn loop_response(p: &Plant, c: &Controller, omega: f64) -> Complex64 {
    c.freq_response(omega) * p.freq_response(omega)
}

/// `d arg L / d ln omega` at omega: `Im(C'/C) + Im(P'/P)` (analytic derivatives).
pub fn phase_slope(p: &Plant, c: &Controller, omega: f64) -> f64 {
    (c.dlog_omega(omega) / c.freq_response(omega)).im + p.dlog(omega).im
}

/// The frequency grid of the analysis: `per_decade` points per decade over
/// `[wc 1e-6, wc 1e5]`.
fn grid(wc: f64, per_decade: usize) -> Vec<f64> {
    let (lo, hi) = ((wc * 1e-6).ln(), (wc * 1e5).ln());
    let n = (11.0 * per_decade as f64) as usize;
    (0..=n)
        .map(|i| (lo + (hi - lo) * i as f64 / n as f64).exp())
        .collect()
}

/// Bisection in `ln omega` of where the predicate `above` changes between `a` and `b`.
fn bisect_log(mut a: f64, mut b: f64, above: impl Fn(f64) -> bool) -> f64 {
    let fa0 = above(a);
    for _ in 0..80 {
        let m = (a * b).sqrt();
        if above(m) == fa0 {
            a = m;
        } else {
            b = m;
        }
        if b / a - 1.0 < 1e-13 {
            break;
        }
    }
    (a * b).sqrt()
}

/// The change of `arg(1 + L)` from `w0` to `w1`, subdividing where it turns fast.
fn arg_change(p: &Plant, c: &Controller, w0: f64, w1: f64, depth: u32) -> f64 {
    let f = |w: f64| Complex64::new(1.0, 0.0) + loop_response(p, c, w);
    let d = (f(w1) / f(w0)).arg();
    if d.abs() < 0.3 || depth > 40 {
        return d;
    }
    let m = (w0 * w1).sqrt();
    arg_change(p, c, w0, m, depth + 1) + arg_change(p, c, m, w1, depth + 1)
}

/// Closed-loop poles in the right half-plane by the Nyquist criterion. On the D contour (up the
/// imaginary axis, around the origin on the right by `s = eps e^(j theta)`, closed at infinity
/// where a strictly proper `L` vanishes), the change of `arg(1 + L)` is
/// `2 Delta_+ - n pi`, with `Delta_+` its change from `eps` to infinity along `j omega` and
/// `L ~ K s^-n` near the origin. With no open-loop pole in the right half-plane (a stable model;
/// the controller's only pole is at the origin) the closed loop has `-total / 2 pi` of them.
fn nyquist_unstable(p: &Plant, c: &Controller, omega: &[f64]) -> i64 {
    let mut delta = 0.0;
    for w in omega.windows(2) {
        delta += arg_change(p, c, w[0], w[1], 0);
    }
    let n = p.low_order() + if c.ki != 0.0 { c.lambda } else { 0.0 };
    let total = 2.0 * delta - n.max(0.0) * PI;
    (-total / (2.0 * PI)).round() as i64
}

/// The analysis of `L = C P` around the intended crossover `wc_design` (rad/s).
pub fn analyse(p: &Plant, c: &Controller, wc_design: f64) -> LoopMetrics {
    let omega = grid(wc_design, 200);
    let l: Vec<Complex64> = omega.iter().map(|&w| loop_response(p, c, w)).collect();
    let mag = |w: f64| loop_response(p, c, w).norm() >= 1.0;
    let mut cross = Vec::new();
    let mut gm: Option<f64> = None;
    let (mut ms, mut ms_i) = (0.0, 0);
    for i in 0..omega.len() {
        let s = 1.0 / (Complex64::new(1.0, 0.0) + l[i]).norm();
        if s > ms {
            (ms, ms_i) = (s, i);
        }
        if i == 0 {
            continue;
        }
        let (a, b) = (l[i - 1], l[i]);
        if (a.norm() >= 1.0) != (b.norm() >= 1.0) {
            cross.push(bisect_log(omega[i - 1], omega[i], mag));
        }
        // the negative real axis: Im changes sign where Re < 0
        if a.im * b.im <= 0.0 && (a.re < 0.0 || b.re < 0.0) && a.im != b.im {
            let w = bisect_log(omega[i - 1], omega[i], |w| loop_response(p, c, w).im > 0.0);
            let lw = loop_response(p, c, w);
            if lw.re < 0.0 {
                let g = -20.0 * lw.norm().log10();
                gm = Some(gm.map_or(g, |x: f64| x.min(g)));
            }
        }
    }
    // refine the sensitivity peak by golden section around the best sample
    let (lo, hi) = (
        omega[ms_i.saturating_sub(1)],
        omega[(ms_i + 1).min(omega.len() - 1)],
    );
    let sens = |w: f64| 1.0 / (Complex64::new(1.0, 0.0) + loop_response(p, c, w)).norm();
    let (ms_omega, ms_ref) = golden_max(lo.ln(), hi.ln(), |x| sens(x.exp()));
    if ms_ref > ms {
        ms = ms_ref;
    }
    let pm = |w: f64| 180.0 + loop_response(p, c, w).arg().to_degrees();
    let wrap = |d: f64| {
        let mut d = d;
        while d > 180.0 {
            d -= 360.0;
        }
        while d <= -180.0 {
            d += 360.0;
        }
        d
    };
    let wc = cross.first().copied().unwrap_or(f64::NAN);
    let pm_min = cross
        .iter()
        .map(|&w| wrap(pm(w)))
        .fold(f64::INFINITY, f64::min);
    LoopMetrics {
        wc,
        pm_deg: wrap(pm(wc)),
        crossovers: cross.len(),
        pm_min_deg: pm_min,
        gm_db: gm,
        ms,
        ms_omega: ms_omega.exp(),
        phase_slope: phase_slope(p, c, wc),
        unstable_poles: nyquist_unstable(p, c, &omega),
    }
}

fn golden_max(mut a: f64, mut b: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..60 {
        if f1 > f2 {
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
    if f1 > f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// `|T(j omega)| = |L/(1+L)|`, the complementary sensitivity, in dB.
pub fn t_db(p: &Plant, c: &Controller, omega: f64) -> f64 {
    let l = loop_response(p, c, omega);
    20.0 * (l / (Complex64::new(1.0, 0.0) + l)).norm().log10()
}

/// `|S(j omega)| = |1/(1+L)|`, the sensitivity, in dB.
pub fn s_db(p: &Plant, c: &Controller, omega: f64) -> f64 {
    let l = loop_response(p, c, omega);
    -20.0 * (Complex64::new(1.0, 0.0) + l).norm().log10()
}
