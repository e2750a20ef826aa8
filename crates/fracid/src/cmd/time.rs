//! `fracid time FILE`: time-domain identification by output error (docs/design.md §5, `ident::oe`).

use crate::plot::{self, Figure};
use anyhow::{Context, Result};
use fracsim::approx::Method;
use ident::app::observe::{Observe, Stage};
use ident::app::score::ScoreReport;
use ident::app::time::{Named, TimeData, TimeReport, TimeRequest};
use ident::app::{Held, Names, Preset, Structure};
use ident::data::{Columns, OffsetMode, ReadOptions, Record};
use ident::metrics;
use ident::oe::Identification;
use ident::oe::InitialState;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write as _;
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
    // Model structure: its help is the catalogue's ([`structure_help`]).
    #[arg(long, help = structure_help(), value_parser = crate::cmd::parse_word::<Structure>,
          default_value_t = TimeRequest::default().structure)]
    pub structure: Structure,
    /// Approximation of the fractional operators: refined (Xue's refined Oustaloup, the default),
    /// oustaloup or trigeassou (Poinot-Trigeassou); the model is then simulated exactly for the
    /// held input (see `fracid sim --help`).
    #[arg(long, value_parser = crate::cmd::parse_word::<Method>,
          default_value_t = TimeRequest::default().approx)]
    pub approx: Method,
    /// Approximation band "w_b,w_h" in rad/s (default fracsim's [1e-6/dt, 30 pi/dt]).
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
    #[arg(long, value_parser = crate::cmd::parse_word::<Held>)]
    pub fix: Option<Held>,
    /// Fit parameters a structure holds fixed (comma-separated names).
    #[arg(long, value_parser = crate::cmd::parse_word::<Names>)]
    pub free: Option<Names>,
    /// Fit an input delay (seconds, up to --max-delay); a delay written in the structure
    /// (exp(-tau s)) is then fitted from its value.
    #[arg(long)]
    pub delay: bool,
    /// Largest input delay (seconds) for --delay and fopdt (default: a fifth of the record, at
    /// most 1000 samples).
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
    #[arg(long, value_parser = crate::cmd::parse_word::<OffsetMode>,
          default_value_t = TimeRequest::default().offsets)]
    pub offsets: OffsetMode,
    /// Do not fit a constant output offset.
    #[arg(long)]
    pub no_offset: bool,
    /// Initial state of the plant at the first sample: auto (rest when the record rests before
    /// its first input change, input constant and output steady; else estimate), estimate (the
    /// state a past held input left, fitted with the model: records that start in motion,
    /// mid-transient or on a ramp) or rest (at the operating point).
    #[arg(long, value_parser = crate::cmd::parse_word::<InitialState>,
          default_value_t = TimeRequest::default().initial)]
    pub initial: InitialState,
    /// Maximum Levenberg-Marquardt iterations of every fit (the diagnosis's refits take at most
    /// 60, or this when it is smaller).
    #[arg(long, default_value_t = TimeRequest::default().max_iterations)]
    pub max_iter: usize,
    /// Start from the given structure's values instead of the automatic start.
    #[arg(long)]
    pub no_auto_start: bool,
    /// Start values "NAME=VALUE,..." (names as the report prints them): the fit starts from
    /// them instead of the automatic start.
    #[arg(long)]
    pub start: Option<String>,
    /// Samples at the start of the estimation part left out of the cost (a transient the model
    /// need not explain).
    #[arg(long, default_value_t = TimeRequest::default().skip)]
    pub skip: usize,
    /// Lags of the residual whiteness and cross-correlation test (JSON `residual_test`).
    #[arg(long, default_value_t = TimeRequest::default().max_lag)]
    pub max_lag: usize,
    /// The diagnosis's margin (not with --plain): the held-out improvement an effect must bring (fraction of the RMSE).
    #[arg(long, default_value_t = TimeRequest::default().margin)]
    pub margin: f64,
    /// The diagnosis's evidence (not with --plain): the R^2 a candidate effect needs to be refitted.
    #[arg(long, default_value_t = TimeRequest::default().min_r2)]
    pub min_r2: f64,
    /// The diagnosis's rounds of effects (not with --plain).
    #[arg(long, default_value_t = TimeRequest::default().max_rounds)]
    pub max_rounds: usize,
    /// Print JSON (docs/design.md §7) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write a plot (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Fit the named structure alone, once (no structures compared, no diagnosis): the fast
    /// path for fleets of records already understood. Without it (the default) the candidate
    /// structures are compared, the best is diagnosed (the effects that pay on held-out data
    /// kept, docs/design.md §6) and the report leads with that model; with --plot the residual
    /// before and after is drawn to PLOT_diagnosis.EXT.
    #[arg(long)]
    pub plain: bool,
    /// The default (the loop closed), named: kept so that scripts that ask for it run.
    #[arg(long, conflicts_with = "plain")]
    pub diagnose: bool,
    /// Fleet mode (many files at once): see `fracid::cmd::fleet`.
    #[command(flatten)]
    pub fleet: super::fleet::FleetArgs,
}

