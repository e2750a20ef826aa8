//! The comparison's rule, shared by the named structures' comparison ([`super::structures`]) and
//! the general structure's ([`super::general`]): the row each structure gets ([`StructureScore`])
//! and the decision among the rows ([`decide`]): among the final models whose base fit is usable
//! (and those not usable but more than [`FAR`] times better than every usable one), those whose
//! held-out RMSE is within [`TIE`] of the best are ties, and the tie with the lowest BIC wins;
//! among ties whose BIC is within [`BIC_EVEN`] of the lowest, the one with the fewest effects.

use crate::oe::Identification;
use crate::Result;
use serde::Serialize;

/// Relative margin of held-out RMSE within which two structures are ties (2%: about the
/// standard error of an RMSE ratio over 1000 held-out samples of noise, `1/sqrt(2N)`).
pub const TIE: f64 = 0.02;

/// One structure's fit and diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureScore {
    /// Its name (a name of the catalogue, [`Preset::name`], or the user's words; `+ integrator`).
    pub name: String,
    /// The fitted linear part (empty when the fit failed).
    pub model: String,
    /// Why the structure has no result, in one line: its fit failed, or its diagnosis did
    /// (`None` when neither). Said once: not repeated in `problems`.
    pub failed: Option<String>,
    /// Held-out RMSE of the base fit (estimation RMSE without a held-out part).
    pub rmse: Option<f64>,
    /// Why the base fit cannot be used (empty when it can, or when there is no base fit: see
    /// `failed`).
    pub problems: Vec<String>,
    /// The effects its diagnosis kept.
    pub effects: Vec<String>,
    /// Free parameters of the final model (offsets, initial-state levels and effects included).
    pub free_params: usize,
    /// Held-out RMSE of the final model.
    pub rmse_after: Option<f64>,
    /// BIC of the final model on the estimation part.
    pub bic_after: Option<f64>,
    /// Why the final model cannot be used, judged at its values by the rules the report judges
    /// the model it leads with, nothing held ([`judge_finals`]): given when the base fit is not
    /// usable and the final model could be chosen (empty: it can be used, and is chosen from as a
    /// usable one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problems_after: Option<Vec<String>>,
}

/// How far behind the best usable base fit a structure's base fit may be and still be diagnosed:
/// a structure whose base held-out RMSE (estimation RMSE without a held-out part) exceeds `FAR`
/// times the best usable one's is not diagnosed (its row shows the base fit only). The effects
/// are the same for every structure (a delay, friction, an offset helps the best structure as
/// much), so a structure twice as far from the data is not expected to overtake the best one by its
/// effects alone; on the real records in `data/` the structures so left out ended at least 4%
/// behind the chosen one when they were diagnosed anyway.
pub const FAR: f64 = 2.0;

/// The comparison and its decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureChoice {
    /// Every candidate, the user's first.
    pub scores: Vec<StructureScore>,
    /// Index of the chosen one in `scores`.
    pub chosen: usize,
    /// Whether the RMSEs compared are held-out ones (on a step test the tail of the response);
    /// else, with nothing held out, they are of the estimation part.
    pub held_out: bool,
    /// The decision in words.
    pub reason: String,
    /// The usable integer-order model the chosen one is compared with (`None` when the chosen one
    /// is itself integer or no integer-order candidate is usable).
    pub integer_reference: Option<IntegerReference>,
}

/// A diagnosis on the best structure ([`super::structures::diagnose_best`]).
#[derive(Debug, Clone)]
pub struct Diagnosed {
    /// The identification of the chosen structure (the diagnosis's base model).
    pub id: Identification,
    /// The comparison.
    pub choice: StructureChoice,
    /// The diagnosis of the chosen structure.
    pub diagnosis: super::Diagnosis,
}

/// One structure's identification (when it succeeded) and diagnosis (`None`: not diagnosed).
pub(crate) struct Outcome {
    pub(crate) id: Option<Identification>,
    pub(crate) diagnosis: Option<Result<super::Diagnosis>>,
}

