//! The general structure's starts: the record's frequency response fitted for each size by
//! Levy's weighted least squares with Sanathanan-Koerner iterations ([`crate::levy`]), made
//! stable, and ranked by a frequency-domain information criterion ([`criterion`]).
//!
//! - The response ([`frf`]): periodic averages when the input is periodic
//!   ([`crate::oe::init::periodic_frf`], inverse-variance weights), Welch's H1 estimate otherwise
//!   (coherence-chosen frequencies, inverse-variance weights); both with the hold divided out.
//!   When Welch's has fewer than [`MIN_WELCH_POINTS`] frequencies, or none, an ARX model's
//!   response ([`arx_frf`]).
//! - A free integrator is fitted as `G(s) = H(s) s` on the response times `j w` (weights divided
//!   by `w^2`, the same error), its start then `N/(s D)`.
//! - Orders: `q = 1` (integer), and for denominators up to [`super::MAX_DEN_FRACTIONAL`] the
//!   grid `0.1, 0.15, ..., 0.95` refined by steps of 0.01 around the best (within `[0.1, 1)`,
//!   [`refined`]), each screened with
//!   [`SK_SCREEN`] Sanathanan-Koerner iterations; the integer order and the best fractional one
//!   iterated to convergence ([`fit_size`]).
//! - Stability: an integer-order start's poles in the right half-plane are reflected into the left
//!   one (`p -> -conj(p)`: the same `|D(jw)|`) and the numerator refitted by weighted least
//!   squares with that denominator; a fractional start with a pole outside the stable sector is
//!   left out.
//! - Sizes: only those within the record's parameter budget ([`Budget`]).
//! - Delay ([`ranked_delayed`]): whole-sample input delays `d = 1 ..` [`MAX_DELAY_SAMPLES`] are
//!   tried on the response advanced by them (`H(jw) e^(j w d dt)`), each with the sizes the
//!   criterion ranks first without a delay and the smallest ones (screened fits only,
//!   [`Sk::Screened`]); the delay whose best fit has
//!   the lowest criterion (the delay one parameter more) is kept when it beats every fit without
//!   one, and the sizes are ranked again on that response.

use super::{Budget, GeneralStart, Size, MAX_DEN_FRACTIONAL, MAX_DEN_INTEGER};
use crate::levy;
use crate::oe::init::{periodic_frf, Frf};
use crate::{Error, Result};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Sanathanan-Koerner iterations of each Levy fit (they stop sooner once converged).
const SK_ITERATIONS: usize = 20;

/// Which estimate a response is ([`frf`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// Periodic averages at the harmonics of a periodic input.
    Periodic,
    /// Welch's H1 estimate.
    Welch,
    /// An ARX model's response ([`arx_frf`]).
    Arx,
}

/// The frequency response of deviations `u`, `y` sampled every `dt` seconds, with how it was made
/// and which estimate it is.
///
/// # Errors
/// [`Error::NotEnoughData`] when neither estimate can be made.
pub fn frf(u: &[f64], y: &[f64], dt: f64) -> Result<(Frf, String, Source)> {
    let arx = |why: &Error| arx_frf(u, y, dt, why).map(|(f, how)| (f, how, Source::Arx));
    match periodic_frf(u, y, dt) {
        Ok(f) => {
            let how = format!(
                "the response at {} harmonics of a periodic input ({} period(s) of {} samples \
                 averaged)",
                f.omega.len(),
                f.periods_averaged,
                f.period.unwrap_or(0)
            );
            Ok((f, how, Source::Periodic))
        }
        Err(_) => match crate::oe::init::welch::h1(u, y, dt) {
            Ok((f, how)) if f.omega.len() < MIN_WELCH_POINTS => {
                let few = Error::NotEnoughData(format!(
                    "{} frequencies only in Welch's estimate, {how}",
                    f.omega.len()
                ));
                arx(&few).or(Ok((f, how, Source::Welch)))
            }
            Ok((f, how)) => Ok((f, how, Source::Welch)),
            Err(e) => arx(&e),
        },
    }
}

/// The fewest frequencies of Welch's estimate the sizes are ranked on; with fewer (a record of
/// a few steps, a short one) the ARX model's response ([`arx_frf`]) is used, when it can be
/// made.
pub const MIN_WELCH_POINTS: usize = 16;

