//! `fracid freq FILE`: identify a fractional model from Bode data (docs/design.md §4).
//!
//! Reads `freq_hz,gain_db,phase_deg` (other units and names by flags), fits Levy's weighted least
//! squares with an order search ([`ident::levy::fit_bode`]), optionally Sanathanan-Koerner
//! iterations and the nonlinear PMSM refit, prints a side-by-side table (or `--json`), and draws
//! the Bode plot with the `J(q)` curve (`--plot`).

use crate::bad_input;
use crate::plot::{self, Figure};
use anyhow::{Context, Result};
use fracsim::FracTf;
use ident::app::freq::{FreqData, FreqReport, FreqRequest};
use ident::levy::{FreqFit, FreqOptions, OrderChoice, QPoint};
use num_complex::Complex64;
use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::Value;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// Options of `fracid freq`.
#[derive(Debug, clap::Args)]
pub struct FreqArgs {
    /// Bode data: CSV with a header, columns `freq_hz,gain_db,phase_deg` by default; `,` `;` or
    /// tab separated; `#` starts a comment; or a MATLAB v5/v7 .mat file with variables of those
    /// names. A table without a header needs --columns (by index) and the unit flags.
    pub file: PathBuf,
    /// The frequency column is omega in rad/s (default name `omega_rad_s`), not Hz.
    #[arg(long)]
    pub rad_s: bool,
    /// The gain column is linear (|G|, default name `gain`), not dB.
    #[arg(long)]
    pub linear_gain: bool,
    /// The phase column is in radians (default name `phase_rad`), not degrees.
    #[arg(long)]
    pub radians: bool,
    /// Column names: FREQ,GAIN,PHASE (or 0-based indices, e.g. 0,1,2: needed for a table with no
    /// header line).
    #[arg(long, value_name = "FREQ,GAIN,PHASE")]
    pub columns: Option<String>,
    /// Denominator degree n (in powers of s^q).
    #[arg(long, default_value_t = 2)]
    pub n: usize,
    /// Numerator degree m (in powers of s^q).
    #[arg(long, default_value_t = 0)]
    pub m: usize,
    /// Fix the commensurate order q instead of searching it.
    #[arg(long, conflicts_with_all = ["q_step", "q_max"])]
    pub q: Option<f64>,
    /// Step of the q grid over (0, q-max] (the paper: 0.01).
    #[arg(long, default_value_t = 0.01)]
    pub q_step: f64,
    /// Largest q of the grid.
    #[arg(long, default_value_t = 1.0)]
    pub q_max: f64,
    /// Keep the best grid q (the paper's procedure) instead of refining it by golden section.
    #[arg(long)]
    pub no_q_refine: bool,
    /// Weights: `spread` (the table's spread columns, as `fracid drive sine --repeats` writes:
    /// Levy's weights are Vinagre's divided by each point's relative variance, and the refit
    /// weights by inverse variance, so its standard errors reflect the spread), `vinagre` (the
    /// paper's eq. 29), `none` (uniform), a column name of FILE, or a file with one weight per
    /// line. `auto` (default): `spread` if the table has the spread columns, else `vinagre`.
    #[arg(long, default_value = "auto")]
    pub weights: String,
    /// Refit the PMSM structure K/(a2 s^(zeta+theta) + a1 s^zeta + 1) with two free orders by
    /// Levenberg-Marquardt (needs n = 2, m = 0).
    #[arg(long)]
    pub refine: bool,
    /// Sanathanan-Koerner iterations after Levy, at most (0: none); they stop once no
    /// coefficient changes by more than 1e-8 of its value or J by more than 1e-10 of its value,
    /// and the number used is reported.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub sk: usize,
    /// Also evaluate J for this model (e.g. a published one); repeatable.
    #[arg(long, value_name = "MODEL")]
    pub compare: Vec<String>,
    /// Diagnose the residual of the best model (delay, extra pole; docs/design.md §6) and refit
    /// with what pays.
    #[arg(long)]
    pub diagnose: bool,
    /// The table was measured through a sampled loop with a zero-order hold of this period
    /// (seconds): the hold `(1 - e^(-j w T))/(j w T)` (half a sample of delay, a sinc droop) is
    /// divided out before the fit, so a fitted delay is the plant's. `auto` (default): the period
    /// stated by a `# hold: zero-order, sample period T s` comment (as `fracid drive sine` writes),
    /// else none; `none`: the table is the plant's continuous response.
    #[arg(long, default_value = "auto", value_name = "SECONDS|auto|none")]
    pub hold: String,
    /// Print JSON (docs/design.md §7) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Exit 0 even when the model is not usable (unstable, undetermined parameters, ...): the
    /// problems are then printed as warnings. Without it such a fit prints its result, then
    /// exits 1 with the reasons.
    #[arg(long)]
    pub allow_unusable: bool,
    /// Draw the Bode plot (magnitude, phase) with each model, and J(q), to FILE (.png or .svg).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Fleet mode (many files at once): see `fracid::cmd::fleet`.
    #[command(flatten)]
    pub fleet: super::fleet::FleetArgs,
}

