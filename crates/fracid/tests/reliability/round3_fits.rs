//! Issue 46, round 3, the fits' items: one test per item (`item_N_...`), each failing on the
//! behaviour the issue found (main, e364c0a).

use super::{fracid, stderr};
use crate::json;
use std::fmt::Write as _;

/// The repository's UNAL PRBS record with its time column multiplied by `c`.
fn unal_in_units(dir: &tempfile::TempDir, c: f64) -> std::path::PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../data/unal_dcmotor/DCmotor_prbs_open_exp.csv"
    ))
    .unwrap();
    let mut out = String::new();
    for (i, l) in text.lines().enumerate() {
        if i == 0 {
            writeln!(out, "{l}").unwrap();
            continue;
        }
        let (t, rest) = l.split_once(',').unwrap();
        writeln!(out, "{:.12e},{rest}", t.parse::<f64>().unwrap() * c).unwrap();
    }
    let p = dir.path().join(format!("unal_{c:e}.csv"));
    std::fs::write(&p, out).unwrap();
    p
}

/// Item 13: the fit does not depend on the time unit. The UNAL PRBS record with its time in
/// units of 1e4 s (every time value times 1e-4) stopped early at 94.00% ("parameter step below
/// tolerance", the highest order run to 2) where seconds give 95.31%; now every unit from 1e-5
/// to 1e6 gives the seconds' fit, and its parameters converted back to seconds.
#[test]
fn item_13_the_fit_does_not_depend_on_the_time_unit() {
    let dir = tempfile::tempdir().unwrap();
    let fit = |c: f64| {
        let p = unal_in_units(&dir, c);
        let o = fracid(&["time", p.to_str().unwrap(), "--json", "--quiet", "--plain"]);
        assert_eq!(o.status.code(), Some(0), "{c:e}: {}", stderr(&o));
        json(&o)
    };
    let seconds = fit(1.0);
    let pct = |v: &serde_json::Value| v["fit"]["estimation"]["nrmse_percent"].as_f64().unwrap();
    let param = |v: &serde_json::Value, n: &str| {
        v["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == n)
            .unwrap()["value"]
            .as_f64()
            .unwrap()
    };
    assert!((pct(&seconds) - 95.31).abs() < 0.01, "{}", pct(&seconds));
    for c in [1e-4, 1e4] {
        let v = fit(c);
        assert!(
            (pct(&v) - pct(&seconds)).abs() < 1e-3,
            "time x {c:e}: {} against {} in seconds",
            pct(&v),
            pct(&seconds)
        );
        // a1 s^zeta: a1 in seconds is a1' / c^zeta
        let (zeta, a1) = (
            param(&v, "zeta"),
            param(&v, "a1") / c.powf(param(&v, "zeta")),
        );
        assert!((zeta - param(&seconds, "zeta")).abs() < 1e-3, "zeta {zeta}");
        assert!(
            (a1 / param(&seconds, "a1") - 1.0).abs() < 1e-2,
            "a1 {a1} against {}",
            param(&seconds, "a1")
        );
    }
}
/// The recommended model of a report, `(coefficient, order)` of each numerator and denominator
/// term and the delay (seconds of the record's unit).
type Terms = (Vec<(f64, f64)>, Vec<(f64, f64)>, f64);

fn terms(v: &serde_json::Value) -> Terms {
    let side = |k: &str| {
        v["model"][k]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| (t["coef"].as_f64().unwrap(), t["order"].as_f64().unwrap()))
            .collect()
    };
    (
        side("num"),
        side("den"),
        v["model"]["delay"].as_f64().unwrap_or(0.0),
    )
}

/// `G(j w)` of [`Terms`] without its delay.
fn response(t: &Terms, w: f64) -> num_complex::Complex64 {
    let sum = |side: &[(f64, f64)]| {
        side.iter()
            .map(|&(a, q)| a * num_complex::Complex64::new(0.0, w).powf(q))
            .sum::<num_complex::Complex64>()
    };
    sum(&t.0) / sum(&t.1)
}

