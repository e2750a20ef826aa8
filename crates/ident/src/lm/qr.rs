//! The QR of `[J r]` once per iteration ([`qr_of_jr`]: Cholesky QR for a well-conditioned `J`,
//! else a blocked Householder QR, both by faer through [`crate::linalg`]), and what `R` and
//! `Q^T r` give without another pass over `J`.

use super::passes::JT_R_BLOCK;
use super::problem::{ColSlices, Mat};
use crate::linalg::{self, Again, LstsqWork};
use crate::par::{on_row_halves, Par};

/// Rows of `[J r]` factored at a time by [`qr_of_jr`].
const QR_BLOCK: usize = 8192;

/// QR of `[J r]`: returns the `k x n` upper-trapezoidal `R` (k = min(m, n)) and `Q^T r` (length k).
///
/// A well-conditioned `J` is factored through its Gram matrix ([`cholesky_qr_of_jr`]: one pass
/// over the data, a matrix product instead of `n` reflections); any other by Householder
/// reflections ([`householder_qr_of_jr`]). `R` is unique up to the signs of its rows, which
/// `Q^T r` shares, so every use below (the damped steps, the covariance, `J^T r = R^T Q^T r`) is
/// the same.
pub(super) fn qr_of_jr(par: Par, jac: &Mat<f64>, r: &[f64]) -> (Mat<f64>, Vec<f64>) {
    cholesky_qr_of_jr(par, jac, r).unwrap_or_else(|| householder_qr_of_jr(par, jac, r))
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
pub(super) fn cholesky_qr_of_jr(
    par: Par,
    jac: &Mat<f64>,
    r: &[f64],
) -> Option<(Mat<f64>, Vec<f64>)> {
    let (m, n) = (jac.nrows(), jac.ncols());
    if m < n || n == 0 {
        return None;
    }
    // The Gram matrix and J^T r of each block of rows together: the block is read from memory
    // once, and from the cache by the second.
    let parts = on_row_halves(par, m, n, |rows| {
        let mut gram = Mat::<f64>::zeros(n, n);
        let mut g = vec![0.0; n];
        let mut a = rows.start;
        while a < rows.end {
            let b = (a + JT_R_BLOCK).min(rows.end);
            linalg::gram_add(&mut gram, &mut g, jac, r, a..b);
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
    let scaled = Mat::<f64>::from_fn(n, n, |i, j| gram[(i, j)] / (d[i] * d[j]));
    let l = linalg::cholesky_lower(&scaled)?;
    if (0..n).any(|j| !(l[j * n + j] > MIN_PIVOT)) {
        return None;
    }
    // R = L^T D.
    let rmat = Mat::<f64>::from_fn(n, n, |i, j| if j >= i { l[j * n + i] * d[j] } else { 0.0 });
    // R^T q = g.
    let q = linalg::solve_upper_transposed(&rmat, &g);
    q.iter().all(|v| v.is_finite()).then_some((rmat, q))
}

/// Householder QR of `[J r]`, as [`qr_of_jr`] returns it.
///
/// Factored by blocks of rows (the tall-skinny QR): the `R` of the rows so far stacked on the
/// next [`QR_BLOCK`] rows is factored again, so memory stays one block whatever the record's
/// length and `[J r]` is never copied whole.
pub(super) fn householder_qr_of_jr(par: Par, jac: &Mat<f64>, r: &[f64]) -> (Mat<f64>, Vec<f64>) {
    let (m, n) = (jac.nrows(), jac.ncols());
    let w = n + 1;
    let col = |j: usize| if j < n { jac.col_as_slice(j) } else { r };
    // Each half of the rows (on two threads for a large J) to its R, then the two stacked.
    let tops = on_row_halves(par, m, w, |rows| {
        tsqr(|j| &col(j)[rows.clone()], rows.len(), w)
    });
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
/// (faer's Householder QR, [`linalg::qr_r_in_place`]). With `m = 0`, the `R` of two stacked `R`s: column `j` of the upper one is
/// `col(j)`, of the lower one `col(w + j)` (each as long as the `R` has rows).
fn tsqr<'a>(col: impl Fn(usize) -> &'a [f64], m: usize, w: usize) -> Mat<f64> {
    if m == 0 {
        let (ha, hb) = (col(0).len(), col(w).len());
        let mut a = Vec::with_capacity((ha + hb) * w);
        for j in 0..w {
            a.extend_from_slice(col(j));
            a.extend_from_slice(col(w + j));
        }
        return linalg::qr_r_in_place(&mut a, ha + hb, w, &mut LstsqWork::new(), Again::Copy);
    }
    let mut top = Mat::<f64>::zeros(0, w);
    let mut a = Vec::with_capacity((QR_BLOCK + w) * w);
    let mut work = LstsqWork::new();
    let mut start = 0;
    while start < m {
        let end = (start + QR_BLOCK).min(m);
        let rows = top.nrows() + end - start;
        // `R` so far stacked on the block, column by column: built here, and again by the
        // factorisation only in the rare case it needs `A` back (no copy of every block)
        let mut fill = |dst: &mut [f64]| {
            for (j, out) in dst.chunks_exact_mut(rows).enumerate() {
                let (upper, lower) = out.split_at_mut(top.nrows());
                upper.copy_from_slice(top.col_as_slice(j));
                lower.copy_from_slice(&col(j)[start..end]);
            }
        };
        a.resize(rows * w, 0.0);
        fill(&mut a);
        top = linalg::qr_r_in_place(&mut a, rows, w, &mut work, Again::Refill(&mut fill));
        start = end;
    }
    top
}

/// `J^T r = R^T (Q^T r)` from the QR of `[J r]` ([`qr_of_jr`]), without a pass over `J`.
pub(super) fn jt_r_of(rmat: &Mat<f64>, qtr: &[f64]) -> Vec<f64> {
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
pub(super) fn col_norms_of(rmat: &Mat<f64>) -> Vec<f64> {
    (0..rmat.ncols())
        .map(|j| {
            (0..rmat.nrows().min(j + 1))
                .map(|i| rmat[(i, j)] * rmat[(i, j)])
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::passes::jt_r;
    use super::super::testproblems::uniform;
    use super::*;
    use crate::numeric::sumsq;
    use crate::par::PARALLEL_ENTRIES;

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
        assert_same_r(
            &whole,
            householder_qr_of_jr(Par::threads(2), &jac, &r),
            1e-11,
        );
        // Well-conditioned: the Gram matrix path serves, to 1e-11 too (its error is machine
        // epsilon times the square of a small condition number).
        let chol = cholesky_qr_of_jr(Par::threads(2), &jac, &r).expect("a well-conditioned J");
        assert_same_r(&whole, chol.clone(), 1e-11);
        assert_eq!(qr_of_jr(Par::threads(2), &jac, &r), chol);
        // J^T r by halves of the rows, and from R and Q^T r, against the plain sums.
        let want: Vec<f64> = (0..n)
            .map(|j| (0..m).map(|i| jac[(i, j)] * r[i]).sum())
            .collect();
        let norms: Vec<f64> = (0..n)
            .map(|j| (0..m).map(|i| jac[(i, j)].powi(2)).sum::<f64>().sqrt())
            .collect();
        for (j, w) in want.iter().enumerate() {
            let tol = 1e-12 * norms[j] * sumsq(&r).sqrt();
            assert!(
                (jt_r(Par::threads(2), &jac, &r)[j] - w).abs() < tol,
                "J^T r [{j}]"
            );
            assert!(
                (jt_r_of(&chol.0, &chol.1)[j] - w).abs() < 1e3 * tol,
                "R^T Q^T r [{j}]"
            );
            assert!((col_norms_of(&chol.0)[j] - norms[j]).abs() < 1e-12 * norms[j]);
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
        assert!(cholesky_qr_of_jr(Par::threads(2), &jac, &r).is_none());
        let whole = Mat::<f64>::from_fn(m, 4, |i, j| if j < 3 { jac[(i, j)] } else { r[i] });
        assert_same_r(&whole, qr_of_jr(Par::threads(2), &jac, &r), 1e-9);
        // A zero column (a parameter without influence) also goes to Householder.
        let jz = Mat::<f64>::from_fn(m, 2, |i, j| if j == 0 { base[i][0] } else { 0.0 });
        assert!(cholesky_qr_of_jr(Par::threads(2), &jz, &r).is_none());
    }
}
