//! Sampled input/output records as engineers take them: reading delimited text, checking the
//! sampling, removing the operating point, and splitting into estimation and validation parts.
//!
//! Conventions (documented choices):
//! - **Uniform sampling** is required: `dt` is the mean step, every step must be within 1% of it
//!   (time stamps printed with a few digits jitter by far less).
//! - **Operating point** ([`OffsetMode::Initial`], the default): the record is assumed to start with
//!   the plant at rest at the input level `u0 = u[0]` (the motor "running at a steady speed before
//!   the PRBS"). `y0` is the *median* of `y` over the samples before the input first changes (the
//!   median ignores a start-up transient), or `y[0]` when the input changes at once. The model is
//!   fitted on deviations `u - u0`, `y - y0`, starting from a zero state; any remaining constant
//!   error can be fitted as an output-offset parameter (see `oe::FitOptions::fit_offset`).
//! - **Split** ([`Record::split`]): the first `1 - holdout` of the samples estimate, the last
//!   `holdout` (default 30%) validate. The validation run is simulated from the start of the record
//!   (the model state carries over), then scored on the held-out samples only.
//!
//! ```
//! use ident::data::Record;
//! let text = "# a comment\nt;u;y\n0;0;0\n0.1;1;0\n0.2;1;0.5\n0.3;0;0.8\n";
//! let rec = Record::parse(text, &Default::default()).unwrap();
//! assert_eq!(rec.len(), 4);
//! assert!((rec.dt - 0.1).abs() < 1e-12);
//! ```

use crate::files::{read_text_scanned, shorten};
use crate::{Error, Result};

mod fast;

/// A record whose input is constant is a step at its first sample when its output moves by more
/// than this many noise levels ([`Record::starts_with_step`]): the range of `N` samples of white
/// noise is about 6 levels at `N = 1e3` and 10 at `N = 1e6`.
pub const STEP_NOISE_LEVELS: f64 = 20.0;

/// The noise level of `y` from its first differences, robustly: `median |dy| / (0.6745 sqrt 2)`
/// (`y` has at least two samples).
fn diff_noise(y: &[f64]) -> f64 {
    let mut dy: Vec<f64> = y.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let mid = dy.len() / 2;
    let (_, &mut med, _) = dy.select_nth_unstable_by(mid, f64::total_cmp);
    med / (0.6745 * std::f64::consts::SQRT_2)
}

/// The fewest samples of constant input before the first change for a record to be taken as
/// resting there ([`Record::rests_until`]): fewer cannot tell a steady output from a ramp.
pub const MIN_REST_SAMPLES: usize = 8;

/// The smallest part of the record the constant input before the first change must last for the
/// record to be taken as resting there ([`Record::rests_until`]): a few samples cannot tell rest
/// from the slow start of a response to an input applied at the first sample (a multi-level
/// PRBS whose first level lasts 10 of 3000 samples while the output creeps up within its noise).
pub const MIN_REST_FRACTION: f64 = 0.01;

/// The drift, as a fraction of the output's range, below which an output is steady whatever its
/// noise ([`Record::rests_until`]): the motor/generator record's first 50 samples, wandering by
/// less than 0.01% of its range, rest; the creep of a fractional plant 40 ms after a step (many
/// noise levels: the test `the_default_initial_state_is_rest_only_for_a_record_at_rest`) does not.
pub const REST_DRIFT: f64 = 1e-3;

/// A uniformly sampled single-input single-output record.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Time stamps (seconds), strictly increasing and uniform.
    pub t: Vec<f64>,
    /// Input samples.
    pub u: Vec<f64>,
    /// Output samples.
    pub y: Vec<f64>,
    /// The sampling step (seconds): the mean of the time steps.
    pub dt: f64,
}

/// Which columns of a delimited file hold `t`, `u`, `y`: by header name or by 0-based index.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    /// Time column (name or index as text).
    pub t: String,
    /// Input column.
    pub u: String,
    /// Output column.
    pub y: String,
}

impl Default for Columns {
    fn default() -> Self {
        Self {
            t: "t".into(),
            u: "u".into(),
            y: "y".into(),
        }
    }
}

/// How the operating point is removed (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum OffsetMode {
    /// `u0 = u[0]`, `y0` = median of `y` before the first input change (default); for a step at
    /// the first sample ([`Record::starts_with_step`]) `u0 = 0`, `y0 = y[0]`.
    #[default]
    Initial,
    /// `u0`, `y0` = the means of the estimation part (for records with no rest at the start).
    Mean,
    /// No offsets: the data are already deviations.
    None,
}

impl OffsetMode {
    /// Its name, as the options take it.
    pub fn as_str(self) -> &'static str {
        match self {
            OffsetMode::Initial => "initial",
            OffsetMode::Mean => "mean",
            OffsetMode::None => "none",
        }
    }
}

impl std::fmt::Display for OffsetMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for OffsetMode {
    type Err = Error;
    /// `initial`, `mean` or `none`, any case.
    fn from_str(s: &str) -> Result<Self> {
        [OffsetMode::Initial, OffsetMode::Mean, OffsetMode::None]
            .into_iter()
            .find(|m| s.trim().eq_ignore_ascii_case(m.as_str()))
            .ok_or_else(|| Error::Options(format!("offsets '{s}' must be initial, mean or none")))
    }
}

/// The operating point removed from a record.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Offsets {
    /// Input level subtracted.
    pub u0: f64,
    /// Output level subtracted.
    pub y0: f64,
}

/// The delimiter of a header line: whichever of tab, `;` and `,` it holds most often, `,` on a tie
/// or when it has none.
pub fn delimiter(header: &str) -> char {
    ['\t', ';', ',']
        .into_iter()
        .max_by_key(|d| header.matches(*d).count())
        .unwrap_or(',')
}

fn split_line(line: &str, delim: char) -> Vec<&str> {
    line.split(delim).map(|s| s.trim()).collect()
}

