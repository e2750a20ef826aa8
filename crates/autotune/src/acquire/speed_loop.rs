//! A speed loop run (`fracid drive loop`): a controller downloaded to the drive, the reference 0
//! for `pre_s`, then a step.

use crate::realise::{self, StepFigures, StepSink};
use crate::Result;
use drive::client::{Acquisition, Client, LoopTest, RunInfo, SampleSink};
use drive::ctrl::FixedCtrl;
use drive::protocol::{Configure, StartLoop};
use serde::{Deserialize, Serialize};

/// The reference's step and the record's timing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopRequest {
    /// The reference step, rad/s.
    pub step_rad_s: f64,
    /// Time at reference 0 before the step, s.
    pub pre_s: f64,
    /// The whole record, s.
    pub duration_s: f64,
}

impl Default for LoopRequest {
    fn default() -> Self {
        Self {
            step_rad_s: 50.0,
            pre_s: 0.1,
            duration_s: 0.6,
        }
    }
}

impl LoopRequest {
    /// The START_LOOP for `conf`.
    ///
    /// # Errors
    /// Non-finite numbers; a step beyond the speed trip; times the drive cannot take.
    pub fn command(&self, conf: &Configure) -> Result<StartLoop> {
        if !(self.step_rad_s.is_finite() && self.duration_s.is_finite() && self.pre_s.is_finite()) {
            return crate::error::invalid("--step, --duration and --pre must be finite numbers");
        }
        Ok(LoopTest {
            step: self.step_rad_s,
            pre_s: self.pre_s,
            duration_s: self.duration_s,
        }
        .to_command(conf)?)
    }
}

/// A loop run as acquired.
#[derive(Debug, Clone)]
pub struct LoopRecord {
    /// The request.
    pub request: LoopRequest,
    /// The run.
    pub acquisition: Acquisition,
    /// The command run.
    pub command: StartLoop,
    /// The measured step's figures `(overshoot %, 10-90% rise s, 2% settling s)`, taken as the
    /// samples arrived (`None` without samples after the step).
    pub figures: Option<(f64, Option<f64>, Option<f64>)>,
}

/// A sink passing every sample to a borrowed one.
struct Fwd<'a>(&'a mut dyn SampleSink);

impl SampleSink for Fwd<'_> {
    fn begin(&mut self, info: &RunInfo) -> std::io::Result<()> {
        self.0.begin(info)
    }
    fn sample(&mut self, index: u64, t: f64, u: f64, y: f64, i: f64) -> std::io::Result<()> {
        self.0.sample(index, t, u, y, i)
    }
    fn finish(&mut self, acq: &Acquisition) -> std::io::Result<()> {
        self.0.finish(acq)
    }
}

/// Download `k` to the drive behind `client` (configured with `conf`) and run `req`, every
/// sample into `sink`.
///
/// # Errors
/// [`LoopRequest::command`]; the drive's errors (the download, the run).
pub fn run(
    client: &mut Client,
    conf: &Configure,
    k: &FixedCtrl,
    req: &LoopRequest,
    sink: &mut dyn SampleSink,
) -> Result<LoopRecord> {
    let command = req.command(conf)?;
    let mut watch = StepSink::new(Fwd(sink), command, conf.y_lsb(), conf.sample_rate_hz);
    let acquisition = realise::run_on(client, k, &command, &mut watch)?;
    let (_, step): (_, StepFigures) = watch.into_inner();
    Ok(LoopRecord {
        request: req.clone(),
        figures: step.figures(),
        acquisition,
        command,
    })
}
