//! `fracid demo`: the main job end to end on an embedded default.
//!
//! 1. Start the drive simulator on a pseudo-terminal: the paper's PMSM model with effects the
//!    identification is *not* told about (an input delay, measurement noise, encoder quantisation).
//! 2. Acquire over the serial protocol: a PRBS record (the paper's experiment, 4 periods, around an
//!    operating point) and a sine sweep turned into a Bode table.
//! 3. Identify in both domains and diagnose the residuals in this process, with the use cases
//!    `fracid time` and `fracid freq` run (`ident::app::time::run`, `freq::compute`): each model
//!    fitted and diagnosed once, its text, JSON and plots made from that one result.
//! 4. A FOPI tuned on the time-domain model run in a speed loop on the drive
//!    (`demo_loop.rs`), then `fracid drive autotune` with its defaults on the same drive, told
//!    nothing (`demo_autotune.rs`).
//! 5. Write `report.md` with the models, fits, the diagnosis against the hidden truth, the loops,
//!    and plots.

use crate::bad_input;
use anyhow::{Context, Result};
use drive::bode::BodePoint;
use drive::client::{
    Acquisition, Client, ClientConfig, ClientStats, CsvSink, LazyFile, PrbsTest, SineSweep,
    SweepEvent,
};
use drive::protocol::{Configure, HelloReply};
use drive::sim::{DriveSim, Effects, SimClock, SimConfig, SimStats};
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
    /// instead of the simulator's Rust firmware.
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
    let (sim, true_model) = spawn_drive(&a)?;

    // 2. Acquire.
    // The link's settings, the same for every session with the drive below.
    let link = ClientConfig {
        baud: a.baud,
        clock: sim.virtual_clock(),
        ..ClientConfig::default()
    };
    let mut client =
        Client::open(sim.port_path(), link.clone()).context("cannot open the simulated drive")?;
    let hello = client.hello().context("the drive did not answer HELLO")?;
    let cfg = Configure {
        sample_rate_hz: a.sample_rate_hz,
        ..Configure::default()
    };
    client.configure(&cfg).context("CONFIGURE failed")?;
    let prbs = acquire_prbs(&mut client, &a)?;
    let sweep = acquire_sweep(&mut client, &a)?;
    let link_stats = client.stats();
    drop(client);
    let sim_stats = sim.stats();

    // 3. Identify and diagnose in this process, with the use cases the commands run (each
    // model fitted and diagnosed once; its text, JSON and plots made from the one result).
    let models = identify(&a, &prbs.steady_path, &sweep.path)?;
    step("the two models side by side (the paper's Fig. 5)");
    let cmp_txt = compare_models(dir, &models)?;

    // 3b. The tuned loop on the drive (cmd/demo_loop.rs); the drive was kept running for it.
    step("the tuned loop on the drive");
    let model = crate::cmd::demo_loop::model_of(&dir.join("time.json"))?;
    let tuned =
        crate::cmd::demo_loop::run(sim.port_path(), link.clone(), a.sample_rate_hz, &model, dir)?;
    if let (Some(rec), Some(fig)) = (&tuned.record, &tuned.figure) {
        step(&format!(
            "tuned loop: {} and {}",
            rec.display(),
            fig.display()
        ));
    }

    // 3c. One-button tuning on the same drive (cmd/demo_autotune.rs), told nothing.
    step("autotune on the drive (fracid drive autotune, defaults)");
    let t_auto = Instant::now();
    let autotune_lines =
        crate::cmd::demo_autotune::run(sim.port_path(), link, a.sample_rate_hz, dir)?;
    sim.stop();
    step(&format!(
        "autotune: {} in {:.1} s",
        dir.join("autotune.txt").display(),
        t_auto.elapsed().as_secs_f64()
    ));

    // 4. The report.
    let outcome = Outcome {
        hello,
        prbs,
        sweep,
        link_stats,
        sim_stats,
        models,
        cmp_txt,
        true_model,
        loop_lines: tuned.lines,
        autotune_lines,
    };
    let mut r = report_md(&a, &outcome)?;
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

/// The simulated drive on virtual time with the demo's hidden effects, and its true motor model
/// as text.
fn spawn_drive(a: &DemoArgs) -> Result<(DriveSim, String)> {
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
    let true_model = sim_cfg.model.to_string();
    let firmware_c = sim_cfg.firmware == drive::sim::FirmwareKind::C;
    let sim = DriveSim::spawn(sim_cfg).context("cannot start the drive simulator")?;
    step(&format!(
        "drive simulator ({} firmware) on {} at {} baud",
        if firmware_c { "C" } else { "Rust" },
        sim.port_path(),
        a.baud
    ));
    Ok((sim, true_model))
}

/// The PRBS run as acquired, and the record the identification gets.
struct Prbs {
    test: PrbsTest,
    acq: Acquisition,
    /// From this time on (s) the record is at its steady operating point.
    t_start: f64,
    steady_path: PathBuf,
}

