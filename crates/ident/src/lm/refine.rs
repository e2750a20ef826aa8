//! [`refine`]: Gauss-Newton with chord steps from near the optimum, few Jacobians, handing over
//! to [`minimize`] when it does not go well.

use super::covariance::covariance_and_errors;
use super::passes::{check_finite, jt_r};
use super::problem::{Mat, Problem};
use super::qr::{cholesky_qr_of_jr, col_norms_of, householder_qr_of_jr, jt_r_of};
use super::solver::gradient_cosine;
use super::trust_region::gauss_newton_step;
use super::{minimize, LmOptions, LmReport, RefineOptions, Termination};
use crate::numeric::{all_finite, norm, sumsq};
use crate::par::Par;
use crate::Result;

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

    /// These buffers if they are for `m` residuals and `n` parameters, else new ones.
    fn sized(self, m: usize, n: usize) -> Self {
        if self.jac.nrows() == m
            && self.jac.ncols() == n
            && self.r.len() == m
            && self.r_trial.len() == m
        {
            self
        } else {
            Self::new(m, n)
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
    } = bufs.sized(m, n);
    // Damping only to keep the small system definite: the chord's fixed point does not depend
    // on it.
    let lambda = opts.initial_lambda.clamp(1e-14, 1e-8);
    let mut p = p0.to_vec();
    let mut evaluations = 0;
    for round in 0..ropts.max_rounds {
        evaluations += 1;
        if problem.eval(&p, &mut r, Some(&mut jac)).is_err() {
            return handover(problem, &p, opts, evaluations, round);
        }
        let Some(mut chord) = Chord::start(problem, &p, &jac, &r, lambda, opts.par, ropts) else {
            return handover(problem, &p, opts, evaluations, round);
        };
        let mut at = Point {
            p: &mut p,
            r: &mut r,
            r_trial: &mut r_trial,
            evaluations: &mut evaluations,
        };
        if !chord.steps(problem, &mut at, &jac, ropts) {
            return handover(problem, &p, opts, evaluations, round + 1);
        }
        if chord.last {
            return Ok(chord.report(opts, p, r, &jac, round, evaluations));
        }
    }
    handover(problem, &p, opts, evaluations, ropts.max_rounds)
}

/// [`minimize`] from `p`, its report counting the `evaluations` and `rounds` done before.
fn handover(
    problem: &mut impl Problem,
    p: &[f64],
    opts: &LmOptions,
    evaluations: usize,
    rounds: usize,
) -> Result<LmReport> {
    let mut rep = minimize(problem, p, opts)?;
    rep.evaluations += evaluations;
    rep.iterations += rounds;
    Ok(rep)
}

/// The point a round's chord steps move, its residual, the trial's residual, and the
/// evaluations counted.
struct Point<'a> {
    p: &'a mut Vec<f64>,
    r: &'a mut Vec<f64>,
    r_trial: &'a mut Vec<f64>,
    evaluations: &'a mut usize,
}

/// A round of [`refine`]: the factored Jacobian of its start and the step to take.
struct Chord {
    /// The `R` of the chord's Jacobian `J S` (its columns rescaled by `scale`).
    rmat: Mat<f64>,
    /// `S`: the columns' factors as the parameters moved ([`Problem::column_scale`]).
    scale: Vec<f64>,
    /// The parameters at a bound, held there.
    held: Vec<bool>,
    /// The sum of squares at the current point, the residual variance at the round's start.
    ssr: f64,
    sigma2: f64,
    /// The step to take next and its predicted reduction of the sum of squares.
    d: Vec<f64>,
    pred: f64,
    /// The round's own Gauss-Newton step is under the tolerance: the last round.
    last: bool,
    lambda: f64,
    /// The width of the passes over `J`.
    par: Par,
}

impl Chord {
    /// The round at `p` (residual `r`, Jacobian `jac` evaluated): the QR of `[J r]`, the
    /// Gauss-Newton step; `None` when a factor or the step is not finite (or not definite).
    fn start(
        problem: &impl Problem,
        p: &[f64],
        jac: &Mat<f64>,
        r: &[f64],
        lambda: f64,
        par: Par,
        ropts: &RefineOptions,
    ) -> Option<Self> {
        let (n, m) = (p.len(), r.len());
        let ssr = sumsq(r);
        let sigma2 = ssr / (m - n) as f64;
        // The finiteness of `r` and `J` is checked on what the factorisation reads anyway: a
        // non-finite residual makes `ssr` non-finite, a non-finite entry of `J` the Gram
        // matrix's diagonal (the Householder QR only runs after a full check).
        let qr = ssr
            .is_finite()
            .then(|| {
                cholesky_qr_of_jr(par, jac, r).or_else(|| {
                    check_finite(par, r, jac, "")
                        .is_ok()
                        .then(|| householder_qr_of_jr(par, jac, r))
                })
            })
            .flatten();
        let (rmat, qtr) = qr.filter(|(rm, q)| {
            all_finite(q) && (0..rm.ncols()).all(|j| rm.column(j).iter().all(|v| v.is_finite()))
        })?;
        // g = J^T r = R^T (Q^T r) at the round's point.
        let g = jt_r_of(&rmat, &qtr);
        let held: Vec<bool> = (0..n).map(|j| problem.at_bound(j, p[j])).collect();
        let (d, pred) = gauss_newton_step(&rmat, &g, lambda, &held)?;
        Some(Self {
            last: pred <= ropts.tolerance * ropts.tolerance * sigma2,
            rmat,
            // The chord's Jacobian is `J S`: the round's `J`, its columns rescaled as the
            // parameters move ([`Problem::column_scale`]); `R S` is its `R`.
            scale: vec![1.0; n],
            held,
            ssr,
            sigma2,
            d,
            pred,
            lambda,
            par,
        })
    }

