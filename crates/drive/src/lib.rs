#![doc = include_str!("../PROTOCOL.md")]

pub mod bode;
pub mod cfw;
pub mod client;
pub mod codec;
mod error;
pub mod prbs;
pub mod protocol;
pub mod sim;

pub use error::{Error, Result};
