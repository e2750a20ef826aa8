//! The approximated model in pole-residue (modal) form: the continuous rational system that the
//! rational approximations of every fractional operator make together, written
//! `G~(s) = direct + sum_i r_i / (s - lambda_i)`, without ever multiplying a polynomial out.
//!
//! With each operator approximated as `R_nu(s) = g s^n prod_k (s + z_k)/(s + p_k)` (see
//! [`crate::approx`]), the model is `G~ = N~/D~` with `N~ = sum_i b_i R_(beta_i)` and
//! `D~ = sum_j a_j R_(alpha_j)`. Dividing both by `s^n_max` (`n_max` the largest integer part in
//! the denominator) makes them proper: `G~ = N_H/H` with
//! `H(s) = sum_groups P_g(1/s) prod_(k in g) (s + z_k)/(s + p_k)`, where terms sharing the same
//! cells are one group and `P_g` a polynomial in `1/s` (its constant term `d = H(infinity)`).
//!
//! - The poles of `G~` are the zeros of `H`: the eigenvalues of a state-space realisation of `H`
//!   closed around its feed-through (`A - B C/d`, balanced, real Schur form by nalgebra), each
//!   polished by Newton's method on `H` evaluated in factored form, plus the poles of `N_H` that
//!   `H` does not cancel (a free integrator, numerator cells).
//! - The residues are `r_i = N_H(lambda_i)/H'(lambda_i)`, with `H'` from the logarithmic
//!   derivative of the factored form. For a root within `NEAR_CELL_POLE` (relative) of a
//!   denominator cell pole `-p` (the slow modes, and near-cancelling pole-zero pairs) both the
//!   last Newton step and the residue go through `F(s) = H(s)(s + p)`, which has no pole there:
//!   `lambda = s0 - F/F'`, `r = N_H(lambda)(lambda + p)/F'(lambda)`. On `H` itself the value and
//!   the dual part are differences of nearly equal numbers (`lambda + p`, `d lambda + d p`)
//!   divided by their square or cube, and the residues' derivatives came out wrong by orders of
//!   magnitude (then so did the weight `-r/lambda` of a slow mode in a free response).
//! - Everything after the (value-only) eigenvalue problem is generic over [`Real`]: one last
//!   Newton step in dual arithmetic from the converged root gives the exact derivative of each pole
//!   (`d lambda = -dH/H'`, the implicit function theorem), and the residues follow.
//!
//! The expansion is checked by evaluating both forms at test frequencies.

use crate::approx::{approximate, ApproxSpec, Rational};
use crate::cx::Cx;
use crate::error::{finite, invalid, Error, Result};
use crate::scalar::Real;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Terms that share the same cells: `sum_k coef[k] s^-k prod (s + z)/(s + p)`.
#[derive(Debug, Clone)]
struct Group<T> {
    zeros: Vec<T>,
    poles: Vec<T>,
    coef: Vec<T>,
}

impl<T: Real> Group<T> {
    fn same_cells(&self, zeros: &[T], poles: &[T]) -> bool {
        self.zeros.len() == zeros.len()
            && self.zeros.iter().zip(zeros).all(|(a, b)| a.re() == b.re())
            && self.poles.iter().zip(poles).all(|(a, b)| a.re() == b.re())
    }

    fn same_as(&self, o: &Self) -> bool {
        self.same_cells(&o.zeros, &o.poles)
    }

    /// The group's value and its derivative with respect to `s`, at `s != 0`.
    fn eval(&self, s: Cx<T>) -> (Cx<T>, Cx<T>) {
        self.eval_without(s, None)
    }

    /// [`Group::eval`] with cell `skip` (its `(s + z)/(s + p)`) left out: the rest of the cells
    /// `R(s)` times `P(1/s)`, and the `s`-derivative (`R'` by the logarithmic derivative).
    fn eval_without(&self, s: Cx<T>, skip: Option<usize>) -> (Cx<T>, Cx<T>) {
        if s.im == T::from(0.0) {
            // On the real axis (most poles are real): real arithmetic, a quarter of the work.
            let (v, d) = self.eval_without_real(s.re, skip);
            return (Cx::real(v), Cx::real(d));
        }
        let zero = Cx::real(T::from(0.0));
        let mut cells = Cx::real(T::from(1.0));
        let mut logd = zero;
        for (l, (&z, &p)) in self.zeros.iter().zip(&self.poles).enumerate() {
            if skip == Some(l) {
                continue;
            }
            let a = s + Cx::real(z);
            let rb = (s + Cx::real(p)).recip();
            cells = cells * a * rb;
            logd += a.recip() - rb;
        }
        // P(x) = sum_k c_k x^k at x = 1/s, and P'(x) (Horner).
        let x = s.recip();
        let (mut p, mut dp) = (zero, zero);
        for &c in self.coef.iter().rev() {
            dp = dp * x + p;
            p = p * x + Cx::real(c);
        }
        // d/ds P(1/s) = -P'(x) x^2
        let dps = -(dp * x * x);
        (cells * p, cells * (logd * p + dps))
    }

    /// [`Group::eval_without`] at a real `s` (every part of its imaginary part zero).
    fn eval_without_real(&self, s: T, skip: Option<usize>) -> (T, T) {
        let one = T::from(1.0);
        let (mut cells, mut logd) = (one, T::from(0.0));
        for (l, (&z, &p)) in self.zeros.iter().zip(&self.poles).enumerate() {
            if skip == Some(l) {
                continue;
            }
            let a = s + z;
            let rb = one / (s + p);
            cells = cells * a * rb;
            logd += one / a - rb;
        }
        let x = one / s;
        let (mut p, mut dp) = (T::from(0.0), T::from(0.0));
        for &c in self.coef.iter().rev() {
            dp = dp * x + p;
            p = p * x + c;
        }
        let dps = -(dp * x * x);
        (cells * p, cells * (logd * p + dps))
    }

    /// The group times `(s + p)`, `G(s)(s + p)`, and its derivative with respect to `s`, at
    /// `s != 0`. When `p` is one of the group's own cell poles that cell's `1/(s + p)` is never
    /// formed: the value is `(s + z_i) R(s) P(1/s)` with `R` the other cells, and the derivative
    /// `R P + (s + z_i) (R P)'` (`R'` by the logarithmic derivative), so nothing is divided by the
    /// small `s + p` or `s + z_i` near a nearly cancelling cell. Otherwise
    /// `(G(s + p))' = G'(s + p) + G`.
    fn eval_times(&self, s: Cx<T>, p: T) -> (Cx<T>, Cx<T>) {
        let own = self.poles.iter().position(|q| q.re() == p.re());
        // The rest (R P) and its derivative, times the factor m = s + z_i or s + p.
        let (g, dg) = self.eval_without(s, own);
        let m = s + Cx::real(own.map_or(p, |i| self.zeros[i]));
        (g * m, dg * m + g)
    }

    /// `prod (s + z)/(s + p)` at `s = 0`.
    fn cells_at_zero(&self) -> T {
        let mut v = T::from(1.0);
        for (&z, &p) in self.zeros.iter().zip(&self.poles) {
            v = v * z / p;
        }
        v
    }

    /// The residue of `prod (s + z)/(s + p)` at its pole `-p_i`:
    /// `(z_i - p_i) prod_(l != i) (z_l - p_i)/(p_l - p_i)`.
    fn cell_residue(&self, i: usize) -> T {
        let pi = self.poles[i];
        let mut r = self.zeros[i] - pi;
        for (l, (&z, &p)) in self.zeros.iter().zip(&self.poles).enumerate() {
            if l != i {
                r = r * (z - pi) / (p - pi);
            }
        }
        r
    }
}

/// A sum of groups, evaluated with its `s`-derivative.
fn eval_sum<T: Real>(groups: &[Group<T>], s: Cx<T>) -> (Cx<T>, Cx<T>) {
    eval_sum_times(groups, s, None)
}

/// [`eval_sum`], times `(s + p)` when `times` is `Some(p)` ([`Group::eval_times`]):
/// `(sum_g G_g(s)) (s + p)` and its `s`-derivative.
fn eval_sum_times<T: Real>(groups: &[Group<T>], s: Cx<T>, times: Option<T>) -> (Cx<T>, Cx<T>) {
    let zero = Cx::real(T::from(0.0));
    groups.iter().fold((zero, zero), |(v, d), g| {
        let (gv, gd) = match times {
            Some(p) => g.eval_times(s, p),
            None => g.eval(s),
        };
        (v + gv, d + gd)
    })
}

/// A root this close (relative) to a denominator cell pole `-p` has its dual Newton step and its
/// residue computed through `F(s) = H(s)(s + p)`, which has no pole there (see [`pole_residue`]).
const NEAR_CELL_POLE: f64 = 1e-3;

/// The continuous approximated model `direct + sum r/(s - lambda)`: real poles, and complex poles
/// of positive imaginary part (each standing for its conjugate pair: `2 Re(r/(s - lambda))` on
/// the real axis).
#[derive(Debug, Clone)]
pub struct PoleResidue<T> {
    /// Real poles `(lambda, r)`, rad/s.
    pub real: Vec<(T, T)>,
    /// Complex poles with positive imaginary part `(lambda, r)`, each with its conjugate.
    pub complex: Vec<(Cx<T>, Cx<T>)>,
    /// The feed-through `G~(infinity)`.
    pub direct: T,
    /// Whether the model before approximation is strictly proper (its numerator's highest order
    /// below its denominator's): its feed-through is then the approximation's alone, the cells
    /// above the band's upper edge (responses faster than `1/w_h`), and the exact model's
    /// output does not jump when the input does. `K/(a s^0.3 + 1)` approximated keeps
    /// about `K/(a w_h^0.3 + 1)` (the refined method's correction aside), a twentieth of `K` on
    /// the default band at `a` near 1.7 and a 0.09 s step, as a feed-through. A sampled
    /// run ([`crate::Simulator`], [`crate::export::discrete`]) feeds such a feed-through the
    /// input just before the sample instant, `u(t_k^-)`, as the exact model's output at `t_k`
    /// sees it: the cells have settled to `u_(k-1)` and not yet moved with `u_k`.
    pub strictly_proper: bool,
}

