//! What a user waits for (issue 32): `fracid time FILE --diagnose` against `fracid time FILE`,
//! whole process (reading, fit, report; `--json`), best of `runs` wall times each, alternated run
//! by run, on each real time record in `data/` and on a 1e5-sample PMSM PRBS record (written by
//! this program from the benches' fixture: the paper-style PMSM, dt 1e-4 s, noise sigma 0.05,
//! seed 1), plus any `FILE`s given. Prints one line per record: both times (and exit codes) and
//! their ratio.
//!
//! `cargo run --release -p fracid-benches --example diag_ratio -- target/release/fracid [runs] [FILE ...]`

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Wall seconds of one run, and its exit code.
fn run(bin: &Path, file: &Path, diagnose: bool) -> (f64, i32) {
    let mut cmd = Command::new(bin);
    cmd.arg("time").arg(file).arg("--json");
    if diagnose {
        cmd.arg("--diagnose");
    }
    let t0 = Instant::now();
    let out = cmd.output().expect("run fracid");
    (t0.elapsed().as_secs_f64(), out.status.code().unwrap_or(-1))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let bin = PathBuf::from(
        args.get(1)
            .expect("usage: diag_ratio FRACID [runs] [FILE ...]"),
    );
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let mut files: Vec<PathBuf> = fracid_benches::REAL_RECORDS
        .iter()
        .map(|r| fracid_benches::data_path(r))
        .collect();
    let pmsm = std::env::temp_dir().join("fracid_diag_ratio_pmsm_1e5.csv");
    let (u, y) = fracid_benches::pmsm_data(100_000, 0.05, 1);
    let mut text = String::from("t,u,y\n");
    for (k, (u, y)) in u.iter().zip(&y).enumerate() {
        text.push_str(&format!("{},{u},{y}\n", k as f64 * fracid_benches::DT));
    }
    std::fs::write(&pmsm, text).expect("write the PMSM record");
    files.push(pmsm);
    files.extend(args.iter().skip(3).map(PathBuf::from));
    println!("| record | plain fit (exit) | --diagnose (exit) | ratio |");
    println!("|---|---|---|---|");
    for f in &files {
        let (mut plain, mut diag) = ((f64::INFINITY, 0), (f64::INFINITY, 0));
        for _ in 0..runs.max(1) {
            let p = run(&bin, f, false);
            let d = run(&bin, f, true);
            plain = (plain.0.min(p.0), p.1);
            diag = (diag.0.min(d.0), d.1);
        }
        let name = f
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        println!(
            "| {name} | {:.1} ms ({}) | {:.1} ms ({}) | {:.1}x |",
            1e3 * plain.0,
            plain.1,
            1e3 * diag.0,
            diag.1,
            diag.0 / plain.0
        );
    }
}
