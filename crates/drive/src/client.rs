//! The host side: a client over `serialport` (crate docs, section 8).
//!
//! ```no_run
//! use drive::client::{Client, ClientConfig, CsvSink, PrbsTest};
//! let mut c = Client::open("/dev/ttyUSB0", ClientConfig::default())?;
//! c.configure(&drive::protocol::Configure::default())?;
//! let mut sink = CsvSink::new(std::fs::File::create("prbs.csv")?);
//! let acq = c.run_prbs(&PrbsTest::paper(), &mut sink)?;
//! if !acq.complete { eprintln!("incomplete: missing {:?}", acq.missing); }
//! # Ok::<(), drive::Error>(())
//! ```

use crate::bode::{self, BodePoint};
use crate::codec::{self, StreamDecoder};
use crate::error::{Error, Result};
use crate::protocol::*;
use crate::vclock::VirtualClock;
use serialport::{SerialPort, TTYPort};
use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::ops::Range;
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Client settings.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Line rate, baud.
    pub baud: u32,
    /// Time to wait for an answer before resending; None = 100 ms + 3 longest frame times.
    pub timeout: Option<Duration>,
    /// Resends after the first attempt.
    pub retries: u32,
    /// Interval between KEEPALIVE frames during a run (of the drive's clock with
    /// [`ClientConfig::clock`], else of the wall clock).
    pub keepalive: Duration,
    /// Silence on the stream before the client polls the drive; None = max(400 ms, 4 blocks).
    pub stream_timeout: Option<Duration>,
    /// How long to keep trying to reopen a port that failed.
    pub reconnect_timeout: Duration,
    /// Open the port exclusively (TIOCEXCL); released when the client closes it.
    pub exclusive: bool,
    /// The drive's clock of a simulator in virtual time in this process
    /// ([`crate::sim::DriveSim::virtual_clock`]): the keepalive is kept on the drive's time
    /// (a KEEPALIVE every `keepalive` of drive time, and at once when the drive's clock waits
    /// for it), so that the drive need not wait for a wall-clock timer
    /// ([`crate::vclock`]). None (default): the keepalive runs on the wall clock.
    pub clock: Option<VirtualClock>,
    /// What the [`Acquisition`] of a run keeps of its samples ([`Retention`]): all of them
    /// (default), or only their count and gaps, the sink receiving them as they arrive (a long
    /// run written to a file in bounded memory).
    pub samples: Retention,
}

/// What an [`Acquisition`] keeps of the samples that arrive; the run's [`SampleSink`] receives
/// every one of them either way, and the counts, gaps, footer and completeness are the same.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Retention {
    /// Every sample in the acquisition's vectors (`index`, `t`, `u`, `y`, `i`, `raw`: about 46
    /// bytes a sample, more with the vectors' growth).
    #[default]
    Keep,
    /// None: the vectors stay empty; [`Acquisition::received`], the missing ranges and the
    /// excitation check ([`Acquisition::after_settle`]) are kept as the samples arrive.
    CountOnly,
}

impl Default for ClientConfig {
    fn default() -> Self {
        Self {
            baud: 115_200,
            timeout: None,
            retries: 5,
            keepalive: Duration::from_millis(150),
            stream_timeout: None,
            reconnect_timeout: Duration::from_secs(3),
            exclusive: true,
            clock: None,
            samples: Retention::Keep,
        }
    }
}

/// Counters kept by the client.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// Commands sent (first attempts).
    pub commands: u64,
    /// Resends.
    pub retries: u64,
    /// Port reopenings.
    pub reconnects: u64,
    /// Stream recoveries (silence on the stream).
    pub recoveries: u64,
    /// Valid frames received.
    pub frames: u64,
    /// Received frames discarded by the decoder.
    pub bad_frames: u64,
}

/// What a run is about, given to the sink before the first sample.
#[derive(Debug, Clone, PartialEq)]
pub struct RunInfo {
    /// Run id assigned by the drive.
    pub run_id: u16,
    /// Planned number of samples.
    pub total_samples: u64,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// A one-line description of the experiment.
    pub description: String,
}

/// Receives samples as they arrive.
pub trait SampleSink {
    /// Called once before the first sample.
    fn begin(&mut self, info: &RunInfo) -> io::Result<()>;
    /// One sample: index, time (s), u (V), y (rad/s), i (A). Indices only increase.
    fn sample(&mut self, index: u64, t: f64, u: f64, y: f64, i: f64) -> io::Result<()>;
    /// Called once at the end with the result.
    fn finish(&mut self, acq: &Acquisition) -> io::Result<()>;
}

/// A sink that discards everything.
#[derive(Debug, Default, Clone, Copy)]
pub struct NullSink;

impl SampleSink for NullSink {
    fn begin(&mut self, _: &RunInfo) -> io::Result<()> {
        Ok(())
    }
    fn sample(&mut self, _: u64, _: f64, _: f64, _: f64, _: f64) -> io::Result<()> {
        Ok(())
    }
    fn finish(&mut self, _: &Acquisition) -> io::Result<()> {
        Ok(())
    }
}

/// Writes `t,u,y,i` CSV rows as samples arrive, flushing every block; a `#` header with the run
/// parameters and a last line `# complete: N samples` or `# incomplete: missing samples a..b, ...
/// (reason)`. A file without such a footer was interrupted.
#[derive(Debug)]
pub struct CsvSink<W: Write> {
    w: io::BufWriter<W>,
    rows: u64,
}

impl<W: Write> CsvSink<W> {
    /// A sink writing to `w`.
    pub fn new(w: W) -> Self {
        Self {
            w: io::BufWriter::new(w),
            rows: 0,
        }
    }
    /// Unwrap the writer.
    pub fn into_inner(self) -> io::Result<W> {
        self.w.into_inner().map_err(|e| e.into_error())
    }
}

impl<W: Write> SampleSink for CsvSink<W> {
    fn begin(&mut self, info: &RunInfo) -> io::Result<()> {
        writeln!(self.w, "# fracid drive acquisition: {}", info.description)?;
        writeln!(
            self.w,
            "# run_id {}, {} samples planned at {} Hz; units: t s, u V, y rad/s, i A",
            info.run_id, info.total_samples, info.sample_rate_hz
        )?;
        writeln!(self.w, "t,u,y,i")?;
        self.w.flush()
    }
    fn sample(&mut self, _index: u64, t: f64, u: f64, y: f64, i: f64) -> io::Result<()> {
        let r = |v: f64| (v * 1e6).round() / 1e6;
        writeln!(self.w, "{t:.6},{},{},{}", r(u), r(y), r(i))?;
        self.rows += 1;
        if self.rows.is_multiple_of(64) {
            self.w.flush()?;
        }
        Ok(())
    }
    fn finish(&mut self, acq: &Acquisition) -> io::Result<()> {
        for w in acq.warnings() {
            writeln!(self.w, "# {w}")?;
        }
        writeln!(self.w, "{}", acq.footer())?;
        self.w.flush()
    }
}

/// A file created only when the first byte is written to it: the output of a run that never
/// started (bad options, a drive that does not answer or refuses the START) leaves an existing
/// file untouched, and a run that started writes its record as the data arrive (a process killed
/// outright leaves the rows that arrived and no footer, which readers take as interrupted).
///
/// [`LazyFile::new`] checks at once that the file can be created (so that a bad path fails
/// before the experiment, not after it).
///
/// ```
/// use std::io::Write;
/// let dir = std::env::temp_dir().join(format!("lazyfile-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let path = dir.join("keep.csv");
/// std::fs::write(&path, "old record\n")?;
/// let f = drive::client::LazyFile::new(&path)?;
/// drop(f); // nothing written: the old record is still there
/// assert_eq!(std::fs::read_to_string(&path)?, "old record\n");
/// let mut f = drive::client::LazyFile::new(&path)?;
/// writeln!(f, "new")?;
/// assert!(f.is_created());
/// drop(f);
/// assert_eq!(std::fs::read_to_string(&path)?, "new\n");
/// assert!(drive::client::LazyFile::new(dir.join("no/such/dir/x.csv")).is_err());
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), std::io::Error>(())
/// ```
#[derive(Debug)]
pub struct LazyFile {
    path: std::path::PathBuf,
    file: Option<std::fs::File>,
}

impl LazyFile {
    /// A file to be created (truncated if it exists) at the first write.
    ///
    /// # Errors
    /// The path is a directory, or its directory does not exist or cannot be written, or the
    /// existing file cannot be written: the `io::Error`, with the path in its message.
    pub fn new(path: impl Into<std::path::PathBuf>) -> io::Result<Self> {
        let path = path.into();
        check_writable(&path)?;
        Ok(Self { path, file: None })
    }
    /// Whether the file has been created (something was written).
    pub fn is_created(&self) -> bool {
        self.file.is_some()
    }
    /// The path.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }
    fn file(&mut self) -> io::Result<&mut std::fs::File> {
        if self.file.is_none() {
            let f = std::fs::File::create(&self.path).map_err(|e| with_path(&self.path, e))?;
            self.file = Some(f);
        }
        Ok(self.file.as_mut().expect("just created"))
    }
}

impl Write for LazyFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        self.file()?.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        match self.file.as_mut() {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

fn with_path(path: &std::path::Path, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("{}: {e}", path.display()))
}

