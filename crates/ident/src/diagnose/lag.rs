//! A first-order lag, or a resonant pair, in place of a kept delay: a part the structure lacks
//! delays the response as a dead time does. Over a band where `w tau` is small a fast pole and a
//! delay differ only at second order (`e^(-s tau) = 1 - s tau + (s tau)^2/2 - ..`,
//! `1/(1 + s T) = 1 - s T + (s T)^2 - ..`), so a delay the diagnosis keeps may stand for a missing
//! pole (a third-order plant fitted as a second order). Both have one parameter: the lag is
//! refitted in the delay's place, from `T = tau`, to the end of its budget, and takes the delay's
//! place unless the delay makes the whole record decisively likelier ([`DECISIVE`]). A mode above
//! the excited band lags the phase as `2 zeta w/w_n` and leaves the magnitude flat, as a delay
//! does and a lag does not (a two-mode plant whose structure holds one mode kept a delay for the
//! other): where the lag does not stand, the resonant pair `1/(a s^2 + b s + 1)` is refitted in
//! the delay's place, from `1/(1 + s tau + (s tau)^2/2)` (the delay's expansion to second order),
//! and takes its place when it makes the record likelier by more than its second parameter's
//! charge ([`mode_charge`]) and predicts the held-out part no worse (a real record's transport
//! delay in a speed loop, `data/unal_dcmotor`'s closed staircase, was taken by a pair that fitted
//! the estimation part closer and held out 8% worse).

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
    lag_in_place(ctx, before, with_delay, tau)
        .or_else(|| mode_in_place(ctx, before, with_delay, tau))
}

/// The lag of [`in_place`].
fn lag_in_place(
    ctx: &Ctx<'_>,
    before: &State,
    with_delay: &State,
    tau: f64,
) -> Option<(State, RejectedEffect)> {
    let (lag, it) = refitted(ctx, before, |m| m.with_lag(tau))?;
    let gap = deviance(ctx, &lag, with_delay);
    if gap > DECISIVE {
        return None;
    }
    let reason = format!(
        "a first-order lag 1/(T s + 1) in its place, T = {:.3e} s, makes the record as likely \
         (deviance 2 ln(L_delay/L_lag) = {gap:.2}, at most {DECISIVE}: {}): a pole the \
         structure lacked, not a dead time",
        lag.values[it],
        against(ctx, &lag, with_delay),
    );
    Some((lag, rejection(tau, reason)))
}

/// `before` with a factor put in series by `put` (returning its parameters' indices), refitted
/// to the end of the refits' budget (no stall test), and those indices.
fn refitted<I>(
    ctx: &Ctx<'_>,
    before: &State,
    put: impl FnOnce(&mut crate::oe::FracModel) -> Option<I>,
) -> Option<(State, I)> {
    let mut start = before.model_at_values();
    let at = put(&mut start)?;
    let mut opts = ctx.opts.fit.clone();
    opts.lm.stall = None;
    Some((ctx.refit_with(start, &opts).ok()?, at))
}

/// The scored and the estimation RMSE of `st` against the delay's, for a rejection's reason.
fn against(ctx: &Ctx<'_>, st: &State, with_delay: &State) -> String {
    format!(
        "{} RMSE {:.4e} against the delay's {:.4e}, estimation RMSE {:.4e} against {:.4e}",
        super::scored_part(st),
        ctx.score(st),
        ctx.score(with_delay),
        st.est.rmse,
        with_delay.est.rmse,
    )
}

/// The delay `tau` rejected for `reason`.
fn rejection(tau: f64, reason: String) -> RejectedEffect {
    RejectedEffect {
        name: "delay".into(),
        reason,
        params: BTreeMap::from([("tau".to_string(), tau)]),
    }
}

/// The charge for the resonant pair's second parameter against the delay's one: `ln n`, the
/// Bayesian information criterion's for one parameter over the record's `n` samples.
fn mode_charge(ctx: &Ctx<'_>) -> f64 {
    (ctx.rec.y.len() as f64).ln()
}

/// The share of the delay `tau` the resonant pair's own lag at low frequencies, `b = 2 zeta/w_n`
/// (its phase `-b w` as `w -> 0`), must reach for the pair to stand for the delay. A pair with
/// far less has dropped the delay's lag rather than carried it: its fit is bought elsewhere, by a
/// sharp peak where the input has no power (an autotune PRBS clocked at 3 ms, a pair at 330 Hz
/// with damping 0.007 at the input's spectral null: `b` under 1% of `tau`; on the benchmark zoo the
/// pairs that stood for a delay had `b` 10% to 107% of it), and whether the delay is needed is the
/// backward step's question, not this one's.
const LAG_SHARE: f64 = 0.05;

/// The resonant pair of [`in_place`]: refitted in the delay's place, and taken when
/// `2 ln(L_mode / L_delay)` exceeds [`mode_charge`], its held-out RMSE is no larger than the
/// delay's, and its lag at low frequencies is at least [`LAG_SHARE`] of the delay's.
fn mode_in_place(
    ctx: &Ctx<'_>,
    before: &State,
    with_delay: &State,
    tau: f64,
) -> Option<(State, RejectedEffect)> {
    let (mode, (ia, ib)) = refitted(ctx, before, |m| m.with_mode(0.5 * tau * tau, tau))?;
    let gain = -deviance(ctx, &mode, with_delay);
    let charge = mode_charge(ctx);
    if !(gain > charge) || ctx.score(&mode) > ctx.score(with_delay) {
        return None;
    }
    let (a, b) = (mode.values[ia], mode.values[ib]);
    if b < LAG_SHARE * tau {
        return None;
    }
    let w_n = a.sqrt().recip();
    let reason = format!(
        "a resonant pair 1/(a s^2 + b s + 1) in its place, w_n = {w_n:.4e} rad/s, damping \
         {:.3}, makes the record likelier (2 ln(L_mode/L_delay) = {gain:.2}, above {charge:.2} \
         for its second parameter: {}): a mode the structure lacked, not a dead time",
        0.5 * b * w_n,
        against(ctx, &mode, with_delay),
    );
    Some((mode, rejection(tau, reason)))
}

/// `2 ln(L_delay / L_other)` over the whole record, the residual taken Gaussian with each model's
/// own variance on each part: `n_est ln(SSR_other / SSR_delay)` on the estimation part, and
/// `2 n_val ln(RMSE_other / RMSE_delay)` on the held-out part (positive: the delay is likelier).
fn deviance(ctx: &Ctx<'_>, other: &State, with_delay: &State) -> f64 {
    let n_est = ctx.estimation_samples() as f64;
    let mut d = n_est * (other.ssr / with_delay.ssr).ln();
    if let (Some(a), Some(b)) = (other.val, with_delay.val) {
        let n_val = (ctx.rec.y.len() as f64 - n_est).max(0.0);
        d += 2.0 * n_val * (a.rmse / b.rmse).ln();
    }
    d
}
