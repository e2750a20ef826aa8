//! Issue 46, "never hang, never leave a drive running unattended, round 3", the drive's items: one
//! test per numbered item (`item_N_...`), each failing on the behaviour the issue found. Item 11
//! (the keepalive of the run's own host) is tested against both firmwares in the drive crate
//! (`e2e_control::an_orphaned_run_is_not_kept_alive_by_another_programs_polls`).

use super::{stderr, write};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A `fracid tune --json` report holding only its discrete realisation (`dt` 1 ms): what
/// `fracid drive loop --controller` reads. A row of `A` a line (as `fracid tune --json` prints it,
/// pretty).
fn controller_json(a: &[Vec<f64>], b: &[f64], c: &[f64], d: f64) -> String {
    let rows = |m: &[Vec<f64>]| {
        let r: Vec<String> = m
            .iter()
            .map(|r| {
                let v: Vec<String> = r.iter().map(|x| format!("{x:?}")).collect();
                format!("[{}]", v.join(","))
            })
            .collect();
        format!("[\n{}\n]", r.join(",\n"))
    };
    let col: Vec<Vec<f64>> = b.iter().map(|x| vec![*x]).collect();
    format!(
        "{{\"controller\":{{\"text\":\"test\"}},\"discrete\":{{\"dt\":0.001,\"a\":{},\"b\":{},\
         \"c\":{},\"d\":[[{d:?}]]}}}}",
        rows(a),
        rows(&col),
        rows(&[c.to_vec()])
    )
}

/// A PI `0.05 + 1/s` (V per rad/s) at 1 ms: one integrator state.
fn pi_json() -> String {
    controller_json(&[vec![1.0]], &[1e-3], &[1.0], 0.05)
}

/// Run `fracid ARGS` (stdin closed), killing it after `limit`: its exit code (`None`: killed,
/// or ended by a signal), stderr and the time it took.
fn run_within(args: &[&str], limit: Duration) -> (Option<i32>, String, Duration) {
    let t0 = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_fracid"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    (status.and_then(|s| s.code()), err, t0.elapsed())
}

/// `fracid drive loop --controller CONTROLLER --step 10 --duration 1` on a port that does not
/// exist (reaching it would be exit 3), given 30 s: the exit code, standard error, the time taken.
fn loop_without_port(
    dir: &tempfile::TempDir,
    controller: &Path,
) -> (Option<i32>, String, Duration) {
    run_within(
        &[
            "drive",
            "loop",
            "--port",
            "/nonexistent/tty",
            "--controller",
            controller.to_str().unwrap(),
            "--step",
            "10",
            "--duration",
            "1",
            "-o",
            dir.path().join("r.csv").to_str().unwrap(),
        ],
        Duration::from_secs(30),
    )
}

/// Item 4: a controller of 1,600 states (12.8 MB of JSON in the issue) kept `drive loop` busy
/// 121 s of CPU before the port was even opened. It is refused at once (the drive holds at most
/// 48 sections), exit 2, in words, before the port (which does not exist here: reaching it
/// would be exit 3).
#[test]
fn item_4_an_oversized_controller_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let n = 1600;
    let a: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 0.5 } else { 0.0 }).collect())
        .collect();
    let p = write(
        &dir,
        "big.json",
        &controller_json(&a, &vec![1.0; n], &vec![1.0; n], 0.1),
    );
    let (code, err, took) = loop_without_port(&dir, &p);
    assert_eq!(code, Some(2), "after {took:?}: {err}");
    assert!(took < Duration::from_secs(10), "{took:?}");
    assert!(
        err.contains("1600 states") && err.contains("48 sections"),
        "{err}"
    );
}

/// The link options of a host command on a simulated drive in virtual time (a keepalive every
/// 2 ms: the drive's clock runs at most half the keepalive interval past the host's last one).
fn virtual_link(port: &str) -> Vec<&str> {
    vec![
        "--port",
        port,
        "--baud",
        "921600",
        "--keepalive-ms",
        "2",
        "--quiet",
    ]
}

