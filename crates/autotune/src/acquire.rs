//! The drive acquisitions as requests: each a serde type with its defaults once (`Default`, and
//! missing fields when deserialised), checked against the drive's configuration before the drive
//! is asked anything, and one `run` on a configured [`drive::client::Client`] returning a typed
//! record. `fracid drive prbs/sine/loop` parse their flags into these requests and present the
//! records; the autotune ([`crate::tuner`]) builds them from what it measured.

pub mod prbs;
pub mod sine;
pub mod speed_loop;
pub mod step;

use crate::{Error, Result};
use drive::client::Acquisition;
use drive::protocol::Configure;

/// The voltage levels an experiment holds (raw units), against the drive's clamp: an error when
/// every level is beyond it (the drive would clamp the whole excitation away), a warning for each
/// level that is.
///
/// # Errors
/// [`Error::InvalidParam`] when every level is beyond the clamp.
pub fn check_levels(levels: &[(&str, i32)], conf: &Configure) -> Result<Vec<String>> {
    let lim = i32::from(conf.u_limit);
    let v = |raw: i32| raw as f64 * conf.u_lsb();
    let beyond: Vec<String> = levels
        .iter()
        .filter(|(_, raw)| raw.abs() > lim)
        .map(|(name, raw)| format!("{name} {} V", v(*raw)))
        .collect();
    if beyond.len() == levels.len() {
        return Err(Error::InvalidParam(format!(
            "every level of the excitation ({}) is beyond the drive's voltage clamp of +-{} V \
             (--u-limit): the drive would hold the clamp and nothing would be excited",
            beyond.join(", "),
            v(lim)
        )));
    }
    Ok(if beyond.is_empty() {
        vec![]
    } else {
        vec![format!(
            "{} beyond the drive's voltage clamp of +-{} V: those samples will be clamped",
            beyond.join(", "),
            v(lim)
        )]
    })
}

/// The samples of an acquisition as an identification record (`t, u, y`), from sample `from`.
///
/// # Errors
/// [`Error::Experiment`] for a run with gaps (the record would not be uniform) or too few samples.
pub fn record_of(acq: &Acquisition, from: usize) -> Result<ident::data::Record> {
    if !acq.complete || !acq.missing.is_empty() {
        return Err(Error::Experiment(format!(
            "the run is incomplete ({}): a record with gaps cannot be identified",
            acq.problems.join("; ")
        )));
    }
    let n = acq.t.len();
    if from + 10 > n {
        return Err(Error::Experiment(format!(
            "the run has {n} samples: too few to identify"
        )));
    }
    let dt = 1.0 / acq.sample_rate_hz as f64;
    Ok(ident::data::Record::from_samples(
        &acq.u[from..],
        &acq.y[from..],
        dt,
    )?)
}