/// The help of `--structure`: the catalogue's structures ([`Preset`]), `auto`, the general
/// structure and a transfer function.
fn structure_help() -> String {
    let compared: Vec<&str> = ident::diagnose::structures::compared()
        .map(Preset::name)
        .collect();
    let compared = compared.join(", ");
    format!(
        "Model structure: {}, auto ({compared}, and feedthrough when the record shows an instant \
         response, each fitted, the one the data support kept: held-out RMSE, then BIC among \
         ties within 2%; the table is printed), general (a general transfer function \
         (b0 + .. + bN s^(N q))/(1 + .. + aD s^(D q)), with an integrator when the data call for \
         it, its size chosen by held-out error and BIC from a frequency-response start), \
         general:N/D (that size), or a transfer function such as \
         \"6.8/(3e-5 s^1.75 + 0.006 s^0.9 + 1)\" used as the start. Other spellings of the \
         names are taken (second_order, \"second order\")",
        Preset::described()
    )
}

/// The use-case request of `fracid time`'s options (every default is the request's own,
/// `TimeRequest::default()`).
///
/// # Errors
/// A band that is not two numbers, a `--start` item that is not `NAME=VALUE`.
pub(crate) fn request(a: &TimeArgs) -> Result<TimeRequest> {
    let mut start = std::collections::BTreeMap::new();
    for item in a.start.as_deref().unwrap_or("").split(',').map(str::trim) {
        if item.is_empty() {
            continue;
        }
        let Some((name, v)) = item.split_once('=') else {
            crate::bad_input!("--start '{item}' must be NAME=VALUE");
        };
        let Ok(v) = v.trim().parse::<f64>() else {
            crate::bad_input!("--start '{item}': '{}' is not a number", v.trim());
        };
        start.insert(name.trim().to_string(), v);
    }
    let d = TimeRequest::default();
    Ok(TimeRequest {
        structure: a.structure.clone(),
        approx: a.approx,
        band: a.band.as_deref().map(ident::app::band).transpose()?,
        order: a.order,
        integrator: a.integrator,
        delay: a.delay,
        max_delay: a.max_delay,
        fix: a.fix.clone().unwrap_or(d.fix),
        free: a.free.clone().unwrap_or(d.free),
        start,
        auto_start: !a.no_auto_start,
        holdout: a.holdout,
        offsets: a.offsets,
        fit_offset: !a.no_offset,
        initial: a.initial,
        max_iterations: a.max_iter,
        skip: a.skip,
        max_lag: a.max_lag,
        plain: a.plain,
        margin: a.margin,
        min_r2: a.min_r2,
        max_rounds: a.max_rounds,
    })
}

/// The reader options of `fracid time` (columns, `--dt`).
pub(crate) fn read_options(a: &TimeArgs) -> ReadOptions {
    ReadOptions {
        columns: a.columns.columns(),
        dt: a.dt,
    }
}

