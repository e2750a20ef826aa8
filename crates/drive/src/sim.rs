//! A simulated F2812 drive speaking the protocol on a pseudo-terminal.
//!
//! [`DriveSim::spawn`] opens a pty pair (`serialport::TTYPort::pair()`), keeps the master side and
//! runs the "firmware" in a thread; a host opens [`DriveSim::port_path`] (the slave side, or a
//! stable symlink to it when [`SimConfig::link`] is set) like any serial port. The simulator
//! models:
//!
//! - the motor: a fractional PMSM model simulated by [`fracsim::Simulator`] (default: the paper's
//!   time-domain model `6.82 / (2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`), with hidden effects
//!   ([`Effects`]): Coulomb friction, input delay, torque ripple, measurement noise, speed
//!   quantisation;
//! - the line: baud-rate pacing in both directions (a pty paces nothing), a 16-byte receive FIFO
//!   that overflows while the firmware's communication task is stalled, a transmit buffer of a few
//!   DATA blocks (whole blocks dropped and counted when full);
//! - faults ([`Faults`]): bit flips, dropped bytes, bursts, whole-frame corruption, a stall, a
//!   disconnect and reconnect, a drive reset; and one lost answer ([`DriveSim::lose_next_answer`]).
//!
//! Its clock ([`SimClock`]) is the wall clock by default: samples are produced in batches every
//! ~0.5 ms as their time comes, as a real drive would. In virtual time ([`SimClock::Virtual`]) the
//! same drive runs as fast as the host allows, waiting for the host only where the protocol needs
//! it (the host reading what was sent, the keepalive; a host in the same process keeps its
//! keepalive on the drive's clock, [`crate::vclock`]).

use crate::codec::{self, StreamDecoder};
use crate::error::{Error, Result};
use crate::prbs::Lfsr;
use crate::protocol::*;
use crate::vclock::VirtualClock;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serialport::{SerialPort, TTYPort};
use std::collections::VecDeque;
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Hidden physical effects of the simulated drive (all off by default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects {
    /// Coulomb friction as a voltage equivalent at the input, V (`Vc sign(speed)`).
    pub coulomb_v: f64,
    /// Input (transport) delay, s.
    pub delay_s: f64,
    /// Periodic disturbance (torque ripple) as a voltage at the input: amplitude, V.
    pub ripple_v: f64,
    /// Ripple frequency, Hz.
    pub ripple_hz: f64,
    /// Gaussian measurement noise on the speed, standard deviation in rad/s.
    pub noise_std: f64,
    /// Speed quantisation step (encoder resolution), rad/s; 0 = none beyond the channel LSB.
    pub speed_quant: f64,
    /// Winding resistance for the indicative current channel, ohm.
    pub r_ohm: f64,
}

impl Default for Effects {
    fn default() -> Self {
        Self {
            coulomb_v: 0.0,
            delay_s: 0.0,
            ripple_v: 0.0,
            ripple_hz: 0.0,
            noise_std: 0.0,
            speed_quant: 0.0,
            r_ohm: 1.0,
        }
    }
}

impl Effects {
    /// Check the ranges: every value finite; friction, ripple frequency, noise and quantisation
    /// not negative (the ripple amplitude may be: a phase shift); the delay in
    /// `0..=MAX_DELAY_S` (the simulator holds the delayed commands in memory); the winding
    /// resistance positive.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming the first bad value.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("coulomb friction (V)", self.coulomb_v),
            ("ripple frequency (Hz)", self.ripple_hz),
            ("speed noise (rad/s)", self.noise_std),
            ("speed quantisation (rad/s)", self.speed_quant),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidParam(format!(
                    "{name} must be a finite number >= 0, got {v}"
                )));
            }
        }
        if !self.ripple_v.is_finite() {
            return Err(Error::InvalidParam(format!(
                "ripple amplitude must be finite, got {} V",
                self.ripple_v
            )));
        }
        if !(self.delay_s.is_finite() && (0.0..=MAX_DELAY_S).contains(&self.delay_s)) {
            return Err(Error::InvalidParam(format!(
                "input delay must be in [0, {MAX_DELAY_S}] s, got {}",
                self.delay_s
            )));
        }
        if !(self.r_ohm.is_finite() && self.r_ohm > 0.0) {
            return Err(Error::InvalidParam(format!(
                "winding resistance must be finite and > 0 ohm, got {}",
                self.r_ohm
            )));
        }
        Ok(())
    }
}

/// Longest input delay the simulator accepts, s.
pub const MAX_DELAY_S: f64 = 10.0;

/// Longest stall, disconnect or reset the simulator accepts.
pub const MAX_FAULT_DURATION: Duration = Duration::from_secs(3600);

/// A fault that happens once, when the drive has produced `at_sample` run samples (counted over
/// all runs since the simulator started), and lasts `duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultAt {
    /// Trigger: run samples produced since start.
    pub at_sample: u64,
    /// How long it lasts.
    pub duration: Duration,
}

/// Faults injected by the simulator (all off by default).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Faults {
    /// Probability per bit of a flip, both directions.
    pub bit_error_rate: f64,
    /// Probability per byte of losing it, both directions.
    pub drop_rate: f64,
    /// Probability per byte of starting a burst of `burst_len` random bytes (drive to host).
    pub burst_rate: f64,
    /// Burst length, bytes.
    pub burst_len: usize,
    /// Probability per drive-to-host frame of corrupting it (1 to 3 random bit flips).
    pub frame_corrupt_rate: f64,
    /// The communication task stalls: no transmission, receive FIFO overflows; control continues.
    pub stall: Option<FaultAt>,
    /// Disconnect: with [`SimConfig::link`] the pty is closed and a new one appears behind the
    /// link after `duration` (like a USB adapter unplugged and plugged in); without a link the line
    /// goes dead (bytes lost both ways) for `duration`.
    pub disconnect: Option<FaultAt>,
    /// The drive resets (boot id changes, run and configuration lost); `duration` is the boot time.
    pub reset: Option<FaultAt>,
    /// RNG seed for the faults and the noise.
    pub seed: u64,
}

impl Faults {
    /// Check the ranges: rates are probabilities in [0, 1]; a burst is at most 4096 bytes; a
    /// stall, disconnect or reset lasts at most [`MAX_FAULT_DURATION`].
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming the first bad value.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("bit error rate", self.bit_error_rate),
            ("byte drop rate", self.drop_rate),
            ("burst rate", self.burst_rate),
            ("frame corruption rate", self.frame_corrupt_rate),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::InvalidParam(format!(
                    "{name} must be in [0, 1], got {v}"
                )));
            }
        }
        if self.burst_len > 4096 {
            return Err(Error::InvalidParam(format!(
                "burst length must be at most 4096 bytes, got {}",
                self.burst_len
            )));
        }
        for (name, f) in [
            ("stall", self.stall),
            ("disconnect", self.disconnect),
            ("reset", self.reset),
        ] {
            if f.is_some_and(|f| f.duration > MAX_FAULT_DURATION) {
                return Err(Error::InvalidParam(format!(
                    "{name} duration must be at most {} s",
                    MAX_FAULT_DURATION.as_secs()
                )));
            }
        }
        Ok(())
    }
}

/// Which firmware runs behind the pty.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FirmwareKind {
    /// The simulator's own Rust implementation of the protocol.
    #[default]
    Rust,
    /// The C firmware of `firmware/` (fracfw, as flashed on the F2812), linked in through
    /// [`crate::cfw`]: protocol, experiments, streaming, keepalive and trips are the C code's;
    /// motor, hidden effects, line model and fault injection stay the simulator's.
    C,
}

impl FirmwareKind {
    /// `FRACID_SIM_FIRMWARE`: `c` (or `C`) selects [`FirmwareKind::C`]; anything else, or unset,
    /// [`FirmwareKind::Rust`].
    pub fn from_env() -> Self {
        match std::env::var("FRACID_SIM_FIRMWARE") {
            Ok(v) if v.eq_ignore_ascii_case("c") => FirmwareKind::C,
            _ => FirmwareKind::Rust,
        }
    }
}

/// How the simulator's clock runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SimClock {
    /// The wall clock: samples are produced as their time comes (in batches every ~0.5 ms) and
    /// the line is paced to the baud rate in real time, as a real drive does. For testing host
    /// software against the simulator, and for tests of timing (timeouts, keepalive, stalls).
    #[default]
    RealTime,
    /// Virtual time: the drive's clock (sample clock, line pacing at the baud rate, fault
    /// durations) advances in steps of [`VIRTUAL_STEP`] as fast as the host allows. It waits for
    /// the host only where the protocol needs it:
    ///
    /// - the host reads what the drive sent: the clock waits while more than
    ///   [`VIRTUAL_MAX_UNREAD`] bytes sent are unread in the pty, and bytes the pty cannot take
    ///   yet are kept, not lost (a host that merely reads late loses no DATA block);
    /// - the keepalive. A host in this process that shares the drive's clock
    ///   ([`DriveSim::virtual_clock`], [`crate::client::ClientConfig::clock`]) keeps its keepalive
    ///   on it: the clock runs up to the instant the host's next KEEPALIVE is due and waits
    ///   there for a frame, waking the host ([`crate::vclock`]). Any other host keeps it on the
    ///   wall clock: during a run the clock runs at most half the keepalive interval past the
    ///   host's last frame before that host sends its next one, so a host that sends a KEEPALIVE
    ///   every `k` ms of wall time lets the drive run `keepalive / 2` per `k` ms (such a host
    ///   sends them often: [`crate::client::ClientConfig::keepalive`] of a few ms).
    ///
    /// The waits block on the pty (the host's bytes end them at once) instead of sleeping; with
    /// nothing on the line either way the master is read every 8 steps. A host silent for a
    /// whole keepalive interval of wall time, or one that reads nothing for
    /// [`VIRTUAL_HOST_GRACE`], no longer holds the clock: the keepalive expires and bytes are lost
    /// as in real time. With no run and nothing to send, the clock follows the wall clock.
    Virtual,
}

