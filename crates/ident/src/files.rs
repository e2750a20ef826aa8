//! Bounded reading of input files: a text table or a binary file read whole, refused (with
//! the file, the line and the byte where it is) when it is larger than [`MAX_FILE_BYTES`], has a
//! line longer than [`MAX_LINE_BYTES`], a NUL byte or invalid UTF-8, so that `/dev/zero` or a
//! multi-gigabyte file costs at most one limit's worth of reading and a binary file is not dumped
//! into a message. The record readers ([`crate::data`], [`crate::matfile`], [`crate::bodefile`])
//! read through it.

use crate::par::Par;
use crate::{Error, Result};

/// `s` as it may be quoted in a message: at most 40 characters, a longer text cut with its length
/// said (a 300-digit number or a whole binary file is not dumped into an error).
pub fn shorten(s: &str) -> String {
    const MAX: usize = 40;
    let n = s.chars().count();
    if n <= MAX {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX - 8).collect();
        format!("{head}... ({n} characters)")
    }
}

/// The largest file the readers take (bytes): a bigger one is refused before it fills memory.
pub const MAX_FILE_BYTES: u64 = 512 << 20;
/// The longest line of a text table (bytes): a longer one is binary data or a device such as
/// `/dev/zero`, refused after this much is read.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Read a text table from `path`, bounded: at most [`MAX_FILE_BYTES`], no line longer than
/// [`MAX_LINE_BYTES`], UTF-8 with no NUL byte (a binary file is refused, not dumped into a
/// message). Reading stops at the first violation, so `/dev/zero` or a multi-gigabyte file costs
/// at most one limit's worth of reading.
///
/// # Errors
/// [`Error::Io`] when the file cannot be opened or read; an [`Error::File`] of an
/// [`Error::Data`] for a file too large, a line too long, a NUL byte or invalid UTF-8 (with the
/// line and byte where it is).
pub fn read_text(path: &std::path::Path) -> Result<String> {
    read_text_scanned(path).map(|(text, _)| text)
}

/// [`read_text`], and whether the text holds a `#` (a comment: without one there is no
/// acquisition header or footer to look for). A large text is checked (NUL bytes, UTF-8, `#`) in
/// two halves on two threads.
pub(crate) fn read_text_scanned(path: &std::path::Path) -> Result<(String, bool)> {
    let (bytes, scanned) = read_scanned(path, true)?;
    if let Some(hash) = scanned {
        // SAFETY: `TextScan` found every byte read valid UTF-8 as it was read (and no character
        // cut at the end).
        return Ok((unsafe { String::from_utf8_unchecked(bytes) }, hash));
    }
    if let Some(hash) = checked_in_halves(&bytes) {
        // SAFETY: `checked_in_halves` found both halves valid UTF-8, and they meet at a line
        // feed (an ASCII byte, so at a character boundary): the whole is valid UTF-8.
        return Ok((unsafe { String::from_utf8_unchecked(bytes) }, hash));
    }
    if let Some(pos) = memchr::memchr(0, &bytes) {
        return Err(nul_byte(path, &bytes, pos));
    }
    let hash = memchr::memchr(b'#', &bytes).is_some();
    let text = String::from_utf8(bytes)
        .map_err(|e| not_utf8(path, e.as_bytes(), e.utf8_error().valid_up_to()))?;
    Ok((text, hash))
}

/// Where byte `pos` of `bytes` is, for a message: its line and byte.
fn position(bytes: &[u8], pos: usize) -> String {
    let line = 1 + memchr::memchr_iter(b'\n', &bytes[..pos]).count();
    format!("line {line}, byte {pos}")
}

/// The error for a NUL byte at `pos` of the bytes read so far.
fn nul_byte(path: &std::path::Path, bytes: &[u8], pos: usize) -> Error {
    Error::Data(format!(
        "not a text table: a NUL byte at {} (a binary file? MATLAB files must end in .mat; \
         UTF-16 text must be saved as UTF-8)",
        position(bytes, pos)
    ))
    .in_file(path)
}

/// The error for a byte at `pos` that is not UTF-8.
fn not_utf8(path: &std::path::Path, bytes: &[u8], pos: usize) -> Error {
    Error::Data(format!(
        "not UTF-8 text: invalid byte at {} (save it as UTF-8, or is it a binary file?)",
        position(bytes, pos)
    ))
    .in_file(path)
}

