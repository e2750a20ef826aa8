//! A sign-blind speed sensor: it measures `|y|` (an encoder read without its direction, a
//! tachometer through a rectifier).
//!
//! Signature: the data keep one sign while the model output or the input reverses; the
//! rectified model output `|y| - y` regressed with the model's sensitivities. Signs are counted
//! with a dead band of three noise levels, so noise around zero (a rectified speed at rest reads
//! a little below zero) does not count as a change of sign. When the base model could not follow
//! the rectified data at all, extra starts restore the sign from a low-pass of the input.

use super::{Candidate, Findings, Look, Probe};
use crate::oe::{Effect, FracModel};
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
        let mut starts = vec![m.clone()];
        if !model_reverses {
            starts.extend(super::super::abs_starts(ctx, &m));
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