/// The physical lines of `text`: `\n` or `\r\n` ends a line, and in a file with no `\n` at all
/// (old Mac tools) `\r` does.
fn physical_lines(text: &str) -> Box<dyn Iterator<Item = &str> + '_> {
    if text.contains('\n') {
        Box::new(text.lines())
    } else {
        Box::new(text.split('\r'))
    }
}

/// The lines of delimited text that hold something, with their 1-based numbers: a UTF-8
/// byte-order mark (as Windows tools write) skipped, `#` comments cut, blank lines left out.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    physical_lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty())
}

/// A field without its surrounding quotes: `"z1"` and `'z1'` read as `z1` (spreadsheets and the
/// coupled-electric-drives benchmark quote their headers).
fn unquote(s: &str) -> &str {
    let s = s.trim();
    for q in ['"', '\''] {
        if s.len() >= 2 && s.starts_with(q) && s.ends_with(q) {
            return s[1..s.len() - 1].trim();
        }
    }
    s
}

/// The first line of delimited text that holds something (see [`Record::parse`]), split at its
/// [`delimiter`]: the header's names (trimmed, quotes removed), or `None` for a text with no such
/// line.
pub fn header(text: &str) -> Option<Vec<&str>> {
    content_lines(text).next().map(|(_, l)| {
        split_line(l, delimiter(l))
            .into_iter()
            .map(unquote)
            .collect()
    })
}

/// True when every field of a line is a number: a data row, not a header.
fn is_numeric_row(fields: &[&str]) -> bool {
    fields.iter().all(|f| unquote(f).parse::<f64>().is_ok())
}

/// The names of a header, shortened and at most 20 of them, for a message.
fn list_names(names: &[&str]) -> String {
    let mut s: Vec<String> = names.iter().take(20).map(|n| shorten(n)).collect();
    if names.len() > 20 {
        s.push(format!("... ({} columns)", names.len()));
    }
    s.join(", ")
}

/// Where column `want` is among the header's `names`: by name (ASCII case ignored), or by 0-based
/// index when `want` is a number that no name matches.
///
/// # Errors
/// [`Error::Data`] for a name that appears twice in the header (choosing it would silently take
/// the first), or no such column (listing those found).
pub fn column_index(names: &[&str], want: &str) -> Result<usize> {
    let mut hits = (0..names.len()).filter(|&i| names[i].eq_ignore_ascii_case(want));
    if let Some(i) = hits.next() {
        if let Some(j) = hits.next() {
            return Err(Error::Data(format!(
                "column '{}' appears twice in the header (columns {i} and {j}): \
                 rename one or choose by index",
                shorten(want)
            )));
        }
        return Ok(i);
    }
    if let Ok(i) = want.parse::<usize>() {
        if i < names.len() {
            return Ok(i);
        }
    }
    Err(Error::Data(format!(
        "no column '{}' (found: {})",
        shorten(want),
        list_names(names)
    )))
}

