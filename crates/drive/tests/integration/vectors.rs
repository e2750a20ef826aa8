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
pub(crate) fn named_frames() -> Vec<(&'static str, Frame)> {
    [run_commands(), loop_commands(), replies(), stream_frames()].concat()
}

/// The host's commands of the open-loop runs and their control.
fn run_commands() -> Vec<(&'static str, Frame)> {
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
                msg: Message::Keepalive(0x0103),
            },
        ),
        (
            "END_QUERY",
            Frame {
                seq: 0x0009,
                msg: Message::EndQuery(1),
            },
        ),
    ]
}

/// The host's commands of the speed loop: the controller download and the loop's start.
fn loop_commands() -> Vec<(&'static str, Frame)> {
    vec![
        (
            "LOAD_CTRL",
            Frame {
                seq: 0x000A,
                msg: Message::LoadCtrl(LoadCtrl {
                    format: CTRL_FORMAT,
                    n_sections: 2,
                    n_taps: 0,
                    d_q24: 1_638_400,
                    dinv_q16: 2621,
                }),
            },
        ),
        (
            "LOAD_CTRL_TAPS",
            Frame {
                seq: 0x000D,
                msg: Message::LoadCtrl(LoadCtrl {
                    format: CTRL_FORMAT_TAPS,
                    n_sections: 40,
                    n_taps: 3,
                    d_q24: -1_638_400,
                    dinv_q16: -2621,
                }),
            },
        ),
        (
            "LOAD_SECTION",
            Frame {
                seq: 0x000B,
                msg: Message::LoadSection(LoadSection {
                    index: 1,
                    a_q30: 1_062_997_818,
                    g_q24: -1234,
                }),
            },
        ),
        (
            "START_LOOP",
            Frame {
                seq: 0x000C,
                msg: Message::StartLoop(StartLoop {
                    r0: 0,
                    r1: 2000,
                    pre_samples: 100,
                    total_samples: 600,
                }),
            },
        ),
    ]
}

/// The drive's answers to commands.
fn replies() -> Vec<(&'static str, Frame)> {
    vec![
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
                    fw_minor: 3,
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
    ]
}