/// Bode data read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct BodeData {
    /// Frequencies in rad/s.
    pub omega_rad_s: Vec<f64>,
    /// The measured response `G(j omega)`.
    pub h: Vec<Complex64>,
    /// Per-point weights from a column, if asked.
    pub weights: Option<Vec<f64>>,
    /// Standard errors (gain dB, phase deg) of each point from the spread columns
    /// `gain_db_std,phase_deg_std,repeats` (as `fracid drive sine --repeats` writes):
    /// `std/sqrt(repeats - 2)` from 3 repeats on (the trimmed mean averages `repeats - 2`),
    /// else `std/sqrt(repeats)`. None when the table has no spread.
    pub spread_se: Option<Vec<(f64, f64)>>,
}

/// Units of the three columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Units {
    /// Frequency in rad/s (else Hz).
    pub rad_s: bool,
    /// Linear gain (else dB).
    pub linear_gain: bool,
    /// Phase in radians (else degrees).
    pub radians: bool,
}

impl From<Units> for ident::bodefile::BodeUnits {
    fn from(u: Units) -> Self {
        Self {
            rad_s: u.rad_s,
            linear_gain: u.linear_gain,
            radians: u.radians,
        }
    }
}

impl From<ident::bodefile::BodeTable> for BodeData {
    fn from(t: ident::bodefile::BodeTable) -> Self {
        Self {
            omega_rad_s: t.omega_rad_s,
            h: t.h,
            weights: t.weights,
            spread_se: t.spread_se,
        }
    }
}

/// Read Bode data from CSV text with the library's reader ([`ident::bodefile::parse`], shared
/// with Python). `columns` names (or, 0-based, indexes) (freq, gain, phase); `weight_column` an
/// extra column of per-point weights. A table with no header needs `columns`.
///
/// # Errors
/// An [`ident::Error::Data`] naming the line: no rows, a headerless table without `columns`, a
/// missing column, a non-numeric or non-finite value, a frequency <= 0, unsorted or repeated
/// frequencies, a negative linear gain.
pub fn parse_bode(
    text: &str,
    columns: Option<[&str; 3]>,
    units: Units,
    weight_column: Option<&str>,
) -> Result<BodeData> {
    Ok(ident::bodefile::parse(text, columns, units.into(), weight_column)?.into())
}

fn read_weight_file(path: &Path) -> Result<Vec<f64>> {
    let text = super::read_text(path)?;
    let mut w = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.split('#').next().unwrap_or("").trim();
        if l.is_empty() {
            continue;
        }
        let mut fields = l.split([',', ';', '\t', ' ']).filter(|f| !f.is_empty());
        let field = fields.next().unwrap_or("");
        if fields.next().is_some() {
            // A table (the data file itself, say): its first column is not a weight.
            bad_input!(
                "{} line {}: a weights file holds one number per line, this line has more \
                 fields (to weight by a column of the data file, give the column's name)",
                path.display(),
                i + 1
            );
        }
        match field.parse::<f64>() {
            Ok(v) => w.push(v),
            Err(_) if w.is_empty() => continue, // a header line
            Err(_) => bad_input!(
                "{} line {}: weight '{field}' is not a number",
                path.display(),
                i + 1
            ),
        }
    }
    Ok(w)
}

/// Everything `fracid freq FILE` computes, once: the data as read (the hold divided out), the
/// fits, the models compared, the diagnosis, and the assessment. The command, the fleet and the
/// demo present it (text, JSON, plots) without fitting again.
pub(crate) struct FreqOutcome {
    /// The use case's report.
    pub report: FreqReport,
    /// The table as read, its response with the hold divided out (as fitted): for the table's
    /// text and the plot's error bars.
    data: BodeData,
}

impl FreqOutcome {
    /// The report as `fracid freq --json` prints it.
    pub(crate) fn json(&self) -> Result<Value> {
        Ok(serde_json::to_value(&self.report)?)
    }

    /// The report as `fracid freq` prints it.
    pub(crate) fn text(&self) -> String {
        let (r, f) = (&self.report, &self.report.fitted);
        let mut o = String::new();
        if let Some(t) = r.hold_s {
            o += &format!(
                "hold: the zero-order hold of a {t} s sampled loop divided out of the table\n"
            );
        }
        o += &table(&f.fit, &f.compare, &self.data, &r.weights, &f.options);
        if let Some(d) = &f.diagnosis {
            o += &diagnosis_text(d);
        }
        o
    }

    /// Draw the Bode plot to `path`, and with the diagnosis its residual plot beside it (its
    /// path returned).
    pub(crate) fn plot(&self, path: &Path) -> Result<Option<PathBuf>> {
        let f = &self.report.fitted;
        let fig = BodeFigure {
            data: &self.data,
            fit: &f.fit,
            compare: &f.compare,
        };
        plot::save(path, (1400, 900), &fig)?;
        match &f.diagnosis {
            Some(d) => {
                let dp = super::diagnose::residual_plot_path(path);
                super::diagnose::plot_bode(&dp, d)?;
                Ok(Some(dp))
            }
            None => Ok(None),
        }
    }
}

