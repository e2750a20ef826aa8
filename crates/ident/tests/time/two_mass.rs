//! A two-mass drive train (issue 29): the paper's motor `6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)`
//! driving a load of equal inertia through a compliant coupling with fractional (viscoelastic)
//! damping, which multiplies the rigid drive by
//! `R(s) = (s^2/w_a^2 + d s^0.7 + 1)/(s^2/w_r^2 + d s^0.7 + 1)`, `w_r = 2 pi 40 rad/s`,
//! `w_a = w_r/sqrt(2)` (equal inertias), `d = 2.34e-3` (damping ratio 0.05 at the resonance:
//! `d w_r^0.7 sin(0.35 pi) = 2 x 0.05`).
//!
//! The truth is independent of the identifier's simulator: Grunwald-Letnikov with the input held
//! (`fracsim::gl::simulate_held`, two Richardson levels extrapolated once more; no rational
//! approximation). PRBS of order 9 with a 2 ms clock, four periods at `dt = 1 ms`, seeded noise of
//! standard deviation 0.13 (the paper's PMSM tests' noise; the output's own is about 9.6).

use fracsim::prbs::Prbs;
use fracsim::FracTf;
use ident::data::Record;
use ident::diagnose::structures::{diagnose_best, Diagnosed};
use ident::diagnose::DiagnoseOptions;
use ident::oe::{identify, FracModel, IdentOptions};
use num_complex::Complex64;
use std::f64::consts::PI;

const DT: f64 = 1e-3;
const SIGMA: f64 = 0.13;

/// The truth's text (the model language multiplies it out).
pub const TRUTH: &str = "6.77*(3.1663e-5 s^2 + 2.34e-3 s^0.7 + 1)/((0.000028 s^1.78 + 0.0064 s^0.89 + 1)*(1.5831e-5 s^2 + 2.34e-3 s^0.7 + 1))";

/// The record (input, noisy output).
pub fn record(seed: u64) -> (Vec<f64>, Vec<f64>) {
    let p = Prbs {
        order: 9,
        clock: 0.002,
        amplitude: 1.0,
        offset: 0.0,
        periods: 4,
        seed: 1,
    };
    let u = p.signal(DT).unwrap();
    let y = output(&u, seed);
    (u, y)
}

/// The truth's noisy output on `u` (the noise seeded by `seed`).
fn output(u: &[f64], seed: u64) -> Vec<f64> {
    let truth: FracTf = TRUTH.parse().unwrap();
    // Two Richardson levels (dt/10 with dt/20, dt/20 with dt/40), extrapolated once more: the
    // lightly damped resonance needs it (the levels differ by 1.6e-3 of the swing, fracsim's
    // test of the same model).
    let y = fracsim::gl::simulate_held_twice(&truth, u, DT, 10).unwrap();
    let e = super::truth::noise(u.len(), SIGMA, seed);
    y.iter().zip(e).map(|(a, n)| a + n).collect()
}

/// The largest relative error of `tf`'s frequency response against the truth's over
/// `f_lo..f_hi` Hz (200 log-spaced points).
pub fn frf_error(tf: &FracTf, f_lo: f64, f_hi: f64) -> f64 {
    let truth: FracTf = TRUTH.parse().unwrap();
    (0..200)
        .map(|i| {
            let f = f_lo * (f_hi / f_lo).powf(i as f64 / 199.0);
            let w = 2.0 * PI * f;
            let g = truth.freq_response(w);
            let h: Complex64 = tf.freq_response(w);
            (h - g).norm() / g.norm()
        })
        .fold(0.0, f64::max)
}

/// Where the truth's resonance peak is (Hz): about 41 Hz, the viscoelastic damping stiffens the
/// coupling a little.
#[test]
fn the_truth_resonates_near_40_hz() {
    let truth: FracTf = TRUTH.parse().unwrap();
    let (mut best, mut at) = (0.0, 0.0);
    for i in 0..2000 {
        let f = 20.0 + i as f64 * 0.02;
        let m = truth.freq_response(2.0 * PI * f).norm();
        if m > best {
            (best, at) = (m, f);
        }
    }
    assert!((39.0..43.0).contains(&at), "peak at {at} Hz");
    // Ten times the rigid drive's response there (1/(2 zeta) for equal inertias).
    let motor = FracTf::pmsm(6.77, 0.0064, 0.000028, 0.89, 0.89).unwrap();
    let ratio = best / motor.freq_response(2.0 * PI * at).norm();
    assert!((8.0..12.0).contains(&ratio), "{ratio}");
}