/// [`column_index`] of each of `wants`, refusing one column chosen twice.
///
/// # Errors
/// As [`column_index`], and [`Error::Data`] when two of `wants` name the same column.
pub fn column_indices(names: &[&str], wants: &[&str]) -> Result<Vec<usize>> {
    let idx = wants
        .iter()
        .map(|w| column_index(names, w))
        .collect::<Result<Vec<_>>>()?;
    for (k, i) in idx.iter().enumerate() {
        if let Some(j) = idx[..k].iter().position(|x| x == i) {
            return Err(Error::Data(format!(
                "column '{}' is chosen twice ('{}' and '{}' in [{}])",
                shorten(names[*i]),
                shorten(wants[j]),
                shorten(wants[k]),
                wants
                    .iter()
                    .map(|w| shorten(w))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
    }
    Ok(idx)
}

/// Refuse a non-finite sample of the column `name`.
///
/// # Errors
/// [`Error::Data`] naming the first NaN or infinite sample.
pub fn check_finite(name: &str, col: &[f64]) -> Result<()> {
    // One vectorised pass; the sample is searched only when one is not finite.
    if crate::numeric::all_finite(col) {
        return Ok(());
    }
    match col.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(Error::Data(format!(
            "{} is not finite ({}) at sample {i}",
            shorten(name),
            col[i]
        ))),
        None => Ok(()),
    }
}

/// The median of the steps of `t` (at least 2 samples): the element `len/2` of the steps in
/// [`f64::total_cmp`] order, found by selection in linear time (the same value sorting gives:
/// elements equal under the total order are the same bits).
///
/// A long record's steps take few distinct values (the step and its rounding neighbours): the
/// median of a thousand of them spread over the record is tried first, and kept when one counting
/// pass shows it is element `len/2` (fewer steps below it than `len/2`, not fewer up to it);
/// otherwise all the steps are selected.
fn median_step(t: &[f64]) -> f64 {
    let n = t.len() - 1;
    let mid = n / 2;
    let step = |k: usize| t[k + 1] - t[k];
    if n >= 1 << 14 {
        let mut sample: Vec<f64> = (0..n).step_by(n / 1024).map(step).collect();
        let half = sample.len() / 2;
        let c = *sample.select_nth_unstable_by(half, f64::total_cmp).1;
        let (mut below, mut equal) = (0usize, 0usize);
        for d in (0..n).map(step) {
            match d.total_cmp(&c) {
                std::cmp::Ordering::Less => below += 1,
                std::cmp::Ordering::Equal => equal += 1,
                std::cmp::Ordering::Greater => {}
            }
        }
        if below <= mid && mid < below + equal {
            return c;
        }
    }
    let mut d: Vec<f64> = (0..n).map(step).collect();
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The sampling step of the time stamps `t`: the mean step, after checking that there are at
/// least 2, finite, strictly increasing and uniform (every step within 1% of the median step, so
/// that a gap is reported where it is, not at the first sample).
///
/// # Errors
/// [`Error::NotEnoughData`] for fewer than 2 samples; [`Error::Data`] for a non-finite,
/// non-increasing or non-uniform time stamp (with its sample).
pub fn sampling_step(t: &[f64]) -> Result<f64> {
    if t.len() < 2 {
        return Err(Error::NotEnoughData(format!("{} samples", t.len())));
    }
    check_finite("t", t)?;
    if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(Error::Data(format!(
            "time is not strictly increasing at sample {} (t = {} then {})",
            i + 1,
            t[i],
            t[i + 1]
        )));
    }
    // The reference is the median step: a gap or a changed rate in a few places leaves it at
    // the true step, and the first step off it is where the fault is. 1% tolerance: time stamps
    // printed with 6+ significant digits jitter far less; a missing sample shows as 100%.
    let med = median_step(t);
    if let Some(i) = t
        .windows(2)
        .position(|w| ((w[1] - w[0]) - med).abs() > 0.01 * med)
    {
        return Err(Error::Data(format!(
            "non-uniform sampling at sample {}: step {} s (t = {} then {}), usual step {med} s \
             (resample first)",
            i + 1,
            t[i + 1] - t[i],
            t[i],
            t[i + 1]
        )));
    }
    Ok((t[t.len() - 1] - t[0]) / (t.len() - 1) as f64)
}

/// The header of delimited text and where its data start.
struct Table<'a> {
    names: Vec<&'a str>,
    /// False for a headerless file (names are then the 0-based indices).
    has_header: bool,
    delim: char,
    rows: Vec<(usize, &'a str)>,
}

/// Split delimited text into header names and data rows. A first line whose fields are all
/// numbers is a data row of a headerless file.
fn table(text: &str) -> Result<Table<'_>> {
    let mut lines = content_lines(text);
    let (first_no, first) = lines
        .next()
        .ok_or_else(|| Error::Data("empty file: no header line and no data".into()))?;
    let delim = delimiter(first);
    let fields = split_line(first, delim);
    let has_header = !is_numeric_row(&fields);
    let mut rows: Vec<(usize, &str)> = Vec::new();
    let names: Vec<&str> = if has_header {
        fields.into_iter().map(unquote).collect()
    } else {
        rows.push((first_no, first));
        Vec::new()
    };
    rows.extend(lines);
    Ok(Table {
        names,
        has_header,
        delim,
        rows,
    })
}

/// Read the columns `wants` of delimited text: `,`, `;` or tab (detected from the first line),
/// `#` comments and blank lines skipped, one header line naming the columns (quotes around names
/// and fields removed), a UTF-8 byte-order mark (as Windows tools write) ignored, lines ended by
/// `\n`, `\r\n` or (in a file with no `\n`) `\r`. Columns are chosen as in [`column_indices`]
/// (by name, or by 0-based index when the name is a number). A file whose first line is all
/// numbers has no header: every line is data and columns are chosen by index. Returns the
/// header's names (the indices for a headerless file) and the values of each wanted column, in
/// the order of `wants`.
///
/// # Errors
/// [`Error::Data`] for an empty file, a missing column (listing those found), a column chosen by
/// name in a headerless file, a name that appears twice in the header, a column chosen twice, or
/// a field that is missing or not a number (with its line).
pub fn read_columns<const N: usize>(
    text: &str,
    wants: [&str; N],
) -> Result<(Vec<String>, [Vec<f64>; N])> {
    match fast::read(text, &wants, false, fast::PARALLEL_BYTES) {
        Some((names, cols, _)) => Ok((names, cols)),
        None => read_columns_simple(text, wants).map(|(names, cols, _)| (names, cols)),
    }
}

/// Columns read by [`read_columns_at`]: the header's names, the columns, the line of each row.
pub type ColumnsAt<const N: usize> = (Vec<String>, [Vec<f64>; N], Vec<usize>);

/// [`read_columns`], also returning the 1-based line number of each row.
///
/// Data rows are split at the byte level with no allocation per line, only the wanted columns
/// are parsed, plain decimals by an exact fast path (Clinger's: the correctly rounded value
/// `str::parse` gives, to the bit), and a table of 256 KiB or more in two halves on two threads;
/// what that path does not handle (an error, a file whose lines end in a bare `\r`) is read by
/// the simple line-by-line reader, which gives the same values and reports the errors.
///
/// # Errors
/// As [`read_columns`].
pub fn read_columns_at<const N: usize>(text: &str, wants: [&str; N]) -> Result<ColumnsAt<N>> {
    match fast::read(text, &wants, true, fast::PARALLEL_BYTES) {
        Some(r) => Ok(r),
        None => read_columns_simple(text, wants),
    }
}

/// The simple reader behind [`read_columns_at`]: line by line, every rule spelled out once; the
/// reference the fast path is tested against, and the reader of every error.
fn read_columns_simple<const N: usize>(text: &str, wants: [&str; N]) -> Result<ColumnsAt<N>> {
    let tab = table(text)?;
    let index_names: Vec<String>;
    let names: Vec<&str> = if tab.has_header {
        tab.names.clone()
    } else {
        let width = split_line(tab.rows[0].1, tab.delim).len();
        if let Some(w) = wants.iter().find(|w| w.parse::<usize>().is_err()) {
            return Err(Error::Data(format!(
                "the file has no header line (its first line holds only numbers), so there is no \
                 column '{}': choose the columns by 0-based index (0 to {}), e.g. --t-col 0 \
                 --u-col 1 --y-col 2 (Python: t=0, u=1, y=2), or give --dt (Python: dt=) when \
                 there is no time column",
                shorten(w),
                width.saturating_sub(1)
            )));
        }
        index_names = (0..width).map(|i| i.to_string()).collect();
        index_names.iter().map(String::as_str).collect()
    };
    let idx = column_indices(&names, &wants)?;
    let mut cols: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    let width = names.len();
    for (lineno, line) in &tab.rows {
        let f = split_line(line, tab.delim);
        if f.len() != width {
            // a field too many or too few shifts every column after it: never read silently
            return Err(Error::Data(format!(
                "line {lineno}: {} fields where {} has {width} ({}): a field too many or too few \
                 would shift the columns",
                f.len(),
                if tab.has_header {
                    "the header"
                } else {
                    "the first line"
                },
                list_names(&names)
            )));
        }
        for (col, &i) in cols.iter_mut().zip(&idx) {
            let s = unquote(f[i]);
            col.push(s.parse::<f64>().map_err(|_| {
                Error::Data(format!(
                    "line {lineno}: '{}' in column {} is not a number",
                    shorten(s),
                    shorten(names[i])
                ))
            })?);
        }
    }
    let lines = tab.rows.iter().map(|r| r.0).collect();
    Ok((names.into_iter().map(String::from).collect(), cols, lines))
}

/// How to read a time record (see [`Record::parse_with`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ReadOptions {
    /// Which columns (or, in a `.mat` file, variables) hold `t`, `u`, `y`.
    pub columns: Columns,
    /// The sampling step (seconds) of a file with no time column: `t = k dt`, the time column is
    /// not read.
    pub dt: Option<f64>,
}

/// What the footer of an acquisition file (as `fracid drive` writes, `crates/drive/PROTOCOL.md`)
/// says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Acquisition {
    /// Not an acquisition file: no `fracid drive` header and no footer.
    Unknown,
    /// `# complete: N samples`.
    Complete,
    /// `# incomplete: missing samples a..b, ... (reason)`: the text after `missing samples`.
    Incomplete(String),
    /// A `fracid drive` header but no footer: the acquisition was interrupted.
    Interrupted,
}

