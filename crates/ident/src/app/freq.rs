//! The frequency-domain use case (`fracid freq`, `fracid.fit_bode`, the fleet and the demo): one
//! request holding every option and its default once, one [`run`], one typed [`FreqReport`]
//! (Levy 1959 with Vinagre's weights, Vinagre et al. 2001; the order search; Sanathanan-Koerner;
//! the PMSM refit; the residual diagnosis).

use super::observe::{enter, Observe, Stage};
use super::ModelReport;
use crate::diagnose::freq::{diagnose_bode, BodeDiagnoseOptions, BodeDiagnosis};
use crate::levy::{
    error_index, fit_bode, point_std_from_spread, spread_levy_weights, FreqFit, FreqOptions,
    LevyFit, OrderChoice, QPoint, Weights,
};
use crate::{Error, Result};
use fracsim::FracTf;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Every option of the frequency-domain identification, with its default (`Default`, and missing
/// fields when deserialised). Words are those of the CLI flags and the Python keywords.
///
/// ```
/// let r: ident::app::freq::FreqRequest = serde_json::from_str(r#"{"refine": true}"#).unwrap();
/// assert_eq!((r.n, r.m, r.weights.as_str(), r.refine), (2, 0, "auto", true));
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FreqRequest {
    /// Denominator degree in powers of `s^q`.
    pub n: usize,
    /// Numerator degree in powers of `s^q`.
    pub m: usize,
    /// A fixed commensurate order (`None`: searched on the grid).
    pub q: Option<f64>,
    /// Step of the order grid on `(0, q_max]`.
    pub q_step: f64,
    /// Largest order of the grid.
    pub q_max: f64,
    /// Refine the grid's best order by golden section.
    pub refine_q: bool,
    /// Levy weights: `auto` (`spread` when the data carry a measured spread, else `vinagre`),
    /// `vinagre` (eq. 29), `none`, `spread` (Vinagre's over the relative variance for Levy, the
    /// inverse variance for the refit), or `given` (the data's own per-point weights).
    pub weights: String,
    /// Sanathanan-Koerner reweightings (0: none).
    pub sk_iterations: usize,
    /// Refit the PMSM structure with two free orders (needs `n = 2, m = 0`).
    pub refine: bool,
    /// Diagnose the residual `H / Hhat` for a delay and other effects.
    pub diagnose: bool,
    /// The zero-order hold to divide out: `auto` (the sample period the data's comments give),
    /// `none`, or a sample period in seconds.
    pub hold: String,
    /// Models to score on the data (their `J`).
    pub compare: Vec<String>,
}

impl Default for FreqRequest {
    fn default() -> Self {
        Self {
            n: 2,
            m: 0,
            q: None,
            q_step: 0.01,
            q_max: 1.0,
            refine_q: true,
            weights: "auto".into(),
            sk_iterations: 0,
            refine: false,
            diagnose: false,
            hold: "auto".into(),
            compare: Vec::new(),
        }
    }
}

/// Bode data for [`run`].
#[derive(Debug, Clone, Default)]
pub struct FreqData {
    /// Angular frequencies in rad/s.
    pub omega_rad_s: Vec<f64>,
    /// The measured response `G(j omega)`.
    pub h: Vec<Complex64>,
    /// Per-point weights (`weights = "given"`), and their origin in words.
    pub weights: Option<(Vec<f64>, String)>,
    /// The standard deviation of each point's complex error per real component.
    pub point_std: Option<Vec<f64>>,
    /// Or the measured spread as a Bode table gives it: the standard errors of each point's gain
    /// (dB) and phase (deg), turned into `point_std` on the response with the hold divided out
    /// ([`point_std_from_spread`]).
    pub spread_se: Option<Vec<(f64, f64)>>,
    /// The sample period the data's comments name (`hold = "auto"`).
    pub hold_hint: Option<f64>,
}

/// One Levy fit in a report.
#[derive(Debug, Clone, Serialize)]
pub struct LevyReport {
    /// The model.
    pub model: ModelReport,
    /// The commensurate order.
    pub q: f64,
    /// The error index (eq. 30).
    #[serde(rename = "J")]
    pub j: f64,
    /// Numerator coefficients `b_0 .. b_m`.
    pub b: Vec<f64>,
    /// Denominator coefficients `a_1 .. a_n` (`a_0 = 1`).
    pub a: Vec<f64>,
    /// The weighted Levy cost minimised.
    pub levy_cost: f64,
    /// Sanathanan-Koerner iterations done.
    pub sk_iterations: usize,
    /// Whether they converged.
    pub sk_converged: bool,
}

impl From<&LevyFit> for LevyReport {
    fn from(f: &LevyFit) -> Self {
        Self {
            model: ModelReport::from(&f.model),
            q: f.q,
            j: f.j,
            b: f.b.clone(),
            a: f.a.clone(),
            levy_cost: f.levy_cost,
            sk_iterations: f.sk_iterations,
            sk_converged: f.sk_converged,
        }
    }
}

/// `J(q)` at one order of the grid (`J` null where the solve broke down).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct QPointReport {
    /// The order.
    pub q: f64,
    /// The error index.
    #[serde(rename = "J")]
    pub j: Option<f64>,
}

