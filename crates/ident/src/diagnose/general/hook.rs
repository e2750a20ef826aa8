//! The general structure as a candidate of the diagnosis's structure comparison
//! ([`crate::diagnose::structures::diagnose_best`]), when the named structures fit poorly.
//!
//! Once the comparison has chosen among the named structures, the chosen final model is judged
//! ([`fits_poorly`]) by the diagnosis's residual tests on the estimation part
//! ([`crate::diagnose::residual::analyse`], whatever the noise level): its residual depends on
//! the input (the residual-input cross-correlation: dynamics the model misses), or it is not
//! white (Ljung-Box at 1%: with white measurement noise, structure the model misses; a short
//! record's cross-correlation has wide bounds), or it kept an advance of the input on a
//! structure with no feed-through (`leads_without_feedthrough`: a time-stamp skew or an instant
//! response), or its base fit is not usable (no named structure could be fitted well posed) and
//! the diagnosis kept no effect (a final model with
//! effects is not its base fit: its own residual judges it; a sign-blind sensor's or a power
//! law's base fit is unusable and its final model right, and on the zoo the general structure
//! was diagnosed on none of the 10 such cases). Only then is the general structure sized by the
//! data ([`super::fit`], its own pole cache); its chosen size is diagnosed when its base fit is
//! usable and predicts the held-out part within [`BEHIND`] of the chosen structure's base fit,
//! and its diagnosis is given no more rounds once more than [`BEHIND`] behind the chosen
//! structure after as many effects (the successive halving's rule of the comparison: a general
//! base compared with a named final model three effects on was left undiagnosed on the zoo's
//! power-law case 0269, where its own diagnosis finds the power law). The two final models are
//! then compared by the comparison's own rule (held-out RMSE, ties within
//! [`crate::diagnose::choice::TIE`] decided by the lower BIC, within
//! [`crate::diagnose::choice::BIC_EVEN`] of it by the fewer effects, a usable base fit first): the
//! general model is returned, with its diagnosis and verdict, when it predicts the held-out data
//! better. Otherwise the named choice stands; its row is added to the comparison either way, and
//! the reason says what was done.

use super::search::{trim, Then};
use super::{fit, GeneralFit, GeneralRequest};
use crate::data::Record;
use crate::diagnose::choice::{decide, score_of, Diagnosed, Outcome, StructureScore};
use crate::diagnose::halving::{at_or_last, BEHIND};
use crate::diagnose::{diagnose_until, DiagnoseOptions, Diagnosis};
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
    } else if leads_without_feedthrough(d) {
        Some("its output leads the recorded input, a time-stamp skew or an instant response it lacks")
    } else {
        None
    }
}

