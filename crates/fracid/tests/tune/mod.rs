//! `fracid tune`: the must-show request end to end (the JSON's controller evaluated here, from its
//! `{num, den}` terms, with the model's terms), the impossible one refused with exit 1, bad
//! requests exit 2, the final model of a diagnosis report used.

use super::fracid;

const PMSM: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)";

fn json_of(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `sum coef (j w)^order` of a JSON term list, as `(re, im)`.
fn poly(terms: &serde_json::Value, w: f64) -> (f64, f64) {
    terms
        .as_array()
        .unwrap()
        .iter()
        .fold((0.0, 0.0), |(re, im), t| {
            let (c, o) = (t["coef"].as_f64().unwrap(), t["order"].as_f64().unwrap());
            let (m, a) = (c * w.powf(o), o * std::f64::consts::FRAC_PI_2);
            (re + m * a.cos(), im + m * a.sin())
        })
}

fn div(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let d = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
}

fn mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

/// `L(j w)` from the report's model and controller (both `{num, den, delay}`).
fn l(v: &serde_json::Value, w: f64) -> (f64, f64) {
    let tf = |m: &serde_json::Value| {
        let g = div(poly(&m["num"], w), poly(&m["den"], w));
        let tau = m["delay"].as_f64().unwrap();
        mul(g, ((-w * tau).cos(), (-w * tau).sin()))
    };
    mul(tf(&v["model"]), tf(&v["controller"]))
}

#[test]
fn fopi_flat_on_the_pmsm_meets_the_specification() {
    let v = json_of(&fracid(&[
        "tune", PMSM, "--wc", "300", "--pm", "60", "--flat", "--json",
    ]));
    let lw = l(&v, 300.0);
    let mag = lw.0.hypot(lw.1);
    let pm = 180.0 + lw.1.atan2(lw.0).to_degrees();
    assert!((mag - 1.0).abs() < 0.01, "|L| = {mag}");
    assert!((pm - 60.0).abs() < 1.0, "pm = {pm}");
    let h: f64 = 1e-4;
    let (a, b) = (l(&v, 300.0 * (-h).exp()), l(&v, 300.0 * h.exp()));
    let slope = div(b, a).1.atan2(div(b, a).0) / (2.0 * h);
    assert!(slope.abs() <= 0.05, "slope {slope}");
    for k in ["kp", "ki", "lambda", "kd", "mu"] {
        assert!(v["params"][k].is_number(), "params.{k}");
    }
    for k in ["wc", "pm_deg", "gm_db", "ms"] {
        assert!(v["loop"][k].is_number(), "loop.{k}");
    }
    assert!(v["loop"]["ms"].as_f64().unwrap() > 1.0);
    assert!(v["discrete"].is_null());
    assert!(v["integer_pi"]["params"]["ki"].as_f64().unwrap() > 0.0);
}

#[test]
fn sampled_design_gives_a_discrete_realisation() {
    let v = json_of(&fracid(&[
        "tune", PMSM, "--wc", "50", "--pm", "60", "--flat", "--dt", "0.001", "--json",
    ]));
    let d = &v["discrete"];
    assert_eq!(d["dt"].as_f64(), Some(0.001));
    let n = d["states"].as_u64().unwrap() as usize;
    assert_eq!(d["a"].as_array().unwrap().len(), n);
    assert_eq!(d["c"][0].as_array().unwrap().len(), n);
    // the sampled loop with the realisation stays near the design (its extra lags are small)
    let m = &d["sampled_loop"];
    assert!((m["wc"].as_f64().unwrap() / 50.0 - 1.0).abs() < 0.05, "{m}");
    assert!((m["pm_deg"].as_f64().unwrap() - 60.0).abs() < 5.0, "{m}");
}

#[test]
fn impossible_specification_exits_1_with_the_reason() {
    let out = fracid(&["tune", PMSM, "--wc", "3000", "--pm", "89", "--flat"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("impossible specification"), "{err}");
    assert!(err.contains("phase"), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn bad_requests_exit_2() {
    for args in [
        vec!["tune", PMSM, "--wc", "300", "--pm", "60", "--form", "fopid"],
        vec!["tune", PMSM, "--wc", "300", "--pm", "60", "--form", "xyz"],
        vec!["tune", PMSM, "--wc", "-3", "--pm", "60"],
        vec![
            "tune", PMSM, "--wc", "300", "--pm", "60", "--form", "fopid", "--flat", "--t-high",
            "3000",
        ],
        vec!["tune", "1/(s + ", "--wc", "300", "--pm", "60"],
    ] {
        let out = fracid(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// A `time --diagnose` report: the final model is `diagnosis.model`, not the base fit's `model`.
#[test]
fn the_final_model_of_a_diagnosis_report_is_used() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("fit.json");
    let term = |c: f64, o: f64| serde_json::json!({"coef": c, "order": o});
    let doc = serde_json::json!({
        "model": {"num": [term(1.0, 0.0)], "den": [term(0.01, 1.0), term(1.0, 0.0)], "delay": 0.0},
        "diagnosis": {"model": {
            "num": [term(6.77, 0.0)],
            "den": [term(0.000028, 1.78), term(0.0064, 0.89), term(1.0, 0.0)],
            "delay": 0.001,
            "effects": ["delay", "saturation", "output_offset"]
        },
        "effects": [
            {"name": "delay", "params": {"tau": 0.001}},
            {"name": "saturation", "params": {"level": 0.2}},
            {"name": "output_offset", "params": {"y_offset": 0.01}}
        ]}
    });
    std::fs::write(&p, doc.to_string()).unwrap();
    let v = json_of(&fracid(&[
        "tune",
        p.to_str().unwrap(),
        "--wc",
        "300",
        "--pm",
        "60",
        "--flat",
        "--json",
    ]));
    assert_eq!(v["model"]["delay"].as_f64(), Some(0.001));
    assert_eq!(v["model"]["den"].as_array().unwrap().len(), 3);
}

#[test]
fn text_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("tune.png");
    let out = fracid(&[
        "tune",
        PMSM,
        "--wc",
        "300",
        "--pm",
        "60",
        "--flat",
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
        text.contains("controller: C(s) =") && text.contains("integer PI:"),
        "{text}"
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
}

/// A model the simulator cannot run (two free integrators): the design stands and the report
/// says why the loop is not simulated (exit 0).
#[test]
fn a_design_the_simulator_cannot_run_is_still_reported() {
    let v = json_of(&fracid(&[
        "tune",
        "1/(s^2 + 0.01 s^3)",
        "--wc",
        "20",
        "--pm",
        "50",
        "--form",
        "pid",
        "--json",
    ]));
    assert!(v["step"]["metrics"].is_null());
    assert!(v["step"]["not_simulated"]
        .as_str()
        .unwrap()
        .contains("integrator"));
    assert!((v["loop"]["pm_deg"].as_f64().unwrap() - 50.0).abs() < 1e-6);
}

/// The defects the tuner returned with exit 0, end to end: each now exits non-zero with the
/// reason (the loop the tuner returned is shown unstable or fragile in `tune`'s tests).
#[test]
fn unsafe_loops_are_refused_with_the_reason() {
    let cases: [(&[&str], &str); 5] = [
        (
            &["100/(s^2 + 0.001 s + 10000)", "--wc", "0.22", "--pm", "60"],
            "unstable",
        ),
        (
            &[
                "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)",
                "--wc",
                "100",
                "--pm",
                "60",
                "--dt",
                "0.02",
            ],
            "(--max-ms)",
        ),
        (
            &[
                "1/((s + 1)(0.0011111 s^2 + 0.0013333 s + 1))",
                "--wc",
                "2",
                "--pm",
                "60",
                "--flat",
            ],
            "(--max-ms)",
        ),
        (
            &[
                "1/((s + 1)(0.0011111 s^2 + 0.0013333 s + 1))",
                "--wc",
                "2",
                "--pm",
                "60",
                "--flat",
                "--max-ms",
                "100",
                "--min-gm",
                "0",
                "--t-high",
                "10,-17",
            ],
            "|T| = ",
        ),
        (
            &["6.77/(-0.0064 s^0.89 + 1)", "--wc", "300", "--pm", "60"],
            "the model has 1",
        ),
    ];
    for (args, why) in cases {
        let out = fracid(&[&["tune"], args].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(why), "{args:?}: {err}");
        assert!(out.stdout.is_empty());
    }
}

/// An unstable model with a stabilising PI: `1/(s - 1)` at wc = 5 rad/s, pm = 60 deg, the
/// closed loop `s^2 + (kp - 1) s + ki` stable (kp > 1, ki > 0), the model's pole counted.
#[test]
fn an_unstable_model_is_stabilised() {
    let v = json_of(&fracid(&[
        "tune",
        "1/(s - 1)",
        "--form",
        "pi",
        "--wc",
        "5",
        "--pm",
        "60",
        "--json",
    ]));
    let (kp, ki) = (
        v["params"]["kp"].as_f64().unwrap(),
        v["params"]["ki"].as_f64().unwrap(),
    );
    assert!(kp > 1.0 && ki > 0.0, "{}", v["params"]);
    assert_eq!(v["loop"]["unstable_poles"], 0);
    assert_eq!(v["loop"]["plant_unstable_poles"], 1);
}

/// A report marked unusable is refused (exit 2, its problems named), and an absurd crossover
/// returns at once with exit 2 (before: the design on the unusable model; a run that never
/// ended).
#[test]
fn unusable_reports_and_absurd_crossovers_are_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("fit.json");
    let term = |c: f64, o: f64| serde_json::json!({"coef": c, "order": o});
    let doc = serde_json::json!({
        "model": {"num": [term(6.77, 0.0)], "den": [term(0.0064, 0.89), term(1.0, 0.0)], "delay": 0.0},
        "usable": false,
        "problems": ["the validation NRMSE is 85%"]
    });
    std::fs::write(&p, doc.to_string()).unwrap();
    let out = fracid(&["tune", p.to_str().unwrap(), "--wc", "100", "--pm", "60"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("unusable") && err.contains("NRMSE is 85%"),
        "{err}"
    );
    let t = std::time::Instant::now();
    let out = fracid(&["tune", PMSM, "--wc", "1e-100", "--pm", "60"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(t.elapsed().as_secs_f64() < 10.0);
}

/// `--analyse C`: a design's own controller analysed gives the design's loop (exit 0), the
/// controller once returned for the resonant model is shown unstable with its three crossovers
/// (exit 1, the report first), and a `--form fopd` design meets its specification.
#[test]
fn a_given_controller_is_analysed() {
    let v = json_of(&fracid(&[
        "tune", PMSM, "--wc", "300", "--pm", "60", "--flat", "--json",
    ]));
    let c = v["controller"]["text"].as_str().unwrap();
    let a = json_of(&fracid(&["tune", PMSM, "--analyse", c, "--json"]));
    for k in ["wc", "pm_deg", "ms", "gm_db"] {
        let (x, y) = (
            a["loop"][k].as_f64().unwrap(),
            v["loop"][k].as_f64().unwrap(),
        );
        assert!((x - y).abs() <= 1e-6 * y.abs(), "{k}: {x} vs {y}");
    }
    assert_eq!(a["misses"].as_array().unwrap().len(), 0);
    let out = fracid(&[
        "tune",
        "100/(s^2 + 0.001 s + 10000)",
        "--analyse",
        "(0.6444633298468005 s^1.336875 + 13.252662292151571)/(s^1.336875)",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("2 closed-loop poles in the right half-plane"),
        "{text}"
    );
    assert!(text.contains("3 crossovers"), "{text}");
    let d = json_of(&fracid(&[
        "tune",
        "1.0263/(s (0.71 s + 1))",
        "--form",
        "fopd",
        "--wc",
        "2",
        "--pm",
        "60",
        "--flat",
        "--json",
    ]));
    assert_eq!(d["params"]["ki"].as_f64(), Some(0.0));
    let lw = l(&d, 2.0);
    assert!((lw.0.hypot(lw.1) - 1.0).abs() < 1e-6);
    assert!((180.0 + lw.1.atan2(lw.0).to_degrees() - 60.0).abs() < 1e-6);
}

/// A `freq --sk N --json` report whose Sanathanan-Koerner fit beats Levy's (`J` lower; the
/// paper's Table 1 without weights): `tune` designs on the report's answer, its best model
/// (`best_model`, the library's one rule `ident::app::answer`), not on Levy's top-level `model`
/// (on main it took Levy's).
#[test]
fn a_freq_report_is_tuned_on_its_best_model_not_levys() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t1.csv");
    std::fs::copy(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../data/paper_table1_bode.csv"
        ),
        &table,
    )
    .unwrap();
    let out = fracid(&[
        "freq",
        table.to_str().unwrap(),
        "--sk",
        "10",
        "--weights",
        "none",
        "--json",
    ]);
    let report = json_of(&out);
    let (levy, sk) = (
        report["J"].as_f64().unwrap(),
        report["sk"]["J"].as_f64().unwrap(),
    );
    assert!(sk < levy, "SK {sk} should beat Levy {levy} here");
    assert_eq!(report["best_model"], report["sk"]["model"]);
    let p = dir.path().join("freq.json");
    std::fs::write(&p, report.to_string()).unwrap();
    let v = json_of(&fracid(&[
        "tune",
        p.to_str().unwrap(),
        "--wc",
        "300",
        "--pm",
        "60",
        "--json",
    ]));
    assert_eq!(v["model"]["text"], report["sk"]["model"]["text"]);
    assert_ne!(v["model"]["text"], report["model"]["text"]);
}
