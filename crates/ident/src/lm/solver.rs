//! The Levenberg-Marquardt iteration ([`minimize`]): a trial step from the trust region, its
//! acceptance or rejection, the stopping tests, and the report at the end.

use super::covariance::covariance_and_errors;
use super::passes::check_finite;
use super::problem::{Mat, Problem};
use super::qr::{col_norms_of, jt_r_of, qr_of_jr};
use super::trust_region::{damped_step, marquardt_factor, predicted_cost};
use super::{LmOptions, LmReport, Termination};
use crate::numeric::{norm, sumsq};
use crate::{Error, Result};
use std::ops::ControlFlow;

/// The largest last step, in standard errors, after which the covariance may be that of the
/// point before it ([`LmOptions::covariance_before_last_step`]).
const LAST_STEP_SE: f64 = 0.01;

/// Minimise `1/2 sum_i r_i(p)^2` from `p0` by Levenberg-Marquardt (see the [module docs](super)).
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
    let max_evals = check_start(problem, p0, opts)?;
    let mut lm = Lm::start(problem, p0, opts)?;
    let termination = loop {
        let rnorm = match lm.test_and_scale(opts) {
            ControlFlow::Break(t) => break t,
            ControlFlow::Continue(rnorm) => rnorm,
        };
        if let Some(t) = lm.iteration(problem, opts, max_evals, rnorm)? {
            break t;
        }
    };
    Ok(lm.report(problem, opts, termination))
}

/// The residual evaluations [`minimize`] may make, after checking the problem's sizes, the
/// starting point and the options.
fn check_start(problem: &impl Problem, p0: &[f64], opts: &LmOptions) -> Result<usize> {
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
    Ok(if opts.max_evaluations == 0 {
        100 * (n + 1) + opts.max_iterations
    } else {
        opts.max_evaluations
    })
}

/// The state of a [`minimize`] run.
struct Lm {
    n: usize,
    m: usize,
    /// The current point, its residual, Jacobian and cost.
    p: Vec<f64>,
    r: Vec<f64>,
    jac: Mat<f64>,
    cost: f64,
    /// The trial point and its residual.
    p_trial: Vec<f64>,
    r_trial: Vec<f64>,
    /// The scaling `D` and the Marquardt factor `lambda` (with its growth `nu` on rejection).
    diag: Vec<f64>,
    lambda: f64,
    nu: f64,
    iterations: usize,
    evaluations: usize,
    /// The QR of `[J r]` at the current point: R and Q^T r give the gradient, the column norms,
    /// every damped step and its predicted cost, and the covariance at the end.
    qr: (Mat<f64>, Vec<f64>),
    /// The cost at the start and after each accepted iteration (the stall test).
    history: Vec<f64>,
    /// The gradient's cosine ([`LmOptions::gtol`]) at the last point it was computed.
    gcos: f64,
}

/// A trial step and what it did.
struct Trial {
    d: Vec<f64>,
    /// The trial point evaluated to finite residuals.
    ok: bool,
    /// Its cost (infinite when not `ok`).
    cost: f64,
    /// The actual reduction of the cost and its ratio to the predicted one.
    actual: f64,
    rho: f64,
    /// The cost and step tests.
    small_cost: bool,
    small_step: bool,
}

/// What an accepted step leads to.
enum Accepted {
    /// The fit stops.
    Stop(Termination),
    /// The next iteration, from the new point.
    Next,
    /// The new point's Jacobian failed: back to the last point, more damping, another trial.
    Retry,
}

impl Lm {
    /// The residual, Jacobian and QR at `p0`.
    fn start(problem: &mut impl Problem, p0: &[f64], opts: &LmOptions) -> Result<Self> {
        let (n, m) = (problem.n_params(), problem.n_residuals());
        let p = p0.to_vec();
        let mut r = vec![0.0; m];
        let mut jac = Mat::<f64>::zeros(m, n);
        problem.eval(&p, &mut r, Some(&mut jac))?;
        check_finite(opts.par, &r, &jac, "at the starting point")?;
        let cost = 0.5 * sumsq(&r);
        let qr = qr_of_jr(opts.par, &jac, &r);
        Ok(Self {
            n,
            m,
            p,
            r,
            jac,
            cost,
            p_trial: vec![0.0; n],
            r_trial: vec![0.0; m],
            diag: vec![0.0f64; n],
            lambda: opts.initial_lambda,
            nu: 2.0,
            iterations: 0,
            evaluations: 1,
            qr,
            history: vec![cost],
            gcos: 0.0,
        })
    }

