//! End-to-end over a real pseudo-terminal: the run-control and safety paths of the protocol
//! (STOP, ESTOP, keepalive expiry, speed and current trips, a retried START), and the sine DFT
//! computed on the host from streamed samples against the drive's. Serialised with the lock of
//! [`super::e2e`]; 921600 baud and short runs keep each test to about a second.

use crate::e2e::{check_consistent, check_truth, lock, short_prbs};
use drive::client::{
    drive_dft, host_dft, Acquisition, Client, ClientConfig, CsvSink, NullSink, PrbsTest, RunInfo,
    SampleSink,
};
use drive::protocol::{
    fault, ty, Configure, DriveState, EndReason, NakCode, StartSine, StreamEnd, SINE_DFT,
    SINE_STREAM,
};
use drive::sim::{DriveSim, FirmwareKind, SimClock, SimConfig};
use drive::Error;
use std::io;
use std::time::{Duration, Instant};

const BAUD: u32 = 921_600;

/// The simulator at 921600 baud, in real time (the tests that time commands against the samples:
/// STOP, ESTOP, the keepalive) or in virtual time ([`fast_client`] then keeps it going).
fn fast_sim(firmware: FirmwareKind, clock: SimClock) -> DriveSim {
    DriveSim::spawn(SimConfig {
        firmware,
        baud: BAUD,
        clock,
        ..SimConfig::default()
    })
    .expect("simulator starts")
}

/// The client settings for a simulator in virtual time: the keepalive on the drive's clock
/// ([`crate::e2e::vclient_config`]).
fn vcfg(s: &DriveSim) -> ClientConfig {
    crate::e2e::vclient_config(s, BAUD)
}

/// A client of [`fast_sim`] (at its baud rate).
fn fast_client(s: &DriveSim, cfg: ClientConfig, conf: &Configure) -> Client {
    let mut c =
        Client::open(s.port_path(), ClientConfig { baud: BAUD, ..cfg }).expect("client opens");
    c.configure(conf).expect("configure");
    c
}

/// The run's summary, which must have arrived.
fn end_of(acq: &Acquisition) -> StreamEnd {
    acq.end.expect("STREAM_END arrived")
}

/// Every index of `0..n` arrived, in order (a clean line loses nothing).
fn assert_prefix(acq: &Acquisition, n: u64) {
    assert_eq!(acq.index.len() as u64, n, "{:?}", acq.missing);
    assert!(acq.index.iter().copied().eq(0..n));
}

/// Stop (or emergency-stop) the run once `at` samples have arrived, from the progress callback.
fn stop_at(c: &mut Client, at: u64, estop: bool) {
    let mut h = Some(c.stop_handle());
    c.set_progress(move |p| {
        if p.done >= at {
            if let Some(h) = h.take() {
                if estop {
                    h.estop()
                } else {
                    h.stop()
                }
            }
        }
    });
}

fn assert_nak_fault(r: drive::Result<Acquisition>, code: u8) {
    match r {
        Err(Error::Nak {
            code: NakCode::Fault,
            detail,
            ..
        }) => assert_eq!(detail, code as u16),
        other => panic!("START must be refused with NAK FAULT {code}: {other:?}"),
    }
}

on_both_firmwares! {
fn stop_mid_run_keeps_what_arrived(fw) {
    let _g = lock();
    let t0 = Instant::now();
    let s = fast_sim(fw, SimClock::RealTime);
    let mut c = fast_client(&s, ClientConfig::default(), &Configure::default());
    stop_at(&mut c, 250, false);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stopped.csv");
    let mut sink = CsvSink::new(std::fs::File::create(&path).unwrap());
    let acq = c.run_prbs(&short_prbs(), &mut sink).unwrap();
    drop(sink);
    let planned = 100 + 2 * 127 * 2;
    let end = end_of(&acq);
    let n = end.total_samples as u64;
    eprintln!(
        "stop: {n} of {planned} samples, missing {:?}, problems {:?}",
        acq.missing, acq.problems
    );
    assert_eq!(end.reason, EndReason::Stopped);
    assert_eq!(acq.planned_samples, planned);
    assert!((250..planned).contains(&n), "{n}");
    // what the drive produced all arrived and is what it produced; the rest is marked missing
    assert!(!acq.complete);
    assert_prefix(&acq, n);
    assert_eq!(acq.missing, vec![n..planned]);
    assert!(
        acq.problems.iter().any(|p| p.contains("Stopped")),
        "{:?}",
        acq.problems
    );
    check_consistent(&acq);
    check_truth(&acq, &s);
    let st = s.stats();
    assert_eq!(st.truth.len() as u64, n);
    // STOP ends the run at the next sample with the command at zero
    assert_eq!(acq.raw.last().map(|r| r[0]), Some(0));
    assert!(acq.raw[..acq.raw.len() - 1].iter().all(|r| r[0] != 0));
    assert_eq!(st.output, 0);
    // the CSV says so in its footer
    let text = std::fs::read_to_string(&path).unwrap();
    let footer = text.trim_end().lines().last().unwrap();
    assert!(
        footer.starts_with(&format!("# incomplete: missing samples {n}..{planned} (")),
        "{footer}"
    );
    assert_eq!(
        text.lines().filter(|l| !l.starts_with('#')).count() as u64,
        n + 1
    );
    // STOP latches nothing: the drive is idle and runs again without a new CONFIGURE
    let status = c.status().unwrap();
    assert_eq!(status.state, DriveState::Idle);
    assert_eq!(status.fault, fault::NONE);
    assert_eq!(status.samples_done, end.total_samples);
    let acq2 = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    assert!(acq2.complete, "{:?}", acq2.problems);
    check_truth(&acq2, &s);
    eprintln!("stop test: {:?}", t0.elapsed());
}
}

