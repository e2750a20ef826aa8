//! `fracid drive ...`: the drive simulator and acquisition from a drive over a serial port. The
//! acquisitions are the library's requests ([`autotune::acquire`]); this module parses the
//! flags into them and writes their records.

pub use crate::cmd::drive_io::PortArgs;
use crate::cmd::drive_io::{
    autotune_err, check_outputs, close_record, kept_summary, lib_err, lost_output, output_file,
    output_path, port_conf, record_outcome, run_on_drive,
};
use crate::interrupt::Interrupted;
use anyhow::{Context, Result};
use autotune::acquire::prbs::PrbsRequest;
use autotune::acquire::sine::SineRequest;
use drive::bode::BodePoint;
use drive::client::{Client, ClientConfig, CsvSink, LazyFile, SweepEvent};
use drive::protocol::Configure;
use drive::sim::{DriveSim, Effects, FaultAt, Faults, FirmwareKind, SimClock, SimConfig};
use std::io::Write;
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
    /// Probe the drive, design and run the identification experiment and those that separate
    /// what its diagnosis cannot tell apart, tune a FOPI on the final model and measure its step
    /// on the drive; the report round by round (text, --json, --out DIR with report.md and plots).
    Autotune(crate::cmd::drive_autotune::AutotuneArgs),
    /// Show the drive's identity and state.
    Status(StatusArgs),
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
        DriveCmd::Autotune(a) => crate::cmd::drive_autotune::run(a),
        DriveCmd::Status(a) => status(a),
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

impl PrbsArgs {
    /// The request of the options.
    fn request(&self) -> PrbsRequest {
        PrbsRequest {
            order: self.order,
            seed: self.seed,
            clock_s: self.clock,
            amplitude_v: self.amplitude,
            offset_v: self.offset,
            periods: self.periods,
            settle_s: self.settle,
        }
    }
}

fn prbs(a: PrbsArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    // Everything is checked before the output is touched or the drive asked anything.
    let conf = port_conf(&a.port)?;
    let req = a.request();
    let (_, warnings) = req.check(&conf).map_err(autotune_err)?;
    for w in warnings {
        crate::eprintln_safe!("warning: {w}");
    }
    let output = output_path(&a.output);
    check_outputs(&a.port.link.port, &[], &[("--output", &output)])?;
    let mut sink = CsvSink::new(output_file(&output)?);
    // The first SIGINT/SIGTERM/SIGHUP/SIGQUIT/... stops the drive; the record keeps what arrived and its
    // footer says what is missing.
    let (rec, signal) = run_on_drive(&a.port, &conf, "samples", |c| {
        autotune::acquire::prbs::run(c, &conf, &req, &mut sink).map_err(autotune_err)
    })?;
    let acq = close_record(
        rec.map(|r| r.acquisition).context("the PRBS run"),
        sink.into_inner(),
        &output,
    )?;
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

impl SineArgs {
    /// The request of the options.
    fn request(&self) -> SineRequest {
        SineRequest {
            f_min_hz: self.f_min,
            f_max_hz: self.f_max,
            points: self.points,
            freqs_hz: self.freqs.clone(),
            amplitude_v: self.amplitude,
            offset_v: self.offset,
            cycles: self.cycles,
            settle_cycles: self.settle_cycles,
            min_settle_s: self.min_settle,
            stream: self.stream,
            repeats: self.repeats,
        }
    }
}

/// The Bode table's header: the sweep, the hold, the frequencies the drive moved, the repeats.
fn sine_header(a: &SineArgs, conf: &Configure, moved: &[(f64, f64)]) -> String {
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
        let moved: Vec<String> = moved.iter().map(|(f, fa)| format!("{f} -> {fa}")).collect();
        format!(" {}", moved.join(", "))
    };
    if a.repeats > 1 {
        header += &format!(
            "\n{} repeats per frequency: trimmed mean (largest and smallest gain dropped, likewise the phase); \
             gain_db_std, phase_deg_std: sample standard deviations of the repeats",
            a.repeats
        );
    }
    header
}

fn sine(a: SineArgs) -> Result<()> {
    let _pipe = crate::interrupt::PipeErrors::arm();
    let conf = port_conf(&a.port)?;
    let (sweep, warnings) = a.request().sweep(&conf).map_err(autotune_err)?;
    for w in warnings {
        crate::eprintln_safe!("warning: {w}");
    }
    let moved = autotune::acquire::sine::applied(&sweep, &conf).map_err(autotune_err)?;
    let header = sine_header(&a, &conf, &moved);
    let output = output_path(&a.output);
    let reps_path = repeats_path(&a);
    let mut outs: Vec<(&str, &std::path::Path)> = vec![("--output", &output)];
    if let Some(r) = &reps_path {
        outs.push(("the repeats file (--repeats-out)", r));
    }
    check_outputs(&a.port.link.port, &[], &outs)?;
    let mut file = BodeFile::new(&output, header, sweep.repeats > 1)?;
    let mut reps_file = open_repeats_file(&a, &conf, reps_path)?;
    // The first SIGINT/SIGTERM/SIGHUP/SIGQUIT/... stops the drive; the points measured so far are in the
    // file, the rest listed in its footer.
    let (swept, signal) = run_on_drive(&a.port, &conf, "frequencies", |c| {
        autotune::acquire::sine::run(c, &sweep, &mut |ev| match ev {
            SweepEvent::Repeat(p, rep) => match reps_file.as_mut() {
                Some(r) => r.repeat(p, rep),
                None => Ok(()),
            },
            SweepEvent::Point(p) => file.point(p),
        })
        .map_err(autotune_err)
    })?;
    let mut rec = match swept {
        Ok(r) => r,
        Err(e) => {
            // Keep what was measured before the failure, with a footer.
            let _ = file.finish(&[format!("{e:#}")], &["(sweep failed)".into()]);
            let e = e.context(format!("the sine sweep ({})", output.display()));
            return Err(lost_output(e, &output, "table"));
        }
    };
    if let Some(s) = signal {
        rec.problems.push(format!(
            "interrupted by {}: sweep stopped",
            crate::interrupt::signal_name(s)
        ));
    }
    let unmeasured: Vec<String> = rec
        .unmeasured(&sweep, &conf)
        .iter()
        .map(f64::to_string)
        .collect();
    let written = file
        .finish(&rec.problems, &unmeasured)
        .with_context(|| format!("writing {}", output.display()))
        .map_err(|e| lost_output(e, &output, "table"))?;
    sine_outcome(&a, &rec, sweep.freqs_hz.len(), &unmeasured, written, signal)
}

/// How a sweep ends: its problems as warnings, then a signal (exit by it), frequencies not
/// measured (exit 1), or the summary.
fn sine_outcome(
    a: &SineArgs,
    rec: &autotune::acquire::sine::SineRecord,
    asked: usize,
    unmeasured: &[String],
    written: bool,
    signal: Option<i32>,
) -> Result<()> {
    for p in &rec.problems {
        crate::eprintln_safe!("warning: {p}");
    }
    let summary = format!(
        "{}: {} of {} frequencies{}",
        a.output.display(),
        rec.points.len(),
        asked,
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
