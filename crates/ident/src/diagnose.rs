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
//! Candidates with `R^2 >= ` [`DiagnoseOptions::min_r2`] are refitted, strongest first. Each
//! effect is one probe in its own file (`probes/`); the loop below knows none of them by name.
//!
//! | effect | signature (deviation scale, `G` the fitted linear part) | parameters, how fitted |
//! |---|---|---|
//! | `delay` | best of a grid `tau = j dt/2` (the model resimulated) | `tau` in `(0, max)`, then LM |
//! | `delay` (negative) | the recorded input advanced by whole samples | the advance, then LM on the rest |
//! | `coulomb_friction` | `G * (-sign_b(y0 + yhat_prev))`, `sign_b` 0 within the noise band | `Vc > 0`, LM (see below) |
//! | `input_offset` | `G * 1` | `u_offset`, LM |
//! | `output_offset` | `1` | `y_offset`, LM |
//! | `initial_state` | the model's response to each past held input level (resimulated) | `u_past0..3` (the initial state of `InitialState::Estimate`), LM |
//! | `periodic` | `cos, sin (2 pi f t)`, `f` a spectral peak | `f` fixed at the peak; cosine and sine amplitudes, LM |
//! | `abs_sensor` | `abs(y0 + yhat) - (y0 + yhat)` | none; the linear part is refitted |
//! | `saturation` | `G * (clamp(u, -L, L) - u)` over a grid of `L`; off the centre, a two-sided clip over pairs of thresholds (`probes/off_centre.rs`) | `L > 0` (and an input offset `c`): grid, then LM |
//! | `deadzone` | `G * (dz_w(u) - u)` over a grid of `w`; off the centre, as the saturation's with a negative coefficient | `w > 0` (and an input offset `c`): grid, then LM |
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
//! `1/sqrt(2N)`, 2% for `N = 1000`, so 5% is 2.5 standard errors), or by half of it when the
//! refit reaches the noise floor (its held-out residual white at the sample scale, on an output
//! that is not quantized: its RMSE within `1/sqrt(N)` of the noise level `sqrt(sum dr^2 / 2N)`
//! its differences give, where a model error
//! slower than the sampling adds to the RMSE and hardly to the differences; what is left of the
//! margin is then noise no model removes: a friction worth 4.7% on a record whose error was 5%
//! above its noise; and the estimation part agrees, the refit removing at least the share of its
//! sum of squares that half the margin is, `1 - (1 - m/2)^2`: a delay on a two-mode record the
//! structure could not follow took 3.0% off the held-out RMSE and 0.7% off the estimation sum of
//! squares, where the zoo's kept frictions and saturations at the floor took 7.7-12%), (b) BIC
//! `N ln(SSR/N) + k ln N` on the estimation part falls (the added parameters must pay `ln N` each),
//! and (c) none of the effect's own parameters ran to a bound, and (d) it pays by the same rules
//! over the current structure refitted without it from the refit's values (`credited`): a refit
//! moves the linear part too, and an effect fitted where it does nothing is not credited with the
//! structure's better optimum (that refit becomes the current model instead, by the full
//! margin, when no effect is kept in the round). A parameter of the current model
//! that ran to a bound (the missing effect bent the base fit) is refitted once from a fresh start
//! of the base parameters (the automatic start); if it stays at its bound the effect is still kept
//! and the evidence says so (the structure may be short of a term). The report gives each kept
//! effect's share of the residual sum of squares removed by the refit
//! ([`KeptEffect::ssr_removed_percent`]). The best kept candidate of a round is added; the loop repeats
//! (at most [`DiagnoseOptions::max_rounds`]) while something is kept. A candidate proposed
//! without a signature (its evidence set at the [`DiagnoseOptions::min_r2`] floor, such as the
//! delay probed by joint refits from one and two samples) is refitted in the first round that
//! proposes it only: once a refit rejected it, that rejection stands. Without a validation part the
//! margin is applied to the estimation RMSE. On a step test the held-out part is the tail of the
//! response ([`crate::oe::ValidationKind::ResponseTail`]): it holds the settled level a model
//! extrapolates (its static gain), which an effect of the settled response (a drift, an offset)
//! moves and one of the dynamics (a delay) does not. So the margin may be cleared on either part:
//! on the tail, or on the estimation RMSE (as without a held-out part) with the tail predicted no
//! worse than by the margin, which is what an over-fitted step response gets wrong (on the TCLab
//! heater record the estimation part alone chose a 98% fit that held out at 38%). Judged on the
//! tail alone no delay of a step from rest was kept: 0 of the zoo's 6 such delay cases over
//! seeds 44 and 45.
//!
//! # Identifiability
//! An effect the input cannot reveal is reported in [`Diagnosis::ambiguous`], never fitted:
//! friction when the model speed neither changes sign nor rests between motion (`Vc sign(y)` is
//! then a constant input offset; signs are counted with a band of three noise levels, so noise
//! around zero is neither a reversal nor motion), or when it does not reverse under a two-level
//! input (it then acts as the input's level says: a gain and an offset); saturation, dead band and
//! power law when the input has two levels (any static input map is then affine: a gain and an
//! offset) or one magnitude about zero (`-a, 0, a`: an odd map is a gain); an input offset through a
//! linear model whose initial state is estimated (it is then an output offset and a shift of the
//! past input).
//!
//! # Structure
//! [`structures::diagnose_best`] fits the structures that could describe the record and diagnoses
//! the one with the lowest BIC among those within 2% of the best held-out RMSE (within
//! [`choice::BIC_EVEN`] of it, the one with the fewest effects), so that an effect is not found
//! only because the named structure could not bend like the plant.

mod backward;
mod carry;
pub mod choice;
pub mod freq;
pub mod general;
mod halving;
mod lag;
mod probes;
pub mod residual;
pub mod structures;

use crate::data::Record;
use crate::metrics::Fit;
use crate::oe::fit_in_unit;
use crate::oe::{Bounds, Effect, FitOptions, FracModel, Identification, Structure};
use crate::{Error, Result};
use probes::{Candidate, Findings, Look, Probe};
use residual::{analyse, ResidualAnalysis};
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
    /// Candidates with evidence above the floor refitted per round, strongest first (default
    /// 4); those proposed at the floor ([`Self::min_r2`]) are refitted besides.
    pub max_refits: usize,
    /// The output-error fit options of the refits (default: 60 LM iterations, and the stall test
    /// [`REFIT_STALL`]).
    pub fit: FitOptions,
}

/// The refits' stall test ([`crate::lm::LmOptions::stall`]): a refit stops when its cost fell by
/// less than 1e-4 (relative) over its last 5 iterations. At that rate the rest of the 60-iteration
/// budget could remove about 0.1% of the sum of squares, a fiftieth of the smallest gain an
/// effect must bring (the 5% held-out margin is about 10% of the sum of squares): a refit that
/// creeps on (a delay of a fraction of a sample against orders that mimic it) stops where the
/// decision can no longer change.
pub const REFIT_STALL: (usize, f64) = (5, 1e-4);

/// LM iterations each start of a candidate with several starts gets before only the best of them
/// (lowest estimation sum of squares) is refitted on, with the rest of the budget
/// ([`best_refit`]); under variable projection the reduced and the joint fit share them
/// ([`crate::oe::FitOptions::shared_budget`]: each had all 5 before, 10 in all).
pub const START_SCREEN_ITERATIONS: usize = 5;

impl Default for DiagnoseOptions {
    fn default() -> Self {
        let mut fit = FitOptions::default();
        fit.lm.max_iterations = 60;
        fit.lm.stall = Some(REFIT_STALL);
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
    /// The evidence `R^2`: the fraction of the residual's sum of squares its signature explained
    /// to first order, before the refit.
    pub r2: f64,
    /// The fraction (percent) of the estimation residual's sum of squares the refit removed.
    pub ssr_removed_percent: f64,
    /// Relative change of the validation (or estimation) RMSE, percent (negative is better).
    pub rmse_change_percent: f64,
    /// Change of BIC on the estimation part (negative is better).
    pub bic_change: f64,
    /// For Coulomb friction, whether its sign is decided at the sample instant and held over the
    /// interval (`true`, as a simulator stepping the mechanics once per sample has it) or taken
    /// at the interval's middle (`false`, a friction acting continuously); absent for the
    /// other effects. `fracid tune` simulates the loop's friction the same way.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampled: Option<bool>,
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
    /// Validation fit of the base model (estimation fit when there is no validation part; for a
    /// step test the tail of its response, [`crate::oe::ValidationKind::ResponseTail`]).
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
    /// The final model in words: its linear part with its delay, and its effects with their
    /// parameters.
    pub final_model: String,
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
    /// The model after each number of kept effects, the base model first (`path[r]` after `r`
    /// effects): what the structure comparison's successive halving compares
    /// ([`structures::BEHIND`]).
    #[serde(skip)]
    pub path: Vec<Step>,
    /// The number of kept effects at which the diagnosis was ended before its next round (or
    /// refit) because its structure was more than [`structures::BEHIND`] behind another after
    /// as many effects (`None`: it ran to its end). Such a diagnosis is not a final model: only
    /// `path` up to there is.
    #[serde(skip)]
    pub halted: Option<usize>,
    /// A halted diagnosis's state at the start of the round it was halted in ([`Resume`]): the
    /// rest of it, when needed after all, goes on from there ([`diagnose_from`]) instead of
    /// making the rounds before again. `None` when it ran to its end.
    #[serde(skip)]
    pub(crate) resume: Option<Resumable>,
}

/// What [`Rounds`] holds at the start of a round, with the pole cache entered then
/// ([`fracsim::modal::RootsCache::entered`]: its hints move the last bits of what the rounds
/// compute): a halted diagnosis continued from it ([`diagnose_from`]) computes, bit for bit,
/// what the diagnosis made again from its base fit computes from that round on.
#[derive(Clone)]
pub(crate) struct Resume {
    round: usize,
    lead: usize,
    u: Vec<f64>,
    found: Found,
    cache: fracsim::modal::RootsCache,
}

/// What the rounds have found so far: the current model, the effects kept and judged, the path;
/// the rounds carry it ([`Rounds`]) and a halted diagnosis resumes from it ([`Resume`]).
#[derive(Clone)]
struct Found {
    /// The current model.
    st: State,
    kept: Vec<KeptEffect>,
    rejected: BTreeMap<String, RejectedEffect>,
    /// Candidates proposed without a signature that a refit rejected ([`DiagnoseOptions::min_r2`]).
    refuted: Vec<String>,
    ambiguous: Vec<Ambiguity>,
    path: Vec<Step>,
    /// The residual tests of the base model are round 0's; those of the final model the last
    /// round's when it kept nothing (each made once, by the round's `Look`).
    residual_before: Option<ResidualAnalysis>,
    residual_now: Option<ResidualAnalysis>,
}

/// A [`Resume`] shared by the clones of its diagnosis.
#[derive(Clone)]
pub(crate) struct Resumable(std::sync::Arc<Resume>);

impl std::fmt::Debug for Resumable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Resumable(round {})", self.0.round)
    }
}