impl Acquisition {
    /// Read the footer (the last `# complete` / `# incomplete` comment) and the header comment
    /// of delimited text.
    pub fn of_text(text: &str) -> Self {
        if text.contains('\n') {
            Self::of_lines(hash_lines(text))
        } else {
            Self::of_lines(physical_lines(text))
        }
    }

    /// [`Acquisition::of_text`] from the physical lines of a text (only those holding a `#`
    /// matter).
    fn of_lines<'a>(lines: impl Iterator<Item = &'a str>) -> Self {
        let mut drive = false;
        let mut last = Self::Unknown;
        for line in lines {
            let Some(c) = line.trim().strip_prefix('#') else {
                continue;
            };
            let c = c.trim();
            if c.starts_with("fracid drive acquisition") {
                drive = true;
            } else if let Some(rest) = c.strip_prefix("incomplete:") {
                let rest = rest.trim();
                let rest = rest.strip_prefix("missing samples").unwrap_or(rest).trim();
                last = Self::Incomplete(shorten_long(rest));
            } else if c.starts_with("complete:") {
                last = Self::Complete;
            }
        }
        match last {
            Self::Unknown if drive => Self::Interrupted,
            other => other,
        }
    }
}

/// The sample count `N` of the last `# complete: N samples` footer among `lines`, if it has one.
fn complete_count<'a>(lines: impl Iterator<Item = &'a str>) -> Option<usize> {
    lines
        .filter_map(|l| l.trim().strip_prefix('#')?.trim().strip_prefix("complete:"))
        .last()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The physical lines of a text with a `\n` that hold a `#`, in order, each as
/// [`physical_lines`] gives it (found by searching the `#`s, not by walking every line).
fn hash_lines(text: &str) -> impl Iterator<Item = &str> {
    let b = text.as_bytes();
    let mut from = 0;
    std::iter::from_fn(move || {
        let h = from + memchr::memchr(b'#', b.get(from..)?)?;
        let start = memchr::memrchr(b'\n', &b[..h]).map_or(0, |i| i + 1);
        let end = memchr::memchr(b'\n', &b[h..]).map_or(b.len(), |i| h + i);
        from = end + 1;
        let line = &text[start..end];
        // `str::lines` drops the `\r` of a `\r\n`.
        Some(if end < b.len() {
            line.strip_suffix('\r').unwrap_or(line)
        } else {
            line
        })
    })
}

/// At most 200 characters of a footer's text.
fn shorten_long(s: &str) -> String {
    if s.chars().count() <= 200 {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(200).collect::<String>())
    }
}

/// A torn last line: the text does not end with a line end and its last line is cut short (fewer
/// fields than the line before it, a field empty or not a number where the line before has a
/// number), or belongs to an interrupted
/// acquisition (a `fracid drive` file with no footer: its writer ends every line, so an
/// unterminated one was cut mid-write, its last field maybe mid-number). The text without it,
/// and the warning that says it was dropped; the text as it is otherwise.
fn without_torn_line<'a>(text: &'a str, acquisition: &Acquisition) -> (&'a str, Option<String>) {
    if text.is_empty() || text.ends_with(['\n', '\r']) {
        return (text, None);
    }
    let start = text.rfind(['\n', '\r']).map_or(0, |i| i + 1);
    let last = &text[start..];
    if start == 0 || last.trim_start().starts_with('#') || last.trim().is_empty() {
        return (text, None);
    }
    let before = text[..start].trim_end_matches(['\n', '\r']);
    let prev = before.rsplit(['\n', '\r']).next().unwrap_or("");
    let delim = delimiter(prev);
    let (fields, prev_fields) = (split_line(last, delim), split_line(prev, delim));
    let number = |f: &str| unquote(f.trim()).parse::<f64>().is_ok();
    // short, or a field that is a number on the line before and not on this one
    let short = fields.len() < prev_fields.len()
        || fields
            .iter()
            .zip(&prev_fields)
            .any(|(f, p)| !number(f) && number(p));
    if !(short || *acquisition == Acquisition::Interrupted) {
        return (text, None);
    }
    (
        &text[..start],
        Some(format!(
            "the last line '{}' has no line end and is {}: dropped as torn (cut while being \
             written), the complete lines kept",
            shorten(last),
            if short {
                "incomplete"
            } else {
                "the end of an interrupted acquisition"
            }
        )),
    )
}

/// The fewest samples a complete part of an incomplete acquisition must have to be fitted.
pub const MIN_COMPLETE_PART: usize = 50;