/// ARX orders of the fallback response ([`arx_frf`]).
const ARX_ORDER: usize = 6;

/// The response of an ARX model `A(q) y = B(q) u + c` (orders [`ARX_ORDER`], `B` from lag 0: a
/// feed-through) fitted by least squares, at 100 log-spaced frequencies from one period over the
/// record to a quarter of the Nyquist frequency, the hold divided out, weights 1: the start of a
/// record Welch's estimate cannot be made from (a step test, a short record), `why` its reason.
///
/// # Errors
/// [`Error::NotEnoughData`] for fewer than `10 (2 n + 2)` samples
/// ([`super::SAMPLES_PER_PARAM`] a coefficient) or a singular regression.
pub fn arx_frf(u: &[f64], y: &[f64], dt: f64, why: &Error) -> Result<(Frf, String)> {
    let n = u.len().min(y.len());
    let na = ARX_ORDER.min(n / 60).max(1);
    let cols = 2 * na + 2;
    if n < super::SAMPLES_PER_PARAM * cols {
        return Err(Error::NotEnoughData(format!(
            "{n} samples: too few for a response ({})",
            why.detail()
        )));
    }
    let rows = n - na;
    let mut x = DMatrix::<f64>::zeros(rows, cols);
    let mut rhs = DVector::<f64>::zeros(rows);
    for (r, k) in (na..n).enumerate() {
        for i in 1..=na {
            x[(r, i - 1)] = -y[k - i];
        }
        for j in 0..=na {
            x[(r, na + j)] = u[k - j];
        }
        x[(r, cols - 1)] = 1.0;
        rhs[r] = y[k];
    }
    let mut scale = vec![1.0; cols];
    for (c, sc) in scale.iter_mut().enumerate() {
        let nrm = x.column(c).norm();
        if nrm > 0.0 && nrm.is_finite() {
            *sc = nrm;
            x.column_mut(c).scale_mut(1.0 / nrm);
        }
    }
    let bad = || Error::NotEnoughData(format!("no ARX response ({})", why.detail()));
    if x.iter().chain(rhs.iter()).any(|v| !v.is_finite()) {
        return Err(bad());
    }
    let theta = crate::linalg::svd_solve(&x, rhs.as_slice(), 1e-12).ok_or_else(bad)?;
    let th: Vec<f64> = theta.iter().zip(&scale).map(|(v, s)| v / s).collect();
    let (w_lo, w_hi) = (
        2.0 * std::f64::consts::PI / (n as f64 * dt),
        0.25 * std::f64::consts::PI / dt,
    );
    let omega: Vec<f64> = (0..100)
        .map(|i| w_lo * (w_hi / w_lo).powf(i as f64 / 99.0))
        .collect();
    let h: Vec<Complex64> = omega
        .iter()
        .map(|&w| {
            // B(z^-1) = sum_j b_j z^-j, A(z^-1) = 1 + sum_i a_i z^-i
            let zi = Complex64::from_polar(1.0, -w * dt);
            let (mut a, mut b, mut p) = (
                Complex64::new(1.0, 0.0),
                Complex64::new(0.0, 0.0),
                Complex64::new(1.0, 0.0),
            );
            for j in 0..=na {
                if j > 0 {
                    a += th[j - 1] * p;
                }
                b += th[na + j] * p;
                p *= zi;
            }
            b / a / crate::hold::zoh(w, dt)
        })
        .collect();
    if h.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
        return Err(bad());
    }
    let how = format!(
        "the response of an ARX({na},{}) model fitted by least squares ({})",
        na + 1,
        why.detail()
    );
    Ok((
        Frf {
            weight: vec![1.0; omega.len()],
            omega,
            h,
            period: None,
            periods_averaged: 0,
            periods_available: 0,
        },
        how,
    ))
}

/// The information criterion a start is ranked by: `2F ln(e) + k ln(2F)` for a weighted relative
/// error `e` on `F` complex points (`2F` real values) with `k` coefficients (Schwarz's criterion
/// for the frequency-domain least squares, its weights the inverse variances).
pub fn criterion(err: f64, points: usize, k: usize) -> f64 {
    let n = 2.0 * points as f64;
    n * err.max(1e-300).ln() + k as f64 * n.ln()
}

