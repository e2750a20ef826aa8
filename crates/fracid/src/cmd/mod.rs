//! The subcommands, one module each.

pub mod compare;
pub mod demo;
pub mod demo_autotune;
pub mod demo_loop;
pub mod diagnose;
pub mod drive;
pub mod drive_autotune;
pub mod drive_io;
pub mod drive_loop;
pub mod export;
pub mod fleet;
pub mod freq;
pub mod model_in;
pub mod paths;
pub mod score;
pub mod sim;
pub mod time;
pub mod tune;

pub use crate::bad_input::BadInput;

/// Read a time record with the library's reader ([`ident::data::Record::load`], whose errors
/// name the file).
///
/// # Errors
/// Those of [`ident::data::Record::load`].
pub fn load_record(
    path: &std::path::Path,
    opts: &ident::data::ReadOptions,
) -> anyhow::Result<ident::data::Loaded> {
    Ok(ident::data::Record::load(path, opts)?)
}

/// Read a text file (a model, a JSON report, weights, a table) with the library's bounded reader
/// ([`ident::files::read_text`]: at most [`ident::files::MAX_FILE_BYTES`], no line longer than
/// [`ident::files::MAX_LINE_BYTES`], UTF-8), so that `/dev/zero` or a huge file is refused after
/// one limit's worth of reading instead of filling memory. Every file the CLI reads as text goes
/// through here or [`load_record`].
///
/// # Errors
/// An I/O error naming the file (exit 3); a file too large, a line too long, a binary or non-UTF-8
/// file (exit 2, in the context of the file).
pub fn read_text(path: &std::path::Path) -> anyhow::Result<String> {
    Ok(ident::files::read_text(path)?)
}

/// A flag's words parsed into the library's type (`--structure`, `--offsets`, `--approx`, ...):
/// clap reports a word the type does not take (exit 2) with the library's own message.
///
/// # Errors
/// The type's parse error, in words.
pub fn parse_word<T>(s: &str) -> Result<T, String>
where
    T: std::str::FromStr,
    T::Err: Into<ident::Error>,
{
    s.parse().map_err(|e: T::Err| match e.into() {
        ident::Error::Options(m) => m,
        e => e.to_string(),
    })
}

/// `--order N` (approximation order) parsed and checked against the one range shared with
/// Python ([`fracsim::approx::ORDER_RANGE`]): clap reports a value outside it (exit 2).
///
/// # Errors
/// Not a whole number, or outside the range.
pub fn parse_order(s: &str) -> Result<usize, String> {
    let n: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a whole number"))?;
    fracsim::approx::check_order(n).map_err(|e| e.to_string())
}
