//! The design: the gains and orders that meet the specifications at the crossover (Monje,
//! Vinagre, Feliu & Chen 2008), solved in closed form or by bracketing, then checked on the loop.
//!
//! At the crossover `wc` the loop must be `L(j wc) = e^(j(-pi + pm))`, so the controller must be
//! `C(j wc) = e^(j(-pi + pm)) / P(j wc) = a + j b` (two real equations). A flat phase adds
//! `Im(C'/C) = -Im(P'/P)` at `wc` (primes: `d/d ln omega`), linear in the gains. For fixed orders
//! `C` is linear in `(kp, ki, kd)`, so each case reduces to linear algebra plus a search over the
//! orders:
//!
//! - `pi`: `ki = -b wc`, `kp = a`;
//! - `fopi`: `ki = -b wc^lambda / sin(lambda pi/2)`, `kp = a - ki wc^-lambda cos(lambda pi/2)`;
//!   with `--flat`, `Im(-lambda ki (j wc)^-lambda / C) = s` is one equation in lambda, whose
//!   roots in (0, 2) are bracketed on a grid and bisected; without, the lambda of a grid (or
//!   `--lambda`) with the smallest sensitivity peak;
//! - `pid`: `kp = a`; with `--flat`, `ki/wc + kd wc = m = s |C|^2 / a` and `kd wc - ki/wc = b`;
//!   without, `Ti = 4 Td` (`kd = kp^2 / (4 ki)`);
//! - `fopid` (needs `--flat`): for each `(lambda, mu)` of a grid the three linear equations give
//!   `(kp, ki, kd)`; among those that meet `--t-high` and `--s-low`, the smallest sensitivity peak.
//!
//! Every candidate must have `kp >= 0`, `ki > 0`, `kd >= 0`, a stable loop (Nyquist) with one
//! gain crossover; the chosen one is checked against every specification before it is returned.

use crate::analysis::{analyse, LoopMetrics};
use crate::check::{bounds_met_at_edges, check, check_sampled};
use crate::controller::{label, Controller, Form};
use crate::error::{infeasible, invalid, Result};
use crate::plant::Plant;
use crate::spec::{order_grid, Orders, Spec};
use fracsim::FracTf;
use num_complex::Complex64;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI};

/// A designed controller and what its loop achieves.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Design {
    /// The controller.
    pub controller: Controller,
    /// The loop's measured properties (continuous, with the hold's half-sample delay for a
    /// sampled loop).
    pub metrics: LoopMetrics,
    /// For a sampled loop (`dt`): the properties of the loop the drive runs, the controller's
    /// realisation with the model discretised for the held input ([`crate::sampled`]).
    pub sampled: Option<LoopMetrics>,
    /// Caveats of the sampled loop's evaluation.
    pub sampled_note: Option<String>,
}

/// The design problem at the crossover.
pub(crate) struct Target {
    pub(crate) plant: Plant,
    pub(crate) wc: f64,
    /// `C(j wc)` required.
    c: Complex64,
    /// `Im(C'/C)` required for a flat phase.
    slope: f64,
}

/// Why candidates were refused, kept for the message: the first of each kind of reason (the
/// words without the numbers and the candidate's orders), with how many more gave it.
#[derive(Default)]
struct Refusals(Vec<String>, Vec<(String, usize)>);

