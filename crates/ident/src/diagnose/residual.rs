//! Residual analysis: whiteness, independence from the input, spectrum peaks, and the
//! correlation of the residual with an effect's signature (docs/design.md §6).
//!
//! - Whiteness: the normalised autocorrelation `r(k)` ([`crate::metrics::autocorr`]) against the
//!   99% bound `2.58/sqrt(N)`, and the Ljung-Box portmanteau statistic
//!   `Q = N (N + 2) sum_(k=1..h) r(k)^2 / (N - k)`, which is `chi^2(h)` for a white residual
//!   (Ljung & Box 1978). The p-value uses the Wilson-Hilferty cube-root normal approximation
//!   of the `chi^2` tail (accurate to about 1e-3 for `h >= 10`, enough for a 1% test).
//! - Independence from the input: [`crate::metrics::crosscorr`] over `-h..=h` lags, with the
//!   input prewhitened by its autoregression of order 10 (Box-Jenkins; the lags of a held
//!   input's raw levels move together) and with its changes (first differences). Under the
//!   null the residual is white, so the bound holds at each lag whatever the other series' own
//!   correlation (the variance of a cross-correlation of a white series with any independent
//!   one is `1/N`); the input's
//!   changes are its innovations for a step-like input (a staircase, steps from rest), whose raw
//!   levels, each held for many samples, hide a model error that follows every step and dies out
//!   (a lead the first order lacks: on the zoo's lead case 0033 the raw input's largest
//!   correlation was 0.025 against a bound of 0.073, its changes' 0.088 with three lags
//!   outside). The changes are the input prewhitened by the one filter that whitens a held
//!   input's steps, the autoregression by one fitted to any input, as Ljung's residual test
//!   asks (Ljung 1999, §16.6).
//! - Spectrum: the periodogram `I(f) = |sum_k e_k exp(-j 2 pi f k dt)|^2 / N` at the Fourier
//!   frequencies; a peak is a bin whose power exceeds [`PEAK_RATIO`] times the median of its
//!   neighbours. For white noise `I / mean` is `Exp(1)`, its median `ln 2`, so
//!   `P(I > 20 median) = exp(-20 ln 2) ~ 1e-6` per bin: about 1e-3 false alarms per record of a few
//!   thousand bins.
//! - Signatures: [`explained`] regresses the residual on the signature columns after projecting
//!   the model's own sensitivities out (a Lagrange-multiplier / score test); the fraction of the
//!   residual's sum of squares it explains, `R^2`, is the evidence. `N R^2` is `chi^2(p)` under the
//!   null of no effect with a white residual.

use crate::lm::Mat;
use crate::metrics::{autocorr, bound99, crosscorr};
use serde::Serialize;
use std::f64::consts::PI;

/// Ratio of a spectral peak to the median of its neighbours (see the module documentation).
pub const PEAK_RATIO: f64 = 20.0;

/// A narrow peak in the residual spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpectralPeak {
    /// Its frequency in Hz (refined between Fourier bins).
    pub freq_hz: f64,
    /// Its power over the median power of the neighbouring bins.
    pub ratio: f64,
    /// The amplitude of a sinusoid with that periodogram value, `2 |X(f)| / N`.
    pub amplitude: f64,
}