/// Run `fracid freq`.
///
/// # Errors
/// Unreadable files (exit 3), bad data or options (exit 2), a numerical breakdown (exit 1).
pub fn run(a: FreqArgs) -> Result<()> {
    if a.fleet.active(&a.file) {
        return run_fleet(&a);
    }
    check_paths(&a)?;
    if let Some(path) = &a.plot {
        plot::format_of(path)?; // a bad extension fails before the work
    }
    let o = compute(&a, &a.file)?;
    if a.json {
        emit(&(serde_json::to_string_pretty(&o.json()?)? + "\n"))?;
    } else {
        emit(&o.text())?;
    }
    if let Some(path) = &a.plot {
        let residual = o.plot(path)?;
        if !a.json {
            emit(&format!("plot: {}\n", path.display()))?;
            if let Some(dp) = residual {
                emit(&format!("residual plot: {}\n", dp.display()))?;
            }
        }
    }
    for w in &o.report.warnings {
        crate::interrupt::eprint_line(&format!("warning: {w}"));
    }
    if !o.report.problems.is_empty() {
        if a.allow_unusable {
            for p in &o.report.problems {
                crate::interrupt::eprint_line(&format!(
                    "warning: the model is not usable (kept as --allow-unusable asks): {p}"
                ));
            }
        } else {
            anyhow::bail!(
                "the fitted model is not usable: {} (--allow-unusable keeps it with exit 0)",
                o.report.problems.join("; ")
            );
        }
    }
    Ok(())
}

/// `fracid freq` on many files: each fitted in this process exactly as `fracid freq FILE --json`
/// would (the same options, `freq::compute`), on a pool of threads. A model that is not usable
/// is a failed file unless `--allow-unusable` keeps it.
///
/// # Errors
/// As [`super::fleet::run`].
fn run_fleet(a: &FreqArgs) -> Result<()> {
    if a.plot.is_some() {
        crate::bad_input!("--plot draws one record: not with many files");
    }
    let mut paths = vec![a.file.clone()];
    paths.extend(a.fleet.more.iter().cloned());
    let files = super::fleet::expand(&paths)?;
    super::fleet::run("freq", &files, &a.fleet, a.json, |f| {
        let o = compute(a, f)?;
        let mut v = o.json()?;
        v["file"] = serde_json::json!(f.display().to_string());
        let problems = if a.allow_unusable {
            Vec::new()
        } else {
            o.report.problems.clone()
        };
        Ok((v, problems))
    })
}

/// No plot overwrites an input ([`super::paths::check`]): the table and a `--weights` file
/// against `--plot` and, with `--diagnose`, the residual plot beside it.
fn check_paths(a: &FreqArgs) -> Result<()> {
    let mut inputs = vec![("the table", a.file.as_path())];
    inputs.extend(super::paths::file_arg(a.weights.trim()).map(|p| ("--weights", p)));
    super::paths::check_plots(&inputs, a.plot.as_deref(), a.diagnose)
}

