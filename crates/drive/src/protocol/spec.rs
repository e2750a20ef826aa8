//! The frames described once: every message's type code, name and payload layout (its fields in
//! order, each with its wire type), and the codes and limits the two sides share.
//!
//! Everything that speaks the protocol is held to this table:
//!
//! - the Rust codec ([`super::Message`]) takes its payload lengths and type names from it, and a
//!   test checks, field by field on the shared vectors and on random messages, that each
//!   message's bytes sit where the table says (`tests/integration/spec.rs`);
//! - the simulator's Rust firmware speaks through that codec and reports [`FW_MAJOR`].[`FW_MINOR`];
//! - the C firmware's constants, payload lengths and field offsets are the header
//!   `firmware/include/fw_protocol.h`, generated from this table by [`c_header`] (a test fails
//!   when the file in the tree differs; `DRIVE_REGEN_PROTOCOL=1 cargo test -p drive --lib spec`
//!   writes it), and its tests run the shared vectors `testvectors/frames.txt` the Rust codec
//!   writes.

/// Protocol version carried in the low nibble of the first body byte. Version 2: SINE_RESULT
/// carries the window's level and ramp moments (38 bytes; 22 in version 1), so that the host
/// removes the operating point and its drift (PROTOCOL.md, section 3). Version 3: KEEPALIVE
/// carries the run id (2 bytes; empty before), and only a KEEPALIVE of the running run keeps it
/// alive: not any valid frame, such as another program's STATUS (PROTOCOL.md, section 7).
pub const PROTO_VERSION: u8 = 3;

/// Number of channels per sample (u, y, i).
pub const N_CHANNELS: usize = 3;
/// Largest number of samples in one DATA block.
pub const MAX_BLOCK_SAMPLES: u8 = 66;

/// Message type codes.
pub mod ty {
    /// HELLO.
    pub const HELLO: u8 = 0x01;
    /// CONFIGURE.
    pub const CONFIGURE: u8 = 0x02;
    /// START_PRBS.
    pub const START_PRBS: u8 = 0x03;
    /// START_SINE.
    pub const START_SINE: u8 = 0x04;
    /// STOP.
    pub const STOP: u8 = 0x05;
    /// ESTOP.
    pub const ESTOP: u8 = 0x06;
    /// STATUS.
    pub const STATUS: u8 = 0x07;
    /// KEEPALIVE.
    pub const KEEPALIVE: u8 = 0x08;
    /// END_QUERY.
    pub const END_QUERY: u8 = 0x09;
    /// LOAD_CTRL (firmware 1.1): the controller's header; clears its sections.
    pub const LOAD_CTRL: u8 = 0x0A;
    /// LOAD_SECTION (firmware 1.1): one first-order section of the controller (or, format 2, one
    /// delay tap).
    pub const LOAD_SECTION: u8 = 0x0B;
    /// START_LOOP (firmware 1.1): a speed loop with a reference step.
    pub const START_LOOP: u8 = 0x0C;
    /// ACK.
    pub const ACK: u8 = 0x80;
    /// HELLO_REPLY.
    pub const HELLO_REPLY: u8 = 0x81;
    /// STATUS_REPLY.
    pub const STATUS_REPLY: u8 = 0x87;
    /// NAK.
    pub const NAK: u8 = 0x8F;
    /// DATA.
    pub const DATA: u8 = 0x90;
    /// STREAM_END.
    pub const STREAM_END: u8 = 0x91;
    /// SINE_RESULT.
    pub const SINE_RESULT: u8 = 0x92;
}

/// START_SINE flag: stream DATA blocks.
pub const SINE_STREAM: u8 = 0x01;
/// START_SINE flag: compute the single-bin DFT on the drive.
pub const SINE_DFT: u8 = 0x02;
/// Longest sine measurement window with the DFT (START_SINE flag bit 1), samples (2^22): the
/// drive's 64-bit ramp sum `sum (2k - (n-1)) y_k` cannot overflow below it.
pub const MAX_DFT_SAMPLES: u32 = 1 << 22;

