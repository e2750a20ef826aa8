//! The error type of `autotune`.

/// Errors of the acquisitions and of an autotune run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A request out of range or not understood: bad input.
    #[error("{0}")]
    InvalidParam(String),
    /// The drive or its link failed.
    #[error("the drive: {0}")]
    Drive(#[source] drive::Error),
    /// The identification failed.
    #[error("the identification: {0}")]
    Ident(#[source] ident::Error),
    /// The tuner failed (not a refusal of a design: those are in the report).
    #[error("the tuner: {0}")]
    Tune(#[source] tune::Error),
    /// The run was interrupted (Ctrl-C, a signal): the drive was stopped.
    #[error("interrupted: {0}")]
    Interrupted(String),
    /// An experiment's record is unusable (incomplete, the speed trip, no response).
    #[error("{0}")]
    Experiment(String),
}

impl From<drive::Error> for Error {
    fn from(e: drive::Error) -> Self {
        match e {
            drive::Error::InvalidParam(m) => Error::InvalidParam(m),
            e => Error::Drive(e),
        }
    }
}

impl From<ident::Error> for Error {
    fn from(e: ident::Error) -> Self {
        Error::Ident(e)
    }
}

impl From<tune::Error> for Error {
    fn from(e: tune::Error) -> Self {
        Error::Tune(e)
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

pub(crate) fn invalid<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::InvalidParam(msg.into()))
}
