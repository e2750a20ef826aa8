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

use crate::{Error, Result};
/// The dense matrix of [`Problem::eval`]'s Jacobian: nalgebra's `DMatrix` (column-major).
pub use nalgebra::DMatrix as Mat;
use std::ops::Range;

/// A nonlinear least-squares problem: residuals `r(p)` and their Jacobian `dr/dp`.
///
/// The cost minimised is `1/2 sum r_i^2`: put weights in the residuals (`sqrt(w_i) e_i`).
pub trait Problem {
    /// Number of parameters `n` (the length of `p`).
    fn n_params(&self) -> usize;
    /// Number of residuals `m` (the length of `r`).
    fn n_residuals(&self) -> usize;
    /// Evaluate the residuals `r(p)` into `r` (length [`Problem::n_residuals`]) and, when `jac`
    /// is `Some`, the Jacobian `J_ij = d r_i / d p_j` into it (an `m x n` column-major nalgebra matrix, already
    /// sized; every entry must be written).
    ///
    /// # Errors
    /// Any error: at the starting point it is returned by [`minimize`]; at a trial point it only
    /// makes [`minimize`] reject that step (as a non-finite residual does).
    fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()>;

    /// Whether parameter `j` at the value `pj` sits at a bound of its range (a bounded
    /// parameter mapped to an unbounded one, run to the edge): [`refine`] holds it there and
    /// judges convergence on the others (the fit is the optimum with it on the bound). Default:
    /// never.
    fn at_bound(&self, j: usize, pj: f64) -> bool {
        let _ = (j, pj);
        false
    }

    /// `Some(f)` when column `j` of the Jacobian is `f` times what it was after parameter `j`
    /// alone moves from `from` to `to` (residuals linear in a transformed parameter: the column
    /// is the transform's derivative times a column that does not depend on it); `None` when it
    /// is not known. [`refine`]'s chord steps rescale their Jacobian's columns by it, so that
    /// such a parameter near the edge of its range (where the derivative of the transform
    /// changes fast) converges in one or two steps, not one round of several. Default: `None`.
    fn column_scale(&self, j: usize, from: f64, to: f64) -> Option<f64> {
        let _ = (j, from, to);
        None
    }
}

/// Wraps a [`Problem`] whose Jacobian is not available (or not trusted) and replaces it with
/// central finite differences, step `h_j = rel_step * max(|p_j|, 1)`.
///
/// The inner problem is always called with `jac = None`. Costs `2 n` extra residual evaluations
/// per Jacobian.
#[derive(Debug, Clone)]
pub struct FiniteDiff<P> {
    /// The problem whose residuals are differentiated.
    pub inner: P,
    /// Relative step; `6e-6` (about the cube root of machine epsilon) is right for central
    /// differences of smooth residuals.
    pub rel_step: f64,
}

impl<P: Problem> FiniteDiff<P> {
    /// Wrap `inner` with the default relative step `6e-6`.
    pub fn new(inner: P) -> Self {
        Self {
            inner,
            rel_step: 6e-6,
        }
    }
}

impl<P: Problem> Problem for FiniteDiff<P> {
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }
    fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
        self.inner.eval(p, r, None)?;
        if let Some(jac) = jac {
            let m = r.len();
            let mut pp = p.to_vec();
            let (mut rp, mut rm) = (vec![0.0; m], vec![0.0; m]);
            for j in 0..p.len() {
                let h = self.rel_step * p[j].abs().max(1.0);
                pp[j] = p[j] + h;
                self.inner.eval(&pp, &mut rp, None)?;
                pp[j] = p[j] - h;
                self.inner.eval(&pp, &mut rm, None)?;
                pp[j] = p[j];
                for i in 0..m {
                    jac[(i, j)] = (rp[i] - rm[i]) / (2.0 * h);
                }
            }
        }
        Ok(())
    }
}

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
        }
    }
}

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

/// `sum_i a_i b_i` over the shorter of `a` and `b`, in eight interleaved partial sums.
///
/// A plain `iter().sum()` is one chain of dependent additions (one add latency per element,
/// about 1 ms per 1e6 terms); eight independent sums let the compiler use vector registers and
/// overlap the additions, about 4x faster on records of 1e5 samples and more. The rounding
/// differs from the sequential sum by the usual `O(n eps)` bound of either order.
///
/// ```
/// let a: Vec<f64> = (0..19).map(f64::from).collect();
/// assert_eq!(ident::lm::dot(&a, &a), (0..19).map(|k| f64::from(k * k)).sum::<f64>());
/// ```
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    sum_of2(a, b, |x, y| x * y)
}

/// `sum_i r_i^2` ([`dot`] of `r` with itself).
pub fn sumsq(r: &[f64]) -> f64 {
    dot(r, r)
}

fn norm(v: &[f64]) -> f64 {
    sumsq(v).sqrt()
}

/// Minimise `1/2 sum_i r_i(p)^2` from `p0` by Levenberg-Marquardt (see the [module docs](self)).
///
/// ```
/// use ident::lm::{minimize, LmOptions, Mat, Problem};
///
/// // Fit y = a exp(-b t) to exact data with a = 2, b = 0.5.
/// struct Exp { t: Vec<f64>, y: Vec<f64> }
/// impl Problem for Exp {
///     fn n_params(&self) -> usize { 2 }
///     fn n_residuals(&self) -> usize { self.t.len() }
///     fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> ident::Result<()> {
///         for (i, (&t, &y)) in self.t.iter().zip(&self.y).enumerate() {
///             r[i] = p[0] * (-p[1] * t).exp() - y;
///         }
///         if let Some(j) = jac {
///             for (i, &t) in self.t.iter().enumerate() {
///                 j[(i, 0)] = (-p[1] * t).exp();
///                 j[(i, 1)] = -p[0] * t * (-p[1] * t).exp();
///             }
///         }
///         Ok(())
///     }
/// }
/// let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.5).collect();
/// let y = t.iter().map(|t| 2.0 * (-0.5 * t).exp()).collect();
/// let rep = minimize(&mut Exp { t, y }, &[1.0, 1.0], &LmOptions::default()).unwrap();
/// assert!(rep.converged);
/// assert!((rep.params[0] - 2.0).abs() < 1e-8 && (rep.params[1] - 0.5).abs() < 1e-8);
/// ```
///
/// # Errors
/// [`Error::Options`] for a wrong `p0` length, no parameters, no residuals or bad options;
/// [`Error::Numerical`] for non-finite residuals or Jacobian at `p0` (or later at an accepted
/// point); any error of [`Problem::eval`] at `p0`. Non-convergence is *not* an error.
pub fn minimize(problem: &mut impl Problem, p0: &[f64], opts: &LmOptions) -> Result<LmReport> {
    let n = problem.n_params();
    let m = problem.n_residuals();
    if n == 0 || m == 0 {
        return Err(Error::Options(format!(
            "Levenberg-Marquardt needs at least one parameter and one residual (got {n} and {m})"
        )));
    }
    if p0.len() != n {
        return Err(Error::Options(format!(
            "starting point has {} parameters, the problem {n}",
            p0.len()
        )));
    }
    if let Some(i) = p0.iter().position(|v| !v.is_finite()) {
        return Err(Error::Options(format!(
            "starting parameter {i} is {}",
            p0[i]
        )));
    }
    let tols = [opts.gtol, opts.xtol, opts.ftol, opts.initial_lambda];
    if tols.iter().any(|t| !t.is_finite() || *t < 0.0) || opts.initial_lambda <= 0.0 {
        return Err(Error::Options(
            "tolerances must be finite and >= 0, initial_lambda > 0".into(),
        ));
    }
    let max_evals = if opts.max_evaluations == 0 {
        100 * (n + 1) + opts.max_iterations
    } else {
        opts.max_evaluations
    };

    let mut p = p0.to_vec();
    let mut r = vec![0.0; m];
    let mut jac = Mat::<f64>::zeros(m, n);
    problem.eval(&p, &mut r, Some(&mut jac))?;
    let mut evaluations = 1;
    check_finite(&r, &jac, "at the starting point")?;
    let mut cost = 0.5 * sumsq(&r);

    let mut diag = vec![0.0f64; n];
    let mut lambda = opts.initial_lambda;
    let mut nu = 2.0;
    let mut iterations = 0;
    let mut r_trial = vec![0.0; m];
    let mut p_trial = vec![0.0; n];
    let mut gcos;

    // The QR of `[J r]` at the current point: R and Q^T r give the gradient, the column norms,
    // every damped step and its predicted cost, and the covariance at the end.
    let mut qr = qr_of_jr(&jac, &r);
    // The cost at the start and after each accepted iteration (the stall test).
    let mut history = vec![cost];
    let termination = 'outer: loop {
        // -- gradient test and scaling --
        let col_norms = col_norms_of(&qr.0);
        let rnorm = norm(&r);
        gcos = gradient_cosine(&jt_r_of(&qr.0, &qr.1), &col_norms, rnorm);
        if cost == 0.0 {
            break Termination::ZeroResidual;
        }
        if gcos <= opts.gtol {
            break Termination::SmallGradient;
        }
        for j in 0..n {
            diag[j] = if opts.scale {
                diag[j].max(col_norms[j])
            } else {
                1.0
            };
            if diag[j] == 0.0 {
                diag[j] = 1.0; // a parameter with no influence: damp it with unit weight
            }
        }
        if iterations >= opts.max_iterations {
            break Termination::MaxIterations;
        }
        iterations += 1;
        let (rmat, qtr) = (&qr.0, &qr.1);
        // |r|^2 - |Q^T r|^2: the part of r no step can reach.
        let r_out = (rnorm * rnorm - sumsq(qtr)).max(0.0);

        // -- inner loop over lambda until a step lowers the cost --
        loop {
            if evaluations >= max_evals {
                break 'outer Termination::MaxEvaluations;
            }
            if lambda > 1e30 {
                break 'outer Termination::NoProgress;
            }
            let d = damped_step(rmat, qtr, &diag, lambda);
            let dnorm = norm(&d.iter().zip(&diag).map(|(a, b)| a * b).collect::<Vec<_>>());
            let pnorm = norm(&p.iter().zip(&diag).map(|(a, b)| a * b).collect::<Vec<_>>());
            // predicted cost: 1/2 |r + J d|^2 = 1/2 (|Q^T r + R d|^2 + |r|^2 - |Q^T r|^2)
            let lin: Vec<f64> = (0..qtr.len())
                .map(|i| qtr[i] + (i..n).map(|j| rmat[(i, j)] * d[j]).sum::<f64>())
                .collect();
            let pred = cost - 0.5 * (sumsq(&lin) + r_out);
            for j in 0..n {
                p_trial[j] = p[j] + d[j];
            }
            evaluations += 1;
            let ok = d.iter().all(|v| v.is_finite())
                && problem.eval(&p_trial, &mut r_trial, None).is_ok()
                && r_trial.iter().all(|v| v.is_finite());
            let cost_trial = if ok {
                0.5 * sumsq(&r_trial)
            } else {
                f64::INFINITY
            };
            let actual = cost - cost_trial;
            let rho = if pred > 0.0 { actual / pred } else { -1.0 };

            let small_cost =
                ok && actual.abs() <= opts.ftol * cost && pred <= opts.ftol * cost && rho <= 2.0;
            let small_step = dnorm <= opts.xtol * (pnorm + opts.xtol);

            if ok && rho > 0.0 && actual > 0.0 {
                // accept
                std::mem::swap(&mut p, &mut p_trial);
                let stalled = opts.stall.is_some_and(|(k, rel)| {
                    k > 0
                        && history.len() >= k
                        && history[history.len() - k] - cost_trial
                            <= rel * history[history.len() - k]
                });
                if !opts.covariance && (small_cost || small_step || stalled) {
                    // The fit stops here and nothing needs the Jacobian at this point (no
                    // covariance): the residual is the trial's, the gradient's cosine the last
                    // point's.
                    std::mem::swap(&mut r, &mut r_trial);
                    cost = cost_trial.max(0.0);
                    let t = 2.0 * rho - 1.0;
                    lambda *= (1.0 - t * t * t).max(1.0 / 3.0);
                    history.push(cost);
                    break 'outer if small_cost || !small_step {
                        Termination::SmallCostChange
                    } else {
                        Termination::SmallStep
                    };
                }
                evaluations += 1;
                let jac_ok = problem.eval(&p, &mut r, Some(&mut jac)).is_ok()
                    && check_finite(&r, &jac, "at an accepted point").is_ok();
                if !jac_ok {
                    // The point simulates but its sensitivities do not (a model at the edge
                    // of what the approximation can represent): take the step back, restore
                    // the residual and Jacobian of the last good point, and damp more.
                    std::mem::swap(&mut p, &mut p_trial);
                    // (`qr` is still that of this point's `J` and `r`.)
                    problem.eval(&p, &mut r, Some(&mut jac))?;
                    evaluations += 1;
                    lambda *= nu;
                    nu *= 2.0;
                    continue;
                }
                cost = cost_trial;
                cost = cost.min(0.5 * sumsq(&r)).max(0.0);
                let t = 2.0 * rho - 1.0;
                lambda *= (1.0 - t * t * t).max(1.0 / 3.0);
                nu = 2.0;
                qr = qr_of_jr(&jac, &r);
                history.push(cost);
                let stalled = opts.stall.is_some_and(|(k, rel)| {
                    k > 0
                        && history.len() > k
                        && history[history.len() - 1 - k] - cost
                            <= rel * history[history.len() - 1 - k]
                });
                let hopeless = opts.give_up.is_some_and(|(k, target)| {
                    k > 0 && history.len() > k && {
                        let fall = (history[history.len() - 1 - k] - cost) / k as f64;
                        let left = opts.max_iterations.saturating_sub(iterations) as f64;
                        cost - fall.max(0.0) * left > target
                    }
                });
                if small_cost || small_step || stalled || hopeless {
                    gcos = gradient_cosine(&jt_r_of(&qr.0, &qr.1), &col_norms_of(&qr.0), norm(&r));
                    break 'outer if small_cost || !small_step {
                        Termination::SmallCostChange
                    } else {
                        Termination::SmallStep
                    };
                }
                break;
            }
            // reject
            if small_cost {
                break 'outer Termination::SmallCostChange;
            }
            if small_step && ok {
                break 'outer Termination::SmallStep;
            }
            lambda *= nu;
            nu *= 2.0;
        }
    };

    let (covariance, std_errors) = if opts.covariance && m > n {
        // The R of `J` is the leading block of the R of `[J r]` (`qr` is always that of the
        // current `J` and `r`).
        let held: Vec<bool> = (0..n).map(|j| problem.at_bound(j, p[j])).collect();
        covariance_and_errors(&qr.0, sumsq(&r) / (m - n) as f64, &held)
    } else {
        (None, None)
    };

    Ok(LmReport {
        params: p,
        cost,
        residuals: r,
        iterations,
        evaluations,
        termination,
        converged: termination.is_converged(),
        covariance,
        std_errors,
        lambda,
        gradient_cosine: gcos,
    })
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

