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
        let starts: Vec<FracModel> = distinct_starts(&taus, (max as f64 - 0.5) * dt)
            .into_iter()
            .map(|tau| {
                let mut m = st.model.clone();
                m.with_delay(tau, max as f64 * dt);
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

/// The refit's start delays `taus` (s), each at most `top`, in their order with repeats left out:
/// the grid's best point is often one of the lags' (a correlation peak at lag 0 or 1 gives
/// `dt` and `dt/2`, both on the grid), and a repeated start is the same refit again (the best
/// start is the first with the smallest sum of squares, [`crate::diagnose`], so leaving out a
/// later repeat changes nothing).
fn distinct_starts(taus: &[f64], top: f64) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(taus.len());
    for tau in taus.iter().map(|t| t.min(top)) {
        if !out.contains(&tau) {
            out.push(tau);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::distinct_starts;

    #[test]
    fn a_start_delay_is_refitted_once() {
        let dt = 1e-3;
        // a correlation peak at lag 1 whose grid point is one sample: dt, dt, dt/2
        assert_eq!(distinct_starts(&[dt, dt, 0.5 * dt], 9.5 * dt), vec![dt, 0.5 * dt]);
        // lag 0 with the grid's best at dt/2: dt/2, dt, dt/2
        assert_eq!(distinct_starts(&[0.5 * dt, dt, 0.5 * dt], 9.5 * dt), vec![0.5 * dt, dt]);
        // starts beyond the top are clamped first, then told apart
        assert_eq!(distinct_starts(&[3.0 * dt, dt, 2.0 * dt], 1.5 * dt), vec![1.5 * dt, dt]);
        // distinct starts are all kept, in their order
        assert_eq!(
            distinct_starts(&[2.5 * dt, dt, 2.0 * dt], 9.5 * dt),
            vec![2.5 * dt, dt, 2.0 * dt]
        );
    }
}
