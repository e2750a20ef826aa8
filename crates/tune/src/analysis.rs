//! The loop `L(s) = C(s) P(s)` analysed: crossovers, margins and the sensitivity peak on a grid
//! refined around every lightly damped pole and zero, and the closed loop's stability from its
//! characteristic function ([`crate::argument`]).

use crate::argument::{near_zeros, product, refine_around, rhp_zeros, NoCount, Quasi};
use crate::controller::Controller;
use crate::plant::Plant;
use fracsim::Term;
use num_complex::Complex64;
use serde::Serialize;

/// What a designed loop achieves.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopMetrics {
    /// The gain crossover in rad/s (`|L(j wc)| = 1`; the lowest one when there are several).
    pub wc: f64,
    /// The phase margin at `wc` in degrees, `180 + arg L(j wc)`.
    pub pm_deg: f64,
    /// How many times `|L|` crosses 1.
    pub crossovers: usize,
    /// Every gain crossover, rad/s, in increasing order.
    pub crossover_omegas: Vec<f64>,
    /// The smallest phase margin over every gain crossover, degrees.
    pub pm_min_deg: f64,
    /// The gain margin in dB: how much the loop gain may rise before the closed loop turns
    /// unstable (`-20 log10 |L|` at the phase crossovers where `|L| < 1`); `None` (infinite)
    /// when `L` never crosses the negative real axis inside the unit circle.
    pub gm_db: Option<f64>,
    /// The lower gain margin in dB: how much the loop gain may fall before the closed loop turns
    /// unstable (`20 log10 |L|` at the phase crossovers where `|L| > 1`, a conditionally stable
    /// loop); `None` (infinite) when there are none.
    pub gm_low_db: Option<f64>,
    /// The sensitivity peak `Ms = max |1/(1+L(j w))|`.
    pub ms: f64,
    /// The frequency of the sensitivity peak, rad/s.
    pub ms_omega: f64,
    /// The phase slope at `wc`, `d arg L / d ln omega` (rad): 0 for a flat phase.
    pub phase_slope: f64,
    /// The number of closed-loop poles in the right half-plane (0: stable), the zeros of the
    /// characteristic function `D_c D_p + N_c N_p e^(-s tau)` by the argument principle
    /// ([`crate::argument`]); `-1` when they could not be counted (see `stability_note`).
    pub unstable_poles: i64,
    /// The number of the model's own poles in the right half-plane (the zeros of its
    /// denominator, counted the same way); `-1` when not counted.
    pub plant_unstable_poles: i64,
    /// Why the closed loop's poles could not be counted (a pole on the imaginary axis, a loop
    /// that does not roll off), when they could not.
    pub stability_note: Option<String>,
}

impl LoopMetrics {
    /// The metrics of a loop `l` (its frequency response at omega rad/s) from its sweep: the
    /// first crossover, the margins there and over every crossover, the gain margins and the
    /// sensitivity peak, with the phase slope at the crossover (`phase_slope(wc)`), the closed
    /// loop's count of unstable poles (or why not counted) and the model's. Both analyses, the
    /// continuous ([`analyse`]) and the sampled ([`crate::sampled`]), build their metrics here.
    pub(crate) fn of_sweep(
        sw: Sweep,
        l: impl Fn(f64) -> Complex64,
        phase_slope: impl FnOnce(f64) -> f64,
        (unstable_poles, stability_note): (i64, Option<String>),
        plant_unstable_poles: i64,
    ) -> Self {
        let pm = |w: f64| wrap_deg(180.0 + l(w).arg().to_degrees());
        let wc = sw.cross.first().copied().unwrap_or(f64::NAN);
        let pm_min_deg = sw
            .cross
            .iter()
            .map(|&w| pm(w))
            .fold(f64::INFINITY, f64::min);
        Self {
            wc,
            pm_deg: pm(wc),
            crossovers: sw.cross.len(),
            crossover_omegas: sw.cross,
            pm_min_deg,
            gm_db: sw.gm,
            gm_low_db: sw.gm_low,
            ms: sw.ms,
            ms_omega: sw.ms_omega,
            phase_slope: phase_slope(wc),
            unstable_poles,
            plant_unstable_poles,
            stability_note,
        }
    }
}

/// `L(j omega)`.
pub fn loop_response(p: &Plant, c: &Controller, omega: f64) -> Complex64 {
    c.freq_response(omega) * p.freq_response(omega)
}

/// `d arg L / d ln omega` at omega: `Im(C'/C) + Im(P'/P)` (analytic derivatives).
pub fn phase_slope(p: &Plant, c: &Controller, omega: f64) -> f64 {
    (c.dlog_omega(omega) / c.freq_response(omega)).im + p.dlog(omega).im
}

