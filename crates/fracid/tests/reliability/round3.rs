//! Issue 46, "never lose data, never hang, round 3": one test per numbered item of the reader and
//! output side (`item_N_...`), each failing on the behaviour the issue found: an output written
//! over an input (1-3, and every other command that reads and writes files), unbounded sizes (7),
//! a binary stream buffered whole (8), a row with a field too many read shifted (12), fleet
//! entries that are not files skipped without a word (16).

use super::{fracid, stderr, write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `fracid` under test.
fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_fracid"))
}

/// `fracid args` with its address space limited to `kib` KiB (`ulimit -v`): what it takes
/// beyond that is an abort, not a machine out of memory.
#[cfg(unix)]
fn run_within(kib: u64, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib}; exec \"$0\" \"$@\""))
        .arg(bin())
        .args(args)
        .output()
        .unwrap()
}

/// A measured record as `fracid sim` writes it (`t,u,y`, a comment): a PRBS through a plant
/// that is not sim's default, so a simulation written over it changes it.
fn record(dir: &Path, name: &str) -> PathBuf {
    super::sim_record(dir.join(name), Some("3/(0.02 s^0.8 + 1)"))
}

/// `args` (with `{IN}` and `{OUT}` replaced) refused with exit 2 and words naming both files,
/// and the input byte for byte what it was.
fn refused(args: &[&str], input: &Path, out: &Path, out_name: &str) {
    let before = std::fs::read(input).unwrap();
    let args: Vec<String> = args
        .iter()
        .map(|a| {
            a.replace("{IN}", input.to_str().unwrap())
                .replace("{OUT}", out.to_str().unwrap())
        })
        .collect();
    let o = Command::new(bin()).args(&args).output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(e.contains("would overwrite the input"), "{args:?}: {e}");
    assert!(e.contains(out_name), "{args:?}: {e}");
    assert!(
        e.contains(input.file_name().unwrap().to_str().unwrap()),
        "{args:?}: {e}"
    );
    assert!(
        std::fs::read(input).unwrap() == before,
        "{args:?}: the input was changed"
    );
}

/// The same file under three other names: `./NAME`, a symbolic link, a hard link.
fn aliases(p: &Path) -> Vec<PathBuf> {
    let dir = p.parent().unwrap();
    let name = p.file_name().unwrap().to_str().unwrap();
    #[allow(unused_mut)]
    let mut v = vec![dir.join(".").join(name)];
    #[cfg(unix)]
    {
        let sym = dir.join(format!("sym-{name}"));
        std::os::unix::fs::symlink(p, &sym).unwrap();
        let hard = dir.join(format!("hard-{name}"));
        std::fs::hard_link(p, &hard).unwrap();
        v.extend([sym, hard]);
    }
    v
}