/// One point of a diagnosis's [`Diagnosis::path`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Held-out RMSE (estimation RMSE without a held-out part), as [`Diagnosis::after`].
    pub rmse: f64,
    /// BIC on the estimation part, as the structure comparison computes it.
    pub bic: f64,
    /// Free parameters.
    pub free_params: usize,
}

/// A fitted model and its scores.
#[derive(Clone)]
pub(crate) struct State {
    model: FracModel,
    values: Vec<f64>,
    /// Deviation-scale output, whole record.
    yhat: Vec<f64>,
    est: Fit,
    val: Option<Fit>,
    ssr: f64,
}

impl State {
    /// Its model with every parameter at the state's value.
    fn model_at_values(&self) -> FracModel {
        let mut model = self.model.clone();
        for (p, v) in model.params.iter_mut().zip(&self.values) {
            p.value = *v;
        }
        model
    }
}

#[derive(Clone)]
pub(crate) struct Ctx<'a> {
    rec: &'a Record,
    /// Input deviations, advanced by `lead` samples.
    u: Vec<f64>,
    /// Samples by which the recorded input is advanced (a negative delay: the recorded input
    /// lags the output, a time-stamp skew of the logger).
    lead: usize,
    y: Vec<f64>,
    split: usize,
    /// The held-out blocks ([`crate::oe::ValidationKind::HeldOutBlocks`]; empty: the samples
    /// after `split` are held out): left out of every refit's cost and scored as the held-out
    /// part.
    held: Vec<(usize, usize)>,
    dt: f64,
    /// Effects of another structure's final model offered as starts in the first round
    /// ([`carry`]).
    carried: &'a [carry::Carried],
    u0: f64,
    y0: f64,
    /// The base fit's starting values.
    start: Vec<f64>,
    /// The output is not quantized ([`find_quantization`]): what a model leaves of it at best is
    /// white noise ([`Ctx::at_noise_floor`]), not the quantizer's error, a function of the signal.
    unquantized: bool,
    /// The held-out part is a step test's response tail
    /// ([`crate::oe::ValidationKind::ResponseTail`]): an effect may be judged on the estimation
    /// part ([`Verdict::of`]), the tail vetoing a refit that predicts it worse.
    tail: bool,
    opts: &'a DiagnoseOptions,
}

impl Diagnosis {
    /// Whether the diagnosis kept an advance of the recorded input ([`Diagnosis::skew_samples`]).
    pub(crate) fn advances_input(&self) -> bool {
        self.effects
            .iter()
            .any(|e| e.name == "delay" && e.params.get("tau").is_some_and(|&t| t < 0.0))
    }

    /// The advance of the recorded input (samples) the diagnosis kept: a `delay` with a negative
    /// `tau`, a time-stamp skew of the logger. The final model cannot carry it (its delay is
    /// causal), so its figures are those of the record with the input advanced; `None` when none
    /// is kept.
    pub(crate) fn skew_samples(&self, dt: f64) -> Option<usize> {
        self.effects
            .iter()
            .filter(|e| e.name == "delay")
            .filter_map(|e| e.params.get("tau"))
            .find(|&&tau| tau < 0.0)
            .map(|tau| (-tau / dt).round() as usize)
    }
}

/// `u` advanced by `lead` samples (`u'_k = u_(k + lead)`, the last value held): the input a kept
/// time-stamp skew is fitted and scored on, here and in the final model's figures
/// ([`crate::app::time`]).
pub(crate) fn advanced(u: &[f64], lead: usize) -> Vec<f64> {
    let n = u.len();
    (0..n).map(|k| u[(k + lead).min(n - 1)]).collect()
}

