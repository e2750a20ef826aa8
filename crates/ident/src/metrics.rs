//! Fit measures and residual tests, as users know them from MATLAB's `compare` and `resid`
//! (Ljung, *System Identification: Theory for the User*, 2nd ed. 1999, sections 16.5-16.6).
//!
//! - [`nrmse_percent`]: `100 (1 - ||y - yhat|| / ||y - mean(y)||)`;
//! - [`rmse`]: `sqrt(mean((y - yhat)^2))`;
//! - [`autocorr`]: normalised residual autocorrelation `r_ee(k) / r_ee(0)`, lags `0..=max_lag`;
//! - [`crosscorr`]: normalised residual-input cross-correlation, lags `-max_lag..=max_lag`;
//! - [`bound99`]: the 99% confidence bound `2.58 / sqrt(N)` for both under whiteness/independence.
//!
//! ```
//! use ident::metrics::{nrmse_percent, rmse};
//! let y = [1.0, 2.0, 3.0, 4.0];
//! let yhat = [1.1, 1.9, 3.1, 3.9];
//! assert!((rmse(&y, &yhat) - 0.1).abs() < 1e-12);
//! assert!(nrmse_percent(&y, &yhat) > 90.0);
//! ```

use serde::Serialize;

/// The two fit figures reported for a data segment (docs/design.md §7 `fit.estimation`/`fit.validation`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Fit {
    /// Root-mean-square error, in the unit of `y`.
    pub rmse: f64,
    /// NRMSE fit in percent: 100 is perfect, 0 is no better than the mean, negative is worse.
    pub nrmse_percent: f64,
}

impl Fit {
    /// Both figures for measured `y` and model output `yhat` (same length).
    pub fn of(y: &[f64], yhat: &[f64]) -> Self {
        Self {
            rmse: rmse(y, yhat),
            nrmse_percent: nrmse_percent(y, yhat),
        }
    }
}

/// Root-mean-square error `sqrt(1/N sum (y_k - yhat_k)^2)`; NaN for empty input.
///
/// Only the common length of the two slices is used.
pub fn rmse(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().min(yhat.len());
    if n == 0 {
        return f64::NAN;
    }
    let s = crate::numeric::sum_of2(y, yhat, |a, b| (a - b) * (a - b));
    (s / n as f64).sqrt()
}

/// NRMSE fit in percent (MATLAB `compare`, `goodnessOfFit(..., 'NRMSE')` as a fit):
/// `100 (1 - ||y - yhat|| / ||y - mean(y)||)`.
///
/// `-inf` when `y` is constant and the model misses it, 100 when both are exact; NaN for empty input.
pub fn nrmse_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().min(yhat.len());
    if n == 0 {
        return f64::NAN;
    }
    let y = &y[..n];
    // (Sums in eight lanes: one vectorised pass each.)
    let mean = crate::numeric::sum_of(y, |a| a) / n as f64;
    let num = crate::numeric::sum_of2(y, yhat, |a, b| (a - b) * (a - b)).sqrt();
    let den = crate::numeric::sum_of(y, |a| (a - mean) * (a - mean)).sqrt();
    if den == 0.0 {
        return if num == 0.0 { 100.0 } else { f64::NEG_INFINITY };
    }
    100.0 * (1.0 - num / den)
}

/// The 99% confidence bound `2.58 / sqrt(N)` of a normalised correlation estimate from `N`
/// samples of white noise (Ljung 1999, section 16.6).
pub fn bound99(n: usize) -> f64 {
    2.58 / (n.max(1) as f64).sqrt()
}

fn centred(x: &[f64]) -> Vec<f64> {
    let m = if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    };
    x.iter().map(|v| v - m).collect()
}

/// Normalised residual autocorrelation `r(k) = sum_t e_t e_{t+k} / sum_t e_t^2` for
/// `k = 0..=max_lag` (means removed; biased estimator, as MATLAB `resid`). `r(0) = 1`.
///
/// A white residual stays within `+-`[`bound99`]`(N)` for `k >= 1` with 99% probability.
/// An all-zero residual gives zeros after lag 0.
pub fn autocorr(e: &[f64], max_lag: usize) -> Vec<f64> {
    let e = centred(e);
    let n = e.len();
    let r0: f64 = e.iter().map(|v| v * v).sum();
    (0..=max_lag)
        .map(|k| {
            if k == 0 {
                1.0
            } else if k >= n || r0 == 0.0 {
                0.0
            } else {
                e[..n - k]
                    .iter()
                    .zip(&e[k..])
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    / r0
            }
        })
        .collect()
}

