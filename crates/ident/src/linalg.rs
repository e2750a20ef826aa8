//! ident's dense linear algebra, on faer: the Householder QR of a column-major block
//! ([`qr_r_in_place`]), least squares in reused memory ([`LstsqWork`]) or at once ([`lstsq`]),
//! the thin QR ([`thin_qr`]), the projection out of a span ([`Span`]), Cholesky solves
//! ([`cholesky_solve`]), minimum-norm least squares by the SVD ([`svd_solve`]), Gram products
//! ([`gram_add`]) and the inverse of a triangular factor ([`upper_inverse`]). Every
//! factorisation is faer's: its SVD, its plain QR (of the columns it keeps and of the rest's
//! remainders where its rank estimate is short, [`factor`]), and its column-pivoted QR where
//! those cannot be told apart or a rank is wanted ([`Span`]).
//!
//! Every call here is sequential (`Par::Seq`): the matrices are a few columns wide, and the
//! parallelism over a tall matrix's rows is the caller's ([`crate::par`]). Matrices cross the
//! boundary as nalgebra's column-major `DMatrix` (the [`crate::lm::Problem`] Jacobian's type) or
//! as column-major slices, viewed by faer without a copy.

use std::mem::MaybeUninit;

use faer::dyn_stack::{MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::matmul::matmul;
use faer::linalg::qr::{col_pivoting, no_pivoting};
use faer::linalg::triangular_solve::solve_upper_triangular_in_place;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Conj, MatMut, MatRef, Par};
use nalgebra::DMatrix as Mat; // the LM Jacobian's matrix (`lm::Mat` is this type)

/// faer's view of a column-major `rows x cols` slice.
fn view(a: &[f64], rows: usize, cols: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(a, rows, cols)
}

/// faer's view of nalgebra's column-major matrix.
pub(crate) fn as_faer(a: &Mat<f64>) -> MatRef<'_, f64> {
    view(a.as_slice(), a.nrows(), a.ncols())
}

/// The memory of faer's QR ([`factor`]), kept across the many small solves of one search (a
/// Levy search solves thousands of systems of one size): the matrix as given, the Householder
/// coefficients, the column permutation, the small matrix `S`, the column scales and faer's
/// scratch. It grows to the largest system it is given.
#[derive(Debug, Default)]
pub(crate) struct LstsqWork {
    /// `A` as given, for the pivoted factorisation when the plain one took a column for dependent.
    orig: Vec<f64>,
    /// The Householder coefficients of the plain or the pivoted QR of `A` (`1 x k`).
    tau: Vec<f64>,
    /// Those of the QR of `S` (`1 x k`).
    tau_s: Vec<f64>,
    /// `perm[p]` is the column of `A` at position `p` of the pivoted QR; `perm_inv` its inverse.
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    /// `S = R_p P^T D` (`k x w`, column-major), then its QR.
    s: Vec<f64>,
    /// The power of two `D_j` each column was multiplied by ([`scale_up`], the plain QR) or
    /// divided by ([`factor_pivoted`]).
    scale: Vec<f64>,
    /// faer's scratch.
    mem: Vec<MaybeUninit<u8>>,
}

/// How [`factor`] factored `A` (where `Q` is).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Factored {
    /// faer's plain QR: `Q`'s reflectors below `A`'s diagonal, their coefficients in `tau`.
    Plain,
    /// The pivoted QR and the QR of `S`: `Q = Q_p Q_s`, `Q_p`'s reflectors below `A`'s diagonal
    /// (coefficients in `tau`), `Q_s`'s below `S`'s (in `tau_s`).
    Pivoted,
    /// The QR of the columns faer's plain QR kept (`r` of them, first) with the rest after
    /// them, then the QR of `S` ([`factor_split`]): `Q = Q_1 diag(I_r, Q_2) Q_s`, `Q_1`'s
    /// reflectors below the diagonal of `A`'s first `r` columns (coefficients `tau[..r]`),
    /// `Q_2`'s `r2` below that of the block from row and column `r` (`tau[r..r + r2]`), `Q_s`'s
    /// below `S`'s.
    Split { r: usize, r2: usize },
    /// Every column zero: `R = 0`, `Q = I`.
    Zero,
    /// An entry not finite: `A` and `extra` set to NaN.
    NotFinite,
}

/// How [`factor`] gets `A` back when faer's plain QR took a column for dependent (it has
/// overwritten `A` by then).
pub(crate) enum Again<'f> {
    /// From a copy taken before (a pass over `A` each time).
    Copy,
    /// Written again by the caller into the column-major slice it is given: for many small
    /// solves whose `A` costs less to build again in the rare case than to copy every time.
    Refill(&'f mut dyn FnMut(&mut [f64])),
}

/// The power of two nearest above `norm` (`norm > 0`, finite), within `2^-1020..2^1020` (its
/// reciprocal finite and normal): dividing by it is exact.
fn power_of_two(norm: f64) -> f64 {
    2f64.powi((norm.log2().ceil() as i32).clamp(-1020, 1020))
}

/// The largest entry of a column that [`scale_up`] brings it to: `2^480`, so that the squares of
/// a column of up to `2^60` rows stay finite.
const SCALED_MAX: i32 = 480;