/// The Gauss-Newton step `d = -(R^T R + lambda D^2)^-1 g` for `J^T J = R^T R`, the gradient
/// `g = J^T r` and `D^2 = diag(R^T R)` (1 for a zero column), in the parameters not `held` (a held
/// one's step is 0), with its predicted reduction of the sum of squares `-2 g.d - |R d|^2`
/// (`None` if the small system is not positive definite).
fn gauss_newton_step(
    rmat: &Mat<f64>,
    g: &[f64],
    lambda: f64,
    held: &[bool],
) -> Option<(Vec<f64>, f64)> {
    let n = rmat.ncols();
    let free: Vec<usize> = (0..n).filter(|&j| !held[j]).collect();
    let mut d = vec![0.0; n];
    if !free.is_empty() {
        let ata = rmat.tr_mul(rmat);
        let k = free.len();
        let mut a = Mat::<f64>::from_fn(k, k, |i, j| ata[(free[i], free[j])]);
        for j in 0..k {
            let d2 = a[(j, j)];
            a[(j, j)] += lambda * if d2 > 0.0 { d2 } else { 1.0 };
        }
        let llt = a.cholesky()?;
        let rhs = Mat::<f64>::from_fn(k, 1, |i, _| -g[free[i]]);
        let x = llt.solve(&rhs);
        for (i, &j) in free.iter().enumerate() {
            d[j] = x[(i, 0)];
        }
    }
    let rd2: f64 = (0..rmat.nrows())
        .map(|i| {
            let v: f64 = (0..n).map(|j| rmat[(i, j)] * d[j]).sum();
            v * v
        })
        .sum();
    let pred = -2.0 * g.iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() - rd2;
    d.iter().all(|v| v.is_finite()).then_some((d, pred))
}

/// Below this many entries of `J`, the passes over it ([`jt_r`], [`qr_of_jr`]) run on one
/// thread (a thread costs more than it saves).
const PARALLEL_ENTRIES: usize = 1 << 17;

/// `f` of the rows `0..m` of a `m x n` matrix: of `0..m/2` and `m/2..m` on two threads when
/// the matrix is large and the machine has two cores (the passes over `J` are bound by memory
/// bandwidth, which one core does not use up), else of `0..m` alone.
fn on_row_halves<T: Send>(m: usize, n: usize, f: impl Fn(Range<usize>) -> T + Sync) -> Vec<T> {
    if m * n < PARALLEL_ENTRIES || m < 2 || !two_cores() {
        return vec![f(0..m)];
    }
    let half = m / 2;
    std::thread::scope(|sc| {
        let second = sc.spawn(|| f(half..m));
        let first = f(0..half);
        // `f` does not panic here; were the thread lost, its half is computed on this one.
        let second = second.join().unwrap_or_else(|_| f(half..m));
        vec![first, second]
    })
}

/// Whether the machine has at least two cores (the two-thread paths here and in the fit). Asked
/// once per process: `available_parallelism` reads the affinity mask and the cgroup quota files
/// (system calls and file reads; it was 8% of a 400-sample fit asking per pass).
pub(crate) fn two_cores() -> bool {
    static TWO: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *TWO.get_or_init(|| std::thread::available_parallelism().is_ok_and(|c| c.get() >= 2))
}

/// Rows of `J` taken at a time by [`jt_r_rows`]: their part of `r` (32 KiB) stays in the L1
/// cache while every column reads it.
const JT_R_BLOCK: usize = 4096;

/// `J^T r` over the rows `rows` only, a block of rows at a time (one pass over `J`; `r` is read
/// from memory once, not once per column).
fn jt_r_rows(jac: &Mat<f64>, r: &[f64], rows: Range<usize>) -> Vec<f64> {
    let mut g = vec![0.0; jac.ncols()];
    let mut a = rows.start;
    while a < rows.end {
        let b = (a + JT_R_BLOCK).min(rows.end);
        for (j, gj) in g.iter_mut().enumerate() {
            *gj += dot(&jac.col_as_slice(j)[a..b], &r[a..b]);
        }
        a = b;
    }
    g
}

/// `G += J[rows]^T J[rows]` (`G` is `n x n`): the upper triangle by [`dot`]s of the
/// columns' parts (`rows` is a block that stays in the cache), mirrored below.
fn gram_add(gram: &mut Mat<f64>, jac: &Mat<f64>, rows: Range<usize>) {
    let n = jac.ncols();
    for j in 0..n {
        let cj = &jac.col_as_slice(j)[rows.clone()];
        for i in 0..=j {
            let v = gram[(i, j)] + dot(&jac.col_as_slice(i)[rows.clone()], cj);
            gram[(i, j)] = v;
            gram[(j, i)] = v;
        }
    }
}

/// Column `j` of a matrix as one slice (nalgebra's dense matrices are column-major).
pub(crate) trait ColSlices {
    /// Column `j`, contiguous.
    fn col_as_slice(&self, j: usize) -> &[f64];
    /// Column `j`, contiguous and writable.
    fn col_as_slice_mut(&mut self, j: usize) -> &mut [f64];
}

impl ColSlices for Mat<f64> {
    fn col_as_slice(&self, j: usize) -> &[f64] {
        let m = self.nrows();
        &self.as_slice()[j * m..(j + 1) * m]
    }

    fn col_as_slice_mut(&mut self, j: usize) -> &mut [f64] {
        let m = self.nrows();
        &mut self.as_mut_slice()[j * m..(j + 1) * m]
    }
}