/// The controller's numerator and denominator terms: `(kd s^(lambda+mu) + kp s^lambda + ki) /
/// s^lambda`, or `(kd s^mu + kp) / 1` without integral action.
pub fn controller_terms(c: &Controller) -> (Vec<Term>, Vec<Term>) {
    let keep = |v: Vec<Term>| v.into_iter().filter(|t| t.coef != 0.0).collect::<Vec<_>>();
    if c.ki != 0.0 {
        (
            keep(vec![
                Term::new(c.kd, c.lambda + c.mu),
                Term::new(c.kp, c.lambda),
                Term::new(c.ki, 0.0),
            ]),
            vec![Term::new(1.0, c.lambda)],
        )
    } else {
        (
            keep(vec![Term::new(c.kd, c.mu), Term::new(c.kp, 0.0)]),
            vec![Term::new(1.0, 0.0)],
        )
    }
}

/// The closed loop's characteristic function `D_c D_p + N_c N_p e^(-s tau)` (its zeros are the
/// closed loop's poles), `tau` the plant's delay with the hold's.
pub fn characteristic(p: &Plant, c: &Controller) -> Quasi {
    let (nc, dc) = controller_terms(c);
    Quasi {
        a: product(&dc, &p.tf.den),
        b: product(&nc, &p.tf.num),
        tau: p.delay(),
    }
}

/// The closed loop's poles in the right half-plane (see [`crate::argument`]).
///
/// # Errors
/// [`NoCount`]: a closed-loop pole on the imaginary axis (or at the origin), a loop that does
/// not roll off, too much work.
pub fn closed_loop_unstable(
    p: &Plant,
    c: &Controller,
    hint: f64,
    extra: &[f64],
) -> Result<u32, NoCount> {
    let phi = characteristic(p, c);
    if phi.lowest().0 > 1e-12 {
        return Err(NoCount::OnAxis(0.0));
    }
    rhp_zeros(&phi, hint, extra)
}

/// The model's poles in the right half-plane (its denominator's zeros; those at the origin, an
/// integrator's, are not counted).
///
/// # Errors
/// [`NoCount`] (a pole on the imaginary axis away from the origin, too much work).
pub fn plant_unstable(p: &Plant, hint: f64) -> Result<u32, NoCount> {
    let d = Quasi {
        a: p.tf.den.clone(),
        b: Vec::new(),
        tau: 0.0,
    };
    let extra = refine_around(&near_zeros(&p.tf.den, hint * 1e-7, hint * 1e6));
    rhp_zeros(&d, hint, &extra)
}

/// The frequency grid of the analysis: 200 points a decade over `[wc 1e-6, wc 1e5]`, refined
/// around every lightly damped pole or zero of the model and zero of the controller found in
/// `[wc 1e-7, wc 1e6]` ([`near_zeros`]): a resonance narrower than the grid's step is resolved.
pub fn loop_grid(p: &Plant, c: &Controller, wc: f64) -> Vec<f64> {
    let (lo, hi) = ((wc * 1e-6).ln(), (wc * 1e5).ln());
    let n = 11 * 200;
    let mut g: Vec<f64> = (0..=n)
        .map(|i| (lo + (hi - lo) * i as f64 / n as f64).exp())
        .collect();
    let (first, last) = (g[0], g[n]);
    g.extend(
        resonances(p, c, wc)
            .into_iter()
            .filter(|&w| w >= first && w <= last),
    );
    g.sort_by(f64::total_cmp);
    g.dedup();
    g
}