/// The controller format LOAD_CTRL carries: 1, parallel first-order sections in Q-format
/// (poles Q30, gains Q24, 64-bit states Q32), at most [`MAX_SECTIONS`] (firmware 1.1)
/// (PROTOCOL.md section 3, "Speed loop").
pub const CTRL_FORMAT: u8 = 1;
/// The most sections a controller of format [`CTRL_FORMAT`] has.
pub const MAX_SECTIONS: u8 = 24;
/// Controller format 2 (firmware 1.2): the sections of format 1, at most [`MAX_SECTIONS_TAPS`],
/// and a short delay chain, at most [`MAX_TAPS`] taps `h_j` on the past conditioned errors
/// `e'_(k-j)`, `j = 1..=n_taps` (the fast modes of a derivative's realisation: backward
/// differences after poles that round to 0).
pub const CTRL_FORMAT_TAPS: u8 = 2;
/// The most sections a controller of format [`CTRL_FORMAT_TAPS`] has.
pub const MAX_SECTIONS_TAPS: u8 = 48;
/// The most delay taps a controller of format [`CTRL_FORMAT_TAPS`] has.
pub const MAX_TAPS: u8 = 8;

/// Fault codes in STATUS_REPLY.
pub mod fault {
    /// No fault.
    pub const NONE: u8 = 0;
    /// Emergency stop.
    pub const ESTOP: u8 = 1;
    /// Keepalive expired.
    pub const KEEPALIVE: u8 = 2;
    /// Speed trip.
    pub const SPEED_LIMIT: u8 = 3;
    /// Current trip.
    pub const CURRENT_LIMIT: u8 = 4;
}

/// NAK codes (the detail of BAD_VALUE is the field's payload offset; of FAULT, the fault code).
pub mod nak {
    /// Unknown type.
    pub const UNKNOWN_TYPE: u8 = 1;
    /// Bad length.
    pub const BAD_LENGTH: u8 = 2;
    /// A field out of range.
    pub const BAD_VALUE: u8 = 3;
    /// A run is active.
    pub const BUSY: u8 = 4;
    /// No configuration yet.
    pub const NOT_CONFIGURED: u8 = 5;
    /// A fault is latched.
    pub const FAULT: u8 = 6;
    /// Version mismatch.
    pub const VERSION: u8 = 7;
    /// START_LOOP without a complete controller (LOAD_CTRL and all its sections).
    pub const NO_CONTROLLER: u8 = 8;
}

/// STREAM_END reasons.
pub mod end {
    /// Ran to the end.
    pub const COMPLETE: u8 = 0;
    /// Host STOP.
    pub const STOPPED: u8 = 1;
    /// ESTOP.
    pub const ESTOP: u8 = 2;
    /// Keepalive expired.
    pub const KEEPALIVE: u8 = 3;
    /// Speed or current trip.
    pub const LIMIT: u8 = 4;
}

/// Drive states in STATUS_REPLY.
pub mod state {
    /// No configuration since boot.
    pub const UNCONFIGURED: u8 = 0;
    /// Configured, idle.
    pub const IDLE: u8 = 1;
    /// A run is active.
    pub const RUNNING: u8 = 2;
    /// A fault is latched.
    pub const FAULT: u8 = 3;
}

/// The firmware version the simulator's Rust firmware and the C firmware (fracfw) report in
/// HELLO_REPLY: major.
pub const FW_MAJOR: u8 = 1;
/// Minor: 1.1 the speed loop (LOAD_CTRL, LOAD_SECTION, START_LOOP); 1.2 controller format 2 (up
/// to 48 sections and 8 delay taps); 1.3 protocol 3 (only a KEEPALIVE of the run keeps it alive).
pub const FW_MINOR: u8 = 3;

