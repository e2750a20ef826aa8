//! Bad user input found by the CLI itself (exit 2), and the macro that returns it.

/// Bad user input found by the CLI itself (as opposed to the library crates): exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Return early with a [`BadInput`] error.
#[macro_export]
macro_rules! bad_input {
    ($($arg:tt)*) => {
        return Err(anyhow::Error::new($crate::bad_input::BadInput(format!($($arg)*))))
    };
}
