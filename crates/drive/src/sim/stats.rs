//! The simulator's counters and ground truth.

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
    /// Answers deliberately lost by [`DriveSim::lose_next_answer`](super::DriveSim::lose_next_answer).
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