/// The step of the virtual clock ([`SimClock::Virtual`]), as the real-time loop's period.
pub const VIRTUAL_STEP: Duration = Duration::from_micros(500);

/// Unread bytes in the pty above which the virtual clock waits for the host to read.
pub const VIRTUAL_MAX_UNREAD: usize = 512;

/// Virtual time, nothing on the line either way: the master is read every this many steps
/// (every 4 ms of drive time; at once after a wait for the host, and every step while bytes
/// are on their way).
const VIRTUAL_QUIET_READ: u32 = 8;

/// Longest the kernel is taken to lag in moving bytes written to the pty master to the slave's
/// input queue (where FIONREAD counts them).
const VIRTUAL_PTY_LAG: Duration = Duration::from_millis(2);

/// Wall time a host may leave the line unread before the virtual clock stops waiting for it.
pub const VIRTUAL_HOST_GRACE: Duration = Duration::from_secs(2);

/// Simulator configuration.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// The firmware behind the line.
    pub firmware: FirmwareKind,
    /// Motor model, voltage (V) to speed (rad/s).
    pub model: fracsim::FracTf,
    /// Approximation used to simulate it.
    pub approx: fracsim::ApproxSpec,
    /// Line rate the simulator paces to, baud (8N1: 10 bits per byte).
    pub baud: u32,
    /// Hidden effects.
    pub effects: Effects,
    /// Faults.
    pub faults: Faults,
    /// If set, a symlink at this path points to the current pty (needed for a real disconnect).
    pub link: Option<PathBuf>,
    /// Highest sample rate accepted, Hz.
    pub max_sample_rate_hz: u32,
    /// Transmit buffer capacity in DATA blocks.
    pub tx_blocks: usize,
    /// Receive FIFO depth, bytes.
    pub rx_fifo: usize,
    /// Print events to stderr.
    pub verbose: bool,
    /// The drive's clock: real time (default) or virtual time.
    pub clock: SimClock,
}

impl Default for SimConfig {
    /// The paper's motor, 115200 baud, no effects, no faults. The firmware is the Rust one unless
    /// the environment variable `FRACID_SIM_FIRMWARE` is `c` ([`FirmwareKind::from_env`]), which
    /// runs every simulator built from defaults (tests, `fracid drive sim`, the demo, the
    /// Python package's) on the C firmware.
    fn default() -> Self {
        Self {
            firmware: FirmwareKind::from_env(),
            model: fracsim::FracTf::pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252)
                .expect("the paper's model is valid"),
            approx: fracsim::ApproxSpec::default(),
            baud: 115_200,
            effects: Effects::default(),
            faults: Faults::default(),
            link: None,
            max_sample_rate_hz: 20_000,
            tx_blocks: 4,
            rx_fifo: 16,
            verbose: false,
            clock: SimClock::RealTime,
        }
    }
}

/// Counters and ground truth from the simulator (for tests and measurements).
#[derive(Debug, Clone, Default)]
pub struct SimStats {
    /// Frames transmitted (all types).
    pub frames_sent: u64,
    /// Frames transmitted with at least one corrupted, dropped or injected byte.
    pub frames_damaged: u64,
    /// Bytes transmitted.
    pub bytes_sent: u64,
    /// DATA blocks dropped because the transmit buffer was full.
    pub blocks_dropped: u64,
    /// Received bytes lost to receive FIFO overruns.
    pub rx_overruns: u64,
    /// Valid frames received.
    pub frames_received: u64,
    /// Received frames discarded.
    pub rx_errors: u64,
    /// Commands answered from the replay cache.
    pub replays: u64,
    /// Runs started.
    pub runs_started: u64,
    /// The samples of the last run as produced (raw u, y, i), index = sample index.
    pub truth: Vec<[i16; 3]>,
    /// The voltage command applied to the inverter now, raw (0 when no run is active: idle,
    /// stopped, tripped, emergency-stopped).
    pub output: i16,
    /// Answers deliberately lost by [`DriveSim::lose_next_answer`].
    pub answers_lost: u64,
    /// Run id of `truth`.
    pub truth_run_id: u16,
    /// Events, in order (fault injections, resets, runs).
    pub events: Vec<String>,
    /// Virtual time: blocking waits on the wall clock while a run was on (for the host to read,
    /// or for its KEEPALIVE). With a host that shares the drive's clock
    /// ([`crate::vclock::VirtualClock`]) about one per keepalive interval of drive time, plus
    /// the flow control of a host slower than the drive; never one per step.
    pub wall_waits: u64,
}

/// A running simulator. Dropping it stops the thread.
#[derive(Debug)]
pub struct DriveSim {
    path: String,
    clock: SimClock,
    vclock: Option<VirtualClock>,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<SimStats>>,
    lose_answer: Arc<AtomicU16>,
    thread: Option<JoinHandle<()>>,
}

impl DriveSim {
    /// Open a pty pair and start the firmware thread.
    ///
    /// # Errors
    /// Out-of-range effects or faults ([`Effects::validate`], [`Faults::validate`]), a baud rate
    /// of 0 (all [`Error::InvalidParam`]); the pty or the link cannot be made.
    pub fn spawn(cfg: SimConfig) -> Result<Self> {
        cfg.effects.validate()?;
        cfg.faults.validate()?;
        if cfg.baud == 0 {
            return Err(Error::InvalidParam("baud rate must be positive".into()));
        }
        let (master, slave_name) = open_pty()?;
        let watch = match cfg.clock {
            SimClock::Virtual => Some(watch_pty(&master, &slave_name)?),
            SimClock::RealTime => None,
        };
        let path = match &cfg.link {
            Some(link) => {
                retarget_link(link, &slave_name)?;
                link.to_string_lossy().into_owned()
            }
            None => slave_name,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(SimStats::default()));
        let cfg_clock = cfg.clock;
        let mut fw = Firmware::new(cfg, master, stats.clone())?;
        fw.slave = watch;
        let vclock = fw.vclock.clone();
        let lose_answer = fw.lose_answer.clone();
        let stop2 = stop.clone();
        let thread = std::thread::Builder::new()
            .name("drive-sim".into())
            .spawn(move || fw.run(&stop2))
            .map_err(Error::Io)?;
        Ok(Self {
            path,
            clock: cfg_clock,
            vclock,
            stop,
            stats,
            lose_answer,
            thread: Some(thread),
        })
    }

    /// Fault injection: the drive's next answer to a command of type `ty` (a [`ty`] code) is
    /// lost on the line, once: the command is executed (and its answer cached for a replay) but
    /// the answer never reaches the host, as if the line ate it.
    pub fn lose_next_answer(&self, ty: u8) {
        self.lose_answer.store(0x100 | ty as u16, Ordering::Relaxed);
    }

    /// The path a host opens (the pty slave, or the link).
    pub fn port_path(&self) -> &str {
        &self.path
    }

    /// The simulator's clock.
    pub fn clock(&self) -> SimClock {
        self.clock
    }

    /// In virtual time, the drive's clock for a host in this process to keep its keepalive on
    /// ([`crate::client::ClientConfig::clock`]); None in real time.
    pub fn virtual_clock(&self) -> Option<VirtualClock> {
        self.vclock.clone()
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> SimStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// Whether the firmware thread is still running.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stop the simulator and wait for its thread.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for DriveSim {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Open a pty pair; keep the master, close the slave (the host opens it by name).
fn open_pty() -> Result<(TTYPort, String)> {
    let (mut master, slave) = TTYPort::pair().map_err(|e| Error::Port {
        path: "pty".into(),
        source: e,
    })?;
    let name = slave
        .name()
        .ok_or_else(|| Error::Protocol("pty slave has no name".into()))?;
    drop(slave);
    let _ = master.set_timeout(Duration::ZERO);
    Ok((master, name))
}

/// Virtual time: the master in non-blocking mode (what the pty cannot take waits in the
/// simulator), and the slave held open to see how much the host has not read yet.
fn watch_pty(master: &TTYPort, slave_name: &str) -> Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    let fd = master.as_raw_fd();
    // SAFETY: fcntl on a descriptor we own, no pointers.
    let ok = unsafe {
        let fl = libc::fcntl(fd, libc::F_GETFL);
        fl >= 0 && libc::fcntl(fd, libc::F_SETFL, fl | libc::O_NONBLOCK) == 0
    };
    if !ok {
        return Err(Error::Io(std::io::Error::last_os_error()));
    }
    let slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
        .open(slave_name)?;
    Ok(slave)
}

/// Bytes waiting to be read on the pty slave (FIONREAD); 0 if that cannot be known.
fn unread(slave: &std::fs::File) -> usize {
    let mut n: libc::c_int = 0;
    // SAFETY: FIONREAD writes one c_int through a valid pointer.
    let r = unsafe { libc::ioctl(slave.as_raw_fd(), libc::FIONREAD, &mut n) };
    if r == 0 {
        n.max(0) as usize
    } else {
        0
    }
}

fn retarget_link(link: &std::path::Path, target: &str) -> Result<()> {
    let tmp = link.with_extension("tmp-link");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp)?;
    std::fs::rename(&tmp, link)?;
    Ok(())
}

