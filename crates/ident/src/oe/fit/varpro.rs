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
use crate::linalg;
use crate::lm::Mat;
use crate::lm::{dot, minimize, ColSlices, LmOptions, LmReport, Problem};
use crate::oe::{Bounds, LinearRole, Structure};
use crate::par::Par;
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

/// Orthonormalise `cols` in place (Householder, [`linalg::thin_qr`]); returns `R` (row-major,
/// `c x c`) with `cols_in = Q R`, or `None` when a column is (numerically) in the span of those
/// before it. The fallback of [`LinearBasis`] when the Gram matrix is too ill-conditioned for
/// its Cholesky factor.
fn orthonormalise(cols: &mut [Vec<f64>]) -> Option<Vec<f64>> {
    linalg::thin_qr(cols)
}

/// The smallest pivot of the equilibrated Gram matrix's Cholesky factor (the sine of the angle
/// between a column and the span of those before it) a [`LinearBasis`] is built from: below it,
/// the Gram matrix's rounding (`~eps`, on the pivot's square) would show in the solution, and the
/// columns are orthonormalised instead.
const GRAM_MIN_PIVOT: f64 = 1e-5;

/// The Gram matrix `A^T A` of the columns `cols` (row-major `c x c`).
fn gram(cols: &[Vec<f64>]) -> Vec<f64> {
    linalg::gram_of_columns(cols)
}

/// `D` and `L` of the equilibrated Gram matrix `D A^T A D = L L^T` ([`LinearBasis`]) of `c`
/// columns from their Gram matrix `gram` (row-major `c x c`); `None` when a pivot is below
/// [`GRAM_MIN_PIVOT`] (or a column is zero or not finite).
fn equilibrated_cholesky(gram: &[f64], c: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let scale: Vec<f64> = (0..c)
        .map(|j| 1.0 / gram[j * c + j].sqrt())
        .collect::<Vec<f64>>();
    if !scale.iter().all(|d| d.is_finite() && *d > 0.0) {
        return None;
    }
    let scaled = Mat::<f64>::from_fn(c, c, |i, j| gram[i * c + j] * scale[i] * scale[j]);
    let l = linalg::cholesky_lower(&scaled)?;
    if (0..c).any(|j| !(l[j * c + j] > GRAM_MIN_PIVOT)) {
        return None;
    }
    Some((scale, l))
}

/// The linear parameters' columns `A` (`c` of them) with the Cholesky factor of their
/// equilibrated Gram matrix, `D A^T A D = L L^T` (`D` = `1/||A_j||` on the diagonal): the least
/// squares solution `x = D (L L^T)^-1 D A^T y` and the projection orthogonal to the columns,
/// `d - A x(d)`, without forming an orthonormal basis (the semi-normal equations; Björck,
/// *Numerical methods for least squares problems*, 1996, sec. 6.6.5: with one step of iterative
/// refinement, as accurate as a QR factorisation for well-conditioned columns). For an
/// orthonormalised basis `A = Q`, `D = L = I`.
#[derive(Debug, Clone, Default)]
struct LinearBasis {
    cols: Vec<Vec<f64>>,
    /// `D`, the columns' inverse norms.
    scale: Vec<f64>,
    /// `L`, row-major `c x c`, lower triangle.
    chol: Vec<f64>,
    /// For an orthonormalised basis `Q` of columns `A = Q R`: `R` (row-major `c x c`), which
    /// maps the solution in `Q` to the solution in `A`.
    r: Option<Vec<f64>>,
}

impl LinearBasis {
    /// From the columns `cols` and their Gram matrix `gram` (row-major `c x c`, `A^T A`); `None`
    /// when a pivot is below [`GRAM_MIN_PIVOT`] (or a column is zero or not finite).
    #[cfg(test)]
    fn from_gram(cols: Vec<Vec<f64>>, gram: &[f64]) -> Option<Self> {
        let (scale, chol) = equilibrated_cholesky(gram, cols.len())?;
        Some(Self::with_factor(cols, scale, chol))
    }

