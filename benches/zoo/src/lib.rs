//! The benchmark zoo: hundreds of generated drives whose truth is computed by code that shares
//! nothing with fracsim (`truth`), the cases drawn from them (`cases`) and the scoreboard that
//! judges fracid's reports against that truth (`score`), run by `run` (the `zoo` binary) and, on a
//! fixed subset with floors, by `cargo test` (`ci`). See benches/README.md for the table and the
//! command that makes it.

pub mod cases;
pub mod ci;
pub mod run;
pub mod score;
pub mod truth;