impl Ctx<'_> {
    /// The same context with the recorded input advanced by `lead` samples
    /// (`u'_k = u_(k + lead)`, the last value held).
    fn with_lead(&self, lead: usize) -> Self {
        let mut c = self.clone();
        c.lead = lead;
        c.u = advanced(&self.rec.u, lead)
            .into_iter()
            .map(|v| v - self.u0)
            .collect();
        c
    }

    fn state(&self, model: FracModel, values: Vec<f64>) -> Result<State> {
        let mut yhat = vec![0.0; self.u.len()];
        model.simulate(&values, &self.u, self.dt, &mut yhat)?;
        let ya: Vec<f64> = yhat.iter().map(|v| v + self.y0).collect();
        let (est, val) = crate::oe::checks::figures(&self.rec.y, &ya, self.split, &self.held);
        let ssr = est.rmse * est.rmse * self.estimation_samples() as f64;
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

    /// The held-out residual's RMSE over its noise level seen from one sample to the next
    /// (`sqrt(sum dr^2 / 2)` within each held-out stretch): about 1 for a white residual, above 1
    /// when a model error slower than the sampling is left (module documentation, Decision);
    /// `None` without a held-out part.
    fn whiteness(&self, st: &State) -> Option<(f64, usize)> {
        let n = self.rec.y.len();
        let tail = [(self.split, n)];
        let parts: &[(usize, usize)] = if self.held.is_empty() {
            &tail
        } else {
            &self.held
        };
        let (mut sq, mut dsq, mut count, mut dcount) = (0.0, 0.0, 0usize, 0usize);
        for &(a, b) in parts {
            let r: Vec<f64> = (a.min(n)..b.min(n))
                .map(|i| self.rec.y[i] - self.y0 - st.yhat[i])
                .collect();
            sq += r.iter().map(|v| v * v).sum::<f64>();
            dsq += r.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>();
            count += r.len();
            dcount += r.len().saturating_sub(1);
        }
        (dcount >= 2 && dsq > 0.0).then(|| {
            (
                (sq / count as f64).sqrt() / (dsq / (2.0 * dcount as f64)).sqrt(),
                count,
            )
        })
    }

    /// Whether `st`'s held-out residual is white at the sample scale: its [`Ctx::whiteness`] is
    /// within one standard error (`1/sqrt(N)` over `N` held-out samples) of 1, on an output that
    /// is not quantized (a quantizer's error follows the signal: the zoo's quantisation case 0045
    /// kept a spurious delay at 3.7% on it).
    fn at_noise_floor(&self, st: &State) -> bool {
        self.unquantized
            && self
                .whiteness(st)
                .is_some_and(|(w, n)| w <= 1.0 + 1.0 / (n as f64).sqrt())
    }

    /// The samples the fits' cost counts: the first `split` less the held-out blocks'.
    fn estimation_samples(&self) -> usize {
        crate::oe::checks::estimation_samples(self.split, &self.held)
    }

    fn bic(&self, st: &State) -> f64 {
        let k = st.model.params.iter().filter(|p| p.free).count();
        bic(st.ssr, self.estimation_samples(), k)
    }

    /// The point of the path ([`Diagnosis::path`]) at `st`, its BIC computed as the structure
    /// comparison does (from the estimation RMSE; an advance of the input, chosen from the data,
    /// counted as a parameter).
    fn step(&self, st: &State) -> Step {
        let free_params =
            st.model.params.iter().filter(|p| p.free).count() + usize::from(self.lead != 0);
        let n = self.estimation_samples();
        let ssr = st.est.rmse.powi(2) * n as f64;
        Step {
            rmse: self.score(st),
            bic: bic(ssr, n, free_params),
            free_params,
        }
    }

    /// The linear part of the current model applied to `x` (deviation scale).
    fn lin(&self, st: &State, x: &[f64]) -> Option<Vec<f64>> {
        let mut sim = st.model.simulator::<f64>(&st.values, self.dt).ok()?;
        let y = sim.simulate(x);
        y.iter().all(|v| v.is_finite()).then_some(y)
    }

    /// Refit `model` (its values are the start) on the estimation part.
    fn refit(&self, model: FracModel) -> Result<State> {
        self.refit_with(model, &self.opts.fit)
    }

    /// [`Ctx::refit`] with the fit options `opts`.
    fn refit_with(&self, mut model: FracModel, opts: &FitOptions) -> Result<State> {
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
        self.fit_from(model, opts)
    }

    /// Fit `model` from its values as they are on the estimation part with `opts`.
    fn fit_from(&self, mut model: FracModel, opts: &FitOptions) -> Result<State> {
        let s = self.split;
        let held = FitOptions {
            held: self.held.clone(),
            ..opts.clone()
        };
        // in a time unit the refit does not depend on, as the base fit ([`crate::oe::identify`])
        let values = fit_in_unit(&model, &self.u[..s], &self.y[..s], self.dt, &held)?;
        for (p, v) in model.params.iter_mut().zip(&values) {
            p.value = *v;
        }
        self.state(model, values)
    }
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

/// A candidate's rejection, with the current structure refitted without the effect when that
/// refit, not the effect, made the gain ([`credited`]).
type Refuted = (RejectedEffect, Option<Box<State>>);

/// Whether a candidate's gain must be shown to be the effect's ([`try_candidate`]'s call of
/// [`credited`]), its refit `ns` and its kept effect `k` when it passed the decision.
type NeedsCredit<'a> = dyn Fn(&State, Option<&KeptEffect>) -> bool + 'a;

/// Whether a candidate's refit that pays must be [`credited`] to its effect: `floor` whether it
/// was proposed at the evidence floor (its rejection stands in later rounds,
/// [`Rounds::refuted`]), `best` the round's best kept refit so far and `passed` the candidate's
/// (both `(held-out RMSE, rank in the library)`, [`beats`]) when the rest of the decision keeps
/// it. The check only turns a kept candidate into a rejected one, and the refit without the
/// effect it makes becomes the current model only when the round keeps nothing: so once the
/// round has a best, a candidate that does not beat it, or is rejected anyway, is not checked
/// (dropped or rejected, as it would be after the check), and the round keeps what it kept with
/// every candidate checked. Only the rejections listed can differ: such a candidate is not
/// listed, or listed with the decision's reason, not the check's.
fn needs_credit(floor: bool, best: Option<(f64, usize)>, passed: Option<(f64, usize)>) -> bool {
    floor || best.is_none_or(|b| passed.is_some_and(|p| beats(p, b)))
}

/// Refit a candidate from each of its starts and decide (module documentation, Decision).
/// Returns the refitted state and the kept effect, or the rejection. The refit's gain is
/// [`credited`] to the effect where `needs` says the round's outcome can depend on it.
fn try_candidate(
    ctx: &Ctx<'_>,
    st: &State,
    c: &Candidate,
    probe: Option<&dyn Probe>,
    needs: &NeedsCredit<'_>,
) -> std::result::Result<(State, KeptEffect, Option<usize>), Refuted> {
    let lead_ctx = c.lead.map(|l| ctx.with_lead(l));
    let rctx = lead_ctx.as_ref().unwrap_or(ctx);
    let params_of = |ns: &State, lead: Option<usize>| {
        let mut params = probe.map_or_else(BTreeMap::new, |p| p.params(&ns.model, &ns.values));
        if let Some(l) = lead {
            params.insert("tau".into(), -(l as f64) * ctx.dt);
        }
        params
    };
    let mut ns = refit_candidate(ctx, rctx, st, c, &params_of).map_err(|r| (r, None))?;
    let lead = c.lead.map(|l| longer_lead(ctx, l, &mut ns));
    let longer_ctx = lead
        .filter(|&l| Some(l) != c.lead)
        .map(|l| ctx.with_lead(l));
    let rctx = longer_ctx.as_ref().unwrap_or(rctx);
    let verdict = fresh_if_bent(ctx, rctx, st, &mut ns);
    let params = params_of(&ns, lead);
    let judged = judge(ctx, st, &ns, c, &verdict, params.clone());
    if verdict.pays(ctx) && lead.is_none() && needs(&ns, judged.as_ref().ok()) {
        credited(ctx, st, &ns, c, &verdict, &params)?;
    }
    let k = judged.map_err(|r| (r, None))?;
    Ok((ns, k, lead))
}

/// Whether the gain of refit `ns` over the current model `st` is the effect's: the current
/// structure refitted without the effect, from the refit's values of its own parameters, must
/// not come within the margin of it (held-out RMSE and BIC, as any effect is judged). A refit
/// moves the linear part as well, and can leave a poor optimum of the base fit that the
/// structure alone reaches from there: an effect fitted inactive (a saturation at the input's
/// largest level, a power law of exponent 1) then took the credit for the structure's better
/// fit. Then the effect is rejected, and the refit without it is returned beside the rejection
/// when it pays over `st` by the full margin (it becomes the current model when no effect is kept
/// in the round).
/// Nothing is checked when `ns` does not extend the current model's parameters.
fn credited(
    ctx: &Ctx<'_>,
    st: &State,
    ns: &State,
    c: &Candidate,
    verdict: &Verdict,
    params: &BTreeMap<String, f64>,
) -> std::result::Result<(), Refuted> {
    let Some(null) = refit_at_values(ctx, &st.model, ns) else {
        return Ok(());
    };
    let own = Verdict::of(ctx, &null, ns);
    if own.pays(ctx) {
        return Ok(());
    }
    let rejected = RejectedEffect {
        name: c.name.into(),
        reason: format!(
            "{} RMSE {:.4e} -> {:.4e} ({:+.1}%), but the structure refitted from the refit's \
             values without the effect reaches {:.4e} ({} RMSE): the effect adds {:+.1}% \
             (BIC {:+.1}), short of the {:.0}% margin; the gain is the structure's (evidence: {})",
            verdict.part,
            verdict.before,
            verdict.after,
            100.0 * verdict.change,
            own.before,
            own.part,
            100.0 * own.change,
            own.dbic,
            100.0 * ctx.opts.margin,
            c.evidence
        ),
        params: params.clone(),
    };
    // The structure refitted alone replaces the current model by the full margin: the noise
    // floor's half ([`Verdict::clears`]) is for an effect, a term its signature proposed.
    let pays = Verdict::of(ctx, st, &null).pays_in_full(ctx);
    Err((rejected, pays.then(|| Box::new(null))))
}

/// The structure `model` refitted from the values of refit `ns`, which extends it (its
/// parameters, by name, the first of `ns`'s): the refit without what `ns` added. `None` when
/// `ns` does not extend `model` or the refit fails.
fn refit_at_values(ctx: &Ctx<'_>, model: &FracModel, ns: &State) -> Option<State> {
    let extends = ns.model.params.len() >= model.params.len()
        && model
            .params
            .iter()
            .zip(&ns.model.params)
            .all(|(a, b)| a.name == b.name);
    if !extends {
        return None;
    }
    let mut without = model.clone();
    for (p, v) in without.params.iter_mut().zip(&ns.values) {
        p.value = p.bounds.clamp_inside(*v);
    }
    ctx.fit_from(without, &ctx.opts.fit).ok()
}

/// A candidate's parameters in its report, from its refit and its input advance.
type ParamsOf<'a> = dyn Fn(&State, Option<usize>) -> BTreeMap<String, f64> + 'a;

/// Candidate `c` refitted on `rctx` (its input advanced when it has a lead) from the current
/// model `st`: on a long record screened on its leading part first ([`lead_screen`]) and
/// rejected there when it removes too little; else from each of its starts ([`best_refit`]),
/// with the give-up test when its refit is judged where it ends ([`with_give_up`]).
fn refit_candidate(
    ctx: &Ctx<'_>,
    rctx: &Ctx<'_>,
    st: &State,
    c: &Candidate,
    params_of: &ParamsOf<'_>,
) -> std::result::Result<State, RejectedEffect> {
    let rejection = |reason: String, params: BTreeMap<String, f64>| RejectedEffect {
        name: c.name.into(),
        reason,
        params,
    };
    let screened = lead_screen(rctx, st, &c.starts);
    if let Some((lead, removed)) = &screened {
        if removed.1 < LEAD_SCREEN_GAIN {
            return Err(rejection(
                format!(
                    "refitted on the first {lead} estimation samples only (a long record's \
                     leading part, excited like the whole), it removes {:.2}% of their sum of \
                     squares, less than the {:.0}% screen (the {:.0}% held-out margin needs \
                     about {:.0}%): not refitted on the whole record (evidence: {})",
                    100.0 * removed.1,
                    100.0 * LEAD_SCREEN_GAIN,
                    100.0 * ctx.opts.margin,
                    100.0 * (1.0 - (1.0 - ctx.opts.margin).powi(2)),
                    c.evidence
                ),
                params_of(&removed.0, c.lead),
            ));
        }
    }
    let refitted = match screened {
        // The whole record's refit goes on from the leading part's (as a long record's fit
        // does from its own leading part, [`crate::oe::fit`]), with the whole budget.
        Some((_, (part, _))) => rctx.fit_from(clamped(part.model), &ctx.opts.fit),
        // A candidate whose refit is judged where it ends (no longer advance refitted after
        // it, no leading part) gives up when it cannot end below its keep ceiling.
        None if c.lead.is_none() && ctx.split < 4 * LEAD_SCREEN_SAMPLES => {
            let opts = with_give_up(ctx, st, c);
            best_refit(
                &Ctx {
                    opts: &opts,
                    ..rctx.clone()
                },
                &c.starts,
            )
        }
        None => best_refit(rctx, &c.starts),
    };
    refitted.map_err(|e| rejection(format!("the refit failed: {e}"), BTreeMap::new()))
}

/// What the refit `ns` gains over `st`. A base parameter at a bound says the missing effect (or
/// the structure) bent the base fit, not that the effect is spurious: `ns` is then refitted once
/// from a fresh start of the base parameters, and replaced when that pays with no more base
/// parameters at a bound.
fn fresh_if_bent(ctx: &Ctx<'_>, rctx: &Ctx<'_>, st: &State, ns: &mut State) -> Verdict {
    let verdict = Verdict::of(ctx, st, ns);
    if !verdict.pays(ctx) || verdict.base_at_bound.is_empty() {
        return verdict;
    }
    let mut fresh = ns.model.clone();
    for (i, p) in fresh
        .params
        .iter_mut()
        .enumerate()
        .take(st.model.params.len())
    {
        if let Some(&v) = ctx.start.get(i) {
            p.value = v;
        }
    }
    if let Ok(f) = rctx.refit(fresh) {
        let fv = Verdict::of(ctx, st, &f);
        if fv.pays(ctx) && fv.base_at_bound.len() <= verdict.base_at_bound.len() {
            *ns = f;
            return fv;
        }
    }
    verdict
}

/// The part a refit is scored on ([`Ctx::score`]): the held-out part when there is one.
fn scored_part(ns: &State) -> &'static str {
    if ns.val.is_some() {
        "validation"
    } else {
        "estimation"
    }
}