/// The drive simulator (the paper's PMSM, no faults) on a pseudo-terminal in this process, with
/// the firmware `firmware`, in virtual time or in real time.
#[cfg(unix)]
fn sim(firmware: drive::sim::FirmwareKind, virtual_time: bool) -> drive::sim::DriveSim {
    drive::sim::DriveSim::spawn(drive::sim::SimConfig {
        baud: 921_600,
        firmware,
        clock: if virtual_time {
            drive::sim::SimClock::Virtual
        } else {
            drive::sim::SimClock::RealTime
        },
        ..Default::default()
    })
    .unwrap()
}

#[cfg(unix)]
const FIRMWARES: [drive::sim::FirmwareKind; 2] =
    [drive::sim::FirmwareKind::Rust, drive::sim::FirmwareKind::C];

/// Item 5: a realisation without states (a pure gain, `u = 0.05 (r - y)`: a proportional speed
/// loop) panicked in nalgebra's Schur decomposition (exit 101). It is a controller of no
/// sections, which both firmwares run: the record is complete, its command the gain times the
/// error at every sample.
#[cfg(unix)]
#[test]
fn item_5_a_pure_gain_runs_as_a_proportional_loop() {
    let dir = tempfile::tempdir().unwrap();
    let ctrl = write(&dir, "p.json", &controller_json(&[], &[], &[], 0.05));
    for fw in FIRMWARES {
        let s = sim(fw, true);
        let out = dir.path().join(format!("p_{fw:?}.csv"));
        let mut args = vec!["drive", "loop"];
        args.extend(virtual_link(s.port_path()));
        args.extend([
            "--controller",
            ctrl.to_str().unwrap(),
            "--step",
            "20",
            "--pre",
            "0.05",
            "--duration",
            "0.3",
            "-o",
            out.to_str().unwrap(),
        ]);
        let (code, err, _) = run_within(&args, Duration::from_secs(60));
        assert_eq!(code, Some(0), "{fw:?}: {err}");
        assert!(err.contains("0 fixed-point sections"), "{fw:?}: {err}");
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(
            text.trim_end().ends_with("# complete: 300 samples"),
            "{fw:?}: {text}"
        );
        let rows: Vec<Vec<f64>> = text
            .lines()
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 300);
        // u = 0.05 (r - y) to the millivolt the drive's command has (t, r, u, y)
        for r in &rows {
            assert!(
                (r[2] - 0.05 * (r[1] - r[3])).abs() <= 1.5e-3,
                "{fw:?}: {r:?}"
            );
        }
        assert!(
            rows.last().unwrap()[3] > 5.0,
            "{fw:?}: the speed follows the step"
        );
    }
}

/// Item 6: a realisation with poles at `z = -1` (and a chain at the origin) hung forever in
/// nalgebra's eigenvalue iteration, which has no iteration limit. It ends at once, exit 1 (a
/// numerical failure), saying what did not converge, before the port is opened.
#[test]
fn item_6_poles_at_minus_one_end_with_an_error_not_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    let a = [
        vec![-1.0, 0.0, 0.0, 0.0],
        vec![1.0, 0.0, 0.0, 0.0],
        vec![-1.0, -1.0, 0.0, 0.0],
        vec![0.0, 0.0, -1.0, 0.0],
    ];
    let p = write(
        &dir,
        "m1.json",
        &controller_json(&a, &[-1.0, 0.0, -1.0, 0.0], &[1.0, 0.0, 0.0, -1.0], 1.0),
    );
    let (code, err, took) = loop_without_port(&dir, &p);
    assert_eq!(code, Some(1), "after {took:?}: {err}");
    assert!(took < Duration::from_secs(10), "{took:?}");
    assert!(err.contains("did not converge"), "{err}");
}

