//! The file readers (`ident::data`, `ident::bodefile`, `ident::matfile`) on the files of real
//! labs and of interrupted acquisitions, and fuzzed: a clear `Err`, never a panic.

use ident::bodefile::{self, BodeUnits};
use ident::data::{self, Acquisition, Columns, ReadOptions, Record};
use ident::Error;
use proptest::prelude::*;
use std::path::PathBuf;

/// A scratch file under the target directory, unique per test.
fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ident-readers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn cols(t: &str, u: &str, y: &str) -> ReadOptions {
    ReadOptions {
        columns: Columns {
            t: t.into(),
            u: u.into(),
            y: y.into(),
        },
        dt: None,
    }
}

#[test]
fn quoted_header_of_the_coupled_drives_benchmark() {
    // the benchmark's CSV: quoted names, no time column (50 Hz sampling)
    let text = "\"z1\",\"z2\",\"u1\",\"u2\"\n1.5,0.1,2,0\n1.6,0.2,3,0\n1.7,0.3,2,0\n";
    let opts = ReadOptions {
        columns: Columns {
            t: "t".into(),
            u: "u1".into(),
            y: "z1".into(),
        },
        dt: Some(0.02),
    };
    let l = Record::parse_with(text, &opts).unwrap();
    assert_eq!(l.record.u, vec![2.0, 3.0, 2.0]);
    assert_eq!(l.record.y, vec![1.5, 1.6, 1.7]);
    assert!((l.record.dt - 0.02).abs() < 1e-15);
    assert_eq!(l.record.t[2], 0.04);
    // without --dt the missing time column is named
    let e = Record::parse_with(text, &cols("t", "u1", "z1")).unwrap_err();
    assert!(e.to_string().contains("no column 't'"), "{e}");
    // quoted fields too
    let l = Record::parse_with(
        "\"t\",\"u\",\"y\"\n\"0\",\"1\",\"2\"\n\"1\",\"1\",\"3\"\n",
        &Default::default(),
    )
    .unwrap();
    assert_eq!(l.record.y, vec![2.0, 3.0]);
    // dt must be positive
    let bad = ReadOptions {
        dt: Some(0.0),
        ..opts
    };
    assert!(matches!(
        Record::parse_with(text, &bad),
        Err(Error::Options(_))
    ));
}

#[test]
fn headerless_files_lose_no_row() {
    let text = "0,1,5\n0.1,2,6\n0.2,3,7\n";
    let l = Record::parse_with(text, &cols("0", "1", "2")).unwrap();
    // the first row was taken as the header and lost
    assert_eq!(l.record.len(), 3);
    assert_eq!(l.record.u, vec![1.0, 2.0, 3.0]);
    // names on a headerless file: a message that says how to choose
    let e = Record::parse_with(text, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("no header line"), "{e}");
    assert!(e.to_string().contains("--t-col 0"), "{e}");
    // with dt: two columns
    let opts = ReadOptions {
        columns: Columns {
            t: "t".into(),
            u: "0".into(),
            y: "1".into(),
        },
        dt: Some(0.5),
    };
    let l = Record::parse_with("1 ;5\n2; 6\n", &opts).unwrap();
    assert_eq!(l.record.t, vec![0.0, 0.5]);
}

#[test]
fn a_gap_is_reported_where_it_is() {
    // 1000 samples at 1 ms with sample 768 missing: the mean step moved every step past 1%, so
    // the message said "sample 1"
    let t: Vec<f64> = (0..1001)
        .filter(|&k| k != 768)
        .map(|k| k as f64 * 1e-3)
        .collect();
    let e = data::sampling_step(&t).unwrap_err().to_string();
    assert!(e.contains("non-uniform sampling at sample 768"), "{e}");
}

/// A `fracid drive` file of 400 samples at 1 kHz with `skip` rows left out and `footer`.
fn drive_file(skip: std::ops::Range<usize>, footer: Option<&str>) -> String {
    let mut s = String::from(
        "# fracid drive acquisition: PRBS order 7\n# run_id 3, 400 samples planned at 1000 Hz; units: t s, u V, y rad/s, i A\nt,u,y,i\n",
    );
    for k in (0..400).filter(|k| !skip.contains(k)) {
        s += &format!("{:.6},{},{},0\n", k as f64 * 1e-3, (k / 7) % 2, k % 5);
    }
    if let Some(f) = footer {
        s += f;
        s += "\n";
    }
    s
}

