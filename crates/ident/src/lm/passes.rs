//! Passes over a tall Jacobian by halves of its rows ([`crate::par::on_row_halves`]): `J^T r`
//! and the finiteness check of `[J r]`.

use super::problem::{ColSlices, Mat};
use crate::linalg;
use crate::numeric::all_finite;
use crate::par::{on_row_halves, Par};
use crate::{Error, Result};
use std::ops::Range;

/// Rows of `J` taken at a time by the Gram products ([`super::qr`]): the block stays in the
/// cache from the product `J^T J` to `J^T r`.
pub(super) const JT_R_BLOCK: usize = 4096;

/// `J^T r` over the rows `rows` only (faer's product, [`linalg::jt_b_add`]).
fn jt_r_rows(jac: &Mat<f64>, r: &[f64], rows: Range<usize>) -> Vec<f64> {
    let mut g = vec![0.0; jac.ncols()];
    linalg::jt_b_add(&mut g, jac, r, rows);
    g
}

/// `J^T r`, in two halves of the rows on two threads for a large `J`.
pub(super) fn jt_r(par: Par, jac: &Mat<f64>, r: &[f64]) -> Vec<f64> {
    let parts = on_row_halves(par, jac.nrows(), jac.ncols(), |rows| {
        jt_r_rows(jac, r, rows)
    });
    (0..jac.ncols())
        .map(|j| parts.iter().map(|g| g[j]).sum())
        .collect()
}

pub(super) fn check_finite(par: Par, r: &[f64], jac: &Mat<f64>, when: &str) -> Result<()> {
    let n = jac.ncols();
    let halves = on_row_halves(par, jac.nrows(), n, |rows| {
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
    use crate::par::{Par, PARALLEL_ENTRIES};

    /// A NaN or an infinity anywhere in `[J r]` (either half of the rows) is found and located.
    #[test]
    fn non_finite_entries_are_found_in_either_half() {
        let (m, n) = (2 * PARALLEL_ENTRIES / 3, 3);
        let mut rnd = uniform(3);
        let mut jac = Mat::<f64>::from_fn(m, n, |_, _| rnd());
        let mut r: Vec<f64> = (0..m).map(|_| rnd()).collect();
        assert!(check_finite(Par::threads(2), &r, &jac, "").is_ok());
        jac[(m - 3, 2)] = f64::INFINITY;
        let e = check_finite(Par::threads(2), &r, &jac, "")
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("({}, 2)", m - 3)), "{e}");
        jac[(m - 3, 2)] = 0.5;
        r[7] = f64::NAN;
        let e = check_finite(Par::threads(2), &r, &jac, "")
            .unwrap_err()
            .to_string();
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
