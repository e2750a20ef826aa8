//! Writes the side-by-side comparison's data: the paper's PMSM model on the paper's PRBS
//! (order 7, 3 ms clock, repeated as needed), default approximation, plus seeded Gaussian noise.
//! CSV columns `t,u,y,y_clean`.
//!
//! The input is `level +- amplitude` (default `0 +- 1`); the plant has stood at the first input
//! level since forever (the output starts at its steady state `6.82 u_0`), so `fracid time`'s
//! default operating point (`u0 = u[0]`) is the true one.
//!
//! `cargo run --release -p fracid-benches --example gen_data -- OUT.csv [samples] [sigma] [seed]
//! [dt] [amplitude] [level]` (defaults 10000, 0.05, 1, 1e-4 s, 1, 0).

use fracid_benches::{noise, pmsm, prbs_input, DT};
use fracsim::{lsim, ApproxSpec};
use std::io::Write;

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: f64| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let out = args.get(1).map_or("pmsm_prbs.csv", String::as_str);
    let n = arg(2, 10_000.0) as usize;
    let sigma = arg(3, 0.05);
    let seed = arg(4, 1.0) as u64;
    let dt = arg(5, DT);
    let (amp, level) = (arg(6, 1.0), arg(7, 0.0));
    let u: Vec<f64> = prbs_input(n, dt).iter().map(|v| level + amp * v).collect();
    let du: Vec<f64> = u.iter().map(|v| v - u[0]).collect();
    let g = pmsm();
    let clean = lsim(&g, &du, dt, &ApproxSpec::default()).expect("simulation");
    let y_ss = g.dc_gain() * u[0];
    let e = noise(n, sigma, seed);
    let mut w = std::io::BufWriter::new(std::fs::File::create(out)?);
    writeln!(
        w,
        "# {} on the paper's PRBS {level} +- {amp}, dt = {dt} s, noise sigma {sigma}, seed {seed}",
        fracid_benches::PMSM
    )?;
    writeln!(w, "t,u,y,y_clean")?;
    for k in 0..n {
        let yc = y_ss + clean[k];
        writeln!(
            w,
            "{:.6e},{},{:.10e},{:.10e}",
            k as f64 * dt,
            u[k],
            yc + e[k],
            yc
        )?;
    }
    w.flush()
}
