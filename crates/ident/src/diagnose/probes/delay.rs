//! Input delay `e^(-tau s)`: the input acts later than the model assumes.
//!
//! Signature: the model resimulated over a grid `tau = j dt/2` (other parameters held), and the
//! residual-input cross-correlation at lags `>= 0`. A base fit with free orders bends them to
//! mimic a small delay, so the delay is also probed without a signature (joint refits from one and
//! two samples); it then ranks last and the held-out margin and BIC decide.

use super::{named, Candidate, Findings, Look, Probe};
use crate::diagnose::{Ctx, RejectedEffect, State};
use crate::oe::FracModel;
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
        // The grid's smallest sum of squares: a delay whose partial sum already reaches the best
        // so far is given up there ([`FracModel::ssr_below`]; the same best, most delays of the
        // grid far from it cost a few thousand samples instead of the record).
        // The plant's modal form does not depend on the delay: built once for the grid
        // ([`FracModel::ssr_below_on`]: the same sums bit for bit).
        let mut best = (f64::INFINITY, 0.0);
        if let Ok(plant) = st.model.plant(&st.values, dt) {
            let mut m = st.model.clone();
            let mut v = st.values.clone();
            m.with_delay(0.0, max as f64 * dt);
            v.push(0.0);
            for j in 1..=2 * max {
                let tau = j as f64 * dt / 2.0;
                m.with_delay(tau, max as f64 * dt);
                *v.last_mut().expect("the delay was pushed") = tau;
                if let Ok(Some(ssr)) =
                    m.ssr_below_on(&plant, &v, &ctx.u[..s], &ctx.y[..s], dt, best.0)
                {
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

    fn in_place_of(
        &self,
        ctx: &Ctx<'_>,
        before: &State,
        kept: &State,
    ) -> Option<(State, RejectedEffect)> {
        crate::diagnose::lag::in_place(ctx, before, kept)
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
    use crate::oe::{FracModel, Structure};

    /// `m`'s values with its three past held-input levels at 0.7, -0.4, 0.2 (an initial state
    /// away from rest).
    fn past_levels_set(m: &FracModel) -> Vec<f64> {
        let mut v = m.values();
        for (i, level) in m.past.as_ref().unwrap().levels.iter().zip([0.7, -0.4, 0.2]) {
            v[*i] = level;
        }
        v
    }

    /// [`FracModel::ssr_below`] against the model simulated whole and the sum taken after it
    /// (the delay grid's former way): the same sum bit for bit on a model with a fractional
    /// delay, a past held input (the initial state) and an output offset over 20000 samples (a
    /// few chunks), `None` exactly when the sum is not below the limit; and a model with an input
    /// effect (a saturation: the whole run) the same.
    #[test]
    fn the_chunked_sum_of_squares_is_the_whole_runs() {
        let dt = 5e-4;
        let n = 20_000;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 173) % 3 == 0 { 1.0 } else { -0.5 })
            .collect();
        let y: Vec<f64> = (0..n).map(|k| 2.0 * (k as f64 * 1e-3).sin()).collect();
        let mut m = FracModel::pmsm(6.8, 0.0064, 2.8e-5, 0.89, 0.89);
        m.with_delay(2.5 * dt, 10.0 * dt);
        m.with_past_input(vec![0.01, 0.05], (-3.0, 3.0));
        m.with_output_offset(0.3);
        let v = past_levels_set(&m);
        let whole = |m: &FracModel, v: &[f64]| {
            let mut yhat = vec![0.0; n];
            m.simulate(v, &u, dt, &mut yhat).unwrap();
            (0..n).map(|k| (y[k] - yhat[k]).powi(2)).sum::<f64>()
        };
        let ssr = whole(&m, &v);
        assert!(ssr > 0.0 && ssr.is_finite());
        assert_eq!(
            m.ssr_below(&v, &u, &y, dt, f64::INFINITY).unwrap(),
            Some(ssr)
        );
        assert_eq!(
            m.ssr_below(&v, &u, &y, dt, ssr * (1.0 + 1e-12)).unwrap(),
            Some(ssr)
        );
        assert_eq!(m.ssr_below(&v, &u, &y, dt, ssr).unwrap(), None);
        assert_eq!(m.ssr_below(&v, &u, &y, dt, 0.5 * ssr).unwrap(), None);
        // An input effect: simulated whole, the same rule.
        let mut sat = m.clone();
        let level = sat.add_param(crate::oe::Param::new(
            "level",
            0.8,
            crate::oe::Bounds::Positive,
        ));
        sat.effects.push(crate::oe::Effect::Saturation { level });
        let mut w = v.clone();
        w.push(0.8);
        let ssr = whole(&sat, &w);
        assert_eq!(
            sat.ssr_below(&w, &u, &y, dt, f64::INFINITY).unwrap(),
            Some(ssr)
        );
        assert_eq!(sat.ssr_below(&w, &u, &y, dt, ssr).unwrap(), None);
    }

    /// The grid's way ([`FracModel::ssr_below_on`], the plant built once from the model without
    /// delay, a delay parameter reset per point) against today's ([`FracModel::ssr_below`] of the
    /// model cloned with the delay: its own simulator): the same sums BIT FOR BIT (the
    /// diagnosis's decisions hang on the grid's smallest sum) for fractional and whole-sample
    /// delays, the first in the head only, with a past held input and an output offset over 9000
    /// samples (a few chunks), with no limit and with limits that give up early; on inputs
    /// advanced by a few samples (the skew probe's use: one model, several inputs) the same.
    #[test]
    fn the_plant_built_once_gives_the_grids_sums_bit_for_bit() {
        let dt = 5e-4;
        let n = 9_000;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 97) % 3 == 0 { 1.3 } else { -0.4 })
            .collect();
        let y: Vec<f64> = (0..n)
            .map(|k| 1.5 * (k as f64 * 2e-3).sin() + 0.1)
            .collect();
        let mut base = FracModel::pmsm(6.8, 0.0064, 2.8e-5, 0.89, 0.89);
        base.with_past_input(vec![0.01, 0.05], (-3.0, 3.0));
        base.with_output_offset(0.3);
        let v0 = past_levels_set(&base);
        let plant = base.plant(&v0, dt).unwrap();
        let max = 10;
        let (mut reused, mut v) = (base.clone(), v0.clone());
        reused.with_delay(0.0, max as f64 * dt);
        v.push(0.0);
        let mut sums = vec![];
        for j in [1, 2, 3, 4, 5, 9, 14, 20] {
            let tau = j as f64 * dt / 2.0;
            let mut today = base.clone();
            today.with_delay(tau, max as f64 * dt);
            reused.with_delay(tau, max as f64 * dt);
            *v.last_mut().unwrap() = tau;
            let whole = today.ssr_below(&v, &u, &y, dt, f64::INFINITY).unwrap();
            let ssr = whole.unwrap();
            assert!(ssr > 0.0 && ssr.is_finite());
            sums.push(ssr);
            for limit in [
                f64::INFINITY,
                ssr * (1.0 + 1e-12),
                ssr,
                0.5 * ssr,
                1e-3 * ssr,
            ] {
                let a = today.ssr_below(&v, &u, &y, dt, limit).unwrap();
                let b = reused.ssr_below_on(&plant, &v, &u, &y, dt, limit).unwrap();
                assert_eq!(
                    a.map(f64::to_bits),
                    b.map(f64::to_bits),
                    "delay {j}/2 samples, limit {limit}"
                );
            }
        }
        // The delays do move the sum (the comparison is not of one number).
        assert!(sums.windows(2).all(|w| w[0] != w[1]), "{sums:?}");
        // One model, inputs advanced (the skew probe): the plant of the model itself.
        for lead in [1, 2, 5] {
            let a = base.ssr_below(&v0, &u[lead..], &y[..n - lead], dt, f64::INFINITY);
            let b = base.ssr_below_on(&plant, &v0, &u[lead..], &y[..n - lead], dt, f64::INFINITY);
            let (a, b) = (a.unwrap().unwrap(), b.unwrap().unwrap());
            assert_eq!(a.to_bits(), b.to_bits(), "lead {lead}");
        }
    }

    #[test]
    fn a_start_delay_is_refitted_once() {
        let dt = 1e-3;
        // a correlation peak at lag 1 whose grid point is one sample: dt, dt, dt/2
        assert_eq!(
            distinct_starts(&[dt, dt, 0.5 * dt], 9.5 * dt),
            vec![dt, 0.5 * dt]
        );
        // lag 0 with the grid's best at dt/2: dt/2, dt, dt/2
        assert_eq!(
            distinct_starts(&[0.5 * dt, dt, 0.5 * dt], 9.5 * dt),
            vec![0.5 * dt, dt]
        );
        // starts beyond the top are clamped first, then told apart
        assert_eq!(
            distinct_starts(&[3.0 * dt, dt, 2.0 * dt], 1.5 * dt),
            vec![1.5 * dt, dt]
        );
        // distinct starts are all kept, in their order
        assert_eq!(
            distinct_starts(&[2.5 * dt, dt, 2.0 * dt], 9.5 * dt),
            vec![2.5 * dt, dt, 2.0 * dt]
        );
    }
}
