//! The AVX-512 kernels: [`super`]'s, with vectors of eight lanes (eight real modes, or four
//! complex modes as `[re_0..re_3, im_0..im_3]`, a vector). The layout is [`Packed`] with
//! `lanes = 8`; `swap` exchanges the two 256-bit halves. Half as many vectors a sample as the
//! AVX2 kernels for the same modes: the per-sample work (multiply-adds, loads, stores) about
//! halves.

use super::{sum_parts, Drive, FlushSubnormals, Packed};
use std::arch::x86_64::*;
use std::ops::Range;

/// Whether the CPU has AVX-512F (and AVX2 and FMA, which the shared output sums use).
pub(in crate::discrete) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f") && super::available()
}

/// Load vector `i` of `s`.
#[target_feature(enable = "avx512f")]
#[inline]
fn ld(s: &[f64], i: usize) -> __m512d {
    let c: &[f64; 8] = s[8 * i..8 * i + 8].try_into().expect("eight lanes");
    // SAFETY: `c` is eight f64.
    unsafe { _mm512_loadu_pd(c.as_ptr()) }
}

/// Store vector `i` of `s`.
#[target_feature(enable = "avx512f")]
#[inline]
fn st(s: &mut [f64], i: usize, v: __m512d) {
    let c: &mut [f64; 8] = (&mut s[8 * i..8 * i + 8]).try_into().expect("eight lanes");
    // SAFETY: `c` is eight f64.
    unsafe { _mm512_storeu_pd(c.as_mut_ptr(), v) }
}

/// The two 256-bit halves exchanged: `[re.., im..]` -> `[im.., re..]`.
#[target_feature(enable = "avx512f")]
#[inline]
fn swap(v: __m512d) -> __m512d {
    _mm512_shuffle_f64x2::<0x4E>(v, v)
}

/// The real parts of a complex vector (its low four lanes).
#[target_feature(enable = "avx512f")]
#[inline]
fn re_part(v: __m512d) -> __m512d {
    _mm512_maskz_mov_pd(0x0F, v)
}

/// The eight lanes folded to four (`l_i + l_(i+4)`), for the AVX2 output sums.
#[target_feature(enable = "avx512f,avx2,fma")]
#[inline]
fn fold(v: __m512d) -> __m256d {
    _mm256_add_pd(_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v))
}

/// Sum of the eight lanes.
#[target_feature(enable = "avx512f,avx2,fma")]
#[inline]
fn hsum(v: __m512d) -> f64 {
    super::hsum(fold(v))
}