/// Whether the response calls for a free integrator: over its lowest decade (at least 4 points)
/// the magnitude falls with frequency at least as `w^-0.7` and the phase lags by more than 60°.
pub fn calls_for_integrator(frf: &Frf) -> bool {
    let Some(&w0) = frf.omega.first() else {
        return false;
    };
    let low: Vec<usize> = (0..frf.omega.len())
        .filter(|&i| frf.omega[i] <= 10.0 * w0)
        .collect();
    if low.len() < 4 {
        return false;
    }
    // least-squares slope of ln|H| against ln w
    let xs: Vec<f64> = low.iter().map(|&i| frf.omega[i].ln()).collect();
    let ys: Vec<f64> = low
        .iter()
        .map(|&i| frf.h[i].norm().max(1e-300).ln())
        .collect();
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    let slope = sxy / sxx.max(f64::MIN_POSITIVE);
    let lag = frf.h[low[0]].arg().abs();
    slope <= -0.7 && lag > 60f64.to_radians()
}

/// The orders searched for a denominator of degree `n`.
fn orders(n: usize) -> Vec<f64> {
    let mut qs = vec![1.0];
    if (1..=MAX_DEN_FRACTIONAL).contains(&n) {
        qs.extend((2..=19).map(|i| i as f64 * 0.05));
    }
    qs
}

/// The orders within 0.04 of the best grid order `q0`, by steps of 0.01, in the grid's range
/// (from its lowest fractional order `q_min` up to, not including, 1): an order below the grid's
/// makes every term of a size nearly flat, its cells' poles and zeros nearly cancel, and the
/// modal form's roots crowd them (the motor/generator record's general 4/4 at q = 0.06 cost
/// 1.6 s of CPU, at q = 0.12 1.2 s, the held-out fit as good).
fn refined(q0: f64, q_min: f64) -> Vec<f64> {
    (-4..=4)
        .filter(|&i| i != 0)
        .map(|i| q0 + f64::from(i) * 0.01)
        .filter(|&q| q >= q_min - 1e-12 && q < 1.0)
        .collect()
}

/// The response the Levy fit sees: `H` itself, or `H j w` (with weights over `w^2`) for a
/// structure with a free integrator.
fn target(frf: &Frf, integrator: bool) -> (Vec<Complex64>, Vec<f64>) {
    if !integrator {
        return (frf.h.clone(), frf.weight.clone());
    }
    let h = frf
        .omega
        .iter()
        .zip(&frf.h)
        .map(|(&w, &h)| h * Complex64::new(0.0, w))
        .collect();
    let wt = frf
        .omega
        .iter()
        .zip(&frf.weight)
        .map(|(&w, &v)| v / (w * w))
        .collect();
    (h, wt)
}

/// The best stable start of `size` with or without a free integrator on `frf`: the best order of
/// the grid by the Levy fit's weighted error, refined, then made stable ([`stable`]); `None` when
/// no order gives a stable start.
///
/// The grid and its refinement are screened with [`SK_SCREEN`] Sanathanan-Koerner iterations;
/// only the two orders kept (the integer one and the best fractional one) are fitted with the
/// [`Sk`] iterations asked for, so a size costs about a third of the solves of fitting every
/// order to convergence. The screened error ranks the orders of one size (they differ by the
/// order alone); the criterion that ranks sizes is the kept fits'.
pub fn fit_size(frf: &Frf, size: Size, integrator: bool, sk: Sk) -> Option<GeneralStart> {
    let (h, wt) = target(frf, integrator);
    let unknowns = size.num + 1 + size.den;
    if frf.omega.len() < unknowns + 1 {
        return None;
    }
    type Raw = (f64, Vec<f64>, Vec<f64>, f64);
    let visit = |qs: &[f64], sk_iterations: usize, raw: &mut Vec<Raw>| {
        let _ = levy::levy_orders(
            &frf.omega,
            &h,
            (size.num, size.den),
            &wt,
            sk_iterations,
            qs.iter().copied(),
            |q, b, a, e| {
                if e.is_finite() {
                    raw.push((q, b.to_vec(), a.to_vec(), e));
                }
            },
        );
    };
    let grid = orders(size.den);
    let best_frac = |raw: &[Raw]| {
        raw.iter()
            .filter(|r| r.0 < 1.0)
            .min_by(|a, b| a.3.total_cmp(&b.3))
            .cloned()
    };
    let mut screened: Vec<Raw> = vec![];
    if grid.len() > 1 {
        visit(&grid[1..], SK_SCREEN, &mut screened);
        // refine around the best fractional order
        if let Some((q0, ..)) = best_frac(&screened) {
            visit(&refined(q0, grid[1]), SK_SCREEN, &mut screened);
        }
    }
    let fractional = best_frac(&screened);
    let mut raw: Vec<Raw> = vec![];
    match sk {
        Sk::Converged => {
            let kept: Vec<f64> = [1.0].into_iter().chain(fractional.map(|r| r.0)).collect();
            visit(&kept, SK_ITERATIONS, &mut raw);
        }
        // the screened fit of the best fractional order is already the one asked for
        Sk::Screened => {
            visit(&[1.0], SK_SCREEN, &mut raw);
            raw.extend(fractional);
        }
    }
    // The integer order and the best fractional one, each made stable; the better stable one
    // is the size's start.
    raw.into_iter()
        .filter_map(|(q, b, a, _)| stable(frf, size, q, integrator, &b, &a))
        .min_by(|a, b| a.frf_error.total_cmp(&b.frf_error))
}