/// The frequencies [`refine_around`] adds for the model's and the controller's narrow features.
pub fn resonances(p: &Plant, c: &Controller, wc: f64) -> Vec<f64> {
    let (nc, _) = controller_terms(c);
    let (lo, hi) = (wc * 1e-7, wc * 1e6);
    let mut f = near_zeros(&p.tf.den, lo, hi);
    f.extend(near_zeros(&p.tf.num, lo, hi));
    f.extend(near_zeros(&nc, lo, hi));
    refine_around(&f)
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

/// The crossovers, the gain margins and the sensitivity peak of the loop `l` sampled on the
/// sorted grid `omega` (the peak refined by golden section around every local maximum within
/// a third of the largest).
pub(crate) struct Sweep {
    pub cross: Vec<f64>,
    pub gm: Option<f64>,
    pub gm_low: Option<f64>,
    pub ms: f64,
    pub ms_omega: f64,
}

pub(crate) fn sweep(omega: &[f64], l: impl Fn(f64) -> Complex64) -> Sweep {
    let vals: Vec<Complex64> = omega.iter().map(|&w| l(w)).collect();
    let sens = |v: Complex64| 1.0 / (Complex64::new(1.0, 0.0) + v).norm();
    let mut cross = Vec::new();
    let (mut gm, mut gm_low): (Option<f64>, Option<f64>) = (None, None);
    for i in 1..omega.len() {
        let (a, b) = (vals[i - 1], vals[i]);
        if (a.norm() >= 1.0) != (b.norm() >= 1.0) {
            cross.push(bisect_log(omega[i - 1], omega[i], |w| l(w).norm() >= 1.0));
        }
        // the negative real axis: Im changes sign where Re < 0
        if a.im * b.im <= 0.0 && (a.re < 0.0 || b.re < 0.0) && a.im != b.im {
            let w = bisect_log(omega[i - 1], omega[i], |w| l(w).im > 0.0);
            let lw = l(w);
            if lw.re < 0.0 {
                let g = -20.0 * lw.norm().log10();
                if g >= 0.0 {
                    gm = Some(gm.map_or(g, |x: f64| x.min(g)));
                } else {
                    gm_low = Some(gm_low.map_or(-g, |x: f64| x.min(-g)));
                }
            }
        }
    }
    let s: Vec<f64> = vals.iter().map(|&v| sens(v)).collect();
    let top = s.iter().copied().fold(0.0, f64::max);
    let (mut ms, mut ms_omega) = (0.0, omega[0]);
    for i in 0..s.len() {
        let left = if i > 0 { s[i - 1] } else { f64::NEG_INFINITY };
        let right = if i + 1 < s.len() {
            s[i + 1]
        } else {
            f64::NEG_INFINITY
        };
        if s[i] >= left && s[i] >= right && s[i] >= top / 3.0 {
            let (lo, hi) = (
                omega[i.saturating_sub(1)],
                omega[(i + 1).min(omega.len() - 1)],
            );
            let (x, v) = golden_max(lo.ln(), hi.ln(), |x| sens(l(x.exp())));
            let (x, v) = if v > s[i] {
                (x.exp(), v)
            } else {
                (omega[i], s[i])
            };
            if v > ms {
                (ms, ms_omega) = (v, x);
            }
        }
    }
    Sweep {
        cross,
        gm,
        gm_low,
        ms,
        ms_omega,
    }
}

/// `d` wrapped into `(-180, 180]` degrees.
pub(crate) fn wrap_deg(d: f64) -> f64 {
    let mut d = d % 360.0;
    if d > 180.0 {
        d -= 360.0;
    }
    if d <= -180.0 {
        d += 360.0;
    }
    d
}

/// The analysis of `L = C P` around the intended crossover `wc_design` (rad/s).
pub fn analyse(p: &Plant, c: &Controller, wc_design: f64) -> LoopMetrics {
    let extra = resonances(p, c, wc_design);
    let omega = loop_grid(p, c, wc_design);
    let sw = sweep(&omega, |w| loop_response(p, c, w));
    let stability = match closed_loop_unstable(p, c, wc_design, &extra) {
        Ok(n) => (i64::from(n), None),
        Err(e) => (-1, Some(e.to_string())),
    };
    LoopMetrics::of_sweep(
        sw,
        |w| loop_response(p, c, w),
        |wc| phase_slope(p, c, wc),
        stability,
        plant_unstable(p, wc_design).map_or(-1, i64::from),
    )
}

pub(crate) fn golden_max(mut a: f64, mut b: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_of_a_sweep_take_the_first_crossover_and_the_worst_margin() {
        // |L| = 1 everywhere, arg L = -(90 + 10 w) deg: pm = 80 deg at w = 1, 60 deg at w = 3
        let l = |w: f64| Complex64::from_polar(1.0, -(90.0 + 10.0 * w).to_radians());
        let sw = Sweep {
            cross: vec![1.0, 3.0],
            gm: Some(6.0),
            gm_low: None,
            ms: 1.5,
            ms_omega: 2.0,
        };
        let m = LoopMetrics::of_sweep(sw, l, |wc| 2.0 * wc, (0, None), 1);
        assert_eq!(
            (m.wc, m.crossovers, m.crossover_omegas.clone()),
            (1.0, 2, vec![1.0, 3.0])
        );
        assert!((m.pm_deg - 80.0).abs() < 1e-12, "{m:?}");
        assert!((m.pm_min_deg - 60.0).abs() < 1e-12, "{m:?}");
        assert_eq!(
            (m.phase_slope, m.gm_db, m.gm_low_db),
            (2.0, Some(6.0), None)
        );
        assert_eq!((m.ms, m.ms_omega), (1.5, 2.0));
        assert_eq!((m.unstable_poles, m.plant_unstable_poles), (0, 1));
    }
}