    /// From the columns and the factor [`equilibrated_cholesky`] made of their Gram matrix.
    fn with_factor(cols: Vec<Vec<f64>>, scale: Vec<f64>, chol: Vec<f64>) -> Self {
        Self {
            cols,
            scale,
            chol,
            r: None,
        }
    }

    /// By modified Gram-Schmidt ([`orthonormalise`]); `None` when the columns are singular.
    fn orthonormal(mut cols: Vec<Vec<f64>>) -> Option<Self> {
        let r = orthonormalise(&mut cols)?;
        let c = cols.len();
        let mut chol = vec![0.0; c * c];
        (0..c).for_each(|i| chol[i * c + i] = 1.0);
        Some(Self {
            cols,
            scale: vec![1.0; c],
            chol,
            r: Some(r),
        })
    }

    /// `x = (A^T A)^-1 h` for `h = A^T v`.
    fn solve_normal(&self, h: &[f64]) -> Vec<f64> {
        let (l, d) = (&self.chol, &self.scale);
        let mut x: Vec<f64> = h.iter().zip(d).map(|(a, b)| a * b).collect();
        linalg::solve_llt_row_major(l, &mut x);
        x.iter_mut().zip(d).for_each(|(a, b)| *a *= b);
        x
    }

    /// `A^T v`.
    fn at(&self, v: &[f64]) -> Vec<f64> {
        self.cols.iter().map(|a| dot(a, v)).collect()
    }

    /// `out += s A x`.
    fn add_ax(&self, x: &[f64], s: f64, out: &mut [f64]) {
        for (a, &xj) in self.cols.iter().zip(x) {
            let f = s * xj;
            out.iter_mut().zip(a).for_each(|(o, b)| *o += f * b);
        }
    }

    /// The least-squares solution `x` of `A x ~ y` given `aty = A^T y`, and `A x` (into
    /// `fitted`). From the Gram matrix, refined once: `x += (A^T A)^-1 A^T (y - A x)`. For an
    /// orthonormalised basis, `x` is in the original columns (`R^-1 Q^T y`).
    fn least_squares(&self, aty: &[f64], y: &[f64], fitted: &mut [f64]) -> Vec<f64> {
        let mut x = self.solve_normal(aty);
        fitted.iter_mut().for_each(|v| *v = 0.0);
        self.add_ax(&x, 1.0, fitted);
        let Some(r) = &self.r else {
            let res: Vec<f64> = y.iter().zip(fitted.iter()).map(|(a, b)| a - b).collect();
            let dx = self.solve_normal(&self.at(&res));
            self.add_ax(&dx, 1.0, fitted);
            x.iter_mut().zip(&dx).for_each(|(a, b)| *a += b);
            return x;
        };
        linalg::solve_upper_row_major(r, &mut x);
        x
    }

