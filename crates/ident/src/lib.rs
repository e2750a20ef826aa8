//! # ident: fractional-order system identification
//!
//! - [`app`]: the application layer the CLI and Python share (typed requests, use cases, reports).
//! - [`catalogue`]: the named structures (`pmsm`, `second-order`, ...): names, formulas, models.
//! - [`levy`]: weighted Levy least squares (Levy 1959) with Vinagre weights (Vinagre 2001) and a
//!   commensurate-order search; Sanathanan-Koerner iterations; a nonlinear refit of the PMSM
//!   structure in the frequency domain.
//! - [`lm`]: a Levenberg-Marquardt solver (Marquardt 1963) with a report of why it stopped.
//! - [`oe`]: output-error identification in the time domain with exact sensitivities.
//! - [`compare`]: two models side by side over a band (largest gain and phase differences, coefficients).
//! - [`data`]: records `t, u, y` from delimited text, sampling checks, operating point, split.
//! - [`files`]: bounded reading of input files (size, line length, text checks).
//! - [`diagnose`]: residual diagnosis, the effect library, error before and after.
//! - [`metrics`]: fit measures (NRMSE, RMSE), residual correlations with their bounds.
//! - [`numeric`]: vectorised sums, dot products, ranges and finiteness checks over slices.

pub mod app;
pub mod bodefile;
pub mod catalogue;
pub mod compare;
pub mod data;
pub mod diagnose;
mod error;
pub mod files;
pub mod hold;
pub mod levy;
pub mod lm;
pub mod matfile;
pub mod metrics;
pub mod numeric;
pub mod oe;
mod par;
#[cfg(test)]
mod testdata;

pub use error::{Error, Result};
