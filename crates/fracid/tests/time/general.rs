//! `fracid time --structure general`: the general structure sized by the data, end to end on a
//! resonance measured at the load, and the model it reports used by `fracid sim`, `fracid export`
//! and `fracid tune`, each checked against an independent computation (the reported integer-order
//! model simulated here by its own state space and matrix exponential; the loop evaluated here
//! from the reported terms).

use super::{stderr, stdout};
use crate::exact::{random_binary, simulate, Lcg};
use crate::fracid;
use std::fmt::Write as _;

/// Ascending integer-power coefficients of a JSON term list (orders must be integers).
fn coefs(terms: &serde_json::Value) -> Vec<f64> {
    let mut out = vec![];
    for t in terms.as_array().unwrap() {
        let (c, o) = (t["coef"].as_f64().unwrap(), t["order"].as_f64().unwrap());
        assert_eq!(o, o.round(), "an integer order: {t}");
        let k = o as usize;
        if out.len() <= k {
            out.resize(k + 1, 0.0);
        }
        out[k] += c;
    }
    out
}

/// A record of `2/((0.02 s + 1)(s^2/w^2 + 2 z s/w + 1))`, `w = 2 pi 40`, `z = 0.05`, on a random
/// binary input (1 ms, 8000 samples), with 1% output noise, written as CSV.
fn load_resonance_csv(dir: &tempfile::TempDir) -> std::path::PathBuf {
    let w = 2.0 * std::f64::consts::PI * 40.0;
    let (c2, c1) = (1.0 / (w * w), 0.1 / w);
    let a = [1.0, c1 + 0.02, c2 + 0.02 * c1, 0.02 * c2];
    record_csv(dir, "load.csv", &[2.0], &a, 21)
}

/// A record of `b(s)/a(s)` (ascending powers) simulated exactly on a random binary input
/// (switching with probability 1/3 each 1 ms sample, 8000 samples, seeded), with uniform output
/// noise of standard deviation 0.01, written as CSV.
fn record_csv(
    dir: &tempfile::TempDir,
    name: &str,
    b: &[f64],
    a: &[f64],
    seed: u64,
) -> std::path::PathBuf {
    let dt = 1e-3;
    let mut rng = Lcg(seed);
    let u = random_binary(&mut rng, 8000, 1.0 / 3.0);
    let y = simulate(b, a, &u, dt);
    let mut text = String::from("t,u,y\n");
    for (k, (u, y)) in u.iter().zip(&y).enumerate() {
        let noise = 0.01 * 3f64.sqrt() * (2.0 * rng.uniform() - 1.0);
        writeln!(text, "{:.6},{u},{}", k as f64 * dt, y + noise).unwrap();
    }
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `sum coef (j w)^order` of a JSON term list.
fn poly(terms: &serde_json::Value, w: f64) -> num_complex::Complex64 {
    terms
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let (c, o) = (t["coef"].as_f64().unwrap(), t["order"].as_f64().unwrap());
            c * num_complex::Complex64::new(0.0, w).powf(o)
        })
        .sum()
}

