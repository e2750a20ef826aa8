//! The kernels of [`Simulator::run_into`], written once over the instruction set
//! ([`super::isa::Simd`]): the modes packed `L` to a vector (`L = S::LANES`: 4 for AVX2 and the
//! portable set, 8 for AVX-512), complex modes `L / 2` to a vector, and the delayed input read
//! straight from the input slice.
//!
//! Layout ([`Packed`]): `rows` rows (row `rows - 1` the values, rows `0..rows - 1` the derivative
//! parts of a [`crate::Dual`] simulation), each of `vr` real vectors (real mode `i` in vector
//! `i / L`, lane `i % L`) then `vc` complex vectors (complex modes `hc .. hc + L/2` of vector `c`
//! as `[re.., im..]`). A complex product `phi x` is then `phi1 * x + phi2 * swap(x)` with
//! `phi1 = [re.., re..]`, `phi2 = [-im.., im..]` and `swap` the exchange of the two halves: the
//! same lane-wise multiply-adds as the real modes plus one permutation. Padding lanes are inert
//! (zero coefficients, zero state).
//!
//! The per-sample work is then, per vector and row, two or three multiply-adds (three more for a
//! complex vector) and one addition into the output: the value kernel ([`value_regs`]) keeps the
//! whole state in registers when the set has an instance of its size
//! ([`Simd::value_in_registers`]: up to 48 real modes and 2 complex vectors); the row kernel
//! ([`rows_mem`]: dual numbers, or more modes) keeps it in memory, one pass over the vectors per
//! sample with the value of each mode loaded once for all its derivative rows.

use super::isa::{RegKernel, Simd, WithSimd};
use super::Simulator;
use crate::scalar::Real;
use std::ops::Range;

/// The modes of a [`Simulator`] packed for the kernels (see the module documentation).
pub(crate) struct Packed {
    pub(super) rows: usize,
    /// Lanes of a vector: 4 or 8.
    pub(super) lanes: usize,
    pub(super) vr: usize,
    pub(super) vc: usize,
    phi1: Vec<f64>,
    phi2: Vec<f64>,
    b0: Vec<f64>,
    b1: Vec<f64>,
    x: Vec<f64>,
}

/// Part `r` of `v`: derivative `r`, or the value for `r` = the number of derivatives.
#[inline(always)]
pub(super) fn part<T: Real>(v: T, r: usize) -> f64 {
    v.derivs().as_ref().get(r).copied().unwrap_or(v.re())
}

impl Packed {
    /// Pack `sim`'s coefficients and state (every part of its scalars, [`part`]) in vectors of
    /// `lanes` (4 or 8).
    pub(super) fn of<T: Real>(sim: &Simulator<T>, lanes: usize) -> Self {
        let rows = T::derivs_of(()).as_ref().len() + 1;
        let nr = sim.re_phi.len();
        let half = lanes / 2;
        let (vr, nc) = (nr.div_ceil(lanes), sim.cx_phi.len());
        let vc = nc.div_ceil(half);
        let v = vr + vc;
        let len = rows * v * lanes;
        let mut p = Self {
            rows,
            lanes,
            vr,
            vc,
            phi1: vec![0.0; len],
            phi2: vec![0.0; len],
            b0: vec![0.0; len],
            b1: vec![0.0; len],
            x: vec![0.0; len],
        };
        for r in 0..rows {
            let row = r * v * lanes;
            for i in 0..nr {
                p.phi1[row + i] = part(sim.re_phi[i], r);
                p.b0[row + i] = part(sim.re_b0[i], r);
                p.b1[row + i] = part(sim.re_b1[i], r);
                p.x[row + i] = part(sim.re_x[i], r);
            }
            for m in 0..nc {
                let (at, j) = (row + (vr + m / half) * lanes, m % half);
                let (pr, pi) = (part(sim.cx_phi[m].re, r), part(sim.cx_phi[m].im, r));
                p.phi1[at + j] = pr;
                p.phi1[at + half + j] = pr;
                p.phi2[at + j] = -pi;
                p.phi2[at + half + j] = pi;
                p.b0[at + j] = part(sim.cx_b0[m].re, r);
                p.b0[at + half + j] = part(sim.cx_b0[m].im, r);
                p.b1[at + j] = part(sim.cx_b1[m].re, r);
                p.b1[at + half + j] = part(sim.cx_b1[m].im, r);
                p.x[at + j] = part(sim.cx_x[m].re, r);
                p.x[at + half + j] = part(sim.cx_x[m].im, r);
            }
        }
        p
    }

