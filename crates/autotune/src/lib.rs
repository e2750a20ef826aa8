//! The use-case layer of the drive commands: the acquisitions (`fracid drive prbs`, `sine`,
//! `loop`, and a step) as serde requests with their defaults once, each with one `run` returning
//! a typed record ([`acquire`]), the controller's realisation as the drive runs it
//! ([`realise`]), and `fracid drive autotune` ([`tuner`]): a probe, the identification
//! experiment designed from it, the experiments that separate what the diagnosis cannot tell
//! apart, the controller tuned on the final model and its step measured on the drive.
//!
//! It sits above `drive` (the client), `ident` (the identification and its diagnosis) and `tune`
//! (the controller): the loop's acquisition needs the tuner's realisation and the autotune all
//! three, while `drive` stays a protocol crate with no model of its own. The CLI and Python only
//! parse, call and present.

pub mod acquire;
mod error;
pub mod realise;
pub mod tuner;

pub use error::{Error, Result};