/// The Sanathanan-Koerner iterations of a size's kept orders ([`fit_size`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sk {
    /// To convergence ([`SK_ITERATIONS`] at most): a start that is fitted and ranked.
    Converged,
    /// [`SK_SCREEN`] only: a delay probed ([`ranked_delayed`]), whose fits serve only to compare
    /// delays.
    Screened,
}

/// Sanathanan-Koerner iterations of a screening Levy fit ([`fit_size`]): the reweighting that
/// moves the fit most is the first; two rank a size's orders as the converged fits do.
const SK_SCREEN: usize = 2;

/// The start `(b, a)` at order `q` made stable: an integer order's right-half-plane poles
/// reflected and the numerator refitted; a fractional one checked. With its error on `frf` and
/// its criterion.
fn stable(
    frf: &Frf,
    size: Size,
    q: f64,
    integrator: bool,
    b: &[f64],
    a: &[f64],
) -> Option<GeneralStart> {
    let (b, a) = if q == 1.0 {
        let (a2, moved) = reflect(a)?;
        let b2 = if moved {
            let (h, wt) = target(frf, integrator);
            refit_numerator(&frf.omega, &h, &wt, &a2, size.num)?
        } else {
            b.to_vec()
        };
        (b2, a2)
    } else {
        let tf = levy::commensurate_tf(q, b, a).ok()?;
        if levy::checks::rhp_poles(&tf.den) != levy::checks::RhpPoles::Count(0) {
            return None;
        }
        (b.to_vec(), a.to_vec())
    };
    if b.iter().chain(&a).any(|v| !v.is_finite()) {
        return None;
    }
    let mut tf = levy::commensurate_tf(q, &b, &a).ok()?;
    if integrator {
        tf.den.iter_mut().for_each(|t| t.order += 1.0);
    }
    let err = crate::oe::init::frf_error(frf, &tf);
    let k = size.num + 1 + size.den + usize::from(q != 1.0);
    Some(GeneralStart {
        size,
        q,
        integrator,
        b,
        a,
        delay_samples: 0,
        frf_error: err,
        criterion: criterion(err, frf.omega.len(), k),
    })
}

/// The roots of `1 + a_1 s + ... + a_n s^n` (companion matrix eigenvalues).
fn roots(a: &[f64]) -> Option<Vec<Complex64>> {
    let n = a.len();
    let an = *a.last()?;
    if !(an.abs() > 0.0 && an.is_finite()) {
        return None;
    }
    // monic: s^n + c_(n-1) s^(n-1) + ... + c_0, c_k = coef_k / a_n with coef_0 = 1
    let coef = |k: usize| if k == 0 { 1.0 } else { a[k - 1] };
    let mut m = DMatrix::<f64>::zeros(n, n);
    for k in 0..n {
        m[(0, k)] = -coef(n - 1 - k) / an;
        if k + 1 < n {
            m[(k + 1, k)] = 1.0;
        }
    }
    let ev = m.complex_eigenvalues();
    let out: Vec<Complex64> = ev.iter().map(|z| Complex64::new(z.re, z.im)).collect();
    out.iter()
        .all(|z| z.re.is_finite() && z.im.is_finite())
        .then_some(out)
}

