//! Integration tests of the drive crate: test vectors, codec properties, and end-to-end runs over
//! a real pseudo-terminal.

/// An end-to-end test run once on each firmware behind the pty, chosen explicitly: `NAME::rust`
/// (the simulator's own Rust firmware) and `NAME::c` (the C firmware of `firmware/`, linked in
/// through `drive::cfw`). The body sees the firmware as `$fw`.
macro_rules! on_both_firmwares {
    ($(#[doc = $doc:expr])* fn $name:ident($fw:ident) $body:block) => {
        $(#[doc = $doc])*
        mod $name {
            #[allow(unused_imports)]
            use super::*;

            fn run($fw: drive::sim::FirmwareKind) $body

            #[test]
            fn rust() {
                run(drive::sim::FirmwareKind::Rust)
            }

            #[test]
            fn c() {
                run(drive::sim::FirmwareKind::C)
            }
        }
    };
}

mod e2e;
mod e2e_control;
mod firmware_c;
mod loss;
mod models;
mod props;
mod sine;
mod spec;
mod vectors;