impl<T: Real> PoleResidue<T> {
    /// The model with its frequency axis scaled by `c`: `G~(s/c) = direct + sum c r_i/(s - c
    /// lambda_i)`, the poles and residues times `c`, the feed-through unchanged. For a model
    /// approximated over a band, this is the frequency-scaled system (each coefficient
    /// `a s^alpha` of the original times `c^-alpha`) approximated with its cells at `c` times the
    /// original's: no eigenvalue problem.
    ///
    /// ```
    /// use fracsim::{modal::pole_residue, ApproxSpec};
    /// // 1/(0.1 s + 1) scaled by 2 is 1/(0.05 s + 1): the pole -20 with residue 20.
    /// let pr = pole_residue::<f64>(&[(1.0, 0.0)], &[(0.1, 1.0), (1.0, 0.0)], (1e-3, 1e4),
    ///                              &ApproxSpec::default()).unwrap();
    /// let fast = pr.frequency_scaled(2.0).unwrap();
    /// assert!((fast.real[0].0 + 20.0).abs() < 1e-12 && (fast.real[0].1 - 20.0).abs() < 1e-12);
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] when `c` is not positive and finite.
    pub fn frequency_scaled(&self, c: f64) -> Result<Self> {
        if !(c > 0.0 && c.is_finite()) {
            return invalid(
                "frequency scale",
                format!("{c} must be positive and finite"),
            );
        }
        let k = T::from(c);
        Ok(Self {
            real: self.real.iter().map(|&(l, r)| (l * k, r * k)).collect(),
            complex: self
                .complex
                .iter()
                .map(|&(l, r)| (l.scale(k), r.scale(k)))
                .collect(),
            direct: self.direct,
            strictly_proper: self.strictly_proper,
        })
    }

    /// No pole and no feed-through (an expansion being built).
    fn empty() -> Self {
        Self {
            real: vec![],
            complex: vec![],
            direct: T::from(0.0),
            strictly_proper: false,
        }
    }

    /// The frequency response at `omega` rad/s (values only).
    pub fn freq_response(&self, omega: f64) -> Complex64 {
        let s = Complex64::new(0.0, omega);
        let mut h = Complex64::new(self.direct.re(), 0.0);
        for &(l, r) in &self.real {
            h += r.re() / (s - l.re());
        }
        for &(l, r) in &self.complex {
            let (l, r) = (l.val(), r.val());
            h += r / (s - l) + r.conj() / (s - l.conj());
        }
        h
    }

    /// The number of states (a complex pair counts two).
    pub fn order(&self) -> usize {
        self.real.len() + 2 * self.complex.len()
    }

    /// The value `direct + sum r/(s - lambda)` (each complex pole with its conjugate) at any `s`
    /// that is no pole.
    pub fn eval(&self, s: Cx<T>) -> Cx<T> {
        let mut h = Cx::real(self.direct);
        for &(l, r) in &self.real {
            h += (s - Cx::real(l)).recip().scale(r);
        }
        for &(l, r) in &self.complex {
            let (lc, rc) = (Cx::new(l.re, -l.im), Cx::new(r.re, -r.im));
            h += r * (s - l).recip() + rc * (s - lc).recip();
        }
        h
    }

    /// The series connection `self(s) other(s)` in the same form: every pole of each factor, with
    /// its residue times the other factor's value there (`r_i B(lambda_i)`, simple poles), and the
    /// feed-through the product of the two. Exact for the two approximated models; what a model
    /// whose denominator is a product multiplied out (a two-mass drive train's nine terms, whose
    /// poles crowd too many cells for one eigenvalue problem) is simulated with.
    ///
    /// ```
    /// use fracsim::{modal::pole_residue, ApproxSpec};
    /// let spec = ApproxSpec::default();
    /// let a = pole_residue::<f64>(&[(2.0, 0.0)], &[(0.1, 1.0), (1.0, 0.0)], (1e-3, 1e4), &spec).unwrap();
    /// let b = pole_residue::<f64>(&[(1.0, 0.0)], &[(0.01, 1.0), (1.0, 0.0)], (1e-3, 1e4), &spec).unwrap();
    /// let ab = a.product(&b).unwrap();
    /// let w = 30.0;
    /// assert!((ab.freq_response(w) - a.freq_response(w) * b.freq_response(w)).norm() < 1e-12);
    /// ```
    ///
    /// # Errors
    /// [`Error::Numerical`] when the factors share a pole (within `1e-9` relative): the product
    /// would have a double pole.
    pub fn product(&self, other: &Self) -> Result<Self> {
        let poles = |m: &Self| -> Vec<Complex64> {
            m.real
                .iter()
                .map(|&(l, _)| Complex64::new(l.re(), 0.0))
                .chain(m.complex.iter().map(|&(l, _)| l.val()))
                .collect()
        };
        let (pa, pb) = (poles(self), poles(other));
        if pa.iter().any(|x| {
            pb.iter()
                .any(|y| (x - y).norm() <= 1e-9 * x.norm().max(y.norm()))
        }) {
            return Err(Error::Numerical(
                "the factors of a product share a pole (a double pole)".into(),
            ));
        }
        let mut out = PoleResidue {
            real: vec![],
            complex: vec![],
            direct: self.direct * other.direct,
            // A strictly proper factor makes the product strictly proper.
            strictly_proper: self.strictly_proper || other.strictly_proper,
        };
        for (x, y) in [(self, other), (other, self)] {
            for &(l, r) in &x.real {
                out.real.push((l, r * y.eval(Cx::real(l)).re));
            }
            for &(l, r) in &x.complex {
                out.complex.push((l, r * y.eval(l)));
            }
        }
        Ok(out)
    }
}

/// The approximation of one term's operator, with cells that cancel exactly (an integer order)
/// removed.
fn operator<T: Real>(order: T, band: (f64, f64), spec: &ApproxSpec) -> Result<Rational<T>> {
    if order.re() == 0.0 {
        return Ok(Rational {
            int_order: 0,
            gain: T::from(1.0),
            zeros: vec![],
            poles: vec![],
        });
    }
    let mut r = approximate(order, band, spec)?;
    let keep: Vec<bool> = r
        .zeros
        .iter()
        .zip(&r.poles)
        .map(|(z, p)| z.re() != p.re())
        .collect();
    let mut it = keep.iter();
    r.zeros.retain(|_| *it.next().unwrap_or(&true));
    let mut it = keep.iter();
    r.poles.retain(|_| *it.next().unwrap_or(&true));
    Ok(r)
}

/// Collect terms into groups: each term `c s^(n - n_max) R` adds `c g` to `coef[n_max - n]` of the
/// group with its cells.
fn groups<T: Real>(terms: &[(T, Rational<T>)], n_max: i32) -> Vec<Group<T>> {
    let mut out: Vec<Group<T>> = vec![];
    for (c, r) in terms {
        let k = (n_max - r.int_order) as usize;
        let gi = match out.iter().position(|g| g.same_cells(&r.zeros, &r.poles)) {
            Some(i) => i,
            None => {
                out.push(Group {
                    zeros: r.zeros.clone(),
                    poles: r.poles.clone(),
                    coef: vec![],
                });
                out.len() - 1
            }
        };
        let g = &mut out[gi];
        if g.coef.len() <= k {
            g.coef.resize(k + 1, T::from(0.0));
        }
        g.coef[k] += *c * r.gain;
    }
    out
}

/// The zeros of `H` (values) from its partial fractions
/// `H(s) = d + sum_k h_k/(s + p_k) + e_1/s + e_2/s^2`: the closed realisation `A - B C/d` is
/// diagonal plus rank one (with a Jordan block at 0), whose eigenvalues are well conditioned even
/// where they crowd the cell poles. `None` when the partial fractions do not apply (more than two
/// powers of `1/s`, repeated cell poles).
fn zeros_of_h_modal(groups: &[Group<f64>], d: f64) -> Option<Vec<Complex64>> {
    let k_max = groups.iter().map(|g| g.coef.len()).max().unwrap_or(1) - 1;
    if k_max > 2 {
        return None;
    }
    let mut poles = vec![];
    let mut h = vec![];
    let (mut e1, mut e2) = (0.0, 0.0);
    for g in groups {
        for k in 0..g.poles.len() {
            let x = -1.0 / g.poles[k];
            let pv = g.coef.iter().rev().fold(0.0, |acc, &c| acc * x + c);
            poles.push(-g.poles[k]);
            h.push(pv * g.cell_residue(k));
        }
        let c0 = g.cells_at_zero();
        // d/ds prod (s+z)/(s+p) at 0 = sum_k (p_k - z_k)/p_k^2 prod_(l != k) z_l/p_l
        let dc0: f64 = (0..g.poles.len())
            .map(|k| {
                let mut t = (g.poles[k] - g.zeros[k]) / (g.poles[k] * g.poles[k]);
                for l in (0..g.poles.len()).filter(|&l| l != k) {
                    t *= g.zeros[l] / g.poles[l];
                }
                t
            })
            .sum();
        let c = |k: usize| g.coef.get(k).copied().unwrap_or(0.0);
        e1 += c(1) * c0 + c(2) * dc0;
        e2 += c(2) * c0;
    }
    if h.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let n = poles.len() + k_max;
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DVector::<f64>::zeros(n);
    let mut c = DVector::<f64>::zeros(n);
    for (i, (&p, &hk)) in poles.iter().zip(&h).enumerate() {
        a[(i, i)] = p;
        b[i] = 1.0;
        c[i] = hk;
    }
    let m = poles.len();
    match k_max {
        1 => {
            b[m] = 1.0;
            c[m] = e1;
        }
        2 => {
            // xi1' = xi2, xi2' = y: xi1 = y/s^2, xi2 = y/s
            a[(m, m + 1)] = 1.0;
            b[m + 1] = 1.0;
            c[m] = e2;
            c[m + 1] = e1;
        }
        _ => {}
    }
    eigenvalues(a - (&b * c.transpose()) / d).ok()
}

/// The eigenvalues of `m` after balancing (the QR iteration without Schur vectors, [`crate::eig`]).
fn eigenvalues(mut m: DMatrix<f64>) -> Result<Vec<Complex64>> {
    if m.nrows() == 0 {
        return Ok(vec![]);
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical(
            "the approximated model's state space is not finite".into(),
        ));
    }
    let n = m.nrows();
    nalgebra::linalg::balancing::balance_parlett_reinsch(&mut m);
    crate::eig::eigenvalues_only(m, 100 * n).ok_or_else(|| {
        Error::Numerical("the eigenvalues of the approximated model did not converge".into())
    })
}