/// A record read from a file, with what the reader found and the user must be told.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The record (for an incomplete acquisition, its longest complete contiguous part).
    pub record: Record,
    /// The footer's verdict.
    pub acquisition: Acquisition,
    /// The rows of the file kept, `first..end` (0-based among the data rows).
    pub rows_kept: std::ops::Range<usize>,
    /// The data rows in the file.
    pub rows_read: usize,
    /// Warnings: an incomplete or interrupted acquisition, the part kept.
    pub warnings: Vec<String>,
}

/// The longest run of `t` with no gap: steps within 1% of the median step (the uniformity test
/// of [`sampling_step`]) and increasing.
fn longest_contiguous(t: &[f64]) -> std::ops::Range<usize> {
    if t.len() < 3 {
        return 0..t.len();
    }
    let med = median_step(t);
    let mut best = 0..1;
    let mut start = 0;
    for k in 1..=t.len() {
        let breaks = k == t.len() || {
            let d = t[k] - t[k - 1];
            !(d > 0.0 && (d - med).abs() <= 0.01 * med)
        };
        if breaks {
            if k - start > best.len() {
                best = start..k;
            }
            start = k;
        }
    }
    best
}

impl Record {
    /// Build a record from columns and check it: equal lengths, at least 2 samples, finite values,
    /// strictly increasing and uniform time.
    ///
    /// # Errors
    /// [`Error::Data`] for NaN/inf, unequal lengths, non-monotonic or non-uniform time (with the
    /// row of the first offending sample); [`Error::NotEnoughData`] for fewer than 2 samples.
    pub fn new(t: Vec<f64>, u: Vec<f64>, y: Vec<f64>) -> Result<Self> {
        if t.len() != u.len() || t.len() != y.len() {
            return Err(Error::Data(format!(
                "columns have different lengths (t {}, u {}, y {})",
                t.len(),
                u.len(),
                y.len()
            )));
        }
        let dt = sampling_step(&t)?;
        check_finite("u", &u)?;
        check_finite("y", &y)?;
        Ok(Self { t, u, y, dt })
    }

