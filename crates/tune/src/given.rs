//! `fracid tune --analyse C`: a given controller (a published design, one tuned elsewhere)
//! analysed on the model as a design is checked: the loop (stability counted on its
//! characteristic equation, crossovers, margins, `Ms`), the sampled loop with `dt`, the floors it
//! misses, the closed loop simulated.

use crate::analysis::{analyse, loop_response, LoopMetrics};
use crate::closed::LoopRun;
use crate::controller::Controller;
use crate::error::{invalid, Result};
use crate::plant::Plant;
use crate::report::{discrete_json, setup_of, simulate_loop, DiscreteJson, SimOptions, StepJson};
use crate::sampled::SampledLoop;
use crate::spec::Floors;
use fracsim::{ApproxSpec, FracTf};
use ident::app::ModelReport;
use serde::Serialize;

/// The analysis of a given controller.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    /// The model.
    pub model: ModelReport,
    /// `C(s)` in the model JSON's format.
    pub controller: ModelReport,
    /// Its gains and orders.
    pub params: Controller,
    /// The continuous loop (with the hold's half-sample delay for `dt`).
    #[serde(rename = "loop")]
    pub loop_: LoopMetrics,
    /// The realisation and the sampled loop, with `dt`.
    pub discrete: Option<DiscreteJson>,
    /// The floors it was judged by.
    pub floors: Floors,
    /// What the loop misses (instability, a floor), in words; empty when nothing.
    pub misses: Vec<String>,
    /// The closed loop simulated.
    pub step: StepJson,
}

/// The crossover to centre the analysis on: `wc` when given, else the lowest crossing of
/// `|L| = 1` found on 20 points a decade over `[1e-6, 1e9]` rad/s (1 rad/s when there is none).
fn centre(p: &Plant, c: &Controller, wc: Option<f64>) -> f64 {
    if let Some(w) = wc {
        return w;
    }
    let ws: Vec<f64> = (0..=300)
        .map(|i| 1e-6 * 10f64.powf(i as f64 / 20.0))
        .collect();
    ws.windows(2)
        .find(|w| {
            (loop_response(p, c, w[0]).norm() >= 1.0) != (loop_response(p, c, w[1]).norm() >= 1.0)
        })
        .map_or(1.0, |w| (w[0] * w[1]).sqrt())
}

/// Analyse `c` on `model` (sampled every `dt` seconds when given), around `wc` when given.
///
/// # Errors
/// A controller with non-finite or negative gains or orders outside (0, 2), a bad `dt` or `wc`,
/// the realisation's and the simulation's errors.
pub fn analyse_given(
    model: &FracTf,
    c: &Controller,
    wc: Option<f64>,
    dt: Option<f64>,
    floors: Floors,
    opts: &SimOptions,
) -> Result<(Analysis, Option<LoopRun>)> {
    let gains = [c.kp, c.ki, c.kd];
    if !(gains.iter().all(|g| g.is_finite() && *g >= 0.0) && c.kp + c.ki + c.kd > 0.0) {
        return invalid(
            "controller",
            format!("gains must be finite and >= 0: {c:?}"),
        );
    }
    if !((c.ki == 0.0 || (c.lambda > 0.0 && c.lambda < 2.0))
        && (c.kd == 0.0 || (c.mu > 0.0 && c.mu < 2.0)))
    {
        return invalid("controller", format!("orders must be in (0, 2): {c:?}"));
    }
    if let Some(dt) = dt.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return invalid("dt", format!("{dt} s must be positive"));
    }
    if let Some(w) = wc.filter(|w| !(w.is_finite() && *w > 0.0)) {
        return invalid("wc", format!("{w} rad/s must be positive"));
    }
    let plant = Plant::new(model.clone(), dt);
    let w0 = centre(&plant, c, wc);
    let m = analyse(&plant, c, w0);
    let mut misses = Vec::new();
    judge("the loop", &m, &floors, c, &mut misses);
    let approx = ApproxSpec::default();
    let discrete = match dt {
        Some(dt) => {
            let l = SampledLoop::new(model, c, dt, &approx)?;
            let sm = l.analyse(w0);
            judge(
                &format!("the loop sampled every {dt} s"),
                &sm,
                &floors,
                c,
                &mut misses,
            );
            Some(DiscreteJson {
                sampled_loop: Some(sm),
                sampled_note: l.note,
                ..discrete_json(&crate::realise::discrete(c, dt, &approx)?)
            })
        }
        None => None,
    };
    let setup = setup_of(model, w0, dt, opts)?;
    let (step, run, _) = simulate_loop(model, c, &setup, opts)?;
    Ok((
        Analysis {
            model: model.into(),
            controller: (&c.tf()?).into(),
            params: *c,
            loop_: m,
            discrete,
            floors,
            misses,
            step,
        },
        run,
    ))
}

/// Stability and the floors of one loop, what it misses pushed to `misses`.
fn judge(name: &str, m: &LoopMetrics, floors: &Floors, c: &Controller, misses: &mut Vec<String>) {
    if let Some(n) = &m.stability_note {
        misses.push(format!("{name}: {n}"));
    } else if m.unstable_poles != 0 {
        misses.push(format!(
            "{name}: unstable, {} closed-loop poles in the right half-plane (or outside the unit \
             circle)",
            m.unstable_poles
        ));
    }
    if let Err(e) = floors.met(c.ki != 0.0, c, m) {
        misses.push(format!("{name}: {e}"));
    }
}