#[test]
fn acquisition_footers_are_honoured() {
    // complete: all of it, no warning
    let l = Record::parse_with(
        &drive_file(0..0, Some("# complete: 400 samples")),
        &Default::default(),
    )
    .unwrap();
    assert_eq!((l.record.len(), l.warnings.len()), (400, 0));
    assert_eq!(l.acquisition, Acquisition::Complete);
    // a gap in the middle: the longest complete part (samples 0..300), the range named
    let text = drive_file(
        300..330,
        Some("# incomplete: missing samples 300..330 (port lost)"),
    );
    let l = Record::parse_with(&text, &Default::default()).unwrap();
    assert_eq!(l.record.len(), 300);
    assert_eq!(l.rows_kept, 0..300);
    assert_eq!(l.record.t[299], 0.299);
    assert!(
        l.warnings[0].contains("missing samples 300..330 (port lost)"),
        "{:?}",
        l.warnings
    );
    // the same file without its footer used to fail as non-uniform; a run cut at the end: kept
    let text = drive_file(
        250..400,
        Some("# incomplete: missing samples 250..400 (stopped)"),
    );
    let l = Record::parse_with(&text, &Default::default()).unwrap();
    assert_eq!(l.record.len(), 250);
    // too short a complete part: refused, saying why
    let text = drive_file(
        30..400,
        Some("# incomplete: missing samples 30..400 (reset)"),
    );
    let e = Record::parse_with(&text, &Default::default()).unwrap_err();
    assert!(matches!(e, Error::NotEnoughData(_)), "{e:?}");
    assert!(e.to_string().contains("30 samples"), "{e}");
    // no footer at all: interrupted
    let l = Record::parse_with(&drive_file(0..0, None), &Default::default()).unwrap();
    assert_eq!(l.acquisition, Acquisition::Interrupted);
    assert!(l.warnings[0].contains("interrupted"), "{:?}", l.warnings);
    // a file that is not an acquisition: no warning
    let l = Record::parse_with("t,u,y\n0,0,0\n1,1,1\n", &Default::default()).unwrap();
    assert_eq!(l.acquisition, Acquisition::Unknown);
    assert!(l.warnings.is_empty());
}

