//! Bad input is an error, never a panic.