/// The decision on candidate `c` refitted as `ns` (module documentation, Decision): the kept
/// effect, or the rejection with the reason.
fn judge(
    ctx: &Ctx<'_>,
    st: &State,
    ns: &State,
    c: &Candidate,
    verdict: &Verdict,
    params: BTreeMap<String, f64>,
) -> std::result::Result<KeptEffect, RejectedEffect> {
    let rejection = |reason: String, params: BTreeMap<String, f64>| RejectedEffect {
        name: c.name.into(),
        reason,
        params,
    };
    let part = verdict.part;
    let gain = format!(
        "{part} RMSE {:.4e} -> {:.4e} ({:+.1}%), BIC {:+.1}; the refit removes {:.1}% of the \
         estimation residual's sum of squares",
        verdict.before,
        verdict.after,
        100.0 * verdict.change,
        verdict.dbic,
        100.0 * verdict.removed
    );
    let margin = ctx.opts.margin;
    if let Some(worse) = verdict.tail_worse {
        return Err(rejection(
            format!(
                "{gain}, but it predicts the held-out response tail (the settled response) worse: \
                 RMSE {:.4e} -> {:.4e} ({:+.1}%, beyond the {:.0}% margin) (evidence: {})",
                ctx.score(st),
                ctx.score(ns),
                100.0 * worse,
                100.0 * margin,
                c.evidence
            ),
            params,
        ));
    }
    if !verdict.clears(ctx) {
        let parts = if ctx.tail {
            format!(
                "neither the {} nor the estimation error falls",
                scored_part(ns)
            )
        } else {
            format!("the {part} error does not fall")
        };
        return Err(rejection(
            format!(
                "{gain}: {parts} by the {:.0}% margin (evidence: {})",
                100.0 * margin,
                c.evidence
            ),
            params,
        ));
    }
    if verdict.dbic >= 0.0 {
        return Err(rejection(
            format!("{gain}: BIC does not agree (evidence: {})", c.evidence),
            params,
        ));
    }
    if !verdict.own_at_bound.is_empty() {
        return Err(rejection(
            format!(
                "{gain}, but its {} ran to a bound (evidence: {})",
                verdict.own_at_bound.join(", "),
                c.evidence
            ),
            params,
        ));
    }
    let floor = if verdict.change > -margin {
        let w = ctx.whiteness(ns).map_or(f64::NAN, |w| w.0);
        format!(
            "; short of the {:.0}% margin but at the noise floor: the refit's {part} residual is \
             white at the sample scale (its RMSE {w:.3}x its noise level from one sample to the \
             next)",
            100.0 * margin
        )
    } else {
        String::new()
    };
    let note = if verdict.base_at_bound.is_empty() {
        floor
    } else {
        format!(
            "{floor}; {} stayed at a bound when refitted from a fresh start (the structure may be \
             short of a term)",
            verdict.base_at_bound.join(", ")
        )
    };
    let refitted = params
        .iter()
        .map(|(k, v)| format!("{k} = {v:.4e}"))
        .collect::<Vec<_>>()
        .join(", ");
    Ok(KeptEffect {
        name: c.name.into(),
        evidence: format!(
            "{} (screening); refitted: {refitted}; {gain}{note}",
            c.evidence
        ),
        params,
        r2: c.r2,
        ssr_removed_percent: 100.0 * verdict.removed,
        rmse_change_percent: 100.0 * verdict.change,
        bic_change: verdict.dbic,
        sampled: ns
            .model
            .effects
            .iter()
            .find_map(|e| match e {
                Effect::Coulomb { sampled, .. } => Some(*sampled),
                _ => None,
            })
            .filter(|_| c.name == "coulomb_friction"),
    })
}

/// Accepted LM iterations over which a refit's fall is measured by its give-up test
/// ([`with_give_up`]).
pub const GIVE_UP_WINDOW: usize = 2;

/// The largest estimation sum of squares a refit of candidate `c` can end at and still be kept
/// (module documentation, Decision): BIC must fall, `n ln(S'/S) + dk ln n < 0`, so `S' < S
/// exp(-dk ln n / n)` (`S` the current model's sum of squares, `dk` the parameters the candidate
/// adds, `n` the estimation samples); without a held-out part the margin is on the estimation
/// RMSE as well, `S' <= (1 - margin)^2 S`. A refit that ends above it is rejected, whatever its
/// held-out error.
fn keep_ceiling(ctx: &Ctx<'_>, st: &State, c: &Candidate) -> f64 {
    let free = |m: &FracModel| m.params.iter().filter(|p| p.free).count() as f64;
    let dk = c.starts.first().map_or(0.0, free) - free(&st.model);
    let margin = st.val.is_none().then_some(ctx.opts.margin);
    ceiling(st.ssr, ctx.estimation_samples(), dk, margin)
}

/// Schwarz's (1978) Bayesian information criterion of a least-squares fit with `k` free
/// parameters and sum of squares `ssr` over `n` samples, `n ln(ssr/n) + k ln n` (Gaussian errors,
/// constants dropped): the diagnosis's and the structure comparison's.
pub(crate) fn bic(ssr: f64, n: usize, k: usize) -> f64 {
    let n = n as f64;
    n * (ssr / n).max(1e-300).ln() + k as f64 * n.ln()
}

/// [`keep_ceiling`] for a current sum of squares `ssr` over `n` estimation samples, `dk` added
/// parameters, and the margin when it applies to the estimation RMSE (no held-out part).
fn ceiling(ssr: f64, n: usize, dk: f64, margin: Option<f64>) -> f64 {
    let n = n as f64;
    let bic = ssr * (-dk * n.ln() / n).exp();
    margin.map_or(bic, |m| bic.min(ssr * (1.0 - m).powi(2)))
}

/// The diagnosis options with the refits' give-up test ([`crate::lm::LmOptions::give_up`]) at
/// candidate `c`'s [`keep_ceiling`], over [`GIVE_UP_WINDOW`] accepted iterations: a refit
/// whose cost, falling on at its mean fall over its last 2 accepted iterations for every
/// iteration left, would still end above the ceiling stops there, and is rejected as it would
/// have been at the end of its budget. The assumption is the stall test's (a refit's fall does
/// not speed up), with the decision's own threshold instead of a fixed 1e-4. Refits that reach
/// the ceiling are not touched (the same refit, bit for bit).
fn with_give_up(ctx: &Ctx<'_>, st: &State, c: &Candidate) -> DiagnoseOptions {
    let mut opts = ctx.opts.clone();
    opts.fit.lm.give_up = Some((GIVE_UP_WINDOW, 0.5 * keep_ceiling(ctx, st, c)));
    opts
}

/// The advance of the recorded input (a time-stamp skew) a candidate was refitted with, made
/// longer one sample at a time while the refit (from the last one) lowers the estimation sum of
/// squares: the probe picks its advance with the base model held, and a base model fitted to a
/// skewed record has bent its dynamics to follow it, so that advance falls short (measured: a
/// 3-sample skew of a first-order plant, held-model choice 1 sample, [`crate::app::time`]'s test
/// `a_kept_time_skew_states_the_figures_of_its_final_model`). Up to the largest delay searched.
/// A longer advance is taken only when its refit lowers the estimation RMSE beyond [`REFIT_TIE`]
/// (the refits' own stopping rule leaves differences that small: they are no evidence): on the
/// zoo's power-law case 0169 (88k samples) the first order and the PMSM with an integrator each
/// walked from 1 to 50 samples, every step lowering the sum of squares by 1.2e-5 (0.06% in all,
/// the advance then rejected at -0.0% held out), 49 refits of the whole record each: that case's
/// CPU fell from 16.7 s to 12.0 s with the tie, no row of the zoo (300 cases, seed 44) changed.
fn longer_lead(ctx: &Ctx<'_>, lead: usize, ns: &mut State) -> usize {
    let h = ctx.opts.max_delay_samples.max(1);
    let mut l = lead;
    let lower = |f: &State, ns: &State| f.ssr.sqrt() < (1.0 - REFIT_TIE) * ns.ssr.sqrt();
    while l < h {
        match ctx
            .with_lead(l + 1)
            .fit_from(ns.model.clone(), &ctx.opts.fit)
        {
            Ok(f) if lower(&f, ns) => {
                *ns = f;
                l += 1;
            }
            _ => break,
        }
    }
    l
}

/// Estimation samples of the leading part a long record's candidate is first refitted on
/// ([`lead_screen`]): the fit's own leading part ([`crate::oe::fit`], `2^14` samples).
pub const LEAD_SCREEN_SAMPLES: usize = 1 << 14;

/// The fraction of the leading part's sum of squares a candidate's refit there must remove to be
/// refitted on the whole record ([`lead_screen`]): 1%, a tenth of what the held-out margin asks
/// (`1 - 0.95^2`, about 10% of the sum of squares), and some 15 times what refitting the base
/// model's own 10 parameters on `2^14` samples removes by itself (`k / N`, 0.06%).
pub const LEAD_SCREEN_GAIN: f64 = 0.01;

/// A long record's screen of a candidate (at least `4 x` [`LEAD_SCREEN_SAMPLES`] estimation
/// samples, the first of them excited like the whole: input and output standard deviations at
/// least half the estimation part's, the fit's own rule): the candidate refitted
/// ([`best_refit`]) on the leading [`LEAD_SCREEN_SAMPLES`] estimation samples only, and the
/// fraction of their sum of squares (under the current model `st`) it removes. A candidate that
/// does not remove [`LEAD_SCREEN_GAIN`] there is not refitted on the whole record (a refit of
/// `7 x 10^4` samples costs about as much as the rest of the diagnosis); one that does is
/// refitted on the whole estimation part from the leading part's refit (one start, the whole
/// budget: what a long record's fit does from its own leading part, [`crate::oe::fit`]). `None`
/// for a record too short or whose leading part is not excited like the whole.
fn lead_screen(ctx: &Ctx<'_>, st: &State, starts: &[FracModel]) -> Option<(usize, (State, f64))> {
    let (s, lead) = (ctx.split, LEAD_SCREEN_SAMPLES);
    // (With held-out blocks, the leading part's sums of squares would count different samples.)
    if s < 4 * lead || !ctx.held.is_empty() {
        return None;
    }
    let sd = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let excited = |x: &[f64]| sd(&x[..lead]) >= 0.5 * sd(&x[..s]);
    if !(excited(&ctx.u) && excited(&ctx.y)) {
        return None;
    }
    let before: f64 = (0..lead).map(|k| (ctx.y[k] - st.yhat[k]).powi(2)).sum();
    let part = Ctx {
        split: lead,
        ..ctx.clone()
    };
    let fitted = best_refit(&part, starts).ok()?;
    let removed = 1.0 - fitted.ssr / before.max(1e-300);
    Some((lead, (fitted, removed)))
}