on_both_firmwares! {
fn estop_latches_until_configure(fw) {
    let _g = lock();
    let t0 = Instant::now();
    let s = fast_sim(fw, SimClock::RealTime);
    let mut c = fast_client(&s, ClientConfig::default(), &Configure::default());
    stop_at(&mut c, 250, true);
    let acq = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    let end = end_of(&acq);
    let n = end.total_samples as u64;
    eprintln!(
        "estop: {n} samples, missing {:?}, problems {:?}",
        acq.missing, acq.problems
    );
    assert_eq!(end.reason, EndReason::Estop);
    assert!(!acq.complete);
    assert_prefix(&acq, n);
    assert_eq!(acq.missing, vec![n..acq.planned_samples]);
    check_consistent(&acq);
    check_truth(&acq, &s);
    // immediate: no ramp sample, the last sample is the excitation's; the output is off
    assert!(acq.raw.iter().all(|r| r[0] != 0));
    let st = s.stats();
    assert_eq!(st.truth.len() as u64, n);
    assert_eq!(st.output, 0);
    // the drive reports the latched fault and refuses to start
    let status = c.status().unwrap();
    assert_eq!(status.state, DriveState::Fault);
    assert_eq!(status.fault, fault::ESTOP);
    assert_eq!(status.samples_done, end.total_samples);
    assert_nak_fault(c.run_prbs(&short_prbs(), &mut NullSink), fault::ESTOP);
    // neither STOP (ACKed when idle) nor a new HELLO clears it; ESTOP when idle is ACKed too
    c.stop().unwrap();
    c.estop().unwrap();
    c.hello().unwrap();
    assert_eq!(c.status().unwrap().fault, fault::ESTOP);
    assert_nak_fault(c.run_prbs(&short_prbs(), &mut NullSink), fault::ESTOP);
    assert_eq!(s.stats().runs_started, 1);
    // CONFIGURE re-enables the drive
    c.configure(&Configure::default()).unwrap();
    let status = c.status().unwrap();
    assert_eq!(
        (status.state, status.fault),
        (DriveState::Idle, fault::NONE)
    );
    let acq2 = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    assert!(acq2.complete, "{:?}", acq2.problems);
    check_truth(&acq2, &s);
    eprintln!("estop test: {:?}", t0.elapsed());
}
}

/// Records when each sample arrived.
#[derive(Default)]
struct ArrivalSink(Vec<(u64, Instant)>);

impl SampleSink for ArrivalSink {
    fn begin(&mut self, _: &RunInfo) -> io::Result<()> {
        Ok(())
    }
    fn sample(&mut self, index: u64, _: f64, _: f64, _: f64, _: f64) -> io::Result<()> {
        self.0.push((index, Instant::now()));
        Ok(())
    }
    fn finish(&mut self, _: &Acquisition) -> io::Result<()> {
        Ok(())
    }
}

