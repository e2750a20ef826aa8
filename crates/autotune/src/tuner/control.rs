//! The controller: the crossover chosen from the final model (its bandwidth, its delay, the
//! sample rate, a resonance), the tuner's FOPI at it (a lower crossover when the tuner refuses),
//! and the step run on the drive beside the tuner's prediction.

use super::rounds::Model;
use crate::realise::{self, Realisation};
use crate::Result;
use fracsim::FracTf;
use num_complex::Complex64;
use serde::Serialize;
use tune::closed::InputEffect;
use tune::report::{Report, Runs, SimOptions};
use tune::{Form, Spec};

/// A lightly damped resonance of a model: the peak of `|G(j omega)|` over its surroundings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Resonance {
    /// Its frequency, Hz.
    pub freq_hz: f64,
    /// Its damping, from the half-power width of the peak.
    pub damping: f64,
    /// The peak over the lowest gain between half its frequency and it.
    pub prominence: f64,
}

/// `|G(j omega)|` of `g` on a log grid of `per_decade` points from `w0` to `w1` rad/s.
fn gain_grid(g: &FracTf, w0: f64, w1: f64, per_decade: usize) -> Vec<(f64, f64)> {
    let n = ((w1 / w0).log10() * per_decade as f64).ceil() as usize;
    (0..=n)
        .map(|i| {
            let w = w0 * 10f64.powf(i as f64 / per_decade as f64);
            (w, g.freq_response(w).norm())
        })
        .collect()
}

/// The most prominent resonance of `g` below `w_max` rad/s (a peak at least 1.5 times the lowest
/// gain between half its frequency and it), if any.
pub fn resonance(g: &FracTf, w_max: f64) -> Option<Resonance> {
    let grid = gain_grid(g, 1.0, w_max, 400);
    let mut best: Option<Resonance> = None;
    for k in 1..grid.len().saturating_sub(1) {
        let (w, a) = grid[k];
        if !(a > grid[k - 1].1 && a >= grid[k + 1].1) {
            continue;
        }
        let low = grid
            .iter()
            .filter(|(x, _)| *x >= 0.5 * w && *x < w)
            .map(|p| p.1)
            .fold(f64::INFINITY, f64::min);
        let prominence = a / low;
        if !(prominence >= 1.5) {
            continue;
        }
        // the half-power width about the peak
        let half = a / std::f64::consts::SQRT_2;
        let lo = grid[..k].iter().rev().find(|p| p.1 < half).map(|p| p.0);
        let hi = grid[k..].iter().find(|p| p.1 < half).map(|p| p.0);
        let damping = match (lo, hi) {
            (Some(l), Some(h)) => (h - l) / (2.0 * w),
            _ => 0.5 / prominence,
        };
        let r = Resonance {
            freq_hz: w / (2.0 * std::f64::consts::PI),
            damping,
            prominence,
        };
        if best.is_none_or(|b| b.prominence < prominence) {
            best = Some(r);
        }
    }
    best
}

/// The frequency (rad/s) where `|G|` first falls below `|G(0)|/sqrt 2`, searched up to `w_max`.
pub fn bandwidth(g: &FracTf, w_max: f64) -> Option<f64> {
    let g0 = g.freq_response(1e-3).norm();
    gain_grid(g, 1e-2, w_max, 100)
        .into_iter()
        .find(|(_, a)| *a < g0 / std::f64::consts::SQRT_2)
        .map(|p| p.0)
}

/// The crossover chosen and why.
#[derive(Debug, Clone, Serialize)]
pub struct Crossover {
    /// rad/s.
    pub wc: f64,
    /// Phase margin, deg.
    pub pm_deg: f64,
    /// What set it.
    pub reasons: Vec<String>,
}