    /// The state back into `sim`.
    pub(super) fn state_back<T: Real>(&self, sim: &mut Simulator<T>) {
        let (v, l, half) = (self.vr + self.vc, self.lanes, self.lanes / 2);
        let make = |at: usize| {
            let mut d = T::derivs_of(0.0);
            for (r, q) in d.as_mut().iter_mut().enumerate() {
                *q = self.x[r * v * l + at];
            }
            T::from_parts(self.x[(self.rows - 1) * v * l + at], d)
        };
        for i in 0..sim.re_x.len() {
            sim.re_x[i] = make(i);
        }
        for m in 0..sim.cx_x.len() {
            let at = (self.vr + m / half) * l + m % half;
            sim.cx_x[m] = crate::cx::Cx::new(make(at), make(at + half));
        }
    }

    /// The arrays' length, checked.
    fn checked_len(&self) -> usize {
        let len = self.rows * (self.vr + self.vc) * self.lanes;
        assert!([&self.phi1, &self.phi2, &self.b0, &self.b1, &self.x]
            .iter()
            .all(|a| a.len() == len));
        len
    }
}

/// What a kernel reads besides the packed modes: the input, the whole-sample delay `m`
/// (`a_k = u[k - m]`, `b_k = u[k - m - 1]`, so `k >= m + 1`), the feed-through's parts (one per
/// row) and whether it sees `b_k` (a fractional-sample delay) instead of `a_k`.
pub(crate) struct Drive<'a> {
    pub u: &'a [f64],
    pub m: usize,
    pub direct: &'a [f64],
    pub direct_prev: bool,
}

/// Vector `i` of `a` (bounds checked).
#[inline(always)]
fn ld<S: Simd>(s: S, a: &[f64], i: usize) -> S::V {
    let c = &a[S::LANES * i..S::LANES * (i + 1)];
    // SAFETY: `c` is `LANES` f64.
    unsafe { s.load(c.as_ptr()) }
}

/// Store `v` as vector `i` of `a` (bounds checked).
#[inline(always)]
fn st<S: Simd>(s: S, a: &mut [f64], i: usize, v: S::V) {
    let c = &mut a[S::LANES * i..S::LANES * (i + 1)];
    // SAFETY: `c` is `LANES` f64.
    unsafe { s.store(c.as_mut_ptr(), v) }
}

/// [`value_regs`]' arguments; [`Simd::value_in_registers`] picks the instance of their size (the
/// x86-64 sets have such instances, [`super::isa::Portable`] none).
pub(crate) struct ValueRegs<'a, 'b> {
    pub p: &'a mut Packed,
    pub d: &'a Drive<'b>,
    pub range: Range<usize>,
    pub y: &'a mut [f64],
}

impl<const VR: usize, const VC: usize, const B1: bool> WithSimd
    for ValueRegsOf<'_, '_, VR, VC, B1>
{
    type Output = ();
    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        let r = self.0;
        value_regs::<S, VR, VC, B1>(s, r.p, r.d, r.range, r.y);
    }
}

/// [`ValueRegs`] at one size: what [`Simd::vectorize`] compiles.
struct ValueRegsOf<'a, 'b, const VR: usize, const VC: usize, const B1: bool>(ValueRegs<'a, 'b>);

impl RegKernel for ValueRegs<'_, '_> {
    #[inline(always)]
    fn run<const VR: usize, const VC: usize, const B1: bool, S: Simd>(self, s: S) {
        s.vectorize(ValueRegsOf::<VR, VC, B1>(self));
    }
}

