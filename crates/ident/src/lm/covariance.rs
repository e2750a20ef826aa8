//! The parameters' covariance and standard errors from the `R` of the Jacobian.

use super::problem::Mat;
#[allow(unused_imports)] // (doc links)
use super::Problem;
use crate::linalg::{self, Again, LstsqWork};

/// The covariance and standard errors from the `R` of `J`, with the parameters `held` at a
/// bound ([`Problem::at_bound`]) fixed there: the covariance of the others is that of the
/// columns of `J` without theirs (the `R` of `R[:, kept]`, which is `Q^T J[:, kept]`), and a
/// held parameter's rows and columns and standard error are NaN (it has no spread: it sits on
/// its bound). A held parameter's column is about zero (the bound's map is flat there), which
/// would otherwise make the whole covariance singular.
pub(super) fn covariance_and_errors(
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
        let r_sub = if sub.nrows() >= nk {
            let (rows, mut a) = (sub.nrows(), sub.as_slice().to_vec());
            linalg::qr_r_in_place(&mut a, rows, nk, &mut LstsqWork::new(), Again::Copy)
        } else {
            sub
        };
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
    // Rinv, upper triangular, row-major.
    let rinv = linalg::upper_inverse(r);
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
    use super::super::qr::qr_of_jr;
    use super::super::testproblems::uniform;
    use super::*;
    use crate::par::Par;

    /// `sigma2 (J^T J)^-1` by nalgebra's QR of `J` (another library's factorisation): the truth.
    fn reference(jac: &Mat<f64>, sigma2: f64) -> Mat<f64> {
        let r = jac.clone().qr().r();
        let rinv = r.try_inverse().expect("a regular R");
        &rinv * rinv.transpose() * sigma2
    }

    /// A tall `J` (three blocks of the blocked QR, where faer's plain QR would take a part under
    /// `16 m eps = 3e-11` of a column's norm for dependent and shift the columns after it up a
    /// row) whose column 1 is column 0 plus `1e-12` of another: its pivot stays `1e-12` of its
    /// norm and column 2 keeps its own, so the covariance is there and
    /// its standard errors are huge (`~1e12` times the others': "not determined"), as nalgebra's
    /// QR gives them (to `1e-3` of `sqrt(C_ii C_jj)`: rounding sets the remainder's direction to
    /// about `eps / 1e-12`). Column 1 exactly twice column 0: the covariance is singular (`None`).
    #[test]
    fn nearly_dependent_columns_are_not_determined_and_dependent_ones_singular() {
        let m = 3 * 8192 + 101;
        let mut rnd = uniform(29);
        let base: Vec<[f64; 3]> = (0..m).map(|_| [rnd(), rnd(), rnd()]).collect();
        let r: Vec<f64> = (0..m).map(|_| rnd()).collect();
        let sigma2 = 0.25;
        let near = Mat::<f64>::from_fn(m, 3, |i, j| match j {
            1 => base[i][0] + 1e-12 * base[i][1],
            _ => base[i][j],
        });
        let (rmat, _) = qr_of_jr(Par::Seq, &near, &r);
        let norm1 = near.column(1).norm();
        assert!(rmat[(1, 1)].abs() > 1e-13 * norm1 && rmat[(1, 1)].abs() < 1e-11 * norm1);
        let norm2 = near.column(2).norm();
        assert!(
            rmat[(2, 2)].abs() > 0.5 * norm2,
            "column 2's pivot {:e}",
            rmat[(2, 2)]
        );
        let (cov, se) = covariance_and_errors(&rmat, sigma2, &[false; 3]);
        let (cov, se) = (cov.expect("not singular"), se.unwrap());
        let want = reference(&near, sigma2);
        for i in 0..3 {
            for j in 0..3 {
                let (w, scale) = (want[(i, j)], (want[(i, i)] * want[(j, j)]).sqrt());
                let got = cov[i * 3 + j];
                assert!(
                    (got - w).abs() <= 1e-3 * scale,
                    "cov[{i},{j}] {got:e} vs {w:e}"
                );
            }
        }
        assert!(se[0] > 1e9 * se[2] && se[1] > 1e9 * se[2], "{se:?}");

        let exact = Mat::<f64>::from_fn(m, 3, |i, j| match j {
            1 => 2.0 * base[i][0],
            _ => base[i][j],
        });
        let (rmat, _) = qr_of_jr(Par::Seq, &exact, &r);
        assert_eq!(
            covariance_and_errors(&rmat, sigma2, &[false; 3]),
            (None, None)
        );
    }
}