/// `A`'s columns multiplied by powers of two `D_j` (exact), each to its largest entry near
/// `2^`[`SCALED_MAX`], `D` into `scale` (1 for a zero or not finite column).
///
/// faer 0.24's Euclidean norm (the Householder reflector's) keeps a third sum of squares of
/// the entries times `2^-511` against overflow; for entries between about `1e-8` and `1` those
/// squares are subnormal numbers, which the CPU computes some 40 times slower than normal ones
/// (measured: 23.5 us for 3500 entries of order 1, 0.62 us for the same entries times
/// `1e100`). The QR of the scaled matrix is the same factorisation (its reflectors are `A`'s,
/// `R` is `R D`), its norms fast.
fn scale_up(scale: &mut Vec<f64>, mut a: MatMut<'_, f64>) {
    scale.clear();
    for j in 0..a.ncols() {
        let mut col = a.rb_mut().col_mut(j);
        // The largest |entry| by its bits (ordered as the values for non-negative numbers):
        // an integer maximum, which vectorises.
        let bits = match col.rb().try_as_col_major() {
            Some(c) => c.as_slice().iter().map(|v| v.abs().to_bits()).max(),
            None => col.rb().iter().map(|v| v.abs().to_bits()).max(),
        };
        let largest = f64::from_bits(bits.unwrap_or(0));
        let d = if largest > 0.0 && largest.is_finite() {
            let e = largest.log2().floor() as i32;
            2f64.powi((SCALED_MAX - e).clamp(-1000, 1000))
        } else {
            1.0
        };
        scale.push(d);
        if d != 1.0 {
            match col.rb_mut().try_as_col_major_mut() {
                Some(c) => c.as_slice_mut().iter_mut().for_each(|v| *v *= d),
                None => col.iter_mut().for_each(|v| *v *= d),
            }
        }
    }
}

/// The plain Householder QR `A = Q R` of the column-major `m x w` matrix `a` by faer, `R` into
/// `a`'s upper triangle (`k = min(m, w)` rows; unique up to the signs of its rows where `A` has
/// full rank) and `Q^T` applied to `extra` (`m` rows).
///
/// faer's plain QR ([`no_pivoting`]) first (`A` kept or got back as `again` says). It takes a column whose part outside the span of the
/// ones before it is under `16 (m - k) eps` of its norm (`3e-11` for a block of 8192 rows) for
/// dependent and leaves a staircase `R` with zeros on its diagonal from there on (its rank
/// estimate). A fit needs the plain `R` of its `J`: two nearly dependent columns have a pivot of
/// `1e-11` to `1e-13` of their norm, and their huge standard errors say "not determined" (the
/// fit refused), where a zero pivot would say "singular covariance" (a warning only). So when
/// faer's rank is short, `A` is factored again: the columns it kept first, the others'
/// remainders after them ([`factor_split`]), or, when the kept ones cannot be read back, faer's
/// column-pivoted QR, which takes no column for dependent ([`factor_pivoted`]); then the plain
/// QR of the small `R_P P^T`. The columns are scaled first ([`scale_up`]).
fn factor(
    work: &mut LstsqWork,
    mut a: MatMut<'_, f64>,
    mut extra: MatMut<'_, f64>,
    again: Again<'_>,
) -> Factored {
    let (m, w) = a.shape();
    let k = m.min(w);
    if k == 0 {
        return Factored::Zero;
    }
    ensure_scratch(&mut work.mem, m, w, extra.ncols());
    work.orig.clear();
    if let Again::Copy = again {
        for j in 0..w {
            match a.rb().col(j).try_as_col_major() {
                Some(col) => work.orig.extend_from_slice(col.as_slice()),
                None => work.orig.extend(a.rb().col(j).iter()),
            }
        }
    }
    work.tau.resize(k, 0.0);
    scale_up(&mut work.scale, a.rb_mut());
    let info = no_pivoting::factor::qr_in_place(
        a.rb_mut(),
        MatMut::from_column_major_slice_mut(&mut work.tau, 1, k),
        Par::Seq,
        MemStack::new(&mut work.mem),
        Default::default(),
    );
    if info.rank < k {
        let kept = kept_columns(a.rb(), info.rank);
        if let Again::Refill(fill) = again {
            work.orig.resize(m * w, 0.0);
            fill(&mut work.orig);
        }
        if let Some(how) =
            kept.and_then(|kept| factor_split(work, a.rb_mut(), extra.rb_mut(), &kept))
        {
            return how;
        }
        a.copy_from(MatRef::from_column_major_slice(&work.orig, m, w));
        return factor_pivoted(work, a, extra);
    }
    unscale_r(a.rb_mut(), &work.scale, k);
    if extra.ncols() > 0 {
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            a.rb(),
            MatRef::from_column_major_slice(&work.tau, 1, k),
            Conj::Yes,
            extra,
            Par::Seq,
            MemStack::new(&mut work.mem),
        );
    }
    Factored::Plain
}

/// The upper triangle's columns (`k` rows) divided by the powers of two [`scale_up`] multiplied
/// them by: `R` of `A D` is `R D`.
fn unscale_r(mut a: MatMut<'_, f64>, scale: &[f64], k: usize) {
    for (j, &d) in scale.iter().enumerate() {
        let inv = d.recip();
        a.rb_mut()
            .col_mut(j)
            .subrows_mut(0, (j + 1).min(k))
            .iter_mut()
            .for_each(|v| *v *= inv);
    }
}

/// The columns faer's plain QR (unblocked, as [`factor`] calls it) took as independent, read
/// back from its staircase `R` in `a` by its own rule: column `c`, met at row `p`, counts when
/// its part outside the span of the ones before it (`|R[p, c]|`) exceeds `16 (m - p) eps` of its
/// norm. `None` when that count is not faer's `rank` (a rounding of the rule's norm put a column
/// on the other side: the caller then pivots).
fn kept_columns(a: MatRef<'_, f64>, rank: usize) -> Option<Vec<bool>> {
    let (m, w) = a.shape();
    let size = m.min(w);
    let mut kept = vec![false; w];
    let mut row = 0;
    for (c, kept) in kept.iter_mut().enumerate() {
        if row >= size {
            break;
        }
        let head = a[(row, c)].abs();
        let above = (0..row).map(|i| a[(i, c)] * a[(i, c)]).sum::<f64>().sqrt();
        if head > f64::EPSILON * 16.0 * (m - row) as f64 * head.hypot(above) {
            *kept = true;
            row += 1;
        }
    }
    (row == rank).then_some(kept)
}