/// The crossover from the model: its bandwidth, at most a third of `0.35 rad` over the delay
/// (the delay's lag at the crossover at most 20 deg), a tenth of the sample rate in rad/s, and a
/// fifth of a resonance's frequency (a lower crossover rather than a notch: the loop then stays
/// below the resonance, whose peak the tuner's floors check).
pub fn crossover(
    g: &FracTf,
    res: Option<&Resonance>,
    fs: f64,
    wc: Option<f64>,
    pm: Option<f64>,
) -> Crossover {
    let pm_deg = pm.unwrap_or(60.0);
    if let Some(wc) = wc {
        return Crossover {
            wc,
            pm_deg,
            reasons: vec!["as asked (--wc)".into()],
        };
    }
    let nyq = std::f64::consts::PI * fs;
    let wb = bandwidth(g, nyq).unwrap_or(nyq / 10.0);
    let mut wc = wb;
    let mut reasons = vec![format!("the model's bandwidth {wb:.1} rad/s")];
    let mut cap = |w: f64, why: String| {
        if w < wc {
            wc = w;
            reasons.push(why);
        }
    };
    cap(
        fs / 10.0,
        format!("a tenth of the sample rate, {:.1} rad/s", fs / 10.0),
    );
    let delay = g.delay + 1.0 / fs;
    cap(
        0.35 / delay,
        format!(
            "the delay with a sample ({:.2} ms) allows {:.1} rad/s (20 deg of lag)",
            1e3 * delay,
            0.35 / delay
        ),
    );
    if let Some(r) = res {
        let w = 2.0 * std::f64::consts::PI * r.freq_hz / 5.0;
        cap(
            w,
            format!(
                "the resonance at {:.1} Hz (damping {:.3}): the crossover a fifth of it, {w:.1} \
                 rad/s, the loop's gain falling well before it",
                r.freq_hz, r.damping
            ),
        );
    }
    Crossover {
        wc,
        pm_deg,
        reasons,
    }
}

/// The tuner's design at the crossover, or at 0.7 times it each time the tuner refuses (at most
/// six times): the report, the runs, the crossover used and the refusals.
///
/// # Errors
/// None of the crossovers gives a design (the last refusal's message is in [`crate::Error`]).
pub fn design(
    model: &Model,
    g: &FracTf,
    xo: &Crossover,
    dt: f64,
    step: f64,
    u_limit: f64,
) -> Result<(Report, Runs, f64, Vec<String>)> {
    let mut effects = vec![];
    if let Some(vc) = model.param("Vc") {
        effects.push(InputEffect::CoulombFriction { vc });
    }
    if let Some(u_offset) = model.param("u_offset") {
        effects.push(InputEffect::InputOffset { u_offset });
    }
    let opts = SimOptions {
        step: Some(step),
        u_limit: Some(u_limit),
        effects,
        ..SimOptions::default()
    };
    let mut refusals = vec![];
    let mut wc = xo.wc;
    for _ in 0..7 {
        let spec = Spec {
            form: Form::Fopi,
            wc,
            pm_deg: xo.pm_deg,
            flat: false,
            t_high: None,
            s_low: None,
            dt: Some(dt),
            lambda: None,
            floors: tune::Floors::default(),
            orders: tune::Orders::default(),
        };
        match tune::report::tune(g, &spec, &opts) {
            Ok((r, runs)) if r.discrete.is_some() => return Ok((r, runs, wc, refusals)),
            Ok(_) => refusals.push(format!("wc {wc:.1} rad/s: no discrete realisation")),
            Err(e @ (tune::Error::Infeasible(_) | tune::Error::Unsafe(_))) => {
                refusals.push(format!("wc {wc:.1} rad/s: {e}"))
            }
            Err(e) => return Err(e.into()),
        }
        if xo
            .reasons
            .first()
            .is_some_and(|r| r.starts_with("as asked"))
        {
            break;
        }
        wc *= 0.7;
    }
    Err(crate::Error::Experiment(format!(
        "the tuner refused every crossover tried: {}",
        refusals.join("; ")
    )))
}

/// The drive's controller of a design: pruned, in fixed point, with its deviation from the
/// realisation.
///
/// # Errors
/// A realisation the drive cannot run.
pub fn fixed(
    report: &Report,
    conf: &drive::protocol::Configure,
) -> Result<(drive::ctrl::FixedCtrl, f64, usize)> {
    let disc = report
        .discrete
        .as_ref()
        .ok_or_else(|| crate::Error::Experiment("no discrete realisation".into()))?;
    let real = Realisation::of_discrete(disc, &report.controller.text);
    let (pruned, dropped) = realise::prune(&real);
    let k = realise::fixed_controller(&pruned, conf)?;
    let qerr = realise::quantisation_error(&real, &k, conf);
    Ok((k, qerr, dropped.len()))
}

/// The relative error of `model`'s frequency response against `truth`'s, the largest over a log
/// grid from `w0` to `w1` rad/s (delays included).
pub fn frf_error(model: &FracTf, truth: &FracTf, w0: f64, w1: f64) -> f64 {
    gain_grid(truth, w0, w1, 100)
        .into_iter()
        .map(|(w, _)| {
            let (m, t): (Complex64, Complex64) = (model.freq_response(w), truth.freq_response(w));
            (m - t).norm() / t.norm()
        })
        .fold(0.0, f64::max)
}
