//! Sequences by FFT: truncated products (convolutions), and causal convolutions whose inputs are
//! decided sample by sample from the past output (`online`: the GL recursion `x_k = w_k -
//! sum_{i=1..k} d_i x_{k-i}`, the series `w / d`, and the loops with feedback), by divide and
//! conquer: the first half of a range solved, its effect on the second half added by one FFT
//! product, the second half solved. That is the step-by-step recursion's arithmetic regrouped,
//! O(n log^2 n) and as stable as the recursion itself (Newton's iteration for `1 / d`, the usual fast
//! division, amplifies rounding by the truncated tail at every doubling and diverges on the
//! lightly damped symbols of orders near 2).

use num_complex::Complex64;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::collections::HashMap;
use std::sync::Arc;

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

/// The blocks solved directly.
const BLOCK: usize = 256;

/// A causal convolution computed as its inputs are decided: `streams` sequences `x_s`, each
/// with its kernel `k_s`; at sample `k` the step is handed `past_k = sum_s sum_{m<k} x_s[m]
/// k_s[k-m]` and writes `x_s[k]`. Divide and conquer: the first half of a range solved, its
/// effect on the second half added by one FFT product per stream, the second half solved.
struct Online<'a, F: FnMut(usize, f64, &mut [f64])> {
    kernels: Vec<&'a [f64]>,
    x: Vec<Vec<f64>>,
    acc: Vec<f64>,
    step: F,
    planner: RealFftPlanner<f64>,
    /// The spectrum of `kernels[s][..b]` at FFT size `p`, per `(s, b, p)`.
    spectra: HashMap<(usize, usize, usize), Arc<Vec<Complex64>>>,
    decided: Vec<f64>,
    /// Work buffers per FFT size (a size's merge ends before another of that size starts).
    scratch: HashMap<usize, Scratch>,
}

/// The buffers of one merge at FFT size `p`.
struct Scratch {
    signal: Vec<f64>,
    spectrum: Vec<Complex64>,
    total: Vec<Complex64>,
    work: Vec<Complex64>,
}

impl<F: FnMut(usize, f64, &mut [f64])> Online<'_, F> {
    fn plans(&mut self, p: usize) -> (Arc<dyn RealToComplex<f64>>, Arc<dyn ComplexToReal<f64>>) {
        (
            self.planner.plan_fft_forward(p),
            self.planner.plan_fft_inverse(p),
        )
    }

    fn spectrum(&mut self, s: usize, b: usize, p: usize) -> Arc<Vec<Complex64>> {
        if let Some(k) = self.spectra.get(&(s, b, p)) {
            return k.clone();
        }
        let (forward, _) = self.plans(p);
        let mut buf = vec![0.0; p];
        buf[..b].copy_from_slice(&self.kernels[s][..b]);
        let mut out = forward.make_output_vec();
        forward
            .process(&mut buf, &mut out)
            .expect("sizes from the plan");
        let k = Arc::new(out);
        self.spectra.insert((s, b, p), k.clone());
        k
    }

    fn leaf(&mut self, lo: usize, hi: usize) {
        for k in lo..hi {
            let mut past = self.acc[k];
            for (x, kernel) in self.x.iter().zip(&self.kernels) {
                past += dot_reversed(&x[lo..k], &kernel[1..=k - lo]);
            }
            (self.step)(k, past, &mut self.decided);
            for (x, v) in self.x.iter_mut().zip(&self.decided) {
                x[k] = *v;
            }
        }
    }

    fn solve(&mut self, lo: usize, hi: usize) {
        if hi - lo <= BLOCK {
            self.leaf(lo, hi);
            return;
        }
        let mid = lo + (hi - lo) / 2;
        self.solve(lo, mid);
        // acc[k] += sum_s sum_{j in lo..mid} k_s[k-j] x_s[j] for k in mid..hi: a circular product
        // of size p >= hi - lo is exact at the indices >= mid - lo that are wanted.
        let b = hi - lo;
        let p = b.next_power_of_two();
        let (forward, inverse) = self.plans(p);
        let mut w = self.scratch.remove(&p).unwrap_or_else(|| Scratch {
            signal: vec![0.0; p],
            spectrum: forward.make_output_vec(),
            total: forward.make_output_vec(),
            work: vec![
                Complex64::new(0.0, 0.0);
                forward.get_scratch_len().max(inverse.get_scratch_len())
            ],
        });
        w.total
            .iter_mut()
            .for_each(|v| *v = Complex64::new(0.0, 0.0));
        for s in 0..self.kernels.len() {
            let kernel = self.spectrum(s, b, p);
            w.signal[..mid - lo].copy_from_slice(&self.x[s][lo..mid]);
            w.signal[mid - lo..].iter_mut().for_each(|v| *v = 0.0);
            forward
                .process_with_scratch(&mut w.signal, &mut w.spectrum, &mut w.work)
                .expect("sizes from the plan");
            w.total
                .iter_mut()
                .zip(w.spectrum.iter().zip(kernel.iter()))
                .for_each(|(t, (x, k))| *t += x * k);
        }
        w.total[0].im = 0.0;
        if let Some(last) = w.total.last_mut() {
            last.im = 0.0;
        }
        inverse
            .process_with_scratch(&mut w.total, &mut w.signal, &mut w.work)
            .expect("sizes from the plan");
        let norm = 1.0 / p as f64;
        for k in mid..hi {
            self.acc[k] += w.signal[k - lo] * norm;
        }
        self.scratch.insert(p, w);
        self.solve(mid, hi);
    }
}