static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many times [`compute`] ran in this process (the demo reports that each record was fitted
/// and diagnosed once).
pub(crate) fn runs() -> usize {
    RUNS.load(std::sync::atomic::Ordering::Relaxed)
}

/// The options of `fracid freq` from its words (`["freq", FILE, "--refine", ...]`), with the
/// command's own defaults: for the demo, which runs the command's use case in process.
///
/// # Errors
/// Words the command does not take (exit 2).
pub(crate) fn args_from(argv: &[&str]) -> Result<FreqArgs> {
    #[derive(clap::Parser)]
    struct Words {
        #[command(flatten)]
        args: FreqArgs,
    }
    use clap::Parser as _;
    Words::try_parse_from(argv)
        .map(|w| w.args)
        .map_err(|e| super::BadInput(e.to_string()).into())
}

/// `fracid freq`'s work on `file` with the options of `a` (its `file` is not read).
///
/// # Errors
/// As [`run`].
pub(crate) fn compute(a: &FreqArgs, file: &Path) -> Result<FreqOutcome> {
    RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let is_mat = ident::matfile::is_mat(file);
    let text = if is_mat {
        String::new() // read below by variables
    } else {
        super::read_text(file)?
    };
    let units = Units {
        rad_s: a.rad_s,
        linear_gain: a.linear_gain,
        radians: a.radians,
    };
    let cols: Option<Vec<String>> = a
        .columns
        .as_ref()
        .map(|c| c.split(',').map(|s| s.trim().to_string()).collect());
    let cols3 = match &cols {
        Some(c) if c.len() == 3 && c.iter().all(|s| !s.is_empty()) => {
            Some([c[0].as_str(), c[1].as_str(), c[2].as_str()])
        }
        Some(c) => bad_input!(
            "--columns needs three names FREQ,GAIN,PHASE, got {}",
            c.join(",")
        ),
        None => None,
    };
    // per-point weights from a column of the table or a file of weights: the request's "given"
    let wkey = a.weights.trim().to_string();
    let word = ["auto", "vinagre", "none", "uniform", "1", "spread"]
        .iter()
        .any(|w| wkey.eq_ignore_ascii_case(w));
    let (weight_column, weight_file) = if word {
        (None, None)
    } else if ident::data::header(&text)
        .is_some_and(|h| h.iter().any(|f| f.eq_ignore_ascii_case(&wkey)))
    {
        (Some(wkey.clone()), None)
    } else if Path::new(&wkey).is_file() {
        (None, Some(read_weight_file(Path::new(&wkey))?))
    } else {
        bad_input!(
            "--weights '{wkey}' is neither vinagre, none, a column of {} nor a file",
            file.display()
        )
    };
    let data = if is_mat {
        BodeData::from(ident::bodefile::load(
            file,
            cols3,
            units.into(),
            weight_column.as_deref(),
        )?)
    } else {
        parse_bode(&text, cols3, units, weight_column.as_deref())
            .with_context(|| format!("in {}", file.display()))?
    };
    let hold_hint = if is_mat {
        None
    } else {
        ident::hold::sample_period_from_comments(&text)
            .with_context(|| format!("in {}", file.display()))?
    };
    let given = match (weight_column, weight_file, data.weights.clone()) {
        (Some(c), _, Some(w)) => Some((w, format!("column '{c}'"))),
        (_, Some(w), _) => Some((w, format!("file {wkey}"))),
        _ => None,
    };
    let req = request(a, given.is_some());
    let fd = FreqData {
        omega_rad_s: data.omega_rad_s.clone(),
        h: data.h.clone(),
        weights: given,
        point_std: None,
        spread_se: data.spread_se.clone(),
        hold_hint,
    };
    if req.weights == "spread" && fd.spread_se.is_none() {
        bad_input!(
            "--weights spread: {} has no gain_db_std and phase_deg_std columns",
            file.display()
        );
    }
    let report = ident::app::freq::run(&req, &fd, &mut ident::app::observe::Quiet)
        .with_context(|| format!("identifying {}", file.display()))?;
    let data = BodeData {
        h: report.fitted.h.clone(),
        ..data
    };
    Ok(FreqOutcome { report, data })
}

/// The use-case request of `fracid freq`'s options (`given`: the weights are the data's own, a
/// column or a file).
pub(crate) fn request(a: &FreqArgs, given: bool) -> FreqRequest {
    let weights = if given {
        "given".to_string()
    } else if a.weights.trim() == "1" {
        "none".to_string()
    } else {
        a.weights.trim().to_ascii_lowercase()
    };
    FreqRequest {
        n: a.n,
        m: a.m,
        q: a.q,
        q_step: a.q_step,
        q_max: a.q_max,
        refine_q: !a.no_q_refine,
        weights,
        sk_iterations: a.sk,
        refine: a.refine,
        diagnose: a.diagnose,
        hold: a.hold.clone(),
        compare: a.compare.clone(),
    }
}

/// Write to stdout; a closed pipe (`fracid freq ... | head`) is not an error.
fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

/// `x` to `sig` significant digits, plain or scientific as fits.
fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let e = x.abs().log10().floor() as i32;
    if (-2..5).contains(&e) {
        let dec = (digits as i32 - 1 - e).max(0) as usize;
        format!("{x:.dec$}")
    } else {
        format!("{x:.*e}", digits - 1)
    }
}

/// `x` in scientific notation with `digits` significant digits.
fn sci(x: f64, digits: usize) -> String {
    format!("{x:.*e}", digits.max(1) - 1)
}

/// A model with rounded coefficients, for reading.
fn short_tf(g: &FracTf, digits: usize) -> String {
    let poly = |t: &[fracsim::Term]| -> String {
        t.iter()
            .map(|t| {
                if t.order == 0.0 && t.coef == 1.0 {
                    "1".to_string()
                } else if t.order == 0.0 {
                    sig(t.coef, digits)
                } else {
                    format!("{} s^{}", sig(t.coef, digits), sig(t.order, digits.min(4)))
                }
            })
            .collect::<Vec<_>>()
            .join(" + ")
            .replace("+ -", "- ")
    };
    let num = if g.num.len() > 1 {
        format!("({})", poly(&g.num))
    } else {
        poly(&g.num)
    };
    let delay = if g.delay != 0.0 {
        format!(" exp(-{} s)", sig(g.delay, digits))
    } else {
        String::new()
    };
    format!("{num}/({}){delay}", poly(&g.den))
}

/// A table column: (row name, value) pairs.
type Column = Vec<(String, String)>;

