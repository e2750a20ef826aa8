//! Property tests of the codec.

use drive::codec::{self, StreamDecoder};
use drive::protocol::*;
use proptest::prelude::*;

/// Any message, each type about as likely (the weights are the families' sizes).
pub(crate) fn arb_msg() -> impl Strategy<Value = Message> {
    prop_oneof![
        6 => arb_short(),
        3 => arb_loop_command(),
        3 => arb_run_command(),
        3 => arb_reply(),
        3 => arb_stream(),
    ]
}

/// The messages of at most one field: HELLO, STOP, ESTOP, STATUS, KEEPALIVE, END_QUERY.
fn arb_short() -> impl Strategy<Value = Message> {
    prop_oneof![
        Just(Message::Hello),
        Just(Message::Stop),
        Just(Message::Estop),
        Just(Message::Status),
        any::<u16>().prop_map(Message::Keepalive),
        any::<u16>().prop_map(Message::EndQuery),
    ]
}

/// LOAD_CTRL, LOAD_SECTION, START_LOOP.
fn arb_loop_command() -> impl Strategy<Value = Message> {
    prop_oneof![
        (
            any::<u8>(),
            any::<u8>(),
            any::<u8>(),
            any::<i32>(),
            any::<i32>()
        )
            .prop_map(|(f, n, m, d, di)| {
                Message::LoadCtrl(LoadCtrl {
                    format: f,
                    n_sections: n,
                    n_taps: m,
                    d_q24: d,
                    dinv_q16: di,
                })
            }),
        (any::<u8>(), any::<i32>(), any::<i32>()).prop_map(|(i, a, g)| {
            Message::LoadSection(LoadSection {
                index: i,
                a_q30: a,
                g_q24: g,
            })
        }),
        (any::<i16>(), any::<i16>(), any::<u32>(), any::<u32>()).prop_map(|(r0, r1, p, t)| {
            Message::StartLoop(StartLoop {
                r0,
                r1,
                pre_samples: p,
                total_samples: t,
            })
        }),
    ]
}

/// CONFIGURE, START_PRBS, START_SINE.
fn arb_run_command() -> impl Strategy<Value = Message> {
    prop_oneof![
        (
            any::<u32>(),
            1u8..=66,
            any::<u16>(),
            any::<[u32; 3]>(),
            any::<[i16; 3]>()
        )
            .prop_map(|(fs, b, ka, sc, l)| {
                Message::Configure(Configure {
                    sample_rate_hz: fs,
                    block_samples: b,
                    keepalive_ms: ka,
                    scale_u_uv: sc[0],
                    scale_y_urad_s: sc[1],
                    scale_i_ua: sc[2],
                    u_limit: l[0],
                    y_limit: l[1],
                    i_limit: l[2],
                })
            }),
        (
            any::<u8>(),
            any::<u32>(),
            any::<u32>(),
            any::<u16>(),
            any::<i16>(),
            any::<i16>(),
            any::<u16>(),
            any::<u32>()
        )
            .prop_map(
                |(order, taps, seed, clock_samples, amplitude, offset, periods, settle_samples)| {
                    Message::StartPrbs(StartPrbs {
                        order,
                        taps,
                        seed,
                        clock_samples,
                        amplitude,
                        offset,
                        periods,
                        settle_samples,
                    })
                }
            ),
        (
            any::<u32>(),
            any::<i16>(),
            any::<i16>(),
            any::<u16>(),
            any::<u16>(),
            0u8..4
        )
            .prop_map(|(f, a, o, s, c, fl)| {
                Message::StartSine(StartSine {
                    freq_mhz: f,
                    amplitude: a,
                    offset: o,
                    settle_cycles: s,
                    cycles: c,
                    flags: fl,
                })
            }),
    ]
}

