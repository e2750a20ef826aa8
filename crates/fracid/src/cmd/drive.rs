//! `fracid drive ...`: the drive simulator and acquisition from a drive over a serial port.

use crate::cmd::BadInput;
use crate::interrupt::{Interrupted, StopOnInterrupt};
use anyhow::{Context, Result};
use drive::bode::BodePoint;
use drive::client::{
    Client, ClientConfig, CsvSink, LazyFile, PrbsTest, Progress, SineSweep, SweepEvent,
};
use drive::protocol::{Configure, MAX_BLOCK_SAMPLES};
use drive::sim::{DriveSim, Effects, FaultAt, Faults, FirmwareKind, SimClock, SimConfig};
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
    /// Run a speed loop with a controller of `fracid tune --dt ... --json` (its discrete
    /// realisation, downloaded to the drive) and a reference step; write t,r,u,y as CSV.
    Loop(crate::cmd::drive_loop::LoopArgs),
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
    /// Interval between the host's KEEPALIVE frames during a run, ms (a few ms lets a drive
    /// simulator in virtual time, `fracid drive sim --virtual-time`, run far faster than real time).
    #[arg(long, default_value_t = 150, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub keepalive_ms: u64,
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
    /// Motor model, voltage to speed (default: the paper's time-domain PMSM model): any model the
    /// identification returns, products of factors as written included, e.g. a resonance at the
    /// load `3/((0.005 s + 1)(1.2509e-5 s^2 + 3.5368e-4 s + 1))`.
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
    /// Hidden effect: a constant offset added to the command at the input, V.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub offset: f64,
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
    /// Firmware behind the pty: `rust` (the simulator's own) or `c` (the C firmware of
    /// `firmware/`, as flashed on the F2812). Default: rust.
    #[arg(long, value_enum)]
    pub firmware: Option<SimFirmware>,
    /// Run the drive in virtual time: its clock runs as fast as the host allows instead of the
    /// wall clock, waiting only for the host to read and for its keepalive (a host sending its
    /// KEEPALIVE every few ms, `--keepalive-ms`, gets the most out of it). Default: real time.
    #[arg(long)]
    pub virtual_time: bool,
}

/// The firmware of `fracid drive sim --firmware`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SimFirmware {
    /// The simulator's Rust implementation of the protocol.
    Rust,
    /// The C firmware (`firmware/`, fracfw) linked into the simulator.
    C,
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
        DriveCmd::Loop(a) => crate::cmd::drive_loop::run(a),
        DriveCmd::Status(a) => status(a),
    }
}

/// Library errors to CLI errors: bad parameters exit 2, port/I-O problems exit 3.
pub(crate) fn lib_err(e: drive::Error) -> anyhow::Error {
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
    // An improper model cannot be simulated: every acquisition would fail, so refuse it now.
    model
        .check_proper()
        .context("--model cannot be simulated by the drive simulator")?;
    if let Some(link) = &a.link {
        check_link_path(link)?;
    }
    if let Some(d) = a.duration {
        if !(d.is_finite() && d > 0.0) {
            crate::bad_input!("--duration must be a finite number of seconds > 0, got {d}");
        }
    }
    // Effects, faults and the baud rate are checked by the simulator (exit 2 when out of range).
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
            offset_v: a.offset,
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
        firmware: match a.firmware {
            Some(SimFirmware::Rust) | None => FirmwareKind::Rust,
            Some(SimFirmware::C) => FirmwareKind::C,
        },
        clock: if a.virtual_time {
            SimClock::Virtual
        } else {
            SimClock::RealTime
        },
        ..SimConfig::default()
    };
    let firmware = match cfg.firmware {
        FirmwareKind::C => "C",
        FirmwareKind::Rust => "Rust",
    };
    let s = DriveSim::spawn(cfg).map_err(lib_err)?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", s.port_path())?;
    out.flush()?;
    drop(out);
    crate::eprintln_safe!(
        "drive simulator ({firmware} firmware) at {} ({} baud); stop with Ctrl-C",
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
    crate::eprintln_safe!(
        "drive simulator: {} frames sent ({} damaged), {} received, {} blocks dropped, {} runs",
        st.frames_sent,
        st.frames_damaged,
        st.frames_received,
        st.blocks_dropped,
        st.runs_started
    );
    s.stop();
    Ok(())
}