#[test]
fn bad_files_are_data_errors_bounded_and_short() {
    // invalid UTF-8: a data error (exit 2), not I/O
    let p = scratch("latin1.csv", b"t,u,y\n0,1,\xe9\n");
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(matches!(e, Error::Data(_)), "{e:?}");
    assert!(e.to_string().contains("not UTF-8"), "{e}");
    assert!(e.to_string().contains("line 2"), "{e}");
    // a CR-only file is read as lines, and a bad value is not the whole file in the message
    let mut cr = String::from("t,u,y\r");
    for k in 0..5000 {
        cr += &format!("{k},1,2\r");
    }
    cr += "5000,x,2\r";
    let e = Record::parse_with(&cr, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 5002"), "{e}");
    assert!(e.len() < 200, "{} characters", e.len());
    // one line of 1 MiB + 1 byte: refused while reading
    let p = scratch("long.csv", &vec![b'1'; ident::files::MAX_LINE_BYTES + 1]);
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("longer than"), "{e}");
    // a missing file: I/O, in words
    let e = Record::load(
        std::path::Path::new("/nonexistent/x.csv"),
        &Default::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    assert!(!e.to_string().contains("os error"), "{e}");
    // binary
    let p = scratch("bin.csv", b"t,u,y\n\0\0\0");
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("NUL byte"), "{e}");
    // a 300-character name is quoted short
    let long = "9".repeat(300);
    let e = Record::parse_with(&format!("t,u,y\n0,1,{long}x\n"), &Default::default()).unwrap_err();
    assert!(e.to_string().contains("(301 characters)"), "{e}");
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_after_a_bounded_read() {
    let t0 = std::time::Instant::now();
    let e = Record::load(std::path::Path::new("/dev/zero"), &Default::default()).unwrap_err();
    // refused at the first read, by its first byte (a stream is checked as it is read)
    assert!(e.to_string().contains("NUL byte at line 1, byte 0"), "{e}");
    // one read, not unbounded: seconds at most even on a loaded machine
    assert!(t0.elapsed().as_secs() < 20);
}

#[test]
fn headerless_bode_tables_are_refused_unless_columns_are_said() {
    // a linear gain in a headerless table was read as dB
    let text = "1\t2\t-10\n10\t0.5\t-80\n";
    let e = bodefile::parse(text, None, BodeUnits::default(), None).unwrap_err();
    assert!(e.to_string().contains("--columns 0,1,2"), "{e}");
    let units = BodeUnits {
        linear_gain: true,
        ..Default::default()
    };
    let b = bodefile::parse(text, Some(["0", "1", "2"]), units, None).unwrap();
    assert!((b.h[0].norm() - 2.0).abs() < 1e-12);
    // quoted header, semicolons
    let b = bodefile::parse(
        "\"freq_hz\";\"gain_db\";\"phase_deg\"\n1;0;0\n2;-6;-90\n",
        None,
        BodeUnits::default(),
        None,
    )
    .unwrap();
    assert_eq!(b.omega_rad_s.len(), 2);
}

// --- MATLAB level 5 files, written here from the format's specification ---------------------

/// A level 5 `.mat` file of double variables `(name, rows, cols, column-major data)`, each
/// optionally zlib-compressed (as `save -v7` writes).
fn mat_file(vars: &[(&str, usize, usize, Vec<f64>)], compress: bool) -> Vec<u8> {
    fn element(ty: u32, data: &[u8]) -> Vec<u8> {
        let mut e = Vec::new();
        e.extend(ty.to_le_bytes());
        e.extend((data.len() as u32).to_le_bytes());
        e.extend(data);
        while e.len() % 8 != 0 {
            e.push(0);
        }
        e
    }
    let mut f = b"MATLAB 5.0 MAT-file, written by ident's tests".to_vec();
    f.resize(116, b' ');
    f.extend([0u8; 8]);
    f.extend([0x00, 0x01, b'I', b'M']);
    for (name, rows, cols, data) in vars {
        let mut m = Vec::new();
        let mut flags = 6u32.to_le_bytes().to_vec(); // class double
        flags.extend(0u32.to_le_bytes());
        m.extend(element(6, &flags));
        let mut dims = (*rows as i32).to_le_bytes().to_vec();
        dims.extend((*cols as i32).to_le_bytes());
        m.extend(element(5, &dims));
        m.extend(element(1, name.as_bytes()));
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        m.extend(element(9, &bytes));
        let matrix = element(14, &m);
        if compress {
            // not padded: the format pads neither miMATRIX nor miCOMPRESSED elements
            let z = miniz_oxide::deflate::compress_to_vec_zlib(&matrix, 6);
            f.extend(15u32.to_le_bytes());
            f.extend((z.len() as u32).to_le_bytes());
            f.extend(z);
        } else {
            f.extend(matrix);
        }
    }
    f
}

#[test]
fn mat_files_time_records_and_bode_tables() {
    let n = 200;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let u: Vec<f64> = (0..n).map(|k| ((k / 10) % 2) as f64).collect();
    let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
    for compress in [false, true] {
        let bytes = mat_file(
            &[
                ("t", n, 1, t.clone()),
                ("u", 1, n, u.clone()),
                ("y", n, 1, y.clone()),
            ],
            compress,
        );
        let p = scratch(&format!("rec{compress}.mat"), &bytes);
        let l = Record::load(&p, &Default::default()).unwrap();
        assert_eq!((&l.record.u, &l.record.y), (&u, &y));
        assert!((l.record.dt - 1e-3).abs() < 1e-12);
    }
    // one N x 3 matrix, columns by index
    let mut m = t.clone();
    m.extend(&u);
    m.extend(&y);
    let p = scratch("matrix.mat", &mat_file(&[("data", n, 3, m)], true));
    let l = Record::load(&p, &cols("0", "1", "2")).unwrap();
    assert_eq!(l.record.y, y);
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("no variable 't'"), "{e}");
    assert!(e.to_string().contains("found: data"), "{e}");
    // a Bode table
    let f = vec![1.0, 10.0, 100.0];
    let g = vec![0.0, -3.0, -20.0];
    let ph = vec![0.0, -45.0, -84.0];
    let p = scratch(
        "bode.mat",
        &mat_file(
            &[
                ("freq_hz", 3, 1, f),
                ("gain_db", 3, 1, g),
                ("phase_deg", 3, 1, ph),
            ],
            false,
        ),
    );
    let b = bodefile::load(&p, None, BodeUnits::default(), None).unwrap();
    assert!((b.omega_rad_s[1] - 20.0 * std::f64::consts::PI).abs() < 1e-12);
    assert!((b.h[2].arg().to_degrees() + 84.0).abs() < 1e-9);
    // v7.3 (HDF5) and level 4: refused in words
    let mut v73 = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon".to_vec();
    v73.resize(512, b' ');
    v73.extend(b"\x89HDF\r\n\x1a\n");
    let p = scratch("v73.mat", &v73);
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("v7.3 (HDF5)"), "{e}");
    let p = scratch("v4.mat", &[0u8; 64]);
    let e = Record::load(&p, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("level 4"), "{e}");
}