/// ACK, NAK, HELLO_REPLY.
fn arb_reply() -> impl Strategy<Value = Message> {
    prop_oneof![
        (any::<u8>(), any::<u16>(), any::<u32>()).prop_map(|(t, r, n)| Message::Ack(Ack {
            acked_type: t,
            run_id: r,
            total_samples: n
        })),
        (1u8..8, any::<u8>(), any::<u16>()).prop_map(|(c, t, d)| Message::Nak(Nak {
            nak_type: t,
            code: NakCode::from_code(c),
            detail: d
        })),
        (any::<u16>(), any::<u32>(), any::<u8>()).prop_map(|(b, f, m)| Message::HelloReply(
            HelloReply {
                proto_version: drive::protocol::PROTO_VERSION,
                fw_major: m,
                fw_minor: 0,
                n_channels: 3,
                max_block_samples: 66,
                boot_id: b,
                max_sample_rate_hz: f
            }
        )),
    ]
}

/// STREAM_END, DATA, SINE_RESULT.
fn arb_stream() -> impl Strategy<Value = Message> {
    prop_oneof![
        (any::<u16>(), any::<u32>(), any::<u32>(), any::<u16>()).prop_map(|(r, t, s, d)| {
            Message::StreamEnd(StreamEnd {
                run_id: r,
                reason: EndReason::from_code((t % 5) as u8),
                total_samples: t,
                samples_sent: s,
                blocks_dropped: d,
            })
        }),
        (
            any::<u16>(),
            any::<u32>(),
            0u8..2,
            prop::collection::vec(any::<[i16; 3]>(), 1..=66)
        )
            .prop_map(|(r, f, fl, s)| {
                Message::Data(DataBlock {
                    run_id: r,
                    first_index: f,
                    flags: fl,
                    samples: s,
                })
            }),
        (any::<u16>(), any::<u32>(), any::<[i32; 8]>()).prop_map(|(r, n, v)| Message::SineResult(
            SineResult {
                run_id: r,
                n,
                u_re: v[0],
                u_im: v[1],
                y_re: v[2],
                y_im: v[3],
                u_mean: v[4],
                u_ramp: v[5],
                y_mean: v[6],
                y_ramp: v[7],
            }
        )),
    ]
}

fn arb_frame() -> impl Strategy<Value = Frame> {
    (any::<u16>(), arb_msg()).prop_map(|(seq, msg)| Frame { seq, msg })
}

fn wire(frames: &[Frame]) -> Vec<u8> {
    frames.iter().flat_map(codec::encode).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn round_trip(f in arb_frame()) {
        let w = codec::encode(&f);
        prop_assert_eq!(w[0], 0);
        prop_assert_eq!(*w.last().unwrap(), 0);
        prop_assert!(!w[1..w.len() - 1].contains(&0));
        prop_assert_eq!(codec::decode_encoded(&w[1..w.len() - 1]), Ok(f.clone()));
        prop_assert_eq!(StreamDecoder::new().push(&w), vec![f]);
    }

    #[test]
    fn any_split_gives_the_same_frames(frames in prop::collection::vec(arb_frame(), 1..6), cuts in prop::collection::vec(any::<prop::sample::Index>(), 0..20)) {
        let w = wire(&frames);
        let mut pos: Vec<usize> = cuts.iter().map(|c| c.index(w.len() + 1)).collect();
        pos.sort_unstable();
        let mut d = StreamDecoder::new();
        let mut got = Vec::new();
        let mut last = 0;
        for p in pos.into_iter().chain([w.len()]) {
            got.extend(d.push(&w[last..p]));
            last = p;
        }
        prop_assert_eq!(got, frames);
        prop_assert_eq!(d.stats().errors, 0);
    }

    #[test]
    fn recovers_after_garbage(garbage in prop::collection::vec(any::<u8>(), 0..600), frames in prop::collection::vec(arb_frame(), 1..4)) {
        let mut d = StreamDecoder::new();
        let _ = d.push(&garbage);
        // every frame after the garbage arrives (each starts with its own delimiter)
        prop_assert_eq!(d.push(&wire(&frames)), frames);
    }

    #[test]
    fn one_dropped_byte_loses_at_most_its_frame(frames in prop::collection::vec(arb_frame(), 1..5), which in any::<prop::sample::Index>()) {
        let w = wire(&frames);
        let k = which.index(w.len());
        let mut damaged = w.clone();
        damaged.remove(k);
        let got = StreamDecoder::new().push(&damaged);
        // the frame whose byte was dropped may be lost; all others arrive, in order, unchanged
        let mut start = 0;
        let mut hit = None;
        for (i, f) in frames.iter().enumerate() {
            let len = codec::encode(f).len();
            if k >= start && k < start + len { hit = Some(i); }
            start += len;
        }
        let expect: Vec<Frame> = frames.iter().enumerate().filter(|(i, _)| Some(*i) != hit).map(|(_, f)| f.clone()).collect();
        let with_hit = frames.clone();
        prop_assert!(got == expect || got == with_hit, "got {} frames", got.len());
    }

    #[test]
    fn single_bit_flips_are_caught(frames in prop::collection::vec(arb_frame(), 1..4), which in any::<prop::sample::Index>(), bit in 0u8..8) {
        let w = wire(&frames);
        let k = which.index(w.len());
        let mut damaged = w.clone();
        damaged[k] ^= 1 << bit;
        let got = StreamDecoder::new().push(&damaged);
        // nothing that was not sent is accepted; at most one frame is lost
        for f in &got {
            prop_assert!(frames.contains(f), "accepted a corrupted frame: {:?}", f);
        }
        prop_assert!(got.len() + 1 >= frames.len());
    }

    #[test]
    fn decoder_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        let mut d = StreamDecoder::new();
        let _ = d.push(&bytes);
        let _ = codec::decode_body(&bytes);
        let _ = codec::decode_encoded(&bytes);
    }
}