/// The value kernel with the whole state in registers: `VR` real and `VC` complex vectors, `B1`
/// whether any `beta1` is nonzero. Writes `y[k]` for `k` in `range`.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
fn value_regs<S: Simd, const VR: usize, const VC: usize, const B1: bool>(
    s: S,
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    y: &mut [f64],
) {
    assert!(p.lanes == S::LANES && p.rows == 1 && p.vr == VR && p.vc == VC && range.start > d.m);
    let z = s.splat(0.0);
    let (mut xr, mut phr, mut b0r, mut b1r) = ([z; VR], [z; VR], [z; VR], [z; VR]);
    for j in 0..VR {
        (xr[j], phr[j]) = (ld(s, &p.x, j), ld(s, &p.phi1, j));
        (b0r[j], b1r[j]) = (ld(s, &p.b0, j), ld(s, &p.b1, j));
    }
    let (mut xc, mut p1c, mut p2c, mut b0c, mut b1c) =
        ([z; VC], [z; VC], [z; VC], [z; VC], [z; VC]);
    for c in 0..VC {
        let j = VR + c;
        (xc[c], p1c[c], p2c[c]) = (ld(s, &p.x, j), ld(s, &p.phi1, j), ld(s, &p.phi2, j));
        (b0c[c], b1c[c]) = (ld(s, &p.b0, j), ld(s, &p.b1, j));
    }
    let m = d.m;
    // The output's partial sums of each sample are kept for a block and summed a few samples at
    // a time ([`Simd::sum_parts`]), off the loop-carried path.
    const BLOCK: usize = 256;
    let mut parts = [s.part_zero(); BLOCK];
    let mut k0 = range.start;
    while k0 < range.end {
        let k1 = (k0 + BLOCK).min(range.end);
        let u = &d.u[k0 - m - 1..k1 - m];
        for (acc, w) in parts.iter_mut().zip(u.windows(2)) {
            let (va, vb) = (s.splat(w[1]), s.splat(w[0]));
            let (mut acc0, mut acc1) = (z, z);
            for j in 0..VR {
                if j % 2 == 0 {
                    acc0 = s.add(acc0, xr[j]);
                } else {
                    acc1 = s.add(acc1, xr[j]);
                }
                let mut t = s.mul(b0r[j], va);
                if B1 {
                    t = s.fma(b1r[j], vb, t);
                }
                xr[j] = s.fma(phr[j], xr[j], t);
            }
            for c in 0..VC {
                acc1 = s.add(acc1, s.re_part(xc[c]));
                let mut t = s.mul(b0c[c], va);
                if B1 {
                    t = s.fma(b1c[c], vb, t);
                }
                let t2 = s.mul(p2c[c], s.swap(xc[c]));
                xc[c] = s.add(s.fma(p1c[c], xc[c], t), t2);
            }
            *acc = s.fold(s.add(acc0, acc1));
        }
        s.sum_parts(&parts[..k1 - k0], &mut y[k0..k1]);
        if d.direct[0] != 0.0 {
            let back = m + usize::from(d.direct_prev);
            for k in k0..k1 {
                y[k] += d.direct[0] * d.u[k - back];
            }
        }
        k0 = k1;
    }
    for j in 0..VR {
        st(s, &mut p.x, j, xr[j]);
    }
    for c in 0..VC {
        st(s, &mut p.x, VR + c, xc[c]);
    }
}

/// [`rows_mem`], compiled for a set by [`Simd::vectorize`].
struct RowsMem<'a, 'b, T: Real, const B1: bool> {
    p: &'a mut Packed,
    d: &'a Drive<'b>,
    range: Range<usize>,
    y: &'a mut [T],
}

impl<T: Real, const B1: bool> WithSimd for RowsMem<'_, '_, T, B1> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        rows_mem::<S, T, B1>(s, self.p, self.d, self.range, self.y);
    }
}

