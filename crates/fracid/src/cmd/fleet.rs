//! Fleets: `fracid time` and `fracid freq` on many files at once (end-of-line testing of a
//! production line), one fit per core.
//!
//! The files are given as `FILE...` (the shell expands globs), as a directory (every `*.csv` in
//! it, sorted by name), or as a quoted pattern whose file-name part holds `*` or `?` (matched in
//! its directory). Each file is fitted on its own: `fracid time` in a pool of threads in this
//! process (`std::thread::scope`, one worker per core, `--jobs` to choose); `fracid freq` runs the
//! single-file command for each file in child processes, the same pool size, so each report is
//! exactly what `fracid freq FILE --json` gives. Each report is written beside its file as
//! `STEM.time.json` / `STEM.freq.json` (or into `--out DIR`), and one summary table,
//! `time-summary.csv` and `.json` (`freq-summary.*`), into `--out DIR` or the current directory:
//! file, status, exit code, model, fit, effects kept, warnings, error, report.
//!
//! One failing file does not stop the others (a panic is caught and reported as that file's
//! error); the command exits non-zero when any file failed, and names them on stderr: with the
//! failures' exit code when they all share it (2 bad input, 3 I/O), else 1.

use crate::cmd::BadInput;
use anyhow::{Context, Result};
use serde::Serialize;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// The fleet options of `fracid time` and `fracid freq`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct FleetArgs {
    /// More files: fit every one (fleet mode, one per core), write a report per file and a
    /// summary table. FILE may also be a directory (its *.csv) or a quoted glob ("runs/*.csv").
    #[arg(value_name = "MORE")]
    pub more: Vec<PathBuf>,
    /// Fleet mode: write the per-file reports and the summary here (created if missing)
    /// instead of beside each file and the current directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Fleet mode: fits at once (default: one per core).
    #[arg(long)]
    pub jobs: Option<usize>,
}

impl FleetArgs {
    /// Whether `file` (the first positional) and these options ask for the fleet mode: more than
    /// one file, a directory, a glob, or `--out`.
    pub fn active(&self, file: &Path) -> bool {
        !self.more.is_empty() || self.out.is_some() || file.is_dir() || is_glob(file)
    }
}

fn is_glob(p: &Path) -> bool {
    !p.exists()
        && p.file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.contains(['*', '?']))
}

/// `*` any run of characters, `?` one character (no classes, no `**`).
fn glob_match(pat: &[char], name: &[char]) -> bool {
    match (pat.first(), name.first()) {
        (None, None) => true,
        (Some('*'), _) => {
            glob_match(&pat[1..], name) || (!name.is_empty() && glob_match(pat, &name[1..]))
        }
        (Some('?'), Some(_)) => glob_match(&pat[1..], &name[1..]),
        (Some(a), Some(b)) if a == b => glob_match(&pat[1..], &name[1..]),
        _ => false,
    }
}

/// The files: directories expanded to their `*.csv`, globs to their matches (sorted), others kept
/// as given (a missing file fails on its own, in the summary).
///
/// # Errors
/// An unreadable directory (exit 3); a glob or directory that matches nothing (exit 2).
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        let (dir, pat): (PathBuf, Vec<char>) = if p.is_dir() {
            (p.clone(), "*.csv".chars().collect())
        } else if is_glob(p) {
            let dir = match p.parent() {
                Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                _ => PathBuf::from("."),
            };
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            (dir, name.chars().collect())
        } else {
            out.push(p.clone());
            continue;
        };
        let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
            .with_context(|| format!("cannot read directory {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            // every entry but a folder: a dangling link, a link loop or a FIFO fails in the
            // summary with its reason ([`not_a_record`]), not silently left out
            .filter(|f| !f.is_dir())
            .filter(|f| {
                let n: Vec<char> = f
                    .file_name()
                    .map(|n| n.to_string_lossy().chars().collect())
                    .unwrap_or_default();
                glob_match(&pat, &n)
            })
            .collect();
        if found.is_empty() {
            crate::bad_input!("{} matches no file", p.display());
        }
        found.sort();
        out.extend(found);
    }
    Ok(out)
}