/// The PRBS run into `prbs.csv` (the file created when the drive acknowledges the START, as
/// `fracid drive prbs`), and `prbs_steady.csv` from 0.1 s before the PRBS on.
///
/// # Errors
/// A failed or incomplete run (what arrived stays in the file), a file that cannot be written.
fn acquire_prbs(client: &mut Client, a: &DemoArgs) -> Result<Prbs> {
    let prbs_path = a.out.join("prbs.csv");
    let test = PrbsTest {
        periods: a.periods,
        ..PrbsTest::paper()
    };
    step(&format!(
        "PRBS: order {}, clock {} s, {} periods, {} V around {} V, at {} Hz",
        test.order, test.clock_s, test.periods, test.amplitude_v, test.offset_v, a.sample_rate_hz
    ));
    let file = LazyFile::new(&prbs_path)
        .with_context(|| format!("cannot create {}", prbs_path.display()))?;
    let mut sink = CsvSink::new(file);
    let acq = client
        .run_prbs(&test, &mut sink)
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
    let t_start = (test.settle_s - 0.1).max(0.0);
    let steady_path = a.out.join("prbs_steady.csv");
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
    Ok(Prbs {
        test,
        acq,
        t_start,
        steady_path,
    })
}

/// The sine sweep's Bode table as measured.
struct Sweep {
    sweep: SineSweep,
    points: Vec<BodePoint>,
    lost: Vec<String>,
    path: PathBuf,
}

/// The sine sweep (1-100 Hz, 16 frequencies, `--repeats` each) into `bode.csv`, written point
/// by point as measured; the frequencies that gave no point named in it.
///
/// # Errors
/// A failed sweep (the points measured stay in the file, with the error), a file that cannot
/// be written.
fn acquire_sweep(client: &mut Client, a: &DemoArgs) -> Result<Sweep> {
    let mut sweep = SineSweep::log(1.0, 100.0, 16);
    sweep.repeats = a.repeats;
    step(&format!(
        "sine sweep: {} frequencies from {} to {} Hz, {} measurement(s) each",
        sweep.freqs_hz.len(),
        sweep.freqs_hz[0],
        sweep.freqs_hz[sweep.freqs_hz.len() - 1],
        sweep.repeats
    ));
    let path = a.out.join("bode.csv");
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
    let mut bode_file = super::drive::BodeFile::new(&path, comment, sweep.repeats > 1)?;
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
        .with_context(|| format!("writing {}", path.display()))?;
    step(&format!(
        "Bode table: {} points -> {}",
        points.len(),
        path.display()
    ));
    Ok(Sweep {
        sweep,
        points,
        lost,
        path,
    })
}

/// Both identifications' text and JSON, the commands they stand for, and how many use-case
/// runs each took.
struct Models {
    time_cmd: String,
    time_txt: String,
    time_json: Value,
    freq_cmd: String,
    freq_txt: String,
    freq_json: Value,
    time_runs: usize,
    freq_runs: usize,
}

/// `fracid time STEADY` and `fracid freq BODE --weights W --refine --diagnose` in this
/// process (`time.*` and `freq.*`, text, JSON and plot, in the output folder).
///
/// # Errors
/// A failed identification, a file that cannot be written.
fn identify(a: &DemoArgs, steady_path: &Path, bode_path: &Path) -> Result<Models> {
    let dir = &a.out;
    let (time_runs, freq_runs) = (ident::app::time::runs(), super::freq::runs());
    step("time domain: output-error fit and diagnosis");
    let time_req = ident::app::time::TimeRequest {
        plain: false,
        ..Default::default()
    };
    let time_cmd = format!("time {}", steady_path.display());
    let (rec, reader_warnings) =
        super::time::read_record_noting(steady_path, &ident::data::ReadOptions::default())?;
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
    let freq_req = ident::app::freq::FreqRequest {
        weights: weights.to_string(),
        refine: true,
        diagnose: true,
        ..ident::app::freq::FreqRequest::default()
    };
    let freq =
        super::freq::compute_request(&freq_req, bode_path).context("identifying the Bode table")?;
    let freq_txt = freq.text();
    let freq_json = freq.json()?;
    write_file(&dir.join("freq.txt"), &freq_txt)?;
    write_file(
        &dir.join("freq.json"),
        &(serde_json::to_string_pretty(&freq_json)? + "\n"),
    )?;
    freq.plot(&dir.join("bode.png"))?;
    Ok(Models {
        time_cmd,
        time_txt,
        time_json,
        freq_cmd: format!(
            "freq {} --weights {weights} --refine --diagnose",
            bode_path.display()
        ),
        freq_txt,
        freq_json,
        time_runs: ident::app::time::runs() - time_runs,
        freq_runs: super::freq::runs() - freq_runs,
    })
}