/// The row kernel: the derivative rows of `T` (none for `f64`) and the value row, the state in
/// memory; writes `y[k]` for `k` in `range`. Per vector, each derivative row is
/// `dx' = phi dx + dphi x + dbeta0 a + dbeta1 b` with the value `x` before its own update.
#[inline(always)]
fn rows_mem<S: Simd, T: Real, const B1: bool>(
    s: S,
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    y: &mut [T],
) {
    let z = s.splat(0.0);
    let n = T::derivs_of(()).as_ref().len();
    assert!(p.lanes == S::LANES && p.rows == n + 1 && d.direct.len() == n + 1);
    assert!(range.start > d.m && range.end <= d.u.len().min(y.len()));
    let (vr, v) = (p.vr, p.vr + p.vc);
    let val = n * v;
    // Every vector index below is `< (n + 1) v`: the loads and stores go through raw pointers
    // (no bounds check per access, the hot loop's main overhead) once the lengths are checked.
    p.checked_len();
    let (phi1, phi2, b0, b1) = (
        p.phi1.as_ptr(),
        p.phi2.as_ptr(),
        p.b0.as_ptr(),
        p.b1.as_ptr(),
    );
    let x = p.x.as_mut_ptr();
    let l = S::LANES;
    // SAFETY (for `ld` and `st` below): `i < (n + 1) v`, so lanes `L i .. L i + L` are inside
    // the arrays of `(n + 1) v L` f64 checked above; `x` is not aliased while this runs.
    let ld = |a: *const f64, i: usize| unsafe { s.load(a.add(l * i)) };
    let st = |a: *mut f64, i: usize, w: S::V| unsafe { s.store(a.add(l * i), w) };
    let input = |o: usize, va: S::V, vb: S::V| {
        let t = s.mul(ld(b0, o), va);
        if B1 {
            s.fma(ld(b1, o), vb, t)
        } else {
            t
        }
    };
    for k in range {
        let (a, b) = (d.u[k - d.m], d.u[k - d.m - 1]);
        let (va, vb) = (s.splat(a), s.splat(b));
        let mut acc = T::derivs_of(z);
        let mut accv = z;
        for j in 0..vr {
            let xv = ld(x, val + j);
            let ph = ld(phi1, val + j);
            for (r, ar) in acc.as_mut().iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = s.add(*ar, dx);
                let t = s.fma(ld(phi1, o), xv, input(o, va, vb));
                st(x, o, s.fma(ph, dx, t));
            }
            accv = s.add(accv, xv);
            let t = input(val + j, va, vb);
            st(x, val + j, s.fma(ph, xv, t));
        }
        for j in vr..v {
            let xv = ld(x, val + j);
            let xs = s.swap(xv);
            let (p1, p2) = (ld(phi1, val + j), ld(phi2, val + j));
            for (r, ar) in acc.as_mut().iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = s.add(*ar, s.re_part(dx));
                let mut t = input(o, va, vb);
                t = s.fma(ld(phi1, o), xv, t);
                t = s.fma(ld(phi2, o), xs, t);
                t = s.fma(p2, s.swap(dx), t);
                st(x, o, s.fma(p1, dx, t));
            }
            accv = s.add(accv, s.re_part(xv));
            let mut t = input(val + j, va, vb);
            t = s.fma(p2, xs, t);
            st(x, val + j, s.fma(p1, xv, t));
        }
        let din = if d.direct_prev { b } else { a };
        let mut dd = T::derivs_of(0.0);
        for (r, q) in dd.as_mut().iter_mut().enumerate() {
            *q = s.hsum(acc.as_ref()[r]) + d.direct[r] * din;
        }
        y[k] = T::from_parts(s.hsum(accv) + d.direct[n] * din, dd);
    }
}

/// The value kernel for `p` (one row): in registers when the set has an instance of its size,
/// else [`rows_mem`].
pub(super) fn run_value<S: Simd>(
    s: S,
    p: &mut Packed,
    d: &Drive<'_>,
    b1: bool,
    range: Range<usize>,
    y: &mut [f64],
) {
    let _ftz = s.flush_subnormals();
    let (vr, vc) = (p.vr, p.vc);
    let regs = ValueRegs {
        p: &mut *p,
        d,
        range: range.clone(),
        y: &mut *y,
    };
    if s.value_in_registers(vr, vc, b1, regs) {
        return;
    }
    run_rows(s, p, d, b1, range, y);
}

/// The row kernel for `p` (a row per part of `T`).
pub(super) fn run_rows<S: Simd, T: Real>(
    s: S,
    p: &mut Packed,
    d: &Drive<'_>,
    b1: bool,
    range: Range<usize>,
    y: &mut [T],
) {
    let _ftz = s.flush_subnormals();
    if b1 {
        s.vectorize(RowsMem::<T, true> { p, d, range, y });
    } else {
        s.vectorize(RowsMem::<T, false> { p, d, range, y });
    }
}
