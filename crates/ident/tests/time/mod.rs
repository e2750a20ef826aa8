//! Time-domain identification tests (output error, `ident::oe`, `ident::data`, `ident::metrics`).

mod bad_input;
mod held;
mod records;
mod readers;
mod roundtrip;
mod sensitivity;
mod starts;
mod truth;
