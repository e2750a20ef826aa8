//! `fracid time FILE`: time-domain identification by output error (docs/design.md §5, `ident::oe`).

use crate::plot::{self, Figure};
use anyhow::Result;
use ident::data::{Columns, ReadOptions, Record};
use ident::metrics;
use ident::oe::{identify_with_progress, FracModel, IdentOptions, Identification, StartMode};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::IsTerminal;
use std::path::PathBuf;

/// The columns of a time record (`fracid time`, `fracid score`).
#[derive(Debug, clap::Args)]
pub struct ColumnArgs {
    /// Time column (name or 0-based index).
    #[arg(long, default_value = "t")]
    pub t_col: String,
    /// Input column.
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Output column.
    #[arg(long, default_value = "y")]
    pub y_col: String,
}

impl ColumnArgs {
    /// The reader's [`Columns`].
    pub fn columns(&self) -> Columns {
        Columns {
            t: self.t_col.clone(),
            u: self.u_col.clone(),
            y: self.y_col.clone(),
        }
    }
}

/// Options of `fracid time`.
#[derive(Debug, clap::Args)]
pub struct TimeArgs {
    /// CSV file with columns t, u, y (`,` `;` or tab; `#` comments).
    pub file: PathBuf,
    /// The columns of t, u and y.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Sampling step in seconds, for a file with no time column (t = k dt; --t-col is not read).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Model structure: pmsm (K/(a2 s^(zeta+theta) + a1 s^zeta + 1)), commensurate,
    /// second-order, third-order (the integer K/(a2 s^2 + a1 s + 1), K/(a3 s^3 + ... + 1)),
    /// two-mass (pmsm times (b2 s^2 + d s^mu + 1)/(c2 s^2 + d s^mu + 1): a compliant coupling),
    /// fopdt, auto (pmsm, commensurate, the integer first, second and third order and two-mass
    /// each fitted, the one the data support kept: held-out RMSE,
    /// then BIC among ties within 2%; the table is printed), or a
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
    #[arg(long, value_parser = crate::cmd::parse_order)]
    pub order: Option<usize>,
    /// Put a free integrator in series with the structure (K/(s (...))): for an output that
    /// integrates, such as a position; an input offset is then fitted too (a drift).
    #[arg(long)]
    pub integrator: bool,
    /// Hold parameters fixed: "NAME" or "NAME=VALUE", comma-separated (names as the report
    /// prints them: K, a1, a2, zeta, theta; b0, a0, a1_order, ... for a model; tau).
    #[arg(long)]
    pub fix: Option<String>,
    /// Fit parameters a structure holds fixed (comma-separated names).
    #[arg(long)]
    pub free: Option<String>,
    /// Fit an input delay (seconds, up to --max-delay); a delay written in the structure
    /// (exp(-tau s)) is then fitted from its value.
    #[arg(long)]
    pub delay: bool,
    /// Largest input delay (seconds) for --delay and fopdt (default: 1 s, at most a fifth of the
    /// record).
    #[arg(long)]
    pub max_delay: Option<f64>,
    /// Fraction of the record held out for validation (at the end); default 0.3, or 0 with
    /// --validate.
    #[arg(long)]
    pub holdout: Option<f64>,
    /// Another estimation record of the same plant (repeatable): all are fitted jointly, one
    /// model, each record with its own operating point, output offset and initial state; each is
    /// used whole (score on another record with --validate).
    #[arg(long)]
    pub joint: Vec<PathBuf>,
    /// A separate validation record (same columns): the fitted model is scored on it with its
    /// own initial state and output offset estimated, the plant's parameters held.
    #[arg(long)]
    pub validate: Option<PathBuf>,
    /// Operating point removal: initial (u[0], median y before the first input change), mean, none.
    #[arg(long, default_value = "initial")]
    pub offsets: String,
    /// Do not fit a constant output offset.
    #[arg(long)]
    pub no_offset: bool,
    /// Initial state of the plant at the first sample: estimate (the state a past held input
    /// left, fitted with the model: records that start in motion, mid-transient or on a ramp) or
    /// rest (at the operating point).
    #[arg(long, default_value = "estimate")]
    pub initial: String,
    /// Maximum Levenberg-Marquardt iterations.
    #[arg(long, default_value_t = 500)]
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
        None => ident::app::default_max_delay(duration),
    };
    let (mut m, _) = ident::app::structure(&a.structure, max_delay)?;
    m.approx.method = a.approx.parse()?;
    if let Some(n) = a.order {
        m.approx.order = n;
    }
    if let Some(b) = &a.band {
        m.approx.band = Some(ident::app::band(b)?);
    }
    if a.integrator {
        m.with_integrator();
    }
    if a.delay {
        // A delay written in the structure (exp(-tau s)) starts the fit when it is in range.
        let tau = m
            .delay
            .map(|i| m.params[i].value)
            .filter(|&t| t > 0.0 && t < max_delay)
            .unwrap_or(0.05 * max_delay);
        m.with_delay(tau, max_delay);
    }
    ident::app::fix_free(
        &mut m,
        a.fix.as_deref().unwrap_or(""),
        a.free.as_deref().unwrap_or(""),
    )?;
    Ok(m)
}

