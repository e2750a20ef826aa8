//! `fracid export`: JSON and MATLAB state spaces, from a model string and from a fit report; the
//! exported discrete model run by its own recursion equals `fracid sim`.

use super::fracid;
use std::path::Path;

/// `fracid export ARGS... -o OUT`, which must succeed: the text it wrote.
fn export_to(args: &[&str], out: &Path) -> String {
    let mut all = vec!["export"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["-o", out.to_str().unwrap()]);
    let o = fracid(&all);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read_to_string(out).unwrap()
}

fn json_file(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn matrix(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
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
}

/// The step response of the exported discrete model, by `x <- A x + B u`, `y = C x + D u`.
fn step(v: &serde_json::Value, n: usize) -> Vec<f64> {
    let (a, b, c, d) = (
        matrix(&v["a"]),
        matrix(&v["b"]),
        matrix(&v["c"]),
        matrix(&v["d"]),
    );
    let mut x = vec![0.0; a.len()];
    let mut y = Vec::new();
    for _ in 0..n {
        y.push(c[0].iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() + d[0][0]);
        x = (0..a.len())
            .map(|i| a[i].iter().zip(&x).map(|(a, x)| a * x).sum::<f64>() + b[i][0])
            .collect();
    }
    y
}

#[test]
fn discrete_export_steps_like_fracid_sim() {
    let dir = tempfile::tempdir().unwrap();
    let model = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.00025 s)";
    let out = dir.path().join("ss.json");
    export_to(&[model, "--dt", "1e-4"], &out);
    let v = json_file(&out);
    assert_eq!(v["time"], "discrete");
    assert_eq!(v["delay_states"], 3); // 2.5 samples: two whole, one for the fraction
    assert_eq!(v["approximation"]["method"], "refined");
    let o = fracid(&[
        "sim", "--model", model, "--step", "--dt", "1e-4", "--t-end", "0.03",
    ]);
    assert!(o.status.success());
    let sim: Vec<f64> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    let y = step(&v, sim.len());
    let peak = sim.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (k, (a, b)) in y.iter().zip(&sim).enumerate() {
        // sim prints with limited digits: 1e-6 of the peak is far below a wrong hold or delay
        assert!((a - b).abs() <= 1e-6 * peak, "k = {k}: {a} vs {b}");
    }
}

#[test]
fn matlab_script_and_fit_reports() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("motor.m");
    let text = export_to(
        &[
            "6.77/(0.0064 s^0.89 + 1) exp(-0.01 s)",
            "--band",
            "1e-2,1e5",
            "--order",
            "4",
        ],
        &m,
    );
    assert!(
        text.contains("sys = ss(A, B, C, D, 'InputDelay', tau);"),
        "{text}"
    );
    assert!(text.contains("tau = 1e-2;") && text.contains("G = tf(sys);"));
    // A report of `fracid time --json` (its "model") is a model too.
    let rep = dir.path().join("fit.json");
    std::fs::write(
        &rep,
        r#"{"model": {"num": [{"coef": 2.0, "order": 0.0}], "den": [{"coef": 0.1, "order": 1.0}, {"coef": 1.0, "order": 0.0}], "delay": 0.0}}"#,
    )
    .unwrap();
    let o = fracid(&["export", rep.to_str().unwrap(), "--dt", "0.01"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // 2/(0.1 s + 1) held over 10 ms: one state, a = e^-0.1, DC gain 2
    let a = matrix(&v["a"]);
    assert_eq!(a.len(), 1);
    assert!((a[0][0] - (-0.1f64).exp()).abs() < 1e-15);
    let (b, c) = (matrix(&v["b"])[0][0], matrix(&v["c"])[0][0]);
    assert!((c * b / (1.0 - a[0][0]) - 2.0).abs() < 1e-12);
}

#[test]
fn bad_requests_exit_2() {
    for args in [
        vec!["export", "1/(0.1 s + 1)"], // continuous without a band
        vec!["export", "1/(0.1 s + 1", "--dt", "1e-3"],
        vec!["export", "1/(0.1 s + 1)", "--dt", "-1"],
        vec!["export", "1/(0.1 s + 1)", "--dt", "1e-3", "--format", "mat"],
        vec!["export", "1/(0.1 s + 1) exp(-5 s)", "--dt", "1e-3"], // 5000 delay states
    ] {
        let o = fracid(&args);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(String::from_utf8_lossy(&o.stderr).starts_with("error: "));
    }
    let o = fracid(&["export", "/nonexistent/fit.json", "--dt", "1e-3"]);
    assert_eq!(o.status.code(), Some(3));
}

/// The paper's PMSM with a 1 ms delay.
const PMSM: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)";

