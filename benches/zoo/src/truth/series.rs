//! Power series and sequences by FFT: truncated products (convolutions) and division, the latter
//! by Newton's iteration `f <- f (2 - d f)`, which doubles the number of correct coefficients per
//! step, so `num / den` to `len` terms costs a few products of length <= 2 len.

use num_complex::Complex64;
use realfft::RealFftPlanner;

/// The first `len` coefficients of `a * b`.
pub(crate) fn convolve(a: &[f64], b: &[f64], len: usize) -> Vec<f64> {
    let a = &a[..a.len().min(len)];
    let b = &b[..b.len().min(len)];
    if a.is_empty() || b.is_empty() {
        return vec![0.0; len];
    }
    if a.len().min(b.len()) <= 32 {
        let mut out = vec![0.0; len];
        for (i, x) in a.iter().enumerate() {
            for (o, y) in out[i..].iter_mut().zip(b) {
                *o += x * y;
            }
        }
        return out;
    }
    let size = (a.len() + b.len() - 1).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(size);
    let inverse = planner.plan_fft_inverse(size);
    let spectrum = |x: &[f64]| -> Vec<Complex64> {
        let mut buf = vec![0.0; size];
        buf[..x.len()].copy_from_slice(x);
        let mut out = forward.make_output_vec();
        forward
            .process(&mut buf, &mut out)
            .expect("sizes from the plan");
        out
    };
    let mut prod: Vec<Complex64> = spectrum(a)
        .iter()
        .zip(spectrum(b))
        .map(|(x, y)| x * y)
        .collect();
    // The inverse of a real signal's spectrum: the DC and Nyquist bins are real up to rounding.
    prod[0].im = 0.0;
    if let Some(last) = prod.last_mut() {
        last.im = 0.0;
    }
    let mut out = inverse.make_output_vec();
    inverse
        .process(&mut prod, &mut out)
        .expect("sizes from the plan");
    let norm = 1.0 / size as f64;
    let mut res: Vec<f64> = out.into_iter().take(len).map(|v| v * norm).collect();
    res.resize(len, 0.0);
    res
}

/// The first `len` coefficients of `1 / d` (`d[0] != 0`).
pub(crate) fn inverse(d: &[f64], len: usize) -> Vec<f64> {
    let mut f = vec![1.0 / d[0]];
    let mut m = 1;
    while m < len {
        let m2 = (2 * m).min(len);
        let mut e = convolve(&d[..d.len().min(m2)], &f, m2);
        e.iter_mut().for_each(|v| *v = -*v);
        e[0] += 2.0;
        f = convolve(&f, &e, m2);
        m = m2;
    }
    f.truncate(len);
    f
}

/// The first `len` coefficients of `num / den`.
pub(crate) fn divide(num: &[f64], den: &[f64], len: usize) -> Vec<f64> {
    convolve(num, &inverse(den, len), len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_inverses_by_hand() {
        // (1 + z)^2 = 1 + 2z + z^2.
        assert_eq!(
            convolve(&[1.0, 1.0], &[1.0, 1.0], 4),
            vec![1.0, 2.0, 1.0, 0.0]
        );
        // A long product through the FFT against the direct sum.
        let a: Vec<f64> = (0..300)
            .map(|i| ((i * 7 % 13) as f64 - 6.0) / 7.0)
            .collect();
        let b: Vec<f64> = (0..200)
            .map(|i| ((i * 5 % 11) as f64 - 5.0) / 3.0)
            .collect();
        let fast = convolve(&a, &b, 450);
        for (n, v) in fast.iter().enumerate() {
            let direct: f64 = (0..=n)
                .filter(|&i| i < a.len() && n - i < b.len())
                .map(|i| a[i] * b[n - i])
                .sum();
            assert!((v - direct).abs() < 1e-11, "{n}: {v} {direct}");
        }
        // 1 / (1 - z) = 1 + z + z^2 + ...; 1 / (1 - 0.5 z)^2 has coefficients (k + 1) / 2^k.
        let geo = inverse(&[1.0, -1.0], 1000);
        assert!(geo.iter().all(|v| (v - 1.0).abs() < 1e-12));
        let sq = inverse(&[1.0, -1.0, 0.25], 100);
        for (k, v) in sq.iter().enumerate() {
            assert!(
                (v - (k as f64 + 1.0) / 2f64.powi(k as i32)).abs() < 1e-13,
                "{k} {v}"
            );
        }
    }
}
