//! `fracid demo`: the main job end to end on an embedded default.
//!
//! 1. Start the drive simulator on a pseudo-terminal: the paper's PMSM model with effects the
//!    identification is *not* told about (an input delay, measurement noise, encoder quantisation).
//! 2. Acquire over the serial protocol: a PRBS record (the paper's experiment, 4 periods, around an
//!    operating point) and a sine sweep turned into a Bode table.
//! 3. Identify in both domains and diagnose the residuals in this process, with the use cases
//!    `fracid time` and `fracid freq` run (`ident::app::time::run`, `freq::compute`): each model
//!    fitted and diagnosed once, its text, JSON and plots made from that one result.
//! 4. Write `report.md` with the models, fits, the diagnosis against the hidden truth, and plots.

use crate::bad_input;
use anyhow::{Context, Result};
use drive::client::{Client, ClientConfig, CsvSink, LazyFile, PrbsTest, SineSweep, SweepEvent};
use drive::protocol::Configure;
use drive::sim::{DriveSim, Effects, SimClock, SimConfig};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `fracid demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Folder for the data, plots and report (created if needed).
    #[arg(long, default_value = "fracid-demo")]
    pub out: PathBuf,
    /// Line rate of the simulated serial link, baud (the simulator paces to it).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Sample rate of the acquisition, Hz.
    #[arg(long, default_value_t = 1000)]
    pub sample_rate_hz: u32,
    /// PRBS periods to acquire (the first is discarded as transient by the identification).
    #[arg(long, default_value_t = 4)]
    pub periods: u16,
    /// Hidden input delay of the simulated drive, s.
    #[arg(long, default_value_t = 0.001)]
    pub hidden_delay: f64,
    /// Hidden speed-measurement noise (standard deviation), rad/s.
    #[arg(long, default_value_t = 0.05)]
    pub hidden_noise: f64,
    /// Seed of the simulator's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Measurements per frequency of the sine sweep, combined by the paper's trimmed mean (the
    /// largest and smallest dropped): 3 by default, the fewest that drop the extremes (one
    /// damaged measurement cannot move a point) and leave a spread for the error bars, at 3
    /// times the sweep's time. From 5 on the frequency-domain fit weights by the spread
    /// (`--weights spread`); below, a 2-degree-of-freedom variance is too noisy to weight by and
    /// the paper's Vinagre weights are kept. 10 is the paper's procedure.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeats: u32,
    /// Run the C drive firmware (`firmware/`, as flashed on the F2812) in the simulated drive
    /// instead of the simulator's Rust firmware (also: FRACID_SIM_FIRMWARE=c).
    #[arg(long)]
    pub firmware: bool,
}

fn step(msg: &str) {
    crate::eprintln_safe!("fracid demo: {msg}");
}

/// Write `text` to `path`.
fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn path_str(p: &Path) -> Result<&str> {
    p.to_str()
        .with_context(|| format!("path {} is not valid UTF-8", p.display()))
}

/// Run `fracid demo`.
pub fn run(a: DemoArgs) -> Result<()> {
    if !(a.hidden_delay.is_finite() && a.hidden_delay >= 0.0) {
        bad_input!("--hidden-delay must be a non-negative number of seconds");
    }
    if !(a.hidden_noise.is_finite() && a.hidden_noise >= 0.0) {
        bad_input!("--hidden-noise must be a non-negative number");
    }
    let started = Instant::now();
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let dir = &a.out;

    // 1. The simulated drive, with effects nobody declares to the identification.
    let effects = Effects {
        delay_s: a.hidden_delay,
        noise_std: a.hidden_noise,
        speed_quant: 0.01,
        ..Effects::default()
    };
    // Virtual time: nobody watches the demo's drive on the wall clock. The host below shares the
    // drive's clock and keeps its keepalive on it (`drive::vclock`), so that the drive's clock
    // runs as fast as the two can go, waiting only where the protocol needs it.
    let sim_cfg = SimConfig {
        clock: SimClock::Virtual,
        baud: a.baud,
        effects,
        faults: drive::sim::Faults {
            seed: a.seed,
            ..Default::default()
        },
        ..SimConfig::default()
    };
    let sim_cfg = SimConfig {
        firmware: if a.firmware {
            drive::sim::FirmwareKind::C
        } else {
            sim_cfg.firmware
        },
        ..sim_cfg
    };
    let true_model = sim_cfg.model.clone();
    let firmware_c = sim_cfg.firmware == drive::sim::FirmwareKind::C;
    let sim = DriveSim::spawn(sim_cfg).context("cannot start the drive simulator")?;
    step(&format!(
        "drive simulator ({} firmware) on {} at {} baud",
        if firmware_c { "C" } else { "Rust" },
        sim.port_path(),
        a.baud
    ));

    // 2. Acquire.
    let mut client = Client::open(
        sim.port_path(),
        ClientConfig {
            baud: a.baud,
            clock: sim.virtual_clock(),
            ..ClientConfig::default()
        },
    )
    .context("cannot open the simulated drive")?;
    let hello = client.hello().context("the drive did not answer HELLO")?;
    let cfg = Configure {
        sample_rate_hz: a.sample_rate_hz,
        ..Configure::default()
    };
    client.configure(&cfg).context("CONFIGURE failed")?;
    let prbs_path = dir.join("prbs.csv");
    let prbs_test = PrbsTest {
        periods: a.periods,
        ..PrbsTest::paper()
    };
    step(&format!(
        "PRBS: order {}, clock {} s, {} periods, {} V around {} V, at {} Hz",
        prbs_test.order,
        prbs_test.clock_s,
        prbs_test.periods,
        prbs_test.amplitude_v,
        prbs_test.offset_v,
        a.sample_rate_hz
    ));
    // created when the drive has acknowledged the START (as `fracid drive prbs`)
    let file = LazyFile::new(&prbs_path)
        .with_context(|| format!("cannot create {}", prbs_path.display()))?;
    let mut sink = CsvSink::new(file);
    let acq = client
        .run_prbs(&prbs_test, &mut sink)
        .context("the PRBS run failed")?;
    drop(sink);
    if !acq.complete {
        anyhow::bail!(
            "the PRBS record is incomplete ({}); what arrived is in {}",
            acq.footer(),
            prbs_path.display()
        );
    }
    step(&format!(
        "PRBS record: {} samples -> {}",
        acq.t.len(),
        prbs_path.display()
    ));
    // The record starts with the motor at rest; the drive then holds the operating point for
    // `settle_s` before the PRBS. Identification works on deviations from a steady operating
    // point, so it gets the record from 0.1 s before the PRBS on (the raw record stays as acquired).
    let t_start = (prbs_test.settle_s - 0.1).max(0.0);
    let steady_path = dir.join("prbs_steady.csv");
    {
        let mut w = std::io::BufWriter::new(
            std::fs::File::create(&steady_path)
                .with_context(|| format!("cannot create {}", steady_path.display()))?,
        );
        use std::io::Write as _;
        writeln!(
            w,
            "# {} from t = {t_start} s (steady operating point)",
            prbs_path.display()
        )?;
        writeln!(w, "t,u,y")?;
        for k in (0..acq.t.len()).filter(|&k| acq.t[k] >= t_start - 1e-9) {
            writeln!(w, "{:.6},{},{}", acq.t[k], acq.u[k], acq.y[k])?;
        }
        w.flush()?;
    }

    let mut sweep = SineSweep::log(1.0, 100.0, 16);
    sweep.repeats = a.repeats;
    step(&format!(
        "sine sweep: {} frequencies from {} to {} Hz, {} measurement(s) each",
        sweep.freqs_hz.len(),
        sweep.freqs_hz[0],
        sweep.freqs_hz[sweep.freqs_hz.len() - 1],
        sweep.repeats
    ));
    let bode_path = dir.join("bode.csv");
    let mut comment = format!(
        "fracid demo sine sweep\n{}",
        drive::bode::hold_line(1.0 / f64::from(a.sample_rate_hz))
    );
    if sweep.repeats > 1 {
        comment += &format!(
            "\n{} repeats per frequency: trimmed mean (largest and smallest gain dropped, likewise \
             the phase); gain_db_std, phase_deg_std: sample standard deviations of the repeats",
            sweep.repeats
        );
    }
    // written point by point as measured, the file created with the first point
    let mut bode_file = super::drive::BodeFile::new(&bode_path, comment, sweep.repeats > 1)?;
    let (points, lost) = match client.run_sine_sweep_with(&sweep, &mut |ev| match ev {
        SweepEvent::Repeat(..) => Ok(()),
        SweepEvent::Point(p) => bode_file.point(p),
    }) {
        Ok(r) => r,
        Err(e) => {
            let _ = bode_file.finish(&[format!("{e:#}")], &["(sweep failed)".into()]);
            return Err(anyhow::Error::new(e).context("the sine sweep failed"));
        }
    };
    let missing: Vec<String> = sweep
        .freqs_hz
        .iter()
        .zip(sweep.applied_freqs_hz(a.sample_rate_hz))
        .filter(|(_, fa)| {
            !fa.is_some_and(|fa| points.iter().any(|p| (p.freq_hz - fa).abs() <= 1e-9 * fa))
        })
        .map(|(f, _)| f.to_string())
        .collect();
    bode_file
        .finish(&lost, &missing)
        .with_context(|| format!("writing {}", bode_path.display()))?;
    step(&format!(
        "Bode table: {} points -> {}",
        points.len(),
        bode_path.display()
    ));
    let link_stats = client.stats();
    drop(client);
    let sim_stats = sim.stats();

    // 3. Identify and diagnose in this process, with the use cases the commands run (each
    // model fitted and diagnosed once; its text, JSON and plots made from the one result).
    let (time_runs, freq_runs) = (ident::app::time::runs(), super::freq::runs());
    step("time domain: output-error fit and diagnosis");
    let time_req = ident::app::time::TimeRequest {
        diagnose: true,
        ..Default::default()
    };
    let time_cmd = format!("time {} --diagnose", steady_path.display());
    let (rec, reader_warnings) =
        super::time::read_record_noting(&steady_path, &ident::data::ReadOptions::default())?;
    let time_data = ident::app::time::TimeData {
        record: rec,
        validation: None,
        joint: Vec::new(),
        reader_warnings,
    };
    let time_report = ident::app::time::run(&time_req, &time_data, &mut ident::app::observe::Quiet)
        .context("identifying the PRBS record")?;
    let time_txt = super::time::report_text(&time_report, &time_data.record);
    let time_json = serde_json::to_value(&time_report)?;
    write_file(&dir.join("time.txt"), &time_txt)?;
    write_file(
        &dir.join("time.json"),
        &(serde_json::to_string_pretty(&time_json)? + "\n"),
    )?;
    super::time::plot_report(&dir.join("time.png"), &time_report, &time_data.record)?;

    step("frequency domain: weighted Levy, refit and diagnosis");
    let weights = if a.repeats >= 5 { "spread" } else { "vinagre" };
    let freq_argv = [
        "freq",
        path_str(&bode_path)?,
        "--weights",
        weights,
        "--refine",
        "--diagnose",
    ];
    let freq_args = super::freq::args_from(&freq_argv)?;
    let freq =
        super::freq::compute(&freq_args, &bode_path).context("identifying the Bode table")?;
    let freq_txt = freq.text();
    let freq_json = freq.json()?;
    write_file(&dir.join("freq.txt"), &freq_txt)?;
    write_file(
        &dir.join("freq.json"),
        &(serde_json::to_string_pretty(&freq_json)? + "\n"),
    )?;
    freq.plot(&dir.join("bode.png"))?;
    let (time_runs, freq_runs) = (
        ident::app::time::runs() - time_runs,
        super::freq::runs() - freq_runs,
    );

    step("the two models side by side (the paper's Fig. 5)");
    // the final models (after the diagnosis), as `fracid compare time.json freq.json` takes them
    let ga = super::model_in::from_json(super::model_in::final_model(&time_json))?;
    let gb = super::model_in::from_json(super::model_in::final_model(&freq_json))?;
    let names = ("time", "frequency");
    let cmp = ident::compare::compare(&ga, &gb, (0.1, 100.0), 2000)?;
    let cmp_txt = super::compare::text(&ga, &gb, &cmp, names);
    write_file(&dir.join("compare.txt"), &cmp_txt)?;
    crate::plot::save(
        &dir.join("compare.png"),
        (1000, 800),
        &super::compare::CompareFigure { c: &cmp, names },
    )?;

    // 3b. The tuned loop on the drive (cmd/demo_loop.rs); the drive was kept running for it.
    step("the tuned loop on the drive");
    let model = crate::cmd::demo_loop::model_of(&dir.join("time.json"))?;
    let tuned = crate::cmd::demo_loop::run(
        sim.port_path(),
        ClientConfig {
            baud: a.baud,
            clock: sim.virtual_clock(),
            ..ClientConfig::default()
        },
        a.sample_rate_hz,
        &model,
        dir,
    )?;
    sim.stop();
    if let (Some(rec), Some(fig)) = (&tuned.record, &tuned.figure) {
        step(&format!(
            "tuned loop: {} and {}",
            rec.display(),
            fig.display()
        ));
    }

    // 4. The report.
    let mut r = String::new();
    writeln!(r, "# fracid demo report\n")?;
    writeln!(
        r,
        "Drive: simulated F2812 (protocol {}, firmware {}.{}) on a pseudo-terminal at {} baud. The \
         identification was told nothing about the drive's hidden effects; they are revealed at the end.\n",
        hello.proto_version, hello.fw_major, hello.fw_minor, a.baud
    )?;
    writeln!(r, "## Acquisition\n")?;
    writeln!(
        r,
        "- PRBS: order {}, clock {} s, {} periods, {} V around {} V, {} Hz: {} samples, complete: {}.",
        prbs_test.order,
        prbs_test.clock_s,
        prbs_test.periods,
        prbs_test.amplitude_v,
        prbs_test.offset_v,
        a.sample_rate_hz,
        acq.t.len(),
        acq.complete
    )?;
    writeln!(
        r,
        "- Sine sweep: {} of {} frequencies measured, {} time(s) each{}{}.",
        points.len(),
        sweep.freqs_hz.len(),
        sweep.repeats,
        if sweep.repeats > 1 {
            " (the paper's trimmed mean; the spread is in the table and drawn as error bars)"
        } else {
            ""
        },
        if lost.is_empty() {
            String::new()
        } else {
            format!(" (lost: {})", lost.join("; "))
        }
    )?;
    writeln!(r, "- Link: {link_stats:?}.")?;
    writeln!(
        r,
        "- Files: `prbs.csv` (as acquired), `prbs_steady.csv` (from {t_start} s, the steady operating \
         point before the PRBS), `bode.csv`.\n"
    )?;
    writeln!(
        r,
        "Each model was fitted and diagnosed once, in this process, by the use cases `fracid \
         time` and `fracid freq` run (use-case runs: time {time_runs}, freq {freq_runs}).\n"
    )?;
    writeln!(r, "## Time domain (`fracid {time_cmd}`)\n")?;
    writeln!(r, "![time-domain fit](time.png)\n")?;
    writeln!(r, "```\n{}```\n", time_txt)?;
    writeln!(
        r,
        "## Frequency domain (`fracid {}`)\n",
        freq_argv.join(" ")
    )?;
    writeln!(r, "![Bode plot](bode.png)\n")?;
    writeln!(r, "```\n{}```\n", freq_txt)?;
    writeln!(
        r,
        "## Time- and frequency-domain models compared (`fracid compare time.json freq.json ...`)\n"
    )?;
    writeln!(
        r,
        "As the paper's Fig. 5: both final models (after diagnosis) on one Bode plot, where they \
         differ most over 0.1-100 Hz, and their coefficients.\n"
    )?;
    writeln!(r, "![the two models](compare.png)\n")?;
    writeln!(r, "```\n{}```\n", cmp_txt)?;
    writeln!(r, "## The hidden truth\n")?;
    writeln!(r, "- Motor model: `{true_model}`.")?;
    writeln!(
        r,
        "- Hidden effects: input delay {} s, speed noise {} rad/s (standard deviation), speed \
         quantisation 0.01 rad/s.",
        a.hidden_delay, a.hidden_noise
    )?;
    let found = |v: &Value| -> String {
        v.pointer("/diagnosis/effects")
            .and_then(Value::as_array)
            .map(|e| {
                e.iter()
                    .map(|x| {
                        format!(
                            "{} {}",
                            x.get("name").and_then(Value::as_str).unwrap_or("?"),
                            x.get("params").map(Value::to_string).unwrap_or_default()
                        )
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "nothing".into())
    };
    writeln!(
        r,
        "- The time-domain diagnosis found: {}.",
        found(&time_json)
    )?;
    writeln!(
        r,
        "- The frequency-domain diagnosis found: {}.",
        found(&freq_json)
    )?;
    writeln!(
        r,
        "- Simulator counters: {} frames sent, {} damaged, {} blocks dropped, {} receive overruns.\n",
        sim_stats.frames_sent, sim_stats.frames_damaged, sim_stats.blocks_dropped, sim_stats.rx_overruns
    )?;
    for l in &tuned.lines {
        writeln!(r, "{l}")?;
    }
    writeln!(r, "Total time: {:.1} s.", started.elapsed().as_secs_f64())?;
    let report = dir.join("report.md");
    std::fs::write(&report, r).with_context(|| format!("cannot write {}", report.display()))?;
    step(&format!(
        "done in {:.1} s: report {}",
        started.elapsed().as_secs_f64(),
        report.display()
    ));
    Ok(())
}