/// A field's type on the wire (little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wire {
    /// Unsigned byte.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// Unsigned 32-bit.
    U32,
    /// Signed 32-bit.
    I32,
    /// A reserved byte, sent as 0 and refused otherwise.
    Reserved,
}

impl Wire {
    /// Bytes on the wire.
    pub fn size(self) -> usize {
        match self {
            Wire::U8 | Wire::Reserved => 1,
            Wire::U16 | Wire::I16 => 2,
            Wire::U32 | Wire::I32 => 4,
        }
    }

    /// Whether the value is signed (two's complement).
    pub fn signed(self) -> bool {
        matches!(self, Wire::I16 | Wire::I32)
    }
}

/// One payload field: its name (the Rust struct's field; in C, `FW_OFF_<MESSAGE>_<NAME>`) and
/// wire type. Offsets follow from the order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    /// Name.
    pub name: &'static str,
    /// Wire type.
    pub wire: Wire,
}

const fn f(name: &'static str, wire: Wire) -> Field {
    Field { name, wire }
}

/// A message type: code, name, payload fields; DATA also repeats a sample record `n` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageSpec {
    /// Type code.
    pub code: u8,
    /// The specification's name.
    pub name: &'static str,
    /// Payload fields in order.
    pub fields: &'static [Field],
    /// DATA: the record repeated after the fields (`n` times, `n` the field of that name).
    pub repeated: &'static [Field],
}

impl MessageSpec {
    /// Payload length of the fields (DATA: without its samples).
    pub fn fixed_len(&self) -> usize {
        self.fields.iter().map(|f| f.wire.size()).sum()
    }

    /// Length of one repeated record (0 if none).
    pub fn record_len(&self) -> usize {
        self.repeated.iter().map(|f| f.wire.size()).sum()
    }

    /// The fields with their offsets.
    pub fn layout(&self) -> impl Iterator<Item = (usize, Field)> + '_ {
        self.fields.iter().scan(0, |off, &fl| {
            let at = *off;
            *off += fl.wire.size();
            Some((at, fl))
        })
    }

    /// Offset of a field by name.
    pub fn offset(&self, name: &str) -> Option<usize> {
        self.layout().find(|(_, f)| f.name == name).map(|(o, _)| o)
    }

    /// The exact payload length given its first bytes (DATA: `n` read from them); None if they
    /// are too short to tell.
    pub fn payload_len(&self, payload: &[u8]) -> Option<usize> {
        if self.repeated.is_empty() {
            return Some(self.fixed_len());
        }
        let n = *payload.get(self.offset("n")?)? as usize;
        Some(self.fixed_len() + n * self.record_len())
    }
}

use Wire::{Reserved as R0, I16, I32, U16, U32, U8};

const RUN_ID: &[Field] = &[f("run_id", U16)];

