//! A model scored on a separate record of the same plant: the report of [`crate::oe::score`]
//! (the time use case's `fit.validation_file`, `fracid score`), which the verdict reads
//! ([`super::verdict`]).

use crate::oe::{ParamEstimate, Scored};
use serde::Serialize;

/// A model scored on a separate record (`fit.validation_file`).
#[derive(Debug, Clone, Serialize)]
pub struct ScoreReport {
    /// The record's name.
    pub file: String,
    /// RMSE over the whole record.
    pub rmse: f64,
    /// NRMSE fit (%) over the whole record.
    pub nrmse_percent: f64,
    /// The record's operating point.
    pub offsets: crate::data::Offsets,
    /// The record's own output offset and initial-state levels.
    pub record_params: Vec<ParamEstimate>,
    /// Caveats of the score.
    pub warnings: Vec<String>,
}

impl ScoreReport {
    /// The report of `sc` on the record named `file`.
    pub fn new(file: &str, sc: &Scored) -> Self {
        Self {
            file: file.to_string(),
            rmse: sc.fit.rmse,
            nrmse_percent: sc.fit.nrmse_percent,
            offsets: sc.offsets,
            record_params: sc.record_params.clone(),
            warnings: sc.warnings.clone(),
        }
    }
}
