//! The crate's error type.

use crate::protocol::FrameError;
use std::ops::Range;

/// Everything that can go wrong in the drive crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A frame failed to decode (COBS, header, length or CRC). Carries a short description.
    #[error("bad frame: {0}")]
    Frame(#[from] FrameError),
    /// An I/O error on the serial port or a file.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The serial port could not be opened or configured.
    #[error("serial port {path}: {source}")]
    Port {
        /// The port path.
        path: String,
        /// The underlying error.
        source: serialport::Error,
    },
    /// The drive did not answer a command after all retries.
    #[error("drive did not answer {what} after {attempts} attempts")]
    Timeout {
        /// The command that went unanswered.
        what: &'static str,
        /// How many times it was sent.
        attempts: u32,
    },
    /// The drive rejected a command.
    #[error("drive rejected {what}: {}", nak_text(*code, *detail))]
    Nak {
        /// The rejected command.
        what: &'static str,
        /// The NAK code.
        code: crate::protocol::NakCode,
        /// The NAK detail field.
        detail: u16,
    },
    /// The drive speaks another protocol version.
    #[error(
        "the drive speaks protocol version {drive}, this host speaks {host}: frames of the other \
         version are ignored on both sides (version 2 changed SINE_RESULT); update the drive's \
         firmware or use a host of the drive's version"
    )]
    Version {
        /// The drive's version.
        drive: u8,
        /// Ours.
        host: u8,
    },
    /// The drive reset (its boot id changed) and lost its state.
    #[error("drive reset (boot id {old:#06x} -> {new:#06x})")]
    DriveReset {
        /// Boot id before.
        old: u16,
        /// Boot id after.
        new: u16,
    },
    /// An invalid parameter (host side).
    #[error("invalid parameter: {0}")]
    InvalidParam(String),
    /// A numerical computation on the host did not succeed (an eigenvalue iteration that did
    /// not converge).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The drive answered with something unexpected.
    #[error("protocol violation: {0}")]
    Protocol(String),
    /// A run ended with samples missing (used where a complete run is required).
    #[error("incomplete run: missing {missing:?}")]
    Incomplete {
        /// Missing sample ranges.
        missing: Vec<Range<u64>>,
    },
}

/// The crate's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A NAK's code and detail in words: a latched fault by its name.
fn nak_text(code: crate::protocol::NakCode, detail: u16) -> String {
    use crate::protocol::{spec::fault, NakCode};
    match code {
        NakCode::Fault => {
            let name = match u8::try_from(detail) {
                Ok(fault::ESTOP) => "emergency stop",
                Ok(fault::KEEPALIVE) => {
                    "keepalive expired (the host's KEEPALIVE frames stopped arriving in time)"
                }
                Ok(fault::SPEED_LIMIT) => "speed trip",
                Ok(fault::CURRENT_LIMIT) => "current trip",
                _ => "unknown fault",
            };
            format!("a fault is latched: {name} (fault code {detail}; CONFIGURE clears it)")
        }
        NakCode::BadValue => format!("a field out of range (at payload offset {detail})"),
        other => format!("{other:?} (detail {detail})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{spec::fault, NakCode};

    #[test]
    fn a_latched_fault_is_named() {
        let e = Error::Nak {
            what: "START_SINE",
            code: NakCode::Fault,
            detail: fault::KEEPALIVE.into(),
        };
        let text = e.to_string();
        assert!(
            text.starts_with("drive rejected START_SINE: a fault is latched: keepalive expired"),
            "{text}"
        );
        let e = Error::Nak {
            what: "CONFIGURE",
            code: NakCode::BadValue,
            detail: 4,
        };
        assert!(e
            .to_string()
            .ends_with("a field out of range (at payload offset 4)"));
    }
}