/// Every message of the protocol (PROTOCOL.md, section 3).
#[rustfmt::skip]
pub const MESSAGES: &[MessageSpec] = &[
    m(ty::HELLO, "HELLO", &[]),
    m(ty::CONFIGURE, "CONFIGURE", &[
        f("sample_rate_hz", U32), f("block_samples", U8), f("reserved", R0),
        f("keepalive_ms", U16), f("scale_u_uv", U32), f("scale_y_urad_s", U32),
        f("scale_i_ua", U32), f("u_limit", I16), f("y_limit", I16), f("i_limit", I16),
    ]),
    m(ty::START_PRBS, "START_PRBS", &[
        f("order", U8), f("reserved", R0), f("taps", U32), f("seed", U32),
        f("clock_samples", U16), f("amplitude", I16), f("offset", I16), f("periods", U16),
        f("settle_samples", U32),
    ]),
    m(ty::START_SINE, "START_SINE", &[
        f("freq_mhz", U32), f("amplitude", I16), f("offset", I16), f("settle_cycles", U16),
        f("cycles", U16), f("flags", U8), f("reserved", R0),
    ]),
    m(ty::STOP, "STOP", &[]),
    m(ty::ESTOP, "ESTOP", &[]),
    m(ty::STATUS, "STATUS", &[]),
    m(ty::KEEPALIVE, "KEEPALIVE", RUN_ID),
    m(ty::END_QUERY, "END_QUERY", RUN_ID),
    m(ty::LOAD_CTRL, "LOAD_CTRL", &[
        f("format", U8), f("n_sections", U8), f("n_taps", U8), f("reserved", R0),
        f("d_q24", I32), f("dinv_q16", I32),
    ]),
    m(ty::LOAD_SECTION, "LOAD_SECTION", &[
        f("index", U8), f("reserved", R0), f("a_q30", I32), f("g_q24", I32),
    ]),
    m(ty::START_LOOP, "START_LOOP", &[
        f("r0", I16), f("r1", I16), f("pre_samples", U32), f("total_samples", U32),
    ]),
    m(ty::ACK, "ACK", &[
        f("acked_type", U8), f("reserved", R0), f("run_id", U16), f("total_samples", U32),
    ]),
    m(ty::HELLO_REPLY, "HELLO_REPLY", &[
        f("proto_version", U8), f("fw_major", U8), f("fw_minor", U8), f("n_channels", U8),
        f("max_block_samples", U8), f("reserved", R0), f("boot_id", U16),
        f("max_sample_rate_hz", U32),
    ]),
    m(ty::STATUS_REPLY, "STATUS_REPLY", &[
        f("state", U8), f("fault", U8), f("run_id", U16), f("samples_done", U32),
        f("blocks_dropped", U16), f("boot_id", U16), f("rx_errors", U16), f("clamped", U16),
    ]),
    m(ty::NAK, "NAK", &[f("nak_type", U8), f("code", U8), f("detail", U16)]),
    MessageSpec {
        code: ty::DATA,
        name: "DATA",
        fields: &[f("run_id", U16), f("first_index", U32), f("n", U8), f("flags", U8)],
        repeated: &[f("u", I16), f("y", I16), f("i", I16)],
    },
    m(ty::STREAM_END, "STREAM_END", &[
        f("run_id", U16), f("reason", U8), f("reserved", R0), f("total_samples", U32),
        f("samples_sent", U32), f("blocks_dropped", U16),
    ]),
    m(ty::SINE_RESULT, "SINE_RESULT", &[
        f("run_id", U16), f("n", U32), f("u_re", I32), f("u_im", I32), f("y_re", I32),
        f("y_im", I32), f("u_mean", I32), f("u_ramp", I32), f("y_mean", I32),
        f("y_ramp", I32),
    ]),
];

const fn m(code: u8, name: &'static str, fields: &'static [Field]) -> MessageSpec {
    MessageSpec {
        code,
        name,
        fields,
        repeated: &[],
    }
}

/// The message of a type code.
pub fn message(code: u8) -> Option<&'static MessageSpec> {
    MESSAGES.iter().find(|m| m.code == code)
}

/// A named constant of the protocol, as the C firmware names it, with its value and what it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Constant {
    /// The C name.
    pub name: &'static str,
    /// Value.
    pub value: u32,
    /// What it is (a comment in the header).
    pub doc: &'static str,
}

const fn c(name: &'static str, value: u32, doc: &'static str) -> Constant {
    Constant { name, value, doc }
}