/// The motor with its hidden effects.
struct Plant {
    sim: fracsim::Simulator<f64>,
    dc_gain: f64,
    fx: Effects,
    delay: VecDeque<f64>,
    y: f64,
    k: u64,
    dt: f64,
    noise: Normal<f64>,
}

impl Plant {
    fn new(cfg: &SimConfig, fs: u32) -> Result<Self> {
        let dt = 1.0 / fs as f64;
        let sim = fracsim::Simulator::<f64>::new(&cfg.model, dt, &cfg.approx)
            .map_err(|e| Error::InvalidParam(format!("motor model: {e}")))?;
        let dc_gain = cfg.model.num.iter().map(|t| t.coef).sum::<f64>()
            / cfg
                .model
                .den
                .iter()
                .filter(|t| t.order == 0.0)
                .map(|t| t.coef)
                .sum::<f64>();
        let nd = (cfg.effects.delay_s.max(0.0) * fs as f64).round() as usize;
        Ok(Self {
            sim,
            dc_gain: if dc_gain.is_finite() && dc_gain != 0.0 {
                dc_gain
            } else {
                1.0
            },
            fx: cfg.effects,
            delay: std::iter::repeat_n(0.0, nd).collect(),
            y: 0.0,
            k: 0,
            dt,
            noise: Normal::new(0.0, cfg.effects.noise_std.max(0.0))
                .unwrap_or(Normal::new(0.0, 0.0).expect("valid")),
        })
    }

    /// One sample: command u (V) -> (measured speed rad/s, current A).
    fn step(&mut self, u: f64, rng: &mut StdRng) -> (f64, f64) {
        self.delay.push_back(u);
        let ud = self.delay.pop_front().unwrap_or(u);
        let fx = &self.fx;
        let mut ue = ud;
        if fx.coulomb_v > 0.0 {
            if self.y.abs() > 1e-3 {
                ue -= fx.coulomb_v * self.y.signum();
            } else if ud.abs() <= fx.coulomb_v {
                ue = 0.0;
            } else {
                ue -= fx.coulomb_v * ud.signum();
            }
        }
        if fx.ripple_v != 0.0 {
            ue += fx.ripple_v
                * (2.0 * std::f64::consts::PI * fx.ripple_hz * self.k as f64 * self.dt).sin();
        }
        self.k += 1;
        let y = self.sim.step(ue);
        self.y = if y.is_finite() { y } else { 0.0 };
        let mut ym = self.y;
        if fx.noise_std > 0.0 {
            ym += self.noise.sample(rng);
        }
        if fx.speed_quant > 0.0 {
            ym = (ym / fx.speed_quant).round() * fx.speed_quant;
        }
        let i = (ue - self.y / self.dc_gain) / fx.r_ohm.max(1e-6);
        (ym, i)
    }

    /// The speed measured at the tick, before this sample's command: the output at `t_k`
    /// ([`fracsim::Simulator::next_output`]; the last output for a model that feeds its input
    /// through), with the measurement noise and quantisation.
    fn measure(&mut self, rng: &mut StdRng) -> f64 {
        let y = self
            .sim
            .next_output()
            .filter(|v| v.is_finite())
            .unwrap_or(self.y);
        let mut ym = y;
        if self.fx.noise_std > 0.0 {
            ym += self.noise.sample(rng);
        }
        if self.fx.speed_quant > 0.0 {
            ym = (ym / self.fx.speed_quant).round() * self.fx.speed_quant;
        }
        ym
    }

    fn reset(&mut self) {
        self.sim.reset();
        for d in &mut self.delay {
            *d = 0.0;
        }
        self.y = 0.0;
        self.k = 0;
    }
}

enum Excitation {
    Prbs {
        lfsr: Lfsr,
        p: StartPrbs,
        bit: bool,
    },
    Sine {
        s: StartSine,
        phase: u32,
        inc: u32,
        settle: u32,
        measure: u32,
        acc: [f64; 4],
        /// Level and ramp sums of u and y (exact integers, as the C firmware's).
        moments: crate::bode::WindowSums,
    },
    /// The speed loop: the reference step and the controller with its states.
    Loop {
        p: StartLoop,
        ctrl: crate::ctrl::FixedCtrl,
        z: Vec<i64>,
    },
}

struct Run {
    id: u16,
    total: u32,
    done: u32,
    sent: u32,
    dropped: u16,
    clamped: u16,
    start: Instant,
    block: Vec<[i16; 3]>,
    block_first: u32,
    block_flags: u8,
    exc: Excitation,
    /// Streams DATA blocks (always for PRBS; START_SINE flag bit 0).
    stream: bool,
    ramp: Option<(u32, u32, EndReason)>, // (samples left, ramp length, reason)
    last_u: f64,
}

struct Firmware {
    cfg: SimConfig,
    master: Option<TTYPort>,
    stats: Arc<Mutex<SimStats>>,
    /// 0, or 0x100 | the command type whose next answer is lost.
    lose_answer: Arc<AtomicU16>,
    /// The answer being produced now is to be lost.
    losing: bool,
    rng: StdRng,
    boot_id: u16,
    conf: Option<Configure>,
    plant: Option<Plant>,
    run: Option<Run>,
    last_run: Option<(u16, u32, u16, u16)>, // id, done, dropped, clamped
    last_end: Option<StreamEnd>,
    /// The controller being downloaded: LOAD_CTRL and the sections loaded so far.
    ctrl_load: Option<(LoadCtrl, Vec<LoadSection>)>,
    fault: u8,
    next_run_id: u16,
    tx_seq: u16,
    cache: Option<(u16, u8, Vec<u8>)>,
    dec: StreamDecoder,
    // line model
    rx_pending: VecDeque<u8>,
    rx_fifo: VecDeque<u8>,
    rx_budget: f64,
    tx_prio: VecDeque<Vec<u8>>,
    tx_data: VecDeque<Vec<u8>>,
    tx_bytes: VecDeque<u8>,
    tx_budget: f64,
    burst_left: usize,
    last_tick: Instant,
    /// When the run's keepalive timer was last reset: its START, or a KEEPALIVE of its run id.
    last_keepalive: Instant,
    rx_errors: u16,
    // faults
    run_samples_total: u64,
    stall_until: Option<Instant>,
    dead_until: Option<Instant>,
    reopen_at: Option<Instant>,
    boot_until: Option<Instant>,
    fired: [bool; 3],
    /// The C firmware, when [`FirmwareKind::C`].
    c: Option<CState>,
    // virtual time (SimClock::Virtual)
    /// The drive's clock.
    vnow: Instant,
    /// Wall time of the loop's last pass (idle, the clock follows the wall clock).
    wall_last: Instant,
    /// Wall time of `last_keepalive`.
    last_keepalive_wall: Instant,
    /// Bytes sent that the pty could not take yet.
    out_backlog: VecDeque<u8>,
    /// The pty slave, held open to see what the host has not read.
    slave: Option<std::fs::File>,
    /// Since when (wall) the clock waits for the host to read.
    wait_since: Option<Instant>,
    /// The host has read nothing for [`VIRTUAL_HOST_GRACE`]: the clock no longer waits for it.
    host_absent: bool,
    /// The drive's clock shared with an in-process host ([`DriveSim::virtual_clock`]).
    vclock: Option<VirtualClock>,
    /// Wall time of the last write to the pty.
    last_write: Option<Instant>,
    /// The pty was counted within [`VIRTUAL_MAX_UNREAD`] at least [`VIRTUAL_PTY_LAG`] after the
    /// last write: until the next write it need not be counted again.
    unread_settled: bool,
    /// Steps since the master was last read (virtual time, quiet line).
    quiet_steps: u32,
}

/// What the virtual clock does next ([`Firmware::may_advance`]).
enum Advance {
    /// Take a step.
    Go,
    /// Wait for the host to read what was sent.
    WaitRead,
    /// Wait for a frame of the host (its KEEPALIVE), at most this long on the wall clock.
    WaitFrame(Duration),
}

/// The C engine and what the simulator tracks around it.
struct CState {
    eng: crate::cfw::CEngine,
    /// Wall-clock start of the current run and the samples produced in it.
    start: Instant,
    ticks: u64,
    /// Counters already added to [`SimStats`].
    seen: crate::cfw::CCounters,
    seen_rx_errors: u16,
}

const FW_MAJOR: u8 = 1;
/// 1.1: the speed loop (LOAD_CTRL, LOAD_SECTION, START_LOOP); 1.2: controller format 2 (up to 48
/// sections and 8 delay taps); 1.3: protocol 3 (only a KEEPALIVE of the run keeps it alive).
const FW_MINOR: u8 = 3;

