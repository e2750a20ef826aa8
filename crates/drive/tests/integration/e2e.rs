//! End-to-end over a real pseudo-terminal: simulator thread + client. Serialised with a lock (the
//! timing tests run the simulator in real time; two at once on a 2-core machine would distort
//! their timing). Tests whose outcome does not depend on the wall clock run the simulator in
//! virtual time ([`vsim`], [`vclient`]).

use drive::client::{Acquisition, Client, ClientConfig, CsvSink, NullSink, PrbsTest, SineSweep};
use drive::protocol::Configure;
use drive::sim::{DriveSim, FaultAt, Faults, FirmwareKind, SimClock, SimConfig};
use std::sync::Mutex;
use std::time::Duration;

static SERIAL: Mutex<()> = Mutex::new(());

pub(crate) fn lock() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A short PRBS run: 1 kHz, order 7, clock 2 samples, 2 periods: 100 + 508 samples, ~0.6 s.
pub(crate) fn short_prbs() -> PrbsTest {
    PrbsTest {
        order: 7,
        seed: 1,
        clock_s: 0.002,
        amplitude_v: 1.0,
        offset_v: 3.0,
        periods: 2,
        settle_s: 0.1,
    }
}

pub(crate) fn sim(
    firmware: FirmwareKind,
    faults: Faults,
    baud: u32,
    link: Option<std::path::PathBuf>,
) -> DriveSim {
    DriveSim::spawn(SimConfig {
        firmware,
        baud,
        faults,
        link,
        ..SimConfig::default()
    })
    .expect("simulator starts")
}

pub(crate) fn client(path: &str, baud: u32) -> Client {
    let mut c = Client::open(
        path,
        ClientConfig {
            baud,
            ..ClientConfig::default()
        },
    )
    .expect("client opens");
    c.configure(&Configure::default()).expect("configure");
    c
}

/// A fault-free simulator in virtual time (the default model and effects).
pub(crate) fn vsim(firmware: FirmwareKind, baud: u32) -> DriveSim {
    vspawn(SimConfig {
        firmware,
        baud,
        ..SimConfig::default()
    })
}

/// `cfg` in virtual time.
pub(crate) fn vspawn(cfg: SimConfig) -> DriveSim {
    DriveSim::spawn(SimConfig {
        clock: SimClock::Virtual,
        ..cfg
    })
    .expect("simulator starts")
}

/// [`client`] for a simulator in virtual time: the keepalive on the drive's clock.
pub(crate) fn vclient(sim: &DriveSim, baud: u32) -> Client {
    let mut c = Client::open(sim.port_path(), vclient_config(sim, baud)).expect("client opens");
    c.configure(&Configure::default()).expect("configure");
    c
}

/// The client settings of [`vclient`]: the default keepalive interval, kept on the simulator's
/// clock ([`ClientConfig::clock`]), so that the drive's clock need not wait for a wall-clock
/// timer.
pub(crate) fn vclient_config(sim: &DriveSim, baud: u32) -> ClientConfig {
    ClientConfig {
        baud,
        clock: sim.virtual_clock(),
        ..ClientConfig::default()
    }
}

/// Every received sample must equal what the drive produced: never silently wrong data.
pub(crate) fn check_truth(acq: &Acquisition, sim: &DriveSim) {
    let st = sim.stats();
    if st.truth_run_id != acq.run_id {
        return; // the drive reset: the truth of that run was discarded with it
    }
    for (k, &idx) in acq.index.iter().enumerate() {
        assert_eq!(
            Some(&acq.raw[k]),
            st.truth.get(idx as usize),
            "sample {idx} differs from what the drive produced"
        );
    }
}

pub(crate) fn check_consistent(acq: &Acquisition) {
    // missing + received = the run's span (produced or planned, whichever is longer), disjoint
    let missing: u64 = acq.missing.iter().map(|r| r.end - r.start).sum();
    assert_eq!(
        missing + acq.index.len() as u64,
        acq.total_samples.max(acq.planned_samples),
        "{acq:?}"
    );
    assert_eq!(
        acq.complete,
        acq.missing.is_empty() && acq.problems.is_empty()
    );
    for r in &acq.missing {
        assert!(acq.index.iter().all(|i| !r.contains(i)));
    }
}

on_both_firmwares! {
fn clean_run_is_complete(fw) {
    let _g = lock();
    let s = vsim(fw, 115_200);
    let mut c = vclient(&s, 115_200);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("prbs.csv");
    let mut sink = CsvSink::new(std::fs::File::create(&path).unwrap());
    let acq = c.run_prbs(&short_prbs(), &mut sink).unwrap();
    drop(sink);
    assert!(acq.complete, "{:?}", acq.problems);
    assert_eq!(acq.total_samples, 100 + 2 * 127 * 2);
    assert_eq!(acq.index.len() as u64, acq.total_samples);
    check_truth(&acq, &s);
    // the excitation is the PRBS of fracsim, sample for sample
    let p = fracsim::prbs::Prbs {
        order: 7,
        clock: 0.002,
        amplitude: 1.0,
        offset: 3.0,
        periods: 2,
        seed: 1,
    };
    let u = p.signal(1e-3).unwrap();
    for (k, &v) in u.iter().enumerate() {
        assert!((acq.u[100 + k] - v).abs() < 1e-9, "u[{k}]");
    }
    // the speed responds: mean speed near 6.82 * 3 V at the end of the settle
    assert!(acq.y[99] > 10.0, "y = {}", acq.y[99]);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\nt,u,y,i\n"));
    assert!(text
        .trim_end()
        .ends_with(&format!("# complete: {} samples", acq.total_samples)));
    let st = c.status().unwrap();
    assert_eq!(st.samples_done as u64, acq.total_samples);
}
}

