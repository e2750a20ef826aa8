//! `fracid export MODEL`: a parsed or fitted model's approximation as a state space (A, B, C, D),
//! continuous or discrete with the exact zero-order hold, to JSON or to a MATLAB script
//! (`fracsim::export`).

use crate::bad_input;
use crate::cmd::sim::parse_band;
use anyhow::{Context, Result};
use fracsim::export::{self, StateSpace};
use fracsim::{ApproxSpec, FracTf};
use serde_json::Value;
use std::path::PathBuf;

/// Options of `fracid export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The model: a transfer function such as "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
    /// (`exp(-tau s)` allowed), or a JSON file written by `fracid time --json` or
    /// `fracid freq --json` (its final model: the diagnosis's refit if any, else the refined
    /// model, else `model`), or a report of `fracid tune --json` (its controller). A controller
    /// `kp + ki/s^lambda (+ kd s^mu)` (the text `fracid tune` prints) is realised with --dt as
    /// `fracid tune --dt` realises it.
    pub model: String,
    /// Sample period in seconds: export the discrete model, exact for an input held over each
    /// period, its input delay as extra states (whole and fractional samples). Without it the
    /// model is continuous (its delay beside the matrices) and --band is needed.
    #[arg(long)]
    pub dt: Option<f64>,
    /// With --dt: export the continuous model anyway (--dt then only sets the default band).
    #[arg(long)]
    pub continuous: bool,
    /// Approximation of the fractional operators: refined (Xue's refined Oustaloup, the
    /// default), oustaloup or trigeassou.
    #[arg(long, default_value = "refined")]
    pub approx: String,
    /// Approximation band "w_b,w_h" in rad/s (default with --dt: [1e-6/dt, 30 pi/dt], as `fracid sim`).
    #[arg(long, value_name = "W_B,W_H")]
    pub band: Option<String>,
    /// Approximation order N (2N+1 cells per operator).
    #[arg(long, default_value_t = 8, value_parser = crate::cmd::parse_order)]
    pub order: usize,
    /// Output format: json, or m (a MATLAB script that builds `sys = ss(...)` and `G = tf(sys)`).
    /// Default: from the extension of -o, else json.
    #[arg(long)]
    pub format: Option<String>,
    /// Write here instead of stdout.
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

/// The state space the options ask for.
pub fn state_space(g: &FracTf, a: &ExportArgs) -> Result<StateSpace> {
    let spec = ApproxSpec {
        method: a.approx.parse()?,
        band: a.band.as_deref().map(parse_band).transpose()?,
        order: a.order,
    };
    if let Some(dt) = a.dt {
        if !(dt.is_finite() && dt > 0.0) {
            bad_input!("--dt must be a positive number of seconds, got {dt}");
        }
    }
    Ok(match (a.dt, a.continuous) {
        (Some(dt), false) => export::discrete(g, dt, &spec)?,
        (Some(dt), true) => export::continuous(g, spec.band_for(dt)?, &spec)?,
        (None, _) => {
            let Some(band) = spec.band else {
                bad_input!(
                    "a continuous export needs --band w_b,w_h (rad/s), or --dt T for the discrete \
                     model (its default band is [1e-6/T, 30 pi/T])"
                );
            };
            export::continuous(g, band, &spec)?
        }
    })
}

/// The controller of a `fracid tune --json` report (its `params`), which is what exporting
/// such a report means; `None` for any other document.
fn tuned_controller(v: &Value) -> Option<tune::Controller> {
    v.get("controller")?;
    serde_json::from_value(v.get("params")?.clone()).ok()
}

/// A controller `kp + ki/s^lambda (+ kd s^mu)` realised as `fracid tune --dt` realises it
/// (`tune::realise::discrete`: the fractional integrator's modes, each held exactly, the
/// derivative as backward differences), with the options' approximation. The general route
/// cannot: a pure fractional integrator has no order-0 denominator term and its clustered poles
/// are lost.
fn controller_state_space(c: &tune::Controller, dt: f64, a: &ExportArgs) -> Result<StateSpace> {
    if !(dt.is_finite() && dt > 0.0) {
        bad_input!("--dt must be a positive number of seconds, got {dt}");
    }
    let spec = ApproxSpec {
        method: a.approx.parse()?,
        band: a.band.as_deref().map(parse_band).transpose()?,
        order: a.order,
    };
    Ok(tune::realise::discrete(c, dt, &spec)?)
}

/// Run `fracid export`.
pub fn run(a: ExportArgs) -> Result<()> {
    let model: Vec<_> = super::paths::file_arg(&a.model)
        .map(|p| ("the model", p))
        .into_iter()
        .collect();
    let outputs: Vec<_> = a.output.iter().map(|p| ("-o", p.as_path())).collect();
    super::paths::check(&model, &outputs)?;
    let format = match (&a.format, &a.output) {
        (Some(f), _) => f.to_ascii_lowercase(),
        (None, Some(p)) if p.extension().is_some_and(|e| e == "m") => "m".into(),
        _ => "json".into(),
    };
    if format != "json" && format != "m" {
        bad_input!("--format must be json or m, got '{format}'");
    }
    let loaded = crate::cmd::model_in::load(&a.model)?;
    let g = match loaded.report.as_ref().and_then(tuned_controller) {
        Some(c) => c.tf()?,
        None => loaded.tf,
    };
    let ss = match (tune::Controller::from_tf(&g), a.dt, a.continuous) {
        (Some(c), Some(dt), false) => controller_state_space(&c, dt, &a)?,
        _ => state_space(&g, &a)?,
    };
    let text = if format == "m" {
        ss.to_matlab(&g.to_string())
    } else {
        serde_json::to_string_pretty(&ss.to_json(&g.to_string()))? + "\n"
    };
    match &a.output {
        Some(p) => std::fs::write(p, text).with_context(|| format!("cannot write {}", p.display())),
        None => {
            print!("{text}");
            Ok(())
        }
    }
}
