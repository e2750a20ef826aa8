//! `fracid drive autotune` end to end: the CLI against the drive simulator in virtual time (in
//! this process; the CLI keeps its keepalive on the wall clock every 5 ms).

use super::{fracid, stderr, stdout};

/// `fracid drive autotune --port PORT --keepalive-ms 5 EXTRA...`.
#[cfg(unix)]
fn autotune(port: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["drive", "autotune", "--port", port, "--keepalive-ms", "5"];
    args.extend_from_slice(extra);
    fracid(&args)
}

#[cfg(unix)]
fn sim(coulomb_v: f64) -> drive::sim::DriveSim {
    drive::sim::DriveSim::spawn(drive::sim::SimConfig {
        model: "6.1/(2.4e-5 s^1.77 + 0.0063 s^0.91 + 1)".parse().unwrap(),
        effects: drive::sim::Effects {
            coulomb_v,
            noise_std: 0.015,
            ..Default::default()
        },
        clock: drive::sim::SimClock::Virtual,
        ..Default::default()
    })
    .unwrap()
}

/// The report as JSON on stdout, its text on stderr, `report.md` with its plots and
/// `report.json` in the folder; exit 0 for a usable controller.
#[cfg(unix)]
#[test]
fn autotune_reports_round_by_round_and_exits_0_for_a_usable_controller() {
    let s = sim(0.28);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("at");
    let o = autotune(s.port_path(), &["--json", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["usable"], true);
    assert!(v["rounds"].as_array().unwrap().len() >= 2, "{v}");
    assert!(v["control"]["measured"]["rise_time_s"].as_f64().is_some());
    assert!(stderr(&o).contains("round 2 (reversals"), "{}", stderr(&o));
    for f in ["report.md", "report.json", "records.png", "step.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("![step](step.png)") && md.contains("round 1"));
}

/// A limit out of range is bad input (exit 2) before the drive is asked anything.
#[cfg(unix)]
#[test]
fn autotune_refuses_a_limit_out_of_range() {
    let o = fracid(&["drive", "autotune", "--port", "/dev/null", "--u-limit", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--u-limit"), "{}", stderr(&o));
}

/// `fracid demo` shows the autotune: on its simulated drive, after the tuned loop, the autotune
/// with its defaults, told nothing; its section in `report.md` (each round, the final model, the
/// controller, the step predicted beside measured, the verdict), `autotune.txt` and a usable
/// `autotune.json`.
#[cfg(unix)]
#[test]
fn the_demo_shows_the_autotune() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let t0 = std::time::Instant::now();
    let o = fracid(&["demo", "--out", out.to_str().unwrap()]);
    let wall = t0.elapsed().as_secs_f64();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    println!("demo {wall:.2} s wall\n{}", stderr(&o));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let section = md
        .split("## One-button tuning")
        .nth(1)
        .expect("the autotune's section");
    for want in [
        "- Round 1 (prbs)",
        "- Final model:",
        "- Controller:",
        "predicted overshoot",
        "measured on the drive overshoot",
        "- Verdict: a usable controller.",
    ] {
        assert!(section.contains(want), "{want}: {section}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("autotune.json")).unwrap()).unwrap();
    assert_eq!(v["usable"], true);
    assert!(v["control"]["measured"]["overshoot_percent"].is_number());
    assert!(std::fs::read_to_string(out.join("autotune.txt"))
        .unwrap()
        .contains("round 1 (prbs, identification)"));
}

/// `--filter none`: for a resonance (here 52 Hz, damping 0.06, at the load) no filter in the
/// controller and the lower crossover with its reason, in the JSON as in the text.
#[cfg(unix)]
#[test]
fn autotune_without_a_filter_lowers_the_crossover_for_a_resonance() {
    let wr = 2.0 * std::f64::consts::PI * 52.0;
    let s = drive::sim::DriveSim::spawn(drive::sim::SimConfig {
        model: format!(
            "3.7/((0.0048 s + 1)({} s^2 + {} s + 1))",
            wr.powi(-2),
            2.0 * 0.06 / wr
        )
        .parse()
        .unwrap(),
        effects: drive::sim::Effects {
            noise_std: 0.01,
            delay_s: 0.0005,
            ..Default::default()
        },
        clock: drive::sim::SimClock::Virtual,
        ..Default::default()
    })
    .unwrap();
    let o = autotune(s.port_path(), &["--filter", "none", "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["request"]["filter"], "none");
    let f = v["model"]["resonance"]["freq_hz"]
        .as_f64()
        .expect("a resonance");
    assert!((f - 52.0).abs() < 2.6, "{f}");
    assert!(v["control"]["filter"].is_null(), "{}", v["control"]);
    let reasons = v["control"]["crossover"]["reasons"].to_string();
    assert!(reasons.contains("a fifth of it"), "{reasons}");
    assert!(v["control"]["wc_used"].as_f64().unwrap() <= wr / 5.0 + 1e-9);
    assert!(stderr(&o).contains("the crossover a fifth of it"));
}
