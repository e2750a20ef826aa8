//! The general structure's size chosen by the data: the starts the frequency-domain criterion
//! ranks first and the smallest ones nearly as good ([`shortlist`], at most [`SHORTLIST`]) are
//! each fitted by output error ([`crate::oe::identify`], from their start, raced: [`raced`]),
//! and the one chosen by the structure
//! comparison's rule: among the usable fits (all of them when none is), those whose held-out RMSE
//! (estimation RMSE without a held-out part) is within [`TIE`] of the best are ties, and the tie
//! with the lowest BIC on the estimation part wins.
//!
//! When the response is Welch's estimate (the input is not periodic), the sizes are also ranked
//! on an ARX model's response ([`start::arx_frf`]) and its shortlist's starts not already picked
//! are fitted too: Welch's estimate of a record with few input tones (a multisine not periodic
//! within the record) is mostly leakage between them, and no size's start on it may hold the
//! plant's modes (the zoo's two-mode case 0179: the fits from Welch's starts ended 7x the
//! truth's held-out RMSE, a fifth order from the ARX response's 1.003x). On the zoo (300 cases,
//! seed 44) this changed 6 rows, each held-out RMSE closer to the truth's.
//!
//! The response is estimated on the estimation part only (the part [`crate::oe::identify`] fits:
//! the same split), so the held-out part stays unseen by the start as by the fit.

use super::start::{self, calls_for_integrator};
use super::{Budget, GeneralRequest, GeneralStart};
use crate::data::Record;
use crate::diagnose::choice::{StructureChoice, StructureScore, TIE};
use crate::oe::{identify, FracModel, IdentOptions, Identification, InitialState, StartMode};
use crate::{Error, Result};

/// The most sizes fitted by output error.
pub const SHORTLIST: usize = 5;

/// The general structure's fit: the chosen identification, the comparison of the sizes fitted
/// (in the structure comparison's form), and the chosen structure with its fitted values (no
/// output offset or initial state: the linear part, as a structure to fit again).
#[derive(Debug, Clone)]
pub struct GeneralFit {
    /// The chosen size's identification.
    pub id: Identification,
    /// The sizes fitted and the decision.
    pub choice: StructureChoice,
    /// The chosen structure, its parameters at their fitted values.
    pub model: FracModel,
    /// The chosen size's name (`general N/D`, ...).
    pub name: String,
    /// The chosen size's start (its size and integrator), for trimming it later ([`trim`]).
    pub start: GeneralStart,
}

/// The estimation part's deviations of `rec` as [`identify`] splits and centres them for `opts`.
///
/// # Errors
/// A holdout out of range.
fn estimation_part(rec: &Record, opts: &IdentOptions) -> Result<(Vec<f64>, Vec<f64>)> {
    // (With held-out blocks, the whole record: a start made on the estimation samples
    // concatenated would see a jump at each block.)
    let (split, _, _) =
        crate::oe::checks::validation_split(rec, rec.split_index(opts.holdout)?, opts.holdout);
    let off = rec.offsets(opts.offsets, split);
    let u = rec.u[..split].iter().map(|v| v - off.u0).collect();
    let y = rec.y[..split].iter().map(|v| v - off.y0).collect();
    Ok((u, y))
}

/// The parameter budget of the general structure on `rec` ([`Budget`]): the free parameters the
/// fit adds beside the structure are the output offset (`opts.fit_offset`), with an integrator
/// an input offset as well, the initial state's levels when it is estimated
/// ([`crate::oe::past_edges`]), a free order, and the template's own free delay.
fn budget(
    rec: &Record,
    template: &FracModel,
    opts: &IdentOptions,
    req: &GeneralRequest,
    samples: usize,
) -> Budget {
    let levels = match opts.initial.resolve(rec, opts.offsets) {
        InitialState::Estimate => crate::oe::past_edges(samples as f64 * rec.dt).len() + 1,
        _ => 0,
    };
    let delay = template.delay.is_some_and(|i| template.params[i].free);
    let counted = usize::from(opts.fit_offset) + usize::from(req.free_q) + usize::from(delay);
    let beside = counted + levels;
    Budget::new(
        samples,
        beside,
        beside + usize::from(opts.fit_offset),
        counted,
    )
}

