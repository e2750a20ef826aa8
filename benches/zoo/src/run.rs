//! One run of the zoo: generate the cases into `OUT/cases` (what fracid reads) and `OUT/truth`
//! (kept out of it), fit them through fracid's fleet path twice (`fracid time OUT/cases --json --plain
//! --out OUT/reports/plain --jobs N`, and again with `--diagnose` (the loop closed) into `OUT/reports/diagnose`),
//! score every case and write the table (`OUT/table.md`, `table.csv`, `table.json`) and the
//! per-case scores (`OUT/cases.csv`, `cases.json`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::cases::{self, write, Sizing};
use crate::score::{self, floors, table, Outcome, Row};

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Generating or reading a case.
    #[error(transparent)]
    Cases(#[from] cases::Error),
    /// fracid could not be run or printed no summary.
    #[error("fracid ({0}): {1}")]
    Fracid(String, String),
    /// Writing the table.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Options {
    /// The zoo's seed.
    pub seed: u64,
    /// The cases' indices.
    pub indices: Vec<usize>,
    /// Record lengths.
    pub sizing: Sizing,
    /// The output directory.
    pub out: PathBuf,
    /// The fracid binary.
    pub fracid: PathBuf,
    /// Fits at once (fracid's `--jobs`) and generator threads.
    pub jobs: usize,
}

/// What one fleet run cost.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FleetCost {
    /// Wall time [s].
    pub wall_s: f64,
    /// The process's CPU, user + system [s] (None off Unix).
    pub cpu_s: Option<f64>,
}

/// A run's results.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Results {
    /// The table by class (last row "all").
    pub table: Vec<table::ClassRow>,
    /// The floors' counts ([`floors::floors`]).
    #[serde(default)]
    pub floors: floors::Floors,
    /// Every case on every path.
    pub outcomes: Vec<Outcome>,
    /// Generation wall time [s].
    pub generate_s: f64,
    /// The plain fleet's cost.
    pub plain: FleetCost,
    /// The diagnosed fleet's cost.
    pub diagnose: FleetCost,
    /// The command line of the plain fleet (`--plain`; the diagnosed one `--diagnose`).
    pub fracid_command: String,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |e| Error::Io(path.display().to_string(), e)
}