/// The least-squares solution `X` of `min ||A X - B||` (`A` is `m x n`, `m >= n`) by Householder
/// QR (nalgebra's): `R X = (Q^T B)[..n]` by back substitution. A zero pivot (dependent columns)
/// gives infinite or NaN entries, not an error: callers check them.
pub(crate) fn lstsq(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let n = a.ncols();
    let qr = a.clone().qr();
    let mut qtb = b.clone();
    qr.q_tr_mul(&mut qtb);
    let r = qr.r();
    let k = r.nrows().min(n);
    let mut x = Mat::<f64>::zeros(n, b.ncols());
    for c in 0..b.ncols() {
        for i in (0..k).rev() {
            let s: f64 = (i + 1..n).map(|j| r[(i, j)] * x[(j, c)]).sum();
            x[(i, c)] = (qtb[(i, c)] - s) / r[(i, i)];
        }
    }
    x
}

/// `J^T r`, in two halves of the rows on two threads for a large `J`.
fn jt_r(jac: &Mat<f64>, r: &[f64]) -> Vec<f64> {
    let parts = on_row_halves(jac.nrows(), jac.ncols(), |rows| jt_r_rows(jac, r, rows));
    (0..jac.ncols())
        .map(|j| parts.iter().map(|g| g[j]).sum())
        .collect()
}

/// `J^T r = R^T (Q^T r)` from the QR of `[J r]` ([`qr_of_jr`]), without a pass over `J`.
fn jt_r_of(rmat: &Mat<f64>, qtr: &[f64]) -> Vec<f64> {
    (0..rmat.ncols())
        .map(|j| {
            (0..rmat.nrows().min(j + 1))
                .map(|i| rmat[(i, j)] * qtr[i])
                .sum()
        })
        .collect()
}

/// The column norms `|J e_j| = |R e_j|` (`Q` has orthonormal columns), from the `R` of
/// [`qr_of_jr`].
fn col_norms_of(rmat: &Mat<f64>) -> Vec<f64> {
    (0..rmat.ncols())
        .map(|j| {
            (0..rmat.nrows().min(j + 1))
                .map(|i| rmat[(i, j)] * rmat[(i, j)])
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

/// Gauss-Newton from a point near the least-squares optimum (the optimum of part of the data,
/// say), with few Jacobians: each round evaluates the Jacobian `J` once, then takes chord steps
/// (Ortega & Rheinboldt 1970, the simplified Newton method) `d_k = -(J^T J)^-1 J^T r(p_k)`,
/// which need only the residuals; the round ends when a step's predicted reduction is under
/// `chord_tolerance^2 sigma^2` (a chord step that small is not taken: the next round's
/// Gauss-Newton step contains it). The next round's Jacobian is at that point: when its own
/// Gauss-Newton step is under `tolerance^2 sigma^2` (see [`RefineOptions`]) the step is taken
/// (if it lowers the cost) and the fit ends, its covariance from that Jacobian. A chord step
/// converges linearly (at the rate of the change of `J` over the steps, small near the
/// optimum), the final test is on the exact gradient, so the result is the optimum to the stated
/// tolerance, not that of the frozen Jacobian.
///
/// Whenever a step does not lower the cost, the small system is not positive definite, or the
/// rounds run out, [`minimize`] takes over from the best point with `opts` (its report then
/// counts the work of both).
///
/// ```
/// use ident::lm::{refine, LmOptions, Mat, Problem, RefineOptions};
/// struct Exp { t: Vec<f64>, y: Vec<f64> }
/// impl Problem for Exp {
///     fn n_params(&self) -> usize { 2 }
///     fn n_residuals(&self) -> usize { self.t.len() }
///     fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> ident::Result<()> {
///         for (i, (&t, &y)) in self.t.iter().zip(&self.y).enumerate() {
///             r[i] = p[0] * (-p[1] * t).exp() - y;
///         }
///         if let Some(j) = jac {
///             for (i, &t) in self.t.iter().enumerate() {
///                 j[(i, 0)] = (-p[1] * t).exp();
///                 j[(i, 1)] = -p[0] * t * (-p[1] * t).exp();
///             }
///         }
///         Ok(())
///     }
/// }
/// let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.05).collect();
/// // a little deterministic "noise"
/// let y = t.iter().enumerate().map(|(i, t)| 2.0 * (-0.5 * t).exp() + 1e-3 * ((i * 7 % 5) as f64 - 2.0)).collect();
/// let rep = refine(&mut Exp { t, y }, &[2.01, 0.49], &LmOptions::default(), &RefineOptions::default()).unwrap();
/// assert!(rep.converged && rep.std_errors.is_some());
/// assert!((rep.params[0] - 2.0).abs() < 1e-2);
/// ```
///
/// # Errors
/// As [`minimize`].
pub fn refine(
    problem: &mut impl Problem,
    p0: &[f64],
    opts: &LmOptions,
    ropts: &RefineOptions,
) -> Result<LmReport> {
    let bufs = RefineBuffers::new(problem.n_residuals(), problem.n_params());
    refine_with(problem, p0, opts, ropts, bufs)
}

/// The Jacobian and the two residual vectors [`refine`] works in (`m x n`, `m`, `m`), written
/// through once so that their pages are mapped: on a long record that costs as much as a
/// simulation, and a caller with a core to spare makes them there ([`refine_with`]).
#[derive(Debug)]
pub struct RefineBuffers {
    jac: Mat<f64>,
    r: Vec<f64>,
    r_trial: Vec<f64>,
}

impl RefineBuffers {
    /// Buffers for `m` residuals and `n` parameters, zeroed.
    pub fn new(m: usize, n: usize) -> Self {
        let touched = |m: usize| {
            let mut v = Vec::with_capacity(m);
            v.resize(m, 0.0);
            // The write through `black_box` maps the pages here: `vec![0.0; m]` (and a zeroing
            // of a fresh allocation the compiler may turn into one) gets lazily zeroed pages,
            // faulted in at the first write, in the fit.
            std::hint::black_box(v.as_mut_slice()).fill(0.0);
            v
        };
        Self {
            jac: Mat::zeros(m, n),
            r: touched(m),
            r_trial: touched(m),
        }
    }
}

/// [`refine`] in the given buffers (new ones if their sizes are not the problem's).
///
/// # Errors
/// As [`refine`].
pub fn refine_with(
    problem: &mut impl Problem,
    p0: &[f64],
    opts: &LmOptions,
    ropts: &RefineOptions,
    bufs: RefineBuffers,
) -> Result<LmReport> {
    let (n, m) = (problem.n_params(), problem.n_residuals());
    if n == 0 || m <= n || p0.len() != n || p0.iter().any(|v| !v.is_finite()) {
        return minimize(problem, p0, opts);
    }
    let RefineBuffers {
        mut jac,
        mut r,
        mut r_trial,
    } = if bufs.jac.nrows() == m
        && bufs.jac.ncols() == n
        && bufs.r.len() == m
        && bufs.r_trial.len() == m
    {
        bufs
    } else {
        RefineBuffers::new(m, n)
    };
    // Damping only to keep the small system definite: the chord's fixed point does not depend
    // on it.
    let lambda = opts.initial_lambda.clamp(1e-14, 1e-8);
    let mut p = p0.to_vec();
    let mut evaluations = 0;
    let handover = |problem: &mut _, p: &[f64], evaluations: usize, rounds: usize| {
        let mut rep = minimize(problem, p, opts)?;
        rep.evaluations += evaluations;
        rep.iterations += rounds;
        Ok(rep)
    };
    for round in 0..ropts.max_rounds {
        evaluations += 1;
        if problem.eval(&p, &mut r, Some(&mut jac)).is_err() {
            return handover(problem, &p, evaluations, round);
        }
        let mut ssr = sumsq(&r);
        let sigma2 = ssr / (m - n) as f64;
        // The finiteness of `r` and `J` is checked on what the factorisation reads anyway: a
        // non-finite residual makes `ssr` non-finite, a non-finite entry of `J` the Gram
        // matrix's diagonal (the Householder QR only runs after a full check).
        let qr = ssr
            .is_finite()
            .then(|| {
                cholesky_qr_of_jr(&jac, &r).or_else(|| {
                    check_finite(&r, &jac, "")
                        .is_ok()
                        .then(|| householder_qr_of_jr(&jac, &r))
                })
            })
            .flatten();
        let Some((mut rmat, qtr)) = qr.filter(|(rm, q)| {
            all_finite(q) && (0..rm.ncols()).all(|j| rm.column(j).iter().all(|v| v.is_finite()))
        }) else {
            return handover(problem, &p, evaluations, round);
        };
        // The chord's Jacobian is `J S`: the round's `J`, its columns rescaled as the
        // parameters move ([`Problem::column_scale`]); `R S` is its `R`.
        let mut scale = vec![1.0; n];
        // g = J^T r = R^T (Q^T r) at the round's point.
        let mut g = jt_r_of(&rmat, &qtr);
        let held: Vec<bool> = (0..n).map(|j| problem.at_bound(j, p[j])).collect();
        let Some((d, pred)) = gauss_newton_step(&rmat, &g, lambda, &held) else {
            return handover(problem, &p, evaluations, round);
        };
        let last = pred <= ropts.tolerance * ropts.tolerance * sigma2;
        let (mut d, mut pred) = (d, pred);
        let mut first = true;
        for _ in 0..ropts.max_chord_steps.max(1) {
            let trial: Vec<f64> = p.iter().zip(&d).map(|(a, b)| a + b).collect();
            evaluations += 1;
            // (A non-finite residual makes the sum non-finite.)
            let ssr_trial = match problem.eval(&trial, &mut r_trial, None) {
                Ok(()) => Some(sumsq(&r_trial)).filter(|s| s.is_finite()),
                Err(_) => None,
            }
            .unwrap_or(f64::INFINITY);
            if !(ssr_trial <= ssr) {
                if last {
                    // The step was below the tolerance and does not lower the cost: `p` is the
                    // optimum to rounding.
                    break;
                }
                if first {
                    // The round's own Gauss-Newton step fails: LM's damping is needed.
                    return handover(problem, &p, evaluations, round + 1);
                }
                // A chord step fails (the Jacobian changed too much): a new round from here.
                break;
            }
            first = false;
            for j in 0..n {
                if let Some(f) = problem
                    .column_scale(j, p[j], trial[j])
                    .filter(|f| f.is_finite() && *f > 0.0)
                {
                    scale[j] *= f;
                    rmat.column_mut(j).iter_mut().for_each(|v| *v *= f);
                }
            }
            p = trial;
            std::mem::swap(&mut r, &mut r_trial);
            ssr = ssr_trial;
            if last || pred <= ropts.chord_tolerance * ropts.chord_tolerance * sigma2 {
                break;
            }
            // The chord step: the same J^T J, the gradient with the round's J.
            g = scaled(jt_r(&jac, &r), &scale);
            match gauss_newton_step(&rmat, &g, lambda, &held) {
                Some(dp) => (d, pred) = dp,
                None => return handover(problem, &p, evaluations, round + 1),
            }
            if pred <= ropts.chord_tolerance * ropts.chord_tolerance * sigma2 {
                // A chord step this small is not worth a simulation: the next round's Jacobian
                // is taken here, and its own step includes this one.
                break;
            }
        }
        if last {
            let (covariance, std_errors) = if opts.covariance {
                covariance_and_errors(&rmat, ssr / (m - n) as f64, &held)
            } else {
                (None, None)
            };
            // The gradient at the final point (the step was taken), with the round's Jacobian.
            let g_end = scaled(jt_r(&jac, &r), &scale);
            return Ok(LmReport {
                params: p,
                cost: 0.5 * ssr,
                gradient_cosine: gradient_cosine(&g_end, &col_norms_of(&rmat), norm(&r)),
                residuals: r,
                iterations: round + 1,
                evaluations,
                termination: Termination::SmallStatisticalStep,
                converged: true,
                covariance,
                std_errors,
                lambda,
            });
        }
    }
    handover(problem, &p, evaluations, ropts.max_rounds)
}

/// `v_j s_j` for each `j`.
fn scaled(mut v: Vec<f64>, s: &[f64]) -> Vec<f64> {
    v.iter_mut().zip(s).for_each(|(a, b)| *a *= b);
    v
}

/// `sum_i f(v_i)` in eight interleaved partial sums (vectorised, as in [`dot`]).
pub(crate) fn sum_of(v: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    const LANES: usize = 8;
    let mut acc = [0.0; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().map(|&x| f(x)).sum();
    for c in chunks {
        for l in 0..LANES {
            acc[l] += f(c[l]);
        }
    }
    acc.iter().sum::<f64>() + tail
}

pub(crate) use fracsim::lanes::sum_of2;

/// `(min, max)` of `v` (`(inf, -inf)` when empty; NaNs are passed over, as by `f64::min`), in
/// eight lanes (one vectorised pass; a fold of `f64::min` is a chain of dependent operations).
/// Each lane keeps its extreme by a comparison and a select, which compiles to the machine's
/// min and max instructions; `f64::min`'s NaN rules cost three instructions more a vector.
pub(crate) fn range_of(v: &[f64]) -> (f64, f64) {
    const LANES: usize = 8;
    let (mut lo, mut hi) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
    let chunks = v.chunks_exact(LANES);
    for &x in chunks.remainder() {
        lo[0] = lo[0].min(x);
        hi[0] = hi[0].max(x);
    }
    for c in chunks {
        for l in 0..LANES {
            // (A NaN compares false: the lane keeps its value.)
            lo[l] = if c[l] < lo[l] { c[l] } else { lo[l] };
            hi[l] = if c[l] > hi[l] { c[l] } else { hi[l] };
        }
    }
    (
        lo.iter().fold(f64::INFINITY, |a, &b| a.min(b)),
        hi.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b)),
    )
}

/// Whether every entry of `v` (its value part, for a dual number) is finite: `0 x` is 0 for a
/// finite `x` and NaN otherwise, and a sum of those in eight lanes is one vectorised pass where
/// a search is not.
pub(crate) fn all_finite<T: fracsim::Real>(v: &[T]) -> bool {
    const LANES: usize = 8;
    let chunks = v.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().map(|x| x.re() * 0.0).sum();
    let mut acc = [0.0; LANES];
    for c in chunks {
        for l in 0..LANES {
            acc[l] += c[l].re() * 0.0;
        }
    }
    acc.iter().sum::<f64>() + tail == 0.0
}

fn check_finite(r: &[f64], jac: &Mat<f64>, when: &str) -> Result<()> {
    let n = jac.ncols();
    let halves = on_row_halves(jac.nrows(), n, |rows| {
        all_finite(&r[rows.clone()])
            && (0..n).all(|j| all_finite(&jac.col_as_slice(j)[rows.clone()]))
    });
    if halves.iter().all(|ok| *ok) {
        return Ok(());
    }
    if let Some(i) = r.iter().position(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!("residual {i} is {} {when}", r[i])));
    }
    for j in 0..jac.ncols() {
        if let Some(i) = jac.col_as_slice(j).iter().position(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "Jacobian entry ({i}, {j}) is {} {when}",
                jac[(i, j)]
            )));
        }
    }
    Ok(())
}