/// `a` with the poles of `1 + sum a_k s^k` in the closed right half-plane reflected into the left
/// one (`p -> -conj(p)`, and a pole on the axis moved to `-1e-3 |p|`), the constant term kept 1;
/// and whether any moved.
fn reflect(a: &[f64]) -> Option<(Vec<f64>, bool)> {
    if a.is_empty() {
        return Some((vec![], false));
    }
    let rs = roots(a)?;
    if rs.iter().all(|r| r.re < 0.0) {
        return Some((a.to_vec(), false));
    }
    let moved: Vec<Complex64> = rs
        .iter()
        .map(|&r| {
            if r.re > 0.0 {
                Complex64::new(-r.re, r.im)
            } else if r.re == 0.0 {
                Complex64::new(-1e-3 * r.norm().max(f64::MIN_POSITIVE), r.im)
            } else {
                r
            }
        })
        .collect();
    // prod (1 - s/r)
    let mut p = vec![Complex64::new(1.0, 0.0)];
    for r in &moved {
        if r.norm() == 0.0 {
            return None;
        }
        let mut next = vec![Complex64::new(0.0, 0.0); p.len() + 1];
        for (k, &c) in p.iter().enumerate() {
            next[k] += c;
            next[k + 1] -= c / r;
        }
        p = next;
    }
    Some((p[1..].iter().map(|c| c.re).collect(), true))
}

/// The numerator `b_0 .. b_m` (integer powers) minimising `sum w |H - N/D|^2` with the
/// denominator `1 + sum a_k s^k` given.
fn refit_numerator(
    omega: &[f64],
    h: &[Complex64],
    wt: &[f64],
    a: &[f64],
    m: usize,
) -> Option<Vec<f64>> {
    let f = omega.len();
    let mut x = DMatrix::<f64>::zeros(2 * f, m + 1);
    let mut rhs = DVector::<f64>::zeros(2 * f);
    for (g, ((&w, &hg), &wg)) in omega.iter().zip(h).zip(wt).enumerate() {
        let s = Complex64::new(0.0, w);
        let mut d = Complex64::new(1.0, 0.0);
        let mut sp = Complex64::new(1.0, 0.0);
        for &ak in a {
            sp *= s;
            d += ak * sp;
        }
        let sw = wg.max(0.0).sqrt();
        let mut sk = Complex64::new(1.0, 0.0);
        for k in 0..=m {
            let c = sk / d * sw;
            x[(2 * g, k)] = c.re;
            x[(2 * g + 1, k)] = c.im;
            sk *= s;
        }
        rhs[2 * g] = hg.re * sw;
        rhs[2 * g + 1] = hg.im * sw;
    }
    // column scaling to unit norm
    let mut scale = vec![1.0; m + 1];
    for (k, sc) in scale.iter_mut().enumerate() {
        let nrm = x.column(k).norm();
        if nrm > 0.0 && nrm.is_finite() {
            *sc = nrm;
            x.column_mut(k).scale_mut(1.0 / nrm);
        }
    }
    if x.iter().chain(rhs.iter()).any(|v| !v.is_finite()) {
        return None;
    }
    let sol = crate::linalg::svd_solve(&x, rhs.as_slice(), 1e-14)?;
    Some(sol.iter().zip(&scale).map(|(v, s)| v / s).collect())
}

/// The largest whole-sample input delay searched on the response ([`ranked_delayed`]).
pub const MAX_DELAY_SAMPLES: usize = 10;

/// The sizes probed at each delay beside the best ranked ones ([`ranked_delayed`]): the first
/// order, the all-pole second order and a second order with a zero.
const SMALL_SIZES: [Size; 3] = [
    Size { num: 0, den: 1 },
    Size { num: 0, den: 2 },
    Size { num: 1, den: 2 },
];

/// The best ranked starts probed at each delay ([`ranked_delayed`]).
const PROBED: usize = 3;

