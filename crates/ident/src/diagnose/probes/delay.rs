//! Input delay `e^(-tau s)`: the input acts later than the model assumes.
//!
//! Signature: the model resimulated over a grid `tau = j dt/2` (other parameters held), and the
//! residual-input cross-correlation at lags `>= 0`. A base fit with free orders bends them to
//! mimic a small delay, so the delay is also probed without a signature (joint refits from one and
//! two samples); it then ranks last and the held-out margin and BIC decide.

use super::{named, Candidate, Findings, Look, Probe};
use crate::oe::{FracModel, Structure};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Delay;

impl Probe for Delay {
    fn name(&self) -> &'static str {
        "delay"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let (ctx, st) = (look.ctx, look.st);
        if st.model.delay.is_some() {
            if !look.kept("delay") {
                found.reject(
                    "delay",
                    "not tested: the model already has a fitted delay".into(),
                );
            }
            return Ok(());
        }
        if ctx.lead != 0 {
            // The input is already advanced (a time-stamp skew kept): a delay on top would be
            // one time shift fitted twice.
            return Ok(());
        }
        let (s, dt) = (look.s(), ctx.dt);
        let max = ctx.opts.max_delay_samples.max(1);
        let mut best = (f64::INFINITY, 0.0);
        let mut y = vec![0.0; s];
        for j in 1..=2 * max {
            let tau = j as f64 * dt / 2.0;
            let mut m = st.model.clone();
            m.with_delay(tau, max as f64 * dt);
            let mut v = st.values.clone();
            v.push(tau);
            if m.simulate(&v, &ctx.u[..s], dt, &mut y).is_ok() {
                let ssr: f64 = (0..s).map(|k| (ctx.y[k] - y[k]).powi(2)).sum();
                if ssr < best.0 {
                    best = (ssr, tau);
                }
            }
        }
        let r2_held = (1.0 - best.0 / look.ee.max(1e-300)).max(0.0);
        let rc = crate::metrics::crosscorr(&look.e, &ctx.u[..s], 10);
        let (lag, peak) = rc
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map_or((0, 0.0), |(i, v)| (i as isize - 10, *v));
        // A significant residual-input correlation at a lag >= 0 (the model answers the input
        // sooner than the data) is the delay's own signature: its squared peak stands for the
        // evidence, and the refit starts at that lag as well.
        let bound = crate::metrics::bound99(s);
        let signature = lag >= 0 && peak.abs() > bound;
        let r2 = if signature {
            r2_held.max(peak * peak)
        } else {
            r2_held.max(ctx.opts.min_r2)
        };
        let mut taus = vec![best.1];
        if signature {
            taus.push(lag.max(1) as f64 * dt);
            taus.push((lag as f64 - 0.5).max(0.5) * dt);
        } else {
            taus.push(dt);
            taus.push(2.0 * dt);
        }
        let starts: Vec<FracModel> = taus
            .into_iter()
            .map(|tau| {
                let mut m = st.model.clone();
                m.with_delay(tau.min((max as f64 - 0.5) * dt), max as f64 * dt);
                m
            })
            .collect();
        found.candidates.push(Candidate {
            lead: None,
            name: "delay",
            key: "delay".into(),
            r2,
            evidence: format!(
                "a delay of {:.3e} s alone (other parameters held) explains {:.1}% of the residual \
                 sum of squares; residual-input cross-correlation peaks at lag {lag} ({peak:.3}, \
                 99% bound {bound:.3}){}",
                best.1,
                100.0 * r2_held,
                if signature {
                    ": the input acts later than the model assumes"
                } else {
                    "; probed by a joint refit from 1 and 2 samples"
                }
            ),
            starts,
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("tau", "tau")])
    }
}
