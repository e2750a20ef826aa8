//! The time-domain use case (`fracid time`, `fracid.fit_time`, the fleet and the demo): one
//! request holding every option and its default once, one [`run`], one typed [`TimeReport`].
//!
//! The CLI parses its flags into a [`TimeRequest`], Python its keyword arguments; both call
//! [`run`] and present the report (text, JSON, a dict): the same request gives the same report.

use super::observe::{enter, Observe, Stage};
use super::score::ScoreReport;
use super::{Held, ModelReport, Names, Preset, Structure};
use crate::data::{OffsetMode, Record};
use crate::diagnose::structures::{diagnose_best_fitting, fit_best, StructureChoice};
use crate::diagnose::{DiagnoseOptions, Diagnosis};
use crate::metrics::{residual_test, Fit, ResidualTest};
use crate::oe::checks::gather;
use crate::oe::{
    identify_with_progress, score, FracModel, IdentOptions, Identification, InitialState,
    ParamEstimate, StartMode, Validation, ValidationKind,
};
use crate::{Error, Result};
use fracsim::approx::Method;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Every option of the time-domain identification, with its default (`Default`, and missing
/// fields when deserialised). Words are those of the CLI flags and the Python keywords.
///
/// The words the CLI and Python use are the JSON's (`"structure": "second-order"`), read into
/// enums once ([`super::request::words`]).
///
/// ```
/// use ident::app::{time::TimeRequest, Preset, Structure};
/// let r: TimeRequest = serde_json::from_str(r#"{"holdout": 0.2, "structure": "Second order"}"#).unwrap();
/// assert_eq!((&r.structure, r.holdout, r.max_iterations), (&Structure::Named(Preset::SecondOrder), Some(0.2), 500));
/// assert!(serde_json::to_string(&r).unwrap().contains(r#""structure":"second-order""#));
/// assert!(serde_json::from_str::<TimeRequest>(r#"{"offsets": "median"}"#).is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TimeRequest {
    /// A structure of the catalogue ([`super::Preset`]), `auto`, `general`, `general:N/D` or a
    /// transfer function used as the start.
    #[serde(with = "super::request::words")]
    pub structure: Structure,
    /// Approximation of the fractional operators: `refined`, `oustaloup` or `trigeassou`.
    #[serde(with = "super::request::words")]
    pub approx: Method,
    /// Approximation band `(w_b, w_h)` in rad/s (`None`: fracsim's `[1e-6/dt, 30 pi/dt]`).
    pub band: Option<(f64, f64)>,
    /// Approximation order `N` (`None`: fracsim's, 8).
    pub order: Option<usize>,
    /// A free integrator in series (an output that integrates, such as a position).
    pub integrator: bool,
    /// Fit an input delay (seconds, up to `max_delay`).
    pub delay: bool,
    /// Largest input delay in seconds (`None`: a fifth of the record, at most 1000 samples).
    pub max_delay: Option<f64>,
    /// Parameters held: `NAME` or `NAME=VALUE`, comma-separated ([`super::fix_free`]).
    #[serde(with = "super::request::words")]
    pub fix: Held,
    /// Parameters a structure holds that are fitted (comma-separated names).
    #[serde(with = "super::request::words")]
    pub free: Names,
    /// Start values by parameter name: the fit then starts from them (no automatic start).
    pub start: BTreeMap<String, f64>,
    /// The automatic start from the data (false: the structure's values).
    pub auto_start: bool,
    /// Fraction held out for validation at the end (`None`: 0.3, or 0 with a validation record).
    pub holdout: Option<f64>,
    /// Operating point removal: `initial`, `mean` or `none`.
    #[serde(with = "super::request::words")]
    pub offsets: OffsetMode,
    /// Fit a constant output offset.
    pub fit_offset: bool,
    /// Initial state: `auto` (rest when the record rests before its first input change, else
    /// estimated), `estimate` (a past held input, fitted) or `rest`.
    #[serde(with = "super::request::words")]
    pub initial: InitialState,
    /// Maximum Levenberg-Marquardt iterations of every fit (the diagnosis's refits take at most
    /// 60, or this when it is smaller).
    pub max_iterations: usize,
    /// Samples at the start of the estimation part left out of the cost (a transient the model
    /// need not explain).
    pub skip: usize,
    /// Lags of the residual whiteness and cross-correlation test.
    pub max_lag: usize,
    /// Fit the named structure alone, once: no structures compared, no diagnosis (the fast path,
    /// for fleets of records already understood). By default (`false`) the loop is closed: the
    /// candidate structures are compared, the best is diagnosed and its effects kept when they
    /// pay on held-out data, and the report leads with that model ([`run`]).
    pub plain: bool,
    /// The diagnosis's margin: the held-out improvement an effect must bring.
    pub margin: f64,
    /// The diagnosis's evidence `R^2` a candidate effect needs to be refitted.
    pub min_r2: f64,
    /// The diagnosis's rounds of effects.
    pub max_rounds: usize,
}

impl Default for TimeRequest {
    fn default() -> Self {
        let d = DiagnoseOptions::default();
        Self {
            structure: Structure::Named(Preset::Pmsm),
            approx: Method::Refined,
            band: None,
            order: None,
            integrator: false,
            delay: false,
            max_delay: None,
            fix: Held::default(),
            free: Names::default(),
            start: BTreeMap::new(),
            auto_start: true,
            holdout: None,
            offsets: OffsetMode::Initial,
            fit_offset: true,
            initial: InitialState::Auto,
            max_iterations: 500,
            skip: 0,
            max_lag: 25,
            plain: false,
            margin: d.margin,
            min_r2: d.min_r2,
            max_rounds: d.max_rounds,
        }
    }
}

/// A record with the name it is reported under (a file's path).
#[derive(Debug, Clone)]
pub struct Named {
    /// The name (a path, or `"validation"` for arrays).
    pub name: String,
    /// The record.
    pub record: Record,
}

/// The data of a time-domain request: the record, an optional separate validation record, other
/// estimation records for a joint fit, and the warnings of the reader that made them (they lead
/// the report's warnings).
#[derive(Debug, Clone)]
pub struct TimeData {
    /// The estimation record.
    pub record: Record,
    /// A separate validation record of the same plant.
    pub validation: Option<Named>,
    /// Further estimation records of the same plant ([`run_joint`]: one model fitted to all).
    pub joint: Vec<Named>,
    /// The readers' caveats (an incomplete acquisition, the part kept).
    pub reader_warnings: Vec<String>,
}

/// The fit figures of one model (docs/design.md §7 `fit`).
#[derive(Debug, Clone, Serialize)]
pub struct FitFigures {
    /// On the estimation part.
    pub estimation: Fit,
    /// On the held-out part (`None` when nothing was held out).
    pub validation: Option<Fit>,
    /// On a separate validation record.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation_file: Option<ScoreReport>,
}

/// `(order, alpha, eta)` of a non-integer order (Poinot & Trigeassou 2004).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct AlphaEta {
    /// The order.
    pub order: f64,
    /// Poinot-Trigeassou alpha.
    pub alpha: f64,
    /// Poinot-Trigeassou eta.
    pub eta: f64,
}