    /// The gradient and zero-residual tests, the scaling `D` from the column norms, the
    /// iteration cap; the residual's norm when the fit goes on.
    fn test_and_scale(&mut self, opts: &LmOptions) -> ControlFlow<Termination, f64> {
        let col_norms = col_norms_of(&self.qr.0);
        let rnorm = norm(&self.r);
        self.gcos = gradient_cosine(&jt_r_of(&self.qr.0, &self.qr.1), &col_norms, rnorm);
        if self.cost == 0.0 {
            return ControlFlow::Break(Termination::ZeroResidual);
        }
        if self.gcos <= opts.gtol {
            return ControlFlow::Break(Termination::SmallGradient);
        }
        for j in 0..self.n {
            self.diag[j] = if opts.scale {
                self.diag[j].max(col_norms[j])
            } else {
                1.0
            };
            if self.diag[j] == 0.0 {
                self.diag[j] = 1.0; // a parameter with no influence: damp it with unit weight
            }
        }
        if self.iterations >= opts.max_iterations {
            return ControlFlow::Break(Termination::MaxIterations);
        }
        self.iterations += 1;
        ControlFlow::Continue(rnorm)
    }

    /// Trial steps, more damped after each rejection, until one lowers the cost (`None`: the
    /// next iteration) or the fit stops.
    fn iteration(
        &mut self,
        problem: &mut impl Problem,
        opts: &LmOptions,
        max_evals: usize,
        rnorm: f64,
    ) -> Result<Option<Termination>> {
        // |r|^2 - |Q^T r|^2: the part of r no step can reach.
        let r_out = (rnorm * rnorm - sumsq(&self.qr.1)).max(0.0);
        loop {
            if self.evaluations >= max_evals {
                return Ok(Some(Termination::MaxEvaluations));
            }
            if self.lambda > 1e30 {
                return Ok(Some(Termination::NoProgress));
            }
            let trial = self.trial(problem, opts, r_out);
            if trial.ok && trial.rho > 0.0 && trial.actual > 0.0 {
                match self.accept(problem, opts, &trial)? {
                    Accepted::Stop(t) => return Ok(Some(t)),
                    Accepted::Next => return Ok(None),
                    Accepted::Retry => continue,
                }
            }
            // reject
            if trial.small_cost {
                return Ok(Some(Termination::SmallCostChange));
            }
            if trial.small_step && trial.ok {
                return Ok(Some(Termination::SmallStep));
            }
            self.damp_more();
        }
    }

    /// The damped step at the current `lambda`, evaluated at `p + d` (into `p_trial`,
    /// `r_trial`), with its gain ratio and the cost and step tests.
    fn trial(&mut self, problem: &mut impl Problem, opts: &LmOptions, r_out: f64) -> Trial {
        let (rmat, qtr) = (&self.qr.0, &self.qr.1);
        let d = damped_step(rmat, qtr, &self.diag, self.lambda);
        let scaled = |v: &[f64]| {
            norm(
                &v.iter()
                    .zip(&self.diag)
                    .map(|(a, b)| a * b)
                    .collect::<Vec<_>>(),
            )
        };
        let (dnorm, pnorm) = (scaled(&d), scaled(&self.p));
        let pred = predicted_cost(rmat, qtr, &d, self.cost, r_out);
        for j in 0..self.n {
            self.p_trial[j] = self.p[j] + d[j];
        }
        self.evaluations += 1;
        let ok = d.iter().all(|v| v.is_finite())
            && problem.eval(&self.p_trial, &mut self.r_trial, None).is_ok()
            && self.r_trial.iter().all(|v| v.is_finite());
        let cost_trial = if ok {
            0.5 * sumsq(&self.r_trial)
        } else {
            f64::INFINITY
        };
        let actual = self.cost - cost_trial;
        let rho = if pred > 0.0 { actual / pred } else { -1.0 };
        let cost = self.cost;
        Trial {
            small_cost: ok
                && actual.abs() <= opts.ftol * cost
                && pred <= opts.ftol * cost
                && rho <= 2.0,
            small_step: dnorm <= opts.xtol * (pnorm + opts.xtol),
            d,
            ok,
            cost: cost_trial,
            actual,
            rho,
        }
    }

