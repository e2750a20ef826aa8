//! The AVX2 + FMA kernels of [`Simulator::run_into`]: the modes packed four to a 256-bit vector,
//! complex modes two to a vector, and the delayed input read straight from the input slice.
//!
//! Layout ([`Packed`]): `rows` rows (row `rows - 1` the values, rows `0..rows - 1` the derivative
//! parts of a [`crate::Dual`] simulation), each of `vr` real vectors (real mode `i` in vector
//! `i / 4`, lane `i % 4`) then `vc` complex vectors (complex modes `2c`, `2c + 1` of vector `c` as
//! `[re_0, re_1, im_0, im_1]`). A complex product `phi x` is then
//! `phi1 * x + phi2 * swap(x)` with `phi1 = [re_0, re_1, re_0, re_1]`,
//! `phi2 = [-im_0, -im_1, im_0, im_1]` and `swap` the exchange of the two 128-bit halves: the
//! same lane-wise multiply-adds as the real modes plus one permutation. Padding lanes are inert
//! (zero coefficients, zero state).
//!
//! The per-sample work is then, per vector and row, two or three fused multiply-adds (three more
//! for a complex vector) and one addition into the output: the value kernel keeps the whole state
//! in registers for up to 12 real and 2 complex vectors (48 real modes and 4 complex pairs); the
//! row kernel (dual numbers, or more modes) keeps it in memory, one pass over the vectors per
//! sample with the value of each mode loaded once for all its derivative rows.

use super::Simulator;
use crate::scalar::Real;
use std::arch::x86_64::*;
use std::ops::Range;

pub(super) mod wide;

#[cfg(test)]
thread_local! {
    /// Tests run the AVX2 kernels on a machine with AVX-512 too.
    static NARROW: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// `f` with the AVX2 kernels (`narrow`) or the widest the CPU has (tests).
#[cfg(test)]
pub(super) fn with_narrow<R>(narrow: bool, f: impl FnOnce() -> R) -> R {
    NARROW.with(|n| n.set(narrow));
    let r = f();
    NARROW.with(|n| n.set(false));
    r
}

/// Whether the AVX-512 kernels ([`wide`]) run: the CPU has AVX-512F.
pub(super) fn use_wide() -> bool {
    #[cfg(test)]
    if NARROW.with(|n| n.get()) {
        return false;
    }
    wide::available()
}

/// The modes of a [`Simulator`] packed for the kernels (see the module documentation).
pub(super) struct Packed {
    rows: usize,
    /// Lanes of a vector: 4 (AVX2) or 8 (AVX-512).
    lanes: usize,
    vr: usize,
    vc: usize,
    phi1: Vec<f64>,
    phi2: Vec<f64>,
    b0: Vec<f64>,
    b1: Vec<f64>,
    x: Vec<f64>,
}

impl Packed {
    /// Pack `sim`'s coefficients and state in vectors of `lanes` (4 or 8); `part(v, r)` is part
    /// `r` of `v` (`r = rows - 1` the value).
    pub(super) fn of<T: Real>(
        sim: &Simulator<T>,
        rows: usize,
        lanes: usize,
        part: impl Fn(T, usize) -> f64,
    ) -> Self {
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

    /// The state back into `sim`: `make(parts)` builds a scalar from its `rows` parts.
    pub(super) fn state_back<T: Real>(&self, sim: &mut Simulator<T>, make: impl Fn(&[f64]) -> T) {
        let (v, l, half) = (self.vr + self.vc, self.lanes, self.lanes / 2);
        let mut parts = vec![0.0; self.rows];
        for i in 0..sim.re_x.len() {
            for (r, q) in parts.iter_mut().enumerate() {
                *q = self.x[r * v * l + i];
            }
            sim.re_x[i] = make(&parts);
        }
        let mut im = vec![0.0; self.rows];
        for m in 0..sim.cx_x.len() {
            for r in 0..self.rows {
                let at = r * v * l + (self.vr + m / half) * l + m % half;
                parts[r] = self.x[at];
                im[r] = self.x[at + half];
            }
            sim.cx_x[m] = crate::cx::Cx::new(make(&parts), make(&im));
        }
    }
}

/// What a kernel reads besides the packed modes: the input, the whole-sample delay `m`
/// (`a_k = u[k - m]`, `b_k = u[k - m - 1]`, so `k >= m + 1`), the feed-through's parts (one per
/// row) and whether it sees `b_k` (a fractional-sample delay) instead of `a_k`.
pub(super) struct Drive<'a> {
    pub u: &'a [f64],
    pub m: usize,
    pub direct: &'a [f64],
    pub direct_prev: bool,
}

/// Horizontal sum of four lanes, `(l0 + l1) + (l2 + l3)`.
#[target_feature(enable = "avx2,fma")]
#[inline]
pub(super) fn hsum(v: __m256d) -> f64 {
    // (l0 + l1) + (l2 + l3), as `sum_parts` groups them: a sample's output does not depend on
    // where it falls in a block.
    let mut l = [0.0f64; 4];
    // SAFETY: `l` holds four f64.
    unsafe { _mm256_storeu_pd(l.as_mut_ptr(), v) };
    (l[0] + l[1]) + (l[2] + l[3])
}

/// `y[k] = ` the sum of the four lanes of `parts[k]`, four samples at a time.
#[target_feature(enable = "avx2,fma")]
#[inline]
pub(super) fn sum_parts(parts: &[__m256d], y: &mut [f64]) {
    let mut quads = parts.chunks_exact(4);
    let mut outs = y.chunks_exact_mut(4);
    for (q, o) in (&mut quads).zip(&mut outs) {
        // [p0_0 + p0_1, p1_0 + p1_1, p0_2 + p0_3, p1_2 + p1_3], the same for p2, p3
        let s01 = _mm256_hadd_pd(q[0], q[1]);
        let s23 = _mm256_hadd_pd(q[2], q[3]);
        let lo = _mm256_permute2f128_pd::<0x20>(s01, s23);
        let hi = _mm256_permute2f128_pd::<0x31>(s01, s23);
        let o: &mut [f64; 4] = o.try_into().expect("four samples");
        // SAFETY: `o` is four f64.
        unsafe { _mm256_storeu_pd(o.as_mut_ptr(), _mm256_add_pd(lo, hi)) };
    }
    for (q, o) in quads.remainder().iter().zip(outs.into_remainder()) {
        *o = hsum(*q);
    }
}

/// The two 128-bit halves exchanged: `[re_0, re_1, im_0, im_1]` -> `[im_0, im_1, re_0, re_1]`.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn swap(v: __m256d) -> __m256d {
    _mm256_permute2f128_pd::<0x01>(v, v)
}

