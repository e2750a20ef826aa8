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

/// A run's standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A run's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run's standard output parsed as JSON (a parse failure shows its standard error).
pub fn json(o: &Output) -> serde_json::Value {
    serde_json::from_str(&stdout(o)).unwrap_or_else(|e| panic!("{e}: {}", stderr(o)))
}
