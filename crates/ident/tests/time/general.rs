//! The general structure sized by the data (`ident::diagnose::general`) against independent truth:
//! records of integer-order plants simulated exactly here (a state-space realisation discretised
//! for the held input by its own matrix exponential, no code shared with fracsim), each
//! recovered with a frequency-response error of at most 5% over the excited band.

use crate::exact::{random_binary, simulate, Lcg};
use ident::data::Record;
use ident::diagnose::general::{self, GeneralRequest};
use ident::oe::IdentOptions;
use num_complex::Complex64;

/// `G(j w)` of the polynomial ratio.
fn response(b: &[f64], a: &[f64], w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    let p = |c: &[f64]| {
        c.iter()
            .rev()
            .fold(Complex64::new(0.0, 0.0), |acc, &v| acc * s + v)
    };
    p(b) / p(a)
}

/// A random binary sequence (seeded), switching with probability `1/hold` each sample, plus
/// Gaussian-free uniform output noise of `noise` (relative to the output's standard deviation).
fn record(b: &[f64], a: &[f64], n: usize, dt: f64, hold: u64, noise: f64, seed: u64) -> Record {
    let mut rng = Lcg(seed);
    let u = random_binary(&mut rng, n, 1.0 / hold as f64);
    let y = with_noise(&simulate(b, a, &u, dt), noise, &mut rng);
    Record::from_samples(&u, &y, dt).unwrap()
}

