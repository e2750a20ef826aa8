//! The record under faults that end a run for the host: the port vanishing for good mid-run or
//! mid-sweep, a START refused, a command clamped away. Over a real pseudo-terminal; serialised
//! with the other end-to-end tests.

use crate::e2e::{lock, short_prbs, sim};
use drive::client::{Client, ClientConfig, CsvSink, LazyFile, NullSink, PrbsTest, SineSweep};
use drive::protocol::Configure;
use drive::sim::{DriveSim, Effects, Faults, FirmwareKind, SimConfig};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const BAUD: u32 = 921_600;

/// A client that gives a vanished port 0.5 s to come back.
fn client(path: &str) -> Client {
    let mut c = Client::open(
        path,
        ClientConfig {
            baud: BAUD,
            reconnect_timeout: Duration::from_millis(500),
            ..ClientConfig::default()
        },
    )
    .expect("client opens");
    c.configure(&Configure::default()).expect("configure");
    c
}

/// The simulator, stoppable from a callback (stopping it closes the pty for good).
fn shared(s: DriveSim) -> Arc<Mutex<Option<DriveSim>>> {
    Arc::new(Mutex::new(Some(s)))
}

fn kill(s: &Arc<Mutex<Option<DriveSim>>>) {
    if let Some(s) = s.lock().unwrap_or_else(|e| e.into_inner()).take() {
        s.stop();
    }
}

fn data_rows(text: &str) -> usize {
    text.lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count()
}