impl StructureScore {
    /// A row with nothing measured yet.
    pub(crate) fn named(name: &str) -> Self {
        Self {
            name: name.to_string(),
            model: String::new(),
            failed: None,
            rmse: None,
            problems: vec![],
            effects: vec![],
            free_params: 0,
            rmse_after: None,
            bic_after: None,
            problems_after: None,
        }
    }
}

pub(crate) fn score_of(name: &str, o: &Outcome) -> StructureScore {
    let mut s = StructureScore::named(name);
    if let Some(id) = &o.id {
        s.model = id.tf.to_string();
        s.rmse = Some(id.validation.unwrap_or(id.estimation).rmse);
        s.problems = id.problems.clone();
    }
    match (&o.id, &o.diagnosis) {
        (Some(id), Some(Ok(d))) => {
            let ne = id.validated_by.estimation_samples(id.split);
            let n = ne as f64;
            // A kept advance of the input (a time-stamp skew) is chosen from the data like a
            // parameter, though the model does not carry it: counted as one (a one-sample skew
            // on a first order tied the general structure's direct term, one parameter more,
            // on the zoo's feed-through 0055, and won by that parameter's BIC).
            let k =
                d.model.params.iter().filter(|p| p.free).count() + usize::from(d.advances_input());
            let ssr = d.estimation.after.rmse.powi(2) * n;
            s.effects = d.effects.iter().map(|e| e.name.clone()).collect();
            s.free_params = k;
            s.rmse_after = Some(d.after.rmse);
            s.bic_after = Some(super::bic(ssr, ne, k));
        }
        (Some(_), Some(Err(e))) => s.failed = Some(format!("its diagnosis failed: {e}")),
        (None, Some(Err(e))) => s.failed = Some(e.to_string()),
        _ => {}
    }
    s
}

/// The integer-order model the chosen one is compared with ([`StructureChoice::integer_reference`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IntegerReference {
    /// Its name in the comparison (`first-order`, `second-order`, `third-order`).
    pub name: String,
    /// Its RMSE, on the same data as the chosen one's (held-out, or the estimation part).
    pub rmse: f64,
    /// Whether that is its final model's (diagnosed); else its base fit's.
    pub diagnosed: bool,
    /// The chosen model's RMSE relative to it, `rmse_chosen / rmse - 1` (negative: better).
    pub relative_change: f64,
}

/// Whether a structure with held-out RMSE `rmse` (its base fit `usable` or not) is among those the
/// comparison chooses from, `best_usable` the best usable one's RMSE (infinite when none is): a
/// usable one, or one whose base fit is not usable but more than [`FAR`] times better than every
/// usable one. Such a fit says that the usable structures do not describe these data (a static
/// gain that fits the record to its last digit, while a first order's fit stalls 1e15 times
/// higher): the comparison then ends on it, and its final model's verdict says what is wrong
/// with it (no dynamics, terms not determined), rather than on a usable model the data refute.
pub(crate) fn far_better(usable: bool, rmse: f64, best_usable: f64) -> bool {
    usable || !best_usable.is_finite() || FAR * rmse < best_usable
}

impl StructureScore {
    /// Whether its base fit is usable, or its final model judged at its values
    /// ([`judge_finals`]).
    pub(crate) fn usable(&self) -> bool {
        self.problems.is_empty() || self.problems_after.as_ref().is_some_and(Vec::is_empty)
    }
}

/// The best held-out RMSE among the usable final models of `scores` (infinite when none is).
fn best_usable(scores: &[StructureScore]) -> f64 {
    scores
        .iter()
        .filter(|s| s.usable())
        .filter_map(|s| s.rmse_after.filter(|r| r.is_finite()))
        .fold(f64::INFINITY, f64::min)
}

