//! The instruction sets the simulation kernels are compiled for, as values: [`Isa`] names one
//! (the widest the CPU has, [`Isa::detect`], or any other it runs, for tests), and each set is a
//! type implementing [`Simd`] (a vector of `f64` lanes and its operations). A kernel is written
//! once over `S: Simd` and compiled for each set by [`Simd::vectorize`], which runs it inside a
//! function built with that set's target features (the style of the `pulp` crate, by hand: a few
//! operations, no dependency).
//!
//! [`Portable`] is plain Rust on four-lane arrays (unfused multiply-adds) and runs on every CPU;
//! on x86-64, [`Avx2`] (AVX2 and FMA, four lanes) and [`Avx512`] (AVX-512F, eight lanes) are
//! tokens that exist only where the CPU has those instructions ([`Avx2::new`], [`Avx512::new`]).
//!
//! A complex vector holds `LANES / 2` complex numbers, the real parts in the low half and the
//! imaginary parts in the high half: [`Simd::swap`] exchanges the halves, [`Simd::re_part`] keeps
//! the low one.

/// An operation compiled for an instruction set ([`Simd::vectorize`]).
pub(crate) trait WithSimd {
    /// What it returns.
    type Output;
    /// Run with the set `s`. Implementations are `#[inline(always)]`, so that the body is
    /// compiled inside [`Simd::vectorize`]'s function with the set's target features.
    fn with_simd<S: Simd>(self, s: S) -> Self::Output;
}

/// A vector instruction set: vectors of [`Simd::LANES`] `f64` lanes. Every method is
/// `#[inline(always)]`: it is compiled where it is called, inside [`Simd::vectorize`].
pub(crate) trait Simd: Copy {
    /// Lanes of a vector (even).
    const LANES: usize;
    /// Whether [`Simd::fma`] rounds once (a fused multiply-add).
    const FUSED: bool;
    /// A vector.
    type V: Copy;
    /// A sample's partial sums as [`Simd::sum_parts`] takes them.
    type Part: Copy;
    /// What [`Simd::flush_subnormals`] returns: a guard that restores the caller's mode.
    type Flush;

    /// Every lane `x`.
    fn splat(self, x: f64) -> Self::V;
    /// Lane-wise `a + b`.
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane-wise `a b`.
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane-wise `a b + c` (rounded once when [`Simd::FUSED`]).
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// The two halves exchanged: `[re.., im..]` -> `[im.., re..]`.
    fn swap(self, v: Self::V) -> Self::V;
    /// The low half (the real parts of a complex vector), the high half zero.
    fn re_part(self, v: Self::V) -> Self::V;
    /// The vector at `p`.
    ///
    /// # Safety
    /// `p .. p + LANES` must be readable `f64`s.
    unsafe fn load(self, p: *const f64) -> Self::V;
    /// `v` stored at `p`.
    ///
    /// # Safety
    /// `p .. p + LANES` must be writable `f64`s.
    unsafe fn store(self, p: *mut f64, v: Self::V);
    /// A sample's partial sums kept for [`Simd::sum_parts`].
    fn fold(self, v: Self::V) -> Self::Part;
    /// The zero [`Simd::Part`].
    fn part_zero(self) -> Self::Part;
    /// `y[k] = ` the sum of the lanes of `parts[k]`, as [`Simd::hsum`] groups them.
    fn sum_parts(self, parts: &[Self::Part], y: &mut [f64]);
    /// The sum of the lanes of `v`, in a fixed grouping (a sample's output does not depend on
    /// where it falls in a block).
    fn hsum(self, v: Self::V) -> f64;
    /// Subnormal numbers flushed to zero while the guard lives, where the set does that (the
    /// x86-64 sets: MXCSR's FTZ and DAZ bits); nothing for [`Portable`].
    fn flush_subnormals(self) -> Self::Flush;
    /// `op` compiled for this set.
    fn vectorize<Op: WithSimd>(self, op: Op) -> Op::Output;
    /// `k`'s instance for `vr` real and `vc` complex vectors, run, if this set has one of that
    /// size (AVX2: up to 12 real vectors, AVX-512: 6, that is 48 real modes; at most two complex
    /// vectors; none for [`Portable`]): `false` if not.
    fn value_in_registers<K: RegKernel>(self, vr: usize, vc: usize, b1: bool, k: K) -> bool;
}

/// A kernel with its state in registers, instantiated by [`Simd::value_in_registers`] for the
/// sizes a set has an instance of: `VR` vectors of real modes, `VC` of complex modes, `B1` with or
/// without `beta1`.
pub(crate) trait RegKernel {
    /// Run the instance of this size with the set `s`.
    fn run<const VR: usize, const VC: usize, const B1: bool, S: Simd>(self, s: S);
}

