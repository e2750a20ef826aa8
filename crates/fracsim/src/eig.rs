//! Eigenvalues of a real square matrix without its Schur vectors: Hessenberg reduction, then the
//! implicit double-shift (Francis) QR iteration applied to the active block only (LAPACK's
//! `dlahqr` with `wantt = wantz = false`; Golub & Van Loan, *Matrix Computations*, 4th ed.,
//! algorithm 7.5.2). The shifts, deflation tests and reflections are those of nalgebra's
//! `Schur` (which [`crate::modal`] used before), without accumulating `Q` nor updating the
//! parts of `T` outside the block being reduced: only the eigenvalues are wanted (the model's
//! poles, each polished by Newton's method afterwards), and those parts do not change them.
//! About half the work of `nalgebra::Schur::try_new` for the models' 20-40 states.

use nalgebra::DMatrix;
use num_complex::Complex64;

/// The eigenvalues of `m` (any order; complex ones in conjugate pairs), or `None` when the QR
/// iteration does not converge within `max_iterations` double-shift steps. The matrix should be
/// balanced by the caller.
pub fn eigenvalues_only(m: DMatrix<f64>, max_iterations: usize) -> Option<Vec<Complex64>> {
    let n = m.nrows();
    assert_eq!(n, m.ncols(), "eigenvalues of a non-square matrix");
    match n {
        0 => return Some(vec![]),
        1 => return Some(vec![Complex64::new(m[(0, 0)], 0.0)]),
        _ => {}
    }
    let amax = m.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if amax == 0.0 {
        return Some(vec![Complex64::new(0.0, 0.0); n]);
    }
    let h = nalgebra::linalg::Hessenberg::new(m / amax).unpack_h();
    let mut t = Hess {
        n,
        a: h.as_slice().to_vec(),
    };
    t.francis(max_iterations)?;
    Some(t.eigenvalues(amax))
}

/// An upper Hessenberg matrix, column-major.
struct Hess {
    n: usize,
    a: Vec<f64>,
}

impl Hess {
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> f64 {
        self.a[j * self.n + i]
    }

    #[inline(always)]
    fn set(&mut self, i: usize, j: usize, v: f64) {
        self.a[j * self.n + i] = v;
    }

    /// Set negligible subdiagonal entries to zero from `end` up: the block `(start, end)` to
    /// reduce next (`end == start` when none is left), as nalgebra's `delimit_subproblem`.
    fn delimit(&mut self, end: usize) -> (usize, usize) {
        let eps = f64::EPSILON;
        let small = |t: &Self, i: usize| {
            let v = t.at(i, i - 1).abs();
            v == 0.0 || v <= eps * eps || v <= eps * (t.at(i, i).abs() + t.at(i - 1, i - 1).abs())
        };
        let mut n = end;
        while n > 0 {
            if small(self, n) {
                self.set(n, n - 1, 0.0);
                n -= 1;
            } else {
                break;
            }
        }
        if n == 0 {
            return (0, 0);
        }
        let mut start = n - 1;
        while start > 0 {
            if small(self, start) {
                self.set(start, start - 1, 0.0);
                break;
            }
            start -= 1;
        }
        (start, n)
    }

    /// Reflect rows `r..r + v.len()` by `I - 2 v v^T` over columns `cols`.
    fn reflect_rows_of<const K: usize>(
        &mut self,
        v: &[f64; K],
        r: usize,
        cols: std::ops::Range<usize>,
    ) {
        for j in cols {
            let col = &mut self.a[j * self.n + r..j * self.n + r + K];
            let f = -2.0 * (0..K).map(|i| v[i] * col[i]).sum::<f64>();
            for i in 0..K {
                col[i] += f * v[i];
            }
        }
    }

    /// Reflect columns `c..c + v.len()` by `I - 2 v v^T` over rows `rows`.
    fn reflect_cols_of<const K: usize>(
        &mut self,
        v: &[f64; K],
        c: usize,
        rows: std::ops::Range<usize>,
    ) {
        let n = self.n;
        for i in rows {
            let w: f64 = (0..K).map(|l| self.a[(c + l) * n + i] * v[l]).sum();
            for l in 0..K {
                self.a[(c + l) * n + i] -= 2.0 * w * v[l];
            }
        }
    }

