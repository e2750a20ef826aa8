//! End-to-end tests of the `fracid` binary, one module per subcommand.

mod compare;
mod drive_autotune;
#[path = "../../ident/tests/exact/mod.rs"]
mod exact;
mod export;
mod fleet;
mod freq;
mod reliability;
mod time;
mod tune;

use std::process::{Command, Output};

/// Run the built `fracid` with `args`.
pub fn fracid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fracid"))
        .args(args)
        .output()
        .expect("the fracid binary runs")
}
