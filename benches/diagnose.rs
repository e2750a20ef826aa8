//! The price of the diagnosis against the plain fit (issue 32), in process: `identify` of the
//! default structure (pmsm) and the whole `--diagnose` path (that fit, then
//! `diagnose_best`: the candidate structures fitted, screened and diagnosed) on each real time
//! record in `data/` and on a 1e5-sample PMSM PRBS record; and a 3k-sample fit at dt 0.1 ms
//! and 0.5 ms.
//! The whole-process ratio (what the user waits for, the table in `docs/performance.md`) is
//! `examples/diag_ratio.rs`.
//!
//! `cargo bench -p fracid-benches --bench diagnose`

use divan::{black_box, Bencher};
use fracid_benches::{noise, pmsm_data, prbs_input, real_record, REAL_RECORDS};
use fracsim::{lsim, ApproxSpec};
use ident::data::Record;
use ident::diagnose::{structures::diagnose_best, DiagnoseOptions};
use ident::oe::{identify, FracModel, IdentOptions};

fn main() {
    divan::main();
}

/// The records: the real ones by their file under `data/`, and `pmsm 1e5`.
fn records() -> Vec<&'static str> {
    REAL_RECORDS.iter().copied().chain(["pmsm 1e5"]).collect()
}

fn record(name: &str) -> Record {
    if name == "pmsm 1e5" {
        pmsm_record(100_000)
    } else {
        real_record(name)
    }
}

/// The PMSM PRBS record of `n` samples with noise sigma 0.05 ([`pmsm_data`]).
fn pmsm_record(n: usize) -> Record {
    let (u, y) = pmsm_data(n, 0.05, 1);
    let t = (0..n).map(|k| k as f64 * fracid_benches::DT).collect();
    Record::new(t, u, y).expect("a valid record")
}

/// The default structure, as `fracid time` names it.
fn pmsm() -> FracModel {
    FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9)
}

/// The plain fit (`fracid time FILE`'s identification).
#[divan::bench(args = records(), sample_count = 3, sample_size = 1)]
fn fit(b: Bencher<'_, '_>, name: &str) {
    let rec = record(name);
    b.bench(|| identify(black_box(&rec), &pmsm(), &IdentOptions::default()).ok());
}

/// The fit and the diagnosis (`fracid time FILE --diagnose`'s identification and diagnosis).
#[divan::bench(args = records(), sample_count = 3, sample_size = 1)]
fn diagnose(b: Bencher<'_, '_>, name: &str) {
    let rec = record(name);
    let opts = IdentOptions::default();
    b.bench(|| {
        let id = identify(black_box(&rec), &pmsm(), &opts).ok()?;
        diagnose_best(
            &rec,
            "pmsm",
            &pmsm(),
            id,
            &opts,
            &DiagnoseOptions::default(),
        )
        .ok()
    });
}

/// A 3k-sample fit (the PMSM PRBS record, default options: automatic start, initial state,
/// output offset), what an end-of-line fleet of short records pays per file.
#[divan::bench(sample_count = 30, sample_size = 1)]
fn fit_3k(b: Bencher<'_, '_>) {
    let rec = pmsm_record(3_000);
    b.bench(|| identify(black_box(&rec), &pmsm(), &IdentOptions::default()).unwrap());
}

/// The same 3k-sample fit at dt = 0.5 ms (the record `fit_short -- 3000 30 5e-4` fits: the
/// benches' PRBS at that step, whose period the start finds, so it starts from a Levy fit).
#[divan::bench(sample_count = 30, sample_size = 1)]
fn fit_3k_dt05(b: Bencher<'_, '_>) {
    let (n, dt) = (3_000, 5e-4);
    let u = prbs_input(n, dt);
    let mut y = lsim(&fracid_benches::pmsm(), &u, dt, &ApproxSpec::default()).expect("simulation");
    for (y, e) in y.iter_mut().zip(noise(n, 0.05, 1)) {
        *y += e;
    }
    let t = (0..n).map(|k| k as f64 * dt).collect();
    let rec = Record::new(t, u, y).expect("a valid record");
    b.bench(|| identify(black_box(&rec), &pmsm(), &IdentOptions::default()).unwrap());
}