/// `max_j |g_j| / (|J e_j| |r|)` for the gradient `g = J^T r` (MINPACK's `gtol` test).
fn gradient_cosine(g: &[f64], col_norms: &[f64], rnorm: f64) -> f64 {
    if rnorm == 0.0 {
        return 0.0;
    }
    g.iter()
        .zip(col_norms)
        .map(|(g, &c)| if c == 0.0 { 0.0 } else { g.abs() / (c * rnorm) })
        .fold(0.0, f64::max)
}

/// Rows of `[J r]` factored at a time by [`qr_of_jr`].
const QR_BLOCK: usize = 8192;

/// QR of `[J r]`: returns the `k x n` upper-trapezoidal `R` (k = min(m, n)) and `Q^T r` (length k).
///
/// A well-conditioned `J` is factored through its Gram matrix ([`cholesky_qr_of_jr`]: one pass
/// over the data, a matrix product instead of `n` reflections); any other by Householder
/// reflections ([`householder_qr_of_jr`]). `R` is unique up to the signs of its rows, which
/// `Q^T r` shares, so every use below (the damped steps, the covariance, `J^T r = R^T Q^T r`) is
/// the same.
fn qr_of_jr(jac: &Mat<f64>, r: &[f64]) -> (Mat<f64>, Vec<f64>) {
    cholesky_qr_of_jr(jac, r).unwrap_or_else(|| householder_qr_of_jr(jac, r))
}

/// The smallest pivot of the column-scaled Cholesky factor [`cholesky_qr_of_jr`] accepts: `J`'s
/// columns, scaled to unit norm, have a condition number of about `1/MIN_PIVOT` or less, so the
/// Gram matrix (whose condition is the square) loses at most about `1e-16 / MIN_PIVOT^2 = 1e-6`
/// relative in `R`, far below what a damped step or a standard error needs.
const MIN_PIVOT: f64 = 1e-5;

/// Cholesky QR (e.g. Yamamoto et al. 2015) of `[J r]`: `J^T J = R^T R` with `R` the Cholesky factor
/// of the Gram matrix (columns scaled to unit norm first), and `Q^T r = R^-T (J^T r)`. `None`
/// when `m < n`, a column is zero, or a scaled pivot is under [`MIN_PIVOT`] (nearly dependent
/// columns): the Householder QR then does it.
fn cholesky_qr_of_jr(jac: &Mat<f64>, r: &[f64]) -> Option<(Mat<f64>, Vec<f64>)> {
    let (m, n) = (jac.nrows(), jac.ncols());
    if m < n || n == 0 {
        return None;
    }
    // The Gram matrix and J^T r of each block of rows together: the block is read from memory
    // once, and from the cache by the second.
    let parts = on_row_halves(m, n, |rows| {
        let mut gram = Mat::<f64>::zeros(n, n);
        let mut g = vec![0.0; n];
        let mut a = rows.start;
        while a < rows.end {
            let b = (a + JT_R_BLOCK).min(rows.end);
            gram_add(&mut gram, jac, a..b);
            g.iter_mut()
                .zip(jt_r_rows(jac, r, a..b))
                .for_each(|(x, y)| *x += y);
            a = b;
        }
        (gram, g)
    });
    let mut gram = Mat::<f64>::zeros(n, n);
    let mut g = vec![0.0; n];
    for (gp, gr) in &parts {
        gram += gp;
        g.iter_mut().zip(gr).for_each(|(a, b)| *a += b);
    }
    let d: Vec<f64> = (0..n).map(|j| gram[(j, j)].sqrt()).collect();
    if d.iter().any(|v| !(*v > 0.0 && v.is_finite())) {
        return None;
    }
    // L L^T = D^-1 G D^-1 (unit diagonal), lower triangular, row-major.
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let s = 1.0 - (0..j).map(|k| l[j * n + k] * l[j * n + k]).sum::<f64>();
        if !(s > MIN_PIVOT * MIN_PIVOT) {
            return None;
        }
        let ljj = s.sqrt();
        l[j * n + j] = ljj;
        for i in j + 1..n {
            let sij = gram[(i, j)] / (d[i] * d[j]);
            let dot: f64 = (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            l[i * n + j] = (sij - dot) / ljj;
        }
    }
    // R = L^T D.
    let rmat = Mat::<f64>::from_fn(n, n, |i, j| if j >= i { l[j * n + i] * d[j] } else { 0.0 });
    // R^T q = g by forward substitution.
    let mut q = vec![0.0; n];
    for i in 0..n {
        let s: f64 = (0..i).map(|k| rmat[(k, i)] * q[k]).sum();
        q[i] = (g[i] - s) / rmat[(i, i)];
    }
    q.iter().all(|v| v.is_finite()).then_some((rmat, q))
}

/// Householder QR of `[J r]`, as [`qr_of_jr`] returns it.
///
/// Factored by blocks of rows (the tall-skinny QR): the `R` of the rows so far stacked on the
/// next [`QR_BLOCK`] rows is factored again, so memory stays one block whatever the record's
/// length and `[J r]` is never copied whole.
fn householder_qr_of_jr(jac: &Mat<f64>, r: &[f64]) -> (Mat<f64>, Vec<f64>) {
    let (m, n) = (jac.nrows(), jac.ncols());
    let w = n + 1;
    let col = |j: usize| if j < n { jac.col_as_slice(j) } else { r };
    // Each half of the rows (on two threads for a large J) to its R, then the two stacked.
    let tops = on_row_halves(m, w, |rows| tsqr(|j| &col(j)[rows.clone()], rows.len(), w));
    let top = if let [a, b] = &tops[..] {
        tsqr(
            |j| {
                if j < w {
                    a.col_as_slice(j)
                } else {
                    b.col_as_slice(j - w)
                }
            },
            0,
            w,
        )
    } else {
        tops.into_iter().next().unwrap_or_else(|| Mat::zeros(0, w))
    };
    // `top` has min(m, n + 1) >= k rows.
    let k = m.min(n);
    let rmat = Mat::<f64>::from_fn(k, n, |i, j| top[(i, j)]);
    let qtr = (0..k).map(|i| top[(i, n)]).collect();
    (rmat, qtr)
}