/// `fracid tune --json` of [`PMSM`] at crossover `wc` rad/s, 60 degrees of phase margin, sampled
/// every `dt` s: the report as printed.
fn tune_report(wc: &str, dt: &str) -> Vec<u8> {
    let out = fracid(&["tune", PMSM, "--wc", wc, "--pm", "60", "--dt", dt, "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// A FOPI as `fracid tune` prints it, and a `fracid tune --json` report, export the controller's
/// realisation (before: "found 4 of the 19 poles"; the report's plant): the discrete steps match
/// `tune`'s own realisation in the report for the same `dt`.
#[test]
fn a_tuned_controller_exports() {
    let dir = tempfile::tempdir().unwrap();
    let report = tune_report("50", "0.001");
    let rep = dir.path().join("c.json");
    std::fs::write(&rep, &report).unwrap();
    let v: serde_json::Value = serde_json::from_slice(&report).unwrap();
    let text = v["controller"]["text"].as_str().unwrap().to_string();
    let d = &v["discrete"];
    let from_report = step(
        &serde_json::json!({"a": d["a"], "b": d["b"], "c": d["c"], "d": d["d"]}),
        200,
    );
    for arg in [text.as_str(), rep.to_str().unwrap()] {
        let o = dir.path().join("x.json");
        export_to(&[arg, "--dt", "0.001"], &o);
        let e = json_file(&o);
        let s = step(&e, 200);
        for (a, b) in s.iter().zip(&from_report) {
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                "{arg}: {a} vs {b}"
            );
        }
    }
}

/// `fracid export C.json --format c`: the header of the fixed-point sections the drive runs,
/// compiled with the C firmware's section code (`firmware/src/fw_ctrl.c`) and run on an error
/// step, agrees with the step of the floating-point realisation in the report to the output's
/// rounding and the quantisation (1 LSB + 0.2 %).
#[test]
fn the_c_header_steps_like_the_realisation() {
    let dir = tempfile::tempdir().unwrap();
    let tuned = tune_report("100", "1e-3");
    let c_json = dir.path().join("C.json");
    std::fs::write(&c_json, &tuned).unwrap();
    let header = dir.path().join("ctrl.h");
    let text = export_to(&[c_json.to_str().unwrap(), "--format", "c"], &header);
    assert!(text.contains("fracid_ctrl_load"), "{text}");
    // the error step, raw speed LSB (10 mrad/s each: 0.5 rad/s), and the samples run
    let (e_raw, n) = (50, 400);
    let main = dir.path().join("step.c");
    std::fs::write(
        &main,
        format!(
            "#include <stdio.h>\n#include \"fracfw.h\"\n#include \"ctrl.h\"\n\
             int main(void) {{\n    fw_ctrl c; uint16_t cl; int k;\n    fracid_ctrl_load(&c);\n\
             for (k = 0; k < {n}; k++) {{ printf(\"%d\\n\", fw_ctrl_step(&c, {e_raw}, 32767, &cl)); }}\n\
             return 0;\n}}\n"
        ),
    )
    .unwrap();
    let fw = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../firmware");
    let exe = dir.path().join("step");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = std::process::Command::new(&cc)
        .args([
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-O1",
        ])
        .arg("-I")
        .arg(fw.join("include"))
        .arg("-I")
        .arg(dir.path())
        .arg(fw.join("src/fw_ctrl.c"))
        .arg(&main)
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler {cc}: {e}"));
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let run = std::process::Command::new(&exe).output().unwrap();
    assert!(run.status.success());
    let u_c: Vec<f64> = String::from_utf8(run.stdout)
        .unwrap()
        .lines()
        .map(|l| l.trim().parse().unwrap())
        .collect();
    assert_eq!(u_c.len(), n);
    // the realisation's step in floating point: e = 0.5 rad/s, u in V, raw at 1 mV per LSB
    let v: serde_json::Value = serde_json::from_slice(&tuned).unwrap();
    let unit = step(&v["discrete"], n);
    let e = e_raw as f64 * 0.01;
    for (k, (&uc, &s)) in u_c.iter().zip(&unit).enumerate() {
        let want = e * s / 1e-3;
        let tol = 1.0 + 2e-3 * want.abs();
        assert!(
            (uc - want).abs() <= tol,
            "sample {k}: the C firmware gives {uc}, the realisation {want:.3} (raw LSB)"
        );
    }
    // the step moves: the controller integrates the error
    assert!(u_c[n - 1] > u_c[0] + 10.0, "{} -> {}", u_c[0], u_c[n - 1]);
    // a plant is no controller, and a controller needs its sample period: bad input
    for args in [
        vec!["export", PMSM, "--format", "c"],
        vec!["export", "0.1 + 20/s^0.9", "--format", "c"],
    ] {
        let o = fracid(&args);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}
