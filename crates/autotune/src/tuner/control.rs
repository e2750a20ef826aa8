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
use tune::filter::Filter;
use tune::report::{Report, Runs, SimOptions};
use tune::{Form, Spec};

/// The poles' damping of the notch (real poles at half and twice its frequency): the narrowest
/// notch of real poles whose two sections stay apart.
pub const NOTCH_POLE_DAMPING: f64 = 1.25;

/// The filter `choice` puts in the controller for the resonance `r`: a notch at it whose zeros
/// have its damping (they cancel its poles), or a low-pass at half its frequency.
pub fn filter_for(r: &Resonance, choice: super::FilterChoice) -> Option<Filter> {
    let w = 2.0 * std::f64::consts::PI * r.freq_hz;
    match choice {
        super::FilterChoice::Auto | super::FilterChoice::Notch => Some(Filter::Notch {
            omega: w,
            zeta_z: r.damping.clamp(0.0, 0.5),
            zeta_p: NOTCH_POLE_DAMPING,
        }),
        super::FilterChoice::LowPass => Some(Filter::LowPass { omega: 0.5 * w }),
        super::FilterChoice::None => None,
    }
}

/// A filter in words.
pub fn filter_text(f: &Filter) -> String {
    match *f {
        Filter::Notch {
            omega,
            zeta_z,
            zeta_p,
        } => format!(
            "a notch at {:.1} Hz (zeros' damping {zeta_z:.3}, real poles' {zeta_p:.2}: depth \
             {:.1} dB)",
            omega / (2.0 * std::f64::consts::PI),
            20.0 * (zeta_z / zeta_p).log10()
        ),
        Filter::LowPass { omega } => format!(
            "a first-order low-pass at {:.1} Hz",
            omega / (2.0 * std::f64::consts::PI)
        ),
    }
}

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
/// (the delay's lag at the crossover at most 20 deg), a tenth of the sample rate in rad/s, and,
/// for a resonance with no `filter` in the controller, a fifth of its frequency (the loop then
/// stays below the resonance, whose peak the tuner's floors check). With a filter the resonance
/// sets no cap: the filter is in the plant the tuner designs on.
pub fn crossover(
    g: &FracTf,
    res: Option<&Resonance>,
    filter: Option<&Filter>,
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
    if let (Some(r), None) = (res, filter) {
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
    if let (Some(r), Some(f)) = (res, filter) {
        reasons.push(format!(
            "the resonance at {:.1} Hz (damping {:.3}): {} in the controller",
            r.freq_hz,
            r.damping,
            filter_text(f)
        ));
    }
    Crossover {
        wc,
        pm_deg,
        reasons,
    }
}

/// The tuner's design at the crossover, or at 0.7 times it each time the tuner refuses (at most
/// six times): the report, the runs, the crossover used and the refusals. With a `filter` the
/// design is on the model times the filter (the loop `C F G` the drive runs, the filter then
/// the controller: [`fixed`]).
///
/// # Errors
/// None of the crossovers gives a design (the last refusal's message is in [`crate::Error`]).
pub fn design(
    model: &Model,
    g: &FracTf,
    filter: Option<&Filter>,
    xo: &Crossover,
    dt: f64,
    step: f64,
    u_limit: f64,
) -> Result<(Report, Runs, f64, Vec<String>)> {
    let filtered;
    let g = match filter {
        Some(f) => {
            filtered = tune::filter::series_tf(g, f)?;
            &filtered
        }
        None => g,
    };
    let mut effects = vec![];
    if let Some(vc) = model.param("Vc") {
        let sampled = model
            .spec
            .effects
            .iter()
            .any(|e| matches!(e, ident::oe::Effect::Coulomb { sampled: true, .. }));
        effects.push(InputEffect::CoulombFriction { vc, sampled });
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

/// A design and how it was reached.
#[derive(Debug, Clone)]
pub struct Chosen {
    /// The tuner's report (on the model times the filter, with one).
    pub report: Report,
    /// Its simulated runs.
    pub runs: Runs,
    /// The crossover chosen, with its reasons and the choice of filter.
    pub crossover: Crossover,
    /// The crossover the design was made at.
    pub wc_used: f64,
    /// The tuner's refusals on the way.
    pub refusals: Vec<String>,
    /// The filter in the controller.
    pub filter: Option<Filter>,
}

/// The controller for the final model `g` (with its resonance `res`): with no resonance or
/// [`super::FilterChoice::None`], the design at [`crossover`]'s choice; for a resonance with a
/// filter asked, the design with it; with [`super::FilterChoice::Auto`] the notch's design,
/// kept when its loop is faster (a higher crossover) than the lower crossover's (designed only
/// when the notch's crossover is not above the one it would start from), the reason in the
/// crossover's.
///
/// # Errors
/// The tuner refuses every crossover (with the filter asked, or both ways for `Auto`).
pub fn choose(
    model: &Model,
    g: &FracTf,
    res: Option<&Resonance>,
    req: &super::AutotuneRequest,
    fs: f64,
    step: f64,
) -> Result<Chosen> {
    let dt = 1.0 / fs;
    let run = |filter: Option<Filter>| -> Result<Chosen> {
        let xo = crossover(g, res, filter.as_ref(), fs, req.wc, req.pm_deg);
        let (report, runs, wc_used, refusals) =
            design(model, g, filter.as_ref(), &xo, dt, step, req.u_limit_v)?;
        Ok(Chosen {
            report,
            runs,
            crossover: xo,
            wc_used,
            refusals,
            filter,
        })
    };
    let Some(f) = res.and_then(|r| filter_for(r, req.filter)) else {
        return run(None);
    };
    if req.filter != super::FilterChoice::Auto {
        return run(Some(f));
    }
    // the lower crossover's design reaches its chosen crossover at best: a notch's loop faster
    // than that needs no comparison
    let cap = crossover(g, res, None, fs, req.wc, req.pm_deg).wc;
    match run(Some(f)) {
        Ok(mut with) if with.wc_used > cap => {
            with.crossover.reasons.push(format!(
                "the notch's loop is faster than the lower crossover's ({cap:.1} rad/s at most \
                 without it)"
            ));
            Ok(with)
        }
        Ok(with) => match run(None) {
            Ok(mut without) if with.wc_used <= without.wc_used => {
                without.crossover.reasons.push(format!(
                    "with {} the loop is no faster (wc {:.1} rad/s): no filter",
                    filter_text(&f),
                    with.wc_used
                ));
                Ok(without)
            }
            _ => Ok(with),
        },
        Err(e) => run(None).map(|mut without| {
            without
                .crossover
                .reasons
                .push(format!("with {}: {e}", filter_text(&f)));
            without
        }),
    }
}

/// The drive's controller of a design (with a `filter`: the filter's sections then the
/// controller's, [`tune::filter::then`]): pruned, in fixed point, with its deviation from the
/// realisation.
///
/// # Errors
/// A realisation the drive cannot run.
pub fn fixed(
    report: &Report,
    filter: Option<&Filter>,
    conf: &drive::protocol::Configure,
) -> Result<(drive::ctrl::FixedCtrl, f64, usize)> {
    let disc = report
        .discrete
        .as_ref()
        .ok_or_else(|| crate::Error::Experiment("no discrete realisation".into()))?;
    let real = match filter {
        None => Realisation::of_discrete(disc, &report.controller.text),
        Some(f) => {
            let dt = disc.dt();
            let c = tune::realise::discrete(&report.params, dt, &fracsim::ApproxSpec::default())?;
            let both = tune::filter::then(&f.discrete(dt, &c)?, &c);
            let text = format!("{} after {}", report.controller.text, filter_text(f));
            let json = tune::report::DiscreteJson {
                ss: both.to_json(&text),
                sampled_loop: None,
                sampled_note: None,
            };
            Realisation::of_discrete(&json, &text)
        }
    };
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