on_both_firmwares! {
fn keepalive_expiry_ramps_down(fw) {
    let _g = lock();
    let t0 = Instant::now();
    let s = fast_sim(fw, SimClock::RealTime);
    // The host goes silent during the run: no KEEPALIVE, and DATA keep flowing so it never polls.
    let conf = Configure {
        block_samples: 10,
        ..Configure::default()
    };
    let silent = ClientConfig {
        keepalive: Duration::from_secs(3600),
        ..ClientConfig::default()
    };
    let mut c = fast_client(&s, silent, &conf);
    let test = PrbsTest {
        periods: 4,
        ..short_prbs()
    };
    let mut sink = ArrivalSink::default();
    let started = Instant::now();
    let acq = c.run_prbs(&test, &mut sink).unwrap();
    let took = started.elapsed();
    let end = end_of(&acq);
    let n = end.total_samples as u64;
    let planned = 100 + 4 * 127 * 2;
    assert_eq!(end.reason, EndReason::Keepalive);
    // the ramp: 50 ms (50 samples at 1 kHz) from the last command down to zero
    let ramp = 50;
    let k0 = n - ramp;
    eprintln!(
        "keepalive: expired at sample {k0}, run ended at {n} of {planned} after {took:?}; problems {:?}",
        acq.problems
    );
    assert!((490..=530).contains(&k0), "expired at sample {k0}");
    // The samples are paced at 1 kHz in real time, so the run lasts about its `n` samples (the
    // silence really expired; a block of 10 samples of slack). A fixed 550 ms failed whenever the
    // expiry fell before sample 500, which the bound above allows (548.5 ms measured).
    assert!(
        took >= Duration::from_millis(n - 10),
        "{took:?} for {n} samples"
    );
    assert!(!acq.complete);
    assert_prefix(&acq, n);
    assert_eq!(acq.missing, vec![n..planned]);
    assert!(
        acq.problems.iter().any(|p| p.contains("Keepalive")),
        "{:?}",
        acq.problems
    );
    check_consistent(&acq);
    check_truth(&acq, &s);
    let u_last = acq.raw[k0 as usize - 1][0] as f64;
    for j in 0..ramp {
        let want = (u_last * (ramp - 1 - j) as f64 / ramp as f64).round();
        let got = acq.raw[(k0 + j) as usize][0] as f64;
        assert!(
            (got - want).abs() <= 1.0,
            "ramp sample {j}: {got} vs {want}"
        );
    }
    assert_eq!(acq.raw.last().map(|r| r[0]), Some(0));
    assert_eq!(s.stats().output, 0);
    // paced in real time: the ramp's samples arrive over its 50 ms (blocks of 10 samples)
    let at = |k: u64| {
        sink.0
            .iter()
            .find(|(i, _)| *i == k)
            .map(|(_, t)| *t)
            .unwrap()
    };
    let spread = at(n - 1).duration_since(at(k0));
    eprintln!("keepalive: ramp arrived over {spread:?}");
    assert!(spread >= Duration::from_millis(20), "{spread:?}");
    // the fault is latched and reported
    let status = c.status().unwrap();
    assert_eq!(status.state, DriveState::Fault);
    assert_eq!(status.fault, fault::KEEPALIVE);
    assert_nak_fault(c.run_prbs(&test, &mut NullSink), fault::KEEPALIVE);
    c.configure(&conf).unwrap();
    assert_eq!(c.status().unwrap().state, DriveState::Idle);
    eprintln!("keepalive test: {:?}", t0.elapsed());
}
}

/// A run that trips: ends with LIMIT at the first sample beyond the limit, which is kept.
fn trip(
    fw: FirmwareKind,
    conf: Configure,
    test: PrbsTest,
    channel: usize,
    limit: i16,
    code: u8,
) -> u64 {
    let s = fast_sim(fw, SimClock::Virtual);
    let mut c = fast_client(&s, vcfg(&s), &conf);
    let acq = c.run_prbs(&test, &mut NullSink).unwrap();
    let end = end_of(&acq);
    let n = end.total_samples as u64;
    eprintln!(
        "trip (channel {channel}, limit {limit}): {n} of {} samples, last {:?}, problems {:?}",
        acq.planned_samples,
        acq.raw.last(),
        acq.problems
    );
    assert_eq!(end.reason, EndReason::Limit);
    assert!(n >= 1 && n < acq.planned_samples);
    assert!(!acq.complete);
    assert_prefix(&acq, n);
    assert_eq!(acq.missing, vec![n..acq.planned_samples]);
    check_consistent(&acq);
    check_truth(&acq, &s);
    assert_eq!(s.stats().truth.len() as u64, n);
    // the last sample is the first beyond the limit
    let (last, before) = acq.raw.split_last().unwrap();
    assert!(last[channel].unsigned_abs() > limit as u16, "{last:?}");
    assert!(before
        .iter()
        .all(|r| r[channel].unsigned_abs() <= limit as u16));
    assert_eq!(s.stats().output, 0);
    let status = c.status().unwrap();
    assert_eq!((status.state, status.fault), (DriveState::Fault, code));
    assert_nak_fault(c.run_prbs(&test, &mut NullSink), code);
    c.configure(&Configure::default()).unwrap();
    assert_eq!(c.status().unwrap().state, DriveState::Idle);
    n
}