/// One row of the summary table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// The record.
    pub file: String,
    /// `ok` or `failed`.
    pub status: &'static str,
    /// The exit code `fracid time FILE` / `fracid freq FILE` would give.
    pub exit_code: u8,
    /// The identified model (`fracid freq`: the best one).
    pub model: Option<String>,
    /// `time`: NRMSE fit in percent on the estimation part.
    pub fit_estimation_percent: Option<f64>,
    /// `time`: NRMSE fit in percent on the held-out validation part.
    pub fit_validation_percent: Option<f64>,
    /// `freq`: the error index J of the best model.
    #[serde(rename = "J")]
    pub j: Option<f64>,
    /// Effects the diagnosis kept (with `--diagnose`).
    pub effects: Vec<String>,
    /// Warnings of the fit.
    pub warnings: Vec<String>,
    /// Why the file failed.
    pub error: Option<String>,
    /// The per-file report.
    pub report: Option<String>,
    /// Wall time of this file's fit in seconds.
    pub seconds: f64,
}

impl Row {
    fn new(file: &Path) -> Self {
        Self {
            file: file.display().to_string(),
            status: "ok",
            exit_code: 0,
            model: None,
            fit_estimation_percent: None,
            fit_validation_percent: None,
            j: None,
            effects: vec![],
            warnings: vec![],
            error: None,
            report: None,
            seconds: 0.0,
        }
    }

    /// The summary fields of a report (`fracid time --json` or `fracid freq --json`).
    fn fill_from(&mut self, v: &Value) {
        // The report's answer, by the library's one rule (`ident::app::answer`): a `time`
        // report's leading model, a `freq` report's diagnosed or best model.
        let answer = ident::app::answer::of_report(v);
        self.model = model_text(answer.model);
        let f = |p: &str| v.pointer(p).and_then(Value::as_f64);
        self.fit_estimation_percent = f("/fit/estimation/nrmse_percent");
        self.fit_validation_percent = f("/fit/validation/nrmse_percent");
        self.j = f("/best_J").or_else(|| f("/J"));
        // With the diagnosis the report leads with the final model: its fit is the one above.
        if let Some(d) = v.get("diagnosis") {
            self.effects = d
                .get("effects")
                .and_then(Value::as_array)
                .map(|a| {
                    a.iter()
                        .filter_map(|e| e.get("name").and_then(Value::as_str))
                        .map(String::from)
                        .collect()
                })
                .unwrap_or_default();
        }
        self.warnings = v
            .get("warnings")
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .map(|w| w.as_str().map_or_else(|| w.to_string(), String::from))
                    .collect()
            })
            .unwrap_or_default();
    }
}

/// The text of a model object `{"num", "den", "delay"}` (or its "text").
fn model_text(m: &Value) -> Option<String> {
    if let Some(t) = m.get("text").and_then(Value::as_str) {
        return Some(t.to_string());
    }
    let terms = |k: &str| -> Option<Vec<fracsim::Term>> {
        m.get(k)?
            .as_array()?
            .iter()
            .map(|t| {
                Some(fracsim::Term {
                    coef: t.get("coef")?.as_f64()?,
                    order: t.get("order")?.as_f64()?,
                })
            })
            .collect()
    };
    let delay = m.get("delay").and_then(Value::as_f64).unwrap_or(0.0);
    fracsim::FracTf::new(terms("num")?, terms("den")?, delay)
        .ok()
        .map(|g| g.to_string())
}

/// Where the report of `file` goes: beside it, or into `out` (a name made unique by a suffix
/// among those `taken` before it).
fn report_path(file: &Path, out: Option<&Path>, kind: &str, taken: &mut Vec<PathBuf>) -> PathBuf {
    let stem = file
        .file_stem()
        .map_or_else(|| "record".into(), |s| s.to_string_lossy().into_owned());
    let dir = match out {
        Some(d) => d.to_path_buf(),
        None => file.parent().map(Path::to_path_buf).unwrap_or_default(),
    };
    let mut p = dir.join(format!("{stem}.{kind}.json"));
    let mut i = 2;
    while taken.contains(&p) {
        p = dir.join(format!("{stem}-{i}.{kind}.json"));
        i += 1;
    }
    taken.push(p.clone());
    p
}