/// A PRBS run under `faults`, checked against the drive's truth. With `link`, the host opens a
/// symlink that follows the simulator's pty; a watcher then checks that the path is absent while
/// the port is closed (a freed pty number taken by another process must never be reopened).
fn faulty_run(fw: FirmwareKind, faults: Faults, link: bool) -> (Acquisition, DriveSim, Client) {
    let dir = tempfile::tempdir().unwrap();
    let link = link.then(|| dir.path().join("drive-tty"));
    let s = sim(fw, faults, 115_200, link.clone());
    let mut c = client(s.port_path(), 115_200);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watcher = link.map(|path| {
        let done = done.clone();
        std::thread::spawn(move || {
            let mut vanished = false;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                vanished |= std::fs::symlink_metadata(&path).is_err();
                std::thread::sleep(Duration::from_millis(2));
            }
            vanished
        })
    });
    let acq = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    if let Some(w) = watcher {
        assert!(
            w.join().unwrap(),
            "the port's path stayed while the drive was disconnected"
        );
    }
    check_consistent(&acq);
    check_truth(&acq, &s);
    // keep the tempdir alive until the run is over
    drop(dir);
    (acq, s, c)
}

on_both_firmwares! {
fn bit_errors_1e4(fw) {
    let _g = lock();
    let (acq, s, c) = faulty_run(
        fw,
        Faults {
            bit_error_rate: 1e-4,
            seed: 11,
            ..Faults::default()
        },
        false,
    );
    let st = s.stats();
    eprintln!(
        "ber 1e-4: complete {}, missing {:?}, damaged frames {}/{}, client {:?}",
        acq.complete,
        acq.missing,
        st.frames_damaged,
        st.frames_sent,
        c.stats()
    );
    // damaged frames are lost, never accepted: the truth check above found no wrong sample
    if st.frames_damaged == 0 {
        assert!(acq.complete);
    }
}
}

on_both_firmwares! {
fn dropped_bytes(fw) {
    let _g = lock();
    let (acq, s, _c) = faulty_run(
        fw,
        Faults {
            drop_rate: 2e-4,
            seed: 3,
            ..Faults::default()
        },
        false,
    );
    let st = s.stats();
    assert!(st.frames_damaged > 0, "the test should drop something");
    eprintln!(
        "drops: complete {}, missing {:?}, problems {:?}",
        acq.complete, acq.missing, acq.problems
    );
}
}

on_both_firmwares! {
fn stall_longer_than_timeout(fw) {
    let _g = lock();
    let (acq, s, c) = faulty_run(
        fw,
        Faults {
            stall: Some(FaultAt {
                at_sample: 300,
                // 200 ms over the stream timeout: 450 ms left 50 ms, which a loaded machine ate
                // (the client then saw no timeout and did not retry).
                duration: Duration::from_millis(600),
            }),
            ..Faults::default()
        },
        false,
    );
    // longer than the stream timeout (400 ms) and the command timeout: the client polls, retries
    assert!(c.stats().retries > 0, "{:?}", c.stats());
    assert!(!acq.complete);
    assert!(!acq.missing.is_empty());
    assert!(acq.missing[0].start >= 250, "{:?}", acq.missing);
    assert!(s.stats().blocks_dropped > 0);
    assert!(acq.end.is_some(), "the summary arrives after the stall");
    eprintln!(
        "stall: missing {:?}, problems {:?}, client {:?}",
        acq.missing,
        acq.problems,
        c.stats()
    );
}
}

on_both_firmwares! {
fn disconnect_and_reconnect(fw) {
    let _g = lock();
    let (acq, s, c) = faulty_run(
        fw,
        Faults {
            disconnect: Some(FaultAt {
                at_sample: 300,
                duration: Duration::from_millis(300),
            }),
            ..Faults::default()
        },
        true,
    );
    assert!(!acq.complete);
    assert!(c.stats().reconnects >= 1, "{:?}", c.stats());
    assert!(acq.index.len() >= 250);
    eprintln!(
        "disconnect: missing {:?}, problems {:?}, client {:?}, events {:?}",
        acq.missing,
        acq.problems,
        c.stats(),
        s.stats().events
    );
}
}

