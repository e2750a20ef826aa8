//! The fit does not depend on the time unit (issue 46, item 13): a record whose sampling step is
//! outside `[MIN_DT, MAX_DT]` (a time column in units of 1e-4 s, or of 1e4 s) is fitted with its
//! time in another unit, a power of ten bringing its step into `[1e-3, 1e-2)` times ten, and the
//! model's parameters converted to that unit and back.
//!
//! In log coordinates (the solver's `theta = ln a` for a positive coefficient `a` of `s^q`) a
//! change of the time unit by `c` is a shear, `ln a' = ln a + q ln c`, that couples every
//! coefficient with the orders; Levenberg-Marquardt's scaling is diagonal, so its path depends on
//! the unit: the UNAL PRBS record with its time multiplied by 1e-4 stopped at 94.00% ("parameter
//! step below tolerance", the highest order run to 2), 95.31% in seconds. Converted to the unit
//! whose step is 0.02 (the record's own in seconds), every power-of-ten unit of that record gives
//! the seconds' fit; a final fit in the record's own unit, started at the converted optimum,
//! gives the covariance and the figures in the record's units.

use super::super::{Bounds, Effect, FracModel, Param};
use crate::data::Record;

/// The smallest sampling step (in the record's unit) fitted as it is.
const MIN_DT: f64 = 1e-5;

/// The largest sampling step (in the record's unit) fitted as it is.
const MAX_DT: f64 = 1e2;

/// A change of the time unit: time values multiplied by `c` (a power of ten).
pub(super) struct TimeScale {
    c: f64,
    /// The order of the denominator's fixed term (its coefficient stays as it is).
    q_ref: f64,
}

impl TimeScale {
    /// The change of unit for `rec` and `m`, or `None` when the record's step is within
    /// `[MIN_DT, MAX_DT]` (fitted as it always was), or the model cannot be converted: effects,
    /// an initial state already in the model, a coefficient that is not one parameter (a product
    /// multiplied out), or no denominator term of fixed coefficient and order to normalise by.
    pub(super) fn of(rec: &Record, m: &FracModel) -> Option<Self> {
        if !m.effects.is_empty() || m.past.is_some() {
            return None;
        }
        Self::with_effects(rec.dt, m)
    }

    /// [`TimeScale::of`] for a model that may carry effects and an initial state (a diagnosis's
    /// refit, [`fit_in_unit`]): a sinusoid's frequency, a drift's rate and the past input's
    /// window edges are converted with the rest ([`TimeScale::model`]); the other effects are
    /// amplitudes.
    fn with_effects(dt: f64, m: &FracModel) -> Option<Self> {
        if (MIN_DT..=MAX_DT).contains(&dt) || !(dt.is_finite() && dt > 0.0) {
            return None;
        }
        let single = |e: &super::super::Expr| {
            e.factors.is_empty()
                && (e.terms.is_empty()
                    || e.constant == 0.0 && e.terms.len() == 1 && e.terms[0].1 == 1.0)
        };
        let terms = || m.num.iter().chain(&m.den);
        if !terms().all(|(c, _)| single(c)) {
            return None;
        }
        // Each coefficient its own parameter, and a held one only on a term of a held order
        // (held in one unit, it would not be held in the other while the order moves).
        let order_free = |o: &super::super::Expr| o.terms.iter().any(|&(i, _)| m.params[i].free);
        for (c, o) in terms() {
            if let Some(&(i, _)) = c.terms.first() {
                if terms().filter(|(d, _)| d.has(i)).count() > 1
                    || (!m.params[i].free && order_free(o))
                {
                    return None;
                }
            }
        }
        // The denominator term whose coefficient and order are fixed: the transfer function is
        // divided by `c^q_ref` so that it keeps its value.
        let fixed = |e: &super::super::Expr| e.terms.iter().all(|&(i, _)| !m.params[i].free);
        let q_ref = m
            .den
            .iter()
            .find(|(c, o)| fixed(c) && o.terms.is_empty())
            .map(|(_, o)| o.constant)?;
        // c brings dt into [0.01, 0.1): a step of 2e-6 times 1e4 is 0.02
        let c = 10f64.powi(-(dt.log10().floor() as i32) - 2);
        let c = if dt * c >= 0.1 {
            c / 10.0
        } else if dt * c < 0.01 {
            c * 10.0
        } else {
            c
        };
        Some(Self { c, q_ref })
    }

    /// The record in the new unit.
    pub(super) fn record(&self, rec: &Record) -> Record {
        let mut r = rec.clone();
        r.t.iter_mut().for_each(|t| *t *= self.c);
        r.dt *= self.c;
        r
    }

