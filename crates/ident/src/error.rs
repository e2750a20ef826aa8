//! The error type of `ident`.

use std::path::PathBuf;

/// Errors from identification: bad data, bad options, numerical breakdown.
///
/// A fit that runs but does not converge is *not* an error: its report says so.
///
/// An error about a file says which file by its variant ([`Error::Io`], [`Error::File`]) and
/// keeps what went wrong as its [`source`](std::error::Error::source): the operating system's
/// error, or the error in the file's content. [`Error::report`] says it all in one line.
#[derive(Debug, thiserror::Error)]
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
    /// A file that cannot be opened or read.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why, as the operating system says it.
        #[source]
        source: std::io::Error,
    },
    /// What is wrong in a file's content (or in what it holds, for a reader that knows the
    /// file): the file, and the error as the content's reader said it.
    #[error("in {}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// The error in it.
        #[source]
        source: Box<Error>,
    },
    /// The observer asked to stop ([`crate::app::observe::Observe::cancelled`]); where.
    #[error("cancelled {0}")]
    Cancelled(String),
    /// An error from the simulation layer.
    #[error(transparent)]
    Sim(#[from] fracsim::Error),
}

impl Error {
    /// `self` in the context of the file `path`: an error that already names a file (an
    /// [`Error::Io`], an [`Error::File`]) as it is, any other wrapped in an [`Error::File`].
    #[must_use]
    pub fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            e @ (Self::Io { .. } | Self::File { .. }) => e,
            e => Self::File {
                path: path.to_path_buf(),
                source: Box::new(e),
            },
        }
    }

    /// The error that decides what kind of failure this is: the error in a file's content for
    /// an [`Error::File`], else `self`.
    ///
    /// ```
    /// let e = ident::Error::Data("no column 'y'".into()).in_file("r.csv".as_ref());
    /// assert!(matches!(e.innermost(), ident::Error::Data(_)));
    /// ```
    #[must_use]
    pub fn innermost(&self) -> &Self {
        match self {
            Self::File { source, .. } => source.innermost(),
            e => e,
        }
    }

    /// The error and its sources in one line, each after the one it explains (as `anyhow`
    /// prints a chain with `{:#}`).
    ///
    /// ```
    /// let e = ident::Error::Data("no column 'y'".into()).in_file("r.csv".as_ref());
    /// assert_eq!(e.to_string(), "in r.csv");
    /// assert_eq!(e.report(), "in r.csv: invalid data: no column 'y'");
    /// ```
    #[must_use]
    pub fn report(&self) -> String {
        let mut out = self.to_string();
        let mut cause = std::error::Error::source(self);
        while let Some(c) = cause {
            out.push_str(": ");
            out.push_str(&c.to_string());
            cause = c.source();
        }
        out
    }

    /// What went wrong without the variant's leading words (`"invalid data: "`, ...): for a
    /// message that wraps another error's reason. An error about a file keeps the file and its
    /// sources ([`Error::report`]), a simulation error its own words.
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
            Self::Io { .. } | Self::File { .. } | Self::Sim(_) => self.report(),
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