/// The zeros of `H` (values): eigenvalues of the closed realisation `A - B C/d`.
fn zeros_of_h(groups: &[Group<f64>], d: f64) -> Result<Vec<Complex64>> {
    let k_max = groups.iter().map(|g| g.coef.len()).max().unwrap_or(1) - 1;
    let n_cells: usize = groups.iter().map(|g| g.zeros.len()).sum();
    let n = n_cells + k_max;
    if n == 0 {
        return Ok(vec![]);
    }
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DVector::<f64>::zeros(n);
    let mut c = DVector::<f64>::zeros(n);
    let mut off = 0;
    for g in groups {
        let m = g.zeros.len();
        // Cascade of cells driven by y: x_i' = -p_i x_i + v_(i-1), v_i = v_(i-1) + (z_i - p_i) x_i.
        for i in 0..m {
            a[(off + i, off + i)] = -g.poles[i];
            for l in 0..i {
                a[(off + i, off + l)] = g.zeros[l] - g.poles[l];
            }
            b[off + i] = 1.0;
        }
        // The group's output w = y + sum (z_l - p_l) x_l enters P(1/s): coef[0] the output,
        // coef[k] the k-th integrator.
        for (k, &ck) in g.coef.iter().enumerate() {
            if k == 0 {
                for l in 0..m {
                    c[off + l] += ck * (g.zeros[l] - g.poles[l]);
                }
            } else {
                let row = n_cells + k - 1;
                for l in 0..m {
                    a[(row, off + l)] += ck * (g.zeros[l] - g.poles[l]);
                }
                b[row] += ck;
            }
        }
        off += m;
    }
    for k in 1..k_max {
        a[(n_cells + k - 1, n_cells + k)] = 1.0;
    }
    if k_max >= 1 {
        c[n_cells] = 1.0;
    }
    eigenvalues(a - (&b * c.transpose()) / d)
}

/// Newton's method for a zero of `H` from `s0` (values only), deflated by the roots `found`
/// already (Maehly); `None` if it does not converge.
///
/// The iteration runs on `F(s) = H(s) prod_k (s + p_k) c_k` over every cell of the denominator
/// (`c_k = 1/(|s0| + p_k)`, a constant scale), which has the zeros of `H` but not its poles: the slow
/// zeros sit a hair away from cell poles, where Newton on `H` itself jumps across the pole.
fn polish(groups: &[Group<f64>], s0: Complex64, found: &[Complex64]) -> Option<Complex64> {
    // The scales c_k, once per call (not per cell, group and iteration).
    let norm0 = s0.norm();
    let scales: Vec<Vec<f64>> = groups
        .iter()
        .map(|h| h.poles.iter().map(|&p| 1.0 / (norm0 + p)).collect())
        .collect();
    let mut work = (
        vec![[0.0; 4]; groups.len()],
        vec![[Complex64::new(0.0, 0.0); 4]; groups.len()],
    );
    let mut s = s0;
    // A real root's iterates stay on the real axis: real arithmetic there (most roots are real).
    type Work = (Vec<[f64; 4]>, Vec<[Complex64; 4]>);
    let f_and_df = |s: Complex64, work: &mut Work| -> (Complex64, Complex64) {
        if s.im == 0.0 {
            let (f, df) = f_and_df_of(groups, &scales, s.re, &mut work.0);
            (Complex64::new(f, 0.0), Complex64::new(df, 0.0))
        } else {
            f_and_df_of(groups, &scales, s, &mut work.1)
        }
    };
    for _ in 0..60 {
        let (f, df) = f_and_df(s, &mut work);
        // Maehly's deflation: the roots found already repel the iteration.
        let defl: Complex64 = found.iter().map(|r| 1.0 / (s - r)).sum();
        let q = f / df;
        let step = q / (1.0 - q * defl);
        if !(step.re.is_finite() && step.im.is_finite()) {
            return None;
        }
        s -= step;
        if step.norm() <= 4.0 * f64::EPSILON * s.norm() {
            return Some(s);
        }
    }
    // Accept a root that stalls within rounding of F.
    let (f, df) = f_and_df(s, &mut work);
    (f.norm() <= 1e-10 * (df * s).norm().max(1e-300)).then_some(s)
}

/// The arithmetic [`f_and_df_of`] runs in: `f64` on the real axis, `Complex64` off it.
trait Field:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + From<f64>
{
}
impl Field for f64 {}
impl Field for Complex64 {}

/// `F(s) = sum_g P_g(1/s) prod_(k in g) (s + z_k) c_k prod_(k not in g) (s + p_k) c_k` and its
/// `s`-derivative ([`polish`]'s function), in `O(cells)`: each group's products and logarithmic
/// derivatives over its own zeros and poles (`work[g]`: `prod (s + z) c`, `prod (s + p) c`,
/// `sum 1/(s + z)`, `sum 1/(s + p)`), then each term from its own zeros and the other groups' poles.
fn f_and_df_of<C: Field>(
    groups: &[Group<f64>],
    scales: &[Vec<f64>],
    s: C,
    work: &mut [[C; 4]],
) -> (C, C) {
    let (zero, one) = (C::from(0.0), C::from(1.0));
    for ((g, sc), w) in groups.iter().zip(scales).zip(work.iter_mut()) {
        let (mut pz, mut pp, mut lz, mut lp) = (one, one, zero, zero);
        for ((&z, &p), &c) in g.zeros.iter().zip(&g.poles).zip(sc) {
            let a = s + C::from(z);
            let b = s + C::from(p);
            pz = pz * (a * C::from(c));
            pp = pp * (b * C::from(c));
            lz = lz + one / a;
            lp = lp + one / b;
        }
        *w = [pz, pp, lz, lp];
    }
    let x = one / s;
    let (mut f, mut df) = (zero, zero);
    for (gi, g) in groups.iter().enumerate() {
        let (mut t, mut logd) = (work[gi][0], work[gi][2]);
        for (hi, w) in work.iter().enumerate() {
            if hi != gi {
                t = t * w[1];
                logd = logd + w[3];
            }
        }
        let (mut pv, mut dp) = (zero, zero);
        for &c in g.coef.iter().rev() {
            dp = dp * x + pv;
            pv = pv * x + C::from(c);
        }
        let dps = -(dp * x * x);
        f = f + t * pv;
        df = df + t * (logd * pv + dps);
    }
    (f, df)
}

/// Add root `r` of `H` to `roots` (real when its imaginary part is within rounding of zero), and
/// for a complex root its conjugate, a root too.
fn push_root(roots: &mut Vec<Complex64>, mut r: Complex64) {
    if r.im.abs() <= 1e-12 * r.norm() {
        r.im = 0.0;
    }
    roots.push(r);
    if r.im != 0.0 {
        roots.push(r.conj());
    }
}

/// Every zero of `H` (values), each polished by [`polish`]. Newton starts from the eigenvalues of
/// the realisation and from every cell pole: the slow zeros sit a hair away from cell poles, where
/// the eigenvalues of the (non-normal) realisation are too coarse to tell neighbours apart. The
/// distinct roots must number the states of the realisation. Returns the roots and whether they
/// came from the hint (every root found by plain Newton from it), not from the eigenvalues.
fn roots_of_h(groups: &[Group<f64>], d: f64, hint: &[Complex64]) -> Result<(Vec<Complex64>, bool)> {
    let k_max = groups.iter().map(|g| g.coef.len()).max().unwrap_or(1) - 1;
    let n_states: usize = groups.iter().map(|g| g.zeros.len()).sum::<usize>() + k_max;
    let tol = |r: Complex64| 1e-12 * r.norm().max(1e-300);
    let is_new =
        |r: Complex64, roots: &[Complex64]| !roots.iter().any(|q| (q - r).norm() <= tol(r));
    let mut roots: Vec<Complex64> = vec![];
    // The roots of a nearby `H` first: when plain Newton from them finds every root (distinct
    // roots numbering the states are all of them), the eigenvalue problem is not needed.
    if !hint.is_empty() {
        for &e in hint.iter().filter(|e| e.im >= 0.0) {
            let Some(r) = polish(groups, e, &[]) else {
                break;
            };
            if !is_new(r, &roots) {
                break;
            }
            push_root(&mut roots, r);
        }
        if roots.len() == n_states {
            return Ok((roots, true));
        }
        roots.clear();
    }
    let eig = match zeros_of_h_modal(groups, d) {
        Some(z) => z,
        None => zeros_of_h(groups, d)?,
    };
    // Starts in rounds, used only while roots are missing: the eigenvalues; a hair off every
    // cell pole (`F` is smooth there, its log-derivative is not at the pole); the cell zeros (where
    // a pole and a zero nearly cancel, an order close to an integer, a root can hide between them).
    let rounds: [Vec<Complex64>; 3] = [
        // one of each conjugate pair: the other is added with its root
        eig.iter().copied().filter(|e| e.im >= 0.0).collect(),
        groups
            .iter()
            .flat_map(|g| {
                g.poles
                    .iter()
                    .map(|&p| Complex64::new(-p * (1.0 + 1e-10), 0.0))
            })
            .collect(),
        groups
            .iter()
            .flat_map(|g| {
                g.zeros
                    .iter()
                    .map(|&z| Complex64::new(-z * (1.0 + 1e-10), 0.0))
            })
            .collect(),
    ];
    for &e in rounds.iter().flatten() {
        if roots.len() >= n_states {
            break;
        }
        // Plain Newton first; from a start that leads to a known root, Newton deflated by the
        // known roots, then plain Newton again from there for full accuracy.
        let r = match polish(groups, e, &[]) {
            Some(r) if is_new(r, &roots) => Some(r),
            _ => polish(groups, e, &roots)
                .and_then(|r| polish(groups, r, &[]))
                .filter(|&r| is_new(r, &roots)),
        };
        let Some(r) = r else {
            continue;
        };
        push_root(&mut roots, r);
    }
    // A root that Newton cannot settle a hair from a cell pole is half of a pole-zero pair of
    // `G~` that cancels to rounding (an order within a few ppm of an integer): its mode carries no
    // weight and is left out; the check of the expansion judges the result.
    let cell_poles: Vec<f64> = groups
        .iter()
        .flat_map(|g| g.poles.iter().copied())
        .collect();
    let mut cancelled = 0;
    for &e in &eig {
        if roots.len() + cancelled < n_states
            && !roots
                .iter()
                .any(|q| (q - e).norm() <= 1e-6 * e.norm().max(1e-300))
            && cell_poles
                .iter()
                .any(|&p| (e.re + p).abs() + e.im.abs() <= 1e-6 * p)
        {
            cancelled += 1;
        }
    }
    if roots.len() + cancelled != n_states {
        return Err(Error::Numerical(format!(
            "found {} of the {n_states} poles of the approximated model (repeated or clustered \
             poles?)",
            roots.len()
        )));
    }
    Ok((roots, false))
}

