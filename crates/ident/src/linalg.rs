//! ident's dense linear algebra, on faer: the Householder QR of a column-major block
//! ([`qr_r_in_place`]), least squares in reused memory ([`LstsqWork`]) or at once ([`lstsq`]),
//! Cholesky solves ([`cholesky_solve`]), Gram products ([`gram_add`]) and the inverse of a
//! triangular factor ([`upper_inverse`]).
//!
//! Every call here is sequential (`Par::Seq`): the matrices are a few columns wide, and the
//! parallelism over a tall matrix's rows is the caller's ([`crate::par`]). Matrices cross the
//! boundary as nalgebra's column-major `DMatrix` (the [`crate::lm::Problem`] Jacobian's type) or
//! as column-major slices, viewed by faer without a copy.

use crate::lm::Mat;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::qr::no_pivoting::{factor, solve};
use faer::{Accum, MatMut, MatRef, Par};

/// faer's view of a column-major `rows x cols` slice.
fn view(a: &[f64], rows: usize, cols: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(a, rows, cols)
}

/// faer's view of nalgebra's column-major matrix.
pub(crate) fn as_faer(a: &Mat<f64>) -> MatRef<'_, f64> {
    view(a.as_slice(), a.nrows(), a.ncols())
}

/// The memory of faer's Householder QR of a `rows x cols` matrix and its least-squares solve
/// with one right-hand side: the block reflectors' factors and the scratch, kept across solves
/// of one size (a Levy search solves thousands of systems of one size, where allocating them
/// each time costs as much as the solve).
pub(crate) struct LstsqWork {
    rows: usize,
    cols: usize,
    q_coeff: faer::Mat<f64>,
    mem: MemBuffer,
}

impl LstsqWork {
    /// Memory for `rows x cols` systems.
    pub(crate) fn new(rows: usize, cols: usize) -> Self {
        let size = rows.min(cols).max(1);
        let block = factor::recommended_block_size::<f64>(rows, cols).clamp(1, size);
        let req = StackReq::any_of(&[
            factor::qr_in_place_scratch::<f64>(rows, cols, block, Par::Seq, Default::default()),
            solve::solve_lstsq_in_place_scratch::<f64>(rows, cols, block, 1, Par::Seq),
        ]);
        Self {
            rows,
            cols,
            q_coeff: faer::Mat::zeros(block, size),
            mem: MemBuffer::new(req),
        }
    }

