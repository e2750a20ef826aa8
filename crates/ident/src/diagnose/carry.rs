//! An effect carried from the chosen structure's diagnosis to the structures it was compared
//! with (docs/design.md §5, "an effect one structure found, tried on the others").
//!
//! Each structure is diagnosed from its own base fit, and a base fit without an effect the
//! record holds spends its terms on it: a PMSM fitted to a speed that drifts explained the
//! ramp with a fractional mode slower than the record (gain 681 against the plant's 1.24, the
//! zoo's drift case 0171), so that the drift's signature was left with 0.3% of the residual and
//! its refit from that fit diverged; a PMSM fitted to a saturated record left four terms
//! undetermined and was never diagnosed (saturation case 0039). A first order, with nothing to
//! spend, kept the effect and was chosen, 7% above the truth's held-out error and 11-19% off
//! in its frequency response. So once a structure is chosen with one effect, each richer
//! structure is fitted again with that effect from its own automatic start (the effect's
//! parameters started at the chosen model's values); one whose fit predicts the held-out part
//! better than the chosen final model is diagnosed again with that fit offered as the effect's
//! refit in its first round ([`Carried`]): the effect is kept or rejected there by the rules
//! every candidate meets (the margin on held-out data, BIC, the credit check), and the
//! comparison's rule ([`super::choice::decide`]) then chooses among the final models as before.

use super::choice::{score_of, Outcome, StructureScore};
use super::DiagnoseOptions;
use crate::data::Record;
use crate::oe::{identify, Effect, FracModel, IdentOptions, Param};
use std::collections::BTreeMap;

/// One effect of another structure's final model, offered to a diagnosis as a start of that
/// effect's refit in its first round.
#[derive(Debug, Clone)]
pub(crate) struct Carried {
    /// The effect's report name (its probe's).
    pub name: &'static str,
    /// The effect's entries, their parameter indices into `params`.
    pub effects: Vec<Effect>,
    /// The effect's parameters, at the values of the model they were taken from.
    pub params: Vec<Param>,
    /// The start's values by parameter name (a fit of the diagnosed structure with the effect):
    /// they replace the current model's and the effect's where the names match.
    pub values: BTreeMap<String, f64>,
    /// Where the start comes from, for the kept effect's evidence.
    pub evidence: String,
}

impl Carried {
    /// The one effect a final `model` holds beside its output offset and the effects of the
    /// structure it was diagnosed from (`base`: an integrating structure's own input offset is
    /// no effect its diagnosis found), a sensor's zero and its rectification counting as one,
    /// with its parameters at the model's values; `None` for none or several (each would be one
    /// candidate of its own, and a start holding them all the refit of one of them).
    pub(crate) fn of(model: &FracModel, base: &FracModel) -> Option<Carried> {
        let effects: Vec<&Effect> = model
            .effects
            .iter()
            .filter(|e| !matches!(e, Effect::OutputOffset { .. }) && !holds(base, e.name()))
            .collect();
        let name = effects.first()?.name();
        if effects.iter().any(|e| e.name() != name) {
            return None;
        }
        let mut index: Vec<usize> = effects.iter().flat_map(|e| e.params()).collect();
        index.dedup();
        let local = |i: usize| index.iter().position(|&j| j == i).unwrap_or(0);
        Some(Carried {
            name,
            effects: effects.iter().map(|e| e.renumbered(local)).collect(),
            params: index.iter().map(|&i| model.params[i].clone()).collect(),
            values: BTreeMap::new(),
            evidence: String::new(),
        })
    }

    /// `model` with the effect added (its parameters at their values), and then every parameter
    /// whose name `values` holds at that value.
    pub(crate) fn onto(&self, model: &FracModel) -> FracModel {
        let mut m = model.clone();
        let at: Vec<usize> = self.params.iter().map(|p| m.add_param(p.clone())).collect();
        for e in &self.effects {
            m.effects.push(e.renumbered(|i| at[i]));
        }
        for p in &mut m.params {
            if let Some(&v) = self.values.get(&p.name) {
                p.value = v;
            }
        }
        m
    }
}

