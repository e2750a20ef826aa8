//! A Levenberg-Marquardt least-squares solver (Levenberg 1944, Marquardt 1963) for any residual
//! vector with a Jacobian: the frequency-domain refit ([`crate::levy`]) and the time-domain
//! output-error fit ([`crate::oe`]) both use it.
//!
//! It minimises the cost `C(p) = 1/2 sum_i r_i(p)^2`. Each iteration solves the damped
//! linearised problem
//!
//! `min_d || J d + r ||^2 + lambda || D d ||^2`,
//!
//! i.e. `(J^T J + lambda D^2) d = -J^T r` (Marquardt's eq. with the scaling `D`): `[J r]` is
//! factored once per iteration, giving `R` and `Q^T r` (by Cholesky QR when its scaled columns are
//! well conditioned, else by Householder QR), and each trial `lambda` solves the small
//! stacked system `[R; sqrt(lambda) D] d = [-Q^T r; 0]` by QR again. [`refine`] finishes a fit
//! from near its optimum with fewer Jacobians. `D = diag(d_i)` with `d_i` the largest Euclidean norm of column `i`
//! of `J` seen so far (Moré 1978), which makes the method invariant to the units of each
//! parameter. The Marquardt factor `lambda` follows Nielsen's (1999) rule: with the gain ratio
//! `rho = (actual reduction)/(predicted reduction)`, an accepted step (`rho > 0`) sets
//! `lambda *= max(1/3, 1 - (2 rho - 1)^3)`, a rejected one `lambda *= nu, nu *= 2`.
//!
//! A fit that runs but does not converge is not an error: [`minimize`] returns a [`LmReport`]
//! with `converged == false` and the [`Termination`] reason.
//!
//! The modules, after the `levenberg-marquardt` crate's: [`Problem`] (what is minimised), the
//! solver ([`minimize`]) and its Gauss-Newton finish ([`refine`]), the QR of `[J r]`, the trust
//! region's damped steps, the covariance; the vectorised sums they use live in
//! [`crate::numeric`], the two-thread passes in [`crate::par`].

mod covariance;
mod options;
mod passes;
mod problem;
mod qr;
mod refine;
mod report;
mod solver;
#[cfg(test)]
mod testproblems;
mod trust_region;

pub(crate) use crate::linalg::lstsq;
pub use options::{LmOptions, RefineOptions};
pub(crate) use problem::ColSlices;
pub use problem::{FiniteDiff, Mat, Problem};
pub use refine::{refine, refine_with, RefineBuffers};
pub use report::{LmReport, Termination};
pub use solver::minimize;

// Where the fit (`oe`) and the diagnosis (`diagnose`) still import them from: the vectorised sums
// and the two-core test belong to `crate::numeric` and `crate::par`.
pub(crate) use crate::numeric::{all_finite, range_of, sum_of, sum_of2};
pub use crate::numeric::{dot, sumsq};
