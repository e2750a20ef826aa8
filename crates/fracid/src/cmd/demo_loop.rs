//! The last step of `fracid demo`: a FOPI tuned on the identified model (`fracid tune`, wc = 50
//! rad/s, pm = 60 deg, sampled at the drive's rate) run on the drive in a speed loop (`fracid
//! drive loop`), the step tune predicts beside the step measured.
//!
//! Kept apart from `demo.rs`: [`run`] takes the drive's port, the model and the output folder and
//! returns the report's lines and the figure's path.

use crate::cmd::drive_io::autotune_err;
use crate::plot::{self, Figure, Line, Look, TimeChart};
use anyhow::{Context, Result};
use autotune::acquire::speed_loop::{self, LoopRequest};
use autotune::realise::{self, MeasuredStep, Realisation};
use drive::client::{Client, ClientConfig, LazyFile, LoopCsvSink};
use drive::protocol::Configure;
use fracsim::FracTf;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use tune::closed::StepMetrics;
use tune::report::{Report, Runs, SimOptions};
use tune::{Form, Spec};

/// The demo's loop: crossover (rad/s), phase margin (deg), the reference step (rad/s), time at
/// reference 0 before it and the record's length (s).
pub const WC: f64 = 50.0;
/// Phase margin, degrees.
pub const PM_DEG: f64 = 60.0;
/// The reference step, rad/s.
pub const STEP: f64 = 50.0;
/// Time at reference 0 before the step, s.
pub const PRE_S: f64 = 0.1;
/// The record, s.
pub const DURATION_S: f64 = 0.6;

/// What the step adds to the demo's report.
#[derive(Debug, Clone)]
pub struct DemoLoop {
    /// Markdown lines for the report (a heading, the controller, predicted and measured side by
    /// side, the files).
    pub lines: Vec<String>,
    /// The figure (predicted and measured steps), if the loop ran.
    pub figure: Option<PathBuf>,
    /// The record `t,r,u,y`, if the loop ran.
    pub record: Option<PathBuf>,
}

/// Open the drive at `port` with `client_cfg` (its own client: call it after the demo's client
/// is closed, the port is opened exclusively; the demo passes the simulator's virtual clock in
/// it) and run [`run_with`].
///
/// # Errors
/// As [`run_with`]; the port does not open.
pub fn run(
    port: &str,
    client_cfg: ClientConfig,
    sample_rate_hz: u32,
    model: &FracTf,
    dir: &Path,
) -> Result<DemoLoop> {
    let mut client =
        Client::open(port, client_cfg).context("cannot open the drive for the tuned loop")?;
    let conf = Configure {
        sample_rate_hz,
        ..Configure::default()
    };
    client.configure(&conf).context("CONFIGURE failed")?;
    run_with(&mut client, &conf, model, dir)
}

/// The demo's FOPI on `model` at the drive's rate: the tuner's report and runs, or why it was
/// refused.
fn design(model: &FracTf, conf: &Configure) -> std::result::Result<(Report, Runs), String> {
    let dt = 1.0 / conf.sample_rate_hz as f64;
    let spec = Spec {
        form: Form::Fopi,
        wc: WC,
        pm_deg: PM_DEG,
        flat: false,
        t_high: None,
        s_low: None,
        dt: Some(dt),
        lambda: None,
        floors: tune::Floors::default(),
        orders: tune::Orders::default(),
    };
    let opts = SimOptions {
        step: Some(STEP),
        u_limit: Some(conf.u_limit as f64 * conf.u_lsb()),
        ..SimOptions::default()
    };
    tune::report::tune(model, &spec, &opts).map_err(|e| e.to_string())
}

/// Tune a FOPI on `model` for the drive's rate, run it on the drive behind `client` (configured
/// with `conf`), write `loop.csv` and `loop.png` into `dir`. A design the tuner refuses is
/// reported in the lines, not an error.
///
/// # Errors
/// The drive's errors (download, run), the files.
pub fn run_with(
    client: &mut Client,
    conf: &Configure,
    model: &FracTf,
    dir: &Path,
) -> Result<DemoLoop> {
    let dt = 1.0 / conf.sample_rate_hz as f64;
    let mut lines = vec![
        "## The tuned loop on the drive\n".to_string(),
        format!(
            "A FOPI designed by `fracid tune` on the identified model for wc = {WC} rad/s, pm = \
             {PM_DEG} deg, sampled every {dt} s (`--dt`), downloaded to the drive as fixed-point \
             sections and run in a speed loop (`fracid drive loop`): the reference 0 for {PRE_S} s, \
             then a step of {STEP} rad/s.\n"
        ),
    ];
    let (report, runs) = match design(model, conf) {
        Ok(r) => r,
        Err(e) => {
            lines.push(format!("The design was refused: {e}.\n"));
            return Ok(DemoLoop {
                lines,
                figure: None,
                record: None,
            });
        }
    };
    let Some(disc) = &report.discrete else {
        anyhow::bail!("the tuner gave no discrete realisation for --dt {dt}");
    };
    let real = Realisation::of_discrete(disc, &report.controller.text);
    let (pruned, dropped) = realise::prune(&real);
    let k = realise::fixed_controller(&pruned, conf).map_err(autotune_err)?;
    let qerr = realise::quantisation_error(&real, &k, conf);
    let req = LoopRequest {
        step_rad_s: STEP,
        pre_s: PRE_S,
        duration_s: DURATION_S,
    };
    let cmd = req.command(conf).map_err(autotune_err)?;
    let record = dir.join("loop.csv");
    let mut sink = LoopCsvSink::new(
        LazyFile::new(&record).with_context(|| record.display().to_string())?,
        cmd,
        conf.y_lsb(),
    );
    let acq = speed_loop::run(client, conf, &k, &req, &mut sink)
        .map_err(autotune_err)?
        .acquisition;
    sink.into_inner()
        .and_then(|mut f| std::io::Write::flush(&mut f))
        .with_context(|| format!("writing {}", record.display()))?;
    lines.push(format!(
        "Controller: C(s) = {} (kp = {:.4}, ki = {:.4}, lambda = {:.4}); {} sections on the \
         drive{}, frequency response within {:.1e} of the realisation.\n",
        report.controller.text,
        report.params.kp,
        report.params.ki,
        report.params.lambda,
        k.sections.len(),
        if dropped.is_empty() {
            String::new()
        } else {
            format!(" ({} negligible state(s) left out)", dropped.len())
        },
        qerr
    ));
    let measured = realise::measured_step(&acq, &cmd, conf.y_lsb());
    lines.extend(step_table(report.step.metrics, measured.as_ref()));
    lines.push(format!(
        "Record `{}`: {}{}.\n",
        record.file_name().unwrap_or_default().to_string_lossy(),
        acq.footer().trim_start_matches("# "),
        if acq.clamped_blocks > 0 {
            "; the drive clamped the voltage (anti-windup engaged)"
        } else {
            ""
        }
    ));
    let figure = figure(dir, dt, &report, &runs, measured.as_ref(), &mut lines)?;
    Ok(DemoLoop {
        lines,
        figure,
        record: Some(record),
    })
}