    /// `m` in the new unit (`dir = 1`) or back (`dir = -1`): each coefficient of `s^q` times
    /// `c^(q - q_ref)` at the model's values, the delay times `c`, the approximation band
    /// divided by `c`.
    pub(super) fn model(&self, m: &FracModel, dir: f64) -> FracModel {
        let mut out = m.clone();
        let p = m.values();
        let f = |q: f64| self.c.powf(dir * (q - self.q_ref));
        for (c, o) in m.num.iter().chain(&m.den) {
            if let Some(&(i, _)) = c.terms.first() {
                scale(&mut out.params[i], f(o.eval(&p)));
            }
        }
        if let Some(i) = m.delay {
            scale(&mut out.params[i], self.c.powf(dir));
        }
        if let Some((lo, hi)) = m.approx.band {
            let k = self.c.powf(-dir);
            out.approx.band = Some((lo * k, hi * k));
        }
        for e in &mut out.effects {
            match e {
                Effect::Sinusoid { freq_hz, .. } => *freq_hz *= self.c.powf(-dir),
                // A rate per unit of time.
                Effect::OutputDrift { r } => scale(&mut out.params[*r], self.c.powf(-dir)),
                _ => {}
            }
        }
        if let Some(past) = &mut out.past {
            past.edges.iter_mut().for_each(|t| *t *= self.c.powf(dir));
        }
        out
    }
}

/// `p`'s value and its range's bounds multiplied by `k` (a change of unit).
fn scale(p: &mut Param, k: f64) {
    p.value *= k;
    if let Bounds::Interval(lo, hi) = p.bounds {
        p.bounds = Bounds::Interval(lo * k, hi * k);
    }
}

/// The output-error fit ([`super::fit`]) of `m` on `u`, `y` sampled every `dt` in a time unit
/// the fit does not depend on: when `dt` is outside `[MIN_DT, MAX_DT]` the model (its effects
/// and initial state too) is converted to the unit [`TimeScale::of`] would choose, fitted there,
/// and its values converted back (each within its range); else the fit as it is. The fitted
/// values, in the record's unit. The diagnosis's refits go through it, so that a record's time
/// unit changes none of its decisions (issue 46, item 13, for the loop closed as for the plain fit).
///
/// # Errors
/// As [`super::fit`].
pub(crate) fn fit_in_unit(
    m: &FracModel,
    u: &[f64],
    y: &[f64],
    dt: f64,
    opts: &super::FitOptions,
) -> crate::Result<Vec<f64>> {
    let Some(ts) = TimeScale::with_effects(dt, m) else {
        return Ok(super::fit(m, u, y, dt, opts)?.values);
    };
    let mut there = ts.model(m, 1.0);
    let rep = super::fit(&there, u, y, dt * ts.c, opts)?;
    for (p, v) in there.params.iter_mut().zip(&rep.values) {
        p.value = *v;
    }
    let back = ts.model(&there, -1.0);
    Ok(back
        .params
        .iter()
        .zip(&m.params)
        .map(|(b, p)| match p.bounds {
            // the factor of a coefficient moves with the fitted orders: keep its range
            Bounds::Interval(lo, hi) => b.value.clamp(lo, hi),
            _ => b.value,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_converted_and_back_is_the_same_and_keeps_its_response() {
        let m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
        let rec = Record::from_samples(&[0.0; 64], &[0.0; 64], 2e-6).unwrap();
        let ts = TimeScale::of(&rec, &m).unwrap();
        assert_eq!(ts.c, 1e4);
        assert!((ts.record(&rec).dt - 0.02).abs() < 1e-15);
        let there = ts.model(&m, 1.0);
        // G(j w) in seconds equals G'(j w / c) in the new unit
        let (g, g2) = (
            m.tf(&m.values()).unwrap(),
            there.tf(&there.values()).unwrap(),
        );
        for w in [1.0, 30.0, 1e3] {
            let (a, b) = (g.freq_response(w), g2.freq_response(w / ts.c));
            assert!((a - b).norm() <= 1e-12 * a.norm(), "{a} {b}");
        }
        let back = ts.model(&there, -1.0);
        for (p, q) in back.params.iter().zip(&m.params) {
            assert!((p.value - q.value).abs() <= 1e-12 * q.value.abs(), "{p:?}");
        }
        // a step within the range is fitted as it is
        let ok = Record::from_samples(&[0.0; 64], &[0.0; 64], 1e-3).unwrap();
        assert!(TimeScale::of(&ok, &m).is_none());
    }

    #[test]
    fn a_drift_rate_is_converted_with_the_time_unit() {
        use super::super::super::Structure;
        let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
        let r = m.add_param(Param::new("y_drift", 2.5e3, Bounds::Interval(-1e4, 1e4)));
        m.effects.push(Effect::OutputDrift { r });
        let dt = 2e-6;
        let ts = TimeScale::with_effects(dt, &m).unwrap();
        let there = ts.model(&m, 1.0);
        assert!((there.params[r].value - 2.5e3 / ts.c).abs() <= 1e-12);
        assert_eq!(
            there.params[r].bounds,
            Bounds::Interval(-1e4 / ts.c, 1e4 / ts.c)
        );
        // the same samples in either unit: the ramp (10 at the end, beside a response of 6.8)
        // ends at the same value
        let u: Vec<f64> = (0..2000).map(|k| f64::from((k / 200) % 2 == 0)).collect();
        let (mut y, mut y2) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        m.simulate(&m.values(), &u, dt, &mut y).unwrap();
        there
            .simulate(&there.values(), &u, dt * ts.c, &mut y2)
            .unwrap();
        for (a, b) in y.iter().zip(&y2) {
            assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "{a} {b}");
        }
        let back = ts.model(&there, -1.0);
        assert!((back.params[r].value - 2.5e3).abs() <= 1e-9);
    }
}