/// The sizes the value kernel keeps in registers, one instance (compiled for the set) each:
/// `$vr` vectors of real modes, 0 to 2 of complex modes, with or without `beta1`.
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_macros))]
macro_rules! value_in_registers {
    ($($vr:literal)*) => {
        #[inline(always)]
        fn value_in_registers<K: RegKernel>(self, vr: usize, vc: usize, b1: bool, k: K) -> bool {
            match (vr, vc, b1) {
                $(
                    ($vr, 0, false) => k.run::<$vr, 0, false, Self>(self),
                    ($vr, 0, true) => k.run::<$vr, 0, true, Self>(self),
                    ($vr, 1, false) => k.run::<$vr, 1, false, Self>(self),
                    ($vr, 1, true) => k.run::<$vr, 1, true, Self>(self),
                    ($vr, 2, false) => k.run::<$vr, 2, false, Self>(self),
                    ($vr, 2, true) => k.run::<$vr, 2, true, Self>(self),
                )*
                _ => return false,
            }
            true
        }
    };
}

/// Plain Rust on four-lane arrays: every CPU. Unfused multiply-adds; subnormals not flushed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

impl Simd for Portable {
    const LANES: usize = 4;
    const FUSED: bool = false;
    type V = [f64; 4];
    type Part = [f64; 4];
    type Flush = ();

