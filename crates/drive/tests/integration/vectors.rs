//! Shared test vectors (`crates/drive/testvectors/`): the codec must reproduce them byte for
//! byte. Regenerate the frame file with `DRIVE_REGEN_VECTORS=1 cargo test -p drive --test
//! integration vectors` (only when the protocol version changes).

use drive::codec::{self, StreamDecoder};
use drive::protocol::*;

fn dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testvectors")
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    if s == "-" {
        return Vec::new();
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// The named frames of `frames.txt`, one or more per message type.
fn named_frames() -> Vec<(&'static str, Frame)> {
    let c = Configure::default();
    vec![
        (
            "HELLO",
            Frame {
                seq: 0x0001,
                msg: Message::Hello,
            },
        ),
        (
            "CONFIGURE",
            Frame {
                seq: 0x0002,
                msg: Message::Configure(c),
            },
        ),
        (
            "START_PRBS",
            Frame {
                seq: 0x0003,
                msg: Message::StartPrbs(StartPrbs {
                    order: 7,
                    taps: 0x60,
                    seed: 1,
                    clock_samples: 3,
                    amplitude: 1000,
                    offset: 6000,
                    periods: 1,
                    settle_samples: 300,
                }),
            },
        ),
        (
            "START_SINE",
            Frame {
                seq: 0x0004,
                msg: Message::StartSine(StartSine {
                    freq_mhz: 12_500,
                    amplitude: 1000,
                    offset: 6000,
                    settle_cycles: 3,
                    cycles: 4,
                    flags: SINE_DFT,
                }),
            },
        ),
        (
            "STOP",
            Frame {
                seq: 0x0005,
                msg: Message::Stop,
            },
        ),
        (
            "ESTOP",
            Frame {
                seq: 0x0006,
                msg: Message::Estop,
            },
        ),
        (
            "STATUS",
            Frame {
                seq: 0x0007,
                msg: Message::Status,
            },
        ),
        (
            "KEEPALIVE",
            Frame {
                seq: 0x0008,
                msg: Message::Keepalive,
            },
        ),
        (
            "END_QUERY",
            Frame {
                seq: 0x0009,
                msg: Message::EndQuery(1),
            },
        ),
        (
            "ACK",
            Frame {
                seq: 0x0003,
                msg: Message::Ack(Ack {
                    acked_type: ty::START_PRBS,
                    run_id: 1,
                    total_samples: 681,
                }),
            },
        ),
        (
            "HELLO_REPLY",
            Frame {
                seq: 0x0001,
                msg: Message::HelloReply(HelloReply {
                    proto_version: drive::protocol::PROTO_VERSION,
                    fw_major: 1,
                    fw_minor: 0,
                    n_channels: 3,
                    max_block_samples: 66,
                    boot_id: 0xBEEF,
                    max_sample_rate_hz: 20_000,
                }),
            },
        ),
        (
            "STATUS_REPLY",
            Frame {
                seq: 0x0007,
                msg: Message::StatusReply(StatusReply {
                    state: DriveState::Running,
                    fault: fault::NONE,
                    run_id: 1,
                    samples_done: 400,
                    blocks_dropped: 0,
                    boot_id: 0xBEEF,
                    rx_errors: 2,
                    clamped: 0,
                }),
            },
        ),
        (
            "NAK",
            Frame {
                seq: 0x0003,
                msg: Message::Nak(Nak {
                    nak_type: ty::START_PRBS,
                    code: NakCode::Busy,
                    detail: 0,
                }),
            },
        ),
        (
            "DATA",
            Frame {
                seq: 0x0010,
                msg: Message::Data(DataBlock {
                    run_id: 1,
                    first_index: 64,
                    flags: 0,
                    samples: vec![[6000, 4092, 120], [7000, 4100, -256], [-1, 0, 32767]],
                }),
            },
        ),
        (
            "STREAM_END",
            Frame {
                seq: 0x0011,
                msg: Message::StreamEnd(StreamEnd {
                    run_id: 1,
                    reason: EndReason::Complete,
                    total_samples: 681,
                    samples_sent: 681,
                    blocks_dropped: 0,
                }),
            },
        ),
        (
            "SINE_RESULT",
            Frame {
                seq: 0x0012,
                msg: Message::SineResult(SineResult {
                    run_id: 2,
                    n: 320,
                    u_re: 0,
                    u_im: -256_000,
                    y_re: -300_000,
                    y_im: -1_500_000,
                    u_mean: 1_536_000,
                    u_ramp: -3,
                    y_mean: 2_500_000,
                    y_ramp: 70_000,
                }),
            },
        ),
    ]
}

#[test]
fn crc_check_value() {
    let text = std::fs::read_to_string(dir().join("crc.txt")).unwrap();
    let mut n = 0;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut it = line.split_whitespace();
        let data = unhex(it.next().unwrap());
        let crc = u16::from_str_radix(it.next().unwrap(), 16).unwrap();
        assert_eq!(codec::crc16(&data), crc, "{line}");
        n += 1;
    }
    assert!(n >= 3);
    assert_eq!(codec::crc16(b"123456789"), 0x6F91);
}