/// The ranked starts of the general structure on `rec` for `req`, `template` giving the
/// integrator when the user asked for one and the delay when it has one (else the delay is
/// searched on the response, [`start::ranked_delayed`]); sizes within the record's
/// [`budget`]; with `arx`, the ranking on an ARX model's response beside Welch's estimate too.
fn starts(
    rec: &Record,
    template: &FracModel,
    opts: &IdentOptions,
    (req, arx): (&GeneralRequest, bool),
) -> Result<Starts> {
    let (u, y) = estimation_part(rec, opts)?;
    let (frf, how, source) = start::frf(&u, &y, rec.dt)?;
    let integrators: Vec<bool> = match req.integrator {
        Some(i) => vec![i],
        None if template.integrator => vec![true],
        None if calls_for_integrator(&frf) => vec![false, true],
        None => vec![false],
    };
    let budget = budget(rec, template, opts, req, u.len());
    let search = template.delay.is_none();
    let ranked = start::ranked_delayed(&frf, rec.dt, req.size, &integrators, budget, search)?;
    // Welch's estimate of a record whose input is not periodic: an ARX model's response ranks
    // the sizes too (see [`fit`]).
    let second = if arx && source == start::Source::Welch && req.size.is_none() {
        let why = Error::NotEnoughData("beside Welch's estimate".into());
        start::arx_frf(&u, &y, rec.dt, &why)
            .ok()
            .and_then(|(f, _)| {
                start::ranked_delayed(&f, rec.dt, req.size, &integrators, budget, search).ok()
            })
            .unwrap_or_default()
    } else {
        vec![]
    };
    Ok(Starts {
        ranked,
        how,
        second,
    })
}

/// The general structure's starts ([`starts`]).
struct Starts {
    /// Ranked on the record's response (best first).
    ranked: Vec<GeneralStart>,
    /// How the response was made.
    how: String,
    /// Ranked on an ARX model's response when the record's is Welch's estimate (else empty).
    second: Vec<GeneralStart>,
}

/// The start's structure with the template's approximation and delay, or the delay found on
/// the response (free, from its whole-sample value, within `(0, (2 d + 1) dt)`).
fn structure(s: &GeneralStart, template: &FracModel, req: &GeneralRequest, dt: f64) -> FracModel {
    let mut m = s.model(req.free_q);
    m.approx = template.approx;
    if let Some(i) = template.delay {
        let p = &template.params[i];
        if let crate::oe::Bounds::Interval(_, hi) = p.bounds {
            m.with_delay(p.value, hi);
        }
        if let Some(j) = m.delay {
            m.params[j].free = p.free;
        }
    } else if s.delay_samples > 0 {
        let d = s.delay_samples as f64;
        m.with_delay(d * dt, (2.0 * d + 1.0) * dt);
    }
    m
}