/// The records of `fracid time` (`FILE`, `--validate`) with the readers' caveats.
///
/// # Errors
/// As [`read_record_noting`].
pub(crate) fn time_data(file: &std::path::Path, a: &TimeArgs) -> Result<TimeData> {
    let read = read_options(a);
    let (record, mut reader_warnings) = read_record_noting(file, &read)?;
    let validation = match &a.validate {
        Some(p) => {
            let (v, w) = read_record_noting(p, &read)?;
            reader_warnings.extend(w);
            Some(Named {
                name: p.display().to_string(),
                record: v,
            })
        }
        None => None,
    };
    Ok(TimeData {
        record,
        validation,
        joint: Vec::new(),
        reader_warnings,
    })
}

/// The progress of `fracid time` on the terminal: a spinner with the stage and the fit's RMSE.
struct Spinner(indicatif::ProgressBar);

impl Spinner {
    fn new(quiet: bool) -> Self {
        Self(if quiet || !std::io::stderr().is_terminal() {
            indicatif::ProgressBar::hidden()
        } else {
            let b = indicatif::ProgressBar::new_spinner();
            b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            b.enable_steady_tick(std::time::Duration::from_millis(120));
            b
        })
    }
}

impl Observe for Spinner {
    fn stage(&mut self, stage: Stage) {
        self.0.set_message(stage.to_string());
    }
    fn simulation(&mut self, k: usize, rmse: f64) {
        self.0
            .set_message(format!("simulation {k}, rmse {rmse:.4e}"));
    }
}

/// Run `fracid time`.
///
/// # Errors
/// Unreadable file (exit 3), bad data or options (exit 2), numerical breakdown (exit 1).
pub fn run(a: TimeArgs) -> Result<()> {
    if a.fleet.active(&a.file) {
        return run_fleet(a);
    }
    check_paths(&a)?;
    if let Some(p) = &a.plot {
        plot::format_of(p)?;
    }
    let req = request(&a)?;
    // The readers' caveats (an incomplete acquisition, the part kept) go into the report's
    // warnings, text and JSON alike; printed at once if the fit fails.
    let data = time_data(&a.file, &a)?;
    let print_reader = || {
        data.reader_warnings
            .iter()
            .for_each(|w| eprintln!("warning: {w}"))
    };
    if !a.joint.is_empty() {
        let warnings = data.reader_warnings.clone();
        return run_joint(&a, &req, data).inspect_err(|_| {
            warnings.iter().for_each(|w| eprintln!("warning: {w}"));
        });
    }
    let mut spin = Spinner::new(a.quiet);
    let r = ident::app::time::run(&req, &data, &mut spin);
    spin.0.finish_and_clear();
    let r = r.inspect_err(|_| print_reader())?;
    let files = [r.base.as_ref(), Some(&r.lead)].into_iter().flatten();
    let file_warnings = files.filter_map(|m| m.fit.validation_file.as_ref());
    for w in r
        .lead
        .warnings
        .iter()
        .chain(file_warnings.flat_map(|sc| &sc.warnings))
    {
        eprintln!("warning: {w}");
    }
    let rec = &data.record;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", report_text(&r, rec));
    }
    if let Some(p) = &a.plot {
        if let Some(dp) = plot_report(p, &r, rec)? {
            if !a.json {
                println!("residual plot: {}", dp.display());
            }
        }
    }
    if !r.lead.usable {
        anyhow::bail!(
            "the fitted model is not usable: {}",
            r.lead.problems.join("; ")
        );
    }
    Ok(())
}

/// No plot overwrites a record ([`super::paths::check`]): the record, `--validate` and `--joint`
/// against `--plot` and, unless `--plain` (or `--joint`), the residual plot beside it.
fn check_paths(a: &TimeArgs) -> Result<()> {
    let mut inputs = vec![("the record", a.file.as_path())];
    inputs.extend(a.validate.iter().map(|p| ("--validate", p.as_path())));
    inputs.extend(a.joint.iter().map(|p| ("--joint", p.as_path())));
    super::paths::check_plots(&inputs, a.plot.as_deref(), !a.plain && a.joint.is_empty())
}