/// The diagnosis with defaults, from the default structure (the PMSM), chooses the two-mass
/// structure, keeps no effect (the resonance's phase lag is not a delay), and its model's
/// frequency response is within 5% of the truth's from 1 Hz to twice the resonance (measured: 0.25%,
/// held-out RMSE 0.130 against noise 0.13, the best integer-order model 8.30).
/// The diagnosis with defaults (the paper's structure named, structures compared) on `rec`: it
/// must choose the two-mass structure and keep no effect. Returns the diagnosis, its model and
/// that model's frequency-response error over 1-80 Hz ([`frf_error`]).
fn diagnosed_as_two_mass(rec: &Record) -> (Diagnosed, FracTf, f64) {
    let opts = IdentOptions::default();
    let (model, _) = ident::app::structure("pmsm", 0.2).unwrap();
    let id = identify(rec, &model, &opts).unwrap();
    let t0 = std::time::Instant::now();
    let d = diagnose_best(rec, "pmsm", &model, id, &opts, &DiagnoseOptions::default()).unwrap();
    eprintln!(
        "{:.1} s; structures {:#?}\nkept {:?}\nrejected {:#?}\nfinal {}",
        t0.elapsed().as_secs_f64(),
        d.choice,
        d.diagnosis.effects,
        d.diagnosis.rejected,
        d.diagnosis.final_model
    );
    let chosen = &d.choice.scores[d.choice.chosen];
    assert_eq!(chosen.name, "two-mass", "{}", d.choice.reason);
    assert!(d.diagnosis.effects.is_empty(), "{:?}", d.diagnosis.effects);
    let tf = d.diagnosis.model.tf(&d.diagnosis.model.values()).unwrap();
    let err = frf_error(&tf, 1.0, 80.0);
    (d, tf, err)
}

#[test]
fn the_diagnosis_holds_the_resonance_of_a_two_mass_drive_train() {
    let (u, y) = record(11);
    let rec = Record::from_samples(&u, &y, DT).unwrap();
    let (d, tf, err) = diagnosed_as_two_mass(&rec);
    eprintln!("two-mass: {tf}; FRF error 1-80 Hz {err:.4}");
    assert!(err <= 0.05, "frequency-response error {err}");
    assert!(d
        .choice
        .reason
        .contains("against the best usable integer-order model"));
    let r = d
        .choice
        .integer_reference
        .as_ref()
        .expect("an integer reference");
    let row = d.choice.scores.iter().find(|s| s.name == r.name).unwrap();
    assert!(row.problems.is_empty() && row.failed.is_none(), "{row:?}");
}

/// Without a periodic input: the same drive train driven by a PRBS that is not repeated (the
/// first 4088 samples of one period of an order-12 sequence, 8190 samples long, 2 ms clock), so
/// the two-mass start comes from Welch's estimate of the response. The diagnosis with defaults
/// still chooses the two-mass structure, keeps no effect, and its model's response is within 5%
/// of the truth's from 1 Hz to twice the resonance (measured: see the note printed).
#[test]
fn the_diagnosis_holds_the_resonance_without_a_periodic_input() {
    let mut u = Prbs {
        order: 12,
        clock: 0.002,
        amplitude: 1.0,
        offset: 0.0,
        periods: 1,
        seed: 1,
    }
    .signal(DT)
    .unwrap();
    u.truncate(4088);
    assert_eq!(ident::oe::init::periodic_part(&u), None);
    let y = output(&u, 11);
    let rec = Record::from_samples(&u, &y, DT).unwrap();
    let (_, tf, err) = diagnosed_as_two_mass(&rec);
    eprintln!("two-mass (aperiodic input): {tf}; FRF error 1-80 Hz {err:.4}");
    assert!(err <= 0.05, "frequency-response error {err}");
}