/// The refit over `starts`: those with the fewest free parameters refitted ([`refit_starts`]), and
/// the others (a static map off the input's centre, its input offset a parameter more:
/// `probes/off_centre.rs`) refitted apart and taken only when their refit pays over the first by
/// the rules an effect meets ([`Verdict::pays`]: the margin on held-out data, and BIC), and over
/// the first refitted from their refit's values of its parameters ([`credited`]'s rule), so that
/// the parameter more is an effect of its own that must pay (a dead band about the zero kept an
/// input offset beside it on the zoo's symmetric dead band 44/0113 when the lower BIC alone
/// decided).
fn best_refit(ctx: &Ctx<'_>, starts: &[FracModel]) -> Result<State> {
    let free = |m: &FracModel| m.params.iter().filter(|p| p.free).count();
    let fewest = starts.iter().map(free).min().unwrap_or(0);
    let (first, more): (Vec<FracModel>, Vec<FracModel>) =
        starts.iter().cloned().partition(|m| free(m) == fewest);
    if more.is_empty() {
        return refit_starts(ctx, &first);
    }
    match (refit_starts(ctx, &first), refit_starts(ctx, &more)) {
        (Ok(a), Ok(b)) if Verdict::of(ctx, &a, &b).pays(ctx) => {
            // ... and over the first refitted from its values (the credit check's rule,
            // [`credited`]): the other start may only have led the shared parameters to a
            // better optimum (a clamp's level: the zoo's 47/0089, its offset -0.1 of 4.2).
            match refit_at_values(ctx, &a.model, &b) {
                Some(a2) if !Verdict::of(ctx, &a2, &b).pays(ctx) => {
                    Ok(if a2.ssr < a.ssr { a2 } else { a })
                }
                _ => Ok(b),
            }
        }
        (Ok(a), _) => Ok(a),
        (Err(_), b) => b,
    }
}

/// The refit over `starts` with the smallest estimation sum of squares. With several starts (a
/// delay's grid point and lags), each is refitted for [`START_SCREEN_ITERATIONS`] LM iterations
/// and only the best of those goes on from where it stopped with the rest of the budget: the
/// starts of one candidate mostly end in the same minimum, and the one ahead after a few
/// iterations is the one to finish (successive halving), so the candidate costs about one refit
/// and not one per start.
fn refit_starts(ctx: &Ctx<'_>, starts: &[FracModel]) -> Result<State> {
    let budget = ctx.opts.fit.lm.max_iterations;
    if starts.len() < 2 || budget <= 2 * START_SCREEN_ITERATIONS {
        return lowest(starts.iter().map(|m| ctx.refit(m.clone())));
    }
    let mut short = ctx.opts.clone();
    short.fit.lm.max_iterations = START_SCREEN_ITERATIONS;
    // The screen's budget is what it says under variable projection too (the reduced fit's
    // iterations and the joint fit's together).
    short.fit.shared_budget = true;
    // Nor does the screen give up: the give-up test projects the cost's fall over the
    // iterations left of the budget it is given, and over the screen's few it would stop every
    // start still far above the keep ceiling (a friction added at the signature's level before
    // the gain has made room for it) after two iterations; the rest of the budget judges it.
    short.fit.lm.give_up = None;
    let screen = Ctx {
        opts: &short,
        ..ctx.clone()
    };
    let best = lowest(starts.iter().map(|m| screen.refit(m.clone())))?;
    let mut rest = ctx.opts.fit.clone();
    rest.lm.max_iterations = budget - START_SCREEN_ITERATIONS;
    let model = clamped(best.model.clone());
    // The continuation cannot end worse than where it started (LM only accepts descents), but
    // it can fail (a model at the edge of what the approximation represents): keep the screen's.
    Ok(match ctx.fit_from(model, &rest) {
        Ok(s) if s.ssr <= best.ssr => s,
        _ => best,
    })
}

/// `model` with each value moved inside its range (a refit starts strictly inside).
fn clamped(mut model: FracModel) -> FracModel {
    for p in &mut model.params {
        p.value = p.bounds.clamp_inside(p.value);
    }
    model
}

/// The state with the smallest estimation sum of squares among `fits`, or their errors.
fn lowest(fits: impl Iterator<Item = Result<State>>) -> Result<State> {
    let mut fitted: Option<State> = None;
    let mut errs = vec![];
    for f in fits {
        match f {
            Ok(s) if fitted.as_ref().is_none_or(|f| s.ssr < f.ssr) => fitted = Some(s),
            Ok(_) => {}
            Err(e) => errs.push(e.to_string()),
        }
    }
    fitted.ok_or_else(|| Error::Numerical(errs.join("; ")))
}

/// What a refit gained over the current model.
struct Verdict {
    /// The part the refit is judged on: the held-out part when there is one ("validation"), else
    /// the estimation part; on a step test's response tail ([`Ctx::tail`]) the estimation part
    /// when the refit gains more there (module documentation, Decision).
    part: &'static str,
    /// That part's RMSE before and after the refit.
    before: f64,
    after: f64,
    /// Their relative change.
    change: f64,
    /// Judged on the estimation part of a step test: the response tail's RMSE rose by this much,
    /// beyond the margin (the refit extrapolates the settled response worse); it vetoes the
    /// effect.
    tail_worse: Option<f64>,
    /// Judged on the held-out part: the refit's held-out residual is white at the sample scale
    /// ([`Ctx::at_noise_floor`]).
    at_floor: bool,
    /// Change of BIC on the estimation part.
    dbic: f64,
    /// Fraction of the estimation sum of squares removed.
    removed: f64,
    /// Parameters of the current model that ran to a bound (they were not there before).
    base_at_bound: Vec<String>,
    /// The effect's own parameters at a bound.
    own_at_bound: Vec<String>,
}

impl Verdict {
    fn of(ctx: &Ctx<'_>, st: &State, ns: &State) -> Self {
        let nb = st.model.params.len();
        let mut base_at_bound = vec![];
        let mut own_at_bound = vec![];
        for (i, (p, v)) in ns.model.params.iter().zip(&ns.values).enumerate() {
            // The record's initial state is not the plant: its levels may sit at the edge of
            // their range without saying anything about the effect. A parameter the current
            // model already had at a bound does not count either.
            if !p.free
                || ns.model.is_initial_state(i)
                || !p.bounds.at_edge(*v)
                || st.values.get(i).is_some_and(|w| p.bounds.at_edge(*w))
            {
                continue;
            }
            let s = format!("{} = {v:.3e}", p.name);
            if i < nb {
                base_at_bound.push(s);
            } else {
                own_at_bound.push(s);
            }
        }
        let held = (ctx.score(st), ctx.score(ns));
        let est = (st.est.rmse, ns.est.rmse);
        let held_change = held.1 / held.0 - 1.0;
        // A step test's tail holds the settled response, which an effect of the dynamics (a
        // delay) does not move: such an effect shows on the estimation part alone.
        let on_estimation = ctx.tail && est.1 / est.0 - 1.0 < held_change;
        let (part, (before, after)) = if on_estimation {
            ("estimation", est)
        } else {
            (scored_part(ns), held)
        };
        Verdict {
            part,
            before,
            after,
            change: after / before - 1.0,
            tail_worse: (on_estimation && held_change > ctx.opts.margin).then_some(held_change),
            at_floor: !on_estimation && ctx.at_noise_floor(ns),
            dbic: ctx.bic(ns) - ctx.bic(st),
            removed: 1.0 - ns.ssr / st.ssr.max(1e-300),
            base_at_bound,
            own_at_bound,
        }
    }

    /// Clears the held-out margin and BIC.
    fn pays(&self, ctx: &Ctx<'_>) -> bool {
        self.clears(ctx) && self.dbic < 0.0
    }

    /// Clears the whole held-out margin and BIC (the structure's own refit, [`credited`]).
    fn pays_in_full(&self, ctx: &Ctx<'_>) -> bool {
        self.tail_worse.is_none() && self.change <= -ctx.opts.margin && self.dbic < 0.0
    }

    /// Clears the held-out margin: the held-out RMSE falls by it, or by half of it to the noise
    /// floor (the refit's held-out residual white at the sample scale: what is left of the margin
    /// is noise no model can remove) with the estimation part agreeing (module documentation,
    /// Decision).
    fn clears(&self, ctx: &Ctx<'_>) -> bool {
        self.tail_worse.is_none() && self.clears_margin(ctx.opts.margin)
    }

    /// [`Verdict::clears`] with the margin `m`.
    fn clears_margin(&self, m: f64) -> bool {
        let half = 0.5 * m;
        // At the floor the estimation part must agree: the refit removes from its sum of squares
        // at least the share half the margin is in RMSE.
        let agreed = self.removed >= 1.0 - (1.0 - half) * (1.0 - half);
        self.change <= -m || (self.at_floor && self.change <= -half && agreed)
    }
}

