//! The subcommands, one module each.

pub mod compare;
pub mod demo;
pub mod diagnose;
pub mod drive;
pub mod export;
pub mod fleet;
pub mod freq;
pub mod score;
pub mod sim;
pub mod time;
pub mod tune;

/// Bad user input found by the CLI itself (as opposed to the library crates): exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Return early with a [`BadInput`] error.
#[macro_export]
macro_rules! bad_input {
    ($($arg:tt)*) => {
        return Err(anyhow::Error::new($crate::cmd::BadInput(format!($($arg)*))))
    };
}

/// Read a time record with the library's reader ([`ident::data::Record::load`]): a data error is
/// put in the context of the file; an I/O error already names it.
///
/// # Errors
/// Those of [`ident::data::Record::load`].
pub fn load_record(
    path: &std::path::Path,
    opts: &ident::data::ReadOptions,
) -> anyhow::Result<ident::data::Loaded> {
    ident::data::Record::load(path, opts).map_err(|e| match e {
        ident::Error::Io { .. } => anyhow::Error::new(e),
        e if e.to_string().contains(&path.display().to_string()) => anyhow::Error::new(e),
        e => anyhow::Error::new(e).context(format!("in {}", path.display())),
    })
}