    /// Move to the trial point: its Jacobian and QR (unless the fit stops there and nothing
    /// needs them), the Marquardt factor's update, the stopping tests.
    fn accept(
        &mut self,
        problem: &mut impl Problem,
        opts: &LmOptions,
        t: &Trial,
    ) -> Result<Accepted> {
        let (n, m) = (self.n, self.m);
        std::mem::swap(&mut self.p, &mut self.p_trial);
        let end = if t.small_cost || !t.small_step {
            Termination::SmallCostChange
        } else {
            Termination::SmallStep
        };
        let stalled = stalled(opts, &self.history, t.cost);
        // `|J d|` against the residual's standard deviation at the new point: the step
        // in standard errors (in the metric of `J^T J`).
        let covariance_from_before =
            opts.covariance_before_last_step && (t.small_cost || t.small_step) && m > n && {
                let rmat = &self.qr.0;
                let jd2: f64 = (0..n)
                    .map(|i| (i..n).map(|j| rmat[(i, j)] * t.d[j]).sum::<f64>().powi(2))
                    .sum();
                let sigma2 = 2.0 * t.cost / (m - n) as f64;
                jd2 <= LAST_STEP_SE * LAST_STEP_SE * sigma2
            };
        if (!opts.covariance && (t.small_cost || t.small_step || stalled)) || covariance_from_before
        {
            // The fit stops here and nothing needs the Jacobian at this point (no
            // covariance, or the covariance of the point before a step this small): the
            // residual is the trial's, the gradient's cosine the last point's.
            std::mem::swap(&mut self.r, &mut self.r_trial);
            self.cost = t.cost.max(0.0);
            self.lambda *= marquardt_factor(t.rho);
            self.history.push(self.cost);
            return Ok(Accepted::Stop(end));
        }
        self.evaluations += 1;
        let jac_ok = problem
            .eval(&self.p, &mut self.r, Some(&mut self.jac))
            .is_ok()
            && check_finite(opts.par, &self.r, &self.jac, "at an accepted point").is_ok();
        if !jac_ok {
            // The point simulates but its sensitivities do not (a model at the edge
            // of what the approximation can represent): take the step back, restore
            // the residual and Jacobian of the last good point, and damp more.
            std::mem::swap(&mut self.p, &mut self.p_trial);
            // (`qr` is still that of this point's `J` and `r`.)
            problem.eval(&self.p, &mut self.r, Some(&mut self.jac))?;
            self.evaluations += 1;
            self.damp_more();
            return Ok(Accepted::Retry);
        }
        self.cost = t.cost;
        self.cost = self.cost.min(0.5 * sumsq(&self.r)).max(0.0);
        self.lambda *= marquardt_factor(t.rho);
        self.nu = 2.0;
        self.qr = qr_of_jr(opts.par, &self.jac, &self.r);
        self.history.push(self.cost);
        let stalled = stalled_after(opts, &self.history);
        let hopeless = hopeless(opts, &self.history, self.iterations);
        if t.small_cost || t.small_step || stalled || hopeless {
            let (rmat, qtr) = (&self.qr.0, &self.qr.1);
            self.gcos = gradient_cosine(&jt_r_of(rmat, qtr), &col_norms_of(rmat), norm(&self.r));
            return Ok(Accepted::Stop(end));
        }
        Ok(Accepted::Next)
    }