/// Item 13 with the loop closed (`--diagnose`): the structure comparison and the diagnosis's
/// refits are in a time unit they do not depend on as the base fits are, so the UNAL PRBS
/// record in units of 1e-4 s and of 1e4 s ends on the seconds' choice (the same structure and
/// effects), with the seconds' figures, and its model is the seconds' model in that unit
/// (`G_c(j w / c) = G(j w)`, the delay times `c`). Before, the refits ran in the record's unit.
#[test]
fn item_13_the_closed_loop_does_not_depend_on_the_time_unit() {
    let dir = tempfile::tempdir().unwrap();
    let fit = |c: f64| {
        let p = unal_in_units(&dir, c);
        let o = fracid(&[
            "time",
            p.to_str().unwrap(),
            "--json",
            "--quiet",
            "--diagnose",
        ]);
        assert_eq!(o.status.code(), Some(0), "{c:e}: {}", stderr(&o));
        json(&o)
    };
    let pct = |v: &serde_json::Value, part: &str| v["fit"][part]["nrmse_percent"].as_f64().unwrap();
    let seconds = fit(1.0);
    let st = terms(&seconds);
    for c in [1e-4, 1e4] {
        let v = fit(c);
        assert_eq!(v["model_is"], seconds["model_is"], "time x {c:e}");
        for part in ["estimation", "validation"] {
            assert!(
                (pct(&v, part) - pct(&seconds, part)).abs() < 1e-2,
                "time x {c:e}, {part}: {} against {} in seconds",
                pct(&v, part),
                pct(&seconds, part)
            );
        }
        let t = terms(&v);
        assert!(
            (t.2 / c - st.2).abs() <= 1e-3 * st.2.max(1e-12 * c),
            "delay {} vs {}",
            t.2,
            st.2
        );
        for w in [0.3, 3.0, 30.0] {
            let (a, b) = (response(&st, w), response(&t, w / c));
            assert!(
                (a - b).norm() <= 1e-2 * a.norm(),
                "time x {c:e}, w {w}: {a} against {b}"
            );
        }
    }
}

/// Item 14: an output exactly 3 times the input. The fit is a static gain with orders
/// the data do not determine; a drive engineer asking for the plant's dynamics is told that the
/// record shows none, and the gain (exit 1; on main: `usable: true`, orders 0.004 and 0.039
/// without a standard error).
#[test]
fn item_14_a_static_gain_says_so_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let dt = 1e-3;
    let u = fracsim::prbs::Prbs {
        clock: 3.0 * dt,
        periods: 3,
        ..fracsim::prbs::Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    let mut text = String::from("t,u,y\n");
    for (k, u) in u.iter().take(1000).enumerate() {
        writeln!(text, "{:.6},{u},{}", k as f64 * dt, 3.0 * u).unwrap();
    }
    let p = dir.path().join("gain.csv");
    std::fs::write(&p, text).unwrap();
    // the loop closed too: a first order whose fit stalled 1e15 times above the static gain's
    // kept friction and ran its time constant to 0 (an improper final model); the structures
    // far better than every usable one are now compared (structures::far_better)
    for path in ["--plain", "--diagnose"] {
        let o = fracid(&["time", p.to_str().unwrap(), "--json", "--quiet", path]);
        assert_eq!(o.status.code(), Some(1), "{path}: {}", stderr(&o));
        let v = json(&o);
        let problems = v["problems"].to_string();
        assert!(problems.contains("no dynamics"), "{path}: {problems}");
        // The plain path's PMSM is strictly proper: its output at a sample instant has not moved
        // with that instant's input, so its static fit of an output that follows the input at
        // once is off (a PRBS held 3 samples: about 2/3 of the gain); the loop closed compares
        // the structures that feed the input through.
        if path == "--diagnose" {
            assert!(
                problems.contains("static gain G(0) = 3.0000e0"),
                "{path}: {problems}"
            );
        }
        // Either way the record's own ratio is stated, not the model's G(0) taken for it; the
        // plain PMSM's G(0) (about 2) is said not to reproduce it.
        assert!(
            problems.contains("the output is the input times 3.0000e0 at the same instants"),
            "{path}: {problems}"
        );
        assert_eq!(
            problems.contains("which this model does not reproduce: it has no instant response"),
            path == "--plain",
            "{path}: {problems}"
        );
    }
}