#[test]
fn a_port_lost_mid_run_still_finishes_the_record() {
    let _g = lock();
    let s = sim(FirmwareKind::Rust, Faults::default(), BAUD, None);
    let mut c = client(s.port_path());
    let s = shared(s);
    let s2 = s.clone();
    // The simulator goes away (as if killed, or unplugged for longer than the reconnect window)
    // once about 300 samples have arrived.
    c.set_progress(move |p| {
        if p.done >= 300 {
            kill(&s2);
        }
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lost.csv");
    let mut sink = CsvSink::new(LazyFile::new(&path).unwrap());
    let test = PrbsTest {
        periods: 20,
        ..short_prbs()
    };
    let t0 = Instant::now();
    let acq = c
        .run_prbs(&test, &mut sink)
        .expect("the acquisition survives the port");
    let took = t0.elapsed();
    sink.into_inner().unwrap();
    kill(&s);
    assert!(acq.port_lost, "{acq:?}");
    assert!(!acq.complete);
    assert!(
        acq.problems.iter().any(|p| p.contains("lost the port")),
        "{:?}",
        acq.problems
    );
    // 20 periods of 254 samples + 100 would take 5.2 s; the loss ends it well before.
    assert!(took < Duration::from_secs(4), "took {took:?}");
    let text = std::fs::read_to_string(&path).unwrap();
    let rows = data_rows(&text);
    assert!(rows >= 300, "{rows} rows");
    assert_eq!(rows, acq.index.len());
    // every sample kept is contiguous from 0 here (no line faults), so the footer's first
    // missing sample is the number of rows, and the range ends at the planned length
    let footer = text.trim_end().lines().last().unwrap();
    let expected = format!(
        "# incomplete: missing samples {rows}..{} (",
        acq.planned_samples
    );
    assert!(footer.starts_with(&expected), "{footer}");
    assert!(footer.contains("lost the port"), "{footer}");
    assert_eq!(acq.planned_samples, 100 + 20 * 254);
}

#[test]
fn a_path_that_leads_to_another_drive_after_a_reconnect_ends_the_run_as_a_lost_port() {
    let _g = lock();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("drive-tty");
    let a = sim(
        FirmwareKind::Rust,
        Faults::default(),
        BAUD,
        Some(link.clone()),
    );
    let other = sim(FirmwareKind::Rust, Faults::default(), BAUD, None);
    let mut c = client(a.port_path());
    let a = shared(a);
    let (a2, other_port) = (a.clone(), other.port_path().to_string());
    // The drive goes away and its path comes back leading to another drive (a freed device name
    // taken by the next adapter plugged in).
    c.set_progress(move |p| {
        if p.done >= 300 && a2.lock().unwrap().is_some() {
            kill(&a2);
            let _ = std::fs::remove_file(&link);
            std::os::unix::fs::symlink(&other_port, &link).unwrap();
        }
    });
    let acq = c
        .run_prbs(&short_prbs(), &mut NullSink)
        .expect("the acquisition survives the port");
    kill(&a);
    assert!(acq.port_lost, "{acq:?}");
    assert!(
        acq.problems
            .iter()
            .any(|p| p.contains("lost the port") && p.contains("boot id")),
        "{:?}",
        acq.problems
    );
    assert!(acq.index.len() >= 300 && !acq.complete, "{acq:?}");
    assert_eq!(other.stats().runs_started, 0);
}

#[test]
fn a_sweep_stops_at_once_when_the_port_vanishes_and_keeps_its_points() {
    let _g = lock();
    let s = sim(FirmwareKind::Rust, Faults::default(), BAUD, None);
    let mut c = client(s.port_path());
    let s = shared(s);
    let mut sweep = SineSweep::log(20.0, 100.0, 9);
    sweep.min_settle_s = 0.05;
    sweep.cycles = 2;
    let mut seen = Vec::new();
    let mut lost_at = None;
    let r = c.run_sine_sweep_with(&sweep, &mut |ev| {
        let drive::client::SweepEvent::Point(p) = ev else {
            return Ok(());
        };
        seen.push(*p);
        if seen.len() == 2 {
            kill(&s);
            lost_at = Some(Instant::now());
        }
        Ok(())
    });
    let (points, problems) = r.expect("a lost port ends the sweep, not the measurements");
    let after_loss = lost_at.expect("two points measured").elapsed();
    assert_eq!(points, seen, "every point is handed over as measured");
    assert_eq!(points.len(), 2, "{problems:?}");
    let last = problems.last().unwrap();
    assert!(last.contains("sweep stopped"), "{problems:?}");
    // One reconnect window (0.5 s) and a STATUS, not 3 attempts at each of 7 frequencies (>= 10 s).
    assert!(after_loss < Duration::from_secs(3), "{after_loss:?}");
}

#[test]
fn a_refused_start_leaves_an_existing_record_untouched() {
    let _g = lock();
    let s = sim(FirmwareKind::Rust, Faults::default(), BAUD, None);
    let mut c = client(s.port_path());
    // An emergency stop is latched until the next CONFIGURE: the drive refuses the START.
    c.estop().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("keep.csv");
    std::fs::write(&path, "a recording worth keeping\n").unwrap();
    let mut sink = CsvSink::new(LazyFile::new(&path).unwrap());
    let r = c.run_prbs(&short_prbs(), &mut sink);
    assert!(matches!(r, Err(drive::Error::Nak { .. })), "{r:?}");
    assert!(!sink.into_inner().unwrap().is_created());
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "a recording worth keeping\n"
    );
    drop(s);
}

#[test]
fn a_command_clamped_away_is_flagged_in_the_record() {
    let _g = lock();
    // virtual time: nothing here depends on the wall clock
    let s = crate::e2e::vsim(FirmwareKind::Rust, BAUD);
    let mut c = crate::e2e::vclient(&s, BAUD);
    let dir = tempfile::tempdir().unwrap();
    // 30 V +- 1 V against the default 24 V clamp: every sample at 24 V.
    let path = dir.path().join("clamped.csv");
    let mut sink = CsvSink::new(std::fs::File::create(&path).unwrap());
    let test = PrbsTest {
        offset_v: 30.0,
        ..short_prbs()
    };
    let acq = c.run_prbs(&test, &mut sink).unwrap();
    sink.into_inner().unwrap();
    assert!(acq.complete, "{acq:?}");
    assert!(acq.clamped_blocks > 0);
    assert!(acq.u.iter().all(|&u| (u - 24.0).abs() < 1e-9));
    assert!(acq.excitation_missing());
    let text = std::fs::read_to_string(&path).unwrap();
    let tail: Vec<&str> = text.trim_end().lines().rev().take(3).collect();
    assert!(tail[0].starts_with("# complete: "), "{tail:?}");
    assert!(
        tail[1].starts_with("# no excitation: u is 24 V"),
        "{tail:?}"
    );
    assert!(tail[2].starts_with("# clamped: "), "{tail:?}");

    // 23.5 V +- 1 V: the high level is clamped to 24 V, the excitation (22.5 V / 24 V) is
    // still there: a warning, not a dead record.
    let path = dir.path().join("half.csv");
    let mut sink = CsvSink::new(std::fs::File::create(&path).unwrap());
    let test = PrbsTest {
        offset_v: 23.5,
        ..short_prbs()
    };
    let acq = c.run_prbs(&test, &mut sink).unwrap();
    sink.into_inner().unwrap();
    assert!(acq.clamped_blocks > 0);
    assert!(!acq.excitation_missing());
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\n# clamped: "));
    assert!(!text.contains("no excitation"));

    // An unclamped run: no warnings.
    let acq = c
        .run_prbs(&short_prbs(), &mut drive::client::NullSink)
        .unwrap();
    assert_eq!(acq.clamped_blocks, 0);
    assert!(acq.warnings().is_empty(), "{:?}", acq.warnings());
    drop(s);
}

#[test]
fn out_of_range_simulator_options_are_refused() {
    let spawn = |effects: Effects, faults: Faults| {
        DriveSim::spawn(SimConfig {
            effects,
            faults,
            ..SimConfig::default()
        })
    };
    for fx in [
        Effects {
            delay_s: 1e9,
            ..Effects::default()
        },
        Effects {
            delay_s: -1.0,
            ..Effects::default()
        },
        Effects {
            noise_std: f64::NAN,
            ..Effects::default()
        },
        Effects {
            coulomb_v: f64::INFINITY,
            ..Effects::default()
        },
        Effects {
            ripple_hz: -50.0,
            ..Effects::default()
        },
    ] {
        let r = spawn(fx, Faults::default());
        assert!(
            matches!(r, Err(drive::Error::InvalidParam(_))),
            "{fx:?}: {r:?}"
        );
    }
    let r = spawn(
        Effects::default(),
        Faults {
            drop_rate: f64::NAN,
            ..Faults::default()
        },
    );
    assert!(matches!(r, Err(drive::Error::InvalidParam(_))), "{r:?}");
    // the largest delay accepted still starts
    let ok = spawn(
        Effects {
            delay_s: drive::sim::MAX_DELAY_S,
            ..Effects::default()
        },
        Faults::default(),
    );
    assert!(ok.is_ok(), "{ok:?}");
}