/// The general structure fitted on `rec` (see the module documentation): `template` is the
/// structure the request's options made (its approximation, delay and integrator are kept),
/// `opts` the fit's options (its start is the general structure's own).
///
/// With [`Then::Trimmed`] the chosen size is trimmed ([`trimmed`]) unless the request fixes
/// it.
///
/// # Errors
/// [`Error::NotEnoughData`] when no frequency response can be estimated or no size gives a
/// stable start; the first size's fit error when none could be fitted.
pub fn fit(
    rec: &Record,
    template: &FracModel,
    opts: &IdentOptions,
    (req, then): (&GeneralRequest, Then),
) -> Result<GeneralFit> {
    let Starts {
        ranked,
        how,
        second,
    } = starts(rec, template, opts, (req, true))?;
    let given = IdentOptions {
        start: StartMode::Given,
        ..opts.clone()
    };
    let ranked_count = ranked.len();
    let mut picked = shortlist(ranked);
    let first_count = picked.len();
    for s in shortlist(second) {
        if !picked.iter().any(|p| p.name() == s.name()) {
            picked.push(s);
        }
    }
    let short: Vec<(GeneralStart, FracModel)> = picked
        .into_iter()
        .map(|s| {
            let m = structure(&s, template, req, rec.dt);
            (s, m)
        })
        .collect();
    let fits = raced(rec, &short, &given);
    let scores: Vec<StructureScore> = short
        .iter()
        .zip(&fits)
        .map(|((s, _), f)| score(&s.name(), f))
        .collect();
    let Some(chosen) = decide(&scores) else {
        let mut fits = fits;
        return Err(match fits.swap_remove(0) {
            Err(e) => e,
            Ok(_) => Error::Numerical("no size of the general structure could be fitted".into()),
        });
    };
    let mut fits = fits;
    let id = fits.swap_remove(chosen)?;
    let held_out = id.validation.is_some();
    let (s, m) = &short[chosen];
    let (mut scores, mut chosen) = (scores, chosen);
    let at = (s.clone(), fitted(m, &id), id);
    // a size the user fixed is the size fitted
    let (s, model, id) = match (req.size, then) {
        (None, Then::Trimmed) => trimmed(rec, &given, at, (&mut scores, &mut chosen))?,
        _ => at,
    };
    let also = if short.len() > first_count {
        format!(
            ", and {} more ranked first on an ARX model's response",
            short.len() - first_count
        )
    } else {
        String::new()
    };
    let trim = match scores.len() - short.len() {
        0 => String::new(),
        n => format!(
            ", then its highest terms dropped while a smaller size was as good ({n} smaller \
             sizes refitted)"
        ),
    };
    let reason = format!(
        "general structure: {ranked_count} sizes ranked by a frequency-domain BIC on {how}; \
         {first_count} fitted by output error (the best by it and the smallest nearly as \
         good){also}; {} chosen by {} RMSE (ties within {:.0}%: lowest BIC){trim}",
        s.name(),
        if held_out { "held-out" } else { "estimation" },
        100.0 * TIE
    );
    let choice = StructureChoice {
        scores,
        chosen,
        held_out,
        reason,
        integer_reference: None,
    };
    Ok(GeneralFit {
        id,
        choice,
        model,
        name: s.name(),
        start: s,
    })
}

/// `g`, a size kept as chosen ([`Then::AsChosen`]), trimmed as [`Then::Trimmed`] trims a size
/// ([`trimmed`]), with `g`'s options `opts`: the smaller size and its fit, or `None` when no
/// smaller size is chosen. The diagnosis trims a size whose diagnosis kept no effect (its final
/// model is its base fit, and no effect needs a term a smaller size drops:
/// [`super::hook::consider`]).
///
/// # Errors
/// A smaller size's fit error where it was chosen.
pub fn trim(rec: &Record, opts: &IdentOptions, g: &GeneralFit) -> Result<Option<GeneralFit>> {
    let given = IdentOptions {
        start: StartMode::Given,
        ..opts.clone()
    };
    let (mut scores, mut chosen) = (g.choice.scores.clone(), g.choice.chosen);
    let at = (g.start.clone(), g.model.clone(), g.id.clone());
    let (s, model, id) = trimmed(rec, &given, at, (&mut scores, &mut chosen))?;
    if chosen == g.choice.chosen {
        return Ok(None);
    }
    let reason = format!(
        "{}; then trimmed to {} (its highest terms dropped while a smaller size was as good, {} \
         smaller sizes refitted)",
        g.choice.reason,
        s.name(),
        scores.len() - g.choice.scores.len()
    );
    Ok(Some(GeneralFit {
        id,
        choice: StructureChoice {
            scores,
            chosen,
            reason,
            ..g.choice.clone()
        },
        model,
        name: s.name(),
        start: s,
    }))
}

/// What follows the choice of a size ([`fit`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Then {
    /// The chosen size is trimmed ([`trimmed`]): the fit is the answer (the plain fit of the
    /// general structure).
    Trimmed,
    /// The chosen size is kept as chosen: it is diagnosed before it is compared, and a term a
    /// base fit without the record's effects does not need may be the one an effect needs (the
    /// zoo's cell case 0284: a 2/2 trimmed to a 1/2 that held out better without effects ended
    /// 3.5x the truth's error where the 2/2 with a drift ended at 1.0x).
    AsChosen,
}

/// `m` at the values `id` fitted (its own parameters: the output offset and the initial state's
/// levels come after them).
fn fitted(m: &FracModel, id: &Identification) -> FracModel {
    let mut m = m.clone();
    for (p, v) in m.params.iter_mut().zip(&id.report.values) {
        p.value = *v;
    }
    m
}