    /// A rejected step: `lambda *= nu`, `nu *= 2`.
    fn damp_more(&mut self) {
        self.lambda *= self.nu;
        self.nu *= 2.0;
    }

    /// The report at the end, with the covariance when asked.
    fn report(
        self,
        problem: &impl Problem,
        opts: &LmOptions,
        termination: Termination,
    ) -> LmReport {
        let (n, m) = (self.n, self.m);
        let (covariance, std_errors) = if opts.covariance && m > n {
            // The R of `J` is the leading block of the R of `[J r]` (`qr` is that of the current
            // `J` and `r`, or of the point before a last step under the cost test with
            // `covariance_before_last_step`; the residual variance is the final point's).
            let held: Vec<bool> = (0..n).map(|j| problem.at_bound(j, self.p[j])).collect();
            covariance_and_errors(&self.qr.0, sumsq(&self.r) / (m - n) as f64, &held)
        } else {
            (None, None)
        };
        LmReport {
            params: self.p,
            cost: self.cost,
            residuals: self.r,
            iterations: self.iterations,
            evaluations: self.evaluations,
            termination,
            budget_ends: usize::from(matches!(
                termination,
                Termination::MaxIterations | Termination::MaxEvaluations
            )),
            converged: termination.is_converged(),
            covariance,
            std_errors,
            lambda: self.lambda,
            gradient_cosine: self.gcos,
        }
    }
}

/// The stall test ([`LmOptions::stall`]) for a trial cost `cost_trial` not yet in `history`.
fn stalled(opts: &LmOptions, history: &[f64], cost_trial: f64) -> bool {
    opts.stall.is_some_and(|(k, rel)| {
        k > 0
            && history.len() >= k
            && history[history.len() - k] - cost_trial <= rel * history[history.len() - k]
    })
}

/// The stall test ([`LmOptions::stall`]) with the last cost in `history`.
fn stalled_after(opts: &LmOptions, history: &[f64]) -> bool {
    opts.stall.is_some_and(|(k, rel)| {
        let cost = history[history.len() - 1];
        k > 0
            && history.len() > k
            && history[history.len() - 1 - k] - cost <= rel * history[history.len() - 1 - k]
    })
}

/// The give-up test ([`LmOptions::give_up`]) with the last cost in `history`, after
/// `iterations`.
fn hopeless(opts: &LmOptions, history: &[f64], iterations: usize) -> bool {
    opts.give_up.is_some_and(|(k, target)| {
        k > 0 && history.len() > k && {
            let cost = history[history.len() - 1];
            let fall = (history[history.len() - 1 - k] - cost) / k as f64;
            let left = opts.max_iterations.saturating_sub(iterations) as f64;
            cost - fall.max(0.0) * left > target
        }
    })
}