fn panic_text(e: &(dyn std::any::Any + Send)) -> String {
    e.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| e.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Fit every file with `fit` (the report as JSON and the problems that make its model unusable)
/// on `jobs` threads, write the reports and the summary, print one line per file; an error when
/// any file failed. A file whose model is not usable is written and failed (exit 1), as the
/// single-file command does.
///
/// # Errors
/// The summary or output directory cannot be written (exit 3); any file failed (its exit code
/// when all failures share one, else 1).
pub fn run<F>(kind: &str, files: &[PathBuf], fa: &FleetArgs, json_out: bool, fit: F) -> Result<()>
where
    F: Fn(&Path) -> Result<(Value, Vec<String>)> + Sync,
{
    if let Some(d) = &fa.out {
        std::fs::create_dir_all(d)
            .with_context(|| format!("cannot create the output directory {}", d.display()))?;
    }
    let dir = fa.out.clone().unwrap_or_else(|| PathBuf::from("."));
    let (csv_path, json_path) = (
        dir.join(format!("{kind}-summary.csv")),
        dir.join(format!("{kind}-summary.json")),
    );
    let files = &not_the_summary(files, &csv_path)?;
    if files.is_empty() {
        crate::bad_input!(
            "no file to fit: the only one given is this command's own summary {}",
            csv_path.display()
        );
    }
    // Every report's name decided before any fit (in the files' order), and no report nor
    // summary written over a record.
    let mut taken = Vec::new();
    let reports: Vec<PathBuf> = files
        .iter()
        .map(|f| report_path(f, fa.out.as_deref(), kind, &mut taken))
        .collect();
    let inputs: Vec<_> = files.iter().map(|f| ("the record", f.as_path())).collect();
    let mut outputs = vec![
        ("the summary", csv_path.as_path()),
        ("the summary", json_path.as_path()),
    ];
    outputs.extend(reports.iter().map(|r| ("the report", r.as_path())));
    super::paths::check(&inputs, &outputs)?;
    let jobs = match fa.jobs {
        Some(0) => crate::bad_input!("--jobs must be at least 1"),
        Some(j) => j,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    }
    .min(files.len().max(1));
    let t0 = Instant::now();
    // A standard output that cannot be written (a full disk, /dev/full) must not stop the fits
    // nor the summary files: the first error is kept and reported at the end (exit 3).
    let stdout_error: Mutex<Option<std::io::Error>> = Mutex::new(None);
    let rows = on_pool(files.len(), jobs, |i| {
        let row = fit_one(&files[i], &reports[i], &fit);
        if !json_out {
            print_row(&row, &stdout_error);
        }
        row
    });
    let wall = t0.elapsed().as_secs_f64();
    let failed: Vec<&Row> = rows.iter().filter(|r| r.status != "ok").collect();
    let summary = json!({
        "command": kind,
        "files": rows.len(),
        "failed": failed.len(),
        "jobs": jobs,
        "seconds": wall,
        "rows": rows,
    });
    write_csv(&csv_path, &rows)?;
    std::fs::write(&json_path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    if json_out {
        out_line(&serde_json::to_string_pretty(&summary)?, &stdout_error);
    } else {
        out_line(
            &format!(
                "{} files, {} failed, {jobs} at once, {wall:.2} s; summary: {}, {}",
                rows.len(),
                failed.len(),
                csv_path.display(),
                json_path.display()
            ),
            &stdout_error,
        );
    }
    let stdout_error = stdout_error.into_inner().unwrap_or_else(|e| e.into_inner());
    if let Some(e) = stdout_error {
        return Err(anyhow::Error::new(e).context(format!(
            "cannot write to standard output (the reports and the summary {} are written)",
            csv_path.display()
        )));
    }
    if failed.is_empty() {
        return Ok(());
    }
    Err(fleet_error(&failed, rows.len()))
}

/// `one(i)` for every `i < n` on `jobs` threads, each taking the next index; the results in index
/// order.
fn on_pool<T: Send>(n: usize, jobs: usize, one: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(usize, T)>> = Mutex::new(Vec::with_capacity(n));
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= n {
                    break;
                }
                let r = one(i);
                done.lock().unwrap_or_else(|e| e.into_inner()).push((i, r));
            });
        }
    });
    let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// One file fitted by `fit` (a panic caught as an internal error), its report written to
/// `report`, and its summary row: failed with the exit code `fracid` would give when the file is
/// not a record ([`not_a_record`]), the fit fails or reports problems.
fn fit_one<F>(file: &Path, report: &Path, fit: &F) -> Row
where
    F: Fn(&Path) -> Result<(Value, Vec<String>)>,
{
    let mut row = Row::new(file);
    let t = Instant::now();
    let res = match not_a_record(file) {
        Some(e) => Err(e),
        None => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| fit(file)))
            .unwrap_or_else(|e| Err(anyhow::anyhow!("internal error: {}", panic_text(&*e)))),
    };
    let res = res.and_then(|(v, problems)| {
        let p = report.to_path_buf();
        std::fs::write(&p, serde_json::to_string_pretty(&v)? + "\n")
            .with_context(|| format!("cannot write {}", p.display()))?;
        Ok((v, p, problems))
    });
    row.seconds = t.elapsed().as_secs_f64();
    match res {
        Ok((v, p, problems)) => {
            row.fill_from(&v);
            row.report = Some(p.display().to_string());
            if !problems.is_empty() {
                row.status = "failed";
                row.exit_code = 1;
                row.error = Some(unusable_message(&problems));
            }
        }
        Err(e) => {
            row.status = "failed";
            row.exit_code = crate::exit_code(&e);
            row.error = Some(format!("{e:#}"));
        }
    }
    row
}

