//! Issue 31, "never lose data, never exit 0 on nonsense, round 2": one test per numbered item
//! (`item_N_...`), each failing on the behaviour the issue found.

use super::{fracid, stderr, write};
use crate::stdout;
use std::path::Path;
use std::process::Command;

/// `a.csv` of the issue: `fracid sim --prbs --dt 1e-3 --t-end 1.5 -o a.csv`.
pub(crate) fn a_csv(dir: &tempfile::TempDir) -> std::path::PathBuf {
    super::sim_record(dir.path().join("a.csv"), None)
}

/// A record of `a.csv`'s input with a constant output: single-file `fracid time` fits it and
/// exits 1 (the model is not usable).
fn constant_output(dir: &tempfile::TempDir, a: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(a).unwrap();
    let mut out = String::from("t,u,y\n");
    for l in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        out += &format!("{},{},5\n", f[0], f[1]);
    }
    write(dir, "const.csv", &out)
}

/// With the single fit and with the loop closed (`--diagnose`: a candidate structure fitted the
/// constant output exactly, RMSE 0, and was usable by every other rule, so the loop exited 0;
/// now no model of an output that does not vary is usable, `oe::checks`).
#[test]
fn item_1_the_fleet_fails_an_unusable_fit_as_the_single_file_run_does() {
    for path in ["--plain", "--diagnose"] {
        fleet_fails_an_unusable_fit(path);
    }
}

