//! Closing the loop: residual diagnosis and the effect library (docs/design.md §6).
//!
//! After a time-domain fit ([`crate::oe::identify`]), [`diagnose`] looks at what the model cannot
//! explain, tests the residual against the signature of each effect of the library, refits the
//! model with each strong candidate by the same output-error machinery ([`crate::oe::fit`]), and
//! keeps an effect only when it pays on held-out data. [`freq::diagnose_bode`] does the same for a
//! frequency response.
//!
//! # Evidence
//! For each candidate the signature is the change of the model output the effect would make, to
//! first order (the output sensitivity to the effect's parameter at "no effect"); the evidence is the
//! fraction `R^2` of the estimation residual's sum of squares that the signature explains after
//! the model's own sensitivities are projected out ([`residual::explained`], a score test).
//! Candidates with `R^2 >= ` [`DiagnoseOptions::min_r2`] are refitted, strongest first.
//!
//! | effect | signature (deviation scale, `G` the fitted linear part) | parameters, how fitted |
//! |---|---|---|
//! | `delay` | best of a grid `tau = j dt/2` (the model resimulated) | `tau` in `(0, max)`, then LM |
//! | `coulomb_friction` | `G * (-sign(y0 + yhat_prev))` | `Vc > 0`, LM (see below) |
//! | `offset` (input) | `G * 1` | `u_offset`, LM |
//! | `offset` (output) | `1` | `y_offset`, LM |
//! | `periodic` | `cos, sin (2 pi f t)`, `f` a spectral peak | `f` fixed at the peak; cosine and sine amplitudes, LM |
//! | `abs_sensor` | `abs(y0 + yhat) - (y0 + yhat)` | none; the linear part is refitted |
//! | `saturation` | `G * (clamp(u, -L, L) - u)` over a grid of `L` | `L > 0`: grid, then LM |
//! | `deadzone` | `G * (dz_w(u) - u)` over a grid of `w` | `w > 0`: grid, then LM |
//! | `quantization` | few distinct output levels on a grid of step `q` | not fitted: noise floor `q/sqrt(12)` |
//!
//! Non-smooth effects. Sign, clamp and dead band are piecewise linear in their parameter: their
//! derivative with respect to `Vc`, `L` or `w` is exact wherever the signal is not exactly at a
//! switching point (a set of measure zero on sampled data), so LM runs on the exact piecewise
//! derivative. What is not smooth is *where* the pieces switch; that is handled by a 1-D search
//! over the threshold (`L`, `w`, `tau`) with the linear parameters refitted by least squares on the
//! linearised model (the regression of [`residual::explained`]), and LM starts from the best grid
//! point. Friction switches with the sign of the model's own previous output; its threshold is 0,
//! so only the magnitude `Vc` is fitted, started from the regression coefficient.
//!
//! # Decision
//! An effect is kept when (a) the validation RMSE falls by at least [`DiagnoseOptions::margin`]
//! (default 5%: the standard error of an RMSE ratio over `N` validation samples of noise is about
//! `1/sqrt(2N)`, 2% for `N = 1000`, so 5% is 2.5 standard errors), (b) BIC
//! `N ln(SSR/N) + k ln N` on the estimation part falls (the added parameters must pay `ln N` each),
//! and (c) no parameter ran to a bound. The best kept candidate of a round is added; the loop repeats
//! (at most [`DiagnoseOptions::max_rounds`]) while something is kept. Without a validation part the
//! margin is applied to the estimation RMSE.
//!
//! # Identifiability
//! An effect the input cannot reveal is reported in [`Diagnosis::ambiguous`], never fitted:
//! friction when the model speed never changes sign (`Vc sign(y)` is then a constant input offset);
//! saturation and dead band when the input has two levels (any static input map is then affine:
//! a gain and an offset).

pub mod freq;
pub mod residual;

use crate::data::Record;
use crate::metrics::Fit;
use crate::oe::effects::sign;
use crate::oe::{
    fit, sensitivities, Bounds, Effect, FitOptions, FracModel, Identification, Param, Structure,
};
use crate::{Error, Result};
use residual::{analyse, explained, ResidualAnalysis};
use serde::Serialize;
use std::collections::BTreeMap;

/// Options of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    /// Relative fall of the validation RMSE an effect must bring (default 0.05).
    pub margin: f64,
    /// Evidence `R^2` a candidate needs to be refitted (default 0.005: it must explain half a
    /// percent of the residual's sum of squares; for `N = 3000` white samples `N R^2 = 15`, beyond
    /// the 99.9% point of `chi^2(2)`).
    pub min_r2: f64,
    /// Rounds of the loop (default 3).
    pub max_rounds: usize,
    /// Largest delay searched, in samples (default 50).
    pub max_delay_samples: usize,
    /// Candidates refitted per round, strongest first (default 4).
    pub max_refits: usize,
    /// The output-error fit options of the refits (default: 60 LM iterations).
    pub fit: FitOptions,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        let mut fit = FitOptions::default();
        fit.lm.max_iterations = 60;
        Self {
            margin: 0.05,
            min_r2: 0.005,
            max_rounds: 3,
            max_delay_samples: 50,
            max_refits: 4,
            fit,
        }
    }
}

