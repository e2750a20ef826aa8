//! What the solvers minimise: a [`Problem`] (residuals and their Jacobian), its finite-difference
//! wrapper [`FiniteDiff`], and the dense matrix the Jacobian is written into.

use crate::Result;
/// The dense matrix of [`Problem::eval`]'s Jacobian: nalgebra's `DMatrix` (column-major).
pub use nalgebra::DMatrix as Mat;

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
