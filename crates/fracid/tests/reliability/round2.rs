//! Issue 31, "never lose data, never exit 0 on nonsense, round 2": one test per numbered item
//! (`item_N_...`), each failing on the behaviour the issue found.

use super::{fracid, stderr, write};
use std::path::Path;
use std::process::Command;

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `a.csv` of the issue: `fracid sim --prbs --dt 1e-3 --t-end 1.5 -o a.csv`.
fn a_csv(dir: &tempfile::TempDir) -> std::path::PathBuf {
    let p = dir.path().join("a.csv");
    let o = fracid(&[
        "sim",
        "--prbs",
        "--dt",
        "1e-3",
        "--t-end",
        "1.5",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    p
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

#[test]
fn item_1_the_fleet_fails_an_unusable_fit_as_the_single_file_run_does() {
    let dir = tempfile::tempdir().unwrap();
    let recs = tempfile::tempdir().unwrap();
    let a = a_csv(&recs);
    let c = constant_output(&recs, &a);
    let single = fracid(&["time", "--quiet", c.to_str().unwrap()]);
    assert_eq!(single.status.code(), Some(1), "{}", stderr(&single));
    assert!(stderr(&single).contains("not usable"));
    let out = dir.path().join("out");
    let o = fracid(&[
        "time",
        "--quiet",
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
            assert!(Path::new(row["report"].as_str().unwrap()).is_file(), "{row}");
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

/// Run the built `fracid` with `args` (output discarded) under an address-space limit of 3 GiB
/// (so a run that still asks for gigabytes fails instead of taking the machine); its exit code
/// and its peak resident memory in MiB (`wait4`'s `ru_maxrss`, Linux, no tool needed).
#[cfg(target_os = "linux")]
fn exit_and_peak_mib(args: &[&str]) -> (Option<i32>, f64) {
    use std::os::unix::process::CommandExt;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_fracid"));
    cmd.args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
    // SAFETY: setrlimit is async-signal-safe; it touches only the child being started.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 3 << 30,
                rlim_max: 3 << 30,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let child = cmd.spawn().unwrap();
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value; wait4 fills it for our own child.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut ru) };
    assert_eq!(r, pid);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    (code, ru.ru_maxrss as f64 / 1024.0)
}

/// The memory bound of the README: no input file under 1 MB makes a command use more than 1 GB.
/// `.mat` files that inflate to gigabytes (one `uint8` variable of 500 million zeros, 0.5 MB;
/// four of 200 million, 0.8 MB; before the fix 4.4 GB and 6.7 GB resident), and the largest
/// record a small `.mat` may hold (a periodic `u`, `y` pair just inside the 16 MiB budget),
/// fitted.
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
        vec!["time", "--quiet", "--dt", "1e-3", "--u-col", "t", "--y-col", "u", four],
        vec!["freq", "--columns", "t,u,y", four],
        vec!["sim", "--input", four, "--dt", "1e-3", "--u-col", "t"],
        vec!["time", "--quiet", "--dt", "1e-3", "--max-iter", "2", fit],
    ];
    for args in &runs {
        let (code, mib) = exit_and_peak_mib(args);
        assert!(matches!(code, Some(0..=3)), "{args:?}: exit {code:?}");
        assert!(mib < 1024.0, "{args:?}: {mib:.0} MiB");
    }
    // the large ones are refused for their decoded size, in words
    let o = fracid(&["time", "--quiet", four]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("decodes to more than 16 MiB"), "{}", stderr(&o));
    // the largest allowed is read whole: n samples, 70% of them for estimation
    let o = fracid(&["time", "--dt", "1e-3", "--max-iter", "1", fit]);
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
    let bode = write(&dir, "b.csv", "freq_hz,gain_db,phase_deg\n1,0,-5\n10,-3,-45\n100,-20,-84\n");
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
        let (code, mib) = exit_and_peak_mib(args);
        assert_eq!(code, Some(2), "{args:?}");
        assert!(mib < 100.0, "{args:?}: {mib:.0} MiB");
        let o = fracid(args);
        assert!(stderr(&o).contains("longer than"), "{args:?}: {}", stderr(&o));
    }
}
