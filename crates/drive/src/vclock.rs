//! The clock a simulator in virtual time ([`crate::sim::SimClock::Virtual`]) shares with a host
//! in the same process ([`crate::client::ClientConfig::clock`]).
//!
//! A host on the wall clock keeps a virtual-time drive alive by sending KEEPALIVE frames every
//! few milliseconds of wall time, and the drive's clock may run only half its keepalive interval
//! past the host's last frame: the drive's speed is bounded by the host's wall-clock cadence. A
//! host that shares the drive's clock keeps its keepalive on the drive's time instead: it sends a
//! KEEPALIVE every [`crate::client::ClientConfig::keepalive`] of *drive* time, and publishes when
//! the next one is due ([`VirtualClock::host_due`]). The drive's clock runs up to that instant
//! and no further until a frame of the host arrives; if it has to wait there, it wakes the host
//! through a pipe ([`VirtualClock::wake_fd`]), which the host polls beside its port. The wire
//! protocol is unchanged (the same KEEPALIVE frames, the drive's keepalive interval unchanged);
//! only the host's timer runs on the drive's clock. A host that does not answer within the
//! drive's keepalive interval of wall time is silent: the drive's clock runs on without it and
//! its keepalive expires, as with a host on the wall clock.

use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// No host has published a due time.
const NO_HOST: u64 = u64::MAX;

/// The drive's clock of a simulator in virtual time, shared with an in-process host (cheap to
/// clone: all clones are the same clock).
#[derive(Clone)]
pub struct VirtualClock(Arc<Inner>);

struct Inner {
    /// The drive's time 0 (the simulator's start).
    origin: Instant,
    /// The drive's time, ns since `origin`.
    now_ns: AtomicU64,
    /// The host's next KEEPALIVE is due at this drive time (ns), or [`NO_HOST`].
    due_ns: AtomicU64,
    /// The drive's clock waits for a frame of the host (set by the drive, cleared by the host's
    /// next frame).
    waiting: AtomicBool,
    /// Times the drive woke the host.
    wakes: AtomicU64,
    /// Pipe: the host polls `rx`, the drive writes a byte to `tx` to wake it.
    rx: OwnedFd,
    tx: OwnedFd,
}

impl std::fmt::Debug for VirtualClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VirtualClock")
            .field("now", &self.now())
            .field("host_due", &self.host_due())
            .field("wakes", &self.wakes())
            .finish()
    }
}

impl VirtualClock {
    /// A clock at drive time 0 = `origin`, no host attached.
    ///
    /// # Errors
    /// The wake pipe cannot be made.
    pub(crate) fn new(origin: Instant) -> io::Result<Self> {
        let mut fds = [0 as libc::c_int; 2];
        // SAFETY: pipe2 writes two descriptors into a valid array of two.
        if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_NONBLOCK | libc::O_CLOEXEC) } != 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: both descriptors were just opened and are owned by nothing else.
        let (rx, tx) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
        Ok(Self(Arc::new(Inner {
            origin,
            now_ns: AtomicU64::new(0),
            due_ns: AtomicU64::new(NO_HOST),
            waiting: AtomicBool::new(false),
            wakes: AtomicU64::new(0),
            rx,
            tx,
        })))
    }

    /// The drive's time since the simulator started.
    pub fn now(&self) -> Duration {
        Duration::from_nanos(self.0.now_ns.load(Ordering::Acquire))
    }

    /// The drive's clock as an instant (`origin + now`), as the simulator keeps it.
    pub(crate) fn set_now(&self, t: Instant) {
        let ns = t.saturating_duration_since(self.0.origin).as_nanos();
        self.0
            .now_ns
            .store(ns.min(NO_HOST as u128 - 1) as u64, Ordering::Release);
    }

    /// When the attached host's next KEEPALIVE is due, as a drive instant; None without a host.
    pub(crate) fn host_due(&self) -> Option<Instant> {
        match self.0.due_ns.load(Ordering::Acquire) {
            NO_HOST => None,
            ns => Some(self.0.origin + Duration::from_nanos(ns)),
        }
    }

    /// The host sent a frame at drive time `now`: its next KEEPALIVE is due `keepalive` later
    /// (`None`: the host detaches, the drive no longer waits for it).
    pub(crate) fn host_sent(&self, due: Option<Duration>) {
        let ns = due.map_or(NO_HOST, |d| d.as_nanos().min(NO_HOST as u128 - 1) as u64);
        self.0.due_ns.store(ns, Ordering::Release);
        self.0.waiting.store(false, Ordering::Release);
    }

    /// Whether the drive's clock waits for a frame of the host.
    pub(crate) fn drive_waits(&self) -> bool {
        self.0.waiting.load(Ordering::Acquire)
    }

    /// The drive waits for the host's frame: wake the host (once per wait).
    pub(crate) fn wake_host(&self) {
        if self.0.waiting.swap(true, Ordering::AcqRel) {
            return;
        }
        self.0.wakes.fetch_add(1, Ordering::Relaxed);
        let b = 1u8;
        // SAFETY: writes one byte from a valid buffer to a descriptor we own. A full pipe
        // (EAGAIN) already holds a wake-up.
        let _ = unsafe { libc::write(self.0.tx.as_raw_fd(), (&b as *const u8).cast(), 1) };
    }

    /// The descriptor the host polls: readable when the drive has woken it.
    pub(crate) fn wake_fd(&self) -> RawFd {
        self.0.rx.as_raw_fd()
    }

    /// Empty the wake pipe (the host has seen the wake-up).
    pub(crate) fn drain_wake(&self) {
        let mut buf = [0u8; 64];
        // SAFETY: reads into a valid buffer from a non-blocking descriptor we own.
        while unsafe { libc::read(self.0.rx.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) } > 0 {
        }
    }

    /// How many times the drive's clock had to wait for the host's KEEPALIVE and woke it (a
    /// host that keeps its keepalive on this clock is woken about once per keepalive interval
    /// of drive time at most).
    pub fn wakes(&self) -> u64 {
        self.0.wakes.load(Ordering::Relaxed)
    }
}

/// `d` as the `timespec` of `ppoll` (the drive's and the host's waits on the pty).
pub(crate) fn timespec(d: std::time::Duration) -> libc::timespec {
    libc::timespec {
        tv_sec: d.as_secs() as libc::time_t,
        tv_nsec: d.subsec_nanos() as libc::c_long,
    }
}