/// One model of a report (the base fit, or the final model after the diagnosis), with its own
/// parameters, fit figures and caveats.
#[derive(Debug, Clone, Serialize)]
pub struct ModelFit {
    /// The linear model and the names of its effects.
    pub model: ModelReport,
    /// Its parameters (the final model's have no standard errors: `null`).
    pub params: Vec<ParamEstimate>,
    /// Its fit figures.
    pub fit: FitFigures,
    /// Poinot-Trigeassou's `(alpha, eta)` of each non-integer order at the record's `dt`.
    pub alpha_eta: Vec<AlphaEta>,
    /// Its caveats (for the final model: the base fit's, then its own).
    pub warnings: Vec<String>,
    /// Whether it can be used.
    pub usable: bool,
    /// Why not, when it cannot.
    pub problems: Vec<String>,
    /// The whole model as fitted (structure, parameters with their ranges, effects, delay,
    /// approximation, operating point, initial state), as [`rescore`] and `fracid score` read it
    /// back.
    pub spec: FracModel,
    /// Its output on the absolute scale over the whole record (for plots and arrays; not
    /// serialised).
    #[serde(skip)]
    pub yhat: Vec<f64>,
}

/// The estimation/validation split (docs/design.md §7 `split`).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Split {
    /// Samples in the estimation part (the fit's cost counts them; with held-out blocks, the
    /// samples outside the blocks).
    pub estimation_samples: usize,
    /// Samples held out (the tail after the estimation part, or the blocks').
    pub validation_samples: usize,
}

/// The report of [`run`] (docs/design.md §7). The top-level model (`model`, `params`, `fit`,
/// `alpha_eta`, `warnings`, `usable`, `problems`) is the one the report recommends: the final
/// model with the diagnosis, else the fit; `model_is` says which, and with the diagnosis the base
/// fit is under `base`.
#[derive(Debug, Clone, Serialize)]
pub struct TimeReport {
    /// The recommended model and its figures.
    #[serde(flatten)]
    pub lead: ModelFit,
    /// Which model leads, in words.
    pub model_is: String,
    /// The base fit (with the diagnosis only: the chosen structure before its effects).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base: Option<ModelFit>,
    /// How the fit started.
    pub start: crate::oe::init::StartReport,
    /// The parameter values the base fit started from, by name.
    pub start_values: BTreeMap<String, f64>,
    /// The operating point removed.
    pub offsets: crate::data::Offsets,
    /// The initial state the record was fitted from, and why.
    pub initial_state: crate::oe::InitialReport,
    /// The split.
    pub split: Split,
    /// How the model was validated.
    pub validated_by: Validation,
    /// Levenberg-Marquardt iterations of the base fit.
    pub iterations: usize,
    /// Simulations of the base fit.
    pub evaluations: usize,
    /// Whether the base fit converged.
    pub converged: bool,
    /// How the base fit ended (the optimiser's word).
    pub termination: String,
    /// How the base fit ended, in words.
    pub stop_reason: String,
    /// Wall time of the whole use case (s).
    pub seconds: f64,
    /// Residual whiteness and independence of the base fit on its estimation part.
    pub residual_test: ResidualTest,
    /// The diagnosis (docs/design.md §7 `diagnosis`) with the structure comparison.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diagnosis: Option<DiagnosisReport>,
    /// The structure comparison of `structure = "auto"` (without the diagnosis).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub structures: Option<StructureChoice>,
    /// The request as run (every option with its value).
    pub request: TimeRequest,
    /// What the report was made from, for presentation (plots, arrays): not serialised.
    #[serde(skip)]
    pub fitted: Fitted,
}

/// One record of a joint fit in its report.
#[derive(Debug, Clone, Serialize)]
pub struct JointRecord {
    /// The record's name (a file's path; `record` for the first one given as arrays).
    pub file: String,
    /// Its operating point.
    pub offsets: crate::data::Offsets,
    /// The model's RMSE on it (its own initial state and output offset).
    pub rmse: f64,
    /// Its NRMSE fit (%).
    pub nrmse_percent: f64,
}

/// The report of [`run_joint`].
#[derive(Debug, Clone, Serialize)]
pub struct JointReport {
    /// The model fitted to all records.
    pub model: ModelReport,
    /// Its parameters: the plant's, then each further record's own.
    pub params: Vec<ParamEstimate>,
    /// Per record, its fit.
    pub records: Vec<JointRecord>,
    /// Whether the fit converged.
    pub converged: bool,
    /// Caveats (the readers' first).
    pub warnings: Vec<String>,
    /// The score on a separate validation record.
    pub fit: Option<FitFigures>,
    /// Whether the model can be used ([`super::verdict`]: the rules of a single record's fit on
    /// the record it fits worst, and its score on the validation record).
    pub usable: bool,
    /// Why not.
    pub problems: Vec<String>,
    /// The request as run.
    pub request: TimeRequest,
}

/// One model fitted to the record and the further records of `data.joint` (the plant's
/// parameters shared, each record with its own operating point, output offset and initial
/// state; each used whole), scored on the validation record when there is one
/// ([`crate::oe::identify_joint`]); `first` names the first record in the report. Not with the
/// diagnosis or `structure = "auto"`.
///
/// # Errors
/// [`Error::Options`] for the diagnosis or `auto`; as [`crate::oe::identify_joint`].
pub fn run_joint(
    req: &TimeRequest,
    data: &TimeData,
    first: &str,
    obs: &mut dyn Observe,
) -> Result<JointReport> {
    with_own_poles(|| run_joint_request(req, data, first, obs))
}

/// [`run_joint`] in the request's pole cache.
fn run_joint_request(
    req: &TimeRequest,
    data: &TimeData,
    first: &str,
    obs: &mut dyn Observe,
) -> Result<JointReport> {
    if req.structure.is_auto() {
        return Err(Error::Options(
            "a joint fit takes a named structure (not auto)".into(),
        ));
    }
    let rec = &data.record;
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    let (model, opts) = model_and_options(req, duration, rec.dt, data.validation.is_some())?;
    let mut recs = vec![rec.clone()];
    recs.extend(data.joint.iter().map(|n| n.record.clone()));
    enter(obs, Stage::Fit)?;
    let mut j = crate::oe::identify_joint(&recs, &model, &opts)?;
    j.report
        .warnings
        .splice(0..0, data.reader_warnings.iter().cloned());
    let fit = match &data.validation {
        Some(v) => {
            enter(obs, Stage::Validate)?;
            let sc = score(&j.model, &v.record, opts.offsets, opts.initial)?;
            Some(FitFigures {
                estimation: sc.fit,
                validation: None,
                validation_file: Some(ScoreReport::new(&v.name, &sc)),
            })
        }
        None => None,
    };
    let names = std::iter::once(first).chain(data.joint.iter().map(|n| n.name.as_str()));
    let v = super::verdict::verdict(
        j.problems.clone(),
        fit.as_ref().and_then(|f| f.validation_file.as_ref()),
    );
    Ok(JointReport {
        model: ModelReport::from(&j.tf),
        params: j.report.params.clone(),
        records: names
            .zip(&j.records)
            .map(|(file, (op, f, _))| JointRecord {
                file: file.to_string(),
                offsets: *op,
                rmse: f.rmse,
                nrmse_percent: f.nrmse_percent,
            })
            .collect(),
        converged: j.report.converged,
        warnings: j.report.warnings.clone(),
        fit,
        usable: v.usable,
        problems: v.problems,
        request: req.clone(),
    })
}

