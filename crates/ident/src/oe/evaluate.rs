//! A fitted model judged at its values: its own identification with no iteration (its covariance
//! and the checks of [`super::checks`] there), and the same with the plant parameters the record
//! does not determine held, when those are all that stands between it and a usable model. The
//! report's final model is judged so (`app::time`); a structure's final model whose base fit is
//! not usable is judged at its values with nothing held before the comparison takes it as usable
//! (`diagnose::choice::judge_finals`): a model usable only with its dynamics held is no
//! alternative to a usable one.

use super::{identify, FracModel, IdentOptions, Identification, InitialState, StartMode};
use crate::data::Record;
use crate::Result;

/// The identification of `spec` at its values on `rec`: the parameters it was fitted with free,
/// no iteration, `opts`' operating point, split and initial state (an initial state of past
/// input levels, which `spec` carries, is kept at its values).
pub(crate) fn at_values(
    rec: &Record,
    spec: &FracModel,
    opts: &IdentOptions,
) -> Result<Identification> {
    let mut opts = opts.clone();
    opts.start = StartMode::Given;
    opts.fit.lm.max_iterations = 0;
    if spec.past.is_some() && opts.initial == InitialState::Auto {
        opts.initial = InitialState::Estimate;
    }
    identify(rec, spec, &opts)
}

/// The free plant parameters of `id` the data do not determine ([`super::checks::free_plant`],
/// [`super::checks::not_determined`]), when that is `id`'s only problem; else none.
pub(crate) fn undetermined(id: &Identification) -> Vec<usize> {
    let only_weak = id.problems.len() == 1 && id.problems[0].contains("not determined");
    if !only_weak {
        return vec![];
    }
    id.report
        .params
        .iter()
        .enumerate()
        .filter(|&(i, e)| {
            super::checks::free_plant(&id.model, i, e) && super::checks::not_determined(e)
        })
        .map(|(i, _)| i)
        .collect()
}

/// `spec` with its `weak` parameters held at their values, and its identification at its values
/// ([`at_values`]), when that has no problem: the model does without them within what the
/// record shows. `None` when nothing is weak or the model is still not usable so.
pub(crate) fn held(
    rec: &Record,
    spec: &FracModel,
    opts: &IdentOptions,
    weak: &[usize],
) -> Option<(FracModel, Identification)> {
    if weak.is_empty() {
        return None;
    }
    let mut spec = spec.clone();
    for &i in weak {
        spec.params[i].free = false;
    }
    let id = at_values(rec, &spec, opts).ok()?;
    id.problems.is_empty().then_some((spec, id))
}

/// The problems of `spec` judged at its values on `rec` ([`at_values`]), nothing held: an
/// evaluation that fails is a problem.
pub(crate) fn problems_at_values(
    rec: &Record,
    spec: &FracModel,
    opts: &IdentOptions,
) -> Vec<String> {
    match at_values(rec, spec, opts) {
        Ok(id) => id.problems,
        Err(e) => vec![format!(
            "the model cannot be evaluated at its values on this record ({e})"
        )],
    }
}