fn curve(c: &[QPoint]) -> Vec<QPointReport> {
    c.iter()
        .map(|p| QPointReport {
            q: p.q,
            j: p.j.is_finite().then_some(p.j),
        })
        .collect()
}

/// The PMSM refit in a report.
#[derive(Debug, Clone, Serialize)]
pub struct RefinedReport {
    /// The model.
    pub model: ModelReport,
    /// The error index.
    #[serde(rename = "J")]
    pub j: f64,
    /// Gain.
    #[serde(rename = "K")]
    pub k: f64,
    /// `a1`.
    pub a1: f64,
    /// `a2`.
    pub a2: f64,
    /// `zeta`.
    pub zeta: f64,
    /// `theta`.
    pub theta: f64,
    /// Standard errors by name (`None` when the Jacobian is singular).
    pub std_errors: Option<std::collections::BTreeMap<String, f64>>,
    /// Whether Levenberg-Marquardt converged.
    pub converged: bool,
    /// How it ended.
    pub termination: String,
    /// Its iterations.
    pub iterations: usize,
}

/// A model scored on the data.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    /// The model.
    pub model: ModelReport,
    /// Its error index on the data.
    #[serde(rename = "J")]
    pub j: f64,
}

/// The diagnosis in a report, with its final model.
#[derive(Debug, Clone, Serialize)]
pub struct BodeDiagnosisReport {
    /// The diagnosis.
    #[serde(flatten)]
    pub diagnosis: BodeDiagnosis,
    /// The final model.
    pub model: ModelReport,
}

/// The report of [`run`] (docs/design.md §7): `model`, `q`, `J` are Levy's at the chosen order;
/// `refined`, `sk`, `diagnosis` when asked; `usable`, `problems`, `warnings` of the final model.
#[derive(Debug, Clone, Serialize)]
pub struct FreqReport {
    /// Levy's model at the chosen order.
    pub model: ModelReport,
    /// The chosen order.
    pub q: f64,
    /// Its error index.
    #[serde(rename = "J")]
    pub j: f64,
    /// What `J` is.
    #[serde(rename = "J_definition")]
    pub j_definition: String,
    /// `levy`.
    pub method: String,
    /// The weights, in words.
    pub weights: String,
    /// Number of points.
    pub points: usize,
    /// Levy's fit at the chosen order.
    pub levy: LevyReport,
    /// Levy's fit at the grid's best order.
    pub levy_grid: LevyReport,
    /// `J(q)` on the grid.
    pub curve: Vec<QPointReport>,
    /// The models compared.
    pub compare: Vec<CompareReport>,
    /// The Sanathanan-Koerner fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sk: Option<LevyReport>,
    /// Its `J(q)`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sk_curve: Option<Vec<QPointReport>>,
    /// The PMSM refit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined: Option<RefinedReport>,
    /// The best model by `J` among Levy's, SK's and the refit.
    pub best_model: ModelReport,
    /// Its error index.
    #[serde(rename = "best_J")]
    pub best_j: f64,
    /// The sample period whose hold was divided out.
    pub hold_s: Option<f64>,
    /// The diagnosis.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diagnosis: Option<BodeDiagnosisReport>,
    /// Whether the final model can be used.
    pub usable: bool,
    /// Why not.
    pub problems: Vec<String>,
    /// Caveats.
    pub warnings: Vec<String>,
    /// The request as run.
    pub request: FreqRequest,
    /// What the report was made from, for presentation: not serialised.
    #[serde(skip)]
    pub fitted: FreqFitted,
}