/// The root sets of the last few `H` one computation solved, each with the values it solved
/// (`d`, then each group's cells and coefficients; the group sizes alongside). A fit builds the
/// model at nearby parameters again and again (each trial, then each part of its Jacobian in
/// dual numbers), and the eigenvalue problem of [`roots_of_h`] is most of the cost of a build:
/// the roots of the nearest `H` solved before start Newton's method instead, and the same `H`
/// again is answered at once.
///
/// A cache is a value its computation owns (a request, a fit) and enters on its thread
/// ([`RootsCache::enter`]): the models built inside use it and leave their roots in it; outside
/// of any, a model is built cold and nothing is kept, so that what a computation gives never
/// depends on what ran before it on the same thread. Its hints move the last bits of a result,
/// so a helper thread that shares a computation's work starts from a copy of its cache
/// ([`RootsCache::entered`]) and computes what the calling thread would.
///
/// ```
/// use fracsim::{modal::{pole_residue, RootsCache}, ApproxSpec};
/// let build = || pole_residue::<f64>(&[(1.0, 0.0)], &[(0.1, 0.9), (1.0, 0.0)], (1e-3, 1e4),
///                                    &ApproxSpec::default()).unwrap();
/// let mut cache = RootsCache::new();
/// assert!(cache.is_empty());
/// let (a, b) = cache.enter(|| (build(), build()));
/// assert!(!cache.is_empty());
/// assert_eq!(format!("{:?}", a.real), format!("{:?}", b.real));
/// ```
#[derive(Debug, Clone, Default)]
pub struct RootsCache(Vec<Solved>);

thread_local! {
    /// The cache entered on this thread ([`RootsCache::enter`]), `None` outside of one.
    static ENTERED: std::cell::RefCell<Option<Vec<Solved>>> =
        const { std::cell::RefCell::new(None) };
}

#[cfg(test)]
thread_local! {
    /// How many builds on this thread used a hinted root set (tests only).
    static HINTED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

impl RootsCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether it holds no root set.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Run `f` with this cache answering the pole solves of the models `f` builds on the calling
    /// thread (and keeping theirs), then hold what it ended with, whether `f` returns or
    /// unwinds. Entered inside another cache's `enter`, it stands for that one during `f`, which
    /// is restored after.
    pub fn enter<R>(&mut self, f: impl FnOnce() -> R) -> R {
        /// Takes the entered cache back into `cache` and restores the one it stood for.
        struct Leave<'a> {
            cache: &'a mut RootsCache,
            outer: Option<Vec<Solved>>,
        }
        impl Drop for Leave<'_> {
            fn drop(&mut self) {
                let mine = ENTERED.with(|e| e.replace(self.outer.take()));
                self.cache.0 = mine.unwrap_or_default();
            }
        }
        let outer = ENTERED.with(|e| e.replace(Some(std::mem::take(&mut self.0))));
        let _leave = Leave { cache: self, outer };
        f()
    }

    /// A copy of the cache entered on the calling thread (empty outside of one), for a helper
    /// thread that shares its computation's work to enter: it then builds each model from the
    /// same poles as the calling thread would, and what is computed does not depend on which
    /// thread computes it.
    pub fn entered() -> Self {
        Self(ENTERED.with(|e| e.borrow().clone().unwrap_or_default()))
    }

    /// Run `f` from an empty cache: the cache entered on the calling thread, emptied (what `f`
    /// leaves in it stays for the rest of its computation), or outside of one a new cache
    /// entered for `f` alone. A computation that starts so (an identification) gives the same
    /// result wherever it runs.
    pub fn afresh<R>(f: impl FnOnce() -> R) -> R {
        let inside = ENTERED.with(|e| match e.borrow_mut().as_mut() {
            Some(c) => {
                c.clear();
                true
            }
            None => false,
        });
        if inside {
            f()
        } else {
            Self::new().enter(f)
        }
    }
}

/// One entry of a [`RootsCache`]: the sizes, the values and the roots.
type Solved = (Vec<usize>, Vec<f64>, Vec<Complex64>);

/// How many root sets a [`RootsCache`] keeps.
const ROOTS_KEPT: usize = 8;

/// The largest relative change of any value for which a solved `H`'s roots start Newton's
/// method ([`roots_of_h`]'s hint); the same `H` again is answered at once. A hinted root set is
/// used only when plain Newton from the hint finds every root and the expansion built on it
/// passes its check; otherwise the roots are found cold, from the eigenvalues (see
/// [`pole_residue`]). An LM step of the 3k PMSM fit changes a denominator coefficient by
/// 10-25%: at 0.05 each such step was a cold build of 39 states, at 0.3 two of the three are
/// found from the hint (the third fails at its first root, which costs a few Newton steps). The
/// coarse start's trials (a coefficient 1.4-1.9x apart) stay cold: beyond 0.3 most of their
/// hints fail after part of the polishing, and the work is lost.
const HINT_DISTANCE: f64 = 0.3;

/// The largest relative change of any value for which a solved `H`'s roots are taken as they
/// are by [`roots_of_h_cached`] (measured: a Jacobian's dual build differs from the value build
/// at the same parameters by 1e-16 to 3e-15; an LM step changes values by 1e-5 or more).
const SAME_H: f64 = 1e-13;

/// How [`roots_of_h_cached`] may answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lookup {
    /// From the cache: the same `H`, or the roots of a nearby one as the hint.
    Cached,
    /// Cold: from the eigenvalues, whatever the cache holds; the result replaces the cache's
    /// entry for this `H` (a hinted root set that failed the expansion check).
    Cold,
}

/// [`roots_of_h`] with the roots of the nearest `H` in the entered [`RootsCache`] as its hint. Returns the roots
/// and whether they came from a nearby `H`'s (not the same `H` again, not cold).
fn roots_of_h_cached(
    groups: &[Group<f64>],
    d: f64,
    lookup: Lookup,
) -> Result<(Vec<Complex64>, bool)> {
    let sizes: Vec<usize> = groups
        .iter()
        .flat_map(|g| [g.zeros.len(), g.coef.len()])
        .collect();
    let mut values = vec![d];
    for g in groups {
        values.extend(g.zeros.iter().chain(&g.poles).chain(&g.coef));
    }
    let distance = |other: &[f64]| -> f64 {
        values
            .iter()
            .zip(other)
            .map(|(a, b)| {
                let scale = a.abs().max(b.abs());
                if scale == 0.0 {
                    0.0
                } else {
                    (a - b).abs() / scale
                }
            })
            .fold(0.0, f64::max)
    };
    let nearest = match lookup {
        Lookup::Cold => None,
        Lookup::Cached => ENTERED.with(|c| {
            c.borrow().as_ref().and_then(|cache| {
                cache
                    .iter()
                    .filter(|(s, _, _)| *s == sizes)
                    .map(|(_, v, r)| (distance(v), r.clone()))
                    .min_by(|a, b| a.0.total_cmp(&b.0))
            })
        }),
    };
    let (roots, hinted) = match nearest {
        Some((0.0, r)) => return Ok((r, false)),
        // The same `H` to rounding (a dual model's values, computed through its derivative
        // parts, a few ulps from the plain model's just solved): its roots as they are (the
        // expansion takes one Newton step from each in any case), counted as hinted (a failed
        // expansion check solves cold), and cached for these values as a solved root set is
        // (which entries the cache keeps decides the next builds' hints).
        Some((dist, r)) if dist <= SAME_H => (r, true),
        Some((dist, r)) if dist <= HINT_DISTANCE => roots_of_h(groups, d, &r)?,
        _ => roots_of_h(groups, d, &[])?,
    };
    ENTERED.with(|c| {
        if let Some(cache) = c.borrow_mut().as_mut() {
            cache.retain(|(s, v, _)| !(*s == sizes && *v == values));
            if cache.len() >= ROOTS_KEPT {
                cache.remove(0);
            }
            cache.push((sizes, values, roots.clone()));
        }
    });
    Ok((roots, hinted))
}

/// A denominator whose highest-order terms sum to under 1e-13 of the sum of its terms' sizes is
/// refused as improper by [`pole_residue`] (its top terms cancel, or are so small that a fit is
/// kept away from them rather than led to drop them) unless, weighed at the band's upper edge
/// `w_h` (each term `|c| w_h^(n - n_max)`), they are at least this fraction of the denominator:
/// its top pole then lies within `w_h / VANISHING` (a thousand times the band's edge), a pole of
/// the model rather than a term that stands for nothing. The first test alone depends on the
/// time unit: a fifth order in seconds (`2e-14 s^5` beside `1`, five poles of a few thousand
/// rad/s) failed it.
pub const VANISHING: f64 = 1e-3;

/// Denominator terms under this fraction of the denominator's scale stand for zero (a
/// coefficient at the floor of a positive parameter's range, 1e-300) and are left out by
/// [`pole_residue`].
pub const NOTHING: f64 = 1e-200;