/// Check, without changing anything, that a file can be created or overwritten at `path`: not a
/// directory; an existing file opens for writing (without truncation); otherwise a scratch file
/// can be created (and is removed) in its directory.
///
/// # Errors
/// The `io::Error` of the failed check, with the path in its message.
pub fn check_writable(path: &std::path::Path) -> io::Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            format!("{} is a directory", path.display()),
        )),
        Ok(_) => std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .map(drop)
            .map_err(|e| with_path(path, e)),
        Err(_) => {
            let dir = match path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => std::path::Path::new("."),
            };
            let name = path.file_name().ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("{} is not a file name", path.display()),
                )
            })?;
            let mut probe = std::ffi::OsString::from(".");
            probe.push(name);
            probe.push(format!(".{}.probe", std::process::id()));
            let probe = dir.join(probe);
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&probe)
                .map_err(|e| with_path(path, e))?;
            std::fs::remove_file(&probe).map_err(|e| with_path(&probe, e))
        }
    }
}

/// The result of a streamed run. Samples that arrived are kept whatever happened.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Acquisition {
    /// Run id.
    pub run_id: u16,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Samples received (whether kept or not, [`Retention`]).
    pub received: u64,
    /// Index of the last sample received.
    pub last_index: Option<u64>,
    /// The voltage command after the settling part, as the samples arrived.
    pub after_settle: AfterSettle,
    /// Sample indices received (increasing); empty with [`Retention::CountOnly`], as are `t`,
    /// `u`, `y`, `i` and `raw`.
    pub index: Vec<u64>,
    /// Time of each sample, s (index / sample rate).
    pub t: Vec<f64>,
    /// Voltage command, V.
    pub u: Vec<f64>,
    /// Speed, rad/s.
    pub y: Vec<f64>,
    /// Current, A.
    pub i: Vec<f64>,
    /// Raw samples `[u, y, i]` as received.
    pub raw: Vec<[i16; 3]>,
    /// Samples the drive produced (from STREAM_END if it arrived, else as planned).
    pub total_samples: u64,
    /// Samples the run was to have (the START's ACK).
    pub planned_samples: u64,
    /// True only if every index in `0..total_samples` arrived and the run ended normally.
    pub complete: bool,
    /// Missing sample ranges (half-open) in `0..max(total_samples, planned_samples)`: samples lost
    /// on the way and, for a run that ended early, the planned samples never produced. Empty for
    /// a sine run without streaming (nothing was to arrive).
    pub missing: Vec<Range<u64>>,
    /// The drive's end-of-run summary, if obtained.
    pub end: Option<StreamEnd>,
    /// Why the run is incomplete (empty when complete).
    pub problems: Vec<String>,
    /// Blocks with a clamped command sample.
    pub clamped_blocks: u64,
    /// The drive's single-bin DFT (sine runs).
    pub sine: Option<SineResult>,
    /// The port vanished during the run and did not come back within the reconnect window
    /// ([`ClientConfig::reconnect_timeout`]): the run ended for this host (the drive stops by
    /// itself when its keepalive expires). Listed in `problems` too.
    pub port_lost: bool,
    /// Index of the first sample of the excitation (after the settling part at the operating
    /// point): the START's settle samples.
    pub settle_samples: u64,
}

/// The voltage command of the samples after the settling part of a run, summarised as they arrive
/// ([`Acquisition::excitation_missing`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AfterSettle {
    /// Samples received after the settling part.
    pub samples: u64,
    /// The first one's command: raw (the drive's clamped command), and V.
    pub first: Option<(i16, f64)>,
    /// Whether every one's raw command equals the first's.
    pub constant: bool,
}

impl AfterSettle {
    /// One more sample after the settling part: its raw command and the command in V.
    pub fn push(&mut self, raw_u: i16, u: f64) {
        match self.first {
            None => {
                self.first = Some((raw_u, u));
                self.constant = true;
            }
            Some((r, _)) => self.constant &= r == raw_u,
        }
        self.samples += 1;
    }
}

impl Acquisition {
    /// The footer line written by [`CsvSink`].
    pub fn footer(&self) -> String {
        if self.complete {
            format!("# complete: {} samples", self.received)
        } else {
            let ranges: Vec<String> = self
                .missing
                .iter()
                .map(|r| format!("{}..{}", r.start, r.end))
                .collect();
            format!(
                "# incomplete: missing samples {} ({})",
                if ranges.is_empty() {
                    "none".to_string()
                } else {
                    ranges.join(", ")
                },
                self.problems.join("; ")
            )
        }
    }

    /// Whether the excitation is missing from the record: at least two samples arrived after the
    /// settling part and the voltage applied (`raw[0]`, the drive's clamped command) is the same
    /// in all of them. That is what a command beyond the drive's voltage clamp gives (an
    /// operating point of 30 V with a 24 V clamp puts every sample at 24 V), or a zero amplitude:
    /// a record that cannot identify anything, however complete.
    ///
    /// ```
    /// let mut a = drive::client::Acquisition::default();
    /// for _ in 0..3 {
    ///     a.after_settle.push(24000, 24.0);
    /// }
    /// assert!(a.excitation_missing());
    /// a.after_settle.push(22000, 22.0);
    /// assert!(!a.excitation_missing());
    /// ```
    pub fn excitation_missing(&self) -> bool {
        self.after_settle.samples >= 2 && self.after_settle.constant
    }

    /// The comment lines [`CsvSink`] writes before the footer: the drive's clamping of the
    /// voltage command, and a missing excitation ([`Acquisition::excitation_missing`]). Empty
    /// for a clean run.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.clamped_blocks > 0 {
            w.push(format!(
                "clamped: the drive limited the voltage command in {} data blocks (u is the applied, clamped voltage)",
                self.clamped_blocks
            ));
        }
        if let (true, Some((_, u))) = (self.excitation_missing(), self.after_settle.first) {
            w.push(format!(
                "no excitation: u is {} V in every sample after the settling part; not usable for identification",
                (u * 1e6).round() / 1e6
            ));
        }
        w
    }
}

/// A speed-loop experiment in physical units: the reference at 0 for `pre_s`, then `step`,
/// `duration_s` in all.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopTest {
    /// The reference step, rad/s.
    pub step: f64,
    /// Time at reference 0 before the step, s.
    pub pre_s: f64,
    /// The whole record, s (the step lasts `duration_s - pre_s`).
    pub duration_s: f64,
}

impl LoopTest {
    /// The START_LOOP for the configuration's rate and speed scale.
    ///
    /// # Errors
    /// [`Error::InvalidParam`]: a step beyond the speed channel or the speed trip, non-finite or
    /// negative times, a duration not longer than `pre_s`, more than 2^32 - 1 samples.
    pub fn to_command(&self, c: &Configure) -> Result<StartLoop> {
        let fs = c.sample_rate_hz as f64;
        let r1 = (self.step / c.y_lsb()).round();
        if !(r1.is_finite() && r1.abs() <= c.y_limit as f64) {
            return Err(Error::InvalidParam(format!(
                "step {} rad/s is beyond the speed trip of {} rad/s",
                self.step,
                c.y_limit as f64 * c.y_lsb()
            )));
        }
        if !(self.pre_s.is_finite() && self.pre_s >= 0.0 && self.duration_s.is_finite())
            || self.duration_s <= self.pre_s
        {
            return Err(Error::InvalidParam(format!(
                "need 0 <= pre ({} s) < duration ({} s)",
                self.pre_s, self.duration_s
            )));
        }
        let total = (self.duration_s * fs).round();
        if total > u32::MAX as f64 {
            return Err(Error::InvalidParam(format!(
                "{} s at {fs} Hz is more than 2^32 - 1 samples",
                self.duration_s
            )));
        }
        Ok(StartLoop {
            r0: 0,
            r1: r1 as i16,
            pre_samples: (self.pre_s * fs).round() as u32,
            total_samples: total as u32,
        })
    }
}

/// Writes a loop run as `t,r,u,y` CSV (r, the reference, from the START_LOOP), with the header
/// comments and the footer of [`CsvSink`].
#[derive(Debug)]
pub struct LoopCsvSink<W: Write> {
    w: io::BufWriter<W>,
    cmd: StartLoop,
    y_lsb: f64,
    rows: u64,
}

impl<W: Write> LoopCsvSink<W> {
    /// A sink for the run of `cmd` with the speed scale `y_lsb` (rad/s per LSB).
    pub fn new(w: W, cmd: StartLoop, y_lsb: f64) -> Self {
        Self {
            w: io::BufWriter::new(w),
            cmd,
            y_lsb,
            rows: 0,
        }
    }
    /// Unwrap the writer.
    pub fn into_inner(self) -> io::Result<W> {
        self.w.into_inner().map_err(|e| e.into_error())
    }
}