/// The results behind a [`FreqReport`], for tables and plots.
#[derive(Debug, Clone)]
pub struct FreqFitted {
    /// Angular frequencies (rad/s).
    pub omega_rad_s: Vec<f64>,
    /// The response fitted (the hold divided out).
    pub h: Vec<Complex64>,
    /// The fits.
    pub fit: FreqFit,
    /// The models compared and their `J`.
    pub compare: Vec<(FracTf, f64)>,
    /// The diagnosis.
    pub diagnosis: Option<BodeDiagnosis>,
    /// The options the fit ran with.
    pub options: FreqOptions,
}

/// The fit options of a request on `data`, and the weights in words.
///
/// # Errors
/// [`Error::Options`] for an option out of range, weights the data cannot give.
pub fn options(req: &FreqRequest, data: &FreqData) -> Result<(FreqOptions, String)> {
    if req.n == 0 {
        return Err(Error::Options(
            "n (denominator degree) must be at least 1".into(),
        ));
    }
    if req.sk_iterations > 1000 {
        return Err(Error::Options(format!(
            "sk_iterations = {} is too many (at most 1000)",
            req.sk_iterations
        )));
    }
    let order = match req.q {
        Some(q) => OrderChoice::Fixed(q),
        None => {
            let (step, q_max) = (req.q_step, req.q_max);
            if !(step.is_finite() && step > 0.0 && q_max.is_finite() && q_max >= step) {
                return Err(Error::Options(format!(
                    "q grid: need 0 < q_step <= q_max, got q_step = {step}, q_max = {q_max}"
                )));
            }
            if q_max / step > 1e6 {
                return Err(Error::Options(format!(
                    "q grid of {:.0} points is too fine",
                    q_max / step
                )));
            }
            OrderChoice::Search {
                step,
                q_max,
                refine: req.refine_q,
            }
        }
    };
    let mut key = req.weights.trim().to_ascii_lowercase();
    if key == "auto" {
        key = if data.point_std.is_some() {
            "spread"
        } else {
            "vinagre"
        }
        .into();
    }
    let (weights, label, point_std) = match key.as_str() {
        "vinagre" => (Weights::Vinagre, "vinagre (eq. 29)".to_string(), None),
        "none" | "uniform" => (Weights::Uniform, "none".to_string(), None),
        "spread" => {
            let Some(sd) = &data.point_std else {
                return Err(Error::Options(
                    "weights spread: the data carry no measured spread (gain_db_std and \
                     phase_deg_std columns, or point_std)"
                        .into(),
                ));
            };
            if let Some(i) = sd.iter().position(|v| !(*v > 0.0 && v.is_finite())) {
                return Err(Error::Options(format!(
                    "weights spread: point {} has no spread (0); measure with --repeats 3 or \
                     more, or use --weights vinagre",
                    i + 1
                )));
            }
            (
                Weights::PerPoint(spread_levy_weights(&data.omega_rad_s, &data.h, sd)?),
                "spread: vinagre / relative variance (Levy), inverse variance (refit)".to_string(),
                Some(sd.clone()),
            )
        }
        "given" => match &data.weights {
            Some((w, origin)) => (Weights::PerPoint(w.clone()), origin.clone(), None),
            None => {
                return Err(Error::Options(
                    "weights given: the data carry no per-point weights".into(),
                ))
            }
        },
        w => {
            return Err(Error::Options(format!(
                "weights '{w}': expected auto, vinagre, none, spread or given"
            )))
        }
    };
    let opts = FreqOptions {
        n: req.n,
        m: req.m,
        order,
        weights,
        sk_iterations: req.sk_iterations,
        refine: req.refine,
        point_std,
    };
    Ok((opts, label))
}

