//! `fracid drive autotune` from Python: `fracid._fracid._autotune`, wrapped by
//! `fracid.autotune`: the same request (`autotune::tuner::AutotuneRequest`), the same `run` and
//! the same report as the CLI's `--json`.

use crate::errors;
use crate::time::to_py;
use autotune::tuner::{self, AutotuneRequest};
use drive::client::{Client, ClientConfig};
use pyo3::prelude::*;
use std::time::Duration;

/// The defaults of the autotune's request, as `fracid drive autotune`'s flags and
/// `fracid.autotune`'s keywords take them.
#[pyfunction]
pub(crate) fn _autotune_request_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_py(py, &AutotuneRequest::default())
}

/// The library's errors as the package's exceptions: a bad request is a `DataError`, the drive's
/// are the drive's, the rest run-time failures.
fn error(e: autotune::Error) -> PyErr {
    match e {
        autotune::Error::InvalidParam(m) => errors::data(m),
        autotune::Error::Drive(d) => errors::drive(d),
        autotune::Error::Ident(i) => errors::ident(i),
        e => errors::error(errors::Kind::Drive, e.to_string()),
    }
}

/// Run the autotune on the drive at `port` (`request`: the JSON of the options given, the rest
/// defaulted). Returns the report as `fracid drive autotune --json` prints it. The GIL is
/// released during the run; the drive is stopped on every way out.
#[pyfunction]
#[pyo3(signature = (port, request, sample_rate_hz = 1000, baud = 115_200, keepalive_ms = 150))]
pub(crate) fn _autotune<'py>(
    py: Python<'py>,
    port: &str,
    request: &str,
    sample_rate_hz: u32,
    baud: u32,
    keepalive_ms: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let req: AutotuneRequest = serde_json::from_str(request)
        .map_err(|e| errors::data(format!("autotune options: {e}")))?;
    if !(1..=10_000).contains(&keepalive_ms) {
        return Err(errors::data(format!(
            "keepalive_ms = {keepalive_ms} must be in 1..=10000"
        )));
    }
    let report = py.allow_threads(|| {
        let cfg = ClientConfig {
            baud,
            keepalive: Duration::from_millis(keepalive_ms),
            ..ClientConfig::default()
        };
        let mut client = Client::open(port, cfg).map_err(autotune::Error::from)?;
        tuner::run(&mut client, sample_rate_hz, &req, &mut tuner::Quiet)
    });
    to_py(py, &report.map_err(error)?)
}