/// The pole-residue form of `sum b_i s^beta_i / sum a_j s^alpha_j` with every operator approximated
/// as `spec` says over `band` (rad/s).
///
/// ```
/// use fracsim::{modal::pole_residue, ApproxSpec};
/// // 1/(0.1 s + 1): one real pole at -10 with residue 10.
/// let pr = pole_residue::<f64>(&[(1.0, 0.0)], &[(0.1, 1.0), (1.0, 0.0)], (1e-3, 1e4),
///                              &ApproxSpec::default()).unwrap();
/// assert_eq!(pr.real.len(), 1);
/// assert!((pr.real[0].0 + 10.0).abs() < 1e-12 && (pr.real[0].1 - 10.0).abs() < 1e-12);
/// ```
///
/// # Errors
/// Non-finite terms, an all-zero denominator, an improper model (a numerator integer part above
/// the denominator's), a denominator that vanishes at high frequency (its highest-order terms
/// under 1e-13 of the denominator's scale, and under [`VANISHING`] of it with each term weighed
/// at the band's upper edge; terms under [`NOTHING`] of the scale are left out instead),
/// more than one free integrator, repeated poles, or an expansion that fails its check.
pub fn pole_residue<T: Real>(
    num: &[(T, T)],
    den: &[(T, T)],
    band: (f64, f64),
    spec: &ApproxSpec,
) -> Result<PoleResidue<T>> {
    let approx = |terms: &[(T, T)], what: &'static str| -> Result<Vec<(T, Rational<T>)>> {
        terms
            .iter()
            .filter(|(c, _)| c.re() != 0.0)
            .map(|&(c, o)| {
                finite(what, c.re())?;
                finite("order", o.re())?;
                Ok((c, operator(o, band, spec)?))
            })
            .collect()
    };
    let den_ops = approx(den, "denominator coefficient")?;
    let num_ops = approx(&shared_fractions(num, den), "numerator coefficient")?;
    let Some(n_max) = den_ops.iter().map(|(_, r)| r.int_order).max() else {
        return Err(Error::ZeroDenominator);
    };
    if let Some(n) = num_ops.iter().map(|(_, r)| r.int_order).max() {
        if n > n_max {
            return invalid(
                "model",
                "improper: the numerator's order exceeds the denominator's by an integer \
                 or more (it differentiates the input)",
            );
        }
    }
    let hg = groups(&den_ops, n_max);
    let ng = groups(&num_ops, n_max);
    let d = hg.iter().fold(T::from(0.0), |acc, g| acc + g.coef[0]);
    let scale: f64 = den_ops
        .iter()
        .map(|(c, r)| (c.re() * r.gain.re()).abs())
        .sum();
    // The same terms weighed at the band's upper edge (`|c| w_h^(n - n_max)`): a scale in the
    // model's own units, by which a denominator of high degree in seconds (`1e-14 s^5` beside
    // `1`, five poles of a few thousand rad/s) has a top term that matters.
    // Made only for a denominator the first test refuses (every model build passes here).
    let weighed = || -> f64 {
        let w_h = band.1.abs().max(f64::MIN_POSITIVE);
        den_ops
            .iter()
            .map(|(c, r)| (c.re() * r.gain.re()).abs() * w_h.powi(r.int_order - n_max))
            .sum()
    };
    if !(d.re().abs() > 1e-13 * scale) && !(d.re().abs() > VANISHING * weighed()) {
        let top = |r: &Rational<T>| r.int_order == n_max;
        let top_abs: f64 = den_ops
            .iter()
            .filter(|(_, r)| top(r))
            .map(|(c, r)| (c.re() * r.gain.re()).abs())
            .sum();
        if top_abs <= NOTHING * scale && den_ops.len() > 1 {
            // Terms that stand for zero (a coefficient at its range's floor, 1e-300): the model
            // is the one without them. A top term that is merely small still makes the model
            // improper here: the fit is kept away from it rather than led to drop it.
            let rest: Vec<(T, T)> = den
                .iter()
                .filter(|(c, _)| c.re() != 0.0)
                .zip(&den_ops)
                .filter(|(_, (_, r))| !top(r))
                .map(|(&t, _)| t)
                .collect();
            return pole_residue(num, &rest, band, spec);
        }
        return invalid(
            "model",
            "the denominator's highest-order terms cancel: the model is improper",
        );
    }
    let values = |gs: &[Group<T>]| -> Vec<Group<f64>> {
        gs.iter()
            .map(|g| Group {
                zeros: g.zeros.iter().map(|v| v.re()).collect(),
                poles: g.poles.iter().map(|v| v.re()).collect(),
                coef: g.coef.iter().map(|v| v.re()).collect(),
            })
            .collect()
    };
    let hg64 = values(&hg);
    let ng64 = values(&ng);
    // Strictly proper before approximation (see [`PoleResidue::strictly_proper`]).
    let top = |terms: &[(T, T)]| {
        terms
            .iter()
            .filter(|(c, _)| c.re() != 0.0)
            .map(|(_, o)| o.re())
            .fold(f64::NEG_INFINITY, f64::max)
    };
    // (Orders within [`SAME_FRACTION`] are one order: `0.9 + 1` against `1.9`.)
    let strictly_proper = top(num) + SAME_FRACTION < top(den);
    let (roots, hinted) = roots_of_h_cached(&hg64, d.re(), Lookup::Cached)?;
    let mut out = expansion(&roots, &hg, &ng, &hg64, d)?;
    out.strictly_proper = strictly_proper;
    #[cfg(test)]
    if hinted {
        HINTED.with(|h| h.set(h.get() + 1));
    }
    match check(&out, &hg64, &ng64, band).map_err(|e| repeated_pole(&roots).unwrap_or(e)) {
        Ok(()) => Ok(out),
        // Roots from a nearby model's can include what the cold path leaves out as cancelled
        // (a near-cancelling pole-zero pair), or miss the accuracy it reaches: the cold roots
        // decide, and replace the cache's entry.
        Err(_) if hinted => {
            #[cfg(test)]
            HINTED.with(|h| h.set(h.get() - 1));
            let (roots, _) = roots_of_h_cached(&hg64, d.re(), Lookup::Cold)?;
            let mut out = expansion(&roots, &hg, &ng, &hg64, d)?;
            out.strictly_proper = strictly_proper;
            check(&out, &hg64, &ng64, band).map_err(|e| repeated_pole(&roots).unwrap_or(e))?;
            Ok(out)
        }
        Err(e) => Err(e),
    }
}

/// The numerator terms `num` with each order whose fractional part agrees with a denominator
/// order's to [`SAME_FRACTION`] given that one's exactly (the value moved, the derivative parts
/// kept): `1.9 - 1` is `0.8999999999999999`, an ulp from `0.9`, and a numerator's `s^0.9` over a
/// denominator's `s^1.9` (a feed-through beside an integrator makes them) must share their cells
/// for the modal form to cancel them; cells an ulp apart leave a numerator pole on a
/// denominator pole, whose residue is 0/0. The denominator's terms are left as they are (its
/// near-equal cells are its own poles, which the pole search handles, or refuses so that a
/// product is simulated factor by factor); so is a numerator without such a pair.
fn shared_fractions<T: Real>(num: &[(T, T)], den: &[(T, T)]) -> Vec<(T, T)> {
    let frac = |o: f64| o - o.floor();
    let fractions: Vec<f64> = den
        .iter()
        .map(|(_, o)| frac(o.re()))
        .filter(|&f| f != 0.0)
        .collect();
    num.iter()
        .map(|&(c, o)| {
            let f = frac(o.re());
            match fractions.iter().find(|&&g| (g - f).abs() <= SAME_FRACTION) {
                Some(&g) if f != 0.0 && g != f => (c, o + (g - f)),
                _ => (c, o),
            }
        })
        .collect()
}

/// Fractional parts of orders this close are one ([`shared_fractions`]): some 45 ulps of a
/// fraction near 1, far below any difference an approximation resolves.
const SAME_FRACTION: f64 = 1e-14;

/// The pole-residue form on the zeros `roots` of `H` (values): one Newton step in `T` from each
/// root (exact derivatives of the pole), its residue, the poles of `N_H` that `H` does not cancel,
/// and the feed-through `N_H(infinity)/d`.
fn expansion<T: Real>(
    roots: &[Complex64],
    hg: &[Group<T>],
    ng: &[Group<T>],
    hg64: &[Group<f64>],
    d: T,
) -> Result<PoleResidue<T>> {
    if hg.iter().chain(ng).all(|g| g.poles.is_empty()) {
        return rational_expansion(roots, hg, ng, d);
    }
    let mut out = PoleResidue::empty();
    // The denominator's cell poles (as indices into the groups, to take them in type T).
    let cell_poles: Vec<(usize, usize)> = hg64
        .iter()
        .enumerate()
        .flat_map(|(gi, g)| (0..g.poles.len()).map(move |k| (gi, k)))
        .collect();
    for &r in roots.iter().filter(|r| r.im >= 0.0) {
        // One Newton step in the scalar type: exact derivatives of the root.
        let s0 = Cx::<T>::cst(r);
        let near = cell_poles
            .iter()
            .map(|&(gi, k)| (hg64[gi].poles[k], (gi, k)))
            // |r + p| >= its real and imaginary parts' magnitudes: most cells are left out
            // without the norm (a `hypot` per root and cell).
            .filter(|&(p, _)| {
                let bound = NEAR_CELL_POLE * p.abs();
                (r.re + p).abs() <= bound && r.im.abs() <= bound && (r + p).norm() <= bound
            })
            .min_by(|a, b| (r + a.0).norm().total_cmp(&(r + b.0).norm()));
        // A hair from the cell pole -p: H and H' are differences of nearly equal numbers
        // divided by (s + p) and its powers, and so are their derivatives. F = H (s + p) has
        // the same root and no pole there; H'(lambda) = F'(lambda)/(lambda + p), and the
        // residue N(lambda)/H'(lambda) = (N (s + p))(lambda)/F'(lambda).
        let times = near.map(|(_, (gi, k))| hg[gi].poles[k]);
        let (f, df) = eval_sum_times(hg, s0, times);
        let lam = s0 - f / df;
        let df = if lam == s0 {
            // A step of zero (a value root polished to the last bit): `F'` at `lam` is the one
            // just computed.
            df
        } else {
            eval_sum_times(hg, lam, times).1
        };
        let (nv, _) = eval_sum_times(ng, lam, times);
        let res = nv / df;
        push_pole(&mut out, lam, res, r.im == 0.0);
    }
    finish(out, hg, ng, d)
}

