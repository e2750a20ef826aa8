//! A short record's fit in process (issue 32 item 2): the paper's PMSM on the benches' PRBS
//! (`pmsm_data(n, 0.05, 1)`, dt = 0.1 ms unless given), `identify` with the default options
//! (automatic start, initial state, output offset) run `repeats` times. Prints the min and median
//! of the in-process time, then the fitted parameters with their standard errors, the RMSE, the
//! LM iterations and evaluations (to compare fits before and after a change).
//!
//! `cargo run --release -p fracid-benches --example fit_short -- [samples] [repeats] [dt]`
//!
//! Each repeat starts from an empty pole cache (`fracsim::modal::RootsCache`), as every
//! `identify` does.

use fracid_benches::{noise, prbs_input};
use fracsim::{lsim, ApproxSpec};
use ident::data::Record;
use ident::oe::{identify, FracModel, IdentOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(30);
    let dt: f64 = args
        .get(3)
        .and_then(|s| s.parse().ok())
        .unwrap_or(fracid_benches::DT);
    let u = prbs_input(n, dt);
    let mut y = lsim(&fracid_benches::pmsm(), &u, dt, &ApproxSpec::default()).expect("simulation");
    for (y, e) in y.iter_mut().zip(noise(n, 0.05, 1)) {
        *y += e;
    }
    let t = (0..n).map(|k| k as f64 * dt).collect();
    let rec = Record::new(t, u, y).expect("a valid record");
    let model = FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9);
    let opts = IdentOptions::default();
    let mut ms = vec![];
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let id = identify(&rec, &model, &opts).expect("identify");
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
        last = Some(id);
    }
    ms.sort_by(f64::total_cmp);
    let id = last.expect("one run");
    println!(
        "samples {n} dt {dt:e}: min {:.2} ms, median {:.2} ms ({} runs); rmse {:.8}, \
         iterations {}, evaluations {}",
        ms[0],
        ms[ms.len() / 2],
        ms.len(),
        id.estimation.rmse,
        id.report.iterations,
        id.report.evaluations
    );
    println!(
        "  start: {:?} {:.2}%: {}",
        id.start_report.method,
        id.start_report.fit_percent.unwrap_or(f64::NAN),
        id.start_report.note
    );
    for p in id.report.params.iter().filter(|p| p.free) {
        println!(
            "  {:>10} {:>16.9e} +- {:.3e}",
            p.name,
            p.value,
            p.std_error.unwrap_or(f64::NAN)
        );
    }
}
