//! Bad input to the time-domain identification: a clear error (or a warning in the report), never
//! a panic.

use fracsim::prbs::Prbs;
use fracsim::{ApproxSpec, FracTf, Simulator};
use ident::data::{Columns, OffsetMode, Record};
use ident::oe::{identify, FracModel, IdentOptions, StartMethod, StartMode};
use ident::Error;

fn parse(text: &str) -> ident::Result<Record> {
    Record::parse(text, &Columns::default())
}

/// A PRBS record (order 7, 10-sample bits, 3 periods at 1 ms) of `g`, noise-free.
fn record_of(g: &FracTf) -> Record {
    let dt = 1e-3;
    let u = Prbs {
        clock: 10.0 * dt,
        periods: 3,
        ..Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    let y = Simulator::<f64>::new(g, dt, &ApproxSpec::default())
        .unwrap()
        .simulate(&u);
    Record::from_samples(&u, &y, dt).unwrap()
}

#[test]
fn missing_columns_are_named() {
    let e = parse("t,u\n0,1\n1,2\n").unwrap_err();
    assert!(matches!(e, Error::Data(_)), "{e:?}");
    assert!(e.to_string().contains("no column 'y'"), "{e}");
    assert!(e.to_string().contains("found: t, u"), "{e}");
    // A row shorter than the header.
    let e = parse("t,u,y\n0,1,2\n1,2\n").unwrap_err();
    assert!(e.to_string().contains("line 3"), "{e}");
    let e = parse("").unwrap_err();
    assert!(e.to_string().contains("no header"), "{e}");
}

#[test]
fn windows_files_and_ambiguous_headers() {
    // Excel's "CSV UTF-8" starts with a byte-order mark and ends lines with CRLF: the BOM was
    // read as part of the first name ("no column 't' (found: \u{feff}t, u, y)").
    let rec = parse("\u{feff}t,u,y\r\n0,0,0\r\n0.1,1,0\r\n0.2,1,0.5\r\n").unwrap();
    assert_eq!(rec.t, vec![0.0, 0.1, 0.2]);
    assert_eq!(rec.y, vec![0.0, 0.0, 0.5]);
    // A name twice in the header silently took the first.
    let e = parse("t,u,y,y\n0,0,0,5\n1,1,0,6\n").unwrap_err();
    assert!(matches!(e, Error::Data(_)), "{e:?}");
    assert!(e.to_string().contains("'y' appears twice"), "{e}");
    // ...by index it is unambiguous
    let cols = Columns {
        y: "3".into(),
        ..Columns::default()
    };
    let rec = Record::parse("t,u,y,y\n0,0,0,5\n1,1,0,6\n", &cols).unwrap();
    assert_eq!(rec.y, vec![5.0, 6.0]);
}

#[test]
fn nan_and_text_are_errors() {
    for (text, want) in [
        ("t,u,y\n0,1,2\n1,1,NaN\n2,1,2\n", "not finite"),
        ("t,u,y\n0,1,2\n1,inf,2\n2,1,2\n", "not finite"),
        ("t,u,y\n0,1,2\n1,one,2\n2,1,2\n", "not a number"),
    ] {
        let e = parse(text).unwrap_err();
        assert!(matches!(e, Error::Data(_)), "{e:?}");
        assert!(e.to_string().contains(want), "{text:?}: {e}");
    }
}

#[test]
fn time_must_be_increasing_and_uniform() {
    let e = parse("t,u,y\n0,1,2\n0.1,1,2\n0.1,1,2\n0.3,1,2\n").unwrap_err();
    assert!(
        e.to_string().contains("strictly increasing at sample 2"),
        "{e}"
    );
    let e = parse("t,u,y\n0,1,2\n0.2,1,2\n0.1,1,2\n").unwrap_err();
    assert!(e.to_string().contains("strictly increasing"), "{e}");
    // A missing sample: one step twice the others.
    let e = parse("t,u,y\n0,1,2\n0.1,1,2\n0.2,1,2\n0.4,1,2\n0.5,1,2\n").unwrap_err();
    assert!(e.to_string().contains("non-uniform sampling"), "{e}");
    // Jitter below the 1% tolerance is accepted.
    assert!(parse("t,u,y\n0,1,2\n0.1001,1,2\n0.2,1,2\n").is_ok());
}

#[test]
fn an_input_without_excitation_is_refused() {
    let u = vec![1.5; 500];
    let y: Vec<f64> = (0..500).map(|k| 3.0 + 1e-3 * (k % 7) as f64).collect();
    let rec = Record::from_samples(&u, &y, 1e-3).unwrap();
    let e = identify(
        &rec,
        &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9),
        &Default::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::NotEnoughData(_)), "{e:?}");
    assert!(e.to_string().contains("no excitation"), "{e}");
}

