//! Virtual time: the drive's clock advanced in steps, waiting for the host only where the
//! protocol needs it ([`crate::sim::SimClock::Virtual`]).

use super::Firmware;
use crate::sim::pty::unread;
use crate::sim::{VIRTUAL_HOST_GRACE, VIRTUAL_MAX_UNREAD, VIRTUAL_STEP};
use crate::vclock::VirtualClock;
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

/// Virtual time, nothing on the line either way: the master is read every this many steps
/// (every 4 ms of drive time; at once after a wait for the host, and every step while bytes
/// are on their way).
pub(super) const VIRTUAL_QUIET_READ: u32 = 8;

/// Longest the kernel is taken to lag in moving bytes written to the pty master to the slave's
/// input queue (where FIONREAD counts them).
pub(super) const VIRTUAL_PTY_LAG: Duration = Duration::from_millis(2);

/// What the virtual clock does next ([`Firmware::may_advance`]).
pub(super) enum Advance {
    /// Take a step.
    Go,
    /// Wait for the host to read what was sent.
    WaitRead,
    /// Wait for a frame of the host (its KEEPALIVE), at most this long on the wall clock.
    WaitFrame(Duration),
}

impl Firmware {
    /// Virtual time: write what waits for the pty, then advance the clock by one step, or wait
    /// for the host where the protocol needs it ([`SimClock::Virtual`]). A wait blocks on the
    /// wall clock until the host acts (its bytes arrive, or it reads), not for a fixed sleep.
    pub(super) fn virtual_tick(&mut self) {
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
    pub(super) fn publish_clock(&self) {
        if let Some(c) = &self.vclock {
            c.set_now(self.vnow);
        }
    }

    /// Block until the host's bytes arrive on the master, or `max` passes (the master is read
    /// at the next step).
    pub(super) fn wait_input(&mut self, max: Duration) {
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
    pub(super) fn busy(&self) -> bool {
        let running = match &self.c {
            Some(c) => c.eng.running(),
            None => self.run.is_some(),
        };
        running || !self.line_quiet()
    }

    /// No bytes on their way in either direction.
    pub(super) fn line_quiet(&self) -> bool {
        !(!self.rx_pending.is_empty()
            || !self.rx_fifo.is_empty()
            || !self.tx_prio.is_empty()
            || !self.tx_data.is_empty()
            || !self.tx_bytes.is_empty()
            || !self.out_backlog.is_empty())
    }

    /// The keepalive interval of the run in progress, if any.
    pub(super) fn run_keepalive(&self) -> Option<Duration> {
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
    pub(super) fn may_advance(&mut self, wall: Instant) -> Advance {
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
    pub(super) fn flush_out(&mut self) {
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
}