impl<W: Write> SampleSink for LoopCsvSink<W> {
    fn begin(&mut self, info: &RunInfo) -> io::Result<()> {
        writeln!(self.w, "# fracid drive loop: {}", info.description)?;
        writeln!(
            self.w,
            "# run_id {}, {} samples planned at {} Hz; units: t s, r rad/s, u V, y rad/s",
            info.run_id, info.total_samples, info.sample_rate_hz
        )?;
        writeln!(self.w, "t,r,u,y")?;
        self.w.flush()
    }
    fn sample(&mut self, index: u64, t: f64, u: f64, y: f64, _i: f64) -> io::Result<()> {
        let q = |v: f64| (v * 1e6).round() / 1e6;
        let r = self.cmd.reference(index) as f64 * self.y_lsb;
        writeln!(self.w, "{t:.6},{},{},{}", q(r), q(u), q(y))?;
        self.rows += 1;
        if self.rows.is_multiple_of(64) {
            self.w.flush()?;
        }
        Ok(())
    }
    fn finish(&mut self, acq: &Acquisition) -> io::Result<()> {
        if acq.clamped_blocks > 0 {
            writeln!(
                self.w,
                "# clamped: the drive limited the voltage command in {} data blocks (the \
                 controller's anti-windup held its states)",
                acq.clamped_blocks
            )?;
        }
        writeln!(self.w, "{}", acq.footer())?;
        self.w.flush()
    }
}

/// A PRBS experiment in physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrbsTest {
    /// LFSR length (2..=16 with default taps).
    pub order: u8,
    /// Seed (nonzero).
    pub seed: u32,
    /// Bit duration, s (a whole number of samples).
    pub clock_s: f64,
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// Offset (operating point), V.
    pub offset_v: f64,
    /// Periods.
    pub periods: u16,
    /// Settling time at the offset before the PRBS, s.
    pub settle_s: f64,
}

impl PrbsTest {
    /// The paper's experiment: order 7, 3 ms clock, one period, 1 V around a 6 V operating
    /// point reached during 0.3 s.
    pub fn paper() -> Self {
        Self {
            order: 7,
            seed: 1,
            clock_s: 0.003,
            amplitude_v: 1.0,
            offset_v: 6.0,
            periods: 1,
            settle_s: 0.3,
        }
    }

    /// The START_PRBS command for a configuration.
    pub fn to_command(&self, c: &Configure) -> Result<StartPrbs> {
        let fs = c.sample_rate_hz as f64;
        let clock = (self.clock_s * fs).round();
        if !(1.0..=65535.0).contains(&clock) || ((self.clock_s * fs) - clock).abs() > 1e-6 * clock {
            return Err(Error::InvalidParam(format!(
                "PRBS clock {} s is not a whole number of samples at {} Hz",
                self.clock_s, c.sample_rate_hz
            )));
        }
        let taps = crate::prbs::default_taps(self.order).ok_or_else(|| {
            Error::InvalidParam(format!("PRBS order {} is not in 2..=16", self.order))
        })?;
        let raw = |v: f64, what: &str| -> Result<i16> {
            let r = (v / c.u_lsb()).round();
            if !r.is_finite() || r.abs() > 32767.0 {
                return Err(Error::InvalidParam(format!(
                    "{what} {v} V is out of the command range (+-{} V)",
                    32767.0 * c.u_lsb()
                )));
            }
            Ok(r as i16)
        };
        let settle = (self.settle_s * fs).round();
        if !(0.0..=u32::MAX as f64).contains(&settle) {
            return Err(Error::InvalidParam("settle time out of range".into()));
        }
        let cmd = StartPrbs {
            order: self.order,
            taps,
            seed: self.seed,
            clock_samples: clock as u16,
            amplitude: raw(self.amplitude_v.abs(), "amplitude")?,
            offset: raw(self.offset_v, "offset")?,
            periods: self.periods.max(1),
            settle_samples: settle as u32,
        };
        crate::prbs::Lfsr::new(cmd.order, cmd.taps, cmd.seed).ok_or_else(|| {
            Error::InvalidParam(format!(
                "PRBS seed {} is not valid for order {} (1..={})",
                self.seed,
                self.order,
                (1u32 << self.order) - 1
            ))
        })?;
        cmd.total_samples()
            .ok_or_else(|| Error::InvalidParam("PRBS run too long".into()))?;
        Ok(cmd)
    }
}

/// A sine sweep in physical units.
#[derive(Debug, Clone, PartialEq)]
pub struct SineSweep {
    /// Frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// Offset (operating point), V.
    pub offset_v: f64,
    /// Cycles before measuring.
    pub settle_cycles: u16,
    /// Cycles measured.
    pub cycles: u16,
    /// Minimum settling time, s (more settle cycles at high frequencies).
    pub min_settle_s: f64,
    /// Stream the samples too (and compute the DFT on the host from them).
    pub stream: bool,
    /// Attempts per frequency when a point is lost.
    pub attempts: u32,
    /// Measurements per frequency, combined by the paper's trimmed mean
    /// ([`bode::combine_repeats`]); 1 measures once and keeps no spread.
    pub repeats: u32,
}

impl SineSweep {
    /// `n` log-spaced frequencies from `f0_hz` to `f1_hz`, 1 V around 6 V, 2 settle cycles (at
    /// least 0.2 s), 4 measured cycles, DFT on the drive.
    pub fn log(f0_hz: f64, f1_hz: f64, n: usize) -> Self {
        let freqs_hz = (0..n)
            .map(|k| {
                if n <= 1 {
                    f0_hz
                } else {
                    f0_hz * (f1_hz / f0_hz).powf(k as f64 / (n - 1) as f64)
                }
            })
            .collect();
        Self {
            freqs_hz,
            amplitude_v: 1.0,
            offset_v: 6.0,
            settle_cycles: 2,
            cycles: 4,
            min_settle_s: 0.2,
            stream: false,
            attempts: 3,
            repeats: 1,
        }
    }

    /// The frequency the drive will really apply for each requested one (Hz): moved to a
    /// whole-cycle window ([`bode::whole_cycle_mhz`]) and as generated
    /// ([`StartSine::applied_freq_hz`]); `None` where the request cannot be measured.
    pub fn applied_freqs_hz(&self, sample_rate_hz: u32) -> Vec<Option<f64>> {
        self.freqs_hz
            .iter()
            .map(|&f| {
                let freq_mhz = bode::whole_cycle_mhz(f, self.cycles.max(1), sample_rate_hz)?;
                Some(
                    StartSine {
                        freq_mhz,
                        amplitude: 0,
                        offset: 0,
                        settle_cycles: 0,
                        cycles: 1,
                        flags: 0,
                    }
                    .applied_freq_hz(sample_rate_hz),
                )
            })
            .collect()
    }
}

/// Progress of a run, for a progress bar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Samples (or sweep points) done.
    pub done: u64,
    /// Samples (or sweep points) planned.
    pub total: u64,
}

/// Asks the run in progress on a [`Client`] to end, from another thread or a progress callback
/// ([`Client::stop_handle`]). The client sends STOP (or ESTOP) at its next turn, keeps what
/// arrives and returns the acquisition marked incomplete with the reason.
#[derive(Debug, Clone, Default)]
pub struct StopHandle(Arc<AtomicU8>);

const STOP_NONE: u8 = 0;
const STOP_STOP: u8 = 1;
const STOP_ESTOP: u8 = 2;

impl StopHandle {
    /// Request a STOP (the output ramps to zero, the run ends with reason STOPPED).
    pub fn stop(&self) {
        self.0.fetch_max(STOP_STOP, Ordering::SeqCst);
    }
    /// Request an ESTOP (output off at once, fault latched until the next CONFIGURE).
    pub fn estop(&self) {
        self.0.store(STOP_ESTOP, Ordering::SeqCst);
    }
    /// Whether a request is pending (not yet sent to the drive).
    pub fn is_pending(&self) -> bool {
        self.0.load(Ordering::SeqCst) != STOP_NONE
    }
    /// Withdraw a request not yet sent (one that came too late for the run it was meant for,
    /// so that it does not end the next one). Returns whether one was pending.
    pub fn cancel(&self) -> bool {
        self.take() != STOP_NONE
    }
    fn take(&self) -> u8 {
        self.0.swap(STOP_NONE, Ordering::SeqCst)
    }
}

/// A connection to a drive (or the simulator).
pub struct Client {
    path: String,
    cfg: ClientConfig,
    port: Option<TTYPort>,
    dec: StreamDecoder,
    seq: u16,
    hello: Option<HelloReply>,
    conf: Option<Configure>,
    inbox: VecDeque<Frame>,
    /// When the drive's keepalive timer was last reset by this host: its last KEEPALIVE or
    /// START.
    last_keepalive: Instant,
    /// The same on the drive's clock (with [`ClientConfig::clock`]).
    last_keepalive_drive: Duration,
    /// The run being received, whose keepalive is kept (KEEPALIVE carries its id).
    run: Option<u16>,
    stats: ClientStats,
    progress: Option<Box<dyn FnMut(Progress) + Send>>,
    stop_req: StopHandle,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("path", &self.path)
            .field("hello", &self.hello)
            .field("stats", &self.stats)
            .finish()
    }
}

fn port_err(path: &str, e: serialport::Error) -> Error {
    Error::Port {
        path: path.to_string(),
        source: e,
    }
}

impl Client {
    /// Open the port, say HELLO and check the protocol version.
    pub fn open(path: &str, cfg: ClientConfig) -> Result<Self> {
        let mut c = Self {
            path: path.to_string(),
            cfg,
            port: None,
            dec: StreamDecoder::new(),
            seq: rand::random(),
            hello: None,
            conf: None,
            inbox: VecDeque::new(),
            last_keepalive: Instant::now(),
            last_keepalive_drive: Duration::ZERO,
            run: None,
            stats: ClientStats::default(),
            progress: None,
            stop_req: StopHandle::default(),
        };
        c.port = Some(c.open_port()?);
        c.hello()?;
        Ok(c)
    }

