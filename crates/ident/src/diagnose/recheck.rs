//! The kept effects checked again once the later ones are in (docs/design.md §6): an effect is
//! kept when it pays over the model of its round, but a later effect can take up what it
//! explained (a drift kept first stands in for part of a friction found in the next round). Each
//! effect kept before the last round is refitted out of the final model (the model without its
//! parameters, refitted from the final values): when the final model does not clear the margin
//! and BIC over that refit, as any effect is judged, the effect is no longer credited and the
//! refit without it becomes the final model. A delay, a time-stamp skew and the initial state
//! are no effects of the model's list and are not checked so.

use super::{Ctx, KeptEffect, RejectedEffect, State, Verdict};
use crate::oe::{Effect, Expr, FracModel};

/// The effects of `st` that `base` does not have and that are named `name` (an effect's
/// parameters are appended, so the base model's effects are unchanged in the final model).
fn added_effects(base: &FracModel, st: &FracModel, name: &str) -> Vec<usize> {
    (0..st.effects.len())
        .filter(|&i| st.effects[i].name() == name && !base.effects.contains(&st.effects[i]))
        .collect()
}

/// `e` with each parameter index mapped by `f`.
fn reindexed(e: &Effect, f: &dyn Fn(usize) -> usize) -> Effect {
    match *e {
        Effect::InputOffset { c } => Effect::InputOffset { c: f(c) },
        Effect::SensorZero { c } => Effect::SensorZero { c: f(c) },
        Effect::OutputOffset { c } => Effect::OutputOffset { c: f(c) },
        Effect::Coulomb { vc } => Effect::Coulomb { vc: f(vc) },
        Effect::Saturation { level } => Effect::Saturation { level: f(level) },
        Effect::Deadzone { width } => Effect::Deadzone { width: f(width) },
        Effect::PowerLaw { p, u_ref } => Effect::PowerLaw { p: f(p), u_ref },
        Effect::AbsSensor => Effect::AbsSensor,
        Effect::OutputDrift { r } => Effect::OutputDrift { r: f(r) },
        Effect::Sinusoid { freq_hz, a, b } => Effect::Sinusoid {
            freq_hz,
            a: f(a),
            b: f(b),
        },
    }
}

/// `model` at `values` without its effects `which` (indices into its effects) and their
/// parameters, every other parameter index moved down past the removed ones.
pub(crate) fn without_effects(
    model: &FracModel,
    values: &[f64],
    which: &[usize],
) -> (FracModel, Vec<f64>) {
    let mut gone: Vec<usize> = which
        .iter()
        .flat_map(|&i| model.effects[i].params())
        .collect();
    gone.sort_unstable();
    gone.dedup();
    let f = |i: usize| i - gone.iter().filter(|&&g| g < i).count();
    let expr = |e: &Expr| Expr {
        constant: e.constant,
        terms: e.terms.iter().map(|&(i, c)| (f(i), c)).collect(),
        factors: e.factors.iter().map(|&i| f(i)).collect(),
    };
    let terms = |t: &[(Expr, Expr)]| -> Vec<(Expr, Expr)> {
        t.iter().map(|(a, b)| (expr(a), expr(b))).collect()
    };
    let mut m = model.clone();
    m.num = terms(&model.num);
    m.den = terms(&model.den);
    m.series = model
        .series
        .iter()
        .map(|(n, d)| (terms(n), terms(d)))
        .collect();
    m.delay = model.delay.map(f);
    if let Some(p) = m.past.as_mut() {
        p.levels = p.levels.iter().map(|&i| f(i)).collect();
    }
    m.effects = (0..model.effects.len())
        .filter(|i| !which.contains(i))
        .map(|i| reindexed(&model.effects[i], &f))
        .collect();
    let keep = |i: &usize| !gone.contains(i);
    m.params = (0..model.params.len())
        .filter(keep)
        .map(|i| {
            let mut p = model.params[i].clone();
            p.value = values[i];
            p
        })
        .collect();
    let v = (0..values.len()).filter(keep).map(|i| values[i]).collect();
    (m, v)
}

