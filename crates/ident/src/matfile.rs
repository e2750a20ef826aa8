//! MATLAB `.mat` files, level 5 (what MATLAB writes with `save -v6` and `-v7`, the default before
//! R2006b and still the default of `save` unless `-v7.3` is asked; also scipy's `savemat`):
//! numeric matrices (double, single, and the integer classes, real part; compressed variables
//! of `-v7` included), by name. Other classes (char, cell, struct, sparse, objects) are skipped.
//! `-v7.3` files are HDF5 and refused with a message saying how to save them; level 4 files are
//! refused too.
//!
//! Reference: MathWorks, "MAT-File Format", version 7 (2019), chapter 1 (level 5 MAT-files):
//! a 128-byte header (116 bytes of text, 8 of subsystem offset, version 0x0100 and the endian
//! indicator `IM`), then data elements, each an 8-byte tag (type, byte count) or a 4-byte
//! "small data element" tag, padded to 8 bytes; `miMATRIX` (14) holds array flags, dimensions,
//! name and the real (and imaginary) part; `miCOMPRESSED` (15) holds one zlib-compressed
//! element.
//!
//! Written by hand rather than with the `matfile` crate (0.5): that crate inflates compressed
//! variables without a size limit and brings `nom` and `libflate`; this one bounds every size
//! by the file's and needs only `miniz_oxide`, already in the build through the PNG encoder.
//!
//! ```
//! // a 1x3 double vector "u" = [1, 2, 3], uncompressed
//! let mut f = vec![b' '; 116];
//! f[..19].copy_from_slice(b"MATLAB 5.0 MAT-file");
//! f.extend([0u8; 8]);
//! f.extend([0x00, 0x01, b'I', b'M']);
//! let mut m = Vec::new();
//! m.extend(6u32.to_le_bytes()); m.extend(8u32.to_le_bytes()); // array flags
//! m.extend(6u32.to_le_bytes()); m.extend(0u32.to_le_bytes()); //   class double
//! m.extend(5u32.to_le_bytes()); m.extend(8u32.to_le_bytes()); // dimensions 1 x 3
//! m.extend(1i32.to_le_bytes()); m.extend(3i32.to_le_bytes());
//! m.extend((1u32 | (1 << 16)).to_le_bytes()); m.extend([b'u', 0, 0, 0]); // name, small
//! m.extend(9u32.to_le_bytes()); m.extend(24u32.to_le_bytes()); // miDOUBLE
//! for v in [1.0f64, 2.0, 3.0] { m.extend(v.to_le_bytes()); }
//! f.extend(14u32.to_le_bytes()); f.extend((m.len() as u32).to_le_bytes()); f.extend(m);
//! let vars = ident::matfile::parse(&f).unwrap();
//! assert_eq!(vars[0].name, "u");
//! assert_eq!(vars[0].data, vec![1.0, 2.0, 3.0]);
//! ```

use crate::files::{read_bytes, shorten};
use crate::{Error, Result};
use std::path::Path;

/// One numeric variable of a `.mat` file: its name, dimensions and real part (column-major, as
/// MATLAB stores it), converted to `f64`.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// The variable's name.
    pub name: String,
    /// Its dimensions (rows, columns, ...).
    pub dims: Vec<usize>,
    /// The real part, column-major.
    pub data: Vec<f64>,
    /// True when the variable has an imaginary part (not read).
    pub complex: bool,
}

/// True when `path` ends in `.mat` (any case).
pub fn is_mat(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mat"))
}

/// Read the numeric variables of a `.mat` file (at most [`crate::files::MAX_FILE_BYTES`]).
///
/// # Errors
/// [`Error::Io`] when it cannot be read; those of [`parse`] (with the file's name).
pub fn read(path: &Path) -> Result<Vec<Variable>> {
    let bytes = read_bytes(path, false)?;
    parse(&bytes).map_err(|e| match e {
        Error::Data(m) => Error::Data(format!("{}: {m}", path.display())),
        e => e,
    })
}

fn bad<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Data(msg.into()))
}

/// Byte order of the file.
#[derive(Clone, Copy)]
struct Endian {
    little: bool,
}

impl Endian {
    fn u32(self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        if self.little {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        }
    }
    fn u16(self, b: &[u8]) -> u16 {
        let a = [b[0], b[1]];
        if self.little {
            u16::from_le_bytes(a)
        } else {
            u16::from_be_bytes(a)
        }
    }
}

