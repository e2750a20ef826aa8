//! `fracid drive autotune`: the probe, the identification experiment designed from it, the
//! experiments that separate what the diagnosis cannot tell apart, the controller tuned on the
//! final model and its step measured on the drive ([`autotune::tuner`]). This module parses the
//! flags into an [`AutotuneRequest`], runs it under a signal handler that stops the drive, and
//! presents the report (text, `--json`, `report.md` with plots).

use crate::cmd::drive_io::{autotune_err, check_outputs, connect, LinkArgs, PortArgs};
use crate::interrupt::{Interrupted, StopOnInterrupt};
use crate::plot::{self, Figure, Line, Look, TimeChart};
use anyhow::{Context, Result};
use autotune::tuner::{self, report::AutotuneReport, AutotuneRequest, FilterChoice};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Options of `fracid drive autotune`.
#[derive(Debug, clap::Args)]
pub struct AutotuneArgs {
    /// The serial link.
    #[command(flatten)]
    pub link: LinkArgs,
    /// Voltage limit, V: the drive's clamp (the experiments stay within 80% of it).
    /// Default 12.
    #[arg(long)]
    pub u_limit: Option<f64>,
    /// Speed limit, rad/s: the drive's speed trip (the experiments aim below 80% of it).
    /// Default 200.
    #[arg(long)]
    pub speed_limit: Option<f64>,
    /// Drive time all experiments may take, s. Default 20.
    #[arg(long)]
    pub budget: Option<f64>,
    /// Crossover, rad/s (default: chosen from the model's bandwidth, delay, sample rate and
    /// resonances).
    #[arg(long)]
    pub wc: Option<f64>,
    /// Phase margin, degrees (default 60).
    #[arg(long)]
    pub pm: Option<f64>,
    /// The identification's operating point, V (default: half the voltage the speed limit
    /// allows).
    #[arg(long)]
    pub operating_point: Option<f64>,
    /// Rounds of experiments after the first. Default 3.
    #[arg(long)]
    pub max_rounds: Option<usize>,
    /// For a resonance of the final model: a notch at it in the controller (`notch`), a
    /// first-order low-pass at half its frequency (`low-pass`), no filter and the crossover a
    /// fifth of it (`none`), or the notch when its loop is faster than the lower crossover's
    /// (`auto`).
    #[arg(long, value_enum, default_value_t = FilterArg::Auto)]
    pub filter: FilterArg,
    /// Write the report as JSON to standard output (the text goes to standard error).
    #[arg(long)]
    pub json: bool,
    /// Folder for `report.md`, `report.json` and the plots (created).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `--filter`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FilterArg {
    /// The notch when its loop is faster.
    Auto,
    /// A notch at the resonance.
    Notch,
    /// A low-pass at half the resonance.
    LowPass,
    /// No filter: a lower crossover.
    None,
}

impl From<FilterArg> for FilterChoice {
    fn from(f: FilterArg) -> Self {
        match f {
            FilterArg::Auto => FilterChoice::Auto,
            FilterArg::Notch => FilterChoice::Notch,
            FilterArg::LowPass => FilterChoice::LowPass,
            FilterArg::None => FilterChoice::None,
        }
    }
}

impl AutotuneArgs {
    /// The request of the options (the library's defaults where a flag is absent).
    pub fn request(&self) -> AutotuneRequest {
        let d = AutotuneRequest::default();
        AutotuneRequest {
            u_limit_v: self.u_limit.unwrap_or(d.u_limit_v),
            speed_limit_rad_s: self.speed_limit.unwrap_or(d.speed_limit_rad_s),
            budget_s: self.budget.unwrap_or(d.budget_s),
            wc: self.wc,
            pm_deg: self.pm,
            operating_point_v: self.operating_point,
            max_rounds: self.max_rounds.unwrap_or(d.max_rounds),
            filter: self.filter.into(),
            ..d
        }
    }

    fn port_args(&self, req: &AutotuneRequest) -> PortArgs {
        PortArgs {
            link: self.link.clone(),
            block: 32,
            u_limit: req.u_limit_v,
            quiet: self.quiet,
        }
    }
}

/// Progress on standard error; a signal cancels between experiments.
struct Observer<'a> {
    quiet: bool,
    signals: &'a StopOnInterrupt,
}

impl tuner::Observe for Observer<'_> {
    fn stage(&mut self, what: &str) {
        if !self.quiet {
            crate::eprintln_safe!("autotune: {what}");
        }
    }
    fn cancelled(&self) -> bool {
        self.signals.signal().is_some()
    }
}