/// The two-mass structure is simulated factor by factor (motor times pair); with integer orders
/// its product multiplied out is simulated directly too (no fractional cells, one small eigenvalue
/// problem), and the two agree. Its coefficients that are products of parameters carry the
/// units of their linear part: `K` scales as output over input, the pair's `b2`, `c2`, `d` not.
#[test]
fn the_two_mass_model_is_its_product_multiplied_out() {
    use ident::oe::Structure;
    let m = FracModel::two_mass(
        [6.77, 0.0064, 2.8e-5, 1.0, 1.0],
        [3.1663e-5, 1.5831e-5, 4e-4, 1.0],
    );
    let (u, _) = (record_input(), ());
    let mut y = vec![0.0; u.len()];
    m.simulate(&m.values(), &u, DT, &mut y).unwrap();
    let tf = m.tf(&m.values()).unwrap();
    assert_eq!(tf.den.len(), 5, "{tf}"); // orders 4, 3, 2, 1, 0 after merging
    let direct = fracsim::lsim(&tf, &u, DT, &m.approx).unwrap();
    let swing = direct.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let worst = y
        .iter()
        .zip(&direct)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    // Two exact discretisations of the same rational model: rounding only.
    assert!(worst < 1e-9 * swing, "{worst} of {swing}");
    for (name, want) in [
        ("K", 2.0 / 3.0),
        ("b2", 1.0),
        ("c2", 1.0),
        ("d", 1.0),
        ("mu", 1.0),
    ] {
        let j = m.index_of(name).unwrap();
        assert_eq!(m.unit_scale(j, 3.0, 2.0), Some(want), "{name}");
    }
}

/// The record's input alone.
fn record_input() -> Vec<f64> {
    Prbs {
        order: 9,
        clock: 0.002,
        amplitude: 1.0,
        offset: 0.0,
        periods: 1,
        seed: 1,
    }
    .signal(DT)
    .unwrap()
}