on_both_firmwares! {
fn speed_limit_trips(fw) {
    let _g = lock();
    let t0 = Instant::now();
    // 3 V drives the motor towards 20 rad/s; the trip is at 10 rad/s, during the settle
    let conf = Configure {
        y_limit: 1000,
        ..Configure::default()
    };
    let n = trip(fw, conf, short_prbs(), 1, 1000, fault::SPEED_LIMIT);
    assert!(n < 100, "{n}");
    eprintln!("speed trip test: {:?}", t0.elapsed());
}
}

on_both_firmwares! {
fn current_limit_trips(fw) {
    let _g = lock();
    let t0 = Instant::now();
    // 50 samples at 0 V (no current), then the PRBS's first bit (a 0, seed 1) steps to -3 V:
    // -3 A at standstill, beyond the 2 A trip at once
    let conf = Configure {
        i_limit: 2000,
        ..Configure::default()
    };
    let test = PrbsTest {
        amplitude_v: 3.0,
        offset_v: 0.0,
        settle_s: 0.05,
        ..short_prbs()
    };
    let n = trip(fw, conf, test, 2, 2000, fault::CURRENT_LIMIT);
    assert_eq!(n, 51);
    eprintln!("current trip test: {:?}", t0.elapsed());
}
}

on_both_firmwares! {
fn streamed_sine_dft_matches_the_drive(fw) {
    let _g = lock();
    let t0 = Instant::now();
    let s = fast_sim(fw, SimClock::Virtual);
    let conf = Configure::default();
    let mut c = fast_client(&s, vcfg(&s), &conf);
    let fs = conf.sample_rate_hz;
    let mut worst_phasor: f64 = 0.0;
    let (mut worst_db, mut worst_deg): (f64, f64) = (0.0, 0.0);
    // 7 Hz and 130 Hz: measurement windows that are not whole periods of the sample clock
    for (f_mhz, settle, cycles) in [
        (5_000, 1, 2),
        (7_000, 1, 2),
        (20_000, 4, 4),
        (130_000, 8, 8),
    ] {
        let cmd = StartSine {
            freq_mhz: f_mhz,
            amplitude: 1000,
            offset: 3000,
            settle_cycles: settle,
            cycles,
            flags: SINE_STREAM | SINE_DFT,
        };
        let acq = c.run_sine(&cmd, &mut NullSink).unwrap();
        assert!(acq.complete, "{:?}", acq.problems);
        check_truth(&acq, &s);
        let (settle_n, measure_n) = cmd.sample_counts(fs).unwrap();
        assert_eq!(acq.index.len() as u32, settle_n + measure_n);
        assert_eq!(acq.sine.map(|r| r.n), Some(measure_n));
        let d = drive_dft(&acq).unwrap();
        let h = host_dft(&acq, &cmd, fs).unwrap();
        for k in 0..2 {
            worst_phasor = worst_phasor
                .max((d[k].0 - h[k].0).abs())
                .max((d[k].1 - h[k].1).abs());
        }
        let f = f_mhz as f64 / 1000.0;
        let pd = drive::client::bode_point(f, d, measure_n, true, &conf).unwrap();
        let ph = drive::client::bode_point(f, h, measure_n, false, &conf).unwrap();
        worst_db = worst_db.max((pd.gain_db - ph.gain_db).abs());
        let mut dp = pd.phase_deg - ph.phase_deg;
        dp -= 360.0 * (dp / 360.0).round();
        worst_deg = worst_deg.max(dp.abs());
        eprintln!(
            "{f} Hz: drive {:.4} dB {:.4} deg, host {:.4} dB {:.4} deg (U {:?} vs {:?})",
            pd.gain_db, pd.phase_deg, ph.gain_db, ph.phase_deg, d[0], h[0]
        );
        if f_mhz == 130_000 {
            // the same point with the DFT only: nothing streamed, the same measurement
            let quiet = StartSine {
                flags: SINE_DFT,
                ..cmd
            };
            let acq_q = c.run_sine(&quiet, &mut NullSink).unwrap();
            assert!(acq_q.complete, "{:?}", acq_q.problems);
            assert!(acq_q.index.is_empty() && acq_q.missing.is_empty());
            let e = end_of(&acq_q);
            assert_eq!((e.samples_sent, e.blocks_dropped), (0, 0));
            assert_eq!(acq_q.sine.map(|r| (r.u_re, r.u_im, r.y_re, r.y_im)), {
                acq.sine.map(|r| (r.u_re, r.u_im, r.y_re, r.y_im))
            });
        }
    }
    eprintln!(
        "host vs drive DFT: worst phasor difference {worst_phasor:.2e} LSB, gain {worst_db:.2e} dB, phase {worst_deg:.2e} deg"
    );
    // The drive sends the DFT in Q8: each component is within 0.5/256 LSB of the exact sum.
    assert!(worst_phasor <= 0.5 / 256.0 + 1e-9, "{worst_phasor}");
    assert!(worst_db < 1e-3, "{worst_db}");
    assert!(worst_deg < 1e-2, "{worst_deg}");
    eprintln!("sine stream test: {:?}", t0.elapsed());
}
}

