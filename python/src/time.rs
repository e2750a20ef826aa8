//! The time-domain output-error fit (Levenberg-Marquardt with exact sensitivities):
//! `fracid._fracid._fit_time`, wrapped by `fracid.fit_time` in Python.

use crate::arrays::{floats, positive, same_len, FloatArray};
use crate::errors;
use crate::tf::{approx_spec, PyFracTf};
use ident::data::Record;
use ident::diagnose::{DiagnoseOptions, Diagnosis};
use ident::metrics::{residual_test, Fit};
use ident::oe::{identify, FracModel, IdentOptions, StartMode};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::collections::HashMap;

fn fit_dict<'py>(py: Python<'py>, f: &Fit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rmse", f.rmse)?;
    d.set_item("nrmse_percent", f.nrmse_percent)?;
    Ok(d)
}

/// The model to fit: a named structure ([`ident::app::structure`], the CLI's presets) or a
/// `FracTf` whose coefficients and orders are all fitted.
fn structure_of(s: &Bound<'_, PyAny>, duration: f64) -> PyResult<(FracModel, bool)> {
    if let Ok(tf) = s.downcast::<PyFracTf>() {
        return Ok((FracModel::from_tf(&tf.get().inner, true, true), true));
    }
    if let Ok(name) = s.downcast::<PyString>() {
        let name = name.to_cow()?;
        return ident::app::structure(&name, ident::app::default_max_delay(duration))
            .map_err(errors::ident);
    }
    Err(errors::data(
        "structure must be 'pmsm', 'commensurate', 'second-order', 'third-order', 'two-mass', \
         'fopdt', 'auto', a model string or a FracTf",
    ))
}

