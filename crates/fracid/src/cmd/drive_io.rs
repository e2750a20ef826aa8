//! What the drive commands share (`fracid drive prbs/sine/loop/autotune`): the port options,
//! the connection, the outputs' checks, the run under a signal handler that stops the drive, and
//! how a recorded run ends.

use crate::cmd::BadInput;
use crate::interrupt::{Interrupted, StopOnInterrupt};
use anyhow::{Context, Result};
use drive::client::{Client, ClientConfig, LazyFile, Progress};
use drive::protocol::{Configure, MAX_BLOCK_SAMPLES};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::Duration;

/// The autotune layer's errors to CLI errors: bad requests exit 2, the drive's as
/// [`lib_err`] maps them, the rest (an unusable experiment, an interruption) by their source.
pub(crate) fn autotune_err(e: autotune::Error) -> anyhow::Error {
    match e {
        autotune::Error::InvalidParam(m) => anyhow::Error::new(BadInput(m)),
        autotune::Error::Drive(d) => lib_err(d),
        e => anyhow::Error::new(e),
    }
}

/// The serial link's options, shared by every command that talks to a drive (flattened into
/// [`PortArgs`] and `fracid drive autotune`'s options).
#[derive(Debug, Clone, clap::Args)]
pub struct LinkArgs {
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
}

/// Connection options shared by the client subcommands: the link, the block size, the clamp.
#[derive(Debug, clap::Args)]
pub struct PortArgs {
    /// The serial link.
    #[command(flatten)]
    pub link: LinkArgs,
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

/// The drive configuration from the options, checked before anything is opened (exit 2).
pub(crate) fn port_conf(p: &PortArgs) -> Result<Configure> {
    if p.link.baud == 0 {
        crate::bad_input!("--baud must be positive");
    }
    if p.link
        .timeout_ms
        .is_some_and(|t| !(1..=60_000).contains(&t))
    {
        crate::bad_input!("--timeout-ms must be in 1..=60000");
    }
    if p.link.retries > 100 {
        crate::bad_input!("--retries must be at most 100, got {}", p.link.retries);
    }
    if p.link.sample_rate == 0 {
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
        sample_rate_hz: p.link.sample_rate,
        block_samples: p.block,
        u_limit: (p.u_limit * 1000.0).round() as i16,
        ..Configure::default()
    })
}

/// Open the port, check the sample rate against the drive's, configure.
pub(crate) fn connect(p: &PortArgs, conf: &Configure) -> Result<Client> {
    let cfg = ClientConfig {
        baud: p.link.baud,
        timeout: p.link.timeout_ms.map(Duration::from_millis),
        retries: p.link.retries,
        keepalive: Duration::from_millis(p.link.keepalive_ms),
        ..ClientConfig::default()
    };
    let mut c = Client::open(&p.link.port, cfg)
        .map_err(lib_err)
        .with_context(|| format!("connecting to the drive at {}", p.link.port))?;
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