on_both_firmwares! {
fn retried_start_runs_once(fw) {
    let _g = lock();
    let t0 = Instant::now();
    let s = fast_sim(fw, SimClock::Virtual);
    let mut c = fast_client(&s, vcfg(&s), &Configure::default());
    // the drive starts the run but its ACK is lost: the client resends START with the same seq
    s.lose_next_answer(ty::START_PRBS);
    let acq = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    let st = s.stats();
    eprintln!(
        "retried START: client {:?}, sim runs {} replays {} lost {}, events {:?}",
        c.stats(),
        st.runs_started,
        st.replays,
        st.answers_lost,
        st.events
    );
    assert_eq!(st.answers_lost, 1);
    assert_eq!(c.stats().retries, 1);
    assert_eq!(st.replays, 1, "the retry is answered from the replay cache");
    assert_eq!(
        st.runs_started, 1,
        "the retried START must not start a second run"
    );
    assert!(acq.complete, "{:?}", acq.problems);
    check_truth(&acq, &s);
    let status = c.status().unwrap();
    assert_eq!(status.run_id, acq.run_id);
    assert_eq!(status.samples_done as u64, acq.total_samples);
    eprintln!("retried START test: {:?}", t0.elapsed());
}
}

/// A drive of an earlier protocol version (2: an empty KEEPALIVE that any frame stood in for)
/// ignores version-3 frames, and a version-3 host ignores its answers: before, the host reported
/// a drive that does not answer (`Timeout`). Now it probes with a HELLO of each earlier version
/// and names both versions. The drive here is a version-2 stand-in on a real pty that answers only
/// HELLOs framed in version 2 (in version 2).
#[test]
fn a_drive_of_another_protocol_version_is_named() {
    use drive::codec::{encode_body_as, wrap_body};
    use drive::protocol::{Frame, HelloReply, Message, PROTO_VERSION};
    use serialport::{SerialPort, TTYPort};
    use std::io::{Read, Write};
    assert_eq!(PROTO_VERSION, 3);
    let (mut master, slave) = TTYPort::pair().expect("a pty pair");
    let path = slave.name().expect("the slave's path");
    drop(slave);
    master
        .set_timeout(Duration::from_millis(50))
        .expect("timeout");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = stop.clone();
    let old_drive = std::thread::spawn(move || {
        let (mut buf, mut frame, mut seen) = ([0u8; 512], Vec::new(), Vec::new());
        while !stop2.load(std::sync::atomic::Ordering::SeqCst) {
            let n = match master.read(&mut buf) {
                Ok(n) => n,
                Err(_) => continue,
            };
            for &b in &buf[..n] {
                if b != 0 {
                    frame.push(b);
                    continue;
                }
                let Ok(body) = cobs::decode_vec(&frame) else {
                    frame.clear();
                    continue;
                };
                frame.clear();
                if body.len() < 6 {
                    continue;
                }
                seen.push(body[0]);
                if body[0] == 2 && body[1] == 0x01 {
                    let seq = u16::from_le_bytes([body[2], body[3]]);
                    let reply = Frame {
                        seq,
                        msg: Message::HelloReply(HelloReply {
                            proto_version: 2,
                            fw_major: 1,
                            fw_minor: 2,
                            n_channels: 3,
                            max_block_samples: 66,
                            boot_id: 0xBEEF,
                            max_sample_rate_hz: 20_000,
                        }),
                    };
                    let _ = master.write_all(&wrap_body(&encode_body_as(&reply, 2)));
                }
            }
        }
        seen
    });
    let t0 = Instant::now();
    let r = Client::open(
        &path,
        ClientConfig {
            baud: 921_600,
            timeout: Some(Duration::from_millis(100)),
            retries: 1,
            ..ClientConfig::default()
        },
    );
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    let seen = old_drive.join().unwrap();
    let Err(e) = r else {
        panic!("no client for a drive of another version")
    };
    assert!(
        matches!(e, Error::Version { drive: 2, host: 3 }),
        "{e:?} after {:?}",
        t0.elapsed()
    );
    let msg = e.to_string();
    assert!(
        msg.contains("protocol version 2") && msg.contains("speaks 3"),
        "{msg}"
    );
    // the host said HELLO in its version (twice: one retry), then once in version 2, which
    // answered
    assert_eq!(seen, [3, 3, 2], "versions of the host's frames");
}

/// A sink that stops reading (sleeps) once, at sample `at`, for `pause`, and notes how many
/// samples the drive had produced when the pause ended.
struct PausingSink<'a> {
    sim: &'a DriveSim,
    at: u64,
    pause: Duration,
    produced: Option<usize>,
}

