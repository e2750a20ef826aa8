//! The start of the feed-through structure `D + K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`
//! ([`FracModel::feedthrough`]), and the screen that says whether a record shows a feed-through
//! at all ([`instant_response`]).
//!
//! For the input held over each step (`u_k` acts on `[t_k, t_(k+1))`, the sampled-data path of the
//! simulator) the sampled output is `y_k = sum_(j >= 0) h_j u_(k-j)` with `h_0 = D`: a strictly
//! proper plant's output at `t_k` does not yet see `u_k`, so the lag-0 coefficient of the
//! sampled pulse response is the feed-through and nothing else. Differenced,
//! `dy_k = sum_j h_j du_(k-j)`: the constant operating point drops out, and the input's changes are
//! sparse (a PRBS, steps), so a finite pulse response of [`LAGS`] lags explains `dy` up to the
//! pulse response's tail. `h_0` is estimated by least squares (Frisch-Waugh: the lag-0 column
//! after the other lags are regressed out); its standard error uses the residual's variance and
//! its lag-1 autocovariance (differenced white noise is a moving average of order 1).
//!
//! The start: `D = h_0` (or the value given when `D` is held), then the PMSM's start
//! ([`super::auto_start`], whose gain is positive) on `y - D u` and on `D u - y`, the one that
//! fits better kept with its gain's sign (`K < 0` for the second: the dynamic path inverts the
//! instant one); a held `K` keeps its sign.

use super::{auto_start, StartReport};
use crate::lm::Mat;
use crate::oe::FracModel;
use crate::Result;

/// Lags of the finite pulse response after lag 0 (at most a quarter of the record).
pub const LAGS: usize = 32;

/// The screen looks at most at this many leading samples (the estimate's standard error is then
/// far below any feed-through worth a structure; the cost stays bounded, `LAGS^2/2` products a
/// sample).
pub const MAX_SCREEN_SAMPLES: usize = 1 << 15;

/// A record shows a feed-through when the instant response is at least this many standard
/// errors from zero (a false alarm from Gaussian noise has probability about 2e-9)...
pub const MIN_Z: f64 = 6.0;

/// ... and explains at least this fraction of the output's standard deviation
/// (`|D| std(u) / std(y)`): a feed-through too small to matter is not worth a structure.
pub const MIN_SHARE: f64 = 0.01;

/// The structures with a feed-through are fitted when the instant response is at least this many
/// standard errors from zero ([`InstantResponse::may_be_feedthrough`]: a false alarm from Gaussian
/// noise has probability about 3e-3, and costs two structures fitted in vain).
pub const MAYBE_Z: f64 = 3.0;

/// The lag-0 column's part not explained by the next lags' (relative, in norm) below which the
/// instant response is not measured: the input is smooth at the sampling step.
pub const UNMEASURED: f64 = 1e-3;

/// The output's instant response to the input ([`instant_response`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct InstantResponse {
    /// The lag-0 coefficient of the sampled pulse response, `h_0 = D` (output over input units).
    pub d: f64,
    /// Its standard error.
    pub std_error: f64,
    /// `|d| std(u) / std(y)`: the share of the output's standard deviation it explains.
    pub share: f64,
}

impl InstantResponse {
    /// Whether it is a feed-through worth a structure: [`MIN_Z`] standard errors and
    /// [`MIN_SHARE`] of the output.
    pub fn is_feedthrough(&self) -> bool {
        self.d.abs() >= MIN_Z * self.std_error && self.share >= MIN_SHARE
    }

    /// Whether the structures with a feed-through are worth fitting: the instant response at
    /// [`MAYBE_Z`] standard errors (a record with few input changes, a staircase, measures it
    /// coarsely: a cell's ohmic drop at 4.9 standard errors) and [`MIN_SHARE`] of the output.
    pub fn may_be_feedthrough(&self) -> bool {
        self.d.abs() >= MAYBE_Z * self.std_error && self.share >= MIN_SHARE
    }

    /// Whether the record does not measure it: the input is smooth at the sampling step (its
    /// lag-0 change is the next lags', [`UNMEASURED`]), as a multisine or a sweep.
    pub fn unmeasured(&self) -> bool {
        !self.std_error.is_finite()
    }
}