    /// Report progress to `f` during runs.
    pub fn set_progress(&mut self, f: impl FnMut(Progress) + Send + 'static) {
        self.progress = Some(Box::new(f));
    }

    /// A handle to stop the run in progress (see [`StopHandle`]). A request made while no run is
    /// active ends the next run as soon as it has started.
    pub fn stop_handle(&self) -> StopHandle {
        self.stop_req.clone()
    }

    /// The drive's HELLO_REPLY.
    pub fn drive_info(&self) -> Option<HelloReply> {
        self.hello
    }

    /// Counters.
    pub fn stats(&self) -> ClientStats {
        let mut s = self.stats;
        s.bad_frames = self.dec.stats().errors;
        s
    }

    /// What the acquisitions of the next runs keep of their samples ([`ClientConfig::samples`]).
    pub fn set_retention(&mut self, samples: Retention) {
        self.cfg.samples = samples;
    }

    /// The port path.
    pub fn path(&self) -> &str {
        &self.path
    }

    fn open_port(&self) -> Result<TTYPort> {
        let p = serialport::new(&self.path, self.cfg.baud)
            .timeout(Duration::from_millis(10))
            .exclusive(self.cfg.exclusive)
            .open_native()
            .map_err(|e| port_err(&self.path, e))?;
        let _ = p.clear(serialport::ClearBuffer::All);
        Ok(p)
    }

    fn close_port(&mut self) {
        if let Some(c) = &self.cfg.clock {
            // detached: the drive no longer waits for this host's keepalive
            c.host_sent(None);
        }
        if let Some(mut p) = self.port.take() {
            // Release TIOCEXCL explicitly: on a pty the flag can outlive our descriptor.
            if self.cfg.exclusive {
                let _ = p.set_exclusive(false);
            }
        }
    }

