//! Integration tests of the drive crate: test vectors, codec properties, and end-to-end runs over
//! a real pseudo-terminal.

mod e2e;
mod e2e_control;
mod firmware_c;
mod loss;
mod props;
mod sine;
mod vectors;