impl SampleSink for PausingSink<'_> {
    fn begin(&mut self, _: &RunInfo) -> io::Result<()> {
        Ok(())
    }
    fn sample(&mut self, index: u64, _: f64, _: f64, _: f64, _: f64) -> io::Result<()> {
        if index == self.at {
            std::thread::sleep(self.pause);
            self.produced = Some(self.sim.stats().truth.len());
        }
        Ok(())
    }
    fn finish(&mut self, _: &Acquisition) -> io::Result<()> {
        Ok(())
    }
}

on_both_firmwares! {
/// Virtual time waits for a host that reads late: the host stops reading (and sending) for
/// 300 ms of wall time at sample 200 of 2132. With a keepalive of 5 s nothing but the flow control
/// holds the drive's clock: it must stop within what the host's read buffer (2048 bytes), the pty
/// (512 bytes unread), one step of the line and the drive's 4 DATA blocks hold, under 4500 bytes
/// or 700 samples, not run the record to its end; then the run completes with nothing lost or
/// expired, in far less than its 2.13 s of drive time besides the pause.
fn virtual_time_waits_for_a_host_that_reads_late(fw) {
    let _g = lock();
    let s = fast_sim(fw, SimClock::Virtual);
    let conf = Configure {
        keepalive_ms: 5000,
        ..Configure::default()
    };
    // the host's keepalive on the drive's clock, but longer than the run: only the flow control
    // can hold the clock
    let host = ClientConfig {
        keepalive: Duration::from_secs(4),
        ..vcfg(&s)
    };
    let mut c = fast_client(&s, host, &conf);
    let mut sink = PausingSink {
        sim: &s,
        at: 200,
        pause: Duration::from_millis(300),
        produced: None,
    };
    let test = PrbsTest {
        periods: 8,
        ..short_prbs()
    };
    let started = Instant::now();
    let acq = c.run_prbs(&test, &mut sink).unwrap();
    let took = started.elapsed();
    let produced = sink.produced.expect("the sink paused");
    eprintln!(
        "virtual time, host paused at sample 200: the drive had produced {produced}; run {took:?}"
    );
    assert_eq!(acq.total_samples, 100 + 8 * 254);
    assert!(produced < 200 + 700, "{produced}");
    assert!(acq.complete, "{:?}", acq.problems);
    assert_eq!(s.stats().blocks_dropped, 0);
    check_consistent(&acq);
    check_truth(&acq, &s);
    assert!(took < Duration::from_millis(1200), "{took:?}");
}
}

on_both_firmwares! {
/// Virtual time with the host's keepalive on the drive's clock is paced by the protocol alone: a
/// 1 Hz sine run without streaming (6 s of drive time, nothing on the line but the answers)
/// takes one KEEPALIVE per keepalive interval (150 ms) of drive time, and the drive's clock
/// blocks on the wall clock about once for each (it wakes the host, which answers at once),
/// never per step. A drive clock bounded by a wall-clock keepalive timer (the host's every
/// 150 ms of wall time, the drive at most 250 ms past it) or a simulator that sleeps between
/// steps would wait on the wall clock tens to thousands of times. Counters, not timings.
fn virtual_time_with_the_host_on_its_clock_waits_only_for_the_keepalive(fw) {
    let _g = lock();
    let s = fast_sim(fw, SimClock::Virtual);
    let clock = s
        .virtual_clock()
        .expect("a simulator in virtual time has a clock");
    let mut c = fast_client(&s, vcfg(&s), &Configure::default());
    let cmd = StartSine {
        freq_mhz: 1000,
        amplitude: 1000,
        offset: 3000,
        settle_cycles: 2,
        cycles: 4,
        flags: SINE_DFT,
    };
    let (st0, wakes0, t0) = (s.stats(), clock.wakes(), clock.now());
    let acq = c.run_sine(&cmd, &mut NullSink).unwrap();
    let (st, wakes, drive_s) = (
        s.stats(),
        clock.wakes() - wakes0,
        (clock.now() - t0).as_secs_f64(),
    );
    let frames = st.frames_received - st0.frames_received;
    let waits = st.wall_waits - st0.wall_waits;
    eprintln!(
        "virtual time, host on the drive's clock: {drive_s:.2} s of drive time, {frames} frames \
         from the host, {wakes} wake-ups, {waits} waits on the wall clock"
    );
    assert!(acq.complete, "{:?}", acq.problems);
    assert_eq!(end_of(&acq).reason, EndReason::Complete);
    assert!(drive_s >= 6.0, "{drive_s}");
    // START and one KEEPALIVE per interval of drive time (the drive's clock cannot pass the
    // host's due time without a frame); a host thread preempted between publishing its due time
    // and writing its frame costs a spare wake-up and KEEPALIVE, hence the slack above
    let intervals = drive_s / 0.150;
    assert!(frames >= (intervals as u64).saturating_sub(2), "{frames}");
    assert!(frames as f64 <= 1.5 * intervals + 4.0, "{frames}");
    assert!(wakes as f64 <= 1.5 * intervals + 2.0, "{wakes}");
    // each wait ends when the host's frame arrives
    assert!(waits <= 2 * wakes + 4, "{waits} waits for {wakes} wake-ups");
}
}

