//! The parts of `fracid time` outside the fit, timed one by one on a record file (issue 18): reading
//! it (`Record::load`), the automatic start (`ident::oe::init::auto_start` on the estimation part's
//! deviations, as `identify` calls it) and, for comparison, the whole identification. Prints one
//! JSON line of milliseconds (best of `repeats`).
//!
//! `cargo run --release -p fracid-benches --example io_time -- FILE.csv [repeats] [load]` (with
//! `load`, only the reading is timed).

use ident::data::{OffsetMode, ReadOptions, Record};
use ident::oe::{init::auto_start, FracModel, IdentOptions};
use std::time::Instant;

fn best_ms<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let v = f();
        best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        out = Some(v);
    }
    (best, out.expect("at least one run"))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::PathBuf::from(args.get(1).expect("usage: io_time FILE.csv [repeats]"));
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let opts = ReadOptions::default();
    let (load_ms, loaded) = best_ms(repeats, || Record::load(&path, &opts).expect("load"));
    let rec = loaded.record;
    if args.get(3).is_some_and(|a| a == "load") {
        println!("{{\"samples\": {}, \"load_ms\": {load_ms:.2}}}", rec.len());
        return;
    }
    let n = rec.len();
    let split = rec.split_index(0.3).expect("split");
    let off = rec.offsets(OffsetMode::Initial, split);
    let u: Vec<f64> = rec.u[..split].iter().map(|v| v - off.u0).collect();
    let y: Vec<f64> = rec.y[..split].iter().map(|v| v - off.y0).collect();
    let base = FracModel::pmsm(5.0, 0.008, 2e-5, 0.8, 0.7);
    let (start_ms, report) = best_ms(repeats, || {
        let mut m = base.clone();
        auto_start(&mut m, &u, &y, rec.dt, ident::par::Par::available()).expect("auto start")
    });
    let (ident_ms, id) = best_ms(1, || {
        ident::oe::identify(&rec, &base, &IdentOptions::default()).expect("identify")
    });
    println!(
        "{{\"samples\": {n}, \"load_ms\": {load_ms:.2}, \"auto_start_ms\": {start_ms:.2}, \
         \"identify_ms\": {ident_ms:.1}, \"fit_ms\": {:.1}, \"start_fit_percent\": {:.4}, \
         \"rmse\": {:.6}}}",
        id.report.elapsed.as_secs_f64() * 1e3,
        report.fit_percent.unwrap_or(f64::NAN),
        id.estimation.rmse
    );
}