/// The peak resident memory (VmHWM, KiB) of a running process, read from /proc.
#[cfg(target_os = "linux")]
fn vm_hwm_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// `fracid drive loop` of the PI for `duration_s` on a fresh simulated drive in virtual time:
/// the record's text and the process's peak resident memory (KiB; VmHWM polled until it ends:
/// `wait4`'s figure would include this test process's, carried across the fork).
#[cfg(target_os = "linux")]
fn loop_record_and_peak(dir: &Path, duration_s: &str) -> (String, u64, String) {
    let s = sim(drive::sim::FirmwareKind::Rust, true);
    let ctrl = write_path(dir, "pi.json", &pi_json());
    let out = dir.join(format!("loop_{duration_s}.csv"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_fracid"))
        .args(["drive", "loop"])
        .args(virtual_link(s.port_path()))
        .args(["--controller", ctrl.to_str().unwrap(), "--step", "20"])
        .args(["--pre", "0.05", "--duration", duration_s, "-o"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut peak = 0;
    let t0 = Instant::now();
    let status = loop {
        if let Some(k) = vm_hwm_kib(child.id()) {
            peak = peak.max(k);
        }
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(300), "still running");
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{err}");
    (std::fs::read_to_string(&out).unwrap(), peak, err)
}

#[cfg(target_os = "linux")]
fn write_path(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Item 9: `drive loop` kept every sample in memory beside the file (about 69 bytes a sample:
/// 76 MB for 1,000 s at 1 kHz). A run of 120 s (120,000 samples: 8 MB more than a run of 5 s
/// before) now peaks within 4 MB of a run of 5 s, and its record is the one the samples make:
/// complete, every row.
#[cfg(target_os = "linux")]
#[test]
fn item_9_a_long_loop_run_is_written_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let (short, peak_short, _) = loop_record_and_peak(dir.path(), "5");
    let (long, peak_long, err) = loop_record_and_peak(dir.path(), "120");
    assert!(short.trim_end().ends_with("# complete: 5000 samples"));
    assert!(
        long.trim_end().ends_with("# complete: 120000 samples"),
        "{}",
        long.lines().last().unwrap()
    );
    assert!(err.contains("overshoot"), "the step's figures: {err}");
    // the long record begins as the short one: the same rows, byte for byte, up to the end of
    // the short one (the header's planned count aside)
    let body = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
            .map(String::from)
            .collect()
    };
    let (b_short, b_long) = (body(&short), body(&long));
    assert_eq!(b_long.len(), 120_000);
    assert_eq!(b_short[..], b_long[..5000]);
    eprintln!("peak resident memory: {peak_short} KiB for 5 s, {peak_long} KiB for 120 s");
    assert!(
        peak_long < peak_short + 4096,
        "{peak_long} KiB for 120 s against {peak_short} KiB for 5 s"
    );
}

/// A child `fracid drive ARGS -o OUT` with every signal this test sends at its default action (a
/// test run as a background job inherits some ignored, which fracid then leaves alone).
#[cfg(unix)]
fn drive_child(args: &[&str], out: &Path) -> std::process::Child {
    use std::os::unix::process::CommandExt;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_fracid"));
    // SAFETY: only signal(2), async-signal-safe, between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            for s in [
                libc::SIGINT,
                libc::SIGQUIT,
                libc::SIGUSR1,
                libc::SIGUSR2,
                libc::SIGALRM,
                libc::SIGVTALRM,
                libc::SIGPROF,
                libc::SIGXCPU,
                libc::SIGXFSZ,
            ] {
                libc::signal(s, libc::SIG_DFL);
            }
            Ok(())
        });
    }
    cmd.arg("drive")
        .args(args)
        .arg("-o")
        .arg(out)
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Data rows (starting with a digit) of a CSV.
fn data_rows(text: &str) -> usize {
    text.lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count()
}

/// The drive's state line (`fracid drive status`).
fn drive_state(port: &str) -> String {
    let o = super::fracid(&["drive", "status", "--port", port, "--baud", "921600"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Signal `sig` to a `fracid drive ARGS` on a fresh simulated drive (real time) once `rows`
/// data rows are in its output: it must end by itself with 128 + sig, saying which signal, with
/// the drive stopped (not Running) and the output finished with its footer (`footer` starts it).
#[cfg(unix)]
fn a_signal_stops_the_run(
    fw: drive::sim::FirmwareKind,
    cmd: &[&str],
    rows: usize,
    sig: libc::c_int,
    name: &str,
    footer: &str,
) {
    let dir = tempfile::tempdir().unwrap();
    let s = sim(fw, false);
    let port = s.port_path().to_string();
    let out = dir.path().join("out.csv");
    let mut args = cmd.to_vec();
    args.extend(["--port", &port, "--baud", "921600", "--quiet"]);
    let mut child = drive_child(&args, &out);
    let t0 = Instant::now();
    while data_rows(&std::fs::read_to_string(&out).unwrap_or_default()) < rows {
        assert!(child.try_wait().unwrap().is_none(), "{cmd:?} ended early");
        assert!(t0.elapsed() < Duration::from_secs(20), "{cmd:?}: no data");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: signalling our own child, not reaped yet.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, sig) }, 0);
    let t1 = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(
            t1.elapsed() < Duration::from_secs(10),
            "{cmd:?}: still running"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(
        status.code(),
        Some(128 + sig),
        "{fw:?} {cmd:?} {name}: {status:?} {err}"
    );
    assert!(err.contains(&format!("interrupted by {name}")), "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let last = text.trim_end().lines().last().unwrap();
    assert!(last.starts_with(footer), "{fw:?} {cmd:?} {name}: {last}");
    // stopped: Idle after the STOP (or, on a machine loaded enough to stall the host for the
    // keepalive interval, ended by the keepalive): never left Running
    let st = drive_state(&port);
    assert!(
        st.contains("state Idle") || st.contains("fault 2,"),
        "{fw:?} {cmd:?} {name}: {st} ({err})"
    );
}

/// Item 10: SIGQUIT (Ctrl-\), SIGUSR1 or SIGALRM during `drive loop`, `drive prbs` or `drive
/// sine` ended the host at once: no STOP (the drive Running until its keepalive tripped), no
/// footer. They are handled as SIGINT, SIGTERM and SIGHUP are: STOP, the footer, exit 128 + the
/// signal; with both firmwares.
#[cfg(unix)]
#[test]
fn item_10_quit_usr1_and_alrm_stop_the_drive_and_finish_the_record() {
    let dir = tempfile::tempdir().unwrap();
    let ctrl = write(&dir, "pi.json", &pi_json());
    let ctrl = ctrl.to_str().unwrap();
    let looping = [
        "loop",
        "--controller",
        ctrl,
        "--step",
        "20",
        "--duration",
        "30",
    ];
    let prbs = ["prbs", "--periods", "30"];
    let sine = [
        "sine",
        "--freqs",
        "20,25,30,35,40,45,50,55,60,65,70,75,80,85,90,95",
        "--min-settle",
        "0.05",
        "--repeats",
        "1",
    ];
    for fw in FIRMWARES {
        a_signal_stops_the_run(fw, &looping, 200, libc::SIGQUIT, "SIGQUIT", "# incomplete");
        a_signal_stops_the_run(fw, &prbs, 200, libc::SIGUSR1, "SIGUSR1", "# incomplete");
        a_signal_stops_the_run(
            fw,
            &sine,
            1,
            libc::SIGALRM,
            "SIGALRM",
            "# incomplete: missing frequencies",
        );
    }
}

/// Item 10, the other signals whose default action ends the process and that can be caught:
/// each stops a PRBS run the same way.
#[cfg(target_os = "linux")]
#[test]
fn item_10_every_catchable_terminating_signal_stops_the_drive() {
    let prbs = ["prbs", "--periods", "30"];
    for (sig, name) in [
        (libc::SIGUSR2, "SIGUSR2"),
        (libc::SIGVTALRM, "SIGVTALRM"),
        (libc::SIGPROF, "SIGPROF"),
        (libc::SIGXCPU, "SIGXCPU"),
        (libc::SIGXFSZ, "SIGXFSZ"),
        (libc::SIGPOLL, "SIGPOLL"),
        (libc::SIGPWR, "SIGPWR"),
        (libc::SIGRTMIN() + 2, "SIGRTMIN+2"),
    ] {
        a_signal_stops_the_run(
            drive::sim::FirmwareKind::Rust,
            &prbs,
            200,
            sig,
            name,
            "# incomplete",
        );
    }
}