/// The table's columns and their heads: the Levy fit (at the grid q and the refined q when they
/// differ), Sanathanan-Koerner, the refined LM fit with its standard errors.
fn columns(fit: &FreqFit) -> (Vec<String>, Vec<Column>) {
    let mut heads: Vec<String> = Vec::new();
    let mut columns: Vec<Column> = Vec::new();
    let levy_col = |f: &ident::levy::LevyFit| -> Column {
        let mut c = vec![("q (zeta)".to_string(), sig(f.q, 4))];
        for (u, b) in f.b.iter().enumerate() {
            c.push((format!("b{u}"), sig(*b, 5)));
        }
        for (p, a) in f.a.iter().enumerate() {
            c.push((format!("a{}", p + 1), sig(*a, 5)));
        }
        c.push(("J".into(), sci(f.j, 4)));
        c
    };
    if fit.levy_grid.q != fit.levy.q {
        heads.push("Levy, grid q".into());
        columns.push(levy_col(&fit.levy_grid));
        heads.push("Levy, refined q".into());
    } else {
        heads.push("Levy".into());
    }
    columns.push(levy_col(&fit.levy));
    if let Some(sk) = &fit.sk {
        heads.push(format!("SK ({} it.)", sk.sk_iterations));
        columns.push(levy_col(sk));
    }
    if let Some(r) = &fit.refined {
        heads.push("refined (LM)".into());
        let pm = |x: f64, i: usize| match r.std_errors {
            Some(s) => format!("{} ± {}", sig(x, 5), sig(s[i], 2)),
            None => sig(x, 5),
        };
        columns.push(vec![
            ("q (zeta)".into(), pm(r.zeta, 3)),
            ("theta".into(), pm(r.theta, 4)),
            ("b0".into(), pm(r.k, 0)),
            ("a1".into(), pm(r.a1, 1)),
            ("a2".into(), pm(r.a2, 2)),
            ("J".into(), sci(r.j, 4)),
        ]);
    }
    (heads, columns)
}

/// The columns laid out as text: the rows are the orders (theta when `theta`), then b_u, a_p and
/// J; a value a column lacks is "-".
fn grid(heads: &[String], columns: &[Column], theta: bool) -> String {
    use std::fmt::Write;
    let mut rows: Vec<String> = vec!["q (zeta)".into()];
    if theta {
        rows.push("theta".into());
    }
    for c in columns {
        for (k, _) in c {
            if !rows.contains(k) && k != "J" {
                rows.push(k.clone());
            }
        }
    }
    rows.push("J".into());
    let widths: Vec<usize> = columns
        .iter()
        .zip(heads)
        .map(|(c, h)| {
            c.iter()
                .map(|(_, v)| v.chars().count())
                .chain([h.chars().count()])
                .max()
                .unwrap_or(8)
                + 2
        })
        .collect();
    let mut out = String::new();
    let _ = write!(out, "{:<10}", "");
    for (h, w) in heads.iter().zip(&widths) {
        let _ = write!(out, "{h:>w$}");
    }
    out.push('\n');
    for r in &rows {
        let _ = write!(out, "{r:<10}");
        for (c, w) in columns.iter().zip(&widths) {
            let v = c
                .iter()
                .find(|(k, _)| k == r)
                .map_or("-".to_string(), |(_, v)| v.clone());
            let _ = write!(out, "{v:>w$}");
        }
        out.push('\n');
    }
    out.push('\n');
    out
}

fn table(
    fit: &FreqFit,
    compare: &[(FracTf, f64)],
    data: &BodeData,
    weights: &str,
    opts: &FreqOptions,
) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let w0 = data.omega_rad_s[0];
    let w1 = *data.omega_rad_s.last().unwrap_or(&w0);
    let _ = writeln!(
        out,
        "fracid freq: {} points, {} .. {} Hz ({} .. {} rad/s); n = {}, m = {}, weights {}",
        data.omega_rad_s.len(),
        sig(w0 / (2.0 * PI), 4),
        sig(w1 / (2.0 * PI), 4),
        sig(w0, 4),
        sig(w1, 4),
        opts.n,
        opts.m,
        weights
    );
    let _ = writeln!(
        out,
        "J = (1/f) sum |G(jw) - Ghat(jw)|^2, w in rad/s (paper eq. 30)\n"
    );
    let (heads, columns) = columns(fit);
    out.push_str(&grid(&heads, &columns, fit.refined.is_some()));
    if let OrderChoice::Search { step, q_max, .. } = opts.order {
        if fit.levy_grid.q + step > q_max {
            let _ = writeln!(
                out,
                "note: the best grid q is at the end of the grid (q-max = {q_max}); try a larger --q-max\n"
            );
        }
    }
    let _ = writeln!(out, "Levy:     {}", short_tf(&fit.levy.model, 5));
    if let Some(sk) = &fit.sk {
        let _ = writeln!(
            out,
            "SK:       {}   ({} after {} of at most {} iterations)",
            short_tf(&sk.model, 5),
            if sk.sk_converged {
                "converged"
            } else {
                "NOT converged"
            },
            sk.sk_iterations,
            opts.sk_iterations
        );
    }
    if let Some(r) = &fit.refined {
        let _ = writeln!(
            out,
            "refined:  {}   ({}, {} iterations)",
            short_tf(&r.model, 5),
            if r.report.converged {
                "converged"
            } else {
                "NOT converged"
            },
            r.report.iterations
        );
    }
    for (g, j) in compare {
        let _ = writeln!(out, "compare:  {}   J = {}", short_tf(g, 5), sci(*j, 4));
    }
    out
}

