//! `fracid time --structure general`: the general structure sized by the data, end to end on a
//! resonance measured at the load, and the model it reports used by `fracid sim`, `fracid export`
//! and `fracid tune`, each checked against an independent computation (the reported integer-order
//! model simulated here by its own state space and matrix exponential; the loop evaluated here
//! from the reported terms).

use super::{stderr, stdout};
use crate::fracid;
use std::fmt::Write as _;

/// `exp(M)` by scaling and squaring with a 20-term Taylor series.
fn expm(m: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = m.len();
    let norm: f64 = m
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let s = (norm.max(1e-300).log2().ceil() + 1.0).max(0.0) as i32;
    let f = 0.5f64.powi(s);
    let a: Vec<Vec<f64>> = m
        .iter()
        .map(|r| r.iter().map(|v| v * f).collect())
        .collect();
    let mul = |x: &[Vec<f64>], y: &[Vec<f64>]| -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (0..n).map(|k| x[i][k] * y[k][j]).sum())
                    .collect()
            })
            .collect()
    };
    let mut term: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    let mut sum = term.clone();
    for k in 1..=20 {
        term = mul(&term, &a);
        term.iter_mut()
            .for_each(|r| r.iter_mut().for_each(|v| *v /= k as f64));
        for i in 0..n {
            for j in 0..n {
                sum[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..s {
        sum = mul(&sum, &sum);
    }
    sum
}

/// The exact response of `sum b_k s^k / sum a_k s^k` (ascending powers, proper) to `u` held over
/// each step of `dt`, from rest.
fn simulate(b: &[f64], a: &[f64], u: &[f64], dt: f64) -> Vec<f64> {
    let n = a.len() - 1;
    let an = a[n];
    let a: Vec<f64> = a.iter().map(|v| v / an).collect();
    let mut b: Vec<f64> = b.iter().map(|v| v / an).collect();
    b.resize(n + 1, 0.0);
    let d = b[n];
    let c: Vec<f64> = (0..n).map(|k| b[k] - d * a[k]).collect();
    let mut m = vec![vec![0.0; n + 1]; n + 1];
    for i in 0..n - 1 {
        m[i][i + 1] = dt;
    }
    for k in 0..n {
        m[n - 1][k] = -a[k] * dt;
    }
    m[n - 1][n] = dt;
    let e = expm(&m);
    let mut x = vec![0.0; n];
    u.iter()
        .map(|&uk| {
            let y = c.iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() + d * uk;
            x = (0..n)
                .map(|i| (0..n).map(|j| e[i][j] * x[j]).sum::<f64>() + e[i][n] * uk)
                .collect();
            y
        })
        .collect()
}

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
    let mut state = seed;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut level = 1.0;
    let u: Vec<f64> = (0..8000)
        .map(|_| {
            if next() < 1.0 / 3.0 {
                level = -level;
            }
            level
        })
        .collect();
    let y = simulate(b, a, &u, dt);
    let mut text = String::from("t,u,y\n");
    for (k, (u, y)) in u.iter().zip(&y).enumerate() {
        let noise = 0.01 * 3f64.sqrt() * (2.0 * next() - 1.0);
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