/// [`expansion`] of a model with no cells (every order an integer: a rational model, nothing
/// approximated): `H(s) = P(s)/s^n` with `P(s) = d prod_j (s - lambda_j)` over its `n` poles, so
/// the residue at `lambda_i` is `N_H(lambda_i) lambda_i^n / (d prod_(j != i) (lambda_i - lambda_j))`,
/// taken on the poles themselves (each after one Newton step in `T`) instead of `N_H/H'`. The
/// expansion is then exactly the partial fractions of `N_H/(d prod (s - lambda_j))`: for two poles
/// `delta` apart (relative), whose computed values err by about `eps/delta`, the model is off by
/// that much, not by the `eps/delta^2` of residues from `H'` at slightly wrong poles (measured on
/// poles 1e-3 apart: 4e-10 of the gain through `H'`).
fn rational_expansion<T: Real>(
    roots: &[Complex64],
    hg: &[Group<T>],
    ng: &[Group<T>],
    d: T,
) -> Result<PoleResidue<T>> {
    let mut out = PoleResidue::empty();
    // Every pole in `T` (one Newton step from its root), conjugates included.
    let mut lams: Vec<Cx<T>> = vec![];
    for &r in roots.iter().filter(|r| r.im >= 0.0) {
        let s0 = Cx::<T>::cst(r);
        let (f, df) = eval_sum(hg, s0);
        let lam = s0 - f / df;
        let lam = if r.im == 0.0 { Cx::real(lam.re) } else { lam };
        lams.push(lam);
        if r.im != 0.0 {
            lams.push(Cx::new(lam.re, -lam.im));
        }
    }
    let n = lams.len();
    for (i, &lam) in lams.iter().enumerate() {
        if lam.im.re() < 0.0 {
            continue;
        }
        let (nv, _) = eval_sum(ng, lam);
        let mut den = Cx::real(d);
        for (j, &other) in lams.iter().enumerate() {
            if j != i {
                den = den * (lam - other);
            }
        }
        let mut lam_n = Cx::real(T::from(1.0));
        for _ in 0..n {
            lam_n = lam_n * lam;
        }
        let res = nv * lam_n / den;
        push_pole(&mut out, lam, res, lam.im.re() == 0.0);
    }
    finish(out, hg, ng, d)
}

/// A pole and its residue into `out`: its real part when `real`, else the pair (upper half plane).
fn push_pole<T: Real>(out: &mut PoleResidue<T>, lam: Cx<T>, res: Cx<T>, real: bool) {
    if real {
        out.real.push((lam.re, res.re));
    } else {
        out.complex.push((lam, res));
    }
}

/// The expansion's end, shared by both constructions: the numerator's own poles and the direct
/// term `N_H(inf)/d`.
fn finish<T: Real>(
    mut out: PoleResidue<T>,
    hg: &[Group<T>],
    ng: &[Group<T>],
    d: T,
) -> Result<PoleResidue<T>> {
    numerator_poles(&mut out, hg, ng)?;
    let n_inf = ng.iter().fold(T::from(0.0), |acc, g| acc + g.coef[0]);
    out.direct = n_inf / d;
    Ok(out)
}

/// The poles of `N_H` that `H` does not cancel: a free integrator at `s = 0`, and the cells of
/// numerator groups that are not denominator cells.
fn numerator_poles<T: Real>(
    out: &mut PoleResidue<T>,
    hg: &[Group<T>],
    ng: &[Group<T>],
) -> Result<()> {
    // Pole order at 0: N_H has coef up to k_n, H up to k_h.
    let order = |gs: &[Group<T>]| -> usize {
        gs.iter()
            .filter_map(|g| {
                g.coef
                    .iter()
                    .rposition(|c| c.re() != 0.0)
                    .filter(|_| g.cells_at_zero().re() != 0.0)
            })
            .max()
            .unwrap_or(0)
    };
    let (k_n, k_h) = (order(ng), order(hg));
    if k_n > k_h + 1 {
        return invalid(
            "model",
            format!(
                "{} integrators: at most one free integrator is supported",
                k_n - k_h
            ),
        );
    }
    if k_n == k_h + 1 {
        let lead = |gs: &[Group<T>], k: usize| {
            gs.iter()
                .filter(|g| g.coef.len() > k)
                .fold(T::from(0.0), |acc, g| acc + g.coef[k] * g.cells_at_zero())
        };
        let r = lead(ng, k_n) / lead(hg, k_h);
        out.real.push((T::from(0.0), r));
    }
    for g in ng {
        if g.zeros.is_empty() || hg.iter().any(|h| h.same_as(g)) {
            continue;
        }
        for i in 0..g.poles.len() {
            let s = Cx::real(-g.poles[i]);
            let x = s.recip();
            let mut p = Cx::real(T::from(0.0));
            for &c in g.coef.iter().rev() {
                p = p * x + Cx::real(c);
            }
            let (h, _) = eval_sum(hg, s);
            let r = p.scale(g.cell_residue(i)) / h;
            out.real.push((-g.poles[i], r.re));
        }
    }
    Ok(())
}

/// Two poles closer than this (relative) are taken for a repeated pole when the expansion fails
/// its check ([`repeated_pole`]). A pair `delta` apart (relative) has residues about `1/delta`
/// times the model's gain that cancel in the sum, so the expansion keeps about
/// `eps/delta^2` of its accuracy there (the poles of a near-double root are found to `eps/delta`):
/// at `1e-6` apart that is all of it.
const REPEATED_POLE: f64 = 1e-6;

/// The error for an expansion that failed its check on a repeated pole, if two of `roots` are
/// within [`REPEATED_POLE`] of each other: a modal form (a sum of first-order modes) cannot
/// represent a repeated pole (its response has `t e^(lambda t)` terms). An integer-order model
/// has one at critical damping (`a1^2 = 4 a2` for `a2 s^2 + a1 s + 1`); any pair of distinct poles
/// is represented, to `eps/delta^2` (relative) for poles `delta` apart.
fn repeated_pole(roots: &[Complex64]) -> Option<Error> {
    roots.iter().enumerate().find_map(|(i, &a)| {
        roots[i + 1..]
            .iter()
            .find(|&&b| (a - b).norm() <= REPEATED_POLE * a.norm().max(b.norm()))
            .map(|_| {
                Error::Numerical(format!(
                    "the model has a repeated pole at {:.6e}{:+.3e}i rad/s (a critically damped \
                     pair, or poles within {REPEATED_POLE:.0e} of each other): its modal form \
                     cannot represent it",
                    a.re, a.im
                ))
            })
    })
}

/// How far below the largest response over the check's frequencies the expansion may be off at
/// any of them ([`check_against`]): where the response has fallen far below its peak (an all-pole
/// fifth order a decade above its band, `1/s^5` summed from terms of `1/s`), the sum's rounding is
/// far above the response itself, and no simulation of the modes resolves it there.
const PEAK_TOLERANCE: f64 = 1e-12;

/// Compare the expansion with the factored model at test frequencies across the band.
fn check<T: Real>(
    pr: &PoleResidue<T>,
    hg: &[Group<f64>],
    ng: &[Group<f64>],
    band: (f64, f64),
) -> Result<()> {
    check_against(pr, band, |w| {
        let s = Cx::<f64>::cst(Complex64::new(0.0, w));
        (eval_sum(ng, s).0 / eval_sum(hg, s).0).val()
    })
}

/// The expansion's response against `want` at 7 frequencies spread evenly (log) across the band:
/// within `1e-6` of the response, or of [`PEAK_TOLERANCE`] times the largest response there (or
/// the feed-through).
fn check_against<T: Real>(
    pr: &PoleResidue<T>,
    band: (f64, f64),
    want: impl Fn(f64) -> Complex64,
) -> Result<()> {
    let (w_b, w_h) = band;
    let points: Vec<(f64, Complex64, Complex64)> = (0..7)
        .map(|i| {
            let w = w_b * (w_h / w_b).powf((i as f64 + 0.5) / 7.0);
            (w, pr.freq_response(w), want(w))
        })
        .collect();
    let peak = points
        .iter()
        .map(|p| p.2.norm())
        .fold(pr.direct.re().abs(), f64::max);
    for &(w, got, want) in &points {
        if !((got - want).norm() <= 1e-6 * want.norm() + PEAK_TOLERANCE * peak) {
            return Err(Error::Numerical(format!(
                "the modal form of the approximated model is off by {:.2e} (relative) at \
                 {w:.3e} rad/s",
                (got - want).norm() / want.norm()
            )));
        }
    }
    Ok(())
}
#[cfg(test)]
mod tests {
    use super::*;

    /// An integer fifth order, all poles (the zoo's two-mode plant of seed 45, case 0129, at its
    /// sampling step's default band): a decade above its band the response, `1/s^5`, is summed
    /// from terms of `1/s` that cancel to 1e-13 of their size, and the expansion was refused
    /// there for its rounding ("off by 1.58e-6 (relative) at 6.707e4 rad/s"). It is expanded, its
    /// response equal to the polynomial's evaluated directly up to the Nyquist frequency; a residue off by
    /// 1e-6 of itself is still beyond the check's tolerance at the check's own frequencies.
    #[test]
    fn an_all_pole_fifth_order_is_expanded_and_a_wrong_residue_is_not() {
        let dt = 3.785_565_827_638_113e-4;
        let band = (1e-6 / dt, 30.0 * std::f64::consts::PI / dt);
        let k = 6.337_609_086_312_144;
        let den = [
            (8.667_193_456_999_004e-12, 5.0),
            (1.800_031_979_011_896e-9, 4.0),
            (1.772_091_050_173_599e-6, 3.0),
            (1.129_360_769_502_137e-4, 2.0),
            (4.354_680_331_897_03e-2, 1.0),
            (1.0, 0.0),
        ];
        let pr = pole_residue::<f64>(&[(k, 0.0)], &den, band, &ApproxSpec::default()).unwrap();
        assert_eq!(pr.order(), 5);
        let direct = |w: f64| {
            let s = Complex64::new(0.0, w);
            k / den
                .iter()
                .map(|&(c, o)| c * s.powi(o as i32))
                .sum::<Complex64>()
        };
        for w in [1.0, 30.0, 170.0, 410.0, 3e3, 8e3] {
            let (got, want) = (pr.freq_response(w), direct(w));
            assert!(
                (got - want).norm() <= 1e-9 * want.norm(),
                "{w}: {got} {want}"
            );
        }
        check_against(&pr, band, direct).unwrap();
        let mut wrong = pr.clone();
        wrong.complex[0].1 = wrong.complex[0].1.scale(1.0 + 1e-6);
        assert!(check_against(&wrong, band, direct).is_err());
    }

