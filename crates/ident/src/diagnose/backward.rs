//! The backward step: an effect kept in an earlier round is checked again once a later round
//! keeps another (stepwise regression's backward elimination, Efroymson 1960). Effects are added
//! one per round, strongest first, so an early one can stand in for one tried later: a power law
//! fitted to a dead band's input levels before the dead band was refitted. Each earlier effect
//! must still pay over the current model refitted without it (held-out RMSE and BIC, the rules it
//! was kept by); the one whose removal costs least is dropped while one does not, and its
//! rejection says which later effect it stood in for.

use super::{Ctx, KeptEffect, RejectedEffect, Rounds, State, Verdict};
use crate::oe::{Effect, FracModel};

impl Rounds<'_> {
    /// Drop the earlier kept effects that no longer pay over the current model (module
    /// documentation); the round's point of the path is the model left.
    pub(super) fn backward(&mut self) {
        while self.found.kept.len() > 1 {
            let newest = self.found.kept.len() - 1;
            let mut drop: Option<(usize, State, Verdict)> = None;
            for j in 0..newest {
                let Some(without) = refit_without(&self.ctx, &self.found.st, &self.found.kept[j])
                else {
                    continue;
                };
                let v = Verdict::of(&self.ctx, &without, &self.found.st);
                let cheaper = drop
                    .as_ref()
                    .is_none_or(|(_, b, _)| self.ctx.score(&without) < self.ctx.score(b));
                if !v.pays(&self.ctx) && cheaper {
                    drop = Some((j, without, v));
                }
            }
            let Some((j, without, v)) = drop else {
                return;
            };
            let k = self.found.kept.remove(j);
            let reason = format!(
                "kept in an earlier round, but once {} was kept the model refitted without it \
                 reaches {:.4e} against {:.4e} with it ({:+.1}%, BIC {:+.1}), short of the \
                 {:.0}% margin; it stood in for an effect found later",
                self.found.kept[newest - 1].name,
                v.before,
                v.after,
                100.0 * v.change,
                v.dbic,
                100.0 * self.ctx.opts.margin,
            );
            self.found.rejected.insert(
                k.name.clone(),
                RejectedEffect {
                    name: k.name,
                    reason,
                    params: k.params,
                },
            );
            self.found.st = without;
            if let Some(last) = self.found.path.last_mut() {
                *last = self.ctx.step(&self.found.st);
            }
        }
    }
}

/// The current model `st` without kept effect `k`, refitted from `st`'s values; `None` when the
/// effect is not one of the model's effects alone (a delay, the initial state, a sign-blind
/// sensor and its zero) or the refit fails.
fn refit_without(ctx: &Ctx<'_>, st: &State, k: &KeptEffect) -> Option<State> {
    let e = model_effect(&st.model, k)?;
    let (mut model, kept) = st.model.without_effect(e);
    for (p, &o) in model.params.iter_mut().zip(&kept) {
        p.value = p.bounds.clamp_inside(st.values[o]);
    }
    ctx.fit_from(model, &ctx.opts.fit).ok()
}

/// The index in `m.effects` of kept effect `k`: the one effect of its name (a periodic one: the
/// sinusoid at its frequency).
fn model_effect(m: &FracModel, k: &KeptEffect) -> Option<usize> {
    let freq = k.params.get("freq_hz");
    let mut found = m.effects.iter().enumerate().filter(|(_, e)| match e {
        Effect::Sinusoid { freq_hz, .. } => freq == Some(freq_hz),
        e => e.name() == k.name && k.name != "abs_sensor",
    });
    let first = found.next().map(|(i, _)| i);
    first.filter(|_| found.next().is_none())
}