/// Why `file` is no record a fleet reads, if it is not one: a dangling symbolic link or a link
/// loop (I/O, exit 3, as reading it alone fails), a FIFO, a socket or a device (bad input, exit
/// 2: a FIFO would hold the fleet until something writes to it). Said in the summary, never
/// skipped.
fn not_a_record(file: &Path) -> Option<anyhow::Error> {
    // the summary's row names the file: the reason only
    let io = |reason: String| Some(anyhow::Error::new(std::io::Error::other(reason)));
    let m = match std::fs::metadata(file) {
        Ok(m) => m,
        Err(e) if std::fs::symlink_metadata(file).is_ok_and(|l| l.is_symlink()) => {
            let target = std::fs::read_link(file).unwrap_or_default();
            return if e.kind() == std::io::ErrorKind::NotFound {
                io(format!(
                    "a dangling symbolic link (its target {} does not exist)",
                    target.display()
                ))
            } else {
                io(format!(
                    "a symbolic link that cannot be followed (to {}): {} (a link loop?)",
                    target.display(),
                    e.to_string()
                        .split(" (os error")
                        .next()
                        .unwrap_or_default()
                        .to_lowercase()
                ))
            };
        }
        Err(_) => return None, // a missing file fails on its own, as the reader says it
    };
    if m.is_file() {
        return None;
    }
    let kind = {
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt;
            let t = m.file_type();
            if t.is_fifo() {
                "a FIFO (named pipe)"
            } else if t.is_socket() {
                "a socket"
            } else if t.is_char_device() || t.is_block_device() {
                "a device"
            } else {
                "not a regular file"
            }
        }
        #[cfg(not(unix))]
        {
            "not a regular file"
        }
    };
    Some(anyhow::Error::new(BadInput(format!(
        "{kind}, not a regular file: a fleet reads files only (give it alone to read it)"
    ))))
}

/// The failed files on standard error, and the fleet's error: bad input (exit 2) or I/O (exit 3)
/// when every failure is one, else a run-time failure (exit 1).
fn fleet_error(failed: &[&Row], total: usize) -> anyhow::Error {
    for r in failed {
        eprintln!(
            "failed (exit {}): {}: {}",
            r.exit_code,
            r.file,
            r.error.as_deref().unwrap_or("")
        );
    }
    let names: Vec<&str> = failed.iter().map(|r| r.file.as_str()).collect();
    let msg = format!(
        "{} of {} files failed: {}",
        failed.len(),
        total,
        names.join(", ")
    );
    let code = failed[0].exit_code;
    if failed.iter().all(|r| r.exit_code == code) && code == 2 {
        anyhow::Error::new(BadInput(msg))
    } else if failed.iter().all(|r| r.exit_code == code) && code == 3 {
        anyhow::Error::new(std::io::Error::other(msg))
    } else {
        anyhow::anyhow!(msg)
    }
}

/// The error of a model that is not usable, worded as `fracid time FILE` words it.
pub(crate) fn unusable_message(problems: &[String]) -> String {
    format!("the fitted model is not usable: {}", problems.join("; "))
}

/// One line to standard output; the first write error is kept in `error`, later lines dropped.
fn out_line(line: &str, error: &Mutex<Option<std::io::Error>>) {
    use std::io::Write;
    let mut e = error.lock().unwrap_or_else(|e| e.into_inner());
    if e.is_none() {
        let mut out = std::io::stdout().lock();
        if let Err(err) = writeln!(out, "{line}").and_then(|()| out.flush()) {
            *e = Some(err);
        }
    }
}

