//! Integration tests of `ident`.

mod freq;
mod time;
