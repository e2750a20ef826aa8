//! Fleet mode of `fracid time` and `fracid freq`: many files, per-file reports equal to the
//! single-file runs, one summary, failures isolated and reported with a non-zero exit.

use super::fracid;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A noisy PRBS record (from rest) of a commensurate fractional model with gain `k` (seeded noise).
fn record(dir: &Path, name: &str, k: f64, seed: u64) -> PathBuf {
    let dt = 1e-3;
    let g: fracsim::FracTf = format!("{k}/(0.0004 s^1.8 + 0.02 s^0.9 + 1)")
        .parse()
        .unwrap();
    // at rest for 50 samples, then the PRBS
    let mut u = vec![0.0; 50];
    u.extend(
        fracsim::prbs::Prbs {
            clock: 5.0 * dt,
            periods: 2,
            ..fracsim::prbs::Prbs::paper()
        }
        .signal(dt)
        .unwrap(),
    );
    let y = fracsim::lsim(&g, &u, dt, &Default::default()).unwrap();
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    let mut text = String::from("t,u,y\n");
    for (i, (u, y)) in u.iter().zip(&y).enumerate() {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let noise = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02;
        writeln!(text, "{},{u},{}", i as f64 * dt, y + noise).unwrap();
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn time_fleet_equals_single_runs_and_isolates_failures() {
    let dir = tempfile::tempdir().unwrap();
    let recs = dir.path().join("recs");
    std::fs::create_dir(&recs).unwrap();
    let files: Vec<PathBuf> = (0..4)
        .map(|i| record(&recs, &format!("m{i}.csv"), 2.0 + i as f64, i))
        .collect();
    std::fs::write(recs.join("broken.csv"), "t,u,y\n0,1,2\n0.001,x,3\n").unwrap();
    let out = dir.path().join("out");
    let opts = ["--structure", "commensurate", "--quiet"];
    let mut args = vec![
        "time",
        recs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(opts);
    let o = fracid(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    // one bad file: exit 2 (bad data), named; the others fitted
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("broken.csv") && err.contains("1 of 5 files failed"),
        "{err}"
    );
    let summary = json(&out.join("time-summary.json"));
    assert_eq!(summary["files"], 5);
    assert_eq!(summary["failed"], 1);
    let rows = summary["rows"].as_array().unwrap();
    assert_eq!(rows[0]["status"], "failed"); // sorted by name: broken.csv first
    assert_eq!(rows[0]["exit_code"], 2);
    let csv = std::fs::read_to_string(out.join("time-summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 6, "{csv}");
    assert!(csv.starts_with("file,status,exit_code,model,fit_estimation_percent"));
    for (i, f) in files.iter().enumerate() {
        let mut one = vec!["time", f.to_str().unwrap(), "--json"];
        one.extend(opts);
        let o = fracid(&one);
        assert!(o.status.success());
        let single: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let fleet = json(&out.join(format!("m{i}.time.json")));
        assert_eq!(fleet["model"], single["model"], "{}", f.display());
        assert_eq!(fleet["fit"], single["fit"]);
        let row = &rows[i + 1];
        assert_eq!(row["status"], "ok");
        let k = single["model"]["num"][0]["coef"].as_f64().unwrap();
        // the gain of each record is found (noise 0.01 RMS on an output of several units)
        assert!(
            (k - (2.0 + i as f64)).abs() < 0.05 * (2.0 + i as f64),
            "K = {k}"
        );
        assert_eq!(
            row["fit_validation_percent"],
            single["fit"]["validation"]["nrmse_percent"]
        );
    }
}

#[test]
fn files_beside_and_freq_fleet() {
    let dir = tempfile::tempdir().unwrap();
    record(dir.path(), "a.csv", 3.0, 7);
    record(dir.path(), "b.csv", 4.0, 8);
    // the summary lands in the current directory: run there
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_fracid"))
        .current_dir(dir.path())
        .args([
            "time",
            "a.csv",
            "b.csv",
            "--structure",
            "commensurate",
            "--quiet",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["failed"], 0);
    assert!(dir.path().join("a.time.json").is_file() && dir.path().join("b.time.json").is_file());
    assert!(dir.path().join("time-summary.csv").is_file());

    // freq: the paper's table twice (and a glob), reports equal to the single-file command
    let t1 = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/paper_table1_bode.csv");
    let bode = dir.path().join("bode");
    std::fs::create_dir(&bode).unwrap();
    for n in ["p1.csv", "p2.csv"] {
        std::fs::copy(&t1, bode.join(n)).unwrap();
    }
    let glob = bode.join("p*.csv");
    let out = dir.path().join("fo");
    let o = fracid(&[
        "freq",
        glob.to_str().unwrap(),
        "--no-q-refine",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let single = fracid(&["freq", t1.to_str().unwrap(), "--no-q-refine", "--json"]);
    let single: serde_json::Value = serde_json::from_slice(&single.stdout).unwrap();
    for n in ["p1", "p2"] {
        let r = json(&out.join(format!("{n}.freq.json")));
        assert_eq!(r["model"], single["model"]);
        assert_eq!(r["q"].as_f64(), Some(0.91)); // the paper's grid answer on Table 1
    }
    let s = json(&out.join("freq-summary.json"));
    assert_eq!(s["files"], 2);
    assert_eq!(s["rows"][0]["J"], single["J"]);
}