/// `--link` replaces a symlink (the simulator's own, from an earlier run) but never a file or a
/// directory: their data would be lost (exit 2).
fn check_link_path(link: &std::path::Path) -> Result<()> {
    match std::fs::symlink_metadata(link) {
        Ok(m) if !m.file_type().is_symlink() => crate::bad_input!(
            "--link {}: a {} exists there and would be replaced by the link; choose a new path \
             (an existing symlink is replaced)",
            link.display(),
            if m.is_dir() { "directory" } else { "file" }
        ),
        _ => Ok(()),
    }
}

/// The drive configuration from the options, checked before anything is opened (exit 2).
pub(crate) fn port_conf(p: &PortArgs) -> Result<Configure> {
    if p.baud == 0 {
        crate::bad_input!("--baud must be positive");
    }
    if p.timeout_ms.is_some_and(|t| !(1..=60_000).contains(&t)) {
        crate::bad_input!("--timeout-ms must be in 1..=60000");
    }
    if p.retries > 100 {
        crate::bad_input!("--retries must be at most 100, got {}", p.retries);
    }
    if p.sample_rate == 0 {
        crate::bad_input!("--sample-rate must be positive");
    }
    if !(1..=MAX_BLOCK_SAMPLES).contains(&p.block) {
        crate::bad_input!(
            "--block must be in 1..={MAX_BLOCK_SAMPLES}, got {}",
            p.block
        );
    }
    if !(p.u_limit > 0.0 && p.u_limit <= 32.767) {
        crate::bad_input!("--u-limit must be in (0, 32.767] V, got {}", p.u_limit);
    }
    Ok(Configure {
        sample_rate_hz: p.sample_rate,
        block_samples: p.block,
        u_limit: (p.u_limit * 1000.0).round() as i16,
        ..Configure::default()
    })
}

/// Open the port, check the sample rate against the drive's, configure.
pub(crate) fn connect(p: &PortArgs, conf: &Configure) -> Result<Client> {
    let cfg = ClientConfig {
        baud: p.baud,
        timeout: p.timeout_ms.map(Duration::from_millis),
        retries: p.retries,
        keepalive: Duration::from_millis(p.keepalive_ms),
        ..ClientConfig::default()
    };
    let mut c = Client::open(&p.port, cfg)
        .map_err(lib_err)
        .with_context(|| format!("connecting to the drive at {}", p.port))?;
    if let Some(h) = c.drive_info() {
        if conf.sample_rate_hz > h.max_sample_rate_hz {
            crate::bad_input!(
                "--sample-rate {} Hz is above the drive's maximum, {} Hz",
                conf.sample_rate_hz,
                h.max_sample_rate_hz
            );
        }
    }
    c.configure(conf)
        .map_err(lib_err)
        .context("configuring the drive")?;
    Ok(c)
}

/// `-` as an output path: standard output (`/dev/stdout`), not a file named `-`.
pub(crate) fn output_path(p: &std::path::Path) -> PathBuf {
    if p.as_os_str() == "-" {
        PathBuf::from("/dev/stdout")
    } else {
        p.to_path_buf()
    }
}

/// Device and inode of an existing file.
fn inode(p: &std::path::Path) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = p;
        None
    }
}

/// The device number of a character device (a serial port, a terminal, `/dev/null`).
fn char_device(p: &std::path::Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{FileTypeExt, MetadataExt};
        std::fs::metadata(p)
            .ok()
            .filter(|m| m.file_type().is_char_device())
            .map(|m| m.rdev())
    }
    #[cfg(not(unix))]
    {
        let _ = p;
        None
    }
}