    #[inline(always)]
    fn splat(self, x: f64) -> [f64; 4] {
        [x; 4]
    }
    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] + b[l])
    }
    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] * b[l])
    }
    #[inline(always)]
    fn fma(self, a: [f64; 4], b: [f64; 4], c: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] * b[l] + c[l])
    }
    #[inline(always)]
    fn swap(self, v: [f64; 4]) -> [f64; 4] {
        [v[2], v[3], v[0], v[1]]
    }
    #[inline(always)]
    fn re_part(self, v: [f64; 4]) -> [f64; 4] {
        [v[0], v[1], 0.0, 0.0]
    }
    #[inline(always)]
    unsafe fn load(self, p: *const f64) -> [f64; 4] {
        // SAFETY: the caller's (four readable f64).
        unsafe { p.cast::<[f64; 4]>().read_unaligned() }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f64, v: [f64; 4]) {
        // SAFETY: the caller's (four writable f64).
        unsafe { p.cast::<[f64; 4]>().write_unaligned(v) }
    }
    #[inline(always)]
    fn fold(self, v: [f64; 4]) -> [f64; 4] {
        v
    }
    #[inline(always)]
    fn part_zero(self) -> [f64; 4] {
        [0.0; 4]
    }
    #[inline(always)]
    fn sum_parts(self, parts: &[[f64; 4]], y: &mut [f64]) {
        for (p, o) in parts.iter().zip(y) {
            *o = self.hsum(*p);
        }
    }
    #[inline(always)]
    fn hsum(self, v: [f64; 4]) -> f64 {
        (v[0] + v[1]) + (v[2] + v[3])
    }
    #[inline(always)]
    fn flush_subnormals(self) {}
    #[inline(always)]
    fn vectorize<Op: WithSimd>(self, op: Op) -> Op::Output {
        op.with_simd(self)
    }
    #[inline(always)]
    fn value_in_registers<K: RegKernel>(self, _: usize, _: usize, _: bool, _: K) -> bool {
        false
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x86::{Avx2, Avx512};

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{RegKernel, Simd, WithSimd};
    use std::arch::x86_64::*;

    /// AVX2 and FMA: four lanes. Only [`Avx2::new`] makes one, on a CPU that has both.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx2(());

    impl Avx2 {
        /// The token, if the CPU has AVX2 and FMA.
        pub(crate) fn new() -> Option<Self> {
            (is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"))
                .then_some(Self(()))
        }
    }

    /// AVX-512F (and AVX2 and FMA, which its output sums use): eight lanes. Only
    /// [`Avx512::new`] makes one, on a CPU that has them.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx512(());

    impl Avx512 {
        /// The token, if the CPU has AVX-512F, AVX2 and FMA.
        pub(crate) fn new() -> Option<Self> {
            (is_x86_feature_detected!("avx512f") && Avx2::new().is_some()).then_some(Self(()))
        }
    }

    // SAFETY (every `unsafe` block calling an intrinsic below): the token exists only on a CPU
    // with the instructions (`Avx2::new`, `Avx512::new`).

    /// `y[k] = ` the sum of the four lanes of `parts[k]`, `(l0 + l1) + (l2 + l3)`, four
    /// samples at a time (a transpose by `hadd`).
    #[inline(always)]
    fn sum_parts4(parts: &[__m256d], y: &mut [f64]) {
        let mut quads = parts.chunks_exact(4);
        let mut outs = y.chunks_exact_mut(4);
        for (q, o) in (&mut quads).zip(&mut outs) {
            let o: &mut [f64; 4] = o.try_into().expect("four samples");
            // SAFETY: AVX2 (see above); `o` is four f64.
            unsafe {
                // [p0_0 + p0_1, p1_0 + p1_1, p0_2 + p0_3, p1_2 + p1_3], the same for p2, p3
                let s01 = _mm256_hadd_pd(q[0], q[1]);
                let s23 = _mm256_hadd_pd(q[2], q[3]);
                let lo = _mm256_permute2f128_pd::<0x20>(s01, s23);
                let hi = _mm256_permute2f128_pd::<0x31>(s01, s23);
                _mm256_storeu_pd(o.as_mut_ptr(), _mm256_add_pd(lo, hi));
            }
        }
        for (q, o) in quads.remainder().iter().zip(outs.into_remainder()) {
            *o = hsum4(*q);
        }
    }

    /// The sum of four lanes, `(l0 + l1) + (l2 + l3)`, as [`sum_parts4`] groups them.
    #[inline(always)]
    fn hsum4(v: __m256d) -> f64 {
        let mut l = [0.0f64; 4];
        // SAFETY: AVX (see above); `l` holds four f64.
        unsafe { _mm256_storeu_pd(l.as_mut_ptr(), v) };
        (l[0] + l[1]) + (l[2] + l[3])
    }

    impl Simd for Avx2 {
        const LANES: usize = 4;
        const FUSED: bool = true;
        type V = __m256d;
        type Part = __m256d;
        type Flush = FlushSubnormals;

        #[inline(always)]
        fn splat(self, x: f64) -> __m256d {
            unsafe { _mm256_set1_pd(x) }
        }
        #[inline(always)]
        fn add(self, a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_add_pd(a, b) }
        }
        #[inline(always)]
        fn mul(self, a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_mul_pd(a, b) }
        }
        #[inline(always)]
        fn fma(self, a: __m256d, b: __m256d, c: __m256d) -> __m256d {
            unsafe { _mm256_fmadd_pd(a, b, c) }
        }
        #[inline(always)]
        fn swap(self, v: __m256d) -> __m256d {
            unsafe { _mm256_permute2f128_pd::<0x01>(v, v) }
        }
        #[inline(always)]
        fn re_part(self, v: __m256d) -> __m256d {
            unsafe { _mm256_blend_pd::<0b0011>(_mm256_setzero_pd(), v) }
        }
        #[inline(always)]
        unsafe fn load(self, p: *const f64) -> __m256d {
            // SAFETY: AVX; `p` as the caller promises.
            unsafe { _mm256_loadu_pd(p) }
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut f64, v: __m256d) {
            // SAFETY: AVX; `p` as the caller promises.
            unsafe { _mm256_storeu_pd(p, v) }
        }
        #[inline(always)]
        fn fold(self, v: __m256d) -> __m256d {
            v
        }
        #[inline(always)]
        fn part_zero(self) -> __m256d {
            unsafe { _mm256_setzero_pd() }
        }
        #[inline(always)]
        fn sum_parts(self, parts: &[__m256d], y: &mut [f64]) {
            sum_parts4(parts, y);
        }
        #[inline(always)]
        fn hsum(self, v: __m256d) -> f64 {
            hsum4(v)
        }
        #[inline(always)]
        fn flush_subnormals(self) -> FlushSubnormals {
            FlushSubnormals::new()
        }
        #[inline(always)]
        fn vectorize<Op: WithSimd>(self, op: Op) -> Op::Output {
            #[target_feature(enable = "avx2,fma")]
            fn imp<Op: WithSimd>(s: Avx2, op: Op) -> Op::Output {
                op.with_simd(s)
            }
            // SAFETY: the token exists only on a CPU with AVX2 and FMA.
            unsafe { imp(self, op) }
        }
        value_in_registers!(0 1 2 3 4 5 6 7 8 9 10 11 12);
    }

    impl Simd for Avx512 {
        const LANES: usize = 8;
        const FUSED: bool = true;
        type V = __m512d;
        /// The eight lanes folded to four (`l_i + l_(i+4)`) for the AVX2 output sums.
        type Part = __m256d;
        type Flush = FlushSubnormals;

        #[inline(always)]
        fn splat(self, x: f64) -> __m512d {
            unsafe { _mm512_set1_pd(x) }
        }
        #[inline(always)]
        fn add(self, a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_add_pd(a, b) }
        }
        #[inline(always)]
        fn mul(self, a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_mul_pd(a, b) }
        }
        #[inline(always)]
        fn fma(self, a: __m512d, b: __m512d, c: __m512d) -> __m512d {
            unsafe { _mm512_fmadd_pd(a, b, c) }
        }
        #[inline(always)]
        fn swap(self, v: __m512d) -> __m512d {
            unsafe { _mm512_shuffle_f64x2::<0x4E>(v, v) }
        }
        #[inline(always)]
        fn re_part(self, v: __m512d) -> __m512d {
            unsafe { _mm512_maskz_mov_pd(0x0F, v) }
        }
        #[inline(always)]
        unsafe fn load(self, p: *const f64) -> __m512d {
            // SAFETY: AVX-512F; `p` as the caller promises.
            unsafe { _mm512_loadu_pd(p) }
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut f64, v: __m512d) {
            // SAFETY: AVX-512F; `p` as the caller promises.
            unsafe { _mm512_storeu_pd(p, v) }
        }
        #[inline(always)]
        fn fold(self, v: __m512d) -> __m256d {
            unsafe { _mm256_add_pd(_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v)) }
        }
        #[inline(always)]
        fn part_zero(self) -> __m256d {
            unsafe { _mm256_setzero_pd() }
        }
        #[inline(always)]
        fn sum_parts(self, parts: &[__m256d], y: &mut [f64]) {
            sum_parts4(parts, y);
        }
        #[inline(always)]
        fn hsum(self, v: __m512d) -> f64 {
            hsum4(self.fold(v))
        }
        #[inline(always)]
        fn flush_subnormals(self) -> FlushSubnormals {
            FlushSubnormals::new()
        }
        #[inline(always)]
        fn vectorize<Op: WithSimd>(self, op: Op) -> Op::Output {
            #[target_feature(enable = "avx512f,avx2,fma")]
            fn imp<Op: WithSimd>(s: Avx512, op: Op) -> Op::Output {
                op.with_simd(s)
            }
            // SAFETY: the token exists only on a CPU with AVX-512F, AVX2 and FMA.
            unsafe { imp(self, op) }
        }
        value_in_registers!(0 1 2 3 4 5 6);
    }

    /// Subnormal numbers flushed to zero (MXCSR's FTZ and DAZ bits) while it lives, the caller's
    /// MXCSR restored when it drops.
    ///
    /// A free response (an initial-state level's sensitivity, a simulation of a quiet input)
    /// decays through the subnormal range, where every add and multiply takes a microcode assist
    /// about a hundred times slower than a normal one: a level column of 1e6 samples took most of
    /// a Jacobian's time. Values below `2.2e-308` are far under the rounding of any output, so the
    /// results do not change visibly (the kernel tests compare against the scalar step to 1e-12).
    pub(crate) struct FlushSubnormals(u32);

    impl FlushSubnormals {
        /// Flush-to-zero (bit 15) and denormals-are-zero (bit 6).
        const BITS: u32 = (1 << 15) | (1 << 6);

        #[inline]
        pub(crate) fn new() -> Self {
            let mut old: u32 = 0;
            // SAFETY: `stmxcsr` writes the 4-byte register to the given address; `ldmxcsr` loads
            // a value that differs from the current one only in the FTZ and DAZ bits, which SSE2
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
}

/// An instruction set to run the kernels in, as a value: the widest the CPU has
/// ([`Isa::detect`], what [`crate::Simulator::run_into`] uses) or any other it runs
/// ([`Isa::available`]: the tests run each on the same input).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Isa {
    /// [`Portable`].
    Portable,
    /// [`Avx2`].
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    /// [`Avx512`].
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Isa {
    /// The widest set the CPU has.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(s) = Avx512::new() {
                return Self::Avx512(s);
            }
            if let Some(s) = Avx2::new() {
                return Self::Avx2(s);
            }
        }
        Self::Portable
    }

    /// Every set the CPU runs, [`Isa::Portable`] first, the widest last.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn available() -> Vec<Self> {
        #[allow(unused_mut)]
        let mut v = vec![Self::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            v.extend(Avx2::new().map(Self::Avx2));
            v.extend(Avx512::new().map(Self::Avx512));
        }
        v
    }

    /// The set's name (test messages).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Portable => "portable",
            #[cfg(target_arch = "x86_64")]
            Self::Avx2(_) => "avx2",
            #[cfg(target_arch = "x86_64")]
            Self::Avx512(_) => "avx512",
        }
    }
}

/// `$body` with `$s` bound to the set `$isa` names (a value of its [`Simd`] type): the body is
/// compiled once per set.
macro_rules! with_isa {
    ($isa:expr, $s:ident => $body:expr) => {
        match $isa {
            $crate::discrete::isa::Isa::Portable => {
                let $s = $crate::discrete::isa::Portable;
                $body
            }
            #[cfg(target_arch = "x86_64")]
            $crate::discrete::isa::Isa::Avx2($s) => $body,
            #[cfg(target_arch = "x86_64")]
            $crate::discrete::isa::Isa::Avx512($s) => $body,
        }
    };
}
pub(crate) use with_isa;