/// Output-error identification on sampled `u`, `y`; returns a dict the Python layer turns into
/// `TimeFit`.
#[pyfunction]
#[pyo3(signature = (u, y, dt, structure, start = None, holdout = 0.3, offsets = "initial", fit_offset = true, max_iterations = 500, skip = 0, initial = "estimate", method = "refined", band = None, order = 8, max_lag = 25, diagnose = false, margin = 0.05, min_r2 = 0.005, max_rounds = 3))]
pub(crate) fn _fit_time<'py>(
    py: Python<'py>,
    u: FloatArray<'py>,
    y: FloatArray<'py>,
    dt: f64,
    structure: Bound<'py, PyAny>,
    start: Option<HashMap<String, f64>>,
    holdout: f64,
    offsets: &str,
    fit_offset: bool,
    max_iterations: usize,
    skip: usize,
    initial: &str,
    method: &str,
    band: Option<(f64, f64)>,
    order: usize,
    max_lag: usize,
    diagnose: bool,
    margin: f64,
    min_r2: f64,
    max_rounds: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let u = floats("u", &u, 2)?;
    let y = floats("y", &y, 2)?;
    same_len(("u", u.len()), ("y", y.len()))?;
    let dt = positive("dt", dt)?;
    if max_iterations == 0 {
        return Err(errors::data("max_iterations must be at least 1"));
    }
    if skip >= u.len() {
        return Err(errors::data(format!(
            "skip = {skip} leaves no sample of {}",
            u.len()
        )));
    }
    let offsets = ident::app::offsets(offsets).map_err(errors::ident)?;
    let initial: ident::oe::InitialState = initial.parse().map_err(errors::ident)?;
    let (mut model, general) = structure_of(&structure, dt * u.len() as f64)?;
    model.approx = approx_spec(method, band, order)?;
    let mode = if general || start.is_some() {
        StartMode::Given
    } else {
        StartMode::Auto
    };
    if let Some(start) = &start {
        for (name, v) in start {
            let Some(i) = model.index_of(name) else {
                let names: Vec<&str> = model.params.iter().map(|p| p.name.as_str()).collect();
                return Err(errors::data(format!(
                    "start: no parameter '{name}' (the model has {})",
                    names.join(", ")
                )));
            };
            if !v.is_finite() {
                return Err(errors::data(format!("start: {name} = {v} must be finite")));
            }
            model.params[i].value = *v;
        }
        ident::oe::check_params(&model.params).map_err(errors::ident)?;
    }
    let mut opts = IdentOptions {
        offsets,
        holdout,
        fit_offset,
        start: mode,
        initial,
        ..IdentOptions::default()
    };
    opts.fit.lm.max_iterations = max_iterations;
    opts.fit.skip = skip;
    let rec = Record::from_samples(&u, &y, dt).map_err(errors::ident)?;
    let dopts = DiagnoseOptions {
        margin,
        min_r2,
        max_rounds,
        ..DiagnoseOptions::default()
    };
    let label = structure
        .extract::<String>()
        .unwrap_or_else(|_| "the given model".to_string());
    // `auto`: the structure the data support (the CLI's --structure auto); with the diagnosis
    // the comparison is the diagnosis's own, from the PMSM.
    let (auto, label) = ident::app::auto_label(&label);
    let (id, rt, diag, auto_choice) = py
        .allow_threads(|| {
            let (id, auto_choice) = if auto && !diagnose {
                let (id, c) = ident::diagnose::structures::fit_best(&rec, &model, &opts)?;
                (id, Some(c))
            } else {
                (identify(&rec, &model, &opts)?, None)
            };
            // The diagnosis compares the structures and runs on the chosen one, which is then
            // the fit reported.
            let (id, diag) = if diagnose {
                let d = ident::diagnose::structures::diagnose_best(
                    &rec, label, &model, id, &opts, &dopts,
                )?;
                (d.id, Some((d.diagnosis, d.choice)))
            } else {
                (id, None)
            };
            let split = id.split;
            let e: Vec<f64> = rec.y[..split]
                .iter()
                .zip(&id.yhat[..split])
                .map(|(a, b)| a - b)
                .collect();
            let ud: Vec<f64> = rec.u[..split].iter().map(|v| v - id.offsets.u0).collect();
            let rt = residual_test(&e, &ud, max_lag.min(split.saturating_sub(1)));
            Ok::<_, ident::Error>((id, rt, diag, auto_choice))
        })
        .map_err(errors::ident)?;

    let d = PyDict::new(py);
    d.set_item("model", PyFracTf::from(id.tf.clone()))?;
    let params = pyo3::types::PyList::empty(py);
    for p in &id.report.params {
        let e = PyDict::new(py);
        e.set_item("name", &p.name)?;
        e.set_item("value", p.value)?;
        e.set_item("std_error", p.std_error)?;
        e.set_item("free", p.free)?;
        e.set_item("at_bound", p.at_bound)?;
        params.append(e)?;
    }
    d.set_item("params", params)?;
    d.set_item("estimation", fit_dict(py, &id.estimation)?)?;
    match &id.validation {
        Some(v) => d.set_item("validation", fit_dict(py, v)?)?,
        None => d.set_item("validation", py.None())?,
    }
    d.set_item("yhat", id.yhat.clone().into_pyarray(py))?;
    d.set_item("split", id.split)?;
    let vb = PyDict::new(py);
    let kind = serde_json::to_value(id.validated_by.kind)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("validation kind: {e}")))?;
    vb.set_item("kind", kind.as_str().unwrap_or(""))?;
    vb.set_item("first", id.validated_by.first)?;
    vb.set_item("note", &id.validated_by.note)?;
    d.set_item("validated_by", vb)?;
    let off = PyDict::new(py);
    off.set_item("u0", id.offsets.u0)?;
    off.set_item("y0", id.offsets.y0)?;
    d.set_item("offsets", off)?;
    d.set_item("converged", id.report.converged)?;
    d.set_item("termination", format!("{:?}", id.report.termination))?;
    d.set_item("stop_reason", id.report.stop_reason())?;
    d.set_item("iterations", id.report.iterations)?;
    d.set_item("evaluations", id.report.evaluations)?;
    d.set_item("elapsed_s", id.report.elapsed.as_secs_f64())?;
    d.set_item("warnings", id.report.warnings.clone())?;
    d.set_item("usable", id.usable())?;
    d.set_item("problems", id.problems.clone())?;
    d.set_item("alpha_eta", id.alpha_eta.clone())?;
    let st = PyDict::new(py);
    for (p, v) in id.model.params.iter().zip(&id.start) {
        st.set_item(&p.name, v)?;
    }
    d.set_item("start", st)?;
    let r = PyDict::new(py);
    r.set_item("bound", rt.bound)?;
    r.set_item("auto_outside", rt.auto_outside)?;
    r.set_item("cross_outside", rt.cross_outside)?;
    r.set_item("cross_peak_lag", rt.cross_peak_lag)?;
    r.set_item("cross_peak", rt.cross_peak)?;
    d.set_item("residual_test", r)?;
    match diag {
        Some((g, c)) => {
            let dd = diagnosis_dict(py, &g)?;
            let text = serde_json::to_string(&c)
                .map_err(|e| errors::error(errors::Kind::Numerical, format!("structures: {e}")))?;
            dd.set_item(
                "structures",
                py.import("json")?.call_method1("loads", (text,))?,
            )?;
            d.set_item("diagnosis", dd)?
        }
        None => d.set_item("diagnosis", py.None())?,
    }
    match auto_choice {
        Some(c) => {
            let text = serde_json::to_string(&c)
                .map_err(|e| errors::error(errors::Kind::Numerical, format!("structures: {e}")))?;
            d.set_item(
                "structures",
                py.import("json")?.call_method1("loads", (text,))?,
            )?
        }
        None => d.set_item("structures", py.None())?,
    }
    Ok(d)
}

/// The diagnosis as a dict: its serde form (the docs/design.md §7 `diagnosis` object and more), the final
/// linear model and the model outputs before and after.
fn diagnosis_dict<'py>(py: Python<'py>, g: &Diagnosis) -> PyResult<Bound<'py, PyDict>> {
    let text = serde_json::to_string(g)
        .map_err(|e| errors::error(errors::Kind::Numerical, format!("diagnosis: {e}")))?;
    let d = py
        .import("json")?
        .call_method1("loads", (text,))?
        .downcast_into::<PyDict>()?;
    let values = g.model.values();
    d.set_item(
        "model",
        PyFracTf::from(g.model.tf(&values).map_err(errors::ident)?),
    )?;
    let names: Vec<&str> = g.model.params.iter().map(|p| p.name.as_str()).collect();
    let pv = PyDict::new(py);
    for (n, v) in names.iter().zip(&values) {
        pv.set_item(*n, v)?;
    }
    d.set_item("params", pv)?;
    d.set_item("yhat_before", g.yhat_before.clone().into_pyarray(py))?;
    d.set_item("yhat_after", g.yhat_after.clone().into_pyarray(py))?;
    d.set_item("split", g.split)?;
    Ok(d)
}