/// `frf` with a delay of `d` samples of `dt` removed: `H(jw) e^(j w d dt)`.
pub fn advanced(frf: &Frf, d: usize, dt: f64) -> Frf {
    let tau = d as f64 * dt;
    Frf {
        h: frf
            .omega
            .iter()
            .zip(&frf.h)
            .map(|(&w, &h)| h * Complex64::from_polar(1.0, w * tau))
            .collect(),
        ..frf.clone()
    }
}

/// [`ranked`] with the whole-sample input delay the response calls for (see the module
/// documentation; `search` false: none, the template has its own): the starts of the chosen
/// delay, each with its `delay_samples` and the delay counted in its criterion.
///
/// # Errors
/// [`Error::NotEnoughData`] when no size gives a stable start at the delay chosen.
pub fn ranked_delayed(
    frf: &Frf,
    dt: f64,
    fixed: Option<Size>,
    integrators: &[bool],
    budget: Budget,
    search: bool,
) -> Result<Vec<GeneralStart>> {
    let undelayed = ranked(frf, fixed, integrators, budget, 0);
    if !search {
        return undelayed;
    }
    let mut probes: Vec<(Size, bool)> = vec![];
    if let Ok(r) = &undelayed {
        for s in r {
            if probes.len() >= PROBED {
                break;
            }
            if !probes.contains(&(s.size, s.integrator)) {
                probes.push((s.size, s.integrator));
            }
        }
    }
    if fixed.is_none() {
        for &int in integrators {
            for size in SMALL_SIZES {
                if !probes.contains(&(size, int)) {
                    probes.push((size, int));
                }
            }
        }
    }
    let mut best = (
        undelayed
            .as_ref()
            .ok()
            .and_then(|r| r.first())
            .map_or(f64::INFINITY, |s| s.criterion),
        0,
    );
    for d in 1..=MAX_DELAY_SAMPLES {
        let f = advanced(frf, d, dt);
        for &(size, int) in &probes {
            if !budget.allows(size, int, true) {
                continue;
            }
            if let Some(s) = fit_size(&f, size, int, Sk::Screened) {
                let c = delayed(s, d, frf.omega.len()).criterion;
                if c < best.0 {
                    best = (c, d);
                }
            }
        }
    }
    match best.1 {
        0 => undelayed,
        d => ranked(&advanced(frf, d, dt), fixed, integrators, budget, d),
    }
}

/// `s` (fitted on the response advanced by `d` samples) with that delay: one parameter more in
/// its criterion when `d > 0` (`points` complex points).
fn delayed(mut s: GeneralStart, d: usize, points: usize) -> GeneralStart {
    s.delay_samples = d;
    if d > 0 {
        s.criterion += (2.0 * points as f64).ln();
    }
    s
}

/// The sizes searched: a fixed one, or every denominator degree up to [`MAX_DEN_INTEGER`] with
/// every numerator degree up to it (one more with an integrator: a feed-through beside it; and
/// with an integrator the denominator `s` alone, `(b_0 + b_1 s)/s`).
pub fn sizes(fixed: Option<Size>, integrator: bool) -> Vec<Size> {
    if let Some(s) = fixed {
        return vec![s];
    }
    let mut out = vec![];
    for den in usize::from(!integrator)..=MAX_DEN_INTEGER {
        for num in 0..=den + usize::from(integrator) {
            out.push(Size { num, den });
        }
    }
    out
}

