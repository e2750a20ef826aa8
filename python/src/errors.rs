//! Rust errors to the Python exception hierarchy defined in `fracid/_errors.py`:
//! `FracidError` (base), `ParseError`, `DataError` (both also `ValueError`), `NumericalError`
//! (also `ArithmeticError`), `DriveError` (the drive or the serial link). The message of the Rust
//! error is kept as it is.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyType;

/// Which exception class of the hierarchy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A model expression that does not parse.
    Parse,
    /// Unusable data or arguments.
    Data,
    /// A numerical breakdown.
    Numerical,
    /// The drive or the serial link failed (port, timeout, rejected command, reset).
    Drive,
    /// A controller specification no controller of the form meets (`fracid.tune`).
    Infeasible,
}

impl Kind {
    fn class_name(self) -> &'static str {
        match self {
            Self::Parse => "ParseError",
            Self::Data => "DataError",
            Self::Numerical => "NumericalError",
            Self::Drive => "DriveError",
            Self::Infeasible => "InfeasibleError",
        }
    }
}

fn class<'py>(py: Python<'py>, kind: Kind) -> PyResult<Bound<'py, PyType>> {
    let m = py.import("fracid._errors")?;
    Ok(m.getattr(kind.class_name())?.downcast_into::<PyType>()?)
}

/// A Python exception of `kind` with `msg`.
pub(crate) fn error(kind: Kind, msg: impl Into<String>) -> PyErr {
    let msg = msg.into();
    Python::with_gil(|py| match class(py, kind) {
        Ok(t) => PyErr::from_type(t, msg),
        // The package is broken (the errors module is missing): still say what went wrong.
        Err(_) => PyRuntimeError::new_err(format!("{}: {msg}", kind.class_name())),
    })
}

/// A `DataError` with `msg`.
pub(crate) fn data(msg: impl Into<String>) -> PyErr {
    error(Kind::Data, msg)
}

/// Map a simulation-layer error.
pub(crate) fn sim(e: fracsim::Error) -> PyErr {
    error(sim_kind(&e), e.to_string())
}

/// The Python error class of a simulation-layer error.
fn sim_kind(e: &fracsim::Error) -> Kind {
    match e {
        fracsim::Error::Parse { .. } => Kind::Parse,
        fracsim::Error::Numerical(_) => Kind::Numerical,
        _ => Kind::Data,
    }
}

/// Map an identification-layer error (its kind from the error in a file's content, its message
/// with the file and every source, [`ident::Error::report`]).
pub(crate) fn ident(e: ident::Error) -> PyErr {
    let msg = e.report();
    match e.innermost() {
        // a file that cannot be read: Python's OSError (FileNotFoundError for a missing one)
        ident::Error::Io { source, .. } => {
            if source.kind() == std::io::ErrorKind::NotFound {
                pyo3::exceptions::PyFileNotFoundError::new_err(msg)
            } else {
                pyo3::exceptions::PyOSError::new_err(msg)
            }
        }
        ident::Error::Cancelled(_) => pyo3::exceptions::PyKeyboardInterrupt::new_err(msg),
        ident::Error::Numerical(_) => error(Kind::Numerical, msg),
        ident::Error::Sim(s) => error(sim_kind(s), msg),
        _ => error(Kind::Data, msg),
    }
}

/// Map a drive-crate error: a bad host-side parameter is a `DataError`, the rest (the port, the
/// link, the drive's answers) a `DriveError`.
pub(crate) fn drive(e: drive::Error) -> PyErr {
    let kind = match &e {
        // "configure the drive first" is a state, not a value: a DriveError.
        drive::Error::InvalidParam(m) if !m.starts_with("configure") => Kind::Data,
        _ => Kind::Drive,
    };
    error(kind, e.to_string())
}