    /// Factor the column-major `rows x cols` matrix `a` in place (`R` in its upper triangle, the
    /// reflectors below), memory made again if the size is not this one's.
    fn factor(&mut self, a: &mut [f64], rows: usize, cols: usize) {
        // The memory of a taller system of as many columns serves (the reflectors' block size
        // and the scratch depend on the columns; `q_coeff` has `cols` columns then).
        let fits = (rows, cols) == (self.rows, self.cols)
            || (cols == self.cols && rows >= cols && rows <= self.rows);
        if !fits {
            *self = Self::new(rows, cols);
        }
        let a = MatMut::from_column_major_slice_mut(a, rows, cols);
        factor::qr_in_place(
            a,
            self.q_coeff.as_mut(),
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
    }

    /// The least-squares solution of `min |A x - b|` into `b[..cols]` (`A` column-major
    /// `b.len() x cols`, `A` and `b` overwritten), and the diagonal of `R` (of either sign)
    /// into `diag` (length `cols`), by which the caller judges the rank. `rows >= cols`.
    pub(crate) fn solve(&mut self, a: &mut [f64], b: &mut [f64], diag: &mut [f64]) {
        let (rows, cols) = (b.len(), diag.len());
        debug_assert!(rows >= cols && a.len() == rows * cols);
        self.factor(a, rows, cols);
        let qr = view(a, rows, cols);
        for (j, d) in diag.iter_mut().enumerate() {
            *d = qr[(j, j)];
        }
        solve::solve_lstsq_in_place(
            qr,
            self.q_coeff.as_ref(),
            qr,
            MatMut::from_column_major_slice_mut(b, rows, 1),
            Par::Seq,
            MemStack::new(&mut self.mem),
        );
    }
}

/// The `R` (`min(rows, w) x w`, upper trapezoidal) of the column-major `rows x w` matrix `a`
/// (overwritten) by faer's Householder QR. `R` is unique up to the signs of its rows.
pub(crate) fn qr_r_in_place(
    a: &mut [f64],
    rows: usize,
    w: usize,
    work: &mut LstsqWork,
) -> Mat<f64> {
    debug_assert_eq!(a.len(), rows * w);
    let k = rows.min(w);
    if k == 0 {
        return Mat::zeros(0, w);
    }
    work.factor(a, rows, w);
    Mat::<f64>::from_fn(k, w, |i, j| if j >= i { a[j * rows + i] } else { 0.0 })
}

/// The least-squares solution `X` of `min ||A X - B||` (`A` is `m x n`, `m >= n`) by faer's
/// Householder QR. A zero pivot (dependent columns) gives infinite or NaN entries, not an
/// error: callers check them.
pub(crate) fn lstsq(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut x = Mat::<f64>::zeros(n, b.ncols());
    if n == 0 {
        return x;
    }
    let mut qr = a.as_slice().to_vec();
    let mut work = LstsqWork::new(m, n);
    work.factor(&mut qr, m, n);
    let qr = view(&qr, m, n);
    let mut rhs = b.as_slice().to_vec();
    let mut stack_mem = MemBuffer::new(solve::solve_lstsq_in_place_scratch::<f64>(
        m,
        n,
        work.q_coeff.nrows(),
        b.ncols(),
        Par::Seq,
    ));
    solve::solve_lstsq_in_place(
        qr,
        work.q_coeff.as_ref(),
        qr,
        MatMut::from_column_major_slice_mut(&mut rhs, m, b.ncols()),
        Par::Seq,
        MemStack::new(&mut stack_mem),
    );
    for c in 0..b.ncols() {
        for i in 0..n {
            x[(i, c)] = rhs[c * m + i];
        }
    }
    x
}

/// The solution of `A x = b` for a symmetric positive definite `A` (`n x n`, its lower
/// triangle read) by faer's Cholesky factorisation; `None` when `A` is not positive definite.
pub(crate) fn cholesky_solve(a: &Mat<f64>, b: &[f64]) -> Option<Vec<f64>> {
    let llt = as_faer(a).llt(faer::Side::Lower).ok()?;
    let mut x = faer::Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]);
    faer::linalg::solvers::SolveCore::solve_in_place_with_conj(&llt, faer::Conj::No, x.as_mut());
    Some((0..b.len()).map(|i| x[(i, 0)]).collect())
}

/// The lower Cholesky factor `L` (`L L^T = A`) of the symmetric `A` (`n x n`, its lower
/// triangle read), row-major; `None` when `A` is not positive definite.
pub(crate) fn cholesky_lower(a: &Mat<f64>) -> Option<Vec<f64>> {
    let n = a.nrows();
    let llt = as_faer(a).llt(faer::Side::Lower).ok()?;
    let l = llt.L();
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            out[i * n + j] = l[(i, j)];
        }
    }
    Some(out)
}

/// `G += A^T A` and `g += A^T b` for the rows `rows` of the column-major `m x n` matrix `a`
/// and of `b` (one block: the second product reads it from the cache).
pub(crate) fn gram_add(
    gram: &mut Mat<f64>,
    g: &mut [f64],
    a: &Mat<f64>,
    b: &[f64],
    rows: std::ops::Range<usize>,
) {
    let n = a.ncols();
    let block = as_faer(a).subrows(rows.start, rows.len());
    let gram_mut = MatMut::from_column_major_slice_mut(gram.as_mut_slice(), n, n);
    faer::linalg::matmul::matmul(
        gram_mut,
        Accum::Add,
        block.transpose(),
        block,
        1.0,
        Par::Seq,
    );
    jt_b_add(g, a, b, rows);
}

/// `g += A^T b` for the rows `rows` of the column-major `m x n` matrix `a` and of `b`.
pub(crate) fn jt_b_add(g: &mut [f64], a: &Mat<f64>, b: &[f64], rows: std::ops::Range<usize>) {
    let n = a.ncols();
    let block = as_faer(a).subrows(rows.start, rows.len());
    let rb = view(&b[rows.clone()], rows.len(), 1);
    let g_mut = MatMut::from_column_major_slice_mut(g, n, 1);
    faer::linalg::matmul::matmul(g_mut, Accum::Add, block.transpose(), rb, 1.0, Par::Seq);
}