    /// A highest-order term at 1e-300 (a coefficient held at its range's floor) is no term: the
    /// expansion is the one of the model written without it (the zoo's case 0269 ended its fit
    /// with `a4 = 5e-298` beside `a3 = 2e5`, and every simulation of it failed as "improper"); a
    /// top term that is merely tiny (1e-10 beside 2e5 s^3: a pole at 2e15 rad/s, 2e11 times the
    /// band's upper edge) and a top group whose terms are large and cancel are still refused.
    #[test]
    fn a_top_term_at_its_floor_is_left_out_and_a_cancelling_one_refused() {
        let band = (1e-3, 1e4);
        let spec = ApproxSpec::default();
        let num = [(1.5, 0.0), (1105.7, 1.0)];
        let without = [(2.0e5, 3.0), (6.8e4, 2.0), (1.04e3, 1.0), (1.0, 0.0)];
        let mut with = vec![(5.2e-298, 4.0)];
        with.extend(without);
        let a = pole_residue::<f64>(&num, &without, band, &spec).unwrap();
        let b = pole_residue::<f64>(&num, &with, band, &spec).unwrap();
        assert_eq!(format!("{:?}", a.real), format!("{:?}", b.real));
        assert_eq!(a.complex.len(), b.complex.len());
        assert!(!a.real.is_empty() || !a.complex.is_empty());
        let mut tiny = vec![(1e-10, 4.0)];
        tiny.extend(without);
        let e = pole_residue::<f64>(&num, &tiny, band, &spec).unwrap_err();
        assert!(e.to_string().contains("cancel"), "{e}");
        let cancelling = [(2.0, 2.0), (-2.0, 2.0), (1.0, 1.0), (1.0, 0.0)];
        let e = pole_residue::<f64>(&num, &cancelling, band, &spec).unwrap_err();
        assert!(e.to_string().contains("cancel"), "{e}");
    }

    /// A denominator of high degree in seconds is no vanishing one: the zoo's two-mode case 0029
    /// (a lag of 27 ms and modes at 87 Hz and 327 Hz, dt 0.22 ms) has `2.1e-14 s^5` beside `1`,
    /// 2e-14 of the coefficients' sum, and was refused as improper; weighed at the band's upper
    /// edge its top term dominates, and its five poles are the plant's.
    #[test]
    fn a_high_degree_in_seconds_is_not_taken_for_a_vanishing_top_term() {
        let dt = 2.1905579290911107e-4;
        let band = (1e-6 / dt, 30.0 * std::f64::consts::PI / dt);
        let den = [
            (2.1467101503133472e-14, 5.0),
            (6.667670008658963e-12, 4.0),
            (9.748313707886227e-8, 3.0),
            (1.3782538556488682e-5, 2.0),
            (2.749854033126512e-2, 1.0),
            (1.0, 0.0),
        ];
        let pr = pole_residue::<f64>(&[(1.15, 0.0)], &den, band, &ApproxSpec::default()).unwrap();
        assert_eq!((pr.real.len(), pr.complex.len()), (1, 2), "{pr:?}");
        // the modes' natural frequencies, 87.1 Hz and 326.7 Hz, and the lag's pole, -1/27.1 ms
        let mut hz: Vec<f64> = pr
            .complex
            .iter()
            .map(|(l, _)| l.val().norm() / (2.0 * std::f64::consts::PI))
            .collect();
        hz.sort_by(f64::total_cmp);
        assert!(
            (hz[0] - 87.1).abs() < 0.1 && (hz[1] - 326.7).abs() < 0.1,
            "{hz:?}"
        );
        assert!(
            (pr.real[0].0 * 2.712e-2 + 1.0).abs() < 1e-3,
            "{:?}",
            pr.real
        );
    }