/// Whether the diagnosis `d` kept an advance of the input (a time-stamp skew: a `delay` with a
/// negative `tau`) on a structure with no direct feed-through. To a strictly proper model an
/// output that responds at once to its input looks the same: it moves a sample before the input
/// the model sees. Where the record's feed-through screen cannot tell
/// ([`crate::oe::init::feedthrough::instant_response`]: an input whose lag-0 change its past
/// changes predict, a band-limited sweep or multisine), the structures with a feed-through were
/// not compared, and the general structure, whose sizes include a direct term, tells the two
/// apart (the zoo's feed-through 0055 kept a one-sample skew on a first order).
fn leads_without_feedthrough(d: &Diagnosed) -> bool {
    d.diagnosis.advances_input() && !matches!(d.id.model.kind, Kind::Feedthrough | Kind::Cell)
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
    let g = roots.enter(|| {
        fit(
            rec,
            template,
            opts,
            (&GeneralRequest::default(), Then::AsChosen),
        )
    });
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
    let named: Vec<f64> = d.diagnosis.path.iter().map(|s| s.rmse).collect();
    if !g.id.usable() || behind(&named, 0, base) {
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
                format!(", more than {BEHIND}x the chosen structure's base RMSE")
            } else {
                ", not usable".into()
            }
        ));
        return d;
    }
    // Such a diagnosis, halted, is no final model.
    let halt = |r: usize, rmse: f64| behind(&named, r, rmse);
    let diagnosis = roots.enter(|| diagnose_until(rec, &g.id, dopts, &|| false, &halt));
    let (g, diagnosis, trim_note) = trimmed(rec, (opts, dopts), &mut roots, (g, diagnosis), &halt);
    let halted = diagnosis.as_ref().ok().and_then(|d| d.halted);
    let outcome = Outcome {
        id: Some(g.id),
        diagnosis: Some(diagnosis),
    };
    let row = score_of(&g.name, &outcome);
    let pair = [d.choice.scores[chosen].clone(), row.clone()];
    let wins = halted.is_none() && matches!(decide(&pair), Some((1, _)));
    d.choice.scores.push(row);
    let index = d.choice.scores.len() - 1;
    let s = &d.choice.scores[index];
    let words = format!(
        "; {}{trim_note} (the general structure, compared because {} fits poorly: {why}) \
         held-out RMSE {:.4e} against {:.4e}{}",
        g.name,
        d.choice.scores[chosen].name,
        s.rmse_after.unwrap_or(f64::NAN),
        reference,
        match (wins, halted) {
            (true, _) => ": chosen instead".to_string(),
            (false, Some(r)) => format!(
                ": given no more rounds after {r} effect(s) (more than {BEHIND}x the chosen \
                 structure's RMSE after as many)"
            ),
            (false, None) => ": not chosen".to_string(),
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

/// The general size `g` and its diagnosis, or, when that diagnosis ran to its end and kept no
/// effect (its final model is its base fit, and no effect needs a term a smaller size drops), the
/// size trimmed as the plain fit trims it ([`trim`]) with its own diagnosis, when that one ran to
/// its end keeping no effect either and the comparison's rule prefers it (then with words saying
/// so). The sizes the frequency-domain criterion
/// shortlists may all be larger than the plant's: the zoo's lead case 0183, a first-order
/// numerator over a second order, was fitted as a 1/4 with a lightly damped mode at the Nyquist
/// frequency, its held-out RMSE 1.007x the truth's and its response 58% off over the excited band.
fn trimmed(
    rec: &Record,
    (opts, dopts): (&IdentOptions, &DiagnoseOptions),
    roots: &mut RootsCache,
    (g, diagnosis): (GeneralFit, crate::Result<Diagnosis>),
    halt: &dyn Fn(usize, f64) -> bool,
) -> (GeneralFit, crate::Result<Diagnosis>, String) {
    let bare = match &diagnosis {
        Ok(d) if d.halted.is_none() && d.effects.is_empty() => d.clone(),
        _ => return (g, diagnosis, String::new()),
    };
    let Ok(Some(t)) = roots.enter(|| trim(rec, opts, &g)) else {
        return (g, diagnosis, String::new());
    };
    // The smaller size stands only as what the plain fit would give, bare too: a smaller size
    // whose diagnosis keeps an effect is another optimum, not the trim of this one (the zoo's
    // friction case 0161: a 5/5 stuck at 6.7x the truth's held-out RMSE trimmed to a 4/5 with
    // the friction that held out better than the named structure with it, its response 24% off).
    let td = match roots.enter(|| diagnose_until(rec, &t.id, dopts, &|| false, halt)) {
        Ok(d) if d.halted.is_none() && d.effects.is_empty() => d,
        _ => return (g, diagnosis, String::new()),
    };
    let row = |f: &GeneralFit, d: &Diagnosis| {
        score_of(
            &f.name,
            &Outcome {
                id: Some(f.id.clone()),
                diagnosis: Some(Ok(d.clone())),
            },
        )
    };
    let pair = [row(&g, &bare), row(&t, &td)];
    let as_good = pair[1].rmse_after <= pair[0].rmse_after;
    if as_good && matches!(decide(&pair), Some((1, _))) {
        let note = format!(
            ", trimmed from {} (its diagnosis kept no effect; held-out RMSE {:.4e} -> {:.4e})",
            g.name,
            pair[0].rmse_after.unwrap_or(f64::NAN),
            pair[1].rmse_after.unwrap_or(f64::NAN)
        );
        (t, Ok(td), note)
    } else {
        (g, diagnosis, String::new())
    }
}

/// Whether a held-out RMSE `rmse` after `r` kept effects is more than [`BEHIND`] behind the
/// chosen structure's after as many (`path[r]`, its held-out RMSE after `r` effects, the base
/// first; its last after fewer): the general structure is diagnosed only when its base fit is not
/// behind the chosen structure's base fit, and given no more rounds once it is behind.
fn behind(path: &[f64], r: usize, rmse: f64) -> bool {
    at_or_last(path, r).is_some_and(|v| rmse > BEHIND * v)
}

/// Whether every order of `m` is a whole number (an integer-order model: no integer reference).
fn is_integer(m: &FracModel) -> bool {
    let v = m.values();
    m.den
        .iter()
        .chain(&m.num)
        .all(|(_, o)| o.eval(&v).fract() == 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The zoo's power-law case 0269: the chosen structure's path (held-out RMSE after 0..3 kept
    /// effects) and the general structure's base fit, behind the named final model but not its
    /// base: diagnosed; halted only when behind after as many effects.
    #[test]
    fn the_general_structure_is_compared_after_as_many_effects() {
        let path = [0.1159, 0.0698, 0.0573, 0.0532];
        let base = 0.0792;
        assert!(base > BEHIND * path[3]);
        assert!(!behind(&path, 0, base));
        assert!(!behind(&path, 1, 0.0202));
        assert!(behind(&path, 1, 0.08));
        // beyond the path's end: against its last value
        assert!(behind(&path, 5, 0.06) && !behind(&path, 5, 0.058));
        assert!(!behind(&[], 0, base));
    }
}
