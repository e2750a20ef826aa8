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

use crate::{Error, Result};

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
    /// `u0 = u[0]`, `y0` = median of `y` before the first input change (default).
    #[default]
    Initial,
    /// `u0`, `y0` = the means of the estimation part (for records with no rest at the start).
    Mean,
    /// No offsets: the data are already deviations.
    None,
}

/// The operating point removed from a record.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
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

/// The lines of delimited text that hold something, with their 1-based numbers: a UTF-8
/// byte-order mark (as Windows tools write) skipped, `#` comments cut, blank lines left out.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty())
}

/// The first line of delimited text that holds something (see [`Record::parse`]), split at its
/// [`delimiter`]: the header's names (trimmed), or `None` for a text with no such line.
pub fn header(text: &str) -> Option<Vec<&str>> {
    content_lines(text)
        .next()
        .map(|(_, l)| split_line(l, delimiter(l)))
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
                "column '{want}' appears twice in the header (columns {i} and {j}): \
                 rename one or choose by index"
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
        "no column '{want}' (found: {})",
        names.join(", ")
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
                names[*i],
                wants[j],
                wants[k],
                wants.join(", ")
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
    match col.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(Error::Data(format!(
            "{name} is not finite ({}) at sample {i}",
            col[i]
        ))),
        None => Ok(()),
    }
}

/// The sampling step of the time stamps `t`: the mean step, after checking that there are at
/// least 2, finite, strictly increasing and uniform (every step within 1% of the mean).
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
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    // 1% tolerance: time stamps printed with 6+ significant digits jitter far less; a
    // missing sample or a changed rate shows as a 100% deviation.
    if let Some(i) = t
        .windows(2)
        .position(|w| ((w[1] - w[0]) - dt).abs() > 0.01 * dt)
    {
        return Err(Error::Data(format!(
            "non-uniform sampling at sample {}: step {} s, mean step {dt} s (resample first)",
            i + 1,
            t[i + 1] - t[i]
        )));
    }
    Ok(dt)
}

/// Read the columns `wants` of delimited text: `,`, `;` or tab (detected from the header line),
/// `#` comments and blank lines skipped, one header line naming the columns, a UTF-8 byte-order
/// mark (as Windows tools write) ignored. Columns are chosen as in [`column_indices`] (by name, or
/// by 0-based index when the name is a number). Returns the header's names and the values of
/// each wanted column, in the order of `wants`.
///
/// # Errors
/// [`Error::Data`] for a missing header or column (listing those found), a name that appears
/// twice in the header, a column chosen twice, or a field that is missing or not a number (with
/// its line).
pub fn read_columns<const N: usize>(
    text: &str,
    wants: [&str; N],
) -> Result<(Vec<String>, [Vec<f64>; N])> {
    let mut lines = content_lines(text);
    let (_, header) = lines
        .next()
        .ok_or_else(|| Error::Data("empty file: no header line".into()))?;
    let delim = delimiter(header);
    let names = split_line(header, delim);
    let idx = column_indices(&names, &wants)?;
    let mut cols: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    for (lineno, line) in lines {
        let f = split_line(line, delim);
        for (col, &i) in cols.iter_mut().zip(&idx) {
            let s = f.get(i).ok_or_else(|| {
                Error::Data(format!(
                    "line {lineno}: {} fields, column {} missing",
                    f.len(),
                    names[i]
                ))
            })?;
            col.push(s.parse::<f64>().map_err(|_| {
                Error::Data(format!(
                    "line {lineno}: '{s}' in column {} is not a number",
                    names[i]
                ))
            })?);
        }
    }
    Ok((names.into_iter().map(String::from).collect(), cols))
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
                u0: self.u[..n_est].iter().sum::<f64>() / n_est as f64,
                y0: self.y[..n_est].iter().sum::<f64>() / n_est as f64,
            },
            OffsetMode::Initial => {
                let u0 = self.u[0];
                let first_change = self
                    .u
                    .iter()
                    .position(|&v| v != u0)
                    .unwrap_or(self.len())
                    .max(1);
                let mut pre = self.y[..first_change].to_vec();
                pre.sort_by(f64::total_cmp);
                let m = pre.len();
                let y0 = if m % 2 == 1 {
                    pre[m / 2]
                } else {
                    0.5 * (pre[m / 2 - 1] + pre[m / 2])
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
                "validation fraction {holdout} must be in [0, 0.9]"
            )));
        }
        Ok(((1.0 - holdout) * self.len() as f64).round() as usize)
    }

    /// Check that the input excites the system: its range over the first `n` samples must exceed
    /// `1e-9` times its magnitude.
    ///
    /// # Errors
    /// [`Error::NotEnoughData`] when the input is constant.
    pub fn check_excitation(&self, n: usize) -> Result<()> {
        let u = &self.u[..n.clamp(1, self.len())];
        let (lo, hi) = u
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
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
