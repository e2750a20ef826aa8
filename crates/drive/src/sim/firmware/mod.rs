//! The firmware thread: its state and main loop, scheduled faults and the drive reset; the line
//! and virtual time around the firmware, the Rust firmware's dispatch and sample loop, and the C
//! firmware behind the same line.

mod cfirmware;
mod control;
mod dispatch;
mod line;
mod run;
mod vtime;

use super::plant::Plant;
use super::{FirmwareKind, SimClock, SimConfig, SimStats};
use crate::codec::StreamDecoder;
use crate::error::Result;
use crate::protocol::*;
use crate::vclock::VirtualClock;
use cfirmware::CState;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use run::Run;
use serialport::TTYPort;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub(super) struct Firmware {
    cfg: SimConfig,
    master: Option<TTYPort>,
    stats: Arc<Mutex<SimStats>>,
    /// 0, or 0x100 | the command type whose next answer is lost.
    pub(super) lose_answer: Arc<AtomicU16>,
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
    pub(super) slave: Option<std::fs::File>,
    /// Since when (wall) the clock waits for the host to read.
    wait_since: Option<Instant>,
    /// The host has read nothing for [`VIRTUAL_HOST_GRACE`]: the clock no longer waits for it.
    host_absent: bool,
    /// The drive's clock shared with an in-process host ([`DriveSim::virtual_clock`]).
    pub(super) vclock: Option<VirtualClock>,
    /// Wall time of the last write to the pty.
    last_write: Option<Instant>,
    /// The pty was counted within [`VIRTUAL_MAX_UNREAD`] at least [`VIRTUAL_PTY_LAG`] after the
    /// last write: until the next write it need not be counted again.
    unread_settled: bool,
    /// Steps since the master was last read (virtual time, quiet line).
    quiet_steps: u32,
}

/// A boot id no other simulator in this or another process is likely to share (std's per-instance
/// random hash keys; 0 is never used).
fn fresh_boot_id() -> u16 {
    use std::hash::{BuildHasher, Hasher};
    let h = std::collections::hash_map::RandomState::new()
        .build_hasher()
        .finish();
    ((h ^ (h >> 16) ^ (h >> 32) ^ (h >> 48)) as u16).max(1)
}

impl Firmware {
    pub(super) fn new(
        cfg: SimConfig,
        master: TTYPort,
        stats: Arc<Mutex<SimStats>>,
    ) -> Result<Self> {
        let mut rng = StdRng::seed_from_u64(cfg.faults.seed);
        // The faults' stream stays the seed's (its first draw was the boot id); the boot id is each
        // simulated drive's own, as a real drive's differs from the next one's: a host that
        // reopens a path and finds another drive behind it tells them apart by it.
        let _: u16 = rng.gen();
        let boot_id = fresh_boot_id();
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

    pub(super) fn event(&self, s: String) {
        if self.cfg.verbose {
            eprintln!("drive-sim: {s}");
        }
        if let Ok(mut st) = self.stats.lock() {
            st.events.push(s);
        }
    }

    pub(super) fn with_stats(&self, f: impl FnOnce(&mut SimStats)) {
        if let Ok(mut s) = self.stats.lock() {
            f(&mut s);
        }
    }

    pub(super) fn run(&mut self, stop: &AtomicBool) {
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

    /// Trigger scheduled faults; returns true if the drive reset.
    pub(super) fn check_faults(&mut self, now: Instant) -> bool {
        let f = self.cfg.faults;
        let n = self.run_samples_total;
        if let Some(s) = f.stall.filter(|s| !self.fired[0] && n >= s.at_sample) {
            self.fired[0] = true;
            self.stall_until = Some(now + s.duration);
            self.event(format!("stall for {:?} at sample {n}", s.duration));
        }
        if let Some(d) = f.disconnect.filter(|d| !self.fired[1] && n >= d.at_sample) {
            self.fired[1] = true;
            if let Some(link) = &self.cfg.link {
                // A device unplugged leaves no node behind: the link goes with the pty, so a
                // host reopening the path waits for this drive and can never open another
                // process's pty that took the freed number meanwhile.
                let _ = std::fs::remove_file(link);
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

    pub(super) fn reset(&mut self, boot_until: Instant) {
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
}