/// The model in words: `K/(...) exp(-tau s)` and its effects, e.g. `; output_offset (y_offset =
/// 0.1)`.
fn describe(m: &FracModel) -> String {
    let v = m.values();
    let mut o = m
        .tf(&v)
        .map_or_else(|e| format!("({e})"), |tf| tf.to_string());
    for e in &m.effects {
        let p: Vec<String> = e
            .params()
            .into_iter()
            .map(|i| format!("{} = {:.4e}", m.params[i].name, v[i]))
            .collect();
        o.push_str(&format!("; {}", e.name()));
        if !p.is_empty() {
            o.push_str(&format!(" ({})", p.join(", ")));
        }
        if matches!(e, Effect::Coulomb { sampled: true, .. }) {
            o.push_str(" decided at the sample instants");
        }
    }
    o
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
            "the residual depends on the input: {} cross-correlation lags with the prewhitened \
             input outside +-{:.3} ({} with its changes), peak {:.3} at lag {}",
            an.cross_outside, an.bound, an.change_outside, an.cross_peak, an.cross_peak_lag
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
    diagnose_until(rec, id, opts, &|| false, &|_, _| false)
}

/// [`diagnose`], given up ([`Error::Cancelled`]) as soon as `stop()` says so: it is asked before
/// each round and each refit (a diagnosis started before it was known whether it is needed,
/// [`structures::diagnose_best`]). `halt(r, rmse)`, asked at the same points with the number of
/// effects kept so far and the current model's held-out RMSE, ends the diagnosis there instead
/// ([`Diagnosis::halted`]: the structure comparison's successive halving).
pub(crate) fn diagnose_until(
    rec: &Record,
    id: &Identification,
    opts: &DiagnoseOptions,
    stop: &dyn Fn() -> bool,
    halt: &dyn Fn(usize, f64) -> bool,
) -> Result<Diagnosis> {
    diagnose_from(rec, id, opts, (stop, halt), None)
}

/// [`diagnose_until`], from the start of the round a halted diagnosis of the same `id` and
/// `opts` was halted in when `from` is its [`Diagnosis::resume`] (the rounds before are not
/// made again: the same diagnosis, bit for bit, as made again from the base fit).
pub(crate) fn diagnose_from(
    rec: &Record,
    id: &Identification,
    opts: &DiagnoseOptions,
    (stop, halt): (&dyn Fn() -> bool, &dyn Fn(usize, f64) -> bool),
    from: Option<&Resume>,
) -> Result<Diagnosis> {
    run_from(rec, id, opts, (stop, halt), (from, &[])).map_err(|(e, _)| e)
}

/// [`diagnose`] with `carried`, effects of another structure's final model, each offered in
/// the first round as a start of that effect's refit ([`carry`]).
pub(crate) fn diagnose_carrying(
    rec: &Record,
    id: &Identification,
    opts: &DiagnoseOptions,
    carried: &[carry::Carried],
) -> Result<Diagnosis> {
    run_from(rec, id, opts, (&|| false, &|_, _| false), (None, carried)).map_err(|(e, _)| e)
}

/// [`diagnose_until`], and when `stop` gave it up, the state at the start of the round it was
/// given up in ([`Resume`]): the diagnosis, when needed after all, goes on from there
/// ([`diagnose_from`]).
pub(crate) fn diagnose_resumable(
    rec: &Record,
    id: &Identification,
    opts: &DiagnoseOptions,
    (stop, halt): (&dyn Fn() -> bool, &dyn Fn(usize, f64) -> bool),
) -> (Result<Diagnosis>, Option<Resumable>) {
    match run_from(rec, id, opts, (stop, halt), (None, &[])) {
        Ok(d) => (Ok(d), None),
        Err((e, r)) => {
            let given_up = matches!(e, Error::Cancelled(_));
            let r = r.filter(|_| given_up);
            (Err(e), r.map(|r| Resumable(std::sync::Arc::from(r))))
        }
    }
}

/// An error of [`run_from`], with the state at the start of the round it arose in.
type Interrupted = (Error, Option<Box<Resume>>);

/// [`diagnose_from`], its error with the state at the start of the round it arose in. Continued
/// from `from`, the path up to there is published again (`halt`'s board: the values the rounds
/// not made again would have published). `carried` as [`diagnose_carrying`].
fn run_from(
    rec: &Record,
    id: &Identification,
    opts: &DiagnoseOptions,
    (stop, halt): (&dyn Fn() -> bool, &dyn Fn(usize, f64) -> bool),
    (from, carried): (Option<&Resume>, &[carry::Carried]),
) -> std::result::Result<Diagnosis, Interrupted> {
    let mut ctx = Ctx::of(rec, id, opts).map_err(|e| (e, None))?;
    ctx.carried = carried;
    let base = ctx
        .state(id.model.clone(), id.report.values.clone())
        .map_err(|e| (e, None))?;
    let Some(r) = from else {
        let found = Found {
            st: base.clone(),
            path: vec![ctx.step(&base)],
            kept: vec![],
            rejected: BTreeMap::new(),
            refuted: vec![],
            ambiguous: vec![],
            residual_before: None,
            residual_now: None,
        };
        let run = Rounds {
            ctx,
            found,
            halted: None,
        };
        return run.rounds(0, &base, (stop, halt));
    };
    for (k, step) in r.found.path.iter().enumerate().take(r.round) {
        halt(k, step.rmse);
    }
    ctx.lead = r.lead;
    ctx.u = r.u.clone();
    let run = Rounds {
        ctx,
        found: r.found.clone(),
        halted: None,
    };
    r.cache
        .clone()
        .enter(|| run.rounds(r.round, &base, (stop, halt)))
}

impl<'a> Ctx<'a> {
    /// The context of a diagnosis of `id` on `rec`, its record and options checked.
    fn of(rec: &'a Record, id: &Identification, opts: &'a DiagnoseOptions) -> Result<Self> {
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
        Ok(Ctx {
            rec,
            u: rec.u.iter().map(|v| v - u0).collect(),
            y: rec.y.iter().map(|v| v - y0).collect(),
            lead: 0,
            split: id.split,
            held: id.validated_by.blocks.clone(),
            dt: rec.dt,
            carried: &[],
            u0,
            y0,
            start: id.start.clone(),
            unquantized: find_quantization(&rec.y).is_none(),
            tail: id.validated_by.kind == crate::oe::ValidationKind::ResponseTail,
            opts,
        })
    }
}

/// Held-out RMSEs of two refits of one round within this relative difference are a tie
/// ([`beats`]): their difference is rounding and the refits' stopping rule, not evidence. Two
/// one-parameter static input maps on an input of three levels, or of five symmetric ones (a
/// saturation, a dead band, a power law), each fit any map of those levels with the gain: their
/// refits end at the same model, as near to it as their stopping rule takes them (a refit stops
/// when its cost falls by less than 1e-4 over 5 iterations: RMSEs 5e-5 apart), and which RMSE
/// came out lower decided the effect kept (the zoo's saturation case 0089: a power law 7e-6
/// below the saturation, with a tie at 1e-6).
pub const REFIT_TIE: f64 = 1e-4;

/// Whether a refit `(score, rank)` beats the round's best so far: a lower held-out RMSE beyond
/// [`REFIT_TIE`], or within it the effect earlier in the library ([`probes::library`]'s order,
/// `rank`), so that ties are settled the same way whatever the last bits.
fn beats(new: (f64, usize), best: (f64, usize)) -> bool {
    if (new.0 - best.0).abs() <= REFIT_TIE * new.0.abs().max(best.0.abs()) {
        new.1 < best.1
    } else {
        new.0 < best.0
    }
}

/// The diagnosis loop's state between rounds ([`diagnose_until`]).
struct Rounds<'a> {
    ctx: Ctx<'a>,
    found: Found,
    halted: Option<usize>,
}

/// The best kept candidate of a round: its refit, the kept effect, its key and its input advance.
type Best = (State, KeptEffect, String, Option<usize>);