/// An effect kept by the diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KeptEffect {
    /// Report name (docs/design.md §6 table).
    pub name: String,
    /// Its fitted parameters (SI units of the record).
    pub params: BTreeMap<String, f64>,
    /// What in the residual pointed to it, and what the refit gained.
    pub evidence: String,
    /// The evidence `R^2` (fraction of the residual's sum of squares its signature explains).
    pub r2: f64,
    /// Relative change of the validation (or estimation) RMSE, percent (negative is better).
    pub rmse_change_percent: f64,
    /// Change of BIC on the estimation part (negative is better).
    pub bic_change: f64,
}

/// A candidate that was tested and not kept, or could not be tested.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RejectedEffect {
    /// Report name.
    pub name: String,
    /// Why.
    pub reason: String,
    /// Its fitted parameters, when it was refitted.
    pub params: BTreeMap<String, f64>,
}

/// An effect the input cannot separate from another explanation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ambiguity {
    /// Report name of the effect.
    pub name: String,
    /// What it cannot be told from.
    pub confused_with: String,
    /// Why, and what experiment would separate them.
    pub reason: String,
}

/// Output quantization found in the data (reported, not fitted).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Quantization {
    /// The step between output levels.
    pub step: f64,
    /// Distinct output levels in the record.
    pub levels: usize,
    /// The RMS error the quantizer alone adds, `step / sqrt(12)`.
    pub noise_floor_rms: f64,
}

/// Error before and after on one part of the record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BeforeAfter {
    /// With the base model.
    pub before: Fit,
    /// With the kept effects.
    pub after: Fit,
}

/// The result of [`diagnose`] (serialises to the docs/design.md §7 `diagnosis` object).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Validation fit of the base model (estimation fit when there is no validation part).
    pub before: Fit,
    /// The same with the kept effects.
    pub after: Fit,
    /// Estimation part before and after.
    pub estimation: BeforeAfter,
    /// Validation part before and after.
    pub validation: Option<BeforeAfter>,
    /// Effects kept, in the order they were added.
    pub effects: Vec<KeptEffect>,
    /// Candidates tested and rejected (or not testable), with the reason.
    pub rejected: Vec<RejectedEffect>,
    /// Effects these data cannot identify.
    pub ambiguous: Vec<Ambiguity>,
    /// Output quantization, if found.
    pub quantization: Option<Quantization>,
    /// Whether structure remains in the final residual that no effect explains.
    pub unexplained: bool,
    /// What remains (empty when nothing does).
    pub remaining: Vec<String>,
    /// Residual tests of the base model (estimation part).
    pub residual_before: ResidualAnalysis,
    /// Residual tests of the final model (estimation part).
    pub residual_after: ResidualAnalysis,
    /// The final model (fitted values in its parameters).
    #[serde(skip)]
    pub model: FracModel,
    /// Base model output on the absolute scale, whole record.
    #[serde(skip)]
    pub yhat_before: Vec<f64>,
    /// Final model output on the absolute scale, whole record.
    #[serde(skip)]
    pub yhat_after: Vec<f64>,
    /// First validation sample.
    #[serde(skip)]
    pub split: usize,
}

/// A fitted model and its scores.
#[derive(Clone)]
struct State {
    model: FracModel,
    values: Vec<f64>,
    /// Deviation-scale output, whole record.
    yhat: Vec<f64>,
    est: Fit,
    val: Option<Fit>,
    ssr: f64,
}

#[derive(Clone)]
struct Ctx<'a> {
    rec: &'a Record,
    /// Input deviations, advanced by `lead` samples.
    u: Vec<f64>,
    /// Samples by which the recorded input is advanced (a negative delay: the recorded input
    /// lags the output, a time-stamp skew of the logger).
    lead: usize,
    y: Vec<f64>,
    split: usize,
    dt: f64,
    u0: f64,
    y0: f64,
    /// The base fit's starting values.
    start: Vec<f64>,
    opts: &'a DiagnoseOptions,
}