impl Firmware {
    fn new(cfg: SimConfig, master: TTYPort, stats: Arc<Mutex<SimStats>>) -> Result<Self> {
        let mut rng = StdRng::seed_from_u64(cfg.faults.seed);
        let boot_id = rng.gen();
        let now = Instant::now();
        let c = (cfg.firmware == FirmwareKind::C).then(|| CState {
            eng: crate::cfw::CEngine::new(boot_id, cfg.max_sample_rate_hz),
            start: now,
            ticks: 0,
            seen: Default::default(),
            seen_rx_errors: 0,
        });
        let vclock = match cfg.clock {
            SimClock::Virtual => Some(VirtualClock::new(now)?),
            SimClock::RealTime => None,
        };
        let fw = Self {
            cfg,
            master: Some(master),
            stats,
            lose_answer: Arc::new(AtomicU16::new(0)),
            losing: false,
            rng,
            boot_id,
            conf: None,
            plant: None,
            run: None,
            last_run: None,
            last_end: None,
            ctrl_load: None,
            fault: fault::NONE,
            next_run_id: 1,
            tx_seq: 0,
            cache: None,
            dec: StreamDecoder::new(),
            rx_pending: VecDeque::new(),
            rx_fifo: VecDeque::new(),
            rx_budget: 0.0,
            tx_prio: VecDeque::new(),
            tx_data: VecDeque::new(),
            tx_bytes: VecDeque::new(),
            tx_budget: 0.0,
            burst_left: 0,
            last_tick: now,
            last_keepalive: now,
            rx_errors: 0,
            run_samples_total: 0,
            stall_until: None,
            dead_until: None,
            reopen_at: None,
            boot_until: None,
            fired: [false; 3],
            c: None,
            vnow: now,
            wall_last: now,
            last_keepalive_wall: now,
            out_backlog: VecDeque::new(),
            slave: None,
            wait_since: None,
            host_absent: false,
            vclock,
            last_write: None,
            unread_settled: false,
            quiet_steps: 0,
        };
        Ok(Self { c, ..fw })
    }

    fn event(&self, s: String) {
        if self.cfg.verbose {
            eprintln!("drive-sim: {s}");
        }
        if let Ok(mut st) = self.stats.lock() {
            st.events.push(s);
        }
    }

    fn with_stats(&self, f: impl FnOnce(&mut SimStats)) {
        if let Ok(mut s) = self.stats.lock() {
            f(&mut s);
        }
    }

    fn run(&mut self, stop: &AtomicBool) {
        let virtual_time = self.cfg.clock == SimClock::Virtual;
        while !stop.load(Ordering::Relaxed) {
            let now = if virtual_time {
                self.vnow
            } else {
                Instant::now()
            };
            let elapsed = now.duration_since(self.last_tick).as_secs_f64().min(0.05);
            self.last_tick = now;
            self.line_state(now);
            if self.boot_until.is_some_and(|t| now < t) {
                // Booting: nothing runs, bytes arriving are lost.
                self.drain_input_lost();
            } else {
                self.boot_until = None;
                self.receive(elapsed, now);
                self.control(now);
                self.transmit(elapsed, now);
            }
            if virtual_time {
                self.virtual_tick();
            } else {
                std::thread::sleep(Duration::from_micros(400));
            }
        }
    }

    /// Virtual time: write what waits for the pty, then advance the clock by one step, or wait
    /// for the host where the protocol needs it ([`SimClock::Virtual`]). A wait blocks on the
    /// wall clock until the host acts (its bytes arrive, or it reads), not for a fixed sleep.
    fn virtual_tick(&mut self) {
        self.flush_out();
        let wall = Instant::now();
        if !self.busy() {
            // Nothing to simulate: time passes as on the wall clock (a frame of the host ends
            // the wait at once).
            self.wait_input(Duration::from_micros(400));
            let w = Instant::now();
            self.vnow += w.duration_since(self.wall_last);
            self.wall_last = w;
            self.wait_since = None;
            self.publish_clock();
            return;
        }
        self.wall_last = wall;
        match self.may_advance(wall) {
            Advance::Go => {
                self.vnow += VIRTUAL_STEP;
                self.wait_since = None;
                self.publish_clock();
            }
            Advance::WaitRead => {
                self.wait_since.get_or_insert(wall);
                self.with_stats(|s| s.wall_waits += 1);
                std::thread::sleep(Duration::from_micros(50));
            }
            Advance::WaitFrame(left) => {
                self.wait_since.get_or_insert(wall);
                self.with_stats(|s| s.wall_waits += 1);
                self.wait_input(left.clamp(Duration::from_micros(100), Duration::from_millis(50)));
            }
        }
    }

    /// Publish the drive's clock to a host that shares it.
    fn publish_clock(&self) {
        if let Some(c) = &self.vclock {
            c.set_now(self.vnow);
        }
    }