    /// The round's steps from `at`: the Gauss-Newton step, then chord steps (the same `J^T J`,
    /// the gradient with the round's `J`) while they lower the cost and are not below the
    /// chord tolerance. `false`: hand over to [`minimize`].
    fn steps(
        &mut self,
        problem: &mut impl Problem,
        at: &mut Point<'_>,
        jac: &Mat<f64>,
        ropts: &RefineOptions,
    ) -> bool {
        let chord_tol2 = ropts.chord_tolerance * ropts.chord_tolerance * self.sigma2;
        let mut first = true;
        for _ in 0..ropts.max_chord_steps.max(1) {
            let trial: Vec<f64> = at.p.iter().zip(&self.d).map(|(a, b)| a + b).collect();
            *at.evaluations += 1;
            // (A non-finite residual makes the sum non-finite.)
            let ssr_trial = match problem.eval(&trial, at.r_trial, None) {
                Ok(()) => Some(sumsq(at.r_trial)).filter(|s| s.is_finite()),
                Err(_) => None,
            }
            .unwrap_or(f64::INFINITY);
            if !(ssr_trial <= self.ssr) {
                // Below the tolerance and no lower cost: `p` is the optimum to rounding. The
                // round's own Gauss-Newton step failing: LM's damping is needed. A chord step
                // failing (the Jacobian changed too much): a new round from here.
                return self.last || !first;
            }
            first = false;
            self.rescale(problem, at.p, &trial);
            *at.p = trial;
            std::mem::swap(at.r, at.r_trial);
            self.ssr = ssr_trial;
            if self.last || self.pred <= chord_tol2 {
                return true;
            }
            let g = scaled(jt_r(self.par, jac, at.r), &self.scale);
            match gauss_newton_step(&self.rmat, &g, self.lambda, &self.held) {
                Some(dp) => (self.d, self.pred) = dp,
                None => return false,
            }
            if self.pred <= chord_tol2 {
                // A chord step this small is not worth a simulation: the next round's Jacobian
                // is taken here, and its own step includes this one.
                return true;
            }
        }
        true
    }

    /// The chord's columns rescaled for the parameters' move from `p` to `trial`
    /// ([`Problem::column_scale`]).
    fn rescale(&mut self, problem: &impl Problem, p: &[f64], trial: &[f64]) {
        for j in 0..p.len() {
            if let Some(f) = problem
                .column_scale(j, p[j], trial[j])
                .filter(|f| f.is_finite() && *f > 0.0)
            {
                self.scale[j] *= f;
                self.rmat.column_mut(j).iter_mut().for_each(|v| *v *= f);
            }
        }
    }

    /// The report at the end of the last round (its step taken), the covariance from its
    /// Jacobian.
    fn report(
        self,
        opts: &LmOptions,
        p: Vec<f64>,
        r: Vec<f64>,
        jac: &Mat<f64>,
        round: usize,
        evaluations: usize,
    ) -> LmReport {
        let (n, m) = (p.len(), r.len());
        let (covariance, std_errors) = if opts.covariance {
            covariance_and_errors(&self.rmat, self.ssr / (m - n) as f64, &self.held)
        } else {
            (None, None)
        };
        // The gradient at the final point (the step was taken), with the round's Jacobian.
        let g_end = scaled(jt_r(self.par, jac, &r), &self.scale);
        LmReport {
            params: p,
            cost: 0.5 * self.ssr,
            gradient_cosine: gradient_cosine(&g_end, &col_norms_of(&self.rmat), norm(&r)),
            residuals: r,
            iterations: round + 1,
            evaluations,
            termination: Termination::SmallStatisticalStep,
            // The rounds end at `RefineOptions::max_rounds`, not at the LM budget.
            budget_ends: 0,
            converged: true,
            covariance,
            std_errors,
            lambda: self.lambda,
        }
    }
}

/// `v_j s_j` for each `j`.
fn scaled(mut v: Vec<f64>, s: &[f64]) -> Vec<f64> {
    v.iter_mut().zip(s).for_each(|(a, b)| *a *= b);
    v
}

#[cfg(test)]
mod tests {
    use super::super::testproblems::NoisyExp;
    use super::*;

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
}