/// The real parts of a complex vector (the lanes the output sums).
#[target_feature(enable = "avx2,fma")]
#[inline]
fn re_part(v: __m256d) -> __m256d {
    _mm256_blend_pd::<0b0011>(_mm256_setzero_pd(), v)
}

/// `beta0 a + beta1 b` of vector `o`: the input's part of a mode's update.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn input<const B1: bool>(b0: &[f64], b1: &[f64], o: usize, va: __m256d, vb: __m256d) -> __m256d {
    let t = _mm256_mul_pd(ld(b0, o), va);
    if B1 {
        _mm256_fmadd_pd(ld(b1, o), vb, t)
    } else {
        t
    }
}

/// Load vector `i` of `s`.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn ld(s: &[f64], i: usize) -> __m256d {
    let c: &[f64; 4] = s[4 * i..4 * i + 4].try_into().expect("four lanes");
    // SAFETY: `c` is four f64.
    unsafe { _mm256_loadu_pd(c.as_ptr()) }
}

/// Store vector `i` of `s`.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn st(s: &mut [f64], i: usize, v: __m256d) {
    let c: &mut [f64; 4] = (&mut s[4 * i..4 * i + 4]).try_into().expect("four lanes");
    // SAFETY: `c` is four f64.
    unsafe { _mm256_storeu_pd(c.as_mut_ptr(), v) }
}

