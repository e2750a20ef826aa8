//! `fracid drive autotune`: one request, one [`run`], one typed [`report::AutotuneReport`].
//!
//! 1. A probe: a small voltage step from rest, raised until the speed stands out of the noise,
//!    lengthened until it settles ([`probe`]): the gain, the time constant, the delay.
//! 2. The identification PRBS designed from it ([`design::identification`]: its clock for the
//!    band, its period for the settling time, the operating point and the amplitude within the
//!    limits), acquired, identified and diagnosed ([`rounds::first`]).
//! 3. For each ambiguity the diagnosis names, the experiment that separates it (speed reversals
//!    for friction against an input offset, a slow sine of many levels for a static map), for a
//!    resonance of the model a sine dwell around it, for a probe that did not settle a longer
//!    record: acquired, diagnosed alone, and one model fitted jointly to all records
//!    ([`rounds::later`]), each record's error before and after.
//! 4. A FOPI tuned on the final model ([`control`]: the crossover from its bandwidth, delay, the
//!    sample rate; for a resonance a notch in the controller, or a crossover a fifth of it;
//!    lower when the tuner refuses), run on the drive, its step measured beside the tuner's
//!    prediction.
//!
//! The drive's voltage clamp and speed trip are set to the request's limits, and every design
//! stays within [`design::LIMIT_SHARE`] of them; the drive is stopped on every way out.

pub mod control;
pub mod design;
pub mod probe;
pub mod report;
pub mod rounds;
mod steps;

use crate::{Error, Result};
use drive::client::Client;
use serde::{Deserialize, Serialize};

/// Every option of the autotune, with its default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutotuneRequest {
    /// The voltage limit, V (the drive's clamp; the designs stay within 80% of it).
    pub u_limit_v: f64,
    /// The speed limit, rad/s (the drive's speed trip; the designs aim below 80% of it).
    pub speed_limit_rad_s: f64,
    /// The drive time all experiments may take, s.
    pub budget_s: f64,
    /// The crossover, rad/s (`None`: chosen from the model).
    pub wc: Option<f64>,
    /// The phase margin, deg (`None`: 60).
    pub pm_deg: Option<f64>,
    /// The identification's operating point, V (`None`: half the voltage the speed limit allows).
    pub operating_point_v: Option<f64>,
    /// Rounds after the first (experiments that separate ambiguities).
    pub max_rounds: usize,
    /// The PRBS seed.
    pub seed: u32,
    /// What the controller does about a resonance of the final model.
    pub filter: FilterChoice,
}

/// What the controller does about a resonance of the final model (none found: nothing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FilterChoice {
    /// A notch at the resonance, the crossover then set by the delay, the sample rate and the
    /// bandwidth; the lower crossover with no filter when the tuner refuses every crossover
    /// with the notch, or when the notch's loop is not faster.
    #[default]
    Auto,
    /// A notch at the resonance ([`tune::filter::Filter::Notch`]).
    Notch,
    /// A first-order low-pass at half the resonance.
    LowPass,
    /// No filter: the crossover a fifth of the resonance.
    None,
}

impl Default for AutotuneRequest {
    fn default() -> Self {
        Self {
            u_limit_v: 12.0,
            speed_limit_rad_s: 200.0,
            budget_s: 20.0,
            wc: None,
            pm_deg: None,
            operating_point_v: None,
            max_rounds: 3,
            seed: 1,
            filter: FilterChoice::Auto,
        }
    }
}

impl AutotuneRequest {
    /// Check the request.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a limit, budget, crossover or margin out of range.
    pub fn check(&self) -> Result<()> {
        if !(self.u_limit_v > 0.0 && self.u_limit_v <= 32.767) {
            return crate::error::invalid(format!(
                "--u-limit must be in (0, 32.767] V, got {}",
                self.u_limit_v
            ));
        }
        if !(self.speed_limit_rad_s > 0.0 && self.speed_limit_rad_s <= 327.67) {
            return crate::error::invalid(format!(
                "--speed-limit must be in (0, 327.67] rad/s (the speed channel), got {}",
                self.speed_limit_rad_s
            ));
        }
        if !(self.budget_s.is_finite() && self.budget_s >= 1.0) {
            return crate::error::invalid(format!(
                "--budget must be at least 1 s of drive time, got {}",
                self.budget_s
            ));
        }
        if self.wc.is_some_and(|w| !(w.is_finite() && w > 0.0)) {
            return crate::error::invalid("--wc must be a positive number of rad/s");
        }
        if self.pm_deg.is_some_and(|p| !(p > 0.0 && p < 90.0)) {
            return crate::error::invalid("--pm must be in (0, 90) degrees");
        }
        if self
            .operating_point_v
            .is_some_and(|v| !(v.is_finite() && v.abs() < self.u_limit_v))
        {
            return crate::error::invalid("--operating-point must be within --u-limit");
        }
        Ok(())
    }
}

/// What a caller sees of a run, and how it stops one.
pub trait Observe {
    /// A stage starts (in words).
    fn stage(&mut self, _what: &str) {}
    /// Whether the user asked to stop (checked between experiments; a run in progress is stopped
    /// by the client's [`drive::client::StopHandle`]).
    fn cancelled(&self) -> bool {
        false
    }
}

/// The observer that shows nothing and never cancels.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;

impl Observe for Quiet {}

/// Run the autotune on the drive behind `client` at `sample_rate_hz`: it configures the drive
/// with the request's limits, runs the experiments, and stops the drive on every way out.
///
/// A run that ends without a usable controller (an experiment unusable, the tuner refusing
/// every crossover, the loop oscillating) returns its report with `usable: false` and the
/// reasons.
///
/// # Errors
/// [`Error::InvalidParam`] for a bad request; the drive's errors; [`Error::Interrupted`] when
/// the observer cancels.
pub fn run(
    client: &mut Client,
    sample_rate_hz: u32,
    req: &AutotuneRequest,
    obs: &mut dyn Observe,
) -> Result<report::AutotuneReport> {
    req.check()?;
    let out = steps::Run::new(client, sample_rate_hz, req)
        .and_then(|mut r| r.all(obs).map(|()| r.finish()));
    // the drive stopped whatever happened (the runs end on their own; this ends any left)
    let _ = client.stop();
    match out {
        Err(Error::Drive(e)) if obs.cancelled() => Err(Error::Interrupted(e.to_string())),
        out => out,
    }
}