/// The drive's frames of a run: DATA, its end, the sine's result.
fn stream_frames() -> Vec<(&'static str, Frame)> {
    vec![
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
        let v = PROTO_VERSION;
        let mut s = format!(
            "# fracid drive protocol v{v}: one frame per line: NAME seq(hex) wire-bytes(hex, with both 0x00 delimiters)\n\
             # body = ver(0x{v:02X}) type seq(LE) payload crc16-mcrf4xx(LE over ver..payload); wire = 00 COBS(body) 00\n",
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
        // a name is the message's, or the message's with a suffix (LOAD_CTRL_TAPS)
        assert!(name.starts_with(f.msg.name()), "{name}: {}", f.msg.name());
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

/// The controllers of `ctrl.txt`: a fractional PI's sections (from a realisation), a pure
/// integrator without feed-through (conditional integration), states driven into saturation.
fn vector_controllers() -> Vec<(&'static str, drive::ctrl::FixedCtrl, i16, Vec<i32>)> {
    use drive::ctrl::{FixedCtrl, Section};
    let s = |a: f64, g: i32| Section {
        a_q30: (a * (1u64 << 30) as f64).round() as i32,
        g_q24: g,
    };
    let mut errs: Vec<i32> = (0..40).map(|k| 2000 - 97 * k).collect();
    errs.extend((0..40).map(|k| -((k * 7919) % 3001) + 1500));
    errs.extend([30000, 30000, 30000, -30000, -30000, 5, -5, 0, 1, -1]);
    vec![
        (
            "fopi",
            FixedCtrl {
                d_q24: (0.56 * 16_777_216.0f64).round() as i32,
                dinv_q16: (65536.0f64 / 0.56).round() as i32,
                sections: vec![
                    s(1.0, 90_000_000),
                    s(0.9999990, -333),
                    s(0.99, -70_000_000),
                    s(0.5, -5_000_000),
                    s(-0.25, -3000),
                    s(0.0, 123_456),
                ],
                taps: vec![],
            },
            12000,
            errs.clone(),
        ),
        (
            "integrator",
            FixedCtrl {
                d_q24: 0,
                dinv_q16: 0,
                sections: vec![s(1.0, 40_000 << 8)],
                taps: vec![],
            },
            5000,
            errs.clone(),
        ),
        (
            "saturating",
            FixedCtrl {
                d_q24: -7 << 24,
                dinv_q16: -(65536 / 7),
                sections: vec![s(1.0, i32::MAX), s(-1.0, i32::MIN), s(0.75, i32::MAX)],
                taps: vec![],
            },
            32767,
            errs.clone(),
        ),
        (
            // format 2: a FOPID's fast modes as delay taps (differences: taps of both signs),
            // linear and clamped in turn (Hanus through the delay line)
            "fopid",
            FixedCtrl {
                d_q24: (0.9 * 16_777_216.0f64).round() as i32,
                dinv_q16: (65536.0f64 / 0.9).round() as i32,
                sections: vec![s(1.0, 3_000_000), s(0.995, -900_000), s(0.3, 2_000_000)],
                taps: vec![-25_000_000, 12_000_000, -3_000_000, 40_000_000, -40_000_000],
            },
            9000,
            errs,
        ),
    ]
}

/// `ctrl.txt`: the fixed-point controller's outputs and states, sample by sample, for the C
/// firmware's `fw_ctrl_step` and [`drive::ctrl::FixedCtrl::step`] alike.
#[test]
fn controller_steps() {
    let path = dir().join("ctrl.txt");
    if std::env::var_os("DRIVE_REGEN_VECTORS").is_some() {
        let mut s = String::from(
            "# fracid drive speed-loop controller (PROTOCOL.md section 3): fixed-point steps\n\
             # CTRL name d_q24 dinv_q16 u_limit n a_q30 g_q24 ... m h_1 .. h_m (states start at 0)\n\
             # STEP e u clamped z_0 .. z_(n-1) w_1 .. w_m (the states and delay line after the step)\n",
        );
        for (name, k, lim, errs) in vector_controllers() {
            s += &format!(
                "CTRL {name} {} {} {lim} {}",
                k.d_q24,
                k.dinv_q16,
                k.sections.len()
            );
            for sec in &k.sections {
                s += &format!(" {} {}", sec.a_q30, sec.g_q24);
            }
            s += &format!(" {}", k.taps.len());
            for h in &k.taps {
                s += &format!(" {h}");
            }
            s += "\n";
            let mut z = vec![0; k.n_states()];
            for e in errs {
                let (u, c) = k.step(&mut z, e, lim);
                s += &format!("STEP {e} {u} {}", c as u8);
                for v in &z {
                    s += &format!(" {v}");
                }
                s += "\n";
            }
        }
        std::fs::write(&path, s).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let mut cur: Option<(drive::ctrl::FixedCtrl, i16, Vec<i64>, Vec<i64>)> = None;
    let (mut steps, mut ctrls, mut clamped) = (0, 0, 0);
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let f: Vec<&str> = line.split_whitespace().collect();
        let num = |i: usize| f[i].parse::<i64>().unwrap();
        if f[0] == "CTRL" {
            let n = num(5) as usize;
            let m = num(6 + 2 * n) as usize;
            let k = drive::ctrl::FixedCtrl {
                d_q24: num(2) as i32,
                dinv_q16: num(3) as i32,
                sections: (0..n)
                    .map(|i| drive::ctrl::Section {
                        a_q30: num(6 + 2 * i) as i32,
                        g_q24: num(7 + 2 * i) as i32,
                    })
                    .collect(),
                taps: (0..m).map(|j| num(7 + 2 * n + j) as i32).collect(),
            };
            assert_eq!(f.len(), 7 + 2 * n + m, "{line}");
            cur = Some((k, num(4) as i16, vec![0; n + m], vec![0; n + m]));
            ctrls += 1;
        } else {
            let (k, lim, z, zc) = cur.as_mut().expect("STEP after CTRL");
            let e = num(1) as i32;
            let want_z: Vec<i64> = f[4..].iter().map(|v| v.parse().unwrap()).collect();
            let (u, c) = k.step(z, e, *lim);
            assert_eq!((u as i64, c as i64), (num(2), num(3)), "{line}: Rust");
            assert_eq!(*z, want_z, "{line}: Rust states");
            let (uc, cc) = drive::cfw::ctrl_step(k, zc, e, *lim);
            assert_eq!((uc as i64, cc as i64), (num(2), num(3)), "{line}: C");
            assert_eq!(*zc, want_z, "{line}: C states");
            clamped += c as usize;
            steps += 1;
        }
    }
    assert_eq!(ctrls, 4);
    assert!(
        steps >= 360 && clamped >= 20,
        "{steps} steps, {clamped} clamped"
    );
}
