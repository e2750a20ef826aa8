//! Framing: `0x00 | COBS(body) | 0x00`, body = `ver | type | seq | payload | crc16`.
//! Pure functions and a streaming decoder; no I/O.

use crate::protocol::FrameError;
use crate::protocol::{Frame, Message, PROTO_VERSION};
use crc::{Crc, CRC_16_MCRF4XX};

/// The frame CRC: CRC-16/MCRF4XX (check value 0x6F91).
pub const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_MCRF4XX);

/// Largest accepted body (header + payload + CRC), bytes.
pub const MAX_BODY: usize = 6 + 8 + 6 * crate::protocol::MAX_BLOCK_SAMPLES as usize;

/// Largest COBS-encoded body (without delimiters).
pub const MAX_ENCODED: usize = MAX_BODY + MAX_BODY / 254 + 1;

/// CRC-16/MCRF4XX of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

/// The frame body (unencoded): header, payload, CRC.
pub fn encode_body(frame: &Frame) -> Vec<u8> {
    encode_body_as(frame, PROTO_VERSION)
}

/// [`encode_body`] with another protocol version in the header: how a host probes a drive of an
/// earlier version (its HELLO has the same empty payload in every version).
pub fn encode_body_as(frame: &Frame, version: u8) -> Vec<u8> {
    let mut body = Vec::with_capacity(16);
    body.push(version);
    body.push(frame.msg.type_code());
    body.extend_from_slice(&frame.seq.to_le_bytes());
    frame.msg.write_payload(&mut body);
    let crc = crc16(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    body
}

/// The complete wire frame `0x00 | COBS(body) | 0x00`.
pub fn encode(frame: &Frame) -> Vec<u8> {
    wrap_body(&encode_body(frame))
}

/// Wrap an already-built body (with CRC) into `0x00 | COBS(body) | 0x00`.
pub fn wrap_body(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + body.len() / 254 + 3);
    out.push(0);
    out.extend_from_slice(&cobs::encode_vec(body));
    out.push(0);
    out
}

/// Decode an unencoded body (after COBS): check length, version, CRC, type and payload.
pub fn decode_body(body: &[u8]) -> Result<Frame, FrameError> {
    if body.len() > MAX_BODY {
        return Err(FrameError::TooLong);
    }
    if body.len() < 6 {
        return Err(FrameError::TooShort);
    }
    let (data, crc_bytes) = body.split_at(body.len() - 2);
    let crc = u16::from_le_bytes([crc_bytes[0], crc_bytes[1]]);
    if crc16(data) != crc {
        return Err(FrameError::Crc);
    }
    if data[0] != PROTO_VERSION {
        return Err(FrameError::Version(data[0]));
    }
    let ty = data[1];
    let seq = u16::from_le_bytes([data[2], data[3]]);
    let msg = Message::parse(ty, &data[4..])?;
    Ok(Frame { seq, msg })
}

/// Decode the bytes between two delimiters (COBS-encoded, no 0x00 inside). The encoding must be
/// canonical: it must re-encode to the same bytes.
pub fn decode_encoded(encoded: &[u8]) -> Result<Frame, FrameError> {
    if encoded.len() > MAX_ENCODED {
        return Err(FrameError::TooLong);
    }
    let body = cobs::decode_vec(encoded).map_err(|_| FrameError::Cobs)?;
    if cobs::encode_vec(&body) != encoded {
        return Err(FrameError::Cobs);
    }
    decode_body(&body)
}

/// Counters kept by a [`StreamDecoder`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Frames accepted.
    pub frames: u64,
    /// Candidate frames discarded (any reason).
    pub errors: u64,
    /// ... of which CRC mismatches.
    pub crc_errors: u64,
    /// ... of which COBS errors.
    pub cobs_errors: u64,
    /// ... of which over-long frames.
    pub too_long: u64,
    /// Bytes received.
    pub bytes: u64,
}

/// A streaming decoder: accepts arbitrary chunks of bytes, emits frames at each 0x00 delimiter,
/// resynchronises at the next 0x00 after garbage. Never panics and never allocates more than
/// [`MAX_ENCODED`] bytes per frame.
#[derive(Debug, Default, Clone)]
pub struct StreamDecoder {
    buf: Vec<u8>,
    overflow: bool,
    stats: DecoderStats,
    last_error: Option<FrameError>,
    foreign_version: Option<u8>,
}

impl StreamDecoder {
    /// A new decoder, waiting for the first delimiter's content.
    pub fn new() -> Self {
        Self::default()
    }

    /// Counters.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// The last discard reason.
    pub fn last_error(&self) -> Option<FrameError> {
        self.last_error
    }

    /// The version of the last frame discarded for carrying another protocol version (its CRC
    /// was valid: a peer of that version, not line noise), taken (reset to `None`).
    pub fn take_foreign_version(&mut self) -> Option<u8> {
        self.foreign_version.take()
    }

    /// Drop any partial frame (e.g. after reopening a port).
    pub fn reset(&mut self) {
        self.buf.clear();
        self.overflow = false;
    }

    /// Feed bytes; calls `on_frame` for every valid frame completed by them.
    pub fn push_with(&mut self, data: &[u8], mut on_frame: impl FnMut(Frame)) {
        self.stats.bytes += data.len() as u64;
        for &b in data {
            if b != 0 {
                if self.buf.len() < MAX_ENCODED {
                    self.buf.push(b);
                } else {
                    self.overflow = true;
                }
                continue;
            }
            if self.overflow {
                self.note(FrameError::TooLong);
            } else if !self.buf.is_empty() {
                match decode_encoded(&self.buf) {
                    Ok(f) => {
                        self.stats.frames += 1;
                        on_frame(f);
                    }
                    Err(e) => self.note(e),
                }
            }
            self.buf.clear();
            self.overflow = false;
        }
    }

    /// Feed bytes; returns the valid frames completed by them.
    pub fn push(&mut self, data: &[u8]) -> Vec<Frame> {
        let mut out = Vec::new();
        self.push_with(data, |f| out.push(f));
        out
    }

    fn note(&mut self, e: FrameError) {
        self.stats.errors += 1;
        match e {
            FrameError::Crc => self.stats.crc_errors += 1,
            FrameError::Cobs => self.stats.cobs_errors += 1,
            FrameError::TooLong => self.stats.too_long += 1,
            FrameError::Version(v) => self.foreign_version = Some(v),
            _ => {}
        }
        self.last_error = Some(e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x6F91);
    }

    #[test]
    fn residue_zero() {
        let body = encode_body(&Frame {
            seq: 7,
            msg: Message::Hello,
        });
        assert_eq!(crc16(&body), 0);
    }
}