impl Ctx<'_> {
    /// The same context with the recorded input advanced by `lead` samples
    /// (`u'_k = u_(k + lead)`, the last value held).
    fn with_lead(&self, lead: usize) -> Self {
        let n = self.rec.len();
        let mut c = self.clone();
        c.lead = lead;
        c.u = (0..n)
            .map(|k| self.rec.u[(k + lead).min(n - 1)] - self.u0)
            .collect();
        c
    }

    fn state(&self, model: FracModel, values: Vec<f64>) -> Result<State> {
        let mut yhat = vec![0.0; self.u.len()];
        model.simulate(&values, &self.u, self.dt, &mut yhat)?;
        let ya: Vec<f64> = yhat.iter().map(|v| v + self.y0).collect();
        let s = self.split;
        let est = Fit::of(&self.rec.y[..s], &ya[..s]);
        let val = (s < ya.len()).then(|| Fit::of(&self.rec.y[s..], &ya[s..]));
        let ssr = est.rmse * est.rmse * s as f64;
        Ok(State {
            model,
            values,
            yhat,
            est,
            val,
            ssr,
        })
    }

    fn score(&self, st: &State) -> f64 {
        st.val.map_or(st.est.rmse, |v| v.rmse)
    }

    fn bic(&self, st: &State) -> f64 {
        let n = self.split as f64;
        let k = st.model.params.iter().filter(|p| p.free).count() as f64;
        n * (st.ssr / n).max(1e-300).ln() + k * n.ln()
    }

    /// The linear part of the current model applied to `x` (deviation scale).
    fn lin(&self, st: &State, x: &[f64]) -> Option<Vec<f64>> {
        let tf = st.model.tf(&st.values).ok()?;
        fracsim::lsim(&tf, x, self.dt, &st.model.approx).ok()
    }

    /// Refit `model` (its values are the start) on the estimation part.
    fn refit(&self, mut model: FracModel) -> Result<State> {
        let levels = model
            .past
            .as_ref()
            .map(|p| p.levels.clone())
            .unwrap_or_default();
        for (i, p) in model.params.iter_mut().enumerate() {
            // The initial state restarts from rest: the base fit's levels took up what the
            // missing effect left in the residual.
            if levels.contains(&i) {
                p.value = 0.0;
            }
            // A parameter the base fit drove to a bound (the missing effect distorted it) restarts
            // from the base fit's own start, or mid-range.
            if p.free && p.bounds.at_edge(p.value) {
                p.value = match (self.start.get(i), p.bounds) {
                    (Some(&v), b) if !b.at_edge(v) => v,
                    (_, Bounds::Interval(lo, hi)) => 0.5 * (lo + hi),
                    _ => p.value,
                };
            }
            p.value = p.bounds.clamp_inside(p.value);
        }
        let s = self.split;
        let rep = fit(&model, &self.u[..s], &self.y[..s], self.dt, &self.opts.fit)?;
        for (p, v) in model.params.iter_mut().zip(&rep.values) {
            p.value = *v;
        }
        self.state(model, rep.values)
    }
}

/// A candidate: its evidence and the model(s) to refit from.
struct Candidate {
    name: &'static str,
    /// For a negative delay: the input advance in samples.
    lead: Option<usize>,
    key: String,
    r2: f64,
    evidence: String,
    starts: Vec<FracModel>,
}

/// Find output quantization: at most `N/5` distinct values lying on a grid (90% of the gaps
/// between consecutive levels within 5% of a whole multiple of the smallest gap).
pub fn find_quantization(y: &[f64]) -> Option<Quantization> {
    let mut v: Vec<f64> = y.iter().copied().filter(|x| x.is_finite()).collect();
    if v.len() < 20 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let range = v[v.len() - 1] - v[0];
    if range <= 0.0 {
        return None;
    }
    let tol = 1e-9 * range.max(v[0].abs());
    v.dedup_by(|a, b| (*a - *b).abs() <= tol);
    let levels = v.len();
    if levels < 3 || levels > y.len() / 5 {
        return None;
    }
    let gaps: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = gaps.clone();
    sorted.sort_by(f64::total_cmp);
    // The step: the median of the gaps no larger than 1.5 times the smallest.
    let small: Vec<f64> = sorted
        .iter()
        .copied()
        .filter(|g| *g <= 1.5 * sorted[0])
        .collect();
    let step = small[small.len() / 2];
    let on_grid = gaps
        .iter()
        .filter(|g| {
            let m = (*g / step).round();
            m >= 1.0 && (*g / step - m).abs() <= 0.05 * m
        })
        .count();
    (on_grid as f64 >= 0.9 * gaps.len() as f64).then(|| Quantization {
        step,
        levels,
        noise_floor_rms: step / 12f64.sqrt(),
    })
}

fn params_of(model: &FracModel, values: &[f64], name: &str) -> BTreeMap<String, f64> {
    let get = |n: &str| model.index_of(n).map(|i| values[i]);
    let mut m = BTreeMap::new();
    let mut put = |k: &str, v: Option<f64>| {
        if let Some(v) = v {
            m.insert(k.to_string(), v);
        }
    };
    match name {
        "delay" => put("tau", get("tau")),
        "coulomb_friction" => put("Vc", get("Vc")),
        "offset" => {
            put("u_offset", get("u_offset"));
            put("y_offset", get("y_offset"));
        }
        "saturation" => put("level", get("sat_level")),
        "deadzone" => put("width", get("dz_width")),
        "periodic" => {
            // The last sinusoid added.
            if let Some(Effect::Sinusoid { freq_hz, a, b }) = model
                .effects
                .iter()
                .rev()
                .find(|e| matches!(e, Effect::Sinusoid { .. }))
            {
                put("freq_hz", Some(*freq_hz));
                put("amplitude", Some(values[*a].hypot(values[*b])));
                put("phase_rad", Some((-values[*b]).atan2(values[*a])));
            }
        }
        _ => {}
    }
    m
}

/// Insert an output effect before the existing output effects (an offset added by the base fit
/// then acts after it: `|x| + c`).
fn push_front(m: &mut FracModel, e: Effect) {
    m.effects.insert(0, e);
}

