//! The error type of `ident`.

/// Errors from identification: bad data, bad options, numerical breakdown.
///
/// A fit that runs but does not converge is *not* an error: its report says so.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The data are unusable (NaN, unsorted or repeated frequencies, non-uniform time, ...).
    #[error("invalid data: {0}")]
    Data(String),
    /// Fewer data points than unknowns, or no excitation.
    #[error("not enough information in the data: {0}")]
    NotEnoughData(String),
    /// An option or starting value is out of range.
    #[error("invalid option: {0}")]
    Options(String),
    /// A linear solve or a simulation broke down.
    #[error("numerical breakdown: {0}")]
    Numerical(String),
    /// A file that cannot be opened or read (the operating system's reason in words).
    #[error("cannot read {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// Why, as the operating system says it.
        reason: String,
    },
    /// The observer asked to stop ([`crate::app::observe::Observe::cancelled`]); where.
    #[error("cancelled {0}")]
    Cancelled(String),
    /// An error from the simulation layer.
    #[error(transparent)]
    Sim(#[from] fracsim::Error),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