fn diagnosis_text(d: &ident::diagnose::freq::BodeDiagnosis) -> String {
    use std::fmt::Write;
    let mut out = String::from("\nresidual diagnosis of the best model (docs/design.md §6):\n");
    let row = |e: &ident::diagnose::freq::BodeError| {
        format!(
            "J = {}, magnitude RMS {} dB, phase RMS {} deg",
            sci(e.j, 4),
            sig(e.mag_rms_db, 3),
            sig(e.phase_rms_deg, 3)
        )
    };
    let _ = writeln!(out, "  before:  {}", row(&d.before));
    if let Some(r) = &d.refit_without_effect {
        let _ = writeln!(out, "  refit without effect: {}", row(r));
    }
    let _ = writeln!(out, "  after:   {}", row(&d.after));
    for e in &d.effects {
        let params: Vec<String> = e
            .params
            .iter()
            .map(|(k, v)| format!("{k} = {}", sig(*v, 4)))
            .collect();
        let _ = writeln!(
            out,
            "  kept {}: {} ({})",
            e.name,
            params.join(", "),
            e.evidence
        );
    }
    for r in &d.rejected {
        let _ = writeln!(out, "  rejected {}: {}", r.name, r.reason);
    }
    if d.effects.is_empty() {
        let _ = writeln!(out, "  no effect kept");
    }
    let _ = writeln!(
        out,
        "  unexplained structure: {}{}",
        if d.unexplained { "yes" } else { "no" },
        if d.remaining.is_empty() {
            String::new()
        } else {
            format!(" ({})", d.remaining.join("; "))
        }
    );
    if !d.effects.is_empty() {
        let _ = writeln!(out, "  final model: {}", short_tf(&d.model, 5));
    }
    out
}

// ------------------------------------------------------------------------------------------------
// The plot

/// A model curve of the Bode plot: (label, color, dashed, magnitude dB, phase deg).
type Curve = (String, RGBColor, bool, Vec<f64>, Vec<f64>);

struct BodeFigure<'a> {
    data: &'a BodeData,
    fit: &'a FreqFit,
    compare: &'a [(FracTf, f64)],
}

/// Unwrap a phase sequence (degrees) so that steps stay below 180.
fn unwrap_deg(ph: &mut [f64]) {
    for i in 1..ph.len() {
        while ph[i] - ph[i - 1] > 180.0 {
            ph[i] -= 360.0;
        }
        while ph[i] - ph[i - 1] < -180.0 {
            ph[i] += 360.0;
        }
    }
}

fn mag_phase(h: &[Complex64]) -> (Vec<f64>, Vec<f64>) {
    let mag = h.iter().map(|g| 20.0 * g.norm().log10()).collect();
    let mut ph: Vec<f64> = h.iter().map(|g| g.arg().to_degrees()).collect();
    unwrap_deg(&mut ph);
    (mag, ph)
}

/// Where the Bode panels draw: the frequency axis (Hz) and the dense grid the models are drawn on.
struct Axis {
    f_lo: f64,
    f_hi: f64,
    dense_hz: Vec<f64>,
}