/// The final models' own verdicts where they decide the choice ([`decide`]): a structure whose
/// base fit is not usable (a term the record does not determine, a base fit worse than the
/// held-out part's mean that its effects mend), whose diagnosis ran to its end, and whose final
/// model is better than every usable one's by more than the tie, is judged at its values by the
/// rules the report judges the model it leads with ([`crate::oe::evaluate::problems_at_values`],
/// on the input advanced by a kept time-stamp skew), nothing held: with no problem it is chosen
/// from as a usable one. (The report would hold terms the record does not determine; a final
/// model usable only so, its dynamics held, is no alternative to a usable one: on the zoo a PMSM
/// with an integrator, every order held, would have won on a record that excites two bins.)
pub(crate) fn judge_finals(
    rec: &crate::data::Record,
    outcomes: &[Outcome],
    scores: &mut [StructureScore],
    opts: &crate::oe::IdentOptions,
) {
    let best = best_usable(scores);
    for (s, o) in scores.iter_mut().zip(outcomes) {
        let Some(Ok(d)) = &o.diagnosis else {
            continue;
        };
        let contends = s.rmse_after.is_some_and(|r| (1.0 + TIE) * r < best);
        if s.problems.is_empty() || d.halted.is_some() || !contends {
            continue;
        }
        s.problems_after = Some(final_problems(rec, d, opts));
    }
}

/// Why the final model of diagnosis `d` cannot be used, judged at its values by the rules the
/// report judges the model it leads with ([`crate::oe::evaluate::problems_at_values`]), on the
/// input advanced by a kept time-stamp skew, nothing held.
pub(crate) fn final_problems(
    rec: &crate::data::Record,
    d: &super::Diagnosis,
    opts: &crate::oe::IdentOptions,
) -> Vec<String> {
    let advanced = d.skew_samples(rec.dt).map(|lead| {
        let mut r = rec.clone();
        r.u = super::advanced(&rec.u, lead);
        r
    });
    let on = advanced.as_ref().unwrap_or(rec);
    crate::oe::evaluate::problems_at_values(on, &d.model, opts)
}

/// The index chosen by the rule of the module documentation, or `None` when no candidate has a
/// final model.
pub(crate) fn decide(scores: &[StructureScore]) -> Option<(usize, f64)> {
    let finals: Vec<usize> = (0..scores.len())
        .filter(|&i| scores[i].rmse_after.is_some_and(f64::is_finite))
        .collect();
    let best_usable = best_usable(scores);
    let pool: Vec<usize> = finals
        .into_iter()
        .filter(|&i| {
            let r = scores[i].rmse_after.unwrap_or(f64::INFINITY);
            far_better(scores[i].usable(), r, best_usable)
        })
        .collect();
    let best = pool
        .iter()
        .filter_map(|&i| scores[i].rmse_after)
        .fold(f64::INFINITY, f64::min);
    let bic = |i: usize| scores[i].bic_after.unwrap_or(f64::INFINITY);
    let ties: Vec<usize> = pool
        .iter()
        .copied()
        .filter(|&i| {
            scores[i]
                .rmse_after
                .is_some_and(|r| r <= (1.0 + TIE) * best)
        })
        .collect();
    let lowest = ties.iter().map(|&i| bic(i)).fold(f64::INFINITY, f64::min);
    ties.into_iter()
        .filter(|&i| !(bic(i) > lowest + BIC_EVEN))
        .min_by(|&a, &b| {
            let effects = |i: usize| scores[i].effects.len();
            effects(a).cmp(&effects(b)).then(bic(a).total_cmp(&bic(b)))
        })
        .map(|c| (c, best))
}

/// BIC differences up to this are no evidence for either of two models (Kass and Raftery 1995:
/// "not worth more than a bare mention", a Bayes factor under e): among the ties whose BIC is
/// within it of the lowest, the one with the fewest kept effects wins ([`decide`]). A model that
/// needs an effect to tie one that needs none has not shown the effect (the zoo's integrator
/// 0006: a first order with a delay standing in for the missing pole, BIC 1.2 below the second
/// order without it, 0.4% behind it on the held-out part).
pub const BIC_EVEN: f64 = 2.0;