    /// `d` projected orthogonally to the columns, in place: `d -= A (A^T A)^-1 A^T d`.
    fn project_out(&self, d: &mut [f64]) {
        let z = self.solve_normal(&self.at(d));
        self.add_ax(&z, -1.0, d);
    }
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
    /// The linear parameters' columns there (a held level's response in the gain's).
    basis: LinearBasis,
    yhat: Vec<f64>,
    /// The sum of squares at the start (before any linear solution).
    start_ssr: Option<f64>,
    /// The levels (indices into `free`) the last solution held at an edge of their range.
    held: Vec<usize>,
    /// Column buffers of `m` samples a former basis left, for the next solution's columns
    /// (each solution would otherwise allocate and fault in its own).
    spare: Vec<Vec<f64>>,
    /// On how many threads its Jacobian is computed.
    par: Par,
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
        (theta, par): (&[f64], Par),
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
            basis: LinearBasis::default(),
            yhat: vec![0.0; u.len()],
            start_ssr: None,
            held: vec![],
            spare: vec![],
            par,
        }
    }

    /// A column of `m` samples from [`Reduced::spare`] (any values), or a new one.
    fn spare_column(&mut self, m: usize) -> Vec<f64> {
        match self.spare.pop() {
            Some(c) if c.len() == m => c,
            _ => vec![0.0; m],
        }
    }

    /// The raw columns of the linear basis at the physical values `p` (`which`: the linear
    /// parameters' indices): `G0 u`, the levels' free responses `F_i` and, with an output
    /// offset, 1, from one simulation (into `yhat`; the first one's sum of squares kept).
    fn raw_columns(&mut self, p: &[f64], which: &[usize]) -> Result<Vec<Vec<f64>>> {
        let (s, plan, skip) = (self.s, self.plan, self.skip);
        let m = self.y.len() - skip;
        let mut cols: Vec<Vec<f64>> = (0..which.len()).map(|_| self.spare_column(m)).collect();
        {
            let mut out: Vec<&mut [f64]> = cols.iter_mut().map(|c| c.as_mut_slice()).collect();
            s.simulate_with_linear(p, which, self.u, self.dt, &mut self.yhat, skip, &mut out)?;
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
        let k = p[which[plan.gain]];
        if !(k.is_finite() && k != 0.0) {
            return Err(Error::Numerical("variable projection: a zero gain".into()));
        }
        // The basis: F_i = d yhat/d w_i / K; G0 u = d yhat/d K - sum_i w_i F_i (each column
        // made in its own buffer).
        let f: Vec<Vec<f64>> = plan
            .levels
            .iter()
            .map(|&l| {
                let mut c = std::mem::take(&mut cols[l]);
                c.iter_mut().for_each(|v| *v /= k);
                c
            })
            .collect();
        let mut g = std::mem::take(&mut cols[plan.gain]);
        for (&l, fi) in plan.levels.iter().zip(&f) {
            let w = p[which[l]];
            g.iter_mut().zip(fi).for_each(|(a, b)| *a -= w * b);
        }
        // The columns the bases are made of: G0 u, the levels' responses, 1 (a held level's
        // response joins the gain's column, a combination of these).
        let mut raw: Vec<Vec<f64>> = Vec::with_capacity(f.len() + 2);
        raw.push(g);
        raw.extend(f);
        if let Some(o) = plan.offset {
            // The offset's sensitivity: 1 at every sample.
            let mut ones = std::mem::take(&mut cols[o]);
            ones.iter_mut().for_each(|v| *v = 1.0);
            raw.push(ones);
        }
        Ok(raw)
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
        let mut raw = self.raw_columns(&p, &which)?;
        let y_all = self.y;
        let y = &y_all[skip..];
        let gain_j = which[plan.gain];
        // The raw columns' Gram matrix and their products with y, once.
        let nr = raw.len();
        let gram = gram(&raw);
        let raw_y: Vec<f64> = raw.iter().map(|a| dot(a, y)).collect();
        let nf = nr - 1 - usize::from(plan.offset.is_some());
        let mut held: Vec<Option<f64>> = vec![None; nf];
        for _ in 0..=nf {
            let free_levels: Vec<usize> = (0..nf).filter(|&i| held[i].is_none()).collect();
            let comb = combinations(&held, &free_levels, nr, plan.offset.is_some());
            let c = comb.len();
            let ga = combined_gram(&comb, &gram, nr);
            let aty: Vec<f64> = comb
                .iter()
                .map(|t| t.iter().zip(&raw_y).map(|(a, b)| a * b).sum())
                .collect();
            // With no level held the columns are the raw ones: moved into the basis (and back
            // should a level be held after all), not copied.
            let unit = held.iter().all(Option::is_none);
            let basis = match equilibrated_cholesky(&ga, c) {
                Some((scale, chol)) if unit => {
                    LinearBasis::with_factor(std::mem::take(&mut raw), scale, chol)
                }
                Some((scale, chol)) => {
                    LinearBasis::with_factor(combined_columns(&comb, &raw, m), scale, chol)
                }
                None => {
                    LinearBasis::orthonormal(combined_columns(&comb, &raw, m)).ok_or_else(|| {
                        Error::Numerical("variable projection: the linear basis is singular".into())
                    })?
                }
            };
            let aty = if basis.r.is_some() { basis.at(y) } else { aty };
            let mut fitted = self.spare_column(m);
            let x = basis.least_squares(&aty, y, &mut fitted);
            let a = x[0];
            if !(a.is_finite() && a != 0.0)
                || (params[gain_j].bounds == Bounds::Positive && a <= 0.0)
            {
                return Err(Error::Numerical(
                    "variable projection: the gain left its range".into(),
                ));
            }
            let (w, again) = self.hold_levels(&which, &x, &free_levels, &mut held);
            if again {
                if raw.is_empty() {
                    raw = basis.cols;
                }
                self.spare.push(fitted);
                continue;
            }
            let solution = Solution {
                x: &x,
                w: &w,
                held: &held,
            };
            self.accept(th, theta_n, &which, &solution, basis, fitted, raw)?;
            return Ok(());
        }
        Err(Error::Numerical(
            "variable projection: the levels do not settle in their ranges".into(),
        ))
    }

    /// The levels `w` of a solution `x` (the free levels' `K w_i` after the gain `x[0]`); a free
    /// level outside its range is held just inside it (into `held`), and then `true`: solve
    /// again.
    fn hold_levels(
        &self,
        which: &[usize],
        x: &[f64],
        free_levels: &[usize],
        held: &mut [Option<f64>],
    ) -> (Vec<f64>, bool) {
        let params = self.s.params();
        let a = x[0];
        let mut again = false;
        let mut w = vec![0.0; held.len()];
        for (slot, &i) in free_levels.iter().enumerate() {
            w[i] = x[1 + slot] / a;
            let b = params[which[self.plan.levels[i]]].bounds;
            if let Bounds::Interval(lo, hi) = b {
                if !(w[i] > lo && w[i] < hi) {
                    held[i] = Some(b.clamp_inside(w[i]));
                    again = true;
                }
            }
        }
        (w, again)
    }

    /// Keep the solution at `theta_n` (every free parameter's `th`, the linear ones set from
    /// `sol`), its basis and fitted output; the buffers it no longer needs are kept as spares.
    #[allow(clippy::too_many_arguments)]
    fn accept(
        &mut self,
        mut th: Vec<f64>,
        theta_n: &[f64],
        which: &[usize],
        sol: &Solution<'_>,
        basis: LinearBasis,
        fitted: Vec<f64>,
        raw: Vec<Vec<f64>>,
    ) -> Result<()> {
        let (plan, params) = (self.plan, self.s.params());
        let m = self.y.len() - self.skip;
        let c = sol.x.len();
        let to = |k: usize, v: f64| {
            let j = which[k];
            let b = params[j].bounds;
            b.to_theta(b.clamp_inside(v), &params[j].name)
        };
        th[plan.lin[plan.gain]] = to(plan.gain, sol.x[0])?;
        for (i, &l) in plan.levels.iter().enumerate() {
            th[plan.lin[l]] = to(l, sol.held[i].unwrap_or(sol.w[i]))?;
        }
        if let Some(o) = plan.offset {
            th[plan.lin[o]] = to(o, sol.x[c - 1])?;
        }
        self.theta = th;
        self.at = Some(theta_n.to_vec());
        let old = std::mem::replace(&mut self.basis, basis);
        self.spare.extend(old.cols);
        self.spare.push(std::mem::replace(&mut self.fitted, fitted));
        self.spare.extend(raw.into_iter().filter(|c| c.len() == m));
        self.spare.truncate(which.len() + 2);
        let nf = sol.held.len();
        self.held = (0..nf)
            .filter(|&i| sol.held[i].is_some())
            .map(|i| plan.lin[plan.levels[i]])
            .collect();
        Ok(())
    }
}