/// The text checks made as the bytes are read, one read after another, so that a binary stream
/// (`/dev/urandom`, a pipe, a FIFO) is refused at the read that brings its first NUL byte or
/// invalid UTF-8, not after [`MAX_FILE_BYTES`] of it: no NUL byte, UTF-8 (a character cut by
/// the end of a read is checked with the next), and whether a `#` was seen.
#[derive(Default)]
struct TextScan {
    /// The bytes checked (the rest: the start of a character the next read completes).
    checked: usize,
    hash: bool,
}

impl TextScan {
    /// Check the bytes of `out` read since the last call.
    fn scan(&mut self, path: &std::path::Path, out: &[u8]) -> Result<()> {
        let new = &out[self.checked..];
        if let Some(i) = memchr::memchr(0, new) {
            return Err(nul_byte(path, out, self.checked + i));
        }
        self.hash = self.hash || memchr::memchr(b'#', new).is_some();
        match std::str::from_utf8(new) {
            Ok(_) => self.checked = out.len(),
            // a character cut by the read's end: checked with the next read
            Err(e) if e.error_len().is_none() => self.checked += e.valid_up_to(),
            Err(e) => return Err(not_utf8(path, out, self.checked + e.valid_up_to())),
        }
        Ok(())
    }

    /// At the end of the bytes: whether they hold a `#`, or the error of a character cut short.
    fn finish(self, path: &std::path::Path, out: &[u8]) -> Result<bool> {
        if self.checked < out.len() {
            return Err(not_utf8(path, out, self.checked));
        }
        Ok(self.hash)
    }
}

/// Texts of at least this many bytes are checked in two halves on two threads.
const PARALLEL_CHECK_BYTES: usize = 1 << 20;

/// For a large text on a machine with two cores (reading runs before any fit, so on the
/// process's whole width, [`Par::available`]): `Some(holds a '#')` when both halves (split at a
/// line feed) hold no NUL byte and are valid UTF-8; `None` when a half is not (the caller then
/// finds and reports the fault) or the text is small.
fn checked_in_halves(b: &[u8]) -> Option<bool> {
    let par = Par::available();
    if b.len() < PARALLEL_CHECK_BYTES || par.width() < 2 {
        return None;
    }
    let cut = b.len() / 2 + memchr::memchr(b'\n', &b[b.len() / 2..])? + 1;
    let check = |h: &[u8]| -> Option<bool> {
        (memchr::memchr(0, h).is_none() && std::str::from_utf8(h).is_ok())
            .then(|| memchr::memchr(b'#', h).is_some())
    };
    let (first, second) = par.join(|_| check(&b[..cut]), |_| check(&b[cut..]));
    Some(first? || second?)
}

/// The bytes of `path`, at most [`MAX_FILE_BYTES`] of them; with `lines`, also no more than
/// [`MAX_LINE_BYTES`] without a line end (`\n` or `\r`).
///
/// # Errors
/// As [`read_text`].
pub(crate) fn read_bytes(path: &std::path::Path, lines: bool) -> Result<Vec<u8>> {
    read_scanned(path, lines).map(|(bytes, _)| bytes)
}