/// The versions, counts, limits and flags both sides share.
#[rustfmt::skip]
pub fn limits() -> Vec<Constant> {
    vec![
        c("FW_PROTO_VERSION", PROTO_VERSION as u32, "protocol version (low nibble of the first body byte)"),
        c("FW_MAJOR", FW_MAJOR as u32, "firmware version reported in HELLO_REPLY: major"),
        c("FW_MINOR", FW_MINOR as u32, "and minor"),
        c("FW_N_CHANNELS", N_CHANNELS as u32, "channels per sample (u, y, i)"),
        c("FW_MAX_BLOCK", MAX_BLOCK_SAMPLES as u32, "samples per DATA block at most"),
        c("FW_MAX_DFT_SAMPLES", MAX_DFT_SAMPLES, "longest sine window with the DFT, samples"),
        c("FW_SINE_STREAM", SINE_STREAM as u32, "START_SINE flag: stream DATA"),
        c("FW_SINE_DFT", SINE_DFT as u32, "START_SINE flag: the DFT on the drive"),
        c("FW_CTRL_FORMAT", CTRL_FORMAT as u32, "controller format 1: sections"),
        c("FW_CTRL_FORMAT_TAPS", CTRL_FORMAT_TAPS as u32, "controller format 2: sections and delay taps"),
        c("FW_MAX_SECTIONS_V1", MAX_SECTIONS as u32, "sections of a format-1 controller at most"),
        c("FW_MAX_SECTIONS", MAX_SECTIONS_TAPS as u32, "sections of a format-2 controller at most"),
        c("FW_MAX_TAPS", MAX_TAPS as u32, "delay taps of a format-2 controller at most"),
    ]
}

/// The codes of NAK, the faults, the ends of a run and the drive's states.
#[rustfmt::skip]
pub fn codes() -> Vec<Constant> {
    vec![
        c("FW_NAK_UNKNOWN_TYPE", nak::UNKNOWN_TYPE as u32, "NAK: unknown type"),
        c("FW_NAK_BAD_LENGTH", nak::BAD_LENGTH as u32, "NAK: bad length"),
        c("FW_NAK_BAD_VALUE", nak::BAD_VALUE as u32, "NAK: a field out of range (detail: its offset)"),
        c("FW_NAK_BUSY", nak::BUSY as u32, "NAK: a run is active"),
        c("FW_NAK_NOT_CONFIGURED", nak::NOT_CONFIGURED as u32, "NAK: no configuration yet"),
        c("FW_NAK_FAULT", nak::FAULT as u32, "NAK: a fault is latched (detail: its code)"),
        c("FW_NAK_VERSION", nak::VERSION as u32, "NAK: version mismatch"),
        c("FW_NAK_NO_CONTROLLER", nak::NO_CONTROLLER as u32, "NAK: START_LOOP without a complete controller"),
        c("FW_FAULT_NONE", fault::NONE as u32, "no fault"),
        c("FW_FAULT_ESTOP", fault::ESTOP as u32, "emergency stop"),
        c("FW_FAULT_KEEPALIVE", fault::KEEPALIVE as u32, "keepalive expired"),
        c("FW_FAULT_SPEED", fault::SPEED_LIMIT as u32, "speed trip"),
        c("FW_FAULT_CURRENT", fault::CURRENT_LIMIT as u32, "current trip"),
        c("FW_END_COMPLETE", end::COMPLETE as u32, "run ended: ran to the end"),
        c("FW_END_STOPPED", end::STOPPED as u32, "run ended: host STOP"),
        c("FW_END_ESTOP", end::ESTOP as u32, "run ended: ESTOP"),
        c("FW_END_KEEPALIVE", end::KEEPALIVE as u32, "run ended: keepalive expired"),
        c("FW_END_LIMIT", end::LIMIT as u32, "run ended: speed or current trip"),
        c("FW_STATE_UNCONFIGURED", state::UNCONFIGURED as u32, "state: not configured"),
        c("FW_STATE_IDLE", state::IDLE as u32, "state: configured, idle"),
        c("FW_STATE_RUNNING", state::RUNNING as u32, "state: a run is active"),
        c("FW_STATE_FAULT", state::FAULT as u32, "state: a fault is latched"),
    ]
}

/// Where the C firmware's generated header lives, from the crate's directory.
pub const C_HEADER_PATH: &str = "../../firmware/include/fw_protocol.h";