/// Every size's best stable start on `frf` (the response advanced by `delay` samples, counted
/// in the criterion, [`delayed`]) for each choice of `integrators`, ranked by [`criterion`] (best
/// first); a size beyond the `budget` is left out unless it is the `fixed` one.
///
/// # Errors
/// [`Error::NotEnoughData`] when no size gives a stable start.
pub fn ranked(
    frf: &Frf,
    fixed: Option<Size>,
    integrators: &[bool],
    budget: Budget,
    delay: usize,
) -> Result<Vec<GeneralStart>> {
    let mut out: Vec<GeneralStart> = vec![];
    for &int in integrators {
        for size in sizes(fixed, int) {
            if fixed.is_none() && size.num > size.den + usize::from(int) {
                continue;
            }
            if fixed.is_none() && !budget.allows(size, int, delay > 0) {
                continue;
            }
            if let Some(s) = fit_size(frf, size, int, Sk::Converged) {
                out.push(delayed(s, delay, frf.omega.len()));
            }
        }
    }
    if out.is_empty() {
        let within = if budget == Budget::UNLIMITED || fixed.is_some() {
            String::new()
        } else {
            format!(
                " within the record's parameter budget ({} free parameters, {} with an \
                 integrator)",
                budget.plain, budget.integrator
            )
        };
        return Err(Error::NotEnoughData(format!(
            "no size of the general structure{within} gives a stable fit of the response at {} \
             frequencies",
            frf.omega.len()
        )));
    }
    out.sort_by(|a, b| a.criterion.total_cmp(&b.criterion));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_refined_orders_stay_in_the_grids_range() {
        let grid = orders(2);
        let (lo, hi) = (grid[1], grid[grid.len() - 1]);
        assert!((lo - 0.1).abs() < 1e-12 && (hi - 0.95).abs() < 1e-12);
        let low = refined(lo, lo);
        assert_eq!(low.len(), 4, "{low:?}");
        assert!(
            low.iter().all(|&q| q > lo && q <= lo + 0.04 + 1e-12),
            "{low:?}"
        );
        let high = refined(hi, lo);
        assert_eq!(high.len(), 8, "{high:?}");
        assert!(high.iter().all(|&q| q < 1.0), "{high:?}");
    }

    fn frf_of(tf: &fracsim::FracTf, lo_decade: f64) -> Frf {
        let omega = (0..80)
            .map(|i| 10f64.powf(lo_decade + i as f64 / 79.0 * 3.0))
            .collect();
        Frf::exact(tf, omega)
    }

    /// A step test (four levels) of `y_k = 0.9 y_(k-1) + 0.1 u_(k-1)`: the ARX response (the
    /// hold multiplied back) is the system's own at every frequency.
    #[test]
    fn the_arx_response_of_a_step_test_is_the_systems() {
        let u: Vec<f64> = (0..600).map(|k| [0.0, 1.0, 0.2, 0.8][k / 150]).collect();
        let mut y = vec![0.0; u.len()];
        for k in 1..u.len() {
            y[k] = 0.9 * y[k - 1] + 0.1 * u[k - 1];
        }
        let dt = 0.1;
        let (frf, how) = arx_frf(&u, &y, dt, &Error::NotEnoughData("steps".into())).unwrap();
        assert!(how.contains("ARX"), "{how}");
        for (&w, &h) in frf.omega.iter().zip(&frf.h) {
            let z1 = Complex64::from_polar(1.0, -w * dt);
            let g = 0.1 * z1 / (1.0 - 0.9 * z1);
            let e = (h * crate::hold::zoh(w, dt) - g).norm() / g.norm();
            assert!(e < 1e-6, "{w}: {e}");
        }
    }

    #[test]
    fn reflection_keeps_the_magnitude_and_makes_it_stable() {
        // (1 - s/10)(1 + s/50) = 1 + (1/50 - 1/10) s - s^2/500
        let a = [1.0 / 50.0 - 0.1, -1.0 / 500.0];
        let (b, moved) = reflect(&a).unwrap();
        assert!(moved);
        assert!(roots(&b).unwrap().iter().all(|r| r.re < 0.0));
        for w in [1.0, 10.0, 100.0] {
            let d = |c: &[f64]| {
                let s = Complex64::new(0.0, w);
                1.0 + c[0] * s + c[1] * s * s
            };
            assert!((d(&a).norm() - d(&b).norm()).abs() < 1e-12 * d(&a).norm());
        }
    }

    #[test]
    fn an_exact_response_gives_its_size_the_best_criterion() {
        // a resonance at the load: 2 / ((0.01 s + 1)(s^2/100^2 + 0.1 s/100 + 1))
        let g: fracsim::FracTf = "2/((0.01 s + 1) (0.0001 s^2 + 0.001 s + 1))"
            .parse()
            .unwrap();
        let frf = frf_of(&g, 0.0);
        let r = ranked(&frf, None, &[false], Budget::UNLIMITED, 0).unwrap();
        // exact data: the sizes that hold the plant tie to rounding; each has its three poles
        let best = &r[0];
        assert_eq!((best.size.den, best.q), (3, 1.0), "{r:?}");
        assert!(best.frf_error < 1e-12, "{}", best.frf_error);
        for (a, want) in best.a.iter().zip([0.011, 1.1e-4, 1e-6]) {
            assert!((a - want).abs() < 1e-9 * want, "{:?}", best.a);
        }
        assert!(best.b[1..].iter().all(|b| b.abs() < 1e-12), "{:?}", best.b);
        assert!(!calls_for_integrator(&frf));
    }

    #[test]
    fn an_integrator_beside_a_feedthrough_is_found() {
        let g: fracsim::FracTf = "(0.5 s + 2)/s".parse().unwrap();
        let frf = frf_of(&g, -1.0);
        assert!(calls_for_integrator(&frf));
        let s = fit_size(&frf, Size { num: 1, den: 0 }, true, Sk::Converged).unwrap();
        assert!(s.frf_error < 1e-20, "{s:?}");
        assert!(
            (s.b[0] - 2.0).abs() < 1e-9 && (s.b[1] - 0.5).abs() < 1e-9,
            "{s:?}"
        );
        let r = ranked(&frf, None, &[false, true], Budget::UNLIMITED, 0).unwrap();
        assert!(r[0].integrator, "{:?}", r[0]);
    }

    /// A first order behind three samples of delay: the delay is found on the response, the
    /// first order fits it exactly, and no size beyond the budget is ranked.
    #[test]
    fn a_whole_sample_delay_is_found_on_the_response() {
        let dt = 0.01;
        let g: fracsim::FracTf = "2/(0.1 s + 1)".parse().unwrap();
        let mut frf = frf_of(&g, -1.0);
        frf.h = frf
            .omega
            .iter()
            .zip(&frf.h)
            .map(|(&w, &h)| h * Complex64::from_polar(1.0, -w * 3.0 * dt))
            .collect();
        let budget = Budget {
            plain: 4,
            integrator: 4,
        };
        let r = ranked_delayed(&frf, dt, None, &[false], budget, true).unwrap();
        let best = &r[0];
        // exact data: the sizes that hold the plant tie to rounding; the first order is one
        assert_eq!(best.delay_samples, 3, "{best:?}");
        assert!(best.frf_error < 1e-9, "{best:?}");
        assert!((best.a[0] - 0.1).abs() < 1e-9 && (best.b[0] - 2.0).abs() < 1e-9);
        let first = r
            .iter()
            .find(|s| s.size == Size { num: 0, den: 1 })
            .unwrap();
        assert!(first.frf_error < 1e-9, "{first:?}");
        assert!(r
            .iter()
            .all(|s| s.delay_samples == 3 && budget.allows(s.size, false, true)));
        // without the search the delay is mimicked by a larger size, never exactly
        let plain = ranked_delayed(&frf, dt, None, &[false], budget, false).unwrap();
        assert!(plain.iter().all(|s| s.delay_samples == 0));
        assert!(plain[0].frf_error > 1e3 * best.frf_error, "{:?}", plain[0]);
        // and a response without a delay keeps none
        let r = ranked_delayed(&frf_of(&g, -1.0), dt, None, &[false], budget, true).unwrap();
        assert_eq!(r[0].delay_samples, 0, "{:?}", r[0]);
    }

    #[test]
    fn the_budget_counts_the_parameters_beside_the_structure() {
        // 60 estimation samples: 6 parameters, 5 of them beside the structure; a first order
        // still passes the fit's own check (the output offset and its two coefficients)
        let b = Budget::new(60, 5, 6, 1);
        assert_eq!((b.plain, b.integrator), (2, 2));
        assert!(b.allows(Size { num: 0, den: 1 }, false, false));
        assert!(!b.allows(Size { num: 1, den: 1 }, false, false));
        // 141 samples: 14 in all, 9 coefficients
        assert_eq!(Budget::new(141, 5, 6, 1).plain, 9);
        // a long record: at most 16 in all, the offset and four levels beside
        let b = Budget::new(100_000, 5, 6, 1);
        assert_eq!((b.plain, b.integrator), (11, 10));
        assert!(b.allows(Size { num: 4, den: 6 }, false, false));
        assert!(!b.allows(Size { num: 4, den: 6 }, false, true));
    }
}