    /// Block until the host's bytes arrive on the master, or `max` passes (the master is read
    /// at the next step).
    fn wait_input(&mut self, max: Duration) {
        self.quiet_steps = VIRTUAL_QUIET_READ;
        let Some(m) = self.master.as_ref() else {
            std::thread::sleep(max);
            return;
        };
        let mut pfd = libc::pollfd {
            fd: m.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ts = crate::vclock::timespec(max);
        // SAFETY: one valid pollfd, a valid timespec, no signal mask.
        let r = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
        if r > 0 && pfd.revents & (libc::POLLHUP | libc::POLLERR) != 0 {
            // No host has the slave open (a pty master reports a hang-up then): nothing can
            // arrive, do not spin.
            std::thread::sleep(max);
        }
    }

    /// A run is on, or bytes are on their way in either direction.
    fn busy(&self) -> bool {
        let running = match &self.c {
            Some(c) => c.eng.running(),
            None => self.run.is_some(),
        };
        running || !self.line_quiet()
    }

    /// No bytes on their way in either direction.
    fn line_quiet(&self) -> bool {
        !(!self.rx_pending.is_empty()
            || !self.rx_fifo.is_empty()
            || !self.tx_prio.is_empty()
            || !self.tx_data.is_empty()
            || !self.tx_bytes.is_empty()
            || !self.out_backlog.is_empty())
    }

    /// The keepalive interval of the run in progress, if any.
    fn run_keepalive(&self) -> Option<Duration> {
        let ms = match &self.c {
            Some(c) if c.eng.running() => c.eng.config().map(|cc| cc.keepalive_ms),
            Some(_) => None,
            None => self
                .run
                .as_ref()
                .and(self.conf)
                .map(|conf| conf.keepalive_ms),
        }?;
        Some(Duration::from_millis(ms as u64))
    }

    /// Whether the virtual clock may take its next step now, or what it waits for.
    fn may_advance(&mut self, wall: Instant) -> Advance {
        // The host reads what was sent: the pty is counted at every step, unless nothing was
        // written since a count within the limit that the kernel's moving of the bytes could no
        // longer lag (the count can then only have fallen).
        let over = !self.unread_settled && {
            let u = self.slave.as_ref().map_or(0, unread);
            let settled = self
                .last_write
                .is_none_or(|t| t.elapsed() >= VIRTUAL_PTY_LAG);
            self.unread_settled = u <= VIRTUAL_MAX_UNREAD && settled;
            u > VIRTUAL_MAX_UNREAD
        };
        if self.out_backlog.is_empty() && !over {
            self.host_absent = false;
        } else if !self.host_absent {
            if self
                .wait_since
                .is_some_and(|t| wall.duration_since(t) >= VIRTUAL_HOST_GRACE)
            {
                self.host_absent = true;
                self.event(format!(
                    "virtual time: the host has read nothing for {VIRTUAL_HOST_GRACE:?}; the \
                     clock runs on without it"
                ));
            } else {
                return Advance::WaitRead;
            }
        }
        // The keepalive. A host sharing the drive's clock has said when its next KEEPALIVE is
        // due: the clock runs up to then and waits for it (waking the host). Otherwise the
        // clock runs at most half the interval past the run's last KEEPALIVE. Either way, unless
        // a frame is arriving or the run's host has really been silent the whole interval (wall
        // time: no KEEPALIVE of the run, whatever else came).
        if let Some(ka) = self.run_keepalive() {
            let host_due = self.vclock.as_ref().and_then(VirtualClock::host_due);
            let horizon = host_due.unwrap_or(self.last_keepalive + ka / 2);
            let silent = wall.duration_since(self.last_keepalive_wall);
            if self.vnow + VIRTUAL_STEP > horizon && self.rx_pending.is_empty() && silent < ka {
                if let (Some(c), Some(_)) = (&self.vclock, host_due) {
                    c.wake_host();
                }
                return Advance::WaitFrame(ka - silent);
            }
        }
        Advance::Go
    }

    /// Virtual time: write what waits for the pty, as much as it takes (the rest waits; all of it
    /// is lost if the host is absent, as on a real line).
    fn flush_out(&mut self) {
        if self.out_backlog.is_empty() {
            return;
        }
        let Some(m) = self.master.as_ref() else {
            self.out_backlog.clear();
            return;
        };
        let fd = m.as_raw_fd();
        let before = self.slave.as_ref().map(unread);
        let mut wrote = false;
        loop {
            let buf = self.out_backlog.make_contiguous();
            if buf.is_empty() {
                break;
            }
            // SAFETY: writes from a valid buffer of `buf.len()` bytes to a descriptor we own.
            let n = unsafe { libc::write(fd, buf.as_ptr().cast(), buf.len()) };
            if n > 0 {
                self.out_backlog.drain(..n as usize);
                wrote = true;
            } else {
                let e = std::io::Error::last_os_error();
                if n < 0 && e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                if n == 0 || e.kind() != std::io::ErrorKind::WouldBlock {
                    self.out_backlog.clear();
                }
                break;
            }
        }
        if self.host_absent {
            self.out_backlog.clear();
        }
        if wrote {
            self.last_write = Some(Instant::now());
            self.unread_settled = false;
        }
        // The kernel moves what the master wrote to the slave's input queue in a worker thread:
        // until it has, FIONREAD does not count it, and a clock running flat out could write
        // the pty full before the host's lag shows. Wait (up to 0.3 ms) until the count moves (it
        // may not: the host read it at once).
        if let (true, Some(u0), Some(slave)) = (wrote, before, self.slave.as_ref()) {
            let t0 = Instant::now();
            while unread(slave) == u0 && t0.elapsed() < Duration::from_micros(300) {
                std::thread::yield_now();
            }
        }
    }

    fn byte_rate(&self) -> f64 {
        self.cfg.baud as f64 / 10.0
    }

    fn line_state(&mut self, now: Instant) {
        if let Some(t) = self.stall_until {
            if now >= t {
                self.stall_until = None;
                self.event("stall ends".into());
            }
        }
        if let Some(t) = self.dead_until {
            if now >= t {
                self.dead_until = None;
                self.event("line back".into());
            }
        }
        if let Some(t) = self.reopen_at {
            if now >= t {
                self.reopen_at = None;
                match (open_pty(), &self.cfg.link) {
                    (Ok((m, name)), Some(link)) => {
                        if self.cfg.clock == SimClock::Virtual {
                            self.slave = watch_pty(&m, &name).ok();
                            self.unread_settled = false;
                        }
                        if retarget_link(link, &name).is_ok() {
                            self.master = Some(m);
                            self.event(format!("reconnected as {name}"));
                        }
                    }
                    _ => self.event("reconnect failed".into()),
                }
            }
        }
    }

    fn drain_input_lost(&mut self) {
        if let Some(m) = self.master.as_mut() {
            let mut buf = [0u8; 512];
            let _ = m.read(&mut buf);
        }
    }

    /// Read what the host sent, pace it to the line rate, pass it through the FIFO model.
    fn receive(&mut self, elapsed: f64, now: Instant) {
        let mut buf = [0u8; 1024];
        let virtual_time = self.cfg.clock == SimClock::Virtual;
        if virtual_time && self.line_quiet() && self.quiet_steps < VIRTUAL_QUIET_READ {
            // Nothing on the line either way: the master is read every few steps only.
            self.quiet_steps += 1;
        } else if let Some(m) = self.master.as_mut() {
            self.quiet_steps = 0;
            let got = if virtual_time {
                // The master is non-blocking in virtual time: one read, no poll first.
                // SAFETY: reads into a valid buffer of `buf.len()` bytes from a descriptor we own.
                let n = unsafe { libc::read(m.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
                usize::try_from(n).map_err(|_| std::io::Error::last_os_error())
            } else {
                m.read(&mut buf)
            };
            match got {
                Ok(n) if n > 0 => {
                    let dead = self.dead_until.is_some();
                    if !dead {
                        for &b in &buf[..n] {
                            self.rx_pending.push_back(b);
                        }
                    }
                }
                _ => {}
            }
        }
        // Bytes arrive at the line rate.
        self.rx_budget = (self.rx_budget + elapsed * self.byte_rate()).min(4096.0);
        let stalled = self.stall_until.is_some();
        while self.rx_budget >= 1.0 {
            let Some(mut b) = self.rx_pending.pop_front() else {
                self.rx_budget = self.rx_budget.min(1.0);
                break;
            };
            self.rx_budget -= 1.0;
            // Line faults, host -> drive.
            let f = self.cfg.faults;
            if f.drop_rate > 0.0 && self.rng.gen_bool(f.drop_rate.min(1.0)) {
                continue;
            }
            b = self.flip_bits(b);
            if self.rx_fifo.len() < self.cfg.rx_fifo.max(1) {
                self.rx_fifo.push_back(b);
            } else {
                self.with_stats(|s| s.rx_overruns += 1);
            }
            if !stalled {
                self.service_fifo(now);
            }
        }
        if !stalled {
            self.service_fifo(now);
        }
    }

    fn flip_bits(&mut self, mut b: u8) -> u8 {
        let ber = self.cfg.faults.bit_error_rate;
        if ber > 0.0 {
            let p_byte = 1.0 - (1.0 - ber.min(1.0)).powi(8);
            if self.rng.gen_bool(p_byte) {
                b ^= 1 << self.rng.gen_range(0..8);
            }
        }
        b
    }

    fn service_fifo(&mut self, now: Instant) {
        if self.rx_fifo.is_empty() {
            return;
        }
        if self.c.is_some() {
            return self.c_service_fifo(now);
        }
        let bytes: Vec<u8> = self.rx_fifo.drain(..).collect();
        let before = self.dec.stats().errors;
        let frames = self.dec.push(&bytes);
        let errs = self.dec.stats().errors - before;
        if errs > 0 {
            self.rx_errors = self.rx_errors.saturating_add(errs as u16);
            self.with_stats(|s| s.rx_errors += errs);
        }
        for f in frames {
            self.with_stats(|s| s.frames_received += 1);
            self.handle(f, now);
        }
    }

    fn reply(&mut self, seq: u16, msg: Message) -> Vec<u8> {
        let name = msg.name();
        let bytes = codec::encode(&Frame { seq, msg });
        self.push_answer(bytes.clone(), name, seq);
        bytes
    }

    /// Queue an answer ahead of DATA, unless it is to be lost ([`DriveSim::lose_next_answer`]).
    fn push_answer(&mut self, bytes: Vec<u8>, name: &str, seq: u16) {
        if std::mem::take(&mut self.losing) {
            self.with_stats(|s| s.answers_lost += 1);
            self.event(format!("answer {name} (seq {seq}) lost on the line"));
        } else {
            self.tx_prio.push_back(bytes);
        }
    }

    fn nak(&mut self, f: &Frame, code: NakCode, detail: u16) -> Vec<u8> {
        self.reply(
            f.seq,
            Message::Nak(Nak {
                nak_type: f.msg.type_code(),
                code,
                detail,
            }),
        )
    }

    fn ack(&mut self, f: &Frame, run_id: u16, total_samples: u32) -> Vec<u8> {
        self.reply(
            f.seq,
            Message::Ack(Ack {
                acked_type: f.msg.type_code(),
                run_id,
                total_samples,
            }),
        )
    }

    fn handle(&mut self, f: Frame, now: Instant) {
        let t = f.msg.type_code();
        let lose = 0x100 | t as u16;
        self.losing = self
            .lose_answer
            .compare_exchange(lose, 0, Ordering::Relaxed, Ordering::Relaxed)
            .is_ok();
        self.handle_command(f, now);
        self.losing = false;
    }

    fn handle_command(&mut self, f: Frame, now: Instant) {
        let t = f.msg.type_code();
        match f.msg {
            Message::Keepalive(id) => {
                // Only a KEEPALIVE of the running run keeps it alive (PROTOCOL.md, section 7):
                // not any valid frame, such as another program's STATUS.
                if self.run.as_ref().is_some_and(|r| r.id == id) {
                    self.last_keepalive = now;
                    self.last_keepalive_wall = Instant::now();
                }
                return;
            }
            Message::Hello => {
                self.cache = None;
                let r = Message::HelloReply(HelloReply {
                    proto_version: PROTO_VERSION,
                    fw_major: FW_MAJOR,
                    fw_minor: FW_MINOR,
                    n_channels: N_CHANNELS as u8,
                    max_block_samples: MAX_BLOCK_SAMPLES,
                    boot_id: self.boot_id,
                    max_sample_rate_hz: self.cfg.max_sample_rate_hz,
                });
                self.reply(f.seq, r);
                return;
            }
            _ => {}
        }
        if t >= 0x80 {
            return; // drive-to-host types are ignored by the drive
        }
        if let Some((seq, ty, bytes)) = &self.cache {
            if *seq == f.seq && *ty == t {
                let b = bytes.clone();
                self.push_answer(b, "replay", f.seq);
                self.with_stats(|s| s.replays += 1);
                return;
            }
        }
        let answer = self.execute(&f, now);
        self.cache = Some((f.seq, t, answer));
    }

    fn status(&self) -> StatusReply {
        let (state, run_id, done, dropped, clamped) = match (&self.run, self.last_run) {
            (Some(r), _) => (DriveState::Running, r.id, r.done, r.dropped, r.clamped),
            (None, Some((id, d, dr, c))) => (self.idle_state(), id, d, dr, c),
            (None, None) => (self.idle_state(), 0, 0, 0, 0),
        };
        StatusReply {
            state,
            fault: self.fault,
            run_id,
            samples_done: done,
            blocks_dropped: dropped,
            boot_id: self.boot_id,
            rx_errors: self.rx_errors,
            clamped,
        }
    }

    fn idle_state(&self) -> DriveState {
        if self.fault != fault::NONE {
            DriveState::Fault
        } else if self.conf.is_some() {
            DriveState::Idle
        } else {
            DriveState::Unconfigured
        }
    }

    fn execute(&mut self, f: &Frame, now: Instant) -> Vec<u8> {
        match &f.msg {
            Message::Status => {
                let s = self.status();
                self.reply(f.seq, Message::StatusReply(s))
            }
            Message::Configure(c) => {
                if self.run.is_some() {
                    return self.nak(f, NakCode::Busy, 0);
                }
                if let Some(off) = check_configure(c, self.cfg.max_sample_rate_hz) {
                    return self.nak(f, NakCode::BadValue, off);
                }
                match Plant::new(&self.cfg, c.sample_rate_hz) {
                    Ok(p) => self.plant = Some(p),
                    Err(_) => return self.nak(f, NakCode::BadValue, 0),
                }
                self.conf = Some(*c);
                self.fault = fault::NONE;
                // the controller's gains are in the channel units, its poles at the rate
                self.ctrl_load = None;
                self.ack(f, 0, 0)
            }
            Message::LoadCtrl(c) => self.load_ctrl(f, c),
            Message::LoadSection(c) => self.load_section(f, c),
            Message::StartLoop(l) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let ctrl = match &self.ctrl_load {
                    Some((h, s)) if s.len() == h.n_sections as usize + h.n_taps as usize => {
                        crate::ctrl::FixedCtrl::from_messages(h, s)
                    }
                    _ => return self.nak(f, NakCode::NoController, 0),
                };
                if l.pre_samples > l.total_samples {
                    return self.nak(f, NakCode::BadValue, 4);
                }
                if l.total_samples == 0 {
                    return self.nak(f, NakCode::BadValue, 8);
                }
                let z = vec![0; ctrl.n_states()];
                let exc = Excitation::Loop { p: *l, ctrl, z };
                self.start_run(f, l.total_samples, exc, true, now)
            }
            Message::StartPrbs(p) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let Some(total) = p.total_samples() else {
                    return self.nak(f, NakCode::BadValue, 0);
                };
                let Some(lfsr) = Lfsr::new(p.order, p.taps, p.seed) else {
                    return self.nak(f, NakCode::BadValue, 2);
                };
                if p.clock_samples == 0 || p.periods == 0 || p.amplitude < 0 || total == 0 {
                    return self.nak(f, NakCode::BadValue, 10);
                }
                let exc = Excitation::Prbs {
                    lfsr,
                    p: *p,
                    bit: false,
                };
                self.start_run(f, total, exc, true, now)
            }
            Message::StartSine(s) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let fs = self.conf.map(|c| c.sample_rate_hz).unwrap_or(1);
                let counts = s.sample_counts(fs);
                let bad = s.freq_mhz == 0
                    || s.freq_mhz as u64 > fs as u64 * 500
                    || s.amplitude < 0
                    || s.cycles == 0
                    || s.flags & (SINE_STREAM | SINE_DFT) == 0;
                let Some((settle, measure)) = counts.filter(|c| !bad && c.1 > 0) else {
                    return self.nak(f, NakCode::BadValue, 0);
                };
                if s.flags & SINE_DFT != 0 && measure > MAX_DFT_SAMPLES {
                    return self.nak(f, NakCode::BadValue, 10);
                }
                let inc = (((s.freq_mhz as u128) << 32) + 500 * fs as u128) / (1000 * fs as u128);
                let exc = Excitation::Sine {
                    s: *s,
                    phase: 0,
                    inc: inc as u32,
                    settle,
                    measure,
                    acc: [0.0; 4],
                    moments: crate::bode::WindowSums::default(),
                };
                let stream = s.flags & SINE_STREAM != 0;
                self.start_run(f, settle + measure, exc, stream, now)
            }
            Message::Stop => {
                if let Some(r) = self.run.as_mut() {
                    if r.ramp.is_none() {
                        r.ramp = Some((1, 1, EndReason::Stopped));
                    }
                }
                self.ack(f, 0, 0)
            }
            Message::Estop => {
                if self.run.is_some() {
                    self.end_run(EndReason::Estop);
                }
                self.fault = fault::ESTOP;
                self.ack(f, 0, 0)
            }
            Message::EndQuery(id) => match self.last_end {
                Some(e) if e.run_id == *id && self.run.as_ref().is_none_or(|r| r.id != *id) => {
                    self.reply(f.seq, Message::StreamEnd(e))
                }
                _ => self.nak(f, NakCode::BadValue, 0),
            },
            _ => self.nak(f, NakCode::UnknownType, 0),
        }
    }