/// The check of the module documentation on the final state `st` of a diagnosis from `base`
/// with `kept` effects: the effects no longer credited move from `kept` to the returned
/// rejections, and `st` becomes the refit without them.
pub(super) fn recheck(
    ctx: &Ctx<'_>,
    base: &State,
    st: &mut State,
    kept: &mut Vec<KeptEffect>,
) -> Vec<RejectedEffect> {
    let mut dropped = vec![];
    let mut k = 0;
    while k + 1 < kept.len() {
        let name = kept[k].name.clone();
        let which = added_effects(&base.model, &st.model, &name);
        let unique = kept.iter().filter(|e| e.name == name).count() == 1;
        if which.is_empty() || !unique {
            k += 1;
            continue;
        }
        let (m, _) = without_effects(&st.model, &st.values, &which);
        let Ok(null) = ctx.fit_from(m, &ctx.opts.fit) else {
            k += 1;
            continue;
        };
        let own = Verdict::of(ctx, &null, st);
        if own.pays(ctx) {
            k += 1;
            continue;
        }
        let round = k + 1 + dropped.len();
        let e = kept.remove(k);
        let later: Vec<&str> = kept[k..].iter().map(|e| e.name.as_str()).collect();
        let part = super::scored_part(st);
        dropped.push(RejectedEffect {
            name: e.name.clone(),
            reason: format!(
                "kept in round {} ({part} RMSE {:+.1}%), but once {} {} added the final model \
                 refitted without it reaches {:.4e} against {:.4e}: it adds {:+.1}% (BIC {:+.1}), \
                 short of the {:.0}% margin (evidence: {})",
                round,
                e.rmse_change_percent,
                later.join(", "),
                if later.len() == 1 { "was" } else { "were" },
                ctx.score(&null),
                ctx.score(st),
                100.0 * own.change,
                own.dbic,
                100.0 * ctx.opts.margin,
                e.evidence
            ),
            params: e.params,
        });
        *st = null;
    }
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::{Bounds, Param, Structure};

    /// Removing an effect in the middle of the parameters moves every later index down: the
    /// model without it simulates as the model with it at its neutral value (a drift of 0), and
    /// the other effects keep their parameters.
    #[test]
    fn an_effect_removed_leaves_the_rest_of_the_model_as_it_was() {
        let mut m = FracModel::pmsm(6.8, 0.0064, 2.8e-5, 0.89, 0.89);
        m.with_delay(1e-3, 1e-2);
        m.with_past_input(vec![0.01, 0.05], (-3.0, 3.0));
        let r = m.add_param(Param::new("y_drift", 0.0, Bounds::Free));
        m.effects.push(Effect::OutputDrift { r });
        let vc = m.add_param(Param::new("Vc", 0.2, Bounds::Positive));
        m.effects.insert(0, Effect::Coulomb { vc });
        m.with_output_offset(0.3);
        let mut v = m.values();
        for (i, level) in m.past.as_ref().unwrap().levels.iter().zip([0.4, -0.2, 0.1]) {
            v[*i] = level;
        }
        let drift = (0..m.effects.len())
            .filter(|&i| m.effects[i].name() == "output_drift")
            .collect::<Vec<_>>();
        let (w, wv) = without_effects(&m, &v, &drift);
        assert_eq!(w.params.len(), m.params.len() - 1);
        assert!(w.params.iter().all(|p| p.name != "y_drift"));
        assert!(w.effects.iter().all(|e| e.name() != "output_drift"));
        let dt = 5e-4;
        let u: Vec<f64> = (0..3000)
            .map(|k| if (k / 97) % 3 == 0 { 1.3 } else { -0.4 })
            .collect();
        let (mut a, mut b) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        m.simulate(&v, &u, dt, &mut a).unwrap();
        w.simulate(&wv, &u, dt, &mut b).unwrap();
        assert_eq!(a, b);
    }
}
