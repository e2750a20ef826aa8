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
    /// Output format: json, m (a MATLAB script that builds `sys = ss(...)` and `G = tf(sys)`), or
    /// c (a C header for the C firmware of the fixed-point sections `fracid drive loop`
    /// downloads: the realisation of a `fracid tune --dt DT --json` report, or a controller with
    /// --dt, for the drive's default channel scales). Default: from the extension of -o (.m,
    /// .h), else json.
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
        (None, Some(p)) if p.extension().is_some_and(|e| e == "h") => "c".into(),
        _ => "json".into(),
    };
    if !["json", "m", "c"].contains(&format.as_str()) {
        bad_input!("--format must be json, m or c, got '{format}'");
    }
    let loaded = crate::cmd::model_in::load(&a.model)?;
    let g = match loaded.report.as_ref().and_then(tuned_controller) {
        Some(c) => c.tf()?,
        None => loaded.tf,
    };
    if format == "c" {
        return write_out(&a, c_header(&a, loaded.report.as_ref(), &g)?);
    }
    let ss = match (tune::Controller::from_tf(&g), a.dt, a.continuous) {
        (Some(c), Some(dt), false) => controller_state_space(&c, dt, &a)?,
        _ => state_space(&g, &a)?,
    };
    let text = if format == "m" {
        ss.to_matlab(&g.to_string())
    } else {
        serde_json::to_string_pretty(&ss.to_json(&g.to_string()))? + "\n"
    };
    write_out(&a, text)
}

/// The text to `-o`, or to standard output.
fn write_out(a: &ExportArgs, text: String) -> Result<()> {
    match &a.output {
        Some(p) => std::fs::write(p, text).with_context(|| format!("cannot write {}", p.display())),
        None => {
            print!("{text}");
            Ok(())
        }
    }
}

/// The fixed-point controller the drive runs, as a C header
/// (`drive::ctrl::FixedCtrl::c_header`): a `fracid tune --json` report's discrete realisation
/// (or, with --dt, the controller realised anew with the options' approximation), pruned and
/// converted as `fracid drive loop` converts it, for the drive's default channel scales at the
/// rate `1/dt`.
///
/// # Errors
/// Not a controller, no sample period, a realisation the drive cannot run (bad input, exit 2).
fn c_header(a: &ExportArgs, report: Option<&Value>, g: &FracTf) -> Result<String> {
    use autotune::realise::{fixed_controller, parse_realisation, prune, Realisation};
    let realised = report.is_some_and(|v| v.get("discrete").is_some_and(|d| !d.is_null()));
    let real = match (report, a.dt) {
        (Some(v), None) if realised => parse_realisation(&v.to_string())?,
        _ => {
            let Some(c) = tune::Controller::from_tf(g) else {
                bad_input!(
                    "--format c exports a controller: a `fracid tune --dt DT --json` report, or a \
                     controller kp + ki/s^lambda (+ kd s^mu) with --dt; {g} is none"
                );
            };
            let Some(dt) = a.dt else {
                bad_input!(
                    "--format c needs the sample period: --dt, or a report of `fracid tune --dt \
                     DT --json`"
                );
            };
            let ss = controller_state_space(&c, dt, a)?;
            Realisation {
                dt,
                a: ss.a_rows(),
                b: ss.b_col(),
                c: ss.c_row(),
                d: ss.d,
                text: g.to_string(),
            }
        }
    };
    let (pruned, _) = prune(&real);
    let conf = drive::protocol::Configure {
        sample_rate_hz: (1.0 / real.dt).round().min(f64::from(u32::MAX)) as u32,
        ..Default::default()
    };
    let k = fixed_controller(&pruned, &conf)?;
    Ok(k.c_header(&real.text, real.dt, &conf))
}