/// [`super::value_regs`] in eight lanes: `VR` real and `VC` complex vectors in registers.
///
/// # Safety
/// The CPU must support AVX-512F, AVX2 and FMA; `p` has eight lanes and one row of `VR` real and
/// `VC` complex vectors.
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn value_regs<const VR: usize, const VC: usize, const B1: bool>(
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    y: &mut [f64],
) {
    assert!(p.lanes == 8 && p.rows == 1 && p.vr == VR && p.vc == VC && range.start > d.m);
    let z = _mm512_setzero_pd();
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
    const BLOCK: usize = 256;
    let mut parts = [_mm256_setzero_pd(); BLOCK];
    let mut k0 = range.start;
    while k0 < range.end {
        let k1 = (k0 + BLOCK).min(range.end);
        let u = &d.u[k0 - m - 1..k1 - m];
        for (acc, w) in parts.iter_mut().zip(u.windows(2)) {
            let (va, vb) = (_mm512_set1_pd(w[1]), _mm512_set1_pd(w[0]));
            let (mut acc0, mut acc1) = (z, z);
            for j in 0..VR {
                if j % 2 == 0 {
                    acc0 = _mm512_add_pd(acc0, xr[j]);
                } else {
                    acc1 = _mm512_add_pd(acc1, xr[j]);
                }
                let mut t = _mm512_mul_pd(b0r[j], va);
                if B1 {
                    t = _mm512_fmadd_pd(b1r[j], vb, t);
                }
                xr[j] = _mm512_fmadd_pd(phr[j], xr[j], t);
            }
            for c in 0..VC {
                acc1 = _mm512_add_pd(acc1, re_part(xc[c]));
                let mut t = _mm512_mul_pd(b0c[c], va);
                if B1 {
                    t = _mm512_fmadd_pd(b1c[c], vb, t);
                }
                let t2 = _mm512_mul_pd(p2c[c], swap(xc[c]));
                xc[c] = _mm512_add_pd(_mm512_fmadd_pd(p1c[c], xc[c], t), t2);
            }
            *acc = fold(_mm512_add_pd(acc0, acc1));
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

/// [`super::rows_mem`] in eight lanes.
///
/// # Safety
/// The CPU must support AVX-512F, AVX2 and FMA; `p` has eight lanes and `N + 1` rows.
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn rows_mem<const N: usize, const B1: bool>(
    p: &mut Packed,
    d: &Drive<'_>,
    range: Range<usize>,
    out: &mut impl FnMut(usize, f64, &[f64; N]),
) {
    assert!(p.lanes == 8 && p.rows == N + 1 && range.start > d.m && d.direct.len() == N + 1);
    let z = _mm512_setzero_pd();
    let (vr, v) = (p.vr, p.vr + p.vc);
    let val = N * v;
    // Every vector index below is `< (N + 1) v`: the loads and stores go through raw pointers
    // (no bounds check per access, the hot loop's main overhead) once the lengths are checked.
    let len = (N + 1) * v * 8;
    assert!([&p.phi1, &p.phi2, &p.b0, &p.b1, &p.x]
        .iter()
        .all(|a| a.len() == len));
    assert!(range.end <= d.u.len());
    let (phi1, phi2, b0, b1) = (
        p.phi1.as_ptr(),
        p.phi2.as_ptr(),
        p.b0.as_ptr(),
        p.b1.as_ptr(),
    );
    let x = p.x.as_mut_ptr();
    // SAFETY (for `ld` and `st` below): `i < (N + 1) v`, so lanes `8 i .. 8 i + 8` are inside
    // the arrays of `len` f64 checked above; `x` is not aliased while this function runs.
    let ld = |a: *const f64, i: usize| unsafe { _mm512_loadu_pd(a.add(8 * i)) };
    let st = |a: *mut f64, i: usize, w: __m512d| unsafe { _mm512_storeu_pd(a.add(8 * i), w) };
    let input = |o: usize, va: __m512d, vb: __m512d| {
        let t = _mm512_mul_pd(ld(b0, o), va);
        if B1 {
            _mm512_fmadd_pd(ld(b1, o), vb, t)
        } else {
            t
        }
    };
    for k in range {
        let (a, b) = (d.u[k - d.m], d.u[k - d.m - 1]);
        let (va, vb) = (_mm512_set1_pd(a), _mm512_set1_pd(b));
        let mut acc = [z; N];
        let mut accv = z;
        for j in 0..vr {
            let xv = ld(x, val + j);
            let ph = ld(phi1, val + j);
            for (r, ar) in acc.iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = _mm512_add_pd(*ar, dx);
                let t = _mm512_fmadd_pd(ld(phi1, o), xv, input(o, va, vb));
                st(x, o, _mm512_fmadd_pd(ph, dx, t));
            }
            accv = _mm512_add_pd(accv, xv);
            let t = input(val + j, va, vb);
            st(x, val + j, _mm512_fmadd_pd(ph, xv, t));
        }
        for j in vr..v {
            let xv = ld(x, val + j);
            let xs = swap(xv);
            let (p1, p2) = (ld(phi1, val + j), ld(phi2, val + j));
            for (r, ar) in acc.iter_mut().enumerate() {
                let o = r * v + j;
                let dx = ld(x, o);
                *ar = _mm512_add_pd(*ar, re_part(dx));
                let mut t = input(o, va, vb);
                t = _mm512_fmadd_pd(ld(phi1, o), xv, t);
                t = _mm512_fmadd_pd(ld(phi2, o), xs, t);
                t = _mm512_fmadd_pd(p2, swap(dx), t);
                st(x, o, _mm512_fmadd_pd(p1, dx, t));
            }
            accv = _mm512_add_pd(accv, re_part(xv));
            let mut t = input(val + j, va, vb);
            t = _mm512_fmadd_pd(p2, xs, t);
            st(x, val + j, _mm512_fmadd_pd(p1, xv, t));
        }
        let din = if d.direct_prev { b } else { a };
        let mut dd = [0.0; N];
        for r in 0..N {
            dd[r] = hsum(acc[r]) + d.direct[r] * din;
        }
        out(k, hsum(accv) + d.direct[N] * din, &dd);
    }
}

/// The value kernel for `p` (eight lanes, one row): in registers when the vectors fit, else
/// [`rows_mem`].
///
/// # Safety
/// The CPU must support AVX-512F, AVX2 and FMA ([`available`]).
pub(in crate::discrete) unsafe fn run_value(
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
    regs!(0 1 2 3 4 5 6);
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

/// The row kernel for `p` (eight lanes, `N + 1` rows).
///
/// # Safety
/// The CPU must support AVX-512F, AVX2 and FMA ([`available`]).
pub(in crate::discrete) unsafe fn run_rows<const N: usize>(
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