fn fleet_fails_an_unusable_fit(path: &str) {
    let dir = tempfile::tempdir().unwrap();
    let recs = tempfile::tempdir().unwrap();
    let a = a_csv(&recs);
    let c = constant_output(&recs, &a);
    let single = fracid(&["time", "--quiet", path, c.to_str().unwrap()]);
    assert_eq!(single.status.code(), Some(1), "{path}: {}", stderr(&single));
    assert!(stderr(&single).contains("not usable"), "{path}");
    assert!(
        stderr(&single).contains("the output does not vary"),
        "{path}: {}",
        stderr(&single)
    );
    let out = dir.path().join("out");
    let o = fracid(&[
        "time",
        "--quiet",
        path,
        recs.path().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("const.csv"), "{e}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("time-summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["failed"], 1);
    for row in summary["rows"].as_array().unwrap() {
        let file = row["file"].as_str().unwrap();
        if file.ends_with("const.csv") {
            assert_eq!(row["status"], "failed", "{row}");
            assert_eq!(row["exit_code"], 1, "{row}");
            assert!(
                row["error"].as_str().unwrap().contains("not usable"),
                "{row}"
            );
            // the report is still written, as the single-file run prints it
            assert!(
                Path::new(row["report"].as_str().unwrap()).is_file(),
                "{row}"
            );
        } else {
            assert_eq!(row["status"], "ok", "{row}");
        }
    }
    let csv = std::fs::read_to_string(out.join("time-summary.csv")).unwrap();
    assert!(
        csv.lines()
            .any(|l| l.contains("const.csv") && l.contains(",failed,1,")),
        "{csv}"
    );
}

/// A level 5 `.mat` file of compressed variables: `(name, class, data type, bytes per value,
/// data)` each, zlib-compressed as MATLAB's `-v7` writes them.
fn mat_file(vars: &[(&str, u32, u32, usize, Vec<u8>)]) -> Vec<u8> {
    let mut f = vec![b' '; 116];
    f[..19].copy_from_slice(b"MATLAB 5.0 MAT-file");
    f.extend([0u8; 8]);
    f.extend([0x00, 0x01, b'I', b'M']);
    let pad = |v: &mut Vec<u8>| v.resize(v.len().div_ceil(8) * 8, 0);
    for (name, class, ty, width, data) in vars {
        let mut m = Vec::new();
        m.extend(6u32.to_le_bytes());
        m.extend(8u32.to_le_bytes());
        m.extend(class.to_le_bytes());
        m.extend(0u32.to_le_bytes());
        m.extend(5u32.to_le_bytes());
        m.extend(8u32.to_le_bytes());
        m.extend(((data.len() / width) as i32).to_le_bytes());
        m.extend(1i32.to_le_bytes());
        m.extend(1u32.to_le_bytes());
        m.extend((name.len() as u32).to_le_bytes());
        m.extend(name.as_bytes());
        pad(&mut m);
        m.extend(ty.to_le_bytes());
        m.extend((data.len() as u32).to_le_bytes());
        m.extend(data);
        pad(&mut m);
        let mut el = 14u32.to_le_bytes().to_vec();
        el.extend((m.len() as u32).to_le_bytes());
        el.extend(m);
        let z = miniz_oxide::deflate::compress_to_vec_zlib(&el, 9);
        f.extend(15u32.to_le_bytes());
        f.extend((z.len() as u32).to_le_bytes());
        f.extend(z);
    }
    f
}

/// Run the built `fracid` with `args` (output discarded) with its address space limited to
/// 1 GiB (`RLIMIT_AS`, set in the child: no tool needed): memory beyond that cannot be had, so a
/// run that asks for more fails its allocation and aborts (exit 134, or a signal). The exit code,
/// `None` for a signal. (Peak RSS from `wait4` would not do: Linux carries the parent's
/// high-water mark across the fork and exec, the test process's own memory.) An address-space
/// bound is stricter than one on resident memory: stacks and allocator arenas count too.
#[cfg(target_os = "linux")]
fn exit_within_1_gib(args: &[&str]) -> Option<i32> {
    use std::os::unix::process::CommandExt;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_fracid"));
    cmd.args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
    // SAFETY: setrlimit is async-signal-safe; it limits only the child being started.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 1 << 30,
                rlim_max: 1 << 30,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.status().unwrap().code()
}

/// The memory bound of docs/reliability.md: no input file under 1 MB makes a command use more than 1 GB.
/// `.mat` files that inflate to gigabytes (one `uint8` variable of 500 million zeros, 0.5 MB;
/// four of 200 million, 0.8 MB; before the fix 4.4 GB and 6.7 GB resident, and under a 1 GiB
/// limit an abort, exit 134), and the largest record a small `.mat` may hold (a periodic `u`,
/// `y` pair just inside the 16 MiB budget, about a million samples), fitted.
#[cfg(target_os = "linux")]
#[test]
fn item_2_no_small_mat_file_takes_more_than_1_gb() {
    let dir = tempfile::tempdir().unwrap();
    let big = mat_file(&[("t", 9, 2, 1, vec![0u8; 500_000_000])]);
    let four: Vec<(&str, u32, u32, usize, Vec<u8>)> = ["t", "u", "y", "x"]
        .iter()
        .map(|n| (*n, 9, 2, 1, vec![0u8; 200_000_000]))
        .collect();
    let four = mat_file(&four);
    // u: a PRBS-like +-1 pattern of period 381, y a smoothed copy: periodic, so they compress
    let per: Vec<f64> = (0..381)
        .map(|k| if (k / 3 * 37 + 11) % 7 < 3 { 1.0 } else { -1.0 })
        .collect();
    let n = (ident::matfile::MIN_DECODED_BUDGET / 16 - 1000) / 381 * 381;
    let mut yv = 0.0;
    let mut ys = vec![0.0; 381];
    for k in 0..3 * 381 {
        yv = 0.9 * yv + 0.2 * per[k % 381];
        ys[k % 381] = yv;
    }
    let bytes = |v: &[f64]| -> Vec<u8> {
        (0..n)
            .flat_map(|k| v[k % 381].to_le_bytes())
            .collect::<Vec<u8>>()
    };
    let fit = mat_file(&[("u", 6, 9, 8, bytes(&per)), ("y", 6, 9, 8, bytes(&ys))]);
    let mut paths = vec![];
    for (name, f) in [("big.mat", &big), ("four.mat", &four), ("fit.mat", &fit)] {
        assert!(f.len() < 1_000_000, "{name}: {} bytes", f.len());
        paths.push(dir.path().join(name).to_str().unwrap().to_string());
        std::fs::write(paths.last().unwrap(), f).unwrap();
    }
    let (big, four, fit) = (&paths[0], &paths[1], &paths[2]);
    let runs: Vec<Vec<&str>> = vec![
        vec!["time", "--quiet", big],
        vec!["time", "--quiet", four],
        vec![
            "time", "--quiet", "--dt", "1e-3", "--u-col", "t", "--y-col", "u", four,
        ],
        vec!["freq", "--columns", "t,u,y", four],
        vec!["sim", "--input", four, "--dt", "1e-3", "--u-col", "t"],
        vec![
            "time",
            "--quiet",
            "--plain",
            "--dt",
            "1e-3",
            "--max-iter",
            "2",
            fit,
        ],
        // the default, the loop closed: every candidate structure and its diagnosis within the
        // same bound
        vec!["time", "--quiet", "--dt", "1e-3", "--max-iter", "2", fit],
    ];
    for args in &runs {
        let code = exit_within_1_gib(args);
        assert!(matches!(code, Some(0..=3)), "{args:?}: exit {code:?}");
    }
    // the large ones are refused for their decoded size, in words
    let o = fracid(&["time", "--quiet", four]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("decodes to more than 16 MiB"),
        "{}",
        stderr(&o)
    );
    // the largest allowed is read whole: n samples, 70% of them for estimation
    let o = fracid(&["time", "--plain", "--dt", "1e-3", "--max-iter", "1", fit]);
    assert!(
        stdout(&o).contains(&format!("{} estimation", n * 7 / 10)),
        "{}",
        stdout(&o)
    );
}

/// Every file goes through the bounded reader: `/dev/zero` as a model file or a JSON report, a
/// 400 MB weights file of zeros, are refused after one line's limit (1 MiB), not read until
/// memory runs out (before: read whole, gigabytes for `/dev/zero`).
#[cfg(target_os = "linux")]
#[test]
fn item_3_every_file_is_read_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let a = a_csv(&dir);
    let a = a.to_str().unwrap();
    let bode = write(
        &dir,
        "b.csv",
        "freq_hz,gain_db,phase_deg\n1,0,-5\n10,-3,-45\n100,-20,-84\n",
    );
    let bode = bode.to_str().unwrap();
    // score and export take a JSON path; name /dev/zero through a symlink ending in .json
    let zero_json = dir.path().join("zero.json");
    std::os::unix::fs::symlink("/dev/zero", &zero_json).unwrap();
    let zj = zero_json.to_str().unwrap();
    // --weights takes a regular file: 400 MB of zeros, sparse (no disk used), one "line"
    let sparse = dir.path().join("w.txt");
    std::fs::File::create(&sparse)
        .unwrap()
        .set_len(400 << 20)
        .unwrap();
    let sparse = sparse.to_str().unwrap();
    let runs: Vec<Vec<&str>> = vec![
        vec!["compare", "/dev/zero", "1/(s+1)"],
        vec!["score", zj, a],
        vec!["export", zj],
        vec!["freq", "--weights", sparse, bode],
    ];
    for args in &runs {
        assert_eq!(exit_within_1_gib(args), Some(2), "{args:?}");
        // a stream is refused at its first NUL byte (issue 46 item 8), the sparse regular file
        // for its line's length
        let o = fracid(args);
        assert!(
            stderr(&o).contains("longer than") || stderr(&o).contains("NUL byte at line 1"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
}

/// The drive simulator (the paper's PMSM, no faults) on a pseudo-terminal, at 921600 baud so the
/// runs are short.
#[cfg(unix)]
fn drive_sim() -> drive::sim::DriveSim {
    drive::sim::DriveSim::spawn(drive::sim::SimConfig {
        baud: 921_600,
        ..Default::default()
    })
    .unwrap()
}

/// `fracid drive status`: the drive's state line.
#[cfg(unix)]
fn drive_state(port: &str) -> String {
    let o = fracid(&["drive", "status", "--port", port, "--baud", "921600"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    stdout(&o)
}

#[cfg(unix)]
#[test]
fn item_4_a_link_never_replaces_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "p.csv", "t,u,y\n0,1,2\n");
    let o = fracid(&[
        "drive",
        "sim",
        "--link",
        p.to_str().unwrap(),
        "--duration",
        "0.2",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("a file exists there"), "{}", stderr(&o));
    assert!(!p.symlink_metadata().unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&p).unwrap(), "t,u,y\n0,1,2\n");
    // a link from an earlier run is replaced, as before
    let l = dir.path().join("port");
    std::os::unix::fs::symlink("/nonexistent", &l).unwrap();
    let o = fracid(&[
        "drive",
        "sim",
        "--link",
        l.to_str().unwrap(),
        "--duration",
        "0.2",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[cfg(unix)]
#[test]
fn item_5_and_6_outputs_are_distinct_files_and_never_the_port() {
    let dir = tempfile::tempdir().unwrap();
    let sim = drive_sim();
    let port = sim.port_path().to_string();
    let x = dir.path().join("x.csv");
    let x = x.to_str().unwrap();
    let base = ["--port", &port, "--baud", "921600", "--quiet"];
    // item 5: one file for the table and its repeats
    let mut args = vec!["drive", "sine"];
    args.extend(base);
    args.extend([
        "--freqs",
        "20",
        "--repeats",
        "3",
        "--repeats-out",
        x,
        "-o",
        x,
    ]);
    let o = fracid(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("are one file"), "{}", stderr(&o));
    assert!(!Path::new(x).exists());
    // the same file by another name (./x.csv from the folder) is one file too
    let o = Command::new(env!("CARGO_BIN_EXE_fracid"))
        .current_dir(dir.path())
        .args(["drive", "sine"])
        .args(base)
        .args([
            "--freqs",
            "20",
            "--repeats",
            "3",
            "--repeats-out",
            "./x.csv",
            "-o",
            x,
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // item 6: the output is the port, by its name or by the pty's
    let pty = std::fs::canonicalize(&port).unwrap();
    for out in [port.as_str(), pty.to_str().unwrap()] {
        let mut args = vec!["drive", "prbs"];
        args.extend(base);
        args.extend(["-o", out]);
        let o = fracid(&args);
        assert_eq!(o.status.code(), Some(2), "{out}: {}", stderr(&o));
        assert!(stderr(&o).contains("is the serial port"), "{}", stderr(&o));
    }
    // ... and no run was started
    assert!(
        drive_state(&port).contains("run 0 "),
        "{}",
        drive_state(&port)
    );
}

#[cfg(unix)]
#[test]
fn item_7_sweep_frequencies_are_sorted_deduplicated_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let sim = drive_sim();
    let port = sim.port_path().to_string();
    let out = dir.path().join("s.csv");
    let out = out.to_str().unwrap();
    let base = [
        "--port",
        &port,
        "--baud",
        "921600",
        "--quiet",
        "--repeats",
        "1",
    ];
    let mut args = vec!["drive", "sine"];
    args.extend(base);
    args.extend(["--f-min", "100", "--f-max", "10", "-o", out]);
    let o = fracid(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("must be below --f-max"),
        "{}",
        stderr(&o)
    );
    let mut args = vec!["drive", "sine"];
    args.extend(base);
    args.extend(["--freqs", "20,10,10,40", "-o", out]);
    let o = fracid(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("sorted into increasing order"),
        "{}",
        stderr(&o)
    );
    let text = std::fs::read_to_string(out).unwrap();
    let f: Vec<f64> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(f.len(), 3, "{text}");
    assert!(f.windows(2).all(|w| w[0] < w[1]), "{text}");
    // the table is one `fracid freq` reads
    let o = fracid(&["freq", "--n", "1", "--q", "1", out]);
    assert!(!stderr(&o).contains("increas"), "{}", stderr(&o));
    assert_ne!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// Item 8: stdout closed under an acquisition (`drive prbs -o - | head -1`): before, SIGPIPE
/// ended the process (exit 141) with the drive left Running; now the drive is stopped, the loss
/// is said, exit 3.
#[cfg(unix)]
#[test]
fn item_8_a_closed_output_pipe_stops_the_drive_and_exits_3() {
    use std::io::BufRead;
    let sim = drive_sim();
    let port = sim.port_path().to_string();
    for cmd in [
        &["prbs", "--periods", "3"][..],
        &["sine", "--freqs", "5,10", "--repeats", "1"],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_fracid"))
            .arg("drive")
            .args(cmd)
            .args(["--port", &port, "--baud", "921600", "--quiet", "-o", "-"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        assert!(first.starts_with("# fracid drive"), "{first}");
        // the reader goes away, as `head -1` does
        let o = child.wait_with_output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "{cmd:?}: {:?} {e}", o.status);
        assert!(e.contains("was closed during the run"), "{e}");
        assert!(e.contains("drive was stopped"), "{e}");
        let st = drive_state(&port);
        assert!(st.contains("state Idle"), "{cmd:?}: {st}");
    }
    // `-o -` is standard output, not a file named "-"
    assert!(!Path::new("-").exists());
}

#[cfg(unix)]
#[test]
fn item_16_nonsense_models_are_refused_at_the_start() {
    let dir = tempfile::tempdir().unwrap();
    let a = a_csv(&dir);
    let o = fracid(&["score", "1e300/(s+1)", a.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("out of the range"), "{}", stderr(&o));
    let o = fracid(&["score", "1e300/(s+1)", a.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // the drive simulator of an improper model: refused before it starts (it ran before, every
    // acquisition then failing with "BadValue")
    let t = std::time::Instant::now();
    let o = fracid(&["drive", "sim", "--model", "s", "--duration", "5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("improper"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "no port printed: {}", stdout(&o));
    assert!(t.elapsed().as_secs_f64() < 4.0);
}

/// Item 10: a Bode table of random noise (gains uniform in +-20 dB, phases in +-180 degrees, 20
/// log-spaced points; Python's `random.seed(12)`, rounded) is refused with or without the refit.
/// Before, `--refine` accepted it (exit 0, `usable: true`) with both orders run to 0 and no
/// standard errors.
const NOISE_TABLE: &str = "freq_hz,gain_db,phase_deg
1,-1.0172,56.690
1.43845,6.6564,-128.664
2.06914,-19.5656,-45.088
2.97635,-9.0381,111.725
4.28133,7.6237,36.525
6.15848,2.3276,58.076
8.85867,-14.1879,-21.580
12.7427,-13.5093,146.150
18.3298,-17.6470,114.775
26.3665,-17.0156,67.300
37.9269,-6.5200,-34.339
54.5559,13.6961,-173.302
78.476,-17.5686,149.412
112.884,0.3570,-147.248
162.378,19.4854,160.817
233.572,-15.4989,-27.646
335.982,-14.5972,-67.485
483.293,4.8581,-121.131
695.193,7.8734,-161.513
1000,-13.1514,113.651
";

#[test]
fn item_10_refine_applies_the_same_usability_rule() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "noise.csv", NOISE_TABLE);
    let p = p.to_str().unwrap();
    let o = fracid(&["freq", p]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let o = fracid(&["freq", "--refine", "--json", p]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["usable"], false, "{v}");
    assert!(
        v["problems"]
            .to_string()
            .contains("standard errors cannot be computed"),
        "{}",
        v["problems"]
    );
    // kept on request, with the problem as a warning
    let o = fracid(&["freq", "--refine", "--allow-unusable", p]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("not usable"), "{}", stderr(&o));
}

#[test]
fn item_12_every_output_is_checked_before_any_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let ex = write(&dir, "ex.csv", "precious\n");
    let ex_s = ex.to_str().unwrap();
    let o = fracid(&["sim", "-o", ex_s, "--plot", "x.txt"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = fracid(&["sim", "-o", ex_s, "--plot", "/nonexistent/x.png"]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&ex).unwrap(), "precious\n");
    // both good: both written
    let png = dir.path().join("x.png");
    let o = fracid(&["sim", "-o", ex_s, "--plot", png.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(png.is_file() && std::fs::read_to_string(&ex).unwrap().contains("t,u,y"));
}

#[cfg(target_os = "linux")]
#[test]
fn item_13_a_full_stdout_in_fleet_mode_exits_3_with_the_summary_written() {
    let dir = tempfile::tempdir().unwrap();
    let a = a_csv(&dir);
    let b = dir.path().join("b.csv");
    std::fs::copy(&a, &b).unwrap();
    let out = dir.path().join("D");
    for json in [false, true] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_fracid"));
        cmd.args(["time", "--quiet"])
            .arg(&a)
            .arg(&b)
            .arg("--out")
            .arg(&out);
        if json {
            cmd.arg("--json");
        }
        let o = cmd.stdout(full).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "{e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(e.contains("cannot write to standard output"), "{e}");
        assert!(out.join("time-summary.csv").is_file());
        assert!(out.join("time-summary.json").is_file());
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn item_14_the_fleet_never_reads_nor_overwrites_what_is_not_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path().join("R");
    std::fs::create_dir(&r).unwrap();
    let a = a_csv(&dir);
    std::fs::copy(&a, r.join("a.csv")).unwrap();
    let r_s = r.to_str().unwrap();
    // twice into itself: the second run does not fit its own summary
    for _ in 0..2 {
        let o = fracid(&["time", "--quiet", r_s, "--out", r_s]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(r.join("time-summary.json")).unwrap())
                .unwrap();
        assert_eq!(s["files"], 1, "{s}");
    }
    // a record that happens to be named time-summary.csv in the output folder is not overwritten
    let d = dir.path().join("D");
    std::fs::create_dir(&d).unwrap();
    let rec = d.join("time-summary.csv");
    std::fs::copy(&a, &rec).unwrap();
    let before = std::fs::read(&rec).unwrap();
    let o = fracid(&[
        "time",
        "--quiet",
        d.to_str().unwrap(),
        "--out",
        d.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("not a fracid summary"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&rec).unwrap(), before);
}

/// Item 11: a record cut while being written (no footer, the last line `0.600000,5,3,-` with
/// no line end): before, its last row was read as a sample (y = 3); now it is dropped with a
/// warning and the complete lines are fitted. Fewer fields on the torn line: the file was
/// refused whole, now read the same way. A last line that is complete but unterminated in a
/// file that is not an acquisition is data, as before.
#[test]
fn item_11_a_torn_last_line_is_dropped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let head =
        "# fracid drive acquisition: PRBS\n# run_id 1, 600 samples planned at 1000 Hz\nt,u,y,i\n";
    let rows: String = super::record_rows(0..600)
        .lines()
        .map(|l| format!("{l},0.5\n"))
        .collect();
    for (name, tail) in [("a.csv", "0.600000,5,3,-"), ("b.csv", "0.600000,5")] {
        let p = write(&dir, name, &format!("{head}{rows}{tail}"));
        let o = fracid(&["time", "--quiet", "--max-iter", "3", p.to_str().unwrap()]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(0), "{tail}: {e}");
        assert!(e.contains("dropped as torn"), "{e}");
        assert!(e.contains("rows 0..600 of 600"), "{e}");
        assert!(
            stdout(&o).contains("420 estimation + 180 validation"),
            "{}",
            stdout(&o)
        );
    }
    // not an acquisition, a complete last line without a line end: kept
    let text: String = super::record_rows(0..600);
    let p = write(&dir, "c.csv", &format!("t,u,y\n{}", text.trim_end()));
    let o = fracid(&["time", "--quiet", "--max-iter", "3", p.to_str().unwrap()]);
    assert!(!stderr(&o).contains("torn"), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("420 estimation + 180 validation"),
        "{}",
        stdout(&o)
    );
}

/// Item 15: one approximation-order range (1..=64, `fracsim::approx::ORDER_RANGE`) for the CLI
/// and Python, checked where `--order` is parsed. Before, `--order 0` simulated 1.2% off and
/// `--order 1000` ran for minutes.
#[test]
fn item_15_the_order_range_is_one_and_checked_at_parse() {
    let dir = tempfile::tempdir().unwrap();
    let a = a_csv(&dir);
    let a = a.to_str().unwrap();
    assert_eq!(fracsim::approx::ORDER_RANGE, 1..=64);
    for n in ["0", "65", "1000", "x"] {
        for args in [
            vec!["sim", "--order", n],
            vec!["time", "--quiet", "--order", n, a],
            vec!["export", "1/(s^0.5+1)", "--order", n],
        ] {
            let t = std::time::Instant::now();
            let o = fracid(&args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            assert!(stderr(&o).contains("--order"), "{args:?}: {}", stderr(&o));
            assert!(t.elapsed().as_secs_f64() < 5.0, "{args:?}");
        }
    }
    let o = fracid(&["sim", "--order", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = fracid(&["sim", "--order", "64", "--t-end", "0.1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// The minor ones: `--fix K --free K`, a negative `# hold:` period, a weights file that is a
/// table (the data file itself), `drive prbs --periods 0` (in item 8's drive tests: refused
/// before the drive is asked).
#[test]
fn minor_contradictions_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let a = a_csv(&dir);
    let o = fracid(&[
        "time",
        "--quiet",
        "--fix",
        "K",
        "--free",
        "K",
        a.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("both held"), "{}", stderr(&o));
    let table = "# hold: zero-order, sample period -0.001 s\nfreq_hz,gain_db,phase_deg\n\
                 1,0,-5\n10,-3,-45\n100,-20,-84\n";
    let p = write(&dir, "h.csv", table);
    let o = fracid(&["freq", "--n", "1", "--q", "1", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("positive number of seconds"),
        "{}",
        stderr(&o)
    );
    let p = write(&dir, "b.csv", &table.replace("-0.001", "0.0001"));
    let p = p.to_str().unwrap();
    let o = fracid(&["freq", "--n", "1", "--q", "1", "--weights", p, p]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("one number per line"), "{}", stderr(&o));
}

#[cfg(unix)]
#[test]
fn minor_prbs_periods_0_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let sim = drive_sim();
    let port = sim.port_path().to_string();
    let out = dir.path().join("p.csv");
    let o = fracid(&[
        "drive",
        "prbs",
        "--port",
        &port,
        "--baud",
        "921600",
        "--quiet",
        "--periods",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!out.exists());
}
