//! Variable projection (Golub & Pereyra 1973; Kaufman 1975) for the parameters the output is
//! linear in: the gain `K`, the initial state's levels `w_i` and the output offset `c`, with
//! `yhat = K (G0 u + sum_i w_i F_i) + c` ([`LinearRole`]).
//!
//! At given other parameters (the orders and the denominator's coefficients) the best `K`,
//! `K w_i` and `c` solve a linear least-squares problem in the basis `G0 u, F_i, 1`, which one
//! simulation and the levels' free responses give. Levenberg-Marquardt then runs over the other
//! parameters only, on the residual of that solution, with Kaufman's Jacobian: the exact
//! sensitivities at the solution projected orthogonally to the basis. The levels of a short
//! record are nearly undetermined, and a joint fit crawls along the valley they make with the
//! orders; the projection removes the valley. The result starts the joint fit
//! ([`crate::lm::minimize`] over every free parameter), which ends by the same tests and gives
//! the standard errors.

use super::{jacobian, physical, OeProblem};
use crate::lm::Mat;
use crate::lm::{dot, minimize, ColSlices, LmOptions, LmReport, Problem};
use crate::oe::{Bounds, LinearRole, Structure};
use crate::{Error, Result};

/// Which free parameters (indices into the fit's `free`) are solved linearly.
#[derive(Debug, Clone)]
pub(super) struct Plan {
    /// The others: the reduced problem's parameters.
    nonlin: Vec<usize>,
    /// The linear ones, in the order of `free`.
    lin: Vec<usize>,
    /// The gain's position in `lin`.
    gain: usize,
    /// The levels' positions in `lin`.
    levels: Vec<usize>,
    /// The output offset's position in `lin`.
    offset: Option<usize>,
}

/// The plan for the free parameters `free` of `s`, when the projection applies: a free gain, at
/// least one free level, every output offset free (at most one), and other free parameters.
pub(super) fn plan<S: Structure>(s: &S, free: &[usize]) -> Option<Plan> {
    let n = s.params().len();
    let roles: Vec<Option<LinearRole>> = (0..n).map(|j| s.linear_role(j)).collect();
    let is_free = |j: usize| free.contains(&j);
    let offsets: Vec<usize> = (0..n)
        .filter(|&j| roles[j] == Some(LinearRole::Offset))
        .collect();
    let gains: Vec<usize> = (0..n)
        .filter(|&j| roles[j] == Some(LinearRole::Gain))
        .collect();
    if offsets.len() > 1 || !offsets.iter().all(|&j| is_free(j)) || gains.len() != 1 {
        return None;
    }
    let (lin, nonlin): (Vec<usize>, Vec<usize>) =
        (0..free.len()).partition(|&i| roles[free[i]].is_some());
    let role = |k: usize| roles[free[lin[k]]];
    let gain = (0..lin.len()).find(|&k| role(k) == Some(LinearRole::Gain))?;
    let levels: Vec<usize> = (0..lin.len())
        .filter(|&k| role(k) == Some(LinearRole::Level))
        .collect();
    let offset = (0..lin.len()).find(|&k| role(k) == Some(LinearRole::Offset));
    (!levels.is_empty() && !nonlin.is_empty()).then_some(Plan {
        nonlin,
        lin,
        gain,
        levels,
        offset,
    })
}

/// Orthonormalise `cols` in place (modified Gram-Schmidt, twice: as accurate as Householder for
/// a handful of columns); returns `R` (row-major, `c x c`) with `cols_in = Q R`, or `None` when
/// a column is (numerically) in the span of those before it.
fn orthonormalise(cols: &mut [Vec<f64>]) -> Option<Vec<f64>> {
    let c = cols.len();
    let mut r = vec![0.0; c * c];
    for k in 0..c {
        let (done, rest) = cols.split_at_mut(k);
        let v = &mut rest[0];
        let n0 = dot(v, v).sqrt();
        for _ in 0..2 {
            for (i, q) in done.iter().enumerate() {
                let h = dot(q, v);
                r[i * c + k] += h;
                v.iter_mut().zip(q).for_each(|(a, b)| *a -= h * b);
            }
        }
        let nk = dot(v, v).sqrt();
        if !(nk > 1e-12 * n0) || !nk.is_finite() {
            return None;
        }
        r[k * c + k] = nk;
        v.iter_mut().for_each(|a| *a /= nk);
    }
    Some(r)
}

