//! Sequences by FFT: truncated products (convolutions), and the solution of the recursion
//! `x_k = w_k - sum_{i=1..k} d_i x_{k-i}` (the series `w / d`, `d_0 = 1`) by divide and conquer:
//! the first half of a range solved, its effect on the second half added by one FFT product,
//! the second half solved. That is the step-by-step recursion's arithmetic regrouped, O(n log^2 n)
//! and as stable as the recursion itself (Newton's iteration for `1 / d`, the usual fast
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

struct Solver<'a> {
    d: &'a [f64],
    w: &'a [f64],
    x: Vec<f64>,
    acc: Vec<f64>,
    planner: RealFftPlanner<f64>,
    /// The spectrum of `d[..b]` at FFT size `p`, per `(b, p)`.
    kernels: HashMap<(usize, usize), Arc<Vec<Complex64>>>,
}

impl Solver<'_> {
    fn plans(&mut self, p: usize) -> (Arc<dyn RealToComplex<f64>>, Arc<dyn ComplexToReal<f64>>) {
        (
            self.planner.plan_fft_forward(p),
            self.planner.plan_fft_inverse(p),
        )
    }

    fn kernel(&mut self, b: usize, p: usize) -> Arc<Vec<Complex64>> {
        if let Some(k) = self.kernels.get(&(b, p)) {
            return k.clone();
        }
        let (forward, _) = self.plans(p);
        let mut buf = vec![0.0; p];
        buf[..b].copy_from_slice(&self.d[..b]);
        let mut out = forward.make_output_vec();
        forward
            .process(&mut buf, &mut out)
            .expect("sizes from the plan");
        let k = Arc::new(out);
        self.kernels.insert((b, p), k.clone());
        k
    }

    fn solve(&mut self, lo: usize, hi: usize) {
        if hi - lo <= BLOCK {
            for k in lo..hi {
                let inner = dot_reversed(&self.x[lo..k], &self.d[1..=k - lo]);
                self.x[k] = self.w[k] - self.acc[k] - inner;
            }
            return;
        }
        let mid = lo + (hi - lo) / 2;
        self.solve(lo, mid);
        // acc[k] += sum_{j in lo..mid} d_{k-j} x_j for k in mid..hi: a circular product of size
        // p >= hi - lo is exact at the indices >= mid - lo that are wanted.
        let b = hi - lo;
        let p = b.next_power_of_two();
        let kernel = self.kernel(b, p);
        let (forward, inverse) = self.plans(p);
        let mut buf = vec![0.0; p];
        buf[..mid - lo].copy_from_slice(&self.x[lo..mid]);
        let mut spec = forward.make_output_vec();
        forward
            .process(&mut buf, &mut spec)
            .expect("sizes from the plan");
        spec.iter_mut()
            .zip(kernel.iter())
            .for_each(|(s, k)| *s *= k);
        spec[0].im = 0.0;
        if let Some(last) = spec.last_mut() {
            last.im = 0.0;
        }
        inverse
            .process(&mut spec, &mut buf)
            .expect("sizes from the plan");
        let norm = 1.0 / p as f64;
        for k in mid..hi {
            self.acc[k] += buf[k - lo] * norm;
        }
        self.solve(mid, hi);
    }
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
    let n = w.len();
    let mut solver = Solver {
        d,
        w,
        x: vec![0.0; n],
        acc: vec![0.0; n],
        planner: RealFftPlanner::new(),
        kernels: HashMap::new(),
    };
    solver.solve(0, n);
    solver.x
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
