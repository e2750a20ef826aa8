//! Integration tests of `ident`.

mod diagnose;
mod freq;
mod time;