/// A candidate refitted as a smaller structure before its diagnosis (a two-term fit whose terms
/// the record did not determine, refitted as its single mode; a degenerate two-mass fit made
/// well posed): the structure in full, its name, and the fit the reduction was made from. A
/// base fit that an effect bent (a saturation, a friction) may leave a term undetermined that
/// the effect, once fitted, determines: the full structure is then the one the effect is
/// carried to ([`carry`]), where its reduced form would need a delay to stand in for the term
/// it lost (the zoo's saturation 45/0289, friction 45/0236).
#[derive(Debug, Clone)]
pub(crate) struct Unreduced {
    /// The candidate's name (without "(reduced)").
    pub name: String,
    /// The structure in full.
    pub model: FracModel,
    /// The fit the reduction was made from: the base of its diagnosis when the effect is
    /// carried to it.
    pub id: crate::oe::Identification,
}

/// The chosen structure's one effect carried to the structures richer than it (module
/// documentation): each fitted with it from its own start, and one whose fit predicts the
/// held-out part better than the chosen final model beyond the tie diagnosed again from its base
/// fit with that fit as the effect's start; its diagnosis replaces its row when its final model
/// is better. A candidate that was reduced before its diagnosis (`unreduced`) is carried to in
/// full, the chosen one too: its row then becomes the full structure's (its name and base fit).
/// A structure whose diagnosis kept the effect already is carried to only when its final model
/// is behind the chosen one's beyond the tie (its diagnosis started from a base fit the effect
/// had bent; the effect fitted from the structure's own start may end elsewhere). Returns the
/// structures diagnosed again, each with the words for the choice's reason; the caller judges
/// and decides again.
pub(crate) fn carry(
    rec: &Record,
    (cands, unreduced): (&mut [(String, FracModel)], &[Option<Unreduced>]),
    (outcomes, scores): (&mut [Outcome], &mut [StructureScore]),
    chosen: usize,
    (opts, dopts): (&IdentOptions, &DiagnoseOptions),
) -> Vec<(usize, String)> {
    let Some(Some(Ok(d))) = outcomes.get(chosen).map(|o| &o.diagnosis) else {
        return vec![];
    };
    let Some(chosen_base) = outcomes[chosen].id.as_ref() else {
        return vec![];
    };
    let Some(effect) = Carried::of(&d.model, &chosen_base.model) else {
        return vec![];
    };
    let (bar, integrator) = (d.after.rmse, cands[chosen].1.integrator);
    let terms = |m: &FracModel| m.params.iter().filter(|p| p.free).count();
    let fewest = terms(&cands[chosen].1);
    let chosen_name = cands[chosen].0.clone();
    let mut words = vec![];
    for i in 0..cands.len() {
        let full = unreduced.get(i).and_then(Option::as_ref);
        let (structure, base) = match full {
            Some(u) => (&u.model, Some(&u.id)),
            None => (&cands[i].1, outcomes[i].id.as_ref()),
        };
        let Some(base) = base else { continue };
        // A structure whose base fit holds the effect (an integrating structure's input
        // offset) was fitted with it; one whose diagnosis kept it and ties the chosen one
        // competes already.
        let kept = full.is_none()
            && scores[i].effects.iter().any(|e| e == effect.name)
            && scores[i]
                .rmse_after
                .is_none_or(|r| r <= (1.0 + super::choice::TIE) * bar);
        if (i == chosen && full.is_none())
            || structure.integrator != integrator
            || terms(structure) <= fewest
            || holds(&base.model, effect.name)
            || kept
        {
            continue;
        }
        let Ok(fresh) = identify(rec, &effect.onto(structure), opts) else {
            continue;
        };
        let held = fresh.validation.unwrap_or(fresh.estimation).rmse;
        // Better than the chosen final model by no more than the tie, its BIC (terms more, the
        // same effect) would not win the choice.
        if !(held < (1.0 - super::choice::TIE) * bar) {
            continue;
        }
        let start = Carried {
            values: fresh
                .model
                .params
                .iter()
                .map(|p| p.name.clone())
                .zip(fresh.report.values.iter().copied())
                .collect(),
            evidence: format!(
                "carried from {chosen_name}'s diagnosis: this structure fitted with it from its \
                 own start holds out {held:.4e}"
            ),
            ..effect.clone()
        };
        let again = fracsim::modal::RootsCache::new()
            .enter(|| super::diagnose_carrying(rec, base, dopts, std::slice::from_ref(&start)));
        let Ok(again) = again else { continue };
        let before = scores[i].rmse_after.unwrap_or(f64::INFINITY);
        // The structure in full takes a reduced row only with a final model usable at its
        // values (as the choice judges a final model whose base fit is not usable): the row's
        // reduced diagnosis is otherwise lost to one that cannot be chosen.
        let usable =
            || full.is_none() || super::choice::final_problems(rec, &again, opts).is_empty();
        if again.after.rmse < before
            && again.effects.iter().any(|k| k.name == effect.name)
            && usable()
        {
            if let Some(u) = full {
                cands[i] = (u.name.clone(), u.model.clone());
                outcomes[i].id = Some(u.id.clone());
            }
            words.push((
                i,
                format!(
                    "{} diagnosed again{} with {chosen_name}'s {} (fitted with it from its own \
                     start: held-out RMSE {held:.4e}; {:.4e} after its diagnosis)",
                    cands[i].0,
                    if full.is_some() { " in full" } else { "" },
                    effect.name,
                    again.after.rmse
                ),
            ));
            outcomes[i].diagnosis = Some(Ok(again));
            scores[i] = score_of(&cands[i].0, &outcomes[i]);
        }
    }
    words
}