/// The table of the step predicted and measured.
fn step_table(predicted: Option<StepMetrics>, measured: Option<&MeasuredStep>) -> Vec<String> {
    let fmt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4} s"));
    let mut lines = vec![
        "| step | overshoot | rise 10-90% | settling 2% |".to_string(),
        "|---|---:|---:|---:|".into(),
    ];
    if let Some(m) = predicted {
        lines.push(format!(
            "| predicted (tune's simulation of the sampled loop on the identified model) | {:.2}% | {} | {} |",
            m.overshoot_percent,
            fmt(m.rise_time),
            fmt(m.settling_time)
        ));
    }
    if let Some(m) = measured {
        lines.push(format!(
            "| measured on the drive | {:.2}% | {} | {} |",
            m.overshoot_percent,
            fmt(m.rise_time),
            fmt(m.settling_time)
        ));
    }
    lines.push(String::new());
    lines
}

/// `loop.png`: the step predicted (at the drive's sample instants) and measured, its line added
/// to the report's.
fn figure(
    dir: &Path,
    dt: f64,
    report: &Report,
    runs: &Runs,
    measured: Option<&MeasuredStep>,
    lines: &mut Vec<String>,
) -> Result<Option<PathBuf>> {
    let (Some(run), Some(MeasuredStep { t, y, .. })) = (&runs.design, measured) else {
        return Ok(None);
    };
    let path = dir.join("loop.png");
    // the prediction at the drive's sample instants (its fine step divides dt)
    let m = (dt / report.step.setup.h).round().max(1.0) as usize;
    let pred: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, _)| run.y.get(i * m).copied().unwrap_or(f64::NAN))
        .collect();
    plot::save(
        &path,
        (1000, 600),
        &LoopFigure {
            t,
            predicted: &pred,
            measured: y,
            labels: ["predicted (fracid tune)", "measured (fracid drive loop)"],
            look: Look {
                caption: 22,
                labels: Some(16),
                margin: 10,
                x_area: 45,
                y_area: 60,
            },
        },
    )?;
    lines.push(format!(
        "![predicted and measured step]({})\n",
        path.file_name().unwrap_or_default().to_string_lossy()
    ));
    Ok(Some(path))
}

/// The final model of a `fracid time --json` / `fracid freq --json` report ("diagnosis.model",
/// else "model"), as `fracid tune` reads it.
///
/// # Errors
/// The file cannot be read or holds no model.
pub fn model_of(json: &Path) -> Result<FracTf> {
    let text = json
        .to_str()
        .with_context(|| format!("{} is not a UTF-8 path", json.display()))?;
    Ok(crate::cmd::tune::load_model(text)?.0)
}

/// A speed step of a tuned loop, predicted beside measured on the drive (the demo's and
/// `fracid drive autotune`'s), with each line's legend and the chart's look.
pub(crate) struct LoopFigure<'a> {
    pub t: &'a [f64],
    pub predicted: &'a [f64],
    pub measured: &'a [f64],
    /// Legends of the predicted and the measured line.
    pub labels: [&'a str; 2],
    pub look: Look,
}

impl Figure for LoopFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        plot::time_series_chart(
            root,
            &TimeChart {
                title: Some("speed step of the tuned FOPI: predicted and measured on the drive"),
                x_desc: "time after the step (s)",
                y_desc: Some("speed (rad/s)"),
                t: self.t,
                lines: &[
                    Line {
                        label: Some(self.labels[0]),
                        values: self.predicted,
                        style: BLUE.stroke_width(2),
                    },
                    Line {
                        label: Some(self.labels[1]),
                        values: self.measured,
                        style: RED.stroke_width(1),
                    },
                ],
                marker: None,
                look: self.look,
            },
        )
    }
}
