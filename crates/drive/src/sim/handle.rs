//! The running simulator as the host process holds it: spawn, stats, stop.

use super::firmware::Firmware;
use super::pty::{open_pty, retarget_link, watch_pty};
use super::{SimClock, SimConfig, SimStats};
use crate::error::{Error, Result};
use crate::vclock::VirtualClock;
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

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
    /// Out-of-range effects or faults ([`Effects::validate`](super::Effects::validate), [`Faults::validate`](super::Faults::validate)), a baud rate
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

    /// Fault injection: the drive's next answer to a command of type `ty` (a [`ty`](crate::protocol::ty) code) is
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