/// The two final models (after the diagnosis, as `fracid compare time.json freq.json` takes
/// them) over 0.1-100 Hz: `compare.txt` and `compare.png`; the text.
///
/// # Errors
/// A model that cannot be read back, a file that cannot be written.
fn compare_models(dir: &Path, models: &Models) -> Result<String> {
    let ga = super::model_in::from_json(super::model_in::final_model(&models.time_json))?;
    let gb = super::model_in::from_json(super::model_in::final_model(&models.freq_json))?;
    let names = ("time", "frequency");
    let cmp = ident::compare::compare(&ga, &gb, (0.1, 100.0), 2000)?;
    let cmp_txt = super::compare::text(&ga, &gb, &cmp, names);
    write_file(&dir.join("compare.txt"), &cmp_txt)?;
    crate::plot::save(
        &dir.join("compare.png"),
        (1000, 800),
        &super::compare::CompareFigure { c: &cmp, names },
    )?;
    Ok(cmp_txt)
}

/// What the report tells.
struct Outcome {
    hello: HelloReply,
    prbs: Prbs,
    sweep: Sweep,
    link_stats: ClientStats,
    sim_stats: SimStats,
    models: Models,
    cmp_txt: String,
    true_model: String,
    loop_lines: Vec<String>,
    autotune_lines: Vec<String>,
}

/// The report (`report.md`) but its total time: the drive, the acquisition, each model with
/// its text and plot, the comparison, the hidden truth against what the diagnoses found, the
/// tuned loop.
///
/// # Errors
/// None in practice (formatting into a `String`).
fn report_md(a: &DemoArgs, o: &Outcome) -> Result<String> {
    let mut r = String::new();
    writeln!(r, "# fracid demo report\n")?;
    writeln!(
        r,
        "Drive: simulated F2812 (protocol {}, firmware {}.{}) on a pseudo-terminal at {} baud. The \
         identification was told nothing about the drive's hidden effects; they are revealed at the end.\n",
        o.hello.proto_version, o.hello.fw_major, o.hello.fw_minor, a.baud
    )?;
    acquisition_md(&mut r, a, o)?;
    let m = &o.models;
    writeln!(r, "## Time domain (`fracid {}`)\n", m.time_cmd)?;
    writeln!(r, "![time-domain fit](time.png)\n")?;
    writeln!(r, "```\n{}```\n", m.time_txt)?;
    writeln!(r, "## Frequency domain (`fracid {}`)\n", m.freq_cmd)?;
    writeln!(r, "![Bode plot](bode.png)\n")?;
    writeln!(r, "```\n{}```\n", m.freq_txt)?;
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
    writeln!(r, "```\n{}```\n", o.cmp_txt)?;
    truth_md(&mut r, a, o)?;
    for l in o.loop_lines.iter().chain(&o.autotune_lines) {
        writeln!(r, "{l}")?;
    }
    Ok(r)
}

/// The report's acquisition section: the PRBS, the sweep, the link, the files, the use-case runs.
fn acquisition_md(r: &mut String, a: &DemoArgs, o: &Outcome) -> Result<()> {
    let (p, s) = (&o.prbs, &o.sweep);
    writeln!(r, "## Acquisition\n")?;
    writeln!(
        r,
        "- PRBS: order {}, clock {} s, {} periods, {} V around {} V, {} Hz: {} samples, complete: {}.",
        p.test.order,
        p.test.clock_s,
        p.test.periods,
        p.test.amplitude_v,
        p.test.offset_v,
        a.sample_rate_hz,
        p.acq.t.len(),
        p.acq.complete
    )?;
    writeln!(
        r,
        "- Sine sweep: {} of {} frequencies measured, {} time(s) each{}{}.",
        s.points.len(),
        s.sweep.freqs_hz.len(),
        s.sweep.repeats,
        if s.sweep.repeats > 1 {
            " (the paper's trimmed mean; the spread is in the table and drawn as error bars)"
        } else {
            ""
        },
        if s.lost.is_empty() {
            String::new()
        } else {
            format!(" (lost: {})", s.lost.join("; "))
        }
    )?;
    writeln!(r, "- Link: {:?}.", o.link_stats)?;
    writeln!(
        r,
        "- Files: `prbs.csv` (as acquired), `prbs_steady.csv` (from {} s, the steady operating \
         point before the PRBS), `bode.csv`.\n",
        p.t_start
    )?;
    writeln!(
        r,
        "Each model was fitted and diagnosed once, in this process, by the use cases `fracid \
         time` and `fracid freq` run (use-case runs: time {}, freq {}).\n",
        o.models.time_runs, o.models.freq_runs
    )?;
    Ok(())
}

/// The report's hidden truth: the motor model and effects the drive had, what each diagnosis
/// found, the simulator's counters.
fn truth_md(r: &mut String, a: &DemoArgs, o: &Outcome) -> Result<()> {
    writeln!(r, "## The hidden truth\n")?;
    writeln!(r, "- Motor model: `{}`.", o.true_model)?;
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
        found(&o.models.time_json)
    )?;
    writeln!(
        r,
        "- The frequency-domain diagnosis found: {}.",
        found(&o.models.freq_json)
    )?;
    let st = &o.sim_stats;
    writeln!(
        r,
        "- Simulator counters: {} frames sent, {} damaged, {} blocks dropped, {} receive overruns.\n",
        st.frames_sent, st.frames_damaged, st.blocks_dropped, st.rx_overruns
    )?;
    Ok(())
}