    fn load_ctrl(&mut self, f: &Frame, c: &LoadCtrl) -> Vec<u8> {
        if self.run.is_some() {
            return self.nak(f, NakCode::Busy, 0);
        }
        if self.conf.is_none() {
            return self.nak(f, NakCode::NotConfigured, 0);
        }
        let (max_sections, max_taps) = match c.format {
            CTRL_FORMAT => (MAX_SECTIONS, 0),
            CTRL_FORMAT_TAPS => (MAX_SECTIONS_TAPS, MAX_TAPS),
            _ => return self.nak(f, NakCode::BadValue, 0),
        };
        if c.n_sections > max_sections {
            return self.nak(f, NakCode::BadValue, 1);
        }
        if c.n_taps > max_taps {
            return self.nak(f, NakCode::BadValue, 2);
        }
        self.ctrl_load = Some((*c, Vec::new()));
        self.ack(f, 0, 0)
    }

    fn load_section(&mut self, f: &Frame, c: &LoadSection) -> Vec<u8> {
        if self.run.is_some() {
            return self.nak(f, NakCode::Busy, 0);
        }
        if self.conf.is_none() {
            return self.nak(f, NakCode::NotConfigured, 0);
        }
        let next = match &self.ctrl_load {
            Some((h, s)) if s.len() < h.n_sections as usize + h.n_taps as usize => {
                (s.len() as u8, s.len() >= h.n_sections as usize)
            }
            _ => return self.nak(f, NakCode::BadValue, 0),
        };
        if c.index != next.0 {
            return self.nak(f, NakCode::BadValue, 0);
        }
        // a pole within the unit circle; a tap's pole field 0
        if c.a_q30.unsigned_abs() > 1 << 30 || (next.1 && c.a_q30 != 0) {
            return self.nak(f, NakCode::BadValue, 2);
        }
        if let Some((_, s)) = self.ctrl_load.as_mut() {
            s.push(*c);
        }
        self.ack(f, 0, 0)
    }

    fn start_check(&mut self, f: &Frame) -> Option<Vec<u8>> {
        if self.run.is_some() {
            return Some(self.nak(f, NakCode::Busy, 0));
        }
        if self.fault != fault::NONE {
            let d = self.fault as u16;
            return Some(self.nak(f, NakCode::Fault, d));
        }
        if self.conf.is_none() {
            return Some(self.nak(f, NakCode::NotConfigured, 0));
        }
        None
    }

    fn start_run(
        &mut self,
        f: &Frame,
        total: u32,
        exc: Excitation,
        stream: bool,
        now: Instant,
    ) -> Vec<u8> {
        let id = self.next_run_id;
        self.next_run_id = self.next_run_id.wrapping_add(1).max(1);
        if let Some(p) = self.plant.as_mut() {
            p.reset();
        }
        self.run = Some(Run {
            id,
            total,
            done: 0,
            sent: 0,
            dropped: 0,
            clamped: 0,
            start: now,
            block: Vec::new(),
            block_first: 0,
            block_flags: 0,
            exc,
            stream,
            ramp: None,
            last_u: 0.0,
        });
        self.last_end = None;
        self.last_keepalive = now;
        self.last_keepalive_wall = Instant::now();
        self.with_stats(|s| {
            s.runs_started += 1;
            s.truth.clear();
            s.truth_run_id = id;
        });
        self.event(format!("run {id} started, {total} samples"));
        self.ack(f, id, total)
    }

    fn next_tx_seq(&mut self) -> u16 {
        self.tx_seq = self.tx_seq.wrapping_add(1);
        self.tx_seq
    }

    fn end_run(&mut self, reason: EndReason) {
        let Some(mut r) = self.run.take() else { return };
        // The inverter is off from here on.
        self.with_stats(|s| s.output = 0);
        self.flush_block(&mut r);
        if let Excitation::Sine {
            acc,
            measure,
            s,
            moments,
            ..
        } = &r.exc
        {
            if s.flags & SINE_DFT != 0 && reason == EndReason::Complete {
                let n = *measure as f64;
                let q = |v: f64| {
                    (v * 2.0 / n * 256.0)
                        .round()
                        .clamp(i32::MIN as f64, i32::MAX as f64) as i32
                };
                let res = SineResult {
                    run_id: r.id,
                    n: *measure,
                    u_re: q(acc[0]),
                    u_im: q(acc[1]),
                    y_re: q(acc[2]),
                    y_im: q(acc[3]),
                    u_mean: crate::bode::q8_mean(moments.level[0], *measure),
                    u_ramp: crate::bode::q8_ramp(moments.ramp[0], *measure),
                    y_mean: crate::bode::q8_mean(moments.level[1], *measure),
                    y_ramp: crate::bode::q8_ramp(moments.ramp[1], *measure),
                };
                let seq = self.next_tx_seq();
                self.tx_data.push_back(codec::encode(&Frame {
                    seq,
                    msg: Message::SineResult(res),
                }));
            }
        }
        let end = StreamEnd {
            run_id: r.id,
            reason,
            total_samples: r.done,
            samples_sent: r.sent,
            blocks_dropped: r.dropped,
        };
        let seq = self.next_tx_seq();
        // STREAM_END always fits: it goes behind the queued DATA, never dropped.
        self.tx_data.push_back(codec::encode(&Frame {
            seq,
            msg: Message::StreamEnd(end),
        }));
        self.last_end = Some(end);
        self.last_run = Some((r.id, r.done, r.dropped, r.clamped));
        self.event(format!(
            "run {} ended: {reason:?}, {} samples, {} blocks dropped",
            r.id, r.done, r.dropped
        ));
    }