/// [`factor`] when faer's plain QR took some columns for dependent, without factoring the whole
/// of `A` again by the column-pivoted QR (whose norms of entries scaled under 1 run into the
/// subnormal sums [`scale_up`] avoids): `A P = [A_1 A_2]` with `A_1` the columns `kept` and
/// `A_2` the others; faer's plain QR of `A_1` (no column dependent now), `Q_1^T A_2`, whose rows
/// from `r` on (the dependent columns' parts outside `A_1`'s span, tiny but not zero) get faer's
/// plain QR too; then `R` in `A`'s column order from the QR of the small `S = R_P P^T` (as
/// [`factor_pivoted`]). `A` is read from `work.orig`; `None` (with `extra` untouched) when the
/// QR of the kept columns finds one dependent (a rounding of [`kept_columns`]' rule).
///
/// The second QR may take a column for dependent in its turn: one zero in `A` (a parameter
/// the output does not depend on) or whose part outside `A_1`'s span lies within `16 m eps` of
/// the span of the other dependent ones' parts, themselves at most `16 m eps` of their columns:
/// its pivot, at most `(16 m eps)^2` of its column (`1e-21` for 8192 rows), is then zero.
/// (Factoring those parts by the column-pivoted QR instead, which gives such a column a pivot of
/// rounding's size, moved 8 of the zoo's 300 cases, 4 to a spurious effect; this way 1.)
fn factor_split(
    work: &mut LstsqWork,
    mut a: MatMut<'_, f64>,
    mut extra: MatMut<'_, f64>,
    kept: &[bool],
) -> Option<Factored> {
    let (m, w) = a.shape();
    let k = m.min(w);
    let order: Vec<usize> = (0..w)
        .filter(|&j| kept[j])
        .chain((0..w).filter(|&j| !kept[j]))
        .collect();
    let r = kept.iter().filter(|&&v| v).count();
    let orig = MatRef::from_column_major_slice(&work.orig, m, w);
    for (p, &j) in order.iter().enumerate() {
        a.rb_mut().col_mut(p).copy_from(orig.col(j));
    }
    scale_up(&mut work.scale, a.rb_mut());
    let (mut first, mut rest) = a.rb_mut().split_at_col_mut(r);
    let (tau1, tau2) = work.tau.split_at_mut(r);
    let info = no_pivoting::factor::qr_in_place(
        first.rb_mut(),
        MatMut::from_column_major_slice_mut(tau1, 1, r),
        Par::Seq,
        MemStack::new(&mut work.mem),
        Default::default(),
    );
    if info.rank < r {
        return None;
    }
    let q1 = |target: MatMut<'_, f64>, mem: &mut Vec<MaybeUninit<u8>>, tau1: &[f64]| {
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            first.rb(),
            MatRef::from_column_major_slice(tau1, 1, r),
            Conj::Yes,
            target,
            Par::Seq,
            MemStack::new(mem),
        );
    };
    q1(rest.rb_mut(), &mut work.mem, tau1);
    // The dependent columns' parts outside A_1's span, by faer's plain QR: it takes one for
    // dependent only when it is zero or lies within 16 m eps of the span of the others' (its
    // pivot then at most (16 m eps)^2 of its column: zero, as a rounding would leave it).
    let k2 = k - r;
    let mut r2 = 0;
    if k2 > 0 {
        r2 = no_pivoting::factor::qr_in_place(
            rest.rb_mut().subrows_mut(r, m - r),
            MatMut::from_column_major_slice_mut(&mut tau2[..k2], 1, k2),
            Par::Seq,
            MemStack::new(&mut work.mem),
            Default::default(),
        )
        .rank;
    }
    if extra.ncols() > 0 {
        q1(extra.rb_mut(), &mut work.mem, tau1);
        if r2 > 0 {
            householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
                rest.rb().subrows(r, m - r).subcols(0, r2),
                MatRef::from_column_major_slice(&tau2[..r2], 1, r2),
                Conj::Yes,
                extra.rb_mut().subrows_mut(r, m - r),
                Par::Seq,
                MemStack::new(&mut work.mem),
            );
        }
    }
    // S = R_P P^T, R_P's columns back to A's scale.
    work.s.clear();
    work.s.resize(k * w, 0.0);
    let mut sm = MatMut::from_column_major_slice_mut(&mut work.s, k, w);
    for (p, &j) in order.iter().enumerate() {
        for i in 0..=p.min(k - 1) {
            sm[(i, j)] = a[(i, p)] / work.scale[p];
        }
    }
    r_of_s(work, a, extra);
    Some(Factored::Split { r, r2 })
}

/// The last step of [`factor_pivoted`] and [`factor_split`]: faer's plain QR of `S` (in
/// `work.s`, `k x w`), its `R` into `a`'s upper triangle and `Q_s^T` applied to `extra`'s first
/// `k` rows. On `S` faer's rule (`16 k eps` of a column's norm, about `3e-14` for eight columns)
/// takes only a part that rounding alone leaves for dependent.
fn r_of_s(work: &mut LstsqWork, mut a: MatMut<'_, f64>, extra: MatMut<'_, f64>) {
    let (m, w) = a.shape();
    let k = m.min(w);
    let mut sm = MatMut::from_column_major_slice_mut(&mut work.s, k, w);
    work.tau_s.resize(k, 0.0);
    no_pivoting::factor::qr_in_place(
        sm.rb_mut(),
        MatMut::from_column_major_slice_mut(&mut work.tau_s, 1, k),
        Par::Seq,
        MemStack::new(&mut work.mem),
        Default::default(),
    );
    for j in 0..w {
        for i in 0..=j.min(k - 1) {
            a[(i, j)] = sm[(i, j)];
        }
    }
    if extra.ncols() > 0 {
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            sm.rb(),
            MatRef::from_column_major_slice(&work.tau_s, 1, k),
            Conj::Yes,
            extra.subrows_mut(0, k),
            Par::Seq,
            MemStack::new(&mut work.mem),
        );
    }
}

