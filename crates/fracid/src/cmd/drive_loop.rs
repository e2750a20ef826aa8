//! `fracid drive loop`: the controller `fracid tune --dt DT --json` designed, run in a speed loop
//! on the drive (PROTOCOL.md section 3, "Speed loop").
//!
//! The report's discrete realisation (`discrete`: `A, B, C, D` at `dt`) is turned into the
//! drive's fixed-point parallel first-order sections and, for a FOPID's derivative, delay taps
//! ([`drive::ctrl::FixedCtrl`], [`autotune::realise`]), downloaded
//! (LOAD_CTRL, LOAD_SECTION), and START_LOOP runs the reference at 0 for `--pre` seconds, then
//! `--step`. The record is `t,r,u,y` with the acquisition's footer: a broken run keeps what
//! arrived and says what is missing.

use crate::cmd::drive_io::{
    autotune_err, check_outputs, close_record, kept_summary, output_file, output_path, port_conf,
    record_outcome, run_on_drive, PortArgs,
};
use anyhow::Result;
use autotune::acquire::speed_loop::LoopRequest;
use autotune::realise::{self, PRUNE_TOL};
use drive::client::{LoopCsvSink, Retention};
use std::path::PathBuf;

/// Options of `fracid drive loop`.
#[derive(Debug, clap::Args)]
pub struct LoopArgs {
    /// The port and the drive's configuration.
    #[command(flatten)]
    pub port: PortArgs,
    /// The controller: the JSON of `fracid tune ... --dt DT --json` (its discrete realisation
    /// is run; DT must be the sample period, 1/--sample-rate).
    #[arg(long)]
    pub controller: PathBuf,
    /// The reference step, rad/s.
    #[arg(long)]
    pub step: f64,
    /// The whole record, s.
    #[arg(long)]
    pub duration: f64,
    /// Time at reference 0 before the step, s.
    #[arg(long, default_value_t = 0.1)]
    pub pre: f64,
    /// Output CSV (t,r,u,y); `-` for standard output.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Exit 0 even if the run is incomplete (the file is marked either way).
    #[arg(long)]
    pub allow_incomplete: bool,
}

/// `fracid drive loop`.
///
/// # Errors
/// Bad options or controller (exit 2), the port or the output (exit 3), an incomplete run
/// without `--allow-incomplete` (exit 1).
pub fn run(a: LoopArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    let conf = port_conf(&a.port)?;
    let output = output_path(&a.output);
    check_outputs(
        &a.port.link.port,
        &[("--controller", &a.controller)],
        &[("--output", &output)],
    )?;
    let req = LoopRequest {
        step_rad_s: a.step,
        pre_s: a.pre,
        duration_s: a.duration,
    };
    let cmd = req.command(&conf).map_err(autotune_err)?;
    let text = crate::cmd::read_text(&a.controller)?;
    let named = |e: autotune::Error| autotune_err(e).context(a.controller.display().to_string());
    let real = realise::parse_realisation(&text).map_err(named)?;
    let (pruned, dropped) = realise::prune(&real);
    let k = realise::fixed_controller(&pruned, &conf).map_err(named)?;
    let qerr = realise::quantisation_error(&real, &k, &conf);
    describe_controller(&real.text, &k, dropped.len(), qerr);
    // the samples go to the file and the step's figures as they arrive: none is kept in memory
    let mut sink = LoopCsvSink::new(output_file(&output)?, cmd, conf.y_lsb());
    let (rec, signal) = run_on_drive(&a.port, &conf, "samples", |c| {
        c.set_retention(Retention::CountOnly);
        autotune::acquire::speed_loop::run(c, &conf, &k, &req, &mut sink).map_err(autotune_err)
    })?;
    let (acq, figures) = match rec {
        Ok(r) => (Ok(r.acquisition), r.figures),
        Err(e) => (Err(e), None),
    };
    let acq = close_record(acq, sink.into_inner(), &output)?;
    let figures = match figures {
        Some((overshoot_percent, rise_time, settling_time)) => format!(
            "; step {} rad/s: overshoot {:.2}%, rise (10-90%) {}, settling (2%) {}",
            a.step,
            overshoot_percent,
            rise_time.map_or("not reached".into(), |r| format!("{r:.4} s")),
            settling_time.map_or("not within the record".into(), |s| format!("{s:.4} s")),
        ),
        None => String::new(),
    };
    let summary = format!("{}{figures}", kept_summary(&a.output, &acq));
    if acq.clamped_blocks > 0 {
        crate::eprintln_safe!(
            "warning: the drive clamped the voltage in {} blocks (anti-windup engaged): the step \
             is not the linear loop's",
            acq.clamped_blocks
        );
    }
    record_outcome(&acq, signal, summary, None, a.allow_incomplete)
}

/// What the drive runs of the controller, on standard error.
fn describe_controller(text: &str, k: &drive::ctrl::FixedCtrl, dropped: usize, qerr: f64) {
    crate::eprintln_safe!(
        "controller {}: {} fixed-point sections (Q30 poles, Q24 gains, 64-bit states){}{}; \
         frequency response within {:.2e} of the realisation from 1 rad/s to half Nyquist",
        text,
        k.sections.len(),
        if k.taps.is_empty() {
            String::new()
        } else {
            format!(
                " and {} delay taps (the fast modes; controller format 2, firmware 1.2)",
                k.taps.len()
            )
        },
        if dropped == 0 {
            String::new()
        } else {
            format!(", {dropped} state(s) below {PRUNE_TOL:e} of the output left out")
        },
        qerr
    );
    if k.d_q24 != 0 && k.dinv_q16 == 0 {
        crate::eprintln_safe!(
            "anti-windup: conditional integration (the states frozen while the error pushes into \
             the clamp): the controller has a zero outside the unit circle, where Hanus' \
             conditioning would run away"
        );
    }
}