impl BodeFigure<'_> {
    /// The frequency axis: whole decades around the data, with a little room beyond it.
    fn axis(&self) -> Axis {
        let w = &self.data.omega_rad_s;
        let f_lo = w[0] / (2.0 * PI) / 1.5;
        let f_hi = (w[w.len() - 1] / (2.0 * PI) * 1.5).max(f_lo * 10.0);
        let dense_hz = (0..=400)
            .map(|i| f_lo * (f_hi / f_lo).powf(i as f64 / 400.0))
            .collect();
        Axis {
            f_lo,
            f_hi,
            dense_hz,
        }
    }

    /// The models' curves on the dense grid: Levy, Sanathanan-Koerner, the refined fit, then the
    /// compared models (dashed).
    fn curves(&self, dense_hz: &[f64]) -> Vec<Curve> {
        let dense_w: Vec<f64> = dense_hz.iter().map(|f| 2.0 * PI * f).collect();
        let mut curves: Vec<Curve> = Vec::new();
        let mut add = |label: String, color: RGBColor, dashed: bool, g: &FracTf| {
            let (m, p) = mag_phase(&g.bode(&dense_w));
            curves.push((label, color, dashed, m, p));
        };
        let levy = &self.fit.levy;
        add(
            format!("Levy, q = {}: J = {}", sig(levy.q, 4), sig(levy.j, 3)),
            BLUE_LEVY,
            false,
            &levy.model,
        );
        if let Some(sk) = &self.fit.sk {
            let label = format!(
                "Sanathanan-Koerner, q = {}: J = {}",
                sig(sk.q, 4),
                sig(sk.j, 3)
            );
            add(label, GREEN_SK, false, &sk.model);
        }
        if let Some(r) = &self.fit.refined {
            let label = format!(
                "refined, zeta = {}, theta = {}: J = {}",
                sig(r.zeta, 3),
                sig(r.theta, 3),
                sig(r.j, 3)
            );
            add(label, RED_REFINED, false, &r.model);
        }
        let others = [
            RGBColor(255, 127, 14),
            RGBColor(148, 103, 189),
            RGBColor(127, 127, 127),
        ];
        for (i, (g, j)) in self.compare.iter().enumerate() {
            let mut label = short_tf(g, 3);
            if label.chars().count() > 50 {
                label = format!("compare {}", i + 1);
            }
            let label = format!("{label}: J = {}", sig(*j, 3));
            add(label, others[i % others.len()], true, g);
        }
        curves
    }

    /// One Bode panel (magnitude when `is_mag`, else phase): the curves, the measured points with
    /// their error bars, and (on the magnitude) the legend both panels share.
    fn bode_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        is_mag: bool,
        axis: &Axis,
        curves: &[Curve],
        meas: &[f64],
        y_range: (f64, f64),
    ) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e}");
        let label_font = ("sans-serif", 17);
        let (title, y_desc) = if is_mag {
            ("Bode magnitude", "magnitude (dB)")
        } else {
            ("Bode phase", "phase (deg)")
        };
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((axis.f_lo..axis.f_hi).log_scale(), y_range.0..y_range.1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("frequency (Hz)")
            .y_desc(y_desc)
            .label_style(label_font)
            .axis_desc_style(label_font)
            .x_label_formatter(&|v| sig(*v, 2))
            .draw()
            .map_err(e)?;
        for (label, color, dashed, m, p) in curves {
            let ys = if is_mag { m } else { p };
            let pts: Vec<(f64, f64)> = axis
                .dense_hz
                .iter()
                .copied()
                .zip(ys.iter().copied())
                .collect();
            let style = color.stroke_width(2);
            let series = if *dashed {
                chart.draw_series(DashedLineSeries::new(pts, 8, 5, style))
            } else {
                chart.draw_series(LineSeries::new(pts, style))
            };
            series
                .map_err(e)?
                .label(label.as_str())
                .legend(plot::line_legend(style, 24));
        }
        let f_hz: Vec<f64> = self
            .data
            .omega_rad_s
            .iter()
            .map(|w| w / (2.0 * PI))
            .collect();
        if let Some(se) = &self.data.spread_se {
            // error bars: +-1 standard error of each point (from the repeats' spread)
            chart
                .draw_series(f_hz.iter().zip(meas).zip(se).map(|((&f, &y), &(g, p))| {
                    let d = if is_mag { g } else { p };
                    PathElement::new(vec![(f, y - d), (f, y + d)], BLACK.stroke_width(2))
                }))
                .map_err(e)?;
        }
        chart
            .draw_series(
                f_hz.iter()
                    .zip(meas)
                    .map(|(&f, &y)| Circle::new((f, y), 5, BLACK.filled())),
            )
            .map_err(e)?
            .label(if self.data.spread_se.is_some() {
                "measured (bars: +-1 standard error)"
            } else {
                "measured"
            })
            .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.filled()));
        if is_mag {
            // one legend (on the magnitude) serves both panels
            plot::boxed_legend(&mut chart, SeriesLabelPosition::LowerLeft)?;
        }
        Ok(())
    }

    /// The Levy error index J against the commensurate order q (Levy and Sanathanan-Koerner
    /// sweeps), the chosen q, and the refined fit's J as a dashed line.
    fn j_panel<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e}");
        let positive = |p: &&QPoint| p.j.is_finite() && p.j > 0.0;
        let finite: Vec<&QPoint> = self
            .fit
            .curve
            .iter()
            .chain(&self.fit.sk_curve)
            .filter(positive)
            .collect();
        if finite.len() < 2 {
            area.draw_text(
                "J(q): fixed q, no curve",
                &("sans-serif", 18).into_text_style(area),
                (40, 60),
            )
            .map_err(e)?;
            return Ok(());
        }
        let jlo = finite.iter().map(|p| p.j).fold(f64::INFINITY, f64::min);
        let jhi = finite.iter().map(|p| p.j).fold(0.0, f64::max);
        let jlo = match &self.fit.refined {
            Some(r) if r.j > 0.0 => jlo.min(r.j),
            _ => jlo,
        };
        let (jlo, jhi) = (jlo / 2.0, (jhi * 2.0).max(jlo * 10.0));
        let qhi = finite.iter().map(|p| p.q).fold(0.0, f64::max);
        let label_font = ("sans-serif", 17);
        let mut chart = ChartBuilder::on(area)
            .caption("Levy error index J(q)", ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..qhi * 1.02, (jlo..jhi).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("commensurate order q")
            .y_desc("J (eq. 30)")
            .label_style(label_font)
            .axis_desc_style(label_font)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(e)?;
        for (curve, label, color) in [
            (&self.fit.curve, "Levy", BLUE_LEVY),
            (&self.fit.sk_curve, "Sanathanan-Koerner", GREEN_SK),
        ] {
            if curve.is_empty() {
                continue;
            }
            let pts: Vec<(f64, f64)> = curve.iter().filter(positive).map(|p| (p.q, p.j)).collect();
            let style = color.stroke_width(2);
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(e)?
                .label(label)
                .legend(plot::line_legend(style, 24));
        }
        let best = (self.fit.levy.q, self.fit.levy.j);
        chart
            .draw_series(std::iter::once(Circle::new(best, 6, BLACK.filled())))
            .map_err(e)?
            .label(format!("chosen q = {}", sig(best.0, 4)))
            .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.filled()));
        if let Some(r) = &self.fit.refined {
            let style = RED_REFINED.stroke_width(2);
            let jr = r.j.max(jlo * 1.01);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(0.0, jr), (qhi * 1.02, jr)],
                    8,
                    5,
                    style,
                ))
                .map_err(e)?
                .label(format!("refined J = {}", sig(r.j, 3)))
                .legend(plot::line_legend(style, 24));
        }
        plot::boxed_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    }
}

