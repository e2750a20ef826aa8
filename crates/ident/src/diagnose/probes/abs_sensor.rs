//! A sign-blind speed sensor: it measures `|y|` (an encoder read without its direction, a
//! tachometer through a rectifier).
//!
//! Signature: the data keep one sign while the model output or the input reverses; the
//! rectified model output `|y| - y` regressed with the model's sensitivities. Signs are counted
//! with a dead band of three noise levels, so noise around zero (a rectified speed at rest reads
//! a little below zero) does not count as a change of sign. When the base model could not follow
//! the rectified data at all, extra starts restore the sign from a low-pass of the input. The
//! model's zero is located by an input offset fitted with it (the operating point was read from
//! rectified data, so the deviation scale's zero is not the speed's).

use super::{Candidate, Findings, Look, Probe};
use crate::oe::{Bounds, Effect, FracModel, Param, Structure};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct AbsSensor;

impl Probe for AbsSensor {
    fn name(&self) -> &'static str {
        "abs_sensor"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let (ctx, st) = (look.ctx, look.st);
        if st
            .model
            .effects
            .iter()
            .any(|e| matches!(e, Effect::AbsSensor))
        {
            return Ok(());
        }
        let band = 3.0 * look.noise;
        let n = ctx.rec.len() as f64;
        let yd_neg = ctx.rec.y.iter().filter(|v| **v < -band).count() as f64 / n;
        let yd_pos = ctx.rec.y.iter().filter(|v| **v > band).count() as f64 / n;
        let u_neg = look.ua.iter().filter(|v| **v < 0.0).count() as f64 / n;
        let u_pos = look.ua.iter().filter(|v| **v > 0.0).count() as f64 / n;
        let model_reverses = look.motion.reverses();
        let data_one_signed = yd_neg.min(yd_pos) < 0.01;
        let input_reverses = u_neg.min(u_pos) >= 0.1;
        if !(data_one_signed && (model_reverses || input_reverses)) {
            if !look.kept("abs_sensor") {
                found.reject(
                    "abs_sensor",
                    if data_one_signed {
                        format!(
                            "no signature: the data keep one sign (beyond a noise band of \
                             +-{band:.2e}), but neither the model output nor the input reverses"
                        )
                    } else {
                        format!(
                            "no signature: the data take both signs beyond the noise band \
                             +-{band:.2e} (+{:.0}% / -{:.0}% of the samples)",
                            100.0 * yd_pos,
                            100.0 * yd_neg
                        )
                    },
                );
            }
            return Ok(());
        }
        let s = look.s();
        let sig: Vec<f64> = look.ya[..s].iter().map(|v| v.abs() - v).collect();
        let (r2, _) = look.direct(&[sig]);
        let mut m = st.model.clone();
        // Before the existing output effects: an output offset then acts after it, `|x| + c`.
        m.effects.insert(0, Effect::AbsSensor);
        // Where the speed is zero is unknown: the operating point was taken from rectified data.
        // An input offset locates it (through the gain it is the constant inside |.|); the
        // sign-restored starts carry theirs.
        let mut first = m.clone();
        if !look.has("u_offset") {
            with_zero_offset(&mut first, ctx.u0, ctx.y0);
        }
        let mut starts = vec![first];
        if !model_reverses {
            starts.extend(sign_restored_starts(look, &m));
        }
        found.candidates.push(Candidate {
            lead: None,
            name: "abs_sensor",
            key: "abs_sensor".into(),
            r2: if model_reverses {
                r2
            } else {
                r2.max(ctx.opts.min_r2)
            },
            evidence: format!(
                "the data are {} beyond the noise band +-{band:.2e} in {:.1}% of the samples \
                 while the {} reverses; the rectified model output explains {:.1}% of the \
                 residual sum of squares",
                if yd_neg < yd_pos {
                    "non-negative"
                } else {
                    "non-positive"
                },
                100.0 * (1.0 - yd_neg.min(yd_pos)),
                if model_reverses {
                    "model output"
                } else {
                    "input"
                },
                100.0 * r2
            ),
            starts,
        });
        Ok(())
    }

    fn params(&self, _: &FracModel, _: &[f64]) -> BTreeMap<String, f64> {
        BTreeMap::new()
    }
}

/// Add the sensor's zero `c_u = u0 - y0/K` ([`Effect::SensorZero`]: the model's zero is then the
/// plant's, `y0 + K (c_u - u0) = 0` at the operating point).
fn with_zero_offset(m: &mut FracModel, u0: f64, y0: f64) {
    let k = m.index_of("K").map_or(0.0, |i| m.params[i].value);
    let c = if k.abs() > 0.0 && k.is_finite() {
        u0 - y0 / k
    } else {
        0.0
    };
    let i = m.add_param(Param::new("u_offset", c, Bounds::Free));
    m.effects.insert(0, Effect::SensorZero { c: i });
}

/// Starts for the refit when the base model could not follow the rectified data (a linear fit of
/// `|y|` tends to a zero gain): the sign is restored from a first-order low-pass of the absolute
/// input, `y_s = |y| sign(lp_T(u))`, for `T` on a log grid of 8 values from `2 dt` to a twentieth
/// of the record, and the automatic start ([`crate::oe::init::auto_start`]) is made on the
/// absolute `(u, y_s)` (the plant's zero is the signals' zero); the 2 starts whose rectified
/// output is closest to the data are returned, with the input offset that
/// locates the zero ([`with_zero_offset`]) when the model has none.
fn sign_restored_starts(look: &Look<'_>, m: &FracModel) -> Vec<FracModel> {
    let ctx = look.ctx;
    let (s, dt) = (look.s(), ctx.dt);
    let ua = &look.ua[..s];
    let tmax = (s as f64 * dt / 20.0).max(4.0 * dt);
    let mut scored: Vec<(f64, FracModel)> = vec![];
    for i in 0..8 {
        let t = 2.0 * dt * (tmax / (2.0 * dt)).powf(i as f64 / 7.0);
        let a = (-dt / t).exp();
        let mut lp = 0.0;
        let ys: Vec<f64> = (0..s)
            .map(|k| {
                lp = a * lp + (1.0 - a) * ua[k];
                ctx.rec.y[k].abs() * if lp < 0.0 { -1.0 } else { 1.0 }
            })
            .collect();
        let mut c = m.clone();
        if crate::oe::init::auto_start(&mut c, ua, &ys, dt, ctx.opts.fit.lm.par).is_err() {
            continue;
        }
        if let Some(i) = c.index_of("y_offset") {
            c.params[i].value = 0.0;
        }
        for p in &mut c.params {
            p.value = p.bounds.clamp_inside(p.value);
        }
        if !look.has("u_offset") {
            with_zero_offset(&mut c, ctx.u0, ctx.y0);
        }
        let mut y = vec![0.0; s];
        if c.simulate(&c.values(), &ctx.u[..s], dt, &mut y).is_ok() {
            let ssr: f64 = (0..s).map(|k| (ctx.y[k] - y[k]).powi(2)).sum();
            if ssr.is_finite() {
                scored.push((ssr, c));
            }
        }
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored.into_iter().take(2).map(|(_, c)| c).collect()
}
