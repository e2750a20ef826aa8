//! Score a given model on a record it was not fitted on (MATLAB's `compare`): the plant's
//! parameters are held, the record's own initial state, output offset and output drift are
//! estimated (they belong to the record, not to the plant), and the simulated output is compared
//! with the measured.

use super::fit::{fit, past_edges, FitOptions, InitialState, ParamEstimate};
use super::{FracModel, Structure};
use crate::data::{OffsetMode, Offsets, Record};
use crate::metrics::Fit;
use crate::{Error, Result};

/// A model scored on a record ([`score`]).
#[derive(Debug, Clone)]
pub struct Scored {
    /// The fit over the whole record.
    pub fit: Fit,
    /// The model output on the absolute scale.
    pub yhat: Vec<f64>,
    /// The record's operating point.
    pub offsets: Offsets,
    /// The record's own output offset, drift and initial-state levels (fitted; `at_bound` marks
    /// a level at the edge of its range, also said in the warnings).
    pub record_params: Vec<ParamEstimate>,
    /// Warnings (an input with no excitation: the score says little about the dynamics).
    pub warnings: Vec<String>,
}

/// Score `model` (its parameter values as they are) on `rec`: the operating point by `offsets`,
/// then the record's output offset and drift (when the model has them) and, with
/// [`InitialState::Estimate`], its initial state as a past held input, fitted with everything
/// else held; the fit (RMSE, NRMSE) over the whole record.
///
/// ```
/// use ident::data::{OffsetMode, Record};
/// use ident::oe::{score, FracModel, InitialState, Structure};
/// let m = FracModel::commensurate(2.0, 0.05, 1e-3, 0.8);
/// let u: Vec<f64> = (0..400).map(|k| if (k / 25) % 2 == 0 { 1.0 } else { -1.0 }).collect();
/// let mut y = vec![0.0; u.len()];
/// m.simulate(&m.values(), &u, 1e-3, &mut y).unwrap();
/// let rec = Record::from_samples(&u, &y, 1e-3).unwrap();
/// let s = score(&m, &rec, OffsetMode::None, InitialState::Estimate).unwrap();
/// assert!(s.fit.nrmse_percent > 99.99);
/// ```
///
/// # Errors
/// [`Error::NotEnoughData`] for a record shorter than 20 samples; errors of the simulation;
/// [`Error::Numerical`] when the model's output or its error is not finite (a model whose
/// output overflows on this record).
pub fn score(
    model: &FracModel,
    rec: &Record,
    offsets: OffsetMode,
    initial: InitialState,
) -> Result<Scored> {
    let n = rec.len();
    if n < 20 {
        return Err(Error::NotEnoughData(format!(
            "{n} samples: at least 20 are needed to score a model"
        )));
    }
    let mut m = model.clone();
    for p in &mut m.params {
        p.free = false;
    }
    let op = rec.offsets(offsets, n);
    m.operating_point = op;
    // The record's own: its sensor's offset and drift are not the plant's.
    for name in ["y_offset", "y_drift"] {
        if let Some(i) = m.index_of(name) {
            m.params[i].value = 0.0;
            m.params[i].free = true;
        }
    }
    // scored from the state it is fitted from (`identify`)
    let initial = initial.resolve(rec, offsets);
    match initial {
        InitialState::Estimate => {
            m.with_past_input(
                past_edges(n as f64 * rec.dt),
                super::past_range(&rec.u, op.u0),
            );
            for &i in &m
                .past
                .as_ref()
                .map(|p| p.levels.clone())
                .unwrap_or_default()
            {
                m.params[i].free = true;
            }
        }
        InitialState::Rest | InitialState::Auto => m.past = None,
    }
    let u: Vec<f64> = rec.u.iter().map(|v| v - op.u0).collect();
    let y: Vec<f64> = rec.y.iter().map(|v| v - op.y0).collect();
    let mut values = m.values();
    let mut warnings = vec![];
    let mut record_params = vec![];
    if m.params.iter().any(|p| p.free) {
        let rep = fit(&m, &u, &y, rec.dt, &FitOptions::default())?;
        values = rep.values;
        record_params = rep.params.into_iter().filter(|p| p.free).collect();
        warnings.extend(super::checks::levels_at_bound(&m, &record_params));
    }
    let mut yd = vec![0.0; n];
    m.simulate(&values, &u, rec.dt, &mut yd)?;
    let yhat: Vec<f64> = yd.iter().map(|v| v + op.y0).collect();
    if rec.check_excitation(n).is_err() {
        warnings.push(
            "the input is constant over this record: the score says nothing about the dynamics"
                .into(),
        );
    }
    let fit_all = Fit::of(&rec.y, &yhat);
    if !(fit_all.rmse.is_finite() && yhat.iter().all(|v| v.is_finite())) {
        // 1e300/(s+1): an output (or its error) beyond the range of f64 is no score.
        return Err(Error::Numerical(format!(
            "the model's output on this record is out of the range of 64-bit numbers (RMSE \
             {}): are its coefficients in the units of the data?",
            fit_all.rmse
        )));
    }
    Ok(Scored {
        fit: fit_all,
        yhat,
        offsets: op,
        record_params,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::{Bounds, Effect, Param};

    /// A model with an output offset and drift, scored on a record whose sensor has its own: the
    /// record's are fitted (the plant's held), and the score is the noise-free record's.
    #[test]
    fn a_record_is_scored_with_its_own_offset_and_drift() {
        let mut m = FracModel::commensurate(2.0, 0.05, 1e-3, 0.8);
        let c = m.add_param(Param::new("y_offset", 0.3, Bounds::Free));
        m.effects.push(Effect::OutputOffset { c });
        let r = m.add_param(Param::new("y_drift", 0.5, Bounds::Free));
        m.effects.push(Effect::OutputDrift { r });
        let u: Vec<f64> = (0..600)
            .map(|k| if (k / 40) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let dt = 1e-3;
        let mut other = m.values();
        (other[c], other[r]) = (-0.2, -1.5);
        let mut y = vec![0.0; u.len()];
        m.simulate(&other, &u, dt, &mut y).unwrap();
        let rec = Record::from_samples(&u, &y, dt).unwrap();
        let s = score(&m, &rec, OffsetMode::None, InitialState::Rest).unwrap();
        assert!(s.fit.nrmse_percent > 99.99, "{:?}", s.fit);
        let drift = s
            .record_params
            .iter()
            .find(|p| p.name == "y_drift")
            .unwrap();
        assert!((drift.value + 1.5).abs() < 1e-6, "{drift:?}");
    }
}