/// The value kernel with the whole state in registers: `VR` real and `VC` complex vectors, `B1`
/// whether any `beta1` is nonzero. Writes `y[k]` for `k` in `range`.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `p` has one row of `VR` real and `VC` complex vectors.
#[target_feature(enable = "avx2,fma")]
unsafe fn value_regs<const VR: usize, const VC: usize, const B1: bool>(
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    y: &mut [f64],
) {
    assert!(p.lanes == 4 && p.rows == 1 && p.vr == VR && p.vc == VC && range.start > d.m);
    let z = _mm256_setzero_pd();
    let (mut xr, mut phr, mut b0r, mut b1r) = ([z; VR], [z; VR], [z; VR], [z; VR]);
    for j in 0..VR {
        (xr[j], phr[j], b0r[j], b1r[j]) = (ld(&p.x, j), ld(&p.phi1, j), ld(&p.b0, j), ld(&p.b1, j));
    }
    let (mut xc, mut p1c, mut p2c, mut b0c, mut b1c) =
        ([z; VC], [z; VC], [z; VC], [z; VC], [z; VC]);
    for c in 0..VC {
        let j = VR + c;
        (xc[c], p1c[c], p2c[c]) = (ld(&p.x, j), ld(&p.phi1, j), ld(&p.phi2, j));
        (b0c[c], b1c[c]) = (ld(&p.b0, j), ld(&p.b1, j));
    }
    let m = d.m;
    // The output's four partial sums of each sample are kept for a block and summed four samples
    // at a time (a transpose by `hadd`), off the loop-carried path.
    const BLOCK: usize = 256;
    let mut parts = [z; BLOCK];
    let mut k0 = range.start;
    while k0 < range.end {
        let k1 = (k0 + BLOCK).min(range.end);
        let u = &d.u[k0 - m - 1..k1 - m];
        for (acc, w) in parts.iter_mut().zip(u.windows(2)) {
            let (va, vb) = (_mm256_set1_pd(w[1]), _mm256_set1_pd(w[0]));
            let (mut acc0, mut acc1) = (z, z);
            for j in 0..VR {
                if j % 2 == 0 {
                    acc0 = _mm256_add_pd(acc0, xr[j]);
                } else {
                    acc1 = _mm256_add_pd(acc1, xr[j]);
                }
                let mut t = _mm256_mul_pd(b0r[j], va);
                if B1 {
                    t = _mm256_fmadd_pd(b1r[j], vb, t);
                }
                xr[j] = _mm256_fmadd_pd(phr[j], xr[j], t);
            }
            for c in 0..VC {
                acc1 = _mm256_add_pd(acc1, re_part(xc[c]));
                let mut t = _mm256_mul_pd(b0c[c], va);
                if B1 {
                    t = _mm256_fmadd_pd(b1c[c], vb, t);
                }
                let t2 = _mm256_mul_pd(p2c[c], swap(xc[c]));
                xc[c] = _mm256_add_pd(_mm256_fmadd_pd(p1c[c], xc[c], t), t2);
            }
            *acc = _mm256_add_pd(acc0, acc1);
        }
        sum_parts(&parts[..k1 - k0], &mut y[k0..k1]);
        if d.direct[0] != 0.0 {
            let back = m + usize::from(d.direct_prev);
            for k in k0..k1 {
                y[k] += d.direct[0] * d.u[k - back];
            }
        }
        k0 = k1;
    }
    for j in 0..VR {
        st(&mut p.x, j, xr[j]);
    }
    for c in 0..VC {
        st(&mut p.x, VR + c, xc[c]);
    }
}

/// The row kernel: `N` derivative rows and the value row, the state in memory; calls
/// `out(k, value, derivatives)` for `k` in `range`. Per vector, each derivative row is
/// `dx' = phi dx + dphi x + dbeta0 a + dbeta1 b` with the value `x` before its own update.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `p` has `N + 1` rows.
#[target_feature(enable = "avx2,fma")]
unsafe fn rows_mem<const N: usize, const B1: bool>(
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    out: &mut impl FnMut(usize, f64, &[f64; N]),
) {
    assert!(p.lanes == 4 && p.rows == N + 1 && range.start > d.m && d.direct.len() == N + 1);
    let z = _mm256_setzero_pd();
    let (vr, v) = (p.vr, p.vr + p.vc);
    let val = N * v;
    let (phi1, phi2, b0, b1) = (&p.phi1[..], &p.phi2[..], &p.b0[..], &p.b1[..]);
    let x = &mut p.x[..];
    for k in range {
        let (a, b) = (d.u[k - d.m], d.u[k - d.m - 1]);
        let (va, vb) = (_mm256_set1_pd(a), _mm256_set1_pd(b));
        let mut acc = [z; N];
        let mut accv = z;
        for j in 0..vr {
            let xv = ld(x, val + j);
            let ph = ld(phi1, val + j);
            for (r, ar) in acc.iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = _mm256_add_pd(*ar, dx);
                let t = _mm256_fmadd_pd(ld(phi1, o), xv, input::<B1>(b0, b1, o, va, vb));
                st(x, o, _mm256_fmadd_pd(ph, dx, t));
            }
            accv = _mm256_add_pd(accv, xv);
            let t = input::<B1>(b0, b1, val + j, va, vb);
            st(x, val + j, _mm256_fmadd_pd(ph, xv, t));
        }
        for j in vr..v {
            let xv = ld(x, val + j);
            let xs = swap(xv);
            let (p1, p2) = (ld(phi1, val + j), ld(phi2, val + j));
            for (r, ar) in acc.iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = _mm256_add_pd(*ar, re_part(dx));
                let mut t = input::<B1>(b0, b1, o, va, vb);
                t = _mm256_fmadd_pd(ld(phi1, o), xv, t);
                t = _mm256_fmadd_pd(ld(phi2, o), xs, t);
                t = _mm256_fmadd_pd(p2, swap(dx), t);
                st(x, o, _mm256_fmadd_pd(p1, dx, t));
            }
            accv = _mm256_add_pd(accv, re_part(xv));
            let mut t = input::<B1>(b0, b1, val + j, va, vb);
            t = _mm256_fmadd_pd(p2, xs, t);
            st(x, val + j, _mm256_fmadd_pd(p1, xv, t));
        }
        let din = if d.direct_prev { b } else { a };
        let mut dd = [0.0; N];
        for r in 0..N {
            dd[r] = hsum(acc[r]) + d.direct[r] * din;
        }
        out(k, hsum(accv) + d.direct[N] * din, &dd);
    }
}