/// A linear solution of [`Reduced::solve`]: `x` in its basis's columns (the gain's, the free
/// levels', the offset's), the levels `w` and those held at an edge of their range.
struct Solution<'s> {
    x: &'s [f64],
    w: &'s [f64],
    held: &'s [Option<f64>],
}

/// The columns of a basis as combinations `t` (row-major `c x nr`) of the `nr` raw columns: the
/// gain's (`G0 u` and the held levels' responses), the free levels' (`free_levels`), and 1 for
/// an output offset.
fn combinations(
    held: &[Option<f64>],
    free_levels: &[usize],
    nr: usize,
    offset: bool,
) -> Vec<Vec<f64>> {
    let mut comb: Vec<Vec<f64>> = vec![];
    let mut first = vec![0.0; nr];
    first[0] = 1.0;
    for (i, h) in held.iter().enumerate() {
        if let Some(v) = h {
            first[1 + i] = *v;
        }
    }
    comb.push(first);
    for &i in free_levels {
        let mut t = vec![0.0; nr];
        t[1 + i] = 1.0;
        comb.push(t);
    }
    if offset {
        let mut t = vec![0.0; nr];
        t[nr - 1] = 1.0;
        comb.push(t);
    }
    comb
}

/// The Gram matrix (row-major `c x c`) of the combinations `comb` of raw columns whose Gram
/// matrix is `gram` (row-major `nr x nr`).
fn combined_gram(comb: &[Vec<f64>], gram: &[f64], nr: usize) -> Vec<f64> {
    let c = comb.len();
    let mut ga = vec![0.0; c * c];
    for a in 0..c {
        for b in 0..c {
            let mut v = 0.0;
            for i in 0..nr {
                if comb[a][i] == 0.0 {
                    continue;
                }
                for j in 0..nr {
                    v += comb[a][i] * gram[i * nr + j] * comb[b][j];
                }
            }
            ga[a * c + b] = v;
        }
    }
    ga
}

