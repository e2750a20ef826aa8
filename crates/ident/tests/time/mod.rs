//! Time-domain identification tests (output error, `ident::oe`, `ident::data`, `ident::metrics`).

mod bad_input;
mod cell;
mod feedthrough;
mod general;
mod held;
mod history;
mod readers;
mod records;
mod roundtrip;
mod scale;
mod sensitivity;
mod starts;
mod steps;
mod sweep;
mod truth;
mod two_mass;
