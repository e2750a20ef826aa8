//! `fracid time FILE`: time-domain identification by output error (docs/design.md §5, `ident::oe`).

use crate::plot::{self, Figure};
use anyhow::{Context, Result};
use ident::data::{Columns, OffsetMode, Record};
use ident::metrics;
use ident::oe::{identify_with_progress, FracModel, IdentOptions, Identification, StartMode};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::IsTerminal;
use std::path::PathBuf;

/// Options of `fracid time`.
#[derive(Debug, clap::Args)]
pub struct TimeArgs {
    /// CSV file with columns t, u, y (`,` `;` or tab; `#` comments).
    pub file: PathBuf,
    /// Time column (name or 0-based index).
    #[arg(long, default_value = "t")]
    pub t_col: String,
    /// Input column.
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Output column.
    #[arg(long, default_value = "y")]
    pub y_col: String,
    /// Model structure: pmsm (K/(a2 s^(zeta+theta) + a1 s^zeta + 1)), commensurate, fopdt, or a
    /// transfer function such as "6.8/(3e-5 s^1.75 + 0.006 s^0.9 + 1)" used as the start.
    #[arg(long, default_value = "pmsm")]
    pub structure: String,
    /// Approximation of the fractional operators: refined (Xue's refined Oustaloup, the default),
    /// oustaloup or trigeassou (Poinot-Trigeassou); the model is then simulated exactly for the
    /// held input (see `fracid sim --help`).
    #[arg(long, default_value = "refined")]
    pub approx: String,
    /// Approximation band "w_b,w_h" in rad/s (default fracsim's [1e-3, 30 pi/dt]).
    #[arg(long)]
    pub band: Option<String>,
    /// Approximation order N (2N+1 cells; default fracsim's, 8).
    #[arg(long)]
    pub order: Option<usize>,
    /// Fit an input delay (seconds, up to --max-delay).
    #[arg(long)]
    pub delay: bool,
    /// Largest input delay (seconds) for --delay and fopdt (default: 1 s, at most a fifth of the
    /// record).
    #[arg(long)]
    pub max_delay: Option<f64>,
    /// Fraction of the record held out for validation (at the end).
    #[arg(long, default_value_t = 0.3)]
    pub holdout: f64,
    /// Operating point removal: initial (u[0], median y before the first input change), mean, none.
    #[arg(long, default_value = "initial")]
    pub offsets: String,
    /// Do not fit a constant output offset.
    #[arg(long)]
    pub no_offset: bool,
    /// Maximum Levenberg-Marquardt iterations.
    #[arg(long, default_value_t = 100)]
    pub max_iter: usize,
    /// Start from the given structure's values instead of the automatic start.
    #[arg(long)]
    pub no_auto_start: bool,
    /// Print JSON (docs/design.md §7) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write a plot (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Diagnose the residual, add the physical effects that pay on held-out data, report the
    /// error before and after (docs/design.md §6); with --plot also draws the residual before and after
    /// to PLOT_diagnosis.EXT.
    #[arg(long)]
    pub diagnose: bool,
    /// Fleet mode (many files at once): see `fracid::cmd::fleet`.
    #[command(flatten)]
    pub fleet: super::fleet::FleetArgs,
}

pub(crate) fn model_of(a: &TimeArgs, duration: f64) -> Result<FracModel> {
    let max_delay = match a.max_delay {
        Some(d) if !(d > 0.0 && d.is_finite()) => {
            crate::bad_input!("--max-delay must be a positive number of seconds, got {d}")
        }
        Some(d) => d,
        None => (0.2 * duration).min(1.0),
    };
    let mut m = match a.structure.to_ascii_lowercase().as_str() {
        "pmsm" => FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9),
        "commensurate" => FracModel::commensurate(1.0, 0.01, 1e-4, 0.9),
        "fopdt" => FracModel::fopdt(1.0, 0.1, 0.01, max_delay),
        s => {
            let tf: fracsim::FracTf = s.parse().with_context(|| {
                format!("--structure '{s}' is not pmsm, commensurate, fopdt or a model")
            })?;
            FracModel::from_tf(&tf, true, true)
        }
    };
    m.approx.method = a.approx.parse()?;
    if let Some(n) = a.order {
        m.approx.order = n;
    }
    if let Some(b) = &a.band {
        let v: Vec<f64> = b.split(',').filter_map(|x| x.trim().parse().ok()).collect();
        if v.len() != 2 {
            crate::bad_input!("--band must be \"w_b,w_h\" in rad/s, got '{b}'");
        }
        fracsim::approx::check_band(v[0], v[1])?;
        m.approx.band = Some((v[0], v[1]));
    }
    if a.delay && m.delay.is_none() {
        m.with_delay(0.05 * max_delay, max_delay);
    }
    Ok(m)
}

