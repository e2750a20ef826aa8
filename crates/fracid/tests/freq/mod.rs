//! `fracid freq`: Table 1 numbers, JSON, plots, bad input.

use super::fracid;
use std::io::Write;
use std::path::PathBuf;

const TABLE1: &str = "freq_hz,gain_db,phase_deg
0.1,16.62,-0.23
0.5,16.63,-0.95
1,16.63,-1.83
2,16.55,-3.4
5,16.47,-7.95
10,16.26,-16.3
20,15.96,-29.2
50,13.48,-68.9
80,9.5,-95.6
100,6.91,-107
";

const PAPER: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)";

fn file_with(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::File::create(&p)
        .and_then(|mut f| f.write_all(text.as_bytes()))
        .unwrap();
    p
}

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// J of `fracid freq DATA --weights W --q 0.9` (which must succeed).
fn j_with_weights(data: &std::path::Path, w: &str) -> f64 {
    let o = fracid(&[
        "freq",
        data.to_str().unwrap(),
        "--weights",
        w,
        "--q",
        "0.9",
        "--json",
    ]);
    assert!(o.status.success(), "{w}: {}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    v["J"].as_f64().unwrap()
}

fn rel(x: f64, y: f64) -> f64 {
    ((x - y) / y).abs()
}

#[test]
fn table1_json_has_the_reference_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let data = file_with(&dir, "t1.csv", TABLE1);
    let o = fracid(&[
        "freq",
        data.to_str().unwrap(),
        "--refine",
        "--no-q-refine",
        "--json",
        "--compare",
        PAPER,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // the paper's grid: q = 0.91, J = 3.555e-3 (1 %)
    assert_eq!(v["q"].as_f64().unwrap(), 0.91);
    assert!(rel(v["J"].as_f64().unwrap(), 3.555e-3) < 1e-2);
    let den = v["model"]["den"].as_array().unwrap();
    assert_eq!(den.len(), 3);
    assert_eq!(den[2]["order"].as_f64().unwrap(), 0.0);
    assert!(rel(den[0]["order"].as_f64().unwrap(), 1.82) < 1e-12);
    assert!(rel(v["model"]["num"][0]["coef"].as_f64().unwrap(), 6.7832) < 5e-3);
    assert_eq!(v["model"]["delay"].as_f64().unwrap(), 0.0);
    assert!(v["refined"]["J"].as_f64().unwrap() <= 2.0e-3);
    assert_eq!(v["refined"]["model"]["den"].as_array().unwrap().len(), 3);
    assert!(rel(v["compare"][0]["J"].as_f64().unwrap(), 2.06e-2) < 1e-2);
    assert_eq!(v["curve"].as_array().unwrap().len(), 100);
}

#[test]
fn table1_table_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let data = file_with(&dir, "t1.csv", TABLE1);
    let png = dir.path().join("bode.png");
    let svg = dir.path().join("bode.svg");
    for plot in [&png, &svg] {
        let o = fracid(&[
            "freq",
            data.to_str().unwrap(),
            "--refine",
            "--sk",
            "3",
            "--compare",
            PAPER,
            "--plot",
            plot.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        for want in [
            "Levy, grid q",
            "refined (LM)",
            "SK (3 it.)",
            "3.555e-3",
            "2.061e-2",
            "eq. 30",
        ] {
            assert!(out.contains(want), "missing {want:?} in\n{out}");
        }
        assert!(std::fs::metadata(plot).unwrap().len() > 10_000);
    }
}

#[test]
fn other_units_separators_and_columns() {
    // the same table in rad/s, linear gain, radians, semicolons, other names, comments
    let mut text = String::from("# Table 1 in other units\nw;mag;ph\n");
    for line in TABLE1.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        text += &format!(
            "{};{};{}\n",
            2.0 * std::f64::consts::PI * v[0],
            10f64.powf(v[1] / 20.0),
            v[2].to_radians()
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let data = file_with(&dir, "t1.txt", &text);
    let o = fracid(&[
        "freq",
        data.to_str().unwrap(),
        "--rad-s",
        "--linear-gain",
        "--radians",
        "--columns",
        "w,mag,ph",
        "--q",
        "0.89",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(rel(v["J"].as_f64().unwrap(), 3.675e-3) < 1e-2);
    assert!(rel(v["levy"]["a"][1].as_f64().unwrap(), 2.5906e-5) < 5e-3);
}

#[test]
fn weights_none_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("freq_hz,gain_db,phase_deg,wt\n");
    for line in TABLE1.lines().skip(1) {
        text += &format!("{line},1\n");
    }
    let data = file_with(&dir, "t1w.csv", &text);
    let get_j = |w: &str| j_with_weights(&data, w);
    // a column of ones is the unweighted fit
    assert_eq!(get_j("none"), get_j("wt"));
    assert_ne!(get_j("none"), get_j("vinagre"));
}

#[test]
fn duplicated_columns_are_errors_and_a_bom_is_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let mut dup = String::from("freq_hz,freq_hz,gain_db,phase_deg\n");
    let mut bom = String::from("\u{feff}wt,freq_hz,gain_db,phase_deg\r\n");
    for line in TABLE1.lines().skip(1) {
        let f = line.split(',').next().unwrap();
        dup += &format!("{f},{line}\n");
        bom += &format!("1,{line}\r\n");
    }
    // A name twice in the header silently took the first.
    let data = file_with(&dir, "dup.csv", &dup);
    let o = fracid(&["freq", data.to_str().unwrap(), "--q", "0.9"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("column 'freq_hz' appears twice"),
        "{}",
        stderr(&o)
    );
    // One column for the three roles was read as frequency, gain and phase.
    let data = file_with(&dir, "ok.csv", TABLE1);
    let o = fracid(&[
        "freq",
        data.to_str().unwrap(),
        "--columns",
        "freq_hz,freq_hz,freq_hz",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("column 'freq_hz' is chosen twice"),
        "{}",
        stderr(&o)
    );
    // A weight column that is also a role.
    let o = fracid(&["freq", data.to_str().unwrap(), "--weights", "gain_db"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("chosen twice"), "{}", stderr(&o));
    // Excel's CSV UTF-8 (byte-order mark, CRLF) with the weight column first: --weights read
    // the header on its own and saw '\u{feff}wt', so 'wt' was "neither ... a column nor a file".
    let data = file_with(&dir, "bom.csv", &bom);
    assert_eq!(j_with_weights(&data, "wt"), j_with_weights(&data, "none"));
}

#[test]
fn bad_input_exits_2_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str)] = &[
        ("", "no data"),
        ("freq_hz,gain_db,phase_deg\n", "no data"),
        (
            "freq_hz,gain_db,phase_deg\n1,2,3\n0.5,2,3\n3,1,4\n",
            "increase",
        ),
        (
            "freq_hz,gain_db,phase_deg\n1,2,3\n1,2,3\n3,1,4\n",
            "repeated",
        ),
        ("freq_hz,gain_db,phase_deg\n0,2,3\n1,2,3\n3,1,4\n", "> 0"),
        ("freq_hz,gain_db,phase_deg\n-1,2,3\n1,2,3\n3,1,4\n", "> 0"),
        ("freq_hz,gain_db,phase_deg\n1,NaN,3\n2,2,3\n3,1,4\n", "NaN"),
        (
            "freq_hz,gain_db,phase_deg\n1,abc,3\n2,2,3\n3,1,4\n",
            "not a number",
        ),
        ("freq_hz,gain_db\n1,2\n2,2\n3,1\n", "phase"),
        ("freq_hz,gain_db,phase_deg\n1,2,3\n2,2,3\n", "unknowns"),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let data = file_with(&dir, &format!("bad{i}.csv"), text);
        let o = fracid(&["freq", data.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{text:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(want), "{text:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // bad options
    let data = file_with(&dir, "ok.csv", TABLE1);
    let d = data.to_str().unwrap();
    for args in [
        vec!["freq", d, "--q", "0"],
        vec!["freq", d, "--q", "3"],
        vec!["freq", d, "--n", "1", "--refine"],
        vec!["freq", d, "--weights", "nosuchthing"],
        vec!["freq", d, "--columns", "a,b"],
        vec!["freq", d, "--compare", "1/(s +"],
        vec!["freq", d, "--plot", "out.jpg"],
    ] {
        let o = fracid(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
    // a missing file is an I/O error: exit 3
    let o = fracid(&["freq", "/nonexistent/bode.csv"]);
    assert_eq!(o.status.code(), Some(3));
}

#[test]
fn diagnose_adds_the_diagnosis_keys() {
    let dir = tempfile::tempdir().unwrap();
    let data = file_with(&dir, "t1.csv", TABLE1);
    let o = fracid(&[
        "freq",
        data.to_str().unwrap(),
        "--refine",
        "--diagnose",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let d = &v["diagnosis"];
    assert!(d["before"]["J"].as_f64().unwrap() <= 2.0e-3);
    assert!(d["after"]["J"].is_number());
    assert!(d["effects"].is_array() && d["unexplained"].is_boolean());
    assert!(d["model"]["den"].is_array());
}