#[test]
fn too_few_samples_are_refused() {
    // 2 samples: the record itself is fine, the fit is not.
    let rec = parse("t,u,y\n0,0,0\n1,1,1\n").unwrap();
    let e = identify(
        &rec,
        &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9),
        &Default::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::NotEnoughData(_)), "{e:?}");
    // 60 samples, 42 for estimation: below 10 per free parameter (5 + the offset).
    let u: Vec<f64> = (0..60).map(|k| ((k / 5) % 2) as f64).collect();
    let rec = Record::from_samples(&u, &u, 1e-3).unwrap();
    let e = identify(
        &rec,
        &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9),
        &Default::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("need at least 60"), "{e}");
    let e = Record::parse("t,u,y\n0,1,2\n", &Columns::default()).unwrap_err();
    assert!(matches!(e, Error::NotEnoughData(_)), "{e:?}");
}

#[test]
fn bad_options_are_errors() {
    let rec = record_of(&FracTf::pmsm(2.0, 0.05, 1e-3, 0.9, 0.8).unwrap());
    let opts = IdentOptions {
        holdout: 1.5,
        ..Default::default()
    };
    let e = identify(&rec, &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9), &opts).unwrap_err();
    assert!(matches!(e, Error::Options(_)), "{e:?}");
    // A given start outside its range.
    let opts = IdentOptions {
        start: StartMode::Given,
        ..Default::default()
    };
    let e = identify(&rec, &FracModel::pmsm(1.0, 0.01, 1e-4, 2.5, 0.9), &opts);
    assert!(
        e.is_ok(),
        "starting values are clamped inside their range: {e:?}"
    );
}

#[test]
fn an_order_at_its_bound_is_a_warning() {
    // A lightly damped integer second-order plant, 1e4/(s^2 + 40 s + 1e4) (damping 0.2): the
    // commensurate model (q in (0, 1)) can only follow it with q -> 1, the edge of its range.
    let g: FracTf = "1/(1e-4 s^2 + 0.004 s + 1)".parse().unwrap();
    let rec = record_of(&g);
    let opts = IdentOptions {
        offsets: OffsetMode::None,
        fit_offset: false,
        ..Default::default()
    };
    let id = identify(&rec, &FracModel::commensurate(1.0, 0.01, 1e-4, 0.9), &opts).unwrap();
    let q = &id.report.params[3];
    eprintln!("{q:?} {:?} {:?}", id.report.warnings, id.start_report);
    assert_eq!(q.name, "q");
    assert!(q.at_bound, "{q:?}");
    assert!(
        id.report
            .warnings
            .iter()
            .any(|w| w.contains("q = ") && w.contains("bound")),
        "{:?}",
        id.report.warnings
    );
    // It still fits (q = 1 is the truth): the warning says the structure is at its edge.
    assert!(id.estimation.nrmse_percent > 90.0, "{:?}", id.estimation);
    assert_eq!(id.start_report.method, StartMethod::Levy);
}

