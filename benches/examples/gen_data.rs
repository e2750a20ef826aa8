//! Writes the side-by-side comparison's data: the paper's PMSM model on the paper's PRBS
//! (order 7, 3 ms clock, unit amplitude), step `1e-4` s, default approximation, plus seeded
//! Gaussian noise. CSV columns `t,u,y,y_clean`.
//!
//! `cargo run --release -p fracid-benches --example gen_data -- OUT.csv [samples] [sigma] [seed]`

use fracid_benches::{pmsm, pmsm_data, prbs_input, DT};
use fracsim::{lsim, ApproxSpec};
use std::io::Write;

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let out = args.get(1).map_or("pmsm_prbs.csv", String::as_str);
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let sigma: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0.05);
    let seed: u64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(1);
    let (u, y) = pmsm_data(n, sigma, seed);
    let clean = lsim(&pmsm(), &prbs_input(n, DT), DT, &ApproxSpec::default()).expect("simulation");
    let mut w = std::io::BufWriter::new(std::fs::File::create(out)?);
    writeln!(
        w,
        "# {} on the paper's PRBS, dt = {DT} s, noise sigma {sigma}, seed {seed}",
        fracid_benches::PMSM
    )?;
    writeln!(w, "t,u,y,y_clean")?;
    for k in 0..n {
        writeln!(
            w,
            "{},{},{:.17e},{:.17e}",
            k as f64 * DT,
            u[k],
            y[k],
            clean[k]
        )?;
    }
    w.flush()
}
