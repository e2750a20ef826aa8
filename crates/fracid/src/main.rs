//! The `fracid` command line.
fn main() {}
