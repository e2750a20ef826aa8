//! The C firmware (`firmware/`, linked through `drive::cfw`) behind the simulator's pty, against
//! the Rust firmware: the same motor, effects and seed must give the same records, sample for
//! sample. (The fault scenarios of `e2e` and `e2e_control` run against the C firmware with
//! `on_both_firmwares`.)

use crate::e2e::{check_consistent, check_truth, client, lock, short_prbs, vclient};
use drive::client::{Acquisition, NullSink};
use drive::protocol::{StartSine, SINE_DFT, SINE_STREAM};
use drive::sim::{DriveSim, Effects, Faults, FirmwareKind, SimClock, SimConfig};

const BAUD: u32 = 921_600;

fn spawn(firmware: FirmwareKind) -> DriveSim {
    DriveSim::spawn(SimConfig {
        firmware,
        // virtual time: the records depend on the seed alone, not on the wall clock
        clock: SimClock::Virtual,
        baud: BAUD,
        // every hidden effect that is deterministic for a seed
        effects: Effects {
            coulomb_v: 0.2,
            delay_s: 0.002,
            ripple_v: 0.1,
            ripple_hz: 37.0,
            noise_std: 0.05,
            speed_quant: 0.01,
            r_ohm: 1.0,
            offset_v: 0.1,
        },
        faults: Faults {
            seed: 7,
            ..Faults::default()
        },
        ..SimConfig::default()
    })
    .expect("simulator starts")
}

/// A PRBS run and a streamed sine with the DFT, on one firmware.
fn record(firmware: FirmwareKind) -> (Acquisition, Acquisition, Vec<String>) {
    let s = spawn(firmware);
    let mut c = vclient(&s, BAUD);
    let prbs = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    assert!(prbs.complete, "{firmware:?}: {:?}", prbs.problems);
    check_consistent(&prbs);
    check_truth(&prbs, &s);
    let sine = StartSine {
        freq_mhz: 13_000,
        amplitude: 1500,
        offset: 2000,
        settle_cycles: 2,
        cycles: 3,
        flags: SINE_STREAM | SINE_DFT,
    };
    let sine = c.run_sine(&sine, &mut NullSink).unwrap();
    assert!(sine.complete, "{firmware:?}: {:?}", sine.problems);
    check_consistent(&sine);
    check_truth(&sine, &s);
    (prbs, sine, s.stats().events)
}

#[test]
fn c_firmware_records_equal_the_rust_firmware() {
    let _g = lock();
    let (pr, sr, ev_r) = record(FirmwareKind::Rust);
    let (pc, sc, ev_c) = record(FirmwareKind::C);
    // the C engine really ran (its runs are logged as such), the Rust one did not
    assert!(ev_c.iter().any(|e| e.contains("(C firmware)")), "{ev_c:?}");
    assert!(!ev_r.iter().any(|e| e.contains("(C firmware)")), "{ev_r:?}");
    for (r, c) in [(&pr, &pc), (&sr, &sc)] {
        assert_eq!(r.total_samples, c.total_samples);
        assert_eq!(r.index, c.index);
        assert_eq!(r.raw.len(), c.raw.len());
        for (k, (a, b)) in r.raw.iter().zip(&c.raw).enumerate() {
            assert_eq!(
                a, b,
                "sample {k} differs between the Rust and the C firmware"
            );
        }
    }
    // The DFT: Rust sums in f64, C in 64-bit fixed point (Q30 sine, terms in 2^-22 LSB); both
    // round to Q8. They may differ by one Q8 unit where the exact value is near a rounding tie.
    let (a, b) = (
        sr.sine.expect("Rust SINE_RESULT"),
        sc.sine.expect("C SINE_RESULT"),
    );
    assert_eq!(a.n, b.n);
    for (x, y) in [
        (a.u_re, b.u_re),
        (a.u_im, b.u_im),
        (a.y_re, b.y_re),
        (a.y_im, b.y_im),
    ] {
        assert!((x - y).abs() <= 1, "Rust {a:?} vs C {b:?}");
    }
    // The level and ramp moments are exact integer sums with the same rounding on both sides.
    assert_eq!(
        (a.u_mean, a.u_ramp, a.y_mean, a.y_ramp),
        (b.u_mean, b.u_ramp, b.y_mean, b.y_ramp),
        "level/ramp moments: Rust {a:?} vs C {b:?}"
    );
    assert!(a.y_mean != 0 && a.y_ramp != 0, "{a:?}");
    eprintln!(
        "Rust vs C firmware: {} PRBS + {} sine samples identical; DFT Rust {a:?} C {b:?}",
        pr.raw.len(),
        sr.raw.len()
    );
}