/// The reduced problem over the parameters of [`Plan::nonlin`] (in `theta`, reparametrised).
pub(super) struct Reduced<'a, S: Structure> {
    s: &'a S,
    u: &'a [f64],
    y: &'a [f64],
    dt: f64,
    skip: usize,
    free: &'a [usize],
    base: &'a [f64],
    plan: &'a Plan,
    /// Every free parameter's `theta` at the last linear solution.
    theta: Vec<f64>,
    /// The reduced parameters that solution was made at.
    at: Option<Vec<f64>>,
    /// Its fitted output over the fitted samples.
    fitted: Vec<f64>,
    /// An orthonormal basis of the linear parameters' columns there (a held level's response
    /// in the gain's).
    basis: Vec<Vec<f64>>,
    yhat: Vec<f64>,
    /// The sum of squares at the start (before any linear solution).
    start_ssr: Option<f64>,
    /// The levels (indices into `free`) the last solution held at an edge of their range.
    held: Vec<usize>,
}

impl<'a, S: Structure> Reduced<'a, S> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        s: &'a S,
        u: &'a [f64],
        y: &'a [f64],
        dt: f64,
        skip: usize,
        free: &'a [usize],
        base: &'a [f64],
        plan: &'a Plan,
        theta: &[f64],
    ) -> Self {
        let m = u.len() - skip;
        Self {
            s,
            u,
            y,
            dt,
            skip,
            free,
            base,
            plan,
            theta: theta.to_vec(),
            at: None,
            fitted: vec![0.0; m],
            basis: vec![],
            yhat: vec![0.0; u.len()],
            start_ssr: None,
            held: vec![],
        }
    }

    /// Solve the linear parameters at the reduced parameters `theta_n`: one simulation, the
    /// levels' free responses, a least-squares fit in the basis `G0 u, F_i, 1`. A level outside
    /// its range is held just inside it and the others solved again.
    fn solve(&mut self, theta_n: &[f64]) -> Result<()> {
        if self.at.as_deref() == Some(theta_n) {
            return Ok(());
        }
        let (s, plan, skip) = (self.s, self.plan, self.skip);
        let params = s.params();
        let mut th = self.theta.clone();
        for (&i, &t) in plan.nonlin.iter().zip(theta_n) {
            th[i] = t;
        }
        let p = physical(s, self.free, self.base, &th);
        let which: Vec<usize> = plan.lin.iter().map(|&i| self.free[i]).collect();
        let m = self.y.len() - skip;
        let mut cols = vec![vec![0.0; m]; which.len()];
        {
            let mut out: Vec<&mut [f64]> = cols.iter_mut().map(|c| c.as_mut_slice()).collect();
            s.simulate_with_linear(&p, &which, self.u, self.dt, &mut self.yhat, skip, &mut out)?;
        }
        let y = &self.y[skip..];
        if self.start_ssr.is_none() {
            let r: Vec<f64> = self.yhat[skip..]
                .iter()
                .zip(y)
                .map(|(a, b)| a - b)
                .collect();
            self.start_ssr = Some(dot(&r, &r));
        }
        let gain_j = which[plan.gain];
        let k = p[gain_j];
        if !(k.is_finite() && k != 0.0) {
            return Err(Error::Numerical("variable projection: a zero gain".into()));
        }
        // The basis: F_i = d yhat/d w_i / K; G0 u = d yhat/d K - sum_i w_i F_i.
        let f: Vec<Vec<f64>> = plan
            .levels
            .iter()
            .map(|&l| cols[l].iter().map(|v| v / k).collect())
            .collect();
        let mut g = cols[plan.gain].clone();
        for (&l, fi) in plan.levels.iter().zip(&f) {
            let w = p[which[l]];
            g.iter_mut().zip(fi).for_each(|(a, b)| *a -= w * b);
        }
        let mut held: Vec<Option<f64>> = vec![None; f.len()];
        for _ in 0..=f.len() {
            // Columns: the gain's (G0 u and the held levels' responses), the free levels', 1.
            let mut gk = g.clone();
            for (h, fi) in held.iter().zip(&f) {
                if let Some(v) = h {
                    gk.iter_mut().zip(fi).for_each(|(a, b)| *a += v * b);
                }
            }
            let mut basis = vec![gk];
            let free_levels: Vec<usize> = (0..f.len()).filter(|&i| held[i].is_none()).collect();
            basis.extend(free_levels.iter().map(|&i| f[i].clone()));
            if plan.offset.is_some() {
                basis.push(vec![1.0; m]);
            }
            let mut q = basis;
            let c = q.len();
            let r = orthonormalise(&mut q).ok_or_else(|| {
                Error::Numerical("variable projection: the linear basis is singular".into())
            })?;
            let qty: Vec<f64> = q.iter().map(|qk| dot(qk, y)).collect();
            let mut x = qty.clone();
            for i in (0..c).rev() {
                let t: f64 = (i + 1..c).map(|j| r[i * c + j] * x[j]).sum();
                x[i] = (qty[i] - t) / r[i * c + i];
            }
            let a = x[0];
            if !(a.is_finite() && a != 0.0)
                || (params[gain_j].bounds == Bounds::Positive && a <= 0.0)
            {
                return Err(Error::Numerical(
                    "variable projection: the gain left its range".into(),
                ));
            }
            let mut again = false;
            let mut w = vec![0.0; f.len()];
            for (slot, &i) in free_levels.iter().enumerate() {
                w[i] = x[1 + slot] / a;
                let b = params[which[plan.levels[i]]].bounds;
                if let Bounds::Interval(lo, hi) = b {
                    if !(w[i] > lo && w[i] < hi) {
                        held[i] = Some(b.clamp_inside(w[i]));
                        again = true;
                    }
                }
            }
            if again {
                continue;
            }
            self.fitted.iter_mut().for_each(|v| *v = 0.0);
            for (qk, &h) in q.iter().zip(&qty) {
                self.fitted
                    .iter_mut()
                    .zip(qk)
                    .for_each(|(a, b)| *a += h * b);
            }
            let to = |k: usize, v: f64| {
                let j = which[k];
                let b = params[j].bounds;
                b.to_theta(b.clamp_inside(v), &params[j].name)
            };
            th[plan.lin[plan.gain]] = to(plan.gain, a)?;
            for (i, &l) in plan.levels.iter().enumerate() {
                th[plan.lin[l]] = to(l, held[i].unwrap_or(w[i]))?;
            }
            if let Some(o) = plan.offset {
                th[plan.lin[o]] = to(o, x[c - 1])?;
            }
            self.theta = th;
            self.at = Some(theta_n.to_vec());
            self.basis = q;
            self.held = (0..f.len())
                .filter(|&i| held[i].is_some())
                .map(|i| plan.lin[plan.levels[i]])
                .collect();
            return Ok(());
        }
        Err(Error::Numerical(
            "variable projection: the levels do not settle in their ranges".into(),
        ))
    }
}

