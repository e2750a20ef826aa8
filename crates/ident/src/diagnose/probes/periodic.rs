//! An additive output sinusoid at a fixed frequency (torque ripple, a cogging or encoder
//! harmonic, mains pickup): `a cos(2 pi f t) + b sin(2 pi f t)`.
//!
//! Signature: a narrow peak of the residual spectrum ([`super::super::residual::spectral_peaks`]),
//! its cosine and sine columns regressed with the model's sensitivities. A peak at a harmonic of
//! the input's own period is the excitation (the model misses the response to a repeated
//! reference), not a disturbance: it is rejected, as is a peak where the input's own spectrum has
//! a narrow line (a multisine whose period the record does not repeat), a peak with fewer than
//! [`MIN_PERIODS`] periods in the estimation part, and one with fewer than [`FEW_PERIODS`] whose
//! sinusoid explains less than [`FEW_PERIODS_R2`] of the residual. The input's period is found
//! exactly when the input repeats sample for sample ([`crate::oe::init::periodic_part`]), else
//! from the input's autocorrelation ([`input_period`]).

use super::{Candidate, Findings, Look, Probe};
use crate::oe::{Bounds, Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Periodic;

/// A residual peak with fewer periods than this in the estimation part is not taken for a
/// periodic disturbance: several periods are the evidence that it repeats (issue 29: on a
/// thermal record a "period" of a third of the record absorbed a static input nonlinearity).
const MIN_PERIODS: f64 = 4.0;

/// Below this many periods (and from [`MIN_PERIODS`]) a peak is taken for a periodic disturbance
/// only when its sinusoid alone explains [`FEW_PERIODS_R2`] of the residual's sum of squares: the
/// zoo's case 0192 of seed 46, a sinusoid of 4.9 periods, explains 96.9%; on its 0247 of seed 44 a
/// peak of 5.1 periods explaining 46% stood in for a sign-blind sensor's distortion.
const FEW_PERIODS: f64 = 6.0;

/// The share of the residual's sum of squares a peak of fewer than [`FEW_PERIODS`] periods must
/// explain alone.
const FEW_PERIODS_R2: f64 = 0.5;

/// The autocorrelation an input must reach at a lag to be called periodic with that period.
const PERIODIC_R: f64 = 0.5;

/// The period (seconds) of an input that repeats, exactly or approximately: the lag of the
/// highest normalised autocorrelation `r(L) >= 0.5` after it first falls below 0.3, with at
/// least two periods in the record. The input is block-averaged to at most 2048 samples first
/// (the period of a repeated reference is long against the sampling step), so the cost is
/// `O(2048^2)` whatever the record's length. `None` for an input that does not repeat.
pub(crate) fn input_period(u: &[f64], dt: f64) -> Option<f64> {
    if let Some((_, p)) = crate::oe::init::periodic_part(u) {
        return Some(p as f64 * dt);
    }
    let m = u.len().div_ceil(2048).max(1);
    let x: Vec<f64> = u
        .chunks(m)
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect();
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let x: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let var: f64 = x.iter().map(|v| v * v).sum::<f64>() / n as f64;
    if !(var > 0.0) || n < 16 {
        return None;
    }
    let r = |l: usize| -> f64 {
        (0..n - l).map(|k| x[k] * x[k + l]).sum::<f64>() / ((n - l) as f64 * var)
    };
    let rs: Vec<f64> = (0..=n / 2).map(r).collect();
    let first_low = rs.iter().position(|v| *v < 0.3)?;
    let (l, best) = rs
        .iter()
        .enumerate()
        .skip(first_low)
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    if *best < PERIODIC_R || l + 1 >= rs.len() {
        return None;
    }
    // Parabolic refinement of the peak.
    let (a, b, c) = (rs[l - 1], rs[l], rs[l + 1]);
    let den = a - 2.0 * b + c;
    let d = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
    Some((l as f64 + d.clamp(-0.5, 0.5)) * m as f64 * dt)
}

impl Probe for Periodic {
    fn name(&self) -> &'static str {
        "periodic"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let (ctx, st) = (look.ctx, look.st);
        let (s, dt) = (look.s(), ctx.dt);
        let an = &look.analysis;
        let period = input_period(&ctx.u, dt);
        // The input's lines, its periodogram made for the first peak that needs them.
        let mut input_lines = None;
        for pk in an.peaks.iter().take(2) {
            let near_kept = st.model.effects.iter().any(|ef| {
                matches!(ef, Effect::Sinusoid { freq_hz, .. }
                    if (freq_hz - pk.freq_hz).abs() < 2.0 / (s as f64 * dt))
            });
            if near_kept {
                continue;
            }
            let key = format!("periodic@{:.4}Hz", pk.freq_hz);
            if let Some(p) = period {
                let r = pk.freq_hz * p;
                if r.round() >= 1.0 && (r - r.round()).abs() < 0.1 {
                    found.reject_as(
                        &key,
                        "periodic",
                        format!(
                            "spectral peak at {:.4} Hz is harmonic {} of the input's own period \
                             ({p:.4} s): the excitation (a model error at that frequency), not a \
                             disturbance",
                            pk.freq_hz,
                            r.round()
                        ),
                    );
                    continue;
                }
            }
            let line_at =
                input_lines.get_or_insert_with(|| super::super::residual::lines(&ctx.u[..s], dt));
            if let Some(ratio) = line_at(pk.freq_hz) {
                found.reject_as(
                    &key,
                    "periodic",
                    format!(
                        "spectral peak at {:.4} Hz is a line of the input's own spectrum ({ratio:.0} \
                         times its neighbouring median: a multisine's, or a periodic input's with \
                         too few periods to be found): the excitation (a model error at that \
                         frequency), not a disturbance",
                        pk.freq_hz
                    ),
                );
                continue;
            }
            let periods = pk.freq_hz * s as f64 * dt;
            if periods < MIN_PERIODS {
                found.reject_as(
                    &key,
                    "periodic",
                    format!(
                        "spectral peak at {:.4} Hz has only {periods:.1} periods in the estimation \
                         part: a periodic disturbance needs at least {MIN_PERIODS} periods of \
                         evidence (a slow drift, or a static nonlinearity the effects do not \
                         include, leaves a peak at the record's lowest frequencies; a sinusoid \
                         fitted to it would not extrapolate)",
                        pk.freq_hz
                    ),
                );
                continue;
            }
            let w = 2.0 * std::f64::consts::PI * pk.freq_hz;
            let c: Vec<f64> = (0..s).map(|k| (w * k as f64 * dt).cos()).collect();
            let sn: Vec<f64> = (0..s).map(|k| (w * k as f64 * dt).sin()).collect();
            let (r2, beta) = look.direct(&[c, sn]);
            if periods < FEW_PERIODS && r2 < FEW_PERIODS_R2 {
                found.reject_as(
                    &key,
                    "periodic",
                    format!(
                        "spectral peak at {:.4} Hz has {periods:.1} periods in the estimation part \
                         and explains {:.1}% of the residual sum of squares: with fewer than \
                         {FEW_PERIODS} periods a periodic disturbance must explain {:.0}% alone",
                        pk.freq_hz,
                        100.0 * r2,
                        100.0 * FEW_PERIODS_R2
                    ),
                );
                continue;
            }
            let mut m = st.model.clone();
            let n = sinusoids(&st.model).count();
            let a = m.add_param(Param::new(&format!("sin{n}_a"), beta[0], Bounds::Free));
            let b = m.add_param(Param::new(&format!("sin{n}_b"), beta[1], Bounds::Free));
            m.effects.push(Effect::Sinusoid {
                freq_hz: pk.freq_hz,
                a,
                b,
            });
            found.candidates.push(Candidate {
                lead: None,
                name: "periodic",
                key,
                r2,
                evidence: format!(
                    "narrow residual spectrum peak at {:.4} Hz, {:.0} times the neighbouring \
                     median, amplitude about {:.3e}; explains {:.1}% of the residual sum of \
                     squares{}",
                    pk.freq_hz,
                    pk.ratio,
                    pk.amplitude,
                    100.0 * r2,
                    match period {
                        Some(p) => format!(" (not a harmonic of the input's period {p:.4} s)"),
                        None => " (the input does not repeat)".into(),
                    }
                ),
                starts: vec![m],
            });
        }
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        // The last sinusoid added.
        let mut m = BTreeMap::new();
        if let Some(Effect::Sinusoid { freq_hz, a, b }) = sinusoids(model).last() {
            m.insert("freq_hz".into(), *freq_hz);
            m.insert("amplitude".into(), values[*a].hypot(values[*b]));
            m.insert("phase_rad".into(), (-values[*b]).atan2(values[*a]));
        }
        m
    }
}

fn sinusoids(m: &FracModel) -> impl Iterator<Item = &Effect> {
    m.effects
        .iter()
        .filter(|e| matches!(e, Effect::Sinusoid { .. }))
}