impl Rounds<'_> {
    /// The rounds from `first` on, and the diagnosis (`base` the base fit's state); a halted
    /// diagnosis keeps the state at the start of the round it was halted in ([`Resume`]), and
    /// an error comes with the state at the start of the round it arose in.
    fn rounds(
        mut self,
        first: usize,
        base: &State,
        (stop, halt): (&dyn Fn() -> bool, &dyn Fn(usize, f64) -> bool),
    ) -> std::result::Result<Diagnosis, Interrupted> {
        let library = probes::library();
        let mut resume = None;
        for round in first..self.ctx.opts.max_rounds {
            let at_start = self.resume(round);
            match self.round(round, &library, stop, halt) {
                Err(e) => return Err((e, Some(Box::new(at_start)))),
                Ok(true) => {}
                Ok(false) => {
                    resume = self
                        .halted
                        .map(|_| Resumable(std::sync::Arc::new(at_start)));
                    break;
                }
            }
        }
        let quantization = find_quantization(&self.ctx.rec.y);
        let mut d = self.finish(base, quantization);
        d.resume = resume;
        Ok(d)
    }

    /// The state at the start of round `round` ([`Resume`]).
    fn resume(&self, round: usize) -> Resume {
        Resume {
            round,
            lead: self.ctx.lead,
            u: self.ctx.u.clone(),
            found: self.found.clone(),
            cache: fracsim::modal::RootsCache::entered(),
        }
    }

    /// One round: the probes look at the residual, the strong candidates are refitted and the
    /// best kept one is added. Whether the loop goes on (`false`: nothing kept, or halted).
    fn round(
        &mut self,
        round: usize,
        library: &[Box<dyn Probe>],
        stop: &dyn Fn() -> bool,
        halt: &dyn Fn(usize, f64) -> bool,
    ) -> Result<bool> {
        let cancelled = || Error::Cancelled("the diagnosis of a structure not needed".into());
        if stop() {
            return Err(cancelled());
        }
        if halt(round, self.ctx.score(&self.found.st)) {
            self.halted = Some(round);
            return Ok(false);
        }
        let mut findings = self.look(round, library)?;
        if round == 0 {
            self.found.ambiguous = std::mem::take(&mut findings.ambiguous);
        }
        self.found.rejected.extend(findings.rejected);
        let mut cands = findings.candidates;
        let forced = if round == 0 {
            self.offer_carried(&mut cands)
        } else {
            vec![]
        };
        cands.sort_by(|a, b| b.r2.total_cmp(&a.r2));
        let mut best: Option<Best> = None;
        let mut rebase: Option<State> = None;
        // The cap counts the candidates with evidence: one proposed at the floor (a sign-blind
        // sensor's one-signed data, a delay the orders mimic) has no evidence to be ranked by,
        // so candidates with some would otherwise push it out.
        let mut strong = 0;
        for c in cands {
            let opts = self.ctx.opts;
            let capped = c.r2 > opts.min_r2 && strong >= opts.max_refits;
            strong += usize::from(c.r2 > opts.min_r2);
            if (c.r2 < opts.min_r2 || capped) && !forced.contains(&c.key) {
                self.found
                    .rejected
                    .entry(c.key.clone())
                    .or_insert(RejectedEffect {
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
            // A candidate proposed without a signature (its evidence at the floor: the delay a
            // base fit's free orders mimic) is refitted in the first round that proposes it; once
            // a refit has rejected it, a later round (the model with one more effect) does not
            // refit it again, and its rejection stands.
            if c.r2 <= opts.min_r2 && self.found.refuted.contains(&c.key) {
                continue;
            }
            if stop() {
                return Err(cancelled());
            }
            if halt(round, self.ctx.score(&self.found.st)) {
                self.halted = Some(round);
                return Ok(false);
            }
            self.refit(&c, library, (&mut best, &mut rebase));
        }
        Ok(self.keep(best, rebase, library))
    }

    /// The carried effects ([`Ctx::carried`]) among the first round's candidates: each a start
    /// of its effect's refit (the probe's candidate, its starts after it, or a candidate of its
    /// own when the probe proposed none), refitted whatever its evidence (its keys returned).
    fn offer_carried(&self, cands: &mut Vec<Candidate>) -> Vec<String> {
        let mut forced = vec![];
        let now = self.found.st.model_at_values();
        for c in self.ctx.carried {
            let start = c.onto(&now);
            match cands
                .iter_mut()
                .find(|k| k.name == c.name && k.lead.is_none())
            {
                Some(k) => {
                    k.starts.insert(0, start);
                    k.evidence = format!("{}; {}", k.evidence, c.evidence);
                    forced.push(k.key.clone());
                }
                None => {
                    cands.push(Candidate {
                        name: c.name,
                        lead: None,
                        key: c.name.to_string(),
                        r2: 0.0,
                        evidence: c.evidence.clone(),
                        starts: vec![start],
                    });
                    forced.push(c.name.to_string());
                }
            }
        }
        forced
    }

    /// The probes' findings on the current model's residual (its tests kept for the report).
    fn look(&mut self, round: usize, library: &[Box<dyn Probe>]) -> Result<Findings> {
        let mut findings = Findings::default();
        let look = Look::new(&self.ctx, &self.found.st, &self.found.kept)?;
        if round == 0 {
            self.found.residual_before = Some(look.analysis.clone());
        }
        self.found.residual_now = Some(look.analysis.clone());
        for p in library {
            p.probe(&look, &mut findings)?;
        }
        Ok(findings)
    }

    /// Refit candidate `c` ([`try_candidate`]): kept as the round's `best` when it is better,
    /// else its rejection recorded, and the structure's refit without it as the round's
    /// `rebase` when that made the gain ([`credited`]) and is the best such refit so far.
    fn refit(
        &mut self,
        c: &Candidate,
        library: &[Box<dyn Probe>],
        (best, rebase): (&mut Option<Best>, &mut Option<State>),
    ) {
        let ctx = &self.ctx;
        let probe = library.iter().find(|p| p.name() == c.name);
        let rank = |name: &str| {
            library
                .iter()
                .position(|p| p.name() == name)
                .unwrap_or(usize::MAX)
        };
        let needs = |ns: &State, k: Option<&KeptEffect>| {
            needs_credit(
                c.r2 <= ctx.opts.min_r2,
                best.as_ref()
                    .map(|(b, bk, _, _)| (ctx.score(b), rank(&bk.name))),
                k.map(|k| (ctx.score(ns), rank(&k.name))),
            )
        };
        match try_candidate(ctx, &self.found.st, c, probe.map(|p| p.as_ref()), &needs) {
            Ok((ns, k, lead)) => {
                if best.as_ref().is_none_or(|(b, bk, _, _)| {
                    beats(
                        (ctx.score(&ns), rank(&k.name)),
                        (ctx.score(b), rank(&bk.name)),
                    )
                }) {
                    *best = Some((ns, k, c.key.clone(), lead));
                }
            }
            Err((r, null)) => {
                if c.r2 <= ctx.opts.min_r2 {
                    self.found.refuted.push(c.key.clone());
                }
                self.found.rejected.insert(c.key.clone(), r);
                if let Some(null) = null {
                    if rebase
                        .as_ref()
                        .is_none_or(|b| ctx.score(&null) < ctx.score(b))
                    {
                        *rebase = Some(*null);
                    }
                }
            }
        }
    }

    /// Add the round's best kept candidate, or with none the structure's better refit that a
    /// rejected candidate's refit led to ([`credited`]); a model its probe puts in the kept
    /// candidate's place ([`Probe::in_place_of`]) instead of it. Whether the model changed.
    fn keep(
        &mut self,
        best: Option<Best>,
        rebase: Option<State>,
        library: &[Box<dyn Probe>],
    ) -> bool {
        let Some((ns, k, key, lead)) = best else {
            let Some(null) = rebase else {
                return false;
            };
            self.move_to(null);
            return true;
        };
        let probe = library.iter().find(|p| p.name() == k.name);
        // (Not for an advanced input: the other model would be of the record as recorded.)
        let instead = probe
            .filter(|_| lead.is_none())
            .and_then(|p| p.in_place_of(&self.ctx, &self.found.st, &ns));
        if let Some((other, rejected)) = instead {
            self.found.rejected.insert(key.clone(), rejected);
            self.found.refuted.push(key);
            self.move_to(other);
            return true;
        }
        if let Some(l) = lead {
            self.ctx = self.ctx.with_lead(l);
        }
        self.found.rejected.remove(&key);
        self.found.rejected.remove(&k.name);
        self.found.kept.push(k);
        self.found.st = ns;
        self.found.path.push(self.ctx.step(&self.found.st));
        self.backward();
        self.found.residual_now = None;
        true
    }

    /// Make `st`, a model with no effect more, the current one (a step of the path).
    fn move_to(&mut self, st: State) {
        self.found.st = st;
        self.found.path.push(self.ctx.step(&self.found.st));
        self.found.residual_now = None;
    }

    /// The diagnosis from the base model `base` to the current one.
    fn finish(self, base: &State, quantization: Option<Quantization>) -> Diagnosis {
        let Rounds {
            ctx,
            found:
                Found {
                    st,
                    kept,
                    rejected,
                    ambiguous,
                    path,
                    residual_before,
                    residual_now,
                    ..
                },
            halted,
        } = self;
        // Candidates kept in a later round are not rejected.
        let rejected: Vec<RejectedEffect> = rejected
            .into_values()
            .filter(|r| r.name == "periodic" || !kept.iter().any(|k| k.name == r.name))
            .collect();
        let analysis_of = |st: &State| {
            let e: Vec<f64> = (0..ctx.split).map(|k| ctx.y[k] - st.yhat[k]).collect();
            analyse(&e, &ctx.u[..ctx.split], ctx.dt)
        };
        let residual_before = residual_before.unwrap_or_else(|| analysis_of(base));
        let residual_after = residual_now.unwrap_or_else(|| analysis_of(&st));
        let remaining = remaining_structure(&residual_after, quantization);
        let y0 = ctx.y0;
        let ya = |s: &State| s.yhat.iter().map(|v| v + y0).collect::<Vec<f64>>();
        let model = st.model_at_values();
        Diagnosis {
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
            final_model: describe(&model),
            model,
            yhat_before: ya(base),
            yhat_after: ya(&st),
            split: ctx.split,
            path,
            halted,
            resume: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::OffsetMode;
    use crate::oe::{identify, IdentOptions, Structure};

    /// The noise floor's half margin (module documentation, Decision): a refit at the floor
    /// clears it only when the estimation part agrees; the full margin needs no floor.
    #[test]
    fn the_noise_floors_half_margin_needs_the_estimation_part_to_agree() {
        let v = |change: f64, at_floor: bool, removed: f64| Verdict {
            part: "validation",
            before: 1.0,
            after: 1.0 + change,
            change,
            tail_worse: None,
            at_floor,
            dbic: -10.0,
            removed,
            base_at_bound: vec![],
            own_at_bound: vec![],
        };
        let m = 0.05;
        // the CI subset's two-mode case 0029: a delay, -3.0% held out, 0.7% of the estimation SS
        assert!(!v(-0.030, true, 0.007).clears_margin(m));
        // the zoo's friction 0286: -4.7% held out, 12% of the estimation SS
        assert!(v(-0.047, true, 0.12).clears_margin(m));
        assert!(!v(-0.047, false, 0.12).clears_margin(m));
        // just short of half the margin's share of the sum of squares (4.94%)
        assert!(!v(-0.047, true, 0.049).clears_margin(m));
        assert!(v(-0.047, true, 0.0494).clears_margin(m));
        // less than half the margin held out
        assert!(!v(-0.024, true, 0.12).clears_margin(m));
        assert!(v(-0.05, false, 0.0).clears_margin(m));
    }

    /// A paying refit is checked against the structure refitted without its effect (`credited`)
    /// only where the round's outcome can depend on the check.
    #[test]
    fn a_refit_is_credited_to_its_effect_only_where_the_round_can_depend_on_it() {
        // no best yet: every paying refit is checked, kept or not (its refit without the
        // effect may become the current model)
        assert!(needs_credit(false, None, Some((1.0, 3))));
        assert!(needs_credit(false, None, None));
        // a best: only a kept refit that beats it
        let best = Some((1.0, 3));
        assert!(needs_credit(false, best, Some((0.9, 5))));
        assert!(!needs_credit(false, best, Some((1.1, 0))));
        assert!(!needs_credit(false, best, None));
        // a tie goes to the effect earlier in the library, as the round decides it
        assert!(needs_credit(false, best, Some((1.0 + 1e-6, 2))));
        assert!(!needs_credit(false, best, Some((1.0 - 1e-6, 4))));
        // a candidate at the evidence floor always: its rejection is remembered
        assert!(needs_credit(true, best, Some((1.1, 0))));
        assert!(needs_credit(true, best, None));
    }

    /// A refit beats the round's best by a held-out RMSE lower beyond `REFIT_TIE`; within it
    /// (a tie) the effect earlier in the library does, whichever came out lower in its last bits.
    #[test]
    fn ties_between_refits_go_to_the_effect_earlier_in_the_library() {
        let names: Vec<&str> = probes::library().iter().map(|p| p.name()).collect();
        let at = |name: &str| names.iter().position(|n| *n == name).unwrap();
        let (sat, pow) = (at("saturation"), at("power_law"));
        assert!(sat < pow, "{names:?}");
        assert!(beats((0.5, pow), (0.6, sat)));
        assert!(!beats((0.6, sat), (0.5, pow)));
        let x = 2.7428e-2;
        let below = x * (1.0 - 1e-9);
        assert!(beats((x, sat), (below, pow)));
        assert!(!beats((below, pow), (x, sat)));
        assert!(!beats((below, sat), (x, sat)));
        assert!(beats((x * (1.0 - 1e-3), pow), (x, sat)));
        // The zoo's case 0089: two maps of the same levels, the power law's refit 7e-6 lower.
        assert!(beats((x, sat), (x * (1.0 - 7e-6), pow)));
    }

    /// Seeded uniform numbers in `(0, 1)` (a 64-bit LCG's top 53 bits): the same record every run.
    fn uniform_from(seed: u64) -> impl FnMut() -> f64 {
        let mut next = crate::testdata::lcg(seed);
        move || ((next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// A long record for [`lead_screen`]: `6 x 2^14` samples at 1 ms (its estimation part beyond
    /// `4 x 2^14`), a commensurate plant driven by a random binary input (a new level every 20
    /// samples) that reaches it `delay` whole samples late (the input shifted, so the delay does
    /// not rest on the simulator's own), 2% noise. Seeded: the same record every run.
    fn long_record(delay: usize) -> Record {
        let (n, dt) = (6 * LEAD_SCREEN_SAMPLES, 1e-3);
        let mut uniform = uniform_from(0x9e37_79b9_7f4a_7c15);
        let mut level = 1.0;
        let u: Vec<f64> = (0..n)
            .map(|k| {
                if k % 20 == 0 {
                    level = if uniform() < 0.5 { -1.0 } else { 1.0 };
                }
                level
            })
            .collect();
        let late: Vec<f64> = (0..n)
            .map(|k| if k >= delay { u[k - delay] } else { 0.0 })
            .collect();
        let truth = FracModel::commensurate(2.0, 0.05, 1e-3, 0.8);
        let mut y = vec![0.0; n];
        truth.simulate(&truth.values(), &late, dt, &mut y).unwrap();
        let mean = y.iter().sum::<f64>() / n as f64;
        let sd = (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        for v in &mut y {
            // Box-Muller.
            let (a, b) = (uniform(), uniform());
            *v += 0.02 * sd * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos();
        }
        Record::from_samples(&u, &y, dt).unwrap()
    }

    /// A record of a commensurate plant whose output drifts (a ramp) and whose input is offset:
    /// effects the diagnosis keeps one per round.
    fn drifting_record() -> Record {
        let (n, dt) = (3000, 1e-3);
        let mut uniform = uniform_from(0x2545_f491_4f6c_dd1d);
        let mut level = 1.0;
        let u: Vec<f64> = (0..n)
            .map(|k| {
                if k % 50 == 0 {
                    level = 2.0 * uniform() - 1.0;
                }
                level
            })
            .collect();
        let truth = FracModel::commensurate(2.0, 0.05, 1e-3, 0.8);
        let mut y = vec![0.0; n];
        truth.simulate(&truth.values(), &u, dt, &mut y).unwrap();
        for (k, v) in y.iter_mut().enumerate() {
            *v += 0.4 * k as f64 / n as f64 + 0.01 * (uniform() - 0.5);
        }
        Record::from_samples(&u, &y, dt).unwrap()
    }

    /// A diagnosis halted after its first kept effect (or given up by `stop`) and continued
    /// from its [`Resume`] is the diagnosis run to its end, bit for bit (report, path, final
    /// model and output).
    #[test]
    fn a_halted_diagnosis_continued_is_the_diagnosis_run_to_its_end() {
        let rec = drifting_record();
        let opts = IdentOptions {
            offsets: OffsetMode::None,
            ..IdentOptions::default()
        };
        let id = identify(&rec, &FracModel::commensurate(1.0, 0.05, 1e-3, 0.8), &opts).unwrap();
        let dopts = DiagnoseOptions::default();
        let never = || false;
        let full = fracsim::modal::RootsCache::new()
            .enter(|| diagnose_until(&rec, &id, &dopts, &never, &|_, _| false))
            .unwrap();
        assert!(!full.effects.is_empty(), "{:?}", full.rejected);
        assert!(full.halted.is_none() && full.resume.is_none());
        // Continued from a state, from an empty pole cache of its own.
        let continued = |from: &Resume| {
            fracsim::modal::RootsCache::new()
                .enter(|| diagnose_from(&rec, &id, &dopts, (&never, &|_, _| false), Some(from)))
                .unwrap()
        };
        let json = |d: &Diagnosis| serde_json::to_string(d).unwrap();
        for at in 1..=full.effects.len() {
            let mut cache = fracsim::modal::RootsCache::new();
            let halted = cache
                .enter(|| diagnose_until(&rec, &id, &dopts, &never, &|r, _| r >= at))
                .unwrap();
            assert_eq!(halted.halted, Some(at));
            assert_eq!(halted.effects.len(), at);
            let from = halted
                .resume
                .as_ref()
                .expect("a halted diagnosis keeps its state");
            let resumed = continued(&from.0);
            assert_eq!(json(&resumed), json(&full), "halted at {at}");
            assert_eq!(resumed.path, full.path);
            assert_eq!(resumed.yhat_after, full.yhat_after);
            assert_eq!(resumed.model.values(), full.model.values());
            assert!(resumed.halted.is_none() && resumed.resume.is_none());
        }
        // Given up (`stop`) at its n-th test, round start or refit, and continued: the same.
        for n in [2, 4, 7] {
            let calls = std::cell::Cell::new(0);
            let stop = || {
                calls.set(calls.get() + 1);
                calls.get() >= n
            };
            let mut cache = fracsim::modal::RootsCache::new();
            let (d, from) =
                cache.enter(|| diagnose_resumable(&rec, &id, &dopts, (&stop, &|_, _| false)));
            assert!(matches!(d, Err(Error::Cancelled(_))), "given up at {n}");
            let from = from.expect("a diagnosis given up keeps its state");
            let resumed = continued(&from.0);
            assert_eq!(json(&resumed), json(&full), "given up at {n}");
            assert_eq!(resumed.yhat_after, full.yhat_after);
        }
    }

    fn diagnosed(rec: &Record) -> Diagnosis {
        let opts = IdentOptions {
            offsets: OffsetMode::None,
            ..IdentOptions::default()
        };
        let id = identify(rec, &FracModel::commensurate(1.0, 0.05, 1e-3, 0.8), &opts).unwrap();
        assert!(id.split >= 4 * LEAD_SCREEN_SAMPLES, "split {}", id.split);
        diagnose(rec, &id, &DiagnoseOptions::default()).unwrap()
    }

    /// The keep ceiling is the decision's own threshold: a refit just above it is rejected by
    /// BIC (or by the margin without a held-out part), one just below it is not, with BIC as
    /// [`Ctx::bic`] computes it.
    #[test]
    fn the_keep_ceiling_is_where_bic_and_the_margin_stop_agreeing() {
        let (ssr, n, k) = (12.5, 3000, 7);
        for dk in [0, 1, 3] {
            let c = ceiling(ssr, n, dk as f64, None);
            assert!(bic(c * (1.0 + 1e-9), n, k + dk) > bic(ssr, n, k), "dk {dk}");
            assert!(bic(c * (1.0 - 1e-9), n, k + dk) < bic(ssr, n, k), "dk {dk}");
        }
        // Without a held-out part the 5% margin on the estimation RMSE binds first (BIC asks
        // 0.27% of the sum of squares per added parameter here, the margin 9.75%).
        let c = ceiling(ssr, n, 1.0, Some(0.05));
        assert!((c - ssr * 0.95f64.powi(2)).abs() < 1e-12, "{c}");
        assert!(((c / n as f64).sqrt() / (ssr / n as f64).sqrt() - 0.95).abs() < 1e-12);
    }

    #[test]
    fn a_long_clean_record_rejects_the_delay_on_its_leading_part() {
        let d = diagnosed(&long_record(0));
        assert!(d.effects.is_empty(), "{:?}", d.effects);
        let delay = d.rejected.iter().find(|r| r.name == "delay").unwrap();
        assert!(
            delay
                .reason
                .contains("refitted on the first 16384 estimation samples only"),
            "{}",
            delay.reason
        );
    }

    #[test]
    fn a_long_record_keeps_a_delay_that_passes_the_leading_part() {
        let d = diagnosed(&long_record(3));
        let names: Vec<&str> = d.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["delay"], "{:?}", d.rejected);
        let tau = d.effects[0].params["tau"];
        assert!((tau - 3e-3).abs() < 3e-4, "tau = {tau}");
    }
}
