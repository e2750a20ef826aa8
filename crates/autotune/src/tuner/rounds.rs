//! The identification rounds: the first record identified and diagnosed; each later record
//! diagnosed alone (what it separates), then one model fitted jointly to every record so far,
//! each record's error before (the previous model) and after (the joint model).

use super::design::Purpose;
use crate::Result;
use ident::app::observe::Quiet;
use ident::app::time::{self, TimeData, TimeRequest};
use ident::data::{OffsetMode, Record};
use ident::diagnose::Ambiguity;
use ident::oe::{FracModel, InitialState, StartMode};
use serde::Serialize;
use std::collections::BTreeMap;

/// A record of the autotune with its name and why it was taken.
#[derive(Debug, Clone)]
pub struct Named {
    /// Its name in the report (`prbs`, `reversals`, ...).
    pub name: String,
    /// Why it was taken.
    pub purpose: Purpose,
    /// The samples.
    pub record: Record,
}

/// One record's error under a model.
#[derive(Debug, Clone, Serialize)]
pub struct RecordError {
    /// The record's name.
    pub record: String,
    /// RMSE, rad/s.
    pub rmse: f64,
    /// NRMSE fit, percent.
    pub nrmse_percent: f64,
}

/// An effect of a model with its parameters.
#[derive(Debug, Clone, Serialize)]
pub struct EffectValues {
    /// The effect's report name.
    pub name: String,
    /// Its parameters by name.
    pub params: BTreeMap<String, f64>,
}

/// A model of a round.
#[derive(Debug, Clone)]
pub struct Model {
    /// The whole model (structure, values, effects, delay).
    pub spec: FracModel,
    /// The model in words (its linear part, delay and effects).
    pub text: String,
}

impl Model {
    /// The value of the parameter `name`, if the model has it.
    pub fn param(&self, name: &str) -> Option<f64> {
        self.spec.index_of(name).map(|i| self.spec.params[i].value)
    }

    /// The linear part with its delay.
    ///
    /// # Errors
    /// A model whose transfer function cannot be formed.
    pub fn tf(&self) -> Result<fracsim::FracTf> {
        Ok(self.spec.tf(&self.spec.values())?)
    }
}

/// What one identification round found.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The model.
    pub model: Model,
    /// What the new record could not separate (its diagnosis's ambiguities).
    pub ambiguous: Vec<Ambiguity>,
    /// The effects its diagnosis kept on the new record, with their values there.
    pub kept: Vec<EffectValues>,
    /// The effects its diagnosis tried and rejected, with the reason.
    pub rejected: Vec<EffectValues>,
    /// Each record's error under the model.
    pub errors: Vec<RecordError>,
    /// Caveats (a joint fit that failed and the new record's model kept instead, ...).
    pub warnings: Vec<String>,
    /// Whether the identification called the model usable.
    pub usable: bool,
}

/// The time-domain request of every diagnosis: the default, the loop closed (the structures
/// compared, the best diagnosed, its effects kept when they pay).
pub fn request() -> TimeRequest {
    TimeRequest {
        plain: false,
        ..TimeRequest::default()
    }
}

fn rejected(report: &time::TimeReport) -> Vec<EffectValues> {
    report
        .diagnosis
        .as_ref()
        .map(|d| {
            d.diagnosis
                .rejected
                .iter()
                .map(|e| EffectValues {
                    name: format!("{}: {}", e.name, e.reason),
                    params: e.params.clone(),
                })
                .collect()
        })
        .unwrap_or_default()
}