/// The combinations `comb` of the raw columns `raw` as columns of `m` samples (a raw column
/// itself copied).
fn combined_columns(comb: &[Vec<f64>], raw: &[Vec<f64>], m: usize) -> Vec<Vec<f64>> {
    let nr = raw.len();
    comb.iter()
        .map(|t| {
            let nz: Vec<usize> = (0..nr).filter(|&i| t[i] != 0.0).collect();
            if let [i] = nz[..] {
                if t[i] == 1.0 {
                    return raw[i].clone();
                }
            }
            let mut v = vec![0.0; m];
            for &i in &nz {
                let w = t[i];
                v.iter_mut().zip(&raw[i]).for_each(|(a, b)| *a += w * b);
            }
            v
        })
        .collect()
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
        let par = self.par;
        jacobian(
            s,
            &pv,
            &which,
            &th,
            true,
            u,
            dt,
            skip,
            (&mut self.yhat, out),
            par,
        )?;
        r.iter_mut()
            .zip(&self.yhat[skip..])
            .zip(y)
            .for_each(|((rk, f), yk)| *rk = f - yk);
        for c in 0..which.len() {
            self.basis.project_out(out.col_as_slice_mut(c));
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
    let mut red = Reduced::new(s, u, y, dt, skip, &free, &base, plan, (theta0, prob.par));
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
            cold.budget_ends += rep.budget_ends;
            Ok(cold)
        })
    } else {
        rep
    };
    if let Ok(rep) = &mut rep {
        rep.iterations += rr.iterations;
        rep.evaluations += rr.evaluations;
        rep.budget_ends += rr.budget_ends;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Columns `1, t, sin(3 t), exp(-t) + eps t^2` over `m` samples and an output in their span
    /// plus a known residual orthogonal to nothing in particular.
    fn columns(m: usize, eps: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
        let t: Vec<f64> = (0..m).map(|k| k as f64 / m as f64).collect();
        let cols = vec![
            vec![1.0; m],
            t.clone(),
            t.iter().map(|v| (3.0 * v).sin()).collect(),
            t.iter().map(|v| (-v).exp() + eps * v * v).collect(),
        ];
        let y = t.iter().map(|v| (7.0 * v).cos() + 0.5 * v).collect();
        (cols, y)
    }

    #[test]
    fn the_gram_basis_solves_and_projects_as_the_orthonormalised_one() {
        let (cols, y) = columns(3000, 1.0);
        let g = gram(&cols);
        let fast = LinearBasis::from_gram(cols.clone(), &g).expect("well conditioned");
        assert!(fast.r.is_none());
        let slow = LinearBasis::orthonormal(cols.clone()).expect("independent columns");
        let (mut f1, mut f2) = (vec![0.0; y.len()], vec![0.0; y.len()]);
        let x1 = fast.least_squares(&fast.at(&y), &y, &mut f1);
        let x2 = slow.least_squares(&slow.at(&y), &y, &mut f2);
        // The same solution (to far below any standard error: the columns' condition number
        // times the rounding), the same fitted output.
        for (a, b) in x1.iter().zip(&x2) {
            assert!((a - b).abs() <= 1e-10 * (1.0 + b.abs()), "{x1:?} vs {x2:?}");
        }
        for (a, b) in f1.iter().zip(&f2) {
            assert!((a - b).abs() <= 1e-11);
        }
        // The residual is orthogonal to every column (the normal equations hold).
        let r: Vec<f64> = y.iter().zip(&f1).map(|(a, b)| a - b).collect();
        let ry = dot(&r, &r).sqrt();
        for c in &cols {
            assert!(dot(c, &r).abs() <= 1e-12 * ry * dot(c, c).sqrt());
        }
        // The projection removes the columns' span: y projected is that residual.
        let mut p = y.clone();
        fast.project_out(&mut p);
        for (a, b) in p.iter().zip(&r) {
            assert!((a - b).abs() <= 1e-11);
        }
    }

    #[test]
    fn a_nearly_dependent_basis_is_orthonormalised_instead() {
        // A column equal to a combination of the others up to about 1e-9 of its norm: its
        // pivot is below GRAM_MIN_PIVOT, the Gram factor refuses it, Gram-Schmidt takes it.
        let (mut cols, y) = columns(2000, 0.0);
        let near: Vec<f64> = cols[0]
            .iter()
            .zip(&cols[1])
            .enumerate()
            .map(|(k, (a, b))| 2.0 * a - b + 1e-9 * ((k % 7) as f64 - 3.0))
            .collect();
        cols[3] = near;
        let g = gram(&cols);
        assert!(LinearBasis::from_gram(cols.clone(), &g).is_none());
        let slow = LinearBasis::orthonormal(cols.clone()).expect("independent to 1e-12");
        let mut f = vec![0.0; y.len()];
        let x = slow.least_squares(&slow.at(&y), &y, &mut f);
        // x solves the least-squares problem in the original columns: A x = fitted.
        let mut ax = vec![0.0; y.len()];
        for (c, &xj) in cols.iter().zip(&x) {
            ax.iter_mut().zip(c).for_each(|(a, b)| *a += xj * b);
        }
        for (a, b) in ax.iter().zip(&f) {
            assert!((a - b).abs() <= 1e-6, "{a} vs {b}");
        }
        // Exactly dependent columns: neither.
        cols[3] = cols[0]
            .iter()
            .zip(&cols[1])
            .map(|(a, b)| 2.0 * a - b)
            .collect();
        assert!(LinearBasis::from_gram(cols.clone(), &gram(&cols)).is_none());
        assert!(LinearBasis::orthonormal(cols).is_none());
    }
}