/// Normalised residual-input cross-correlation
/// `r_eu(k) = sum_t e_{t+k} u_t / sqrt(sum e^2 sum u^2)` for `k = -max_lag..=max_lag`
/// (means removed). The result has `2 max_lag + 1` entries, lag `k` at index `k + max_lag`.
///
/// A peak at a positive lag `k` means the residual still depends on the input `k` samples
/// earlier (unmodelled dynamics or delay); peaks at negative lags indicate feedback. Under
/// independence it stays within `+-`[`bound99`]`(N)`.
pub fn crosscorr(e: &[f64], u: &[f64], max_lag: usize) -> Vec<f64> {
    let n = e.len().min(u.len());
    let e = centred(&e[..n]);
    let u = centred(&u[..n]);
    let norm = (e.iter().map(|v| v * v).sum::<f64>() * u.iter().map(|v| v * v).sum::<f64>()).sqrt();
    let ml = max_lag as isize;
    (-ml..=ml)
        .map(|k| {
            if norm == 0.0 || k.unsigned_abs() >= n {
                return 0.0;
            }
            let s: f64 = if k >= 0 {
                let k = k as usize;
                e[k..].iter().zip(&u[..n - k]).map(|(a, b)| a * b).sum()
            } else {
                let k = (-k) as usize;
                e[..n - k].iter().zip(&u[k..]).map(|(a, b)| a * b).sum()
            };
            s / norm
        })
        .collect()
}

/// Summary of residual whiteness and independence from the input, at the 99% level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualTest {
    /// The bound `2.58/sqrt(N)`.
    pub bound: f64,
    /// Number of autocorrelation lags `1..=max_lag` outside the bound.
    pub auto_outside: usize,
    /// Number of cross-correlation lags `-max_lag..=max_lag` outside the bound.
    pub cross_outside: usize,
    /// The lag of the largest absolute cross-correlation.
    pub cross_peak_lag: isize,
    /// The largest absolute cross-correlation.
    pub cross_peak: f64,
}

/// Count the correlation lags outside the 99% bound (MATLAB `resid`'s test).
pub fn residual_test(e: &[f64], u: &[f64], max_lag: usize) -> ResidualTest {
    let bound = bound99(e.len());
    let ra = autocorr(e, max_lag);
    let rc = crosscorr(e, u, max_lag);
    let (mut peak_i, mut peak) = (max_lag, 0.0f64);
    for (i, v) in rc.iter().enumerate() {
        if v.abs() > peak.abs() {
            peak = *v;
            peak_i = i;
        }
    }
    ResidualTest {
        bound,
        auto_outside: ra.iter().skip(1).filter(|v| v.abs() > bound).count(),
        cross_outside: rc.iter().filter(|v| v.abs() > bound).count(),
        cross_peak_lag: peak_i as isize - max_lag as isize,
        cross_peak: peak,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nrmse_reference_values() {
        let y = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(nrmse_percent(&y, &y), 100.0);
        // Predicting the mean gives exactly 0.
        assert!(nrmse_percent(&y, &[1.5; 4]).abs() < 1e-12);
        assert_eq!(nrmse_percent(&[1.0; 3], &[1.0; 3]), 100.0);
        assert_eq!(nrmse_percent(&[1.0; 3], &[2.0; 3]), f64::NEG_INFINITY);
        assert!(rmse(&[], &[]).is_nan());
    }

    #[test]
    fn correlations_of_a_delayed_copy_peak_at_the_delay() {
        // A deterministic pseudo-random sequence (LCG) so the test needs no RNG.
        let mut uniform = crate::testdata::uniform(12345);
        let u: Vec<f64> = (0..2000).map(|_| uniform()).collect();
        let e: Vec<f64> = (0..u.len())
            .map(|k| if k >= 3 { u[k - 3] } else { 0.0 })
            .collect();
        let rc = crosscorr(&e, &u, 10);
        assert_eq!(rc.len(), 21);
        let t = residual_test(&e, &u, 10);
        assert_eq!(t.cross_peak_lag, 3);
        assert!(t.cross_peak > 0.99);
        let ra = autocorr(&u, 5);
        assert_eq!(ra[0], 1.0);
        // White input: lags 1..5 are within the 99% bound (2.58/sqrt(2000) = 0.058) for this seed.
        assert!(ra[1..].iter().all(|r| r.abs() < bound99(2000)), "{ra:?}");
    }
}
