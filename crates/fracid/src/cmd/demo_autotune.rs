//! The autotune step of `fracid demo`: `fracid drive autotune` with its defaults on the demo's
//! simulated drive ([`autotune::tuner::run`]), told nothing of the drive (the probe, the
//! identification experiment designed from it, the rounds the diagnosis asks for, the controller
//! and its step measured), its report written beside the demo's and summarised in it.

use crate::cmd::drive_io::autotune_err;
use anyhow::{Context, Result};
use autotune::tuner::{self, report::AutotuneReport, AutotuneRequest};
use drive::client::{Client, ClientConfig};
use std::path::Path;

/// What the autotune adds to the demo's report: markdown lines.
///
/// Runs [`tuner::run`] with the default request on the drive at `port` (its own client: the
/// port is opened exclusively), writes `autotune.txt` (its text, round by round) and
/// `autotune.json` in `dir`.
///
/// # Errors
/// The port does not open; the autotune fails (the drive stopped); a file cannot be written.
pub fn run(
    port: &str,
    client_cfg: ClientConfig,
    sample_rate_hz: u32,
    dir: &Path,
) -> Result<Vec<String>> {
    let mut client =
        Client::open(port, client_cfg).context("cannot open the drive for the autotune")?;
    let req = AutotuneRequest::default();
    let r = tuner::run(
        &mut client,
        sample_rate_hz,
        &req,
        &mut Stages(std::time::Instant::now()),
    )
    .map_err(autotune_err)?;
    let text = r.text();
    let tp = dir.join("autotune.txt");
    std::fs::write(&tp, &text).with_context(|| format!("cannot write {}", tp.display()))?;
    let jp = dir.join("autotune.json");
    std::fs::write(&jp, serde_json::to_string_pretty(&r)? + "\n")
        .with_context(|| format!("cannot write {}", jp.display()))?;
    Ok(lines(&r))
}

/// The report's section: the experiments, each round's reason and errors, the final model, the
/// controller and its step predicted beside measured.
fn lines(r: &AutotuneReport) -> Vec<String> {
    let mut l = vec![
        "## One-button tuning (`fracid drive autotune`, defaults)\n".to_string(),
        format!(
            "The same drive, told nothing: {} experiments ({:.2} s of drive time of the {:.0} s \
             budget, within +-{:.2} V and +-{:.1} rad/s), {:.2} s of computing. Round by round in \
             `autotune.txt`, all of it in `autotune.json`.\n",
            r.experiments.len(),
            r.drive_time_s,
            r.request.budget_s,
            r.envelope.u_max_v,
            r.envelope.speed_max,
            r.seconds
        ),
    ];
    for round in &r.rounds {
        let errs: Vec<String> = round
            .after
            .iter()
            .map(|e| format!("{} {:.4} rad/s", e.record, e.rmse))
            .collect();
        l.push(format!(
            "- Round {} ({}): {}; error {}.",
            round.round,
            round.experiment,
            round.reason,
            errs.join(", ")
        ));
    }
    if let Some(m) = &r.model {
        l.push(format!("- Final model: `{}`.", m.text));
    }
    if let Some(c) = &r.control {
        l.push(format!(
            "- Controller: `C(s) = {}` at {:.1} rad/s (pm {:.1} deg, Ms {:.2}){}.",
            c.text,
            c.wc_used,
            c.pm_deg,
            c.ms,
            c.filter_text
                .as_ref()
                .map_or(String::new(), |f| format!(", after {f}"))
        ));
        let fig = |f: &Option<tuner::report::StepFigures>| {
            f.map_or("-".into(), |f| {
                format!(
                    "overshoot {:.2}%, rise {}",
                    f.overshoot_percent,
                    f.rise_time_s
                        .map_or("-".into(), |t| format!("{:.1} ms", 1e3 * t))
                )
            })
        };
        l.push(format!(
            "- Step of {:.1} rad/s: predicted {}; measured on the drive {}.",
            c.step_rad_s,
            fig(&c.predicted),
            fig(&c.measured)
        ));
    }
    l.push(format!(
        "- Verdict: {}.\n",
        if r.usable {
            "a usable controller".to_string()
        } else {
            format!("no usable controller ({})", r.problems.join("; "))
        }
    ));
    l
}

/// The autotune's stages on standard error, as the demo's steps, with the time since it
/// started.
struct Stages(std::time::Instant);

impl tuner::Observe for Stages {
    fn stage(&mut self, what: &str) {
        crate::eprintln_safe!(
            "fracid demo: autotune {:.2} s: {what}",
            self.0.elapsed().as_secs_f64()
        );
    }
}