/// Whether the CPU has AVX2 and FMA (the kernels here need both).
pub(super) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// Subnormal numbers flushed to zero (MXCSR's FTZ and DAZ bits) while it lives, the caller's
/// MXCSR restored when it drops.
///
/// A free response (an initial-state level's sensitivity, a simulation of a quiet input) decays
/// through the subnormal range, where every add and multiply takes a microcode assist about a
/// hundred times slower than a normal one: a level column of 1e6 samples took most of a
/// Jacobian's time. Values below `2.2e-308` are far under the rounding of any output, so the
/// results do not change visibly (the kernel tests compare against the scalar step to 1e-12).
pub(super) struct FlushSubnormals(u32);

impl FlushSubnormals {
    /// Flush-to-zero (bit 15) and denormals-are-zero (bit 6).
    const BITS: u32 = (1 << 15) | (1 << 6);

    #[inline]
    pub(super) fn new() -> Self {
        let mut old: u32 = 0;
        // SAFETY: `stmxcsr` writes the 4-byte register to the given address; `ldmxcsr` loads a
        // value that differs from the current one only in the FTZ and DAZ bits, which SSE2
        // (baseline on x86-64) defines.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut old, options(nostack, preserves_flags));
            let new = old | Self::BITS;
            std::arch::asm!("ldmxcsr [{}]", in(reg) &new, options(nostack, preserves_flags));
        }
        Self(old)
    }
}

impl Drop for FlushSubnormals {
    #[inline]
    fn drop(&mut self) {
        // SAFETY: restores the value read in `new`.
        unsafe {
            std::arch::asm!("ldmxcsr [{}]", in(reg) &self.0, options(nostack, preserves_flags));
        }
    }
}

/// The value kernel for `p` (one row): in registers when the vectors fit, else [`rows_mem`].
///
/// # Safety
/// The CPU must support AVX2 and FMA ([`available`]).
pub(super) unsafe fn run_value(
    p: &mut Packed,
    d: &Drive<'_>,
    b1: bool,
    range: Range<usize>,
    y: &mut [f64],
) {
    let _ftz = FlushSubnormals::new();
    macro_rules! regs {
        ($($vr:literal)*) => {
            match (p.vr, p.vc, b1) {
                $(
                    ($vr, 0, false) => return unsafe { value_regs::<$vr, 0, false>(p, d, range, y) },
                    ($vr, 0, true) => return unsafe { value_regs::<$vr, 0, true>(p, d, range, y) },
                    ($vr, 1, false) => return unsafe { value_regs::<$vr, 1, false>(p, d, range, y) },
                    ($vr, 1, true) => return unsafe { value_regs::<$vr, 1, true>(p, d, range, y) },
                    ($vr, 2, false) => return unsafe { value_regs::<$vr, 2, false>(p, d, range, y) },
                    ($vr, 2, true) => return unsafe { value_regs::<$vr, 2, true>(p, d, range, y) },
                )*
                _ => {}
            }
        };
    }
    regs!(0 1 2 3 4 5 6 7 8 9 10 11 12);
    let mut out = |k: usize, v: f64, _: &[f64; 0]| y[k] = v;
    // SAFETY: as this function's.
    unsafe {
        if b1 {
            rows_mem::<0, true>(p, d, range, &mut out);
        } else {
            rows_mem::<0, false>(p, d, range, &mut out);
        }
    }
}

/// The row kernel for `p` (`N + 1` rows).
///
/// # Safety
/// The CPU must support AVX2 and FMA ([`available`]).
pub(super) unsafe fn run_rows<const N: usize>(
    p: &mut Packed,
    d: &Drive<'_>,
    b1: bool,
    range: Range<usize>,
    out: &mut impl FnMut(usize, f64, &[f64; N]),
) {
    let _ftz = FlushSubnormals::new();
    // SAFETY: as this function's.
    unsafe {
        if b1 {
            rows_mem::<N, true>(p, d, range, out);
        } else {
            rows_mem::<N, false>(p, d, range, out);
        }
    }
}