/// The decoded size every `.mat` file may reach (bytes): its variables as `f64` in all, and the
/// compressed ones inflated. A file may decode to at most this or [`DECODED_PER_FILE_BYTE`] times
/// its own size, whichever is larger, so that a small compressed file cannot fill memory (a few
/// hundred KiB of zlib inflate to gigabytes, and `int8` data widen 8 times to `f64`): a file
/// under 1 MB decodes to at most 16 MiB (two million values, a `u`, `y` record of a million
/// samples), and decoding holds at most twice the budget (the inflated bytes and their values)
/// besides the file.
pub const MIN_DECODED_BUDGET: usize = 16 << 20;
/// A file's decoded size may be this many times its size, when that is above
/// [`MIN_DECODED_BUDGET`]: an `int8` file widens 8 times to `f64`, twice that for one compressed
/// by half, so the large files real measurements make are read whole.
pub const DECODED_PER_FILE_BYTE: usize = 16;

/// The decoded size a file of `file_bytes` bytes may reach (see [`MIN_DECODED_BUDGET`]).
pub fn decoded_budget(file_bytes: usize) -> usize {
    MIN_DECODED_BUDGET.max(file_bytes.saturating_mul(DECODED_PER_FILE_BYTE))
}

/// What is left of a file's decoded-size budget ([`decoded_budget`]).
struct Budget {
    left: usize,
    whole: usize,
}

impl Budget {
    /// Take `bytes` from the budget, or the error that says the file decodes to too much.
    fn take(&mut self, bytes: usize) -> Result<()> {
        match self.left.checked_sub(bytes) {
            Some(l) => {
                self.left = l;
                Ok(())
            }
            None => bad(self.too_large()),
        }
    }

    fn too_large(&self) -> String {
        format!(
            "the .mat file decodes to more than {} MiB (its variables as 64-bit numbers, \
             compressed ones inflated: at most {} MiB or {DECODED_PER_FILE_BYTE} times the \
             file's size): save only the signals needed, or export a CSV",
            self.whole >> 20,
            MIN_DECODED_BUDGET >> 20
        )
    }
}

/// Parse the bytes of a level 5 `.mat` file into its numeric variables.
///
/// # Errors
/// [`Error::Data`] for a v7.3 (HDF5) or level 4 file, a truncated or malformed element, a
/// compressed variable that does not inflate, a file whose variables decode to more than
/// [`decoded_budget`] of its size (counted before anything is allocated).
pub fn parse(bytes: &[u8]) -> Result<Vec<Variable>> {
    if bytes.len() >= 8 && bytes.starts_with(b"\x89HDF") || looks_v73(bytes) {
        return bad(
            "a MATLAB v7.3 (HDF5) .mat file, which is not supported: save it with \
             save(file, ..., '-v7') (or -v6), or export a CSV",
        );
    }
    if bytes.len() < 128 || !bytes.starts_with(b"MATLAB 5.0 MAT-file") {
        return bad(
            "not a MATLAB level 5 .mat file (no 'MATLAB 5.0 MAT-file' header; level 4 files are \
             not supported): save it with save(file, ..., '-v7'), or export a CSV",
        );
    }
    let endian = match &bytes[126..128] {
        b"IM" => Endian { little: true },
        b"MI" => Endian { little: false },
        _ => return bad("bad endian indicator in the .mat header"),
    };
    let mut vars = Vec::new();
    let whole = decoded_budget(bytes.len());
    let mut budget = Budget { left: whole, whole };
    elements(&bytes[128..], endian, &mut vars, 0, &mut budget)?;
    Ok(vars)
}

/// A v7.3 file starts with the text header "MATLAB 7.3 MAT-file" and carries HDF5 at 512.
fn looks_v73(bytes: &[u8]) -> bool {
    bytes.starts_with(b"MATLAB 7.3 MAT-file")
        || (bytes.len() > 516 && &bytes[512..516] == b"\x89HDF")
}

/// One tag: (type, data, bytes consumed including padding).
///
/// The format's rules (MathWorks, "MAT-File Format", "Data Element Format" and "Small Data
/// Element Format"): a regular element is an 8-byte tag (type, byte count) and its data, padded
/// to a multiple of 8 bytes, except `miMATRIX` (14) and `miCOMPRESSED` (15), which are not
/// padded: a matrix's byte count is a multiple of 8 by construction (its sub-elements are
/// padded), a compressed element is the zlib stream's exact length (scipy's `savemat` and
/// MATLAB's `-v7` write e.g. 61 bytes and start the next element right after). A small element
/// packs the byte count (1..=4) in the upper 16 bits of the first 4-byte word and the type in the
/// lower 16, its data in the next 4 bytes: 8 bytes in all.
fn tag(b: &[u8], e: Endian) -> Result<(u32, &[u8], usize)> {
    if b.len() < 8 {
        return bad("truncated .mat file (a data element's tag is cut)");
    }
    let first = e.u32(&b[..4]);
    if first >> 16 != 0 {
        // small data element: bytes in the upper 16 bits, data in the next 4 bytes
        let n = (first >> 16) as usize;
        if n > 4 {
            return bad("malformed .mat file (a small data element of more than 4 bytes)");
        }
        return Ok((first & 0xffff, &b[4..4 + n], 8));
    }
    let n = e.u32(&b[4..8]) as usize;
    if n > b.len() - 8 {
        return bad(format!(
            "truncated .mat file (an element of {n} bytes, {} left)",
            b.len() - 8
        ));
    }
    let used = if first == MI_MATRIX || first == MI_COMPRESSED {
        8 + n
    } else {
        ((8 + n).div_ceil(8) * 8).min(b.len())
    };
    Ok((first, &b[8..8 + n], used))
}