    /// Poles found from the poles of a nearby model (the cache's hint) equal the poles found
    /// from the eigenvalues, to rounding; the same model again is answered from the cache.
    #[test]
    fn poles_from_a_nearby_models_poles_equal_the_cold_ones() {
        let model = |zeta: f64, a1: f64| {
            pole_residue::<f64>(
                &[(6.82, 0.0)],
                &[(2.655e-5, zeta + 0.8252), (a1, zeta), (1.0, 0.0)],
                (1e-3, 2e5),
                &ApproxSpec::default(),
            )
            .unwrap()
        };
        // Outside of a cache: cold.
        let cold = model(0.93, 0.006);
        let (warm, again) = RootsCache::new().enter(|| {
            // Within the hint's reach: every value of H within 5% (the order moves each term's
            // gain by (2e5)^0.001, 1.2%).
            let _ = model(0.929, 0.00599);
            let hinted = HINTED.with(|h| h.get());
            let warm = model(0.93, 0.006);
            assert_eq!(
                HINTED.with(|h| h.get()),
                hinted + 1,
                "the hint was not used"
            );
            (warm, model(0.93, 0.006))
        });
        assert_eq!(cold.real.len(), warm.real.len());
        assert_eq!(cold.complex.len(), warm.complex.len());
        let mut a: Vec<f64> = cold.real.iter().map(|p| p.0).collect();
        let mut b: Vec<f64> = warm.real.iter().map(|p| p.0).collect();
        a.sort_by(f64::total_cmp);
        b.sort_by(f64::total_cmp);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-12 * x.abs(), "{x} vs {y}");
        }
        let sorted = |pr: &PoleResidue<f64>| {
            let mut c: Vec<Complex64> = pr.complex.iter().map(|p| p.0.val()).collect();
            c.sort_by(|x, y| x.im.total_cmp(&y.im));
            c
        };
        for (x, y) in sorted(&cold).iter().zip(&sorted(&warm)) {
            assert!((x - y).norm() <= 1e-12 * x.norm(), "{x} vs {y}");
        }
        assert_eq!(format!("{:?}", warm.real), format!("{:?}", again.real));
    }

    /// Outside of a cache a build keeps nothing: after a nearby model's build it is the cold
    /// build to the bit, with no hint used. A cache entered inside another stands for it and is
    /// handed back with what was built in it, the outer one restored as it was; a helper's copy
    /// ([`RootsCache::entered`]) is the entered cache's content; [`RootsCache::afresh`] inside a
    /// cache empties it and leaves its own result in it.
    #[test]
    fn a_cache_is_a_value_entered_for_a_computation() {
        let model = |a1: f64| {
            pole_residue::<f64>(
                &[(6.82, 0.0)],
                &[(2.655e-5, 1.75), (a1, 0.93), (1.0, 0.0)],
                (1e-3, 2e5),
                &ApproxSpec::default(),
            )
            .unwrap()
        };
        let key = |p: &PoleResidue<f64>| format!("{:?} {:?}", p.real, p.complex);
        let cold = key(&model(0.006));
        let hinted = HINTED.with(|h| h.get());
        let _ = model(0.00599);
        assert_eq!(key(&model(0.006)), cold);
        assert_eq!(
            HINTED.with(|h| h.get()),
            hinted,
            "a hint outside of a cache"
        );
        assert!(RootsCache::entered().is_empty());
        let mut outer = RootsCache::new();
        let mut inner = RootsCache::new();
        outer.enter(|| {
            let _ = model(0.00599);
            let seen = RootsCache::entered().0.len();
            assert_eq!(seen, 1);
            inner.enter(|| {
                assert!(RootsCache::entered().is_empty());
                let _ = model(0.007);
                let _ = model(0.008);
            });
            assert_eq!(
                RootsCache::entered().0.len(),
                seen,
                "the outer cache changed"
            );
            RootsCache::afresh(|| {
                assert!(RootsCache::entered().is_empty());
                let _ = model(0.006);
            });
        });
        assert_eq!((outer.0.len(), inner.0.len()), (1, 2));
        assert!(RootsCache::entered().is_empty());
        // outside of any: `afresh` enters a cache of its own for its computation alone
        RootsCache::afresh(|| assert!(RootsCache::entered().is_empty()));
        assert!(RootsCache::entered().is_empty());
    }

    /// An LM step's change (a denominator coefficient 10% and an order 0.001 away, within
    /// [`HINT_DISTANCE`] but beyond the former 0.05) is found from the hint, and the poles and
    /// residues equal the cold build's to 1e-12 relative (Newton polishes each root to rounding
    /// from either start; the residues follow from the roots).
    #[test]
    fn an_lm_step_away_is_found_from_the_hint_and_equals_the_cold_build() {
        let model = |zeta: f64, a2: f64| {
            pole_residue::<f64>(
                &[(6.82, 0.0)],
                &[(a2, zeta + 0.8252), (5.94e-3, zeta), (1.0, 0.0)],
                (1e-2, 9.4e5),
                &ApproxSpec::default(),
            )
            .unwrap()
        };
        let cold = model(0.9186, 2.69e-5);
        let warm = RootsCache::new().enter(|| {
            let _ = model(0.9176, 2.69e-5 / 1.1);
            let hinted = HINTED.with(|h| h.get());
            let warm = model(0.9186, 2.69e-5);
            assert_eq!(
                HINTED.with(|h| h.get()),
                hinted + 1,
                "the hint was not used"
            );
            warm
        });
        assert_eq!(cold.real.len(), warm.real.len());
        assert_eq!(cold.complex.len(), warm.complex.len());
        let key = |pr: &PoleResidue<f64>| {
            let mut v: Vec<(f64, f64)> = pr.real.clone();
            v.sort_by(|x, y| x.0.total_cmp(&y.0));
            v
        };
        for (x, y) in key(&cold).iter().zip(&key(&warm)) {
            assert!((x.0 - y.0).abs() <= 1e-12 * x.0.abs(), "{x:?} vs {y:?}");
            let scale = cold.real.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
            assert!((x.1 - y.1).abs() <= 1e-12 * scale, "{x:?} vs {y:?}");
        }
        for (x, y) in cold.complex.iter().zip(&warm.complex) {
            let (a, b) = (x.0.val(), y.0.val());
            assert!((a - b).norm() <= 1e-12 * a.norm(), "{a} vs {b}");
            let (ra, rb) = (x.1.val(), y.1.val());
            assert!((ra - rb).norm() <= 1e-12 * ra.norm(), "{ra} vs {rb}");
        }
    }

    /// The dual derivatives of every pole and of every mode's weight `r/lambda` (the weight of the
    /// mode in a step's or a held past input's free response) with respect to an order equal
    /// central differences. The PMSM at dt = 2e-4 has near-cancelling pole-zero pairs a hair from
    /// cell poles (-1.34e-6 and -2.47e-3 rad/s, residues 1e-18 and 1e-12): with `r = N_H/H'`
    /// taken on `H` there, their `d(r/lambda)` came out 3.5e-3 instead of about 1e-11.
    /// Tolerances: central differences with `h = 1e-6 zeta` err by `h^2/6` times the third
    /// derivative (far below) plus rounding, `eps |f|/h` times the conditioning of `f`: for the
    /// poles 1e-7 of `|lambda|` (their derivatives are of order `lambda`; seen: 1e-6 of that); for
    /// the weights, computed to an absolute `1e-13 max |w|` with `max |w|` about 6, 1e-7 of the
    /// derivative plus 1e-8 (seen: 6.7e-7 on a derivative of 116, 7e-12 on the near-cancelling
    /// modes). And an exact truth: `sum r/lambda = direct - G(0) = -6.8` whatever the order, so
    /// its dual derivative is zero to rounding (1e-9 of `sum |d(r/lambda)|`; seen 3e-12).
    /// `(pole, its derivative, weight r/lambda, its derivative)` of every mode of a build with
    /// one dual part, a complex pair as its upper member, sorted by pole.
    type Mode = (Complex64, Complex64, Complex64, Complex64);
    fn modes_of(pr: &PoleResidue<crate::scalar::Dual<1>>) -> Vec<Mode> {
        use crate::scalar::Dual;
        let c = |v: Cx<Dual<1>>| {
            (
                Complex64::new(v.re.v, v.im.v),
                Complex64::new(v.re.d[0], v.im.d[0]),
            )
        };
        let mut m: Vec<Mode> = pr
            .real
            .iter()
            .map(|&(l, r)| (Cx::real(l), Cx::real(r)))
            .chain(pr.complex.iter().copied())
            .map(|(l, r)| {
                let ((lv, ld), (wv, wd)) = (c(l), c(r / l));
                (lv, ld, wv, wd)
            })
            .collect();
        m.sort_by(|a, b| a.0.re.total_cmp(&b.0.re).then(a.0.im.total_cmp(&b.0.im)));
        m
    }

    #[test]
    fn pole_and_weight_derivatives_match_central_differences() {
        use crate::scalar::Dual;
        let dt = 2e-4;
        let band = (1e-3, 30.0 * std::f64::consts::PI / dt);
        // (Each build cold: outside of a cache.)
        let build = |zeta: Dual<1>| {
            let c = |v: f64| Dual::<1>::cst(v);
            pole_residue::<Dual<1>>(
                &[(c(6.8), c(0.0))],
                &[
                    (c(2.7e-5), zeta + c(0.8)),
                    (c(0.006), zeta),
                    (c(1.0), c(0.0)),
                ],
                band,
                &ApproxSpec::default(),
            )
            .unwrap()
        };
        // (pole, its derivative, weight r/lambda, its derivative) of every mode, a complex pair
        // as its upper member.
        let zeta = 0.9;
        let h = 1e-6 * zeta;
        let dual = modes_of(&build(Dual::var(zeta, 0)));
        let plus = modes_of(&build(Dual::cst(zeta + h)));
        let minus = modes_of(&build(Dual::cst(zeta - h)));
        assert_eq!(dual.len(), plus.len());
        assert_eq!(dual.len(), minus.len());
        let (mut sum, mut scale) = (0.0, 0.0);
        for ((d, p), m) in dual.iter().zip(&plus).zip(&minus) {
            let dl = (p.0 - m.0) / (2.0 * h);
            let dw = (p.2 - m.2) / (2.0 * h);
            assert!(
                (d.1 - dl).norm() <= 1e-7 * d.0.norm(),
                "pole {}: dual {} cd {dl}",
                d.0,
                d.1
            );
            assert!(
                (d.3 - dw).norm() <= 1e-7 * dw.norm() + 1e-8,
                "pole {} weight {}: dual {} cd {dw}",
                d.0,
                d.2,
                d.3
            );
            let k = if d.0.im == 0.0 { 1.0 } else { 2.0 };
            sum += k * d.3.re;
            scale += k * d.3.norm();
        }
        assert!(
            sum.abs() <= 1e-9 * scale,
            "d/dzeta sum r/lambda = {sum}, not zero (scale {scale})"
        );
    }

    /// A model built from the poles of a nearby one (the cache's hint) equals the cold build, for
    /// models with near-cancelling pole-zero pairs a hair from cell poles: the PMSM at dt = 2e-4
    /// (roots within 1e-13 of a cell pole, residues down to 1e-18, which the cold path settles),
    /// and an order 2e-6 from an integer (the cold path leaves a cancelled root out). Same modes,
    /// each pole to 1e-9 relative and each weight `r/lambda` to 1e-9 of the largest (rounding of
    /// two Newton runs on the same `H`, well conditioned through `F = H (s + p)`), and each
    /// derivative with respect to the order to 1e-7 of itself plus 1e-8, the tolerance of
    /// `pole_and_weight_derivatives_match_central_differences`.
    #[test]
    fn a_hinted_build_near_cancelling_pairs_equals_the_cold_build() {
        use crate::scalar::Dual;
        // (zeta, nearby zeta, theta, band, whether the hint serves). The second model's cold
        // path leaves a cancelled root out (39 of 40), and so does the nearby one's: Newton from
        // its 39 roots cannot make the 40 that the hint path needs, and the build goes cold.
        let cases = [
            (
                0.9,
                0.901,
                0.8,
                (1e-3, 30.0 * std::f64::consts::PI / 2e-4),
                1,
            ),
            (2.0 - 2e-6, 2.0 - 1e-5, 0.9, (1e-3, 2e5), 0),
        ];
        for (zeta, near, theta, band, served) in cases {
            let build = |zeta: Dual<1>| {
                let c = |v: f64| Dual::<1>::cst(v);
                pole_residue::<Dual<1>>(
                    &[(c(6.8), c(0.0))],
                    &[
                        (c(2.7e-5), zeta + c(theta)),
                        (c(0.006), zeta),
                        (c(1.0), c(0.0)),
                    ],
                    band,
                    &ApproxSpec::default(),
                )
                .unwrap()
            };
            let cold = modes_of(&build(Dual::var(zeta, 0)));
            let warm = RootsCache::new().enter(|| {
                let _ = build(Dual::var(near, 0));
                let hinted = HINTED.with(|h| h.get());
                let warm = modes_of(&build(Dual::var(zeta, 0)));
                assert_eq!(HINTED.with(|h| h.get()), hinted + served, "{zeta}");
                warm
            });
            assert_eq!(cold.len(), warm.len(), "{zeta}");
            let w_max = cold.iter().map(|m| m.2.norm()).fold(0.0, f64::max);
            for (c, w) in cold.iter().zip(&warm) {
                let same = |what: &str, a: Complex64, b: Complex64, tol: f64| {
                    assert!(
                        (a - b).norm() <= tol,
                        "{zeta}: pole {}: {what} {a} vs {b}",
                        c.0
                    );
                };
                same("pole", c.0, w.0, 1e-9 * c.0.norm());
                same("d", c.1, w.1, 1e-7 * c.1.norm() + 1e-8);
                same("weight", c.2, w.2, 1e-9 * w_max);
                same("d weight", c.3, w.3, 1e-7 * c.3.norm() + 1e-8);
            }
        }
    }

    /// A numerator order an integer below a denominator order (`s^0.9` over `s^1.9`, whose
    /// fractional part `1.9 - 1` rounds to `0.8999999999999999`; a feed-through beside an
    /// integrator makes them) shares the denominator's cells: the expansion holds and its
    /// response is `(jw)^a` arithmetic's (exact powers, not the approximation's) to 1% over the
    /// band's inner decades.
    #[test]
    fn orders_an_integer_apart_share_their_cells() {
        let band = (1e-3, 1e5);
        for (q, c) in [(0.9, 7.0), (0.6, 2.0), (0.3, 0.5)] {
            let pr = pole_residue::<f64>(
                &[(c, q)],
                &[(1.0, q + 1.0), (1.0, 0.0)],
                band,
                &ApproxSpec::default(),
            )
            .unwrap_or_else(|e| panic!("{q}: {e}"));
            for w in [1e-1, 1.0, 10.0, 100.0] {
                let jw = Complex64::new(0.0, w);
                let want = c * jw.powf(q) / (jw.powf(q + 1.0) + 1.0);
                let got = pr.freq_response(w);
                assert!(
                    (got - want).norm() <= 0.01 * want.norm(),
                    "{q} at {w}: {got} vs {want}"
                );
            }
        }
        // The feed-through structure with a free integrator in series:
        // (D a2 s^(z+t) + D a1 s^z + K + D) / (s (a2 s^(z+t) + a1 s^z + 1)).
        let (k, d, a1, a2, z, t) = (-0.175, -0.0408, 176.0, 7759.0, 0.9, 0.9);
        let pr = pole_residue::<f64>(
            &[(d * a2, z + t), (d * a1, z), (k + d, 0.0)],
            &[(a2, z + t + 1.0), (a1, z + 1.0), (1.0, 1.0)],
            band,
            &ApproxSpec::default(),
        )
        .unwrap();
        for w in [1e-1, 1.0, 10.0] {
            let jw = Complex64::new(0.0, w);
            let inner = a2 * jw.powf(z + t) + a1 * jw.powf(z) + 1.0;
            let want = (d * inner + k) / (jw * inner);
            let got = pr.freq_response(w);
            assert!(
                (got - want).norm() <= 0.01 * want.norm(),
                "at {w}: {got} vs {want}"
            );
        }
    }

    /// Orders within ppm of an integer make cells that nearly cancel (and the refined Oustaloup
    /// a pole near 1e11 rad/s); the expansion still holds (it is checked inside) and agrees with
    /// the factored model.
    #[test]
    fn orders_a_hair_from_an_integer_expand() {
        for zeta in [2.0 - 2e-6, 1.0 - 1e-7, 1.0 + 1e-7, 0.5] {
            let pr = pole_residue::<f64>(
                &[(6.8, 0.0)],
                &[(2.6e-5, zeta + 0.9), (0.0059, zeta), (1.0, 0.0)],
                (1e-3, 2e5),
                &ApproxSpec::default(),
            );
            assert!(pr.is_ok(), "{zeta}: {pr:?}");
        }
    }
}