    /// The implicit double-shift QR iteration until every block is 1x1 or 2x2.
    fn francis(&mut self, max_iterations: usize) -> Option<()> {
        let mut iterations = 0;
        let (mut start, mut end) = self.delimit(self.n - 1);
        while end != start {
            if end - start + 1 > 2 {
                let (m, n) = (end - 1, end);
                let (h11, h12) = (self.at(start, start), self.at(start, start + 1));
                let (h21, h22) = (self.at(start + 1, start), self.at(start + 1, start + 1));
                let h32 = self.at(start + 2, start + 1);
                let (hnn, hmm) = (self.at(n, n), self.at(m, m));
                let (hnm, hmn) = (self.at(n, m), self.at(m, n));
                let tra = hnn + hmm;
                let det = hnn * hmm - hnm * hmn;
                let mut axis = [
                    h11 * h11 + h12 * h21 - tra * h11 + det,
                    h21 * (h11 + h22 - tra),
                    h21 * h32,
                ];
                for k in start..n - 1 {
                    if let Some(norm) = reflection_axis(&mut axis) {
                        if k > start {
                            self.set(k, k - 1, norm);
                            self.set(k + 1, k - 1, 0.0);
                            self.set(k + 2, k - 1, 0.0);
                        }
                        self.reflect_rows_of(&axis, k, k..end + 1);
                        self.reflect_cols_of(&axis, k, start..(k + 4).min(end + 1));
                    }
                    axis[0] = self.at(k + 1, k);
                    axis[1] = self.at(k + 2, k);
                    if k < n - 2 {
                        axis[2] = self.at(k + 3, k);
                    }
                }
                let mut axis = [axis[0], axis[1]];
                if let Some(norm) = reflection_axis(&mut axis) {
                    self.set(m, m - 1, norm);
                    self.set(n, m - 1, 0.0);
                    self.reflect_rows_of(&axis, m, m..end + 1);
                    self.reflect_cols_of(&axis, m, start..end + 1);
                }
            } else if end > 2 {
                // A 2x2 block: its eigenvalues are read from it at the end.
                end -= 2;
            } else {
                break;
            }
            (start, end) = self.delimit(end);
            iterations += 1;
            if iterations == max_iterations {
                return None;
            }
        }
        Some(())
    }

    /// The eigenvalues of the quasi-triangular result (1x1 and 2x2 diagonal blocks), times
    /// `scale`.
    fn eigenvalues(&self, scale: f64) -> Vec<Complex64> {
        let n = self.n;
        let mut out = Vec::with_capacity(n);
        let mut m = 0;
        while m < n {
            if m + 1 == n || self.at(m + 1, m) == 0.0 {
                out.push(Complex64::new(self.at(m, m) * scale, 0.0));
                m += 1;
                continue;
            }
            let (hmm, hnm, hmn, hnn) = (
                self.at(m, m),
                self.at(m + 1, m),
                self.at(m, m + 1),
                self.at(m + 1, m + 1),
            );
            let val = (hmm - hnn) * 0.5;
            let discr = hnm * hmn + val * val;
            let half_tra = (hnn + hmm) * 0.5;
            if discr >= 0.0 {
                let r = discr.sqrt();
                out.push(Complex64::new((half_tra + r) * scale, 0.0));
                out.push(Complex64::new((half_tra - r) * scale, 0.0));
            } else {
                let r = (-discr).sqrt();
                out.push(Complex64::new(half_tra * scale, r * scale));
                out.push(Complex64::new(half_tra * scale, -r * scale));
            }
            m += 2;
        }
        out
    }
}

