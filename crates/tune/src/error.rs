//! The error type of `tune`.

/// Errors of a design: bad requests, specifications no controller of the form can meet, and the
/// simulator's errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A request that is malformed (a non-positive crossover, a phase margin outside (0, 180)
    /// degrees, an option the form does not take...): bad input.
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// Which quantity.
        what: &'static str,
        /// Why it is invalid.
        msg: String,
    },
    /// A well-formed specification that no controller of the form meets, with the reason: the
    /// design is refused rather than returned missing it.
    #[error("impossible specification: {0}")]
    Infeasible(String),
    /// A given controller's loop that misses stability or a robustness floor (`fracid tune
    /// --analyse`): the analysis stands, the loop is not one to run.
    #[error("the loop misses: {0}")]
    Unsafe(String),
    /// An error of the simulator (the model, its approximation or discretisation).
    #[error(transparent)]
    Sim(#[from] fracsim::Error),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

pub(crate) fn invalid<T>(what: &'static str, msg: impl Into<String>) -> Result<T> {
    Err(Error::Invalid {
        what,
        msg: msg.into(),
    })
}

pub(crate) fn infeasible<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Infeasible(msg.into()))
}