/// Whether two output paths name one file: the same inode when both exist, else the same
/// canonical folder and name.
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    if let (Some(x), Some(y)) = (inode(a), inode(b)) {
        return x == y;
    }
    let planned = |p: &std::path::Path| {
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => std::path::Path::new("."),
        };
        Some(std::fs::canonicalize(parent).ok()?.join(p.file_name()?))
    };
    planned(a).is_some_and(|x| Some(x) == planned(b))
}

/// The outputs of a drive command, checked before the drive is asked anything (exit 2): none of
/// them an input nor two of them the same file ([`super::paths::check`]), none the serial port
/// (the CSV would go down the line) nor any character device other than standard output and
/// `/dev/null`.
pub(crate) fn check_outputs(
    port: &str,
    inputs: &[super::paths::Named<'_>],
    outputs: &[super::paths::Named<'_>],
) -> Result<()> {
    super::paths::check(inputs, outputs)?;
    let port = std::path::Path::new(port);
    let allowed = [
        char_device(std::path::Path::new("/dev/stdout")),
        char_device(std::path::Path::new("/dev/null")),
    ];
    for (name, p) in outputs {
        let dev = char_device(p);
        if same_file(p, port) || dev.is_some_and(|d| Some(d) == char_device(port)) {
            crate::bad_input!(
                "{name} {} is the serial port {}: the record would be written down the line",
                p.display(),
                port.display()
            );
        }
        if dev.is_some() && !allowed.contains(&dev) {
            crate::bad_input!(
                "{name} {} is a device (a serial port or a terminal?), not a file: write to a \
                 file, or to standard output with -",
                p.display()
            );
        }
    }
    Ok(())
}

/// The output file, created only when the run's first data arrive ([`LazyFile`]); a path that
/// cannot be written fails here, before the drive is asked anything (exit 3).
pub(crate) fn output_file(path: &std::path::Path) -> Result<LazyFile> {
    LazyFile::new(path).context("cannot write the output file")
}

/// The voltage levels a command holds (raw units), against the drive's clamp: exit 2 when every
/// level is beyond it (the drive would clamp the whole excitation away), a warning when some are.
fn check_levels(levels: &[(&str, i32)], conf: &Configure) -> Result<()> {
    let lim = i32::from(conf.u_limit);
    let v = |raw: i32| raw as f64 * conf.u_lsb();
    let beyond: Vec<String> = levels
        .iter()
        .filter(|(_, raw)| raw.abs() > lim)
        .map(|(name, raw)| format!("{name} {} V", v(*raw)))
        .collect();
    if beyond.len() == levels.len() {
        crate::bad_input!(
            "every level of the excitation ({}) is beyond the drive's voltage clamp of +-{} V (--u-limit): the drive would hold the clamp and nothing would be excited",
            beyond.join(", "),
            v(lim)
        );
    }
    if !beyond.is_empty() {
        crate::eprintln_safe!(
            "warning: {} beyond the drive's voltage clamp of +-{} V: those samples will be clamped",
            beyond.join(", "),
            v(lim)
        );
    }
    Ok(())
}

pub(crate) fn progress_bar(quiet: bool, unit: &str) -> Option<indicatif::ProgressBar> {
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

pub(crate) fn attach(c: &mut Client, pb: &Option<indicatif::ProgressBar>) {
    if let Some(pb) = pb.clone() {
        c.set_progress(move |p: Progress| {
            pb.set_length(p.total);
            pb.set_position(p.done);
        });
    }
}

/// What an acquisition kept, in a line: `FILE: N samples kept`, and for an incomplete run its
/// problems and the missing samples (`a..b`).
pub(crate) fn kept_summary(output: &std::path::Path, acq: &drive::client::Acquisition) -> String {
    let missing: Vec<String> = acq
        .missing
        .iter()
        .map(|r| format!("{}..{}", r.start, r.end))
        .collect();
    format!(
        "{}: {} samples kept{}",
        output.display(),
        acq.received,
        if acq.complete {
            String::new()
        } else {
            format!(
                ", run incomplete ({}), missing samples {}",
                acq.problems.join("; "),
                if missing.is_empty() {
                    "none".to_string()
                } else {
                    missing.join(", ")
                }
            )
        }
    )
}

/// The error of an acquisition whose output was closed under it (a broken pipe): the drive was
/// stopped (by the client, on the sink's error), what was lost said; exit 3 (I/O).
pub(crate) fn lost_output(e: anyhow::Error, output: &std::path::Path, what: &str) -> anyhow::Error {
    let broken = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            || c.downcast_ref::<drive::Error>().is_some_and(
                |d| matches!(d, drive::Error::Io(io) if io.kind() == std::io::ErrorKind::BrokenPipe),
            )
    });
    if broken {
        e.context(format!(
            "the output {} was closed during the run (broken pipe): the drive was stopped and \
             the rest of the {what} is lost (what was written before has no footer)",
            output.display()
        ))
    } else {
        e
    }
}

/// Connect to the drive, show the progress in `unit` (unless quiet or not a terminal), and run
/// `body` on the client with the first signal of [`crate::interrupt::handled_signals`] (SIGINT,
/// SIGTERM, SIGHUP, SIGQUIT, ...) stopping the drive (what arrived is
/// kept, the output says what is missing): the body's result and the signal that came during
/// it, if one did. The acquisition runs of `prbs`, `sine` and `loop` go through it.
///
/// # Errors
/// Connecting to the drive (see [`connect`]).
pub(crate) fn run_on_drive<T>(
    port: &PortArgs,
    conf: &Configure,
    unit: &str,
    body: impl FnOnce(&mut Client) -> T,
) -> Result<(T, Option<i32>)> {
    let mut c = connect(port, conf)?;
    let pb = progress_bar(port.quiet, unit);
    attach(&mut c, &pb);
    let signals = StopOnInterrupt::arm(c.stop_handle());
    let out = body(&mut c);
    let signal = signals.signal();
    drop(signals);
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    Ok((out, signal))
}

/// The record of a run (`prbs`, `loop`) closed: its file (the sink's writer) flushed, then the
/// run's result; a run or a flush that failed because the output was closed says what was lost
/// ([`lost_output`]).
///
/// # Errors
/// The run's error, then the file's (exit 3 for a closed output).
pub(crate) fn close_record(
    acq: Result<drive::client::Acquisition>,
    file: std::io::Result<LazyFile>,
    output: &std::path::Path,
) -> Result<drive::client::Acquisition> {
    let written = file
        .and_then(|mut f| f.flush().map(|_| f.is_created()))
        .with_context(|| format!("writing {}", output.display()));
    let acq = acq.map_err(|e| lost_output(e, output, "record"))?;
    written.map_err(|e| lost_output(e, output, "record"))?;
    Ok(acq)
}

/// How a recorded run (`prbs`, `loop`) ends, `summary` saying what was kept: a signal (exit by
/// it: [`Interrupted`]), else `failure` if any, else complete (`summary, complete` on stderr),
/// else incomplete: a warning with `allow_incomplete`, an error (exit 1) without.
///
/// # Errors
/// As said.
pub(crate) fn record_outcome(
    acq: &drive::client::Acquisition,
    signal: Option<i32>,
    summary: String,
    failure: Option<anyhow::Error>,
    allow_incomplete: bool,
) -> Result<()> {
    if let Some(signal) = signal {
        return Err(Interrupted {
            signal,
            message: format!("drive stopped; {summary}"),
        }
        .into());
    }
    if let Some(e) = failure {
        return Err(e);
    }
    if acq.complete {
        crate::eprintln_safe!("{summary}, complete");
        Ok(())
    } else if allow_incomplete {
        crate::eprintln_safe!("warning: {summary}");
        Ok(())
    } else {
        Err(anyhow::anyhow!(summary))
    }
}

fn prbs(a: PrbsArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    // Everything is checked before the output is touched or the drive asked anything.
    let conf = port_conf(&a.port)?;
    let test = PrbsTest {
        order: a.order,
        seed: a.seed,
        clock_s: a.clock,
        amplitude_v: a.amplitude,
        offset_v: a.offset,
        periods: a.periods,
        settle_s: a.settle,
    };
    if !(a.settle.is_finite() && a.settle >= 0.0) {
        crate::bad_input!("--settle must be a finite number of seconds >= 0");
    }
    if a.periods == 0 {
        crate::bad_input!("--periods must be at least 1");
    }
    let cmd = test.to_command(&conf).map_err(lib_err)?;
    let (off, amp) = (i32::from(cmd.offset), i32::from(cmd.amplitude));
    check_levels(
        &[("high level", off + amp), ("low level", off - amp)],
        &conf,
    )?;
    let output = output_path(&a.output);
    check_outputs(&a.port.port, &[], &[("--output", &output)])?;
    let mut sink = CsvSink::new(output_file(&output)?);
    // The first SIGINT/SIGTERM/SIGHUP/SIGQUIT/... stops the drive; the record keeps what arrived and its
    // footer says what is missing.
    let (acq, signal) = run_on_drive(&a.port, &conf, "samples", |c| {
        c.run_prbs(&test, &mut sink).map_err(lib_err)
    })?;
    let acq = close_record(acq.context("the PRBS run"), sink.into_inner(), &output)?;
    let summary = kept_summary(&a.output, &acq);
    for w in acq.warnings() {
        crate::eprintln_safe!("warning: {w}");
    }
    if signal.is_some() && acq.complete {
        crate::eprintln_safe!("{summary}, complete (the signal came after the run had ended)");
    }
    let failure = acq.excitation_missing().then(|| {
        anyhow::anyhow!(
            "{summary}; no excitation: the input is constant after the settling part{} (see the file's comments)",
            if acq.clamped_blocks > 0 {
                ", clamped by the drive"
            } else {
                ""
            }
        )
    });
    record_outcome(&acq, signal, summary, failure, a.allow_incomplete)
}

/// The path of the file of single repeats, if any: `--repeats-out`, or by default with
/// `--repeats` above 1 the output's name with `.repeats.csv` appended. Like the Bode table it is
/// created with the first repeat measured.
fn repeats_path(a: &SineArgs) -> Option<PathBuf> {
    match &a.repeats_out {
        Some(p) => Some(output_path(p)),
        None if a.repeats > 1 => {
            let mut s = a.output.clone().into_os_string();
            s.push(".repeats.csv");
            Some(PathBuf::from(s))
        }
        None => None,
    }
}

/// The file of single repeats at `path` (see [`repeats_path`]).
fn open_repeats_file(
    a: &SineArgs,
    conf: &Configure,
    path: Option<PathBuf>,
) -> Result<Option<RepeatsFile>> {
    let Some(path) = path else {
        return Ok(None);
    };
    Ok(Some(RepeatsFile {
        w: std::io::BufWriter::new(output_file(&path)?),
        header: format!(
            "# fracid drive sine: single repeats as measured, {} V around {} V, {} Hz sampling\n{}",
            a.amplitude,
            a.offset,
            conf.sample_rate_hz,
            drive::bode::REPEATS_HEADER
        ),
        rows: 0,
        path,
    }))
}

/// The single repeats of a sweep, one line each as measured ([`drive::bode::write_repeat_line`]).
struct RepeatsFile {
    w: std::io::BufWriter<LazyFile>,
    header: String,
    rows: usize,
    path: PathBuf,
}

impl RepeatsFile {
    fn repeat(&mut self, p: &BodePoint, rep: u32) -> std::io::Result<()> {
        let r = (|| {
            if self.rows == 0 {
                writeln!(self.w, "{}", self.header)?;
            }
            drive::bode::write_repeat_line(&mut self.w, p, rep)?;
            self.rows += 1;
            self.w.flush()
        })();
        r.map_err(|e| {
            std::io::Error::new(e.kind(), format!("writing {}: {e}", self.path.display()))
        })
    }
}

/// The most frequencies of one sweep (`--points`, `--freqs`).
pub const MAX_SWEEP_FREQUENCIES: usize = 1000;

/// The sweep from the options, checked (exit 2).
fn sine_sweep(a: &SineArgs, conf: &Configure) -> Result<SineSweep> {
    if a.freqs.is_none() && (a.f_min > a.f_max || a.f_min == a.f_max && a.points > 1) {
        crate::bad_input!(
            "--f-min {} Hz must be below --f-max {} Hz (a table of {} frequencies)",
            a.f_min,
            a.f_max,
            a.points
        );
    }
    if a.freqs.is_none() && a.points == 0 {
        crate::bad_input!("--points must be at least 1");
    }
    // Each frequency is seconds of the drive's time: a sweep of more is a typing error, refused
    // before the table is even made (1e8 of them took 2.3 GB).
    let asked = a.freqs.as_ref().map_or(a.points, Vec::len);
    if asked > MAX_SWEEP_FREQUENCIES {
        crate::bad_input!(
            "{asked} frequencies (--points or --freqs): at most {MAX_SWEEP_FREQUENCIES} in one sweep"
        );
    }
    let mut sweep = SineSweep::log(a.f_min, a.f_max, a.points);
    if let Some(f) = &a.freqs {
        sweep.freqs_hz = f.clone();
    }
    if sweep.freqs_hz.is_empty() || sweep.freqs_hz.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
        crate::bad_input!("frequencies must be positive");
    }
    // A Bode table is read in increasing frequency, each once: --freqs in another order is
    // sorted and a repeated frequency measured once, said.
    let asked = sweep.freqs_hz.clone();
    sweep.freqs_hz.sort_by(f64::total_cmp);
    sweep.freqs_hz.dedup();
    if sweep.freqs_hz != asked {
        crate::eprintln_safe!(
            "warning: --freqs sorted into increasing order{}: {}",
            if sweep.freqs_hz.len() < asked.len() {
                ", repeated frequencies measured once"
            } else {
                ""
            },
            sweep
                .freqs_hz
                .iter()
                .map(f64::to_string)
                .collect::<Vec<_>>()
                .join(",")
        );
    }
    let nyq = conf.sample_rate_hz as f64 / 2.0;
    if let Some(f) = sweep.freqs_hz.iter().find(|&&f| f >= nyq) {
        crate::bad_input!(
            "{f} Hz is at or above Nyquist ({nyq} Hz at --sample-rate {})",
            conf.sample_rate_hz
        );
    }
    let raw = |v: f64, name: &str| -> Result<i32> {
        let r = (v / conf.u_lsb()).round();
        if !(r.is_finite() && r.abs() <= 32767.0) {
            crate::bad_input!("{name} {v} V is out of the command range");
        }
        Ok(r as i32)
    };
    let (amp, off) = (raw(a.amplitude, "--amplitude")?, raw(a.offset, "--offset")?);
    if amp <= 0 {
        crate::bad_input!("--amplitude must be > 0 V");
    }
    if !(a.min_settle.is_finite() && a.min_settle >= 0.0) {
        crate::bad_input!("--min-settle must be a finite number of seconds >= 0");
    }
    if a.cycles == 0 {
        crate::bad_input!("--cycles must be at least 1");
    }
    check_levels(&[("crest", off + amp), ("trough", off - amp)], conf)?;
    sweep.amplitude_v = a.amplitude;
    sweep.offset_v = a.offset;
    sweep.cycles = a.cycles;
    sweep.settle_cycles = a.settle_cycles;
    sweep.min_settle_s = a.min_settle;
    sweep.stream = a.stream;
    if a.repeats == 0 {
        crate::bad_input!("--repeats must be at least 1");
    }
    sweep.repeats = a.repeats;
    Ok(sweep)
}

