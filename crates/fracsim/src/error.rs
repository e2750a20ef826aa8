//! The error type of `fracsim`.

/// Errors from building, parsing or simulating fractional systems.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A model expression could not be parsed; `pos` is the byte offset in the input.
    #[error("cannot parse model at position {pos}: {msg}")]
    Parse {
        /// Byte offset of the problem in the input string.
        pos: usize,
        /// What was wrong.
        msg: String,
    },
    /// A number (coefficient, order, delay, step, band edge...) is NaN or infinite.
    #[error("{what} must be finite, got {value}")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// The denominator has no nonzero term.
    #[error("the denominator is zero")]
    ZeroDenominator,
    /// A parameter is outside its valid range.
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// Which quantity.
        what: &'static str,
        /// Why it is invalid.
        msg: String,
    },
    /// The approximation band is empty or not positive.
    #[error("invalid band [{w_b}, {w_h}] rad/s: need 0 < w_b < w_h, both finite")]
    Band {
        /// Lower band edge in rad/s.
        w_b: f64,
        /// Upper band edge in rad/s.
        w_h: f64,
    },
    /// The simulation broke down numerically (a singular implicit step, a non-finite output).
    #[error("numerical breakdown: {0}")]
    Numerical(String),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Check that `value` is finite.
pub(crate) fn finite(what: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error::NonFinite { what, value })
    }
}

pub(crate) fn invalid<T>(what: &'static str, msg: impl Into<String>) -> Result<T> {
    Err(Error::Invalid {
        what,
        msg: msg.into(),
    })
}
