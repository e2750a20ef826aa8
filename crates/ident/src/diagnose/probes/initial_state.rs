//! The record was not at rest at its first sample: the plant still moved from what its input did
//! before the record (a heater's housing still warming, a drive still settling), although the
//! input and the output looked steady over the few samples before the first input change.
//!
//! Why an effect: a record that rests before its first input change is fitted from rest
//! ([`crate::oe::InitialState::Auto`], [`crate::data::Record::rests_until`]); the rest test sees
//! the samples before that change only, so a drift slower than that window (a thermal plant's
//! slow heat path, minutes against an idle window of seconds) passes it. Whether the record was
//! at rest is then a question for the data like any effect: the alternative is the initial state
//! the fit uses for a record that does not rest ([`crate::oe::InitialState::Estimate`]: the state
//! a past held input left, its levels on windows ending `T/64`, `T/8` and `T` before the first
//! sample and before that, [`crate::oe::past_edges`]), kept only when it pays on held-out data
//! and by BIC (four parameters, `4 ln N`).
//!
//! Signature: the model's output change per unit of each past level (the model resimulated with
//! that level alone, other parameters held; exact for the linear part), regressed with the model's
//! sensitivities. Tested only on a record that rests before its first input change
//! ([`crate::data::Record::rests_until`]: the rest is then the auto rule's inference from a short
//! window, not the user's word about a record that moves from its first sample); not tested when
//! the model already has an estimated initial state, on a step at
//! the first sample (its excitation is the step from the input 0 before the record, so a past
//! level is the step itself) and with a free integrator (a held past input would integrate
//! without end).
//!
//! Identifiability: with an output offset fitted, the levels all alike are an input offset
//! through a linear model started from rest (`K p - p G 1`), a step at the first sample, so the
//! two are one candidate here: the input-offset probe leaves that step to this one ([`asks`]),
//! and once this one is kept it reports an input offset as not tested (or ambiguous with the
//! output offset). A level the model no longer feels (its response died out before the record)
//! takes no part in the regression ([`crate::diagnose::residual::explained_in`]).

use super::{named, Candidate, Findings, Look, Probe};
use crate::oe::{past_edges, past_range, FracModel, Structure};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct InitialState;

/// Whether this probe asks whether the record was at rest ([`not_asked`] says why not): the
/// input-offset probe leaves the step from the first sample to it then.
pub(super) fn asks(look: &Look<'_>) -> bool {
    not_asked(look).is_none()
}

/// Why this probe does not ask whether the record was at rest: `Some(None)` when there is nothing
/// to say (only the rest the record's idle start suggests is questioned, the rule of
/// `InitialState::Auto`: a record that moves from its first sample was fitted from rest only
/// because the user said so, and a model with an estimated state has one already), `Some(Some(
/// reason))` when it is not tested for `reason`; `None` when it asks.
fn not_asked(look: &Look<'_>) -> Option<Option<&'static str>> {
    let (rec, m) = (look.ctx.rec, &look.st.model);
    if m.past.is_some() || rec.rests_until().is_none() {
        return Some(None);
    }
    if m.integrator {
        return Some(Some(
            "not tested: through a free integrator a held past input would integrate without end",
        ));
    }
    if rec.starts_with_step() {
        return Some(Some(
            "not tested: a step at the first sample is the step from the input 0 before the \
             record (a past input level is the step itself)",
        ));
    }
    None
}

impl Probe for InitialState {
    fn name(&self) -> &'static str {
        "initial_state"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let (ctx, st) = (look.ctx, look.st);
        if let Some(why) = not_asked(look) {
            if let Some(why) = why {
                found.reject("initial_state", why.into());
            }
            return Ok(());
        }
        let s = look.s();
        let mut m = st.model.clone();
        m.with_past_input(
            past_edges(s as f64 * ctx.dt),
            past_range(&ctx.rec.u, ctx.u0),
        );
        let Some(levels) = m.past.as_ref().map(|p| p.levels.clone()) else {
            return Ok(());
        };
        // A unit of the input's range: the signature is the change per unit, exact for the linear
        // part whatever the step, and of the size the levels take.
        let (lo, hi) = crate::lm::range_of(&ctx.rec.u);
        let unit = (hi - lo).max(1e-12 * hi.abs().max(lo.abs()).max(1.0));
        let mut base = st.values.clone();
        base.resize(m.params.len(), 0.0);
        let mut cols = Vec::with_capacity(levels.len());
        let mut y = vec![0.0; s];
        for &i in &levels {
            let mut v = base.clone();
            v[i] = unit;
            if m.simulate(&v, &ctx.u[..s], ctx.dt, &mut y).is_err() {
                return Ok(());
            }
            cols.push(
                (0..s)
                    .map(|k| (y[k] - st.yhat[k]) / unit)
                    .collect::<Vec<_>>(),
            );
        }
        if cols.iter().flatten().any(|v| !v.is_finite()) {
            return Ok(());
        }
        let (r2, _) = look.direct(&cols);
        found.candidates.push(Candidate {
            lead: None,
            name: "initial_state",
            key: "initial_state".into(),
            r2,
            evidence: format!(
                "the record was fitted from rest (it looks steady for the samples before its first \
                 input change); a past held input on windows ending {} s before the first sample \
                 (the state it left, other parameters held) explains {:.1}% of the residual sum \
                 of squares",
                past_edges(s as f64 * ctx.dt)
                    .iter()
                    .map(|e| format!("{e:.3e}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                100.0 * r2
            ),
            starts: vec![m],
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        let names: Vec<(String, String)> = model
            .past
            .as_ref()
            .map(|p| {
                p.levels
                    .iter()
                    .map(|&i| (model.params[i].name.clone(), model.params[i].name.clone()))
                    .collect()
            })
            .unwrap_or_default();
        let pairs: Vec<(&str, &str)> = names
            .iter()
            .map(|(a, b)| (a.as_str(), b.as_str()))
            .collect();
        named(model, values, &pairs)
    }
}
