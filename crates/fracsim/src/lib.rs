//! # fracsim: fractional operators and simulation
//!
//! - [`FracTf`]: fractional transfer functions `sum b_i s^beta_i / sum a_j s^alpha_j * exp(-tau s)`,
//!   their exact frequency response and a parser.
//! - [`approx`]: rational approximations of `s^nu`: Oustaloup (Oustaloup et al. 2000), refined
//!   Oustaloup (Xue, Zhao & Chen 2006), the Poinot-Trigeassou (alpha, eta) integrator
//!   (Poinot & Trigeassou 2004).
//! - [`modal`]: the approximated model in pole-residue form (every operator and their
//!   interconnection as one rational system, never multiplied out).
//! - [`discrete`]: [`Simulator`], its exact discretisation for a held (zero-order-hold) input,
//!   fractional-sample delays included, run as a bank of first-order recursive filters.
//! - [`export`]: the approximation as a state space (A, B, C, D), continuous or discrete with the
//!   exact hold, to MATLAB.
//! - [`eig`]: eigenvalues of a real matrix (QR iteration without Schur vectors): the poles.
//! - [`gl`]: Grunwald-Letnikov, the reference simulator.
//! - [`prbs`]: maximum-length pseudo-random binary sequences.
//! - [`special`]: the Mittag-Leffler function and the exact step response of `K/(a s^q + 1)`.
//! - [`scalar`]: `f64` and forward-mode [`Dual`] numbers: every simulation is generic over them.

mod error;
pub mod scalar;
pub mod tf;

pub use error::{Error, Result};
pub use scalar::{Dual, Real};
pub use tf::{jw_pow, FracTf, Term};
pub mod approx;
pub mod cx;
pub mod discrete;
pub mod eig;
pub mod export;
pub mod fft;
pub mod gl;
pub mod json;
pub mod lanes;
pub mod modal;
pub mod prbs;
pub mod special;

pub use approx::{ApproxSpec, Method};
pub use discrete::{lsim, Simulator};
