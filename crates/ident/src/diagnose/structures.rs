//! Which structure the diagnosis runs on: the structures that could describe the record are fitted
//! alike and compared by held-out error and BIC, so that the effects found do not hinge on the
//! structure a user happened to name (a dead zone "found" only because a first-order model cannot
//! bend like the plant).
//!
//! The candidates are the user's structure, the PMSM `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`, the
//! commensurate `K/(a2 s^(2q) + a1 s^q + 1)`, the first order `K/(T s + 1)`, and the user's
//! structure with a free integrator (an output that integrates, such as a position). Each is
//! identified with the same options ([`crate::oe::identify`]: automatic start, initial state,
//! offsets). Rule: among the usable fits ([`Identification::usable`]), those whose held-out RMSE
//! (estimation RMSE without a held-out part) is within [`TIE`] of the best are ties, and the tie
//! with the lowest BIC `N ln(SSR/N) + k ln N` on the estimation part wins (`k` free parameters):
//! the simpler structure unless the richer one predicts clearly better.

use crate::data::Record;
use crate::oe::{identify, FracModel, IdentOptions, Identification};
use crate::{Error, Result};
use serde::Serialize;

/// Relative margin of held-out RMSE within which two structures are ties (2%: about the
/// standard error of an RMSE ratio over 1000 held-out samples of noise, `1/sqrt(2N)`).
pub const TIE: f64 = 0.02;

/// One structure's fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureScore {
    /// Its name (`pmsm`, `commensurate`, `first order`, or the user's words, `+ integrator`).
    pub name: String,
    /// The fitted linear part, or why the fit failed.
    pub model: String,
    /// Free parameters (with the offsets and the initial-state levels).
    pub free_params: usize,
    /// Held-out RMSE (estimation RMSE without a held-out part).
    pub rmse: Option<f64>,
    /// BIC on the estimation part.
    pub bic: Option<f64>,
    /// Why the fit cannot be used (empty when it can).
    pub problems: Vec<String>,
}

/// The comparison and its decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureChoice {
    /// Every candidate, the user's first.
    pub scores: Vec<StructureScore>,
    /// Index of the chosen one in `scores`.
    pub chosen: usize,
    /// The decision in words.
    pub reason: String,
}

/// The candidate structures for a user's `model` named `label` (see the module documentation).
pub fn candidates(label: &str, model: &FracModel) -> Vec<(String, FracModel)> {
    let mut first = FracModel::fopdt(1.0, 0.1, 0.01, 1.0);
    first.delay = None;
    first.params.retain(|p| p.name != "tau");
    let mut out = vec![(label.to_string(), model.clone())];
    for (name, mut m) in [
        ("pmsm", FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9)),
        (
            "commensurate",
            FracModel::commensurate(1.0, 0.01, 1e-4, 0.9),
        ),
        ("first order", first),
    ] {
        if out.iter().any(|(n, _)| n.eq_ignore_ascii_case(name)) {
            continue;
        }
        m.approx = model.approx;
        out.push((name.to_string(), m));
    }
    if !model.integrator {
        let mut m = model.clone();
        m.with_integrator();
        out.push((format!("{label} + integrator"), m));
    }
    out
}

fn score_of(name: &str, id: &Identification) -> StructureScore {
    let n = id.split as f64;
    let k = id.model.params.iter().filter(|p| p.free).count();
    let ssr = id.estimation.rmse * id.estimation.rmse * n;
    StructureScore {
        name: name.to_string(),
        model: id.tf.to_string(),
        free_params: k,
        rmse: Some(id.validation.unwrap_or(id.estimation).rmse),
        bic: Some(n * (ssr / n).max(1e-300).ln() + k as f64 * n.ln()),
        problems: id.problems.clone(),
    }
}

/// Fit every candidate structure to `rec` and choose one (see the module documentation).
/// `user` is the identification of the user's `model` (named `label`), already made.
///
/// # Errors
/// None of its own: a candidate whose fit fails is scored as failed, and when no candidate is
/// usable the user's identification is kept.
pub fn choose(
    rec: &Record,
    label: &str,
    model: &FracModel,
    user: Identification,
    opts: &IdentOptions,
) -> Result<(Identification, StructureChoice)> {
    let mut ids: Vec<Option<Identification>> = vec![];
    let mut scores = vec![score_of(label, &user)];
    ids.push(Some(user));
    for (name, m) in candidates(label, model).into_iter().skip(1) {
        match identify(rec, &m, opts) {
            Ok(id) => {
                scores.push(score_of(&name, &id));
                ids.push(Some(id));
            }
            Err(e) => {
                scores.push(StructureScore {
                    name,
                    model: format!("the fit failed: {e}"),
                    free_params: 0,
                    rmse: None,
                    bic: None,
                    problems: vec![e.to_string()],
                });
                ids.push(None);
            }
        }
    }
    let usable: Vec<usize> = (0..scores.len())
        .filter(|&i| scores[i].problems.is_empty() && scores[i].rmse.is_some_and(f64::is_finite))
        .collect();
    let best_rmse = usable
        .iter()
        .filter_map(|&i| scores[i].rmse)
        .fold(f64::INFINITY, f64::min);
    let chosen = usable
        .iter()
        .copied()
        .filter(|&i| scores[i].rmse.is_some_and(|r| r <= (1.0 + TIE) * best_rmse))
        .min_by(|&a, &b| {
            let bic = |i: usize| scores[i].bic.unwrap_or(f64::INFINITY);
            bic(a).total_cmp(&bic(b))
        });
    let reason = match chosen {
        None => format!("no structure gives a usable fit: the diagnosis runs on {label}"),
        Some(c) => {
            let s = &scores[c];
            format!(
                "{} chosen: held-out RMSE {:.4e} (best {best_rmse:.4e}; ties within {:.0}%), the \
                 lowest BIC among the ties ({:.1}, {} free parameters)",
                s.name,
                s.rmse.unwrap_or(f64::NAN),
                100.0 * TIE,
                s.bic.unwrap_or(f64::NAN),
                s.free_params
            )
        }
    };
    let chosen = chosen.unwrap_or(0);
    let id = ids
        .swap_remove(chosen)
        .ok_or_else(|| Error::Numerical(format!("structure {chosen} was not fitted")))?;
    Ok((
        id,
        StructureChoice {
            scores,
            chosen,
            reason,
        },
    ))
}

/// A diagnosis on the best structure: the structures compared ([`choose`]), then [`super::diagnose`]
/// on the chosen one.
#[derive(Debug, Clone)]
pub struct Diagnosed {
    /// The identification of the chosen structure (the diagnosis's base model).
    pub id: Identification,
    /// The comparison.
    pub choice: StructureChoice,
    /// The diagnosis.
    pub diagnosis: super::Diagnosis,
}

/// Compare the structures ([`choose`]) and diagnose the record on the chosen one.
///
/// # Errors
/// As [`super::diagnose`].
pub fn diagnose_best(
    rec: &Record,
    label: &str,
    model: &FracModel,
    user: Identification,
    opts: &IdentOptions,
    dopts: &super::DiagnoseOptions,
) -> Result<Diagnosed> {
    let (id, choice) = choose(rec, label, model, user, opts)?;
    let diagnosis = super::diagnose(rec, &id, dopts)?;
    Ok(Diagnosed {
        id,
        choice,
        diagnosis,
    })
}