/// `miMATRIX`: one variable.
const MI_MATRIX: u32 = 14;
/// `miCOMPRESSED`: one zlib-compressed element.
const MI_COMPRESSED: u32 = 15;

/// Where the top-level element after one of `used` bytes starts. Writers that pad the
/// compressed element to 8 bytes (which the format does not ask) are read too: when the bytes
/// up to the padded end are zeros and no element tag starts right after the unpadded end,
/// the padding is skipped.
fn next_top_level(b: &[u8], used: usize, e: Endian) -> usize {
    let padded = used.div_ceil(8) * 8;
    if padded == used || padded > b.len() || b[used..padded].iter().any(|&x| x != 0) {
        return used;
    }
    let starts_element = b.len() >= used + 8 && {
        let ty = e.u32(&b[used..used + 4]);
        ty == MI_MATRIX || ty == MI_COMPRESSED
    };
    if starts_element {
        used
    } else {
        padded
    }
}

fn elements(
    mut b: &[u8],
    e: Endian,
    vars: &mut Vec<Variable>,
    depth: usize,
    budget: &mut Budget,
) -> Result<()> {
    while b.len() >= 8 {
        let (ty, data, used) = tag(b, e)?;
        match ty {
            MI_MATRIX => {
                if let Some(v) = matrix(data, e, budget)? {
                    vars.push(v);
                }
            }
            MI_COMPRESSED => {
                if depth > 0 {
                    return bad("malformed .mat file (compressed data inside compressed data)");
                }
                // Inflated within what is left of the budget; the inflated bytes are freed once
                // their values are decoded (themselves taken from the budget).
                let raw =
                    miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(data, budget.left)
                        .map_err(|err| {
                            Error::Data(match err.status {
                                miniz_oxide::inflate::TINFLStatus::HasMoreOutput => {
                                    budget.too_large()
                                }
                                _ => "a compressed variable of the .mat file does not inflate \
                                      (corrupt)"
                                    .into(),
                            })
                        })?;
                elements(&raw, e, vars, depth + 1, budget)?;
            }
            _ => {} // other top-level elements: skipped
        }
        b = &b[next_top_level(b, used, e)..];
    }
    Ok(())
}

/// A `miMATRIX` element: a numeric variable, or `None` for another class.
fn matrix(b: &[u8], e: Endian, budget: &mut Budget) -> Result<Option<Variable>> {
    if b.is_empty() {
        return Ok(None); // an empty matrix element (allowed by the format)
    }
    let (ty, flags, used) = tag(b, e)?;
    if ty != 6 || flags.len() < 8 {
        return bad("malformed .mat file (a matrix without array flags)");
    }
    let class = e.u32(&flags[..4]) & 0xff;
    let complex = e.u32(&flags[..4]) & 0x0800 != 0;
    // 6 double, 7 single, 8..15 the integer classes
    if !(6..=15).contains(&class) {
        return Ok(None);
    }
    let b = &b[used..];
    let (ty, dims_raw, used) = tag(b, e)?;
    if ty != 5 {
        return bad("malformed .mat file (a matrix without dimensions)");
    }
    let dims: Vec<usize> = dims_raw
        .chunks_exact(4)
        .map(|c| e.u32(c) as usize)
        .collect();
    let b = &b[used..];
    let (ty, name_raw, used) = tag(b, e)?;
    if ty != 1 && ty != 16 {
        return bad("malformed .mat file (a matrix without a name)");
    }
    let name = String::from_utf8_lossy(name_raw).into_owned();
    let b = &b[used..];
    let (ty, real, _) = tag(b, e)?;
    // The values as f64, counted against the file's budget before they are allocated.
    budget.take(real.len() / width(ty)? * std::mem::size_of::<f64>())?;
    let data = numbers(ty, real, e)?;
    let count = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
    if count != Some(data.len()) {
        return bad(format!(
            "malformed .mat file (variable '{}' has dimensions {dims:?} but {} values)",
            shorten(&name),
            data.len()
        ));
    }
    Ok(Some(Variable {
        name,
        dims,
        data,
        complex,
    }))
}