/// Whether `model` holds an effect named `name`.
fn holds(model: &FracModel, name: &str) -> bool {
    model.effects.iter().any(|e| e.name() == name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Bounds;

    /// A first order with an output offset and `effects` (name, value) added in turn.
    fn first_order_with(effects: &[(&str, f64)]) -> FracModel {
        let mut m = crate::catalogue::Preset::FirstOrder.model(1.0);
        m.with_output_offset(0.3);
        for &(name, v) in effects {
            let i = m.add_param(Param::new(name, v, Bounds::Free));
            m.effects.push(match name {
                "sat_level" => Effect::Saturation { level: i },
                _ => Effect::OutputDrift { r: i },
            });
        }
        m
    }

    #[test]
    fn one_effect_is_carried_onto_another_structure_at_its_values() {
        let a = first_order_with(&[("sat_level", 0.55)]);
        let c = Carried::of(&a, &first_order_with(&[])).expect("one effect");
        assert_eq!(c.name, "saturation");
        assert_eq!(c.params.len(), 1);
        let b = crate::catalogue::Preset::Pmsm.model(1.0);
        let n = b.params.len();
        let on = c.onto(&b);
        assert_eq!(on.params.len(), n + 1);
        assert_eq!(on.params[n].name, "sat_level");
        assert_eq!(on.params[n].value, 0.55);
        assert_eq!(on.effects.last(), Some(&Effect::Saturation { level: n }));
        // the start's values replace the model's by name
        let start = Carried {
            values: [("sat_level".to_string(), 0.6), ("K".to_string(), 19.0)].into(),
            ..c
        };
        let on = start.onto(&b);
        assert_eq!(on.params[n].value, 0.6);
        assert_eq!(on.params[on.index_of("K").unwrap()].value, 19.0);
    }

    #[test]
    fn no_effect_or_two_effects_are_not_carried() {
        let base = first_order_with(&[]);
        assert!(Carried::of(&base, &base).is_none());
        let two = first_order_with(&[("sat_level", 0.55), ("y_drift", 0.1)]);
        assert!(Carried::of(&two, &base).is_none());
    }

    #[test]
    fn an_effect_of_the_structures_own_base_fit_is_not_carried() {
        // an integrating structure's base fit holds its input offset: no effect was found
        let mut base = first_order_with(&[]);
        let c = base.add_param(Param::new("u_offset", 0.1, Bounds::Free));
        base.effects.push(Effect::InputOffset { c });
        assert!(Carried::of(&base, &base).is_none());
        // one effect the diagnosis added beside it is carried alone
        let mut fin = base.clone();
        let r = fin.add_param(Param::new("y_drift", 0.2, Bounds::Free));
        fin.effects.push(Effect::OutputDrift { r });
        let carried = Carried::of(&fin, &base).expect("the drift");
        assert_eq!(carried.name, "output_drift");
        assert_eq!(carried.effects.len(), 1);
        assert_eq!(carried.params.len(), 1);
    }
}
