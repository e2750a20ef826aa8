//! Bode tables from files: the one reader of the CLI (`fracid freq`) and Python
//! (`fracid.load_bode`).
//!
//! A table has a frequency, a gain and a phase column (default names `freq_hz,gain_db,phase_deg`;
//! other units by [`BodeUnits`], other names by `columns`), delimited as the time records are
//! ([`crate::data::read_columns`]: `,` `;` or tab, `#` comments, quoted names). A table with no
//! header line is refused unless the columns are given (by 0-based index): its columns could be
//! anything (a linear gain read as dB goes unnoticed). A `.mat` file holds the columns as
//! variables of those names ([`crate::matfile`]).
//!
//! ```
//! use ident::bodefile::{parse, BodeUnits};
//! let t = "freq_hz,gain_db,phase_deg\n1,0,0\n2,-6.0206,-90\n";
//! let b = parse(t, None, BodeUnits::default(), None).unwrap();
//! assert!((b.h[1].im + 0.5).abs() < 1e-4);
//! // headerless: refused unless the columns are said
//! let e = parse("1,0,0\n2,-6,-90\n", None, BodeUnits::default(), None).unwrap_err();
//! assert!(e.to_string().contains("no header"));
//! assert!(parse("1,0,0\n2,-6,-90\n", Some(["0", "1", "2"]), BodeUnits::default(), None).is_ok());
//! ```

use crate::data::{column_indices, header, read_columns_at};
use crate::files::{read_text, shorten};
use crate::{Error, Result};
use num_complex::Complex64;
use std::f64::consts::PI;
use std::path::Path;

/// Units of the three columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BodeUnits {
    /// Frequency in rad/s (else Hz).
    pub rad_s: bool,
    /// Linear gain (else dB).
    pub linear_gain: bool,
    /// Phase in radians (else degrees).
    pub radians: bool,
}

/// A Bode table read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct BodeTable {
    /// Frequencies in rad/s, strictly increasing.
    pub omega_rad_s: Vec<f64>,
    /// The measured response `G(j omega)`.
    pub h: Vec<Complex64>,
    /// Per-point weights from a column, if asked.
    pub weights: Option<Vec<f64>>,
    /// Standard errors (gain dB, phase deg) of each point from the spread columns
    /// `gain_db_std,phase_deg_std[,repeats]` when the table has both std columns (as
    /// `fracid drive sine --repeats` writes them): `std/sqrt(repeats - 2)` from 3 repeats on (the
    /// trimmed mean averages `repeats - 2`), else `std/sqrt(repeats)` (`repeats` 1 when absent).
    pub spread_se: Option<Vec<(f64, f64)>>,
}

fn bad<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Data(msg.into()))
}

/// The default names of the frequency, gain and phase columns for `units`, in order of
/// preference.
pub fn default_names(units: BodeUnits) -> [&'static [&'static str]; 3] {
    [
        if units.rad_s {
            &["omega_rad_s", "omega", "w_rad_s"][..]
        } else {
            &["freq_hz", "frequency_hz", "freq", "f_hz"][..]
        },
        if units.linear_gain {
            &["gain", "mag", "magnitude", "gain_abs"][..]
        } else {
            &["gain_db", "mag_db", "magnitude_db"][..]
        },
        if units.radians {
            &["phase_rad", "phase"][..]
        } else {
            &["phase_deg", "phase"][..]
        },
    ]
}