    fn flush_block(&mut self, r: &mut Run) {
        if r.block.is_empty() {
            return;
        }
        let samples = std::mem::take(&mut r.block);
        let n = samples.len() as u32;
        if self.tx_data.len() >= self.cfg.tx_blocks.max(1) {
            r.dropped = r.dropped.saturating_add(1);
            self.with_stats(|s| s.blocks_dropped += 1);
        } else {
            let seq = self.next_tx_seq();
            let msg = Message::Data(DataBlock {
                run_id: r.id,
                first_index: r.block_first,
                flags: r.block_flags,
                samples,
            });
            self.tx_data.push_back(codec::encode(&Frame { seq, msg }));
            r.sent += n;
        }
        r.block_flags = 0;
    }

    /// Produce the samples due by now.
    fn control(&mut self, now: Instant) {
        if self.c.is_some() {
            return self.c_control(now);
        }
        let Some(conf) = self.conf else { return };
        let Some(mut r) = self.run.take() else { return };
        let fs = conf.sample_rate_hz as f64;
        // Samples due by the wall clock; the planned run stops at `total`, a ramp-down may run on.
        let wall = (now.duration_since(r.start).as_secs_f64() * fs) as u64;
        let due = wall.min(r.total as u64);
        let keepalive = Duration::from_millis(conf.keepalive_ms as u64);
        let mut end: Option<EndReason> = None;
        loop {
            if r.ramp.is_none() && now.duration_since(self.last_keepalive) > keepalive {
                let n = (fs * 0.05).ceil().max(1.0) as u32;
                r.ramp = Some((n, n, EndReason::Keepalive));
                self.fault = fault::KEEPALIVE;
                self.event(format!(
                    "keepalive expired at sample {}: ramping down",
                    r.done
                ));
            }
            if let Some((0, _, reason)) = r.ramp {
                end = Some(reason);
                break;
            }
            // A ramp-down is paced like the run: one sample per sample period.
            if r.done as u64 >= if r.ramp.is_some() { wall } else { due } {
                break;
            }
            let sat = |v: f64| v.round().clamp(-32767.0, 32767.0) as i16;
            // the loop's speed, measured at the tick before its command is computed
            let mut loop_y: Option<i16> = None;
            let mut ctrl_clamped = false;
            let (u_raw_cmd, measuring) = match &mut r.ramp {
                Some((left, len, _)) => {
                    *left -= 1;
                    let v = r.last_u * (*left as f64) / (*len as f64);
                    ((v / conf.u_lsb()).round(), None)
                }
                None => {
                    let k = r.done;
                    match &mut r.exc {
                        Excitation::Prbs { lfsr, p, bit } => {
                            let v = if k < p.settle_samples {
                                p.offset as f64
                            } else {
                                let j = k - p.settle_samples;
                                if j % (p.clock_samples as u32) == 0 {
                                    let b = j / p.clock_samples as u32;
                                    if (b as u64).is_multiple_of(lfsr.period()) {
                                        lfsr.restart();
                                    }
                                    *bit = lfsr.next_bit();
                                }
                                if *bit {
                                    p.offset as f64 + p.amplitude as f64
                                } else {
                                    p.offset as f64 - p.amplitude as f64
                                }
                            };
                            (v, None)
                        }
                        Excitation::Sine {
                            s,
                            phase,
                            inc,
                            settle,
                            ..
                        } => {
                            let th = *phase as f64 / 4294967296.0 * std::f64::consts::TAU;
                            // the firmware's Q30 sine table (as the C firmware): same samples
                            let v =
                                crate::cfw::sine_command_rs(*phase, s.amplitude, s.offset) as f64;
                            let m = if k >= *settle { Some(th) } else { None };
                            *phase = phase.wrapping_add(*inc);
                            (v, m)
                        }
                        Excitation::Loop { p, ctrl, z } => {
                            let y = self
                                .plant
                                .as_mut()
                                .map_or(0.0, |pl| pl.measure(&mut self.rng));
                            let y_raw = sat(y / conf.y_lsb());
                            loop_y = Some(y_raw);
                            let e = p.reference(k as u64) as i32 - y_raw as i32;
                            let (u, c) = ctrl.step(z, e, conf.u_limit);
                            ctrl_clamped = c;
                            (u as f64, None)
                        }
                    }
                }
            };
            let lim = conf.u_limit as f64;
            let mut flags = 0;
            let u_raw = if u_raw_cmd.abs() > lim || ctrl_clamped {
                r.clamped = r.clamped.saturating_add(1);
                flags |= 1;
                u_raw_cmd.clamp(-lim, lim)
            } else {
                u_raw_cmd
            };
            let u = u_raw * conf.u_lsb();
            if r.ramp.is_none() {
                r.last_u = u;
            }
            let (y, i) = match self.plant.as_mut() {
                Some(p) => p.step(u, &mut self.rng),
                None => (0.0, 0.0),
            };
            let raw = [
                sat(u_raw),
                loop_y.unwrap_or_else(|| sat(y / conf.y_lsb())),
                sat(i / conf.i_lsb()),
            ];
            if let (
                Some(th),
                Excitation::Sine {
                    acc,
                    moments,
                    settle,
                    measure,
                    ..
                },
            ) = (measuring, &mut r.exc)
            {
                moments.add(r.done - *settle, *measure, raw[0], raw[1]);
                acc[0] += raw[0] as f64 * th.cos();
                acc[1] -= raw[0] as f64 * th.sin();
                acc[2] += raw[1] as f64 * th.cos();
                acc[3] -= raw[1] as f64 * th.sin();
            }
            if r.stream {
                if r.block.is_empty() {
                    r.block_first = r.done;
                }
                r.block.push(raw);
                r.block_flags |= flags;
            }
            r.done += 1;
            self.run_samples_total += 1;
            self.with_stats(|s| {
                s.truth.push(raw);
                s.output = raw[0];
            });
            let speed_trip = raw[1].unsigned_abs() > conf.y_limit.unsigned_abs();
            let current_trip = raw[2].unsigned_abs() > conf.i_limit.unsigned_abs();
            if (speed_trip || current_trip) && r.ramp.is_none() {
                self.fault = if speed_trip {
                    fault::SPEED_LIMIT
                } else {
                    fault::CURRENT_LIMIT
                };
                self.flush_block(&mut r);
                end = Some(EndReason::Limit);
                break;
            }
            if r.block.len() >= conf.block_samples as usize {
                self.flush_block(&mut r);
            }
            if r.done >= r.total && r.ramp.is_none() {
                end = Some(EndReason::Complete);
                break;
            }
            if self.check_faults(now) {
                // reset: the run is gone
                return;
            }
        }
        self.run = Some(r);
        if let Some(reason) = end {
            self.end_run(reason);
        }
    }

    /// Trigger scheduled faults; returns true if the drive reset.
    fn check_faults(&mut self, now: Instant) -> bool {
        let f = self.cfg.faults;
        let n = self.run_samples_total;
        if let Some(s) = f.stall.filter(|s| !self.fired[0] && n >= s.at_sample) {
            self.fired[0] = true;
            self.stall_until = Some(now + s.duration);
            self.event(format!("stall for {:?} at sample {n}", s.duration));
        }
        if let Some(d) = f.disconnect.filter(|d| !self.fired[1] && n >= d.at_sample) {
            self.fired[1] = true;
            if self.cfg.link.is_some() {
                self.master = None; // closes the pty: the host's port hangs up
                self.slave = None;
                self.out_backlog.clear();
                self.reopen_at = Some(now + d.duration);
                self.event(format!(
                    "disconnect (pty closed) for {:?} at sample {n}",
                    d.duration
                ));
            } else {
                self.dead_until = Some(now + d.duration);
                self.event(format!("line dead for {:?} at sample {n}", d.duration));
            }
        }
        if let Some(r) = f.reset.filter(|r| !self.fired[2] && n >= r.at_sample) {
            self.fired[2] = true;
            self.event(format!("drive reset at sample {n}"));
            self.reset(now + r.duration);
            return true;
        }
        false
    }

    fn reset(&mut self, boot_until: Instant) {
        let old = self.boot_id;
        while self.boot_id == old {
            self.boot_id = self.rng.gen();
        }
        self.conf = None;
        self.plant = None;
        self.run = None;
        self.with_stats(|s| s.output = 0);
        self.last_run = None;
        self.last_end = None;
        self.fault = fault::NONE;
        self.cache = None;
        self.tx_seq = 0;
        self.dec.reset();
        self.rx_fifo.clear();
        self.rx_pending.clear();
        self.tx_prio.clear();
        self.tx_data.clear();
        self.tx_bytes.clear();
        self.out_backlog.clear();
        self.stall_until = None;
        self.boot_until = Some(boot_until);
        let (boot_id, max_fs) = (self.boot_id, self.cfg.max_sample_rate_hz);
        if let Some(c) = self.c.as_mut() {
            c.eng.init(boot_id, max_fs);
            c.seen = Default::default();
            c.seen_rx_errors = 0;
        }
    }