/// [`factor`] by two faer factorisations: the column-pivoted QR `A D^-1 P = Q_p R_p`, which takes
/// no column for dependent, then the plain QR of the small `S = R_p P^T D = Q_s R` (`k x w`),
/// whose `R` is `A`'s (`A = Q_p S`), with `Q = Q_p Q_s`. On `S` faer's rule (`16 k eps` of a
/// column's norm, about `3e-14` for eight columns) takes only a part that rounding alone leaves
/// for dependent.
///
/// `D` (powers of two, exact) scales each column to about unit norm first: faer's pivoted QR
/// divides the whole matrix by its largest column norm, which would flush a column of `1e-200`
/// beside one of `1e200` to zero.
fn factor_pivoted(
    work: &mut LstsqWork,
    mut a: MatMut<'_, f64>,
    mut extra: MatMut<'_, f64>,
) -> Factored {
    let (m, w) = a.shape();
    let k = m.min(w);
    work.scale.clear();
    let mut nonzero = false;
    for j in 0..w {
        let norm = a.rb().col(j).norm_l2();
        if !norm.is_finite() {
            a.fill(f64::NAN);
            extra.fill(f64::NAN);
            return Factored::NotFinite;
        }
        nonzero |= norm > 0.0;
        let d = if norm > 0.0 { power_of_two(norm) } else { 1.0 };
        work.scale.push(d);
        let inv = d.recip();
        a.rb_mut().col_mut(j).iter_mut().for_each(|v| *v *= inv);
    }
    if !nonzero {
        return Factored::Zero;
    }
    work.pivoted_qr(a.rb_mut(), k);
    if extra.ncols() > 0 {
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            a.rb(),
            MatRef::from_column_major_slice(&work.tau, 1, k),
            Conj::Yes,
            extra.rb_mut(),
            Par::Seq,
            MemStack::new(&mut work.mem),
        );
    }
    // S = R_p P^T D: position p of R_p is column perm[p] of A.
    work.s.clear();
    work.s.resize(k * w, 0.0);
    let mut sm = MatMut::from_column_major_slice_mut(&mut work.s, k, w);
    for (p, &j) in work.perm.iter().enumerate() {
        for i in 0..=p.min(k - 1) {
            sm[(i, j)] = a[(i, p)] * work.scale[j];
        }
    }
    r_of_s(work, a, extra);
    Factored::Pivoted
}

/// Grow `mem` to faer's scratch for [`factor`] of an `m x w` matrix with `e` extra columns (and
/// for forming `Q` in [`thin_qr`]).
fn ensure_scratch(mem: &mut Vec<MaybeUninit<u8>>, m: usize, w: usize, e: usize) {
    let k = m.min(w);
    let req =
        StackReq::any_of(&[
            no_pivoting::factor::qr_in_place_scratch::<f64>(m, w, 1, Par::Seq, Default::default()),
            col_pivoting::factor::qr_in_place_scratch::<usize, f64>(
                m,
                w,
                1,
                Par::Seq,
                Default::default(),
            ),
            householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<
                f64,
            >(m, 1, e.max(k)),
            householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
                m,
                1,
                e.max(k),
            ),
        ]);
    let bytes = req.unaligned_bytes_required();
    if mem.len() < bytes {
        mem.resize(bytes, MaybeUninit::uninit());
    }
}

