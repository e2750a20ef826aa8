//! The damped steps: Levenberg-Marquardt's `(J^T J + lambda D^2) d = -J^T r` from the `R` of
//! `[J r]` ([`damped_step`]), the Gauss-Newton step of [`super::refine`] ([`gauss_newton_step`]),
//! and the Marquardt factor's update after an accepted step (Nielsen 1999).

use super::problem::Mat;
use crate::linalg::{self, lstsq};
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
        let ata = linalg::gram(rmat);
        let k = free.len();
        let mut a = Mat::<f64>::from_fn(k, k, |i, j| ata[(free[i], free[j])]);
        for j in 0..k {
            let d2 = a[(j, j)];
            a[(j, j)] += lambda * if d2 > 0.0 { d2 } else { 1.0 };
        }
        let rhs: Vec<f64> = free.iter().map(|&j| -g[j]).collect();
        let x = linalg::cholesky_solve(&a, &rhs)?;
        for (i, &j) in free.iter().enumerate() {
            d[j] = x[i];
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

#[cfg(test)]
mod tests {
    use super::super::qr::qr_of_jr;
    use super::super::testproblems::uniform;
    use super::*;
    use crate::par::Par;

    /// A small well-conditioned `J` (40 x 3) and `r`.
    fn small_problem() -> (Mat<f64>, Vec<f64>) {
        let mut rnd = uniform(17);
        let jac = Mat::<f64>::from_fn(40, 3, |i, j| rnd() + if i % 3 == j { 1.0 } else { 0.0 });
        let r = (0..40).map(|_| rnd()).collect();
        (jac, r)
    }

    /// `(J^T J + diag(extra)) x = -J^T r` by nalgebra's LU on the dense normal equations: the
    /// truth, by another library and another route than the QR of `[J r]`.
    fn normal_equations(jac: &Mat<f64>, r: &[f64], extra: &[f64]) -> Vec<f64> {
        let n = jac.ncols();
        let mut a = jac.transpose() * jac;
        for j in 0..n {
            a[(j, j)] += extra[j];
        }
        let rhs = -(jac.transpose() * nalgebra::DVector::from_column_slice(r));
        let x = a.lu().solve(&rhs).expect("a regular system");
        x.iter().copied().collect()
    }

    /// The damped step from `R` and `Q^T r` solves Marquardt's normal equations
    /// `(J^T J + lambda D^2) d = -J^T r`, for a small and a large `lambda`; its predicted cost is
    /// `1/2 |r + J d|^2` evaluated directly.
    #[test]
    fn the_damped_step_solves_the_damped_normal_equations() {
        let (jac, r) = small_problem();
        let (rmat, qtr) = qr_of_jr(Par::Seq, &jac, &r);
        let diag = [1.5, 0.7, 2.0];
        let cost = 0.5 * sumsq(&r);
        let r_out = sumsq(&r) - sumsq(&qtr);
        for lambda in [1e-6, 0.3, 50.0] {
            let d = damped_step(&rmat, &qtr, &diag, lambda);
            let extra: Vec<f64> = diag.iter().map(|v| lambda * v * v).collect();
            let want = normal_equations(&jac, &r, &extra);
            for j in 0..3 {
                // Condition about 10: both routes agree to rounding.
                assert!(
                    (d[j] - want[j]).abs() < 1e-12 * (1.0 + want[j].abs()),
                    "lambda {lambda}"
                );
            }
            let rd: Vec<f64> = (0..40)
                .map(|i| r[i] + (0..3).map(|j| jac[(i, j)] * d[j]).sum::<f64>())
                .collect();
            let want_pred = cost - 0.5 * sumsq(&rd);
            let pred = predicted_cost(&rmat, &qtr, &d, cost, r_out);
            assert!((pred - want_pred).abs() < 1e-12 * cost, "lambda {lambda}");
        }
    }

    /// The Gauss-Newton step solves `(J^T J + lambda diag(J^T J)) d = -J^T r` in the free
    /// parameters, a held one's step 0 (the normal equations without its row and column), and
    /// predicts the fall of the sum of squares `|r|^2 - |r + J d|^2`.
    #[test]
    fn the_gauss_newton_step_solves_the_normal_equations_of_the_free_parameters() {
        let (jac, r) = small_problem();
        let (rmat, qtr) = qr_of_jr(Par::Seq, &jac, &r);
        let g: Vec<f64> = (0..3)
            .map(|j| (0..40).map(|i| jac[(i, j)] * r[i]).sum())
            .collect();
        let lambda = 1e-3;
        let (d, pred) = gauss_newton_step(&rmat, &g, lambda, &[false; 3]).unwrap();
        let gram = jac.transpose() * &jac;
        let extra: Vec<f64> = (0..3).map(|j| lambda * gram[(j, j)]).collect();
        let want = normal_equations(&jac, &r, &extra);
        for j in 0..3 {
            assert!((d[j] - want[j]).abs() < 1e-12 * (1.0 + want[j].abs()));
        }
        let rd: Vec<f64> = (0..40)
            .map(|i| r[i] + (0..3).map(|j| jac[(i, j)] * d[j]).sum::<f64>())
            .collect();
        assert!((pred - (sumsq(&r) - sumsq(&rd))).abs() < 1e-12 * sumsq(&r));
        let _ = qtr;
        // Parameter 1 held: the system of columns 0 and 2.
        let (d, _) = gauss_newton_step(&rmat, &g, lambda, &[false, true, false]).unwrap();
        assert_eq!(d[1], 0.0);
        let sub = Mat::<f64>::from_fn(40, 2, |i, j| jac[(i, [0, 2][j])]);
        let want = normal_equations(&sub, &r, &[extra[0], extra[2]]);
        assert!((d[0] - want[0]).abs() < 1e-12 && (d[2] - want[1]).abs() < 1e-12);
    }

    /// Nielsen's factor: 1/3 for a perfect model (`rho = 1`), 1 at `rho = 1/2`, 2 at `rho = 0`.
    #[test]
    fn nielsens_factor_at_its_landmarks() {
        assert_eq!(marquardt_factor(1.0), 1.0 / 3.0);
        assert_eq!(marquardt_factor(0.5), 1.0);
        assert_eq!(marquardt_factor(0.0), 2.0);
    }
}
