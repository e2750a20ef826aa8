//! End-to-end tests: the `fracid` binary on real files, as a user runs it.
//!
//! The binary is the one cargo builds for the workspace's default members (`target/<profile>/fracid`),
//! found beside this test executable.

use std::path::PathBuf;
use std::process::{Command, Output};

#[cfg(unix)] // the drive simulator runs on a pseudo-terminal
mod tune_loop;

fn fracid_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/e2e-<hash> -> target/<profile>/fracid
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let bin = dir.join(format!("fracid{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.exists(),
        "{} not built: run `cargo test` at the workspace root",
        bin.display()
    );
    bin
}

fn fracid(args: &[&str]) -> Output {
    Command::new(fracid_bin())
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run fracid")
}

/// Run fracid with `--json` among `args`; it must succeed; its stdout parsed.
fn fracid_json(args: &[&str]) -> serde_json::Value {
    let out = fracid(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// The output (last column) of the last row of `fracid sim`'s CSV.
fn last_output(csv: &str) -> f64 {
    let row = csv.lines().last().expect("an output row");
    row.rsplit(',').next().unwrap().parse().expect("a number")
}

#[test]
fn sim_step_matches_the_mittag_leffler_oracle_within_half_a_percent() {
    let out = fracid(&[
        "sim",
        "--model",
        "6.77/(0.0064 s^0.89 + 1)",
        "--step",
        "--dt",
        "1e-4",
        "--t-end",
        "0.05",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<(f64, f64)> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (f[0], f[2])
        })
        .collect();
    assert_eq!(rows.len(), 501);
    for (t, exact) in [
        (0.001, 1.958077),
        (0.003, 3.943589),
        (0.010, 6.018918),
        (0.030, 6.615241),
    ] {
        let (_, y) = rows
            .iter()
            .find(|(tt, _)| (tt - t).abs() < 1e-9)
            .expect("time row");
        let rel = (y - exact).abs() / exact;
        // Measured: 1.6e-4, 5.7e-5, 7e-7, 2e-5 (see the note on issue 2); the promise is 0.5%.
        assert!(rel < 5e-3, "t = {t}: {y} vs {exact}");
    }
}

#[test]
fn sim_methods_agree_with_grunwald_letnikov() {
    let run = |method: &str| -> Vec<f64> {
        let out = fracid(&[
            "sim", "--prbs", "--dt", "1e-4", "--t-end", "0.1", "--method", method,
        ]);
        assert!(
            out.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .skip(2)
            .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
            .collect()
    };
    let gl = run("gl");
    for method in ["oustaloup", "refined", "trigeassou"] {
        let y = run(method);
        let num: f64 = y.iter().zip(&gl).map(|(a, b)| (a - b).powi(2)).sum();
        let den: f64 = gl.iter().map(|b| b * b).sum();
        let rel = (num / den).sqrt();
        // GL at dt = 1e-4 is itself first-order accurate (about 1e-2 at the start of a step).
        assert!(rel < 3e-2, "{method}: relative RMS difference {rel}");
    }
}

#[test]
fn bad_input_gives_a_clear_error_and_a_nonzero_exit() {
    for (args, code, needle) in [
        (vec!["sim", "--model", "6.8/(x + 1)"], 2, "unknown name"),
        (vec!["sim", "--model", "1/(0 s + 0)"], 2, "division by zero"),
        (vec!["sim", "--model", "1e999/(s+1)"], 2, "not finite"),
        (vec!["sim", "--band", "10,1"], 2, "band"),
        (vec!["sim", "--band", "1,inf"], 2, "band"),
        (vec!["sim", "--dt", "0"], 2, "dt"),
        (
            vec!["sim", "--input", "/nonexistent/file.csv"],
            3,
            "cannot read",
        ),
        (vec!["sim", "--method", "magic"], 2, "method"),
    ] {
        let out = fracid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn extreme_input_is_an_error_not_a_crash_or_a_hang() {
    let deep = format!("{}1{}", "(".repeat(20_000), ")".repeat(20_000));
    for (args, code, needle) in [
        // stack overflow: the process aborted
        (vec!["sim", "--model", deep.as_str()], 2, "nested more than"),
        // overflow panics
        (
            vec!["sim", "--prbs", "--prbs-clock", "1e300"],
            2,
            "too many",
        ),
        (vec!["sim", "--order", "18446744073709551615"], 2, "order N"),
        // hung building 2e8 cells
        (vec!["sim", "--order", "100000000"], 2, "order N"),
        // printed a band edge with 300 decimal digits
        (vec!["sim", "--dt", "1e300"], 2, "puts the default band at"),
    ] {
        let out = fracid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        let shown: Vec<&str> = args.iter().map(|a| &a[..a.len().min(40)]).collect();
        assert_eq!(out.status.code(), Some(code), "{shown:?}: {err}");
        assert!(err.contains(needle), "{shown:?}: {err}");
        assert!(
            !err.contains("panicked") && err.len() < 400,
            "{shown:?}: {err}"
        );
    }
    // A delay far past the record: Grunwald-Letnikov overflowed its index; the output is zero.
    let out = fracid(&[
        "sim",
        "--method",
        "gl",
        "--model",
        "1/(s+1) exp(-1e300 s)",
        "--t-end",
        "0.001",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let text = String::from_utf8(out.stdout).unwrap();
    let y: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| l.rsplit(',').next().unwrap())
        .collect();
    assert_eq!(y.len(), 11);
    assert!(y.iter().all(|v| v.parse::<f64>() == Ok(0.0)), "{y:?}");
}

#[test]
fn windows_csv_files_are_read() {
    // Excel's "CSV UTF-8": a byte-order mark and CRLF line ends.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("u.csv");
    let mut text = String::from("\u{feff}t,u\r\n");
    for k in 0..100 {
        text.push_str(&format!("{},{}\r\n", k as f64 * 1e-3, 1.0));
    }
    std::fs::write(&input, text).unwrap();
    let out = fracid(&[
        "sim",
        "--model",
        "2/(0.001 s + 1)",
        "--input",
        input.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let last = last_output(&String::from_utf8(out.stdout).unwrap());
    assert!((last - 2.0).abs() < 1e-6, "{last}");
    // A duplicated column name is ambiguous: an error naming it, not the first silently.
    let dup = dir.path().join("dup.csv");
    std::fs::write(&dup, "t,u,u\n0,1,2\n0.001,1,2\n").unwrap();
    let out = fracid(&["sim", "--input", dup.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("'u' appears twice"), "{err}");
}

#[test]
fn sim_reads_a_recorded_input_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("u.csv");
    let mut text = String::from("# a recorded input\nt;u\n");
    for k in 0..200 {
        text.push_str(&format!(
            "{};{}\n",
            k as f64 * 1e-3,
            if k >= 10 { 1.0 } else { 0.0 }
        ));
    }
    std::fs::write(&input, text).unwrap();
    let out_csv = dir.path().join("y.csv");
    let out = fracid(&[
        "sim",
        "--model",
        "2/(0.01 s + 1)",
        "--input",
        input.to_str().unwrap(),
        "-o",
        out_csv.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let last = last_output(&std::fs::read_to_string(&out_csv).unwrap());
    // 190 ms after the step, 19 time constants: the DC gain 2 to 1e-6.
    assert!((last - 2.0).abs() < 1e-6, "{last}");
}

#[test]
fn sim_input_columns_are_chosen_and_checked() {
    // sim --input read its column through the t,u,y record reader, passing u as y too.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("u.csv");
    let mut text = String::from("time;volts;note\n");
    for k in 0..100 {
        text.push_str(&format!("{};{};x\n", k as f64 * 1e-3, 1.0));
    }
    std::fs::write(&input, text).unwrap();
    let f = input.to_str().unwrap();
    let out = fracid(&[
        "sim",
        "--model",
        "2/(0.001 s + 1)",
        "--input",
        f,
        "--t-col",
        "time",
        "--u-col",
        "volts",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let last = last_output(&String::from_utf8(out.stdout).unwrap());
    assert!((last - 2.0).abs() < 1e-6, "{last}");
    for (args, want) in [
        (vec!["--t-col", "time", "--u-col", "time"], "chosen twice"),
        (vec!["--t-col", "time", "--u-col", "note"], "not a number"),
        (vec!["--t-col", "time"], "no column 'u'"),
    ] {
        let mut a = vec!["sim", "--input", f];
        a.extend(&args);
        let out = fracid(&a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    let nan = dir.path().join("nan.csv");
    std::fs::write(&nan, "t,u\n0,1\n0.001,NaN\n0.002,1\n").unwrap();
    let out = fracid(&["sim", "--input", nan.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("u is not finite (NaN) at sample 1"), "{err}");
}

/// Tests that run the drive simulator in real time take turns (two at once on a 2-core machine
/// would distort their timing); the demos (virtual time, but their fits load the machine) too.
fn realtime_lock() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// Run `fracid demo` with `extra` args and check its files, the hidden delay it must find and its
/// models; returns its stderr (the progress lines).
fn demo_checks(extra: &[&str]) -> String {
    let _g = realtime_lock();
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["demo", "--out", dir.path().to_str().unwrap()];
    args.extend(extra);
    let out = fracid(&args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    for f in [
        "prbs.csv",
        "prbs_steady.csv",
        "bode.csv",
        "time.png",
        "bode.png",
        "time.json",
        "freq.json",
        "report.md",
    ] {
        let p = dir.path().join(f);
        assert!(
            p.exists() && std::fs::metadata(&p).unwrap().len() > 0,
            "{f} missing or empty"
        );
    }
    let raw = std::fs::read_to_string(dir.path().join("prbs.csv")).unwrap();
    assert!(
        raw.trim_end().ends_with("# complete: 1824 samples"),
        "acquisition not complete"
    );
    let time: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("time.json")).unwrap())
            .unwrap();
    let val = time["fit"]["validation"]["nrmse_percent"].as_f64().unwrap();
    // The hidden 1 ms delay is not in the base model; even so the fit must be a useful model.
    assert!(val > 85.0, "validation fit {val}%");
    // The hidden 1 ms input delay is what the time-domain diagnosis must find and add.
    let effects = time["diagnosis"]["effects"].as_array().expect("effects");
    let delay = effects
        .iter()
        .find(|e| e["name"] == "delay")
        .unwrap_or_else(|| panic!("no delay found: {effects:?}"));
    let tau = delay["params"]["tau"].as_f64().unwrap();
    assert!((tau - 1e-3).abs() < 0.2e-3, "tau = {tau}");
    let before = time["diagnosis"]["before"]["rmse"].as_f64().unwrap();
    let after = time["diagnosis"]["after"]["rmse"].as_f64().unwrap();
    assert!(after < 0.5 * before, "RMSE {before} -> {after}");
    let freq: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("freq.json")).unwrap())
            .unwrap();
    let dc = freq["model"]["num"][0]["coef"].as_f64().unwrap();
    // DC gain of the simulated motor: 6.82 (rad/s)/V.
    assert!((dc - 6.82).abs() < 0.2, "b0 = {dc}");
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("## The hidden truth"));
    // each model fitted and diagnosed once, in the demo's own process
    assert!(
        report.contains("(use-case runs: time 1, freq 1)"),
        "{report}"
    );
    // it ends with the tuned loop run on the drive: predicted and measured side by side
    tune_loop::check_demo_loop(dir.path(), &report);
    // the sweep: 16 points written as measured, with the footer; by default each the trimmed
    // mean of 3 measurements with its spread columns
    let bode = std::fs::read_to_string(dir.path().join("bode.csv")).unwrap();
    let rows: Vec<&str> = bode
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .collect();
    assert_eq!(rows.len(), 16, "{bode}");
    assert_eq!(
        bode.trim_end().lines().last(),
        Some("# complete: 16 frequencies")
    );
    if !extra.contains(&"--repeats") {
        assert!(
            bode.lines()
                .any(|l| l == "freq_hz,gain_db,phase_deg,gain_db_std,phase_deg_std,repeats"),
            "{bode}"
        );
        assert!(rows.iter().all(|r| r.ends_with(",3")), "{bode}");
    }
    stderr
}

#[test]
fn demo_acquires_identifies_diagnoses_and_reports() {
    demo_checks(&[]);
}

/// The whole demo with the C drive firmware (`firmware/`) behind the simulated drive's pty: the
/// same record length, the same delay found, the same models (a few seconds, as the default demo:
/// the demo's drive runs in virtual time).
#[test]
fn demo_with_the_c_firmware_finds_the_hidden_delay() {
    // one measurement per frequency: the repeats are the host's, tested with the Rust firmware
    let stderr = demo_checks(&["--firmware", "--repeats", "1"]);
    assert!(stderr.contains("(C firmware)"), "{stderr}");
}

/// A file of the repository's example data (`data/` at the root). A missing file is a failure:
/// the data ships with the repository, so no test skips on a clean clone.
fn repo_data(name: &str) -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(name);
    assert!(
        p.is_file(),
        "{} is missing: the example data lives in data/ at the repository root",
        p.display()
    );
    p
}

#[test]
fn diagnosis_of_the_real_dc_motor_finds_its_transport_delay() {
    let f = repo_data("unal_dcmotor/DCmotor_prbs_open_exp.csv");
    let j = fracid_json(&[
        "time",
        f.to_str().unwrap(),
        "--quiet",
        "--diagnose",
        "--json",
    ]);
    let d = &j["diagnosis"];
    // The report leads with the model the diagnosis recommends (with its delay); the base fit
    // of the chosen structure is under `base`, its own model without the delay.
    assert_eq!(j["model"], d["model"], "{j}");
    assert!(j["model_is"].as_str().unwrap().starts_with("final"), "{j}");
    // its figures: the diagnosis's refit, the record's offset and initial state estimated
    // again to convergence (ident::app::time::rescore, what `score --as-fitted` gives)
    let (stated, refit) = (
        j["fit"]["validation"]["rmse"].as_f64().unwrap(),
        d["validation"]["after"]["rmse"].as_f64().unwrap(),
    );
    assert!(
        (stated - refit).abs() <= 1e-3 * refit,
        "{stated} vs {refit}"
    );
    assert_eq!(j["base"]["model"]["delay"].as_f64(), Some(0.0), "{j}");
    assert_eq!(
        j["base"]["fit"]["validation"], d["validation"]["before"],
        "{j}"
    );
    let delay = d["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == "delay")
        .unwrap_or_else(|| panic!("no delay kept: {d}"));
    let tau = delay["params"]["tau"].as_f64().unwrap();
    // Measured 16.9 ms; the record is sampled at 20 ms and FOPDT puts the delay at 19 ms.
    assert!((0.01..0.03).contains(&tau), "tau = {tau}");
    let before = d["before"]["rmse"].as_f64().unwrap();
    let after = d["after"]["rmse"].as_f64().unwrap();
    // Measured 3.90 -> 3.20 deg/s on the validation part (5.34 -> 3.50 before the initial state
    // was estimated: the base fit no longer carries the start-up transient); validation fit at
    // least 96% with the delay.
    assert!(after < 0.9 * before, "{before} -> {after}");
    let fit = d["after"]["nrmse_percent"].as_f64().unwrap();
    assert!(fit >= 96.0, "validation fit {fit}%");
    // The speed never reverses: friction must be reported as ambiguous, not fitted.
    let ambiguous = d["ambiguous"].to_string();
    assert!(ambiguous.contains("coulomb_friction"), "{ambiguous}");
    // The report agrees with the decision: the final model carries the kept delay (JSON and
    // text), the kept effect removed part of the residual, nothing kept is also rejected, and
    // the structure the diagnosis ran on is named among those compared.
    assert!(
        (d["model"]["delay"].as_f64().unwrap() - tau).abs() < 1e-12,
        "{d}"
    );
    let text = d["final_model"].as_str().unwrap();
    assert!(text.contains("exp(-"), "{text}");
    assert!(
        delay["ssr_removed_percent"].as_f64().unwrap() > 10.0,
        "{delay}"
    );
    let rejected = d["rejected"].as_array().unwrap();
    assert!(
        !rejected.iter().any(|r| r["name"] == "delay"),
        "{rejected:?}"
    );
    let s = &d["structures"];
    let chosen = s["chosen"].as_u64().unwrap() as usize;
    let names: Vec<&str> = s["scores"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert!(
        chosen < names.len() && names.contains(&"first-order"),
        "{s}"
    );
}

#[test]
fn diagnosis_of_the_paper_table_adds_nothing() {
    let f = repo_data("paper_table1_bode.csv");
    let j = fracid_json(&[
        "freq",
        f.to_str().unwrap(),
        "--refine",
        "--diagnose",
        "--json",
    ]);
    let d = &j["diagnosis"];
    assert_eq!(d["effects"].as_array().map(Vec::len), Some(0), "{d}");
    assert_eq!(d["unexplained"], false, "{d}");
    let refined_j = j["refined"]["J"].as_f64().unwrap();
    assert!(refined_j <= 2.0e-3, "{refined_j}");
}

#[test]
fn a_closed_stdout_ends_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    // `fracid sim ... | head -1`: the reader goes away after one line.
    let mut child = Command::new(fracid_bin())
        .args(["sim", "--prbs", "--t-end", "20"])
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run fracid");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("# fracid sim"), "{first}");
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn time_defaults_the_largest_delay_to_a_fifth_of_a_short_record() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("short.csv");
    // 0.8 s of a first-order plant (T = 50 ms, gain 2) with a 20 ms delay, dt = 1 ms, on a
    // random telegraph input (an aperiodic one: a periodic input leaves the delay ambiguous).
    let mut seed = 12345u64;
    let mut level = 1.0;
    let u: Vec<f64> = (0..800)
        .map(|k| {
            if k % 10 == 0 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                if seed >> 63 == 1 {
                    level = -level;
                }
            }
            level
        })
        .collect();
    let mut text = String::from("t,u,y\n");
    let mut x = 0.0_f64;
    for k in 0..800 {
        text.push_str(&format!("{},{},{}\n", k as f64 * 1e-3, u[k], x));
        let ud = if k >= 20 { u[k - 20] } else { 0.0 };
        x += 1e-3 / 0.05 * (2.0 * ud - x);
    }
    std::fs::write(&path, text).unwrap();
    let j = fracid_json(&[
        "time",
        path.to_str().unwrap(),
        "--structure",
        "fopdt",
        "--quiet",
        "--json",
    ]);
    let tau = j["model"]["delay"].as_f64().unwrap();
    assert!((tau - 0.02).abs() < 0.005, "tau = {tau}");
}

/// Issue 29's two-mass drive train: the paper's motor `6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)`
/// through a compliant coupling of equal inertias with viscoelastic damping (resonance near
/// 41 Hz, damping ratio about 0.05, anti-resonance near 28 Hz), simulated independently by
/// Grunwald-Letnikov with the input held (`fracsim::gl`, two Richardson levels: `dt/10`, `dt/20`
/// and `dt/20`, `dt/40`, extrapolated once more), PRBS (order 9, 2 ms clock, 4 periods) at
/// `dt = 1 ms`, seeded Gaussian noise of 0.13 (the output's standard deviation is about 9.6).
/// `fracid time FILE --diagnose` with defaults must choose the two-mass structure, keep no
/// effect (the resonance's phase lag was taken for a delay before the structure existed), and
/// its model's frequency response must be within 5% of the truth's from 1 Hz to twice the
/// resonance; the report's model text reads back as the reported terms.
#[test]
fn the_diagnosis_holds_a_two_mass_drive_trains_resonance() {
    use fracsim::FracTf;
    let truth: FracTf = "6.77*(3.1663e-5 s^2 + 2.34e-3 s^0.7 + 1)/((0.000028 s^1.78 + 0.0064 s^0.89 + 1)*(1.5831e-5 s^2 + 2.34e-3 s^0.7 + 1))"
        .parse()
        .unwrap();
    let dt = 1e-3;
    let u = fracsim::prbs::Prbs {
        order: 9,
        clock: 0.002,
        periods: 4,
        ..fracsim::prbs::Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    let clean = fracsim::gl::simulate_held_twice(&truth, &u, dt, 10).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = noisy_record(&dir.path().join("two_mass.csv"), &u, &clean, dt, 2929);
    let j = fracid_json(&[
        "time",
        path.to_str().unwrap(),
        "--quiet",
        "--diagnose",
        "--json",
    ]);
    let d = &j["diagnosis"];
    let s = &d["structures"];
    let chosen = s["chosen"].as_u64().unwrap() as usize;
    assert_eq!(s["scores"][chosen]["name"], "two-mass", "{s}");
    assert_eq!(d["effects"].as_array().map(Vec::len), Some(0), "{d}");
    assert!(
        s["reason"]
            .as_str()
            .unwrap()
            .contains("against the best usable integer-order model"),
        "{s}"
    );
    let terms = |side: &str| -> Vec<fracsim::Term> {
        j["model"][side]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| fracsim::Term::new(t["coef"].as_f64().unwrap(), t["order"].as_f64().unwrap()))
            .collect()
    };
    let model = FracTf::new(
        terms("num"),
        terms("den"),
        j["model"]["delay"].as_f64().unwrap(),
    )
    .unwrap();
    let worst = (0..200)
        .map(|i| {
            let w = 2.0 * std::f64::consts::PI * 80f64.powf(i as f64 / 199.0);
            let g = truth.freq_response(w);
            (model.freq_response(w) - g).norm() / g.norm()
        })
        .fold(0.0, f64::max);
    eprintln!("two-mass: {model}; FRF error 1-80 Hz {worst:.4}");
    assert!(worst <= 0.05, "frequency-response error {worst}");
    // The text reads back as the terms (to the last digit or so of the decimal text).
    let back: FracTf = j["model"]["text"].as_str().unwrap().parse().unwrap();
    let same = |a: &[fracsim::Term], b: &[fracsim::Term]| {
        a.len() == b.len()
            && a.iter().zip(b).all(|(x, y)| {
                (x.coef - y.coef).abs() <= 1e-14 * y.coef.abs()
                    && (x.order - y.order).abs() <= 1e-14 * y.order.abs().max(1.0)
            })
    };
    assert!(
        same(&back.num, &model.num) && same(&back.den, &model.den),
        "{}: read back {back:?}, reported {model:?}",
        j["model"]["text"]
    );
    // The held-out fit is at the noise (RMSE 0.13).
    let rmse = d["after"]["rmse"].as_f64().unwrap();
    assert!(rmse < 0.15, "{rmse}");
    // The text is the product of its factors (motor * pair), which `fracid sim` simulates (the
    // nine-term product multiplied out defeats one pole search) and `fracid export` exports: on
    // the record's own input, from rest, it follows the noiseless truth to a small part of the
    // swing (about 64).
    let text = j["model"]["text"].as_str().unwrap();
    assert!(text.contains(" * "), "{text}");
    let sim = sim_on_input(text, path.to_str().unwrap());
    assert_eq!(sim.len(), u.len());
    let err = (sim
        .iter()
        .zip(&clean)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / sim.len() as f64)
        .sqrt();
    eprintln!("fracid sim of the reported model against the truth: RMSE {err:.4}");
    assert!(err < 0.5, "{err}");
    exports(&j, dir.path());
}

/// A plant with a direct feed-through (issue 29): the paper's PMSM plus an instant response
/// `D = 2`, truth by Grunwald-Letnikov for the PMSM part (input held, Richardson) plus `D u_k`,
/// noise 0.13. `fracid time FILE --diagnose` with defaults must choose the feed-through
/// structure, keep no effect and find `D` within 0.04 (five standard errors of the instant
/// response under this noise, 4e-3, plus 1% of `D`: see crates/ident/tests/time/feedthrough.rs); `--structure feedthrough` alone finds it
/// too; the report's text simulates (`fracid sim`) like the noiseless truth and exports. The
/// plain fit (`--plain`: the PMSM, no feed-through) is reported for comparison.
#[test]
fn the_diagnosis_finds_a_direct_feedthrough() {
    use fracsim::FracTf;
    let (d_true, dt) = (2.0, 1e-3);
    let g: FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
        .parse()
        .unwrap();
    let u = fracsim::prbs::Prbs {
        order: 9,
        clock: 0.002,
        periods: 4,
        ..fracsim::prbs::Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    let g_out = fracsim::gl::simulate_held_twice(&g, &u, dt, 10).unwrap();
    let clean: Vec<f64> = (0..u.len()).map(|k| g_out[k] + d_true * u[k]).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = noisy_record(&dir.path().join("feedthrough.csv"), &u, &clean, dt, 2930);
    let file = path.to_str().unwrap();
    let param = |j: &serde_json::Value, name: &str| -> f64 {
        j["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("no {name} in {}", j["params"]))["value"]
            .as_f64()
            .unwrap()
    };
    let tol = 0.04;
    // The plain fit (`--plain`: the PMSM, no feed-through): it cannot describe the instant
    // response; it imitates it with orders that go undetermined and is refused as not usable
    // (exit 1), or at best predicts the held-out part worse than the feed-through does.
    let plain = fracid(&["time", file, "--quiet", "--plain", "--json"]);
    let plain_err = String::from_utf8_lossy(&plain.stderr).to_string();
    let plain_rmse = serde_json::from_slice::<serde_json::Value>(&plain.stdout)
        .ok()
        .and_then(|j| j["fit"]["validation"]["rmse"].as_f64());
    eprintln!(
        "plain fit: exit {:?}, held-out RMSE {plain_rmse:?}; {}",
        plain.status.code(),
        plain_err.lines().next().unwrap_or("")
    );
    let j = fracid_json(&["time", file, "--quiet", "--diagnose", "--json"]);
    let d = &j["diagnosis"];
    let s = &d["structures"];
    let chosen = s["chosen"].as_u64().unwrap() as usize;
    assert_eq!(s["scores"][chosen]["name"], "feedthrough", "{s}");
    assert_eq!(d["effects"].as_array().map(Vec::len), Some(0), "{d}");
    let dhat = param(&j, "D");
    eprintln!("--diagnose: {} D = {dhat}", j["model"]["text"]);
    assert!((dhat - d_true).abs() < tol, "D = {dhat}");
    let rmse = d["after"]["rmse"].as_f64().unwrap();
    assert!(rmse < 0.14, "{rmse}");
    assert!(
        plain.status.code() == Some(1) && plain_err.contains("not usable")
            || plain_rmse.is_some_and(|r| r > 1.5 * rmse),
        "plain fit: {:?} {plain_rmse:?} {plain_err}",
        plain.status.code()
    );
    let named = fracid_json(&[
        "time",
        file,
        "--quiet",
        "--structure",
        "feedthrough",
        "--json",
    ]);
    let dn = param(&named, "D");
    assert!(
        (dn - d_true).abs() < tol,
        "--structure feedthrough: D = {dn}"
    );
    // The reported text is `D + G` as one fraction: `fracid sim` runs it on the record's input
    // from rest and follows the noiseless truth (swing about 20) to a small part of the noise.
    let text = j["model"]["text"].as_str().unwrap();
    assert!(text.starts_with(&format!("{dhat} + ")), "{text}");
    let sim = sim_on_input(text, file);
    assert_eq!(sim.len(), u.len());
    // The fitted model carries an output offset and an initial state the sim does not: compare
    // after removing the mean difference.
    let diff: Vec<f64> = sim.iter().zip(&clean).map(|(a, b)| a - b).collect();
    let mean = diff.iter().sum::<f64>() / diff.len() as f64;
    let err = (diff
        .iter()
        .skip(50)
        .map(|v| (v - mean).powi(2))
        .sum::<f64>()
        / (diff.len() - 50) as f64)
        .sqrt();
    eprintln!("fracid sim of the reported model against the truth: RMSE {err:.4}");
    assert!(err < 0.05, "{err}");
    exports(&j, dir.path());
}

/// `u` and `clean` plus seeded Gaussian noise of standard deviation 0.13 (Box-Muller on a 64-bit
/// LCG), written to `path` as `t,u,y` at `dt`.
fn noisy_record(path: &std::path::Path, u: &[f64], clean: &[f64], dt: f64, seed: u64) -> PathBuf {
    let mut seed = seed;
    let mut uniform = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut text = String::from("t,u,y\n");
    for k in 0..u.len() {
        let (a, b) = (uniform(), uniform());
        let e = 0.13 * (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos();
        text.push_str(&format!("{},{},{}\n", k as f64 * dt, u[k], clean[k] + e));
    }
    std::fs::write(path, text).unwrap();
    path.to_path_buf()
}

/// `fracid sim --model MODEL --input FILE`'s output column (the command must succeed).
fn sim_on_input(model: &str, file: &str) -> Vec<f64> {
    let out = fracid(&["sim", "--model", model, "--input", file]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect()
}

/// `fracid export REPORT --dt 1e-3` of the report `j` (written into `dir`) succeeds.
fn exports(j: &serde_json::Value, dir: &std::path::Path) {
    let json = dir.join("report.json");
    std::fs::write(&json, j.to_string()).unwrap();
    let out = fracid(&["export", json.to_str().unwrap(), "--dt", "1e-3"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A child process killed when the guard goes, also when the test fails.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `fracid drive sim --baud 921600 --duration 120 EXTRA` on a pty: the process (killed on drop),
/// the port path it prints and its stdout (kept by the caller for a live pipe, or dropped); its
/// stderr goes to `stderr`.
#[cfg(unix)]
fn spawn_drive_sim(
    extra: &[&str],
    stderr: std::process::Stdio,
) -> (
    KillOnDrop,
    String,
    std::io::BufReader<std::process::ChildStdout>,
) {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut sim = KillOnDrop(
        Command::new(fracid_bin())
            .args(["drive", "sim", "--baud", "921600", "--duration", "120"])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .expect("start the drive simulator"),
    );
    let mut port = String::new();
    let mut sim_out = BufReader::new(sim.0.stdout.take().expect("sim stdout"));
    sim_out
        .read_line(&mut port)
        .expect("the simulator prints its port");
    let port = port.trim().to_string();
    assert!(!port.is_empty(), "no port from the simulator");
    (sim, port, sim_out)
}

/// `fracid drive sim` on a pty, fast line, real time; its port path. The child is kept for its
/// stdout pipe.
#[cfg(unix)]
fn drive_sim_piped() -> (
    KillOnDrop,
    String,
    std::io::BufReader<std::process::ChildStdout>,
) {
    spawn_drive_sim(&[], std::process::Stdio::null())
}

/// `fracid drive ARGS --port PORT --baud 921600 -o OUT --quiet`, stderr piped, with SIGINT and
/// SIGQUIT at their default action: a suite started as a background job of a non-interactive
/// shell inherits them ignored, and fracid (as a shell's background job should) then leaves
/// Ctrl-C alone, which the signal tests are not about.
#[cfg(unix)]
fn drive_cmd(args: &[&str], port: &str, out: &std::path::Path) -> KillOnDrop {
    use std::os::unix::process::CommandExt;
    use std::process::Stdio;
    let mut cmd = Command::new(fracid_bin());
    // SAFETY: only signal(2), async-signal-safe, between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            libc::signal(libc::SIGQUIT, libc::SIG_DFL);
            Ok(())
        });
    }
    KillOnDrop(
        cmd.arg("drive")
            .args(args)
            .args(["--port", port, "--baud", "921600", "--quiet"])
            .arg("-o")
            .arg(out)
            .env("RUST_BACKTRACE", "0")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start fracid drive"),
    )
}

/// Rows of a CSV that start with a digit (data, not header or comments).
fn data_rows(text: &str) -> usize {
    text.lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count()
}

/// Wait until `path` has `rows` data rows (the child still running), at most 20 s.
#[cfg(unix)]
fn wait_rows(child: &mut KillOnDrop, path: &std::path::Path, rows: usize) {
    use std::time::{Duration, Instant};
    let t0 = Instant::now();
    loop {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if data_rows(&text) >= rows {
            return;
        }
        assert!(
            child.0.try_wait().unwrap().is_none(),
            "ended before the test acted: {text}"
        );
        assert!(t0.elapsed() < Duration::from_secs(20), "no data: {text}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Wait for the child to end by itself (at most `secs`); its status and stderr.
#[cfg(unix)]
fn wait_end(child: &mut KillOnDrop, secs: u64) -> (std::process::ExitStatus, String) {
    use std::time::{Duration, Instant};
    let t1 = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            t1.elapsed() < Duration::from_secs(secs),
            "still running after {secs} s"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.0.stderr.take().unwrap(), &mut stderr).unwrap();
    (status, stderr)
}

#[cfg(unix)]
fn signal(child: &KillOnDrop, sig: libc::c_int) {
    let pid = child.0.id() as libc::pid_t;
    // SAFETY: signalling our own child, which has not been reaped yet.
    assert_eq!(unsafe { libc::kill(pid, sig) }, 0);
}

/// Every data row of a `t,u,y,i` record has four numbers; their count.
fn check_record_rows(text: &str) -> usize {
    let rows: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("t,"))
        .collect();
    for row in &rows {
        let v: Vec<f64> = row
            .split(',')
            .map(|x| {
                x.parse()
                    .unwrap_or_else(|_| panic!("not a number in {row:?}"))
            })
            .collect();
        assert_eq!(v.len(), 4, "{row}");
    }
    rows.len()
}

/// The first missing sample of an `# incomplete: missing samples a..b` footer.
fn first_missing(footer: &str) -> usize {
    footer["# incomplete: missing samples ".len()..]
        .split("..")
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// A signal during `fracid drive prbs`: STOP to the drive, the record finished with a footer,
/// exit 128 + the signal.
#[cfg(unix)]
fn a_signal_stops_a_prbs_run(sig: libc::c_int, code: i32, name: &str) {
    let (_sim, port, _sim_out) = drive_sim_piped();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("prbs.csv");
    // 20 periods of 127 bits at 3 ms: about 8 s of run, far more than the test waits.
    let mut prbs = drive_cmd(&["prbs", "--periods", "20"], &port, &out);
    wait_rows(&mut prbs, &out, 200);
    signal(&prbs, sig);
    let (status, stderr) = wait_end(&mut prbs, 10);
    // it ended by itself (not killed by the signal), with the signal's exit code
    assert_eq!(status.code(), Some(code), "{status:?}: {stderr}");
    assert!(
        stderr.contains(&format!("interrupted by {name}")),
        "{stderr}"
    );
    assert!(stderr.contains("missing samples"), "{stderr}");

    let text = std::fs::read_to_string(&out).unwrap();
    let footer = text.trim_end().lines().last().unwrap();
    assert!(
        footer.starts_with("# incomplete: missing samples "),
        "{footer}"
    );
    // the drive acknowledged the STOP and ended the run for that reason
    assert!(footer.contains("Stopped"), "{footer}");
    let rows = check_record_rows(&text);
    assert!(rows >= 200, "{rows} rows");
    // the footer's first missing sample is the count of samples kept
    assert_eq!(first_missing(footer), rows, "{footer}");
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_a_prbs_run_and_the_record_says_what_is_missing() {
    a_signal_stops_a_prbs_run(libc::SIGINT, 130, "SIGINT");
}

#[cfg(unix)]
#[test]
fn sigterm_and_sighup_stop_a_prbs_run_like_ctrl_c() {
    a_signal_stops_a_prbs_run(libc::SIGTERM, 143, "SIGTERM");
    a_signal_stops_a_prbs_run(libc::SIGHUP, 129, "SIGHUP");
}

/// Issue 12: SIGHUP from a terminal that closed. stderr is a pty whose master is gone, so every
/// write to it fails with EIO; the summary after the run used `eprintln!`, which panics on that
/// (exit 101, though the record was already finished). Now the run still ends with 129 and the
/// record has its footer.
#[cfg(target_os = "linux")]
#[test]
fn a_sighup_with_stderr_gone_still_finishes_the_record() {
    use std::os::fd::{FromRawFd, OwnedFd};
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let (_sim, port, _sim_out) = drive_sim_piped();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("prbs.csv");
    let (mut m, mut sl) = (-1, -1);
    // SAFETY: openpty writes two new descriptors, owned below.
    let rc = unsafe {
        libc::openpty(
            &mut m,
            &mut sl,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    assert_eq!(rc, 0, "openpty");
    // not inherited by the child (openpty does not set close-on-exec): the master must be gone
    // from every process for the terminal to hang up
    for fd in [m, sl] {
        // SAFETY: fcntl on the descriptors just opened.
        assert_eq!(
            unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) },
            0
        );
    }
    // SAFETY: fresh descriptors from openpty, each owned once.
    let (master, slave) = unsafe { (OwnedFd::from_raw_fd(m), OwnedFd::from_raw_fd(sl)) };
    let mut child = KillOnDrop(
        Command::new(fracid_bin())
            .args(["drive", "prbs", "--periods", "20"])
            .args(["--port", &port, "--baud", "921600", "--quiet"])
            .arg("-o")
            .arg(&out)
            .env("RUST_BACKTRACE", "0")
            .stdout(Stdio::null())
            .stderr(Stdio::from(slave))
            .spawn()
            .expect("start fracid drive"),
    );
    // the terminal goes away: writes to its slave side now fail with EIO
    drop(master);
    wait_rows(&mut child, &out, 200);
    signal(&child, libc::SIGHUP);
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait().unwrap() {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "still running");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(
        status.code(),
        Some(129),
        "{status:?} (101: a panic writing to stderr)"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let footer = text.trim_end().lines().last().unwrap();
    assert!(
        footer.starts_with("# incomplete: missing samples "),
        "{footer}"
    );
    assert_eq!(first_missing(footer), check_record_rows(&text), "{footer}");
}

#[cfg(unix)]
#[test]
fn killing_the_drive_mid_run_leaves_a_finished_record() {
    let (mut sim, port, _sim_out) = drive_sim_piped();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("prbs.csv");
    let mut prbs = drive_cmd(&["prbs", "--periods", "20"], &port, &out);
    wait_rows(&mut prbs, &out, 200);
    // The port's name held (a slave descriptor of our own, never read): once the simulator is
    // gone the kernel would give the pty's number to the next one opened, and with the tests
    // run in parallel another test's simulator then answered at the same path (the client
    // reconnected to a drive on another run and stopped for that reason instead).
    let _held = {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
            .open(&port)
            .unwrap()
    };
    // kill -9 of the simulator: the pty goes away for good
    sim.0.kill().unwrap();
    sim.0.wait().unwrap();
    // the reconnect window (3 s) and a little
    let (status, stderr) = wait_end(&mut prbs, 15);
    assert_eq!(status.code(), Some(1), "{status:?}: {stderr}");
    assert!(stderr.contains("lost the port"), "{stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    let footer = text.trim_end().lines().last().unwrap();
    assert!(
        footer.starts_with("# incomplete: missing samples "),
        "{footer}"
    );
    assert!(footer.contains("lost the port"), "{footer}");
    let rows = check_record_rows(&text);
    assert!(rows >= 200, "{rows} rows");
    assert_eq!(first_missing(footer), rows, "{footer}");
    // ... up to the planned end: 0.3 s settle + 20 x 127 x 3 ms at 1 kHz = 300 + 7620 samples
    assert!(footer.contains(&format!("{rows}..7920 (")), "{footer}");
}

#[cfg(unix)]
#[test]
fn a_sine_sweep_with_repeats_writes_the_spread_and_the_complete_footer() {
    let (_sim, port, _sim_out) = drive_sim_piped();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bode.csv");
    let mut sine = drive_cmd(
        &[
            "sine",
            "--freqs",
            "20,40,80",
            "--min-settle",
            "0.05",
            "--repeats",
            "3",
        ],
        &port,
        &out,
    );
    let (status, stderr) = wait_end(&mut sine, 60);
    assert!(status.success(), "{status:?}: {stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("# hold: zero-order"), "{text}");
    assert!(
        text.contains("# frequencies applied so the window holds whole cycles"),
        "{text}"
    );
    assert!(
        text.contains("# 3 repeats per frequency: trimmed mean"),
        "{text}"
    );
    assert!(
        text.lines()
            .any(|l| l == "freq_hz,gain_db,phase_deg,gain_db_std,phase_deg_std,repeats"),
        "{text}"
    );
    let rows: Vec<Vec<&str>> = text
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 3, "{text}");
    for r in &rows {
        assert_eq!(r.len(), 6, "{r:?}");
        assert_eq!(r[5], "3", "{r:?}");
        for v in &r[3..5] {
            let v: f64 = v.parse().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{r:?}");
        }
    }
    let footer = text.trim_end().lines().last().unwrap();
    assert_eq!(footer, "# complete: 3 frequencies", "{text}");
    // the single repeats, beside it, as measured
    let mut reps = out.clone().into_os_string();
    reps.push(".repeats.csv");
    let reps = std::fs::read_to_string(&reps).unwrap();
    assert!(
        reps.lines()
            .any(|l| l == "freq_hz,repeat,gain_db,phase_deg"),
        "{reps}"
    );
    assert_eq!(data_rows(&reps), 9, "{reps}");
    // and `fracid freq` reads the table back, spread columns included (Vinagre's weights: the
    // simulator has no noise, so the repeats agree too closely for the spread's)
    let fit = fracid(&[
        "freq",
        out.to_str().unwrap(),
        "--n",
        "1",
        "--weights",
        "vinagre",
    ]);
    assert!(
        fit.status.success(),
        "{}",
        String::from_utf8_lossy(&fit.stderr)
    );
}

#[cfg(unix)]
#[test]
fn a_signal_during_a_sine_sweep_keeps_the_measured_points() {
    let (_sim, port, _sim_out) = drive_sim_piped();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bode.csv");
    let freqs = "20,25,30,35,40,45,50,55,60,65,70,75,80,85,90,95";
    let mut sine = drive_cmd(
        &["sine", "--freqs", freqs, "--min-settle", "0.05"],
        &port,
        &out,
    );
    // written as measured: two points in the file while the sweep goes on
    wait_rows(&mut sine, &out, 2);
    signal(&sine, libc::SIGTERM);
    let (status, stderr) = wait_end(&mut sine, 10);
    assert_eq!(status.code(), Some(143), "{status:?}: {stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    let rows = data_rows(&text);
    assert!((2..16).contains(&rows), "{rows}: {text}");
    assert!(text.contains("# hold: zero-order"), "{text}");
    let footer = text.trim_end().lines().last().unwrap();
    assert!(
        footer.starts_with("# incomplete: missing frequencies (Hz) "),
        "{footer}"
    );
    // the missing ones are exactly those not in the table
    let listed: Vec<&str> = footer["# incomplete: missing frequencies (Hz) ".len()..]
        .split(" (")
        .next()
        .unwrap()
        .split(", ")
        .collect();
    assert_eq!(listed.len() + rows, 16, "{footer}");
    for f in &listed {
        assert!(
            !text.lines().any(|l| l.starts_with(&format!("{f},"))),
            "{f} listed as missing but in the table"
        );
    }
}

#[test]
fn bad_drive_options_fail_before_the_drive_and_leave_the_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let keep = dir.path().join("keep.csv");
    let old = "# an earlier recording\nt,u,y,i\n0,6,0,0\n";
    std::fs::write(&keep, old).unwrap();
    let keep_s = keep.to_str().unwrap();
    // No drive at that port: an exit 2 proves the options were checked before it was opened.
    for bad in [
        &["--seed", "0"][..],
        &["--order", "1"],
        &["--amplitude", "100"],
        &["--sample-rate", "0"],
        &["--block", "0"],
        &["--clock", "0.0025"],
        &["--offset", "30"],
        &["--settle", "nan"],
    ] {
        let mut args = vec!["drive", "prbs", "--port", "/nonexistent/tty", "-o", keep_s];
        args.extend_from_slice(bad);
        let out = fracid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(std::fs::read_to_string(&keep).unwrap(), old, "{bad:?}");
    }
    // A port that cannot be opened: exit 3, the file untouched.
    let out = fracid(&["drive", "prbs", "--port", "/nonexistent/tty", "-o", keep_s]);
    assert_eq!(out.status.code(), Some(3));
    assert_eq!(std::fs::read_to_string(&keep).unwrap(), old);
    // An output that cannot be written fails at once, before the drive (the port is named
    // nowhere in the message: it was not tried).
    for cmd in ["prbs", "sine"] {
        let out = fracid(&[
            "drive",
            cmd,
            "--port",
            "/nonexistent/tty",
            "-o",
            "/nonexistent/x.csv",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{cmd}: {err}");
        assert!(err.contains("/nonexistent/x.csv"), "{err}");
        assert!(!err.contains("/nonexistent/tty"), "{err}");
    }
    // sine options
    for bad in [
        &["--freqs", "600"][..],
        &["--sample-rate", "0"],
        &["--amplitude", "0"],
        &["--offset", "40", "--amplitude", "1"],
        &["--cycles", "0"],
    ] {
        let mut args = vec!["drive", "sine", "--port", "/nonexistent/tty", "-o", keep_s];
        args.extend_from_slice(bad);
        let out = fracid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {err}");
        assert_eq!(std::fs::read_to_string(&keep).unwrap(), old, "{bad:?}");
    }
}

#[test]
fn bad_simulator_options_are_refused_with_exit_2() {
    // --duration 1: an option wrongly accepted would start the simulator and exit 0 after 1 s
    for bad in [
        &["--delay", "1e9"][..],
        &["--delay=-1"],
        &["--noise", "nan"],
        &["--noise=-1"],
        &["--coulomb", "inf"],
        &["--ripple-hz", "nan"],
        &["--speed-quant=-0.1"],
        &["--ber", "2"],
        &["--drop-rate", "nan"],
        &["--burst-len", "100000000"],
        &["--stall-ms", "100000000000", "--stall-at", "10"],
        &["--baud", "0"],
    ] {
        let mut args = vec!["drive", "sim", "--duration", "1"];
        args.extend_from_slice(bad);
        let out = fracid(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {err}");
        assert!(err.starts_with("error: "), "{bad:?}: {err}");
        assert!(!err.contains("cannot be used multiple times"), "{err}");
    }
    for d in ["nan", "0", "-1"] {
        let arg = format!("--duration={d}");
        let out = fracid(&["drive", "sim", &arg]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "--duration {d}: {err}");
    }
}

/// `fracid drive sim` with `extra` args, at 921600 baud with deterministic hidden effects: the
/// process (killed on drop), the port it prints and its first stderr line (which names the firmware).
#[cfg(unix)]
fn drive_sim(extra: &[&str]) -> (KillOnDrop, String, String) {
    use std::io::{BufRead, BufReader};
    let mut args = vec!["--delay", "0.002", "--noise", "0.05", "--seed", "7"];
    args.extend(extra);
    let (mut sim, port, _) = spawn_drive_sim(&args, std::process::Stdio::piped());
    let mut banner = String::new();
    BufReader::new(sim.0.stderr.take().expect("sim stderr"))
        .read_line(&mut banner)
        .expect("the simulator says what it runs");
    (sim, port, banner)
}

/// The link options of a host command on a simulated drive in virtual time: the port, the fast
/// line, a keepalive every 2 ms (a simulator in virtual time runs at most half of it past the
/// host's last frame), no progress output.
#[cfg(unix)]
fn virtual_time_link(port: &str) -> [&str; 7] {
    [
        "--port",
        port,
        "--baud",
        "921600",
        "--keepalive-ms",
        "2",
        "--quiet",
    ]
}

/// `fracid drive prbs` and `fracid drive sine` against a simulator in virtual time (a host
/// keepalive every 2 ms): the PRBS CSV and the Bode CSV.
#[cfg(unix)]
fn drive_records(port: &str, dir: &std::path::Path, tag: &str) -> (String, String) {
    let prbs = dir.join(format!("prbs_{tag}.csv"));
    let bode = dir.join(format!("bode_{tag}.csv"));
    let common = virtual_time_link(port);
    let mut a = vec!["drive", "prbs", "--settle", "0.1", "-o"];
    a.push(prbs.to_str().unwrap());
    a.extend(common);
    let out = fracid(&a);
    assert!(
        out.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut a = vec![
        "drive",
        "sine",
        "--freqs",
        "20,70",
        "--min-settle",
        "0.05",
        "-o",
    ];
    a.push(bode.to_str().unwrap());
    a.extend(common);
    let out = fracid(&a);
    assert!(
        out.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        std::fs::read_to_string(prbs).unwrap(),
        std::fs::read_to_string(bode).unwrap(),
    )
}

#[cfg(unix)]
#[test]
fn drive_sim_firmware_c_gives_the_rust_firmware_records() {
    let _g = realtime_lock();
    let dir = tempfile::tempdir().unwrap();
    // virtual time: the records depend on the seed alone
    let (sim_c, port_c, banner_c) = drive_sim(&["--firmware", "c", "--virtual-time"]);
    assert!(banner_c.contains("(C firmware)"), "{banner_c}");
    let (prbs_c, bode_c) = drive_records(&port_c, dir.path(), "c");
    drop(sim_c);
    let (sim_r, port_r, banner_r) = drive_sim(&["--firmware", "rust", "--virtual-time"]);
    assert!(banner_r.contains("(Rust firmware)"), "{banner_r}");
    let (prbs_r, bode_r) = drive_records(&port_r, dir.path(), "rust");
    drop(sim_r);
    // The PRBS record: complete, and the same text row for row (t, u, y, i; y with the seeded
    // noise and the hidden delay), footer included.
    assert!(
        prbs_c.trim_end().ends_with("# complete: 481 samples"),
        "{}",
        prbs_c.lines().last().unwrap_or("")
    );
    assert_eq!(prbs_c.lines().count(), prbs_r.lines().count());
    for (k, (c, r)) in prbs_c.lines().zip(prbs_r.lines()).enumerate() {
        assert_eq!(
            c, r,
            "PRBS line {k} differs between the C and the Rust firmware"
        );
    }
    // The Bode table from the drive's DFT: the C firmware sums in 64-bit fixed point, the Rust one
    // in f64, both rounded to Q8 (1/256 LSB): they may differ by one Q8 unit, far below 1e-3 dB
    // and 1e-3 degrees at these amplitudes.
    let rows = |t: &str| -> Vec<Vec<f64>> {
        t.lines()
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect()
    };
    let (bc, br) = (rows(&bode_c), rows(&bode_r));
    assert_eq!(bc.len(), 2, "{bode_c}");
    assert_eq!(br.len(), 2, "{bode_r}");
    for (c, r) in bc.iter().zip(&br) {
        assert_eq!(c[0], r[0]);
        assert!((c[1] - r[1]).abs() < 1e-3, "gain: C {c:?} vs Rust {r:?}");
        assert!((c[2] - r[2]).abs() < 1e-3, "phase: C {c:?} vs Rust {r:?}");
    }
    // A wrong value is bad input (exit 2), with the choices in the message.
    let out = fracid(&["drive", "sim", "--firmware", "asm"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("[possible values: rust, c]"), "{err}");
}

/// The simulator process paused for 0.8 s in the middle of a PRBS run (as a loaded machine can
/// pause it), while the client goes on sending keepalives: the run must not end on the keepalive,
/// with either firmware. (The C engine counts its keepalive in samples; the simulator used to run
/// the whole backlog of samples at once after such a pause, and the C run expired.)
#[cfg(unix)]
#[test]
fn a_paused_simulator_does_not_expire_the_keepalive() {
    use std::process::Stdio;
    use std::time::Duration;
    let _g = realtime_lock();
    let dir = tempfile::tempdir().unwrap();
    for fw in ["c", "rust"] {
        let (sim, port, _) = drive_sim(&["--firmware", fw]);
        let out = dir.path().join(format!("prbs_{fw}.csv"));
        let mut prbs = KillOnDrop(
            Command::new(fracid_bin())
                .args(["drive", "prbs", "--port", &port, "--baud", "921600"])
                .args(["--periods", "4", "--quiet", "--allow-incomplete", "-o"])
                .arg(&out)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .expect("start fracid drive prbs"),
        );
        std::thread::sleep(Duration::from_millis(700));
        let pid = sim.0.id() as libc::pid_t;
        // SAFETY: signalling our own child, which has not been reaped yet.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGSTOP) }, 0);
        std::thread::sleep(Duration::from_millis(800));
        // SAFETY: as above.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGCONT) }, 0);
        let status = prbs.0.wait().unwrap();
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut prbs.0.stderr.take().unwrap(), &mut stderr).unwrap();
        assert!(status.success(), "{fw}: {status:?} {stderr}");
        let text = std::fs::read_to_string(&out).unwrap();
        let footer = text.trim_end().lines().last().unwrap();
        assert!(footer.starts_with("# "), "{fw}: {footer}");
        assert!(
            !footer.contains("Keepalive") && !footer.contains("ended early"),
            "{fw}: {footer}"
        );
        drop(sim);
    }
}
