//! OE-LM fit time of the PMSM structure against the number of samples, and the scaling exponent
//! (least-squares slope of log time against log samples). Run it under `/usr/bin/time -v` for
//! the peak memory of the largest fit.
//!
//! `cargo run --release -p fracid-benches --example oe_scaling -- [max_samples]`
//! (default 1e6: sizes 1e3, 1e4, 1e5, 1e6).

use fracid_benches::{loglog_slope, pmsm_data, pmsm_start, DT};
use ident::oe::{fit, FitOptions};
use std::time::Instant;

fn main() {
    let max: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let (mut ns, mut ts) = (vec![], vec![]);
    let mut n = 1000;
    while n <= max {
        let (u, y) = pmsm_data(n, 0.05, 1);
        let start = pmsm_start();
        // Best of 3 below 1e5 samples (short runs are noisy), one run above.
        let runs = if n < 100_000 { 3 } else { 1 };
        let mut best = f64::INFINITY;
        for _ in 0..runs {
            let t0 = Instant::now();
            let r = fit(&start, &u, &y, DT, &FitOptions::default()).expect("fit");
            let el = t0.elapsed().as_secs_f64();
            best = best.min(el);
            if runs == 1 || best == el {
                println!(
                    "n = {n:>8}: {:>10.2} ms, {} iterations, {} simulations, converged {}, K = {:.4}, zeta = {:.4}, theta = {:.4}",
                    el * 1e3, r.iterations, r.evaluations, r.converged, r.values[0], r.values[3], r.values[4]
                );
            }
        }
        ns.push(n as f64);
        ts.push(best);
        n *= 10;
    }
    if ns.len() >= 2 {
        println!(
            "scaling exponent (slope of log time vs log samples over {:.0e}..{:.0e}): {:.3}",
            ns[0],
            ns[ns.len() - 1],
            loglog_slope(&ns, &ts)
        );
    }
}
