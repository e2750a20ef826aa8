//! The table by class: per class and path, counts and medians of the case scores; written as
//! markdown, CSV and JSON.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::{Outcome, Path, FRF_OK};
use crate::cases::{Class, ALL_CLASSES};

/// One class on one path.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PathStats {
    /// Cases.
    pub cases: usize,
    /// Exit 0.
    pub exit0: usize,
    /// Right answers (`score` module).
    pub right: usize,
    /// Identifiable cases that exit 0 with an FRF error <= FRF_OK.
    pub frf_ok: usize,
    /// The median FRF error over the identifiable cases that exit 0.
    pub frf_median: Option<f64>,
    /// Kept effects exactly the expected ones.
    pub effects_exact: usize,
    /// Spurious effects, summed.
    pub spurious: usize,
    /// Missed effects, summed.
    pub missed: usize,
    /// The median held-out / oracle RMSE ratio.
    pub heldout_ratio_median: Option<f64>,
    /// The median fit time [s].
    pub seconds_median: Option<f64>,
    /// The summed fit time [s].
    pub seconds_total: f64,
}

impl PathStats {
    /// The fraction of right answers.
    pub fn right_rate(&self) -> f64 {
        ratio(self.right, self.cases)
    }
    /// The fraction with the effects exact.
    pub fn effects_rate(&self) -> f64 {
        ratio(self.effects_exact, self.cases)
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// One class (or "all").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassRow {
    /// The class's name, or "all".
    pub class: String,
    /// Cases.
    pub cases: usize,
    /// Identifiable cases.
    pub identifiable: usize,
    /// The plain path.
    pub plain: PathStats,
    /// The diagnosed path.
    pub diagnose: PathStats,
}

/// The median of the finite values (None when there are none).
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

fn stats(outcomes: &[&Outcome]) -> PathStats {
    // The model a user gets: identifiable cases that exit 0.
    let frf: Vec<f64> = outcomes
        .iter()
        .filter(|o| o.identifiable && o.exit_code == Some(0))
        .filter_map(|o| o.frf_error)
        .collect();
    PathStats {
        cases: outcomes.len(),
        exit0: outcomes.iter().filter(|o| o.exit_code == Some(0)).count(),
        right: outcomes.iter().filter(|o| o.right).count(),
        frf_ok: frf.iter().filter(|e| **e <= FRF_OK).count(),
        frf_median: median(frf),
        effects_exact: outcomes.iter().filter(|o| o.effects_exact()).count(),
        spurious: outcomes.iter().map(|o| o.spurious.len()).sum(),
        missed: outcomes.iter().map(|o| o.missed.len()).sum(),
        heldout_ratio_median: median(outcomes.iter().filter_map(|o| o.heldout_ratio()).collect()),
        seconds_median: median(outcomes.iter().filter_map(|o| o.seconds).collect()),
        seconds_total: outcomes.iter().filter_map(|o| o.seconds).sum(),
    }
}

fn row(label: &str, outcomes: &[Outcome], keep: impl Fn(&Outcome) -> bool) -> Option<ClassRow> {
    let of =
        |p: Path| -> Vec<&Outcome> { outcomes.iter().filter(|o| o.path == p && keep(o)).collect() };
    let plain = of(Path::Plain);
    let diagnose = of(Path::Diagnose);
    let cases = plain.len().max(diagnose.len());
    if cases == 0 {
        return None;
    }
    let base = if plain.len() >= diagnose.len() {
        &plain
    } else {
        &diagnose
    };
    Some(ClassRow {
        class: label.into(),
        cases,
        identifiable: base.iter().filter(|o| o.identifiable).count(),
        plain: stats(&plain),
        diagnose: stats(&diagnose),
    })
}

/// The table: a row per class present, then "all".
pub fn by_class(outcomes: &[Outcome]) -> Vec<ClassRow> {
    let mut rows: Vec<ClassRow> = ALL_CLASSES
        .iter()
        .filter_map(|c| row(c.name(), outcomes, |o| o.class == *c))
        .collect();
    rows.extend(row("all", outcomes, |_| true));
    rows
}

/// The row of `class` (None when absent).
pub fn find(rows: &[ClassRow], class: Class) -> Option<&ClassRow> {
    rows.iter().find(|r| r.class == class.name())
}

fn pct(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{:.1}%", 100.0 * v))
}

fn num(x: Option<f64>, digits: usize) -> String {
    x.map_or("-".into(), |v| format!("{v:.digits$}"))
}

fn ms(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{:.0}", 1e3 * v))
}

/// The table in markdown: each cell "plain / diagnose".
pub fn markdown(rows: &[ClassRow]) -> String {
    let mut s = String::new();
    s.push_str("| class | cases | identifiable | exit 0 | right | FRF err median | FRF <= 20% | effects exact | spurious | missed | held-out / oracle | ms median |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let (p, d) = (&r.plain, &r.diagnose);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} |",
            r.class,
            r.cases,
            r.identifiable,
            p.exit0,
            d.exit0,
            p.right,
            d.right,
            pct(p.frf_median),
            pct(d.frf_median),
            p.frf_ok,
            d.frf_ok,
            p.effects_exact,
            d.effects_exact,
            p.spurious,
            d.spurious,
            p.missed,
            d.missed,
            num(p.heldout_ratio_median, 2),
            num(d.heldout_ratio_median, 2),
            ms(p.seconds_median),
            ms(d.seconds_median),
        );
    }
    s
}

/// The table as CSV: one line per class and path.
pub fn csv(rows: &[ClassRow]) -> String {
    let mut s = String::from(
        "class,path,cases,identifiable,exit0,right,frf_ok,frf_median,effects_exact,spurious,missed,heldout_ratio_median,seconds_median,seconds_total\n",
    );
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:e}"));
    for r in rows {
        for (path, p) in [("plain", &r.plain), ("diagnose", &r.diagnose)] {
            let _ = writeln!(
                s,
                "{},{path},{},{},{},{},{},{},{},{},{},{},{},{:e}",
                r.class,
                p.cases,
                r.identifiable,
                p.exit0,
                p.right,
                p.frf_ok,
                opt(p.frf_median),
                p.effects_exact,
                p.spurious,
                p.missed,
                opt(p.heldout_ratio_median),
                opt(p.seconds_median),
                p.seconds_total
            );
        }
    }
    s
}

/// The per-case scores as CSV.
pub fn cases_csv(outcomes: &[Outcome]) -> String {
    let mut s = String::from(
        "name,class,path,identifiable,exit_code,right,frf_error,heldout_rmse,oracle_rmse,seconds,kept,spurious,missed,named_ambiguous,model\n",
    );
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:e}"));
    for o in outcomes {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},\"{}\"",
            o.name,
            o.class.name(),
            o.path.name(),
            o.identifiable,
            o.exit_code.map_or(String::new(), |c| c.to_string()),
            o.right,
            opt(o.frf_error),
            opt(o.heldout_rmse),
            opt(o.oracle_rmse),
            opt(o.seconds),
            o.kept.join(" "),
            o.spurious.join(" "),
            o.missed.join(" "),
            o.named_ambiguous.join(" "),
            o.model.as_deref().unwrap_or("").replace('"', "'"),
        );
    }
    s
}