/// The results behind a [`TimeReport`], for plots and arrays.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The base identification (with the diagnosis, of the chosen structure).
    pub id: Identification,
}

/// The diagnosis in a report (docs/design.md §7 `diagnosis`): its findings, the structure
/// comparison and the final model (with its effects' names).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnosisReport {
    /// The diagnosis (the final model itself, and the outputs before and after, are in it but
    /// not serialised).
    #[serde(flatten)]
    pub diagnosis: Diagnosis,
    /// The structures compared and the choice.
    pub structures: StructureChoice,
    /// The final model.
    pub model: ModelReport,
}

/// The model and fit options of a request on a record of `duration_s` seconds sampled every
/// `dt_s` seconds, with a separate validation record or not.
///
/// # Errors
/// [`Error::Options`] for any option out of range or not understood.
pub fn model_and_options(
    req: &TimeRequest,
    duration_s: f64,
    dt_s: f64,
    has_validation: bool,
) -> Result<(FracModel, IdentOptions)> {
    let max_delay = match req.max_delay {
        Some(d) if !(d > 0.0 && d.is_finite()) => {
            return Err(Error::Options(format!(
                "max_delay must be a positive number of seconds, got {d}"
            )))
        }
        Some(d) => d,
        None => super::default_max_delay(duration_s, dt_s),
    };
    let (mut m, _) = req.structure.model(max_delay);
    m.approx.method = req.approx;
    if let Some(n) = req.order {
        m.approx.order = n;
    }
    if let Some((lo, hi)) = req.band {
        fracsim::approx::check_band(lo, hi)?;
        m.approx.band = Some((lo, hi));
    }
    if req.integrator {
        if req.structure.is_auto() {
            return Err(Error::Options(
                "structure auto does not go with the integrator (name a structure)".into(),
            ));
        }
        m.with_integrator();
    }
    if req.delay {
        // A delay written in the structure (exp(-tau s)) starts the fit when it is in range.
        let tau = m
            .delay
            .map(|i| m.params[i].value)
            .filter(|&t| t > 0.0 && t < max_delay)
            .unwrap_or(0.05 * max_delay);
        m.with_delay(tau, max_delay);
    }
    super::fix_free(&mut m, &req.fix, &req.free)?;
    for (name, v) in &req.start {
        let Some(i) = m.index_of(name) else {
            let names: Vec<&str> = m.params.iter().map(|p| p.name.as_str()).collect();
            return Err(Error::Options(format!(
                "start: no parameter '{name}' (the model has {})",
                names.join(", ")
            )));
        };
        if !v.is_finite() {
            return Err(Error::Options(format!(
                "start: {name} = {v} must be finite"
            )));
        }
        m.params[i].value = *v;
    }
    crate::oe::check_params(&m.params)?;
    if req.max_iterations == 0 {
        return Err(Error::Options("max_iterations must be at least 1".into()));
    }
    let mut opts = IdentOptions {
        offsets: req.offsets,
        // With a validation record the closed loop still holds out part of the estimation
        // record: its structures and effects are chosen there, never on the estimation error
        // alone, and the validation record stays an independent test of that choice.
        holdout: req.holdout.unwrap_or(if has_validation && req.plain {
            0.0
        } else {
            0.3
        }),
        fit_offset: req.fit_offset,
        start: if req.auto_start && req.start.is_empty() {
            StartMode::Auto
        } else {
            StartMode::Given
        },
        initial: req.initial,
        ..Default::default()
    };
    opts.fit.lm.max_iterations = req.max_iterations;
    opts.fit.skip = req.skip;
    Ok((m, opts))
}

/// The general structure's request when `req` names it (`general`, `general:N/D`), with the
/// request's integrator.
fn general_request(req: &TimeRequest) -> Option<crate::diagnose::general::GeneralRequest> {
    req.structure.general().map(|mut g| {
        if req.integrator {
            g.integrator = Some(true);
        }
        g
    })
}

