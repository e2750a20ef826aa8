//! Discrete Fourier transforms of real records, the one implementation of the workspace: the
//! spectrum at the `n/2 + 1` bins of a record by FFT ([`rfft`], realfft/rustfft, `O(n log n)`
//! for any `n`), and the DFT at one arbitrary frequency by the direct sum ([`dft_at`], `O(n)`).
//!
//! Both compute `X(w) = sum_{k=0}^{n-1} x_k e^(-j w k)`, `w` in radians per sample; the bins of
//! [`rfft`] are `w = 2 pi m / n`, `m = 0..=n/2`.

use num_complex::Complex64;

/// `X(w) = sum_k x_k e^(-j w k)` at one angular step `w` (radians per sample), by the direct sum
/// in four interleaved lanes (samples `4i + l`, each lane's twiddle advanced by a rotation of
/// `4w`: four independent recurrences instead of one chain of dependent complex products; the
/// rounding of each lane's twiddle drifts by about `n/4` ulps over the record).
pub fn dft_at(x: &[f64], w: f64) -> Complex64 {
    let rot = Complex64::from_polar(1.0, -w);
    let rot4 = Complex64::from_polar(1.0, -4.0 * w);
    let (mut zr, mut zi) = ([0.0f64; 4], [0.0f64; 4]);
    let mut z = Complex64::new(1.0, 0.0);
    for l in 0..4 {
        (zr[l], zi[l]) = (z.re, z.im);
        z *= rot;
    }
    let (mut sr, mut si) = ([0.0f64; 4], [0.0f64; 4]);
    let chunks = x.chunks_exact(4);
    let tail = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            sr[l] += zr[l] * c[l];
            si[l] += zi[l] * c[l];
            let (a, b) = (zr[l], zi[l]);
            zr[l] = a * rot4.re - b * rot4.im;
            zi[l] = a * rot4.im + b * rot4.re;
        }
    }
    for (l, &v) in tail.iter().enumerate() {
        sr[l] += zr[l] * v;
        si[l] += zi[l] * v;
    }
    Complex64::new(
        (sr[0] + sr[1]) + (sr[2] + sr[3]),
        (si[0] + si[1]) + (si[2] + si[3]),
    )
}

/// `x` with its mean removed, and its periodogram `|X_m|^2 / n` at the `n/2 + 1` bins of
/// [`rfft`] (a white sequence of variance `s^2` has `s^2` in every bin on average).
pub fn periodogram(x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let m = x.iter().sum::<f64>() / n.max(1) as f64;
    let x: Vec<f64> = x.iter().map(|v| v - m).collect();
    let p = rfft(&x).iter().map(|z| z.norm_sqr() / n as f64).collect();
    (x, p)
}

/// The spectrum of a real record at its `n/2 + 1` non-negative bins:
/// `X_m = sum_k x_k e^(-j 2 pi m k / n)`, `m = 0..=n/2` (`n = x.len()`), by a real-input FFT
/// (realfft on rustfft: mixed radix, Rader and Bluestein, so `O(n log n)` for any `n`). Empty for
/// an empty record.
pub fn rfft(x: &[f64]) -> Vec<Complex64> {
    let n = x.len();
    if n == 0 {
        return vec![];
    }
    let r2c = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = x.to_vec();
    let mut spectrum = r2c.make_output_vec();
    // The buffers come from the plan: their lengths are the ones `process` checks.
    r2c.process(&mut input, &mut spectrum)
        .expect("buffers made by the plan");
    spectrum
}

/// Linear convolutions of real sequences by FFT, the transform plans kept between calls
/// (Grunwald-Letnikov's long memory sums, [`crate::gl`]).
pub(crate) struct Convolver {
    planner: realfft::RealFftPlanner<f64>,
}

impl Convolver {
    pub(crate) fn new() -> Self {
        Self {
            planner: realfft::RealFftPlanner::new(),
        }
    }

    /// The spectrum of `x` zero-padded to `size` samples (`size >= x.len()`).
    pub(crate) fn spectrum(&mut self, x: &[f64], size: usize) -> Vec<Complex64> {
        let r2c = self.planner.plan_fft_forward(size);
        let mut input = vec![0.0; size];
        input[..x.len()].copy_from_slice(x);
        let mut out = r2c.make_output_vec();
        r2c.process(&mut input, &mut out)
            .expect("buffers made by the plan");
        out
    }