/// The `R` (at most `w x w`) of the `m x w` matrix whose column `j` is `col(j)`, by blocks of
/// [`QR_BLOCK`] rows: the `R` of the rows so far stacked on the next block is factored again
/// ([`householder_r`]). With `m = 0`, the `R` of two stacked `R`s: column `j` of the upper one is
/// `col(j)`, of the lower one `col(w + j)` (each as long as the `R` has rows).
fn tsqr<'a>(col: impl Fn(usize) -> &'a [f64], m: usize, w: usize) -> Mat<f64> {
    if m == 0 {
        let (ha, hb) = (col(0).len(), col(w).len());
        let mut a = Vec::with_capacity((ha + hb) * w);
        for j in 0..w {
            a.extend_from_slice(col(j));
            a.extend_from_slice(col(w + j));
        }
        return householder_r(&mut a, ha + hb, w);
    }
    let mut top = Mat::<f64>::zeros(0, w);
    let mut a = Vec::with_capacity((QR_BLOCK + w) * w);
    let mut start = 0;
    while start < m {
        let end = (start + QR_BLOCK).min(m);
        let rows = top.nrows() + end - start;
        a.clear();
        for j in 0..w {
            a.extend_from_slice(top.col_as_slice(j));
            a.extend_from_slice(&col(j)[start..end]);
        }
        top = householder_r(&mut a, rows, w);
        start = end;
    }
    top
}

/// The `R` (`min(rows, w) x w`, upper trapezoidal) of the `rows x w` column-major matrix `a`
/// (overwritten) by Householder reflections (Golub & Van Loan 2013, algorithm 5.2.1, with
/// LAPACK's `dlarfg` reflector: `H = I - tau v v^T`, `v_0 = 1`, `H x = beta e_0`,
/// `beta = -sign(x_0) |x|`).
///
/// Unblocked: for the few columns of a Jacobian the reflections are dot products and updates of
/// whole columns, which stay in the cache for a block of [`QR_BLOCK`] rows. A column norm whose
/// square would over- or underflow is computed scaled by the column's largest entry.
fn householder_r(a: &mut [f64], rows: usize, w: usize) -> Mat<f64> {
    debug_assert_eq!(a.len(), rows * w);
    let k = rows.min(w);
    for j in 0..k {
        let (left, right) = a.split_at_mut((j + 1) * rows);
        let x = &mut left[j * rows + j..];
        let alpha = x[0];
        let sq = alpha * alpha + sumsq(&x[1..]);
        let norm = if sq > 1e-280 && sq < 1e280 {
            sq.sqrt()
        } else {
            let big = x.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            if big > 0.0 && big.is_finite() {
                big * sum_of(x, |v| (v / big) * (v / big)).sqrt()
            } else {
                big
            }
        };
        if norm == 0.0 {
            // A zero column: H = I.
            continue;
        }
        let beta = if alpha > 0.0 { -norm } else { norm };
        let tau = (beta - alpha) / beta;
        let scale = 1.0 / (alpha - beta);
        x[0] = beta;
        let v = &mut x[1..];
        v.iter_mut().for_each(|e| *e *= scale);
        let v = &*v;
        for c in right.chunks_exact_mut(rows) {
            let c = &mut c[j..];
            let s = tau * (c[0] + dot(v, &c[1..]));
            c[0] -= s;
            c[1..].iter_mut().zip(v).for_each(|(e, vi)| *e -= s * vi);
        }
    }
    Mat::<f64>::from_fn(k, w, |i, j| if j >= i { a[j * rows + i] } else { 0.0 })
}

/// Solve `min || R d + Q^T r ||^2 + lambda || D d ||^2` by QR of `[R; sqrt(lambda) D]`.
fn damped_step(rmat: &Mat<f64>, qtr: &[f64], diag: &[f64], lambda: f64) -> Vec<f64> {
    let (k, n) = (rmat.nrows(), rmat.ncols());
    let sl = lambda.sqrt();
    let a = Mat::<f64>::from_fn(k + n, n, |i, j| {
        if i < k {
            rmat[(i, j)]
        } else if i - k == j {
            sl * diag[j]
        } else {
            0.0
        }
    });
    let b = Mat::<f64>::from_fn(k + n, 1, |i, _| if i < k { -qtr[i] } else { 0.0 });
    let x = lstsq(&a, &b);
    (0..n).map(|j| x[(j, 0)]).collect()
}

/// [`covariance`] and the standard errors `sqrt(diag)`.
/// The covariance and standard errors from the `R` of `J`, with the parameters `held` at a
/// bound ([`Problem::at_bound`]) fixed there: the covariance of the others is that of the
/// columns of `J` without theirs (the `R` of `R[:, kept]`, which is `Q^T J[:, kept]`), and a
/// held parameter's rows and columns and standard error are NaN (it has no spread: it sits on
/// its bound). A held parameter's column is about zero (the bound's map is flat there), which
/// would otherwise make the whole covariance singular.
fn covariance_and_errors(
    rmat: &Mat<f64>,
    sigma2: f64,
    held: &[bool],
) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
    let n = rmat.ncols();
    let kept: Vec<usize> = (0..n)
        .filter(|&j| !held.get(j).copied().unwrap_or(false))
        .collect();
    let nk = kept.len();
    let cov = if nk == n {
        covariance(rmat, sigma2)
    } else if nk == 0 {
        None
    } else {
        let sub = Mat::<f64>::from_fn(rmat.nrows(), nk, |i, j| rmat[(i, kept[j])]);
        let r_sub = if sub.nrows() >= nk { sub.qr().r() } else { sub };
        covariance(&r_sub, sigma2).map(|c| {
            let mut full = vec![f64::NAN; n * n];
            for (a, &i) in kept.iter().enumerate() {
                for (b, &j) in kept.iter().enumerate() {
                    full[i * n + j] = c[a * nk + b];
                }
            }
            full
        })
    };
    match cov {
        Some(c) => {
            // (`f64::max` would turn a held parameter's NaN into 0.)
            let se = (0..n)
                .map(|i| match c[i * n + i] {
                    v if v.is_nan() => v,
                    v => v.max(0.0).sqrt(),
                })
                .collect();
            (Some(c), Some(se))
        }
        None => (None, None),
    }
}

