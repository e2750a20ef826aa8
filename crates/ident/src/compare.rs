//! Two models side by side, as the reference paper compares its time- and frequency-domain models
//! (its Fig. 5 and "within 3%"): the gain and phase differences over a band, where they are
//! largest, and the coefficients term by term when the structures match.

use crate::{Error, Result};
use fracsim::FracTf;
use num_complex::Complex64;
use std::f64::consts::PI;

/// The largest difference of one quantity over the band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Largest {
    /// The difference `B - A` (dB or deg) where its magnitude is largest.
    pub value: f64,
    /// Where, Hz.
    pub freq_hz: f64,
}

/// One coefficient (or order, or delay) of both models.
#[derive(Debug, Clone, PartialEq)]
pub struct CoefRow {
    /// What it is, e.g. `den s^1.75 coef`, `den order 2`, `delay`.
    pub name: String,
    /// Model A's value.
    pub a: f64,
    /// Model B's value.
    pub b: f64,
    /// `(b - a)/|a|` (None when `a` is 0).
    pub rel_diff: Option<f64>,
}

/// The comparison of two models over a band.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// Band, Hz.
    pub band_hz: (f64, f64),
    /// The log-spaced frequencies evaluated, Hz.
    pub freq_hz: Vec<f64>,
    /// `20 log10 |A|`, dB.
    pub a_mag_db: Vec<f64>,
    /// `20 log10 |B|`, dB.
    pub b_mag_db: Vec<f64>,
    /// `arg A` (deg), unwrapped along the band.
    pub a_phase_deg: Vec<f64>,
    /// `arg B` (deg), unwrapped along the band.
    pub b_phase_deg: Vec<f64>,
    /// The largest gain difference `20 log10 |B/A|`.
    pub gain: Largest,
    /// The largest phase difference `arg(B/A)` (deg, within (-180, 180]).
    pub phase: Largest,
    /// The largest relative complex difference `|B - A|/|A|`.
    pub complex_rel: Largest,
    /// Term-by-term coefficients when both models have the same numbers of numerator and
    /// denominator terms (terms paired by decreasing order), else `None`.
    pub coefficients: Option<Vec<CoefRow>>,
}

fn unwrap(ph: &mut [f64]) {
    for i in 1..ph.len() {
        let d = ph[i] - ph[i - 1];
        ph[i] -= 360.0 * (d / 360.0).round();
    }
}

fn largest(f: &[f64], d: &[f64]) -> Largest {
    let i = (0..d.len())
        .max_by(|&i, &j| d[i].abs().total_cmp(&d[j].abs()))
        .unwrap_or(0);
    Largest {
        value: d[i],
        freq_hz: f[i],
    }
}

fn rel(a: f64, b: f64) -> Option<f64> {
    (a != 0.0).then(|| (b - a) / a.abs())
}

/// The coefficient table of two models of the same shape (numbers of terms), else `None`.
fn coefficient_rows(a: &FracTf, b: &FracTf) -> Option<Vec<CoefRow>> {
    if a.num.len() != b.num.len() || a.den.len() != b.den.len() {
        return None;
    }
    let mut rows = Vec::new();
    for (side, ta, tb) in [("num", &a.num, &b.num), ("den", &a.den, &b.den)] {
        for (k, (x, y)) in ta.iter().zip(tb.iter()).enumerate() {
            // the order to 4 decimals, trailing zeros dropped: "s^1.7452", "s^0.92", "s^0"
            let o = format!("{:.4}", x.order);
            let o = o.trim_end_matches('0').trim_end_matches('.');
            let label = format!("{side} term {} (s^{o})", k + 1);
            rows.push(CoefRow {
                name: format!("{label} coef"),
                a: x.coef,
                b: y.coef,
                rel_diff: rel(x.coef, y.coef),
            });
            if x.order != 0.0 || y.order != 0.0 {
                rows.push(CoefRow {
                    name: format!("{label} order"),
                    a: x.order,
                    b: y.order,
                    rel_diff: rel(x.order, y.order),
                });
            }
        }
    }
    if a.delay != 0.0 || b.delay != 0.0 {
        rows.push(CoefRow {
            name: "delay (s)".into(),
            a: a.delay,
            b: b.delay,
            rel_diff: rel(a.delay, b.delay),
        });
    }
    Some(rows)
}

/// The most frequencies [`compare`] evaluates: 12 MB of curves (1e8 needed more than 3 GB).
pub const MAX_POINTS: usize = 100_000;

