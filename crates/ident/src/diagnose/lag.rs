//! A first-order lag in place of a kept delay: a fast pole the structure lacks delays the
//! response as a dead time does. Over a band where `w tau` is small the two differ only at second
//! order (`e^(-s tau) = 1 - s tau + (s tau)^2/2 - ..`, `1/(1 + s T) = 1 - s T + (s T)^2 - ..`),
//! so a delay the diagnosis keeps may stand for a missing pole (a third-order plant fitted as a
//! second order). Both have one parameter: the lag is refitted in the delay's place, from
//! `T = tau`, to the end of its budget, and takes the delay's place unless the delay makes the
//! whole record decisively likelier ([`DECISIVE`]).

use super::{Ctx, RejectedEffect, State};
use std::collections::BTreeMap;

/// How much likelier the delay must make the whole record than the lag in its place to stand:
/// the deviance `2 ln(L_delay / L_lag)` ([`deviance`]) above 4, a likelihood ratio above `e^2`
/// (about 7), "positive" evidence on Kass and Raftery's scale (1995); below it the record cannot
/// tell a dead time from a pole, and a pole is what a missing part of the structure is.
const DECISIVE: f64 = 4.0;

/// The current model `before` with a lag `1/(T s + 1)` in series, refitted, and the delay's
/// rejection, unless the delay `with_delay` (the round's kept delay refit of `before`) is
/// decisively likelier; `None` then, and for a model that cannot take a lag
/// ([`crate::oe::FracModel::with_lag`]).
pub(super) fn in_place(
    ctx: &Ctx<'_>,
    before: &State,
    with_delay: &State,
) -> Option<(State, RejectedEffect)> {
    if before.model.delay.is_some() {
        return None;
    }
    let tau = with_delay.values[with_delay.model.delay?];
    let mut start = before.model_at_values();
    let it = start.with_lag(tau)?;
    let mut opts = ctx.opts.fit.clone();
    opts.lm.stall = None;
    let lag = ctx.refit_with(start, &opts).ok()?;
    let gap = deviance(ctx, &lag, with_delay);
    if gap > DECISIVE {
        return None;
    }
    let reason = format!(
        "a first-order lag 1/(T s + 1) in its place, T = {:.3e} s, makes the record as likely \
         (deviance 2 ln(L_delay/L_lag) = {gap:.2}, at most {DECISIVE}: {} RMSE {:.4e} against the \
         delay's {:.4e}, estimation RMSE {:.4e} against {:.4e}): a pole the structure lacked, \
         not a dead time",
        lag.values[it],
        super::scored_part(&lag),
        ctx.score(&lag),
        ctx.score(with_delay),
        lag.est.rmse,
        with_delay.est.rmse,
    );
    let rejected = RejectedEffect {
        name: "delay".into(),
        reason,
        params: BTreeMap::from([("tau".to_string(), tau)]),
    };
    Some((lag, rejected))
}

/// `2 ln(L_delay / L_lag)` over the whole record, the residual taken Gaussian with each model's
/// own variance on each part: `n_est ln(SSR_lag / SSR_delay)` on the estimation part, and
/// `2 n_val ln(RMSE_lag / RMSE_delay)` on the held-out part (positive: the delay is likelier).
fn deviance(ctx: &Ctx<'_>, lag: &State, with_delay: &State) -> f64 {
    let n_est = ctx.estimation_samples() as f64;
    let mut d = n_est * (lag.ssr / with_delay.ssr).ln();
    if let (Some(a), Some(b)) = (lag.val, with_delay.val) {
        let n_val = (ctx.rec.y.len() as f64 - n_est).max(0.0);
        d += 2.0 * n_val * (a.rmse / b.rmse).ln();
    }
    d
}
