//! The frequency-domain fit (weighted Levy with an order search, Sanathanan-Koerner, the PMSM
//! refit): `fracid._fracid._fit_bode`, wrapped by `fracid.fit_bode` in Python.

use crate::arrays::{complexes, floats, same_len, ComplexArray, FloatArray};
use crate::errors;
use crate::tf::PyFracTf;
use ident::levy::{fit_bode, FreqOptions, LevyFit, OrderChoice, PmsmFit, QPoint, Weights};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

fn levy_dict<'py>(py: Python<'py>, f: &LevyFit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("q", f.q)?;
    d.set_item("b", f.b.clone())?;
    d.set_item("a", f.a.clone())?;
    d.set_item("model", PyFracTf::from(f.model.clone()))?;
    d.set_item("J", f.j)?;
    d.set_item("levy_cost", f.levy_cost)?;
    d.set_item("sk_iterations", f.sk_iterations)?;
    d.set_item("sk_converged", f.sk_converged)?;
    Ok(d)
}

fn pmsm_dict<'py>(py: Python<'py>, f: &PmsmFit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("model", PyFracTf::from(f.model.clone()))?;
    d.set_item("K", f.k)?;
    d.set_item("a1", f.a1)?;
    d.set_item("a2", f.a2)?;
    d.set_item("zeta", f.zeta)?;
    d.set_item("theta", f.theta)?;
    d.set_item("J", f.j)?;
    match f.std_errors {
        Some(s) => {
            let e = PyDict::new(py);
            for (name, v) in ["K", "a1", "a2", "zeta", "theta"].iter().zip(s) {
                e.set_item(*name, v)?;
            }
            d.set_item("std_errors", e)?;
        }
        None => d.set_item("std_errors", py.None())?,
    }
    d.set_item("converged", f.report.converged)?;
    d.set_item("termination", format!("{:?}", f.report.termination))?;
    d.set_item("iterations", f.report.iterations)?;
    Ok(d)
}

fn curve_dict<'py>(py: Python<'py>, c: &[QPoint]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "q",
        c.iter().map(|p| p.q).collect::<Vec<_>>().into_pyarray(py),
    )?;
    d.set_item(
        "J",
        c.iter().map(|p| p.j).collect::<Vec<_>>().into_pyarray(py),
    )?;
    Ok(d)
}

fn weights_of(w: &Bound<'_, PyAny>, n_points: usize) -> PyResult<Weights> {
    if let Ok(s) = w.downcast::<PyString>() {
        let s = s.to_cow()?;
        return match s.to_ascii_lowercase().as_str() {
            "vinagre" => Ok(Weights::Vinagre),
            "uniform" | "none" => Ok(Weights::Uniform),
            _ => Err(errors::data(format!(
                "weights '{s}': expected 'vinagre', 'uniform' or an array of {n_points} weights"
            ))),
        };
    }
    let a: FloatArray<'_> = w.extract()?;
    Ok(Weights::PerPoint(floats("weights", &a, 1)?))
}

/// Levy (+ SK, + refit) on Bode data; returns a dict the Python layer turns into `FreqFit`.
#[pyfunction]
#[pyo3(signature = (omega, h, n = 2, m = 0, q = None, q_step = 0.01, q_max = 1.0, refine_q = true, weights = None, sk_iterations = 0, refine = false, point_std = None))]
pub(crate) fn _fit_bode<'py>(
    py: Python<'py>,
    omega: FloatArray<'py>,
    h: ComplexArray<'py>,
    n: usize,
    m: usize,
    q: Option<f64>,
    q_step: f64,
    q_max: f64,
    refine_q: bool,
    weights: Option<Bound<'py, PyAny>>,
    sk_iterations: usize,
    refine: bool,
    point_std: Option<FloatArray<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    let omega = floats("omega", &omega, 1)?;
    let h = complexes("h", &h, 1)?;
    same_len(("omega", omega.len()), ("h", h.len()))?;
    let point_std = match &point_std {
        Some(s) => {
            let s = floats("point_std", s, 1)?;
            same_len(("omega", omega.len()), ("point_std", s.len()))?;
            Some(s)
        }
        None => None,
    };
    let weights = match &weights {
        Some(w) if !w.is_none() => weights_of(w, omega.len())?,
        _ => Weights::Vinagre,
    };
    if n == 0 {
        return Err(errors::data("n (denominator degree) must be at least 1"));
    }
    if sk_iterations > 1000 {
        return Err(errors::data(format!(
            "sk_iterations = {sk_iterations} is too many (at most 1000)"
        )));
    }
    let order = match q {
        Some(q) => OrderChoice::Fixed(q),
        None => {
            if !(q_step.is_finite() && q_step > 0.0 && q_max.is_finite() && q_max >= q_step) {
                return Err(errors::data(format!(
                    "q grid: need 0 < q_step <= q_max, got q_step = {q_step}, q_max = {q_max}"
                )));
            }
            if q_max / q_step > 1e6 {
                return Err(errors::data(format!(
                    "q grid of {:.0} points is too fine",
                    q_max / q_step
                )));
            }
            OrderChoice::Search {
                step: q_step,
                q_max,
                refine: refine_q,
            }
        }
    };
    let opts = FreqOptions {
        n,
        m,
        order,
        weights,
        sk_iterations,
        refine,
        point_std,
    };
    let fit = py
        .allow_threads(|| fit_bode(&omega, &h, &opts))
        .map_err(errors::ident)?;
    let d = PyDict::new(py);
    d.set_item("levy", levy_dict(py, &fit.levy)?)?;
    d.set_item("levy_grid", levy_dict(py, &fit.levy_grid)?)?;
    d.set_item("curve", curve_dict(py, &fit.curve)?)?;
    match &fit.sk {
        Some(s) => d.set_item("sk", levy_dict(py, s)?)?,
        None => d.set_item("sk", py.None())?,
    }
    d.set_item("sk_curve", curve_dict(py, &fit.sk_curve)?)?;
    match &fit.refined {
        Some(r) => d.set_item("refined", pmsm_dict(py, r)?)?,
        None => d.set_item("refined", py.None())?,
    }
    d.set_item("best_model", PyFracTf::from(fit.best_model().clone()))?;
    d.set_item("problems", fit.problems.clone())?;
    d.set_item("warnings", fit.warnings.clone())?;
    Ok(d)
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
