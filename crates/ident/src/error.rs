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
    /// The structure has no start in these data (the two-mass structure without a resonance in
    /// the record's frequency response): said as [`Error::NotEnoughData`], told apart because
    /// it is decided before any iteration, so that a fit with a larger iteration budget fails
    /// the same way (the structure comparison does not fit it again).
    #[error("not enough information in the data: {0}")]
    NoStart(String),
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

impl Error {
    /// What went wrong without the variant's leading words (`"invalid data: "`, ...): for a
    /// message that wraps another error's reason. An I/O error keeps its path, a simulation
    /// error its own words.
    ///
    /// ```
    /// let e = ident::Error::NotEnoughData("no resonance".into());
    /// assert_eq!(e.detail(), "no resonance");
    /// assert_eq!(e.to_string(), "not enough information in the data: no resonance");
    /// ```
    #[must_use]
    pub fn detail(&self) -> String {
        match self {
            Self::Data(m)
            | Self::NotEnoughData(m)
            | Self::NoStart(m)
            | Self::Options(m)
            | Self::Numerical(m)
            | Self::Cancelled(m) => m.clone(),
            Self::Io { .. } | Self::Sim(_) => self.to_string(),
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