/// Replace `v` by the unit axis of the Householder reflection that maps it to `(-+|v|, 0, ...)`
/// and return that first component; `None` when no reflection is needed (nalgebra's
/// `reflection_axis_mut`).
fn reflection_axis<const K: usize>(v: &mut [f64; K]) -> Option<f64> {
    let sq: f64 = v.iter().map(|x| x * x).sum();
    let norm = sq.sqrt();
    let (modulus, sign) = (v[0].abs(), if v[0] < 0.0 { -1.0 } else { 1.0 });
    let signed = sign * norm;
    let factor = (sq + modulus * norm) * 2.0;
    v[0] += signed;
    if factor == 0.0 {
        return None;
    }
    let s = factor.sqrt();
    v.iter_mut().for_each(|x| *x /= s);
    let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if nv > 0.0 {
        v.iter_mut().for_each(|x| *x /= nv);
    }
    Some(-signed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted(mut v: Vec<Complex64>) -> Vec<Complex64> {
        v.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        v
    }

    fn xorshift(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// Against nalgebra's full real Schur decomposition (an independent implementation that
    /// also accumulates `Q` and updates all of `T`): random matrices with real and complex
    /// eigenvalues, well conditioned, to 1e-10 of the matrix's scale.
    #[test]
    fn eigenvalues_equal_nalgebras_schur() {
        let mut rnd = xorshift(0x9e37_79b9_7f4a_7c15);
        let mut complex_seen = 0;
        for n in [2, 3, 4, 7, 12, 25, 40] {
            for _ in 0..5 {
                let m = DMatrix::from_fn(n, n, |_, _| rnd());
                let ours = sorted(eigenvalues_only(m.clone(), 100 * n).unwrap());
                let schur = nalgebra::Schur::try_new(m, f64::EPSILON, 100 * n).unwrap();
                let theirs = sorted(schur.complex_eigenvalues().iter().copied().collect());
                assert_eq!(ours.len(), n);
                complex_seen += ours.iter().filter(|e| e.im != 0.0).count();
                for (a, b) in ours.iter().zip(&theirs) {
                    assert!((a - b).norm() <= 1e-10, "{n}: {a} vs {b}");
                }
            }
        }
        assert!(complex_seen > 10);
    }

    /// A companion matrix of known roots (real, complex, spread over decades as the models'
    /// poles are): the eigenvalues are those roots.
    #[test]
    fn a_companion_matrix_gives_its_roots() {
        let roots = [
            Complex64::new(-1.0, 0.0),
            Complex64::new(-30.0, 0.0),
            Complex64::new(-2.0, 5.0),
            Complex64::new(-2.0, -5.0),
            Complex64::new(-400.0, 0.0),
        ];
        // prod (s - r) = s^5 + c4 s^4 + ... + c0
        let mut c = vec![Complex64::new(1.0, 0.0)];
        for r in roots {
            let mut next = vec![Complex64::new(0.0, 0.0); c.len() + 1];
            for (i, &ci) in c.iter().enumerate() {
                next[i + 1] += ci;
                next[i] -= ci * r;
            }
            c = next;
        }
        let n = roots.len();
        let mut m = DMatrix::<f64>::zeros(n, n);
        for i in 1..n {
            m[(i, i - 1)] = 1.0;
        }
        for i in 0..n {
            m[(i, n - 1)] = -c[i].re;
        }
        nalgebra::linalg::balancing::balance_parlett_reinsch(&mut m);
        let got = sorted(eigenvalues_only(m, 500).unwrap());
        for (g, r) in got.iter().zip(sorted(roots.to_vec())) {
            assert!((g - r).norm() <= 1e-9 * r.norm(), "{g} vs {r}");
        }
    }

    #[test]
    fn small_and_degenerate_sizes() {
        assert!(eigenvalues_only(DMatrix::zeros(0, 0), 10)
            .unwrap()
            .is_empty());
        let one = eigenvalues_only(DMatrix::from_element(1, 1, -3.0), 10).unwrap();
        assert_eq!(one, vec![Complex64::new(-3.0, 0.0)]);
        let zero = eigenvalues_only(DMatrix::zeros(3, 3), 10).unwrap();
        assert!(zero.iter().all(|e| e.norm() == 0.0));
        // [[0, -1], [1, 0]]: +-j
        let rot = DMatrix::from_row_slice(2, 2, &[0.0, -1.0, 1.0, 0.0]);
        let e = sorted(eigenvalues_only(rot, 10).unwrap());
        assert!((e[0] - Complex64::new(0.0, -1.0)).norm() < 1e-15);
        assert!((e[1] - Complex64::new(0.0, 1.0)).norm() < 1e-15);
    }
}
