//! Integration tests of `ident`.

mod diagnose;
mod exact;
mod freq;
mod time;
