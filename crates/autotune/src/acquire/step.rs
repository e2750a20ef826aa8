//! A voltage step from rest: the drive's PRBS run reduced to its settling part (the level held
//! from the first sample, no PRBS after it worth the name: three samples at the same level).

use crate::error::invalid;
use crate::Result;
use drive::client::{Acquisition, Client, PrbsTest, SampleSink};
use drive::protocol::Configure;
use serde::{Deserialize, Serialize};

/// A step of the voltage from 0 (the drive at rest) to `level_v`, held `duration_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StepRequest {
    /// The level, V.
    pub level_v: f64,
    /// How long it is held (the record), s.
    pub duration_s: f64,
}

impl Default for StepRequest {
    fn default() -> Self {
        Self {
            level_v: 1.0,
            duration_s: 0.5,
        }
    }
}

impl StepRequest {
    /// The drive's test: the level as the PRBS's operating point, held `duration_s`, then one
    /// period of an order-2 PRBS of amplitude 0 (three samples at the level).
    ///
    /// # Errors
    /// A non-finite level or duration, or one the drive cannot take.
    pub fn test(&self, conf: &Configure) -> Result<PrbsTest> {
        if !(self.level_v.is_finite() && self.duration_s.is_finite() && self.duration_s > 0.0) {
            return invalid(format!(
                "a step needs a finite level and a positive duration, got {} V for {} s",
                self.level_v, self.duration_s
            ));
        }
        let t = PrbsTest {
            order: 2,
            seed: 1,
            clock_s: 1.0 / conf.sample_rate_hz as f64,
            amplitude_v: 0.0,
            offset_v: self.level_v,
            periods: 1,
            settle_s: self.duration_s,
        };
        let cmd = t.to_command(conf)?;
        super::check_levels(&[("level", i32::from(cmd.offset))], conf)?;
        Ok(t)
    }
}

/// A step as acquired.
#[derive(Debug, Clone)]
pub struct StepRecord {
    /// The request.
    pub request: StepRequest,
    /// The run; its first `samples` samples are the step.
    pub acquisition: Acquisition,
    /// Samples of the step (the settling part).
    pub samples: usize,
}

impl StepRecord {
    /// The step's time (s), input (V) and speed (rad/s) samples.
    pub fn series(&self) -> (&[f64], &[f64], &[f64]) {
        let a = &self.acquisition;
        let n = self.samples.min(a.t.len());
        (&a.t[..n], &a.u[..n], &a.y[..n])
    }
}

/// Run `req` on the drive behind `client`, configured with `conf`.
///
/// # Errors
/// [`StepRequest::test`]; the drive's errors.
pub fn run(
    client: &mut Client,
    conf: &Configure,
    req: &StepRequest,
    sink: &mut dyn SampleSink,
) -> Result<StepRecord> {
    let test = req.test(conf)?;
    let acquisition = client.run_prbs(&test, sink)?;
    Ok(StepRecord {
        request: req.clone(),
        samples: (req.duration_s * conf.sample_rate_hz as f64).round() as usize,
        acquisition,
    })
}