fn kept(report: &time::TimeReport) -> Vec<EffectValues> {
    report
        .diagnosis
        .as_ref()
        .map(|d| {
            d.diagnosis
                .effects
                .iter()
                .map(|e| EffectValues {
                    name: e.name.clone(),
                    params: e.params.clone(),
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Identify and diagnose one record alone.
fn diagnose(rec: &Named) -> Result<time::TimeReport> {
    let data = TimeData {
        record: rec.record.clone(),
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    Ok(time::run(&request(), &data, &mut Quiet)?)
}

/// The first round: the record identified and diagnosed.
///
/// # Errors
/// The identification's.
pub fn first(rec: &Named) -> Result<Outcome> {
    let r = diagnose(rec)?;
    let ambiguous = r
        .diagnosis
        .as_ref()
        .map(|d| d.diagnosis.ambiguous.clone())
        .unwrap_or_default();
    let est = r.lead.fit.estimation;
    let val = r.lead.fit.validation.unwrap_or(est);
    Ok(Outcome {
        model: Model {
            spec: r.lead.spec.clone(),
            text: final_text(&r),
        },
        ambiguous,
        kept: kept(&r),
        rejected: rejected(&r),
        errors: vec![RecordError {
            record: rec.name.clone(),
            rmse: val.rmse,
            nrmse_percent: val.nrmse_percent,
        }],
        warnings: r.lead.warnings.clone(),
        usable: r.lead.usable,
    })
}

fn final_text(r: &time::TimeReport) -> String {
    r.diagnosis
        .as_ref()
        .map(|d| d.diagnosis.final_model.clone())
        .unwrap_or_else(|| r.lead.model.text.clone())
}

/// Each record's error under `model` (its own operating point, output offset and initial
/// state), in the order given.
///
/// # Errors
/// A record too short to score.
pub fn errors(model: &FracModel, recs: &[Named]) -> Result<Vec<RecordError>> {
    recs.iter()
        .map(|r| {
            let s = ident::oe::score(model, &r.record, OffsetMode::Initial, InitialState::Auto)?;
            Ok(RecordError {
                record: r.name.clone(),
                rmse: s.fit.rmse,
                nrmse_percent: s.fit.nrmse_percent,
            })
        })
        .collect()
}

/// `m` with Coulomb friction added (`Vc` from `vc`), unless it has it: the effect a reversal
/// experiment is run for, fitted jointly whether or not the new record alone kept it.
fn with_friction(m: &FracModel, vc: f64) -> FracModel {
    if m.index_of("Vc").is_some() {
        return m.clone();
    }
    let mut m = m.clone();
    let i = m.add_param(ident::oe::Param::positive("Vc", vc.max(1e-3)));
    m.effects.insert(
        0,
        ident::oe::Effect::Coulomb {
            vc: i,
            sampled: false,
        },
    );
    m
}

/// The effect a later round is run for: it joins the joint fit's start even when the new
/// record's diagnosis alone did not keep it (on one record its held-out margin may not pay; the
/// joint fit over every record decides its value).
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// Whatever the new record's diagnosis keeps.
    Diagnosed,
    /// Coulomb friction, started at this `Vc` (V) unless the diagnosis gave one.
    Friction(f64),
    /// This structure, as fitted to an earlier record (a resonant pair the dwell is for).
    Start(Box<FracModel>),
}

/// The start of a joint fit: `m` with its initial-state levels back at 0 (the joint fit gives
/// each record its own range for them; a level left at the edge of one record's range is out of
/// another's).
fn fresh_past(mut m: FracModel) -> FracModel {
    let levels: Vec<usize> = (0..m.params.len())
        .filter(|&i| m.params[i].name.starts_with("u_past"))
        .collect();
    for i in levels {
        m.params[i].value = 0.0;
    }
    m
}

/// The structure `structure` fitted to one record with its delay, without the diagnosis, from
/// `start` (by parameter name; empty: the automatic start).
///
/// # Errors
/// The identification's.
pub fn fit_structure(
    rec: &Named,
    structure: ident::app::Structure,
    start: BTreeMap<String, f64>,
) -> Result<(Model, f64)> {
    let data = TimeData {
        record: rec.record.clone(),
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    let req = TimeRequest {
        structure,
        plain: true,
        delay: true,
        auto_start: start.is_empty(),
        start,
        ..TimeRequest::default()
    };
    let r = time::run(&req, &data, &mut Quiet)?;
    let val = r.lead.fit.validation.unwrap_or(r.lead.fit.estimation);
    Ok((
        Model {
            text: r.lead.model.text.clone(),
            spec: r.lead.spec.clone(),
        },
        val.rmse,
    ))
}

/// A later round: the last of `recs` diagnosed alone (the effects it can separate), then the
/// model of that diagnosis fitted jointly to every record, the new one first (the joint fit
/// starts from a fit to it); for friction, the previous model `prev` with friction added (the
/// linear part the earlier records pinned, the friction the new record shows).
///
/// # Errors
/// The diagnosis's; a joint fit that fails leaves the new record's model, with a warning.
pub fn later(recs: &[Named], prev: &FracModel, target: Target) -> Result<Outcome> {
    let new = recs.last().expect("a later round has a record");
    let r = diagnose(new)?;
    let ambiguous = r
        .diagnosis
        .as_ref()
        .map(|d| d.diagnosis.ambiguous.clone())
        .unwrap_or_default();
    let given = matches!(target, Target::Start(_));
    let start = match target {
        // friction an earlier round separated stays: a record that cannot show it (one sign of
        // speed) leaves it ambiguous, and the joint fit over every record decides its value
        Target::Diagnosed => match prev.index_of("Vc") {
            Some(i) => with_friction(&r.lead.spec, prev.params[i].value),
            None => r.lead.spec.clone(),
        },
        Target::Friction(vc) => {
            // the value the new record's refit found, if it tried friction
            let tried = r.diagnosis.as_ref().and_then(|d| {
                d.diagnosis
                    .rejected
                    .iter()
                    .find(|e| e.name == "coulomb_friction")
                    .and_then(|e| e.params.get("Vc").copied())
            });
            with_friction(prev, tried.unwrap_or(vc))
        }
        Target::Start(m) => *m,
    };
    // a structure fitted to an earlier record is the model kept when the joint fit fails
    let fallback = if given { start.clone() } else { prev.clone() };
    let start = fresh_past(start);
    let mut warnings = vec![];
    let start = within_joint_limit(start, recs.len(), &mut warnings);
    let mut ordered: Vec<Record> = vec![new.record.clone()];
    ordered.extend(recs[..recs.len() - 1].iter().map(|n| n.record.clone()));
    let dur = new.record.len() as f64 * new.record.dt;
    let (_, mut opts) = time::model_and_options(
        &TimeRequest {
            holdout: Some(0.0),
            ..TimeRequest::default()
        },
        dur,
        new.record.dt,
        false,
    )?;
    opts.start = StartMode::Given;
    opts.fit.lm.stall = Some(JOINT_STALL);
    let (spec, usable) = match ident::oe::identify_joint(&ordered, &start, &opts) {
        Ok(j) if j.problems.is_empty() => (j.model, true),
        Ok(j) => {
            warnings.push(format!(
                "the joint fit of {} records is not usable ({}); the model before it is kept",
                recs.len(),
                j.problems.join("; "),
            ));
            (fallback, true)
        }
        Err(e) => {
            warnings.push(format!(
                "the joint fit of {} records failed ({e}); the model before it is kept",
                recs.len(),
            ));
            (fallback, true)
        }
    };
    let errors = errors(&spec, recs)?;
    let text = model_text(&spec).unwrap_or_else(|| final_text(&r));
    Ok(Outcome {
        model: Model { spec, text },
        ambiguous,
        kept: kept(&r),
        rejected: rejected(&r),
        errors,
        warnings,
        usable,
    })
}

/// The joint fit's stall test (`ident::lm::LmOptions::stall`): it stops when its cost fell by
/// less than 1e-5 of itself over the last 5 accepted iterations (the start is a fit to an
/// earlier record; what the joint fit adds comes in its first iterations, and such a creep is
/// 5e-6 of the RMSE). The fit of a reversal round on the demo's drive: 25 iterations to 1e-12,
/// about a third of the time with the test, the same model to the digits reported. A looser
/// test, 1e-4 over 3, stopped that fit with the friction at 7e-12 V undetermined.
pub const JOINT_STALL: (usize, f64) = (5, 1e-5);

/// The most free parameters a fit takes ([`ident::oe::fit`]).
pub const MAX_FREE: usize = 16;

/// `m` with its fractional orders held at their values (the records before fitted them; the new
/// record, a dwell about one frequency, cannot tell them) when its free parameters and each of
/// `n_records` records' own (an output offset and the initial state's levels,
/// [`ident::oe::past_edges`]) exceed [`MAX_FREE`]; the orders held are named in `warnings`.
fn within_joint_limit(mut m: FracModel, n_records: usize, warnings: &mut Vec<String>) -> FracModel {
    let own = |m: &FracModel, i: usize| m.is_initial_state(i) || m.params[i].name == "y_offset";
    let per_record = 2 + ident::oe::past_edges(1.0).len();
    let count = |m: &FracModel| {
        (0..m.params.len())
            .filter(|&i| m.params[i].free && !own(m, i))
            .count()
            + n_records * per_record
    };
    let mut held = vec![];
    for name in ["q", "mu", "theta", "zeta"] {
        if count(&m) <= MAX_FREE {
            break;
        }
        if let Some(i) = m.index_of(name).filter(|&i| m.params[i].free) {
            m.params[i].free = false;
            held.push(format!("{name} = {:.4}", m.params[i].value));
        }
    }
    if !held.is_empty() {
        warnings.push(format!(
            "the joint fit holds {} as the earlier records fitted (at most {MAX_FREE} free \
             parameters with each record's offset and initial state)",
            held.join(", ")
        ));
    }
    m
}

/// A model in words: its linear part and its effects' parameters.
pub fn model_text(m: &FracModel) -> Option<String> {
    let tf = m.tf(&m.values()).ok()?;
    let effects: Vec<String> = m
        .params
        .iter()
        .filter(|p| ["Vc", "u_offset", "L", "w"].contains(&p.name.as_str()))
        .map(|p| format!("{} = {:.4}", p.name, p.value))
        .collect();
    Some(if effects.is_empty() {
        tf.to_string()
    } else {
        format!("{tf}; {}", effects.join(", "))
    })
}

/// A motor measured at the load behind a resonance: the PMSM's fitted linear part `motor`
/// (`K, a1, a2, zeta, theta`, its delay and approximation) times a resonant pair with no
/// anti-resonance, `1/(c2 s^2 + d s + 1)`, started at `freq_hz` and `damping`
/// (`c2 = 1/wr^2`, `d = 2 damping/wr`): the structure of a speed measured on the load side of a
/// compliant coupling, simulated factor by factor ([`FracModel::series`]); `None` when `motor`
/// is not a PMSM.
pub fn load_resonance(motor: &FracModel, freq_hz: f64, damping: f64) -> Option<FracModel> {
    use ident::oe::{Expr, Kind, Param};
    let v = |n: &str| motor.index_of(n).map(|i| motor.params[i].value);
    let mut m = FracModel::pmsm(v("K")?, v("a1")?, v("a2")?, v("zeta")?, v("theta")?);
    m.approx = motor.approx;
    let wr = 2.0 * std::f64::consts::PI * freq_hz;
    let ic2 = m.add_param(Param::positive("c2", wr.powi(-2)));
    let id = m.add_param(Param::positive("d", 2.0 * damping.max(1e-3) / wr));
    let pair = vec![
        (Expr::p(ic2), Expr::cst(2.0)),
        (Expr::p(id), Expr::cst(1.0)),
        (Expr::cst(1.0), Expr::cst(0.0)),
    ];
    let motor_den = m.den.clone();
    m.series = vec![
        (vec![(Expr::p(0), Expr::cst(0.0))], motor_den.clone()),
        (vec![(Expr::cst(1.0), Expr::cst(0.0))], pair.clone()),
    ];
    // the product multiplied out, term by term (the reports' transfer function)
    m.den = motor_den
        .iter()
        .flat_map(|(mc, mo)| {
            pair.iter().map(move |(pc, po)| {
                let coef = match (mc.terms.first(), pc.terms.first()) {
                    (Some(&(a, _)), Some(&(c, _))) => Expr::p(a).times(&[c]),
                    (Some(_), None) => mc.clone(),
                    (None, Some(_)) => pc.clone(),
                    (None, None) => Expr::cst(1.0),
                };
                let mut o = mo.clone();
                o.constant += po.constant;
                (coef, o)
            })
        })
        .collect();
    m.kind = Kind::General;
    if let Some(i) = motor.delay {
        if let ident::oe::Bounds::Interval(_, hi) = motor.params[i].bounds {
            m.with_delay(motor.params[i].value, hi);
        }
    }
    Some(m)
}

/// The record `rec` with its input passed through the resonant pair `1/(c2 s^2 + d s + 1)` at
/// `freq_hz` and `damping` (deviations from its first sample, so that a record that starts
/// settled starts the pair at rest): what a motor measured behind that resonance sees, for a
/// start of the motor alone ([`load_resonance`]) that the resonance does not bend.
///
/// # Errors
/// The simulator's.
pub fn behind_pair(rec: &Named, freq_hz: f64, damping: f64) -> Result<Named> {
    let wr = 2.0 * std::f64::consts::PI * freq_hz;
    let pair = fracsim::FracTf::new(
        vec![fracsim::Term::new(1.0, 0.0)],
        vec![
            fracsim::Term::new(wr.powi(-2), 2.0),
            fracsim::Term::new(2.0 * damping / wr, 1.0),
            fracsim::Term::new(1.0, 0.0),
        ],
        0.0,
    )
    .map_err(tune::Error::Sim)?;
    let u = &rec.record.u;
    let u0 = u.first().copied().unwrap_or(0.0);
    let du: Vec<f64> = u.iter().map(|v| v - u0).collect();
    let uf: Vec<f64> = fracsim::lsim(&pair, &du, rec.record.dt, &Default::default())
        .map_err(tune::Error::Sim)?
        .into_iter()
        .map(|v| v + u0)
        .collect();
    Ok(Named {
        name: rec.name.clone(),
        purpose: rec.purpose,
        record: Record::from_samples(&uf, &rec.record.y, rec.record.dt)?,
    })
}

/// `m` fitted to one record from its values (no automatic start, no diagnosis), scored as
/// [`fit_structure`] scores (the validation RMSE on the held-out 30%).
///
/// # Errors
/// The identification's.
pub fn fit_given(rec: &Named, m: &FracModel) -> Result<(Model, f64)> {
    let dur = rec.record.len() as f64 * rec.record.dt;
    let (_, mut opts) =
        time::model_and_options(&TimeRequest::default(), dur, rec.record.dt, false)?;
    opts.start = StartMode::Given;
    let id = ident::oe::identify(&rec.record, m, &opts)?;
    let val = id.validation.unwrap_or(id.estimation);
    let text = model_text(&id.model).unwrap_or_else(|| id.tf.to_string());
    Ok((
        Model {
            spec: id.model,
            text,
        },
        val.rmse,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64 as C;

    #[test]
    fn load_resonance_is_the_motor_times_the_pair() {
        let mut motor = FracModel::pmsm(2.0, 0.01, 1e-5, 0.9, 0.85);
        motor.with_delay(0.001, 0.01);
        let m = load_resonance(&motor, 40.0, 0.05).unwrap();
        let tf = m.tf(&m.values()).unwrap();
        assert_eq!(tf.factors().len(), 2);
        let alone = motor.tf(&motor.values()).unwrap();
        let wr = 2.0 * std::f64::consts::PI * 40.0;
        for w in [1.0, 100.0, wr, 1000.0] {
            let x = w / wr;
            let pair = C::new(1.0, 0.0) / C::new(1.0 - x * x, 2.0 * 0.05 * x);
            let want = alone.freq_response(w) * pair;
            assert!(
                (tf.freq_response(w) - want).norm() < 1e-9 * want.norm(),
                "{w}"
            );
        }
        // a model without the PMSM's parameters has no such start
        assert!(load_resonance(&FracModel::second_order(1.0, 0.1, 0.01), 40.0, 0.05).is_none());
    }

    #[test]
    fn behind_pair_rings_as_the_pair_from_the_first_sample() {
        // a step from 1 to 2 after 10 samples through 20 Hz, damping 0.05: the first level held
        // (the pair at rest on it), the step's peak 1 + e^(-pi z / sqrt(1 - z^2)) above it
        let u: Vec<f64> = (0..2000).map(|k| if k < 10 { 1.0 } else { 2.0 }).collect();
        let rec = Named {
            name: "r".into(),
            purpose: super::super::design::Purpose::Identification,
            record: Record::from_samples(&u, &vec![0.0; u.len()], 1e-3).unwrap(),
        };
        let f = behind_pair(&rec, 20.0, 0.05).unwrap().record.u;
        assert!(f[..10].iter().all(|v| (v - 1.0).abs() < 1e-12));
        let peak = f.iter().copied().fold(f64::MIN, f64::max);
        let want = 2.0 + (-std::f64::consts::PI * 0.05 / (1.0f64 - 0.0025).sqrt()).exp();
        assert!((peak - want).abs() < 0.01, "{peak} {want}");
    }
}