impl<S: Structure> Problem for Reduced<'_, S> {
    fn n_params(&self) -> usize {
        self.plan.nonlin.len()
    }
    fn n_residuals(&self) -> usize {
        self.y.len() - self.skip
    }
    fn at_bound(&self, j: usize, theta_j: f64) -> bool {
        let b = self.s.params()[self.free[self.plan.nonlin[j]]].bounds;
        b.at_edge(b.to_param(theta_j))
    }
    fn eval(&mut self, theta_n: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
        self.solve(theta_n)?;
        let y = &self.y[self.skip..];
        let Some(out) = jac else {
            r.iter_mut()
                .zip(&self.fitted)
                .zip(y)
                .for_each(|((rk, f), yk)| *rk = f - yk);
            return Ok(());
        };
        // The exact sensitivities of the reduced parameters at the solution, the residual of
        // the simulation there, and Kaufman's Jacobian: those columns projected orthogonally
        // to the linear parameters' (the basis of the solution).
        let (s, u, dt, skip) = (self.s, self.u, self.dt, self.skip);
        let pv = physical(s, self.free, self.base, &self.theta);
        let which: Vec<usize> = self.plan.nonlin.iter().map(|&i| self.free[i]).collect();
        let th: Vec<f64> = self.plan.nonlin.iter().map(|&i| self.theta[i]).collect();
        jacobian(s, &pv, &which, &th, true, u, dt, skip, &mut self.yhat, out)?;
        r.iter_mut()
            .zip(&self.yhat[skip..])
            .zip(y)
            .for_each(|((rk, f), yk)| *rk = f - yk);
        for c in 0..which.len() {
            let d = out.col_as_slice_mut(c);
            for qk in &self.basis {
                let h = dot(qk, d);
                d.iter_mut().zip(qk).for_each(|(a, b)| *a -= h * b);
            }
        }
        Ok(())
    }
}

/// The relative cost change under which the reduced fit hands over to the joint fit (which
/// stops by the caller's tests).
const REDUCED_FTOL: f64 = 1e-7;