impl LstsqWork {
    /// faer's column-pivoted QR of `a` in place (`k = min(rows, cols)` reflectors into `tau`, the
    /// permutation into `perm` and `perm_inv`), in this scratch (`mem` already large enough).
    fn pivoted_qr(&mut self, a: MatMut<'_, f64>, k: usize) {
        let w = a.ncols();
        self.perm.resize(w, 0);
        self.perm_inv.resize(w, 0);
        col_pivoting::factor::qr_in_place(
            a,
            MatMut::from_column_major_slice_mut(&mut self.tau[..k], 1, k),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
    }

    /// The memory (it grows to the widest system it is given).
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The least-squares solution of `min |A x - b|` into `b[..cols]` (`A` column-major
    /// `b.len() x cols`, `A` and `b` overwritten), and the diagonal of `R` (of either sign)
    /// into `diag` (length `cols`), by which the caller judges the rank. `rows >= cols`.
    /// `refill` writes `A` again into the slice it is given (called only when faer's plain QR
    /// took a column for dependent: [`factor`]).
    pub(crate) fn solve(
        &mut self,
        a: &mut [f64],
        b: &mut [f64],
        diag: &mut [f64],
        refill: &mut dyn FnMut(&mut [f64]),
    ) {
        let (rows, cols) = (b.len(), diag.len());
        debug_assert!(rows >= cols && a.len() == rows * cols);
        let mut am = MatMut::from_column_major_slice_mut(a, rows, cols);
        let mut bm = MatMut::from_column_major_slice_mut(b, rows, 1);
        factor(self, am.rb_mut(), bm.rb_mut(), Again::Refill(refill));
        for (j, d) in diag.iter_mut().enumerate() {
            *d = am[(j, j)];
        }
        solve_upper_triangular_in_place(
            am.rb().subrows(0, cols),
            bm.subrows_mut(0, cols),
            Par::Seq,
        );
    }
}

/// The `R` (`min(rows, w) x w`, upper trapezoidal) of the column-major `rows x w` matrix `a`
/// (overwritten) by faer's Householder QR ([`factor`], `A` got back as `again` says when faer's
/// plain QR takes a column for dependent). `R` is unique up to the signs of its rows.
pub(crate) fn qr_r_in_place(
    a: &mut [f64],
    rows: usize,
    w: usize,
    work: &mut LstsqWork,
    again: Again<'_>,
) -> Mat<f64> {
    debug_assert_eq!(a.len(), rows * w);
    let k = rows.min(w);
    if k == 0 {
        return Mat::zeros(0, w);
    }
    let am = MatMut::from_column_major_slice_mut(a, rows, w);
    let none = MatMut::from_column_major_slice_mut(&mut [], rows, 0);
    factor(work, am, none, again);
    Mat::<f64>::from_fn(k, w, |i, j| if j >= i { a[j * rows + i] } else { 0.0 })
}

/// The least-squares solution `X` of `min ||A X - B||` (`A` is `m x n`, `m >= n`) by faer's
/// Householder QR ([`factor`]). A zero pivot (dependent columns) gives infinite or NaN entries,
/// not an error: callers check them.
pub(crate) fn lstsq(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut x = Mat::<f64>::zeros(n, b.ncols());
    if n == 0 {
        return x;
    }
    let mut qr = a.as_slice().to_vec();
    let mut rhs = b.as_slice().to_vec();
    let mut am = MatMut::from_column_major_slice_mut(&mut qr, m, n);
    let mut bm = MatMut::from_column_major_slice_mut(&mut rhs, m, b.ncols());
    factor(&mut LstsqWork::new(), am.rb_mut(), bm.rb_mut(), Again::Copy);
    solve_upper_triangular_in_place(
        am.rb().subrows(0, n),
        bm.rb_mut().subrows_mut(0, n),
        Par::Seq,
    );
    for c in 0..b.ncols() {
        for i in 0..n {
            x[(i, c)] = bm[(i, c)];
        }
    }
    x
}

/// The thin QR of the columns `cols` (each of one length `m >= cols.len()`): `cols` become the
/// orthonormal `Q`, the returned `R` (row-major `c x c`, upper triangular) has `cols_in = Q R`.
/// `None` when a column's part outside the span of the ones before it is `1e-12` of its norm
/// or less (or not finite). faer's Householder QR ([`factor`]), `Q` formed by applying its
/// reflectors to the leading columns of the identity.
pub(crate) fn thin_qr(cols: &mut [Vec<f64>]) -> Option<Vec<f64>> {
    let c = cols.len();
    let m = cols.first().map_or(0, Vec::len);
    if c == 0 || m < c {
        return (c == 0).then(Vec::new);
    }
    let norms: Vec<f64> = cols
        .iter()
        .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
        .collect();
    let mut a: Vec<f64> = cols.iter().flat_map(|v| v.iter().copied()).collect();
    let mut work = LstsqWork::new();
    let mut am = MatMut::from_column_major_slice_mut(&mut a, m, c);
    let none = MatMut::from_column_major_slice_mut(&mut [], m, 0);
    let how = factor(&mut work, am.rb_mut(), none, Again::Copy);
    if matches!(how, Factored::Zero | Factored::NotFinite) {
        return None;
    }
    let mut r = vec![0.0; c * c];
    for k in 0..c {
        let d = am[(k, k)];
        if !(d.abs() > 1e-12 * norms[k]) || !d.is_finite() {
            return None;
        }
        for j in k..c {
            r[k * c + j] = am[(k, j)];
        }
    }
    // Q [I; 0]: the reflectors applied to the identity's leading columns, last to first (for
    // the pivoted QR, Q_p [Q_s; 0]; for the split one, Q_1 diag(I_r, Q_2) [Q_s; 0]).
    let mut q = vec![0.0; m * c];
    let mut qm = MatMut::from_column_major_slice_mut(&mut q, m, c);
    for k in 0..c {
        qm[(k, k)] = 1.0;
    }
    let stack = MemStack::new(&mut work.mem);
    if matches!(how, Factored::Pivoted | Factored::Split { .. }) {
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
            MatRef::from_column_major_slice(&work.s, c, c),
            MatRef::from_column_major_slice(&work.tau_s, 1, c),
            Conj::No,
            qm.rb_mut().subrows_mut(0, c),
            Par::Seq,
            stack,
        );
    }
    // the reflectors of A (plain, pivoted) or of A's kept columns (split), after those of the
    // block from row and column r (split)
    let first = match how {
        Factored::Split { r, r2 } => {
            householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
                am.rb().subrows(r, m - r).subcols(r, r2),
                MatRef::from_column_major_slice(&work.tau[r..r + r2], 1, r2),
                Conj::No,
                qm.rb_mut().subrows_mut(r, m - r),
                Par::Seq,
                stack,
            );
            r
        }
        _ => c,
    };
    householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
        am.rb().subcols(0, first),
        MatRef::from_column_major_slice(&work.tau[..first], 1, first),
        Conj::No,
        qm.rb_mut(),
        Par::Seq,
        stack,
    );
    for (j, col) in cols.iter_mut().enumerate() {
        col.copy_from_slice(&q[j * m..(j + 1) * m]);
    }
    Some(r)
}

/// The Gram matrix `A^T A` (row-major `c x c`, symmetric) of the columns `cols` (each of one
/// length), by faer's product.
pub(crate) fn gram_of_columns(cols: &[Vec<f64>]) -> Vec<f64> {
    let c = cols.len();
    let m = cols.first().map_or(0, Vec::len);
    let a: Vec<f64> = cols.iter().flat_map(|v| v.iter().copied()).collect();
    let mut g = Mat::<f64>::zeros(c, c);
    if c > 0 {
        let av = view(&a, m, c);
        let dst = MatMut::from_column_major_slice_mut(g.as_mut_slice(), c, c);
        matmul(dst, Accum::Replace, av.transpose(), av, 1.0, Par::Seq);
    }
    let mut out = vec![0.0; c * c];
    for i in 0..c {
        for j in 0..=i {
            out[i * c + j] = g[(i, j)];
            out[j * c + i] = g[(i, j)];
        }
    }
    out
}

/// `x := (L L^T)^-1 x` for the lower triangular `L` (row-major `c x c`, `c = x.len()`), by
/// faer's triangular solves.
pub(crate) fn solve_llt_row_major(l: &[f64], x: &mut [f64]) {
    let c = x.len();
    let lm = MatRef::from_row_major_slice(l, c, c);
    let mut xm = MatMut::from_column_major_slice_mut(x, c, 1);
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(lm, xm.rb_mut(), Par::Seq);
    solve_upper_triangular_in_place(lm.transpose(), xm, Par::Seq);
}

/// `x := R^-1 x` for the upper triangular `R` (row-major `c x c`, `c = x.len()`), by faer's
/// triangular solve.
pub(crate) fn solve_upper_row_major(r: &[f64], x: &mut [f64]) {
    let c = x.len();
    let rm = MatRef::from_row_major_slice(r, c, c);
    solve_upper_triangular_in_place(rm, MatMut::from_column_major_slice_mut(x, c, 1), Par::Seq);
}