/// Run `fracid time`.
///
/// # Errors
/// Unreadable file (exit 3), bad data or options (exit 2), numerical breakdown (exit 1).
pub fn run(a: TimeArgs) -> Result<()> {
    if a.fleet.active(&a.file) {
        return super::fleet::run_time(a);
    }
    if let Some(p) = &a.plot {
        plot::format_of(p)?;
    }
    let text = std::fs::read_to_string(&a.file)
        .with_context(|| format!("cannot read {}", a.file.display()))?;
    let cols = Columns {
        t: a.t_col.clone(),
        u: a.u_col.clone(),
        y: a.y_col.clone(),
    };
    let rec = Record::parse(&text, &cols).with_context(|| format!("in {}", a.file.display()))?;
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    let model = model_of(&a, duration)?;
    let offsets = match a.offsets.as_str() {
        "initial" => OffsetMode::Initial,
        "mean" => OffsetMode::Mean,
        "none" => OffsetMode::None,
        o => crate::bad_input!("--offsets must be initial, mean or none, got '{o}'"),
    };
    let mut opts = IdentOptions {
        offsets,
        holdout: a.holdout,
        fit_offset: !a.no_offset,
        start: if a.no_auto_start {
            StartMode::Given
        } else {
            StartMode::Auto
        },
        ..Default::default()
    };
    opts.fit.lm.max_iterations = a.max_iter;
    let bar = if a.quiet || !std::io::stderr().is_terminal() {
        indicatif::ProgressBar::hidden()
    } else {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        b
    };
    let id = identify_with_progress(&rec, &model, &opts, &mut |k, rmse| {
        bar.set_message(format!("simulation {k}, rmse {rmse:.4e}"));
        bar.tick();
    })?;
    bar.finish_and_clear();
    for w in &id.report.warnings {
        eprintln!("warning: {w}");
    }
    let diagnosis = if a.diagnose {
        Some(super::diagnose::run_time(&rec, &id)?)
    } else {
        None
    };
    if a.json {
        let mut v = json_of(&id, &rec);
        if let Some(d) = &diagnosis {
            v["diagnosis"] = super::diagnose::json(d)?;
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_text(&id, &rec);
        if let Some(d) = &diagnosis {
            print!("{}", super::diagnose::text(d));
        }
    }
    if let Some(p) = &a.plot {
        plot::save(p, (1400, 1000), &TimeFigure { id: &id, rec: &rec })?;
        if let Some(d) = &diagnosis {
            let dp = super::diagnose::residual_plot_path(p);
            super::diagnose::plot_time(&dp, &rec, d)?;
            if !a.json {
                println!("residual plot: {}", dp.display());
            }
        }
    }
    Ok(())
}

pub(crate) fn json_of(id: &Identification, rec: &Record) -> serde_json::Value {
    let terms = |t: &[fracsim::Term]| -> Vec<serde_json::Value> {
        t.iter()
            .map(|t| serde_json::json!({"coef": t.coef, "order": t.order}))
            .collect()
    };
    let fit = |f: Option<metrics::Fit>| {
        f.map(|f| serde_json::json!({"rmse": f.rmse, "nrmse_percent": f.nrmse_percent}))
    };
    serde_json::json!({
        "model": {"num": terms(&id.tf.num), "den": terms(&id.tf.den), "delay": id.tf.delay},
        "fit": {"estimation": fit(Some(id.estimation)), "validation": fit(id.validation)},
        "params": id.report.params,
        "start": id.start_report,
        "alpha_eta": id.alpha_eta.iter().map(|(o, a, e)| serde_json::json!({"order": o, "alpha": a, "eta": e})).collect::<Vec<_>>(),
        "offsets": id.offsets,
        "split": {"estimation_samples": id.split, "validation_samples": rec.len() - id.split},
        "iterations": id.report.iterations,
        "converged": id.report.converged,
        "termination": id.report.termination,
        "stop_reason": id.report.stop_reason(),
        "seconds": id.report.elapsed.as_secs_f64(),
        "warnings": id.report.warnings,
    })
}

fn print_text(id: &Identification, rec: &Record) {
    println!("model: {}", id.tf);
    println!(
        "operating point: u0 = {:.6}, y0 = {:.6}; {} estimation + {} validation samples, dt = {} s",
        id.offsets.u0,
        id.offsets.y0,
        id.split,
        rec.len() - id.split,
        rec.dt
    );
    let sr = &id.start_report;
    println!(
        "start: {}{}",
        sr.note,
        sr.fit_percent
            .map_or(String::new(), |f| format!(" (start fits {f:.1}%)"))
    );
    println!("parameters (+- standard error):");
    for p in &id.report.params {
        let se = p.std_error.map_or("-".to_string(), |s| format!("{s:.3e}"));
        let tag = if !p.free {
            " (fixed)"
        } else if p.at_bound {
            " (AT BOUND)"
        } else {
            ""
        };
        println!("  {:<10} {:>14.6e} +- {se}{tag}", p.name, p.value);
    }
    for (o, al, et) in &id.alpha_eta {
        println!("  order {o:.4}: Poinot-Trigeassou alpha = {al:.5}, eta = {et:.5}");
    }
    println!(
        "fit estimation: NRMSE {:.2}%, RMSE {:.5}",
        id.estimation.nrmse_percent, id.estimation.rmse
    );
    if let Some(v) = id.validation {
        println!(
            "fit validation: NRMSE {:.2}%, RMSE {:.5}",
            v.nrmse_percent, v.rmse
        );
    }
    println!(
        "{} iterations, {} simulations, {:.3} s; stopped: {}{}",
        id.report.iterations,
        id.report.evaluations,
        id.report.elapsed.as_secs_f64(),
        id.report.stop_reason(),
        if id.report.converged {
            ""
        } else {
            " (NOT converged)"
        }
    );
}

struct TimeFigure<'a> {
    id: &'a Identification,
    rec: &'a Record,
}