/// A chosen size and its fit.
type Picked = (GeneralStart, FracModel, Identification);

/// The chosen size made smaller while a smaller one is as good (backward elimination of
/// terms): from the chosen fit, its highest denominator term and its highest numerator term are
/// each dropped ([`smaller`]) and the two refitted by output error from the rest of its values;
/// the better of them goes on being trimmed while its held-out RMSE stays within [`TIE`] of the
/// chosen one's, and becomes the chosen size when it predicts the held-out part at least as well
/// and the comparison's rule ([`decide`]) between the two prefers it (usable first, then BIC).
/// The tie's slack is for sizes fitted each from its own start; a size trimmed from the chosen
/// one must lose nothing held out, since the missing effects a base fit is compared without can
/// swamp what a term adds (the zoo's cell case 0284: a 2/2 trimmed to a 1/1 within the tie held
/// out 19% worse once its drift was fitted). A smaller size on the way may have a
/// coefficient the data do not determine (the next term down is the one to drop): it is passed
/// through, not chosen. The frequency-domain criterion ranks sizes on an estimated response, and
/// the sizes it shortlists may all be larger than the plant's: a lead `(b1 s + b0)/(a2 s^2 + a1
/// s + 1)` whose second order it placed at a wrong commensurate order was fitted as a fourth
/// order with a mode near the Nyquist frequency (the zoo's case 0183: 58% response error over
/// the excited band). Each refitted size's row joins `scores`; `chosen` follows the choice.
fn trimmed(
    rec: &Record,
    opts: &IdentOptions,
    mut best: Picked,
    (scores, chosen): (&mut Vec<StructureScore>, &mut usize),
) -> Result<Picked> {
    let mut at = (best.0.clone(), best.1.clone());
    loop {
        let mut smaller: Vec<(GeneralStart, FracModel)> = [true, false]
            .into_iter()
            .filter_map(|den| smaller(&at.0, &at.1, den))
            .collect();
        let mut fits: Vec<Result<Identification>> = smaller
            .iter()
            .map(|(_, m)| identify(rec, m, opts))
            .collect();
        let first = scores.len();
        scores.extend(
            smaller
                .iter()
                .zip(&fits)
                .map(|((s, _), f)| score(&s.name(), f)),
        );
        let rmse = |i: usize| scores[i].rmse.filter(|r| r.is_finite());
        let limit = rmse(*chosen).map_or(f64::INFINITY, |r| r * (1.0 + TIE));
        let Some(k) = (0..smaller.len())
            .filter(|&k| rmse(first + k).is_some_and(|r| r <= limit))
            .min_by(|&a, &b| {
                let r = |k: usize| rmse(first + k).unwrap_or(f64::INFINITY);
                r(a).total_cmp(&r(b))
            })
        else {
            return Ok(best);
        };
        let (s, m) = smaller.swap_remove(k);
        let id = fits.swap_remove(k)?;
        at = (s, fitted(&m, &id));
        let pair = [scores[*chosen].clone(), scores[first + k].clone()];
        if decide(&pair) == Some(1) && rmse(first + k) <= rmse(*chosen) {
            *chosen = first + k;
            best = (at.0.clone(), at.1.clone(), id);
        }
    }
}

/// `m` (the structure of start `s`, at its fitted values) without its highest denominator term
/// (`den`) or numerator term, with the start of that size; `None` when the term is the last one
/// a size keeps (the numerator's `b0`; the denominator's `a1` without an integrator, which would
/// leave a static gain).
fn smaller(s: &GeneralStart, m: &FracModel, den: bool) -> Option<(GeneralStart, FracModel)> {
    let mut s = s.clone();
    let mut m = m.clone();
    let left = if den { usize::from(!s.integrator) } else { 0 };
    let (degree, terms, coefficients) = if den {
        (&mut s.size.den, &mut m.den, &mut s.a)
    } else {
        (&mut s.size.num, &mut m.num, &mut s.b)
    };
    if *degree <= left || terms.len() < 2 {
        return None;
    }
    *degree -= 1;
    coefficients.pop();
    // the highest order first ([`GeneralStart::model`])
    let (c, _) = terms.remove(0);
    let gone: Vec<usize> = c.terms.iter().map(|&(i, _)| i).collect();
    Some((s, m.without_params(&gone).0))
}