/// Generates the cases on `jobs` threads and writes them.
pub fn generate(o: &Options) -> Result<Vec<cases::Truth>, Error> {
    let (cases_dir, truth_dir) = (o.out.join("cases"), o.out.join("truth"));
    let chunks: Vec<Vec<usize>> = (0..o.jobs.max(1))
        .map(|j| {
            o.indices
                .iter()
                .copied()
                .skip(j)
                .step_by(o.jobs.max(1))
                .collect()
        })
        .collect();
    let results: Vec<Result<Vec<cases::Truth>, cases::Error>> = std::thread::scope(|s| {
        let handles: Vec<_> = chunks
            .iter()
            .map(|chunk| {
                let (cases_dir, truth_dir) = (&cases_dir, &truth_dir);
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&i| {
                            let case = cases::generate(o.seed, i, o.sizing)?;
                            write::write_case(&case, cases_dir, truth_dir)?;
                            Ok(case.truth)
                        })
                        .collect()
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a generator thread panicked"))
            .collect()
    });
    let mut truths = Vec::new();
    for r in results {
        truths.extend(r?);
    }
    truths.sort_by_key(|t| t.index);
    Ok(truths)
}

#[cfg(unix)]
fn children_cpu_s() -> Option<f64> {
    // SAFETY: getrusage writes the struct it is given; a zeroed rusage is a valid value.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut ru) };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    (rc == 0).then(|| secs(ru.ru_utime) + secs(ru.ru_stime))
}

#[cfg(not(unix))]
fn children_cpu_s() -> Option<f64> {
    None
}

/// The arguments of a fleet run.
pub fn fleet_args(cases_dir: &Path, reports: &Path, jobs: usize, diagnose: bool) -> Vec<String> {
    let mut args: Vec<String> = vec![
        "time".into(),
        cases_dir.display().to_string(),
        "--json".into(),
        "--quiet".into(),
        "--out".into(),
        reports.display().to_string(),
        "--jobs".into(),
        jobs.to_string(),
    ];
    // The single fit of the named structure, or the loop closed (fracid's default), each asked for.
    args.push(if diagnose { "--diagnose" } else { "--plain" }.into());
    args
}

/// Runs one fleet; returns the summary's rows by file stem and the cost.
pub fn fleet(o: &Options, diagnose: bool) -> Result<(HashMap<String, Row>, FleetCost), Error> {
    let reports = o
        .out
        .join("reports")
        .join(if diagnose { "diagnose" } else { "plain" });
    let args = fleet_args(&o.out.join("cases"), &reports, o.jobs, diagnose);
    let cpu0 = children_cpu_s();
    let start = Instant::now();
    let out = Command::new(&o.fracid)
        .args(&args)
        .output()
        .map_err(|e| Error::Fracid(o.fracid.display().to_string(), e.to_string()))?;
    let wall_s = start.elapsed().as_secs_f64();
    let cpu_s = match (cpu0, children_cpu_s()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let summary: Value = serde_json::from_slice(&out.stdout).map_err(|e| {
        Error::Fracid(
            o.fracid.display().to_string(),
            format!(
                "no summary on stdout ({e}); exit {:?}; stderr: {}",
                out.status.code(),
                String::from_utf8_lossy(&out.stderr)
            ),
        )
    })?;
    let rows = summary_rows(&summary);
    Ok((rows, FleetCost { wall_s, cpu_s }))
}

/// The rows of a fleet summary (`time-summary.json`) by file stem.
pub fn summary_rows(summary: &Value) -> HashMap<String, Row> {
    let mut rows = HashMap::new();
    for r in summary
        .get("rows")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let Some(file) = r.get("file").and_then(Value::as_str) else {
            continue;
        };
        let stem = Path::new(file)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        rows.insert(
            stem,
            Row {
                exit_code: r.get("exit_code").and_then(Value::as_i64).unwrap_or(-1) as i32,
                seconds: r.get("seconds").and_then(Value::as_f64),
                error: r.get("error").and_then(Value::as_str).map(str::to_string),
            },
        );
    }
    rows
}

fn read_report(o: &Options, path: score::Path, name: &str) -> Option<Value> {
    let file = o
        .out
        .join("reports")
        .join(path.name())
        .join(format!("{name}.time.json"));
    let text = std::fs::read_to_string(file).ok()?;
    serde_json::from_str(&text).ok()
}

/// Scores every case on both paths.
pub fn score_all(
    o: &Options,
    truths: &[cases::Truth],
    rows: &[HashMap<String, Row>; 2],
) -> Result<Vec<Outcome>, Error> {
    let mut outcomes = Vec::with_capacity(2 * truths.len());
    for t in truths {
        let y = write::read_column(&write::record_path(&o.out.join("cases"), &t.name), 2)?;
        let y_clean = write::read_column(&write::clean_path(&o.out.join("truth"), &t.name), 1)?;
        for (p, path) in score::Path::BOTH.into_iter().enumerate() {
            let report = read_report(o, path, &t.name);
            outcomes.push(score::score(
                t,
                &y,
                &y_clean,
                path,
                rows[p].get(&t.name),
                report.as_ref(),
            ));
        }
    }
    Ok(outcomes)
}

/// The file that marks a directory as a zoo run's (its cases, truth and reports may be replaced).
const MARKER: &str = ".zoo-run";

/// Makes `out` ready for a run: created if missing; an earlier run's cases, truth and reports
/// removed (a stale file would be fitted or scored with the new ones); a directory that holds
/// other files and no marker is refused (it is not ours to empty).
pub fn prepare(out: &Path) -> Result<(), Error> {
    let ours = out.join(MARKER).exists();
    let empty = std::fs::read_dir(out).map_or(true, |mut d| d.next().is_none());
    if !ours && !empty {
        return Err(Error::Io(
            out.display().to_string(),
            std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "not empty and not a zoo run's directory: give a new or empty --out",
            ),
        ));
    }
    for sub in ["cases", "truth", "reports"] {
        let dir = out.join(sub);
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(io(&dir))?;
        }
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    std::fs::write(
        out.join(MARKER),
        "a zoo run: cases/, truth/ and reports/ are replaced by the next run\n",
    )
    .map_err(io(out))
}

/// Generates, fits, scores and writes the table.
pub fn run(o: &Options) -> Result<Results, Error> {
    prepare(&o.out)?;
    let start = Instant::now();
    let truths = generate(o)?;
    let generate_s = start.elapsed().as_secs_f64();
    let (plain_rows, plain) = fleet(o, false)?;
    let (diag_rows, diagnose) = fleet(o, true)?;
    let outcomes = score_all(o, &truths, &[plain_rows, diag_rows])?;
    let results = Results {
        table: table::by_class(&outcomes),
        floors: floors::floors(&outcomes),
        outcomes,
        generate_s,
        plain,
        diagnose,
        fracid_command: format!(
            "{} {}",
            o.fracid.display(),
            fleet_args(
                &o.out.join("cases"),
                &o.out.join("reports/plain"),
                o.jobs,
                false
            )
            .join(" ")
        ),
    };
    write_results(&o.out, &results)?;
    Ok(results)
}