/// The sample period whose zero-order hold is divided out.
fn hold_of(req: &FreqRequest, data: &FreqData) -> Result<Option<f64>> {
    match req.hold.trim().to_ascii_lowercase().as_str() {
        "auto" => Ok(data.hold_hint),
        "none" => Ok(None),
        v => match v.parse::<f64>() {
            Ok(t) if t.is_finite() && t > 0.0 => Ok(Some(t)),
            _ => Err(Error::Options(format!(
                "hold wants a sample period in seconds, auto or none, got '{v}'"
            ))),
        },
    }
}

/// Run the frequency-domain identification of `req` on `data`: the hold divided out, Levy's fit
/// with the order search (Sanathanan-Koerner and the PMSM refit when asked), the models
/// compared, the diagnosis of the best model when asked, and the report.
///
/// ```
/// use ident::app::{freq, observe::Quiet};
/// let g: fracsim::FracTf = "2/(0.01 s^1.6 + 0.1 s^0.8 + 1)".parse().unwrap();
/// let omega: Vec<f64> = (0..40).map(|k| 10f64.powf(-1.0 + 4.0 * k as f64 / 39.0)).collect();
/// let h = omega.iter().map(|&w| g.freq_response(w)).collect();
/// let data = freq::FreqData { omega_rad_s: omega, h, ..Default::default() };
/// let r = freq::run(&freq::FreqRequest::default(), &data, &mut Quiet).unwrap();
/// assert!((r.q - 0.8).abs() < 1e-6 && r.usable);
/// ```
///
/// # Errors
/// Options out of range ([`Error::Options`]), data that cannot be fitted, numerical breakdown,
/// [`Error::Cancelled`].
pub fn run(req: &FreqRequest, data: &FreqData, obs: &mut dyn Observe) -> Result<FreqReport> {
    let hold = hold_of(req, data)?;
    let mut held = data.clone();
    if let Some(t) = hold {
        crate::hold::divide_hold(&held.omega_rad_s, &mut held.h, t)?;
    }
    if let (None, Some(se)) = (&held.point_std, &held.spread_se) {
        if se.len() != held.h.len() {
            return Err(Error::Data(format!(
                "{} spread values for {} points",
                se.len(),
                held.h.len()
            )));
        }
        held.point_std = Some(point_std(&held.h, se));
    }
    let (opts, label) = options(req, &held)?;
    let (omega, h) = (&held.omega_rad_s, held.h);
    let mut compare = Vec::new();
    for s in &req.compare {
        let g: FracTf = s
            .parse()
            .map_err(|e| Error::Options(format!("compare model '{s}': {e}")))?;
        let j = error_index(omega, &h, &g);
        compare.push((g, j));
    }
    enter(obs, Stage::Fit)?;
    let fit = fit_bode(omega, &h, &opts)?;
    let diagnosis = if req.diagnose {
        enter(obs, Stage::Diagnose { n: 1 })?;
        Some(diagnose_bode(
            omega,
            &h,
            fit.best_model(),
            &BodeDiagnoseOptions::default(),
        )?)
    } else {
        None
    };
    let (mut problems, warnings) = assessment(&fit, diagnosis.as_ref());
    let answer = diagnosis.as_ref().map_or(fit.best_model(), |d| &d.model);
    problems.extend(hardly_better_than_a_constant(omega, &h, answer));
    let verdict = super::verdict::verdict(problems, None);
    let refined = fit.refined.as_ref().map(|r| RefinedReport {
        model: ModelReport::from(&r.model),
        j: r.j,
        k: r.k,
        a1: r.a1,
        a2: r.a2,
        zeta: r.zeta,
        theta: r.theta,
        std_errors: r.std_errors.map(|s| {
            ["K", "a1", "a2", "zeta", "theta"]
                .iter()
                .zip(s)
                .map(|(n, v)| (n.to_string(), v))
                .collect()
        }),
        converged: r.report.converged,
        termination: format!("{:?}", r.report.termination),
        iterations: r.report.iterations,
    });
    Ok(FreqReport {
        model: ModelReport::from(&fit.levy.model),
        q: fit.levy.q,
        j: fit.levy.j,
        j_definition: "(1/f) sum_g |G(j w_g) - Ghat(j w_g)|^2, w in rad/s (paper eq. 30)".into(),
        method: "levy".into(),
        weights: label,
        points: omega.len(),
        levy: LevyReport::from(&fit.levy),
        levy_grid: LevyReport::from(&fit.levy_grid),
        curve: curve(&fit.curve),
        compare: compare
            .iter()
            .map(|(g, j)| CompareReport {
                model: ModelReport::from(g),
                j: *j,
            })
            .collect(),
        sk: fit.sk.as_ref().map(LevyReport::from),
        sk_curve: fit.sk.as_ref().map(|_| curve(&fit.sk_curve)),
        refined,
        best_model: ModelReport::from(fit.best_model()),
        best_j: fit.best_j(),
        hold_s: hold,
        diagnosis: diagnosis.as_ref().map(|d| BodeDiagnosisReport {
            diagnosis: d.clone(),
            model: ModelReport::from(&d.model),
        }),
        usable: verdict.usable,
        problems: verdict.problems,
        warnings,
        request: req.clone(),
        fitted: FreqFitted {
            omega_rad_s: held.omega_rad_s.clone(),
            h,
            fit,
            compare,
            diagnosis,
            options: opts,
        },
    })
}