/// [`read_bytes`]; with `lines` (a text), a stream (a device, a pipe, a FIFO) is also checked as
/// it arrives ([`TextScan`]: refused at the first NUL byte or invalid UTF-8) and `Some(holds a
/// '#')` returned; `None` when the text is still to be checked (a regular file, bounded by its
/// size, or not `lines`).
fn read_scanned(path: &std::path::Path, lines: bool) -> Result<(Vec<u8>, Option<bool>)> {
    use std::io::Read;
    let io = |source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut size = 0;
    if let Ok(m) = file.metadata() {
        if m.is_dir() {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "it is a directory",
            )));
        }
        if m.len() > MAX_FILE_BYTES {
            return Err(too_large(path));
        }
        size = m.len() as usize;
    }
    const CHUNK: usize = 1 << 16;
    if size >= PARALLEL_READ_BYTES {
        if let Some(out) = read_halves(&file, size) {
            if lines {
                if let Some(p) = first_long_run(&out) {
                    // The line the byte-by-byte reading reports: the lines before the read of
                    // `CHUNK` bytes where the run grows too long.
                    return Err(long_line(path, &out[..p / CHUNK * CHUNK]));
                }
            }
            return Ok((out, None));
        }
    }
    // A stream (a device, a pipe, a FIFO: no size known) is checked as it is read; a regular
    // file, bounded by its size, after (on two threads when large).
    let stream = !file.metadata().is_ok_and(|m| m.is_file());
    let mut scan = TextScan::default();
    let mut r = file.take(MAX_FILE_BYTES + 1);
    // Read straight into the result, sized for the file (a device or a pipe grows it).
    let mut out: Vec<u8> = Vec::with_capacity(size + CHUNK);
    let mut run = 0usize; // bytes since the last line end
    loop {
        let filled = out.len();
        out.resize(filled + CHUNK, 0);
        let n = match r.read(&mut out[filled..]) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {
                out.truncate(filled);
                continue;
            }
            Err(e) => return Err(io(e)),
        };
        out.truncate(filled + n);
        if n == 0 {
            break;
        }
        if lines {
            // A run of bytes with no line end (`\n` or `\r`) longer than the limit: only the one
            // that goes on from the previous read can be (a read is shorter than the limit).
            let chunk = &out[filled..];
            let is_end = |b: &u8| *b == b'\n' || *b == b'\r';
            run += chunk.iter().position(is_end).unwrap_or(n);
            if run > MAX_LINE_BYTES {
                return Err(long_line(path, &out[..filled]));
            }
            if let Some(last) = chunk.iter().rposition(is_end) {
                run = n - 1 - last;
            }
            if stream {
                scan.scan(path, &out)?;
            }
        }
        if out.len() as u64 > MAX_FILE_BYTES {
            return Err(too_large(path));
        }
    }
    let hash = if lines && stream {
        Some(scan.finish(path, &out)?)
    } else {
        None
    };
    Ok((out, hash))
}

/// Regular files of at least this many bytes are read in two halves on two threads.
const PARALLEL_READ_BYTES: usize = 8 << 20;

/// The `size` bytes of a regular file, read in two halves (positioned reads: the file's cursor
/// is not moved) on two threads of the process's width ([`Par::available`]: reading runs before
/// any fit; two reads in flight copy from the page cache on two cores), or `None` when that
/// fails or the file is not `size` bytes long (it changed): the caller then reads it from the
/// start, one read after another.
#[cfg(unix)]
fn read_halves(file: &std::fs::File, size: usize) -> Option<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    if !file.metadata().ok()?.is_file() {
        return None;
    }
    let mut out = vec![0u8; size];
    let half = size / 2;
    let (a, b) = out.split_at_mut(half);
    let (first, second) = Par::available().join(
        |_| file.read_exact_at(a, 0).is_ok(),
        |_| file.read_exact_at(b, half as u64).is_ok(),
    );
    let ok = first && second;
    let mut probe = [0u8; 1];
    (ok && matches!(file.read_at(&mut probe, size as u64), Ok(0))).then_some(out)
}

#[cfg(not(unix))]
fn read_halves(_file: &std::fs::File, _size: usize) -> Option<Vec<u8>> {
    None
}

/// Where the first run of more than [`MAX_LINE_BYTES`] bytes with no line end (`\n` or `\r`)
/// grows too long (the index of its byte `MAX_LINE_BYTES + 1`), if there is one. Windows of
/// `MAX_LINE_BYTES + 1` bytes are searched from their end for the last line end, so a table is
/// checked in a few searches, not line by line.
fn first_long_run(b: &[u8]) -> Option<usize> {
    let mut start = 0; // the first byte after the last line end
    loop {
        let lim = (start + MAX_LINE_BYTES + 1).min(b.len());
        match memchr::memrchr2(b'\n', b'\r', &b[start..lim]) {
            Some(i) => start += i + 1,
            None if lim - start > MAX_LINE_BYTES => return Some(start + MAX_LINE_BYTES),
            None => return None,
        }
        if lim == b.len() {
            return None;
        }
    }
}

/// The error for a line longer than [`MAX_LINE_BYTES`] that starts after the bytes `before`.
fn long_line(path: &std::path::Path, before: &[u8]) -> Error {
    Error::Data(format!(
        "line {} is longer than {} bytes: not a text table (a binary file or a device?)",
        1 + memchr::memchr_iter(b'\n', before).count(),
        MAX_LINE_BYTES
    ))
    .in_file(path)
}

