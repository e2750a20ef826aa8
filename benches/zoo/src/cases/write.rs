//! A case on disk: `CASES/NAME.csv` (`t,u,y`, what fracid reads) and, kept out of that directory,
//! `TRUTH/NAME.truth.json` (the hidden truth) and `TRUTH/NAME.clean.csv` (`t,y_clean`: the
//! noise-free output, for the oracle's held-out error).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{Case, Error, Truth};

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |e| Error::Io(path.display().to_string(), e)
}

/// The record fracid reads.
pub fn record_path(cases_dir: &Path, name: &str) -> PathBuf {
    cases_dir.join(format!("{name}.csv"))
}

/// The truth's sidecar.
pub fn truth_path(truth_dir: &Path, name: &str) -> PathBuf {
    truth_dir.join(format!("{name}.truth.json"))
}

/// The noise-free output.
pub fn clean_path(truth_dir: &Path, name: &str) -> PathBuf {
    truth_dir.join(format!("{name}.clean.csv"))
}

/// Writes the case's three files (the directories created if missing).
pub fn write_case(case: &Case, cases_dir: &Path, truth_dir: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(cases_dir).map_err(io(cases_dir))?;
    std::fs::create_dir_all(truth_dir).map_err(io(truth_dir))?;
    let t = &case.truth;
    let mut rec = String::with_capacity(case.u.len() * 48);
    rec.push_str("t,u,y\n");
    let mut clean = String::with_capacity(case.u.len() * 32);
    clean.push_str("t,y_clean\n");
    for k in 0..case.u.len() {
        let time = k as f64 * t.dt;
        // `{:e}` of an f64 is its shortest exact representation: the files hold the values.
        let _ = writeln!(rec, "{time:e},{:e},{:e}", case.u[k], case.y[k]);
        let _ = writeln!(clean, "{time:e},{:e}", case.y_clean[k]);
    }
    let path = record_path(cases_dir, &t.name);
    std::fs::write(&path, rec).map_err(io(&path))?;
    let path = clean_path(truth_dir, &t.name);
    std::fs::write(&path, clean).map_err(io(&path))?;
    let path = truth_path(truth_dir, &t.name);
    let json = serde_json::to_string_pretty(t).map_err(|e| Error::Json(t.name.clone(), e))?;
    std::fs::write(&path, json).map_err(io(&path))
}

/// Reads a truth sidecar.
pub fn read_truth(path: &Path) -> Result<Truth, Error> {
    let text = std::fs::read_to_string(path).map_err(io(path))?;
    serde_json::from_str(&text).map_err(|e| Error::Json(path.display().to_string(), e))
}

/// Reads column `col` (0-based) of a CSV with a header line.
pub fn read_column(path: &Path, col: usize) -> Result<Vec<f64>, Error> {
    let text = std::fs::read_to_string(path).map_err(io(path))?;
    let bad = |line: usize| {
        Error::Io(
            path.display().to_string(),
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("line {line}: no number in column {col}"),
            ),
        )
    };
    text.lines()
        .enumerate()
        .skip(1)
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.split(',')
                .nth(col)
                .and_then(|v| v.trim().parse::<f64>().ok())
                .ok_or_else(|| bad(i + 1))
        })
        .collect()
}
