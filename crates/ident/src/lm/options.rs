//! The options of the two solvers: [`LmOptions`] ([`super::minimize`]) and [`RefineOptions`]
//! ([`super::refine`]).

#[allow(unused_imports)] // (doc links)
use super::{minimize, refine, Termination};
use crate::par::Par;

/// Options of [`minimize`]. `LmOptions::default()` suits most problems.
#[derive(Debug, Clone, PartialEq)]
pub struct LmOptions {
    /// Stop after this many iterations (Jacobian evaluations). Default 200.
    pub max_iterations: usize,
    /// Stop after this many residual evaluations (0: `100 (n + 1)` plus the iterations). Default 0.
    pub max_evaluations: usize,
    /// Gradient test: stop when `max_j |g_j| / (||J_j|| ||r||) <= gtol`, `g = J^T r` (the cosine
    /// between the residual and each Jacobian column). Default 1e-10.
    pub gtol: f64,
    /// Step test: stop when `||D d|| <= xtol (||D p|| + xtol)`. Default 1e-10.
    pub xtol: f64,
    /// Cost test: stop when the actual and the predicted relative reductions of the cost are both
    /// `<= ftol`. Default 1e-12.
    pub ftol: f64,
    /// Starting Marquardt factor, relative to `D^2 = diag(J^T J)` (Marquardt's 1963 scaling).
    /// Default 1e-3.
    pub initial_lambda: f64,
    /// Scale the damping by the Jacobian column norms (Moré). If false, `D = I`. Default true.
    pub scale: bool,
    /// Compute the covariance and standard errors at the solution. Default true.
    pub covariance: bool,
    /// Stall test `(k, rel)`: stop ([`Termination::SmallCostChange`]) when the cost fell by less
    /// than the fraction `rel` over the last `k` accepted iterations (a fit that creeps on at a
    /// rate that cannot matter to its caller). Default `None` (off).
    pub stall: Option<(usize, f64)>,
    /// Give-up test `(k, target)`: stop ([`Termination::SmallCostChange`]) when, after at least
    /// `k` accepted iterations, the cost would still be above `target` (a cost, `1/2` the sum of
    /// squares) even if it went on falling by its mean fall over the last `k` accepted iterations
    /// at every iteration left of [`Self::max_iterations`]: a fit that cannot end where its caller
    /// needs it (the stall test's assumption, a cost whose fall does not speed up, with the
    /// caller's target instead of a fixed fraction). Default `None` (off).
    pub give_up: Option<(usize, f64)>,
    /// With [`Self::covariance`]: when an accepted step `d` ends the fit by the cost or the step
    /// test and is within a hundredth of a standard error (`|J d| <= 0.01 sigma`, `sigma^2` the
    /// residual variance at the new point; the Jacobian, and so the covariance, moves by far less
    /// than the estimate's own uncertainty over such a step), the covariance is computed from
    /// the Jacobian of the point before that step, with the residual variance of the final point,
    /// instead of evaluating a Jacobian at the final point for it. Default false.
    pub covariance_before_last_step: bool,
    /// On how many threads the passes over a tall Jacobian (its QR, `J^T r`, its finiteness
    /// check) may run. The results do not depend on it (the rows are cut by the size alone).
    /// Default [`Par::available`]: the machine's cores.
    pub par: Par,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            max_evaluations: 0,
            gtol: 1e-10,
            xtol: 1e-10,
            ftol: 1e-12,
            initial_lambda: 1e-3,
            scale: true,
            covariance: true,
            stall: None,
            give_up: None,
            covariance_before_last_step: false,
            par: Par::available(),
        }
    }
}

/// Options of [`refine`].
#[derive(Debug, Clone, PartialEq)]
pub struct RefineOptions {
    /// The last Gauss-Newton step, in standard errors (`sqrt(pred / sigma^2)` with `pred` its
    /// predicted reduction of the sum of squares and `sigma^2 = SSR/(m - n)`), under which the
    /// point after it is the solution. Default 0.01: the result is then within a hundredth of a
    /// standard error of the least-squares optimum (in the metric of `J^T J`), far below the
    /// estimate's own uncertainty.
    pub tolerance: f64,
    /// Chord steps (with the Jacobian of the round's start) under which a round's steps stop:
    /// a tenth of [`RefineOptions::tolerance`] by default.
    pub chord_tolerance: f64,
    /// Chord steps a round at most. Default 8.
    pub max_chord_steps: usize,
    /// Rounds (Jacobians) at most before [`minimize`] takes over. Default 3.
    pub max_rounds: usize,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            tolerance: 0.01,
            chord_tolerance: 0.001,
            max_chord_steps: 8,
            max_rounds: 3,
        }
    }
}
