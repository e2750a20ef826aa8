//! The fracid side of the side-by-side comparison: reads `t,u,y` from a CSV (as written by
//! `gen_data`), fits the PMSM structure `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)` by output error
//! (exact dual-number sensitivities, Levenberg-Marquardt, default approximation: Oustaloup N = 8,
//! bilinear) from the fixed start `K = 5, a1 = 0.008, a2 = 2e-5, zeta = 0.8, theta = 0.7`, and
//! prints one JSON line: parameters, NRMSE, RMSE, iterations and the fit time (best of `repeats`).
//!
//! `cargo run --release -p fracid-benches --example fit_csv -- FILE.csv [repeats]`

use fracid_benches::pmsm_start;
use ident::oe::{fit, FitOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("usage: fit_csv FILE.csv [repeats]");
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let text = std::fs::read_to_string(path).expect("read the CSV");
    let (mut t, mut u, mut y) = (vec![], vec![], vec![]);
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse().expect("a number"))
            .collect();
        t.push(v[0]);
        u.push(v[1]);
        y.push(v[2]);
    }
    let dt = t[1] - t[0];
    let start = pmsm_start();
    let mut best = f64::INFINITY;
    let mut rep = None;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let r = fit(&start, &u, &y, dt, &FitOptions::default()).expect("fit");
        best = best.min(t0.elapsed().as_secs_f64());
        rep = Some(r);
    }
    let rep = rep.expect("one fit");
    let mut yhat = vec![0.0; u.len()];
    ident::oe::Structure::simulate(&start, &rep.values, &u, dt, &mut yhat).expect("simulate");
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let (mut e2, mut d2) = (0.0, 0.0);
    for (a, b) in y.iter().zip(&yhat) {
        e2 += (a - b) * (a - b);
        d2 += (a - mean) * (a - mean);
    }
    let nrmse = 100.0 * (1.0 - (e2 / d2).sqrt());
    let rmse = (e2 / y.len() as f64).sqrt();
    let p = &rep.values;
    println!(
        "{{\"tool\": \"fracid\", \"samples\": {}, \"time_s\": {best:.6e}, \"params\": {{\"K\": {:.10e}, \"a1\": {:.10e}, \"a2\": {:.10e}, \"zeta\": {:.10e}, \"theta\": {:.10e}}}, \"nrmse_percent\": {nrmse:.8}, \"rmse\": {rmse:.8e}, \"iterations\": {}, \"evaluations\": {}, \"converged\": {}}}",
        u.len(), p[0], p[1], p[2], p[3], p[4], rep.iterations, rep.evaluations, rep.converged
    );
}
