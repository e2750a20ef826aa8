//! The time-domain output-error fit (Levenberg-Marquardt with exact sensitivities):
//! `fracid._fracid._fit_time`, wrapped by `fracid.fit_time` in Python: the same use case
//! (`ident::app::time`) and report as `fracid time`.

use crate::arrays::{floats, positive, same_len, FloatArray};
use crate::errors;
use ident::app::observe::Observe;
use ident::app::time::{Named, TimeData, TimeRequest};
use ident::data::Record;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A serde value as the Python object `json.loads` makes of it (the same fields as the CLI's
/// JSON).
pub(crate) fn to_py<'py, T: serde_core::Serialize>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v)
        .map_err(|e| errors::error(errors::Kind::Numerical, format!("report: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// The defaults of the time-domain request (`ident::app::time::TimeRequest::default()`), as
/// `fracid time`'s flags and `fracid.fit_time`'s keywords take them.
#[pyfunction]
pub(crate) fn _time_request_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_py(py, &TimeRequest::default())
}

/// The catalogue of named structures (`ident::catalogue::Preset`): `(name, formula)` in its
/// order, as `structure=` takes the names and the reports print them.
#[pyfunction]
pub(crate) fn _structures() -> Vec<(&'static str, &'static str)> {
    ident::catalogue::Preset::ALL
        .iter()
        .map(|p| (p.name(), p.formula()))
        .collect()
}

/// The observer of a fit run from Python: between stages it runs Python's signal handlers (the
/// GIL taken for that moment), so Ctrl-C stops a long diagnosis at the next stage.
pub(crate) struct Interruptible;

impl Observe for Interruptible {
    fn cancelled(&self) -> bool {
        Python::with_gil(|py| match py.check_signals() {
            Ok(()) => false,
            Err(e) => {
                e.restore(py);
                true
            }
        })
    }
}

/// A record `(u, y)` at `dt` named `name`.
fn named(name: String, (u, y): (FloatArray<'_>, FloatArray<'_>), dt: f64) -> PyResult<Named> {
    let u = floats(&format!("{name} u"), &u, 2)?;
    let y = floats(&format!("{name} y"), &y, 2)?;
    same_len(
        (&format!("{name} u"), u.len()),
        (&format!("{name} y"), y.len()),
    )?;
    Ok(Named {
        record: Record::from_samples(&u, &y, dt).map_err(errors::ident)?,
        name,
    })
}

/// One model fitted to several records (`ident::app::time::run_joint`, as `fracid time
/// --joint`): `joint` the further records `(u, y)` at the same `dt`. Returns the report as
/// `fracid time --joint --json` prints it.
#[pyfunction]
#[pyo3(signature = (u, y, dt, request, joint, validation = None))]
pub(crate) fn _fit_time_joint<'py>(
    py: Python<'py>,
    u: FloatArray<'py>,
    y: FloatArray<'py>,
    dt: f64,
    request: &str,
    joint: Vec<(FloatArray<'py>, FloatArray<'py>)>,
    validation: Option<(FloatArray<'py>, FloatArray<'py>)>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut data = time_data(u, y, dt, validation)?;
    data.joint = joint
        .into_iter()
        .enumerate()
        .map(|(i, r)| named(format!("joint[{i}]"), r, dt))
        .collect::<PyResult<_>>()?;
    let req = request_of(request)?;
    let r = py
        .allow_threads(|| ident::app::time::run_joint(&req, &data, "record", &mut Interruptible))
        .map_err(|e| interrupted(py, e))?;
    to_py(py, &r)
}

/// The request `fracid.time_request` wrote: its words read into the library's types here, once (a
/// word a type does not take is a `DataError` with the library's message; the position in the
/// JSON, which the user never wrote, left out).
fn request_of(text: &str) -> PyResult<TimeRequest> {
    serde_json::from_str(text).map_err(|e| {
        let msg = e.to_string();
        let at = format!(" at line {} column {}", e.line(), e.column());
        errors::data(format!(
            "options: {}",
            msg.strip_suffix(&at).unwrap_or(&msg)
        ))
    })
}

/// The error of a use case: Ctrl-C's KeyboardInterrupt as Python's handler raised it.
pub(crate) fn interrupted(py: Python<'_>, e: ident::Error) -> PyErr {
    match e {
        ident::Error::Cancelled(_) => PyErr::take(py).unwrap_or_else(|| errors::ident(e)),
        e => errors::ident(e),
    }
}

/// The data of a request: the record and an optional validation record.
fn time_data(
    u: FloatArray<'_>,
    y: FloatArray<'_>,
    dt: f64,
    validation: Option<(FloatArray<'_>, FloatArray<'_>)>,
) -> PyResult<TimeData> {
    let u = floats("u", &u, 2)?;
    let y = floats("y", &y, 2)?;
    same_len(("u", u.len()), ("y", y.len()))?;
    let dt = positive("dt", dt)?;
    Ok(TimeData {
        record: Record::from_samples(&u, &y, dt).map_err(errors::ident)?,
        validation: validation
            .map(|v| named("validation".into(), v, dt))
            .transpose()?,
        joint: Vec::new(),
        reader_warnings: Vec::new(),
    })
}

/// The time-domain use case (`ident::app::time::run`, as `fracid time`): `request` is the JSON of
/// a `TimeRequest` (missing fields take their defaults), `validation` an optional separate
/// record `(u, y)` at the same `dt`. Returns `(report, arrays)`: the report as `fracid time
/// --json` prints it, and the arrays (`yhat`, with the diagnosis `yhat_before`, `yhat_after`).
#[pyfunction]
#[pyo3(signature = (u, y, dt, request, validation = None))]
pub(crate) fn _fit_time<'py>(
    py: Python<'py>,
    u: FloatArray<'py>,
    y: FloatArray<'py>,
    dt: f64,
    request: &str,
    validation: Option<(FloatArray<'py>, FloatArray<'py>)>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let data = time_data(u, y, dt, validation)?;
    let req = request_of(request)?;
    let r = py
        .allow_threads(|| ident::app::time::run(&req, &data, &mut Interruptible))
        .map_err(|e| interrupted(py, e))?;
    let arrays = PyDict::new(py);
    // `yhat` is the leading model's output: the final model's with the diagnosis.
    let base = r.base.as_ref().unwrap_or(&r.lead);
    arrays.set_item("yhat_base", base.yhat.clone().into_pyarray(py))?;
    arrays.set_item("yhat", r.lead.yhat.clone().into_pyarray(py))?;
    if let Some(d) = &r.diagnosis {
        let g = &d.diagnosis;
        arrays.set_item("yhat_before", g.yhat_before.clone().into_pyarray(py))?;
        arrays.set_item("yhat_after", g.yhat_after.clone().into_pyarray(py))?;
        arrays.set_item("diagnosis_split", g.split)?;
        arrays.set_item(
            "diagnosis_params",
            g.model
                .params
                .iter()
                .map(|p| (p.name.clone(), p.value))
                .collect::<Vec<_>>(),
        )?;
    }
    Ok((to_py(py, &r)?, arrays))
}