/// The Levy fit's colour (curve and J(q) sweep).
const BLUE_LEVY: RGBColor = RGBColor(31, 119, 180);
/// The Sanathanan-Koerner fit's colour.
const GREEN_SK: RGBColor = RGBColor(44, 160, 44);
/// The refined fit's colour.
const RED_REFINED: RGBColor = RGBColor(214, 39, 40);

impl Figure for BodeFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (left, right) = root.split_horizontally(880);
        let (top, bottom) = left.split_vertically(450);
        let axis = self.axis();
        let curves = self.curves(&axis.dense_hz);
        let (meas_mag, meas_ph) = mag_phase(&self.data.h);
        // ranges: the data plus the models, within reason
        let mag_range = plot::range_of(meas_mag.iter().chain(curves.iter().flat_map(|c| &c.3)));
        let ph_range = plot::range_of(meas_ph.iter().chain(curves.iter().flat_map(|c| &c.4)));
        self.bode_panel(&top, true, &axis, &curves, &meas_mag, mag_range)?;
        self.bode_panel(&bottom, false, &axis, &curves, &meas_ph, ph_range)?;
        self.j_panel(&right)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_semicolon_with_comments() {
        let t = "# Bode\nfreq_hz; gain_db; phase_deg\n1;0;0\n# mid\n2;-6.0206;-90\n";
        let d = parse_bode(t, None, Units::default(), None).unwrap();
        assert_eq!(d.omega_rad_s.len(), 2);
        assert!((d.omega_rad_s[1] - 4.0 * PI).abs() < 1e-12);
        // 1e-4: -6.0206 dB is 0.5 to 5 digits
        assert!((d.h[1].im + 0.5).abs() < 1e-4 && d.h[1].re.abs() < 1e-12);
    }

    #[test]
    fn headerless_tab_and_units() {
        let t = "1\t2\t0.5\n3\t1\t1.0\n";
        let u = Units {
            rad_s: true,
            linear_gain: true,
            radians: true,
        };
        // headerless: refused unless the columns are said (a linear gain was read as dB)
        let e = parse_bode(t, None, u, None).unwrap_err();
        assert!(e.to_string().contains("no header line"), "{e}");
        let d = parse_bode(t, Some(["0", "1", "2"]), u, None).unwrap();
        assert_eq!(d.omega_rad_s, vec![1.0, 3.0]);
        assert!((d.h[0] - Complex64::from_polar(2.0, 0.5)).norm() < 1e-15);
    }

    #[test]
    fn bad_rows_are_named() {
        let u = Units::default();
        let cases = [
            ("", "no data"),
            ("freq_hz,gain_db,phase_deg\n", "no data"),
            ("freq_hz,gain_db\n1,2\n", "phase"),
            ("freq_hz,gain_db,phase_deg\n1,2,x\n", "not a number"),
            ("freq_hz,gain_db,phase_deg\n1,2,NaN\n", "NaN"),
            ("freq_hz,gain_db,phase_deg\n0,2,1\n", "> 0"),
            ("freq_hz,gain_db,phase_deg\n2,2,1\n1,2,1\n", "increase"),
            ("freq_hz,gain_db,phase_deg\n2,2,1\n2,2,1\n", "repeated"),
            (
                "freq_hz,gain_db,phase_deg\n2,2\n",
                "line 2: 2 fields where the header has 3",
            ),
        ];
        for (t, want) in cases {
            let err = parse_bode(t, None, u, None).unwrap_err();
            assert!(err.to_string().contains(want), "{t:?}: {err}");
            assert!(err.downcast_ref::<ident::Error>().is_some());
        }
    }

    #[test]
    fn sig_formats() {
        assert_eq!(sig(6.78532, 5), "6.7853");
        assert_eq!(sig(2.5906e-5, 5), "2.5906e-5");
        assert_eq!(sig(0.006632, 4), "6.632e-3");
        assert_eq!(sig(0.9053, 4), "0.9053");
        assert_eq!(sci(0.003555, 4), "3.555e-3");
    }
}
