//! `fracid.tune`: a fractional PI/PID (or integer PI/PID) designed on a model (the `tune` crate),
//! returned as the same JSON report as `fracid tune --json` (the Python wrapper parses it).

use crate::errors::{self, Kind};
use crate::tf::PyFracTf;
use fracsim::FracTf;
use pyo3::prelude::*;
use std::collections::HashMap;
use tune::closed::InputEffect;
use tune::report::SimOptions;
use tune::{GainBound, Spec};

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

/// Design, realise and simulate; the report as JSON text.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (model, wc, pm, form = "fopi", flat = false, dt = None, t_high = None, s_low = None, lambda_ = None, step = 1.0, load = None, effects = Vec::new(), mu = None, max_lambda = None, max_mu = None, max_ms = 2.0, min_gm = 6.0, min_lambda = 0.5))]
pub(crate) fn _tune(
    py: Python<'_>,
    model: Bound<'_, PyAny>,
    wc: f64,
    pm: f64,
    form: &str,
    flat: bool,
    dt: Option<f64>,
    t_high: Option<(f64, f64)>,
    s_low: Option<(f64, f64)>,
    lambda_: Option<f64>,
    step: f64,
    load: Option<f64>,
    effects: Vec<(String, HashMap<String, f64>)>,
    mu: Option<f64>,
    max_lambda: Option<f64>,
    max_mu: Option<f64>,
    max_ms: f64,
    min_gm: f64,
    min_lambda: f64,
) -> PyResult<String> {
    let g = model_of(&model)?;
    let bound = |b: Option<(f64, f64)>| b.map(|(omega, db)| GainBound { omega, db });
    let spec = Spec {
        form: form.parse().map_err(tune_err)?,
        wc,
        pm_deg: pm,
        flat,
        t_high: bound(t_high),
        s_low: bound(s_low),
        dt,
        lambda: lambda_,
        floors: tune::Floors {
            ms_max: max_ms,
            gm_min_db: min_gm,
            lambda_min: min_lambda,
        },
        orders: tune::Orders {
            mu,
            lambda_max: max_lambda,
            mu_max: max_mu,
        },
    };
    let mut fx = Vec::new();
    for (name, params) in &effects {
        if let Some(e) =
            InputEffect::from_report(name, |k| params.get(k).copied()).map_err(tune_err)?
        {
            fx.push(e);
        }
    }
    let opts = SimOptions {
        step: Some(step),
        load,
        effects: fx,
        u_limit: None,
    };
    let report = py
        .allow_threads(|| tune::report::tune(&g, &spec, &opts).map(|(r, _)| r))
        .map_err(tune_err)?;
    serde_json::to_string(&report).map_err(|e| errors::data(e.to_string()))
}