/// The files without this command's own summary table (`--out`'s `time-summary.csv`, read back
/// by a second run of a directory into itself). A file of that name that is not a fracid summary
/// is refused: the summary would overwrite it (exit 2).
fn not_the_summary(files: &[PathBuf], summary: &Path) -> Result<Vec<PathBuf>> {
    let Ok(target) = std::fs::canonicalize(summary) else {
        return Ok(files.to_vec()); // no summary yet: nothing to skip, nothing overwritten
    };
    let ours = std::fs::File::open(summary).is_ok_and(|f| {
        let mut first = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(std::io::Read::take(f, 4096)),
            &mut first,
        )
        .is_ok()
            && first.starts_with("file,status,exit_code,")
    });
    if !ours {
        crate::bad_input!(
            "{} exists and is not a fracid summary: the summary would overwrite it (move it, \
             or choose another --out)",
            summary.display()
        );
    }
    Ok(files
        .iter()
        .filter(|f| std::fs::canonicalize(f).map_or(true, |f| f != target))
        .cloned()
        .collect())
}

fn print_row(r: &Row, error: &Mutex<Option<std::io::Error>>) {
    let fit = match (r.fit_validation_percent, r.j) {
        (Some(f), _) => format!("fit {f:.2}%"),
        (None, Some(j)) => format!("J {j:.3e}"),
        _ => String::new(),
    };
    match &r.error {
        None => out_line(
            &format!(
                "ok      {}: {} {fit}{}",
                r.file,
                r.model.as_deref().unwrap_or("?"),
                if r.effects.is_empty() {
                    String::new()
                } else {
                    format!(" + {}", r.effects.join(", "))
                }
            ),
            error,
        ),
        Some(e) => out_line(&format!("failed  {}: {e}", r.file), error),
    }
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let io = |e: csv::Error| -> anyhow::Error {
        match e.into_kind() {
            csv::ErrorKind::Io(e) => anyhow::Error::new(e),
            k => anyhow::anyhow!("{k:?}"),
        }
    };
    let mut w = csv::Writer::from_path(path)
        .map_err(io)
        .with_context(|| format!("cannot write {}", path.display()))?;
    w.write_record([
        "file",
        "status",
        "exit_code",
        "model",
        "fit_estimation_percent",
        "fit_validation_percent",
        "J",
        "effects",
        "warnings",
        "error",
        "report",
        "seconds",
    ])
    .map_err(io)?;
    let num = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
    for r in rows {
        w.write_record([
            r.file.clone(),
            r.status.to_string(),
            r.exit_code.to_string(),
            r.model.clone().unwrap_or_default(),
            num(r.fit_estimation_percent),
            num(r.fit_validation_percent),
            num(r.j),
            r.effects.join(";"),
            r.warnings.join(" | "),
            r.error.clone().unwrap_or_default(),
            r.report.clone().unwrap_or_default(),
            format!("{:.4}", r.seconds),
        ])
        .map_err(io)?;
    }
    w.flush()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs_match_names() {
        let m = |p: &str, n: &str| {
            glob_match(
                &p.chars().collect::<Vec<_>>(),
                &n.chars().collect::<Vec<_>>(),
            )
        };
        assert!(m("*.csv", "a.csv"));
        assert!(m("rec_??.csv", "rec_01.csv"));
        assert!(!m("rec_??.csv", "rec_1.csv"));
        assert!(!m("*.csv", "a.csv.json"));
        assert!(m("*", ""));
    }

    #[test]
    fn summary_fields_come_from_a_time_report() {
        let v = json!({
            "model": {"num": [{"coef": 2.0, "order": 0.0}], "den": [{"coef": 0.1, "order": 0.9}, {"coef": 1.0, "order": 0.0}], "delay": 0.0},
            "fit": {"estimation": {"nrmse_percent": 97.0}, "validation": {"nrmse_percent": 98.5}},
            "warnings": ["w1"],
            "base": {"fit": {"validation": {"nrmse_percent": 96.0}}},
            "diagnosis": {"after": {"nrmse_percent": 98.4}, "effects": [{"name": "delay"}, {"name": "offset"}]}
        });
        let mut r = Row::new(Path::new("x.csv"));
        r.fill_from(&v);
        assert_eq!(r.model.as_deref(), Some("2/(0.1 s^0.9 + 1)"));
        assert_eq!(r.fit_estimation_percent, Some(97.0));
        // the report leads with the final model: its fit (not the base's, nor the diagnosis's
        // own refit figure before the record's parameters are polished)
        assert_eq!(r.fit_validation_percent, Some(98.5));
        assert_eq!(r.effects, ["delay", "offset"]);
        assert_eq!(r.warnings, ["w1"]);
    }
}