/// The solution of `A x = b` for a symmetric positive definite `A` (`n x n`, its lower
/// triangle read) by faer's Cholesky factorisation; `None` when `A` is not positive definite.
pub(crate) fn cholesky_solve(a: &Mat<f64>, b: &[f64]) -> Option<Vec<f64>> {
    let llt = as_faer(a).llt(faer::Side::Lower).ok()?;
    let mut x = faer::Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]);
    faer::linalg::solvers::SolveCore::solve_in_place_with_conj(&llt, faer::Conj::No, x.as_mut());
    Some((0..b.len()).map(|i| x[(i, 0)]).collect())
}

/// The solution `X` of `A X = B` for a symmetric positive definite `A` (`n x n`, its lower
/// triangle read) by faer's Cholesky factorisation; `None` when `A` is not positive definite.
pub(crate) fn cholesky_solve_cols(a: &Mat<f64>, b: &Mat<f64>) -> Option<Mat<f64>> {
    let llt = as_faer(a).llt(faer::Side::Lower).ok()?;
    let mut x = b.clone();
    let xm = MatMut::from_column_major_slice_mut(x.as_mut_slice(), b.nrows(), b.ncols());
    faer::linalg::solvers::SolveCore::solve_in_place_with_conj(&llt, faer::Conj::No, xm);
    Some(x)
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
    matmul(
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
    matmul(g_mut, Accum::Add, block.transpose(), rb, 1.0, Par::Seq);
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

/// The minimum-norm least-squares solution of `min |A x - b|` by faer's thin SVD, the singular
/// values at or below `eps` taken as zero (a rank-deficient system's pseudo-inverse); `None` when
/// the SVD does not converge or its solution is not finite.
pub(crate) fn svd_solve(a: &Mat<f64>, b: &[f64], eps: f64) -> Option<Vec<f64>> {
    let (m, n) = (a.nrows(), a.ncols());
    debug_assert_eq!(b.len(), m);
    let svd = as_faer(a).thin_svd().ok()?;
    let (u, v, s) = (svd.U(), svd.V(), svd.S().column_vector());
    let mut x = vec![0.0; n];
    for k in 0..s.nrows() {
        if s[k] <= eps {
            continue;
        }
        let c = (0..m).map(|r| u[(r, k)] * b[r]).sum::<f64>() / s[k];
        for (j, xj) in x.iter_mut().enumerate() {
            *xj += c * v[(j, k)];
        }
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The relative size under which a column's part outside the span of the others makes it
/// dependent in [`Span`]: its columns scaled to unit norm, a part of `1e-10` is below the
/// accuracy of the sensitivities it is given (a part that rounding alone leaves from exactly
/// dependent columns is about `1e-16` to `1e-13`).
pub(crate) const DEPENDENT_PART: f64 = 1e-10;

/// The part of each column of `b` (`m x c`) outside the span of the columns of `a` (`m x n`):
/// `b - Q Q^T b` for the orthonormal `Q` of `a`'s independent columns. faer's column-pivoted QR
/// of `a`'s columns scaled to unit norm: its leading pivots above [`DEPENDENT_PART`] are the
/// independent columns; a column whose part outside their span is under it (a column of zeros,
/// or nearly a combination of those) adds nothing to the span.
///
/// Computed from the reflectors, not from least-squares coefficients `x` as `b - a x`: with
/// nearly dependent columns `x` is huge and arbitrary, and `b - a x` loses the digits the
/// projection needs (or is not finite for a column of zeros), so rounding decided the result.
/// (The diagnosis factors `a` once for many `b`: [`Span`].)
#[cfg(test)]
pub(crate) fn project_out(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    Span::of(a).project_out(b)
}

/// The span of a matrix's independent columns, factored once ([`Span::of`]) for the
/// projections of many right-hand sides ([`Span::project_out`], `project_out` of each): the
/// diagnosis projects a model's sensitivities out of every signature its probes try, and the
/// factorisation of the sensitivities (the same for all of them) was most of each projection's
/// cost. The same reflectors applied the same way: each projection is what `project_out`
/// computed alone, bit for bit.
pub(crate) struct Span {
    /// The pivoted QR of the unit-norm columns (reflectors below the diagonal), `m x n`, with
    /// the coefficients and the rank; `None` when every column is zero (nothing to project).
    factored: Option<(Mat<f64>, Vec<f64>, usize)>,
}

impl Span {
    /// The span of `a`'s independent columns (see `project_out`).
    pub(crate) fn of(a: &Mat<f64>) -> Self {
        let (m, n) = (a.nrows(), a.ncols());
        let k = m.min(n);
        let mut q = a.clone();
        let mut nonzero = false;
        for j in 0..n {
            let norm = as_faer(&q).col(j).norm_l2();
            let mut col = q.column_mut(j);
            if norm > 0.0 && norm.is_finite() {
                col.iter_mut().for_each(|v| *v /= norm);
                nonzero = true;
            } else {
                col.iter_mut().for_each(|v| *v = 0.0);
            }
        }
        // (faer's pivoted QR divides by the largest column norm: not by a zero one.)
        if !nonzero {
            return Span { factored: None };
        }
        let mut work = LstsqWork::new();
        ensure_scratch(&mut work.mem, m, n, 0);
        work.tau.resize(k, 0.0);
        let mut qm = MatMut::from_column_major_slice_mut(q.as_mut_slice(), m, n);
        work.pivoted_qr(qm.rb_mut(), k);
        let rank = (0..k)
            .take_while(|&i| qm[(i, i)].abs() > DEPENDENT_PART)
            .count();
        Span {
            factored: Some((q, work.tau, rank)),
        }
    }

    /// `b` with the span projected out (see `project_out`).
    pub(crate) fn project_out(&self, b: &Mat<f64>) -> Mat<f64> {
        let mut out = b.clone();
        let (Some((q, tau, rank)), c) = (&self.factored, b.ncols()) else {
            return out;
        };
        if c == 0 {
            return out;
        }
        let (m, n, k) = (q.nrows(), q.ncols(), tau.len());
        let mut mem = Vec::new();
        ensure_scratch(&mut mem, m, n, c);
        let qm = MatRef::from_column_major_slice(q.as_slice(), m, n);
        // Q^T b with its first rows (the span's coordinates) zeroed, then Q applied: b - Q Q^T b.
        let tau = MatRef::from_column_major_slice(tau, 1, k);
        let mut om = MatMut::from_column_major_slice_mut(out.as_mut_slice(), m, c);
        let stack = MemStack::new(&mut mem);
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            qm,
            tau,
            Conj::Yes,
            om.rb_mut(),
            Par::Seq,
            stack,
        );
        om.rb_mut().subrows_mut(0, *rank).fill(0.0);
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
            qm,
            tau,
            Conj::No,
            om,
            Par::Seq,
            stack,
        );
        out
    }
}

/// `A^T A` (`n x n`) of the column-major `m x n` matrix `a`, by faer's product.
pub(crate) fn gram(a: &Mat<f64>) -> Mat<f64> {
    let n = a.ncols();
    let mut out = Mat::<f64>::zeros(n, n);
    let dst = MatMut::from_column_major_slice_mut(out.as_mut_slice(), n, n);
    let a = as_faer(a);
    matmul(dst, Accum::Replace, a.transpose(), a, 1.0, Par::Seq);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lm::ColSlices;

    /// A seeded generator of uniform numbers in [-0.5, 0.5) (a 64-bit LCG).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut next = crate::testdata::lcg(seed);
        move || (next() >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// A nearly dependent column (`5e-12` outside the span of another, under faer's
    /// `16 m eps = 2.9e-11`) is split off ([`factor_split`], not the pivoted QR), beside a zero
    /// column or not: `Q^T b` keeps `b`'s norm and gives `R^T Q^T b = A^T b` (what the LM reads
    /// its gradient from), the zero column's pivot is 0 and the dependent one's its size; the
    /// thin QR's `Q` is orthonormal with `Q R = A`.
    #[test]
    fn a_nearly_dependent_column_is_split_off_with_q_and_r_exact() {
        let mut rnd = uniform(23);
        let m = 8192;
        let norm = crate::numeric::norm;
        for (w, want) in [
            (5, Factored::Split { r: 4, r2: 1 }),
            (6, Factored::Split { r: 4, r2: 1 }),
            (7, Factored::Split { r: 4, r2: 2 }),
        ] {
            let mut a = Mat::<f64>::from_fn(m, w, |_, j| if j == 5 { 0.0 } else { rnd() });
            for i in 0..m {
                a[(i, 1)] = a[(i, 3)] + 5e-12 * a[(i, 1)];
                if w == 7 {
                    a[(i, 6)] = a[(i, 2)] - 3.0 * a[(i, 0)] + 7e-12 * a[(i, 6)];
                }
            }
            let b: Vec<f64> = (0..m).map(|_| rnd()).collect();
            let mut buf = a.as_slice().to_vec();
            let mut qtb = b.clone();
            let how = factor(
                &mut LstsqWork::new(),
                MatMut::from_column_major_slice_mut(&mut buf, m, w),
                MatMut::from_column_major_slice_mut(&mut qtb, m, 1),
                Again::Copy,
            );
            assert_eq!(how, want, "{w} columns");
            assert!((norm(&qtb) - norm(&b)).abs() <= 1e-13 * norm(&b));
            for j in 0..w {
                let rtq: f64 = (0..=j).map(|i| buf[j * m + i] * qtb[i]).sum();
                let atb: f64 = (0..m).map(|i| a[(i, j)] * b[i]).sum();
                let scale = a.column(j).norm() * norm(&b);
                assert!(
                    (rtq - atb).abs() <= 1e-13 * scale,
                    "column {j}: {rtq} vs {atb}"
                );
            }
            for i in 0..w {
                for j in 0..w {
                    let rtr: f64 = (0..=i.min(j))
                        .map(|k| buf[i * m + k] * buf[j * m + k])
                        .sum();
                    let ata: f64 = (0..m).map(|k| a[(k, i)] * a[(k, j)]).sum();
                    let scale = a.column(i).norm() * a.column(j).norm();
                    assert!((rtr - ata).abs() <= 1e-13 * scale, "{w}: G[{i},{j}]");
                }
            }
            if w > 5 {
                assert_eq!(buf[5 * m + 5], 0.0);
                continue;
            }
            let mut cols: Vec<Vec<f64>> = (0..w)
                .map(|j| a.column(j).iter().copied().collect())
                .collect();
            let r = thin_qr(&mut cols).expect("pivots above 1e-12 of their columns");
            for i in 0..w {
                for j in 0..w {
                    let qq: f64 = (0..m).map(|k| cols[i][k] * cols[j][k]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((qq - want).abs() < 1e-12, "Q^T Q [{i},{j}] = {qq}");
                }
            }
            for j in 0..w {
                let worst = (0..m)
                    .map(|k| {
                        let qr: f64 = (0..=j).map(|i| cols[i][k] * r[i * w + j]).sum();
                        (qr - a[(k, j)]).abs()
                    })
                    .fold(0.0f64, f64::max);
                assert!(
                    worst < 1e-13 * a.column(j).norm(),
                    "Q R column {j}: {worst:e}"
                );
            }
            // the pivot of the dependent part is its size, not a rounding's zero
            let pivot = r[w + 1].abs().min(r[3 * w + 3].abs());
            let col = a.column(3).norm();
            assert!(pivot > 1e-12 * col && pivot < 2e-11 * col, "{pivot:e}");
        }
    }

    /// A matrix of zero columns has `R = 0` and one with a NaN a NaN `R`, with no panic on the way
    /// (faer's plain QR takes every column of either for dependent: the split path with no
    /// column kept).
    #[test]
    fn zero_and_nan_matrices_factor_without_panic() {
        let (m, w) = (50, 3);
        let mut zero = vec![0.0; m * w];
        let r = qr_r_in_place(&mut zero, m, w, &mut LstsqWork::new(), Again::Copy);
        assert!(r.iter().all(|&v| v == 0.0));
        let mut nan: Vec<f64> = (0..m * w).map(|i| i as f64).collect();
        nan[7] = f64::NAN;
        let r = qr_r_in_place(&mut nan, m, w, &mut LstsqWork::new(), Again::Copy);
        assert!(r.iter().any(|v| v.is_nan()));
        let a = Mat::<f64>::zeros(m, w);
        let x = lstsq(&a, &Mat::<f64>::from_element(m, 1, 1.0));
        assert!(x.iter().all(|v| !v.is_finite()));
    }

    /// A nearly dependent column (its part outside the span of the ones before it `1e-12` of its
    /// norm, as two of a fit's terms can be) in a block of 8192 rows: its pivot is that part,
    /// and the columns after it keep theirs (nalgebra's `R` the reference). faer's
    /// `qr_in_place` would take the column for dependent and put zeros on the diagonal from
    /// there on.
    #[test]
    fn a_nearly_dependent_column_keeps_its_pivot_and_the_later_ones() {
        let mut rnd = uniform(11);
        let (m, w) = (8192, 6);
        let mut a = Mat::<f64>::from_fn(m, w, |_, _| rnd());
        for i in 0..m {
            a[(i, 3)] = a[(i, 2)] + 1e-12 * a[(i, 3)];
        }
        let mut buf = a.as_slice().to_vec();
        let got = qr_r_in_place(&mut buf, m, w, &mut LstsqWork::new(), Again::Copy);
        let want = a.clone().qr().r();
        for j in 0..w {
            let (g, x) = (got[(j, j)].abs(), want[(j, j)].abs());
            // (The later pivots depend on the direction of column 3's remainder, which
            // rounding sets to about eps / 1e-12 = 2e-4.)
            let tol = if j < 3 { 1e-12 * x } else { 1e-3 * x };
            assert!((g - x).abs() <= tol, "R[{j},{j}] = {g:e}, nalgebra {x:e}");
        }
        assert!(got[(3, 3)].abs() > 1e-13 * a.column(3).norm());
    }

    /// [`svd_solve`] against nalgebra's SVD solve (another library's SVD, the same rule for the
    /// small singular values): a full-rank system, and one with a repeated column and a column
    /// of zeros, whose minimum-norm solution splits the repeated column's coefficient evenly
    /// and gives the zero column none.
    #[test]
    fn the_svd_solve_is_the_minimum_norm_least_squares_solution() {
        let mut rnd = uniform(5);
        let (m, w) = (40, 5);
        let mut a = Mat::<f64>::from_fn(m, w, |_, _| rnd());
        let b: Vec<f64> = (0..m).map(|_| rnd()).collect();
        // faer's solution of `a`, checked against nalgebra's
        let solved = |a: &Mat<f64>| {
            let rhs = nalgebra::DVector::from_column_slice(&b);
            let want = a.clone().svd(true, true).solve(&rhs, 1e-12).unwrap();
            let got = svd_solve(a, &b, 1e-12).unwrap();
            for j in 0..w {
                let tol = 1e-12 * want.amax();
                assert!((got[j] - want[j]).abs() <= tol, "{j}: {got:?} {want}");
            }
            got
        };
        solved(&a);
        for i in 0..m {
            a[(i, 3)] = a[(i, 1)];
            a[(i, 4)] = 0.0;
        }
        let got = solved(&a);
        assert!(
            (got[1] - got[3]).abs() <= 1e-12 * got[1].abs() && got[4] == 0.0,
            "{got:?}"
        );
    }

    /// [`project_out`] against the projection by nalgebra's SVD (`b - U_k U_k^T b` over the
    /// singular values above `1e-8` of the largest): on independent columns; with a column of
    /// zeros, a column repeated and one that is a combination of two others to `1e-15` (the
    /// span is the independent columns'); and the same matrix with those dependent columns moved
    /// by rounding-sized noise, which must not move the result (least-squares coefficients on
    /// them are arbitrary: `b - A x` was).
    #[test]
    fn project_out_removes_the_span_of_the_independent_columns() {
        let mut rnd = uniform(23);
        let m = 2000;
        let b = Mat::<f64>::from_fn(m, 2, |_, _| rnd());
        let reference = |a: &Mat<f64>| {
            let svd = a.clone().svd(true, false);
            let u = svd.u.unwrap();
            let top = svd.singular_values.max();
            let mut p = b.clone();
            for (k, s) in svd.singular_values.iter().enumerate() {
                if *s > 1e-8 * top {
                    let uk = u.column(k);
                    for c in 0..2 {
                        let h = uk.dot(&b.column(c));
                        p.column_mut(c).axpy(-h, &uk, 1.0);
                    }
                }
            }
            p
        };
        let close = |got: &Mat<f64>, want: &Mat<f64>, what: &str| {
            let err = (got - want).norm();
            assert!(err <= 1e-12 * b.norm(), "{what}: |diff| = {err:e}");
        };
        let free = Mat::<f64>::from_fn(m, 4, |i, j| rnd() * (j + 1) as f64 + (i % 7) as f64);
        let got = project_out(&free, &b);
        close(&got, &reference(&free), "independent");
        let at = free.transpose() * &got;
        assert!(
            at.amax() <= 1e-10 * b.norm() * free.norm(),
            "not orthogonal"
        );
        // Columns 0..4 independent; 4 zeros, 5 = column 1 times 3, 6 = column 0 + column 2
        // (to 1e-15 of its norm).
        let noise: Vec<f64> = (0..m).map(|_| rnd()).collect();
        let dependent = |eps: f64| {
            Mat::<f64>::from_fn(m, 7, |i, j| match j {
                0..=3 => free[(i, j)],
                4 => 0.0,
                5 => 3.0 * free[(i, 1)] * (1.0 + eps * noise[i]),
                _ => free[(i, 0)] + free[(i, 2)] + 1e-15 * noise[i] * (1.0 + eps),
            })
        };
        let a = dependent(0.0);
        let got = project_out(&a, &b);
        close(&got, &reference(&free), "dependent columns");
        let moved = project_out(&dependent(1e-14), &b);
        close(&moved, &got, "dependent columns moved by rounding");
        assert!(got.iter().all(|v| v.is_finite()));
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
            let r = qr_r_in_place(&mut buf, rows, w, &mut LstsqWork::new(), Again::Copy);
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
