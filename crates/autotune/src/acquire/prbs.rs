//! A PRBS experiment (`fracid drive prbs`): the request, its check and its run.

use crate::Result;
use drive::client::{Acquisition, Client, PrbsTest, SampleSink};
use drive::protocol::{Configure, StartPrbs};
use serde::{Deserialize, Serialize};

/// A PRBS around an operating point, after a settling time at it (recorded).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrbsRequest {
    /// LFSR order (2..=16): period `2^order - 1` bits.
    pub order: u8,
    /// LFSR seed (nonzero).
    pub seed: u32,
    /// Bit duration, s (a whole number of samples).
    pub clock_s: f64,
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// Operating point, V.
    pub offset_v: f64,
    /// Number of periods.
    pub periods: u16,
    /// Time at the operating point before the PRBS, s (recorded).
    pub settle_s: f64,
}

impl Default for PrbsRequest {
    /// The paper's experiment: order 7, 3 ms clock, one period, 1 V around 6 V after 0.3 s.
    fn default() -> Self {
        let p = PrbsTest::paper();
        Self {
            order: p.order,
            seed: p.seed,
            clock_s: p.clock_s,
            amplitude_v: p.amplitude_v,
            offset_v: p.offset_v,
            periods: p.periods,
            settle_s: p.settle_s,
        }
    }
}

impl PrbsRequest {
    /// The client's test.
    pub fn test(&self) -> PrbsTest {
        PrbsTest {
            order: self.order,
            seed: self.seed,
            clock_s: self.clock_s,
            amplitude_v: self.amplitude_v,
            offset_v: self.offset_v,
            periods: self.periods,
            settle_s: self.settle_s,
        }
    }

    /// The START_PRBS for `conf`, and the warnings of its levels (some beyond the clamp).
    ///
    /// # Errors
    /// [`crate::Error::InvalidParam`]: a settling time or periods out of range, a command the drive
    /// cannot take, every level beyond the clamp.
    pub fn check(&self, conf: &Configure) -> Result<(StartPrbs, Vec<String>)> {
        if !(self.settle_s.is_finite() && self.settle_s >= 0.0) {
            return crate::error::invalid("--settle must be a finite number of seconds >= 0");
        }
        if self.periods == 0 {
            return crate::error::invalid("--periods must be at least 1");
        }
        let cmd = self.test().to_command(conf)?;
        let (off, amp) = (i32::from(cmd.offset), i32::from(cmd.amplitude));
        let warnings =
            super::check_levels(&[("high level", off + amp), ("low level", off - amp)], conf)?;
        Ok((cmd, warnings))
    }
}

/// A PRBS run as acquired.
#[derive(Debug, Clone)]
pub struct PrbsRecord {
    /// The request.
    pub request: PrbsRequest,
    /// The run (samples kept as the client's retention says).
    pub acquisition: Acquisition,
    /// Caveats: the levels', then the run's.
    pub warnings: Vec<String>,
    /// The input is constant after the settling part (nothing was excited).
    pub excitation_missing: bool,
}

/// Run `req` on the drive behind `client`, configured with `conf`, every sample into `sink`.
///
/// # Errors
/// [`PrbsRequest::check`]; the drive's errors.
pub fn run(
    client: &mut Client,
    conf: &Configure,
    req: &PrbsRequest,
    sink: &mut dyn SampleSink,
) -> Result<PrbsRecord> {
    let (_, mut warnings) = req.check(conf)?;
    let acquisition = client.run_prbs(&req.test(), sink)?;
    warnings.extend(acquisition.warnings());
    Ok(PrbsRecord {
        request: req.clone(),
        excitation_missing: acquisition.excitation_missing(),
        acquisition,
        warnings,
    })
}