/// Files written by scipy 1.17.1 (`scipy.io.savemat`, committed in `tests/data`, made with
/// `k = np.arange(120); t = k/1000; u = ((k//7)%2)*2-1; y = k*k/64`, plus an int8 scalar `n = 3`
/// and a char variable `note`): `do_compression=True` (`_v7`, each variable an unpadded
/// miCOMPRESSED element of 60, 610, ... bytes) and `False` (`_v6`). Before the fix the
/// compressed file was refused ("a small data element of more than 4 bytes": the reader padded
/// the compressed element to 8 bytes and read the next tag 4 bytes late).
#[test]
fn mat_files_written_by_scipy() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let k: Vec<f64> = (0..120).map(f64::from).collect();
    let t: Vec<f64> = k.iter().map(|k| k / 1000.0).collect();
    let u: Vec<f64> = (0..120).map(|k| ((k / 7) % 2) as f64 * 2.0 - 1.0).collect();
    let y: Vec<f64> = k.iter().map(|k| k * k / 64.0).collect();
    for name in ["scipy_savemat_v7.mat", "scipy_savemat_v6.mat"] {
        let vars = ident::matfile::read(&dir.join(name)).unwrap();
        let names: Vec<&str> = vars.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["t", "u", "y", "n"], "{name}: char 'note' skipped");
        assert_eq!(
            vars[3].data,
            [3.0],
            "{name}: int8 scalar in a small element"
        );
        let l = Record::load(&dir.join(name), &Default::default()).unwrap();
        assert_eq!(l.record.t, t, "{name}");
        assert_eq!((&l.record.u, &l.record.y), (&u, &y), "{name}");
    }
}