on_both_firmwares! {
/// Virtual time does not hide a silent host: with no KEEPALIVE and no STATUS poll (the stream
/// timeout longer than the test: in virtual time the drive's clock waiting for the host stops the
/// DATA, which a polling host would answer with a STATUS, a frame that keeps the drive alive), the
/// drive's keepalive still expires, after the host has been silent for the keepalive interval of
/// wall time (the drive's clock waits that long for it), at the same sample as in real time.
fn virtual_time_still_expires_a_silent_host(fw) {
    let _g = lock();
    let s = fast_sim(fw, SimClock::Virtual);
    let conf = Configure {
        block_samples: 10,
        ..Configure::default()
    };
    let silent = ClientConfig {
        keepalive: Duration::from_secs(3600),
        stream_timeout: Some(Duration::from_secs(30)),
        ..ClientConfig::default()
    };
    let mut c = fast_client(&s, silent, &conf);
    let test = PrbsTest {
        periods: 4,
        ..short_prbs()
    };
    let started = Instant::now();
    let acq = c.run_prbs(&test, &mut NullSink).unwrap();
    let took = started.elapsed();
    let end = end_of(&acq);
    eprintln!("virtual keepalive: {end:?} after {took:?}");
    assert_eq!(end.reason, EndReason::Keepalive);
    // keepalive 500 ms at 1 kHz after the START, then a 50-sample ramp
    let k0 = end.total_samples as u64 - 50;
    assert!((495..=510).contains(&k0), "expired at sample {k0}");
    assert!(took >= Duration::from_millis(500), "{took:?}");
    check_consistent(&acq);
    check_truth(&acq, &s);
}
}

/// A drive of firmware 1.1 runs controller format 1 only: it answers LOAD_CTRL of format 2 with
/// NAK BAD_VALUE detail 0 (as the 1.1 engine did for any other format). The host sends a
/// controller that fits format 1 (sections only, at most 24) in format 1, which that drive
/// loads, and for a FOPID's (delay taps) says that it needs firmware 1.2. The drive here is a
/// firmware-1.1 stand-in on a real pty: HELLO, CONFIGURE, LOAD_CTRL and LOAD_SECTION as 1.1
/// answers them.
#[test]
fn a_drive_of_firmware_1_1_loads_format_1_and_a_fopid_is_said_to_need_1_2() {
    use drive::codec::{decode_body, encode_body_as, wrap_body};
    use drive::ctrl::{FixedCtrl, Section};
    use drive::protocol::{Ack, Frame, HelloReply, Message, Nak, NakCode, PROTO_VERSION};
    use serialport::{SerialPort, TTYPort};
    use std::io::{Read, Write};
    let (mut master, slave) = TTYPort::pair().expect("a pty pair");
    let path = slave.name().expect("the slave's path");
    drop(slave);
    master
        .set_timeout(Duration::from_millis(20))
        .expect("timeout");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = stop.clone();
    let drive_1_1 = std::thread::spawn(move || {
        let (mut buf, mut frame, mut formats) = ([0u8; 512], Vec::new(), Vec::new());
        while !stop2.load(std::sync::atomic::Ordering::SeqCst) {
            let n = match master.read(&mut buf) {
                Ok(n) => n,
                Err(_) => continue,
            };
            for &b in &buf[..n] {
                if b != 0 {
                    frame.push(b);
                    continue;
                }
                let body = cobs::decode_vec(&frame);
                frame.clear();
                let Ok(Ok(f)) = body.map(|b| decode_body(&b)) else {
                    continue;
                };
                let ack = |t: u8| {
                    Message::Ack(Ack {
                        acked_type: t,
                        run_id: 0,
                        total_samples: 0,
                    })
                };
                let msg = match f.msg {
                    Message::Hello => Message::HelloReply(HelloReply {
                        proto_version: PROTO_VERSION,
                        fw_major: 1,
                        fw_minor: 1,
                        n_channels: 3,
                        max_block_samples: 66,
                        boot_id: 0x1111,
                        max_sample_rate_hz: 20_000,
                    }),
                    Message::LoadCtrl(c) => {
                        formats.push(c.format);
                        if c.format == 1 && c.n_sections <= 24 {
                            ack(0x0A)
                        } else {
                            Message::Nak(Nak {
                                nak_type: 0x0A,
                                code: NakCode::BadValue,
                                detail: if c.format == 1 { 1 } else { 0 },
                            })
                        }
                    }
                    Message::Configure(_) => ack(0x02),
                    Message::LoadSection(_) => ack(0x0B),
                    _ => continue,
                };
                let reply = Frame { seq: f.seq, msg };
                let _ = master.write_all(&wrap_body(&encode_body_as(&reply, PROTO_VERSION)));
            }
        }
        formats
    });
    let mut c = Client::open(
        &path,
        ClientConfig {
            baud: BAUD,
            timeout: Some(Duration::from_millis(300)),
            retries: 1,
            ..ClientConfig::default()
        },
    )
    .expect("client opens");
    c.configure(&Configure::default()).expect("configure");
    let s = |a: i32, g: i32| Section { a_q30: a, g_q24: g };
    let fopi = FixedCtrl {
        d_q24: 1 << 24,
        dinv_q16: 1 << 16,
        sections: vec![s(1 << 30, 5000), s(0, 70)],
        taps: vec![],
    };
    let fopid = FixedCtrl {
        taps: vec![-9000, 400],
        ..fopi.clone()
    };
    let r1 = c.load_controller(&fopi);
    let r2 = c.load_controller(&fopid);
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    let formats = drive_1_1.join().unwrap();
    r1.expect("firmware 1.1 loads a controller of format 1");
    let e = r2.expect_err("firmware 1.1 refuses format 2").to_string();
    assert!(
        e.contains("firmware 1.1") && e.contains("format 2") && e.contains("needs firmware 1.2"),
        "{e}"
    );
    assert_eq!(formats, [1, 2]);
}