impl Refusals {
    fn kind(s: &str) -> String {
        let rest = s.split_once(": ").map_or(s, |x| x.1);
        rest.chars()
            .filter(|c| c.is_alphabetic() || *c == ' ')
            .collect()
    }
    fn push(&mut self, s: String) {
        let k = Self::kind(&s);
        if let Some(i) = self.1.iter().position(|(x, _)| *x == k) {
            self.1[i].1 += 1;
        } else if self.0.len() < 8 {
            self.0.push(s);
            self.1.push((k, 0));
        }
    }
    fn text(&self) -> String {
        self.0
            .iter()
            .zip(&self.1)
            .map(|(s, (_, more))| match more {
                0 => s.clone(),
                n => format!("{s} (and {n} more like it)"),
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Design the controller of `spec.form` for `model` (see the module documentation).
///
/// # Errors
/// [`crate::Error::Invalid`] for a malformed request; [`crate::Error::Infeasible`] with the reason
/// when no controller of the form meets the specification.
pub fn design(model: &FracTf, spec: &Spec) -> Result<Design> {
    spec.validate()?;
    match design_for(model, spec, Some(spec)) {
        Err(crate::Error::Infeasible(first)) if spec.dt.is_some() => retune(model, spec, first),
        r => r,
    }
}

/// How many times a sampled design is solved again ([`retune`]).
const RETUNES: usize = 6;

/// A sampled design ([`Spec::dt`]) whose sampled loop misses the specification (the
/// realisation's own lags and the hold's aliasing, beyond the half-sample delay the design
/// includes, move its crossover and margin): the design solved again at a crossover and a margin
/// moved by what the sampled loop missed, `wc' <- wc' wc / wc_s`, `pm' <- pm' + pm - pm_s`,
/// until the sampled loop meets `spec` (within the tolerances of [`check_sampled`]) and every
/// floor (on the sampled loop, which the drive runs); refused naming the binding constraint when no retune does (`first`: why the design at
/// `spec` itself was refused).
fn retune(model: &FracTf, spec: &Spec, first: String) -> Result<Design> {
    // the floors are the sampled loop's to meet (the loop the drive runs): the continuous
    // design at the moved target keeps only the integral action's
    let mut target = Spec {
        floors: crate::spec::Floors {
            ms_max: f64::MAX,
            gm_min_db: 0.0,
            ..spec.floors
        },
        ..spec.clone()
    };
    let mut why = String::new();
    for _ in 0..RETUNES {
        let d = match design_for(model, &target, None) {
            Ok(d) => d,
            Err(crate::Error::Infeasible(e)) => {
                why = format!(
                    "the design for wc = {:.4} rad/s, pm = {:.3} deg: {e}",
                    target.wc, target.pm_deg
                );
                break;
            }
            Err(e) => return Err(e),
        };
        let Some(sm) = d.sampled.clone() else {
            break;
        };
        match check_sampled(spec, &d.controller, &sm) {
            Ok(()) => {
                let moved = format!(
                    "the continuous design (with the hold's half-sample delay) solved for wc = \
                     {:.4} rad/s, pm = {:.3} deg so that the sampled loop meets wc = {} rad/s, \
                     pm = {} deg",
                    target.wc, target.pm_deg, spec.wc, spec.pm_deg
                );
                let note = match &d.sampled_note {
                    Some(n) => format!("{moved}; {n}"),
                    None => moved,
                };
                return Ok(Design {
                    sampled_note: Some(note),
                    ..d
                });
            }
            Err(e) => why = e,
        }
        // only a loop that crosses once, stable, is moved towards the specification
        if !(sm.unstable_poles == 0 && sm.crossovers == 1 && sm.wc.is_finite()) {
            break;
        }
        target.wc *= spec.wc / sm.wc;
        target.pm_deg += spec.pm_deg - sm.pm_deg;
        if let Err(e) = target.validate() {
            why = format!("{why}; the retuned target is out of range ({e})");
            break;
        }
    }
    infeasible(format!(
        "{first}; solved again for the sampled loop ({RETUNES} retunes at most): {why}"
    ))
}

/// The design of `target`'s form at its crossover and margin, every candidate checked on the
/// continuous loop against `target` and, when `sampled` is given, on the sampled loop against
/// `sampled` (without it the sampled loop is evaluated, not checked).
fn design_for(model: &FracTf, target: &Spec, sampled: Option<&Spec>) -> Result<Design> {
    let spec = target;
    let plant = Plant::new(model.clone(), spec.dt);
    let p = plant.freq_response(spec.wc);
    if !(p.norm() > 0.0 && p.norm().is_finite()) {
        return invalid("model", format!("|G(j wc)| = {} at wc", p.norm()));
    }
    let target_l = Complex64::from_polar(1.0, -PI + spec.pm_deg.to_radians());
    let t = Target {
        wc: spec.wc,
        c: target_l / p,
        slope: -plant.dlog(spec.wc).im,
        plant,
    };
    // the controller's phase at wc, with the plant's phase unwrapped (a delay turns it many times)
    let p_deg = t.plant.phase_unwrapped(spec.wc).to_degrees();
    let need_deg = -180.0 + spec.pm_deg - p_deg;
    let (lo, hi) = match spec.form {
        Form::Pi => (-90.0, 0.0),
        Form::Fopi => (-180.0, 0.0),
        Form::Pid => (-90.0, 90.0),
        Form::Fopid => (-180.0, 180.0),
        Form::Fopd => (0.0, 180.0),
    };
    if !(need_deg > lo && need_deg < hi) {
        return infeasible(format!(
            "the plant's phase at wc = {} rad/s is {p_deg:.1} deg{}; a phase margin of {} deg \
             needs the controller's phase there to be {need_deg:.1} deg, and a {} with positive \
             gains has its phase in ({lo}, {hi}) deg",
            spec.wc,
            if t.plant.delay() > 0.0 {
                format!(" (delay {} s included)", t.plant.delay())
            } else {
                String::new()
            },
            spec.pm_deg,
            spec.form.name()
        ));
    }
    let mut why = Refusals::default();
    let candidates: Vec<Controller> = match spec.form {
        Form::Pi => vec![fopi_at(&t, 1.0)],
        Form::Fopi => fopi_candidates(&t, spec),
        Form::Pid => vec![pid(&t, spec.flat, &mut why)?],
        Form::Fopid => fopid_candidates(&t, spec),
        Form::Fopd => fopd_candidates(&t, spec),
    };
    let o = spec.orders;
    let within = |c: &Controller| {
        (c.ki == 0.0 || o.lambda_max.is_none_or(|m| c.lambda <= m))
            && (c.kd == 0.0 || o.mu_max.is_none_or(|m| c.mu <= m))
    };
    if !candidates.is_empty() && !candidates.iter().any(within) {
        let caps: Vec<String> = [("--max-lambda", o.lambda_max), ("--max-mu", o.mu_max)]
            .iter()
            .filter_map(|(n, v)| v.map(|v| format!("{n} {v}")))
            .collect();
        return infeasible(format!(
            "every {} meeting the equations has its orders above the caps ({}): {}",
            spec.form.name(),
            caps.join(", "),
            candidates.iter().map(label).collect::<Vec<_>>().join("; ")
        ));
    }
    let candidates: Vec<Controller> = candidates.into_iter().filter(within).collect();
    choose(&t, spec, sampled, candidates, why)
}

/// The FOPI meeting magnitude and phase at `wc` for an integrator order `lambda`.
fn fopi_at(t: &Target, lambda: f64) -> Controller {
    let (s, c) = (lambda * FRAC_PI_2).sin_cos();
    let ki = -t.c.im * t.wc.powf(lambda) / s;
    Controller {
        kp: t.c.re - ki * t.wc.powf(-lambda) * c,
        ki,
        lambda,
        kd: 0.0,
        mu: 1.0,
    }
}

/// `Im(C'/C)` of the FOPI of order `lambda` minus the slope a flat phase needs.
fn fopi_flatness(t: &Target, lambda: f64) -> f64 {
    let c = fopi_at(t, lambda);
    (c.dlog_omega(t.wc) / t.c).im - t.slope
}

fn fopi_candidates(t: &Target, spec: &Spec) -> Vec<Controller> {
    if !spec.flat {
        return Orders::grid(spec.lambda, spec.orders.lambda_max, 192)
            .into_iter()
            .map(|l| fopi_at(t, l))
            .collect();
    }
    // every root of the flatness condition in lambda, by bracketing then bisection
    bracket_roots(|l| fopi_flatness(t, l), 400)
        .into_iter()
        .map(|l| fopi_at(t, l))
        .collect()
}

/// The FOPD `kp + kd s^mu` meeting magnitude and phase at `wc` for a differentiator order `mu`.
fn fopd_at(t: &Target, mu: f64) -> Controller {
    let (s, c) = (mu * FRAC_PI_2).sin_cos();
    let kd = t.c.im / (t.wc.powf(mu) * s);
    Controller {
        kp: t.c.re - kd * t.wc.powf(mu) * c,
        ki: 0.0,
        lambda: 1.0,
        kd,
        mu,
    }
}

/// The FOPD candidates: the fixed order (`spec.lambda`), or the roots in `mu` of the flatness
/// `Im(mu kd (j wc)^mu / C) = slope`, or a grid of orders.
fn fopd_candidates(t: &Target, spec: &Spec) -> Vec<Controller> {
    if !spec.flat {
        return Orders::grid(spec.orders.mu, spec.orders.mu_max, 192)
            .into_iter()
            .map(|mu| fopd_at(t, mu))
            .collect();
    }
    let f = |mu: f64| {
        let c = fopd_at(t, mu);
        (c.dlog_omega(t.wc) / t.c).im - t.slope
    };
    bracket_roots(f, 400)
        .into_iter()
        .map(|mu| fopd_at(t, mu))
        .collect()
}

/// The roots of `f` over the order grid of `n` steps, bracketed then bisected.
fn bracket_roots(f: impl Fn(f64) -> f64, n: usize) -> Vec<f64> {
    let grid: Vec<f64> = order_grid(n).collect();
    let mut roots = Vec::new();
    for w in grid.windows(2) {
        let (fa, fb) = (f(w[0]), f(w[1]));
        if fa == 0.0 {
            roots.push(w[0]);
        } else if fa * fb < 0.0 {
            let (mut a, mut b) = (w[0], w[1]);
            for _ in 0..100 {
                let m = 0.5 * (a + b);
                if (f(m) > 0.0) == (fa > 0.0) {
                    a = m;
                } else {
                    b = m;
                }
            }
            roots.push(0.5 * (a + b));
        }
    }
    roots
}

fn pid(t: &Target, flat: bool, why: &mut Refusals) -> Result<Controller> {
    let (a, b, w) = (t.c.re, t.c.im, t.wc);
    if a <= 0.0 {
        return infeasible(format!(
            "the controller would need a phase of {:.1} deg at wc, outside (-90, 90) deg where \
             a PID with kp > 0 lies",
            t.c.arg().to_degrees()
        ));
    }
    let (ki, kd) = if flat {
        let m = t.slope * t.c.norm_sqr() / a;
        (w * (m - b) / 2.0, (m + b) / (2.0 * w))
    } else {
        let ki = w * (-b + (b * b + a * a).sqrt()) / 2.0;
        (ki, a * a / (4.0 * ki))
    };
    if !(ki > 0.0 && kd >= 0.0) {
        why.push(format!(
            "the flat-phase PID would need ki = {ki:.4e}, kd = {kd:.4e}"
        ));
        return infeasible(format!(
            "no PID with ki > 0 and kd >= 0 meets the specification: {}",
            why.text()
        ));
    }
    Ok(Controller {
        kp: a,
        ki,
        lambda: 1.0,
        kd,
        mu: 1.0,
    })
}

fn fopid_candidates(t: &Target, spec: &Spec) -> Vec<Controller> {
    let mut out = Vec::new();
    let j = |w: f64, a: f64| fracsim::jw_pow(w, a);
    let mus = Orders::grid(spec.orders.mu, spec.orders.mu_max, 48);
    for lambda in Orders::grid(spec.lambda, spec.orders.lambda_max, 48) {
        for &mu in &mus {
            let (il, dm) = (1.0 / j(t.wc, lambda), j(t.wc, mu));
            // Im: ki Im(il) + kd Im(dm) = b; flat: ki Im(-lambda il / C) + kd Im(mu dm / C) = s
            let (a11, a12) = (il.im, dm.im);
            let (a21, a22) = ((-lambda * il / t.c).im, (mu * dm / t.c).im);
            let det = a11 * a22 - a12 * a21;
            if det.abs() < 1e-300 {
                continue;
            }
            let ki = (t.c.im * a22 - a12 * t.slope) / det;
            let kd = (a11 * t.slope - a21 * t.c.im) / det;
            let kp = t.c.re - ki * il.re - kd * dm.re;
            out.push(Controller {
                kp,
                ki,
                lambda,
                kd,
                mu,
            });
        }
    }
    out
}

/// Among `candidates`, the one that meets every specification with the smallest sensitivity
/// peak; the reasons the others failed otherwise.
fn choose(
    t: &Target,
    spec: &Spec,
    sampled: Option<&Spec>,
    candidates: Vec<Controller>,
    mut why: Refusals,
) -> Result<Design> {
    if candidates.is_empty() && spec.flat {
        return no_flat_order(t, spec);
    }
    let ranked = rank(t, spec, candidates, &mut why);
    // the reasons of the candidates that reached the loop's checks, best-ranked first: the
    // binding constraint is named before the candidates that never had positive gains
    let mut checked = Refusals::default();
    let mut best: Option<Design> = None;
    for (_, c) in ranked {
        match judge(t, spec, sampled, c)? {
            Ok(d) => {
                best = Some(d);
                break;
            }
            Err(e) => checked.push(e),
        }
    }
    match best {
        Some(d) => Ok(d),
        None => infeasible(format!(
            "no {} meets wc = {} rad/s, pm = {} deg{}: {}",
            spec.form.name(),
            spec.wc,
            spec.pm_deg,
            if spec.flat { ", flat phase" } else { "" },
            if checked.0.is_empty() {
                why.text()
            } else if why.0.is_empty() {
                checked.text()
            } else {
                format!(
                    "{}; others: {}",
                    checked.text(),
                    why.0.first().map_or("", String::as_str)
                )
            }
        )),
    }
}

/// The candidates worth the full check, ranked by a coarse sensitivity peak (smallest first);
/// the reasons of the others pushed to `why`.
fn rank(
    t: &Target,
    spec: &Spec,
    candidates: Vec<Controller>,
    why: &mut Refusals,
) -> Vec<(f64, Controller)> {
    // Positive gains first, then ranked by a coarse sensitivity peak; the full analysis and check
    // in that order until one passes (the ranking only orders the work: every candidate returned
    // has passed the full check, and its Ms is the full analysis's).
    let mut ranked: Vec<(f64, Controller)> = Vec::new();
    for c in candidates {
        let gains_ok = if spec.form.has_integrator() {
            c.kp >= 0.0 && c.ki > 0.0 && c.kd >= 0.0
        } else {
            c.kp >= 0.0 && c.kd > 0.0
        };
        if !gains_ok && !spec.form.has_integrator() {
            why.push(format!(
                "{} needs kp = {:.4e}, kd = {:.4e} (need kp >= 0, kd > 0)",
                label(&c),
                c.kp,
                c.kd
            ));
            continue;
        }
        if !gains_ok {
            why.push(format!(
                "lambda = {:.3}{} needs kp = {:.4e}, ki = {:.4e}{} (need kp >= 0, ki > 0{})",
                c.lambda,
                if spec.form.has_derivative() {
                    format!(", mu = {:.3}", c.mu)
                } else {
                    String::new()
                },
                c.kp,
                c.ki,
                if spec.form.has_derivative() {
                    format!(", kd = {:.4e}", c.kd)
                } else {
                    String::new()
                },
                if spec.form.has_derivative() {
                    ", kd >= 0"
                } else {
                    ""
                },
            ));
            continue;
        }
        let roll_off = t.plant.tf.den_order() - t.plant.tf.num_order();
        if c.kd > 0.0 && c.mu >= roll_off - 0.05 {
            why.push(format!(
                "mu = {:.3}: the loop would not roll off (the model falls as omega^-{roll_off})",
                c.mu
            ));
            continue;
        }
        let far = crate::analysis::loop_response(&t.plant, &c, t.wc * 1e5).norm();
        if far >= 0.1 {
            why.push(format!(
                "{}: |L| is still {far:.3} at 1e5 wc: the loop does not roll off",
                label(&c)
            ));
            continue;
        }
        ranked.push((coarse_ms(&t.plant, &c, t.wc), c));
    }
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    ranked
}

/// The refusal of a flat phase no order of the form can give: the slopes the form reaches.
fn no_flat_order(t: &Target, spec: &Spec) -> Result<Design> {
    let slope = |l: f64| match spec.form {
        Form::Fopd => (fopd_at(t, l).dlog_omega(t.wc) / t.c).im,
        _ => fopi_flatness(t, l) + t.slope,
    };
    let (lo, hi) = order_grid(400)
        .map(slope)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    infeasible(format!(
        "a flat phase at wc needs the controller's phase slope to be {:.4} rad per unit of \
         ln(omega); with magnitude and phase met, a {} of order in (0, 2) gives slopes in \
         [{lo:.4}, {hi:.4}] only",
        t.slope,
        spec.form.name()
    ))
}

/// One candidate analysed and checked: on the loop, then, with `dt`, on the sampled loop
/// ([`crate::sampled`]); the design, or why not. A bound missed at its band's edge refuses it
/// before the analysis (the search for a bounded FOPID analysed every one of its 2304
/// candidates when none met the bound).
///
/// # Errors
/// The realisation's errors.
fn judge(
    t: &Target,
    spec: &Spec,
    sampled_spec: Option<&Spec>,
    c: Controller,
) -> Result<Result<Design, String>> {
    if let Err(e) = bounds_met_at_edges(&t.plant, spec, &c) {
        return Ok(Err(format!("{}: {e}", label(&c))));
    }
    let m = analyse(&t.plant, &c, t.wc);
    if let Err(e) = check(&t.plant, t.wc, spec, &c, &m) {
        return Ok(Err(e));
    }
    let (sampled, sampled_note) = match spec.dt {
        Some(dt) => {
            let approx = fracsim::ApproxSpec::default();
            let l = crate::sampled::SampledLoop::new(&t.plant.tf, &c, dt, &approx)?;
            let sm = l.analyse(t.wc);
            if let Some(Err(e)) = sampled_spec.map(|s| check_sampled(s, &c, &sm)) {
                return Ok(Err(e));
            }
            (Some(sm), l.note)
        }
        None => (None, None),
    };
    Ok(Ok(Design {
        controller: c,
        metrics: m,
        sampled,
        sampled_note,
    }))
}

/// `max |1/(1+L)|` on 40 points per decade over `[wc/100, wc 100]`.
fn coarse_ms(p: &Plant, c: &Controller, wc: f64) -> f64 {
    (0..=160)
        .map(|i| {
            let w = wc * 10f64.powf(-2.0 + i as f64 / 40.0);
            1.0 / (Complex64::new(1.0, 0.0) + crate::analysis::loop_response(p, c, w)).norm()
        })
        .fold(0.0, f64::max)
}