/// The instant response of `y` to `u` (same sampling; deviations or not: the differences remove
/// a constant), estimated on the leading [`MAX_SCREEN_SAMPLES`] samples as the module
/// documentation says. `None` when the input does not change, the record is too short (fewer
/// than `4 (LAGS + 1)` samples) or the regression is singular. An input whose lag-0 change is
/// the next lags' (smooth at the sampling step, as a multisine or a sweep, or periodic within the
/// lags) leaves it unmeasured: `d` 0 with an infinite standard error. It costs one pass of `LAGS^2/2`
/// products per sample, no simulation.
///
/// ```
/// use ident::oe::init::feedthrough::instant_response;
/// // y = 0.5 u + a first-order lag of u: the instant response is 0.5.
/// // A pseudo-random binary input (k^2 mod 1009: no period shorter than the lags).
/// let u: Vec<f64> = (0..2000).map(|k| if (k * k % 1009) < 504 { 1.0 } else { -1.0 }).collect();
/// let mut x = 0.0;
/// let y: Vec<f64> = u.iter().map(|&v| { let y = 0.5 * v + x; x = 0.5 * x + 0.2 * v; y }).collect();
/// let r = instant_response(&u, &y).unwrap();
/// // The pulse response's tail beyond the 32 lags (0.5^32) is all that is left.
/// assert!((r.d - 0.5).abs() < 1e-6 && r.is_feedthrough(), "{r:?}");
/// // Without the feed-through the instant response is nil.
/// let y: Vec<f64> = y.iter().zip(&u).map(|(a, b)| a - 0.5 * b).collect();
/// assert!(!instant_response(&u, &y).unwrap().is_feedthrough());
/// ```
pub fn instant_response(u: &[f64], y: &[f64]) -> Option<InstantResponse> {
    let n = u.len().min(y.len()).min(MAX_SCREEN_SAMPLES);
    if n < 4 * (LAGS + 1) {
        return None;
    }
    let du: Vec<f64> = u[..n].windows(2).map(|w| w[1] - w[0]).collect();
    let dy: Vec<f64> = y[..n].windows(2).map(|w| w[1] - w[0]).collect();
    if du.iter().all(|&v| v == 0.0) {
        return None;
    }
    // Rows k = LAGS..du.len(): dy_k against du_k (x0) and du_(k-1..k-LAGS) (z_1..z_LAGS).
    let rows = LAGS..du.len();
    let m = rows.len();
    let lag = |j: usize| &du[LAGS - j..du.len() - j];
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let yv = &dy[LAGS..];
    let x0 = lag(0);
    let mut g = Mat::<f64>::zeros(LAGS, LAGS);
    let mut rhs = Mat::<f64>::zeros(LAGS, 2);
    for i in 0..LAGS {
        for j in 0..=i {
            let v = dot(lag(i + 1), lag(j + 1));
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
        rhs[(i, 0)] = dot(lag(i + 1), x0);
        rhs[(i, 1)] = dot(lag(i + 1), yv);
    }
    // A lag column that is all zero (a step near the record's start) gets a zero coefficient.
    let scale = (0..LAGS).map(|i| g[(i, i)]).fold(0.0, f64::max).max(1e-300);
    for i in 0..LAGS {
        g[(i, i)] += 1e-12 * scale;
    }
    let c = crate::linalg::cholesky_solve_cols(&g, &rhs)?;
    // The lag-0 column and the output with the other lags regressed out.
    let mut r0 = x0.to_vec();
    let mut ry = yv.to_vec();
    for i in 0..LAGS {
        let (cx, cy, z) = (c[(i, 0)], c[(i, 1)], lag(i + 1));
        for k in 0..m {
            r0[k] -= cx * z[k];
            ry[k] -= cy * z[k];
        }
    }
    let rr = dot(&r0, &r0);
    if !(rr > UNMEASURED * UNMEASURED * dot(x0, x0)) {
        // The lag-0 change is the next lags' (an input smooth at the sampling step): the
        // instant response is not measured.
        return Some(InstantResponse {
            d: 0.0,
            std_error: f64::INFINITY,
            share: 0.0,
        });
    }
    let d = dot(&r0, &ry) / rr;
    let e: Vec<f64> = ry.iter().zip(&r0).map(|(a, b)| a - d * b).collect();
    let dof = m.saturating_sub(LAGS + 1).max(1) as f64;
    let s0 = dot(&e, &e) / dof;
    let s1 = dot(&e[1..], &e[..m - 1]) / dof;
    // d = sum w_k dy_k with w = r0/rr: its variance under noise of autocovariances s0, s1.
    let w2 = rr / (rr * rr);
    let w11 = dot(&r0[1..], &r0[..m - 1]) / (rr * rr);
    let var = s0 * w2 + 2.0 * s1 * w11;
    let var = if var > 0.0 { var } else { s0 * w2 };
    let sd = |x: &[f64]| {
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        (x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let share = d.abs() * sd(&u[..n]) / sd(&y[..n]).max(f64::MIN_POSITIVE);
    (d.is_finite() && var.is_finite()).then_some(InstantResponse {
        d,
        std_error: var.sqrt(),
        share,
    })
}

/// The start of a [`crate::oe::Kind::Feedthrough`] model on deviations `u`, `y` (step `dt`): see the module
/// documentation. The report's fit is the whole model's (feed-through included).
///
/// # Errors
/// As [`super::auto_start`].
pub(super) fn start(
    model: &mut FracModel,
    u: &[f64],
    y: &[f64],
    dt: f64,
    par: crate::par::Par,
) -> Result<StartReport> {
    let id = model.index_of("D");
    let given = id.filter(|&i| !model.params[i].free);
    let found = instant_response(u, y);
    let (d0, how) = match (given, found) {
        (Some(i), _) => (model.params[i].value, "held at the given value".to_string()),
        (None, Some(r)) if r.std_error.is_infinite() => (
            0.0,
            "0: the input is too smooth at the sampling step to measure the instant response"
                .to_string(),
        ),
        (None, Some(r)) => (
            r.d,
            format!(
                "from the instant response (lag-0 step of y over u, {:.1} standard errors)",
                r.d / r.std_error.max(f64::MIN_POSITIVE)
            ),
        ),
        (None, None) => (0.0, "0: no input change to measure it on".to_string()),
    };
    let v = model.values();
    // The dynamic part's start for each sign of K (a held K: its own), the better kept.
    let signs: &[f64] = match model.params[0].free {
        true => &[1.0, -1.0],
        false if v[0] < 0.0 => &[-1.0],
        false => &[1.0],
    };
    let mut best: Option<(FracModel, StartReport, f64)> = None;
    for &sign in signs {
        let mut inner = FracModel::pmsm(sign * v[0], v[1], v[2], v[3], v[4]);
        inner.approx = model.approx;
        for (p, q) in inner.params.iter_mut().zip(&model.params) {
            p.free = q.free;
        }
        let rest: Vec<f64> = y.iter().zip(u).map(|(a, b)| sign * (a - d0 * b)).collect();
        let report = auto_start(&mut inner, u, &rest, dt, par)?;
        let fit = report.fit_percent.unwrap_or(f64::NEG_INFINITY);
        if best.as_ref().is_none_or(|b| fit > b.2) {
            best = Some((inner, report, sign));
        }
    }
    let Some((inner, mut report, sign)) = best else {
        return Ok(StartReport::given("no sign of K to start from"));
    };
    for (p, q) in model.params.iter_mut().zip(&inner.params) {
        p.value = q.value;
        // A gain the inner start freed (a negative one from the coarse search) stays free; the
        // feed-through's own ranges are never narrowed (its K is free in sign already).
        if matches!(q.bounds, crate::oe::Bounds::Free) {
            p.bounds = q.bounds;
        }
    }
    model.params[0].value *= sign;
    if let Some(i) = id {
        model.params[i].value = d0;
    }
    // The whole model's fit on the part the starts are scored on.
    let scored = u.len().min(y.len()).min(super::START_SCORE_SAMPLES);
    let mut lin = model.clone();
    lin.effects.clear();
    let mut buf = vec![0.0; scored];
    if let (Some(sse), Some(_)) = (
        super::sse_of(
            &lin,
            &lin.values(),
            &u[..scored],
            &y[..scored],
            dt,
            0,
            &mut buf,
        ),
        report.fit_percent,
    ) {
        report.fit_percent = Some(super::fit_percent_of(&y[..scored])(sse));
    }
    let rest = if sign < 0.0 {
        "D u - y (K < 0)"
    } else {
        "y - D u"
    };
    report.note = format!("D = {d0:.4e} {how}; the rest, {rest}: {}", report.note);
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::instant_response;
    use crate::testdata::{first_order_held, lcg};

    /// `y = D u + x` with `x` a first-order lag of `u` (pole 0.9 a sample, unit gain, from rest)
    /// and no noise.
    fn through(u: &[f64], d: f64) -> Vec<f64> {
        let lag = first_order_held(u, 1.0, -1.0 / 0.9_f64.ln(), 1.0);
        lag.iter().zip(u).map(|(x, v)| d * v + x).collect()
    }

    /// A multisine whose fastest line has 200 samples a period: its lag-0 change is the next
    /// lags' to 1e-5, so the instant response is not measured (a regression that far from
    /// determined gave `D = -157 +- 32` on the zoo's cell 0234 of seed 46, whose `D` is 0.072),
    /// with or without a feed-through; a pseudo-random binary input measures it where there is
    /// one, and rules it out where there is none.
    #[test]
    fn a_smooth_input_leaves_the_instant_response_unmeasured() {
        let n = 4000;
        let smooth: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / 200.0;
                (2.0 * std::f64::consts::PI * t).sin()
                    + 0.5 * (0.6 * std::f64::consts::PI * t).cos()
            })
            .collect();
        for d in [0.0, 0.5] {
            let r = instant_response(&smooth, &through(&smooth, d)).unwrap();
            assert!(r.std_error.is_infinite() && r.d == 0.0, "{d}: {r:?}");
            assert!(!r.may_be_feedthrough() && !r.is_feedthrough(), "{d}: {r:?}");
        }
        let prbs: Vec<f64> = (0..n)
            .map(|k| if (k * k % 1009) < 504 { 1.0 } else { -1.0 })
            .collect();
        // A little noise, so that the standard error is finite.
        let mut next = lcg(12345);
        let y: Vec<f64> = through(&prbs, 0.0)
            .into_iter()
            .map(|v| v + 1e-3 * ((next() >> 11) as f64 / (1u64 << 53) as f64 - 0.5))
            .collect();
        let r = instant_response(&prbs, &y).unwrap();
        assert!(r.std_error.is_finite() && !r.may_be_feedthrough(), "{r:?}");
        let y: Vec<f64> = y.iter().zip(&prbs).map(|(a, b)| a + 0.5 * b).collect();
        let r = instant_response(&prbs, &y).unwrap();
        assert!(r.is_feedthrough() && r.may_be_feedthrough(), "{r:?}");
    }
}