/// The C firmware's header of the protocol: the constants, each message's type code
/// (`FW_T_<NAME>`), payload length (`FW_LEN_<NAME>`; DATA's without its samples, each of which
/// adds `FW_LEN_DATA_SAMPLE`) and field offsets (`FW_OFF_<NAME>_<FIELD>`, reserved bytes
/// included: `FW_OFF_<NAME>_RESERVED`).
pub fn c_header() -> String {
    let mut h = String::from(
        "/* The fracid drive protocol for the C firmware: GENERATED from crates/drive/src/protocol/spec.rs\n \
         * (`DRIVE_REGEN_PROTOCOL=1 cargo test -p drive --lib spec`); do not edit. A test fails when\n \
         * this file differs from the table. */\n\
         #ifndef FW_PROTOCOL_H\n#define FW_PROTOCOL_H\n",
    );
    let define = |h: &mut String, name: &str, value: u32, doc: &str| {
        let v = if value > 0xFFFF {
            format!("{value}ul")
        } else {
            format!("{value}u")
        };
        h.push_str(&format!("#define {name} {v}"));
        if !doc.is_empty() {
            h.push_str(&format!(" /* {doc} */"));
        }
        h.push('\n');
    };
    h.push_str("\n/* versions, counts, limits, flags */\n");
    for k in limits() {
        define(&mut h, k.name, k.value, k.doc);
    }
    h.push_str("\n/* NAK codes, faults, end reasons, states */\n");
    for k in codes() {
        define(&mut h, k.name, k.value, k.doc);
    }
    h.push_str("\n/* message types */\n");
    for m in MESSAGES {
        h.push_str(&format!("#define FW_T_{} 0x{:02X}u\n", m.name, m.code));
    }
    h.push_str("\n/* payload lengths (DATA: without its samples) */\n");
    for m in MESSAGES {
        define(
            &mut h,
            &format!("FW_LEN_{}", m.name),
            m.fixed_len() as u32,
            "",
        );
        if !m.repeated.is_empty() {
            define(
                &mut h,
                &format!("FW_LEN_{}_SAMPLE", m.name),
                m.record_len() as u32,
                "",
            );
        }
    }
    h.push_str("\n/* field offsets in the payload */\n");
    for m in MESSAGES {
        for (off, fl) in m.layout() {
            let name = format!("FW_OFF_{}_{}", m.name, fl.name.to_ascii_uppercase());
            define(&mut h, &name, off as u32, "");
        }
        let mut off = 0;
        for fl in m.repeated {
            let name = format!("FW_OFF_{}_SAMPLE_{}", m.name, fl.name.to_ascii_uppercase());
            define(&mut h, &name, off as u32, "in each sample");
            off += fl.wire.size();
        }
    }
    h.push_str("\n#endif\n");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_type_code_is_described_once_with_a_length_the_codec_uses() {
        for (k, m) in MESSAGES.iter().enumerate() {
            assert!(MESSAGES[..k]
                .iter()
                .all(|o| o.code != m.code && o.name != m.name));
            assert_eq!(super::super::type_name(m.code), m.name);
            let probe = [0u8, 0, 0, 0, 0, 0, 3, 0];
            assert_eq!(
                super::super::Message::payload_len(m.code, &probe),
                m.payload_len(&probe),
                "{}",
                m.name
            );
        }
        // the DATA block: 8 bytes of header, 6 per sample
        let data = message(ty::DATA).expect("DATA");
        assert_eq!((data.fixed_len(), data.record_len()), (8, 6));
        assert_eq!(data.offset("n"), Some(6));
    }

    #[test]
    fn the_c_header_in_the_tree_is_generated_from_this_table() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(C_HEADER_PATH);
        let want = c_header();
        if std::env::var_os("DRIVE_REGEN_PROTOCOL").is_some() {
            std::fs::write(&path, &want).expect("write the header");
        }
        let have = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            have == want,
            "{} differs from protocol/spec.rs: regenerate it with DRIVE_REGEN_PROTOCOL=1 \
             cargo test -p drive --lib spec, then rebuild and test the firmware",
            path.display()
        );
    }
}
