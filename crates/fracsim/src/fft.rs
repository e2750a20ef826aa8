//! Discrete Fourier transforms of real records, the one implementation of the workspace: the
//! spectrum at the `n/2 + 1` bins of a record by FFT ([`rfft`], realfft/rustfft, `O(n log n)`
//! for any `n`), and the DFT at one arbitrary frequency by the direct sum ([`dft_at`], `O(n)`).
//!
//! Both compute `X(w) = sum_{k=0}^{n-1} x_k e^(-j w k)`, `w` in radians per sample; the bins of
//! [`rfft`] are `w = 2 pi m / n`, `m = 0..=n/2`.

use num_complex::Complex64;

/// `X(w) = sum_k x_k e^(-j w k)` at one angular step `w` (radians per sample), by the direct sum
/// with the twiddle advanced by a rotation (its rounding drifts by about `n` ulps over the record).
pub fn dft_at(x: &[f64], w: f64) -> Complex64 {
    let rot = Complex64::from_polar(1.0, -w);
    let mut z = Complex64::new(1.0, 0.0);
    let mut s = Complex64::new(0.0, 0.0);
    for &v in x {
        s += z * v;
        z *= rot;
    }
    s
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

    #[test]
    fn dft_at_matches_the_definition_between_bins() {
        let x = record(500);
        for w in [0.0, 0.01, 0.3702, 1.0, 2.5, PI] {
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
        let s = rfft(&x);
        let z = dft_at(&x, 2.0 * PI * 37.0 / 500.0);
        assert!((z - s[37]).norm() < 1e-9 * s[37].norm().max(1.0));
    }
}