/// The iterations every size's fit gets before the race ([`raced`]) decides which go on.
pub const RACE_ITERATIONS: usize = 150;

/// How far behind the best held-out RMSE after [`RACE_ITERATIONS`] a size's fit may be for it to
/// go on with the rest of its budget ([`raced`]).
pub const RACE_BEHIND: f64 = 1.5;

/// The sizes `short` fitted by output error from their starts with `opts`, raced (successive
/// halving with one cut): each fit first gets [`RACE_ITERATIONS`]; a fit stopped there
/// (not converged) goes on from where it stopped with the rest of `opts`' budget only when its
/// held-out RMSE (estimation RMSE without a held-out part) is within [`RACE_BEHIND`] of the
/// best fit's so far. A size the data do not determine creeps on for hundreds of iterations
/// (a fifth order on the zoo's cell case 0259: 430 iterations, eight times the comparison of the
/// named structures), and one 50% behind the best does not catch up by creeping; a size that
/// converges within the first iterations ends where a single fit would have. On the zoo (300
/// cases, seed 44) the race changes no row of the table.
fn raced(
    rec: &Record,
    short: &[(GeneralStart, FracModel)],
    opts: &IdentOptions,
) -> Vec<Result<Identification>> {
    let budget = opts.fit.lm.max_iterations;
    let mut first = opts.clone();
    first.fit.lm.max_iterations = budget.min(RACE_ITERATIONS);
    let mut fits: Vec<Result<Identification>> = short
        .iter()
        .map(|(_, m)| identify(rec, m, &first))
        .collect();
    let held = |id: &Identification| id.validation.unwrap_or(id.estimation).rmse;
    let best = fits
        .iter()
        .flatten()
        .map(held)
        .filter(|r| r.is_finite())
        .fold(f64::INFINITY, f64::min);
    let mut rest = opts.clone();
    rest.fit.lm.max_iterations = budget - first.fit.lm.max_iterations;
    for ((_, m), f) in short.iter().zip(&mut fits) {
        let Ok(id) = f else { continue };
        let stopped = id.report.termination == crate::lm::Termination::MaxIterations;
        if !(stopped && rest.fit.lm.max_iterations > 0 && held(id) <= RACE_BEHIND * best) {
            continue;
        }
        let mut m = m.clone();
        for (p, v) in m.params.iter_mut().zip(&id.report.values) {
            p.value = *v;
        }
        if let Ok(more) = identify(rec, &m, &rest) {
            *f = Ok(more);
        }
    }
    fits
}

/// The starts fitted by output error, from the `ranked` ones (best criterion first): the
/// [`SHORTLIST`]` / 2` best by the criterion, then the small ones: for each bound of
/// [`SMALL_COEFFICIENTS`] in turn, the best by the criterion with at most that many
/// coefficients, not yet picked, whose error on the response is within [`SMALL_ENOUGH`] times
/// the best one's (or [`SMALL_FLOOR`]'s), up to [`SHORTLIST`] in all. The criterion's weights
/// are estimated (or, on an ARX model's response, absent), so it may favour a size larger than
/// the plant's; the smaller sizes then compete on held-out data.
fn shortlist(ranked: Vec<GeneralStart>) -> Vec<GeneralStart> {
    let best_err = ranked
        .iter()
        .take(SHORTLIST / 2)
        .map(|s| s.frf_error)
        .fold(f64::INFINITY, f64::min);
    let coefs = |s: &GeneralStart| s.b.len() + s.a.len() + usize::from(s.q != 1.0);
    let near = |s: &GeneralStart| s.frf_error <= SMALL_ENOUGH * best_err.max(SMALL_FLOOR);
    let mut picked: Vec<usize> = (0..ranked.len().min(SHORTLIST / 2)).collect();
    for bound in SMALL_COEFFICIENTS {
        if picked.len() >= SHORTLIST {
            break;
        }
        // `ranked` is in the criterion's order: the first that qualifies is the best
        if let Some(i) = (0..ranked.len())
            .find(|&i| !picked.contains(&i) && coefs(&ranked[i]) <= bound && near(&ranked[i]))
        {
            picked.push(i);
        }
    }
    picked.into_iter().map(|i| ranked[i].clone()).collect()
}