/// The report as text (what `fracid time` prints): the base fit, the scores on a validation
/// record, the structure comparison and the diagnosis.
pub(crate) fn report_text(r: &TimeReport, rec: &Record) -> String {
    let mut o = String::new();
    if let Some(d) = &r.diagnosis {
        let _ = writeln!(
            o,
            "base fit of the structure the diagnosis ran on ({}), before its effects:",
            d.structures.scores[d.structures.chosen].name
        );
    }
    if let Some(c) = &r.structures {
        o += &super::diagnose::structures_text(c, false);
        o.push('\n');
    }
    o += &fit_text(&r.fitted.id, rec);
    let base = r.base.as_ref().unwrap_or(&r.lead);
    if let Some(sc) = &base.fit.validation_file {
        o += &score_text(sc);
    }
    if let Some(d) = &r.diagnosis {
        o += &super::diagnose::structures_text(&d.structures, true);
        o += &super::diagnose::text(&d.diagnosis);
        if let Some(sc) = &r.lead.fit.validation_file {
            o += "  final model ";
            o += &score_text(sc);
        }
    }
    o
}

/// Draw the fit to `path` (.png or .svg), and with the diagnosis the residual before and after
/// beside it (its path returned).
///
/// # Errors
/// A bad extension, a drawing or file error.
pub(crate) fn plot_report(
    path: &std::path::Path,
    r: &TimeReport,
    rec: &Record,
) -> Result<Option<PathBuf>> {
    plot::save(
        path,
        (1400, 1000),
        &TimeFigure {
            id: &r.fitted.id,
            rec,
        },
    )?;
    match &r.diagnosis {
        Some(d) => {
            let dp = super::diagnose::residual_plot_path(path);
            super::diagnose::plot_time(&dp, rec, &d.diagnosis)?;
            Ok(Some(dp))
        }
        None => Ok(None),
    }
}

/// `fracid time` on many files: each fitted in this process exactly as `fracid time FILE --json`
/// would (the same options), on a pool of threads.
///
/// # Errors
/// As [`super::fleet::run`].
fn run_fleet(a: TimeArgs) -> Result<()> {
    if a.plot.is_some() {
        crate::bad_input!("--plot draws one record: not with many files");
    }
    let mut paths = vec![a.file.clone()];
    paths.extend(a.fleet.more.iter().cloned());
    let files = super::fleet::expand(&paths)?;
    super::fleet::run("time", &files, &a.fleet, a.json, |f| fleet_report(&a, f))
}

/// One file's `fracid time --json` report, with the options of `a`: the same request and
/// `ident::app::time::run` as `fracid time FILE`, in this process; the summary from the typed
/// report.
fn fleet_report(a: &TimeArgs, file: &std::path::Path) -> Result<super::fleet::Fitted> {
    let req = request(a)?;
    let data = time_data(file, a)?;
    let r = ident::app::time::run(&req, &data, &mut ident::app::observe::Quiet)
        .with_context(|| format!("identifying {}", file.display()))?;
    let mut report = serde_json::to_value(&r)?;
    report["file"] = serde_json::json!(file.display().to_string());
    Ok(super::fleet::Fitted {
        report,
        summary: fleet_summary(&r),
        problems: if r.lead.usable {
            Vec::new()
        } else {
            r.lead.problems.clone()
        },
    })
}

/// The fleet's summary of a report: the model it leads with (the diagnosis's final model, else
/// the fit's), its fits, the effects kept, the warnings.
fn fleet_summary(r: &TimeReport) -> super::fleet::Summary {
    let diagnosis = r.diagnosis.as_ref();
    super::fleet::Summary {
        model: Some(diagnosis.map_or(&r.lead.model, |d| &d.model).text.clone()),
        fit_estimation_percent: Some(r.lead.fit.estimation.nrmse_percent),
        fit_validation_percent: r.lead.fit.validation.map(|f| f.nrmse_percent),
        j: None,
        effects: diagnosis.map_or_else(Vec::new, |d| {
            d.diagnosis.effects.iter().map(|e| e.name.clone()).collect()
        }),
        warnings: r.lead.warnings.clone(),
    }
}

