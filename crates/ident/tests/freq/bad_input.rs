//! Bad input is an error, never a panic.

use ident::levy::{fit_bode, levy_fixed_q, FreqOptions, OrderChoice, Weights};
use ident::Error;
use num_complex::Complex64;

fn data() -> (Vec<f64>, Vec<Complex64>) {
    let omega = vec![1.0, 2.0, 5.0, 10.0, 20.0];
    let h = omega
        .iter()
        .map(|w| Complex64::new(2.0, 0.0) / Complex64::new(1.0, 0.1 * w))
        .collect();
    (omega, h)
}

fn fit(omega: &[f64], h: &[Complex64]) -> ident::Result<ident::levy::FreqFit> {
    fit_bode(omega, h, &FreqOptions::default())
}

#[test]
fn unsorted_repeated_nonpositive_nan() {
    let (omega, h) = data();
    let mut o = omega.clone();
    o.swap(1, 2);
    assert!(matches!(fit(&o, &h), Err(Error::Data(m)) if m.contains("increase")));
    let mut o = omega.clone();
    o[2] = o[1];
    assert!(matches!(fit(&o, &h), Err(Error::Data(m)) if m.contains("repeated")));
    let mut o = omega.clone();
    o[0] = 0.0;
    assert!(matches!(fit(&o, &h), Err(Error::Data(_))));
    let mut o = omega.clone();
    o[0] = -1.0;
    assert!(matches!(fit(&o, &h), Err(Error::Data(_))));
    let mut o = omega.clone();
    o[3] = f64::NAN;
    assert!(matches!(fit(&o, &h), Err(Error::Data(_))));
    let mut hh = h.clone();
    hh[3] = Complex64::new(f64::NAN, 0.0);
    assert!(matches!(fit(&omega, &hh), Err(Error::Data(_))));
    assert!(matches!(fit(&omega, &h[..4]), Err(Error::Data(_))));
    assert!(matches!(fit(&[], &[]), Err(Error::Data(_))));
}

#[test]
fn too_few_points_and_bad_options() {
    let (omega, h) = data();
    assert!(matches!(
        fit(&omega[..2], &h[..2]),
        Err(Error::NotEnoughData(_))
    ));
    let opts = FreqOptions {
        n: 3,
        m: 2,
        ..FreqOptions::default()
    };
    assert!(matches!(
        fit_bode(&omega, &h, &opts),
        Err(Error::NotEnoughData(_))
    ));
    let opts = FreqOptions {
        n: 1,
        refine: true,
        ..FreqOptions::default()
    };
    assert!(matches!(
        fit_bode(&omega, &h, &opts),
        Err(Error::Options(_))
    ));
    for order in [
        OrderChoice::Fixed(0.0),
        OrderChoice::Fixed(f64::NAN),
        OrderChoice::Fixed(2.5),
        OrderChoice::Search {
            step: 0.0,
            q_max: 1.0,
            refine: true,
        },
        OrderChoice::Search {
            step: 0.01,
            q_max: 3.0,
            refine: true,
        },
    ] {
        let opts = FreqOptions {
            order,
            ..FreqOptions::default()
        };
        assert!(matches!(
            fit_bode(&omega, &h, &opts),
            Err(Error::Options(_))
        ));
    }
    assert!(matches!(
        levy_fixed_q(&omega, &h, 0.5, 0, 2, &[1.0; 3], 0),
        Err(Error::Data(_))
    ));
}

#[test]
fn bad_weights() {
    let (omega, h) = data();
    for w in [
        vec![1.0; 4],
        vec![1.0, -1.0, 1.0, 1.0, 1.0],
        vec![0.0; 5],
        vec![f64::NAN; 5],
    ] {
        let opts = FreqOptions {
            weights: Weights::PerPoint(w),
            ..FreqOptions::default()
        };
        assert!(matches!(fit_bode(&omega, &h, &opts), Err(Error::Data(_))));
    }
}
