//! `fracid time`: exit codes, JSON keys (docs/design.md §7), the plot, the start report, the UNAL record.

use super::{fracid, stderr, stdout};
use std::fmt::Write as _;
use std::path::PathBuf;

mod general;
mod verdict;

/// A noise-free PRBS record of `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)` around an operating point:
/// order 7, 10-sample bits, 3 periods at 1 ms, after 50 samples at rest.
fn pmsm_csv(dir: &tempfile::TempDir) -> PathBuf {
    let dt = 1e-3;
    let g = fracsim::FracTf::pmsm(3.0, 0.02, 1e-4, 0.9, 0.8).unwrap();
    let mut u = vec![0.0; 50];
    u.extend(
        fracsim::prbs::Prbs {
            clock: 10.0 * dt,
            periods: 3,
            ..fracsim::prbs::Prbs::paper()
        }
        .signal(dt)
        .unwrap(),
    );
    let y = fracsim::Simulator::<f64>::new(&g, dt, &Default::default())
        .unwrap()
        .simulate(&u);
    let mut text = String::from("# generated\nt,u,y\n");
    for (k, (u, y)) in u.iter().zip(&y).enumerate() {
        writeln!(text, "{:.6},{},{}", k as f64 * dt, 12.0 + u, 1500.0 + y).unwrap();
    }
    let p = dir.path().join("pmsm.csv");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_missing_file_exits_3() {
    let o = fracid(&["time", "/nonexistent/record.csv", "--quiet"]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot read"), "{}", stderr(&o));
}

#[test]
fn bad_data_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text, want) in [
        ("cols.csv", "t,u\n0,1\n1,2\n", "no column 'y'"),
        ("nan.csv", "t,u,y\n0,1,2\n1,1,nan\n2,1,2\n", "not finite"),
        (
            "time.csv",
            "t,u,y\n0,1,2\n2,1,2\n1,1,2\n",
            "strictly increasing",
        ),
        ("one.csv", "t,u,y\n0,1,2\n", "samples"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let o = fracid(&["time", p.to_str().unwrap(), "--quiet"]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{name}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{name}: {}", stderr(&o));
    }
    // A constant input: no excitation.
    let mut text = String::from("t,u,y\n");
    for k in 0..300 {
        writeln!(text, "{},1,{}", k as f64 * 0.01, (k % 3) as f64).unwrap();
    }
    let p = dir.path().join("const.csv");
    std::fs::write(&p, text).unwrap();
    let o = fracid(&["time", p.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no excitation"), "{}", stderr(&o));
    // Bad options.
    let csv = pmsm_csv(&dir);
    for args in [
        vec!["--holdout", "2"],
        vec!["--offsets", "sideways"],
        vec!["--band", "100,1"],
    ] {
        let mut a = vec!["time", csv.to_str().unwrap(), "--quiet"];
        a.extend(&args);
        let o = fracid(&a);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn a_delay_not_shorter_than_the_record_exits_2() {
    // 3.86 s of record, 2.702 s for estimation: a delay of 10 s ran and reported a fit with
    // only a singular-covariance warning.
    let dir = tempfile::tempdir().unwrap();
    let csv = pmsm_csv(&dir);
    for args in [
        vec!["--structure", "1/(s+1) exp(-10 s)"],
        vec!["--structure", "fopdt", "--max-delay", "3"],
        vec!["--delay", "--max-delay", "2.8"],
    ] {
        let mut a = vec!["time", csv.to_str().unwrap(), "--quiet"];
        a.extend(&args);
        let o = fracid(&a);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("not shorter than the estimation record"),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn json_has_the_design_keys_and_the_plot_is_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let csv = pmsm_csv(&dir);
    let png = dir.path().join("fit.png");
    let o = fracid(&[
        "time",
        csv.to_str().unwrap(),
        "--json",
        "--quiet",
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for t in ["num", "den"] {
        for term in v["model"][t].as_array().unwrap() {
            assert!(term["coef"].is_f64() && term["order"].is_f64(), "{term}");
        }
    }
    assert_eq!(v["model"]["den"].as_array().unwrap().len(), 3);
    assert!(v["model"]["delay"].is_f64());
    for part in ["estimation", "validation"] {
        assert!(v["fit"][part]["rmse"].is_f64(), "{}", v["fit"]);
        // Noise-free data from the same structure: the fit is near perfect (measured 99.9%).
        let f = v["fit"][part]["nrmse_percent"].as_f64().unwrap();
        assert!(f > 99.0, "{part}: {f}");
    }
    // The input is periodic after the rest: the Levy start is used and said so.
    assert_eq!(v["start"]["method"], "levy", "{}", v["start"]);
    let k = v["model"]["num"][0]["coef"].as_f64().unwrap();
    assert!((k / 3.0 - 1.0).abs() < 0.01, "K = {k}");
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(bytes.len() > 10_000, "{} bytes", bytes.len());
}

#[test]
fn text_output_names_the_start() {
    let dir = tempfile::tempdir().unwrap();
    let csv = pmsm_csv(&dir);
    let o = fracid(&["time", csv.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = stdout(&o);
    assert!(s.contains("start: Levy fit"), "{s}");
    assert!(s.contains("fit validation: NRMSE"), "{s}");
    let o = fracid(&["time", csv.to_str().unwrap(), "--quiet", "--no-auto-start"]);
    assert!(
        stdout(&o).contains("start: the given values"),
        "{}",
        stdout(&o)
    );
}

/// The UNAL DC-motor PRBS record (a real motor; not periodic, so the coarse start).
#[test]
fn unal_record_fits() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/unal_dcmotor/DCmotor_prbs_open_exp.csv");
    assert!(
        p.is_file(),
        "{} is missing (data/ ships with the repository)",
        p.display()
    );
    // Measured validation NRMSE (30% held out): pmsm 93.95%, fopdt 95.73%; floors 3 points lower.
    for (structure, floor) in [("pmsm", 91.0), ("fopdt", 92.5)] {
        let o = fracid(&[
            "time",
            p.to_str().unwrap(),
            "--structure",
            structure,
            "--max-delay",
            "0.1",
            "--json",
            "--quiet",
        ]);
        assert_eq!(o.status.code(), Some(0), "{structure}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        let f = v["fit"]["validation"]["nrmse_percent"].as_f64().unwrap();
        eprintln!(
            "UNAL {structure}: validation {f:.2}%, start {}",
            v["start"]["method"]
        );
        assert!(f > floor, "{structure}: validation NRMSE {f}");
        assert_eq!(v["start"]["method"], "coarse");
    }
}

/// The UNAL DC-motor step record (steady, then one step at 3 s): fitted with defaults, the step
/// kept in the estimation part and the validation said to be the tail of its response.
/// Measured: estimation NRMSE 97.2%, validation RMSE 3.2 deg/s (estimation 2.7).
#[test]
fn unal_step_record_fits_with_defaults() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/unal_dcmotor/DCmotor_step_open_exp.csv");
    let o = fracid(&["time", p.to_str().unwrap(), "--json", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["usable"], true, "{v}");
    assert_eq!(v["validated_by"]["kind"], "response_tail", "{v}");
    // The step is at sample 150 of 302: it stays in the estimation part.
    let est = v["split"]["estimation_samples"].as_u64().unwrap();
    assert!(est > 150, "{est}");
    let fit = v["fit"]["estimation"]["nrmse_percent"].as_f64().unwrap();
    assert!(fit > 90.0, "estimation NRMSE {fit}");
    let warnings = v["warnings"].to_string();
    assert!(warnings.contains("tail of the"), "{warnings}");
    let o = fracid(&["time", p.to_str().unwrap(), "--quiet"]);
    assert!(
        stdout(&o).contains("validated by: the input changes too rarely"),
        "{}",
        stdout(&o)
    );
}

/// The motor/generator record (t in source samples, dt = 100) starts idle, then steps: fitted
/// from rest with the paper's structure, no delay and the approximation band `[1e-3, 0.9425]`
/// rad/s (the default before session 14, when the lower edge was absolute: two decades of this
/// record's band missing), the model predicts the held-out steps worse than their mean (measured
/// NRMSE -161.8%): not usable, exit 1, the reason in the JSON and on stderr; with the default band
/// it is usable (39.9%), and `--diagnose` finds a usable model (> 40%).
#[test]
fn a_model_worse_than_the_mean_on_held_out_steps_is_not_usable() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/sysidentpy_motor_generator/motor_generator_steps.csv");
    let args = ["time", "--plain", p.to_str().unwrap(), "--json", "--quiet"];
    let o = fracid(&[&args[..], &["--band", "1e-3,0.9425"]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["usable"], false);
    assert_eq!(
        v["initial_state"]["state"], "rest",
        "{}",
        v["initial_state"]
    );
    assert_eq!(v["validated_by"]["kind"], "held_out");
    let problems = v["problems"].to_string();
    assert!(problems.contains("worse than its mean"), "{problems}");
    assert!(v["fit"]["validation"]["nrmse_percent"].as_f64().unwrap() < 0.0);
    let o = fracid(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = fracid(&[
        "time",
        p.to_str().unwrap(),
        "--json",
        "--quiet",
        "--diagnose",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["usable"], true);
    assert!(
        v["fit"]["validation"]["nrmse_percent"].as_f64().unwrap() > 40.0,
        "{}",
        v["fit"]
    );
}

/// A record of `g` (simulated by fracsim; these tests are about the CLI, accuracy is shown in
/// ident's tests against an independent truth), PRBS with 10-sample bits at 1 ms after `lead`
/// samples at `level`.
fn record_csv(dir: &tempfile::TempDir, name: &str, g: &str, level: f64, seed: u32) -> PathBuf {
    let dt = 1e-3;
    let g: fracsim::FracTf = g.parse().unwrap();
    let mut u = vec![level; 200];
    u.extend(
        fracsim::prbs::Prbs {
            clock: 10.0 * dt,
            periods: 2,
            seed,
            offset: level,
            ..fracsim::prbs::Prbs::paper()
        }
        .signal(dt)
        .unwrap(),
    );
    let y = fracsim::lsim(&g, &u, dt, &Default::default()).unwrap();
    let mut text = String::from("t,u,y\n");
    // The record starts after the lead: the plant is in motion.
    for k in 200..u.len() {
        writeln!(text, "{:.6},{},{}", (k - 200) as f64 * dt, u[k], y[k]).unwrap();
    }
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const PAPER: &str = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)";

/// `fracid score` with the true model as text and with the JSON `time` wrote; `time --validate`
/// scores on a second record (another seed and operating point) with its own initial state.
#[test]
fn score_and_validate_on_a_second_record() {
    let dir = tempfile::tempdir().unwrap();
    let a = record_csv(&dir, "a.csv", PAPER, 10.0, 1);
    let b = record_csv(&dir, "b.csv", PAPER, 6.0, 9);
    let o = fracid(&["score", PAPER, b.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let f = v["nrmse_percent"].as_f64().unwrap();
    assert!(f > 99.9, "true model scores {f}");

    let o = fracid(&[
        "time",
        "--plain",
        a.to_str().unwrap(),
        "--json",
        "--quiet",
        "--validate",
        b.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report = dir.path().join("fit.json");
    std::fs::write(&report, stdout(&o)).unwrap();
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let fv = v["fit"]["validation_file"]["nrmse_percent"]
        .as_f64()
        .unwrap();
    assert!(fv > 99.0, "validation file {fv}");
    assert!(
        v["fit"]["validation"].is_null(),
        "no holdout with --validate"
    );

    let o = fracid(&[
        "score",
        report.to_str().unwrap(),
        b.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!((v["nrmse_percent"].as_f64().unwrap() - fv).abs() < 1e-6);

    let o = fracid(&["score", "1/(s^0.5", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// The report's figures are those of the models it gives (issue 30): a record with a 4 ms delay
/// nobody declared, `time --diagnose --json`; `score REPORT --as-fitted` on the same file
/// re-scores the final model (the delay kept, as the diagnosis must find) and the base fit as the
/// run did, and each gives the figures the report states for it (to 1e-3 relative: only the
/// record's offset and initial state are estimated again, to the same optimum). Plain `score
/// REPORT FILE` scores the whole model, effects included: the final model beats its base fit.
#[test]
fn score_gives_the_figures_the_report_states() {
    let dir = tempfile::tempdir().unwrap();
    let model = format!("{PAPER} exp(-0.004 s)");
    let a = record_csv(&dir, "a.csv", &model, 10.0, 1);
    let o = fracid(&[
        "time",
        a.to_str().unwrap(),
        "--diagnose",
        "--json",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report = dir.path().join("report.json");
    std::fs::write(&report, stdout(&o)).unwrap();
    let r: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(
        r["model"]["delay"].as_f64().unwrap() > 0.003,
        "the final model keeps the delay: {}",
        r["model"]
    );
    let o = fracid(&[
        "score",
        report.to_str().unwrap(),
        a.to_str().unwrap(),
        "--as-fitted",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for (stated, scored) in [
        (&r["fit"], &s["fit"]),
        (&r["base"]["fit"], &s["base"]["fit"]),
    ] {
        for part in ["estimation", "validation"] {
            let (x, y) = (
                stated[part]["rmse"].as_f64().unwrap(),
                scored[part]["rmse"].as_f64().unwrap(),
            );
            assert!((x - y).abs() <= 1e-3 * x, "{part}: stated {x}, scored {y}");
        }
    }
    let whole = |which: &str| {
        let o = fracid(&[
            "score",
            report.to_str().unwrap(),
            a.to_str().unwrap(),
            "--which",
            which,
            "--json",
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        v["rmse"].as_f64().unwrap()
    };
    let (lead, base) = (whole("lead"), whole("base"));
    assert!(lead < 0.7 * base, "final {lead} vs base {base}");
}

/// A position output (the PMSM integrated): `--integrator` fits it (exit 0, the fit at the
/// noise-free floor). That the plain structure is refused on such data is ident's test
/// (`time::records`).
#[test]
fn an_integrating_output_is_fitted_with_integrator() {
    let dir = tempfile::tempdir().unwrap();
    let p = record_csv(
        &dir,
        "pos.csv",
        "6.82/(2.655e-5 s^2.7452 + 0.0059 s^1.92 + s)",
        0.0,
        3,
    );
    let o = fracid(&[
        "time",
        p.to_str().unwrap(),
        "--quiet",
        "--integrator",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["fit"]["validation"]["nrmse_percent"].as_f64().unwrap() > 99.0);
}

/// Degenerate fits are not usable (issue 30): a written model that cannot move from its start,
/// and `--integrator` on an output that does not integrate, end with a singular covariance and
/// a fit hardly better than a constant: exit 1, `usable: false`, the reason in `problems`.
#[test]
fn degenerate_fits_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let csv = crate::reliability::round2::a_csv(&dir);
    for extra in [
        &["--structure", "(0.002 s + 0.000004)/s"][..],
        &["--integrator"][..],
    ] {
        let mut args = vec![
            "time",
            "--plain",
            csv.to_str().unwrap(),
            "--json",
            "--quiet",
        ];
        args.extend(extra);
        let o = fracid(&args);
        assert_eq!(o.status.code(), Some(1), "{extra:?}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        assert_eq!(v["usable"], false, "{extra:?}");
        let problems = v["problems"].to_string();
        assert!(
            problems.contains("covariance is singular"),
            "{extra:?}: {problems}"
        );
    }
}

/// The reader's caveats are in the JSON report, not only on stderr (issue 30): an incomplete
/// acquisition is fitted on its complete part and `warnings` says which part and what is missing.
#[test]
fn reader_warnings_are_in_the_json_report() {
    let dir = tempfile::tempdir().unwrap();
    let full = std::fs::read_to_string(pmsm_csv(&dir)).unwrap();
    let rows: Vec<&str> = full
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .collect();
    let n = rows.len();
    let mut text = format!(
        "# fracid drive acquisition: PRBS\n# run_id 1, {n} samples planned at 1000 Hz\nt,u,y\n"
    );
    for (k, r) in rows.iter().enumerate() {
        if !(800..900).contains(&k) {
            writeln!(text, "{r}").unwrap();
        }
    }
    writeln!(text, "# incomplete: missing samples 800..900 (port lost)").unwrap();
    let p = dir.path().join("inc.csv");
    std::fs::write(&p, text).unwrap();
    let o = fracid(&["time", p.to_str().unwrap(), "--json", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let w = v["warnings"].to_string();
    assert!(w.contains("missing samples 800..900 (port lost)"), "{w}");
    assert!(
        w.contains("longest complete contiguous part, rows 800.."),
        "{w}"
    );
    // and on stderr once, not twice
    assert_eq!(
        stderr(&o).matches("missing samples 800..900").count(),
        1,
        "{}",
        stderr(&o)
    );
}

/// `--structure auto` fits pmsm, commensurate, the integer first, second and third order and the
/// two-mass drive train (which fails at once here: the input is not periodic) and keeps
/// the one the rule picks (held-out RMSE, ties within 2%, then the lowest BIC; usable fits first):
/// checked here on the table it reports, and the reported model is the chosen row's.
#[test]
fn structure_auto_keeps_the_structure_the_data_support() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/unal_dcmotor/DCmotor_prbs_open_exp.csv");
    let o = fracid(&[
        "time",
        "--plain",
        p.to_str().unwrap(),
        "--structure",
        "auto",
        "--json",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let s = &v["structures"];
    let rows = s["scores"].as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "pmsm",
            "commensurate",
            "first-order",
            "second-order",
            "third-order",
            "two-mass"
        ]
    );
    let chosen = s["chosen"].as_u64().unwrap() as usize;
    // Usable: a base fit (no `failed`) with no problems.
    let usable: Vec<&serde_json::Value> = rows
        .iter()
        .filter(|r| r["problems"].as_array().unwrap().is_empty() && r["failed"].is_null())
        .collect();
    let best = usable
        .iter()
        .map(|r| r["rmse"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    let ties: Vec<&&serde_json::Value> = usable
        .iter()
        .filter(|r| r["rmse"].as_f64().unwrap() <= 1.02 * best)
        .collect();
    let lowest_bic = ties
        .iter()
        .map(|r| r["bic_after"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert_eq!(
        rows[chosen]["bic_after"].as_f64().unwrap(),
        lowest_bic,
        "{s}"
    );
    assert_eq!(v["model"]["text"], rows[chosen]["model"], "{v}");
    let val = v["fit"]["validation"]["rmse"].as_f64().unwrap();
    assert!((val - rows[chosen]["rmse"].as_f64().unwrap()).abs() < 1e-12 * val);
    let o = fracid(&[
        "time",
        "--plain",
        p.to_str().unwrap(),
        "--structure",
        "auto",
        "--quiet",
    ]);
    assert!(
        stdout(&o).contains("structures compared (each fitted;"),
        "{}",
        stdout(&o)
    );
}

/// The structure comparison on real records says each failure once, in one line a drive engineer
/// reads (no Levy coefficient vectors, no "base fit not usable" repeating it), and compares the
/// chosen model only with a usable integer-order one. On the UNAL PRBS record the two-mass start
/// finds no resonance; on the motor/generator record `--structure auto` (session 15: "against the
/// best integer-order model (third order, ...)" whose a3 was not determined).
#[test]
fn the_structure_comparison_says_each_failure_once_and_compares_with_a_usable_integer_model() {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data");
    let prbs = data.join("unal_dcmotor/DCmotor_prbs_open_exp.csv");
    let o = fracid(&["time", prbs.to_str().unwrap(), "--diagnose", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = stdout(&o);
    let table = text
        .split("structures compared")
        .nth(1)
        .and_then(|t| t.split("residual diagnosis").next())
        .unwrap_or_else(|| panic!("no comparison table: {text}"));
    let failed: Vec<&str> = table
        .lines()
        .filter(|l| l.trim_start().starts_with("failed:"))
        .collect();
    assert!(!failed.is_empty(), "{table}");
    for line in &failed {
        let why = line.trim_start().trim_start_matches("failed: ");
        assert_eq!(table.matches(why).count(), 1, "said twice: {why}\n{table}");
        assert!(!line.contains('['), "coefficient vectors: {line}");
        assert!(line.len() < 300, "not one concise line: {line}");
    }
    assert!(
        table.contains("no resonance in the frequency response"),
        "{table}"
    );
    // The JSON: the failure in `failed`, no base-fit problems for a fit that does not exist.
    let o = fracid(&[
        "time",
        prbs.to_str().unwrap(),
        "--diagnose",
        "--json",
        "--quiet",
    ]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let scores = v["diagnosis"]["structures"]["scores"]
        .as_array()
        .unwrap_or_else(|| panic!("{}", v["diagnosis"]));
    let two_mass = scores.iter().find(|s| s["name"] == "two-mass").unwrap();
    assert!(two_mass["failed"].is_string(), "{two_mass}");
    assert_eq!(two_mass["problems"].as_array().map(Vec::len), Some(0));
    // Wherever an integer reference is given, it is a usable row.
    let mg = data.join("sysidentpy_motor_generator/motor_generator_steps.csv");
    for extra in [&["--structure", "auto"][..], &["--diagnose"][..]] {
        let args = [
            &["time", mg.to_str().unwrap(), "--json", "--quiet"][..],
            extra,
        ]
        .concat();
        let o = fracid(&args);
        assert_eq!(o.status.code(), Some(0), "{extra:?}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        let c = if v["structures"].is_object() {
            &v["structures"]
        } else {
            &v["diagnosis"]["structures"]
        };
        let scores = c["scores"].as_array().unwrap_or_else(|| panic!("{v}"));
        let chosen = &scores[c["chosen"].as_u64().unwrap() as usize];
        let reason = c["reason"].as_str().unwrap();
        eprintln!("{extra:?}: {reason}");
        if let Some(name) = c["integer_reference"]["name"].as_str() {
            let r = scores.iter().find(|s| s["name"] == name).unwrap();
            assert_eq!(r["problems"].as_array().map(Vec::len), Some(0), "{r}");
            assert!(r["failed"].is_null(), "{r}");
            assert!(reason.contains(&format!("({name}, RMSE")), "{reason}");
        } else {
            assert!(
                reason.contains("it is an integer-order model")
                    || reason.contains("no integer-order model is usable"),
                "{reason}"
            );
        }
        // No integer row that is not usable is named as the reference.
        for s in scores
            .iter()
            .filter(|s| s["problems"].as_array().is_some_and(|p| !p.is_empty()))
        {
            let name = s["name"].as_str().unwrap();
            assert!(!reason.contains(&format!("({name}, RMSE")), "{reason}");
        }
        assert!(chosen["failed"].is_null());
    }
}