/// `--joint`: one model fitted on several records (`ident::app::time::run_joint`).
fn run_joint(a: &TimeArgs, req: &TimeRequest, data: TimeData) -> Result<()> {
    if a.plot.is_some() {
        crate::bad_input!("--joint does not go with --plot");
    }
    if a.diagnose {
        crate::bad_input!("--joint fits the named structure once: it does not go with --diagnose");
    }
    let read = read_options(a);
    let mut data = data;
    for p in &a.joint {
        let (r, w) = read_record_noting(p, &read)?;
        data.reader_warnings.extend(w);
        data.joint.push(Named {
            name: p.display().to_string(),
            record: r,
        });
    }
    let first = a.file.display().to_string();
    let j = ident::app::time::run_joint(req, &data, &first, &mut Spinner::new(a.quiet))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!("model: {}", j.model.text);
        println!("parameters (+- standard error):");
        for p in j.params.iter().filter(|p| p.free) {
            let se = p.std_error.map_or("-".to_string(), |s| format!("{s:.3e}"));
            println!("  {:<12} {:>14.6e} +- {se}", p.name, p.value);
        }
        for r in &j.records {
            println!(
                "fit on {}: NRMSE {:.2}%, RMSE {:.5}",
                r.file, r.nrmse_percent, r.rmse
            );
        }
        if let Some(sc) = j.fit.as_ref().and_then(|f| f.validation_file.as_ref()) {
            print!("{}", score_text(sc));
        }
    }
    let file_warnings = j.fit.iter().filter_map(|f| f.validation_file.as_ref());
    for w in j
        .warnings
        .iter()
        .chain(file_warnings.flat_map(|sc| &sc.warnings))
    {
        eprintln!("warning: {w}");
    }
    if !j.usable {
        anyhow::bail!("the fitted model is not usable: {}", j.problems.join("; "));
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

/// A model scored on a record, as a line of text (its warnings are in the report's).
pub(crate) fn score_text(sc: &ScoreReport) -> String {
    format!(
        "fit on {} (its own initial state and output offset): NRMSE {:.2}%, RMSE {:.5}\n",
        sc.file, sc.nrmse_percent, sc.rmse
    )
}

/// The fit as text.
fn fit_text(id: &Identification, rec: &Record) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "model: {}", id.tf);
    let _ = writeln!(
        o,
        "operating point: u0 = {:.6}, y0 = {:.6}; {} estimation + {} validation samples, dt = {} s",
        id.offsets.u0,
        id.offsets.y0,
        id.validated_by.estimation_samples(id.split),
        rec.len() - id.validated_by.estimation_samples(id.split),
        rec.dt
    );
    let sr = &id.start_report;
    let _ = writeln!(
        o,
        "start: {}{}",
        sr.note,
        sr.fit_percent
            .map_or(String::new(), |f| format!(" (start fits {f:.1}%)"))
    );
    let _ = writeln!(o, "parameters (+- standard error):");
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
        let _ = writeln!(o, "  {:<10} {:>14.6e} +- {se}{tag}", p.name, p.value);
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
        let _ = writeln!(
            o,
            "initial state: the past input's deviation (newest first) {} on windows ending {} s \
             before the record",
            levels.join(", "),
            edges.join(", ")
        );
    }
    let _ = writeln!(
        o,
        "initial state {}: {}",
        id.initial.state, id.initial.reason
    );
    for (order, al, et) in &id.alpha_eta {
        let _ = writeln!(
            o,
            "  order {order:.4}: Poinot-Trigeassou alpha = {al:.5}, eta = {et:.5}"
        );
    }
    let _ = writeln!(
        o,
        "fit estimation: NRMSE {:.2}%, RMSE {:.5}",
        id.estimation.nrmse_percent, id.estimation.rmse
    );
    if let Some(v) = id.validation {
        let what = match id.validated_by.kind {
            ident::oe::ValidationKind::ResponseTail => " (the tail of the step response only)",
            _ => "",
        };
        let _ = writeln!(
            o,
            "fit validation{what}: NRMSE {:.2}%, RMSE {:.5}",
            v.nrmse_percent, v.rmse
        );
    }
    let _ = writeln!(o, "validated by: {}", id.validated_by.note);
    let _ = writeln!(
        o,
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
    o
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
