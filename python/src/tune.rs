//! `fracid.tune`: a fractional PI/PID (or integer PI/PID) designed on a model (the `tune` crate),
//! returned as the same JSON report as `fracid tune --json` (the Python wrapper parses it).

use crate::errors::{self, Kind};
use crate::tf::PyFracTf;
use fracsim::FracTf;
use pyo3::prelude::*;
use std::collections::HashMap;
use tune::closed::InputEffect;
use tune::TuneRequest;

/// Map a design error: an impossible specification is `InfeasibleError`, a bad request
/// `DataError`, the simulator's errors as usual.
fn tune_err(e: tune::Error) -> PyErr {
    match e {
        tune::Error::Infeasible(_) => errors::error(Kind::Infeasible, e.to_string()),
        tune::Error::Sim(s) => errors::sim(s),
        _ => errors::data(e.to_string()),
    }
}

fn model_of(model: &Bound<'_, PyAny>) -> PyResult<FracTf> {
    if let Ok(m) = model.extract::<PyFracTf>() {
        return Ok(m.inner);
    }
    if let Ok(text) = model.extract::<String>() {
        return text.parse::<FracTf>().map_err(errors::sim);
    }
    Err(errors::data(
        "model must be a FracTf or a transfer function string",
    ))
}

/// Design, realise and simulate as `request` (a `tune::TuneRequest` as JSON: the fields left out
/// take the library's defaults, an unknown one is refused) asks, the model's input `effects`
/// simulated in the loop; the report as JSON text.
#[pyfunction]
#[pyo3(signature = (model, request, effects = Vec::new()))]
pub(crate) fn _tune(
    py: Python<'_>,
    model: Bound<'_, PyAny>,
    request: &str,
    effects: Vec<(String, HashMap<String, f64>, bool)>,
) -> PyResult<String> {
    let g = model_of(&model)?;
    let req: TuneRequest =
        serde_json::from_str(request).map_err(|e| errors::data(format!("tune request: {e}")))?;
    let mut fx = Vec::new();
    for (name, params, sampled) in &effects {
        if let Some(e) = InputEffect::from_report(name, |k| params.get(k).copied(), *sampled)
            .map_err(tune_err)?
        {
            fx.push(e);
        }
    }
    let report = py
        .allow_threads(|| tune::request::run(&g, &req, fx).map(|(r, _)| r))
        .map_err(tune_err)?;
    serde_json::to_string(&report).map_err(|e| errors::data(e.to_string()))
}