    /// Reopen the port path until it works or the reconnect timeout passes.
    pub fn reconnect(&mut self) -> Result<()> {
        self.close_port();
        self.dec.reset();
        self.stats.reconnects += 1;
        let deadline = Instant::now() + self.cfg.reconnect_timeout;
        loop {
            match self.open_port() {
                Ok(p) => {
                    self.port = Some(p);
                    return Ok(());
                }
                Err(e) => {
                    if Instant::now() >= deadline {
                        return Err(e);
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
            }
        }
    }

    fn timeout(&self) -> Duration {
        self.cfg.timeout.unwrap_or_else(|| {
            let frame_s =
                3.0 * (codec::MAX_ENCODED + 2) as f64 * 10.0 / self.cfg.baud.max(1) as f64;
            Duration::from_millis(100) + Duration::from_secs_f64(frame_s)
        })
    }

    fn stream_timeout(&self) -> Duration {
        self.cfg.stream_timeout.unwrap_or_else(|| {
            let block = self
                .conf
                .map(|c| c.block_samples as f64 / c.sample_rate_hz.max(1) as f64)
                .unwrap_or(0.0);
            Duration::from_millis(400).max(Duration::from_secs_f64(4.0 * block))
        })
    }

    fn send(&mut self, frame: &Frame) -> Result<()> {
        let bytes = codec::encode(frame);
        // Only a KEEPALIVE of the run (or the START that begins it) resets the drive's keepalive
        // timer (PROTOCOL.md, section 7): the interval is counted from those.
        let resets = matches!(
            frame.msg,
            Message::Keepalive(_)
                | Message::StartPrbs(_)
                | Message::StartSine(_)
                | Message::StartLoop(_)
        );
        if resets {
            self.last_keepalive = Instant::now();
        }
        if let Some(c) = &self.cfg.clock {
            let now = c.now();
            if resets {
                self.last_keepalive_drive = now;
            }
            // the host speaks again by then (its next KEEPALIVE is due no later)
            c.host_sent(Some(now + self.cfg.keepalive));
        }
        if self.port.is_none() {
            self.reconnect()?;
        }
        let r = match self.port.as_mut() {
            Some(p) => p.write_all(&bytes).and_then(|_| p.flush().or(Ok(()))),
            None => Ok(()),
        };
        if r.is_err() {
            // The port is gone: reopen it; the caller's retry logic resends.
            self.reconnect()?;
        }
        Ok(())
    }

    /// Time since the last KEEPALIVE (or START) sent: of the drive's clock with
    /// [`ClientConfig::clock`], else of the wall clock.
    fn since_last_keepalive(&self) -> Duration {
        match &self.cfg.clock {
            Some(c) => c.now().saturating_sub(self.last_keepalive_drive),
            None => self.last_keepalive.elapsed(),
        }
    }

    /// During a run, send a KEEPALIVE of the run if the interval has passed since the last one,
    /// or if the drive's clock waits for one ([`ClientConfig::clock`]). Other frames (a STATUS
    /// poll, a HELLO after a reconnection) do not keep the run alive.
    fn keepalive_if_due(&mut self) -> Result<()> {
        let Some(run_id) = self.run else {
            return Ok(());
        };
        let waits = self
            .cfg
            .clock
            .as_ref()
            .is_some_and(VirtualClock::drive_waits);
        if waits || self.since_last_keepalive() >= self.cfg.keepalive {
            let seq = self.next_seq();
            self.send(&Frame {
                seq,
                msg: Message::Keepalive(run_id),
            })?;
        }
        Ok(())
    }

    /// With [`ClientConfig::clock`]: wait up to `wait` for the port to be readable or the drive
    /// to wake this host (then send the KEEPALIVE it waits for). True if the port is readable.
    fn wait_port_or_drive(&mut self, fd: std::os::fd::RawFd, wait: Duration) -> Result<bool> {
        let Some(c) = self.cfg.clock.clone() else {
            return Ok(true);
        };
        let mut pfd = [
            libc::pollfd {
                fd,
                events: libc::POLLIN,
                revents: 0,
            },
            libc::pollfd {
                fd: c.wake_fd(),
                events: libc::POLLIN,
                revents: 0,
            },
        ];
        let ts = crate::vclock::timespec(wait);
        // SAFETY: two valid pollfds, a valid timespec, no signal mask.
        let r = unsafe { libc::ppoll(pfd.as_mut_ptr(), 2, &ts, std::ptr::null()) };
        if r > 0 && pfd[1].revents != 0 {
            c.drain_wake();
            self.keepalive_if_due()?;
        }
        Ok(r != 0 && pfd[0].revents != 0)
    }

    /// Read for up to `wait`; valid frames go to the inbox. Reopens the port if it failed.
    fn pump(&mut self, wait: Duration) -> Result<()> {
        if self.port.is_none() {
            self.reconnect()?;
        }
        if let Some(fd) = self.port.as_ref().map(|p| p.as_raw_fd()) {
            if !self.wait_port_or_drive(fd, wait)? {
                return Ok(());
            }
        }
        let Some(p) = self.port.as_mut() else {
            return Ok(());
        };
        let _ = p.set_timeout(wait.max(Duration::from_millis(1)));
        let mut buf = [0u8; 2048];
        match p.read(&mut buf) {
            Ok(0) => {
                // EOF on a tty: the other side hung up.
                self.reconnect()?;
            }
            Ok(n) => {
                let before = self.inbox.len();
                let inbox = &mut self.inbox;
                self.dec.push_with(&buf[..n], |f| inbox.push_back(f));
                self.stats.frames += (self.inbox.len() - before) as u64;
            }
            Err(e)
                if e.kind() == io::ErrorKind::TimedOut
                    || e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => {
                std::thread::sleep(Duration::from_millis(5));
                self.reconnect()?;
            }
        }
        Ok(())
    }

    fn next_seq(&mut self) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        self.seq
    }

    /// Send a command and wait for its answer (ACK, NAK, HELLO_REPLY, STATUS_REPLY or
    /// STREAM_END for END_QUERY), resending with the same seq on timeout. A NAK is an error.
    pub fn request(&mut self, msg: Message) -> Result<Message> {
        let seq = self.next_seq();
        let what = msg.name();
        let frame = Frame { seq, msg };
        let attempts = self.cfg.retries + 1;
        self.stats.commands += 1;
        for attempt in 0..attempts {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            self.send(&frame)?;
            let deadline = Instant::now() + self.timeout();
            while Instant::now() < deadline {
                // a command during a run (a STATUS poll, its retries) keeps the run alive only
                // through the KEEPALIVEs sent meanwhile
                self.keepalive_if_due()?;
                if let Some(ans) = self.take_answer(seq, &frame.msg) {
                    if let Message::Nak(n) = ans {
                        return Err(Error::Nak {
                            what,
                            code: n.code,
                            detail: n.detail,
                        });
                    }
                    return Ok(ans);
                }
                let left = deadline.saturating_duration_since(Instant::now());
                self.pump(left.min(Duration::from_millis(20)))?;
            }
        }
        Err(Error::Timeout { what, attempts })
    }

    /// Remove the answer to (seq, msg) from the inbox, if there.
    fn take_answer(&mut self, seq: u16, msg: &Message) -> Option<Message> {
        let pos = self.inbox.iter().position(|f| {
            f.seq == seq
                && match (&f.msg, msg) {
                    (Message::Ack(a), m) => a.acked_type == m.type_code(),
                    (Message::Nak(n), m) => n.nak_type == m.type_code(),
                    (Message::HelloReply(_), Message::Hello) => true,
                    (Message::StatusReply(_), Message::Status) => true,
                    (Message::StreamEnd(e), Message::EndQuery(id)) => e.run_id == *id,
                    _ => false,
                }
        })?;
        self.inbox.remove(pos).map(|f| f.msg)
    }

    /// HELLO: check the version, remember the boot id. A drive that does not answer is probed
    /// with a HELLO of each earlier protocol version ([`OLDER_VERSIONS`]): one that answers in
    /// its own version is [`Error::Version`], not a timeout.
    pub fn hello(&mut self) -> Result<HelloReply> {
        let _ = self.dec.take_foreign_version();
        let answer = match self.request(Message::Hello) {
            Err(e @ Error::Timeout { .. }) => {
                return Err(match self.probe_version() {
                    Some(v) => Error::Version {
                        drive: v,
                        host: PROTO_VERSION,
                    },
                    None => e,
                })
            }
            r => r?,
        };
        match answer {
            Message::HelloReply(h) => {
                if h.proto_version != PROTO_VERSION {
                    return Err(Error::Version {
                        drive: h.proto_version,
                        host: PROTO_VERSION,
                    });
                }
                if let Some(old) = self.hello {
                    if old.boot_id != h.boot_id {
                        self.conf = None;
                    }
                }
                self.hello = Some(h);
                Ok(h)
            }
            other => Err(Error::Protocol(format!(
                "HELLO answered by {}",
                other.name()
            ))),
        }
    }

    /// The version of a drive that speaks another protocol: one it already used on the line,
    /// else the first earlier version whose HELLO it answers (in that version).
    fn probe_version(&mut self) -> Option<u8> {
        if let Some(v) = self.dec.take_foreign_version() {
            return Some(v);
        }
        for v in OLDER_VERSIONS {
            let seq = self.next_seq();
            let body = codec::encode_body_as(
                &Frame {
                    seq,
                    msg: Message::Hello,
                },
                v,
            );
            let port = self.port.as_mut()?;
            port.write_all(&codec::wrap_body(&body)).ok()?;
            let deadline = Instant::now() + self.timeout();
            while Instant::now() < deadline {
                self.pump(Duration::from_millis(20)).ok()?;
                if let Some(v) = self.dec.take_foreign_version() {
                    return Some(v);
                }
            }
        }
        None
    }

    /// CONFIGURE.
    pub fn configure(&mut self, c: &Configure) -> Result<()> {
        if c.block_samples == 0 || c.block_samples > MAX_BLOCK_SAMPLES {
            return Err(Error::InvalidParam(format!(
                "block_samples {}",
                c.block_samples
            )));
        }
        self.request(Message::Configure(*c))?;
        self.conf = Some(*c);
        Ok(())
    }

    /// STATUS.
    pub fn status(&mut self) -> Result<StatusReply> {
        match self.request(Message::Status)? {
            Message::StatusReply(s) => Ok(s),
            other => Err(Error::Protocol(format!(
                "STATUS answered by {}",
                other.name()
            ))),
        }
    }

    /// STOP the current run.
    pub fn stop(&mut self) -> Result<()> {
        self.request(Message::Stop).map(|_| ())
    }

    /// Emergency stop (latched until the next CONFIGURE).
    pub fn estop(&mut self) -> Result<()> {
        self.request(Message::Estop).map(|_| ())
    }

    fn conf(&self) -> Result<Configure> {
        self.conf
            .ok_or_else(|| Error::InvalidParam("configure the drive first".into()))
    }

    /// Run a PRBS experiment, streaming samples into `sink` as they arrive.
    pub fn run_prbs(&mut self, test: &PrbsTest, sink: &mut dyn SampleSink) -> Result<Acquisition> {
        let conf = self.conf()?;
        let cmd = test.to_command(&conf)?;
        let desc = format!(
            "PRBS order {} taps {:#x} seed {} clock {} s ({} samples), amplitude {} V, offset {} V, {} periods, settle {} s",
            cmd.order, cmd.taps, cmd.seed, test.clock_s, cmd.clock_samples, test.amplitude_v, test.offset_v, cmd.periods, test.settle_s
        );
        self.run(Message::StartPrbs(cmd), desc, true, sink)
    }

    /// Download the speed controller (LOAD_CTRL, then each LOAD_SECTION; PROTOCOL.md section 3,
    /// "Speed loop"), after [`Client::configure`] (a CONFIGURE clears it on the drive).
    ///
    /// # Errors
    /// Not configured; a drive without the speed loop (firmware 1.0 answers NAK UNKNOWN_TYPE:
    /// [`Error::InvalidParam`] saying so; a drive that refuses the controller's format 2, firmware
    /// 1.1: the same, saying which firmware runs it); any NAK or timeout of the download.
    pub fn load_controller(&mut self, k: &crate::ctrl::FixedCtrl) -> Result<()> {
        self.conf()?;
        let (head, sections) = k.messages();
        let v = self
            .hello
            .map(|h| format!(" (firmware {}.{})", h.fw_major, h.fw_minor))
            .unwrap_or_default();
        match self.request(Message::LoadCtrl(head)) {
            Err(Error::Nak {
                code: NakCode::UnknownType,
                ..
            }) => {
                return Err(Error::InvalidParam(format!(
                    "the drive{v} has no speed loop: LOAD_CTRL is unknown to it (firmware 1.1 \
                     or later runs a downloaded controller)"
                )));
            }
            Err(Error::Nak {
                code: NakCode::BadValue,
                detail: 0,
                ..
            }) if head.format != crate::protocol::CTRL_FORMAT => {
                return Err(Error::InvalidParam(format!(
                    "the drive{v} refuses controller format {}: this controller ({} sections, {} \
                     delay taps) needs firmware 1.2 or later",
                    head.format, head.n_sections, head.n_taps
                )));
            }
            r => r?,
        };
        for sec in sections {
            self.request(Message::LoadSection(sec))?;
        }
        Ok(())
    }

    /// Run a speed loop with the downloaded controller ([`Client::load_controller`]): the
    /// reference `cmd.r0` for `cmd.pre_samples`, then `cmd.r1`, streaming `u, y, i` into `sink`.
    ///
    /// # Errors
    /// As the other runs; NAK NO_CONTROLLER without a complete controller.
    pub fn run_loop(&mut self, cmd: &StartLoop, sink: &mut dyn SampleSink) -> Result<Acquisition> {
        let conf = self.conf()?;
        let desc = format!(
            "speed loop: reference {} rad/s for {} samples, then {} rad/s; {} samples",
            cmd.r0 as f64 * conf.y_lsb(),
            cmd.pre_samples,
            cmd.r1 as f64 * conf.y_lsb(),
            cmd.total_samples
        );
        self.run(Message::StartLoop(*cmd), desc, true, sink)
    }

    /// Run one START_SINE and stream into `sink`.
    pub fn run_sine(&mut self, cmd: &StartSine, sink: &mut dyn SampleSink) -> Result<Acquisition> {
        let desc = format!(
            "sine {} Hz, amplitude {} raw, offset {} raw, {}+{} cycles",
            cmd.freq_mhz as f64 / 1000.0,
            cmd.amplitude,
            cmd.offset,
            cmd.settle_cycles,
            cmd.cycles
        );
        self.run(
            Message::StartSine(*cmd),
            desc,
            cmd.flags & SINE_STREAM != 0,
            sink,
        )
    }

    /// Run a started experiment to its end. `streamed`: DATA blocks are to arrive (a sine run
    /// without streaming sends only SINE_RESULT and STREAM_END).
    fn run(
        &mut self,
        start: Message,
        description: String,
        streamed: bool,
        sink: &mut dyn SampleSink,
    ) -> Result<Acquisition> {
        let want_dft = matches!(start, Message::StartSine(s) if s.flags & SINE_DFT != 0);
        // a sine run's samples are kept whatever the retention: the host's DFT reads them
        let keep = self.cfg.samples == Retention::Keep || matches!(start, Message::StartSine(_));
        let conf = self.conf()?;
        let boot = self.hello.map(|h| h.boot_id);
        let settle_samples = match &start {
            Message::StartPrbs(p) => p.settle_samples as u64,
            Message::StartLoop(l) => l.pre_samples as u64,
            Message::StartSine(s) => s
                .sample_counts(conf.sample_rate_hz)
                .map_or(0, |(settle, _)| settle as u64),
            _ => 0,
        };
        let ack = match self.request(start)? {
            Message::Ack(a) => a,
            other => {
                return Err(Error::Protocol(format!(
                    "START answered by {}",
                    other.name()
                )))
            }
        };
        let fs = conf.sample_rate_hz;
        let mut acq = Acquisition {
            run_id: ack.run_id,
            sample_rate_hz: fs,
            total_samples: ack.total_samples as u64,
            planned_samples: ack.total_samples as u64,
            settle_samples,
            ..Default::default()
        };
        if let Err(e) = sink.begin(&RunInfo {
            run_id: ack.run_id,
            total_samples: ack.total_samples as u64,
            sample_rate_hz: fs,
            description,
        }) {
            // The record cannot be written: do not leave the drive running for nothing.
            self.stop_after_sink_error();
            return Err(Error::Io(e));
        }
        self.run = Some(ack.run_id);
        let streamed_run = self.stream(&mut acq, sink, &conf, boot, keep);
        self.run = None;
        match streamed_run {
            Ok(()) => {}
            Err(RunFail::Sink(e)) => {
                self.stop_after_sink_error();
                return Err(Error::Io(e));
            }
            Err(RunFail::Drive(e)) => {
                // The line or the drive failed (the port vanished and did not come back within
                // the reconnect window, a protocol violation): the run is over for this host.
                // What arrived is kept and the record is finished with what is missing.
                acq.port_lost = matches!(e, Error::Port { .. } | Error::Io(_));
                acq.problems.push(if acq.port_lost {
                    format!("lost the port during the run: {e}")
                } else {
                    format!("run abandoned: {e}")
                });
            }
        }
        finish(&mut acq, streamed, want_dft);
        sink.finish(&acq)?;
        Ok(acq)
    }

    /// Best-effort STOP after the record could not be written (one attempt, errors ignored).
    fn stop_after_sink_error(&mut self) {
        let retries = std::mem::replace(&mut self.cfg.retries, 0);
        let _ = self.request(Message::Stop);
        self.cfg.retries = retries;
    }

    /// Receive a started run until STREAM_END (or a reason to give up, recorded in
    /// `acq.problems`). Errors of the sink and of the line are told apart: the first end the
    /// acquisition, the second only the run.
    fn stream(
        &mut self,
        acq: &mut Acquisition,
        sink: &mut dyn SampleSink,
        conf: &Configure,
        boot: Option<u16>,
        keep: bool,
    ) -> Result<(), RunFail> {
        let fs = conf.sample_rate_hz;
        let lsb = [conf.u_lsb(), conf.y_lsb(), conf.i_lsb()];
        let mut st = StreamState {
            next: 0,
            last_data: Instant::now(),
            stalled_polls: 0,
            last_done: 0,
        };
        let stream_timeout = self.stream_timeout();
        let expected = Duration::from_secs_f64(acq.planned_samples as f64 / fs.max(1) as f64);
        let hard_deadline = Instant::now() + expected * 3 + Duration::from_secs(10);
        let mut last_progress = 0u64;
        // STREAM_END fetched by END_QUERY: one more pass over the inbox, then done.
        let mut end_fetched = false;
        // the port was reopened (here, or in a KEEPALIVE's or a request's send) and the drive
        // behind it has not yet said who it is
        let mut unverified = false;
        let mut reconnects = self.stats.reconnects;
        loop {
            self.send_stop_request(acq);
            self.keepalive_if_due().map_err(RunFail::Drive)?;
            // Wait for the line no longer than until the next KEEPALIVE is due (a short keepalive
            // interval is kept even while nothing arrives, as in a sine run without streaming;
            // on the drive's clock the drive wakes this host when it waits for one).
            let keepalive_due = self
                .cfg
                .keepalive
                .saturating_sub(self.since_last_keepalive());
            self.pump(keepalive_due.min(Duration::from_millis(20)))
                .map_err(RunFail::Drive)?;
            unverified |= self.stats.reconnects != reconnects;
            reconnects = self.stats.reconnects;
            if unverified {
                unverified = !self
                    .same_drive_after_reconnect(boot)
                    .map_err(RunFail::Drive)?;
            }
            let ended = self.read_inbox(acq, sink, &mut st, fs, lsb, keep)?;
            if let Some(p) = self.progress.as_mut() {
                if st.next >= last_progress + 256 || ended {
                    last_progress = st.next;
                    p(Progress {
                        done: st.next.min(acq.total_samples),
                        total: acq.total_samples,
                    });
                }
            }
            if ended || end_fetched {
                break;
            }
            if Instant::now() > hard_deadline {
                acq.problems.push("run took too long; gave up".into());
                break;
            }
            if st.last_data.elapsed() < stream_timeout {
                continue;
            }
            match self.recover(acq, &mut st, boot)? {
                Recovery::Wait => {}
                Recovery::EndFetched => end_fetched = true,
                Recovery::GiveUp => break,
            }
        }
        Ok(())
    }

    /// After the port was reopened during a run, no frame is taken before the drive behind it
    /// says it is the one that started the run (its boot id, by STATUS): a path may lead to another
    /// device once the first is gone (a pty number or a `/dev/ttyUSB*` name freed and taken again),
    /// and its samples must never enter this record. Another boot id ends the run as a lost port
    /// (the frames that came with it are dropped); a drive that reset is told by the same figure.
    /// False while the drive stays silent (its frames are dropped until it answers; the stream's
    /// recovery judges the silence).
    fn same_drive_after_reconnect(&mut self, boot: Option<u16>) -> Result<bool> {
        let Some(boot) = boot else {
            return Ok(true);
        };
        let status = match self.status() {
            Ok(s) => s,
            Err(Error::Timeout { .. }) => {
                self.inbox.clear();
                return Ok(false);
            }
            Err(e) => return Err(e),
        };
        if status.boot_id == boot {
            return Ok(true);
        }
        self.inbox.clear();
        Err(Error::Io(io::Error::other(format!(
            "after reconnecting, {} answers with boot id {:#06x} instead of {boot:#06x} (the drive \
             reset, or the path leads to another device)",
            self.path, status.boot_id
        ))))
    }

    /// A STOP or ESTOP asked from another thread ([`Client::stop_handle`]), sent now.
    fn send_stop_request(&mut self, acq: &mut Acquisition) {
        let req = self.stop_req.take();
        if req == STOP_NONE {
            return;
        }
        let (msg, name) = if req == STOP_ESTOP {
            (Message::Estop, "ESTOP")
        } else {
            (Message::Stop, "STOP")
        };
        if let Err(e) = self.request(msg) {
            // The stream recovery finds out what the drive did.
            acq.problems.push(format!("{name} not acknowledged: {e}"));
        }
    }

    /// Take the run's frames from the inbox: DATA into the record and the sink, the SINE_RESULT,
    /// the STREAM_END (returns whether it came).
    fn read_inbox(
        &mut self,
        acq: &mut Acquisition,
        sink: &mut dyn SampleSink,
        st: &mut StreamState,
        fs: u32,
        lsb: [f64; 3],
        keep: bool,
    ) -> Result<bool, RunFail> {
        let mut ended = false;
        while let Some(f) = self.inbox.pop_front() {
            match f.msg {
                Message::Data(d) if d.run_id == acq.run_id => {
                    st.last_data = Instant::now();
                    if d.flags & 1 != 0 {
                        acq.clamped_blocks += 1;
                    }
                    accept_block(acq, sink, &d, &mut st.next, fs, lsb, keep)?;
                }
                Message::StreamEnd(e) if e.run_id == acq.run_id => {
                    acq.end = Some(e);
                    ended = true;
                }
                Message::SineResult(s) if s.run_id == acq.run_id => acq.sine = Some(s),
                _ => {} // stale answers, other runs
            }
        }
        Ok(ended)
    }

    /// Silence on the line: ask the drive what is going on.
    fn recover(
        &mut self,
        acq: &mut Acquisition,
        st: &mut StreamState,
        boot: Option<u16>,
    ) -> Result<Recovery, RunFail> {
        self.stats.recoveries += 1;
        let status = match self.status() {
            Ok(s) => s,
            Err(Error::Timeout { .. }) => {
                acq.problems.push("drive stopped answering".into());
                return Ok(Recovery::GiveUp);
            }
            Err(e) => return Err(RunFail::Drive(e)),
        };
        if boot.is_some_and(|b| b != status.boot_id) {
            acq.problems.push(format!(
                "drive reset during the run (boot id {:#06x} -> {:#06x})",
                boot.unwrap_or(0),
                status.boot_id
            ));
            self.conf = None;
            if let Some(h) = self.hello.as_mut() {
                h.boot_id = status.boot_id;
            }
            return Ok(Recovery::GiveUp);
        }
        if status.run_id != acq.run_id {
            acq.problems.push(format!(
                "drive is on run {} instead of {}",
                status.run_id, acq.run_id
            ));
            return Ok(Recovery::GiveUp);
        }
        if status.state == DriveState::Running {
            if status.samples_done == st.last_done {
                st.stalled_polls += 1;
                if st.stalled_polls > 5 {
                    acq.problems
                        .push("drive reports a run that makes no progress".into());
                    return Ok(Recovery::GiveUp);
                }
            }
            st.last_done = status.samples_done;
            st.last_data = Instant::now();
            return Ok(Recovery::Wait);
        }
        // The run is over and we missed STREAM_END: fetch it.
        match self.request(Message::EndQuery(acq.run_id)) {
            Ok(Message::StreamEnd(e)) => {
                acq.end = Some(e);
                // What came while STATUS was awaited (the run's last DATA, its SINE_RESULT,
                // which precedes STREAM_END) waits in the inbox: one more pass reads it.
                // (Breaking here lost the SINE_RESULT of a sine run as long as the stream
                // timeout: the STATUS poll was in flight when the run ended.)
                Ok(Recovery::EndFetched)
            }
            Ok(_) | Err(_) => {
                acq.problems.push("end-of-run summary unavailable".into());
                Ok(Recovery::GiveUp)
            }
        }
    }

    /// Run a sine sweep and return the frequency response. Points whose measurement was
    /// damaged are measured again (up to `attempts` times); points that never succeed are left out
    /// and reported in the error list returned alongside. With `repeats > 1` each frequency is
    /// measured that many times in a row and the point is their trimmed mean with the spread
    /// ([`bode::combine_repeats`]).
    pub fn run_sine_sweep(&mut self, sweep: &SineSweep) -> Result<(Vec<BodePoint>, Vec<String>)> {
        self.run_sine_sweep_with(sweep, &mut |_| Ok(()))
    }

    /// [`Client::run_sine_sweep`], handing over what it measures as soon as it is measured, so
    /// that a caller can write it at once (a sweep that ends early keeps every point measured):
    /// each single measurement as [`SweepEvent::Repeat`] (repeat from 1), then the point of the
    /// frequency as [`SweepEvent::Point`] (the combined repeats when `repeats > 1`, its phase
    /// already unwrapped against the points before it).
    ///
    /// The sweep stops early, keeping what it has, when the host asks (a [`StopHandle`]), when the
    /// port vanishes for longer than the reconnect window, or when the drive no longer answers at
    /// all (a START and a STATUS both unanswered): the remaining frequencies are not tried. The
    /// repeats measured at the frequency where it stopped still make its point.
    ///
    /// # Errors
    /// The drive refuses a START (NAK) or a parameter is invalid; `on_event` fails (the error,
    /// as [`Error::Io`]).
    pub fn run_sine_sweep_with(
        &mut self,
        sweep: &SineSweep,
        on_event: &mut dyn FnMut(SweepEvent<'_>) -> io::Result<()>,
    ) -> Result<(Vec<BodePoint>, Vec<String>)> {
        let mut prog = self.progress.take();
        let r = self.sweep_points(sweep, on_event, &mut prog);
        self.progress = prog;
        r
    }

    fn sweep_points(
        &mut self,
        sweep: &SineSweep,
        on_event: &mut dyn FnMut(SweepEvent<'_>) -> io::Result<()>,
        prog: &mut Option<Box<dyn FnMut(Progress) + Send>>,
    ) -> Result<(Vec<BodePoint>, Vec<String>)> {
        let conf = self.conf()?;
        let fs = conf.sample_rate_hz as f64;
        let mut points = Vec::new();
        let mut problems = Vec::new();
        let total = sweep.freqs_hz.len() as u64;
        for (k, &f) in sweep.freqs_hz.iter().enumerate() {
            if !(f > 0.0 && f < fs / 2.0) {
                problems.push(format!("{f} Hz skipped: outside (0, {}) Hz", fs / 2.0));
                continue;
            }
            let cycles = sweep.cycles.max(1);
            let Some(freq_mhz) = bode::whole_cycle_mhz(f, cycles, conf.sample_rate_hz) else {
                problems.push(format!("{f} Hz skipped: no whole-cycle window"));
                continue;
            };
            let settle_cycles = sweep
                .settle_cycles
                .max((sweep.min_settle_s * f).ceil().min(65535.0) as u16);
            let cmd = StartSine {
                freq_mhz,
                amplitude: (sweep.amplitude_v.abs() / conf.u_lsb())
                    .round()
                    .min(32767.0) as i16,
                offset: (sweep.offset_v / conf.u_lsb())
                    .round()
                    .clamp(-32767.0, 32767.0) as i16,
                settle_cycles,
                cycles,
                flags: SINE_DFT | if sweep.stream { SINE_STREAM } else { 0 },
            };
            let mut reps = Vec::new();
            let mut stopped = false;
            for rep in 1..=sweep.repeats.max(1) {
                match self.measure_once(&cmd, &conf, sweep.attempts, &mut problems)? {
                    Measured::Point(p) => {
                        on_event(SweepEvent::Repeat(&p, rep))?;
                        reps.push(p);
                    }
                    Measured::Failed => problems.push(format!("{f} Hz: no valid measurement")),
                    Measured::Stop => {
                        stopped = true;
                        break;
                    }
                }
            }
            let point = if sweep.repeats > 1 {
                bode::combine_repeats(&reps)
            } else {
                reps.pop()
            };
            if let Some(mut p) = point {
                if let Some(prev) = points.last() {
                    unwrap_against(&mut p, prev);
                }
                on_event(SweepEvent::Point(&p))?;
                points.push(p);
            }
            if let Some(p) = prog.as_mut() {
                p(Progress {
                    done: k as u64 + 1,
                    total,
                });
            }
            if stopped {
                return Ok((points, problems));
            }
        }
        Ok((points, problems))
    }

    /// One sine measurement, repeated on damage up to `attempts` times. A NAK or an invalid
    /// parameter is an error that ends the sweep; a lost port, a drive that answers neither START
    /// nor STATUS, or a stop on the host's request is [`Measured::Stop`] (reason in `problems`).
    fn measure_once(
        &mut self,
        cmd: &StartSine,
        conf: &Configure,
        attempts: u32,
        problems: &mut Vec<String>,
    ) -> Result<Measured> {
        let f = cmd.applied_freq_hz(conf.sample_rate_hz);
        for _ in 0..attempts.max(1) {
            let acq = match self.run_sine(cmd, &mut NullSink) {
                Ok(a) => a,
                Err(e @ Error::Nak { .. }) | Err(e @ Error::InvalidParam(_)) => {
                    return Err(e);
                }
                Err(e @ Error::Port { .. }) | Err(e @ Error::Io(_)) => {
                    problems.push(format!("{f} Hz: {e}; port lost, sweep stopped"));
                    return Ok(Measured::Stop);
                }
                Err(e @ Error::Timeout { .. }) => {
                    problems.push(format!("{f} Hz: {e}"));
                    if self.status().is_err() {
                        problems.push(format!(
                            "{f} Hz: the drive does not answer STATUS either; sweep stopped"
                        ));
                        return Ok(Measured::Stop);
                    }
                    continue;
                }
                Err(e) => {
                    problems.push(format!("{f} Hz: {e}"));
                    continue;
                }
            };
            if let Some(p) = sine_point(&acq, cmd, conf) {
                return Ok(Measured::Point(p));
            }
            if acq.port_lost {
                problems.push(format!(
                    "{f} Hz: {}; sweep stopped",
                    acq.problems.join("; ")
                ));
                return Ok(Measured::Stop);
            }
            if let Some(r) = acq
                .end
                .map(|e| e.reason)
                .filter(|r| matches!(r, EndReason::Stopped | EndReason::Estop))
            {
                // Stopped on the host's request: the sweep ends here.
                problems.push(format!("{f} Hz: {r:?}; sweep stopped"));
                return Ok(Measured::Stop);
            }
            problems.push(format!(
                "{f} Hz: measurement damaged ({}), repeating",
                acq.problems.join("; ")
            ));
        }
        Ok(Measured::Failed)
    }
}

/// What [`Client::run_sine_sweep_with`] hands over as it measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SweepEvent<'a> {
    /// One single measurement of a frequency and its repeat number (from 1), its phase as
    /// measured (within +-180 deg).
    Repeat(&'a BodePoint, u32),
    /// The point of a frequency, after its repeats: their trimmed mean with the spread when the
    /// sweep repeats, else the single measurement; its phase unwrapped against the points before.
    Point(&'a BodePoint),
}

/// The outcome of [`Client::measure_once`].
enum Measured {
    Point(BodePoint),
    /// No valid measurement in `attempts` tries.
    Failed,
    /// The sweep ends here (port lost, drive silent, or stopped on request).
    Stop,
}

/// Unwrap the phase of `p` so that it differs from the previous point's by at most 180 degrees
/// (as [`bode::unwrap_deg`] does along a whole sweep).
fn unwrap_against(p: &mut BodePoint, prev: &BodePoint) {
    let mut pair = [*prev, *p];
    bode::unwrap_deg(&mut pair);
    p.phase_deg = pair[1].phase_deg;
}

/// Why [`Client::stream`] gave up: the record could not be written, or the line or drive failed.
enum RunFail {
    Sink(io::Error),
    Drive(Error),
}

/// Where [`Client::stream`] is in the run.
struct StreamState {
    /// The next sample index expected.
    next: u64,
    /// When the run's last DATA arrived (or the drive last said it was running).
    last_data: Instant,
    /// STATUS polls in a row that found the run making no progress.
    stalled_polls: u32,
    /// Samples done at the last STATUS poll.
    last_done: u32,
}

/// What [`Client::recover`] found out.
enum Recovery {
    /// The run goes on: wait for its DATA.
    Wait,
    /// The run's STREAM_END was fetched: one more pass over the inbox, then done.
    EndFetched,
    /// The run is lost to this host (the reason is in the record's problems).
    GiveUp,
}

/// One DATA block's samples into the record and the sink: duplicates and absurd indices dropped,
/// gaps before them recorded as missing.
fn accept_block(
    acq: &mut Acquisition,
    sink: &mut dyn SampleSink,
    d: &DataBlock,
    next: &mut u64,
    fs: u32,
    lsb: [f64; 3],
    keep: bool,
) -> Result<(), RunFail> {
    let first = d.first_index as u64;
    for (k, s) in d.samples.iter().enumerate() {
        let idx = first + k as u64;
        if idx < *next || idx >= acq.total_samples.max(*next + 1) + 1_000_000 {
            continue; // duplicate or absurd
        }
        if idx > *next {
            acq.missing.push(*next..idx); // clipped in `finish`
        }
        *next = idx + 1;
        let t = idx as f64 / fs as f64;
        let (u, y, i) = (
            s[0] as f64 * lsb[0],
            s[1] as f64 * lsb[1],
            s[2] as f64 * lsb[2],
        );
        acq.received += 1;
        acq.last_index = Some(idx);
        if idx >= acq.settle_samples {
            acq.after_settle.push(s[0], u);
        }
        if keep {
            acq.index.push(idx);
            acq.t.push(t);
            acq.u.push(u);
            acq.y.push(y);
            acq.i.push(i);
            acq.raw.push(*s);
        }
        sink.sample(idx, t, u, y, i).map_err(RunFail::Sink)?;
    }
    Ok(())
}

/// Judge a run at its end: the summary, the missing ranges, completeness.
fn finish(acq: &mut Acquisition, streamed: bool, want_dft: bool) {
    if let Some(e) = acq.end {
        acq.total_samples = e.total_samples as u64;
        if e.reason != EndReason::Complete {
            acq.problems.push(format!(
                "run ended early: {:?} after {} of {} samples",
                e.reason, e.total_samples, acq.planned_samples
            ));
        }
        if e.blocks_dropped > 0 {
            acq.problems
                .push(format!("drive dropped {} blocks", e.blocks_dropped));
        }
    } else if acq.problems.is_empty() {
        acq.problems.push("no end-of-run summary".into());
    }
    if want_dft && acq.sine.is_none() && acq.end.is_some_and(|e| e.reason == EndReason::Complete) {
        acq.problems.push("no SINE_RESULT".into());
    }
    if !streamed {
        // Nothing was to arrive but the summary (and the DFT).
        if acq.received > 0 {
            acq.problems
                .push("DATA from a run that does not stream".into());
        }
        acq.missing.clear();
        acq.complete = acq.problems.is_empty();
        return;
    }
    // Missing ranges: complement of the received indices in 0..span, where span covers both what
    // the drive produced and what was planned (a run that ended early misses its planned rest).
    // The gaps between received samples were recorded as they arrived (`stream`).
    let span = acq.total_samples.max(acq.planned_samples);
    let mut missing: Vec<Range<u64>> = std::mem::take(&mut acq.missing)
        .into_iter()
        .map(|r| r.start..r.end.min(span))
        .collect();
    let expect = acq.last_index.map_or(0, |l| l + 1);
    if expect < span {
        missing.push(expect..span);
    }
    missing.retain(|r| r.start < r.end);
    if acq.last_index.is_some_and(|l| l >= acq.total_samples) {
        acq.problems.push("samples beyond the announced end".into());
    }
    // Lost on the way (within what the drive produced), as opposed to never produced.
    let lost: u64 = missing
        .iter()
        .map(|r| r.end.min(acq.total_samples).saturating_sub(r.start))
        .sum();
    if let Some(e) = acq.end {
        let got = acq.received;
        if lost == 0 && got != e.samples_sent as u64 {
            acq.problems.push(format!(
                "drive sent {} samples, host got {}",
                e.samples_sent, got
            ));
        }
    }
    if lost > 0 {
        acq.problems.push(format!("{lost} samples lost"));
    }
    acq.missing = missing;
    acq.complete = acq.problems.is_empty();
}

/// The drive's single-bin DFT of a sine run (SINE_RESULT) as `[u, y]` phasors `(re, im)` in raw
/// LSB (the Q8 values / 256).
pub fn drive_dft(acq: &Acquisition) -> Option<[(f64, f64); 2]> {
    let s = acq.sine?;
    let q = |v: i32| v as f64 / 256.0;
    Some([(q(s.u_re), q(s.u_im)), (q(s.y_re), q(s.y_im))])
}

/// The same single-bin DFT computed on the host from the streamed samples of a sine run
/// (section 3, SINE_RESULT): `[u, y]` phasors `(re, im)` in raw LSB over the measurement window,
/// with the drive's phase accumulator. None unless every sample of the window arrived.
pub fn host_dft(
    acq: &Acquisition,
    cmd: &StartSine,
    sample_rate_hz: u32,
) -> Option<[(f64, f64); 2]> {
    let w = SineWindow::of(acq, cmd, sample_rate_hz)?;
    let ph = |k| w.phase(k);
    Some([bode::single_bin(&w.u, ph), bode::single_bin(&w.y, ph)])
}

/// The streamed samples of a sine run's measurement window and the drive's phase accumulator over
/// it ([`host_dft`], [`host_phasors`]).
struct SineWindow {
    settle: u32,
    measure: u32,
    inc: u32,
    u: Vec<f64>,
    y: Vec<f64>,
}

impl SineWindow {
    /// The window `settle..settle+measure`, or None unless every sample of it arrived.
    fn of(acq: &Acquisition, cmd: &StartSine, sample_rate_hz: u32) -> Option<Self> {
        let (settle, measure) = cmd.sample_counts(sample_rate_hz)?;
        if measure == 0 {
            return None;
        }
        // Indices increase, so the window is contiguous iff its first and last indices are
        // `measure - 1` apart.
        let first = acq.index.binary_search(&(settle as u64)).ok()?;
        let last = first + measure as usize - 1;
        if acq.index.get(last) != Some(&(settle as u64 + measure as u64 - 1)) {
            return None;
        }
        let w = &acq.raw[first..=last];
        Some(SineWindow {
            settle,
            measure,
            inc: cmd.phase_increment(sample_rate_hz),
            u: w.iter().map(|s| s[0] as f64).collect(),
            y: w.iter().map(|s| s[1] as f64).collect(),
        })
    }

    /// The drive's phase (rad) at sample `k` of the window.
    fn phase(&self, k: usize) -> f64 {
        let p = ((self.settle as u64 + k as u64).wrapping_mul(self.inc as u64)) as u32;
        p as f64 / 4294967296.0 * std::f64::consts::TAU
    }
}

/// A Bode point from `[u, y]` phasors in raw LSB.
pub fn bode_point(
    freq_hz: f64,
    dft: [(f64, f64); 2],
    n_samples: u32,
    on_drive: bool,
    conf: &Configure,
) -> Option<BodePoint> {
    let (gain, phase) = bode::ratio(dft[0], dft[1])?;
    Some(BodePoint {
        freq_hz,
        gain_db: 20.0 * (gain * conf.y_lsb() / conf.u_lsb()).log10(),
        phase_deg: phase.to_degrees(),
        n_samples,
        on_drive,
        spread: None,
    })
}

/// The drive's measurement of a sine run with the operating point removed: `[u, y]` phasors
/// `(re, im)` in raw LSB from SINE_RESULT's DFT, level and ramp moments, by the joint
/// least-squares fit of level, drift and sine ([`bode::fit_phasor`]) over the window.
pub fn drive_phasors(
    acq: &Acquisition,
    cmd: &StartSine,
    sample_rate_hz: u32,
) -> Option<[(f64, f64); 2]> {
    let s = acq.sine?;
    let (settle, measure) = cmd.sample_counts(sample_rate_hz)?;
    if measure != s.n || measure == 0 {
        return None;
    }
    let q = |v: i32| v as f64 / 256.0;
    let g = bode::WindowGram::new(measure, settle, cmd.phase_increment(sample_rate_hz));
    let u = bode::ChannelMoments {
        dft: (q(s.u_re), q(s.u_im)),
        mean: q(s.u_mean),
        ramp: q(s.u_ramp),
    };
    let y = bode::ChannelMoments {
        dft: (q(s.y_re), q(s.y_im)),
        mean: q(s.y_mean),
        ramp: q(s.y_ramp),
    };
    Some([bode::fit_phasor(&u, &g)?, bode::fit_phasor(&y, &g)?])
}

/// The same measurement from the streamed samples of the window, on the host (f64 moments, the
/// same fit). None unless every sample of the window arrived.
pub fn host_phasors(
    acq: &Acquisition,
    cmd: &StartSine,
    sample_rate_hz: u32,
) -> Option<[(f64, f64); 2]> {
    let w = SineWindow::of(acq, cmd, sample_rate_hz)?;
    let ph = |k| w.phase(k);
    let g = bode::WindowGram::new(w.measure, w.settle, w.inc);
    Some([
        bode::fit_phasor(&bode::ChannelMoments::of(&w.u, ph), &g)?,
        bode::fit_phasor(&bode::ChannelMoments::of(&w.y, ph), &g)?,
    ])
}

/// A Bode point from a sine run that ended normally: the drive's measurement if its SINE_RESULT
/// arrived, else the host's over the streamed window; both with the operating point's level and
/// drift removed ([`drive_phasors`], [`host_phasors`]). The point's frequency is the one the drive
/// really generated ([`StartSine::applied_freq_hz`]).
pub fn sine_point(acq: &Acquisition, cmd: &StartSine, conf: &Configure) -> Option<BodePoint> {
    let end = acq.end?;
    if end.reason != EndReason::Complete {
        return None;
    }
    let fs = conf.sample_rate_hz;
    let freq_hz = cmd.applied_freq_hz(fs);
    let (_, measure) = cmd.sample_counts(fs)?;
    if let Some(d) = drive_phasors(acq, cmd, fs) {
        return bode_point(freq_hz, d, measure, true, conf);
    }
    bode_point(freq_hz, host_phasors(acq, cmd, fs)?, measure, false, conf)
}

impl Drop for Client {
    fn drop(&mut self) {
        self.close_port();
    }
}