/// The bytes of one value of a numeric data element of type `ty`.
fn width(ty: u32) -> Result<usize> {
    Ok(match ty {
        1 | 2 => 1,
        3 | 4 => 2,
        5..=7 => 4,
        9 | 12 | 13 => 8,
        t => return bad(format!("malformed .mat file (numeric data of type {t})")),
    })
}

/// The values of a numeric data element of type `ty`, as `f64`.
fn numbers(ty: u32, b: &[u8], e: Endian) -> Result<Vec<f64>> {
    let le = e.little;
    macro_rules! conv {
        ($t:ty, $n:expr) => {
            b.chunks_exact($n)
                .map(|c| {
                    let a: [u8; $n] = c.try_into().unwrap_or([0; $n]);
                    (if le {
                        <$t>::from_le_bytes(a)
                    } else {
                        <$t>::from_be_bytes(a)
                    }) as f64
                })
                .collect()
        };
    }
    Ok(match ty {
        1 => b.iter().map(|&x| f64::from(x as i8)).collect(),
        2 => b.iter().map(|&x| f64::from(x)).collect(),
        3 => b
            .chunks_exact(2)
            .map(|c| f64::from(e.u16(c) as i16))
            .collect(),
        4 => b.chunks_exact(2).map(|c| f64::from(e.u16(c))).collect(),
        5 => conv!(i32, 4),
        6 => conv!(u32, 4),
        7 => conv!(f32, 4),
        9 => conv!(f64, 8),
        12 => conv!(i64, 8),
        13 => conv!(u64, 8),
        t => return bad(format!("malformed .mat file (numeric data of type {t})")),
    })
}

/// The vectors `wants` of a `.mat` file: each a variable of that name (a row or column vector),
/// or, when no variable has that name and it is a number, that 0-based column of the file's only
/// two-dimensional matrix (a record saved as one `N x k` array).
///
/// # Errors
/// [`Error::Data`] for a missing variable (listing those found), one that is not a vector, a
/// complex one, a column index without a single matrix to take it from, or vectors of different
/// lengths.
pub fn columns<const N: usize>(vars: &[Variable], wants: [&str; N]) -> Result<[Vec<f64>; N]> {
    let names: Vec<&str> = vars.iter().map(|v| v.name.as_str()).collect();
    let found = || {
        if names.is_empty() {
            "no numeric variable".to_string()
        } else {
            names
                .iter()
                .map(|n| shorten(n))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    let mut out: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    for (k, want) in wants.iter().enumerate() {
        let v = match vars.iter().find(|v| v.name == *want) {
            Some(v) => v,
            None => {
                let Ok(col) = want.parse::<usize>() else {
                    return bad(format!(
                        "no variable '{}' in the .mat file (found: {})",
                        shorten(want),
                        found()
                    ));
                };
                let mats: Vec<&Variable> = vars
                    .iter()
                    .filter(|v| v.dims.len() == 2 && v.dims[1] > 1 && v.dims[0] > 1)
                    .collect();
                let [m] = mats.as_slice() else {
                    return bad(format!(
                        "column {col} of which matrix? The .mat file has {} two-dimensional \
                         matrices (variables: {}): choose variables by name",
                        mats.len(),
                        found()
                    ));
                };
                let (rows, cols) = (m.dims[0], m.dims[1]);
                if col >= cols {
                    return bad(format!(
                        "no column {col}: the matrix '{}' has {cols} columns",
                        shorten(&m.name)
                    ));
                }
                out[k] = m.data[col * rows..(col + 1) * rows].to_vec();
                continue;
            }
        };
        if v.complex {
            return bad(format!(
                "variable '{}' is complex: a time record needs real samples",
                shorten(&v.name)
            ));
        }
        if v.dims.iter().filter(|&&d| d > 1).count() > 1 {
            return bad(format!(
                "variable '{}' is a {:?} matrix, not a vector: save each signal as a vector, or \
                 choose columns of the matrix by 0-based index",
                shorten(&v.name),
                v.dims
            ));
        }
        out[k] = v.data.clone();
    }
    // a variable chosen twice, as in the text reader
    for k in 1..N {
        if wants[..k].contains(&wants[k]) {
            return bad(format!("variable '{}' is chosen twice", shorten(wants[k])));
        }
    }
    if let Some(k) = (1..N).find(|&k| out[k].len() != out[0].len()) {
        return bad(format!(
            "'{}' has {} samples but '{}' has {}",
            shorten(wants[0]),
            out[0].len(),
            shorten(wants[k]),
            out[k].len()
        ));
    }
    Ok(out)
}