/// `y0` plus uniform noise of `noise` times its standard deviation, drawn from `rng`.
fn with_noise(y0: &[f64], noise: f64, rng: &mut Lcg) -> Vec<f64> {
    let n = y0.len() as f64;
    let mean = y0.iter().sum::<f64>() / n;
    let sd = (y0.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    y0.iter()
        .map(|v| v + noise * sd * 3f64.sqrt() * (2.0 * rng.uniform() - 1.0))
        .collect()
}

/// The relative frequency-response error `sqrt(sum |G - Ghat|^2 / sum |G|^2)` over 60
/// log-spaced frequencies of `[w_lo, w_hi]`.
fn frf_error(b: &[f64], a: &[f64], fit: &fracsim::FracTf, w_lo: f64, w_hi: f64) -> f64 {
    let (mut e, mut t) = (0.0, 0.0);
    for i in 0..60 {
        let w = w_lo * (w_hi / w_lo).powf(i as f64 / 59.0);
        let g = response(b, a, w);
        e += (g - fit.freq_response(w)).norm_sqr();
        t += g.norm_sqr();
    }
    (e / t).sqrt()
}

/// The band a record of `n` samples of `dt` excites and the fit can see: from ten periods over
/// the record to a quarter of the Nyquist frequency.
fn band(n: usize, dt: f64) -> (f64, f64) {
    let lo = 2.0 * std::f64::consts::PI * 10.0 / (n as f64 * dt);
    (lo, 0.25 * std::f64::consts::PI / dt)
}

fn fitted(rec: &Record, req: &GeneralRequest) -> general::GeneralFit {
    let f = general::fit(
        rec,
        &general::template(),
        &IdentOptions::default(),
        (req, general::search::Then::Trimmed),
    )
    .unwrap();
    eprintln!("{}\n{:#?}", f.choice.reason, f.choice.scores);
    f
}

/// The validation-record check: the chosen fit predicts the held-out part near the noise.
fn held_out_percent(f: &general::GeneralFit) -> f64 {
    f.id.validation.unwrap().nrmse_percent
}

/// A resonance measured at the load (no anti-resonance), `z = 0.05`:
/// `2/((0.02 s + 1)(s^2/w^2 + 2 z s/w + 1))`, `w = 2 pi 40`.
#[test]
fn a_resonance_at_the_load_is_recovered() {
    let w = 2.0 * std::f64::consts::PI * 40.0;
    let z = 0.05;
    // (0.02 s + 1)(s^2/w^2 + 2z s/w + 1), ascending powers
    let (c2, c1) = (1.0 / (w * w), 2.0 * z / w);
    let a = [1.0, c1 + 0.02, c2 + 0.02 * c1, 0.02 * c2];
    let b = [2.0];
    let (n, dt) = (20_000, 1e-3);
    let rec = record(&b, &a, n, dt, 3, 0.01, 7);
    let f = fitted(&rec, &GeneralRequest::default());
    let (lo, hi) = band(n, dt);
    let e = frf_error(&b, &a, &f.id.tf, lo, hi);
    eprintln!("{} -> {} FRF error {e:.4}", f.name, f.id.tf);
    assert!(e <= 0.05, "FRF error {e}: {}", f.id.tf);
    assert!(f.id.usable(), "{:?}", f.id.problems);
    assert!(held_out_percent(&f) > 95.0, "{}", held_out_percent(&f));
}

/// A lead whose zero nearly cancels its slower pole (the zoo's lead case 0183, seed 44):
/// `(2.2344 s + 11.941)/(0.0018071 s^2 + 0.16613 s + 1)` under a random binary input switching
/// every few samples, which excites it up to the Nyquist frequency. The sizes the
/// frequency-domain criterion shortlists may all be larger than the plant's; the chosen one is
/// trimmed back to the plant's size, and its response holds up to 80% of the Nyquist frequency
/// (a fourth order with a mode there was chosen before, at 58% error over the zoo's band).
#[test]
fn a_lead_is_trimmed_to_its_own_size() {
    let b = [11.940820098840119, 2.234364791521463];
    let a = [1.0, 0.16613470994653742, 0.001807056879409209];
    let (n, dt) = (2531, 0.0029943487366425707);
    let rec = record(&b, &a, n, dt, 2, 0.001, 5);
    let f = fitted(&rec, &GeneralRequest::default());
    let (lo, _) = band(n, dt);
    let e = frf_error(&b, &a, &f.id.tf, lo, 0.8 * std::f64::consts::PI / dt);
    eprintln!("{} -> {} FRF error {e:.4}", f.name, f.id.tf);
    assert!(f.name.starts_with("general 1/2"), "{}", f.name);
    assert!(e <= 0.05, "FRF error {e}: {}", f.id.tf);
}

/// A feed-through beside an integrator (a cell's ohmic drop and its charge): `0.5 + 20/s`.
#[test]
fn a_feedthrough_beside_an_integrator_is_recovered() {
    // (0.5 s + 20)/s, simulated as (0.5 s + 20)/(s + 1e-9)... no: exactly, with a0 = 0
    let b = [20.0, 0.5];
    let a = [0.0, 1.0];
    let (n, dt) = (6000, 1e-2);
    let rec = record(&b, &a, n, dt, 20, 0.01, 11);
    let f = fitted(&rec, &GeneralRequest::default());
    let (lo, hi) = band(n, dt);
    let e = frf_error(&b, &a, &f.id.tf, lo, hi);
    eprintln!("{} -> {} FRF error {e:.4}", f.name, f.id.tf);
    assert!(f.id.model.integrator, "{}", f.name);
    assert!(e <= 0.05, "FRF error {e}: {}", f.id.tf);
}

/// A non-minimum-phase zero: `3 (1 - s/30)/((s/10 + 1)(s/100 + 1))`.
#[test]
fn a_non_minimum_phase_zero_is_recovered() {
    let b = [3.0, -0.1];
    let a = [1.0, 0.1 + 0.01, 0.001];
    let (n, dt) = (10_000, 2e-3);
    let rec = record(&b, &a, n, dt, 4, 0.01, 3);
    let f = fitted(&rec, &GeneralRequest::default());
    let (lo, hi) = band(n, dt);
    let e = frf_error(&b, &a, &f.id.tf, lo, hi);
    eprintln!("{} -> {} FRF error {e:.4}", f.name, f.id.tf);
    assert!(e <= 0.05, "FRF error {e}: {}", f.id.tf);
    // the zero in the right half-plane: the high-frequency gain has the opposite sign
    let hf = f.id.tf.freq_response(hi);
    assert!(hf.re < 0.0 || hf.im.abs() > hf.re.abs(), "{hf}");
}

/// A fixed size is fitted as asked: `general:0/3` on the resonance.
#[test]
fn a_fixed_size_is_the_size_fitted() {
    let w = 2.0 * std::f64::consts::PI * 40.0;
    let (c2, c1) = (1.0 / (w * w), 0.1 / w);
    let a = [1.0, c1 + 0.02, c2 + 0.02 * c1, 0.02 * c2];
    let rec = record(&[2.0], &a, 8000, 1e-3, 3, 0.01, 5);
    let req = general::requested("general:0/3").unwrap().unwrap();
    let f = fitted(&rec, &req);
    assert!(f
        .choice
        .scores
        .iter()
        .all(|s| s.name.starts_with("general 0/3")));
    assert_eq!(f.id.tf.den.len(), 4, "{}", f.id.tf);
}

/// A position through a free integrator, `2/(s (0.05 s + 1))`, on a PRBS after a rest, with
/// `offset` added to the input the plant sees (not to the one recorded), diagnosed with
/// `--structure first-order --integrator`: the final model's effects and its `u_offset`.
fn integrator_effects(offset: f64) -> (Vec<String>, f64) {
    use ident::app::observe::Quiet;
    use ident::app::request::{Preset, Structure};
    use ident::app::time::{run, TimeData, TimeRequest};
    let (b, a) = ([2.0], [0.0, 1.0, 0.05]);
    let (rest, n, dt) = (200, 4000, 1e-2);
    let mut rng = Lcg(23);
    let mut u = vec![0.0; rest];
    u.extend(random_binary(&mut rng, n - rest, 1.0 / 15.0));
    let seen: Vec<f64> = u.iter().map(|v| v + offset).collect();
    let y = with_noise(&simulate(&b, &a, &seen, dt), 0.01, &mut rng);
    let data = TimeData {
        record: Record::from_samples(&u, &y, dt).unwrap(),
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    let req = TimeRequest {
        plain: false,
        integrator: true,
        structure: Structure::Named(Preset::FirstOrder),
        ..Default::default()
    };
    let r = run(&req, &data, &mut Quiet).unwrap();
    let u_offset = r
        .lead
        .params
        .iter()
        .find(|p| p.name == "u_offset")
        .map_or(f64::NAN, |p| p.value);
    eprintln!(
        "offset {offset}: effects {:?}, u_offset {u_offset}, {:?}; {}; {:?}",
        r.lead.model.effects,
        r.lead.params,
        r.model_is,
        r.diagnosis.as_ref().map(|d| &d.structures.reason)
    );
    (r.lead.model.effects.clone(), u_offset)
}

/// The integrator's own input offset is fitted whatever the record; the final model names
/// `input_offset` among its effects when the data show it: a plant that sees 0.05 more than the
/// recorded input (a drift of 4 over the 40 s record, the noise 0.01 of the output's spread),
/// with the offset found. (A record with none is not described by an integrator with its offset:
/// the comparison chooses the second order, a lag slow enough to integrate, with fewer
/// parameters; the rule's other side is the unit test `an_integrators_offset_is_named_when_its_drift_stands_out`.)
#[test]
fn an_integrators_input_offset_is_named_when_the_data_show_it() {
    let (some, found) = integrator_effects(0.05);
    assert!(some.iter().any(|e| e == "input_offset"), "{some:?}");
    assert!((found - 0.05).abs() < 0.005, "u_offset {found}");
}
