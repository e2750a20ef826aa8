//! The library's file readers for Python: `fracid._fracid._load_csv` and `_load_bode`, wrapped by
//! `fracid.load_csv` and `fracid.load_bode`. The same reader as the CLI's (`ident::data`,
//! `ident::bodefile`): the same delimiters, headers, limits, `.mat` files and acquisition
//! footers.

use crate::errors;
use ident::bodefile::BodeUnits;
use ident::data::{Columns, ReadOptions, Record};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyString};
use std::path::PathBuf;

/// A column selector: a name (str) or a 0-based index (int).
fn selector(name: &str, v: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(s) = v.downcast::<PyString>() {
        return Ok(s.to_cow()?.into_owned());
    }
    if v.downcast::<PyInt>().is_ok() {
        let i: i64 = v.extract()?;
        if i < 0 {
            return Err(errors::data(format!(
                "{name} = {i}: a column index must be >= 0"
            )));
        }
        return Ok(i.to_string());
    }
    Err(errors::data(format!(
        "{name} must be a column name (str) or a 0-based index (int)"
    )))
}

/// Read a time record; a dict with `t`, `u`, `y`, `dt`, `warnings`, `acquisition`,
/// `rows_kept`, `rows_read`.
#[pyfunction]
#[pyo3(signature = (path, t, u, y, dt = None))]
pub(crate) fn _load_csv<'py>(
    py: Python<'py>,
    path: PathBuf,
    t: Bound<'py, PyAny>,
    u: Bound<'py, PyAny>,
    y: Bound<'py, PyAny>,
    dt: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = ReadOptions {
        columns: Columns {
            t: selector("t", &t)?,
            u: selector("u", &u)?,
            y: selector("y", &y)?,
        },
        dt,
    };
    let l = py
        .allow_threads(|| Record::load(&path, &opts))
        .map_err(errors::ident)?;
    let d = PyDict::new(py);
    let acq = match &l.acquisition {
        ident::data::Acquisition::Unknown => "unknown".to_string(),
        ident::data::Acquisition::Complete => "complete".to_string(),
        ident::data::Acquisition::Incomplete(m) => format!("incomplete: missing samples {m}"),
        ident::data::Acquisition::Interrupted => "interrupted".to_string(),
    };
    d.set_item("dt", l.record.dt)?;
    d.set_item("t", l.record.t.into_pyarray(py))?;
    d.set_item("u", l.record.u.into_pyarray(py))?;
    d.set_item("y", l.record.y.into_pyarray(py))?;
    d.set_item("warnings", l.warnings)?;
    d.set_item("acquisition", acq)?;
    d.set_item("rows_kept", (l.rows_kept.start, l.rows_kept.end))?;
    d.set_item("rows_read", l.rows_read)?;
    Ok(d)
}

/// Read a Bode table; `(omega_rad_s, h, weights or None)`.
#[pyfunction]
#[pyo3(signature = (path, columns = None, rad_s = false, linear_gain = false, radians = false, weights = None))]
#[allow(clippy::type_complexity)]
pub(crate) fn _load_bode<'py>(
    py: Python<'py>,
    path: PathBuf,
    columns: Option<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)>,
    rad_s: bool,
    linear_gain: bool,
    radians: bool,
    weights: Option<Bound<'py, PyAny>>,
) -> PyResult<(PyObject, PyObject, PyObject)> {
    let cols = match &columns {
        Some((f, g, p)) => Some([
            selector("frequency column", f)?,
            selector("gain column", g)?,
            selector("phase column", p)?,
        ]),
        None => None,
    };
    let wcol = weights
        .as_ref()
        .map(|w| selector("weights column", w))
        .transpose()?;
    let units = BodeUnits {
        rad_s,
        linear_gain,
        radians,
    };
    let table = py
        .allow_threads(|| {
            let c = cols
                .as_ref()
                .map(|c| [c[0].as_str(), c[1].as_str(), c[2].as_str()]);
            ident::bodefile::load(&path, c, units, wcol.as_deref())
        })
        .map_err(errors::ident)?;
    let w = match table.weights {
        Some(w) => w.into_pyarray(py).into_any().unbind(),
        None => py.None(),
    };
    Ok((
        table.omega_rad_s.into_pyarray(py).into_any().unbind(),
        table.h.into_pyarray(py).into_any().unbind(),
        w,
    ))
}
