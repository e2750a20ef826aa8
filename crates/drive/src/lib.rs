#![doc = include_str!("../PROTOCOL.md")]

pub mod bode;
pub mod cfw;
pub mod client;
pub mod codec;
pub mod ctrl;
pub mod ctrl_header;
mod error;
pub mod prbs;
pub mod protocol;
pub mod sim;
pub mod vclock;

pub use error::{Error, Result};
