//! Bad input gives clear errors or warnings, never a panic.