/// Every single-bit flip of every position of many frames: none may be accepted.
#[test]
fn exhaustive_single_bit_flips() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let mut flips = 0u64;
    for n in 0..400 {
        let samples = (0..rng.gen_range(1..=66))
            .map(|_| {
                [
                    rng.gen(),
                    rng.gen(),
                    rng.gen::<i16>() & if n % 2 == 0 { 0xFF } else { -1 },
                ]
            })
            .collect();
        let f = Frame {
            seq: rng.gen(),
            msg: Message::Data(DataBlock {
                run_id: rng.gen(),
                first_index: rng.gen(),
                flags: 0,
                samples,
            }),
        };
        let g = Frame {
            seq: rng.gen(),
            msg: Message::Ack(Ack {
                acked_type: 3,
                run_id: 0,
                total_samples: rng.gen(),
            }),
        };
        let w = wire(&[f.clone(), g.clone()]);
        for k in 0..w.len() {
            for b in 0..8 {
                let mut d = w.clone();
                d[k] ^= 1 << b;
                for got in StreamDecoder::new().push(&d) {
                    assert!(got == f || got == g, "flip at byte {k} bit {b} accepted");
                }
                flips += 1;
            }
        }
    }
    eprintln!("{flips} single-bit flips, none accepted");
}

fn arb_ctrl() -> impl Strategy<Value = drive::ctrl::FixedCtrl> {
    (
        any::<i32>(),
        any::<i32>(),
        prop::collection::vec((-(1i32 << 30)..=(1 << 30), any::<i32>()), 0..=48),
        prop::collection::vec(any::<i32>(), 0..=8),
    )
        .prop_map(|(d, di, s, taps)| drive::ctrl::FixedCtrl {
            d_q24: d,
            dinv_q16: di >> 12,
            sections: s
                .into_iter()
                .map(|(a, g)| drive::ctrl::Section { a_q30: a, g_q24: g })
                .collect(),
            taps,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The C firmware's controller and the Rust one agree bit for bit (outputs, clamp flags,
    /// states and delay lines) on any controller (up to 48 sections and 8 delay taps), limit
    /// and error sequence.
    #[test]
    fn controller_c_and_rust_agree(
        k in arb_ctrl(),
        lim in 1i16..=32767,
        errs in prop::collection::vec(-65534i32..=65534, 1..60),
    ) {
        let mut zr = vec![0; k.n_states()];
        let mut zc = zr.clone();
        for e in errs {
            let r = k.step(&mut zr, e, lim);
            let c = drive::cfw::ctrl_step(&k, &mut zc, e, lim);
            prop_assert_eq!(r, c);
            prop_assert_eq!(&zr, &zc);
            prop_assert!(r.0.unsigned_abs() <= lim as u16);
        }
    }
}