fn too_large(path: &std::path::Path) -> Error {
    Error::Data(format!(
        "larger than {} MiB: refused (split or decimate the record)",
        MAX_FILE_BYTES >> 20
    ))
    .in_file(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Acquisition, ReadOptions, Record};

    #[test]
    fn long_runs_are_found_where_the_byte_by_byte_count_finds_them() {
        // The count of the reading loop, byte by byte.
        let reference = |b: &[u8]| {
            let mut run = 0usize;
            for (i, &c) in b.iter().enumerate() {
                run = if c == b'\n' || c == b'\r' { 0 } else { run + 1 };
                if run > MAX_LINE_BYTES {
                    return Some(i);
                }
            }
            None
        };
        let m = MAX_LINE_BYTES;
        let mut cases: Vec<Vec<u8>> = vec![vec![], vec![b'a'; m], vec![b'a'; m + 1]];
        let mut lines = b"t,u,y\n".repeat(1 + 3 * m / 6);
        cases.push(lines.clone());
        lines[m + 10] = b'\r';
        cases.push(lines.clone());
        // A run of exactly the limit, then of one more, between line ends.
        let mut v = vec![b'\n'; 3];
        v.extend(vec![b'x'; m]);
        v.push(b'\r');
        cases.push(v.clone());
        v.extend(vec![b'y'; m + 1]);
        v.extend(b"\n12");
        cases.push(v.clone());
        let mut w = b"1,2\n".repeat(m / 2);
        w.extend(vec![b'z'; m + 5]);
        cases.push(w);
        for c in &cases {
            assert_eq!(first_long_run(c), reference(c), "{} bytes", c.len());
        }
        assert!(cases.iter().filter(|c| reference(c).is_some()).count() >= 3);
    }

    #[test]
    fn a_large_file_is_read_whole_in_halves() {
        let dir = std::env::temp_dir().join(format!("ident-halves-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("big.csv");
        let mut text = String::from("t,u,y\n");
        let mut k = 0usize;
        while text.len() < PARALLEL_READ_BYTES + 12_345 {
            text += &format!("{k},{},{}\n", k % 7, k % 13);
            k += 1;
        }
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read_text(&path).unwrap(), text);
        // A line too long in the second half is refused.
        let mut long = text.clone().into_bytes();
        let at = long.len() - MAX_LINE_BYTES - 100;
        long.splice(at..at, vec![b'x'; MAX_LINE_BYTES + 1]);
        std::fs::write(&path, &long).unwrap();
        let e = read_text(&path).unwrap_err().report();
        assert!(e.contains("is longer than"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A text checked in halves on two threads: read as it is, with whether it holds a `#`;
    /// a NUL byte or invalid UTF-8 in either half is reported where it is, as the one-pass check
    /// reports it; an acquisition footer in a large file is still found.
    #[test]
    fn a_large_text_is_checked_in_halves() {
        let dir = std::env::temp_dir().join(format!("ident-check-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("big.csv");
        let mut text = String::from("t,u,y\n");
        let mut k = 0usize;
        while text.len() < 3 * PARALLEL_CHECK_BYTES {
            text += &format!("{},{},{}\n", k as f64 * 1e-3, k % 7, k % 13);
            k += 1;
        }
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read_text_scanned(&path).unwrap(), (text.clone(), false));
        let n = text.len();
        for (at, bad, what) in [
            (n / 4, 0u8, "NUL byte"),
            (3 * n / 4, 0u8, "NUL byte"),
            (n / 4, 0xff, "not UTF-8"),
            (3 * n / 4, 0xff, "not UTF-8"),
        ] {
            let mut b = text.clone().into_bytes();
            b[at] = bad;
            std::fs::write(&path, &b).unwrap();
            let e = read_text(&path).unwrap_err().report();
            let line = 1 + b[..at].iter().filter(|&&c| c == b'\n').count();
            assert!(
                e.contains(what) && e.contains(&format!("line {line}, byte {at}")),
                "{e}"
            );
        }
        // A footer at the end: found (the `#` is seen by the second half's check).
        let mut footed = text.clone();
        footed += &format!("# complete: {k} samples\n");
        std::fs::write(&path, &footed).unwrap();
        assert!(read_text_scanned(&path).unwrap().1);
        let l = Record::load(&path, &ReadOptions::default()).unwrap();
        assert_eq!(l.acquisition, Acquisition::Complete);
        // An interrupted acquisition (its header, no footer) is still cut and warned about.
        std::fs::write(&path, format!("# fracid drive acquisition\n{text}")).unwrap();
        let l = Record::load(&path, &ReadOptions::default()).unwrap();
        assert_eq!(l.acquisition, Acquisition::Interrupted);
        std::fs::remove_dir_all(&dir).ok();
    }
}
