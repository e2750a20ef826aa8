//! Levy (Vinagre weights) with the full commensurate-order grid (q = 0.01..1, step 0.01, then the
//! golden-section refinement) against the number of frequency points, on the exact frequency
//! response of the paper's PMSM model over 1..1e4 rad/s.
//!
//! `cargo bench -p fracid-benches --bench levy`

use divan::{black_box, Bencher};
use fracid_benches::pmsm;
use ident::levy::{fit_bode, FreqOptions};
use num_complex::Complex64;

fn main() {
    divan::main();
}

fn bode(n: usize) -> (Vec<f64>, Vec<Complex64>) {
    let g = pmsm();
    let w: Vec<f64> = (0..n)
        .map(|i| 10f64.powf(4.0 * i as f64 / (n - 1) as f64))
        .collect();
    let h = w.iter().map(|&w| g.freq_response(w)).collect();
    (w, h)
}

/// `fit_bode` with the default options (n = 2, m = 0, full q grid, refined), `n` points.
#[divan::bench(args = [10, 100, 1000], sample_count = 10)]
fn full_grid(b: Bencher<'_, '_>, n: usize) {
    let (w, h) = bode(n);
    let opts = FreqOptions::default();
    b.bench(|| fit_bode(black_box(&w), black_box(&h), &opts).unwrap());
}