#[test]
fn a_general_model_fits_simulates_exports_and_tunes() {
    let dir = tempfile::tempdir().unwrap();
    let csv = load_resonance_csv(&dir);
    let report = dir.path().join("fit.json");
    let o = fracid(&[
        "time",
        csv.to_str().unwrap(),
        "--structure",
        "general",
        "--plain",
        "--json",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    std::fs::write(&report, stdout(&o)).unwrap();
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let model = &v["model"];
    let text = model["text"].as_str().unwrap().to_string();
    assert!(
        v["structures"]["scores"][0]["name"]
            .as_str()
            .unwrap()
            .starts_with("general "),
        "{}",
        v["structures"]
    );
    let (b, a) = (coefs(&model["num"]), coefs(&model["den"]));
    let dt = 1e-3;
    let n = 400;
    let truth = simulate(&b, &a, &vec![1.0; n], dt);
    let peak = truth.iter().fold(0.0f64, |m, v| m.max(v.abs()));

    // fracid sim --model TEXT: the step response of the reported model
    let o = fracid(&[
        "sim",
        "--model",
        &text,
        "--step",
        "--dt",
        "1e-3",
        "--t-end",
        &format!("{}", (n - 1) as f64 * dt),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sim: Vec<f64> = stdout(&o)
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert!(sim.len() >= n - 1, "{} samples", sim.len());
    for (k, (s, t)) in sim.iter().zip(&truth).enumerate() {
        assert!((s - t).abs() <= 1e-4 * peak, "sim k = {k}: {s} vs {t}");
    }

    // fracid export REPORT: the discrete state space steps like the exact simulation
    let ss = dir.path().join("ss.json");
    let o = fracid(&[
        "export",
        report.to_str().unwrap(),
        "--dt",
        "1e-3",
        "-o",
        ss.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ss).unwrap()).unwrap();
    let m = |k: &str| -> Vec<Vec<f64>> {
        e[k].as_array()
            .unwrap()
            .iter()
            .map(|r| {
                r.as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap())
                    .collect()
            })
            .collect()
    };
    let (ea, eb, ec, ed) = (m("a"), m("b"), m("c"), m("d"));
    let mut x = vec![0.0; ea.len()];
    for (k, t) in truth.iter().enumerate() {
        let y = ec[0].iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() + ed[0][0];
        assert!((y - t).abs() <= 1e-6 * peak, "export k = {k}: {y} vs {t}");
        x = (0..ea.len())
            .map(|i| ea[i].iter().zip(&x).map(|(a, x)| a * x).sum::<f64>() + eb[i][0])
            .collect();
    }

    // fracid tune TEXT: the loop with the reported model meets its specification
    let o = fracid(&["tune", &text, "--wc", "30", "--pm", "60", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let t: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let tf = |m: &serde_json::Value, w: f64| {
        let g = poly(&m["num"], w) / poly(&m["den"], w);
        let tau = m["delay"].as_f64().unwrap_or(0.0);
        g * num_complex::Complex64::from_polar(1.0, -w * tau)
    };
    let l = tf(&t["model"], 30.0) * tf(&t["controller"], 30.0);
    // the model tuned is the one reported
    let g_rep = poly(&model["num"], 30.0) / poly(&model["den"], 30.0);
    assert!((tf(&t["model"], 30.0) - g_rep).norm() <= 1e-9 * g_rep.norm());
    assert!((l.norm() - 1.0).abs() < 0.01, "|L(j wc)| = {}", l.norm());
    let pm = 180.0 + l.arg().to_degrees();
    assert!((pm - 60.0).abs() < 1.0, "pm = {pm}");
}

/// `prod` of polynomials in ascending powers.
fn times(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            out[i + j] += a * b;
        }
    }
    out
}

/// The diagnosis compares the general structure when the named ones fit poorly: a resonance at
/// the load with an anti-resonance whose damping is not the resonance's (the two-mass structure
/// ties them), `2 (s^2/wz^2 + 2 0.15 s/wz + 1) / ((0.01 s + 1)(s^2/wp^2 + 2 0.03 s/wp + 1))`,
/// `wz = 2 pi 25`, `wp = 2 pi 40`. `--diagnose` returns the general model, and its response is
/// within 5% of the truth's over the excited band (the truth evaluated here from its
/// coefficients, the model from the reported terms).
#[test]
fn the_diagnosis_returns_the_general_model_where_the_named_ones_fit_poorly() {
    let (wz, wp) = (
        2.0 * std::f64::consts::PI * 25.0,
        2.0 * std::f64::consts::PI * 40.0,
    );
    let b: Vec<f64> = [2.0, 2.0 * 2.0 * 0.15 / wz, 2.0 / (wz * wz)].to_vec();
    let a = times(&[1.0, 0.01], &[1.0, 2.0 * 0.03 / wp, 1.0 / (wp * wp)]);
    let dir = tempfile::tempdir().unwrap();
    let csv = record_csv(&dir, "anti.csv", &b, &a, 5);
    let o = fracid(&[
        "time",
        csv.to_str().unwrap(),
        "--diagnose",
        "--json",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let choice = &v["diagnosis"]["structures"];
    let chosen = choice["chosen"].as_u64().unwrap() as usize;
    let name = choice["scores"][chosen]["name"].as_str().unwrap();
    assert!(name.starts_with("general "), "{name}: {}", choice["reason"]);
    assert!(
        v["model_is"].as_str().unwrap().starts_with("final"),
        "{}",
        v["model_is"]
    );
    let model = &v["model"];
    let tau = model["delay"].as_f64().unwrap_or(0.0);
    let truth = |w: f64| {
        let s = num_complex::Complex64::new(0.0, w);
        let p = |c: &[f64]| {
            c.iter()
                .rev()
                .fold(num_complex::Complex64::new(0.0, 0.0), |acc, &x| acc * s + x)
        };
        p(&b) / p(&a)
    };
    let (lo, hi) = (
        2.0 * std::f64::consts::PI * 10.0 / 8.0,
        0.25 * std::f64::consts::PI / 1e-3,
    );
    let (mut e, mut t) = (0.0, 0.0);
    for i in 0..60 {
        let w = lo * (hi / lo).powf(i as f64 / 59.0);
        let fit = poly(&model["num"], w) / poly(&model["den"], w)
            * num_complex::Complex64::from_polar(1.0, -w * tau);
        e += (truth(w) - fit).norm_sqr();
        t += truth(w).norm_sqr();
    }
    let err = (e / t).sqrt();
    assert!(
        err < 0.05,
        "FRF error {err}: {} ({})",
        model["text"],
        choice["reason"]
    );
}
