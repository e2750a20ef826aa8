//! The frequency-domain fit (weighted Levy with an order search, Sanathanan-Koerner, the PMSM
//! refit): `fracid._fracid._fit_bode`, wrapped by `fracid.fit_bode` in Python.

use crate::arrays::{complexes, floats, same_len, ComplexArray, FloatArray};
use crate::errors;
use crate::tf::PyFracTf;
use ident::app::freq::{FreqData, FreqRequest};
use pyo3::prelude::*;

/// The defaults of the frequency-domain request (`ident::app::freq::FreqRequest::default()`),
/// as `fracid freq`'s flags and `fracid.fit_bode`'s keywords take them.
#[pyfunction]
pub(crate) fn _freq_request_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    crate::time::to_py(py, &FreqRequest::default())
}

/// The JSON pointer of a report's answer, the model it leads with, by the library's one rule
/// (`ident::app::answer::of_report`: `diagnosis.model`, else `best_model`, else `model`; `""`
/// for a bare model), so that Python's results take the model `fracid tune`, `compare`,
/// `export` and the fleet take.
#[pyfunction]
pub(crate) fn _answer_pointer(report: &str) -> PyResult<String> {
    let v: serde_json::Value =
        serde_json::from_str(report).map_err(|e| errors::data(format!("report: {e}")))?;
    Ok(ident::app::answer::of_report(&v).pointer.to_string())
}

/// The frequency-domain use case (`ident::app::freq::run`, as `fracid freq`): `request` is the
/// JSON of a `FreqRequest`; `weights` per-point weights (`weights = "given"`), `point_std` a
/// measured spread. Returns the report as `fracid freq --json` prints it.
#[pyfunction]
#[pyo3(signature = (omega, h, request, weights = None, point_std = None))]
pub(crate) fn _fit_bode<'py>(
    py: Python<'py>,
    omega: FloatArray<'py>,
    h: ComplexArray<'py>,
    request: &str,
    weights: Option<FloatArray<'py>>,
    point_std: Option<FloatArray<'py>>,
) -> PyResult<Bound<'py, PyAny>> {
    let omega = floats("omega", &omega, 1)?;
    let h = complexes("h", &h, 1)?;
    same_len(("omega", omega.len()), ("h", h.len()))?;
    let per_point = |name: &str, a: &Option<FloatArray<'py>>| -> PyResult<Option<Vec<f64>>> {
        match a {
            Some(a) => {
                let v = floats(name, a, 1)?;
                same_len(("omega", omega.len()), (name, v.len()))?;
                Ok(Some(v))
            }
            None => Ok(None),
        }
    };
    let req: FreqRequest =
        serde_json::from_str(request).map_err(|e| errors::data(format!("options: {e}")))?;
    let data = FreqData {
        weights: per_point("weights", &weights)?.map(|w| (w, "given per point".to_string())),
        point_std: per_point("point_std", &point_std)?,
        omega_rad_s: omega,
        h,
        ..FreqData::default()
    };
    let r = py
        .allow_threads(|| ident::app::freq::run(&req, &data, &mut crate::time::Interruptible))
        .map_err(|e| crate::time::interrupted(py, e))?;
    crate::time::to_py(py, &r)
}

/// The error index `J = (1/f) sum |G(j w) - Ghat(j w)|^2` (paper eq. 30) of `model` on Bode data.
#[pyfunction]
pub(crate) fn error_index<'py>(
    omega: FloatArray<'py>,
    h: ComplexArray<'py>,
    model: &PyFracTf,
) -> PyResult<f64> {
    let omega = floats("omega", &omega, 1)?;
    let h = complexes("h", &h, 1)?;
    same_len(("omega", omega.len()), ("h", h.len()))?;
    Ok(ident::levy::error_index(&omega, &h, &model.inner))
}