/// The problems (the final model cannot be used) and warnings of a fit: the library's
/// ([`FreqFit::problems`], of the best model), and with the diagnosis those of the diagnosed
/// model, which is then the final one.
fn assessment(fit: &FreqFit, diagnosis: Option<&BodeDiagnosis>) -> (Vec<String>, Vec<String>) {
    let (mut problems, mut warnings) = (fit.problems.clone(), fit.warnings.clone());
    if let Some(d) = diagnosis {
        if d.model != *fit.best_model() {
            let (p, w) = crate::levy::checks::model_problems(&d.model);
            problems.extend(p.into_iter().map(|m| format!("diagnosed model: {m}")));
            warnings.extend(w.into_iter().map(|m| format!("diagnosed model: {m}")));
        }
    }
    (problems, warnings)
}

/// The fit (%) below which a frequency-domain model does not describe the response it was fitted
/// to ([`hardly_better_than_a_constant`]): half the response's variation about its mean left
/// unexplained. A fit of the paper's Table 1 reaches 98%; five parameters fitted to a table of
/// noise (gain +-10 dB, phase anywhere) 13%.
const FREQ_FIT_FLOOR: f64 = 50.0;

/// A model whose fit of the response, `100 (1 - sqrt(J / J_c))` % with `J_c` the error index of
/// the best constant (the response's complex mean), is below [`FREQ_FIT_FLOOR`]: it explains
/// too little of what was measured to be a model of it (a table of noise; a response with no
/// dynamics, which a constant describes).
fn hardly_better_than_a_constant(omega: &[f64], h: &[Complex64], g: &FracTf) -> Option<String> {
    let n = h.len().max(1) as f64;
    let mean = h.iter().sum::<Complex64>() / n;
    let j_const = h.iter().map(|v| (v - mean).norm_sqr()).sum::<f64>() / n;
    let fit = 100.0 * (1.0 - (error_index(omega, h, g) / j_const).sqrt());
    (!(fit >= FREQ_FIT_FLOOR)).then(|| {
        format!(
            "the model fits the measured response only {fit:.1}% (below {FREQ_FIT_FLOOR}%: \
             100 (1 - sqrt(J / J_c)), J_c the error of the best constant): it does not describe \
             these data (a table of noise, or a response without dynamics)"
        )
    })
}

/// The measured spread of a Bode table (standard errors of gain dB and phase deg per point) as
/// the standard deviation of each point's complex error ([`point_std_from_spread`]).
pub fn point_std(h: &[Complex64], spread_se: &[(f64, f64)]) -> Vec<f64> {
    let (g, p): (Vec<f64>, Vec<f64>) = spread_se.iter().copied().unzip();
    point_std_from_spread(h, &g, &p)
}