/// `max_j |g_j| / (|J e_j| |r|)` for the gradient `g = J^T r` (MINPACK's `gtol` test).
pub(super) fn gradient_cosine(g: &[f64], col_norms: &[f64], rnorm: f64) -> f64 {
    if rnorm == 0.0 {
        return 0.0;
    }
    g.iter()
        .zip(col_norms)
        .map(|(g, &c)| if c == 0.0 { 0.0 } else { g.abs() / (c * rnorm) })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::super::testproblems::NoisyExp;
    use super::super::{refine, FiniteDiff};
    use super::*;

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

    /// With `covariance_before_last_step`, a fit whose last step (accepted, under the cost test)
    /// is within a hundredth of a standard error skips the Jacobian at its end: the same path,
    /// one Jacobian fewer, and standard errors within 1e-4 relative of the plain fit's (the
    /// Jacobian at the final point: the truth). Why 1e-4: the decay rate's standard error is
    /// 0.45% of its value, so a step of 0.01 SE moves it by 5e-5 relative, and the columns
    /// `exp(-b t)`, `-a t exp(-b t)` (`b t` up to 4) by up to about 2e-4 relative. A last step
    /// larger than 0.01 SE (a loose cost test) still gets its Jacobian: the same result, bit for
    /// bit.
    #[test]
    fn the_covariance_before_a_tiny_last_step_is_the_final_points() {
        for (ftol, reused) in [(1e-6, true), (0.5, false)] {
            let plain = LmOptions {
                ftol,
                ..LmOptions::default()
            };
            let before = LmOptions {
                covariance_before_last_step: true,
                ..plain.clone()
            };
            let p0 = [0.5, 3.0];
            let (mut a, mut b) = (NoisyExp::new(), NoisyExp::new());
            let ra = minimize(&mut a, &p0, &plain).unwrap();
            let rb = minimize(&mut b, &p0, &before).unwrap();
            assert_eq!(ra.params, rb.params);
            assert_eq!(ra.iterations, rb.iterations);
            assert_eq!(ra.termination, rb.termination);
            let (sa, sb) = (ra.std_errors.unwrap(), rb.std_errors.unwrap());
            if reused {
                assert_eq!(b.jacobians + 1, a.jacobians);
                assert_eq!(rb.evaluations + 1, ra.evaluations);
                for (x, y) in sa.iter().zip(&sb) {
                    assert!((x - y).abs() <= 1e-4 * x, "{sa:?} {sb:?}");
                }
                // The residual is the final point's.
                let mut r = vec![0.0; b.t.len()];
                b.eval(&rb.params, &mut r, None).unwrap();
                assert_eq!(r, rb.residuals);
            } else {
                assert_eq!(b.jacobians, a.jacobians);
                assert_eq!(sa, sb);
            }
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
    fn only_a_run_stopped_by_its_budget_reports_ending_there() {
        let p0 = [1.0, 1.0];
        let full = minimize(&mut NoisyExp::new(), &p0, &LmOptions::default()).unwrap();
        assert_ne!(full.termination, Termination::MaxIterations);
        assert_eq!(full.budget_ends, 0);
        let short = LmOptions {
            max_iterations: 1,
            ..LmOptions::default()
        };
        let rep = minimize(&mut NoisyExp::new(), &p0, &short).unwrap();
        assert_eq!(rep.termination, Termination::MaxIterations);
        assert_eq!(rep.budget_ends, 1);
        // a budget the run did not reach gives the full run, bit for bit
        let enough = LmOptions {
            max_iterations: full.iterations + 1,
            ..LmOptions::default()
        };
        let same = minimize(&mut NoisyExp::new(), &p0, &enough).unwrap();
        assert_eq!(same.budget_ends, 0);
        assert_eq!(same.params, full.params);
        assert_eq!(same.iterations, full.iterations);
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

    /// `y = a exp(-b t)` on 70 000 samples with deterministic "noise": a Jacobian of 140 000
    /// entries, above [`crate::par::PARALLEL_ENTRIES`], so its passes run by halves of its rows.
    fn long_exp() -> NoisyExp {
        let mut p = NoisyExp::new();
        p.t = (0..70_000).map(|i| i as f64 * 1e-4).collect();
        p.y =
            p.t.iter()
                .enumerate()
                .map(|(i, t)| 2.0 * (-0.5 * t).exp() + 0.01 * (((i * 37) % 11) as f64 - 5.0))
                .collect();
        p
    }

    /// A fit's report does not depend on its width: by LM and by refine, on one thread
    /// (`Par::Seq`) and on two, the same report bit for bit (the halves of the rows are cut
    /// by the size alone and summed in the same order; only where they run differs).
    #[test]
    fn the_report_does_not_depend_on_the_width() {
        use crate::par::Par;
        let p0 = [1.0, 1.0];
        let fit = |par: Par| {
            let opts = LmOptions {
                par,
                ..LmOptions::default()
            };
            let lm = minimize(&mut long_exp(), &p0, &opts).unwrap();
            let near = [lm.params[0] * 1.01, lm.params[1] * 0.99];
            let rf = refine(&mut long_exp(), &near, &opts, &Default::default()).unwrap();
            (lm, rf)
        };
        let (seq, two) = (fit(Par::Seq), fit(Par::threads(2)));
        assert!(seq.0.converged && seq.1.converged);
        assert_eq!(seq, two);
    }
}
