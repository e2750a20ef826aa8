//! The start of the cell structure `D + Ki/s + K/(a1 s^q + 1)` ([`FracModel::cell`]).
//!
//! `D` from the output's instant response ([`super::feedthrough::instant_response`], the lag-0
//! coefficient of the sampled pulse response; 0 when the record has none). The rest `y - D u`
//! is linear in `K`, `Ki` and the input offset's drift once the polarisation `1/(a1 s^q + 1)`
//! is known: for each trial polarisation (orders [`ORDERS`], time constants `tau` log-spaced
//! from [`TAU_MIN_SAMPLES`] samples to half the scored part, `a1 = tau^q`) it is regressed by
//! least squares on the trial's response to `u`, the integrated input `dt sum u`, time and a
//! constant: the coefficients are `K`, `Ki`, `Ki c` (`c` the input offset) and the output's
//! level. The trial with the least squared error is the start. Scored on the leading
//! [`super::START_SCORE_SAMPLES`] samples.

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

/// One trial's least-squares result: squared error and `[K, Ki, Ki c, level]`.
type Trial = (f64, [f64; 4]);

/// The regression of `rest` on the response `x` of a trial polarisation to `u`, the integrated
/// input `w`, time `t` and a constant (`None` when it is not determined).
fn regress(x: &[f64], w: &[f64], dt: f64, rest: &[f64]) -> Option<Trial> {
    let n = rest.len();
    let a = Mat::<f64>::from_fn(n, 4, |k, j| match j {
        0 => x[k],
        1 => w[k],
        2 => k as f64 * dt,
        _ => 1.0,
    });
    let b = Mat::<f64>::from_fn(n, 1, |k, _| rest[k]);
    let beta = crate::linalg::lstsq(&a, &b);
    let c: [f64; 4] = std::array::from_fn(|j| beta[(j, 0)]);
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    let sse: f64 = (0..n)
        .map(|k| {
            let e = rest[k] - (c[0] * x[k] + c[1] * w[k] + c[2] * k as f64 * dt + c[3]);
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
    let d0 = match model.index_of("D") {
        Some(i) if held("D") => model.params[i].value,
        _ => super::feedthrough::instant_response(u, y).map_or(0.0, |r| r.d),
    };
    let rest: Vec<f64> = y.iter().zip(u).map(|(a, b)| a - d0 * b).collect();
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
            if let Some(t) = regress(&x, &w, dt, &rest) {
                if best.as_ref().is_none_or(|b| t.0 < b.0 .0) {
                    best = Some((t, a1, q));
                }
            }
        }
    }
    let Some(((sse, [k, ki, kic, _level]), a1, q)) = best else {
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
    set("D", d0);
    set("Ki", ki);
    if ki != 0.0 {
        set("u_offset", kic / ki);
    }
    let mut report = StartReport::given(&format!(
        "D = {d0:.4e} from the instant response; K, Ki and the input offset regressed on the \
         best of {} trial polarisations (order {q}, tau {:.3e} s)",
        ORDERS.len() * TAUS,
        a1.powf(1.0 / q)
    ));
    report.fit_percent = Some(super::fit_percent_of(y)(sse));
    Ok(report)
}