/// `R^-1` (`n x n`, upper triangular, row-major) of the upper triangular `n x n` leading block of
/// `r`, by faer.
pub(crate) fn upper_inverse(r: &Mat<f64>) -> Vec<f64> {
    let n = r.ncols();
    let src = as_faer(r).subrows(0, n);
    let mut inv = faer::Mat::<f64>::zeros(n, n);
    faer::linalg::triangular_inverse::invert_upper_triangular(inv.as_mut(), src, Par::Seq);
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in i..n {
            out[i * n + j] = inv[(i, j)];
        }
    }
    out
}

/// The solution `q` of `R^T q = g` for the upper triangular `n x n` leading block of `r`, by
/// faer's triangular solve.
pub(crate) fn solve_upper_transposed(r: &Mat<f64>, g: &[f64]) -> Vec<f64> {
    let n = g.len();
    let mut q = g.to_vec();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(
        as_faer(r).subrows(0, n).transpose(),
        MatMut::from_column_major_slice_mut(&mut q, n, 1),
        Par::Seq,
    );
    q
}

/// `A^T A` (`n x n`) of the column-major `m x n` matrix `a`, by faer's product.
pub(crate) fn gram(a: &Mat<f64>) -> Mat<f64> {
    let n = a.ncols();
    let mut out = Mat::<f64>::zeros(n, n);
    let dst = MatMut::from_column_major_slice_mut(out.as_mut_slice(), n, n);
    let a = as_faer(a);
    faer::linalg::matmul::matmul(dst, Accum::Replace, a.transpose(), a, 1.0, Par::Seq);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lm::ColSlices;

    /// A seeded generator of uniform numbers in [-0.5, 0.5) (a 64-bit LCG).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// faer's Householder `R` ([`qr_r_in_place`]) against nalgebra's QR, up to the signs of its rows: a tall
    /// random matrix, a wide one (fewer rows than columns), one with columns of `1e200` and
    /// `1e-200` (whose squares over- and underflow: `R(A D) = R(A) D` for a positive diagonal
    /// `D`, nalgebra's `R` of `A` times `D` is the reference). Then a rank-deficient one (a column
    /// already zero below the diagonal, a zero column), whose `R` is not unique: `R^T R = A^T A`.
    #[test]
    fn qr_r_equals_nalgebras_qr() {
        let mut rnd = uniform(5);
        let cases: Vec<(Mat<f64>, Vec<f64>)> = vec![
            (Mat::from_fn(300, 7, |_, _| rnd()), vec![1.0; 7]),
            (Mat::from_fn(5, 9, |_, _| rnd()), vec![1.0; 9]),
            (
                Mat::from_fn(60, 4, |_, _| rnd()),
                vec![1.0, 1e200, 1e-200, 1.0],
            ),
        ];
        let r_of = |a: &Mat<f64>| {
            let (rows, w) = (a.nrows(), a.ncols());
            let mut buf: Vec<f64> = (0..w).flat_map(|j| a.col_as_slice(j).to_vec()).collect();
            let r = qr_r_in_place(&mut buf, rows, w, &mut LstsqWork::new(rows, w));
            assert_eq!((r.nrows(), r.ncols()), (rows.min(w), w));
            for i in 0..r.nrows() {
                assert!((0..i).all(|j| r[(i, j)] == 0.0));
            }
            r
        };
        for (case, (b, d)) in cases.iter().enumerate() {
            let a = Mat::<f64>::from_fn(b.nrows(), b.ncols(), |i, j| b[(i, j)] * d[j]);
            let got = r_of(&a);
            let want = b.clone().qr().r();
            for i in 0..got.nrows() {
                let sign = if want[(i, i)] * got[(i, i)] < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for j in i..b.ncols() {
                    let err = (sign * got[(i, j)] / d[j] - want[(i, j)]).abs();
                    assert!(err <= 1e-13 * b.column(j).norm(), "case {case}: R[{i},{j}]");
                }
            }
        }
        let a = Mat::<f64>::from_fn(40, 4, |i, j| match j {
            0 => f64::from(u8::from(i == 0)) * 3.0,
            2 => 0.0,
            _ => (i * j) as f64 % 7.0 - 3.0,
        });
        let got = r_of(&a);
        for i in 0..4 {
            for j in 0..4 {
                let rtr: f64 = (0..=i.min(j)).map(|k| got[(k, i)] * got[(k, j)]).sum();
                let ata: f64 = (0..40).map(|k| a[(k, i)] * a[(k, j)]).sum();
                assert!((rtr - ata).abs() <= 1e-12 * (1.0 + ata.abs()), "G[{i},{j}]");
            }
        }
    }
}
