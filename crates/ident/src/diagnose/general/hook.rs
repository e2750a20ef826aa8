//! The general structure as a candidate of the diagnosis's structure comparison
//! ([`crate::diagnose::structures::diagnose_best`]), when the named structures fit poorly.
//!
//! Once the comparison has chosen among the named structures, the chosen final model is judged
//! ([`fits_poorly`]) by the diagnosis's residual tests on the estimation part
//! ([`crate::diagnose::residual::analyse`], whatever the noise level): its residual depends on
//! the input (the residual-input cross-correlation: dynamics the model misses), or it is not
//! white (Ljung-Box at 1%: with white measurement noise, structure the model misses; a short
//! record's cross-correlation has wide bounds), or its base fit is not usable (no named
//! structure could be fitted well posed) and the diagnosis kept no effect (a final model with
//! effects is not its base fit: its own residual judges it; a sign-blind sensor's or a power
//! law's base fit is unusable and its final model right, and on the zoo the general structure
//! was diagnosed on none of the 10 such cases). Only then is the general structure sized by the data
//! ([`super::fit`], its own pole cache); its chosen size is diagnosed when its base fit is usable
//! and predicts the held-out part within [`BEHIND`] of the chosen final model (the successive
//! halving's margin: a structure further behind after fewer effects is given no more rounds).
//! The two final models are then compared by the comparison's own rule (held-out RMSE, ties
//! within [`crate::diagnose::choice::TIE`] decided by the lower BIC, a usable base fit first): the general model is
//! returned, with its diagnosis and verdict, when it predicts the held-out data better.
//! Otherwise the named choice stands; its row is added to the comparison either way, and the
//! reason says what was done.

use super::{fit, GeneralRequest};
use crate::data::Record;
use crate::diagnose::choice::{decide, score_of, Diagnosed, Outcome, StructureScore};
use crate::diagnose::halving::BEHIND;
use crate::diagnose::{diagnose, DiagnoseOptions};
use crate::oe::{FracModel, IdentOptions, Kind};
use fracsim::modal::RootsCache;

/// Why the chosen final model of `d` fits poorly (see the module documentation), or `None`:
/// its estimation residual depends on the input or is not white, or its base fit is not usable
/// and no effect was kept.
pub fn fits_poorly(d: &Diagnosed) -> Option<&'static str> {
    let r = &d.diagnosis.residual_after;
    if !r.independent {
        Some("its residual depends on the input")
    } else if !r.white {
        Some("its residual is not white")
    } else if !d.choice.scores[d.choice.chosen].problems.is_empty()
        && d.diagnosis.effects.is_empty()
    {
        Some("its base fit is not usable")
    } else {
        None
    }
}

/// The diagnosis `d` of the named structures, with the general structure compared when they fit
/// poorly (see the module documentation); `template` the user's structure (its approximation,
/// integrator and delay are the general structure's), `opts` and `dopts` the comparison's fit
/// and diagnosis options. A user's structure that is the general one is returned as it is.
pub fn consider(
    rec: &Record,
    template: &FracModel,
    opts: &IdentOptions,
    dopts: &DiagnoseOptions,
    mut d: Diagnosed,
) -> Diagnosed {
    let Some(why) = fits_poorly(&d).filter(|_| template.kind != Kind::General) else {
        return d;
    };
    let chosen = d.choice.chosen;
    let mut roots = RootsCache::new();
    let g = roots.enter(|| fit(rec, template, opts, &GeneralRequest::default()));
    let g = match g {
        Ok(g) => g,
        Err(e) => {
            d.choice.reason.push_str(&format!(
                "; the general structure (compared because the chosen model fits poorly: {why}) \
                 could not be fitted: {e}"
            ));
            return d;
        }
    };
    let base = g.id.validation.unwrap_or(g.id.estimation).rmse;
    let reference = d.choice.scores[chosen].rmse_after.unwrap_or(f64::INFINITY);
    if !(g.id.usable() && base <= BEHIND * reference) {
        let mut row = StructureScore::named(&g.name);
        row.model = g.id.tf.to_string();
        row.rmse = Some(base);
        row.problems = g.id.problems.clone();
        d.choice.scores.push(row);
        d.choice.reason.push_str(&format!(
            "; {} (the general structure, compared because the chosen model fits poorly: {why}) \
             not diagnosed: base RMSE {base:.4e}{}",
            g.name,
            if g.id.usable() {
                format!(", more than {BEHIND}x the chosen final model's")
            } else {
                ", not usable".into()
            }
        ));
        return d;
    }
    let diagnosis = roots.enter(|| diagnose(rec, &g.id, dopts));
    let outcome = Outcome {
        id: Some(g.id),
        diagnosis: Some(diagnosis),
    };
    let row = score_of(&g.name, &outcome);
    let pair = [d.choice.scores[chosen].clone(), row.clone()];
    let wins = matches!(decide(&pair), Some((1, _)));
    d.choice.scores.push(row);
    let index = d.choice.scores.len() - 1;
    let s = &d.choice.scores[index];
    let words = format!(
        "; {} (the general structure, compared because {} fits poorly: {why}) held-out RMSE \
         {:.4e} against {:.4e}{}",
        g.name,
        d.choice.scores[chosen].name,
        s.rmse_after.unwrap_or(f64::NAN),
        reference,
        if wins {
            ": chosen instead"
        } else {
            ": not chosen"
        }
    );
    let (Some(id), Some(Ok(diagnosis)), true) = (outcome.id, outcome.diagnosis, wins) else {
        d.choice.reason.push_str(&words);
        return d;
    };
    let r = s.rmse_after.unwrap_or(f64::NAN);
    if let Some(ir) = &mut d.choice.integer_reference {
        ir.relative_change = r / ir.rmse - 1.0;
    }
    if is_integer(&g.model) {
        d.choice.integer_reference = None;
    }
    d.choice.reason.push_str(&words);
    d.choice.chosen = index;
    Diagnosed {
        id,
        choice: d.choice,
        diagnosis,
    }
}

/// Whether every order of `m` is a whole number (an integer-order model: no integer reference).
fn is_integer(m: &FracModel) -> bool {
    let v = m.values();
    m.den
        .iter()
        .chain(&m.num)
        .all(|(_, o)| o.eval(&v).fract() == 0.0)
}
