//! Times `lsim` of the PMSM model on a 1e6-sample PRBS (default approximation), best of 5, for
//! profiling (`perf stat`, `valgrind --tool=callgrind`).
//!
//! `cargo run --release -p fracid-benches --example sim_pmsm [samples]`

use fracid_benches::{pmsm, prbs_input, DT};
use fracsim::{lsim, ApproxSpec};
use std::time::Instant;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let (g, u) = (pmsm(), prbs_input(n, DT));
    let mut best = f64::INFINITY;
    let mut last = 0.0;
    for _ in 0..5 {
        let t = Instant::now();
        let y = lsim(&g, &u, DT, &ApproxSpec::default()).expect("simulation");
        best = best.min(t.elapsed().as_secs_f64());
        last = y[n - 1];
    }
    println!(
        "lsim PMSM, {n} samples: best {:.2} ms ({:.1} Msamples/s), y[end] = {last:.6}",
        best * 1e3,
        n as f64 / best / 1e6
    );
}