/// The residual tests of one segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualAnalysis {
    /// Number of samples.
    pub n: usize,
    /// Mean of the residual.
    pub mean: f64,
    /// RMS of the residual.
    pub rms: f64,
    /// The 99% bound `2.58/sqrt(N)`.
    pub bound: f64,
    /// Lags used (`h`).
    pub lags: usize,
    /// Autocorrelation lags `1..=h` outside the bound.
    pub auto_outside: usize,
    /// The Ljung-Box statistic `Q`.
    pub ljung_box_q: f64,
    /// Its p-value under `chi^2(h)`.
    pub ljung_box_p: f64,
    /// White at the 1% level (Ljung-Box `p >= 0.01`).
    pub white: bool,
    /// Cross-correlation lags `-h..=h` with the prewhitened input ([`prewhitened`]) outside the
    /// bound.
    pub cross_outside: usize,
    /// Lag (samples) of the largest absolute residual-input cross-correlation (the raw input).
    pub cross_peak_lag: isize,
    /// That correlation.
    pub cross_peak: f64,
    /// Cross-correlation lags `-h..=h` of the residual with the input's changes (its first
    /// differences) outside the bound.
    pub change_outside: usize,
    /// Independent of the input: no more than one lag more than 1% of the `2h + 1` lags (at
    /// least one) outside with the prewhitened input, and as many with the input's changes: two
    /// of 51. Two tests at 1% a lag over 51 nearly independent lags, each allowing one, would
    /// take a white residual for dependent about 18% of the time (binomial: 9.2% each), each
    /// allowing two about 3% (1.4% each). The raw levels of a held input give lags that move
    /// together, whose count is not binomial: about 10% for a +-1 input held 20 samples with two
    /// allowed (simulated, white residuals of 3000 samples), 2% prewhitened. A count misses a
    /// single strong lag (a gain error against an input that changes at every sample): one lag
    /// of either beyond the bound of all `2h + 1` at 1% together (Bonferroni, `3.72/sqrt(N)` for
    /// 51) is dependence by itself.
    pub independent: bool,
    /// Narrow spectral peaks, strongest first (at most 5).
    pub peaks: Vec<SpectralPeak>,
}

