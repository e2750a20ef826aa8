//! Passes over a tall Jacobian by halves of its rows ([`crate::par::on_row_halves`]): `J^T r`,
//! the Gram matrix `J^T J`, the finiteness check of `[J r]`.

use super::problem::{ColSlices, Mat};
use crate::numeric::{all_finite, dot};
use crate::par::on_row_halves;
use crate::{Error, Result};
use std::ops::Range;

/// Rows of `J` taken at a time by [`jt_r_rows`]: their part of `r` (32 KiB) stays in the L1
/// cache while every column reads it.
pub(super) const JT_R_BLOCK: usize = 4096;

/// `J^T r` over the rows `rows` only, a block of rows at a time (one pass over `J`; `r` is read
/// from memory once, not once per column).
pub(super) fn jt_r_rows(jac: &Mat<f64>, r: &[f64], rows: Range<usize>) -> Vec<f64> {
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
pub(super) fn gram_add(gram: &mut Mat<f64>, jac: &Mat<f64>, rows: Range<usize>) {
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

/// `J^T r`, in two halves of the rows on two threads for a large `J`.
pub(super) fn jt_r(jac: &Mat<f64>, r: &[f64]) -> Vec<f64> {
    let parts = on_row_halves(jac.nrows(), jac.ncols(), |rows| jt_r_rows(jac, r, rows));
    (0..jac.ncols())
        .map(|j| parts.iter().map(|g| g[j]).sum())
        .collect()
}

pub(super) fn check_finite(r: &[f64], jac: &Mat<f64>, when: &str) -> Result<()> {
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

#[cfg(test)]
mod tests {
    use super::super::testproblems::uniform;
    use super::*;
    use crate::numeric::sumsq;
    use crate::par::PARALLEL_ENTRIES;

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
}