/// The flexible robot arm of `data/slicot_robot_arm` (DaISy 96-009, measured: reaction torque ->
/// arm acceleration, a sine sweep, 1024 samples, t in samples; two lightly damped modes near 0.059
/// and 0.126 cycles/sample with anti-resonances, a negative gain), with the CLI's defaults and
/// `--diagnose` (`ident::app::time::run`, as `fracid time FILE --diagnose`). The two-mass start's
/// fallback (the gain's sign, the resonance peaks up to half the Nyquist frequency, placed in the
/// time domain) starts it; before, the structure could not start and the integer second order
/// with a delay was chosen at a held-out RMSE of 0.0900 (NRMSE 65.77%).
///
/// The two-mass fit itself degenerates here (session 15: 500 iterations, not converged, the
/// covariance singular: `a1 ~ 1e-43`, `K ~ -8e-5` with `b2 ~ 1.8e4`, only `K b2` determined,
/// `mu = 1.958` merging the pair's damping with its inertia): the record is an acceleration (the
/// response starts as `s^2`) of two lightly damped modes. The comparison refits it reduced
/// ([`ident::diagnose::structures::reduced_two_mass`]): `g s/(a2 s^nu + 1) * s/(c s^lambda + 1)`,
/// which converges with every parameter determined.
///
/// Measured (2026-11-26): `two-mass (reduced)` chosen, no effect, held-out RMSE 0.05184 (the
/// degenerate fit's 0.05180), converged, 5 structural parameters each with a standard error
/// (`g = -1.459 +- 0.049`, `nu = 1.8543 +- 0.004`, `lambda = 1.9940 +- 0.0001`), BIC -4200.3
/// against the degenerate fit's -4172.3. Since session 17 the diagnosis reduces the two-mass
/// screening fit (60 iterations, already degenerate) at once, without the 500-iteration fit
/// (`structures::reduce_screened`): the same structure, held-out RMSE 0.05179, BIC -4198.9,
/// `g = -1.460 +- 0.049`, `nu = 1.8549 +- 0.004`, `lambda = 1.9940 +- 0.0001`. Bounds: the RMSE at most 0.060 (16% above the measured
/// one: a change of the LM path or the approximation moves the end point a little) and at most
/// 0.8 times the old choice's 0.0900: the gain that must hold is the resonant structure's, clearly
/// better than the integer second order with a delay; and the base fit converged with every
/// free parameter (but a past-input level at its bound) determined.
///
/// Since the diagnosis compares the general structure when the named ones fit poorly
/// (`ident::diagnose::general::hook`: the two-mass's residual is not white), the general
/// structure's `general 4/4` (two modes with their anti-resonances, free damping each) is
/// returned: held-out RMSE 0.01228 (measured 2026-12-05), a quarter of the reduced two-mass's
/// 0.0518, which stays in the comparison. Bound: 0.015 (22% above).
#[test]
fn the_flexible_robot_arm_is_diagnosed_as_a_resonant_drive_train() {
    use ident::app::observe::Quiet;
    use ident::app::time::{run, TimeData, TimeRequest};
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/slicot_robot_arm/robot_arm.csv");
    let loaded = Record::load(&path, &ident::data::ReadOptions::default()).expect("the arm record");
    assert_eq!(loaded.record.len(), 1024);
    let data = TimeData {
        record: loaded.record,
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    let req = TimeRequest {
        plain: false,
        ..Default::default()
    };
    let r = run(&req, &data, &mut Quiet).unwrap();
    let d = r.diagnosis.as_ref().expect("a diagnosis");
    let chosen = &d.structures.scores[d.structures.chosen];
    eprintln!(
        "arm: {}; start {}; held out {:?}",
        d.structures.reason, r.start.note, r.lead.fit.validation
    );
    assert!(
        chosen.name.starts_with("general "),
        "{}",
        d.structures.reason
    );
    let two_mass = d
        .structures
        .scores
        .iter()
        .find(|s| s.name.starts_with("two-mass"))
        .expect("the two-mass row");
    assert!(
        two_mass.rmse_after.is_some_and(|r| r <= 0.060),
        "{:?}",
        two_mass
    );
    assert!(
        r.converged,
        "the chosen base fit did not converge: {}",
        r.stop_reason
    );
    let base = r.base.as_ref().expect("the base fit");
    assert!(base.usable, "{:?}", base.problems);
    for p in base.params.iter().filter(|p| p.free && !p.at_bound) {
        let se = p.std_error.unwrap_or(f64::NAN);
        assert!(
            se.is_finite() && se < 10.0 * p.value.abs(),
            "{} = {} +- {se}: not determined",
            p.name,
            p.value
        );
    }
    let held = r.lead.fit.validation.expect("a held-out part");
    assert!(held.rmse <= 0.015, "held-out RMSE {}", held.rmse);
}

/// `--structure auto` (without the diagnosis) on the robot arm makes the degenerate two-mass fit
/// well posed as the diagnosis does: its screening fit (60 iterations, already degenerate) is
/// refitted at once as the smallest reduced structure (`structures::reduce_screened`), not fitted
/// for its 500 iterations first (session 18: the whole run 0.71 -> 0.21 s CPU). Measured
/// (2026-11-26): `two-mass (reduced)` chosen at the held-out RMSE 0.051793, the diagnosis's own
/// (before: 0.051839 from the full fit's limit). The reduced refit is the diagnosis's refit (the
/// same screening fit, the same refit on a fresh thread), so the two choices agree to rounding
/// (1e-9 relative); the words say the screening fit was reduced (the full fit's reduction says
/// what collapsed, without "refitted at once").
#[test]
fn auto_reduces_the_arms_degenerate_two_mass_screening_fit_at_once() {
    use ident::app::observe::Quiet;
    use ident::app::time::{run, TimeData, TimeRequest};
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/slicot_robot_arm/robot_arm.csv");
    let loaded = Record::load(&path, &ident::data::ReadOptions::default()).expect("the arm record");
    let data = TimeData {
        record: loaded.record,
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    let auto = TimeRequest {
        structure: ident::app::Structure::Auto,
        plain: true,
        ..Default::default()
    };
    let r = run(&auto, &data, &mut Quiet).unwrap();
    let c = r.structures.as_ref().expect("the comparison");
    let chosen = &c.scores[c.chosen];
    assert_eq!(chosen.name, "two-mass (reduced)", "{}", c.reason);
    assert!(c.reason.contains("refitted at once"), "{}", c.reason);
    let held = r.lead.fit.validation.expect("a held-out part").rmse;
    let diagnosed = run(
        &TimeRequest {
            plain: false,
            ..auto.clone()
        },
        &data,
        &mut Quiet,
    )
    .unwrap();
    let d = diagnosed.diagnosis.as_ref().expect("a diagnosis");
    // The diagnosis compares the same named structures (and may then prefer the general one,
    // compared when the named ones fit poorly): its row of auto's choice is auto's fit.
    let row = d
        .structures
        .scores
        .iter()
        .find(|s| s.name == chosen.name)
        .unwrap_or_else(|| panic!("no {} row in the diagnosis", chosen.name));
    let base = row.rmse.expect("the reduced two-mass base fit's RMSE");
    assert!(
        // the candidates' fits stop on the refits' stall test: the same minimum to 1e-5
        (held - base).abs() <= 1e-5 * base,
        "auto {held} against the diagnosis's base fit {base}"
    );
}
