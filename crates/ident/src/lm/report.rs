//! What a fit returns: the [`LmReport`] and the [`Termination`] reason.

#[allow(unused_imports)] // (doc links)
use super::{minimize, refine, LmOptions, Problem, RefineOptions};

/// Why [`minimize`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub enum Termination {
    /// The residuals are exactly zero.
    ZeroResidual,
    /// The gradient test ([`LmOptions::gtol`]) passed: a stationary point.
    SmallGradient,
    /// The step test ([`LmOptions::xtol`]) passed.
    SmallStep,
    /// The cost test ([`LmOptions::ftol`]) passed.
    SmallCostChange,
    /// [`refine`]: the Gauss-Newton step at the end, taken, was below
    /// [`RefineOptions::tolerance`] in standard errors (its predicted reduction of the sum of
    /// squares under `tolerance^2 sigma^2`).
    SmallStatisticalStep,
    /// No step lowers the cost even with a very large `lambda` (the minimum at the working
    /// precision, or a badly wrong Jacobian). Not counted as converged.
    NoProgress,
    /// [`LmOptions::max_iterations`] reached.
    MaxIterations,
    /// [`LmOptions::max_evaluations`] reached.
    MaxEvaluations,
}

impl Termination {
    /// Whether this reason counts as convergence.
    pub fn is_converged(self) -> bool {
        matches!(
            self,
            Self::ZeroResidual
                | Self::SmallGradient
                | Self::SmallStep
                | Self::SmallCostChange
                | Self::SmallStatisticalStep
        )
    }
}

/// The result of [`minimize`] (like scipy's `OptimizeResult`).
#[derive(Debug, Clone, PartialEq)]
pub struct LmReport {
    /// The parameters at the end (the best point found).
    pub params: Vec<f64>,
    /// The cost `1/2 sum r_i^2` at `params` (half the sum of squared residuals).
    pub cost: f64,
    /// The residuals at `params`.
    pub residuals: Vec<f64>,
    /// Iterations done (Jacobian evaluations after the first).
    pub iterations: usize,
    /// Residual evaluations done (including the first).
    pub evaluations: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// How many of the LM runs this report sums up ended at their budget
    /// ([`super::LmOptions::max_iterations`] or `max_evaluations`): 0 or 1 for one run of
    /// [`super::minimize`], summed where runs are chained (a Gauss-Newton refine handing over, a
    /// lead fit before the whole record's). A run that ends for any other reason ends where it
    /// would with a larger budget (the budget enters it only through those two tests and, with
    /// [`super::LmOptions::give_up`], the give-up test): runs none of which ended at their budget
    /// and none with a give-up test are what a larger budget makes, bit for bit.
    pub budget_ends: usize,
    /// `termination.is_converged()`.
    pub converged: bool,
    /// Parameter covariance `sigma^2 (J^T J)^-1`, `sigma^2 = SSR/(m - n)`, row-major `n x n`; `None`
    /// if not asked, if `m <= n`, or if `J` is rank deficient at the solution. A parameter at a
    /// bound ([`Problem::at_bound`]) is held there: its rows and columns are NaN and the rest is
    /// the covariance of the others with it fixed.
    pub covariance: Option<Vec<f64>>,
    /// Standard errors `sqrt(diag(covariance))` (NaN for a parameter held at a bound).
    pub std_errors: Option<Vec<f64>>,
    /// The Marquardt factor at the end (relative to `D^2`).
    pub lambda: f64,
    /// `max_j |g_j| / (||J_j|| ||r||)` at the end (see [`LmOptions::gtol`]); without
    /// [`LmOptions::covariance`], a fit that stops at an accepted step does not compute the
    /// Jacobian there (nothing needs it), and this is the cosine at the point before.
    pub gradient_cosine: f64,
}

impl LmReport {
    /// The covariance entry `(i, j)`, if computed.
    pub fn cov(&self, i: usize, j: usize) -> Option<f64> {
        let n = self.params.len();
        self.covariance.as_ref().map(|c| c[i * n + j])
    }

    /// The sum of squared residuals `2 cost`.
    pub fn ssr(&self) -> f64 {
        2.0 * self.cost
    }
}