    /// The circular convolution of the two sequences whose `size`-point spectra are `a` and `b`
    /// (from [`Convolver::spectrum`]): the linear one wherever no product wraps around.
    pub(crate) fn convolve(&mut self, a: &[Complex64], b: &[Complex64], size: usize) -> Vec<f64> {
        let c2r = self.planner.plan_fft_inverse(size);
        let mut prod: Vec<Complex64> = a.iter().zip(b).map(|(x, y)| x * y).collect();
        // The products of two real sequences' spectra are real at 0 and at size/2; rounding
        // aside. The inverse transform wants them exactly real.
        prod[0].im = 0.0;
        if size.is_multiple_of(2) {
            prod[size / 2].im = 0.0;
        }
        let mut out = c2r.make_output_vec();
        c2r.process(&mut prod, &mut out)
            .expect("buffers made by the plan, real end bins");
        let scale = 1.0 / size as f64;
        out.iter_mut().for_each(|v| *v *= scale);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// The definition, term by term, each twiddle from its own exact angle (`m k mod n`, so no
    /// recurrence and no large arguments): the independent truth.
    fn direct(x: &[f64], m: usize) -> Complex64 {
        let n = x.len();
        x.iter()
            .enumerate()
            .map(|(k, &v)| {
                v * Complex64::from_polar(1.0, -2.0 * PI * ((m * k) % n) as f64 / n as f64)
            })
            .sum()
    }

    fn record(n: usize) -> Vec<f64> {
        // deterministic, not periodic in n: a sum of incommensurate tones and a ramp
        (0..n)
            .map(|k| {
                let t = k as f64;
                (0.37 * t).sin() + 0.5 * (1.91 * t + 0.3).cos() + 1e-3 * t - 0.2
            })
            .collect()
    }

    #[test]
    fn rfft_matches_the_direct_dft() {
        // even, odd, prime (Bluestein/Rader), power of two, a large composite
        for n in [1, 2, 3, 7, 64, 97, 1000, 4099] {
            let x = record(n);
            let s = rfft(&x);
            assert_eq!(s.len(), n / 2 + 1, "n = {n}");
            let scale: f64 = x.iter().map(|v| v.abs()).sum::<f64>().max(1.0);
            for (m, z) in s.iter().enumerate() {
                let d = direct(&x, m);
                // FFT rounding grows like log n ulps of the record's 1-norm; the direct sum's
                // like n ulps: 1e-11 of the norm is far above both (n <= 4099)
                assert!(
                    (z - d).norm() < 1e-11 * scale,
                    "n = {n}, bin {m}: {z} vs {d}"
                );
            }
        }
        assert!(rfft(&[]).is_empty());
    }

    /// A sine of amplitude `a` on bin `m` of a record with an offset: the periodogram removes
    /// the offset and puts `n a^2 / 4` in bin `m`, nothing elsewhere.
    #[test]
    fn the_periodogram_of_a_sine_is_one_bin() {
        let (n, m, a) = (64usize, 5usize, 2.0);
        let x: Vec<f64> = (0..n)
            .map(|k| 3.0 + a * (std::f64::consts::TAU * (m * k) as f64 / n as f64).sin())
            .collect();
        let (centred, p) = periodogram(&x);
        assert!(centred.iter().sum::<f64>().abs() < 1e-12);
        assert_eq!(p.len(), n / 2 + 1);
        for (k, v) in p.iter().enumerate() {
            let want = if k == m { n as f64 * a * a / 4.0 } else { 0.0 };
            assert!((v - want).abs() < 1e-9, "bin {k}: {v} against {want}");
        }
    }

    #[test]
    fn dft_at_matches_the_definition_between_bins() {
        for (x, w) in [500, 1001, 3, 0]
            .into_iter()
            .flat_map(|n| [0.0, 0.01, 0.3702, 1.0, 2.5, PI].map(|w| (record(n), w)))
        {
            let d: Complex64 = x
                .iter()
                .enumerate()
                .map(|(k, &v)| v * Complex64::from_polar(1.0, -w * k as f64))
                .sum();
            let z = dft_at(&x, w);
            assert!(
                (z - d).norm() < 1e-9 * (1.0 + d.norm()),
                "w = {w}: {z} vs {d}"
            );
        }
        // on a bin, the FFT's value
        let x = record(500);
        let s = rfft(&x);
        let z = dft_at(&x, 2.0 * PI * 37.0 / 500.0);
        assert!((z - s[37]).norm() < 1e-9 * s[37].norm().max(1.0));
    }
}