#[test]
fn a_delay_not_shorter_than_the_estimation_record_is_refused() {
    // 3 periods of 1270 samples at 1 ms: 3.81 s, 2.667 s of it for estimation (holdout 0.3).
    let rec = record_of(&FracTf::pmsm(2.0, 0.05, 1e-3, 0.9, 0.8).unwrap());
    let opts = IdentOptions::default();
    // A fixed delay from a transfer function: the fit ran and only warned of a singular
    // covariance.
    let g: FracTf = "1/(s+1) exp(-10 s)".parse().unwrap();
    let e = identify(&rec, &FracModel::from_tf(&g, true, true), &opts).unwrap_err();
    assert!(matches!(e, Error::Options(_)), "{e:?}");
    let msg = e.to_string();
    assert!(msg.contains("tau = 10 s"), "{msg}");
    assert!(
        msg.contains("not shorter than the estimation record"),
        "{msg}"
    );
    assert!(msg.contains("2.667 s (2667 samples of 0.001 s)"), "{msg}");
    // A fitted delay whose upper bound reaches the record, even from a short start.
    let e = identify(&rec, &FracModel::fopdt(1.0, 0.1, 0.01, 2.7), &opts).unwrap_err();
    assert!(matches!(e, Error::Options(_)), "{e:?}");
    assert!(e.to_string().contains("upper bound of tau"), "{e}");
    // A bound just inside the record is accepted.
    let id = identify(&rec, &FracModel::fopdt(1.0, 0.1, 0.01, 2.6), &opts).unwrap();
    assert!(id.tf.delay < 2.6, "{}", id.tf);
}

#[test]
fn header_lookup_is_shared() {
    use ident::data::{column_indices, header};
    // The header as every reader sees it: byte-order mark, comments and blank lines skipped.
    let names = header("\u{feff}# Bode\n\nfreq_hz; gain_db ;phase_deg\n1;2;3\n").unwrap();
    assert_eq!(names, ["freq_hz", "gain_db", "phase_deg"]);
    assert_eq!(header("# only a comment\n\n"), None);
    assert_eq!(
        column_indices(&names, &["PHASE_DEG", "0", "gain_db"]).unwrap(),
        [2, 0, 1]
    );
    let e = column_indices(&names, &["freq_hz", "freq_hz", "phase_deg"]).unwrap_err();
    assert!(matches!(e, Error::Data(_)), "{e:?}");
    assert!(e.to_string().contains("'freq_hz' is chosen twice"), "{e}");
    let e = column_indices(&["f", "f", "g"], &["f"]).unwrap_err();
    assert!(e.to_string().contains("'f' appears twice"), "{e}");
}

#[test]
fn read_columns_is_the_one_reader() {
    use ident::data::read_columns;
    let text = "\u{feff}# rig 2\ntime;volts;y\n0;1;5 # start\n\n0.1;2;6\n";
    let (names, [u, t]) = read_columns(text, ["volts", "0"]).unwrap();
    assert_eq!(names, ["time", "volts", "y"]);
    assert_eq!((t, u), (vec![0.0, 0.1], vec![1.0, 2.0]));
    // The same checks as the record's.
    for (wants, want) in [
        (["time", "time"], "chosen twice"),
        (["time", "u"], "no column 'u'"),
    ] {
        let e = read_columns(text, wants).unwrap_err();
        assert!(e.to_string().contains(want), "{wants:?}: {e}");
    }
    let e = read_columns("t,u\n0,1\n1\n", ["t", "u"]).unwrap_err();
    assert!(e.to_string().contains("line 3"), "{e}");
    // A record with one column for two of t, u, y.
    let cols = Columns {
        y: "u".into(),
        ..Columns::default()
    };
    let e = Record::parse("t,u,y\n0,0,0\n1,1,1\n", &cols).unwrap_err();
    assert!(matches!(e, Error::Data(_)), "{e:?}");
    assert!(e.to_string().contains("chosen twice"), "{e}");
}