/// Scores an earlier run again (its cases, truth, reports and fleet summaries as they are on disk):
/// for a change of the scoreboard alone.
pub fn rescore(o: &Options) -> Result<Results, Error> {
    let mut truths = Vec::new();
    let truth_dir = o.out.join("truth");
    let entries = std::fs::read_dir(&truth_dir).map_err(io(&truth_dir))?;
    for entry in entries {
        let path = entry.map_err(io(&truth_dir))?.path();
        if path.to_string_lossy().ends_with(".truth.json") {
            truths.push(write::read_truth(&path)?);
        }
    }
    truths.sort_by_key(|t| t.index);
    let rows = |p: score::Path| -> Result<HashMap<String, Row>, Error> {
        let file = o
            .out
            .join("reports")
            .join(p.name())
            .join("time-summary.json");
        let text = std::fs::read_to_string(&file).map_err(io(&file))?;
        let v: Value = serde_json::from_str(&text)
            .map_err(|e| Error::Io(file.display().to_string(), e.into()))?;
        Ok(summary_rows(&v))
    };
    let outcomes = score_all(
        o,
        &truths,
        &[rows(score::Path::Plain)?, rows(score::Path::Diagnose)?],
    )?;
    let earlier: Option<Results> = std::fs::read_to_string(o.out.join("table.json"))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    let results = Results {
        table: table::by_class(&outcomes),
        floors: floors::floors(&outcomes),
        outcomes,
        generate_s: earlier.as_ref().map_or(0.0, |r| r.generate_s),
        plain: earlier
            .as_ref()
            .map(|r| r.plain.clone())
            .unwrap_or_default(),
        diagnose: earlier
            .as_ref()
            .map(|r| r.diagnose.clone())
            .unwrap_or_default(),
        fracid_command: earlier.map(|r| r.fracid_command).unwrap_or_default(),
    };
    write_results(&o.out, &results)?;
    Ok(results)
}

/// Writes the table and the per-case scores.
pub fn write_results(out: &Path, r: &Results) -> Result<(), Error> {
    let put = |name: &str, text: String| {
        let p = out.join(name);
        std::fs::write(&p, text).map_err(io(&p))
    };
    put(
        "table.md",
        format!("{}\n{}", table::markdown(&r.table), r.floors.markdown()),
    )?;
    put("table.csv", table::csv(&r.table))?;
    put("cases.csv", table::cases_csv(&r.outcomes))?;
    let json = serde_json::to_string_pretty(r)
        .map_err(|e| Error::Io(out.display().to_string(), e.into()))?;
    put("table.json", json)
}

/// The fracid binary to use: `ZOO_FRACID` if set, else the workspace's newest of
/// `target/release/fracid` and `target/debug/fracid` (`CARGO_TARGET_DIR` honoured).
pub fn default_fracid() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("ZOO_FRACID") {
        return Some(PathBuf::from(p));
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target"));
    let exe = format!("fracid{}", std::env::consts::EXE_SUFFIX);
    ["release", "debug"]
        .iter()
        .map(|p| target.join(p).join(&exe))
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max_by_key(|(m, _)| *m)
        .map(|(_, p)| p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_rows_by_stem_and_a_foreign_directory_refused() {
        let v: Value = serde_json::from_str(
            r#"{"rows": [{"file": "z/cases/0001_integer.csv", "exit_code": 1, "seconds": 0.5, "error": "bad"},
                          {"file": "z/cases/0002_lead.csv", "exit_code": 0, "seconds": null, "error": null}]}"#,
        )
        .unwrap();
        let rows = summary_rows(&v);
        assert_eq!(rows["0001_integer"].exit_code, 1);
        assert_eq!(rows["0001_integer"].error.as_deref(), Some("bad"));
        assert_eq!(
            (rows["0002_lead"].exit_code, rows["0002_lead"].seconds),
            (0, None)
        );

        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("mine.csv"), "t,u,y\n").unwrap();
        assert!(prepare(dir.path()).is_err());
        assert!(dir.path().join("mine.csv").exists());
        let fresh = dir.path().join("run");
        prepare(&fresh).unwrap();
        std::fs::create_dir_all(fresh.join("cases")).unwrap();
        std::fs::write(fresh.join("cases/old.csv"), "").unwrap();
        prepare(&fresh).unwrap();
        assert!(!fresh.join("cases").exists());
    }
}
