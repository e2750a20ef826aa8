//! The faults the simulator injects on the line and in the drive, and their ranges.

use crate::error::{Error, Result};
use std::time::Duration;

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
    /// Disconnect: with [`SimConfig::link`](super::SimConfig::link) the pty is closed and a new one appears behind the
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