/// Compare `a` and `b` at `points` log-spaced frequencies over `band_hz` (both ends included).
/// Differences are `B - A`; the phase difference is `arg(B/A)`, free of unwrapping.
///
/// ```
/// let a: fracsim::FracTf = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)".parse().unwrap();
/// let b: fracsim::FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)".parse().unwrap();
/// let c = ident::compare::compare(&a, &b, (0.1, 100.0), 2000).unwrap();
/// // K; the s^1.7452 coefficient and order; the s^0.92 coefficient and order; the constant
/// assert!(c.gain.value.abs() < 3.0 && c.coefficients.unwrap().len() == 6);
/// ```
///
/// # Errors
/// [`Error::Options`] for a band that is not `0 < lo < hi` (finite), fewer than 2 points or more
/// than [`MAX_POINTS`].
pub fn compare(a: &FracTf, b: &FracTf, band_hz: (f64, f64), points: usize) -> Result<Comparison> {
    let (lo, hi) = band_hz;
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Err(Error::Options(format!(
            "band {lo}..{hi} Hz: needs 0 < low < high"
        )));
    }
    if !(2..=MAX_POINTS).contains(&points) {
        return Err(Error::Options(format!(
            "{points} points: at least 2 and at most {MAX_POINTS} (a Bode comparison is drawn on far \
             fewer; each point costs about 120 bytes)"
        )));
    }
    let freq_hz: Vec<f64> = (0..points)
        .map(|i| lo * (hi / lo).powf(i as f64 / (points - 1) as f64))
        .collect();
    let omega: Vec<f64> = freq_hz.iter().map(|f| 2.0 * PI * f).collect();
    let ha = a.bode(&omega);
    let hb = b.bode(&omega);
    let db = |h: &Complex64| 20.0 * h.norm().log10();
    let deg = |h: &Complex64| h.arg().to_degrees();
    let (a_mag_db, b_mag_db): (Vec<f64>, Vec<f64>) =
        ha.iter().zip(&hb).map(|(x, y)| (db(x), db(y))).unzip();
    let (mut a_phase_deg, mut b_phase_deg): (Vec<f64>, Vec<f64>) =
        ha.iter().zip(&hb).map(|(x, y)| (deg(x), deg(y))).unzip();
    unwrap(&mut a_phase_deg);
    unwrap(&mut b_phase_deg);
    let ratio: Vec<Complex64> = ha.iter().zip(&hb).map(|(x, y)| y / x).collect();
    let d_gain: Vec<f64> = ratio.iter().map(db).collect();
    let d_phase: Vec<f64> = ratio.iter().map(deg).collect();
    let d_cx: Vec<f64> = ratio.iter().map(|r| (r - 1.0).norm()).collect();
    if d_gain.iter().chain(&d_phase).any(|v| !v.is_finite()) {
        return Err(Error::Numerical(
            "a model's response is zero or not finite in the band".into(),
        ));
    }
    Ok(Comparison {
        band_hz,
        gain: largest(&freq_hz, &d_gain),
        phase: largest(&freq_hz, &d_phase),
        complex_rel: largest(&freq_hz, &d_cx),
        coefficients: coefficient_rows(a, b),
        freq_hz,
        a_mag_db,
        b_mag_db,
        a_phase_deg,
        b_phase_deg,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_models_differ_by_nothing() {
        let a: FracTf = "2/(0.1 s^1.5 + 1)".parse().unwrap();
        let c = compare(&a, &a, (0.1, 10.0), 50).unwrap();
        assert_eq!((c.gain.value, c.phase.value), (0.0, 0.0));
        assert!(c
            .coefficients
            .unwrap()
            .iter()
            .all(|r| r.rel_diff == Some(0.0)));
    }

    #[test]
    fn a_pure_gain_change_is_flat_and_a_delay_is_a_phase_ramp() {
        let a: FracTf = "2/(0.1 s + 1)".parse().unwrap();
        let b: FracTf = "2.2/(0.1 s + 1)".parse().unwrap();
        let c = compare(&a, &b, (1.0, 10.0), 20).unwrap();
        assert!((c.gain.value - 20.0 * 1.1f64.log10()).abs() < 1e-12);
        let rows = c.coefficients.unwrap();
        assert!((rows[0].rel_diff.unwrap() - 0.1).abs() < 1e-12);
        let d = FracTf::new(a.num.clone(), a.den.clone(), 1e-3).unwrap();
        let c = compare(&a, &d, (1.0, 100.0), 20).unwrap();
        // -360 f tau at the top of the band
        assert!((c.phase.value + 36.0).abs() < 1e-9 && c.phase.freq_hz == 100.0);
        assert!(c
            .coefficients
            .unwrap()
            .iter()
            .any(|r| r.name.starts_with("delay")));
    }

    #[test]
    fn different_structures_have_no_table_and_bad_bands_are_errors() {
        let a: FracTf = "2/(0.1 s + 1)".parse().unwrap();
        let b: FracTf = "2/(0.01 s^2 + 0.1 s + 1)".parse().unwrap();
        assert!(compare(&a, &b, (1.0, 10.0), 10)
            .unwrap()
            .coefficients
            .is_none());
        for band in [(0.0, 1.0), (2.0, 1.0), (1.0, f64::NAN)] {
            assert!(matches!(compare(&a, &b, band, 10), Err(Error::Options(_))));
        }
    }
}
