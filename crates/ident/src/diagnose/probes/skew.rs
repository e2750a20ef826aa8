//! A negative delay: the output moves before the recorded input (a time-stamp skew of the
//! logger). Reported as a `delay` with a negative `tau`.
//!
//! Signature: the residual-input cross-correlation beyond the 99% bound at negative lags; integer
//! advances of the recorded input are searched with the model held, and the refit runs on the
//! advanced input.

use super::{Candidate, Findings, Look, Probe};
use crate::oe::FracModel;
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Skew;

impl Probe for Skew {
    fn name(&self) -> &'static str {
        "delay"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let (ctx, st) = (look.ctx, look.st);
        if ctx.lead != 0 {
            return Ok(());
        }
        // An advance on a model that already delays its input is one time shift fitted twice
        // (the output both lags and leads the input): the delay's own refit sets the shift, and
        // the final model (one `tau`) could not say the two. Not a timing skew.
        if st.model.delay.is_some() {
            if !look.kept("delay") {
                found.reject_as(
                    "delay<0",
                    "delay",
                    "not tested: an advance of the input (a time-stamp skew) with the model's \
                     fitted delay would be one time shift fitted twice"
                        .into(),
                );
            }
            return Ok(());
        }
        let (s, dt) = (look.s(), ctx.dt);
        let h = ctx.opts.max_delay_samples.max(1);
        let rc = crate::metrics::crosscorr(&look.e, &ctx.u[..s], h);
        let bound = crate::metrics::bound99(s);
        // rc[i] is lag i - h: negative lags are i < h.
        let (peak_i, neg_peak) = rc[..h]
            .iter()
            .enumerate()
            .fold((h, 0.0f64), |(bi, m), (i, v)| {
                if v.abs() > m {
                    (i, v.abs())
                } else {
                    (bi, m)
                }
            });
        let peak_lag = h - peak_i;
        if neg_peak <= bound {
            return Ok(());
        }
        // The smallest sum of squares over the advances, each given up as soon as its partial
        // sum reaches the best so far ([`crate::oe::FracModel::ssr_below`]: the same best).
        // The model is the same for every advance: its plant is built once
        // ([`crate::oe::FracModel::ssr_below_on`]: the same sums bit for bit).
        let mut best = (f64::INFINITY, 0usize);
        if let Ok(plant) = st.model.plant(&st.values, dt) {
            for m in 1..=h {
                let c = ctx.with_lead(m);
                if let Ok(Some(ssr)) =
                    st.model
                        .ssr_below_on(&plant, &st.values, &c.u[..s], &ctx.y[..s], dt, best.0)
                {
                    best = (ssr, m);
                }
            }
        }
        let mut r2 = (1.0 - best.0 / look.ee.max(1e-300)).max(0.0);
        // The model fitted to the skewed record has bent its dynamics to follow it, so the
        // advance alone may gain nothing before the refit: a cross-correlation beyond three
        // times the bound is evidence enough to refit, at the peak's lag.
        if neg_peak > 3.0 * bound && r2 < ctx.opts.min_r2 {
            r2 = ctx.opts.min_r2;
            best.1 = peak_lag;
        }
        found.candidates.push(Candidate {
            lead: Some(best.1),
            name: "delay",
            key: "delay<0".into(),
            r2,
            evidence: format!(
                "the residual correlates with the input up to {neg_peak:.3} at lag -{peak_lag} \
                 (bound {bound:.3}): the output moves before the recorded input; advancing the \
                 input by {} samples ({:.3e} s, a time-stamp skew) alone explains {:.1}% of the \
                 residual sum of squares before the refit",
                best.1,
                best.1 as f64 * dt,
                100.0 * r2
            ),
            starts: vec![st.model.clone()],
        });
        Ok(())
    }

    fn params(&self, _: &FracModel, _: &[f64]) -> BTreeMap<String, f64> {
        // The advance is not a model parameter: the loop reports it as a negative tau.
        BTreeMap::new()
    }
}