/// The Bode table of a sweep, written point by point as they are measured (each frequency's point
/// once its repeats are done): the header with the first point (a sweep that measures nothing
/// leaves the file untouched), a footer `# complete: N frequencies` or
/// `# incomplete: missing frequencies (Hz) ... (reason)` at the end. Rows as
/// [`drive::bode::write_csv`] writes them (with the spread columns when the sweep repeats).
pub(crate) struct BodeFile {
    w: std::io::BufWriter<LazyFile>,
    header: String,
    spread: bool,
    rows: usize,
}

impl BodeFile {
    /// The table at `path` (created with its first point), `header` as `#` comment lines, the
    /// spread columns if `spread`.
    ///
    /// # Errors
    /// A path that cannot be written (exit 3), checked now.
    pub(crate) fn new(path: &std::path::Path, header: String, spread: bool) -> Result<Self> {
        Ok(Self {
            w: std::io::BufWriter::new(output_file(path)?),
            header,
            spread,
            rows: 0,
        })
    }

    /// Write one point (the header first), flushed.
    pub(crate) fn point(&mut self, p: &BodePoint) -> std::io::Result<()> {
        if self.rows == 0 {
            for line in self.header.lines() {
                writeln!(self.w, "# {line}")?;
            }
            drive::bode::write_csv_columns(&mut self.w, self.spread)?;
        }
        drive::bode::write_csv_row(&mut self.w, p, self.spread)?;
        self.rows += 1;
        self.w.flush()
    }

