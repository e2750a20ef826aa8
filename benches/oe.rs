//! Output-error fit time of the PMSM structure `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)` (all five
//! parameters free, default options and approximation) against the number of samples, on the
//! PRBS response of the paper's model plus seeded noise. The 1e6-sample fit (seconds, peak
//! memory) is in `examples/oe_scaling.rs`.
//!
//! `cargo bench -p fracid-benches --bench oe`

use divan::{black_box, Bencher};
use fracid_benches::{pmsm_data, pmsm_start, DT};
use ident::oe::{fit, FitOptions};

fn main() {
    divan::main();
}

/// A full OE-LM fit, `n` samples.
#[divan::bench(args = [1_000, 10_000, 100_000], sample_count = 3, sample_size = 1)]
fn fit_samples(b: Bencher<'_, '_>, n: usize) {
    let (u, y) = pmsm_data(n, 0.05, 1);
    let start = pmsm_start();
    b.bench(|| {
        let r = fit(
            &start,
            black_box(&u),
            black_box(&y),
            DT,
            &FitOptions::default(),
        )
        .unwrap();
        assert!(r.converged);
        r
    });
}

/// One Jacobian evaluation (output and its 5 exact sensitivities), 10k samples.
#[divan::bench(sample_count = 10, sample_size = 1)]
fn sensitivities_10k(b: Bencher<'_, '_>) {
    let (u, _) = pmsm_data(10_000, 0.0, 1);
    let m = pmsm_start();
    let p = ident::oe::Structure::params(&m)
        .iter()
        .map(|p| p.value)
        .collect::<Vec<_>>();
    b.bench(|| {
        ident::oe::sensitivities(&m, &p, black_box(&u), DT, ident::par::Par::available()).unwrap()
    });
}