/// `fracid drive autotune`.
///
/// # Errors
/// Bad options (exit 2), the port or the outputs (exit 3), the drive's failures, no usable
/// controller (exit 1, after the report), a signal (128 + N, the drive stopped).
pub fn run(a: AutotuneArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    let req = a.request();
    req.check().map_err(autotune_err)?;
    let port = a.port_args(&req);
    let conf = crate::cmd::drive_io::port_conf(&port)?;
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let outs = ["report.md", "report.json", "step.png", "records.png"].map(|f| dir.join(f));
        let named: Vec<(&str, &Path)> = outs.iter().map(|p| ("--out", p.as_path())).collect();
        check_outputs(&a.link.port, &[], &named)?;
    }
    let mut client = connect(&port, &conf)?;
    let signals = StopOnInterrupt::arm(client.stop_handle());
    let mut obs = Observer {
        quiet: a.quiet,
        signals: &signals,
    };
    let out = tuner::run(&mut client, a.link.sample_rate, &req, &mut obs);
    let signal = signals.signal();
    drop(signals);
    drop(client);
    if let Some(signal) = signal {
        return Err(Interrupted {
            signal,
            message: "the autotune was stopped; the drive is stopped".into(),
        }
        .into());
    }
    let report = out.map_err(autotune_err)?;
    present(&a, &report)?;
    if report.usable {
        Ok(())
    } else {
        Err(anyhow::anyhow!(
            "no usable controller: {}",
            report.problems.join("; ")
        ))
    }
}

fn present(a: &AutotuneArgs, r: &AutotuneReport) -> Result<()> {
    let text = r.text();
    if a.json {
        let mut out = std::io::stdout().lock();
        serde_json::to_writer_pretty(&mut out, r)?;
        writeln!(out)?;
        out.flush().context("writing to stdout")?;
        crate::eprintln_safe!("{}", text.trim_end());
    } else {
        let mut out = std::io::stdout().lock();
        write!(out, "{text}")?;
        out.flush().context("writing to stdout")?;
    }
    if let Some(dir) = &a.out {
        write_folder(dir, r, &text)?;
    }
    Ok(())
}

/// `report.md` (the text round by round, and the plots), `report.json`, `records.png` (each
/// record beside the final model) and `step.png` (the step predicted and measured).
fn write_folder(dir: &Path, r: &AutotuneReport, text: &str) -> Result<()> {
    let json = serde_json::to_string_pretty(r)?;
    let jp = dir.join("report.json");
    std::fs::write(&jp, json + "\n").with_context(|| format!("writing {}", jp.display()))?;
    let mut md = String::from("# fracid drive autotune\n\n```text\n");
    md += text;
    md += "```\n\n";
    if !r.series.records.is_empty() {
        plot::save(
            &dir.join("records.png"),
            (1000, 300 * r.series.records.len().min(6) as u32),
            &Records(r),
        )?;
        md += "## The records and the final model\n\n![records](records.png)\n\n";
    }
    if let Some((t, p, m)) = &r.series.step {
        let step = super::demo_loop::LoopFigure {
            t,
            predicted: p,
            measured: m,
            labels: ["predicted (fracid tune, final model)", "measured (drive)"],
            look: LOOK,
        };
        plot::save(&dir.join("step.png"), (1000, 600), &step)?;
        md += "## The step: predicted and measured on the drive\n\n![step](step.png)\n";
    }
    let mp = dir.join("report.md");
    std::fs::write(&mp, md).with_context(|| format!("writing {}", mp.display()))?;
    Ok(())
}

const LOOK: Look = Look {
    caption: 20,
    labels: Some(14),
    margin: 8,
    x_area: 40,
    y_area: 60,
};

struct Records<'a>(&'a AutotuneReport);

impl Figure for Records<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let recs = &self.0.series.records[..self.0.series.records.len().min(6)];
        let areas = root.split_evenly((recs.len(), 1));
        for (rec, area) in recs.iter().zip(&areas) {
            let title = format!("{}: measured and the final model", rec.name);
            plot::time_series_chart(
                area,
                &TimeChart {
                    title: Some(&title),
                    x_desc: "time (s)",
                    y_desc: Some("speed (rad/s)"),
                    t: &rec.t,
                    lines: &[
                        Line {
                            label: Some("measured"),
                            values: &rec.y,
                            style: RED.stroke_width(1),
                        },
                        Line {
                            label: Some("final model"),
                            values: &rec.yhat,
                            style: BLUE.stroke_width(2),
                        },
                    ],
                    marker: None,
                    look: LOOK,
                },
            )?;
        }
        Ok(())
    }
}