#[cfg(unix)]
#[test]
fn item_1_drive_loop_never_writes_its_record_over_the_controller() {
    let dir = tempfile::tempdir().unwrap();
    let c = dir.path().join("c.json");
    let o = fracid(&[
        "tune",
        "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
        "--wc",
        "100",
        "--pm",
        "60",
        "--dt",
        "1e-3",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    std::fs::write(&c, &o.stdout).unwrap();
    let sim = drive::sim::DriveSim::spawn(drive::sim::SimConfig {
        baud: 921_600,
        ..Default::default()
    })
    .unwrap();
    let port = sim.port_path().to_string();
    let mut outs = vec![c.clone()];
    outs.extend(aliases(&c));
    for out in &outs {
        refused(
            &[
                "drive",
                "loop",
                "--port",
                &port,
                "--baud",
                "921600",
                "--quiet",
                "--controller",
                "{IN}",
                "--step",
                "10",
                "--duration",
                "0.3",
                "-o",
                "{OUT}",
            ],
            &c,
            out,
            "--output",
        );
    }
    // the controller and a record beside it: the loop runs
    let rec = dir.path().join("rec.csv");
    let o = fracid(&[
        "drive",
        "loop",
        "--port",
        &port,
        "--baud",
        "921600",
        "--quiet",
        "--controller",
        c.to_str().unwrap(),
        "--step",
        "10",
        "--duration",
        "0.3",
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn item_2_sim_never_writes_over_its_input_record() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path(), "rec.csv");
    let mut outs = vec![rec.clone()];
    outs.extend(aliases(&rec));
    for out in &outs {
        refused(&["sim", "--input", "{IN}", "-o", "{OUT}"], &rec, out, "-o");
    }
    // the plot too: a record whose name ends in .svg
    let svg = record(dir.path(), "rec.svg");
    refused(
        &["sim", "--input", "{IN}", "--plot", "{OUT}"],
        &svg,
        &svg,
        "--plot",
    );
    // -o and --plot one file
    let o = fracid(&[
        "sim",
        "-o",
        dir.path().join("p.svg").to_str().unwrap(),
        "--plot",
        dir.path().join("p.svg").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("are one file"), "{}", stderr(&o));
    assert!(!dir.path().join("p.svg").exists());
}

#[test]
fn item_3_export_never_writes_over_its_model_file() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path(), "rec.csv");
    let fit = dir.path().join("fit.json");
    let o = fracid(&[
        "time",
        "--quiet",
        "--json",
        "--max-iter",
        "5",
        rec.to_str().unwrap(),
    ]);
    std::fs::write(&fit, &o.stdout).unwrap();
    assert!(
        serde_json::from_slice::<serde_json::Value>(&o.stdout).is_ok(),
        "{}",
        stderr(&o)
    );
    let mut outs = vec![fit.clone()];
    outs.extend(aliases(&fit));
    for out in &outs {
        refused(
            &["export", "{IN}", "--dt", "1e-3", "-o", "{OUT}"],
            &fit,
            out,
            "-o",
        );
    }
    // another output: written
    let ss = dir.path().join("ss.json");
    let o = fracid(&[
        "export",
        fit.to_str().unwrap(),
        "--dt",
        "1e-3",
        "-o",
        ss.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(ss.is_file());
}

/// The same hole in every other command that reads files and writes them: `time --plot` (over
/// the record, the `--validate` record, or the diagnosis's residual plot over one), `freq --plot`,
/// `compare --plot` and `tune --plot` over a model file, and a fleet's reports and summary over
/// one of its records. A plot must end in .png or .svg, so the inputs here do.
#[test]
fn items_1_to_3_no_command_writes_an_output_over_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rec = record(d, "rec.png");
    refused(
        &["time", "--quiet", "{IN}", "--plot", "{OUT}"],
        &rec,
        &rec,
        "--plot",
    );
    let val = record(d, "val.svg");
    let other = record(d, "other.csv");
    refused(
        &[
            "time",
            "--quiet",
            other.to_str().unwrap(),
            "--validate",
            "{IN}",
            "--plot",
            "{OUT}",
        ],
        &val,
        &val,
        "--plot",
    );
    let diag = record(d, "fig_diagnosis.png");
    refused(
        &[
            "time",
            "--quiet",
            "--diagnose",
            "{IN}",
            "--plot",
            &d.join("fig.png").to_string_lossy(),
        ],
        &diag,
        &diag,
        "residual plot",
    );
    let bode = write(
        &dir,
        "bode.svg",
        "freq_hz,gain_db,phase_deg\n1,16.6,-4\n10,14,-35\n100,-3,-120\n1000,-40,-165\n",
    );
    refused(&["freq", "{IN}", "--plot", "{OUT}"], &bode, &bode, "--plot");
    let model = write(&dir, "model.svg", "2/(0.01 s^0.9 + 1)\n");
    refused(
        &["compare", "{IN}", "3/(0.01 s + 1)", "--plot", "{OUT}"],
        &model,
        &model,
        "--plot",
    );
    refused(
        &[
            "tune", "{IN}", "--wc", "100", "--pm", "60", "--plot", "{OUT}",
        ],
        &model,
        &model,
        "--plot",
    );
    // a fleet: the report of a.csv is a.time.json, given as a record; the summary likewise
    let fleet = tempfile::tempdir().unwrap();
    let a = record(fleet.path(), "a.csv");
    let a_report = record(fleet.path(), "a.time.json");
    refused(
        &["time", "--quiet", a.to_str().unwrap(), "{IN}"],
        &a_report,
        &a_report,
        "the report",
    );
    let out = tempfile::tempdir().unwrap();
    let summary = record(out.path(), "time-summary.json");
    refused(
        &[
            "time",
            "--quiet",
            a.to_str().unwrap(),
            "{IN}",
            "--out",
            out.path().to_str().unwrap(),
        ],
        &summary,
        &summary,
        "the summary",
    );
}

/// Sizes asked on the command line are bounded with words (exit 2), at once and in little
/// memory: `compare --points 1e8` aborted under a 3 GB limit, `sim` made up to 1e8 samples
/// (2.3 GB) and a whole PRBS period before cutting it to --t-end, `drive sine --points 1e8`
/// 2.3 GB before any check.
#[cfg(unix)]
#[test]
fn item_7_sizes_are_bounded_before_memory_is_taken() {
    let kib = 600 << 10; // 600 MiB of address space
    let cases: [(&[&str], &str); 4] = [
        (
            &["compare", "1/(s+1)", "2/(s+1)", "--points", "100000000"],
            "points",
        ),
        (
            &["sim", "--t-end", "2000", "--dt", "1e-4", "-o", "/dev/null"],
            "samples",
        ),
        (
            &["sim", "--prbs", "--prbs-order", "16", "--prbs-clock", "0.1"],
            "samples",
        ),
        (
            &[
                "drive",
                "sine",
                "--port",
                "/nonexistent",
                "--points",
                "100000000",
                "-o",
                "/dev/null",
            ],
            "frequencies",
        ),
    ];
    for (args, word) in cases {
        let o = run_within(kib, args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains("at most") && e.contains(word), "{args:?}: {e}");
    }
    // the largest --points still runs
    let o = run_within(
        kib,
        &["compare", "1/(s+1)", "2/(s+1)", "--points", "100000"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // a second of a PRBS whose period is 6.5e7 samples: made without the period
    let o = run_within(
        kib,
        &[
            "sim",
            "--prbs",
            "--prbs-order",
            "16",
            "--prbs-clock",
            "0.1",
            "--dt",
            "1e-4",
            "--t-end",
            "1",
            "-o",
            "/dev/null",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// Bytes written into `fracid time PATH`'s input (a pipe, or a FIFO at PATH) until it exits: a
/// short text, then NUL bytes without end.
#[cfg(unix)]
fn bytes_fed_before_refusal(fifo: Option<&Path>) -> (Output, u64) {
    use std::io::Write;
    use std::process::Stdio;
    let path = fifo.map_or("/dev/stdin".into(), |p| p.to_string_lossy().into_owned());
    let mut child = Command::new(bin())
        .args(["time", "--quiet", &path])
        .stdin(if fifo.is_some() {
            Stdio::null()
        } else {
            Stdio::piped()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut sink: Box<dyn Write> = match fifo {
        Some(p) => Box::new(std::fs::OpenOptions::new().write(true).open(p).unwrap()),
        None => Box::new(child.stdin.take().unwrap()),
    };
    let mut fed = 0u64;
    sink.write_all(b"t,u,y\n0,1,2\n").unwrap();
    let zeros = vec![0u8; 1 << 16];
    // until the reader closes its end (broken pipe), or 1 GiB
    while fed < 1 << 30 {
        match sink.write(&zeros) {
            Ok(n) => fed += n as u64,
            Err(_) => break,
        }
    }
    drop(sink);
    (child.wait_with_output().unwrap(), fed)
}

/// A binary stream was buffered to 512 MiB (in a 1 GiB buffer) before it was refused: 4 s and
/// 1.07 GB, or an abort under a 1 GiB limit. It is refused at the read that brings its first NUL
/// byte.
#[cfg(unix)]
#[test]
fn item_8_a_binary_stream_is_refused_at_its_first_nul_byte() {
    let o = run_within(300 << 10, &["time", "--quiet", "/dev/urandom"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("NUL byte") || e.contains("not UTF-8"), "{e}");
    let (o, fed) = bytes_fed_before_refusal(None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("NUL byte at line 3"), "{}", stderr(&o));
    assert!(fed < 16 << 20, "{fed} bytes read before the refusal");
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.csv");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let (o, fed) = bytes_fed_before_refusal(Some(&fifo));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(fed < 16 << 20, "{fed} bytes read before the refusal");
}

/// `0.8,9,<u>,<y>` in a `t,u,y` file was read with its columns shifted (u = 9, y = the input):
/// a row with more or fewer fields than the header is refused, its line named, by the fast
/// reader (a large file, read in two halves) as by the simple one.
#[test]
fn item_12_a_row_with_a_field_too_many_or_too_few_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path(), "rec.csv");
    let text = std::fs::read_to_string(&rec).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // line 803 (t = 0.8): a field put in front of it
    let k = lines.iter().position(|l| l.starts_with("0.8,")).unwrap();
    let more = format!("0.8,9,{}", &lines[k][4..]);
    let fewer = lines[k].rsplit_once(',').unwrap().0.to_string();
    for (name, row) in [("more.csv", more), ("fewer.csv", fewer)] {
        let mut l: Vec<&str> = lines.clone();
        l[k] = &row;
        let p = write(&dir, name, &(l.join("\n") + "\n"));
        let o = fracid(&["time", "--quiet", "--max-iter", "3", p.to_str().unwrap()]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {e}");
        assert!(e.contains(&format!("line {}:", k + 1)), "{name}: {e}");
        assert!(e.contains("the header has 3"), "{name}: {e}");
    }
    // a table of 30000 rows (the fast reader, in two halves), the bad row in its second half
    let mut big = String::from("t,u,y\n");
    for i in 0..30_000 {
        if i == 20_000 {
            big += &format!("{},1,2,3\n", i as f64 * 1e-3);
        } else {
            big += &format!("{},1,{}\n", i as f64 * 1e-3, (i % 7) as f64);
        }
    }
    let p = write(&dir, "big.csv", &big);
    let o = fracid(&["time", "--quiet", "--max-iter", "1", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("line 20002:"), "{}", stderr(&o));
    // the same for a sim input and a Bode table
    let o = fracid(&["sim", "--input", p.to_str().unwrap(), "-o", "/dev/null"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let bode = write(
        &dir,
        "bode.csv",
        "freq_hz,gain_db,phase_deg\n1,16.6,-4\n10,14,-35,7\n100,-3,-120\n",
    );
    let o = fracid(&["freq", bode.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("line 3:"), "{}", stderr(&o));
}

/// Fleets skipped dangling links, link loops and FIFOs among `*.csv` without a word: each is a
/// failed row with its reason, counted, and a FIFO is not opened (it would wait for a writer).
#[cfg(unix)]
#[test]
fn item_16_a_fleet_lists_what_it_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    record(d, "a.csv");
    std::os::unix::fs::symlink("gone.csv", d.join("dangling.csv")).unwrap();
    std::os::unix::fs::symlink("loop.csv", d.join("loop.csv")).unwrap();
    assert!(Command::new("mkfifo")
        .arg(d.join("fifo.csv"))
        .status()
        .unwrap()
        .success());
    std::fs::create_dir(d.join("folder.csv")).unwrap();
    for cmd in ["time", "freq"] {
        let out = tempfile::tempdir().unwrap();
        let o = fracid(&[
            cmd,
            d.to_str().unwrap(),
            "--out",
            out.path().to_str().unwrap(),
        ]);
        let e = stderr(&o);
        assert!(o.status.code().is_some_and(|c| c != 0), "{cmd}: {e}");
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.path().join(format!("{cmd}-summary.json"))).unwrap(),
        )
        .unwrap();
        // a.csv and the three that are no records; a folder is not a file of the fleet
        assert_eq!(summary["files"], 4, "{cmd}: {summary}");
        let rows = summary["rows"].as_array().unwrap();
        for (name, code, why) in [
            ("dangling.csv", 3, "dangling symbolic link"),
            ("loop.csv", 3, "link loop"),
            ("fifo.csv", 2, "FIFO"),
        ] {
            let r = rows
                .iter()
                .find(|r| r["file"].as_str().unwrap().ends_with(name))
                .unwrap_or_else(|| panic!("{cmd}: no row for {name}: {summary}"));
            assert_eq!(r["status"], "failed", "{r}");
            assert_eq!(r["exit_code"], code, "{r}");
            assert!(r["error"].as_str().unwrap().contains(why), "{r}");
            assert!(e.contains(name), "{cmd}: {e}");
        }
        if cmd == "time" {
            assert_eq!(summary["failed"], 3, "{summary}");
        }
    }
}