/// Fit by variable projection, then the joint fit `prob` (every free parameter) from its
/// result; `None` when the reduced fit fails (the caller fits jointly from the start). A level
/// the projection held at an edge of its range stays held there in the joint fit (its standard
/// error NaN, the others' the covariance with it fixed, as [`minimize`] reports a parameter at
/// a bound). The joint fit starts from the start `theta0` instead when the projection's result
/// fits worse than it. With `shared`, the two fits share `lm.max_iterations` (the joint fit
/// has the iterations the reduced one left); else each has all of them.
pub(super) fn fit<S: Structure>(
    prob: &mut OeProblem<'_, S>,
    plan: &Plan,
    theta0: &[f64],
    lm: &LmOptions,
    shared: bool,
) -> Option<Result<LmReport>> {
    let (free, base) = (prob.free.clone(), prob.base.clone());
    let (s, u, y, dt, skip) = (prob.s, prob.u, prob.y, prob.dt, prob.skip);
    let mut red = Reduced::new(s, u, y, dt, skip, &free, &base, plan, theta0);
    let tn0: Vec<f64> = plan.nonlin.iter().map(|&i| theta0[i]).collect();
    let red_lm = LmOptions {
        covariance: false,
        ftol: lm.ftol.max(REDUCED_FTOL),
        ..lm.clone()
    };
    let rr = minimize(&mut red, &tn0, &red_lm).ok()?;
    red.solve(&rr.params).ok()?;
    // The joint fit starts at the projection's optimum (to the projection's cost test): its
    // steps are small, and its last one (under the cost test) is far below the standard errors,
    // so the covariance is that of the point before it (one Jacobian fewer). A shared budget:
    // the joint fit has the iterations the reduced one left.
    let joint_lm = LmOptions {
        initial_lambda: rr.lambda.clamp(1e-12, lm.initial_lambda),
        covariance_before_last_step: true,
        max_iterations: if shared {
            lm.max_iterations.saturating_sub(rr.iterations)
        } else {
            lm.max_iterations
        },
        ..lm.clone()
    };
    let rep = joint_holding(prob, &red.theta, &red.held, &joint_lm);
    let worse = match (&rep, prob.first_ssr, red.start_ssr) {
        (Ok(_), Some(a), Some(b)) => a > b,
        _ => false,
    };
    let mut rep = if worse {
        rep.and_then(|rep| {
            let mut cold = minimize(prob, theta0, lm)?;
            cold.iterations += rep.iterations;
            cold.evaluations += rep.evaluations;
            Ok(cold)
        })
    } else {
        rep
    };
    if let Ok(rep) = &mut rep {
        rep.iterations += rr.iterations;
        rep.evaluations += rr.evaluations;
    }
    Some(rep)
}

/// [`minimize`] of `prob` from `theta` with the free parameters `held` (indices into
/// `prob.free`) held at their values in `theta`; the report over every free parameter (a held
/// one's standard error and covariance NaN, the others' scaled to the residual variance of the
/// whole count of free parameters, as [`minimize`] gives them for a parameter at a bound).
fn joint_holding<S: Structure>(
    prob: &mut OeProblem<'_, S>,
    theta: &[f64],
    held: &[usize],
    lm: &LmOptions,
) -> Result<LmReport> {
    if held.is_empty() {
        return minimize(prob, theta, lm);
    }
    let (free, base) = (prob.free.clone(), prob.base.clone());
    let n = free.len();
    let kept: Vec<usize> = (0..n).filter(|i| !held.contains(i)).collect();
    let params = prob.s.params();
    for &h in held {
        prob.base[free[h]] = params[free[h]].bounds.to_param(theta[h]);
    }
    prob.free = kept.iter().map(|&i| free[i]).collect();
    let sub: Vec<f64> = kept.iter().map(|&i| theta[i]).collect();
    let rep = minimize(prob, &sub, lm);
    prob.free = free;
    prob.base = base;
    let mut rep = rep?;
    let mut p = theta.to_vec();
    for (&i, &v) in kept.iter().zip(&rep.params) {
        p[i] = v;
    }
    rep.params = p;
    let m = prob.y.len() - prob.skip;
    let f = (m - kept.len()) as f64 / (m - n).max(1) as f64;
    let nk = kept.len();
    rep.covariance = rep.covariance.map(|c| {
        let mut full = vec![f64::NAN; n * n];
        for (a, &i) in kept.iter().enumerate() {
            for (b, &j) in kept.iter().enumerate() {
                full[i * n + j] = c[a * nk + b] * f;
            }
        }
        full
    });
    rep.std_errors = rep.covariance.as_ref().map(|c| {
        (0..n)
            .map(|i| match c[i * n + i] {
                v if v.is_nan() => v,
                v => v.max(0.0).sqrt(),
            })
            .collect()
    });
    Ok(rep)
}
