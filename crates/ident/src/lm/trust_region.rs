//! The damped steps: Levenberg-Marquardt's `(J^T J + lambda D^2) d = -J^T r` from the `R` of
//! `[J r]` ([`damped_step`]), the Gauss-Newton step of [`super::refine`] ([`gauss_newton_step`]),
//! and the Marquardt factor's update after an accepted step (Nielsen 1999).

use super::problem::Mat;
use super::qr::lstsq;
use crate::numeric::sumsq;

/// Solve `min || R d + Q^T r ||^2 + lambda || D d ||^2` by QR of `[R; sqrt(lambda) D]`.
pub(super) fn damped_step(rmat: &Mat<f64>, qtr: &[f64], diag: &[f64], lambda: f64) -> Vec<f64> {
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

/// The Gauss-Newton step `d = -(R^T R + lambda D^2)^-1 g` for `J^T J = R^T R`, the gradient
/// `g = J^T r` and `D^2 = diag(R^T R)` (1 for a zero column), in the parameters not `held` (a held
/// one's step is 0), with its predicted reduction of the sum of squares `-2 g.d - |R d|^2`
/// (`None` if the small system is not positive definite).
pub(super) fn gauss_newton_step(
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

/// The cost `1/2 |r + J d|^2 = 1/2 (|Q^T r + R d|^2 + r_out)` the linearised model predicts after
/// the step `d`, from the QR of `[J r]` (`r_out = |r|^2 - |Q^T r|^2`, the part of `r` no step
/// can reach), subtracted from the current `cost`: the predicted reduction.
pub(super) fn predicted_cost(
    rmat: &Mat<f64>,
    qtr: &[f64],
    d: &[f64],
    cost: f64,
    r_out: f64,
) -> f64 {
    let n = rmat.ncols();
    let lin: Vec<f64> = (0..qtr.len())
        .map(|i| qtr[i] + (i..n).map(|j| rmat[(i, j)] * d[j]).sum::<f64>())
        .collect();
    cost - 0.5 * (sumsq(&lin) + r_out)
}

/// Nielsen's (1999) factor on `lambda` after a step accepted with the gain ratio `rho`:
/// `max(1/3, 1 - (2 rho - 1)^3)`.
pub(super) fn marquardt_factor(rho: f64) -> f64 {
    let t = 2.0 * rho - 1.0;
    (1.0 - t * t * t).max(1.0 / 3.0)
}
