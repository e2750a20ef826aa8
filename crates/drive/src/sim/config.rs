//! The simulator's configuration: the firmware behind the line, the clock, the motor model.

use super::{Effects, Faults};
use std::path::PathBuf;
use std::time::Duration;

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
    ///   ([`DriveSim::virtual_clock`](super::DriveSim::virtual_clock), [`crate::client::ClientConfig::clock`]) keeps its keepalive
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
    /// The paper's motor, 115200 baud, no effects, no faults, the Rust firmware, real time. Nothing
    /// here depends on the environment: a caller that wants the C firmware sets
    /// [`SimConfig::firmware`].
    fn default() -> Self {
        Self {
            firmware: FirmwareKind::Rust,
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