fn candidates(
    ctx: &Ctx<'_>,
    st: &State,
    kept: &[KeptEffect],
    ambiguous: &mut Vec<Ambiguity>,
    rejected: &mut BTreeMap<String, RejectedEffect>,
) -> Result<Vec<Candidate>> {
    let s = ctx.split;
    let dt = ctx.dt;
    let e: Vec<f64> = (0..s).map(|k| ctx.y[k] - st.yhat[k]).collect();
    let ee: f64 = e.iter().map(|v| v * v).sum();
    let (_, sens) = sensitivities(&st.model, &st.values, &ctx.u[..s], dt)?;
    let has = |n: &str| st.model.index_of(n).is_some();
    let kept_name = |n: &str| kept.iter().any(|k| k.name == n);
    let mut reject = |name: &str, reason: String| {
        rejected.insert(
            name.to_string(),
            RejectedEffect {
                name: name.to_string(),
                reason,
                params: BTreeMap::new(),
            },
        );
    };
    let mut out = vec![];
    let ya: Vec<f64> = st.yhat.iter().map(|v| v + ctx.y0).collect();
    let ua: Vec<f64> = ctx.u.iter().map(|v| v + ctx.u0).collect();

    // delay: 1-D search over tau with the other parameters held.
    if st.model.delay.is_some() {
        if !kept_name("delay") {
            reject(
                "delay",
                "not tested: the model already has a fitted delay".into(),
            );
        }
    } else {
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
        let r2_held = (1.0 - best.0 / ee.max(1e-300)).max(0.0);
        let rc = crate::metrics::crosscorr(&e, &ctx.u[..s], 10);
        let (lag, peak) = rc
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map_or((0, 0.0), |(i, v)| (i as isize - 10, *v));
        // With the other parameters held, a small delay rarely pays: the base fit has already bent
        // its orders and coefficients to mimic it. A significant residual-input correlation at a
        // lag >= 0 (the model answers the input sooner than the data) is the delay's own signature, so it alone makes the candidate strong (its
        // squared peak stands for the evidence), and the refit starts at that lag as well.
        let bound = crate::metrics::bound99(s);
        let signature = lag >= 0 && peak.abs() > bound;
        // Without the signature the delay is still probed (a joint refit from one and two
        // samples): a base fit with free orders can absorb a delay so well that neither test
        // above sees it. It ranks last, and the held-out margin and BIC decide as for any effect.
        let r2 = if signature {
            r2_held.max(peak * peak)
        } else {
            r2_held.max(ctx.opts.min_r2)
        };
        let mut starts = vec![];
        let mut taus = vec![best.1];
        if signature {
            taus.push(lag.max(1) as f64 * dt);
            taus.push((lag as f64 - 0.5).max(0.5) * dt);
        } else {
            taus.push(dt);
            taus.push(2.0 * dt);
        }
        for tau in taus {
            let mut m = st.model.clone();
            m.with_delay(tau.min((max as f64 - 0.5) * dt), max as f64 * dt);
            starts.push(m);
        }
        out.push(Candidate {
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
    }

    // A negative delay: the residual follows the input before it changes (cross-correlation
    // outside the bound at negative lags). Integer advances of the recorded input are searched.
    if ctx.lead == 0 {
        let h = ctx.opts.max_delay_samples.max(1);
        let rc = crate::metrics::crosscorr(&e, &ctx.u[..s], h);
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
        if neg_peak > bound {
            let mut best = (f64::INFINITY, 0usize);
            let mut y = vec![0.0; s];
            for m in 1..=h {
                let c = ctx.with_lead(m);
                if st.model.simulate(&st.values, &c.u[..s], dt, &mut y).is_ok() {
                    let ssr: f64 = (0..s).map(|k| (ctx.y[k] - y[k]).powi(2)).sum();
                    if ssr < best.0 {
                        best = (ssr, m);
                    }
                }
            }
            let mut r2 = (1.0 - best.0 / ee.max(1e-300)).max(0.0);
            // The model fitted to the skewed record has bent its dynamics to follow it, so the
            // advance alone may gain nothing before the refit: a cross-correlation beyond three
            // times the bound is evidence enough to refit, at the peak's lag.
            if neg_peak > 3.0 * bound && r2 < ctx.opts.min_r2 {
                r2 = ctx.opts.min_r2;
                best.1 = peak_lag;
            }
            out.push(Candidate {
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
        }
    }

    // Coulomb friction.
    let npos = ya.iter().filter(|v| **v > 0.0).count() as f64 / ya.len() as f64;
    let nneg = ya.iter().filter(|v| **v < 0.0).count() as f64 / ya.len() as f64;
    if has("Vc") {
    } else if npos.min(nneg) < 0.02 {
        ambiguous.push(Ambiguity {
            name: "coulomb_friction".into(),
            confused_with: "offset".into(),
            reason: format!(
                "the model speed is {} in {:.1}% of the samples: sign(y) is constant, so Vc sign(y) \
                 is a constant input offset (absorbed by the operating point and the offset); a test \
                 with speed reversals (a zero-mean PRBS) separates them",
                if npos >= nneg { "positive" } else { "negative" },
                100.0 * npos.max(nneg)
            ),
        });
    } else {
        let x: Vec<f64> = (0..ctx.u.len())
            .map(|k| {
                if k == 0 {
                    -sign(ctx.y0)
                } else {
                    -sign(ya[k - 1])
                }
            })
            .collect();
        if let Some(g) = ctx.lin(st, &x) {
            let (r2, beta) = explained(&e, &[g[..s].to_vec()], &sens);
            let corr = {
                let sg: Vec<f64> = ya[..s].iter().map(|v| sign(*v)).collect();
                let n = (sg.iter().map(|v| v * v).sum::<f64>() * ee).sqrt();
                if n > 0.0 {
                    e.iter().zip(&sg).map(|(a, b)| a * b).sum::<f64>() / n
                } else {
                    0.0
                }
            };
            if beta[0] > 0.0 {
                let mut m = st.model.clone();
                let vc = m.add_param(Param::positive("Vc", beta[0]));
                m.effects.insert(0, Effect::Coulomb { vc });
                out.push(Candidate {
                    lead: None,
                    name: "coulomb_friction",
                    key: "coulomb_friction".into(),
                    r2,
                    evidence: format!(
                        "the residual correlates with sign(speed) ({corr:.3}); the friction signature \
                         explains {:.1}% of its sum of squares (speed reverses: {:.0}% / {:.0}% of samples)",
                        100.0 * r2,
                        100.0 * npos,
                        100.0 * nneg
                    ),
                    starts: vec![m],
                });
            } else if r2 >= ctx.opts.min_r2 {
                reject(
                    "coulomb_friction",
                    format!(
                        "the signature fits with the wrong sign (Vc = {:.3e} < 0)",
                        beta[0]
                    ),
                );
            }
        }
    }

    // Offsets.
    if has("y_offset") && !kept_name("offset") {
        reject(
            "offset",
            "not tested: the base model already fits an output offset (y_offset)".into(),
        );
    } else if !has("y_offset") && !has("u_offset") {
        let mean = e.iter().sum::<f64>() / s as f64;
        let ones = vec![1.0; ctx.u.len()];
        let (r2o, bo) = explained(&e, &[ones[..s].to_vec()], &sens);
        let mut m = st.model.clone();
        let c = m.add_param(Param::new("y_offset", bo[0], Bounds::Free));
        m.effects.push(Effect::OutputOffset { c });
        let mut starts = vec![m];
        let mut r2 = r2o;
        if let Some(g) = ctx.lin(st, &ones) {
            let (r2i, bi) = explained(&e, &[g[..s].to_vec()], &sens);
            let mut m = st.model.clone();
            let c = m.add_param(Param::new("u_offset", bi[0], Bounds::Free));
            m.effects.insert(0, Effect::InputOffset { c });
            starts.push(m);
            r2 = r2.max(r2i);
        }
        out.push(Candidate {
            lead: None,
            name: "offset",
            key: "offset".into(),
            r2,
            evidence: format!(
                "residual mean {mean:.3e} ({:.1} standard errors); a constant explains {:.1}% of the \
                 residual sum of squares",
                mean / (ee / s as f64).sqrt().max(1e-300) * (s as f64).sqrt(),
                100.0 * r2
            ),
            starts,
        });
    }

    // Periodic disturbances.
    let an = analyse(&e, &ctx.u[..s], dt);
    let period = crate::oe::init::detect_period(&ctx.u);
    for pk in an.peaks.iter().take(2) {
        let near_kept = st.model.effects.iter().any(|ef| {
            matches!(ef, Effect::Sinusoid { freq_hz, .. } if (freq_hz - pk.freq_hz).abs() < 2.0 / (s as f64 * dt))
        });
        if near_kept {
            continue;
        }
        let key = format!("periodic@{:.4}Hz", pk.freq_hz);
        if let Some(p) = period {
            let fh = 1.0 / (p as f64 * dt);
            let r = pk.freq_hz / fh;
            if (r - r.round()).abs() < 0.1 {
                reject(
                    &key,
                    format!(
                        "spectral peak at {:.4} Hz is harmonic {} of the periodic input: a model \
                         error, not a disturbance",
                        pk.freq_hz,
                        r.round()
                    ),
                );
                continue;
            }
        }
        let w = 2.0 * std::f64::consts::PI * pk.freq_hz;
        let c: Vec<f64> = (0..s).map(|k| (w * k as f64 * dt).cos()).collect();
        let sn: Vec<f64> = (0..s).map(|k| (w * k as f64 * dt).sin()).collect();
        let (r2, beta) = explained(&e, &[c, sn], &sens);
        let mut m = st.model.clone();
        let n = st
            .model
            .effects
            .iter()
            .filter(|e| matches!(e, Effect::Sinusoid { .. }))
            .count();
        let a = m.add_param(Param::new(&format!("sin{n}_a"), beta[0], Bounds::Free));
        let b = m.add_param(Param::new(&format!("sin{n}_b"), beta[1], Bounds::Free));
        m.effects.push(Effect::Sinusoid {
            freq_hz: pk.freq_hz,
            a,
            b,
        });
        out.push(Candidate {
            lead: None,
            name: "periodic",
            key,
            r2,
            evidence: format!(
                "narrow residual spectrum peak at {:.4} Hz, {:.0} times the neighbouring median, \
                 amplitude about {:.3e}; explains {:.1}% of the residual sum of squares",
                pk.freq_hz,
                pk.ratio,
                pk.amplitude,
                100.0 * r2
            ),
            starts: vec![m],
        });
    }

    // abs sensor.
    let has_abs = st
        .model
        .effects
        .iter()
        .any(|e| matches!(e, Effect::AbsSensor));
    if !has_abs {
        let yd_neg = ctx.rec.y.iter().filter(|v| **v < 0.0).count() as f64 / ctx.rec.len() as f64;
        let u_neg = ua.iter().filter(|v| **v < 0.0).count() as f64 / ua.len() as f64;
        let u_pos = ua.iter().filter(|v| **v > 0.0).count() as f64 / ua.len() as f64;
        let model_reverses = npos.min(nneg) >= 0.02;
        let data_one_signed = !(0.01..=0.99).contains(&yd_neg);
        let input_reverses = u_neg.min(u_pos) >= 0.1;
        if data_one_signed && (model_reverses || input_reverses) {
            let sig: Vec<f64> = ya[..s].iter().map(|v| v.abs() - v).collect();
            let (r2, _) = explained(&e, &[sig], &sens);
            let mut m = st.model.clone();
            push_front(&mut m, Effect::AbsSensor);
            // A second start with the gain flipped away from zero (a linear fit of rectified data
            // tends to a small gain): rescale the numerator so the rectified output matches.
            let mut starts = vec![m.clone()];
            if !model_reverses {
                starts.extend(abs_starts(ctx, &m));
            }
            out.push(Candidate {
                lead: None,
                name: "abs_sensor",
                key: "abs_sensor".into(),
                r2: if model_reverses {
                    r2
                } else {
                    r2.max(ctx.opts.min_r2)
                },
                evidence: format!(
                    "the data are {} in {:.1}% of the samples while the {} reverses; the rectified \
                     model output explains {:.1}% of the residual sum of squares",
                    if yd_neg < 0.5 { "non-negative" } else { "non-positive" },
                    100.0 * (1.0 - yd_neg.min(1.0 - yd_neg)),
                    if model_reverses { "model output" } else { "input" },
                    100.0 * r2
                ),
                starts,
            });
        } else if !kept_name("abs_sensor") {
            reject(
                "abs_sensor",
                format!(
                    "no signature: {}",
                    if data_one_signed {
                        "the data never change sign, but neither do the model output and the input"
                    } else {
                        "the data take both signs"
                    }
                ),
            );
        }
    }

    // Static input nonlinearities.
    let mut lv: Vec<f64> = ua.clone();
    lv.sort_by(f64::total_cmp);
    let urange = lv[lv.len() - 1] - lv[0];
    lv.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * urange.max(1e-300));
    let umax = ua.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (name, pname) in [("saturation", "sat_level"), ("deadzone", "dz_width")] {
        if has(pname) {
            continue;
        }
        if lv.len() <= 2 {
            ambiguous.push(Ambiguity {
                name: name.into(),
                confused_with: "gain and offset".into(),
                reason: format!(
                    "the input takes {} levels: any static input map is then affine (a gain and an \
                     offset), so a {name} cannot be identified; a multi-level input separates them",
                    lv.len()
                ),
            });
            continue;
        }
        let grid: Vec<f64> = if name == "saturation" {
            (0..12).map(|i| umax * (0.45 + 0.05 * i as f64)).collect()
        } else {
            (1..=12).map(|i| umax * 0.03 * i as f64).collect()
        };
        let mut best = (0.0, 0.0, 0.0);
        for &l in &grid {
            let d: Vec<f64> = ua
                .iter()
                .map(|&v| {
                    if name == "saturation" {
                        v.clamp(-l, l) - v
                    } else if v.abs() < l {
                        -v
                    } else {
                        -l * sign(v)
                    }
                })
                .collect();
            if d[..s].iter().all(|v| *v == 0.0) {
                continue;
            }
            if let Some(g) = ctx.lin(st, &d) {
                let (r2, beta) = explained(&e, &[g[..s].to_vec()], &sens);
                // The effect enters with coefficient 1: a coefficient far from it is another shape.
                if beta[0] > 0.0 && r2 > best.0 {
                    best = (r2, l, beta[0]);
                }
            }
        }
        if best.1 > 0.0 {
            let mut m = st.model.clone();
            let i = m.add_param(Param::positive(pname, best.1));
            m.effects.insert(
                0,
                if name == "saturation" {
                    Effect::Saturation { level: i }
                } else {
                    Effect::Deadzone { width: i }
                },
            );
            out.push(Candidate {
                lead: None,
                name,
                key: name.into(),
                r2: best.0,
                evidence: format!(
                    "the {name} signature at {} = {:.3e} (grid over {} values, linear parameters \
                     refitted) explains {:.1}% of the residual sum of squares (coefficient {:.2})",
                    if name == "saturation" {
                        "level"
                    } else {
                        "half width"
                    },
                    best.1,
                    grid.len(),
                    100.0 * best.0,
                    best.2
                ),
                starts: vec![m],
            });
        }
    }
    out.sort_by(|a, b| b.r2.total_cmp(&a.r2));
    Ok(out)
}

/// Starts for the `abs_sensor` refit when the base model could not follow the rectified data
/// (a linear fit of `|y|` tends to a zero gain): the sign is restored from a first-order low-pass
/// of the input, `y_s = |y| sign(lp_T(u))`, for `T` on a log grid of 8 values from `2 dt` to a
/// twentieth of the record, and the automatic start ([`crate::oe::init::auto_start`]) is made on
/// `(u, y_s)`; the 2 starts whose rectified output is closest to the data are returned.
fn abs_starts(ctx: &Ctx<'_>, m: &FracModel) -> Vec<FracModel> {
    let s = ctx.split;
    let dt = ctx.dt;
    let ya = &ctx.rec.y[..s];
    let tmax = (s as f64 * dt / 20.0).max(4.0 * dt);
    let mut scored: Vec<(f64, FracModel)> = vec![];
    for i in 0..8 {
        let t = 2.0 * dt * (tmax / (2.0 * dt)).powf(i as f64 / 7.0);
        let a = (-dt / t).exp();
        let mut lp = 0.0;
        let ys: Vec<f64> = (0..s)
            .map(|k| {
                lp = a * lp + (1.0 - a) * ctx.u[k];
                let v = ya[k].abs() * if lp < 0.0 { -1.0 } else { 1.0 };
                v - ctx.y0
            })
            .collect();
        let mut c = m.clone();
        if crate::oe::init::auto_start(&mut c, &ctx.u[..s], &ys, dt).is_err() {
            continue;
        }
        if let Some(i) = c.index_of("y_offset") {
            c.params[i].value = 0.0;
        }
        for p in &mut c.params {
            p.value = p.bounds.clamp_inside(p.value);
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

fn remaining_structure(an: &ResidualAnalysis, q: Option<Quantization>) -> Vec<String> {
    let mut out = vec![];
    let at_floor = q.is_some_and(|q| an.rms <= 1.5 * q.noise_floor_rms);
    if !an.white && !at_floor {
        out.push(format!(
            "the residual is not white: Ljung-Box Q = {:.1} over {} lags (p = {:.2e}), {} autocorrelation \
             lags outside +-{:.3}",
            an.ljung_box_q, an.lags, an.ljung_box_p, an.auto_outside, an.bound
        ));
    }
    if !an.independent && !at_floor {
        out.push(format!(
            "the residual depends on the input: {} cross-correlation lags outside +-{:.3}, peak {:.3} at lag {}",
            an.cross_outside, an.bound, an.cross_peak, an.cross_peak_lag
        ));
    }
    for p in &an.peaks {
        out.push(format!(
            "a spectral peak at {:.4} Hz ({:.0} x the neighbouring median) remains",
            p.freq_hz, p.ratio
        ));
    }
    out
}

/// Diagnose a time-domain identification (see the module documentation): test the residual, try
/// each effect of the library, keep those that pay on held-out data, report before and after.
///
/// `rec` must be the record `id` was identified from (same length; `id.split`, `id.offsets` and
/// `id.model` are used).
///
/// # Errors
/// [`Error::Data`] for a record that does not match the identification; simulation errors of the
/// base model. Refits that fail are reported as rejected candidates, not errors.
pub fn diagnose(rec: &Record, id: &Identification, opts: &DiagnoseOptions) -> Result<Diagnosis> {
    if rec.len() != id.yhat.len() || id.split == 0 || id.split > rec.len() {
        return Err(Error::Data(format!(
            "the record has {} samples but the identification {} (split {})",
            rec.len(),
            id.yhat.len(),
            id.split
        )));
    }
    if !(opts.margin >= 0.0 && opts.margin < 1.0 && opts.min_r2 >= 0.0) {
        return Err(Error::Options(format!(
            "margin {} must be in [0, 1) and min_r2 {} non-negative",
            opts.margin, opts.min_r2
        )));
    }
    let (u0, y0) = (id.offsets.u0, id.offsets.y0);
    let mut ctx = Ctx {
        rec,
        u: rec.u.iter().map(|v| v - u0).collect(),
        y: rec.y.iter().map(|v| v - y0).collect(),
        lead: 0,
        split: id.split,
        dt: rec.dt,
        u0,
        y0,
        start: id.start.clone(),
        opts,
    };
    let base = ctx.state(id.model.clone(), id.report.values.clone())?;
    let e0: Vec<f64> = (0..ctx.split).map(|k| ctx.y[k] - base.yhat[k]).collect();
    let residual_before = analyse(&e0, &ctx.u[..ctx.split], ctx.dt);
    let quantization = find_quantization(&rec.y);
    let mut st = base.clone();
    let mut kept: Vec<KeptEffect> = vec![];
    let mut rejected: BTreeMap<String, RejectedEffect> = BTreeMap::new();
    let mut ambiguous: Vec<Ambiguity> = vec![];
    for round in 0..opts.max_rounds {
        let mut amb = vec![];
        let cands = candidates(&ctx, &st, &kept, &mut amb, &mut rejected)?;
        if round == 0 {
            ambiguous = amb;
        }
        let mut best: Option<(State, KeptEffect, String, Option<usize>)> = None;
        for (i, c) in cands.into_iter().enumerate() {
            if c.r2 < opts.min_r2 || i >= opts.max_refits {
                rejected.entry(c.key.clone()).or_insert(RejectedEffect {
                    name: c.name.into(),
                    reason: format!(
                        "weak evidence: {} (below the {:.1}% needed to refit)",
                        c.evidence,
                        100.0 * opts.min_r2
                    ),
                    params: BTreeMap::new(),
                });
                continue;
            }
            let mut fitted: Option<State> = None;
            let mut errs = vec![];
            let lead_ctx = c.lead.map(|l| ctx.with_lead(l));
            let rctx = lead_ctx.as_ref().unwrap_or(&ctx);
            for m in c.starts {
                match rctx.refit(m) {
                    Ok(s) if fitted.as_ref().is_none_or(|f| s.ssr < f.ssr) => fitted = Some(s),
                    Ok(_) => {}
                    Err(e) => errs.push(e.to_string()),
                }
            }
            let Some(ns) = fitted else {
                rejected.insert(
                    c.key.clone(),
                    RejectedEffect {
                        name: c.name.into(),
                        reason: format!("the refit failed: {}", errs.join("; ")),
                        params: BTreeMap::new(),
                    },
                );
                continue;
            };
            let mut params = params_of(&ns.model, &ns.values, c.name);
            if let Some(l) = c.lead {
                params.insert("tau".into(), -(l as f64) * ctx.dt);
            }
            let change = ctx.score(&ns) / ctx.score(&st) - 1.0;
            let dbic = ctx.bic(&ns) - ctx.bic(&st);
            // Parameters at a bound the current model already had there do not count against
            // the effect (the data push them out of this structure either way).
            let at_bound: Vec<String> = ns
                .model
                .params
                .iter()
                .zip(&ns.values)
                .enumerate()
                .filter(|(i, (p, v))| {
                    // The record's initial state is not the plant: its levels may sit at the
                    // edge of their range without saying anything about the effect.
                    p.free
                        && !ns.model.is_initial_state(*i)
                        && p.bounds.at_edge(**v)
                        && st.values.get(*i).is_none_or(|w| !p.bounds.at_edge(*w))
                })
                .map(|(_, pv)| pv)
                .map(|(p, v)| format!("{} = {v:.3e}", p.name))
                .collect();
            let part = if ns.val.is_some() {
                "validation"
            } else {
                "estimation"
            };
            let gain = format!(
                "{part} RMSE {:.4e} -> {:.4e} ({:+.1}%), BIC {:+.1}",
                ctx.score(&st),
                ctx.score(&ns),
                100.0 * change,
                dbic
            );
            let reason = if change > -opts.margin {
                Some(format!(
                    "{gain}: the {part} error does not fall by the {:.0}% margin",
                    100.0 * opts.margin
                ))
            } else if dbic >= 0.0 {
                Some(format!("{gain}: BIC does not agree"))
            } else if !at_bound.is_empty() {
                Some(format!(
                    "{gain}, but {} ran to a bound",
                    at_bound.join(", ")
                ))
            } else {
                None
            };
            match reason {
                Some(r) => {
                    rejected.insert(
                        c.key.clone(),
                        RejectedEffect {
                            name: c.name.into(),
                            reason: format!("{r} (evidence: {})", c.evidence),
                            params,
                        },
                    );
                }
                None => {
                    if best
                        .as_ref()
                        .is_none_or(|(b, _, _, _)| ctx.score(&ns) < ctx.score(b))
                    {
                        let k = KeptEffect {
                            name: c.name.into(),
                            params,
                            evidence: format!("{}; {gain}", c.evidence),
                            r2: c.r2,
                            rmse_change_percent: 100.0 * change,
                            bic_change: dbic,
                        };
                        best = Some((ns, k, c.key.clone(), c.lead));
                    }
                }
            }
        }
        match best {
            Some((ns, k, key, lead)) => {
                if let Some(l) = lead {
                    ctx = ctx.with_lead(l);
                }
                rejected.remove(&key);
                rejected.remove(&k.name);
                kept.push(k);
                st = ns;
            }
            None => break,
        }
    }
    // Candidates kept in a later round are not rejected.
    let rejected: Vec<RejectedEffect> = rejected
        .into_values()
        .filter(|r| r.name == "periodic" || !kept.iter().any(|k| k.name == r.name))
        .collect();
    let e1: Vec<f64> = (0..ctx.split).map(|k| ctx.y[k] - st.yhat[k]).collect();
    let residual_after = analyse(&e1, &ctx.u[..ctx.split], ctx.dt);
    let remaining = remaining_structure(&residual_after, quantization);
    let ya = |s: &State| s.yhat.iter().map(|v| v + y0).collect::<Vec<f64>>();
    let mut model = st.model.clone();
    for (p, v) in model.params.iter_mut().zip(&st.values) {
        p.value = *v;
    }
    Ok(Diagnosis {
        before: base.val.unwrap_or(base.est),
        after: st.val.unwrap_or(st.est),
        estimation: BeforeAfter {
            before: base.est,
            after: st.est,
        },
        validation: base.val.zip(st.val).map(|(b, a)| BeforeAfter {
            before: b,
            after: a,
        }),
        effects: kept,
        rejected,
        ambiguous,
        quantization,
        unexplained: !remaining.is_empty(),
        remaining,
        residual_before,
        residual_after,
        model,
        yhat_before: ya(&base),
        yhat_after: ya(&st),
        split: ctx.split,
    })
}
