//! A battery cell's voltage per current: `R0 + 1/(C s) + R1/((tau s)^q + 1)` (an ohmic drop, the
//! charge the capacity integrates, a constant-phase polarisation), the structure
//! `ident::oe::FracModel::cell` (`D + Ki/s + K/(a1 s^q + 1)`).
//!
//! The truth is independent of the identifier's simulator: `R0 u_k` and the integral of the held
//! input `dt sum_(j<k) u_j / C` exactly, the polarisation as the sum of its Mittag-Leffler step
//! responses from the input's changes (no rational approximation). The current: a PRBS of order
//! 7 with a 1 s clock, 10 A about a 2 A discharge (the voltage drifts down as the charge goes),
//! at `dt = 0.1 s`; seeded Gaussian noise of 1 mV.

use fracsim::prbs::Prbs;
use fracsim::special::mittag_leffler;
use ident::catalogue::Preset;
use ident::data::Record;
use ident::diagnose::structures::{diagnose_best, with_feedthrough};
use ident::diagnose::DiagnoseOptions;
use ident::oe::{identify, IdentOptions};

const DT: f64 = 0.1;
const SIGMA: f64 = 1e-3;
const R0: f64 = 0.05;
const INV_C: f64 = 5e-4;
const R1: f64 = 0.03;
const TAU: f64 = 5.0;
const Q: f64 = 0.6;

/// The polarisation `R1/((tau s)^q + 1)` of the held input `u` at the samples: the sum of its
/// step response `R1 (1 - E_q(-(t/tau)^q))` (Mittag-Leffler) from each change of `u`.
fn polarisation(u: &[f64]) -> Vec<f64> {
    let mut changes = vec![];
    let mut prev = 0.0;
    for (j, &v) in u.iter().enumerate() {
        if v != prev {
            changes.push((j, v - prev));
            prev = v;
        }
    }
    (0..u.len())
        .map(|k| {
            changes
                .iter()
                .filter(|&&(j, _)| j < k)
                .map(|&(j, du)| {
                    let t = (k - j) as f64 * DT;
                    du * R1 * (1.0 - mittag_leffler(Q, -(t / TAU).powf(Q)))
                })
                .sum()
        })
        .collect()
}

/// The record: the current and the noisy voltage deviation.
fn record(seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = Prbs {
        order: 7,
        clock: 1.0,
        amplitude: 10.0,
        offset: 2.0,
        periods: 1,
        seed: 3,
    }
    .signal(DT)
    .unwrap();
    let yp = polarisation(&u);
    let mut charge = 0.0;
    let clean: Vec<f64> = u
        .iter()
        .zip(&yp)
        .map(|(&uk, &pk)| {
            let v = R0 * uk + INV_C * charge + pk;
            charge += uk * DT;
            v
        })
        .collect();
    let e = super::truth::noise(u.len(), SIGMA, seed);
    let y = clean.iter().zip(e).map(|(a, b)| a + b).collect();
    (u, y)
}

/// The cell structure fitted with its automatic start finds the circuit: `R0`, `1/C` and `R1`
/// within 5%, 10% and 20%, the order within 0.1, `tau` within a factor 1.5, and predicts the
/// held-out part to the noise (within 10%); the feed-through structure (no integrator) cannot.
#[test]
fn the_cell_structure_finds_the_circuit() {
    let (u, y) = record(11);
    let rec = Record::from_samples(&u, &y, DT).unwrap();
    let opts = IdentOptions::default();
    let id = identify(&rec, &Preset::Cell.model(1.0), &opts).unwrap();
    let v = |name: &str| id.model.params[id.model.index_of(name).unwrap()].value;
    let (d, ki, k, a1, q) = (v("D"), v("Ki"), v("K"), v("a1"), v("q"));
    let tau = a1.powf(1.0 / q);
    eprintln!("{}\nD {d} Ki {ki} K {k} q {q} tau {tau}", id.tf);
    assert!((d / R0 - 1.0).abs() < 0.05, "D = {d}");
    assert!((ki / INV_C - 1.0).abs() < 0.10, "Ki = {ki}");
    assert!((k / R1 - 1.0).abs() < 0.20, "K = {k}");
    assert!((q - Q).abs() < 0.1, "q = {q}");
    assert!(tau / TAU < 1.5 && TAU / tau < 1.5, "tau = {tau}");
    let held = id.validation.unwrap().rmse;
    assert!(held < 1.1 * SIGMA, "held-out RMSE {held}");
    let ft = identify(&rec, &Preset::Feedthrough.model(1.0), &opts).unwrap();
    let ft_held = ft.validation.unwrap().rmse;
    assert!(
        ft_held > 2.0 * held,
        "feed-through {ft_held} against {held}"
    );
}

/// The record shows an instant response, so the comparison fits the feed-through and the cell
/// beside the catalogue's structures, and the diagnosis with defaults (from the PMSM, as
/// `fracid time FILE`) ends on the cell with no effect.
#[test]
fn the_diagnosis_chooses_the_cell() {
    let (u, y) = record(12);
    let rec = Record::from_samples(&u, &y, DT).unwrap();
    let (model, _) = ident::app::structure("pmsm", 0.2).unwrap();
    let cands = ident::diagnose::structures::candidates("pmsm", &model);
    let n = cands.len();
    let with = with_feedthrough(&rec, cands, &model);
    let names: Vec<&str> = with[n..].iter().map(|(s, _)| s.as_str()).collect();
    assert_eq!(names, ["feedthrough", "cell"]);
    let opts = IdentOptions::default();
    let id = identify(&rec, &model, &opts).unwrap();
    let d = diagnose_best(&rec, "pmsm", &model, id, &opts, &DiagnoseOptions::default()).unwrap();
    let chosen = &d.choice.scores[d.choice.chosen];
    assert_eq!(chosen.name, "cell", "{}", d.choice.reason);
    assert!(d.diagnosis.effects.is_empty(), "{:?}", d.diagnosis.effects);
    let rmse = chosen.rmse_after.unwrap();
    assert!(rmse < 1.1 * SIGMA, "held-out RMSE {rmse}");
}
