//! The fit and the diagnosis on a held, switching input at a realistic sampling step, against an
//! independent truth ([`super::truth`], Grunwald-Letnikov with the input held, Richardson of dt/10
//! and dt/20): the paper's PMSM `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)` at 0.5 ms. Input: the paper's PRBS (order 7,
//! 3 ms clock) of +-3 V, three periods (2286 samples); seeded white noise sigma = 0.1 on a swing of
//! about 40.

use super::truth::{noise, response, Plant, PMSM};
use fracsim::prbs::Prbs;
use fracsim::FracTf;
use ident::data::{OffsetMode, Record};
use ident::diagnose::{diagnose, DiagnoseOptions};
use ident::oe::{identify, FracModel, IdentOptions};

const DT: f64 = 5e-4;
const SIGMA: f64 = 0.1;
/// (K, a1, a2, zeta, theta)
const TRUTH: (f64, f64, f64, f64, f64) = (6.82, 0.0059, 2.655e-5, 0.92, 1.7452 - 0.92);

fn input() -> Vec<f64> {
    Prbs {
        periods: 3,
        amplitude: 3.0,
        ..Prbs::paper()
    }
    .signal(DT)
    .unwrap()
}

/// The record with the hidden delay and its noise realisation.
fn record(delay_s: f64, seed: u64) -> (Record, Vec<f64>) {
    let u = input();
    let plant = Plant { delay_s, ..PMSM };
    let noise = noise(u.len(), SIGMA, seed);
    let y: Vec<f64> = response(&plant, &u, DT)
        .iter()
        .zip(&noise)
        .map(|(y, e)| y + e)
        .collect();
    (Record::from_samples(&u, &y, DT).unwrap(), noise)
}

fn clean() -> &'static (Record, Vec<f64>) {
    static REC: std::sync::OnceLock<(Record, Vec<f64>)> = std::sync::OnceLock::new();
    REC.get_or_init(|| record(0.0, 11))
}

fn options() -> IdentOptions {
    IdentOptions {
        offsets: OffsetMode::None,
        ..IdentOptions::default()
    }
}

#[test]
fn fit_reaches_the_noise_floor_with_orders_within_three_standard_errors() {
    let (rec, noise) = clean();
    let (k, a1, a2, z, th) = TRUTH;
    let id = identify(rec, &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9), &options()).unwrap();
    let val = id.validation.unwrap();
    // The floor a perfect model reaches on this window: the RMS of the noise realisation there
    // (the RMSE of pure noise over 686 samples scatters by 1/sqrt(2N) = 2.7% around sigma).
    let w = &noise[id.split..];
    let floor = (w.iter().map(|e| e * e).sum::<f64>() / w.len() as f64).sqrt();
    let p = &id.report.params;
    eprintln!(
        "validation RMSE {:.4} (noise RMS there {floor:.4}, sigma {SIGMA}); {}",
        val.rmse,
        p.iter()
            .map(|q| format!(
                "{} {:.5e} +- {:.1e}",
                q.name,
                q.value,
                q.std_error.unwrap_or(f64::NAN)
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    assert!(val.rmse <= 1.02 * floor, "{} vs floor {floor}", val.rmse);
    for (i, truth) in [(0, k), (1, a1), (2, a2), (3, z), (4, th)] {
        let (v, se) = (p[i].value, p[i].std_error.unwrap());
        let zscore = (v - truth) / se;
        eprintln!(
            "{}: {v:.5e} truth {truth:.5e}, {zscore:+.2} standard errors",
            p[i].name
        );
        assert!(
            zscore.abs() <= 3.0,
            "{} off by {zscore} standard errors",
            p[i].name
        );
    }
    // Frequency-response error of the fitted model against the truth, up to 200 Hz.
    let truth = FracTf::pmsm(k, a1, a2, z, th).unwrap();
    let worst = (0..200)
        .map(|i| {
            let w = 2.0 * std::f64::consts::PI * 0.1 * (2000f64).powf(i as f64 / 199.0);
            let (a, b) = (id.tf.freq_response(w), truth.freq_response(w));
            (a - b).norm() / b.norm()
        })
        .fold(0.0, f64::max);
    eprintln!("worst relative frequency-response error over 0.1..200 Hz: {worst:.2e}");
    assert!(worst < 0.01, "{worst}");
}

#[test]
fn diagnosis_adds_nothing_to_a_clean_record_and_only_the_delay_to_a_delayed_one() {
    let model = FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9);
    let (rec, _) = clean();
    let id = identify(rec, &model, &options()).unwrap();
    let d = diagnose(rec, &id, &DiagnoseOptions::default()).unwrap();
    let names: Vec<&str> = d.effects.iter().map(|e| e.name.as_str()).collect();
    eprintln!("clean: kept {names:?}, rejected {:?}", d.rejected);
    assert!(names.is_empty(), "clean record: {names:?}");

    let tau = 2e-3;
    let (rec, _) = record(tau, 12);
    let id = identify(&rec, &model, &options()).unwrap();
    let d = diagnose(&rec, &id, &DiagnoseOptions::default()).unwrap();
    let names: Vec<&str> = d.effects.iter().map(|e| e.name.as_str()).collect();
    eprintln!(
        "delayed: kept {:?}, validation RMSE {:?} -> {:?}",
        d.effects, d.before, d.after
    );
    assert_eq!(names, ["delay"]);
    let est = d.effects[0].params["tau"];
    assert!((est / tau - 1.0).abs() <= 0.1, "tau {est}");
}