/// Issue 46, item 11: the host of a run dies without STOP (its client dropped after the START),
/// and another program polls the drive every 0.2 s (`fracid drive status` under `watch`: HELLO,
/// then STATUS). Before, any valid frame reset the keepalive timer, so the polls kept the orphaned
/// run (and the motor) going with no host; now only a KEEPALIVE of the run's id does: the run
/// ends on the keepalive, ramped down, fault KEEPALIVE latched. With both firmwares.
#[test]
fn an_orphaned_run_is_not_kept_alive_by_another_programs_polls() {
    use drive::protocol::Message;
    use drive::sim::FirmwareKind;
    let _g = lock();
    for firmware in [FirmwareKind::Rust, FirmwareKind::C] {
        let s = DriveSim::spawn(SimConfig {
            baud: BAUD,
            firmware,
            ..SimConfig::default()
        })
        .expect("simulator starts");
        let conf = Configure::default();
        // 10 periods of 254 samples: 2.6 s of run, far longer than the keepalive (500 ms)
        let cmd = PrbsTest {
            periods: 10,
            ..short_prbs()
        }
        .to_command(&conf)
        .unwrap();
        let run_id = {
            let mut host = fast_client(&s, ClientConfig::default(), &conf);
            match host.request(Message::StartPrbs(cmd)).unwrap() {
                Message::Ack(a) => a.run_id,
                other => panic!("{other:?}"),
            }
            // the host goes away without STOP
        };
        // a new program each time, as `fracid drive status` is: HELLO, then STATUS
        let watch = || {
            Client::open(
                s.port_path(),
                ClientConfig {
                    baud: BAUD,
                    ..ClientConfig::default()
                },
            )
            .unwrap()
        };
        let t0 = Instant::now();
        let mut states = Vec::new();
        while t0.elapsed() < Duration::from_millis(1600) {
            let st = watch().status().unwrap();
            assert_eq!(st.run_id, run_id);
            states.push(st.state);
            std::thread::sleep(Duration::from_millis(200));
        }
        let mut watcher = watch();
        let st = watcher.status().unwrap();
        assert_eq!(
            (st.state, st.fault),
            (DriveState::Fault, fault::KEEPALIVE),
            "{firmware:?}: polled for 1.6 s after its host went away: {st:?} ({states:?})"
        );
        assert!(st.samples_done < 1000, "{firmware:?}: {st:?}");
        match watcher.request(Message::EndQuery(run_id)).unwrap() {
            Message::StreamEnd(e) => {
                assert_eq!(e.reason, EndReason::Keepalive, "{firmware:?}: {e:?}");
                // 500 ms of silence from its host at 1 kHz, then the 50 ms ramp (a block of
                // slack for the wall clock)
                assert!(
                    (540..=600).contains(&e.total_samples),
                    "{firmware:?}: {e:?}"
                );
            }
            other => panic!("{firmware:?}: {other:?}"),
        }
        assert_eq!(s.stats().output, 0, "{firmware:?}: the output is zero");
    }
}