/// The columns to read: those given, else the first default name of each role the header has.
fn wanted<'a>(
    names: &[&str],
    columns: Option<[&'a str; 3]>,
    units: BodeUnits,
) -> Result<[&'a str; 3]>
where
    'static: 'a,
{
    if let Some(c) = columns {
        return Ok(c);
    }
    let roles = ["frequency", "gain", "phase"];
    let defaults = default_names(units);
    let mut out = [""; 3];
    for k in 0..3 {
        match defaults[k]
            .iter()
            .find(|n| names.iter().any(|h| h.eq_ignore_ascii_case(n)))
        {
            Some(n) => out[k] = n,
            None => {
                return bad(format!(
                    "no {} column {} in the header [{}]; name the columns with --columns \
                     FREQ,GAIN,PHASE (Python: columns=(...)) and the units with --rad-s, \
                     --linear-gain, --radians",
                    roles[k],
                    defaults[k]
                        .iter()
                        .map(|n| format!("'{n}'"))
                        .collect::<Vec<_>>()
                        .join(" or "),
                    names
                        .iter()
                        .take(20)
                        .map(|n| shorten(n))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            }
        }
    }
    Ok(out)
}

/// The message for a table with no header line.
fn headerless_message() -> String {
    "the Bode table has no header line, so which column is the frequency, the gain and the \
     phase (and in which units) is unknown: add a header (freq_hz,gain_db,phase_deg), or say it \
     with --columns 0,1,2 (0-based FREQ,GAIN,PHASE; Python: columns=(0, 1, 2)) and --rad-s, \
     --linear-gain, --radians for other units than Hz, dB and degrees"
        .to_string()
}

/// Read a Bode table from delimited text. `columns` names (or, 0-based, indexes) the frequency,
/// gain and phase columns; `weight_column` an extra column of per-point weights.
///
/// # Errors
/// [`Error::Data`] naming the line: no rows, a headerless table without `columns`, a missing
/// column, a non-numeric or non-finite value, a frequency <= 0, unsorted or repeated
/// frequencies, a negative linear gain.
pub fn parse(
    text: &str,
    columns: Option<[&str; 3]>,
    units: BodeUnits,
    weight_column: Option<&str>,
) -> Result<BodeTable> {
    let Some(names) = header(text) else {
        return bad("no data rows (an empty file?)");
    };
    let has_header = !names.iter().all(|n| n.parse::<f64>().is_ok());
    if !has_header && columns.is_none() {
        return bad(headerless_message());
    }
    let cols = if has_header {
        wanted(&names, columns, units)?
    } else {
        columns.unwrap_or(["0", "1", "2"])
    };
    // the checks of the time reader: a name twice in the header, one column chosen twice
    let mut wants: Vec<&str> = cols.to_vec();
    wants.extend(weight_column);
    if has_header {
        column_indices(&names, &wants)?;
    }
    let (f, g, ph, w, lines) = match weight_column {
        Some(wc) => {
            let (_, [f, g, p, w], l) = read_columns_at(text, [cols[0], cols[1], cols[2], wc])?;
            (f, g, p, Some(w), l)
        }
        None => {
            let (_, [f, g, p], l) = read_columns_at(text, cols)?;
            (f, g, p, None, l)
        }
    };
    let row = |k: usize| format!("line {}", lines[k]);
    let mut t = build(&f, &g, &ph, w, units, row)?;
    let has = |n: &str| names.iter().any(|h| h.eq_ignore_ascii_case(n));
    if has_header && has(SPREAD_COLUMNS[0]) && has(SPREAD_COLUMNS[1]) {
        let (gs, ps, n) = if has(SPREAD_COLUMNS[2]) {
            let (_, [g, p, n], _) = read_columns_at(text, SPREAD_COLUMNS)?;
            (g, p, Some(n))
        } else {
            let (_, [g, p], _) = read_columns_at(text, [SPREAD_COLUMNS[0], SPREAD_COLUMNS[1]])?;
            (g, p, None)
        };
        t.spread_se = Some(spread_se(&gs, &ps, n.as_deref(), row)?);
    }
    Ok(t)
}

/// The spread columns of a Bode table written from repeated measurements: the standard deviations
/// of the repeats (gain dB, phase deg) and their number.
pub const SPREAD_COLUMNS: [&str; 3] = ["gain_db_std", "phase_deg_std", "repeats"];

/// The standard errors of the points from their spread (see [`BodeTable::spread_se`]).
fn spread_se(
    g: &[f64],
    p: &[f64],
    n: Option<&[f64]>,
    row: impl Fn(usize) -> String,
) -> Result<Vec<(f64, f64)>> {
    let mut out = Vec::with_capacity(g.len());
    for k in 0..g.len() {
        for (name, v) in [(SPREAD_COLUMNS[0], g[k]), (SPREAD_COLUMNS[1], p[k])] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{}: {name} must be a finite number >= 0", row(k)));
            }
        }
        let n = n.map_or(1.0, |n| n[k]);
        if !(n.is_finite() && n >= 1.0 && n.fract() == 0.0) {
            return bad(format!("{}: repeats must be a whole number >= 1", row(k)));
        }
        let kept = if n >= 3.0 { n - 2.0 } else { n };
        out.push((g[k] / kept.sqrt(), p[k] / kept.sqrt()));
    }
    Ok(out)
}

/// Check the columns and make the complex response. `row(k)` says where sample `k` is.
fn build(
    f: &[f64],
    g: &[f64],
    ph: &[f64],
    w: Option<Vec<f64>>,
    units: BodeUnits,
    row: impl Fn(usize) -> String,
) -> Result<BodeTable> {
    if f.is_empty() {
        return bad("a header but no data rows");
    }
    let mut omega = Vec::with_capacity(f.len());
    let mut h = Vec::with_capacity(f.len());
    for k in 0..f.len() {
        for (name, v) in [("frequency", f[k]), ("gain", g[k]), ("phase", ph[k])] {
            if !v.is_finite() {
                return bad(format!("{}: {name} is {v}", row(k)));
            }
        }
        if f[k] <= 0.0 {
            return bad(format!("{}: frequency {} must be > 0", row(k), f[k]));
        }
        let om = if units.rad_s { f[k] } else { 2.0 * PI * f[k] };
        if let Some(&prev) = omega.last() {
            if om == prev {
                return bad(format!("{}: frequency {} is repeated", row(k), f[k]));
            }
            if om < prev {
                return bad(format!(
                    "{}: frequencies must increase ({} follows a larger one)",
                    row(k),
                    f[k]
                ));
            }
        }
        let mag = if units.linear_gain {
            if g[k] < 0.0 {
                return bad(format!(
                    "{}: linear gain {} is negative (give the sign in the phase)",
                    row(k),
                    g[k]
                ));
            }
            g[k]
        } else {
            10f64.powf(g[k] / 20.0)
        };
        let phr = if units.radians {
            ph[k]
        } else {
            ph[k].to_radians()
        };
        omega.push(om);
        h.push(Complex64::from_polar(mag, phr));
    }
    if let Some(w) = &w {
        if let Some(k) = w.iter().position(|x| !x.is_finite()) {
            return bad(format!("{}: weight is {}", row(k), w[k]));
        }
    }
    Ok(BodeTable {
        omega_rad_s: omega,
        h,
        weights: w,
        spread_se: None,
    })
}

/// Read a Bode table from a file: a `.mat` file by its variables (the same names as the
/// columns), any other file as text with [`parse`] (read with the bounds of
/// [`read_text`]).
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; those of [`read_text`], [`parse`] and
/// [`crate::matfile::read`].
pub fn load(
    path: &Path,
    columns: Option<[&str; 3]>,
    units: BodeUnits,
    weight_column: Option<&str>,
) -> Result<BodeTable> {
    if crate::matfile::is_mat(path) {
        let vars = crate::matfile::read(path)?;
        let names: Vec<&str> = vars.iter().map(|v| v.name.as_str()).collect();
        let cols = wanted(&names, columns, units)?;
        let (f, g, ph, w) = match weight_column {
            Some(wc) => {
                let [f, g, p, w] = crate::matfile::columns(&vars, [cols[0], cols[1], cols[2], wc])?;
                (f, g, p, Some(w))
            }
            None => {
                let [f, g, p] = crate::matfile::columns(&vars, cols)?;
                (f, g, p, None)
            }
        };
        let row = |k: usize| format!("{}: point {k}", path.display());
        let mut t = build(&f, &g, &ph, w, units, row)?;
        let has = |n: &str| names.contains(&n);
        if has(SPREAD_COLUMNS[0]) && has(SPREAD_COLUMNS[1]) {
            let [gs, ps] = crate::matfile::columns(&vars, [SPREAD_COLUMNS[0], SPREAD_COLUMNS[1]])?;
            let n = if has(SPREAD_COLUMNS[2]) {
                let [n] = crate::matfile::columns(&vars, [SPREAD_COLUMNS[2]])?;
                Some(n)
            } else {
                None
            };
            t.spread_se = Some(spread_se(&gs, &ps, n.as_deref(), row)?);
        }
        return Ok(t);
    }
    let text = read_text(path)?;
    parse(&text, columns, units, weight_column).map_err(|e| match e {
        Error::Data(m) => Error::Data(format!("{}: {m}", path.display())),
        e => e,
    })
}