    /// Problems and the footer; whether the file was written at all.
    pub(crate) fn finish(
        mut self,
        problems: &[String],
        unmeasured: &[String],
    ) -> std::io::Result<bool> {
        if self.rows == 0 {
            return Ok(false);
        }
        for p in problems {
            writeln!(self.w, "# problem: {p}")?;
        }
        if unmeasured.is_empty() {
            writeln!(self.w, "# complete: {} frequencies", self.rows)?;
        } else {
            let reason = problems.last().map_or("not measured", String::as_str);
            writeln!(
                self.w,
                "# incomplete: missing frequencies (Hz) {} ({reason})",
                unmeasured.join(", ")
            )?;
        }
        self.w.flush()?;
        Ok(true)
    }
}

fn sine(a: SineArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    let conf = port_conf(&a.port)?;
    let sweep = sine_sweep(&a, &conf)?;
    // The drive measures at the whole-cycle frequency nearest each request.
    let applied = sweep.applied_freqs_hz(conf.sample_rate_hz);
    // Two requests that become one applied frequency would make two rows of one frequency.
    for (k, w) in applied.windows(2).enumerate() {
        if let [Some(x), Some(y)] = w {
            if (x - y).abs() <= 1e-9 * x.abs() {
                crate::bad_input!(
                    "{} Hz and {} Hz are both measured at {x} Hz (the nearest frequency with whole \
                     cycles in the window): drop one",
                    sweep.freqs_hz[k],
                    sweep.freqs_hz[k + 1]
                );
            }
        }
    }
    let moved: Vec<String> = sweep
        .freqs_hz
        .iter()
        .zip(&applied)
        .filter_map(|(f, fa)| {
            fa.filter(|fa| (fa - f).abs() > 1e-6)
                .map(|fa| format!("{f} -> {fa}"))
        })
        .collect();
    let mut header = format!(
        "fracid drive sine sweep: {} V around {} V, {} cycles, {} Hz sampling; gain (rad/s)/V\n{}",
        a.amplitude,
        a.offset,
        a.cycles,
        conf.sample_rate_hz,
        drive::bode::hold_line(1.0 / f64::from(conf.sample_rate_hz))
    );
    header +=
        "\nfrequencies applied so the window holds whole cycles (requested Hz -> applied Hz):";
    header += &if moved.is_empty() {
        " all as requested".to_string()
    } else {
        format!(" {}", moved.join(", "))
    };
    if a.repeats > 1 {
        header += &format!(
            "\n{} repeats per frequency: trimmed mean (largest and smallest gain dropped, likewise the phase); \
             gain_db_std, phase_deg_std: sample standard deviations of the repeats",
            a.repeats
        );
    }
    let output = output_path(&a.output);
    let reps_path = repeats_path(&a);
    let mut outs: Vec<(&str, &std::path::Path)> = vec![("--output", &output)];
    if let Some(r) = &reps_path {
        outs.push(("the repeats file (--repeats-out)", r));
    }
    check_outputs(&a.port.port, &[], &outs)?;
    let mut file = BodeFile::new(&output, header, sweep.repeats > 1)?;
    let mut reps_file = open_repeats_file(&a, &conf, reps_path)?;
    // The first SIGINT/SIGTERM/SIGHUP/SIGQUIT/... stops the drive; the points measured so far are in the
    // file, the rest listed in its footer.
    let (swept, signal) = run_on_drive(&a.port, &conf, "frequencies", |c| {
        c.run_sine_sweep_with(&sweep, &mut |ev| match ev {
            SweepEvent::Repeat(p, rep) => match reps_file.as_mut() {
                Some(r) => r.repeat(p, rep),
                None => Ok(()),
            },
            SweepEvent::Point(p) => file.point(p),
        })
        .map_err(lib_err)
    })?;
    let (points, mut problems) = match swept {
        Ok(r) => r,
        Err(e) => {
            // Keep what was measured before the failure, with a footer.
            let _ = file.finish(&[format!("{e:#}")], &["(sweep failed)".into()]);
            let e = e.context(format!("the sine sweep ({})", output.display()));
            return Err(lost_output(e, &output, "table"));
        }
    };
    if let Some(s) = signal {
        problems.push(format!(
            "interrupted by {}: sweep stopped",
            crate::interrupt::signal_name(s)
        ));
    }
    let unmeasured: Vec<String> = sweep
        .freqs_hz
        .iter()
        .zip(&applied)
        .filter(|(_, fa)| {
            !fa.is_some_and(|fa| points.iter().any(|p| (p.freq_hz - fa).abs() <= 1e-9 * fa))
        })
        .map(|(f, _)| f.to_string())
        .collect();
    let written = file
        .finish(&problems, &unmeasured)
        .with_context(|| format!("writing {}", output.display()))
        .map_err(|e| lost_output(e, &output, "table"))?;
    for p in &problems {
        crate::eprintln_safe!("warning: {p}");
    }
    let summary = format!(
        "{}: {} of {} frequencies{}",
        a.output.display(),
        points.len(),
        sweep.freqs_hz.len(),
        if written {
            ""
        } else {
            " (nothing measured: the file was not written)"
        }
    );
    if let Some(signal) = signal {
        return Err(Interrupted {
            signal,
            message: format!("drive stopped; {summary}"),
        }
        .into());
    }
    if !unmeasured.is_empty() {
        return Err(anyhow::anyhow!(
            "{summary}; {} frequencies could not be measured ({} Hz)",
            unmeasured.len(),
            unmeasured.join(", ")
        ));
    }
    crate::eprintln_safe!("{summary}");
    Ok(())
}

fn status(a: StatusArgs) -> Result<()> {
    if a.baud == 0 {
        crate::bad_input!("--baud must be positive");
    }
    let cfg = ClientConfig {
        baud: a.baud,
        ..ClientConfig::default()
    };
    let mut c = Client::open(&a.port, cfg)
        .map_err(lib_err)
        .with_context(|| format!("connecting to {}", a.port))?;
    let h = c.drive_info().context("no HELLO reply")?;
    let s = c.status().map_err(lib_err)?;
    // Written, not printed: a full or closed stdout is an I/O error (exit 3), not a panic.
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "drive at {}: protocol {}, firmware {}.{}, {} channels, blocks up to {} samples, up to {} Hz, boot id {:#06x}",
        a.port, h.proto_version, h.fw_major, h.fw_minor, h.n_channels, h.max_block_samples, h.max_sample_rate_hz, h.boot_id
    )?;
    writeln!(
        out,
        "state {:?}, fault {}, run {} ({} samples, {} blocks dropped, {} clamped), {} receive errors",
        s.state, s.fault, s.run_id, s.samples_done, s.blocks_dropped, s.clamped, s.rx_errors
    )?;
    out.flush().context("writing to stdout")?;
    Ok(())
}