/// Runs the online convolution over `n` samples: `kernels` (each at least `n` long; index 0 is
/// not used, the step adds the current sample's own terms itself), `step(k, past, decided)`
/// writes each stream's value at `k` into `decided`. Returns the streams.
pub(crate) fn online(
    kernels: Vec<&[f64]>,
    n: usize,
    step: impl FnMut(usize, f64, &mut [f64]),
) -> Vec<Vec<f64>> {
    let streams = kernels.len();
    let mut engine = Online {
        kernels,
        x: vec![vec![0.0; n]; streams],
        acc: vec![0.0; n],
        step,
        planner: RealFftPlanner::new(),
        spectra: HashMap::new(),
        decided: vec![0.0; streams],
        scratch: HashMap::new(),
    };
    engine.solve(0, n);
    engine.x
}

/// `sum_i x[i] d[len - 1 - i]` with four running sums.
fn dot_reversed(x: &[f64], d: &[f64]) -> f64 {
    let n = x.len();
    let mut acc = [0.0; 4];
    let mut i = 0;
    while i + 4 <= n {
        for (lane, a) in acc.iter_mut().enumerate() {
            *a += x[i + lane] * d[n - 1 - i - lane];
        }
        i += 4;
    }
    let mut sum = acc[0] + acc[1] + acc[2] + acc[3];
    while i < n {
        sum += x[i] * d[n - 1 - i];
        i += 1;
    }
    sum
}

/// `x` with `x_k = w_k - sum_{i=1..k} d_i x_{k-i}` (`d[0]` taken as 1; `d` at least as long as
/// `w`).
pub(crate) fn recursion(d: &[f64], w: &[f64]) -> Vec<f64> {
    let mut out = online(vec![d], w.len(), |k, past, x| x[0] = w[k] - past);
    out.pop().unwrap_or_default()
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
        let mut unit = vec![0.0; 1000];
        unit[0] = 1.0;
        let mut d = vec![0.0; 1000];
        d[..2].copy_from_slice(&[1.0, -1.0]);
        let geo = recursion(&d, &unit);
        assert!(geo.iter().all(|v| (v - 1.0).abs() < 1e-12));
        d[..3].copy_from_slice(&[1.0, -1.0, 0.25]);
        let sq = recursion(&d, &unit);
        for (k, v) in sq.iter().enumerate() {
            assert!(
                (v - (k as f64 + 1.0) / 2f64.powi(k as i32)).abs() < 1e-13,
                "{k} {v}"
            );
        }
    }
}