    /// Send bytes at the line rate; responses go before queued DATA.
    fn transmit(&mut self, elapsed: f64, _now: Instant) {
        if self.stall_until.is_some() {
            return;
        }
        self.tx_budget =
            (self.tx_budget + elapsed * self.byte_rate()).min(self.byte_rate() * 0.01 + 64.0);
        let mut out = Vec::new();
        while self.tx_budget >= 1.0 {
            if self.tx_bytes.is_empty() {
                let next = match self.c.as_mut() {
                    Some(c) => c.eng.tx_frame(),
                    None => self
                        .tx_prio
                        .pop_front()
                        .or_else(|| self.tx_data.pop_front()),
                };
                let Some(frame) = next else {
                    self.tx_budget = self.tx_budget.min(1.0);
                    break;
                };
                let damaged = self.damage_frame(frame);
                self.tx_bytes.extend(damaged);
            }
            if let Some(b) = self.tx_bytes.pop_front() {
                out.push(b);
                self.tx_budget -= 1.0;
            }
        }
        if out.is_empty() {
            return;
        }
        let n = out.len() as u64;
        self.with_stats(|s| s.bytes_sent += n);
        if self.dead_until.is_some() {
            return;
        }
        if self.cfg.clock == SimClock::Virtual {
            // What the pty cannot take now waits (the clock waits with it).
            self.out_backlog.extend(out);
            self.flush_out();
        } else if let Some(m) = self.master.as_mut() {
            // A full pty buffer or an absent host loses the bytes, as a real line would.
            let _ = m.write_all(&out);
        }
    }

    /// Apply line faults to one outgoing frame.
    fn damage_frame(&mut self, frame: Vec<u8>) -> Vec<u8> {
        let f = self.cfg.faults;
        let mut out = Vec::with_capacity(frame.len());
        let mut damaged = false;
        for b in frame {
            if self.burst_left > 0 {
                self.burst_left -= 1;
                out.push(self.rng.gen());
                damaged = true;
                continue;
            }
            if f.burst_rate > 0.0 && self.rng.gen_bool(f.burst_rate.min(1.0)) {
                self.burst_left = f.burst_len.max(1);
            }
            if f.drop_rate > 0.0 && self.rng.gen_bool(f.drop_rate.min(1.0)) {
                damaged = true;
                continue;
            }
            let c = self.flip_bits(b);
            damaged |= c != b;
            out.push(c);
        }
        if f.frame_corrupt_rate > 0.0
            && !out.is_empty()
            && self.rng.gen_bool(f.frame_corrupt_rate.min(1.0))
        {
            let flips = self.rng.gen_range(1..=3);
            for _ in 0..flips {
                let i = self.rng.gen_range(0..out.len());
                out[i] ^= 1 << self.rng.gen_range(0..8);
            }
            damaged = true;
        }
        self.with_stats(|s| {
            s.frames_sent += 1;
            if damaged {
                s.frames_damaged += 1;
            }
        });
        out
    }
}

/// The C firmware behind the line model ([`FirmwareKind::C`]).
impl Firmware {
    /// Feed the receive FIFO to the C engine; mirror its events into the stats and the plant.
    fn c_service_fifo(&mut self, now: Instant) {
        let bytes: Vec<u8> = self.rx_fifo.drain(..).collect();
        let Some(mut c) = self.c.take() else { return };
        for b in bytes {
            let Some(t) = c.eng.rx(b) else { continue };
            self.with_stats(|s| s.frames_received += 1);
            let lose = 0x100 | t as u16;
            if self
                .lose_answer
                .compare_exchange(lose, 0, Ordering::Relaxed, Ordering::Relaxed)
                .is_ok()
                && c.eng.drop_last_answer()
            {
                self.with_stats(|s| s.answers_lost += 1);
                self.event(format!("answer to type {t:#04x} lost on the line"));
            }
            let k = c.eng.counters();
            if k.keepalives != c.seen.keepalives || k.runs_started != c.seen.runs_started {
                // the engine's keepalive timer was reset (a KEEPALIVE of its run, a START)
                self.last_keepalive = now;
                self.last_keepalive_wall = Instant::now();
            }
            if k.configs != c.seen.configs {
                // a CONFIGURE was accepted: a motor at its sample rate
                self.plant = c
                    .eng
                    .config()
                    .and_then(|cc| Plant::new(&self.cfg, cc.sample_rate_hz).ok());
            }
            if k.runs_started != c.seen.runs_started {
                if let Some(p) = self.plant.as_mut() {
                    p.reset();
                }
                c.start = now;
                c.ticks = 0;
                let id = c.eng.run_id();
                self.with_stats(|s| {
                    s.truth.clear();
                    s.truth_run_id = id;
                });
                self.event(format!("run {id} started (C firmware)"));
            }
            self.c_sync(&mut c, k);
        }
        self.c = Some(c);
    }

    /// Add the C engine's counter increments to the stats.
    fn c_sync(&mut self, c: &mut CState, k: crate::cfw::CCounters) {
        let e = c.eng.rx_errors();
        let d_err = e.wrapping_sub(c.seen_rx_errors) as u64;
        self.rx_errors = e;
        let s0 = c.seen;
        self.with_stats(|s| {
            s.rx_errors += d_err;
            s.replays += (k.replays - s0.replays) as u64;
            s.runs_started += (k.runs_started - s0.runs_started) as u64;
            s.blocks_dropped += (k.blocks_dropped - s0.blocks_dropped) as u64;
        });
        c.seen = k;
        c.seen_rx_errors = e;
    }

    /// Run the C engine's samples due by the wall clock, with the simulator's motor.
    fn c_control(&mut self, now: Instant) {
        let Some(mut c) = self.c.take() else { return };
        let mut reset = false;
        if let (Some(cc), true) = (c.eng.config(), c.eng.running()) {
            let fs = cc.sample_rate_hz as f64;
            let lsb = cc.scales.map(|v| v as f64 * 1e-6);
            let mut wall = (now.duration_since(c.start).as_secs_f64() * fs) as u64;
            // This thread can fall behind the wall clock on a loaded machine; a real drive does
            // not (its sample and receive interrupts interleave). Catching up a long backlog at
            // once would run its samples without the frames that arrived meanwhile, and the C
            // engine, which counts its keepalive in samples, would expire. So a backlog beyond
            // 20 ms is dropped: the run goes on later, the same sample for sample.
            let max_behind = (fs / 50.0).ceil() as u64;
            if wall > c.ticks + max_behind {
                let skip = wall - c.ticks - max_behind;
                c.start += Duration::from_secs_f64(skip as f64 / fs);
                wall = c.ticks + max_behind;
            }
            let sat = |v: f64| v.round().clamp(-32767.0, 32767.0) as i16;
            while c.ticks < wall {
                // a loop run: the speed at the tick, before the command
                let loop_y = c.eng.loop_running().then(|| {
                    let y = self
                        .plant
                        .as_mut()
                        .map_or(0.0, |p| p.measure(&mut self.rng));
                    let y_raw = sat(y / lsb[1]);
                    c.eng.sample_measure(y_raw);
                    y_raw
                });
                let Some(u_raw) = c.eng.sample_begin() else {
                    break;
                };
                let (y, i) = match self.plant.as_mut() {
                    Some(p) => p.step(u_raw as f64 * lsb[0], &mut self.rng),
                    None => (0.0, 0.0),
                };
                let raw = [
                    u_raw,
                    loop_y.unwrap_or_else(|| sat(y / lsb[1])),
                    sat(i / lsb[2]),
                ];
                c.eng.sample_end(raw[1], raw[2]);
                c.ticks += 1;
                self.run_samples_total += 1;
                self.with_stats(|s| {
                    s.truth.push(raw);
                    s.output = raw[0];
                });
                if self.check_faults(now) {
                    reset = true;
                    break;
                }
            }
        }
        if !reset && !c.eng.running() {
            self.with_stats(|s| s.output = 0);
        }
        let k = c.eng.counters();
        self.c_sync(&mut c, k);
        if reset {
            // Firmware::reset re-initialised self.c, which is taken: do it here.
            c.eng.init(self.boot_id, self.cfg.max_sample_rate_hz);
            c.seen = Default::default();
            c.seen_rx_errors = 0;
        }
        self.c = Some(c);
    }
}

/// Offset of the first invalid CONFIGURE field, if any.
fn check_configure(c: &Configure, max_fs: u32) -> Option<u16> {
    if c.sample_rate_hz == 0 || c.sample_rate_hz > max_fs {
        return Some(0);
    }
    if c.block_samples == 0 || c.block_samples > MAX_BLOCK_SAMPLES {
        return Some(4);
    }
    if !(50..=5000).contains(&c.keepalive_ms) {
        return Some(6);
    }
    if c.scale_u_uv == 0 {
        return Some(8);
    }
    if c.scale_y_urad_s == 0 {
        return Some(12);
    }
    if c.scale_i_ua == 0 {
        return Some(16);
    }
    if c.u_limit <= 0 {
        return Some(20);
    }
    if c.y_limit <= 0 {
        return Some(22);
    }
    if c.i_limit <= 0 {
        return Some(24);
    }
    None
}