/// The bounds on the coefficients of the small starts [`shortlist`] adds: a first order (or a
/// lag with a zero); up to a third order with two zeros (a resonance and an anti-resonance
/// beside a lag); up to a fifth order with three zeros (two modes).
pub const SMALL_COEFFICIENTS: [usize; 3] = [3, 6, 9];

/// How much larger than the best one's the response error of a smaller start may be for it to
/// be fitted too ([`shortlist`]).
pub const SMALL_ENOUGH: f64 = 3.0;

/// The best response error [`SMALL_ENOUGH`] is taken of at least: on a response with no
/// variance of its own (an ARX model's, [`start::arx_frf`]) the largest sizes reproduce it to
/// rounding, and the smaller sizes within 15% of it still compete on held-out data.
pub const SMALL_FLOOR: f64 = 0.05;

/// The general structure as a candidate of the structure comparison or the diagnosis: the start
/// the frequency-domain criterion ranks first on `rec` (no output-error fit here: the caller
/// fits it, [`crate::oe::Kind::General`] starting from its values), with its name
/// (`general N/D`, ...). `None` when no frequency response can be estimated or no size gives a
/// stable start.
pub fn candidate(
    rec: &Record,
    template: &FracModel,
    opts: &IdentOptions,
) -> Option<(String, FracModel)> {
    let req = GeneralRequest::default();
    let ranked = starts(rec, template, opts, (&req, false)).ok()?.ranked;
    let s = ranked.first()?;
    let mut m = structure(s, template, &req, rec.dt);
    m.approx = template.approx;
    Some((s.name(), m))
}

/// One size's row in the comparison.
fn score(name: &str, f: &Result<Identification>) -> StructureScore {
    let mut s = StructureScore::named(name);
    match f {
        Ok(id) => {
            let k = id.model.params.iter().filter(|p| p.free).count();
            let n = id.validated_by.estimation_samples(id.split);
            let ssr = id.estimation.rmse.powi(2) * n as f64;
            s.model = id.tf.to_string();
            s.rmse = Some(id.validation.unwrap_or(id.estimation).rmse);
            s.rmse_after = s.rmse;
            s.problems = id.problems.clone();
            s.free_params = k;
            s.bic_after = Some(crate::diagnose::bic(ssr, n, k));
        }
        Err(e) => s.failed = Some(e.to_string()),
    }
    s
}

/// The chosen row: among the usable rows (all when none is) with a finite RMSE, the ties within
/// [`TIE`] of the best, the lowest BIC of them.
fn decide(scores: &[StructureScore]) -> Option<usize> {
    let ok = |s: &StructureScore| s.rmse.is_some_and(f64::is_finite);
    let any_usable = scores.iter().any(|s| ok(s) && s.problems.is_empty());
    let pool: Vec<usize> = (0..scores.len())
        .filter(|&i| ok(&scores[i]) && (!any_usable || scores[i].problems.is_empty()))
        .collect();
    let best = pool
        .iter()
        .filter_map(|&i| scores[i].rmse)
        .fold(f64::INFINITY, f64::min);
    pool.into_iter()
        .filter(|&i| scores[i].rmse.is_some_and(|r| r <= best * (1.0 + TIE)))
        .min_by(|&a, &b| {
            let bic = |i: usize| scores[i].bic_after.unwrap_or(f64::INFINITY);
            bic(a).total_cmp(&bic(b))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(rmse: f64, bic: f64, usable: bool) -> StructureScore {
        StructureScore {
            name: "r".into(),
            model: String::new(),
            failed: None,
            rmse: Some(rmse),
            problems: if usable { vec![] } else { vec!["x".into()] },
            effects: vec![],
            free_params: 1,
            rmse_after: Some(rmse),
            bic_after: Some(bic),
            problems_after: None,
        }
    }

    #[test]
    fn the_rule_prefers_usable_then_ties_by_bic() {
        // the unusable best is passed over; of the two within 2%, the lower BIC
        let rows = [
            row(0.5, 0.0, false),
            row(1.0, 10.0, true),
            row(1.015, 5.0, true),
            row(1.1, -100.0, true),
        ];
        assert_eq!(decide(&rows), Some(2));
        assert_eq!(decide(&rows[..1]), Some(0));
        assert_eq!(decide(&[]), None);
    }
}