    /// A record from input and output samples at a given step, with `t = k dt`.
    ///
    /// # Errors
    /// As [`Record::new`], and [`Error::Data`] for a non-positive or non-finite `dt`.
    pub fn from_samples(u: &[f64], y: &[f64], dt: f64) -> Result<Self> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(Error::Data(format!("sampling step {dt} must be positive")));
        }
        let t = (0..u.len()).map(|k| k as f64 * dt).collect();
        Self::new(t, u.to_vec(), y.to_vec())
    }

    /// Parse delimited text with [`read_columns`] (columns `t`, `u`, `y` by name or 0-based
    /// index), then check as in [`Record::new`].
    ///
    /// # Errors
    /// Those of [`read_columns`] (including one column chosen for two of `t`, `u`, `y`), or any
    /// check of [`Record::new`].
    pub fn parse(text: &str, cols: &Columns) -> Result<Self> {
        let (_, [t, u, y]) = read_columns(text, [&cols.t, &cols.u, &cols.y])?;
        Self::new(t, u, y)
    }

    /// Parse delimited text as [`Record::parse`] does, with a time column or a given `dt`, and
    /// honour an acquisition footer: a file marked `# incomplete: missing samples a..b` or a
    /// `fracid drive` file with no footer (interrupted) is cut to its longest complete contiguous
    /// part, with a warning naming what is missing; a part of fewer than [`MIN_COMPLETE_PART`]
    /// samples is refused.
    ///
    /// ```
    /// use ident::data::{ReadOptions, Record, Columns, Acquisition};
    /// let mut text = String::from("t,u,y\n");
    /// for k in (0..100).chain(150..160) { text += &format!("{},{},0\n", k as f64 * 0.01, k % 2); }
    /// text += "# incomplete: missing samples 100..150 (port lost)\n";
    /// let l = Record::parse_with(&text, &ReadOptions::default()).unwrap();
    /// assert_eq!(l.record.len(), 100);
    /// assert!(l.warnings[0].contains("100..150"));
    /// assert_eq!(l.acquisition, Acquisition::Incomplete("100..150 (port lost)".into()));
    /// ```
    ///
    /// # Errors
    /// Those of [`read_columns`] and [`Record::new`]; [`Error::Options`] for a non-positive `dt`;
    /// [`Error::NotEnoughData`] for an incomplete acquisition whose complete part is too short,
    /// or one without a time column (where the gaps are cannot be told).
    pub fn parse_with(text: &str, opts: &ReadOptions) -> Result<Loaded> {
        Self::parse_text(text, opts, true)
    }

    /// [`Record::parse_with`]; `hash` false when the text is known to hold no `#` (no
    /// acquisition header or footer to look for).
    fn parse_text(text: &str, opts: &ReadOptions, hash: bool) -> Result<Loaded> {
        let acquisition = if hash {
            Acquisition::of_text(text)
        } else {
            Acquisition::Unknown
        };
        let (text, torn) = without_torn_line(text, &acquisition);
        let complete = (acquisition == Acquisition::Complete)
            .then(|| complete_count(hash_lines(text)))
            .flatten();
        let mut loaded = Self::parse_columns(text, opts, acquisition)?;
        if let Some(w) = torn {
            loaded.warnings.insert(0, w);
        }
        if let Some(c) = complete.filter(|&c| c != loaded.rows_read) {
            loaded.warnings.push(format!(
                "the footer says the acquisition is complete with {c} samples, but {} rows were \
                 read: the file was cut or edited after it was written (the rows read are used)",
                loaded.rows_read
            ));
        }
        Ok(loaded)
    }

    /// [`Record::parse_text`] on text whose torn last line is already cut.
    fn parse_columns(text: &str, opts: &ReadOptions, acquisition: Acquisition) -> Result<Loaded> {
        let cols = &opts.columns;
        let (t, u, y) = match opts.dt {
            Some(dt) => {
                if !(dt > 0.0 && dt.is_finite()) {
                    return Err(Error::Options(format!(
                        "dt = {dt}: the sampling step must be a positive number of seconds"
                    )));
                }
                let (_, [u, y]) = read_columns(text, [&cols.u, &cols.y])?;
                let t = (0..u.len()).map(|k| k as f64 * dt).collect();
                (t, u, y)
            }
            None => {
                let (_, [t, u, y]) = read_columns(text, [&cols.t, &cols.u, &cols.y])?;
                (t, u, y)
            }
        };
        Self::checked_part(t, u, y, acquisition, opts.dt.is_some())
    }

    /// Cut an incomplete acquisition to its longest complete part, then check.
    fn checked_part(
        t: Vec<f64>,
        u: Vec<f64>,
        y: Vec<f64>,
        acquisition: Acquisition,
        given_dt: bool,
    ) -> Result<Loaded> {
        let n = t.len();
        let what = match &acquisition {
            Acquisition::Incomplete(m) => Some(format!(
                "the acquisition is marked incomplete (missing samples {m})"
            )),
            Acquisition::Interrupted => Some(
                "the acquisition was interrupted (a `fracid drive` file with no `# complete` or \
                 `# incomplete` footer: the end of the run, and any samples lost, are unknown)"
                    .to_string(),
            ),
            _ => None,
        };
        let Some(what) = what else {
            let record = Record::new(t, u, y)?;
            return Ok(Loaded {
                record,
                acquisition,
                rows_kept: 0..n,
                rows_read: n,
                warnings: Vec::new(),
            });
        };
        if given_dt {
            return Err(Error::NotEnoughData(format!(
                "{what}, and with --dt (no time column) where samples are missing cannot be told: \
                 read the time column instead"
            )));
        }
        if t.len() != u.len() || t.len() != y.len() {
            return Err(Error::Data(format!(
                "columns have different lengths (t {}, u {}, y {})",
                t.len(),
                u.len(),
                y.len()
            )));
        }
        check_finite("t", &t)?;
        let part = longest_contiguous(&t);
        if part.len() < MIN_COMPLETE_PART {
            return Err(Error::NotEnoughData(format!(
                "{what}; its longest complete contiguous part has {} samples (at least \
                 {MIN_COMPLETE_PART} are needed)",
                part.len()
            )));
        }
        let mut warnings = vec![format!(
            "{what}: using its longest complete contiguous part, rows {}..{} of {n} \
             (t = {} s to {} s)",
            part.start,
            part.end,
            t[part.start],
            t[part.end - 1]
        )];
        if part.len() < n {
            warnings.push(format!(
                "{} of {n} rows left out (before or after a gap)",
                n - part.len()
            ));
        }
        let record = Record::new(
            t[part.clone()].to_vec(),
            u[part.clone()].to_vec(),
            y[part.clone()].to_vec(),
        )?;
        Ok(Loaded {
            record,
            acquisition,
            rows_kept: part,
            rows_read: n,
            warnings,
        })
    }

    /// Read a record from a file: a `.mat` file (MATLAB v5/v7, see [`crate::matfile`]) by its
    /// variables, any other file as delimited text with [`Record::parse_with`], read with the
    /// bounds of [`crate::files::read_text`].
    ///
    /// # Errors
    /// Those of [`crate::files::read_text`] (I/O: [`Error::Io`]) and [`crate::matfile::read`];
    /// those of [`Record::parse_with`] (or of the variables) in an [`Error::File`] naming it.
    pub fn load(path: &std::path::Path, opts: &ReadOptions) -> Result<Loaded> {
        if crate::matfile::is_mat(path) {
            let vars = crate::matfile::read(path)?;
            return Self::from_variables(&vars, opts).map_err(|e| e.in_file(path));
        }
        let (text, hash) = read_text_scanned(path)?;
        Self::parse_text(&text, opts, hash).map_err(|e| e.in_file(path))
    }

    /// A record from the variables of a `.mat` file ([`Record::load`]).
    fn from_variables(vars: &[crate::matfile::Variable], opts: &ReadOptions) -> Result<Loaded> {
        let cols = &opts.columns;
        let (t, u, y) = match opts.dt {
            Some(dt) => {
                if !(dt > 0.0 && dt.is_finite()) {
                    return Err(Error::Options(format!(
                        "dt = {dt}: the sampling step must be a positive number of seconds"
                    )));
                }
                let [u, y] = crate::matfile::columns(vars, [&cols.u, &cols.y])?;
                let t = (0..u.len()).map(|k| k as f64 * dt).collect();
                (t, u, y)
            }
            None => {
                let [t, u, y] = crate::matfile::columns(vars, [&cols.t, &cols.u, &cols.y])?;
                (t, u, y)
            }
        };
        Self::checked_part(t, u, y, Acquisition::Unknown, opts.dt.is_some())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if there are no samples (never for a checked record).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The operating point per `mode`, computed on the first `n_est` samples.
    pub fn offsets(&self, mode: OffsetMode, n_est: usize) -> Offsets {
        let n_est = n_est.clamp(1, self.len());
        match mode {
            OffsetMode::None => Offsets::default(),
            OffsetMode::Mean => Offsets {
                u0: crate::numeric::sum_of(&self.u[..n_est], |v| v) / n_est as f64,
                y0: crate::numeric::sum_of(&self.y[..n_est], |v| v) / n_est as f64,
            },
            OffsetMode::Initial if self.starts_with_step() => Offsets {
                u0: 0.0,
                y0: self.y[0],
            },
            OffsetMode::Initial => {
                let u0 = self.u[0];
                let first_change = self
                    .u
                    .iter()
                    .position(|&v| v != u0)
                    .unwrap_or(self.len())
                    .max(1);
                // The median by selection (linear time; the values sorting would give).
                let mut pre = self.y[..first_change].to_vec();
                let m = pre.len();
                let (below, &mut hi, _) = pre.select_nth_unstable_by(m / 2, f64::total_cmp);
                let y0 = if m % 2 == 1 {
                    hi
                } else {
                    let lo = below.iter().copied().max_by(f64::total_cmp).unwrap_or(hi);
                    0.5 * (lo + hi)
                };
                Offsets { u0, y0 }
            }
        }
    }

    /// The index where validation starts when the last `holdout` fraction is held out
    /// (`holdout` in `[0, 1)`; 0 means no validation part).
    ///
    /// # Errors
    /// [`Error::Options`] for `holdout` outside `[0, 0.9]`.
    pub fn split_index(&self, holdout: f64) -> Result<usize> {
        if !(0.0..=0.9).contains(&holdout) {
            return Err(Error::Options(format!(
                "validation fraction (holdout) {holdout} must be in [0, 0.9]"
            )));
        }
        Ok(((1.0 - holdout) * self.len() as f64).round() as usize)
    }

    /// Whether the record is a step applied at its first sample to a plant at rest: the input is
    /// constant and nonzero over the whole record while the output moves by more than
    /// [`STEP_NOISE_LEVELS`] noise levels (the noise estimated from the output's first
    /// differences, robustly: `median |dy| / (0.6745 sqrt 2)`).
    ///
    /// The rule for such a record (the initial state that explains its first samples): the input
    /// was 0 before the first sample and the output at rest at `y[0]`; the operating point is
    /// then `u0 = 0, y0 = y[0]` ([`OffsetMode::Initial`]) and the record is fitted from rest.
    ///
    /// ```
    /// use ident::data::Record;
    /// let y: Vec<f64> = (0..200).map(|k| 2.0 * (1.0 - (-0.05 * k as f64).exp())).collect();
    /// let step = Record::from_samples(&vec![1.0; 200], &y, 0.01).unwrap();
    /// assert!(step.starts_with_step());
    /// let flat = Record::from_samples(&vec![1.0; 200], &vec![2.0; 200], 0.01).unwrap();
    /// assert!(!flat.starts_with_step());
    /// ```
    pub fn starts_with_step(&self) -> bool {
        let (lo, hi) = crate::numeric::range_of(&self.u);
        let constant = hi - lo <= 1e-9 * hi.abs().max(lo.abs()).max(1e-300);
        if !constant || self.u[0] == 0.0 || !self.u[0].is_finite() || self.len() < 3 {
            return false;
        }
        let noise = diff_noise(&self.y);
        let (ylo, yhi) = crate::numeric::range_of(&self.y);
        yhi - ylo > STEP_NOISE_LEVELS * noise && yhi > ylo
    }

    /// The first input change when the record **rests** before it: the input constant over at
    /// least [`MIN_REST_SAMPLES`] samples and [`MIN_REST_FRACTION`] of the record, and the output
    /// steady there: no trend (the means of the
    /// window's two halves apart by no more than [`REST_DRIFT`] of the output's range over the
    /// record, or than three standard errors of that difference, the noise within the halves; a ramp of
    /// rise `R` over `k >= 8` samples moves them `R/2` apart against at most `0.87 R / sqrt(k)`)
    /// and no spread (the window's standard deviation within 2% of the output's range or 1.5
    /// noise levels, the noise from the record's first differences, robustly: a window that
    /// moves and comes back has no trend but spreads).
    ///
    /// The rule for such a record (a step test from rest, a lab record that starts idle): the
    /// plant is at rest at the operating point of [`OffsetMode::Initial`] (`u0 = u[0]`, `y0` =
    /// the median of `y` before the first change), so the initial state is that rest, not a
    /// fitted past input ([`crate::oe::InitialState::Auto`]).
    ///
    /// ```
    /// use ident::data::Record;
    /// let u: Vec<f64> = (0..200).map(|k| if k < 50 { 0.0 } else { 1.0 }).collect();
    /// let rise = |k: usize| if k < 50 { 0.0 } else { 1.0 - (-0.05 * (k - 50) as f64).exp() };
    /// let idle = Record::from_samples(&u, &(0..200).map(rise).collect::<Vec<_>>(), 0.01).unwrap();
    /// assert_eq!(idle.rests_until(), Some(50));
    /// // the output still falls from an earlier move while the input stands still
    /// let y: Vec<f64> = (0..200).map(|k| rise(k) + (-0.02 * k as f64).exp()).collect();
    /// let moving = Record::from_samples(&u, &y, 0.01).unwrap();
    /// assert_eq!(moving.rests_until(), None);
    /// ```
    pub fn rests_until(&self) -> Option<usize> {
        let n = self.len();
        let (ulo, uhi) = crate::numeric::range_of(&self.u);
        let tol = 1e-9 * uhi.abs().max(ulo.abs()).max(1e-300);
        let k1 = (1..n).find(|&k| (self.u[k] - self.u[0]).abs() > tol)?;
        if k1 < MIN_REST_SAMPLES || (k1 as f64) < MIN_REST_FRACTION * n as f64 {
            return None;
        }
        let (ylo, yhi) = crate::numeric::range_of(&self.y);
        let half = k1 / 2;
        let (a, b) = (&self.y[..half], &self.y[half..k1]);
        let mean = |w: &[f64]| w.iter().sum::<f64>() / w.len() as f64;
        let var = |w: &[f64], m: f64| w.iter().map(|v| (v - m).powi(2)).sum::<f64>();
        let (ma, mb) = (mean(a), mean(b));
        let within = (var(a, ma) + var(b, mb)) / (k1 - 2) as f64;
        let se = (within * (1.0 / a.len() as f64 + 1.0 / b.len() as f64)).sqrt();
        let no_trend = (mb - ma).abs() <= (REST_DRIFT * (yhi - ylo)).max(3.0 * se);
        // and no larger spread than the record's noise (robust, from its first differences): a
        // window that moves and comes back has no trend but spreads
        let noise = diff_noise(&self.y);
        let m = mean(&self.y[..k1]);
        let spread = (var(&self.y[..k1], m) / k1 as f64).sqrt();
        let calm = spread <= (0.02 * (yhi - ylo)).max(1.5 * noise);
        (no_trend && calm).then_some(k1)
    }

    /// Check that the input excites the system: its range over the first `n` samples must exceed
    /// `1e-9` times its magnitude.
    ///
    /// # Errors
    /// [`Error::NotEnoughData`] when the input is constant.
    pub fn check_excitation(&self, n: usize) -> Result<()> {
        let u = &self.u[..n.clamp(1, self.len())];
        let (lo, hi) = crate::numeric::range_of(u);
        if hi - lo <= 1e-9 * hi.abs().max(lo.abs()).max(1e-300) {
            return Err(Error::NotEnoughData(format!(
                "the input is constant ({lo}) over the estimation part: no excitation"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_modes_round_trip_through_their_words() {
        for m in [OffsetMode::Initial, OffsetMode::Mean, OffsetMode::None] {
            assert_eq!(m.to_string().parse::<OffsetMode>().unwrap(), m);
            assert_eq!(
                m.to_string().to_uppercase().parse::<OffsetMode>().unwrap(),
                m
            );
        }
        let e = "median".parse::<OffsetMode>().unwrap_err().to_string();
        assert!(
            e.contains("offsets 'median' must be initial, mean or none"),
            "{e}"
        );
    }

    /// The footer's sample count is checked against the rows read (issue 31): a mismatch is a
    /// warning, the rows read are kept; a matching count says nothing.
    #[test]
    fn a_complete_footer_with_another_count_is_warned() {
        let rows: String = (0..40)
            .map(|k| format!("{k},{},{}\n", k % 3, k % 5))
            .collect();
        let head = "# fracid drive acquisition: PRBS\nt,u,y\n";
        let ok = Record::parse_with(
            &format!("{head}{rows}# complete: 40 samples\n"),
            &ReadOptions::default(),
        )
        .unwrap();
        assert!(ok.warnings.is_empty(), "{:?}", ok.warnings);
        let cut = Record::parse_with(
            &format!("{head}{rows}# complete: 50 samples\n"),
            &ReadOptions::default(),
        )
        .unwrap();
        assert_eq!(cut.record.len(), 40);
        assert!(
            cut.warnings
                .iter()
                .any(|w| w.contains("complete with 50 samples, but 40 rows")),
            "{:?}",
            cut.warnings
        );
    }

    #[test]
    fn parse_and_check() {
        let r = Record::parse("t,u,y\n0,1,2\n0.5,1,3\n1.0,2,3\n", &Columns::default()).unwrap();
        assert_eq!(r.u, vec![1.0, 1.0, 2.0]);
        assert_eq!(
            r.offsets(OffsetMode::Initial, 3),
            Offsets { u0: 1.0, y0: 2.5 }
        );
        let tab = Record::parse(
            "time\tv\tw\n0\t1\t2\n1\t1\t3\n",
            &Columns {
                t: "0".into(),
                u: "v".into(),
                y: "2".into(),
            },
        )
        .unwrap();
        assert_eq!(tab.y, vec![2.0, 3.0]);
    }

    /// The median step by a sampled candidate equals the one by selecting every step: uniform
    /// steps with rounding jitter, a record whose first half has another step (the sampled
    /// median may then be on the wrong side), a few gaps.
    #[test]
    fn the_median_step_is_the_selected_one() {
        let full = |t: &[f64]| {
            let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            let mid = d.len() / 2;
            *d.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let n = 50_000;
        let jitter: Vec<f64> = (0..n).map(|k| k as f64 * 5e-4).collect();
        let halves: Vec<f64> = (0..n)
            .map(|k| {
                if k < n / 2 + 1 {
                    k as f64 * 1e-3
                } else {
                    (n / 2 + 1) as f64 * 1e-3 + (k - n / 2 - 1) as f64 * 2e-3
                }
            })
            .collect();
        let mut gaps = jitter.clone();
        for k in (1000..n).step_by(7000) {
            for v in &mut gaps[k..] {
                *v += 0.05;
            }
        }
        let odd: Vec<f64> = (0..n + 1).map(|k| (k as f64).powf(1.01) * 1e-3).collect();
        for t in [&jitter, &halves, &gaps, &odd] {
            assert_eq!(median_step(t).to_bits(), full(t).to_bits());
        }
    }

    #[test]
    fn delimiter_is_the_most_frequent() {
        assert_eq!(delimiter("t;u;y"), ';');
        assert_eq!(delimiter("t\tu\ty"), '\t');
        assert_eq!(delimiter("t,u,y"), ',');
        assert_eq!(delimiter("a;b,c;d"), ';');
        // ties and single columns: ','
        assert_eq!(delimiter("a;b,c"), ',');
        assert_eq!(delimiter("t"), ',');
    }

    #[test]
    fn bad_inputs_are_errors() {
        let c = Columns::default();
        let e = Record::parse("t,u\n0,1\n", &c).unwrap_err();
        assert!(e.to_string().contains("no column 'y'"), "{e}");
        let e = Record::parse("t,u,y\n0,1,2\n1,NaN,2\n", &c).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
        let e = Record::parse("t,u,y\n0,1,2\n1,x,2\n", &c).unwrap_err();
        assert!(e.to_string().contains("not a number"), "{e}");
        let e = Record::parse("t,u,y\n0,1,2\n1,1,2\n0.5,1,2\n", &c).unwrap_err();
        assert!(e.to_string().contains("strictly increasing"), "{e}");
        let e = Record::parse("t,u,y\n0,1,2\n1,1,2\n3,1,2\n", &c).unwrap_err();
        assert!(e.to_string().contains("non-uniform"), "{e}");
        let e = Record::parse("t,u,y\n0,1,2\n", &c).unwrap_err();
        assert!(matches!(e, Error::NotEnoughData(_)));
        let r = Record::parse("t,u,y\n0,1,2\n1,1,2\n2,1,2\n", &c).unwrap();
        assert!(r.check_excitation(3).is_err());
        assert!(r.split_index(1.5).is_err());
        assert!(Record::from_samples(&[1.0, 2.0], &[1.0, 2.0], 0.0).is_err());
    }
}
