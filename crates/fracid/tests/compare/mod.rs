//! `fracid compare` on the paper's two models, against an independent evaluation here.

use super::fracid;
use num_complex::Complex64;
use std::f64::consts::PI;

/// `K/(a2 s^o2 + a1 s^o1 + 1)` at `s = j 2 pi f`, from the formula.
fn pmsm(k: f64, a2: f64, o2: f64, a1: f64, o1: f64, f: f64) -> Complex64 {
    let w = 2.0 * PI * f;
    let p = |o: f64| Complex64::from_polar(w.powf(o), PI * o / 2.0);
    k / (a2 * p(o2) + a1 * p(o1) + 1.0)
}

const TIME: &str = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)";
const FREQ: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)";

#[test]
fn the_papers_two_models_differ_most_where_an_independent_evaluation_says() {
    let out = fracid(&["compare", TIME, FREQ, "--band", "0.1,100", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // independent: 200001 log-spaced points over 0.1-100 Hz, B - A
    let (mut g_best, mut p_best) = ((0.0f64, 0.0), (0.0f64, 0.0));
    for i in 0..=200_000 {
        let f = 0.1 * 1000f64.powf(i as f64 / 200_000.0);
        let r = pmsm(6.77, 0.000028, 1.78, 0.0064, 0.89, f)
            / pmsm(6.82, 0.00002655, 1.7452, 0.0059, 0.92, f);
        let (g, p) = (20.0 * r.norm().log10(), r.arg().to_degrees());
        if g.abs() > g_best.0.abs() {
            g_best = (g, f);
        }
        if p.abs() > p_best.0.abs() {
            p_best = (p, f);
        }
    }
    eprintln!("independent: gain {g_best:?}, phase {p_best:?}; fracid: {v}");
    let gd = &v["largest_gain_diff_db"];
    let pd = &v["largest_phase_diff_deg"];
    // fracid's grid has 2000 points (0.35 % apart): the extreme value within 1e-3 of the fine
    // grid's, its place within one grid step (or at the same band edge)
    assert!(
        (gd["value"].as_f64().unwrap() - g_best.0).abs() < 1e-3,
        "{gd}"
    );
    assert!(
        (pd["value"].as_f64().unwrap() - p_best.0).abs() < 1e-3,
        "{pd}"
    );
    let step = 1000f64.powf(1.0 / 1999.0);
    for (got, want) in [(&gd["freq_hz"], g_best.1), (&pd["freq_hz"], p_best.1)] {
        let r = got.as_f64().unwrap() / want;
        assert!(
            r < step * 1.0001 && r > 1.0 / (step * 1.0001),
            "{got} vs {want}"
        );
    }
    // the coefficient table: K, then the s^1.7452 term, the s^0.92 term, the constant
    let rows = v["coefficients"].as_array().unwrap();
    let rel = |name: &str| {
        rows.iter()
            .find(|r| r["name"].as_str().unwrap().contains(name))
            .unwrap_or_else(|| panic!("{name} in {rows:?}"))["rel_diff"]
            .as_f64()
            .unwrap()
    };
    assert!((rel("num term 1 (s^0) coef") - (6.77 - 6.82) / 6.82).abs() < 1e-12);
    assert!(
        (rel("den term 1 (s^1.7452) coef") - (0.000028 - 0.00002655) / 0.00002655).abs() < 1e-9
    );
    assert!((rel("den term 1 (s^1.7452) order") - (1.78 - 1.7452) / 1.7452).abs() < 1e-12);
    assert!((rel("den term 2 (s^0.92) coef") - (0.0064 - 0.0059) / 0.0059).abs() < 1e-12);
}

#[test]
fn compare_reads_json_models_makes_a_plot_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let js = dir.path().join("m.json");
    std::fs::write(
        &js,
        r#"{"model": {"num": [{"coef": 6.82, "order": 0}], "den": [{"coef": 2.655e-5, "order": 1.7452}, {"coef": 0.0059, "order": 0.92}, {"coef": 1, "order": 0}], "delay": 0.0}}"#,
    )
    .unwrap();
    let png = dir.path().join("c.png");
    let out = fracid(&[
        "compare",
        js.to_str().unwrap(),
        TIME,
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("largest gain difference   +0.0000 dB"),
        "{text}"
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    let bad = fracid(&["compare", "6.8/(s^", TIME]);
    assert_eq!(
        bad.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    let band = fracid(&["compare", TIME, FREQ, "--band", "10,1"]);
    assert_eq!(band.status.code(), Some(2));
}
