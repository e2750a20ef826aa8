//! `fracid drive ...`: the drive simulator and acquisition from a drive over a serial port.

use crate::cmd::BadInput;
use crate::interrupt::StopOnInterrupt;
use anyhow::{Context, Result};
use drive::client::{Client, ClientConfig, CsvSink, PrbsTest, Progress, SineSweep};
use drive::protocol::Configure;
use drive::sim::{DriveSim, Effects, FaultAt, Faults, SimConfig};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::Duration;

/// Options of `fracid drive`.
#[derive(Debug, clap::Args)]
pub struct DriveArgs {
    /// What to do.
    #[command(subcommand)]
    pub cmd: DriveCmd,
}

/// The drive subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum DriveCmd {
    /// Run the drive simulator on a pseudo-terminal; prints the port path to open.
    Sim(SimArgs),
    /// Run a PRBS experiment and write the record as CSV (t,u,y,i).
    Prbs(PrbsArgs),
    /// Run a sine sweep and write a Bode table (freq_hz,gain_db,phase_deg).
    Sine(SineArgs),
    /// Show the drive's identity and state.
    Status(StatusArgs),
}

/// Connection options shared by the client subcommands.
#[derive(Debug, clap::Args)]
pub struct PortArgs {
    /// Serial port (e.g. /dev/ttyUSB0, or the path printed by `fracid drive sim`).
    #[arg(long)]
    pub port: String,
    /// Baud rate (115200 is reachable on the F2812; 921600 is not, 937500 is).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Command timeout in ms (default: 100 ms + 3 frame times).
    #[arg(long)]
    pub timeout_ms: Option<u64>,
    /// Resends of an unanswered command.
    #[arg(long, default_value_t = 5)]
    pub retries: u32,
    /// Sample rate in Hz.
    #[arg(long, default_value_t = 1000)]
    pub sample_rate: u32,
    /// Samples per DATA block (1..=66).
    #[arg(long, default_value_t = 32)]
    pub block: u8,
    /// Voltage clamp on the drive, V.
    #[arg(long, default_value_t = 24.0)]
    pub u_limit: f64,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Options of `fracid drive sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// Line rate to pace to, baud.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Also create a symlink to the pty here (stable across a simulated disconnect).
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Motor model, voltage to speed (default: the paper's time-domain PMSM model).
    #[arg(long, default_value = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)")]
    pub model: String,
    /// Hidden effect: Coulomb friction, voltage equivalent, V.
    #[arg(long, default_value_t = 0.0)]
    pub coulomb: f64,
    /// Hidden effect: input delay, s.
    #[arg(long, default_value_t = 0.0)]
    pub delay: f64,
    /// Hidden effect: periodic disturbance (torque ripple) amplitude, V at the input.
    #[arg(long, default_value_t = 0.0)]
    pub ripple: f64,
    /// Ripple frequency, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub ripple_hz: f64,
    /// Hidden effect: speed measurement noise, standard deviation in rad/s.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Hidden effect: speed quantisation step, rad/s.
    #[arg(long, default_value_t = 0.0)]
    pub speed_quant: f64,
    /// Fault: bit error rate (per bit, both directions).
    #[arg(long, default_value_t = 0.0)]
    pub ber: f64,
    /// Fault: byte drop rate (per byte, both directions).
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// Fault: burst start rate per byte (drive to host).
    #[arg(long, default_value_t = 0.0)]
    pub burst_rate: f64,
    /// Burst length, bytes.
    #[arg(long, default_value_t = 8)]
    pub burst_len: usize,
    /// Fault: fraction of drive-to-host frames corrupted (1 to 3 bit flips each).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_frames: f64,
    /// Fault: stall the drive's communication at this run sample (see --stall-ms).
    #[arg(long)]
    pub stall_at: Option<u64>,
    /// Stall duration, ms.
    #[arg(long, default_value_t = 600)]
    pub stall_ms: u64,
    /// Fault: disconnect at this run sample (a real pty close/reopen with --link).
    #[arg(long)]
    pub disconnect_at: Option<u64>,
    /// Disconnect duration, ms.
    #[arg(long, default_value_t = 300)]
    pub disconnect_ms: u64,
    /// Fault: reset the drive at this run sample.
    #[arg(long)]
    pub reset_at: Option<u64>,
    /// Seed for faults and noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exit after this many seconds (default: run until killed).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Log simulator events to stderr.
    #[arg(long, short)]
    pub verbose: bool,
}

/// Options of `fracid drive prbs`.
#[derive(Debug, clap::Args)]
pub struct PrbsArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// LFSR order (2..=16): period 2^order - 1 bits.
    #[arg(long, default_value_t = 7)]
    pub order: u8,
    /// LFSR seed (nonzero).
    #[arg(long, default_value_t = 1)]
    pub seed: u32,
    /// Bit duration, s (a whole number of samples).
    #[arg(long, default_value_t = 0.003)]
    pub clock: f64,
    /// Amplitude, V.
    #[arg(long, default_value_t = 1.0)]
    pub amplitude: f64,
    /// Operating point, V.
    #[arg(long, default_value_t = 6.0)]
    pub offset: f64,
    /// Number of periods.
    #[arg(long, default_value_t = 1)]
    pub periods: u16,
    /// Time at the operating point before the PRBS, s (recorded).
    #[arg(long, default_value_t = 0.3)]
    pub settle: f64,
    /// Output CSV (t,u,y,i; a footer says whether the run is complete).
    #[arg(long, short)]
    pub output: PathBuf,
    /// Exit 0 even if the run is incomplete (the file is marked either way).
    #[arg(long)]
    pub allow_incomplete: bool,
}

/// Options of `fracid drive sine`.
#[derive(Debug, clap::Args)]
pub struct SineArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Lowest frequency, Hz.
    #[arg(long, default_value_t = 1.0)]
    pub f_min: f64,
    /// Highest frequency, Hz.
    #[arg(long, default_value_t = 100.0)]
    pub f_max: f64,
    /// Number of log-spaced frequencies.
    #[arg(long, default_value_t = 15)]
    pub points: usize,
    /// Explicit frequencies in Hz, comma-separated (overrides --f-min/--f-max/--points).
    #[arg(long, value_delimiter = ',')]
    pub freqs: Option<Vec<f64>>,
    /// Amplitude, V.
    #[arg(long, default_value_t = 1.0)]
    pub amplitude: f64,
    /// Operating point, V.
    #[arg(long, default_value_t = 6.0)]
    pub offset: f64,
    /// Measured cycles per frequency.
    #[arg(long, default_value_t = 4)]
    pub cycles: u16,
    /// Settling cycles per frequency (at least --min-settle seconds).
    #[arg(long, default_value_t = 2)]
    pub settle_cycles: u16,
    /// Minimum settling time, s.
    #[arg(long, default_value_t = 0.2)]
    pub min_settle: f64,
    /// Stream the samples too (host DFT if the drive's is lost).
    #[arg(long)]
    pub stream: bool,
    /// Measurements per frequency, combined by the paper's trimmed mean (the largest and the
    /// smallest gain dropped, likewise the phase, the rest averaged); the table then carries their
    /// spread (gain_db_std, phase_deg_std, repeats). 3 by default: the fewest that drop the
    /// extremes and still give a spread, at three times the time of one (the paper measures 10).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeats: u32,
    /// File of the single repeats (freq_hz,repeat,gain_db,phase_deg), written as they are
    /// measured. Default with --repeats above 1: OUTPUT with `.repeats.csv` appended.
    #[arg(long)]
    pub repeats_out: Option<PathBuf>,
    /// Output CSV (freq_hz,gain_db,phase_deg[,gain_db_std,phase_deg_std,repeats]).
    #[arg(long, short)]
    pub output: PathBuf,
}

/// Options of `fracid drive status`.
#[derive(Debug, clap::Args)]
pub struct StatusArgs {
    /// Serial port.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
}

/// Run `fracid drive ...`.
pub fn run(args: DriveArgs) -> Result<()> {
    match args.cmd {
        DriveCmd::Sim(a) => sim(a),
        DriveCmd::Prbs(a) => prbs(a),
        DriveCmd::Sine(a) => sine(a),
        DriveCmd::Status(a) => status(a),
    }
}

/// Library errors to CLI errors: bad parameters exit 2, port/I-O problems exit 3.
fn lib_err(e: drive::Error) -> anyhow::Error {
    match e {
        drive::Error::InvalidParam(m) => anyhow::Error::new(BadInput(m)),
        drive::Error::Io(io) => anyhow::Error::new(io),
        e @ drive::Error::Port { .. } => {
            let msg = e.to_string();
            anyhow::Error::new(std::io::Error::other(msg))
        }
        e => anyhow::Error::new(e),
    }
}

fn fault_at(at: Option<u64>, ms: u64) -> Option<FaultAt> {
    at.map(|at_sample| FaultAt {
        at_sample,
        duration: Duration::from_millis(ms),
    })
}

fn sim(a: SimArgs) -> Result<()> {
    let model: fracsim::FracTf = a.model.parse().context("--model")?;
    for (name, v) in [
        ("--ber", a.ber),
        ("--drop-rate", a.drop_rate),
        ("--burst-rate", a.burst_rate),
        ("--corrupt-frames", a.corrupt_frames),
    ] {
        if !(0.0..=1.0).contains(&v) {
            crate::bad_input!("{name} must be in [0, 1], got {v}");
        }
    }
    if a.baud == 0 {
        crate::bad_input!("--baud must be positive");
    }
    let cfg = SimConfig {
        model,
        baud: a.baud,
        effects: Effects {
            coulomb_v: a.coulomb,
            delay_s: a.delay,
            ripple_v: a.ripple,
            ripple_hz: a.ripple_hz,
            noise_std: a.noise,
            speed_quant: a.speed_quant,
            ..Effects::default()
        },
        faults: Faults {
            bit_error_rate: a.ber,
            drop_rate: a.drop_rate,
            burst_rate: a.burst_rate,
            burst_len: a.burst_len,
            frame_corrupt_rate: a.corrupt_frames,
            stall: fault_at(a.stall_at, a.stall_ms),
            disconnect: fault_at(a.disconnect_at, a.disconnect_ms),
            reset: fault_at(a.reset_at, 50),
            seed: a.seed,
        },
        link: a.link,
        verbose: a.verbose,
        ..SimConfig::default()
    };
    let s = DriveSim::spawn(cfg).map_err(lib_err)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", s.port_path())?;
    out.flush()?;
    drop(out);
    eprintln!(
        "drive simulator at {} ({} baud); stop with Ctrl-C",
        s.port_path(),
        a.baud
    );
    let start = std::time::Instant::now();
    while s.is_running() {
        if a.duration
            .is_some_and(|d| start.elapsed().as_secs_f64() >= d)
        {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let st = s.stats();
    eprintln!(
        "drive simulator: {} frames sent ({} damaged), {} received, {} blocks dropped, {} runs",
        st.frames_sent, st.frames_damaged, st.frames_received, st.blocks_dropped, st.runs_started
    );
    s.stop();
    Ok(())
}

fn connect(p: &PortArgs) -> Result<(Client, Configure)> {
    let cfg = ClientConfig {
        baud: p.baud,
        timeout: p.timeout_ms.map(Duration::from_millis),
        retries: p.retries,
        ..ClientConfig::default()
    };
    let mut c = Client::open(&p.port, cfg)
        .map_err(lib_err)
        .with_context(|| format!("connecting to the drive at {}", p.port))?;
    if !(p.u_limit > 0.0 && p.u_limit <= 32.767) {
        crate::bad_input!("--u-limit must be in (0, 32.767] V");
    }
    let conf = Configure {
        sample_rate_hz: p.sample_rate,
        block_samples: p.block,
        u_limit: (p.u_limit * 1000.0).round() as i16,
        ..Configure::default()
    };
    c.configure(&conf)
        .map_err(lib_err)
        .context("configuring the drive")?;
    Ok((c, conf))
}

fn progress_bar(quiet: bool, unit: &str) -> Option<indicatif::ProgressBar> {
    if quiet || !std::io::stderr().is_terminal() {
        return None;
    }
    let pb = indicatif::ProgressBar::new(0);
    pb.set_draw_target(indicatif::ProgressDrawTarget::stderr());
    if let Ok(st) = indicatif::ProgressStyle::with_template(&format!(
        "{{bar:40}} {{pos}}/{{len}} {unit} {{elapsed}}"
    )) {
        pb.set_style(st);
    }
    Some(pb)
}

fn attach(c: &mut Client, pb: &Option<indicatif::ProgressBar>) {
    if let Some(pb) = pb.clone() {
        c.set_progress(move |p: Progress| {
            pb.set_length(p.total);
            pb.set_position(p.done);
        });
    }
}

fn prbs(a: PrbsArgs) -> Result<()> {
    let (mut c, _) = connect(&a.port)?;
    let test = PrbsTest {
        order: a.order,
        seed: a.seed,
        clock_s: a.clock,
        amplitude_v: a.amplitude,
        offset_v: a.offset,
        periods: a.periods,
        settle_s: a.settle,
    };
    let file = std::fs::File::create(&a.output)
        .with_context(|| format!("creating {}", a.output.display()))?;
    let mut sink = CsvSink::new(file);
    let pb = progress_bar(a.port.quiet, "samples");
    attach(&mut c, &pb);
    // Ctrl-C stops the drive; the record keeps what arrived and its footer says what is missing.
    let ctrl_c = StopOnInterrupt::arm(c.stop_handle());
    let acq = c.run_prbs(&test, &mut sink).map_err(lib_err);
    let interrupted = ctrl_c.interrupted();
    drop(ctrl_c);
    let acq = acq?;
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    sink.into_inner()
        .with_context(|| format!("writing {}", a.output.display()))?;
    if acq.complete {
        eprintln!(
            "{}: {} samples, complete{}",
            a.output.display(),
            acq.index.len(),
            if interrupted {
                " (interrupted after the run had ended)"
            } else {
                ""
            }
        );
        Ok(())
    } else {
        let missing: Vec<String> = acq
            .missing
            .iter()
            .map(|r| format!("{}..{}", r.start, r.end))
            .collect();
        let msg = format!(
            "{}: {}run incomplete ({}); {} samples kept, missing samples {}",
            a.output.display(),
            if interrupted {
                "interrupted (Ctrl-C), drive stopped; "
            } else {
                ""
            },
            acq.problems.join("; "),
            acq.index.len(),
            if missing.is_empty() {
                "none".to_string()
            } else {
                missing.join(", ")
            }
        );
        if a.allow_incomplete {
            eprintln!("warning: {msg}");
            Ok(())
        } else {
            Err(anyhow::anyhow!(msg))
        }
    }
}

/// The file of single repeats (header written), if any: `--repeats-out`, or by default with
/// `--repeats` above 1 the output's name with `.repeats.csv` appended.
fn open_repeats_file(
    a: &SineArgs,
    conf: &drive::protocol::Configure,
) -> Result<Option<(std::io::BufWriter<std::fs::File>, PathBuf)>> {
    let path = match &a.repeats_out {
        Some(p) => p.clone(),
        None if a.repeats > 1 => {
            let mut s = a.output.clone().into_os_string();
            s.push(".repeats.csv");
            PathBuf::from(s)
        }
        None => return Ok(None),
    };
    let f = std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(f);
    writeln!(
        w,
        "# fracid drive sine: single repeats as measured, {} V around {} V, {} Hz sampling\n{}",
        a.amplitude,
        a.offset,
        conf.sample_rate_hz,
        drive::bode::REPEATS_HEADER
    )
    .and_then(|_| w.flush())
    .with_context(|| format!("writing {}", path.display()))?;
    Ok(Some((w, path)))
}

fn sine(a: SineArgs) -> Result<()> {
    let (mut c, conf) = connect(&a.port)?;
    let mut sweep = SineSweep::log(a.f_min, a.f_max, a.points);
    if let Some(f) = &a.freqs {
        sweep.freqs_hz = f.clone();
    }
    if sweep.freqs_hz.is_empty() || sweep.freqs_hz.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
        crate::bad_input!("frequencies must be positive");
    }
    let nyq = conf.sample_rate_hz as f64 / 2.0;
    if let Some(f) = sweep.freqs_hz.iter().find(|&&f| f >= nyq) {
        crate::bad_input!(
            "{f} Hz is at or above Nyquist ({nyq} Hz at --sample-rate {})",
            conf.sample_rate_hz
        );
    }
    sweep.amplitude_v = a.amplitude;
    sweep.offset_v = a.offset;
    sweep.cycles = a.cycles;
    sweep.settle_cycles = a.settle_cycles;
    sweep.min_settle_s = a.min_settle;
    sweep.stream = a.stream;
    sweep.repeats = a.repeats;
    let mut reps_file = open_repeats_file(&a, &conf)?;
    let pb = progress_bar(a.port.quiet, "frequencies");
    attach(&mut c, &pb);
    // Ctrl-C stops the drive; the frequencies measured so far are written, the rest listed.
    let ctrl_c = StopOnInterrupt::arm(c.stop_handle());
    let swept = c
        .run_sine_sweep_with(&sweep, &mut |p, rep| {
            if let Some((w, path)) = reps_file.as_mut() {
                drive::bode::write_repeat_line(&mut *w, p, rep)
                    .and_then(|_| w.flush())
                    .map_err(|e| {
                        drive::Error::Io(std::io::Error::new(
                            e.kind(),
                            format!("writing {}: {e}", path.display()),
                        ))
                    })?;
            }
            Ok(())
        })
        .map_err(lib_err);
    let interrupted = ctrl_c.interrupted();
    drop(ctrl_c);
    let (points, mut problems) = swept?;
    if interrupted {
        problems.push("interrupted (Ctrl-C): sweep stopped".into());
    }
    // The drive measures at the whole-cycle frequency nearest each request.
    let applied = sweep.applied_freqs_hz(conf.sample_rate_hz);
    let unmeasured: Vec<String> = sweep
        .freqs_hz
        .iter()
        .zip(&applied)
        .filter(|(_, fa)| {
            !fa.is_some_and(|fa| points.iter().any(|p| (p.freq_hz - fa).abs() <= 1e-9 * fa))
        })
        .map(|(f, _)| f.to_string())
        .collect();
    let moved: Vec<String> = sweep
        .freqs_hz
        .iter()
        .zip(&applied)
        .filter_map(|(f, fa)| {
            fa.filter(|fa| (fa - f).abs() > 1e-6)
                .map(|fa| format!("{f} -> {fa}"))
        })
        .collect();
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    let file = std::fs::File::create(&a.output)
        .with_context(|| format!("creating {}", a.output.display()))?;
    let mut comment = format!(
        "fracid drive sine sweep: {} V around {} V, {} cycles, {} Hz sampling; gain (rad/s)/V",
        a.amplitude, a.offset, a.cycles, conf.sample_rate_hz
    );
    comment += &format!(
        "\n{}",
        drive::bode::hold_line(1.0 / f64::from(conf.sample_rate_hz))
    );
    comment +=
        "\nfrequencies applied so the window holds whole cycles (requested Hz -> applied Hz):";
    comment += &if moved.is_empty() {
        " all as requested".to_string()
    } else {
        format!(" {}", moved.join(", "))
    };
    if a.repeats > 1 {
        comment += &format!(
            "\n{} repeats per frequency: trimmed mean (largest and smallest gain dropped, likewise the phase); \
             gain_db_std, phase_deg_std: sample standard deviations of the repeats",
            a.repeats
        );
    }
    for p in &problems {
        comment += &format!("\nproblem: {p}");
    }
    if !unmeasured.is_empty() {
        comment += &format!("\nmissing frequencies (Hz): {}", unmeasured.join(", "));
    }
    drive::bode::write_csv(std::io::BufWriter::new(file), &points, &comment)
        .with_context(|| format!("writing {}", a.output.display()))?;
    for p in &problems {
        eprintln!("warning: {p}");
    }
    eprintln!(
        "{}: {} of {} frequencies",
        a.output.display(),
        points.len(),
        sweep.freqs_hz.len()
    );
    if !unmeasured.is_empty() {
        return Err(anyhow::anyhow!(
            "{}{} frequencies could not be measured ({} Hz)",
            if interrupted {
                "interrupted (Ctrl-C), drive stopped: "
            } else {
                ""
            },
            unmeasured.len(),
            unmeasured.join(", ")
        ));
    }
    Ok(())
}

fn status(a: StatusArgs) -> Result<()> {
    let cfg = ClientConfig {
        baud: a.baud,
        ..ClientConfig::default()
    };
    let mut c = Client::open(&a.port, cfg)
        .map_err(lib_err)
        .with_context(|| format!("connecting to {}", a.port))?;
    let h = c.drive_info().context("no HELLO reply")?;
    let s = c.status().map_err(lib_err)?;
    println!(
        "drive at {}: protocol {}, firmware {}.{}, {} channels, blocks up to {} samples, up to {} Hz, boot id {:#06x}",
        a.port, h.proto_version, h.fw_major, h.fw_minor, h.n_channels, h.max_block_samples, h.max_sample_rate_hz, h.boot_id
    );
    println!(
        "state {:?}, fault {}, run {} ({} samples, {} blocks dropped, {} clamped), {} receive errors",
        s.state, s.fault, s.run_id, s.samples_done, s.blocks_dropped, s.clamped, s.rx_errors
    );
    Ok(())
}
