//! Python bindings of fracid (pyo3 + numpy), built by maturin into the extension module
//! `fracid._fracid`. The Python package `fracid` (in `python/fracid/`) wraps it with typed result
//! classes, numpydoc docstrings and the exception hierarchy.
//!
//! The library crates (`fracsim`, `ident`, `drive`) know nothing of Python: this crate converts
//! numpy arrays to checked slices, maps their errors to Python exceptions with the message kept,
//! and releases the GIL around every simulation and fit so threads run them in parallel, and around
//! every exchange with a drive.

mod arrays;
mod autotune;
mod drive_client;
mod errors;
mod freq;
mod readers;
mod tf;
mod time;
mod tune;

use pyo3::prelude::*;

/// The extension module `fracid._fracid`.
#[pymodule]
fn _fracid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<tf::PyFracTf>()?;
    m.add_function(wrap_pyfunction!(tf::gl_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(tf::prbs, m)?)?;
    m.add_function(wrap_pyfunction!(freq::_fit_bode, m)?)?;
    m.add_function(wrap_pyfunction!(freq::error_index, m)?)?;
    m.add_function(wrap_pyfunction!(freq::_answer_pointer, m)?)?;
    m.add_function(wrap_pyfunction!(time::_fit_time, m)?)?;
    m.add_function(wrap_pyfunction!(time::_fit_time_joint, m)?)?;
    m.add_function(wrap_pyfunction!(time::_time_request_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(time::_structures, m)?)?;
    m.add_function(wrap_pyfunction!(freq::_freq_request_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(tune::_tune, m)?)?;
    m.add_function(wrap_pyfunction!(autotune::_autotune, m)?)?;
    m.add_function(wrap_pyfunction!(autotune::_autotune_request_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(readers::_load_csv, m)?)?;
    m.add_function(wrap_pyfunction!(readers::_load_bode, m)?)?;
    m.add_class::<drive_client::PyDriveSimulator>()?;
    m.add_class::<drive_client::PyDriveClient>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