static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many times [`run`] was called in this process (the demo reports that each record was
/// fitted and diagnosed once).
pub fn runs() -> usize {
    RUNS.load(std::sync::atomic::Ordering::Relaxed)
}

/// `f` with a cache of solved poles of its own (`fracsim::modal::RootsCache`), entered for the
/// request: the models the request builds on this thread find their poles from it, and nothing
/// of it outlives the request (its hints move the last bits of a fit), so that a record fitted
/// after others on the same thread (a fleet's loop, a Dask worker) gives the fit it gives alone.
fn with_own_poles<R>(f: impl FnOnce() -> R) -> R {
    fracsim::modal::RootsCache::new().enter(f)
}

/// The diagnosis options of a request: its refits' budget is the diagnosis's own (60 LM
/// iterations) or the request's `max_iterations` when that is smaller (a cap the user set holds
/// for every fit).
pub fn diagnose_options(req: &TimeRequest) -> DiagnoseOptions {
    let mut opts = DiagnoseOptions {
        margin: req.margin,
        min_r2: req.min_r2,
        max_rounds: req.max_rounds,
        ..DiagnoseOptions::default()
    };
    let lm = &mut opts.fit.lm;
    lm.max_iterations = lm.max_iterations.min(req.max_iterations);
    opts
}

/// Run the time-domain identification of `req` on `data`: the fit (or, with `structure =
/// "auto"`, the candidate structures, the one the data support kept), the diagnosis when asked
/// (structures compared, effects kept), the models scored on a separate validation record, and
/// the report. The observer sees each stage and the plain fit's simulations, and can cancel
/// between stages.
///
/// ```
/// use ident::app::{observe::Quiet, time};
/// use ident::data::Record;
/// let dt = 0.01;
/// // a first-order plant 2/(0.1 s + 1) driven by a square wave, exact for the held input
/// let u: Vec<f64> = (0..600).map(|k| if (k / 37) % 2 == 0 { 1.0 } else { -1.0 }).collect();
/// let (a, mut x) = ((-dt / 0.1f64).exp(), 0.0);
/// let y: Vec<f64> = u.iter().map(|&v| { let o = x; x = a * x + 2.0 * (1.0 - a) * v; o }).collect();
/// let data = time::TimeData {
///     record: Record::from_samples(&u, &y, dt).unwrap(),
///     validation: None,
///     joint: vec![],
///     reader_warnings: vec![],
/// };
/// let req = time::TimeRequest { structure: "2/(0.2 s + 1)".parse().unwrap(), ..Default::default() };
/// let r = time::run(&req, &data, &mut Quiet).unwrap();
/// assert!(r.lead.usable && r.lead.fit.validation.unwrap().nrmse_percent > 99.0);
/// ```
///
/// # Errors
/// Options out of range ([`Error::Options`]), data that cannot be fitted
/// ([`Error::NotEnoughData`], [`Error::Data`]), numerical breakdown, [`Error::Cancelled`].
pub fn run(req: &TimeRequest, data: &TimeData, obs: &mut dyn Observe) -> Result<TimeReport> {
    RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    with_own_poles(|| run_request(req, data, obs))
}

/// [`run`] in the request's pole cache.
fn run_request(req: &TimeRequest, data: &TimeData, obs: &mut dyn Observe) -> Result<TimeReport> {
    let t0 = std::time::Instant::now();
    let rec = &data.record;
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    let (model, opts) = model_and_options(req, duration, rec.dt, data.validation.is_some())?;
    if req.skip >= rec.len() {
        return Err(Error::Options(format!(
            "skip = {} leaves no sample of {}",
            req.skip,
            rec.len()
        )));
    }
    let (auto, label) = (req.structure.is_auto(), req.structure.label());
    let sized = sized_general(req, rec, &model, &opts, obs)?;
    let (model, label) = match &sized {
        Some(f) if !req.plain => (f.model.clone(), f.name.clone()),
        _ => (model, label),
    };
    let label = label.as_str();
    let (id, auto_choice, diagnosis) = if let Some(f) = sized.filter(|_| req.plain) {
        (f.id, Some(f.choice), None)
    } else if !req.plain {
        // The user's structure is fitted here while the other candidates' fits start on the
        // other cores ([`diagnose_best_fitting`]); the stages are entered as before.
        enter(obs, Stage::Fit)?;
        let n = crate::diagnose::structures::candidates(label, &model).len();
        let user = |par| {
            let mut opts = opts.clone();
            opts.fit.lm.par = par;
            let id =
                identify_with_progress(rec, &model, &opts, &mut |k, rmse| obs.simulation(k, rmse))?;
            enter(obs, Stage::Diagnose { n })?;
            Ok(id)
        };
        let d = diagnose_best_fitting(rec, label, &model, user, &opts, &diagnose_options(req))?;
        (d.id, None, Some((d.diagnosis, d.choice)))
    } else if auto {
        let n = crate::diagnose::structures::auto_candidates(&model).len();
        enter(obs, Stage::Structures { n })?;
        let (id, c) = fit_best(rec, &model, &opts)?;
        (id, Some(c), None)
    } else {
        enter(obs, Stage::Fit)?;
        let id =
            identify_with_progress(rec, &model, &opts, &mut |k, rmse| obs.simulation(k, rmse))?;
        (id, None, None)
    };
    let mut id = id;
    let (base_file, final_file) =
        score_validation(req, data, &mut id, &opts, diagnosis.as_ref(), obs)?;
    let mut base = base_fit(&id, base_file, rec);
    base.warnings
        .splice(0..0, data.reader_warnings.iter().cloned());
    let rt = estimation_residual_test(&id, rec, req.max_lag);
    let (lead, base, model_is, diagnosis) = match diagnosis {
        Some((d, c)) => {
            let (fin, is, report) = final_model(d, c, &base, req, data, final_file);
            // With no effect kept the final model is the chosen structure's base fit (or its
            // refit from a rejected effect's values, `diagnose::credited`): when its own
            // evaluation fails where the base fit's did not, the report leads with the base fit
            // (judged on the figures it was fitted with).
            if !fin.usable && report.diagnosis.effects.is_empty() && base.usable {
                let is = format!(
                    "base: the chosen structure's fit ({}; the diagnosis kept no effect, and \
                     the final model could not be judged again: {})",
                    report.structures.scores[report.structures.chosen].name,
                    fin.problems.join("; ")
                );
                (base.clone(), Some(base), is, Some(report))
            } else {
                (fin, Some(base), is, Some(report))
            }
        }
        None => (
            base,
            None,
            "base: the fit of the requested structure".into(),
            None,
        ),
    };
    Ok(TimeReport {
        lead,
        model_is,
        base,
        start: id.start_report.clone(),
        start_values: id
            .model
            .params
            .iter()
            .zip(&id.start)
            .map(|(p, v)| (p.name.clone(), *v))
            .collect(),
        offsets: id.offsets,
        initial_state: id.initial.clone(),
        split: Split {
            estimation_samples: id.validated_by.estimation_samples(id.split),
            validation_samples: rec.len() - id.validated_by.estimation_samples(id.split),
        },
        validated_by: id.validated_by.clone(),
        iterations: id.report.iterations,
        evaluations: id.report.evaluations,
        converged: id.report.converged,
        termination: format!("{:?}", id.report.termination),
        stop_reason: id.report.stop_reason().to_string(),
        seconds: t0.elapsed().as_secs_f64(),
        residual_test: rt,
        diagnosis,
        structures: auto_choice,
        request: req.clone(),
        fitted: Fitted { id },
    })
}

/// The general structure sized by the data ([`crate::diagnose::general`]), when the request names
/// it: fitted here; with the diagnosis (`--diagnose`) its chosen size is the user's structure,
/// else (`plain`) the sizes' fit is the report.
fn sized_general(
    req: &TimeRequest,
    rec: &Record,
    model: &FracModel,
    opts: &IdentOptions,
    obs: &mut dyn Observe,
) -> Result<Option<crate::diagnose::general::GeneralFit>> {
    let Some(g) = general_request(req) else {
        return Ok(None);
    };
    let n = crate::diagnose::general::search::SHORTLIST;
    enter(obs, Stage::Structures { n })?;
    // the plain fit is the answer: its size trimmed; with the diagnosis the size is diagnosed as
    // chosen ([`crate::diagnose::general::search::Then`])
    let then = if req.plain {
        crate::diagnose::general::search::Then::Trimmed
    } else {
        crate::diagnose::general::search::Then::AsChosen
    };
    crate::diagnose::general::fit(rec, model, opts, (&g, then)).map(Some)
}

/// The base fit's and the final model's scores on the separate validation record, if one was
/// given (`id.validated_by` then says how it was scored).
fn score_validation(
    req: &TimeRequest,
    data: &TimeData,
    id: &mut Identification,
    opts: &IdentOptions,
    diagnosis: Option<&(Diagnosis, StructureChoice)>,
    obs: &mut dyn Observe,
) -> Result<(Option<ScoreReport>, Option<ScoreReport>)> {
    let rec = &data.record;
    Ok(match &data.validation {
        Some(v) => {
            enter(obs, Stage::Validate)?;
            let goes_on = continues(rec, &v.record);
            let how = if goes_on {
                "it continues the estimation record (its time stamps follow on): scored from the \
                 state the estimation record ended in, with its operating point and output offset"
            } else {
                "its own initial state and output offset"
            };
            let chosen_on = if req.plain || id.validation.is_none() {
                ""
            } else {
                "; the structures and effects were chosen on the held-out part of the estimation \
                 record, so this record is an independent test of that choice"
            };
            id.validated_by = Validation {
                kind: ValidationKind::File,
                first: id.validated_by.first,
                note: format!("a separate record, {} ({how}){chosen_on}", v.name),
                blocks: id.validated_by.blocks.clone(),
            };
            let scored = |m: &FracModel| {
                if goes_on {
                    return continued(m, rec, &v.record).map(|s| ScoreReport::new(&v.name, &s));
                }
                score(m, &v.record, opts.offsets, opts.initial)
                    .map(|s| ScoreReport::new(&v.name, &s))
            };
            let fin = diagnosis.map(|(d, _)| scored(&d.model));
            (Some(scored(&id.model)?), fin.transpose()?)
        }
        None => (None, None),
    })
}

/// Whether `v` continues `rec` (the tail of the same experiment): the same sample time, and its
/// first time stamp one sample after `rec`'s last (within half a sample).
fn continues(rec: &Record, v: &Record) -> bool {
    let (Some(&last), Some(&first)) = (rec.t.last(), v.t.first()) else {
        return false;
    };
    (v.dt - rec.dt).abs() <= 1e-6 * rec.dt && (first - last - rec.dt).abs() <= 0.5 * rec.dt
}

/// Score `m` (fitted on `rec`, with its operating point, output offset and initial state) on
/// `v`, the record that continues `rec` ([`continues`]): the model simulated over `rec` and `v`
/// in turn, so that `v` starts from the state `rec` ended in (not from rest, not from a state
/// fitted to `v`), and its fit over `v`'s samples.
///
/// # Errors
/// A model that cannot be simulated over the two records.
fn continued(m: &FracModel, rec: &Record, v: &Record) -> Result<crate::oe::Scored> {
    use crate::oe::Structure;
    let (u0, y0) = (m.operating_point.u0, m.operating_point.y0);
    let u: Vec<f64> = rec.u.iter().chain(&v.u).map(|x| x - u0).collect();
    let mut yhat = vec![0.0; u.len()];
    m.simulate(&m.values(), &u, rec.dt, &mut yhat)?;
    let tail: Vec<f64> = yhat[rec.len()..].iter().map(|x| x + y0).collect();
    Ok(crate::oe::Scored {
        fit: Fit::of(&v.y, &tail),
        yhat: tail,
        offsets: m.operating_point,
        record_params: vec![],
        warnings: vec![],
    })
}

fn alpha_eta(v: &[(f64, f64, f64)]) -> Vec<AlphaEta> {
    v.iter()
        .map(|&(order, alpha, eta)| AlphaEta { order, alpha, eta })
        .collect()
}

/// The report of a fitted model's transfer function `tf` (`spec` at its values): a delay that
/// ended at the lower edge of its range (`oe::Bounds::at_edge`, under half a percent of the range
/// above zero: the fit drove it out) is no delay, and the model is written without it.
fn model_report(mut tf: fracsim::FracTf, spec: &FracModel) -> ModelReport {
    if let Some(p) = spec.delay.map(|i| &spec.params[i]) {
        if let crate::oe::Bounds::Interval(lo, hi) = p.bounds {
            if lo == 0.0 && p.value < 0.5 * hi && p.bounds.at_edge(p.value) {
                tf.delay = 0.0;
            }
        }
    }
    ModelReport::from(&tf)
}

/// The base fit as a [`ModelFit`].
fn base_fit(id: &Identification, file: Option<ScoreReport>, rec: &Record) -> ModelFit {
    let mut problems = id.problems.clone();
    problems.extend(crate::oe::checks::narrow_band(id, rec));
    let v = super::verdict::verdict(problems, file.as_ref());
    ModelFit {
        model: model_report(id.tf.clone(), &id.model),
        params: id.report.params.clone(),
        fit: FitFigures {
            estimation: id.estimation,
            validation: id.validation,
            validation_file: file,
        },
        alpha_eta: alpha_eta(&id.alpha_eta),
        warnings: id.report.warnings.clone(),
        usable: v.usable,
        problems: v.problems,
        spec: id.model.clone(),
        yhat: id.yhat.clone(),
    }
}

/// The final model's record parameters (output offset, initial state) estimated to convergence
/// with the plant held, as [`rescore`] does (the diagnosis's refits stop after a few iterations):
/// its figures and `spec` are then those `fracid score --as-fitted` gives. A failure keeps the
/// diagnosis's figures, with a warning.
fn polish(fin: &mut ModelFit, req: &TimeRequest, data: &TimeData) {
    match rescore_id(req, &fin.spec, data) {
        Ok(id) => {
            fin.fit.estimation = id.estimation;
            fin.fit.validation = id.validation;
            for (p, e) in fin.params.iter_mut().zip(&id.report.params) {
                if e.free {
                    p.value = e.value;
                    p.at_bound = e.at_bound;
                }
            }
            // the spec as the diagnosis fitted it (its free parameters), the record's values new
            let mut spec = id.model;
            for (p, q) in spec.params.iter_mut().zip(&fin.spec.params) {
                p.free = q.free;
            }
            fin.spec = spec;
            fin.yhat = id.yhat;
        }
        Err(e) => fin.warnings.push(format!(
            "final model: its record's offset and initial state were not estimated again ({e}); \
             the figures are the diagnosis's"
        )),
    }
}

/// The diagnosis's final model as the report leads with it: its record parameters estimated
/// again with the plant held ([`polish`], on the input advanced by a kept time-stamp skew), its
/// caveats, the sentence saying what it is, and the diagnosis's report.
fn final_model(
    d: Diagnosis,
    c: StructureChoice,
    base: &ModelFit,
    req: &TimeRequest,
    data: &TimeData,
    final_file: Option<ScoreReport>,
) -> (ModelFit, String, DiagnosisReport) {
    let rec = &data.record;
    let mut fin = final_fit(&d, base, rec.dt, final_file);
    let skew = d.skew_samples(rec.dt);
    let advanced = skew.map(|lead| input_advanced(data, lead));
    let fitted_on = advanced.as_ref().unwrap_or(data);
    polish(&mut fin, req, fitted_on);
    if let Some(lead) = skew {
        fin.warnings.push(skew_warning(lead, rec.dt));
    }
    judge_final(&mut fin, req, fitted_on);
    unname_undetermined_drift(&mut fin, rec.len() as f64 * rec.dt);
    let caveats = at_bound(&fin);
    fin.warnings.extend(caveats);
    let is = format!(
        "final: the diagnosis's recommended model ({} with {}); the base fit is under base",
        c.scores[c.chosen].name,
        if d.effects.is_empty() {
            "no effect".to_string()
        } else {
            d.effects
                .iter()
                .map(|e| e.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        }
    );
    let report = DiagnosisReport {
        model: fin.model.clone(),
        diagnosis: d,
        structures: c,
    };
    (fin, is, report)
}

/// `data` with the estimation record's input advanced by `lead` samples (`u'_k = u_(k + lead)`,
/// the last value held), as the diagnosis fitted it.
fn input_advanced(data: &TimeData, lead: usize) -> TimeData {
    let mut shifted = data.clone();
    shifted.record.u = crate::diagnose::advanced(&data.record.u, lead);
    shifted
}

/// The caveat of a kept time-stamp skew, in the report's text and JSON alike.
fn skew_warning(lead: usize, dt: f64) -> String {
    format!(
        "the output leads the recorded input by {lead} samples ({:.4e} s): a time-stamp skew of \
         the logger, not part of the plant; the final model and its figures are for this record \
         with its input advanced by {lead} samples (the last value held): advance the input as \
         much before scoring or simulating the model on this record",
        lead as f64 * dt
    )
}

/// The final model's parameters at a bound of their range, in words: the plant's one by one,
/// the initial state's levels together.
fn at_bound(fin: &ModelFit) -> Vec<String> {
    let m = &fin.spec;
    let plant = fin
        .params
        .iter()
        .enumerate()
        .filter(|(i, p)| p.at_bound && !m.is_initial_state(*i));
    plant
        .map(|(_, p)| {
            format!(
                "final model: {} = {:.4e} is at a bound of its range",
                p.name, p.value
            )
        })
        .chain(
            // not when the base fit's own warning says it already (the same levels)
            crate::oe::levels_at_bound(m, &fin.params)
                .filter(|w| !fin.warnings.contains(w))
                .map(|w| format!("final model: {w}")),
        )
        .collect()
}

/// The final model's own verdict ([`super::verdict`]): the rules every fitted model is judged by
/// (`oe::checks`: stable, a finite static gain, parameters the data determine, the held-out part
/// predicted better than its mean, ...) applied to it, with its standard errors at its values
/// (the covariance of the diagnosis's free parameters there, the record's offset and initial
/// state as polished; one Jacobian, no step), and its score on a separate validation record. The
/// base fit's verdict stays with the base fit (`base`). A final model whose covariance cannot be
/// evaluated keeps the problems it had and says why.
fn judge_final(fin: &mut ModelFit, req: &TimeRequest, data: &TimeData) {
    let mut problems = std::mem::take(&mut fin.problems);
    match own_id(req, &fin.spec, data).map(|id| held_undetermined(fin, req, data, id)) {
        Ok(id) => {
            for (p, e) in fin.params.iter_mut().zip(&id.report.params) {
                p.std_error = e.std_error;
            }
            let band = crate::oe::checks::narrow_band(&id, &data.record);
            problems.extend(id.problems);
            problems.extend(band);
        }
        Err(e) => problems.push(format!(
            "the final model cannot be evaluated at its values on this record ({e})"
        )),
    }
    let v = super::verdict::verdict(problems, fin.fit.validation_file.as_ref());
    fin.usable = v.usable;
    fin.problems = v.problems;
}

/// How many standard errors from zero a free integrator's input offset must be, and how many
/// times the estimation RMSE the drift it makes over the record must reach, for the final model
/// to name it among its effects ([`unname_undetermined_drift`]).
const DETERMINED_Z: f64 = 2.0;

/// A free integrator's input offset (`u_offset`) is part of the structure, fitted whatever the
/// record (any offset left in the input integrates to a drift): the final model names
/// `input_offset` among its effects only when the data show it, the drift it makes over the
/// record of `duration` s (`K_i u_offset duration`, `K_i` the integrator's gain `|G(j w) w|` at a
/// frequency a thousand times below the record's) at least [`DETERMINED_Z`] times the estimation
/// RMSE, and its value more than [`DETERMINED_Z`] standard errors from zero where the covariance
/// gives one. The parameter stays in the model and in `params`, with its value and standard
/// error.
fn unname_undetermined_drift(fin: &mut ModelFit, duration: f64) {
    if !fin.spec.integrator || duration <= 0.0 {
        return;
    }
    let Some(p) = fin.params.iter().find(|p| p.name == "u_offset" && p.free) else {
        return;
    };
    let omega = 2.0 * std::f64::consts::PI * 1e-3 / duration;
    let gain = fin
        .spec
        .tf(&fin.spec.values())
        .map_or(f64::NAN, |tf| tf.freq_response(omega).norm() * omega);
    let drift = gain * p.value.abs() * duration;
    if !drift_shown(drift, p.value, p.std_error, fin.fit.estimation.rmse) {
        fin.model.effects.retain(|e| e != "input_offset");
    }
}

/// Whether an integrator's input offset of `value` (+- `std_error`), making a `drift` over the
/// record, is shown by data fitted at an estimation RMSE of `rmse` ([`DETERMINED_Z`]).
fn drift_shown(drift: f64, value: f64, std_error: Option<f64>, rmse: f64) -> bool {
    let not_zero = std_error.is_none_or(|se| value.abs() > DETERMINED_Z * se);
    not_zero && drift >= DETERMINED_Z * rmse
}

/// The final model with the plant parameters its record does not determine held at their fitted
/// values, when that is all that stands between it and a usable model
/// ([`crate::oe::evaluate::held`]): a term whose standard error is ten times its value or more
/// (`a2 = 1.5e-8 +- 5.4e-6`) changes nothing the data can see, so the model does without it, and
/// the parameters left free are judged on their own covariance. `id` is the final model's own
/// identification at its values ([`own_id`]); it is returned as it is when nothing is
/// undetermined, when something else is wrong with the model, or when the parameters left free
/// are not determined either (the model is then refused as it was). The figures do not move (the
/// same model); the held parameters are `free: false` in the report with a warning that says so.
fn held_undetermined(
    fin: &mut ModelFit,
    req: &TimeRequest,
    data: &TimeData,
    id: Identification,
) -> Identification {
    let weak = crate::oe::evaluate::undetermined(&id);
    let Some((spec, held)) = options(req, data)
        .ok()
        .and_then(|opts| crate::oe::evaluate::held(&data.record, &fin.spec, &opts, &weak))
    else {
        return id;
    };
    let names: Vec<String> = weak
        .iter()
        .map(|&i| format!("{} = {:.4e}", spec.params[i].name, spec.params[i].value))
        .collect();
    fin.warnings.push(format!(
        "final model: {} not determined by these data (standard error {} times the value or \
         more) and held at the fitted value(s): {}; the model does not depend on them within what \
         the record shows, and the parameters left free are determined",
        if weak.len() == 1 {
            "1 parameter is"
        } else {
            "parameters are"
        },
        crate::oe::checks::UNDETERMINED,
        names.join(", ")
    ));
    for &i in &weak {
        fin.params[i].free = false;
        fin.params[i].at_bound = false;
    }
    fin.spec = spec;
    held
}

/// The identification options of `req` on `data`'s record.
fn options(req: &TimeRequest, data: &TimeData) -> Result<crate::oe::IdentOptions> {
    let rec = &data.record;
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    Ok(model_and_options(req, duration, rec.dt, data.validation.is_some())?.1)
}

/// The identification of a report's model `spec` at its values, with the parameters it was
/// fitted with free and no iteration ([`crate::oe::evaluate::at_values`]): its covariance
/// (standard errors) and its checks at those values, with the request's operating point, split
/// and initial state.
fn own_id(req: &TimeRequest, spec: &FracModel, data: &TimeData) -> Result<Identification> {
    crate::oe::evaluate::at_values(&data.record, spec, &options(req, data)?)
}

/// The diagnosis's final model as a [`ModelFit`]: the base fit's caveats, then its own
/// (parameters at a bound of their range).
fn final_fit(d: &Diagnosis, base: &ModelFit, dt: f64, file: Option<ScoreReport>) -> ModelFit {
    let values = d.model.values();
    let params: Vec<ParamEstimate> = d
        .model
        .params
        .iter()
        .map(|p| ParamEstimate {
            name: p.name.clone(),
            value: p.value,
            std_error: None,
            free: p.free,
            at_bound: p.free && p.bounds.at_edge(p.value),
        })
        .collect();
    let warnings = base.warnings.clone();
    // Its own verdict comes from its own figures ([`judge_final`]), not the base fit's.
    let mut problems = vec![];
    let model = match d.model.tf(&values) {
        Ok(tf) => {
            let mut m = model_report(tf, &d.model);
            // (A sensor's zero is named with its sensor: once.)
            for e in &d.model.effects {
                if !m.effects.iter().any(|n| n == e.name()) {
                    m.effects.push(e.name().to_string());
                }
            }
            m
        }
        Err(e) => {
            problems.push(format!("the final model has no transfer function: {e}"));
            base.model.clone()
        }
    };
    ModelFit {
        model,
        params,
        fit: FitFigures {
            estimation: d.estimation.after,
            validation: d.validation.as_ref().map(|b| b.after),
            validation_file: file,
        },
        alpha_eta: alpha_eta(&d.model.alpha_eta(&values, dt)),
        warnings,
        usable: problems.is_empty(),
        problems,
        spec: d.model.clone(),
        yhat: d.yhat_after.clone(),
    }
}

/// Score a report's model (`spec`, a [`ModelFit::spec`]) on `data` as [`run`] scored it: the
/// same request (operating point, split, initial state), every parameter of the plant and its
/// effects held, only what belongs to the record (its output offset and initial-state levels)
/// estimated on the estimation part; the figures on the estimation and held-out parts. On the
/// record the report was made from they are the report's own (up to the convergence of those
/// few parameters): the check that a report's figures are those of the model it gives.
///
/// # Errors
/// As [`run`].
pub fn rescore(req: &TimeRequest, spec: &FracModel, data: &TimeData) -> Result<FitFigures> {
    let id = with_own_poles(|| rescore_id(req, spec, data))?;
    Ok(FitFigures {
        estimation: id.estimation,
        validation: id.validation,
        validation_file: None,
    })
}

/// [`rescore`]'s identification (the model with the record's parameters estimated again).
fn rescore_id(req: &TimeRequest, spec: &FracModel, data: &TimeData) -> Result<Identification> {
    let rec = &data.record;
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    let (_, mut opts) = model_and_options(req, duration, rec.dt, data.validation.is_some())?;
    opts.start = StartMode::Given;
    if spec.past.is_some() && opts.initial == crate::oe::InitialState::Auto {
        // The diagnosis found that the record was not at rest at its first sample (the
        // `initial_state` effect): its final model is scored with the initial state estimated,
        // as it was fitted, although the record looks steady before its first input change.
        opts.initial = crate::oe::InitialState::Estimate;
    }
    let mut m = spec.clone();
    for p in &mut m.params {
        p.free = false;
    }
    let record_params = m
        .index_of("y_offset")
        .into_iter()
        .chain(m.past.iter().flat_map(|p| p.levels.clone()));
    for i in record_params.collect::<Vec<_>>() {
        m.params[i].free = true;
    }
    crate::oe::identify(rec, &m, &opts)
}

/// The residual test of the base fit on its estimation part.
fn estimation_residual_test(id: &Identification, rec: &Record, max_lag: usize) -> ResidualTest {
    let split = id.split;
    let e: Vec<f64> = rec.y[..split]
        .iter()
        .zip(&id.yhat[..split])
        .map(|(a, b)| a - b)
        .collect();
    let ud: Vec<f64> = rec.u[..split].iter().map(|v| v - id.offsets.u0).collect();
    // (With held-out blocks, the estimation samples between them, joined.)
    let blocks = &id.validated_by.blocks;
    let (e, ud) = (gather(&e, blocks).0, gather(&ud, blocks).0);
    residual_test(&e, &ud, max_lag.min(e.len().saturating_sub(1)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::observe::{Observe, Stage};

    /// A delay the fit drove to the lower edge of its range is no delay in the report; one inside
    /// its range is written.
    #[test]
    fn a_delay_driven_to_zero_is_not_reported() {
        let mut m = Preset::FirstOrder.model(0.0);
        for (tau, kept) in [(6.5e-7, false), (2e-4, true)] {
            m.with_delay(tau, 1e-3);
            let tf = m.tf(&m.values()).unwrap();
            assert_eq!(tf.delay, tau);
            let r = model_report(tf, &m);
            assert_eq!(r.delay > 0.0, kept, "tau {tau}: {}", r.text);
            assert_eq!(r.text.contains("exp"), kept, "{}", r.text);
        }
    }

    /// An integrator's input offset is named when its drift over the record reaches twice the
    /// estimation RMSE and its value is two standard errors from zero (or has none): on the zoo
    /// (seed 44) a position record with no offset fitted 0.004 (a drift of 0.026 over the record,
    /// the estimation RMSE 0.034) and a cell 4.6e-4 +- 7.0e-4.
    #[test]
    fn an_integrators_offset_is_named_when_its_drift_stands_out() {
        assert!(drift_shown(4.0, 0.05, None, 0.1));
        assert!(drift_shown(4.0, 0.05, Some(0.02), 0.1));
        assert!(
            !drift_shown(0.15, 0.05, None, 0.1),
            "a drift within the noise"
        );
        assert!(
            !drift_shown(4.0, 0.05, Some(0.03), 0.1),
            "within two standard errors"
        );
    }

    /// A user's iteration cap holds for the diagnosis's refits when it is below their own budget
    /// (a million-sample record run with `--max-iter 2` refitted each candidate for 60 before).
    #[test]
    fn a_smaller_iteration_cap_holds_for_the_diagnosis_refits() {
        let own = DiagnoseOptions::default().fit.lm.max_iterations;
        for (cap, refits) in [(2, 2), (own, own), (500, own)] {
            let req = TimeRequest {
                max_iterations: cap,
                ..TimeRequest::default()
            };
            assert_eq!(
                diagnose_options(&req).fit.lm.max_iterations,
                refits,
                "{cap}"
            );
        }
    }

    /// A first-order plant 2/(0.1 s + 1) driven by a square wave, exact for the held input.
    fn data() -> TimeData {
        let dt = 0.01;
        let u: Vec<f64> = (0..600)
            .map(|k| if (k / 37) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let y = crate::testdata::first_order_held(&u, dt, 0.1, 2.0);
        TimeData {
            record: Record::from_samples(&u, &y, dt).unwrap(),
            validation: None,
            joint: vec![],
            reader_warnings: vec!["file.csv: a reader caveat".into()],
        }
    }

    /// A record cut in two whose second part continues the first (its time stamps follow on) is
    /// scored from the state the first part ended in: the fitted model simulated over both parts
    /// in turn, its error on the second part's samples alone; the same part with its time stamps
    /// restarted is a record of its own (not continued).
    #[test]
    fn a_validation_record_that_continues_the_estimation_record_carries_the_state_over() {
        let whole = data().record;
        let cut = 260;
        let part = |a: usize, b: usize, t0: f64| {
            let mut r = Record::from_samples(&whole.u[a..b], &whole.y[a..b], whole.dt).unwrap();
            for (k, t) in r.t.iter_mut().enumerate() {
                *t = t0 + k as f64 * whole.dt;
            }
            r
        };
        let (head, tail) = (part(0, cut, 0.0), part(cut, 600, whole.t[cut]));
        assert!(continues(&head, &tail));
        assert!(!continues(&head, &part(cut, 600, 0.0)));
        let req = TimeRequest {
            structure: "2/(0.2 s + 1)".parse().unwrap(),
            plain: true,
            ..Default::default()
        };
        let d = TimeData {
            record: head.clone(),
            validation: Some(Named {
                name: "tail".into(),
                record: tail.clone(),
            }),
            joint: vec![],
            reader_warnings: vec![],
        };
        let r = run(&req, &d, &mut crate::app::observe::Quiet).unwrap();
        assert!(
            r.validated_by.note.contains("continues"),
            "{}",
            r.validated_by.note
        );
        // The model over both parts in turn, its output on the tail's samples.
        let m = &r.lead.spec;
        let u: Vec<f64> = head
            .u
            .iter()
            .chain(&tail.u)
            .map(|x| x - m.operating_point.u0)
            .collect();
        let mut y = vec![0.0; u.len()];
        crate::oe::Structure::simulate(m, &m.values(), &u, head.dt, &mut y).unwrap();
        let yt: Vec<f64> = y[cut..].iter().map(|v| v + m.operating_point.y0).collect();
        let file = r.lead.fit.validation_file.unwrap();
        let direct = Fit::of(&tail.y, &yt);
        assert!((file.rmse - direct.rmse).abs() <= 1e-12 * (1.0 + direct.rmse));
        // The plant is first order and the record exact: the state carried over predicts the
        // tail to the fit's own precision.
        assert!(file.nrmse_percent > 99.0, "{}", file.nrmse_percent);
    }

    #[derive(Default)]
    struct Log {
        stages: Vec<Stage>,
        simulations: usize,
        cancel_after: Option<usize>,
    }

    impl Observe for Log {
        fn stage(&mut self, stage: Stage) {
            self.stages.push(stage);
        }
        fn simulation(&mut self, _k: usize, _rmse: f64) {
            self.simulations += 1;
        }
        fn cancelled(&self) -> bool {
            self.cancel_after.is_some_and(|n| self.stages.len() >= n)
        }
    }

    #[test]
    fn the_observer_sees_each_stage_and_can_cancel() {
        let req = TimeRequest {
            structure: "2/(0.2 s + 1)".parse().unwrap(),
            plain: false,
            ..Default::default()
        };
        let mut log = Log::default();
        let r = run(&req, &data(), &mut log).unwrap();
        assert!(matches!(
            log.stages[..],
            [Stage::Fit, Stage::Diagnose { .. }]
        ));
        assert!(log.simulations > 0);
        // the reader's caveat leads the report's warnings; the base fit is under `base`
        assert_eq!(r.lead.warnings[0], "file.csv: a reader caveat");
        assert!(r.base.is_some() && r.model_is.starts_with("final"));
        let mut stop = Log {
            cancel_after: Some(1),
            ..Default::default()
        };
        let e = run(&req, &data(), &mut stop).unwrap_err();
        assert!(matches!(e, Error::Cancelled(_)), "{e}");
        assert_eq!(stop.stages, vec![Stage::Fit]);
    }

    #[test]
    fn each_models_output_gives_its_stated_figures() {
        let req = TimeRequest {
            structure: "2/(0.2 s + 1)".parse().unwrap(),
            plain: false,
            ..Default::default()
        };
        let d = data();
        let r = run(&req, &d, &mut crate::app::observe::Quiet).unwrap();
        let split = r.split.estimation_samples;
        for m in [&r.lead, r.base.as_ref().unwrap()] {
            let held = crate::metrics::Fit::of(&d.record.y[split..], &m.yhat[split..]);
            let stated = m.fit.validation.unwrap();
            assert!((held.rmse - stated.rmse).abs() <= 1e-12 * stated.rmse.max(1e-300));
        }
    }

    /// A time-stamp skew kept alone (the recorded input lags the output: a negative delay) is
    /// found at its length and stated with the figures of the final model's own output on the
    /// record with the input advanced, which rescoring that model there gives again (before: the
    /// final model was polished on the record as logged, held-out 0.41 = 70.3% beside the
    /// diagnosis's 0.024 = 98.3%, and the advance found was 1 sample of 3).
    #[test]
    fn a_kept_time_skew_states_the_figures_of_its_final_model() {
        use rand::{Rng, SeedableRng};
        let mut d = data();
        let lag = 3;
        let late: Vec<f64> = (0..d.record.u.len())
            .map(|k| d.record.u[k.saturating_sub(lag)])
            .collect();
        // measurement noise of 2% of the output's swing, seeded
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let y: Vec<f64> = d
            .record
            .y
            .iter()
            .map(|v| v + 0.08 * (rng.gen::<f64>() - 0.5))
            .collect();
        d.record = Record::from_samples(&late, &y, d.record.dt).unwrap();
        let req = TimeRequest {
            structure: "2/(0.2 s + 1)".parse().unwrap(),
            plain: false,
            ..Default::default()
        };
        let r = run(&req, &d, &mut crate::app::observe::Quiet).unwrap();
        let diag = &r.diagnosis.as_ref().unwrap().diagnosis;
        let names: Vec<&str> = diag.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["delay"], "{:?}", diag.rejected);
        // the output leads the recorded input by the 3 samples of the logging lag
        let tau = diag.effects[0].params["tau"];
        assert!((tau + 0.03).abs() <= 0.5 * d.record.dt, "tau {tau}");
        let split = r.split.estimation_samples;
        let held = crate::metrics::Fit::of(&d.record.y[split..], &r.lead.yhat[split..]);
        let stated = r.lead.fit.validation.unwrap();
        assert!(
            (held.rmse - stated.rmse).abs() <= 1e-12 * stated.rmse,
            "{held:?} vs stated {stated:?}"
        );
        // the final model cannot carry the advance: its report says so, and its figures are
        // those of the record with the input advanced (as `rescore` of that record gives them)
        assert!(
            r.lead
                .warnings
                .iter()
                .any(|w| w.contains("time-stamp skew")),
            "{:?}",
            r.lead.warnings
        );
        let again = rescore(&req, &r.lead.spec, &input_advanced(&d, 3))
            .unwrap()
            .validation
            .unwrap();
        assert!(
            (again.rmse - stated.rmse).abs() <= 1e-6 * stated.rmse,
            "rescored {again:?} vs stated {stated:?}"
        );
        // the model with its skew explains the held-out part down to the noise (its rms 0.023)
        assert!(stated.rmse < 0.03, "{stated:?}");
    }

    #[test]
    fn a_request_names_only_options_that_exist() {
        let e = serde_json::from_str::<TimeRequest>(r#"{"holdot": 0.2}"#).unwrap_err();
        assert!(e.to_string().contains("holdot"), "{e}");
        let r: TimeRequest = serde_json::from_str("{}").unwrap();
        assert_eq!(r, TimeRequest::default());
    }

    #[test]
    fn a_model_spec_round_trips_through_json() {
        let r = run(
            &TimeRequest::default(),
            &data(),
            &mut crate::app::observe::Quiet,
        )
        .unwrap();
        let text = serde_json::to_string(&r.lead.spec).unwrap();
        let back: FracModel = serde_json::from_str(&text).unwrap();
        assert_eq!(back, r.lead.spec);
    }
}