/// The `z` with `P(Z > z) = p` for a standard normal `Z` and `0 < p < 1/2` ([`normal_tail`]
/// inverted by bisection on `[0, 40]`).
fn normal_quantile_upper(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 40.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if normal_tail(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Standard normal upper tail `P(Z > z)` (Abramowitz & Stegun 7.1.26 for erfc, error < 1.5e-7).
pub fn normal_tail(z: f64) -> f64 {
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erfc = poly * (-x * x).exp();
    if z >= 0.0 {
        0.5 * erfc
    } else {
        1.0 - 0.5 * erfc
    }
}

/// `P(chi^2(k) > q)` by the Wilson-Hilferty approximation
/// `z = ((q/k)^(1/3) - (1 - 2/(9k))) / sqrt(2/(9k))`.
pub fn chi2_tail(q: f64, k: usize) -> f64 {
    if k == 0 || !q.is_finite() {
        return if q.is_finite() { 1.0 } else { 0.0 };
    }
    if q <= 0.0 {
        return 1.0;
    }
    let k = k as f64;
    let v = 2.0 / (9.0 * k);
    normal_tail(((q / k).cbrt() - (1.0 - v)) / v.sqrt())
}

/// The Ljung-Box statistic of `e` over lags `1..=h`.
pub fn ljung_box(e: &[f64], h: usize) -> f64 {
    let n = e.len() as f64;
    let r = autocorr(e, h);
    (1..=h.min(e.len().saturating_sub(1)))
        .map(|k| r[k] * r[k] / (n - k as f64))
        .sum::<f64>()
        * n
        * (n + 2.0)
}

/// `sum_k x_k exp(-j w k)` as (re, im), `w` in radians per sample ([`fracsim::fft::dft_at`]).
fn dft(x: &[f64], w: f64) -> (f64, f64) {
    let z = fracsim::fft::dft_at(x, w);
    (z.re, z.im)
}

/// Narrow peaks of the periodogram of `e` (mean removed) sampled every `dt` seconds, strongest
/// first (at most `max`), each refined by a golden-section search of `|X(f)|` within one bin.
pub fn spectral_peaks(e: &[f64], dt: f64, max: usize) -> Vec<SpectralPeak> {
    let n = e.len();
    if n < 64 || !(dt > 0.0) {
        return vec![];
    }
    let (x, p) = fracsim::fft::periodogram(e);
    let nb = n / 2;
    let mut found = vec![];
    for k in 2..nb.saturating_sub(1) {
        if p[k] < p[k - 1] || p[k] < p[k + 1] {
            continue;
        }
        match neighbour_ratio(&p, k) {
            Some(ratio) if ratio > PEAK_RATIO => found.push((k, ratio)),
            _ => {}
        }
    }
    // The strongest `max` by their bin's ratio; only these are refined (each refinement is 33
    // DFTs of the whole record: refining every peak over the ratio cost more than the rest of a
    // diagnosis on long records).
    found.sort_by(|a, b| b.1.total_cmp(&a.1));
    found.truncate(max);
    found
        .into_iter()
        .map(|(k, ratio)| {
            // Golden-section search of |X| over [k - 1, k + 1] bins, one new DFT per step (the
            // other inner point is the last step's).
            let f = |b: f64| {
                let (re, im) = dft(&x, 2.0 * PI * b / n as f64);
                re * re + im * im
            };
            let (mut a, mut b) = (k as f64 - 1.0, k as f64 + 1.0);
            let g = 0.618_033_988_75;
            let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
            let (mut fc, mut fd) = (f(c), f(d));
            for _ in 0..30 {
                if fc > fd {
                    b = d;
                    (d, fd) = (c, fc);
                    c = b - g * (b - a);
                    fc = f(c);
                } else {
                    a = c;
                    (c, fc) = (d, fd);
                    d = a + g * (b - a);
                    fd = f(d);
                }
            }
            let bin = 0.5 * (a + b);
            SpectralPeak {
                freq_hz: bin / (n as f64 * dt),
                ratio,
                amplitude: 2.0 * f(bin).sqrt() / n as f64,
            }
        })
        .collect()
}

/// The power of periodogram `p` at bin `k` over the median of its neighbours (16 bins on each
/// side, the two next to it left out); `None` with fewer than 8 neighbours.
fn neighbour_ratio(p: &[f64], k: usize) -> Option<f64> {
    let half = 16usize;
    let lo = k.saturating_sub(half).max(1);
    let hi = (k + half).min(p.len().saturating_sub(1));
    let mut nbh: Vec<f64> = (lo..=hi)
        .filter(|&j| j + 2 < k || j > k + 2)
        .map(|j| p[j])
        .collect();
    if nbh.len() < 8 {
        return None;
    }
    nbh.sort_by(f64::total_cmp);
    Some(p[k] / nbh[nbh.len() / 2].max(1e-300))
}

/// The narrow lines of `x` sampled every `dt` seconds (its periodogram computed once): for a
/// frequency `freq_hz`, whether the periodogram's largest bin within one of it exceeds
/// [`PEAK_RATIO`] times the median of its neighbours (the test [`spectral_peaks`] makes of a
/// residual); the ratio, `None` when there is no line there (or `x` is too short to tell).
pub fn lines(x: &[f64], dt: f64) -> impl Fn(f64) -> Option<f64> {
    let n = x.len();
    let p = (n >= 64 && dt > 0.0).then(|| fracsim::fft::periodogram(x).1);
    move |freq_hz| {
        let p = p.as_ref()?;
        let k = (freq_hz * n as f64 * dt).round() as usize;
        let top = (k.saturating_sub(1).max(1)..=(k + 1).min(n / 2))
            .max_by(|&a, &b| p[a].total_cmp(&p[b]))?;
        neighbour_ratio(p, top).filter(|&r| r > PEAK_RATIO)
    }
}

/// Analyse the residual `e` against the input `u` (same length), sampled every `dt` seconds, with
/// `h = min(25, N/5)` lags.
pub fn analyse(e: &[f64], u: &[f64], dt: f64) -> ResidualAnalysis {
    let n = e.len().min(u.len());
    let e = &e[..n];
    let h = 25.min(n / 5).max(1);
    let bound = bound99(n);
    let ra = autocorr(e, h);
    let rc = crosscorr(e, &u[..n], h);
    let (mut peak_i, mut peak) = (h, 0.0f64);
    for (i, v) in rc.iter().enumerate() {
        if v.abs() > peak.abs() {
            peak = *v;
            peak_i = i;
        }
    }
    let q = ljung_box(e, h);
    let p = chi2_tail(q, h);
    let rw = crosscorr(e, &prewhitened(&u[..n], PREWHITEN_ORDER), h);
    let cross_outside = rw.iter().filter(|v| v.abs() > bound).count();
    let changes: Vec<f64> = std::iter::once(0.0)
        .chain(u[..n].windows(2).map(|w| w[1] - w[0]))
        .collect();
    let rd = crosscorr(e, &changes, h);
    let change_outside = rd.iter().filter(|v| v.abs() > bound).count();
    let allowed = ((2 * h + 1) / 100).max(1);
    // One lag beyond the bound of all `2h + 1` at 1% together (Bonferroni) is evidence alone.
    let single = normal_quantile_upper(0.005 / (2 * h + 1) as f64) / (n.max(1) as f64).sqrt();
    let strong = rw.iter().chain(&rd).any(|v| v.abs() > single);
    let nn = n.max(1) as f64;
    ResidualAnalysis {
        n,
        mean: e.iter().sum::<f64>() / nn,
        rms: (e.iter().map(|v| v * v).sum::<f64>() / nn).sqrt(),
        bound,
        lags: h,
        auto_outside: ra.iter().skip(1).filter(|v| v.abs() > bound).count(),
        ljung_box_q: q,
        ljung_box_p: p,
        white: p >= 0.01,
        cross_outside,
        cross_peak_lag: peak_i as isize - h as isize,
        cross_peak: peak,
        change_outside,
        independent: cross_outside <= allowed + 1 && change_outside <= allowed + 1 && !strong,
        peaks: spectral_peaks(e, dt, 5),
    }
}

/// The order of the autoregression [`prewhitened`] fits to the input.
const PREWHITEN_ORDER: usize = 10;

/// `u` (centred) through the inverse of its autoregression of order `p` (Yule-Walker, solved by
/// Levinson-Durbin on its autocorrelation): the prediction error `w_t = u_t + sum a_i u_(t-i)`,
/// white for an autoregressive input and nearly so for a held one. Under the null (a white
/// residual independent of the input) the residual's cross-correlations with `w` at different
/// lags are then nearly uncorrelated (their covariance is `rho_w(k - k') / N`), so that counting
/// the lags outside the bound is a calibrated test (Box-Jenkins prewhitening; Ljung 1999,
/// §16.6); with the raw levels of a held input they move together. A constant input is returned
/// as it is (centred: zero).
fn prewhitened(u: &[f64], p: usize) -> Vec<f64> {
    let mean = u.iter().sum::<f64>() / u.len().max(1) as f64;
    let x: Vec<f64> = u.iter().map(|v| v - mean).collect();
    let r = autocorr(&x, p);
    let mut a = vec![0.0; p + 1];
    a[0] = 1.0;
    let mut err = r[0];
    for m in 1..=p.min(r.len() - 1) {
        if !(err > 1e-12) {
            break;
        }
        let acc: f64 = r[m] + (1..m).map(|i| a[i] * r[m - i]).sum::<f64>();
        let k = -acc / err;
        let prev = a.clone();
        for i in 1..m {
            a[i] = prev[i] + k * prev[m - i];
        }
        a[m] = k;
        err *= 1.0 - k * k;
    }
    (0..x.len())
        .map(|t| (0..=p.min(t)).map(|i| a[i] * x[t - i]).sum())
        .collect()
}

/// A model's sensitivity columns factored once ([`crate::linalg::Span`]), to be projected out of
/// many signatures ([`explained_in`]): a round's probes try dozens against the same model, and
/// the factorisation was most of each projection's cost. [`Projection::project_out`] is the
/// least-squares residual of the columns `b` (rows = samples) regressed on them; there may be no
/// column (then `b` is returned). The span of the independent columns is projected out
/// ([`crate::linalg::project_out`]): a model's sensitivities may hold a column of zeros or nearly
/// dependent ones (past-input levels whose response has died out, terms that merged).
pub struct Projection {
    /// The sensitivity columns.
    cols: usize,
    /// Their span, `None` when nothing is projected out (no column, or no more rows than
    /// columns).
    span: Option<crate::linalg::Span>,
}

impl Projection {
    /// The projection out of `a`'s columns.
    pub fn of(a: &Mat<f64>) -> Self {
        let none = a.ncols() == 0 || a.nrows() <= a.ncols();
        Projection {
            cols: a.ncols(),
            span: (!none).then(|| crate::linalg::Span::of(a)),
        }
    }

    /// `b` with the columns projected out.
    fn project_out(&self, b: &Mat<f64>) -> Mat<f64> {
        match &self.span {
            Some(span) => span.project_out(b),
            None => b.clone(),
        }
    }
}

/// The fraction `R^2` of the sum of squares of `e` explained by the signature columns `sig`
/// (each of `e.len()` rows) after the model's sensitivity columns `sens` are projected out of
/// both: `R^2 = 1 - ||e_perp - S_perp beta||^2 / ||e_perp||^2` with `beta` the least-squares
/// coefficients, `e_perp` and `S_perp` the parts orthogonal to `sens`. Returns `(R^2, beta)`;
/// a column with nothing left once `sens` is projected out (a past-input level whose response
/// died out before the record, a column the model's sensitivities already hold) takes no part,
/// its coefficient 0; `(0, zeros)` when no column is left.
pub fn explained(e: &[f64], sig: &[Vec<f64>], sens: &Mat<f64>) -> (f64, Vec<f64>) {
    explained_in(e, sig, &Projection::of(sens))
}

/// [`explained`] with the sensitivity columns factored once ([`Projection`]): the same figures,
/// bit for bit.
pub fn explained_in(e: &[f64], sig: &[Vec<f64>], sens: &Projection) -> (f64, Vec<f64>) {
    let n = e.len();
    let p = sig.len();
    if p == 0 || n <= p + sens.cols || sig.iter().any(|s| s.len() != n) {
        return (0.0, vec![0.0; p]);
    }
    let mut b = Mat::<f64>::zeros(n, p + 1);
    for r in 0..n {
        b[(r, 0)] = e[r];
        for (c, s) in sig.iter().enumerate() {
            b[(r, c + 1)] = s[r];
        }
    }
    let b = sens.project_out(&b);
    let ep: Vec<f64> = (0..n).map(|r| b[(r, 0)]).collect();
    let ee: f64 = ep.iter().map(|v| v * v).sum();
    let scale: Vec<f64> = (0..p)
        .map(|c| (0..n).map(|r| b[(r, c + 1)].powi(2)).sum::<f64>().sqrt())
        .collect();
    let live: Vec<usize> = (0..p)
        .filter(|&c| scale[c] > 1e-12 * (ee.sqrt() + 1e-300))
        .collect();
    if live.is_empty() || ee <= 0.0 {
        return (0.0, vec![0.0; p]);
    }
    let s = Mat::<f64>::from_fn(n, live.len(), |r, j| b[(r, live[j] + 1)] / scale[live[j]]);
    let rhs = Mat::<f64>::from_fn(n, 1, |r, _| ep[r]);
    let x = crate::lm::lstsq(&s, &rhs);
    let fitted = &s * &x;
    let rr: f64 = (0..n).map(|r| (ep[r] - fitted[(r, 0)]).powi(2)).sum();
    let r2 = (1.0 - rr / ee).clamp(0.0, 1.0);
    let mut beta = vec![0.0; p];
    for (j, &c) in live.iter().enumerate() {
        beta[c] = x[(j, 0)] / scale[c];
    }
    if r2.is_finite() {
        (r2, beta)
    } else {
        (0.0, vec![0.0; p])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tails_match_tables() {
        // P(Z > 2.5758) = 0.005; chi2(25) 99th percentile is 44.314.
        assert!((normal_tail(2.5758) - 0.005).abs() < 1e-5);
        assert!((chi2_tail(44.314, 25) - 0.01).abs() < 1e-3);
        assert!((chi2_tail(24.337, 25) - 0.5).abs() < 1e-2);
    }

    /// One [`Projection`] of a model's sensitivities, used for signature after signature, gives
    /// each the figures [`explained`] gives it alone (bit for bit), with the sensitivities (a
    /// column of zeros and a dependent one among them) projected out.
    #[test]
    fn a_projection_made_once_explains_as_one_made_per_signature() {
        let n = 400;
        let mut noise = crate::testdata::uniform(11);
        let t = |k: usize| k as f64 / n as f64;
        let sens = Mat::from_fn(n, 4, |k, c| match c {
            0 => (6.0 * t(k)).sin(),
            1 => 0.0,
            2 => 2.0 * (6.0 * t(k)).sin(),
            _ => t(k) * t(k),
        });
        let e: Vec<f64> = (0..n)
            .map(|k| 0.3 * (6.0 * t(k)).sin() + (17.0 * t(k)).cos() + 0.1 * noise())
            .collect();
        let sigs: Vec<Vec<Vec<f64>>> = vec![
            vec![(0..n).map(|k| (17.0 * t(k)).cos()).collect()],
            vec![(0..n).map(t).collect(), (0..n).map(|_| noise()).collect()],
            vec![(0..n).map(|k| (6.0 * t(k)).sin()).collect()],
        ];
        let once = Projection::of(&sens);
        for sig in &sigs {
            let (r2, beta) = explained_in(&e, sig, &once);
            let (r2_alone, beta_alone) = explained(&e, sig, &sens);
            assert_eq!(r2.to_bits(), r2_alone.to_bits());
            assert_eq!(beta, beta_alone);
        }
        // The cosine explains most of what the sensitivities leave; the sine is their span.
        assert!(explained_in(&e, &sigs[0], &once).0 > 0.9);
        assert_eq!(explained_in(&e, &sigs[2], &once).0, 0.0);
        let b = Mat::from_fn(n, 1, |k, _| (6.0 * t(k)).sin() + t(k) * t(k));
        let out = once.project_out(&b);
        assert!((0..n).all(|k| out[(k, 0)].abs() < 1e-12), "{}", out[(0, 0)]);
    }

    /// A signature of several columns, one of which has nothing left once the sensitivities are
    /// projected out (a past-input level whose response died out before the record: zeros, or
    /// the sensitivities' own span), is judged on the columns that are left: the same `R^2` as
    /// those columns alone, the dead column's coefficient 0. (The whole signature was called
    /// degenerate, `R^2 = 0`: the initial-state probe saw 0.0% of a residual its live levels
    /// explain 63% of, and an input offset or a dead band took the state's place.)
    #[test]
    fn a_dead_column_leaves_the_live_columns_explanation() {
        let n = 300;
        let mut noise = crate::testdata::uniform(5);
        let t = |k: usize| k as f64 / n as f64;
        let sens = Mat::from_fn(n, 1, |k, _| t(k));
        let decay: Vec<f64> = (0..n).map(|k| (-20.0 * t(k)).exp()).collect();
        let e: Vec<f64> = (0..n).map(|k| 2.0 * decay[k] + 0.05 * noise()).collect();
        let live = vec![decay.clone()];
        let (r2_live, beta_live) = explained(&e, &live, &sens);
        assert!(r2_live > 0.9, "{r2_live}");
        for dead in [
            vec![0.0; n],
            (0..n).map(|k| 3.0 * t(k)).collect::<Vec<f64>>(),
        ] {
            let (r2, beta) = explained(&e, &[decay.clone(), dead], &sens);
            assert!((r2 - r2_live).abs() < 1e-12, "{r2} against {r2_live}");
            assert!((beta[0] - beta_live[0]).abs() < 1e-9 * beta_live[0].abs());
            assert_eq!(beta[1], 0.0);
        }
        assert_eq!(explained(&e, &[vec![0.0; n]], &sens), (0.0, vec![0.0]));
    }

    /// A model error that follows every step of a staircase and dies out (a lead the model
    /// lacks), in white noise: the raw input, held at each level for 100 samples, hides it (its
    /// correlation at every lag within the bound); the input's changes and the prewhitened input
    /// ([`prewhitened`]) show it. White noise alone is independent of them.
    #[test]
    fn an_error_after_each_step_depends_on_the_inputs_changes() {
        let n = 2000;
        let u = crate::testdata::random_binary(n, 100, 5);
        let mut uniform = crate::testdata::uniform(2);
        let noise: Vec<f64> = (0..n).map(|_| 3.46 * uniform()).collect();
        let quiet = analyse(&noise, &u, 1e-3);
        assert!(quiet.independent, "{quiet:?}");
        let mut x = 0.0;
        let e: Vec<f64> = (0..n)
            .map(|k| {
                let du = if k == 0 { 0.0 } else { u[k] - u[k - 1] };
                x = 0.7 * x + du;
                x + noise[k]
            })
            .collect();
        let a = analyse(&e, &u, 1e-3);
        let raw = crosscorr(&e, &u, a.lags);
        assert!(raw.iter().filter(|v| v.abs() > a.bound).count() <= 1);
        assert!(a.cross_outside >= 3, "{a:?}");
        assert!(a.change_outside >= 3, "{a:?}");
        assert!(!a.independent);
    }

    /// White residuals against a +-1 input that changes at every sample and one held 20
    /// samples: allowing two of the 51 lags outside the bound with the prewhitened input and two
    /// with its changes takes at most 6% of them for dependent. With one lag allowed for the
    /// input about 10% were (binomial `P(X > 1)` of 51 lags at 1%: 9.2%); with two but the raw
    /// levels of the held input, whose lags move together, about 10% still. A residual that is
    /// half the input plus the same noise is taken for dependent at least 95% of the time:
    /// against the input that changes at every sample that is one lag, which the count allows
    /// but which stands beyond the bound of all 51 lags together (Bonferroni:
    /// `normal_quantile_upper(0.005 / 51) / sqrt(N)`, 3.724 / sqrt(N)).
    #[test]
    fn white_residuals_are_seldom_taken_for_dependent() {
        let (n, trials): (usize, usize) = (1000, 300);
        let mut uniform = crate::testdata::uniform(11);
        for hold in [1, 20] {
            let (mut dependent, mut missed) = (0, 0);
            for _ in 0..trials {
                let levels: Vec<f64> = (0..n.div_ceil(hold)).map(|_| uniform().signum()).collect();
                let u: Vec<f64> = (0..n).map(|k| levels[k / hold]).collect();
                let e: Vec<f64> = (0..n).map(|_| 3.46 * uniform()).collect();
                dependent += usize::from(!analyse(&e, &u, 1e-3).independent);
                let gain_error: Vec<f64> = e.iter().zip(&u).map(|(e, u)| e + 0.5 * u).collect();
                missed += usize::from(analyse(&gain_error, &u, 1e-3).independent);
            }
            assert!(
                dependent * 100 < 6 * trials,
                "held {hold}: {dependent} of {trials}"
            );
            assert!(missed * 100 < 5 * trials, "held {hold}: {missed} missed");
        }
    }

    #[test]
    fn the_normal_quantile_inverts_the_tail() {
        assert!((normal_quantile_upper(0.005) - 2.5758).abs() < 1e-3);
        assert!((normal_quantile_upper(0.005 / 51.0) - 3.7240).abs() < 2e-3);
    }

    #[test]
    fn a_sinusoid_in_noise_is_a_peak() {
        let mut uniform = crate::testdata::uniform(7);
        let e: Vec<f64> = (0..2000)
            .map(|k| {
                let w = uniform();
                w + 0.3 * (2.0 * PI * 37.3 * k as f64 * 1e-3).sin()
            })
            .collect();
        let p = spectral_peaks(&e, 1e-3, 3);
        assert!(!p.is_empty());
        assert!((p[0].freq_hz - 37.3).abs() < 0.1, "{p:?}");
        assert!((p[0].amplitude - 0.3).abs() < 0.05, "{p:?}");
        let (r2, beta) = explained(
            &e,
            &[(0..2000)
                .map(|k| (2.0 * PI * 37.3 * k as f64 * 1e-3).sin())
                .collect()],
            &Mat::zeros(2000, 0),
        );
        assert!(r2 > 0.2 && (beta[0] - 0.3).abs() < 0.02, "{r2} {beta:?}");
    }

    /// A multisine of one period (lines at 7, 19 and 43 Hz, 1.5 s at 1 ms) has a line at each of
    /// its frequencies and none between them; a PRBS-like input of random levels held 5 samples
    /// has none at any of those frequencies.
    #[test]
    fn a_multisine_has_lines_where_it_excites_and_a_random_input_none() {
        let dt = 1e-3;
        let lines = [(7.0, 0.3), (19.0, 1.1), (43.0, 2.0)];
        let ms: Vec<f64> = (0..1500)
            .map(|k| {
                let t = k as f64 * dt;
                lines
                    .iter()
                    .map(|(f, ph)| (2.0 * PI * f * t + ph).sin())
                    .sum()
            })
            .collect();
        let in_ms = super::lines(&ms, dt);
        for (f, _) in lines {
            assert!(in_ms(f).is_some(), "{f} Hz");
        }
        for f in [12.0, 31.0, 60.0] {
            assert!(in_ms(f).is_none(), "{f} Hz");
        }
        let mut lcg = crate::testdata::lcg(11);
        let mut level = 0.0;
        let prbs: Vec<f64> = (0..1500)
            .map(|k| {
                if k % 5 == 0 {
                    level = if (lcg() >> 40) & 1 == 1 { 1.0 } else { -1.0 };
                }
                level
            })
            .collect();
        let in_prbs = super::lines(&prbs, dt);
        for (f, _) in lines {
            assert!(in_prbs(f).is_none(), "{f} Hz");
        }
    }
}