on_both_firmwares! {
/// The simulators of the `e2e` and `e2e_control` tests ([`on_both_firmwares`]) run the firmware
/// they are given: the C engine for `NAME::c`, the Rust firmware for `NAME::rust`. Without this,
/// the C variants could silently test the Rust firmware again. A simulator built from defaults
/// runs the Rust firmware, whatever the environment.
fn e2e_simulators_run_the_firmware_they_are_given(fw) {
    let _g = lock();
    assert_eq!(SimConfig::default().firmware, FirmwareKind::Rust);
    let s = crate::e2e::sim(fw, Faults::default(), BAUD, None);
    let mut c = client(s.port_path(), BAUD);
    let acq = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    assert!(acq.complete, "{:?}", acq.problems);
    let events = s.stats().events;
    assert_eq!(
        events.iter().any(|e| e.contains("(C firmware)")),
        fw == FirmwareKind::C,
        "{fw:?}: {events:?}"
    );
}
}

/// The controller download's checks (PROTOCOL.md "Speed loop", LOAD_CTRL and LOAD_SECTION) on
/// the Rust and the C firmware alike: each refusal's NAK code and detail, then a format-2
/// controller (a section and two taps) loaded and a loop started only once it is complete.
#[test]
fn both_firmwares_check_a_controller_download_alike() {
    use drive::protocol::{
        LoadCtrl, LoadSection, Message, NakCode, StartLoop, CTRL_FORMAT, CTRL_FORMAT_TAPS,
    };
    let _g = lock();
    let head = |format, n_sections, n_taps| {
        Message::LoadCtrl(LoadCtrl {
            format,
            n_sections,
            n_taps,
            d_q24: 1 << 24,
            dinv_q16: 1 << 16,
        })
    };
    let sec = |index, a_q30, g_q24| {
        Message::LoadSection(LoadSection {
            index,
            a_q30,
            g_q24,
        })
    };
    let start = Message::StartLoop(StartLoop {
        r0: 0,
        r1: 100,
        pre_samples: 5,
        total_samples: 10,
    });
    // (request, the NAK's detail, or None for an ACK)
    let script: Vec<(Message, Option<u16>)> = vec![
        (head(3, 1, 0), Some(0)),
        (head(CTRL_FORMAT, 25, 0), Some(1)),
        (head(CTRL_FORMAT, 1, 1), Some(2)),
        (head(CTRL_FORMAT_TAPS, 49, 0), Some(1)),
        (head(CTRL_FORMAT_TAPS, 1, 9), Some(2)),
        (head(CTRL_FORMAT_TAPS, 1, 2), None),
        (sec(1, 0, 5), Some(0)),
        (sec(0, 1 << 30, 5000), None),
        (sec(1, 7, -9000), Some(2)),
        (sec(1, 0, -9000), None),
        (sec(2, 0, 400), None),
        (sec(3, 0, 400), Some(0)),
    ];
    for fw in [FirmwareKind::Rust, FirmwareKind::C] {
        let s = DriveSim::spawn(SimConfig {
            firmware: fw,
            clock: SimClock::Virtual,
            baud: BAUD,
            ..SimConfig::default()
        })
        .expect("simulator starts");
        let mut c = vclient(&s, BAUD);
        for (k, (msg, want)) in script.iter().enumerate() {
            if k == 9 {
                // a tap still missing: no controller to run
                match c.request(start.clone()) {
                    Err(drive::Error::Nak {
                        code: NakCode::NoController,
                        ..
                    }) => {}
                    other => panic!("{fw:?}: START_LOOP with a tap missing: {other:?}"),
                }
            }
            let got = c.request(msg.clone());
            match (want, got) {
                (None, Ok(Message::Ack(_))) => {}
                (
                    Some(d),
                    Err(drive::Error::Nak {
                        code: NakCode::BadValue,
                        detail,
                        ..
                    }),
                ) if detail == *d => {}
                (w, g) => panic!("{fw:?}: step {k} {msg:?}: want NAK detail {w:?}, got {g:?}"),
            }
        }
        let acq = c
            .run_loop(
                &StartLoop {
                    r0: 0,
                    r1: 100,
                    pre_samples: 5,
                    total_samples: 10,
                },
                &mut NullSink,
            )
            .expect("the loop runs with the complete controller");
        assert!(acq.complete, "{fw:?}: {:?}", acq.problems);
    }
}