#[test]
fn cobs_edge_cases() {
    let text = std::fs::read_to_string(dir().join("cobs.txt")).unwrap();
    let mut n = 0;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut it = line.split_whitespace();
        let raw = unhex(it.next().unwrap());
        let enc = unhex(it.next().unwrap());
        assert_eq!(hex(&cobs::encode_vec(&raw)), hex(&enc), "{line}");
        assert_eq!(cobs::decode_vec(&enc).unwrap(), raw, "{line}");
        n += 1;
    }
    assert!(n >= 8);
}

#[test]
fn frames() {
    let path = dir().join("frames.txt");
    let named = named_frames();
    if std::env::var_os("DRIVE_REGEN_VECTORS").is_some() {
        let mut s = String::from(
            "# fracid drive protocol v2: one frame per line: NAME seq(hex) wire-bytes(hex, with both 0x00 delimiters)\n\
             # body = ver(0x02) type seq(LE) payload crc16-mcrf4xx(LE over ver..payload); wire = 00 COBS(body) 00\n",
        );
        for (name, f) in &named {
            s += &format!("{name} {:04X} {}\n", f.seq, hex(&codec::encode(f)));
        }
        std::fs::write(&path, s).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let mut seen = 0;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut it = line.split_whitespace();
        let name = it.next().unwrap();
        let _seq = it.next().unwrap();
        let wire = unhex(it.next().unwrap());
        let (_, f) = named
            .iter()
            .find(|(n, _)| *n == name)
            .unwrap_or_else(|| panic!("unknown {name}"));
        assert_eq!(
            hex(&codec::encode(f)),
            hex(&wire),
            "{name}: encoder differs from the vector"
        );
        assert_eq!(
            StreamDecoder::new().push(&wire),
            vec![f.clone()],
            "{name}: decoder"
        );
        assert_eq!(f.msg.name(), name);
        seen += 1;
    }
    assert_eq!(seen, named.len());
}

#[test]
fn prbs_first_bits() {
    let text = std::fs::read_to_string(dir().join("prbs.txt")).unwrap();
    let mut n = 0;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let f: Vec<&str> = line.split_whitespace().collect();
        let order: u8 = f[0].parse().unwrap();
        let taps = u32::from_str_radix(f[1].trim_start_matches("0x"), 16).unwrap();
        let seed: u32 = f[2].parse().unwrap();
        assert_eq!(drive::prbs::default_taps(order), Some(taps), "{line}");
        let mut l = drive::prbs::Lfsr::new(order, taps, seed).unwrap();
        let bits: String = (0..f[3].len())
            .map(|_| if l.next_bit() { '1' } else { '0' })
            .collect();
        assert_eq!(bits, f[3], "{line}");
        let mut r = fracsim::prbs::Lfsr::new(order as u32, seed).unwrap();
        let bits2: String = (0..f[3].len())
            .map(|_| if r.next_bit() { '1' } else { '0' })
            .collect();
        assert_eq!(bits2, f[3], "fracsim: {line}");
        n += 1;
    }
    assert!(n >= 2);
}