/// `sigma2 (J^T J)^-1 = sigma2 R^-1 R^-T` from the `R` of `J` (`J^T J = R^T R`), row-major;
/// `None` if `R` is numerically singular (a diagonal entry below `1e-13` times the largest).
fn covariance(r: &Mat<f64>, sigma2: f64) -> Option<Vec<f64>> {
    let n = r.ncols();
    if r.nrows() < n {
        return None;
    }
    let rmax = (0..n).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    // 1e-13: about 500 ulp relative; below this the inverse is dominated by rounding.
    if rmax == 0.0 || (0..n).any(|i| r[(i, i)].abs() <= 1e-13 * rmax) {
        return None;
    }
    // Rinv, upper triangular, by back substitution column by column.
    let mut rinv = vec![0.0; n * n]; // row-major
    for c in 0..n {
        for i in (0..=c).rev() {
            let mut s = if i == c { 1.0 } else { 0.0 };
            for k in i + 1..=c {
                s -= r[(i, k)] * rinv[k * n + c];
            }
            rinv[i * n + c] = s / r[(i, i)];
        }
    }
    let mut cov = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let s: f64 = (i.max(j)..n)
                .map(|k| rinv[i * n + k] * rinv[j * n + k])
                .sum();
            cov[i * n + j] = sigma2 * s;
        }
    }
    if cov.iter().all(|v| v.is_finite()) {
        Some(cov)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded generator of uniform numbers in [-0.5, 0.5) (a 64-bit LCG).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// The blocked QR of `[J r]` (three blocks and a part; then, large enough for two halves of
    /// the rows on two threads, each of several blocks) against nalgebra's QR of the whole: the same
    /// `R` and `Q^T r` up to the sign of each row, to rounding.
    #[test]
    fn blocked_qr_equals_the_whole_qr() {
        blocked_qr_case(3 * QR_BLOCK + 517, 4);
        let n = 5;
        let m = 2 * PARALLEL_ENTRIES / (n + 1) + 517;
        assert!(m > 4 * QR_BLOCK);
        blocked_qr_case(m, n);
    }

    fn blocked_qr_case(m: usize, n: usize) {
        let mut rnd = uniform(7);
        let jac = Mat::<f64>::from_fn(m, n, |i, j| {
            rnd() + if j == 0 { 1e-3 * i as f64 } else { 0.0 }
        });
        let r: Vec<f64> = (0..m).map(|_| rnd()).collect();
        let whole = Mat::<f64>::from_fn(m, n + 1, |i, j| if j < n { jac[(i, j)] } else { r[i] });
        assert_same_r(&whole, householder_qr_of_jr(&jac, &r), 1e-11);
        // Well-conditioned: the Gram matrix path serves, to 1e-11 too (its error is machine
        // epsilon times the square of a small condition number).
        let chol = cholesky_qr_of_jr(&jac, &r).expect("a well-conditioned J");
        assert_same_r(&whole, chol.clone(), 1e-11);
        assert_eq!(qr_of_jr(&jac, &r), chol);
        // J^T r by halves of the rows, and from R and Q^T r, against the plain sums.
        let want: Vec<f64> = (0..n)
            .map(|j| (0..m).map(|i| jac[(i, j)] * r[i]).sum())
            .collect();
        let norms: Vec<f64> = (0..n)
            .map(|j| (0..m).map(|i| jac[(i, j)].powi(2)).sum::<f64>().sqrt())
            .collect();
        for (j, w) in want.iter().enumerate() {
            let tol = 1e-12 * norms[j] * sumsq(&r).sqrt();
            assert!((jt_r(&jac, &r)[j] - w).abs() < tol, "J^T r [{j}]");
            assert!(
                (jt_r_of(&chol.0, &chol.1)[j] - w).abs() < 1e3 * tol,
                "R^T Q^T r [{j}]"
            );
            assert!((col_norms_of(&chol.0)[j] - norms[j]).abs() < 1e-12 * norms[j]);
        }
    }

    /// A NaN or an infinity anywhere in `[J r]` (either half of the rows) is found and located.
    #[test]
    fn non_finite_entries_are_found_in_either_half() {
        let (m, n) = (2 * PARALLEL_ENTRIES / 3, 3);
        let mut rnd = uniform(3);
        let mut jac = Mat::<f64>::from_fn(m, n, |_, _| rnd());
        let mut r: Vec<f64> = (0..m).map(|_| rnd()).collect();
        assert!(check_finite(&r, &jac, "").is_ok());
        jac[(m - 3, 2)] = f64::INFINITY;
        let e = check_finite(&r, &jac, "").unwrap_err().to_string();
        assert!(e.contains(&format!("({}, 2)", m - 3)), "{e}");
        jac[(m - 3, 2)] = 0.5;
        r[7] = f64::NAN;
        let e = check_finite(&r, &jac, "").unwrap_err().to_string();
        assert!(e.contains("residual 7"), "{e}");
        // `dot`'s tail and lanes: every length up to three chunks.
        for len in 0..25 {
            let a: Vec<f64> = (0..len).map(|_| rnd()).collect();
            let want: f64 = a.iter().map(|x| x * x).sum();
            assert!((sumsq(&a) - want).abs() < 1e-15 * (1.0 + want), "len {len}");
            let mut b = a.clone();
            if len > 0 {
                b[len - 1] = f64::NEG_INFINITY;
                assert!(!all_finite(&b));
            }
            assert!(all_finite(&a));
        }
    }

    /// `(rmat, qtr)` equals the R of `whole = [J r]` (by nalgebra's QR) up to the signs of its rows:
    /// `R` to `tol` times each row's diagonal, `Q^T r` to `tol` times that or `|r|` (in a nearly
    /// dependent direction its error is about machine epsilon times the condition number times
    /// `|r|`, whichever of two backward-stable factorisations makes it).
    fn assert_same_r(whole: &Mat<f64>, (rmat, qtr): (Mat<f64>, Vec<f64>), tol: f64) {
        let n = whole.ncols() - 1;
        let want = whole.clone().qr().r();
        let rnorm = whole.column(n).norm();
        for i in 0..n {
            let sign = (want[(i, i)] * rmat[(i, i)]).signum();
            let scale = want[(i, i)].abs();
            for j in 0..n {
                assert!(
                    (sign * rmat[(i, j)] - want[(i, j)]).abs() < tol * scale,
                    "R[{i},{j}]"
                );
            }
            assert!(
                (sign * qtr[i] - want[(i, n)]).abs() < tol * scale.max(rnorm),
                "Q^T r [{i}]: {} vs {}",
                sign * qtr[i],
                want[(i, n)]
            );
        }
    }

    /// The unblocked Householder `R` against nalgebra's QR, up to the signs of its rows: a tall
    /// random matrix, a wide one (fewer rows than columns), one with columns of `1e200` and
    /// `1e-200` (whose squares over- and underflow: `R(A D) = R(A) D` for a positive diagonal
    /// `D`, nalgebra's `R` of `A` times `D` is the reference). Then a rank-deficient one (a column
    /// already zero below the diagonal, a zero column), whose `R` is not unique: `R^T R = A^T A`.
    #[test]
    fn householder_r_equals_nalgebras_qr() {
        let mut rnd = uniform(5);
        let cases: Vec<(Mat<f64>, Vec<f64>)> = vec![
            (Mat::from_fn(300, 7, |_, _| rnd()), vec![1.0; 7]),
            (Mat::from_fn(5, 9, |_, _| rnd()), vec![1.0; 9]),
            (
                Mat::from_fn(60, 4, |_, _| rnd()),
                vec![1.0, 1e200, 1e-200, 1.0],
            ),
        ];
        let r_of = |a: &Mat<f64>| {
            let (rows, w) = (a.nrows(), a.ncols());
            let mut buf: Vec<f64> = (0..w).flat_map(|j| a.col_as_slice(j).to_vec()).collect();
            let r = householder_r(&mut buf, rows, w);
            assert_eq!((r.nrows(), r.ncols()), (rows.min(w), w));
            for i in 0..r.nrows() {
                assert!((0..i).all(|j| r[(i, j)] == 0.0));
            }
            r
        };
        for (case, (b, d)) in cases.iter().enumerate() {
            let a = Mat::<f64>::from_fn(b.nrows(), b.ncols(), |i, j| b[(i, j)] * d[j]);
            let got = r_of(&a);
            let want = b.clone().qr().r();
            for i in 0..got.nrows() {
                let sign = if want[(i, i)] * got[(i, i)] < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for j in i..b.ncols() {
                    let err = (sign * got[(i, j)] / d[j] - want[(i, j)]).abs();
                    assert!(err <= 1e-13 * b.column(j).norm(), "case {case}: R[{i},{j}]");
                }
            }
        }
        let a = Mat::<f64>::from_fn(40, 4, |i, j| match j {
            0 => f64::from(u8::from(i == 0)) * 3.0,
            2 => 0.0,
            _ => (i * j) as f64 % 7.0 - 3.0,
        });
        let got = r_of(&a);
        for i in 0..4 {
            for j in 0..4 {
                let rtr: f64 = (0..=i.min(j)).map(|k| got[(k, i)] * got[(k, j)]).sum();
                let ata: f64 = (0..40).map(|k| a[(k, i)] * a[(k, j)]).sum();
                assert!((rtr - ata).abs() <= 1e-12 * (1.0 + ata.abs()), "G[{i},{j}]");
            }
        }
    }

    #[test]
    fn nearly_dependent_columns_go_to_householder() {
        // Column 2 is column 0 plus 1e-7 of noise: a scaled pivot of about 1e-7, under
        // MIN_PIVOT; the Gram matrix would lose about 1e-2 relative in R.
        let m = 5000;
        let mut rnd = uniform(11);
        let base: Vec<[f64; 3]> = (0..m).map(|_| [rnd(), rnd(), rnd()]).collect();
        let jac = Mat::<f64>::from_fn(m, 3, |i, j| match j {
            2 => base[i][0] + 1e-7 * base[i][2],
            _ => base[i][j],
        });
        let r: Vec<f64> = (0..m).map(|_| rnd()).collect();
        assert!(cholesky_qr_of_jr(&jac, &r).is_none());
        let whole = Mat::<f64>::from_fn(m, 4, |i, j| if j < 3 { jac[(i, j)] } else { r[i] });
        assert_same_r(&whole, qr_of_jr(&jac, &r), 1e-9);
        // A zero column (a parameter without influence) also goes to Householder.
        let jz = Mat::<f64>::from_fn(m, 2, |i, j| if j == 0 { base[i][0] } else { 0.0 });
        assert!(cholesky_qr_of_jr(&jz, &r).is_none());
    }

    /// Linear model y = a + b t: LM must give the OLS solution and its textbook covariance.
    struct Line {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Problem for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            for i in 0..self.t.len() {
                r[i] = p[0] + p[1] * self.t[i] - self.y[i];
            }
            if let Some(j) = jac {
                for i in 0..self.t.len() {
                    j[(i, 0)] = 1.0;
                    j[(i, 1)] = self.t[i];
                }
            }
            Ok(())
        }
    }

    /// `y = a + b t + s(c) g_i`, `s` the logistic function, `g_i = (-1)^i`, with `c` run to
    /// where `s` is flat (a bounded parameter at its bound): its column is about 1e-18, so the
    /// whole covariance would be singular.
    struct Clamped {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Problem for Clamped {
        fn n_params(&self) -> usize {
            3
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn at_bound(&self, j: usize, pj: f64) -> bool {
            j == 2 && pj > 30.0
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            let sc = 1.0 / (1.0 + (-p[2]).exp());
            let g = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
            for i in 0..self.t.len() {
                r[i] = p[0] + p[1] * self.t[i] + sc * g(i) - self.y[i];
            }
            if let Some(j) = jac {
                for i in 0..self.t.len() {
                    j[(i, 0)] = 1.0;
                    j[(i, 1)] = self.t[i];
                    j[(i, 2)] = sc * (1.0 - sc) * g(i);
                }
            }
            Ok(())
        }
    }

    /// A parameter held at its bound is left out of the covariance: the others' covariance is
    /// the closed-form OLS one of the model with it fixed (sigma^2 still over `m - 3`), its own
    /// standard error is NaN; by LM and by refine.
    #[test]
    fn a_parameter_at_its_bound_is_held_out_of_the_covariance() {
        let t: Vec<f64> = (0..40).map(|i| i as f64 / 4.0).collect();
        let g = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, t)| 1.5 + 0.7 * t + g(i) + 0.1 * ((i * 7 % 5) as f64 - 2.0))
            .collect();
        // The OLS fit of y - g = a + b t.
        let nn = t.len() as f64;
        let z: Vec<f64> = y.iter().enumerate().map(|(i, y)| y - g(i)).collect();
        let tm = t.iter().sum::<f64>() / nn;
        let zm = z.iter().sum::<f64>() / nn;
        let sxx: f64 = t.iter().map(|t| (t - tm).powi(2)).sum();
        let b = t
            .iter()
            .zip(&z)
            .map(|(t, z)| (t - tm) * (z - zm))
            .sum::<f64>()
            / sxx;
        let a = zm - b * tm;
        let ssr: f64 = t.iter().zip(&z).map(|(t, z)| (a + b * t - z).powi(2)).sum();
        let s2 = ssr / (nn - 3.0);
        let (var_a, var_b, cov_ab) = (s2 * (1.0 / nn + tm * tm / sxx), s2 / sxx, -s2 * tm / sxx);
        let rel = |x: f64, y: f64| ((x - y) / y).abs();
        let mut prob = Clamped { t, y };
        let by_lm = minimize(&mut prob, &[0.0, 0.0, 40.0], &LmOptions::default()).unwrap();
        let near = [a + 1e-3, b - 1e-3, 40.0];
        let by_refine = refine(&mut prob, &near, &LmOptions::default(), &Default::default());
        for rep in [by_lm, by_refine.unwrap()] {
            // 1e-8: the fit lands on the OLS solution; the covariance comes from the same R.
            assert!(rel(rep.params[0], a) < 1e-8 && rel(rep.params[1], b) < 1e-8);
            assert!(rel(rep.cov(0, 0).unwrap(), var_a) < 1e-8);
            assert!(rel(rep.cov(1, 1).unwrap(), var_b) < 1e-8);
            assert!(rel(rep.cov(0, 1).unwrap(), cov_ab) < 1e-8);
            let se = rep.std_errors.clone().unwrap();
            assert!(rel(se[1], var_b.sqrt()) < 1e-8 && se[2].is_nan());
            assert!(rep.cov(2, 2).unwrap().is_nan() && rep.cov(0, 2).unwrap().is_nan());
        }
    }

    #[test]
    fn linear_fit_and_covariance_match_ols() {
        let t: Vec<f64> = (0..12).map(|i| i as f64).collect();
        // deterministic "noise"
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, t)| 1.5 + 0.7 * t + 0.1 * ((i * 7 % 5) as f64 - 2.0))
            .collect();
        let rep = minimize(
            &mut Line {
                t: t.clone(),
                y: y.clone(),
            },
            &[0.0, 0.0],
            &LmOptions::default(),
        )
        .unwrap();
        assert!(rep.converged, "{:?}", rep.termination);
        // closed-form OLS
        let nn = t.len() as f64;
        let tm = t.iter().sum::<f64>() / nn;
        let ym = y.iter().sum::<f64>() / nn;
        let sxx: f64 = t.iter().map(|t| (t - tm).powi(2)).sum();
        let sxy: f64 = t.iter().zip(&y).map(|(t, y)| (t - tm) * (y - ym)).sum();
        let b = sxy / sxx;
        let a = ym - b * tm;
        // 1e-9: the problem is linear, LM must land on the OLS solution to rounding level.
        assert!((rep.params[0] - a).abs() < 1e-9 && (rep.params[1] - b).abs() < 1e-9);
        let ssr: f64 = t.iter().zip(&y).map(|(t, y)| (a + b * t - y).powi(2)).sum();
        let s2 = ssr / (nn - 2.0);
        let var_b = s2 / sxx;
        let var_a = s2 * (1.0 / nn + tm * tm / sxx);
        let cov_ab = -s2 * tm / sxx;
        let rel = |x: f64, y: f64| ((x - y) / y).abs();
        // 1e-9 relative: the covariance comes from the same QR; only rounding differs.
        assert!(rel(rep.cov(0, 0).unwrap(), var_a) < 1e-9);
        assert!(rel(rep.cov(1, 1).unwrap(), var_b) < 1e-9);
        assert!(rel(rep.cov(0, 1).unwrap(), cov_ab) < 1e-9);
        assert!(rel(rep.std_errors.as_ref().unwrap()[1], var_b.sqrt()) < 1e-9);
        assert!((rep.ssr() - ssr).abs() < 1e-9 * ssr);
    }

    /// `y = a exp(-b t)` with deterministic "noise", counting Jacobians.
    struct NoisyExp {
        t: Vec<f64>,
        y: Vec<f64>,
        jacobians: usize,
    }
    impl NoisyExp {
        fn new() -> Self {
            let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.02).collect();
            let y = t
                .iter()
                .enumerate()
                .map(|(i, t)| 2.0 * (-0.5 * t).exp() + 0.01 * (((i * 37) % 11) as f64 - 5.0))
                .collect();
            Self { t, y, jacobians: 0 }
        }
    }
    impl Problem for NoisyExp {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            for (i, (&t, &y)) in self.t.iter().zip(&self.y).enumerate() {
                r[i] = p[0] * (-p[1] * t).exp() - y;
            }
            if let Some(j) = jac {
                self.jacobians += 1;
                for (i, &t) in self.t.iter().enumerate() {
                    j[(i, 0)] = (-p[1] * t).exp();
                    j[(i, 1)] = -p[0] * t * (-p[1] * t).exp();
                }
            }
            Ok(())
        }
    }

    /// Without covariance, a fit that stops at an accepted step skips the Jacobian there and
    /// nothing else: the same parameters, iterations, Marquardt factor and cost as with it (by
    /// the cost test and by the stall test), one Jacobian fewer, and the residual is that point's.
    #[test]
    fn without_covariance_the_last_jacobian_is_skipped_and_nothing_else_changes() {
        // Stopped by the cost test at an accepted step, and by the stall test.
        let by_cost = LmOptions {
            ftol: 1e-4,
            ..LmOptions::default()
        };
        let by_stall = LmOptions {
            stall: Some((1, 1e-2)),
            ..LmOptions::default()
        };
        for with in [by_cost, by_stall] {
            let without = LmOptions {
                covariance: false,
                ..with.clone()
            };
            let p0 = [0.5, 3.0];
            let (mut a, mut b) = (NoisyExp::new(), NoisyExp::new());
            let ra = minimize(&mut a, &p0, &with).unwrap();
            let rb = minimize(&mut b, &p0, &without).unwrap();
            assert_eq!(ra.params, rb.params);
            assert_eq!(ra.iterations, rb.iterations);
            assert_eq!(ra.lambda, rb.lambda);
            assert_eq!(ra.termination, rb.termination);
            assert!(ra.std_errors.is_some() && rb.std_errors.is_none());
            assert_eq!(b.jacobians + 1, a.jacobians, "{with:?}");
            assert_eq!(rb.evaluations + 1, ra.evaluations);
            assert!((ra.cost - rb.cost).abs() <= 1e-14 * ra.cost);
            let mut r = vec![0.0; a.t.len()];
            a.eval(&rb.params, &mut r, None).unwrap();
            assert_eq!(r, rb.residuals);
        }
    }

    /// Tolerances no fit meets: only the stall or give-up test (or the iteration cap) stops it.
    fn tight_options() -> LmOptions {
        LmOptions {
            ftol: 1e-15,
            xtol: 1e-15,
            gtol: 1e-15,
            ..LmOptions::default()
        }
    }

    #[test]
    fn the_stall_test_stops_a_fit_whose_cost_no_longer_falls() {
        let tight = tight_options();
        let p0 = [0.5, 3.0];
        let plain = minimize(&mut NoisyExp::new(), &p0, &tight).unwrap();
        // A window longer than the fit never fires: the same path, bit for bit.
        let long = LmOptions {
            stall: Some((1000, 0.5)),
            ..tight.clone()
        };
        let never = minimize(&mut NoisyExp::new(), &p0, &long).unwrap();
        assert_eq!(never.params, plain.params);
        assert_eq!(never.iterations, plain.iterations);
        // Near the optimum an iteration removes far less than 1% of the cost (the noise's sum of
        // squares stays): the test stops there, sooner than the tight tolerances, within 2% of
        // the optimum's cost (LM converges fast near it, so the rest of the way is smaller still).
        let one_percent = LmOptions {
            stall: Some((1, 1e-2)),
            ..tight
        };
        let stalled = minimize(&mut NoisyExp::new(), &p0, &one_percent).unwrap();
        assert_eq!(stalled.termination, Termination::SmallCostChange);
        assert!(
            stalled.iterations < plain.iterations,
            "stalled {} iterations, plain {}",
            stalled.iterations,
            plain.iterations
        );
        assert!(
            stalled.ssr() >= plain.ssr() && stalled.ssr() <= 1.02 * plain.ssr(),
            "stalled SSR {}, plain {}",
            stalled.ssr(),
            plain.ssr()
        );
    }

    #[test]
    fn the_give_up_test_stops_only_a_fit_that_cannot_reach_its_target() {
        let tight = tight_options();
        let p0 = [0.5, 3.0];
        let plain = minimize(&mut NoisyExp::new(), &p0, &tight).unwrap();
        let best = 0.5 * plain.ssr();
        // A target the fit reaches (twice the optimum's cost): the test never fires, the same
        // path bit for bit (a rule that fired on a fit still falling towards its target would
        // change it).
        let reachable = LmOptions {
            give_up: Some((1, 2.0 * best)),
            ..tight.clone()
        };
        let same = minimize(&mut NoisyExp::new(), &p0, &reachable).unwrap();
        assert_eq!(same.params, plain.params);
        assert_eq!(same.iterations, plain.iterations);
        // A target below the optimum's cost (half of it): no fit reaches it; the test stops the
        // fit as soon as its fall per iteration times the iterations left no longer bridges the
        // gap, sooner than the plain fit, and above the target (what the caller decides on).
        let unreachable = LmOptions {
            give_up: Some((1, 0.5 * best)),
            ..tight
        };
        let gave_up = minimize(&mut NoisyExp::new(), &p0, &unreachable).unwrap();
        assert_eq!(gave_up.termination, Termination::SmallCostChange);
        assert!(
            gave_up.iterations < plain.iterations,
            "gave up after {} iterations, plain {}",
            gave_up.iterations,
            plain.iterations
        );
        assert!(0.5 * gave_up.ssr() > 0.5 * best && gave_up.ssr() >= plain.ssr());
    }

    /// `y = a exp(-b t)` with the amplitude `a = 3 / (1 + exp(-theta_0))` (a logistic map to
    /// (0, 3)) near its edge, `b = theta_1`; counts evaluations. `scales` says whether it tells
    /// [`refine`] how the amplitude's column scales ([`Problem::column_scale`]).
    struct EdgeExp {
        inner: NoisyExp,
        scales: bool,
        evaluations: usize,
    }
    impl EdgeExp {
        fn amplitude(theta: f64) -> f64 {
            3.0 / (1.0 + (-theta).exp())
        }
        fn new(scales: bool) -> Self {
            let mut inner = NoisyExp::new();
            for (y, t) in inner.y.iter_mut().zip(&inner.t) {
                *y += 0.9 * (-0.5 * t).exp();
            }
            Self {
                inner,
                scales,
                evaluations: 0,
            }
        }
    }
    impl Problem for EdgeExp {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.inner.t.len()
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            self.evaluations += 1;
            let a = Self::amplitude(p[0]);
            let da = a * (1.0 - a / 3.0);
            for (i, (&t, &y)) in self.inner.t.iter().zip(&self.inner.y).enumerate() {
                r[i] = a * (-p[1] * t).exp() - y;
            }
            if let Some(j) = jac {
                self.inner.jacobians += 1;
                for (i, &t) in self.inner.t.iter().enumerate() {
                    j[(i, 0)] = da * (-p[1] * t).exp();
                    j[(i, 1)] = -a * t * (-p[1] * t).exp();
                }
            }
            Ok(())
        }
        fn column_scale(&self, j: usize, from: f64, to: f64) -> Option<f64> {
            let d = |th: f64| {
                let a = Self::amplitude(th);
                a * (1.0 - a / 3.0)
            };
            (self.scales && j == 0).then(|| d(to) / d(from))
        }
    }

    #[test]
    fn chord_steps_rescaled_columns_converge_faster_to_the_same_optimum() {
        let opts = LmOptions {
            ftol: 1e-15,
            xtol: 1e-15,
            ..LmOptions::default()
        };
        let best = minimize(&mut EdgeExp::new(false), &[2.0, 0.5], &opts).unwrap();
        // The amplitude's optimum sits where the logistic's derivative is a tenth of its peak.
        let a = EdgeExp::amplitude(best.params[0]);
        assert!(a > 2.85 && a < 2.95, "amplitude {a}");
        let se = best.std_errors.clone().unwrap();
        let p0 = [best.params[0] - 4.0 * se[0], best.params[1] + 2.0 * se[1]];
        let run = |scales: bool| {
            let mut prob = EdgeExp::new(scales);
            let rep = refine(&mut prob, &p0, &opts, &RefineOptions::default()).unwrap();
            assert_eq!(rep.termination, Termination::SmallStatisticalStep);
            for i in 0..2 {
                let off = (rep.params[i] - best.params[i]).abs() / se[i];
                assert!(
                    off < 1e-2,
                    "scales {scales}, parameter {i}: {off} standard errors off"
                );
            }
            (prob.evaluations, prob.inner.jacobians)
        };
        let (plain, plain_jac) = run(false);
        let (rescaled, rescaled_jac) = run(true);
        assert!(
            rescaled < plain && rescaled_jac <= plain_jac,
            "rescaled {rescaled} evaluations ({rescaled_jac} Jacobians), plain {plain} ({plain_jac})"
        );
    }

    #[test]
    fn refine_from_near_the_optimum_reaches_it_with_few_jacobians() {
        let opts = LmOptions {
            ftol: 1e-15,
            xtol: 1e-15,
            ..LmOptions::default()
        };
        let best = minimize(&mut NoisyExp::new(), &[1.0, 1.0], &opts).unwrap();
        let se = best.std_errors.clone().unwrap();
        // Three standard errors off in both parameters, as a part of the record's optimum is.
        let p0 = [best.params[0] + 3.0 * se[0], best.params[1] - 3.0 * se[1]];
        let mut prob = NoisyExp::new();
        let rep = refine(&mut prob, &p0, &opts, &RefineOptions::default()).unwrap();
        assert_eq!(rep.termination, Termination::SmallStatisticalStep);
        // Two rounds: one to get there by chord steps, one to certify.
        assert!(prob.jacobians <= 3, "{} Jacobians", prob.jacobians);
        for i in 0..2 {
            // 1e-3 standard errors: the step under 0.01 was taken, what is left is of its
            // square (Gauss-Newton converges quadratically on a small-residual problem).
            let off = (rep.params[i] - best.params[i]).abs() / se[i];
            assert!(off < 1e-3, "parameter {i}: {off} standard errors off");
            let se_rel = (rep.std_errors.as_ref().unwrap()[i] - se[i]).abs() / se[i];
            assert!(se_rel < 1e-3, "standard error {i} off by {se_rel}");
        }
        assert!(rep.cost <= best.cost * (1.0 + 1e-12));
    }

    #[test]
    fn refine_in_given_buffers_is_refine_and_buffers_of_another_size_are_replaced() {
        let p0 = [2.1, 0.45];
        let (opts, ropts) = (LmOptions::default(), RefineOptions::default());
        let plain = refine(&mut NoisyExp::new(), &p0, &opts, &ropts).unwrap();
        for (m, n) in [(400, 2), (399, 2), (400, 3), (1, 1)] {
            let bufs = RefineBuffers::new(m, n);
            let rep = refine_with(&mut NoisyExp::new(), &p0, &opts, &ropts, bufs).unwrap();
            assert_eq!(rep.params, plain.params, "buffers {m} x {n}");
            assert_eq!(rep.evaluations, plain.evaluations);
        }
    }

    #[test]
    fn refine_from_far_away_hands_over_to_levenberg_marquardt() {
        let best = minimize(&mut NoisyExp::new(), &[1.0, 1.0], &LmOptions::default()).unwrap();
        // Gauss-Newton's first step from here overshoots (b negative: the exponential grows).
        let mut prob = NoisyExp::new();
        let rep = refine(
            &mut prob,
            &[0.1, 5.0],
            &LmOptions::default(),
            &RefineOptions::default(),
        )
        .unwrap();
        assert!(rep.converged, "{:?}", rep.termination);
        assert_ne!(rep.termination, Termination::SmallStatisticalStep);
        assert!((rep.params[0] - best.params[0]).abs() < 1e-6 * best.params[0]);
        assert!((rep.params[1] - best.params[1]).abs() < 1e-6 * best.params[1]);
    }

    #[test]
    fn lane_sums_and_ranges_equal_plain_folds() {
        for n in [0usize, 1, 7, 8, 9, 17, 1000] {
            let a: Vec<f64> = (0..n)
                .map(|k| ((k * 37 % 101) as f64 - 50.0) * 0.25)
                .collect();
            let b: Vec<f64> = (0..n).map(|k| ((k * 13 % 29) as f64) - 9.5).collect();
            let want: f64 = a.iter().zip(&b).map(|(x, y)| (x - y) * (x - y)).sum();
            let got = sum_of2(&a, &b, |x, y| (x - y) * (x - y));
            assert!((got - want).abs() <= 1e-12 * want.abs().max(1.0), "{n}");
            let lo = a.iter().fold(f64::INFINITY, |m, &v| m.min(v));
            let hi = a.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
            assert_eq!(range_of(&a), (lo, hi), "{n}");
            // NaNs anywhere (in the lanes and in the remainder) are passed over.
            let mut with_nan = a.clone();
            for k in (0..n).step_by(3) {
                with_nan[k] = f64::NAN;
            }
            let lo = with_nan.iter().fold(f64::INFINITY, |m, &v| m.min(v));
            let hi = with_nan.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
            assert_eq!(range_of(&with_nan), (lo, hi), "{n} with NaNs");
        }
        // The common length of two slices.
        assert_eq!(sum_of2(&[1.0, 2.0, 3.0], &[1.0], |x, y| x * y), 1.0);
    }

    /// [`NoisyExp`] whose first Jacobian has one entry `bad` (NaN or infinite).
    struct PoisonedFirstJacobian {
        inner: NoisyExp,
        bad: f64,
    }
    impl Problem for PoisonedFirstJacobian {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.inner.n_residuals()
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            let first = jac.is_some() && self.inner.jacobians == 0;
            match jac {
                Some(j) => {
                    self.inner.eval(p, r, Some(&mut *j))?;
                    if first {
                        j[(123, 1)] = self.bad;
                    }
                }
                None => self.inner.eval(p, r, None)?,
            }
            Ok(())
        }
    }

    #[test]
    fn refine_does_not_step_on_a_non_finite_jacobian() {
        let best = minimize(&mut NoisyExp::new(), &[1.0, 1.0], &LmOptions::default()).unwrap();
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut prob = PoisonedFirstJacobian {
                inner: NoisyExp::new(),
                bad,
            };
            let near = [best.params[0] * 1.001, best.params[1] * 0.999];
            let rep = refine(
                &mut prob,
                &near,
                &LmOptions::default(),
                &RefineOptions::default(),
            )
            .unwrap();
            // Handed over to Levenberg-Marquardt, which evaluates its own Jacobian.
            assert_ne!(rep.termination, Termination::SmallStatisticalStep, "{bad}");
            assert!(rep.converged, "{bad}: {:?}", rep.termination);
            for (a, b) in rep.params.iter().zip(&best.params) {
                assert!((a - b).abs() < 1e-6 * b.abs(), "{bad}: {a} vs {b}");
            }
        }
    }

    /// Rosenbrock as residuals r = (10 (y - x^2), 1 - x): a curved valley, minimum at (1, 1).
    struct Rosen;
    impl Problem for Rosen {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            2
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            r[0] = 10.0 * (p[1] - p[0] * p[0]);
            r[1] = 1.0 - p[0];
            if let Some(j) = jac {
                j[(0, 0)] = -20.0 * p[0];
                j[(0, 1)] = 10.0;
                j[(1, 0)] = -1.0;
                j[(1, 1)] = 0.0;
            }
            Ok(())
        }
    }

    #[test]
    fn rosenbrock_converges() {
        let rep = minimize(&mut Rosen, &[-1.2, 1.0], &LmOptions::default()).unwrap();
        assert!(rep.converged, "{:?}", rep.termination);
        // 1e-8: zero-residual problem, LM converges quadratically to the exact minimum.
        assert!((rep.params[0] - 1.0).abs() < 1e-8 && (rep.params[1] - 1.0).abs() < 1e-8);
        assert!(rep.covariance.is_none()); // m == n: no degrees of freedom
    }

    #[test]
    fn finite_diff_matches_and_max_iterations_reports() {
        let mut fd = FiniteDiff::new(Rosen);
        let rep = minimize(&mut fd, &[-1.2, 1.0], &LmOptions::default()).unwrap();
        assert!(rep.converged);
        assert!((rep.params[0] - 1.0).abs() < 1e-6);
        let opts = LmOptions {
            max_iterations: 2,
            ..LmOptions::default()
        };
        let rep = minimize(&mut Rosen, &[-1.2, 1.0], &opts).unwrap();
        assert!(!rep.converged);
        assert_eq!(rep.termination, Termination::MaxIterations);
    }

    struct Bad;
    impl Problem for Bad {
        fn n_params(&self) -> usize {
            1
        }
        fn n_residuals(&self) -> usize {
            1
        }
        fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
            r[0] = if p[0] > 0.0 { f64::NAN } else { p[0] + 1.0 };
            if let Some(j) = jac {
                j[(0, 0)] = 1.0;
            }
            Ok(())
        }
    }

    #[test]
    fn bad_input_is_error() {
        assert!(matches!(
            minimize(&mut Bad, &[1.0], &LmOptions::default()),
            Err(Error::Numerical(_))
        ));
        assert!(matches!(
            minimize(&mut Bad, &[1.0, 2.0], &LmOptions::default()),
            Err(Error::Options(_))
        ));
        assert!(matches!(
            minimize(&mut Bad, &[f64::NAN], &LmOptions::default()),
            Err(Error::Options(_))
        ));
        // NaN at trial points is only a rejected step: minimum at p = -1 from the left
        let rep = minimize(&mut Bad, &[-3.0], &LmOptions::default()).unwrap();
        assert!(rep.converged);
        assert!((rep.params[0] + 1.0).abs() < 1e-10);
    }
}