on_both_firmwares! {
fn drive_reset_mid_run(fw) {
    let _g = lock();
    let (acq, s, mut c) = faulty_run(
        fw,
        Faults {
            reset: Some(FaultAt {
                at_sample: 300,
                duration: Duration::from_millis(50),
            }),
            ..Faults::default()
        },
        false,
    );
    assert!(!acq.complete);
    assert!(
        acq.problems.iter().any(|p| p.contains("reset")),
        "{:?}",
        acq.problems
    );
    assert_eq!(acq.missing.last().map(|r| r.end), Some(acq.total_samples));
    assert!(
        acq.index.len() >= 250 && acq.index.len() <= 300,
        "{}",
        acq.index.len()
    );
    // after a reset the drive must be configured again, then it works
    c.hello().unwrap();
    c.configure(&Configure::default()).unwrap();
    let acq2 = c.run_prbs(&short_prbs(), &mut NullSink).unwrap();
    assert!(acq2.complete, "{:?}", acq2.problems);
    check_truth(&acq2, &s);
}
}

on_both_firmwares! {
fn sine_sweep_matches_the_model(fw) {
    let _g = lock();
    let s = vsim(fw, 115_200);
    let mut c = vclient(&s, 115_200);
    let mut sweep = SineSweep::log(5.0, 40.0, 3);
    sweep.min_settle_s = 0.1;
    sweep.cycles = 3;
    let (pts, problems) = c.run_sine_sweep(&sweep).unwrap();
    assert!(problems.is_empty(), "{problems:?}");
    assert_eq!(pts.len(), 3);
    let g = fracsim::FracTf::pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252).unwrap();
    for p in &pts {
        let h = g.freq_response(2.0 * std::f64::consts::PI * p.freq_hz);
        let gain_db = 20.0 * h.norm().log10();
        // the sampled (zero-order hold) loop adds half a sample of delay
        let phase = h.arg().to_degrees() - 360.0 * p.freq_hz * 0.5e-3;
        eprintln!("{p:?} model {gain_db:.2} dB {phase:.1} deg");
        assert!((p.gain_db - gain_db).abs() < 0.5, "{p:?} vs {gain_db}");
        assert!((p.phase_deg - phase).abs() < 1.5, "{p:?} vs {phase}");
    }
}
}

/// A sink that keeps the indices it received and writes the CSV of [`CsvSink`] to memory.
struct TeeSink {
    csv: CsvSink<Vec<u8>>,
    indices: Vec<u64>,
}

impl drive::client::SampleSink for TeeSink {
    fn begin(&mut self, info: &drive::client::RunInfo) -> std::io::Result<()> {
        self.csv.begin(info)
    }
    fn sample(&mut self, index: u64, t: f64, u: f64, y: f64, i: f64) -> std::io::Result<()> {
        self.indices.push(index);
        self.csv.sample(index, t, u, y, i)
    }
    fn finish(&mut self, acq: &Acquisition) -> std::io::Result<()> {
        self.csv.finish(acq)
    }
}

on_both_firmwares! {
/// Issue 46, item 9: with [`Retention::CountOnly`] (what `fracid drive loop` uses, so a long run
/// needs no memory for its samples) the acquisition keeps none of them, and still says what a
/// kept one says: the count, the missing ranges (the complement of the indices the sink
/// received, on a line that drops bytes), the footer, completeness. Bytes are dropped both ways,
/// so the record has gaps.
fn count_only_retention_keeps_no_sample_and_the_same_account(fw) {
    use drive::client::Retention;
    let _g = lock();
    let s = sim(
        fw,
        Faults {
            drop_rate: 3e-4,
            seed: 5,
            ..Faults::default()
        },
        115_200,
        None,
    );
    let mut c = client(s.port_path(), 115_200);
    c.set_retention(Retention::CountOnly);
    let mut sink = TeeSink {
        csv: CsvSink::new(Vec::new()),
        indices: Vec::new(),
    };
    let acq = c
        .run_prbs(
            &PrbsTest {
                periods: 4,
                ..short_prbs()
            },
            &mut sink,
        )
        .unwrap();
    assert!(acq.index.is_empty() && acq.t.is_empty() && acq.y.is_empty() && acq.raw.is_empty());
    let got = &sink.indices;
    assert_eq!(acq.received, got.len() as u64);
    assert_eq!(acq.last_index, got.last().copied());
    // the missing ranges: the complement of what arrived in the run's span
    let span = acq.total_samples.max(acq.planned_samples);
    let mut want = Vec::new();
    let mut next = 0;
    for &i in got {
        if i > next {
            want.push(next..i.min(span));
        }
        next = i + 1;
    }
    if next < span {
        want.push(next..span);
    }
    want.retain(|r| r.start < r.end);
    assert_eq!(acq.missing, want, "{:?}", acq.problems);
    assert!(
        !want.is_empty(),
        "the line should have lost something: {:?}",
        s.stats()
    );
    assert!(!acq.complete);
    let text = String::from_utf8(sink.csv.into_inner().unwrap()).unwrap();
    assert_eq!(text.lines().last().unwrap(), acq.footer());
    assert!(acq.footer().starts_with("# incomplete: missing samples "));
    // the excitation, judged as the samples arrived: a PRBS that varies
    assert!(acq.after_settle.samples > 100 && !acq.excitation_missing());
}
}