/// The reader options of `fracid time` (columns, `--dt`).
pub(crate) fn read_options(a: &TimeArgs) -> ReadOptions {
    ReadOptions {
        columns: a.columns.columns(),
        dt: a.dt,
    }
}

/// The identification options of `fracid time`.
pub(crate) fn ident_options(a: &TimeArgs) -> Result<IdentOptions> {
    let mut opts = IdentOptions {
        offsets: ident::app::offsets(&a.offsets)?,
        holdout: a
            .holdout
            .unwrap_or(if a.validate.is_some() { 0.0 } else { 0.3 }),
        fit_offset: !a.no_offset,
        start: if a.no_auto_start {
            StartMode::Given
        } else {
            StartMode::Auto
        },
        initial: a.initial.parse()?,
        ..Default::default()
    };
    opts.fit.lm.max_iterations = a.max_iter;
    Ok(opts)
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
    let read = read_options(&a);
    // The readers' caveats (an incomplete acquisition, the part kept) go into the report's
    // warnings, text and JSON alike; printed at once if the fit fails.
    let (rec, mut reader_warnings) = read_record_noting(&a.file, &read)?;
    let validation = match &a.validate {
        Some(p) => {
            let (v, w) = read_record_noting(p, &read)?;
            reader_warnings.extend(w);
            Some((p, v))
        }
        None => None,
    };
    let print_reader = |ws: &[String]| ws.iter().for_each(|w| eprintln!("warning: {w}"));
    let duration = rec.t.last().copied().unwrap_or(0.0) - rec.t.first().copied().unwrap_or(0.0);
    let model = model_of(&a, duration)?;
    let opts = ident_options(&a)?;
    let offsets = opts.offsets;
    if !a.joint.is_empty() {
        if a.diagnose || a.plot.is_some() {
            crate::bad_input!("--joint does not go with --diagnose or --plot");
        }
        let mut recs = vec![rec];
        for p in &a.joint {
            let (r, w) = read_record_noting(p, &read)?;
            reader_warnings.extend(w);
            recs.push(r);
        }
        let mut j = ident::oe::identify_joint(&recs, &model, &opts)
            .inspect_err(|_| print_reader(&reader_warnings))?;
        j.report.warnings.splice(0..0, reader_warnings);
        let scored = match &validation {
            Some((_, vrec)) => Some(ident::oe::score(&j.model, vrec, offsets, opts.initial)?),
            None => None,
        };
        let files: Vec<&PathBuf> = std::iter::once(&a.file).chain(&a.joint).collect();
        print_joint(
            &a,
            &j,
            &files,
            validation.as_ref().map(|v| v.0).zip(scored.as_ref()),
        )?;
        return Ok(());
    }
    let bar = if a.quiet || !std::io::stderr().is_terminal() {
        indicatif::ProgressBar::hidden()
    } else {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        b
    };
    let (auto, label) = ident::app::auto_label(&a.structure);
    if auto && a.integrator {
        crate::bad_input!("--structure auto does not go with --integrator (name a structure)");
    }
    let (id, auto_choice) = if auto && !a.diagnose {
        bar.set_message("fitting the candidate structures (on all cores)");
        bar.tick();
        let (id, c) = ident::diagnose::structures::fit_best(&rec, &model, &opts)
            .inspect_err(|_| print_reader(&reader_warnings))?;
        (id, Some(c))
    } else {
        let id = identify_with_progress(&rec, &model, &opts, &mut |k, rmse| {
            bar.set_message(format!("simulation {k}, rmse {rmse:.4e}"));
            bar.tick();
        })
        .inspect_err(|_| print_reader(&reader_warnings))?;
        (id, None)
    };
    bar.finish_and_clear();
    let (id, diagnosis) = if a.diagnose {
        let spin = if a.quiet || !std::io::stderr().is_terminal() {
            indicatif::ProgressBar::hidden()
        } else {
            let b = indicatif::ProgressBar::new_spinner();
            b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            b.enable_steady_tick(std::time::Duration::from_millis(120));
            b
        };
        let n = ident::diagnose::structures::candidates(label, &model).len();
        spin.set_message(format!(
            "diagnosing: {n} structures fitted and diagnosed (on all cores)"
        ));
        let d = super::diagnose::run_time(&rec, label, &model, id, &opts);
        spin.finish_and_clear();
        let d = d.inspect_err(|_| print_reader(&reader_warnings))?;
        (d.id, Some((d.diagnosis, d.choice)))
    } else {
        (id, None)
    };
    // The fit reported (with --diagnose, the chosen structure's): its warnings (the readers'
    // first), its score on a separate record.
    let mut id = id;
    id.report.warnings.splice(0..0, reader_warnings);
    for w in &id.report.warnings {
        eprintln!("warning: {w}");
    }
    let scored = match &validation {
        Some((_, vrec)) => Some(ident::oe::score(&id.model, vrec, offsets, opts.initial)?),
        None => None,
    };
    if let Some((p, _)) = &validation {
        id.validated_by = ident::oe::Validation {
            kind: ident::oe::ValidationKind::File,
            first: id.validated_by.first,
            note: format!(
                "a separate record, {} (its own initial state and output offset)",
                p.display()
            ),
        };
    }
    if a.json {
        let mut v = json_of(&id, &rec);
        if let (Some((p, _)), Some(sc)) = (&validation, &scored) {
            v["fit"]["validation_file"] = score_json(p, sc);
        }
        if let Some((d, c)) = &diagnosis {
            v = super::diagnose::lead_with_final(v, d, c, rec.dt)?;
        }
        if let Some(c) = &auto_choice {
            v["structures"] = serde_json::to_value(c)?;
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        if let Some((_, c)) = &diagnosis {
            println!(
                "base fit of the structure the diagnosis ran on ({}), before its effects:",
                c.scores[c.chosen].name
            );
        }
        if let Some(c) = &auto_choice {
            print!("{}", super::diagnose::structures_text(c, false));
            println!();
        }
        print_text(&id, &rec);
        if let (Some((p, _)), Some(sc)) = (&validation, &scored) {
            print_score(p, sc);
        }
        if let Some((d, c)) = &diagnosis {
            print!("{}", super::diagnose::structures_text(c, true));
            print!("{}", super::diagnose::text(d));
        }
    }
    if let Some(p) = &a.plot {
        plot::save(p, (1400, 1000), &TimeFigure { id: &id, rec: &rec })?;
        if let Some((d, _)) = &diagnosis {
            let dp = super::diagnose::residual_plot_path(p);
            super::diagnose::plot_time(&dp, &rec, d)?;
            if !a.json {
                println!("residual plot: {}", dp.display());
            }
        }
    }
    if !id.usable() {
        anyhow::bail!("the fitted model is not usable: {}", id.problems.join("; "));
    }
    Ok(())
}

/// Read a time record (t, u, y) from a file, its warnings (an incomplete acquisition fitted on
/// its longest complete part, ...) on stderr.
pub(crate) fn read_record(path: &std::path::Path, read: &ReadOptions) -> Result<Record> {
    let (record, warnings) = read_record_noting(path, read)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok(record)
}

/// [`read_record`] with its warnings returned (each `PATH: warning`) instead of printed.
pub(crate) fn read_record_noting(
    path: &std::path::Path,
    read: &ReadOptions,
) -> Result<(Record, Vec<String>)> {
    let loaded = crate::cmd::load_record(path, read)?;
    let warnings = loaded
        .warnings
        .iter()
        .map(|w| format!("{}: {w}", path.display()))
        .collect();
    Ok((loaded.record, warnings))
}

/// The joint fit of several records, as text or JSON.
fn print_joint(
    a: &TimeArgs,
    j: &ident::oe::JointIdentification,
    files: &[&PathBuf],
    scored: Option<(&PathBuf, &ident::oe::Scored)>,
) -> Result<()> {
    if a.json {
        let records: Vec<serde_json::Value> = files
            .iter()
            .zip(&j.records)
            .map(|(f, (op, fit, _))| {
                serde_json::json!({"file": f.display().to_string(), "offsets": op,
                    "rmse": fit.rmse, "nrmse_percent": fit.nrmse_percent})
            })
            .collect();
        let mut v = serde_json::json!({
            "model": ident::app::ModelReport::from(&j.tf),
            "params": j.report.params,
            "records": records,
            "converged": j.report.converged,
            "warnings": j.report.warnings,
        });
        if let Some((p, sc)) = scored {
            v["fit"] = serde_json::json!({"validation_file": score_json(p, sc)});
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!("model: {}", j.tf);
    println!("parameters (+- standard error):");
    for p in j.report.params.iter().filter(|p| p.free) {
        let se = p.std_error.map_or("-".to_string(), |s| format!("{s:.3e}"));
        println!("  {:<12} {:>14.6e} +- {se}", p.name, p.value);
    }
    for (f, (_, fit, _)) in files.iter().zip(&j.records) {
        println!(
            "fit on {}: NRMSE {:.2}%, RMSE {:.5}",
            f.display(),
            fit.nrmse_percent,
            fit.rmse
        );
    }
    if let Some((p, sc)) = scored {
        print_score(p, sc);
    }
    for w in &j.report.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// A model scored on a record, as JSON.
pub(crate) fn score_json(path: &std::path::Path, sc: &ident::oe::Scored) -> serde_json::Value {
    serde_json::json!({
        "file": path.display().to_string(),
        "rmse": sc.fit.rmse,
        "nrmse_percent": sc.fit.nrmse_percent,
        "offsets": sc.offsets,
        "record_params": sc.record_params,
        "warnings": sc.warnings,
    })
}

/// A model scored on a record, as text.
pub(crate) fn print_score(path: &std::path::Path, sc: &ident::oe::Scored) {
    println!(
        "fit on {} (its own initial state and output offset): NRMSE {:.2}%, RMSE {:.5}",
        path.display(),
        sc.fit.nrmse_percent,
        sc.fit.rmse
    );
    for w in &sc.warnings {
        eprintln!("warning: {w}");
    }
}

pub(crate) fn json_of(id: &Identification, rec: &Record) -> serde_json::Value {
    let fit = |f: Option<metrics::Fit>| {
        f.map(|f| serde_json::json!({"rmse": f.rmse, "nrmse_percent": f.nrmse_percent}))
    };
    serde_json::json!({
        "model": ident::app::ModelReport::from(&id.tf),
        "fit": {"estimation": fit(Some(id.estimation)), "validation": fit(id.validation)},
        "params": id.report.params,
        "start": id.start_report,
        "alpha_eta": id.alpha_eta.iter().map(|(o, a, e)| serde_json::json!({"order": o, "alpha": a, "eta": e})).collect::<Vec<_>>(),
        "offsets": id.offsets,
        "split": {"estimation_samples": id.split, "validation_samples": rec.len() - id.split},
        "validated_by": id.validated_by,
        "iterations": id.report.iterations,
        "converged": id.report.converged,
        "termination": id.report.termination,
        "stop_reason": id.report.stop_reason(),
        "seconds": id.report.elapsed.as_secs_f64(),
        "warnings": id.report.warnings,
        "usable": id.usable(),
        "problems": id.problems,
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
    let (state, plant): (Vec<_>, Vec<_>) = id
        .report
        .params
        .iter()
        .enumerate()
        .partition(|(i, _)| id.model.is_initial_state(*i));
    for (_, p) in plant {
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
    if let Some(past) = &id.model.past {
        let levels: Vec<String> = state
            .iter()
            .map(|(_, p)| {
                let tag = if p.at_bound { " (AT BOUND)" } else { "" };
                format!("{:.4}{tag}", p.value)
            })
            .collect();
        let edges: Vec<String> = past.edges.iter().map(|e| format!("{e:.4}")).collect();
        println!(
            "initial state: the past input's deviation (newest first) {} on windows ending {} s \
             before the record",
            levels.join(", "),
            edges.join(", ")
        );
    }
    for (o, al, et) in &id.alpha_eta {
        println!("  order {o:.4}: Poinot-Trigeassou alpha = {al:.5}, eta = {et:.5}");
    }
    println!(
        "fit estimation: NRMSE {:.2}%, RMSE {:.5}",
        id.estimation.nrmse_percent, id.estimation.rmse
    );
    if let Some(v) = id.validation {
        let what = match id.validated_by.kind {
            ident::oe::ValidationKind::ResponseTail => " (the tail of the step response only)",
            _ => "",
        };
        println!(
            "fit validation{what}: NRMSE {:.2}%, RMSE {:.5}",
            v.nrmse_percent, v.rmse
        );
    }
    println!("validated by: {}", id.validated_by.note);
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
