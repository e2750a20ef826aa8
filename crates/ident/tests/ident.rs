//! Integration tests of `ident`.

mod time;
