//! The start of the cell structure `D + Ki/s + K/(a1 s^q + 1)` ([`FracModel::cell`]).
//!
//! For each trial polarisation `1/(a1 s^q + 1)` (orders [`ORDERS`], time constants `tau`
//! log-spaced from [`TAU_MIN_SAMPLES`] samples to half the scored part, `a1 = tau^q`) the output
//! is linear in the rest: it is regressed by least squares on the trial's response to `u`, the
//! integrated input `dt sum u`, time, a constant and the input itself: the coefficients are `K`,
//! `Ki`, `Ki c` (`c` the input offset), the output's level and `D`. When `D` is held, or the record
//! shows its instant response ([`super::feedthrough::InstantResponse::is_feedthrough`]: the
//! lag-0 coefficient of the sampled pulse response), `y - D u` is regressed without the input
//! instead (an input smooth at the sampling step, a multisine or a sweep, leaves the instant
//! response unmeasured). The trial with the least squared error is the start. Scored on the
//! leading [`super::START_SCORE_SAMPLES`] samples.

use super::StartReport;
use crate::lm::Mat;
use crate::oe::{FracModel, Structure};
use crate::Result;

/// The trial orders of the polarisation.
pub const ORDERS: [f64; 3] = [0.5, 0.7, 0.9];

/// Trial time constants per order, log-spaced.
pub const TAUS: usize = 8;

/// The shortest trial time constant, in samples.
pub const TAU_MIN_SAMPLES: f64 = 3.0;

/// One trial's least-squares result: squared error and `[K, Ki, Ki c, level, D]` (`D` 0 when it
/// is not regressed).
type Trial = (f64, [f64; 5]);

/// The regression of `rest` on the response `x` of a trial polarisation to `u`, the integrated
/// input `w`, time `t`, a constant and, when given, the input itself (the feed-through `D`)
/// (`None` when it is not determined).
fn regress(x: &[f64], w: &[f64], dt: f64, rest: &[f64], u: Option<&[f64]>) -> Option<Trial> {
    let n = rest.len();
    let cols = if u.is_some() { 5 } else { 4 };
    let column = |k: usize, j: usize| match j {
        0 => x[k],
        1 => w[k],
        2 => k as f64 * dt,
        3 => 1.0,
        _ => u.map_or(0.0, |u| u[k]),
    };
    let a = Mat::<f64>::from_fn(n, cols, column);
    let b = Mat::<f64>::from_fn(n, 1, |k, _| rest[k]);
    let beta = crate::linalg::lstsq(&a, &b);
    let c: [f64; 5] = std::array::from_fn(|j| if j < cols { beta[(j, 0)] } else { 0.0 });
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    let sse: f64 = (0..n)
        .map(|k| {
            let e = rest[k] - (0..cols).map(|j| c[j] * column(k, j)).sum::<f64>();
            e * e
        })
        .sum();
    sse.is_finite().then_some((sse, c))
}

/// The start of a [`crate::oe::Kind::Cell`] model on `u`, `y` (the input as recorded, the output
/// a deviation; step `dt`): see the module documentation. Values the user held keep theirs.
///
/// # Errors
/// None today; the signature is [`super::auto_start`]'s.
pub(super) fn start(model: &mut FracModel, u: &[f64], y: &[f64], dt: f64) -> Result<StartReport> {
    let n = u.len().min(y.len()).min(super::START_SCORE_SAMPLES);
    let (u, y) = (&u[..n], &y[..n]);
    let held = |name: &str| model.index_of(name).is_some_and(|i| !model.params[i].free);
    let (d_given, d_how) = match model.index_of("D") {
        Some(i) if held("D") => (Some(model.params[i].value), " (held)"),
        _ => match super::feedthrough::instant_response(u, y).filter(|r| r.is_feedthrough()) {
            Some(r) => (Some(r.d), " from the instant response"),
            None => (None, ""),
        },
    };
    let rest: Vec<f64> = y
        .iter()
        .zip(u)
        .map(|(a, b)| a - d_given.unwrap_or(0.0) * b)
        .collect();
    let regressed_u = d_given.is_none().then_some(u);
    let mut w = Vec::with_capacity(n);
    let mut acc = 0.0;
    for &v in u {
        w.push(acc);
        acc += v * dt;
    }
    let span = n as f64 * dt;
    let tau_min = TAU_MIN_SAMPLES * dt;
    let tau_max = (0.5 * span).max(2.0 * tau_min);
    let mut best: Option<(Trial, f64, f64)> = None;
    let mut x = vec![0.0; n];
    for &q in &ORDERS {
        for i in 0..TAUS {
            let tau = tau_min * (tau_max / tau_min).powf(i as f64 / (TAUS - 1) as f64);
            let a1 = tau.powf(q);
            let trial = FracModel::commensurate(1.0, a1, 0.0, q);
            let Ok(()) = trial.simulate(&[1.0, a1, 0.0, q], u, dt, &mut x) else {
                continue;
            };
            if let Some(t) = regress(&x, &w, dt, &rest, regressed_u) {
                if best.as_ref().is_none_or(|b| t.0 < b.0 .0) {
                    best = Some((t, a1, q));
                }
            }
        }
    }
    let Some(((sse, [k, ki, kic, _level, d]), a1, q)) = best else {
        return Ok(StartReport::given(
            "the given values (no trial polarisation simulated)",
        ));
    };
    let mut set = |name: &str, v: f64| {
        if let Some(i) = model.index_of(name) {
            if model.params[i].free && v.is_finite() {
                model.params[i].value = v;
            }
        }
    };
    set("K", k);
    set("a1", a1);
    set("q", q);
    let d0 = d_given.unwrap_or(d);
    set("D", d0);
    set("Ki", ki);
    if ki != 0.0 {
        set("u_offset", kic / ki);
    }
    let mut report = StartReport::given(&format!(
        "D = {d0:.4e}{}, K, Ki and the input offset regressed on the best of {} trial \
         polarisations (order {q}, tau {:.3e} s)",
        d_how,
        ORDERS.len() * TAUS,
        a1.powf(1.0 / q)
    ));
    report.fit_percent = Some(super::fit_percent_of(y)(sse));
    Ok(report)
}