impl Figure for TimeFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (rec, id) = (self.rec, self.id);
        let areas = root.split_evenly((2, 2));
        let t_split = rec.t[id.split.min(rec.len() - 1)];
        let look = plot::Look {
            caption: 18,
            labels: None,
            margin: 10,
            x_area: 35,
            y_area: 60,
        };
        // 1: measured vs model
        plot::time_series_chart(
            &areas[0],
            &plot::TimeChart {
                title: Some("measured and model output"),
                x_desc: "t [s]",
                y_desc: None,
                t: &rec.t,
                lines: &[
                    plot::Line {
                        label: Some("measured"),
                        values: &rec.y,
                        style: BLACK.into(),
                    },
                    plot::Line {
                        label: Some("model"),
                        values: &id.yhat,
                        style: RED.into(),
                    },
                ],
                marker: Some((t_split, "validation starts", BLUE.into())),
                look,
            },
        )?;
        // 2: residual
        let res: Vec<f64> = rec.y.iter().zip(&id.yhat).map(|(a, b)| a - b).collect();
        plot::time_series_chart(
            &areas[1],
            &plot::TimeChart {
                title: Some("residual y - yhat"),
                x_desc: "t [s]",
                y_desc: None,
                t: &rec.t,
                lines: &[plot::Line {
                    label: None,
                    values: &res,
                    style: BLACK.into(),
                }],
                marker: None,
                look,
            },
        )?;
        // 3 and 4: correlations on the validation part (estimation if none)
        let (a, b) = if id.split < rec.len() {
            (id.split, rec.len())
        } else {
            (0, id.split)
        };
        let e_part = &res[a..b];
        let u_part = &rec.u[a..b];
        let lags = 25usize.min(e_part.len().saturating_sub(1)).max(1);
        let bound = metrics::bound99(e_part.len());
        let ra = metrics::autocorr(e_part, lags);
        let rc = metrics::crosscorr(e_part, u_part, lags);
        let part = if a > 0 { "validation" } else { "estimation" };
        for (k, (title, vals, first)) in [
            (
                format!("residual autocorrelation ({part}), 99% bounds"),
                ra,
                0i32,
            ),
            (
                format!("residual-input cross-correlation ({part}), 99% bounds"),
                rc,
                -(lags as i32),
            ),
        ]
        .into_iter()
        .enumerate()
        {
            plot::correlation_chart(&areas[2 + k], &title, first, &vals, bound, look)?;
        }
        Ok(())
    }
}