#[test]
fn compressed_mat_elements_padded_to_8_bytes_are_read_too() {
    // some writers pad the compressed element (the format does not ask it): still read
    let a = mat_file(&[("u", 3, 1, vec![1.0, 2.0, 3.0])], true);
    let b = mat_file(&[("y", 3, 1, vec![4.0, 5.0, 6.0])], true);
    let mut f = a.clone();
    while !f.len().is_multiple_of(8) {
        f.push(0);
    }
    f.extend(&b[128..]);
    let vars = ident::matfile::parse(&f).unwrap();
    assert_eq!(vars.len(), 2);
    assert_eq!(vars[1].data, [4.0, 5.0, 6.0]);
    // and unpadded, as the format says
    let mut f = a;
    f.extend(&b[128..]);
    assert_eq!(ident::matfile::parse(&f).unwrap().len(), 2);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, rng_seed: proptest::test_runner::RngSeed::Fixed(12), failure_persistence: None, ..ProptestConfig::default() })]

    /// Any text, to the time reader and the Bode reader: `Ok` or `Err`, never a panic; a record
    /// that is read is checked (finite, uniform).
    #[test]
    fn text_readers_never_panic(text in "[0-9tuy,;\t\r\n#\"'. eE+-]{0,200}", dt in proptest::option::of(0.001f64..1.0)) {
        let opts = ReadOptions { dt, ..Default::default() };
        if let Ok(l) = Record::parse_with(&text, &opts) {
            prop_assert!(l.record.u.iter().chain(&l.record.y).all(|v| v.is_finite()));
            prop_assert!(data::sampling_step(&l.record.t).is_ok());
        }
        let _ = Record::parse_with(&text, &cols("0", "1", "2"));
        let _ = bodefile::parse(&text, None, BodeUnits::default(), None);
        let _ = bodefile::parse(&text, Some(["0", "1", "2"]), BodeUnits::default(), Some("3"));
    }

    /// Rows of numbers with a bad field or a gap somewhere: an `Err` that names a line or sample.
    #[test]
    fn one_bad_row_is_found(n in 3usize..60, bad in 0usize..60, kind in 0u8..3) {
        let bad = bad % n;
        let mut text = String::from("t,u,y\n");
        for k in 0..n {
            let t = if kind == 2 && k >= bad && bad > 0 { k + 1 } else { k };
            let u = if kind == 0 && k == bad { "x".to_string() } else { "1".to_string() };
            let y = if kind == 1 && k == bad { "nan".to_string() } else { format!("{k}") };
            text += &format!("{t},{u},{y}\n");
        }
        let r = Record::parse_with(&text, &Default::default());
        match kind {
            0 => {
                let (e, want) = (r.unwrap_err().to_string(), format!("line {}", bad + 2));
                prop_assert!(e.contains(&want), "{}", e);
            }
            1 => {
                let (e, want) = (r.unwrap_err().to_string(), format!("sample {}", bad));
                prop_assert!(e.contains(&want), "{}", e);
            }
            _ if bad > 0 && n > 3 => {
                let e = r.unwrap_err().to_string();
                let want = format!("sample {}", bad);
                prop_assert!(e.contains(&want), "{}", e);
            }
            _ => {}
        }
    }

    /// Random bytes after a valid `.mat` header, and corrupted real files: `Err` or `Ok`, never
    /// a panic or an unbounded allocation.
    #[test]
    fn mat_reader_never_panics(tail in proptest::collection::vec(any::<u8>(), 0..300), flip in 0usize..2000, compress in any::<bool>()) {
        let mut f = b"MATLAB 5.0 MAT-file".to_vec();
        f.resize(124, b' ');
        f.extend([0x00, 0x01, b'I', b'M']);
        f.extend(&tail);
        let _ = ident::matfile::parse(&f);
        let mut good = mat_file(&[("u", 5, 1, vec![1.0, 2.0, 3.0, 4.0, 5.0])], compress);
        let i = 128 + flip % (good.len() - 128);
        good[i] ^= 0xa5;
        let _ = ident::matfile::parse(&good);
        good.truncate(i);
        let _ = ident::matfile::parse(&good);
    }
}

#[test]
fn the_spread_columns_of_repeated_sweeps_are_read_as_standard_errors() {
    // as `fracid drive sine --repeats` writes them: 5 repeats, the trimmed mean of 3
    let text = "# a sweep\nfreq_hz,gain_db,phase_deg,gain_db_std,phase_deg_std,repeats\n\
                1,0,0,0.3,3,5\n2,-6,-90,0.6,6,1\n";
    let b = bodefile::parse(text, None, BodeUnits::default(), None).unwrap();
    let se = b.spread_se.expect("spread read");
    assert!((se[0].0 - 0.3 / 3f64.sqrt()).abs() < 1e-12, "{se:?}");
    assert!((se[0].1 - 3.0 / 3f64.sqrt()).abs() < 1e-12, "{se:?}");
    assert_eq!(se[1], (0.6, 6.0));
    // no spread columns, no spread; a negative spread is refused with its line
    let plain = "freq_hz,gain_db,phase_deg\n1,0,0\n";
    let b = bodefile::parse(plain, None, BodeUnits::default(), None).unwrap();
    assert!(b.spread_se.is_none());
    let bad = "freq_hz,gain_db,phase_deg,gain_db_std,phase_deg_std\n1,0,0,-1,0\n";
    let e = bodefile::parse(bad, None, BodeUnits::default(), None).unwrap_err();
    assert!(e.to_string().contains("line 2"), "{e}");
}
