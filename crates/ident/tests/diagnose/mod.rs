//! Residual diagnosis against hidden effects.
//!
//! The generator simulates the truth `2 / (0.004 s^1.7 + 0.1 s^0.85 + 1)` (corners near 15 and
//! 45 rad/s) with the implicit Grunwald-Letnikov scheme (fracsim::gl weights, full memory) at a
//! step four times finer than the record (GL's first-order error, about `nu w h / 2`, is then
//! 0.5% of phase at the upper corner), so the truth is independent of the Oustaloup filters the
//! fit uses. Effects are applied inside the GL recursion sample by sample (friction sees the
//! previous output), the input is held between record samples (ZOH), and seeded Gaussian noise of
//! 2% of the output's standard deviation is added. Records: 3000 samples at 2 ms (6 s).

use fracsim::prbs::Prbs;
use ident::data::{OffsetMode, Record};
use ident::diagnose::structures::{diagnose_best, Diagnosed};
use ident::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use ident::oe::{identify, FracModel, IdentOptions, Identification, InitialState};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

const DT: f64 = 2e-3;
const N: usize = 3000;
const FINE: usize = 4;
const TRUTH: (f64, f64, f64, f64) = (2.0, 0.1, 0.004, 0.85);

/// Effects hidden in the generated data (physical sizes).
#[derive(Debug, Clone, Copy, Default)]
struct Hidden {
    /// Input delay (s), a multiple of the fine step.
    delay: f64,
    /// Coulomb friction as an input voltage.
    coulomb: f64,
    /// Sensor bias.
    out_offset: f64,
    /// Output ripple (amplitude, Hz).
    sine: Option<(f64, f64)>,
    /// Output drift (output units per second, from the first sample).
    drift: f64,
    /// The sensor measures |speed|.
    abs: bool,
    /// Input clipping level.
    sat: Option<f64>,
    /// Input dead band half width.
    dz: Option<f64>,
    /// Input power law `x -> sign(x) (|x| / u_ref)^p u_ref` (exponent `p`; `u_ref` the input's
    /// largest magnitude), after the clipping and the dead band.
    power: Option<f64>,
    /// Input offset (a voltage added to the input before everything else).
    u_offset: f64,
    /// The plant's commensurate order instead of the truth's 0.85 (1.0: an integer second-order
    /// plant, at the edge of the commensurate structure's range `(0, 1)`).
    q: Option<f64>,
}

fn sgn(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// A zero-mean PRBS (order 7, 20 ms clock) `offset +- 1`, or with `levels` a multi-level PRBS
/// (each bit a seeded uniform level in `[-1, 1]`).
fn input(offset: f64, levels: bool) -> Vec<f64> {
    let p = Prbs {
        order: 7,
        clock: 0.02,
        amplitude: 1.0,
        offset,
        periods: 3,
        seed: 1,
    };
    let mut u = p.signal(DT).unwrap();
    u.truncate(N);
    if levels {
        let mut rng = rand::rngs::StdRng::seed_from_u64(99);
        for bit in u.chunks_mut(10) {
            let l = rng.gen_range(-1.0..1.0);
            for v in bit {
                *v = l;
            }
        }
    }
    u
}

/// GL truth with the hidden effects, decimated, with 2% noise.
fn generate(u: &[f64], h: Hidden, seed: u64) -> Record {
    let (k, a1, a2, q) = TRUTH;
    let q = h.q.unwrap_or(q);
    let hf = DT / FINE as f64;
    let n = u.len() * FINE;
    let c1 = fracsim::gl::weights(q, n);
    let c2 = fracsim::gl::weights(2.0 * q, n);
    let (s1, s2) = (a1 * hf.powf(-q), a2 * hf.powf(-2.0 * q));
    let wd: Vec<f64> = (0..n)
        .map(|j| s1 * c1[j] + s2 * c2[j] + if j == 0 { 1.0 } else { 0.0 })
        .collect();
    let dly = (h.delay / hf).round() as usize;
    let u_ref = u.iter().fold(0.0f64, |m, v| m.max((v + h.u_offset).abs()));
    let mut y = vec![0.0; n];
    for i in 0..n {
        // The implicit GL step at t_i uses x(t_i): a held input u_m acts on (m DT, (m+1) DT], so
        // the sample at t_i comes from one fine step earlier (else the data lead the convention
        // of the simulator, and of a drive's PWM, by one fine step).
        let mut x = if i > dly {
            u[(i - dly - 1) / FINE] + h.u_offset
        } else {
            0.0
        };
        if let Some(l) = h.sat {
            x = x.clamp(-l, l);
        }
        if let Some(w) = h.dz {
            x = if x.abs() < w { 0.0 } else { x - w * sgn(x) };
        }
        if let Some(p) = h.power {
            x = sgn(x) * u_ref * (x.abs() / u_ref).powf(p);
        }
        if i > 0 {
            x -= h.coulomb * sgn(y[i - 1]);
        }
        let mut rhs = k * x;
        for j in 1..=i {
            rhs -= wd[j] * y[i - j];
        }
        y[i] = rhs / wd[0];
    }
    let mut yc: Vec<f64> = (0..u.len())
        .map(|m| {
            let v = y[m * FINE];
            if h.abs {
                v.abs()
            } else {
                v
            }
        })
        .collect();
    let mean = yc.iter().sum::<f64>() / yc.len() as f64;
    let sd = (yc.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / yc.len() as f64).sqrt();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.02 * sd).unwrap();
    for (m, v) in yc.iter_mut().enumerate() {
        *v += h.out_offset + h.drift * m as f64 * DT + noise.sample(&mut rng);
        if let Some((a, f)) = h.sine {
            *v += a * (2.0 * std::f64::consts::PI * f * m as f64 * DT + 0.3).sin();
        }
    }
    Record::from_samples(u, &yc, DT).unwrap()
}

/// Identify the commensurate structure (automatic start) and diagnose.
fn run(rec: &Record, fit_offset: bool) -> (Identification, Diagnosis) {
    let opts = IdentOptions {
        offsets: OffsetMode::None,
        fit_offset,
        ..IdentOptions::default()
    };
    let t0 = std::time::Instant::now();
    let id = identify(rec, &FracModel::commensurate(1.0, 0.05, 1e-3, 0.8), &opts).unwrap();
    let d = diagnose(rec, &id, &DiagnoseOptions::default()).unwrap();
    eprintln!(
        "base {:?} | before {:?} after {:?} | kept {:#?} | rejected {:#?} | ambiguous {:?} | remaining {:?} | {:?}",
        id.report.values,
        d.before,
        d.after,
        d.effects,
        d.rejected,
        d.ambiguous,
        d.remaining,
        t0.elapsed()
    );
    (id, d)
}

fn names(d: &Diagnosis) -> Vec<&str> {
    d.effects.iter().map(|e| e.name.as_str()).collect()
}

/// The kept effect `name` of `d`, or a panic naming what was kept and rejected.
fn kept_effect<'a>(d: &'a Diagnosis, name: &str) -> &'a ident::diagnose::KeptEffect {
    d.effects
        .iter()
        .find(|e| e.name == name)
        .unwrap_or_else(|| panic!("{name} not kept: {:?} {:?}", names(d), d.rejected))
}

fn param(d: &Diagnosis, effect: &str, p: &str) -> f64 {
    d.effects.iter().find(|e| e.name == effect).unwrap().params[p]
}

/// Relative error within 20% (the tolerance).
fn close(est: f64, truth: f64) -> bool {
    (est / truth - 1.0).abs() <= 0.2
}

fn falls(d: &Diagnosis) -> bool {
    d.after.rmse < 0.95 * d.before.rmse
}

/// Generate a record (multi-level input if asked) with one hidden effect, diagnose it, and
/// check that exactly that effect is kept, with its parameter `(name, key, truth)` within the
/// tolerance of `close`, and that the validation error falls.
fn finds_only(multi_level: bool, hidden: Hidden, seed: u64, (name, key, truth): (&str, &str, f64)) {
    let rec = generate(&input(0.0, multi_level), hidden, seed);
    let (_, d) = run(&rec, true);
    assert_eq!(names(&d), [name]);
    assert!(close(param(&d, name, key), truth));
    assert!(falls(&d));
}

#[test]
fn clean_data_add_nothing() {
    let rec = generate(&input(0.0, false), Hidden::default(), 1);
    let (_, d) = run(&rec, true);
    assert!(d.effects.is_empty(), "{:?}", names(&d));
    assert_eq!(d.after, d.before);
}

#[test]
fn delay_is_found() {
    finds_only(
        false,
        Hidden {
            delay: 0.012,
            ..Default::default()
        },
        2,
        ("delay", "tau", 0.012),
    );
}

#[test]
fn a_delay_of_one_sample_is_found() {
    // One sample (2 ms): too small for the held-parameter grid to pay (the base fit bends its
    // orders to mimic it); found from the residual-input correlation at lag 0 and a joint refit.
    finds_only(
        false,
        Hidden {
            delay: 0.002,
            ..Default::default()
        },
        4,
        ("delay", "tau", 0.002),
    );
}

#[test]
fn coulomb_friction_is_found() {
    finds_only(
        false,
        Hidden {
            coulomb: 0.15,
            ..Default::default()
        },
        3,
        ("coulomb_friction", "Vc", 0.15),
    );
}

#[test]
fn offset_is_found() {
    let c = 0.15;
    let rec = generate(
        &input(0.0, false),
        Hidden {
            out_offset: c,
            ..Default::default()
        },
        4,
    );
    let (_, d) = run(&rec, false);
    assert_eq!(names(&d), ["output_offset"]);
    let p = &d.effects[0].params;
    assert!(close(p["y_offset"], c), "{p:?}");
    assert!(falls(&d));
}

#[test]
fn periodic_is_found() {
    let (a, f) = (0.1, 23.7);
    let rec = generate(
        &input(0.0, false),
        Hidden {
            sine: Some((a, f)),
            ..Default::default()
        },
        5,
    );
    let (_, d) = run(&rec, true);
    assert_eq!(names(&d), ["periodic"]);
    assert!(close(param(&d, "periodic", "amplitude"), a));
    assert!(close(param(&d, "periodic", "freq_hz"), f));
    assert!(falls(&d));
}

#[test]
fn abs_sensor_is_found() {
    let rec = generate(
        &input(0.0, false),
        Hidden {
            abs: true,
            ..Default::default()
        },
        6,
    );
    let (_, d) = run(&rec, true);
    assert_eq!(names(&d), ["abs_sensor"]);
    assert!(falls(&d));
    // No parameter: the refitted gain is the check.
    let k = d.model.params[d.model.index_of("K").unwrap()].value;
    assert!(close(k, TRUTH.0), "K = {k}");
}

#[test]
fn saturation_is_found() {
    finds_only(
        true,
        Hidden {
            sat: Some(0.6),
            ..Default::default()
        },
        7,
        ("saturation", "level", 0.6),
    );
}

#[test]
fn deadzone_is_found() {
    finds_only(
        true,
        Hidden {
            dz: Some(0.15),
            ..Default::default()
        },
        8,
        ("deadzone", "width", 0.15),
    );
}

/// A heater-like input map (power rising with the square of the command): the power law is kept
/// with its exponent within 20%, and no other effect (saturation, dead band or a periodic
/// disturbance) takes its place.
#[test]
fn a_power_law_input_map_is_found() {
    finds_only(
        true,
        Hidden {
            power: Some(2.0),
            ..Default::default()
        },
        9,
        ("power_law", "exponent", 2.0),
    );
}

/// A flattening actuator (`p = 0.6`, concave like a soft saturation) is a power law too.
#[test]
fn a_flattening_input_map_is_found() {
    finds_only(
        true,
        Hidden {
            power: Some(0.6),
            ..Default::default()
        },
        10,
        ("power_law", "exponent", 0.6),
    );
}

/// A sinusoid with only about three periods in the estimation part is not kept as a periodic
/// disturbance: too few periods to show that it repeats (issue 29).
#[test]
fn a_peak_with_few_periods_is_not_a_periodic_disturbance() {
    let u = input(0.0, false);
    let f = 3.0 / (0.7 * u.len() as f64 * DT);
    let rec = generate(
        &u,
        Hidden {
            sine: Some((0.3, f)),
            ..Default::default()
        },
        5,
    );
    let (_, d) = run(&rec, true);
    assert!(!names(&d).contains(&"periodic"), "{:?}", names(&d));
    assert!(
        d.rejected
            .iter()
            .any(|r| r.name == "periodic" && r.reason.contains("periods of evidence")),
        "{:?}",
        d.rejected
    );
}

/// The benchmark zoo's case 0192 of seed 46 (`tests/data/README.md`): the PMSM
/// `39.632/(1.5027e-5 s^1.6904 + 0.017657 s^0.71069 + 1)` under a multisine with a sinusoid of
/// amplitude 1.284 at 68.71 Hz at its output, 4.9 periods in the estimation part, explaining 97%
/// of the residual. With 6 periods asked for it was rejected, and the held-out part was predicted
/// 13.7 times the oracle's error; it is kept, and the held-out part is predicted within 10% of the
/// oracle (the noise, RMS 0.0621).
#[test]
fn a_strong_sinusoid_of_five_periods_is_a_periodic_disturbance() {
    let r = default_run_on_fixture("zoo_seed46_0192_periodic.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let d = &dg.diagnosis;
    assert_eq!(names(d), ["periodic"], "{}", dg.structures.reason);
    let f = param(d, "periodic", "freq_hz");
    let a = param(d, "periodic", "amplitude");
    assert!((f / 68.709 - 1.0).abs() < 0.005, "{f} Hz (truth 68.709)");
    assert!(
        (a / 1.2844 - 1.0).abs() < 0.05,
        "amplitude {a} (truth 1.284)"
    );
    let held_out = d.validation.as_ref().expect("a held-out part").after.rmse;
    assert!(held_out < 1.1 * 0.0621, "held-out RMSE {held_out}");
}

/// The benchmark zoo's case 0247 of seed 44: a first order behind a sign-blind sensor with a
/// sinusoid of amplitude 2.58 at 18.80 Hz, a staircase. A residual peak at 2.36 Hz, 5.1 periods
/// in the estimation part, explains 46% of the residual: taken for a periodic disturbance (as 4
/// periods alone would allow), it and a dead band stood in for the sensor's distortion and the
/// default exited 0 with the response 25 times off. It is rejected, and the model is not usable.
#[test]
fn a_weak_peak_of_five_periods_is_not_a_periodic_disturbance() {
    let r = default_run_on_fixture("zoo_seed44_0247_two_effects.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let d = &dg.diagnosis;
    assert!(
        d.rejected
            .iter()
            .any(|x| x.name == "periodic" && x.reason.contains("must explain 50% alone")),
        "{:?}",
        d.rejected
    );
    assert!(!names(d).contains(&"periodic"), "{:?}", names(d));
    assert!(!r.lead.usable, "{:?}", names(d));
}

#[test]
fn two_effects_are_both_found() {
    let (vc, a, f) = (0.15, 0.1, 23.7);
    let rec = generate(
        &input(0.0, false),
        Hidden {
            coulomb: vc,
            sine: Some((a, f)),
            ..Default::default()
        },
        9,
    );
    let (_, d) = run(&rec, true);
    let mut n = names(&d);
    n.sort_unstable();
    assert_eq!(n, ["coulomb_friction", "periodic"]);
    assert!(close(param(&d, "coulomb_friction", "Vc"), vc));
    assert!(close(param(&d, "periodic", "amplitude"), a));
    assert!(falls(&d));
}

#[test]
fn friction_without_speed_reversal_is_ambiguous() {
    // PRBS 2 +- 1: the speed never changes sign.
    let rec = generate(
        &input(2.0, false),
        Hidden {
            coulomb: 0.3,
            ..Default::default()
        },
        10,
    );
    let (_, d) = run(&rec, true);
    assert!(!names(&d).contains(&"coulomb_friction"), "{:?}", names(&d));
    assert!(
        d.ambiguous
            .iter()
            .any(|a| a.name == "coulomb_friction" && a.confused_with == "input offset"),
        "{:?}",
        d.ambiguous
    );
}

/// Diagnose with the structures compared ([`diagnose_best`]), the user's being `label` (a preset
/// of `ident::app::structure`), with the identification defaults (operating point from the
/// first samples, output offset, estimated initial state) unless `initial` says otherwise.
fn run_best(rec: &Record, label: &str, initial: InitialState) -> Diagnosed {
    let opts = IdentOptions {
        initial,
        ..IdentOptions::default()
    };
    let (model, _) = ident::app::structure(label, 0.2).unwrap();
    let id = identify(rec, &model, &opts).unwrap();
    let d = diagnose_best(rec, label, &model, id, &opts, &DiagnoseOptions::default()).unwrap();
    eprintln!(
        "structures {:#?} | before {:?} after {:?} | kept {:#?} | rejected {:#?} | ambiguous {:?} | final {}",
        d.choice,
        d.diagnosis.before,
        d.diagnosis.after,
        d.diagnosis.effects,
        d.diagnosis.rejected,
        d.diagnosis.ambiguous,
        d.diagnosis.final_model
    );
    d
}

/// The zero-mean PRBS of [`input`] after `rest` samples at zero (the plant at rest first).
fn rest_then_prbs(rest: usize) -> Vec<f64> {
    let mut u = vec![0.0; rest];
    u.extend(input(0.0, false));
    u.truncate(N);
    u
}

#[test]
fn an_input_offset_without_speed_reversals_is_told_from_friction_from_rest() {
    // PRBS 2 +- 1 through a 0.3 V input offset, the plant at rest before the record: the speed
    // never reverses, so friction is ambiguous with the offset; the input offset acts through
    // the dynamics (a step from rest), which an output offset cannot follow.
    let rec = generate(
        &input(2.0, false),
        Hidden {
            u_offset: 0.3,
            ..Default::default()
        },
        11,
    );
    let opts = IdentOptions {
        offsets: OffsetMode::None,
        initial: InitialState::Rest,
        ..IdentOptions::default()
    };
    let id = identify(&rec, &FracModel::commensurate(1.0, 0.05, 1e-3, 0.8), &opts).unwrap();
    let d = diagnose(&rec, &id, &DiagnoseOptions::default()).unwrap();
    eprintln!("kept {:#?} | rejected {:#?}", d.effects, d.rejected);
    assert_eq!(names(&d), ["input_offset"]);
    assert!(close(param(&d, "input_offset", "u_offset"), 0.3));
    assert!(falls(&d));
    assert!(d.ambiguous.iter().any(|a| a.name == "coulomb_friction"));
    // With the defaults (the initial state estimated) the base model's output offset and
    // initial state already stand for it: nothing is added, and friction stays ambiguous.
    let d = run_best(&rec, "commensurate", InitialState::Estimate).diagnosis;
    assert!(d.effects.is_empty(), "{:?}", names(&d));
    assert!(d.ambiguous.iter().any(|a| a.name == "coulomb_friction"));
}

#[test]
fn friction_with_a_rest_period_in_front_is_kept() {
    // A fifth of the record at rest, then a zero-mean PRBS; the PMSM structure (two free orders
    // that can run to a bound while the friction is missing), identification defaults.
    let rec = generate(
        &rest_then_prbs(N / 5),
        Hidden {
            coulomb: 0.15,
            ..Default::default()
        },
        12,
    );
    let d = run_best(&rec, "pmsm", InitialState::Estimate).diagnosis;
    assert_eq!(names(&d), ["coulomb_friction"]);
    assert!(close(param(&d, "coulomb_friction", "Vc"), 0.15));
    assert!(falls(&d));
}

#[test]
fn a_repeated_reference_is_excitation_not_a_disturbance() {
    // A smooth reference repeated every 0.5 s (a positioning cycle), with the controller's jitter
    // so that it does not repeat sample for sample, and a hidden friction: the base model's
    // residual has lines at the harmonics of 2 Hz, which are the excitation's.
    let mut rng = rand::rngs::StdRng::seed_from_u64(13);
    let jitter = Normal::new(0.0, 0.02).unwrap();
    let u: Vec<f64> = (0..N)
        .map(|k| {
            let ph = 2.0 * std::f64::consts::PI * (k as f64 * DT) / 0.5;
            (ph.sin() + 0.4 * (2.0 * ph).sin()).clamp(-1.0, 1.0) + jitter.sample(&mut rng)
        })
        .collect();
    let rec = generate(
        &u,
        Hidden {
            coulomb: 0.15,
            ..Default::default()
        },
        13,
    );
    let (_, d) = run(&rec, true);
    assert!(!names(&d).contains(&"periodic"), "{:?}", names(&d));
    assert!(names(&d).contains(&"coulomb_friction"), "{:?}", names(&d));
    assert!(
        d.rejected
            .iter()
            .any(|r| r.name == "periodic" && r.reason.contains("input's own period")),
        "{:#?}",
        d.rejected
    );
}

#[test]
fn a_sign_blind_sensor_is_found_with_noise_around_zero() {
    // The PRBS switched off for the second half of every 0.8 s: the speed comes to rest near zero,
    // where the rectified speed plus noise reads below zero in many samples.
    let mut u = input(0.0, false);
    for block in u.chunks_mut(400) {
        block[200..].fill(0.0);
    }
    let rec = generate(
        &u,
        Hidden {
            abs: true,
            ..Default::default()
        },
        14,
    );
    let below = rec.y.iter().filter(|v| **v < 0.0).count();
    assert!(below > rec.len() / 100, "{below} samples below zero");
    let (_, d) = run(&rec, true);
    assert_eq!(names(&d), ["abs_sensor"]);
    assert!(falls(&d));
}

#[test]
fn the_effects_do_not_hinge_on_the_structure_named() {
    // Friction on a multi-level input, the user naming a first-order model: a first-order fit
    // bends towards a dead zone; the comparison moves to a fractional structure and keeps the
    // friction alone.
    let rec = generate(
        &input(0.0, true),
        Hidden {
            coulomb: 0.15,
            ..Default::default()
        },
        15,
    );
    let opts = IdentOptions::default();
    let (mut model, _) = ident::app::structure("fopdt", 0.2).unwrap();
    model.delay = None;
    model.params.retain(|p| p.name != "tau");
    let id = identify(&rec, &model, &opts).unwrap();
    let d = diagnose_best(
        &rec,
        "first-order",
        &model,
        id,
        &opts,
        &DiagnoseOptions::default(),
    )
    .unwrap();
    eprintln!("{:#?} | kept {:#?}", d.choice, d.diagnosis.effects);
    let chosen = &d.choice.scores[d.choice.chosen].name;
    assert_ne!(chosen, "first-order");
    assert_eq!(names(&d.diagnosis), ["coulomb_friction"]);
    assert!(close(param(&d.diagnosis, "coulomb_friction", "Vc"), 0.15));
}

/// The product's path: the user names nothing (pmsm), operating point from the first samples,
/// output offset and initial state estimated, structures compared. Exactly the hidden effect
/// `name` is kept (nothing on the clean record), its parameter `(key, truth)` within 20%. One
/// test per effect (they run side by side), the record seeded `seed`.
fn with_the_defaults_alone_is_kept(
    name: &str,
    seed: u64,
    levels: bool,
    hidden: Hidden,
    truth: Option<(&str, f64)>,
) {
    let rec = generate(&input(0.0, levels), hidden, seed);
    let d = run_best(&rec, "pmsm", InitialState::Estimate).diagnosis;
    let want: Vec<&str> = if name == "clean" { vec![] } else { vec![name] };
    assert_eq!(names(&d), want, "{name}");
    if let Some((key, t)) = truth {
        let v = param(&d, name, key);
        assert!(close(v, t), "{name}: {key} = {v} (truth {t})");
    }
}

#[test]
fn with_the_defaults_a_clean_record_keeps_nothing() {
    with_the_defaults_alone_is_kept("clean", 20, false, Hidden::default(), None);
}

#[test]
fn with_the_defaults_a_delay_alone_is_kept() {
    let hidden = Hidden {
        delay: 0.012,
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("delay", 21, false, hidden, Some(("tau", 0.012)));
}

#[test]
fn with_the_defaults_friction_alone_is_kept() {
    let hidden = Hidden {
        coulomb: 0.15,
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("coulomb_friction", 22, false, hidden, Some(("Vc", 0.15)));
}

#[test]
fn with_the_defaults_a_periodic_disturbance_alone_is_kept() {
    let hidden = Hidden {
        sine: Some((0.1, 23.7)),
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("periodic", 23, false, hidden, Some(("amplitude", 0.1)));
}

#[test]
fn with_the_defaults_an_output_drift_alone_is_kept() {
    // 0.3 over the 6 s record: 7 noise levels, a seventh of the output's swing.
    let hidden = Hidden {
        drift: 0.05,
        ..Default::default()
    };
    with_the_defaults_alone_is_kept(
        "output_drift",
        31,
        false,
        hidden,
        Some(("rate_per_s", 0.05)),
    );
}

#[test]
fn with_the_defaults_a_sign_blind_sensor_alone_is_kept() {
    let hidden = Hidden {
        abs: true,
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("abs_sensor", 24, false, hidden, None);
    // The offset that places the sensor's zero is the sensor's, not an input offset of the
    // plant (the hidden plant has none): the final model names no input offset.
    let rec = generate(&input(0.0, false), hidden, 24);
    let d = run_best(&rec, "pmsm", InitialState::Estimate).diagnosis;
    let named: Vec<&str> = d.model.effects.iter().map(|e| e.name()).collect();
    assert!(named.contains(&"abs_sensor"), "{named:?}");
    assert!(!named.contains(&"input_offset"), "{named:?}");
}

#[test]
fn with_the_defaults_saturation_alone_is_kept() {
    let hidden = Hidden {
        sat: Some(0.6),
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("saturation", 25, true, hidden, Some(("level", 0.6)));
}

#[test]
fn with_the_defaults_a_dead_zone_alone_is_kept() {
    let hidden = Hidden {
        dz: Some(0.15),
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("deadzone", 26, true, hidden, Some(("width", 0.15)));
}

#[test]
fn with_the_defaults_a_power_law_alone_is_kept() {
    let hidden = Hidden {
        power: Some(2.0),
        ..Default::default()
    };
    with_the_defaults_alone_is_kept("power_law", 27, true, hidden, Some(("exponent", 2.0)));
}

#[test]
fn an_effect_whose_refit_sends_an_order_to_its_bound_is_refitted_from_a_fresh_start() {
    // An integer second-order plant (q = 1, the edge of the commensurate structure's (0, 1))
    // with friction: the base fit without friction bends q inside; the refit with friction sends it
    // to its bound. The effect must not be thrown away for that: it is refitted from a fresh
    // start and kept, the evidence saying whether q stayed at its bound.
    let rec = generate(
        &input(0.0, false),
        Hidden {
            coulomb: 0.15,
            q: Some(1.0),
            ..Default::default()
        },
        1,
    );
    let (id, d) = run(&rec, true);
    let q = id.report.values[id.model.index_of("q").unwrap()];
    let q_after = d.model.params[d.model.index_of("q").unwrap()].value;
    eprintln!("q: base {q}, after {q_after}");
    assert_eq!(names(&d), ["coulomb_friction"]);
    assert!(close(param(&d, "coulomb_friction", "Vc"), 0.15));
    assert!(falls(&d));
    // The path this test is for: q inside before the effect (0.981 on this noise) and at its
    // bound after (0.995; an effect the old rule threw away), refitted from a fresh start and
    // kept, the evidence saying so. (Of 59 noise seeds at this friction, 2 take this path; the
    // others' refits end with q inside and keep the effect without the fresh start.)
    assert!(q < 0.99 && q_after > 0.995, "q: base {q}, after {q_after}");
    let ev = &d.effects[0].evidence;
    assert!(
        ev.contains("stayed at a bound when refitted from a fresh start"),
        "{ev}"
    );
}

/// A record of the truth that starts `idle` samples before its first input change (zero input,
/// then the zero-mean PRBS of [`input`]), the plant either at rest or still relaxing from a past
/// input: `past` volts held for 3 s that ended 0.5 s before the first sample (a fractional
/// plant's memory decays as a power of time, so the output creeps on through the whole record
/// while it looks steady over the idle samples). The GL truth runs over the past and the record
/// alike (full memory); the past is cut off, the noise is 2% of the whole output's spread.
fn relaxing(idle: usize, past: f64) -> Record {
    let (held, gap) = (1500, 250); // 3 s and 0.5 s at DT
    let mut u = vec![past; held];
    u.extend(vec![0.0; gap]);
    u.extend(rest_then_prbs(idle));
    let all = generate(&u, Hidden::default(), 31);
    let y = &all.y[held + gap..];
    Record::from_samples(&u[held + gap..], y, DT).unwrap()
}

#[test]
fn a_record_that_only_looks_at_rest_gets_its_initial_state() {
    // Output still relaxing from a 1 V input held before the record: the 60 idle samples (0.12 s)
    // before the first input change pass the rest test (so the defaults fit from rest), and the
    // diagnosis finds that the record was not at rest: the held-out error falls by more than the
    // 5% margin, to within 5% of the fit that estimates the initial state from the start (what
    // the data support).
    let rec = relaxing(60, 1.0);
    assert_eq!(rec.rests_until(), Some(60), "the record looks at rest");
    let d = run_best(&rec, "commensurate", InitialState::Auto);
    assert_eq!(d.id.initial.state, "rest");
    let diag = &d.diagnosis;
    assert!(
        names(diag).contains(&"initial_state"),
        "kept {:?}",
        names(diag)
    );
    assert!(
        falls(diag),
        "before {:?} after {:?}",
        diag.before,
        diag.after
    );
    let model = FracModel::commensurate(1.0, 0.05, 1e-3, 0.8);
    let est = identify(
        &rec,
        &model,
        &IdentOptions {
            initial: InitialState::Estimate,
            ..IdentOptions::default()
        },
    )
    .unwrap();
    let reference = est.validation.unwrap().rmse;
    assert!(
        diag.after.rmse <= 1.05 * reference,
        "after {} vs estimated from the start {reference}",
        diag.after.rmse
    );
    // The same record from true rest: the initial state is not added.
    let rest = relaxing(60, 0.0);
    assert_eq!(rest.rests_until(), Some(60));
    let d = run_best(&rest, "commensurate", InitialState::Auto).diagnosis;
    assert!(!names(&d).contains(&"initial_state"), "{:?}", names(&d));
}

/// `fracid time FILE` with defaults (the library's use case, `ident::app::time::run`) on the
/// fixture `name` of `tests/data`.
fn default_run_on_fixture(name: &str) -> ident::app::time::TimeReport {
    use ident::app::observe::Quiet;
    use ident::app::time::{run, TimeData, TimeRequest};
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let loaded = Record::load(&path, &ident::data::ReadOptions::default()).unwrap();
    let data = TimeData {
        record: loaded.record,
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    };
    run(&TimeRequest::default(), &data, &mut Quiet).unwrap()
}

/// The benchmark zoo's case 0159 of seed 45 (`tests/data/README.md`): a cell
/// `0.04721 + 7.937e-4/s + K/(a1 s^0.715 + 1)` under a staircase of 2426 samples. Its instant
/// response, measured at the staircase's few steps, is 4.9 standard errors from zero, short of
/// the 6 that admitted the structures with a feed-through: no cell was fitted, and the default
/// exited 1 with a PMSM 40% off in its response. The cell is fitted and chosen, `D` and `Ki`
/// near the truth.
#[test]
fn a_cells_ohmic_drop_measured_coarsely_still_admits_the_cell() {
    let r = default_run_on_fixture("zoo_seed45_0159_cell.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let chosen = &dg.structures.scores[dg.structures.chosen].name;
    assert_eq!(chosen, "cell", "{}", dg.structures.reason);
    assert!(r.lead.usable, "{:?}", r.lead.problems);
    let value = |name: &str| {
        let p = r.lead.params.iter().find(|p| p.name == name);
        p.map(|p| p.value).expect(name)
    };
    let (d, ki) = (value("D"), value("Ki"));
    assert!((d / 0.047_21 - 1.0).abs() < 0.1, "D = {d} (truth 0.04721)");
    assert!(
        (ki / 7.937e-4 - 1.0).abs() < 0.05,
        "Ki = {ki} (truth 7.937e-4)"
    );
}

/// The benchmark zoo's case 0001 of seed 46 (`tests/data/README.md`): a third order without a
/// delay under steps. The chosen second order lacks the fastest pole, and a delay of 12 ms stood
/// in for it (held out at the oracle's error: the delay was kept, and spurious). A first-order lag
/// in the delay's place makes the record no less likely: the lag is taken, near the truth's
/// 16.2 ms pole, and the model has no delay.
#[test]
fn a_delay_standing_in_for_a_missing_pole_gives_way_to_a_lag() {
    let r = default_run_on_fixture("zoo_seed46_0001_integer.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let tau = r.lead.params.iter().find(|p| p.name == "tau");
    assert!(tau.is_none_or(|p| p.value == 0.0), "{:?}", tau);
    let lag = r.lead.params.iter().find(|p| p.name == "T_lag");
    let t = lag.map(|p| p.value).expect("a lag in the lead model");
    assert!(
        (t / 0.016_17 - 1.0).abs() < 0.15,
        "T_lag = {t} (truth 0.01617)"
    );
    let why = dg
        .diagnosis
        .rejected
        .iter()
        .find(|e| e.name == "delay")
        .expect("the delay rejected");
    assert!(why.reason.contains("first-order lag"), "{}", why.reason);
    assert!(r.lead.usable, "{:?}", r.lead.problems);
    let held = r.lead.fit.validation.expect("a held-out part").rmse;
    assert!(held < 1.1 * 2.4778, "held-out RMSE {held} (oracle 2.4778)");
}

/// The benchmark zoo's cell case 0284 of seed 44 (`tests/data/README.md`):
/// `R0 + R1/((tau s)^q + 1) + 1/(C s)` with an ohmic drop `R0` = 0.01601 under a multisine, whose
/// lag-0 change its past changes predict: the record's screen cannot tell the instant response.
/// With the feed-through structures left out, a general 4/4 was chosen, 14.8% off the truth's
/// response over the excited band (the zoo's measure); with the feed-through structure compared,
/// it is chosen with its `D` within 5% of `R0` and its response within 5% of the truth's at every
/// excited frequency.
#[test]
fn a_feedthrough_the_input_cannot_measure_is_decided_by_the_held_out_error() {
    let r = default_run_on_fixture("zoo_seed44_0284_cell.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let d = r.lead.params.iter().find(|p| p.name == "D");
    let d = d
        .map(|p| p.value)
        .expect("a feed-through in the lead model");
    assert!(
        (d / 0.016_01 - 1.0).abs() < 0.05,
        "D = {d}: {}",
        dg.structures.reason
    );
    let truth: fracsim::FracTf = "(0.080184 s^1.59841 + 0.029187 s + 4.3949e-4 s^0.59841 \
                                  + 8.7775e-5)/(5.00697 s^1.59841 + s)"
        .parse()
        .unwrap();
    let fit: fracsim::FracTf = r.lead.model.text.parse().unwrap();
    // The zoo's excited band (rad/s).
    for w in [
        0.0552, 0.0755, 0.1098, 0.1643, 0.2467, 0.3633, 0.5345, 0.7881, 1.1518, 1.6859, 2.481,
    ] {
        let (g, h) = (truth.freq_response(w), fit.freq_response(w));
        let e = (h - g).norm() / g.norm();
        assert!(
            e < 0.05,
            "{:.1}% off at {w} rad/s: {}",
            100.0 * e,
            r.lead.model.text
        );
    }
}

/// The benchmark zoo's two-mode case 0129 of seed 45 (`tests/data/README.md`): a motor lag and
/// modes at 27.0 Hz and 65.2 Hz at the load, under a PRBS whose excited band ends at 47 Hz. The
/// PMSM holds the first mode; the second, above the band, lags the phase and leaves the
/// magnitude flat, as a delay does, and the diagnosis kept a delay of 2.47 ms for it (9.2% off
/// the truth's response over the band, the zoo's measure). A lag cannot stand in for it; the
/// resonant pair refitted in the delay's place makes the record far likelier and takes it: no
/// delay, the pair's natural frequency within 5% of the truth's second mode, the response within
/// 5% of the truth's over the band (RMS of the relative error at the zoo's excited frequencies),
/// held out within 10% of the oracle.
#[test]
fn a_delay_standing_in_for_a_mode_above_the_band_gives_way_to_it() {
    let r = no_delay_and_within_the_oracle("zoo_seed45_0129_multi_mode.csv", 0.137_95);
    let a = r.lead.params.iter().find(|p| p.name == "a_mode");
    let a = a
        .map(|p| p.value)
        .expect("a resonant pair in the lead model");
    let w_n = a.sqrt().recip();
    let truth_w_n = 2.0 * std::f64::consts::PI * 65.2;
    assert!((w_n / truth_w_n - 1.0).abs() < 0.05, "w_n = {w_n} rad/s");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let why = dg.diagnosis.rejected.iter().find(|e| e.name == "delay");
    let why = why.expect("the delay rejected");
    assert!(why.reason.contains("resonant pair"), "{}", why.reason);
    let truth =
        "6.337609/(8.667193e-12 s^5 + 1.800032e-9 s^4 + 1.772091e-6 s^3 + 1.1293608e-4 s^2 \
                 + 0.04354680 s + 1)";
    let band = [
        5.151, 10.30, 15.45, 20.61, 28.22, 41.00, 61.38, 92.15, 135.7, 199.7, 294.4,
    ];
    let e = frf_error(&r.lead.model.text, truth, &band);
    assert!(e < 0.05, "{:.1}% off: {}", 100.0 * e, r.lead.model.text);
}

/// The benchmark zoo's measure of a model's frequency-response error: the RMS over `band_omega`
/// (rad/s) of the relative error of `fit` against `truth` (both transfer functions as text).
fn frf_error(fit: &str, truth: &str, band_omega: &[f64]) -> f64 {
    let fit: fracsim::FracTf = fit.parse().unwrap();
    let truth: fracsim::FracTf = truth.parse().unwrap();
    let sum: f64 = band_omega
        .iter()
        .map(|&w| {
            ((fit.freq_response(w) - truth.freq_response(w)) / truth.freq_response(w)).norm_sqr()
        })
        .sum();
    (sum / band_omega.len() as f64).sqrt()
}

/// The benchmark zoo's PMSM case 0250 of seed 46 (`tests/data/README.md`): a multi-level input
/// logged from its first sample, the plant at rest at input 0 before it: the record starts with a
/// step from 0 to the first level, and its first 12 samples pass the rest test (the output's noise
/// hides the step response's start), so it is fitted from rest at the first level. The step is
/// then the record's initial state: a past input held until the first sample. The input-offset
/// probe's signature is that step (through the linear model, from rest) and it was kept (a
/// spurious input offset, or on another structure a dead band with an input offset before it);
/// the initial-state probe's four past levels, the oldest of which the model no longer feels
/// (its response died out before the record), were called a degenerate signature (0.0% explained).
/// Now the input offset leaves the question to the initial state, whose live levels explain 63%:
/// the initial state alone is kept, held out within 10% of the oracle, the response within 5% of
/// the truth's over the band.
#[test]
fn a_step_at_the_first_sample_is_the_initial_state_not_an_input_offset() {
    let r = default_run_on_fixture("zoo_seed46_0250_pmsm.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    assert_eq!(
        names(&dg.diagnosis),
        ["initial_state"],
        "{:?} {}",
        dg.diagnosis.rejected,
        choice.reason
    );
    let held = choice.scores[choice.chosen].rmse_after.unwrap();
    assert!(held <= 1.1 * 1.730_87, "held-out RMSE {held}");
    let truth = "6.415018/(3.3283108e-4 s^1.1921026 + 8.9198772e-3 s^0.77408269 + 1)";
    let band = [
        64.575, 129.151, 258.302, 353.694, 513.898, 769.478, 1155.126, 1701.119,
    ];
    let e = frf_error(&r.lead.model.text, truth, &band);
    assert!(e < 0.05, "{:.1}% off: {}", 100.0 * e, r.lead.model.text);
}

/// The benchmark zoo's delay case 0010 of seed 45 (`tests/data/README.md`): a step from rest
/// through `12.94/(0.1424 s + 1)` with a dead time of 76.7 ms (2.4 samples). The held-out part is
/// the response's settled tail, which the delay does not move: judged on it alone the delay was
/// rejected at +0.0% and a fourth order with a right-half-plane zero mimicked it. On the
/// estimation part it removes half the error, and the tail is predicted no worse.
#[test]
fn a_delay_of_a_step_from_rest_is_judged_on_the_estimation_part() {
    let k = judged_on_step_test("zoo_seed45_0010_delay.csv", ("delay", "tau"), 0.07673, 0.1);
    assert!(k.evidence.contains("estimation RMSE"), "{}", k.evidence);
    assert!(k.rmse_change_percent < -5.0, "{}", k.rmse_change_percent);
}

/// The benchmark zoo's drift case 0246 of seed 44 (`tests/data/README.md`): a step from rest
/// through a PMSM with an output drift of 0.825 per second. A drift moves the settled response:
/// it clears the margin on the held-out tail (where it extrapolates), not on the estimation
/// part, and is kept so (judged on the estimation part alone it was rejected at -0.6%).
#[test]
fn a_drift_of_a_step_test_is_judged_on_its_settled_tail() {
    let k = judged_on_step_test(
        "zoo_seed44_0246_drift.csv",
        ("output_drift", "rate_per_s"),
        0.8255,
        0.2,
    );
    assert!(k.evidence.contains("validation RMSE"), "{}", k.evidence);
}

/// The effect `(name, parameter)` the default run on fixture `file` (a step test: its held-out
/// part the response's tail) keeps, its parameter within `tolerance` (relative) of `truth`.
fn judged_on_step_test(
    file: &str,
    (name, parameter): (&str, &str),
    truth: f64,
    tolerance: f64,
) -> ident::diagnose::KeptEffect {
    let r = default_run_on_fixture(file);
    assert_eq!(
        r.validated_by.kind,
        ident::oe::ValidationKind::ResponseTail,
        "{file}"
    );
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    let k = kept_effect(d, name).clone();
    let v = k.params[parameter];
    assert!(
        (v - truth).abs() < tolerance * truth,
        "{file}: {parameter} = {v} (truth {truth})"
    );
    k
}

/// The benchmark zoo's friction case 0211 (seed 44, `tests/data/README.md`): a first-order drive
/// `17/(0.065 s + 1)` at 22 ms with Coulomb friction 1.69 at its input, five input levels, 2.3%
/// noise: the friction is kept with the defaults, near the truth's.
#[test]
fn friction_at_five_input_levels_is_kept() {
    let r = default_run_on_fixture("zoo_seed44_0211_friction.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    let vc = kept_effect(d, "coulomb_friction").params["Vc"];
    assert!(vc > 0.7 * 1.69 && vc < 1.3 * 1.69, "Vc = {vc} (truth 1.69)");
}

/// The benchmark zoo's friction case 0186 (seed 44, `tests/data/README.md`): the first order
/// `5.674/(7.02e-3 s + 1)` sampled at 0.4 of its time constant under a PRBS, Coulomb friction
/// 0.283 at its input, 3.4% noise (RMS 0.856). The friction signature, regressed on the base
/// fit's residual with the model's sensitivities projected out, comes out with the wrong sign
/// (the gain fitted without friction took it up); the refit, not that sign, decides, and keeps
/// the friction with the defaults. The speed's reversals are told from rest with the noise
/// level of the base fit's residual: the record's first differences, which carry the PRBS's own
/// steps here, gave 4.97, every sample of the speed looked at rest, and the friction was called
/// ambiguous with an input offset (the model then 16.5% off the truth's frequency response).
#[test]
fn friction_whose_signature_comes_out_with_the_wrong_sign_is_refitted_and_kept() {
    let r = default_run_on_fixture("zoo_seed44_0186_friction_reversal.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    let kept = kept_effect(d, "coulomb_friction");
    assert!(kept.evidence.contains("wrong sign"), "{}", kept.evidence);
    let vc = kept.params["Vc"];
    assert!(
        vc > 0.7 * 0.283 && vc < 1.3 * 0.283,
        "Vc = {vc} (truth 0.283)"
    );
}

/// The benchmark zoo's friction case 0286 (seed 44, `tests/data/README.md`): the first order
/// `2.2107/(0.020776 s + 1)` under a PRBS, Coulomb friction 0.0783 at its input, 1.6% noise. The
/// friction's refit takes the held-out RMSE 4.7% down, to the truth's (the zoo's oracle 0.091213),
/// short of the 5% margin: without the friction the gain comes out 10% low. The refit's held-out
/// residual is white (the noise floor), so half the margin is enough, and the friction is kept.
#[test]
fn an_effect_that_reaches_the_noise_floor_is_kept_short_of_the_margin() {
    let r = default_run_on_fixture("zoo_seed44_0286_friction_reversal.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    let kept = kept_effect(d, "coulomb_friction");
    assert!(kept.evidence.contains("noise floor"), "{}", kept.evidence);
    assert!(
        kept.rmse_change_percent > -5.0,
        "{}",
        kept.rmse_change_percent
    );
    let vc = kept.params["Vc"];
    assert!(
        vc > 0.5 * 0.0783 && vc < 1.5 * 0.0783,
        "Vc = {vc} (truth 0.0783)"
    );
}

/// The benchmark zoo's drift case 0171 (seed 44, `tests/data/README.md`): the PMSM
/// `1.2382/(2.9751e-5 s^1.7707 + 0.034150 s^0.88570 + 1)` at 0.1 ms under a PRBS, its output
/// drifting by 0.2156 per second, 2.4% noise. Fitted without the drift the PMSM explains the ramp
/// with a fractional mode slower than the record (gain 681), the drift's signature is left with
/// 0.3% of its residual, and its diagnosis keeps a delay; the first order keeps the drift and was
/// chosen, 1.07x the truth's held-out RMSE, its frequency response 11% off. The drift the first
/// order kept is carried to the richer structures (each fitted with it from its own start, then
/// diagnosed again): the PMSM with the drift is chosen, its gain within 5% of the truth's, its
/// held-out RMSE within 2% of the truth's (0.021958, the zoo's oracle).
#[test]
fn an_effect_the_chosen_structure_kept_is_carried_to_the_richer_structures() {
    let r = default_run_on_fixture("zoo_seed44_0171_drift.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    assert_eq!(names(&dg.diagnosis), ["output_drift"]);
    let chosen = &dg.structures.scores[dg.structures.chosen];
    assert_eq!(chosen.name, "pmsm", "{}", dg.structures.reason);
    let held = chosen.rmse_after.unwrap();
    assert!(held <= 1.02 * 0.021958, "held-out RMSE {held}");
    let k = r.lead.params.iter().find(|p| p.name == "K").unwrap().value;
    assert!((k / 1.2382 - 1.0).abs() < 0.05, "K = {k} (truth 1.2382)");
    assert!(dg
        .structures
        .reason
        .contains("pmsm diagnosed again with first-order's output_drift"));
}

/// The benchmark zoo's friction case 0136 (seed 44, `tests/data/README.md`): a first order with
/// Coulomb friction under a chirp, not at rest at its first sample (the initial state estimated as
/// a past held input). The report's final model is the diagnosis's with the record's offset and
/// initial state estimated again, the plant held (as `fracid score --as-fitted` does): that fit
/// starts from the diagnosis's values, so it never ends above the diagnosis's own estimation
/// RMSE. Restarted from rest, its levels ended 0.3% above it (0.49897 against 0.49749).
#[test]
fn the_final_models_record_parameters_start_from_the_diagnosis_values() {
    let r = default_run_on_fixture("zoo_seed44_0136_friction_reversal.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    assert!(names(d).contains(&"coulomb_friction"), "{:?}", names(d));
    assert_eq!(r.initial_state.state, "estimate");
    let (led, after) = (r.lead.fit.estimation.rmse, d.estimation.after.rmse);
    assert!(
        led <= after * (1.0 + 1e-9),
        "the led model's estimation RMSE {led} above the diagnosis's {after}"
    );
}

/// The benchmark zoo's friction case 0011 (seed 44, `tests/data/README.md`): the second order
/// `22.56/(0.006272 s^2 + 0.06134 s + 1)` at 21 ms under a chirp, Coulomb friction 0.292 at its
/// input decided at each sample instant and held (the zoo's truth simulator, like the drive
/// simulator, steps the mechanics once per sample). A friction seen only at the middle of the
/// hold interval ends at 5x the truth's held-out RMSE: its sign changes half a sample earlier at
/// every reversal, which on a resonance of 2 rad per sample moves the response more than the
/// noise. The refit, started at both timings, keeps the one the record follows: within 10% of
/// the truth's held-out RMSE (0.17824, the zoo's oracle on the same samples), and the report
/// says the timing (`sampled`, which `fracid tune` simulates).
#[test]
fn friction_decided_at_the_sample_instant_is_fitted_with_that_timing() {
    let r = default_run_on_fixture("zoo_seed44_0011_friction_reversal.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    assert_eq!(names(&dg.diagnosis), ["coulomb_friction"]);
    assert_eq!(dg.diagnosis.effects[0].sampled, Some(true));
    let held = dg.structures.scores[dg.structures.chosen]
        .rmse_after
        .unwrap();
    assert!(held <= 1.1 * 0.17824, "held-out RMSE {held}");
}

/// The benchmark zoo's two-effects case 0022 (seed 44, `tests/data/README.md`): the first order
/// `1.83/(0.1758 s + 1)` at 80 ms under a chirp, Coulomb friction 0.675 at its input, seen
/// through a sign-blind sensor (`|y|`). The friction acts on the speed, not on what the sensor
/// makes of it: seen through the sensor its sign never changes and it is a constant input (the
/// friction was rejected and the sensor alone ended at 6x the truth's held-out RMSE). Friction
/// and sensor are kept, within 10% of the truth's held-out RMSE (0.039108, the zoo's oracle).
#[test]
fn friction_under_a_sign_blind_sensor_sees_the_speed_before_the_sensor() {
    let r = default_run_on_fixture("zoo_seed44_0022_two_effects.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let mut kept = names(&dg.diagnosis);
    kept.sort_unstable();
    assert_eq!(kept, ["abs_sensor", "coulomb_friction"]);
    let held = dg.structures.scores[dg.structures.chosen]
        .rmse_after
        .unwrap();
    assert!(held <= 1.1 * 0.039108, "held-out RMSE {held}");
}

/// The benchmark zoo's sign-blind-sensor case 0193 (seed 44, `tests/data/README.md`): a PMSM
/// `5.63/(1.46e-4 s^1.958 + 0.0651 s^0.872 + 1)` seen through `|y|`, an input of several levels,
/// 0.2% noise. Every linear base fit of the rectified output is poor and the fractional ones
/// predict the held-out part worse than its mean, so the base fits pruned the right structure
/// and the third order, diagnosed alone, kept a power law beside the sensor (held-out RMSE 0.311,
/// 13.5x the truth's). The sensor carries the fit (the held-out RMSE falls below 3/4 of the base
/// fit's), so the pruned structures are diagnosed too: the report ends on a fractional structure
/// with the sensor alone, within 10% of the truth's held-out RMSE (0.023066, the zoo's oracle on
/// the same samples).
#[test]
fn effects_that_carry_the_fit_bring_the_pruned_structures_back() {
    let r = default_run_on_fixture("zoo_seed44_0193_abs_sensor.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    let chosen = &choice.scores[choice.chosen];
    assert!(
        ["pmsm", "commensurate"].contains(&chosen.name.as_str()),
        "{}",
        choice.reason
    );
    assert_eq!(names(&dg.diagnosis), ["abs_sensor"], "{}", choice.reason);
    let held = chosen.rmse_after.unwrap();
    assert!(held <= 1.1 * 0.023066, "held-out RMSE {held}");
}

/// The benchmark zoo's PMSM case 0025 (seed 44, `tests/data/README.md`): no effect, an input of
/// several levels. The base fit ends at a poor optimum (held-out RMSE 0.268 against the truth's
/// 0.204); a saturation refitted at 2.7605, where it clips nothing but the input's largest level
/// (2.762), took the credit for the 23% the refit's linear part gained. The structure refitted
/// from that refit's values without the saturation makes the same gain: the saturation is
/// rejected and the structure's refit carries on, within 10% of the truth's held-out RMSE
/// (0.20429, the zoo's oracle on the same samples).
#[test]
fn an_effect_fitted_inactive_is_not_credited_with_the_structures_better_fit() {
    let r = default_run_on_fixture("zoo_seed44_0025_pmsm.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let d = &dg.diagnosis;
    assert!(d.effects.is_empty(), "kept {:?}", names(d));
    let sat = d
        .rejected
        .iter()
        .find(|e| e.name == "saturation")
        .expect("the saturation refitted and rejected");
    assert!(
        sat.reason.contains("the gain is the structure's"),
        "{}",
        sat.reason
    );
    let held = dg.structures.scores[dg.structures.chosen]
        .rmse_after
        .unwrap();
    assert!(held <= 1.1 * 0.20429, "held-out RMSE {held}");
}

/// The benchmark zoo's CI case 0027 (seed 4401, `tests/data/README.md`): a two-mass drive under a
/// multisine whose period (0.224 s) is found only approximately, from the input's
/// autocorrelation. The structure chosen misses the resonance, and the residual's peak at 112.2
/// Hz is the model's error at a line of the multisine, 25.1 periods of the approximate period
/// (not within 0.1 of a harmonic): a sinusoid fitted there was kept as a periodic disturbance.
/// The input's own spectrum has a narrow line there: the peak is the excitation and is rejected
/// with that reason.
#[test]
fn a_residual_peak_on_a_line_of_the_input_is_not_a_disturbance() {
    let r = default_run_on_fixture("zoo_ci_seed4401_0027_two_mass_motor.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    assert!(!names(d).contains(&"periodic"), "kept {:?}", names(d));
    assert!(
        d.rejected.iter().any(
            |e| e.name == "periodic" && e.reason.contains("a line of the input's own spectrum")
        ),
        "{:?}",
        d.rejected
    );
}

/// The benchmark zoo's two-mode case 0154 (seed 44, `tests/data/README.md`): a lag of 59 ms and
/// two modes at the load, 104 Hz and 320 Hz, `4.81/(3.43e-14 s^5 + ... + 1)`, dt 0.19 ms. The
/// named structures lack a mode and the PMSM kept a delay in its stead (held-out RMSE 1.69x the
/// truth's); the general structure, compared because the PMSM's residual depends on the input,
/// could not be fitted at all: every size of five poles was refused as improper, its `s^5`
/// coefficient 3e-14 of the coefficients' sum in seconds. Weighed in the model's band, the
/// general structure's five poles are fitted and chosen, with no delay, within 10% of the
/// truth's held-out RMSE (8.1655e-3, the zoo's oracle on the same samples).
#[test]
fn two_modes_are_fitted_by_the_general_structure_not_stood_for_by_a_delay() {
    let r = no_delay_and_within_the_oracle("zoo_seed44_0154_multi_mode.csv", 8.1655e-3);
    let choice = &r.diagnosis.as_ref().expect("a diagnosis").structures;
    let chosen = &choice.scores[choice.chosen];
    assert!(chosen.name.starts_with("general"), "{}", choice.reason);
}

/// The benchmark zoo's lead case 0183 (seed 44, `tests/data/README.md`): the lead
/// `(2.2344 s + 11.941)/(1.8071e-3 s^2 + 0.16613 s + 1)` under a PRBS, dt 2.99 ms, no effect. The
/// named structures lack the zero; the general structure's shortlist held only larger sizes, and
/// its 1/4 put a lightly damped mode at the Nyquist frequency (held-out RMSE 1.007x the truth's,
/// the response 58% off over the excited band). Its diagnosis keeps no effect, so it is trimmed
/// as the plain fit trims it: the 1/2, within 2% of the truth's response over the band.
#[test]
fn a_general_size_whose_diagnosis_kept_no_effect_is_trimmed() {
    let r = default_run_on_fixture("zoo_seed44_0183_lead.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    assert_eq!(
        choice.scores[choice.chosen].name, "general 1/2",
        "{}",
        choice.reason
    );
    assert!(
        choice.reason.contains("trimmed from general 1/4"),
        "{}",
        choice.reason
    );
    // the zoo's excited band of this case, 0.83 to 886 rad/s
    response_within(
        &dg.diagnosis.model,
        "(2.234364791521463 s + 11.940820098840119)/\
         (0.001807056879409209 s^2 + 0.16613470994653742 s + 1)",
        &[0.829, 3.32, 14.8, 47.3, 150.0, 400.0, 885.6],
        0.02,
    );
}

/// `m`'s response within `tol` of `truth`'s (relative to it) at each of `omega` (rad/s).
fn response_within(m: &ident::oe::FracModel, truth: &str, omega: &[f64], tol: f64) {
    let tf = m.tf(&m.values()).unwrap();
    let truth: fracsim::tf::FracTf = truth.parse().unwrap();
    for &w in omega {
        let (g, want) = (tf.freq_response(w), truth.freq_response(w));
        let e = (g - want).norm() / want.norm();
        assert!(e < tol, "at {w} rad/s: {g} against {want} ({e})");
    }
}

/// The default run on zoo case `fixture`: no delay kept, and the chosen structure's final model
/// within 10% of `oracle` held out (the truth's held-out RMSE on the same samples, the zoo's
/// oracle). The report, for the test's own checks.
fn no_delay_and_within_the_oracle(fixture: &str, oracle: f64) -> ident::app::time::TimeReport {
    let r = default_run_on_fixture(fixture);
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    assert!(
        !names(&dg.diagnosis).contains(&"delay") && dg.diagnosis.model.delay.is_none(),
        "{:?} {}",
        names(&dg.diagnosis),
        choice.reason
    );
    let held = choice.scores[choice.chosen].rmse_after.unwrap();
    assert!(
        held <= 1.1 * oracle,
        "held-out RMSE {held}: {}",
        choice.reason
    );
    r
}

/// The benchmark zoo's two-mode case 0179 (seed 44, `tests/data/README.md`): a lag of 11 ms and
/// modes at 55 Hz and 121 Hz, `7.90/(1.60e-13 s^5 + ... + 1)`, dt 0.21 ms, a multisine of nine
/// tones over 0.52 s (not periodic within the record). Welch's estimate has 18 frequencies, most
/// of them leakage between the tones, and no size's start on it holds the two modes: the
/// general structure's fits from it ended 7x the truth's held-out RMSE, and the PMSM kept a
/// delay and a periodic disturbance at a mode's frequency in their stead (4.5x). The sizes
/// ranked on an ARX model's response are fitted too, and a fifth order holds both modes (the
/// third order with the resonant pair that takes a kept delay's place holds them too): the
/// model chosen keeps no effect, predicts within 10% of the truth's held-out RMSE (7.2610e-2,
/// the zoo's oracle on the same samples) and its response is within 1% of the truth's over the
/// band (the zoo's measure: 0.06-0.09% measured).
#[test]
fn an_arx_response_gives_the_modes_a_leaky_welch_estimate_misses() {
    let r = default_run_on_fixture("zoo_seed44_0179_multi_mode.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    let chosen = &choice.scores[choice.chosen];
    assert!(
        names(&dg.diagnosis).is_empty(),
        "{:?} {}",
        names(&dg.diagnosis),
        choice.reason
    );
    let held = chosen.rmse_after.unwrap();
    assert!(held <= 1.1 * 7.2610e-2, "held-out RMSE {held}");
    let truth =
        "7.896742/(1.600870e-13 s^5 + 6.494160e-11 s^4 + 1.201670e-7 s^3 + 2.378875e-5 s^2 \
                 + 0.01240847 s + 1)";
    let band = [
        48.45, 66.35, 96.40, 144.3, 216.7, 319.1, 469.5, 692.2, 1011.7,
    ];
    let e = frf_error(&r.lead.model.text, truth, &band);
    assert!(e < 0.01, "{:.2}% off: {}", 100.0 * e, r.lead.model.text);
}

/// The benchmark zoo's two-mass case 0252 (seed 44, `tests/data/README.md`): a drive train
/// measured at the motor, `(1.648e-5 s^2 + 4.817e-4 s + 1.266)/(5.392e-8 s^3 + 6.921e-6 s^2 +
/// 0.03324 s + 1)` (anti-resonance 44 Hz, resonance 125 Hz), dt 0.372 ms, a random binary input
/// clocked slowly (not periodic), 0.23% noise. The input's power at the resonance is 0.02-0.4% of
/// its largest: Welch's estimate with the 1% input-power rule left the resonance out, the
/// two-mass structure had no start ("the sign of the gain is not determined") and a general
/// 2/3 model was chosen at 5.8x the truth's held-out RMSE. With the bins the coherence trusts
/// the two-mass start finds the resonance (quartic Levy fit), and the two-mass structure fits
/// within 10% of the truth's held-out RMSE (0.051926, the zoo's oracle on the same samples;
/// measured 0.053715). Its residual still depends on the input's changes (the two-mass
/// structure ties its numerator's damping to its denominator's), so the general structure is
/// compared: its 2/3 size, the truth's own, holds out better (measured 0.052247) and is chosen.
#[test]
fn a_two_mass_drive_under_a_slow_binary_input_has_its_resonance_found() {
    let r = default_run_on_fixture("zoo_seed44_0252_two_mass_motor.csv");
    let choice = &r.diagnosis.as_ref().expect("a diagnosis").structures;
    let chosen = &choice.scores[choice.chosen];
    assert!(
        ["two-mass", "general 2/3"].contains(&chosen.name.as_str()),
        "{}",
        choice.reason
    );
    let two_mass = choice.scores.iter().find(|s| s.name == "two-mass").unwrap();
    let held = two_mass.rmse_after.unwrap();
    assert!(held <= 1.1 * 0.051926, "two-mass held-out RMSE {held}");
    let held = chosen.rmse_after.unwrap();
    assert!(held <= 1.02 * 0.051926, "held-out RMSE {held}");
}

/// The benchmark zoo's dead-band case 0113 (seed 44, `tests/data/README.md`): a PMSM behind a
/// dead band under a chirp. The first round keeps a power law (an odd input map that bends the
/// chirp's small amplitudes down, as a dead band does), the second the dead band, after which the
/// power law adds nothing: the backward step drops it and says it stood in for the dead band.
#[test]
fn an_effect_that_stood_in_for_one_found_later_is_dropped() {
    let r = default_run_on_fixture("zoo_seed44_0113_deadband.csv");
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    assert_eq!(names(d), ["deadzone"], "{:?}", d.rejected);
    let dropped = d.rejected.iter().find(|e| e.name == "power_law").unwrap();
    assert!(
        dropped.reason.contains("once deadzone was kept"),
        "{}",
        dropped.reason
    );
    let width = d.effects[0].params["width"];
    assert!((width - 1.0695).abs() < 0.02, "width {width}");
}

/// The benchmark zoo's dead-band case 0188 (seed 44, `tests/data/README.md`): the diagnosis keeps
/// a deadzone, and the final model's own verdict evaluates it at its values (no iteration
/// allowed). Its start is a stationary point, so the solver's first test ends the evaluation as
/// a small gradient instead of the iteration budget; the verdict took that for a fit that ran
/// and never moved from its start (with the initial state's undetermined levels making the
/// covariance singular) and called the model unusable, exit 1.
#[test]
fn a_final_model_evaluated_at_a_stationary_point_is_judged_as_evaluated() {
    let r = default_run_on_fixture("zoo_seed44_0188_deadband.csv");
    assert!(r.diagnosis.is_some(), "{}", r.model_is);
    assert!(r.lead.usable, "{:?}", r.lead.problems);
    assert!(
        !r.lead.problems.iter().any(|p| p.contains("never moved")),
        "{:?}",
        r.lead.problems
    );
}

/// A step from rest, two input levels: the speed rests, then moves one way. Friction then acts
/// exactly while the input is at its second level: a lower gain and an offset give the same
/// record, so friction is named ambiguous with them, not fitted.
#[test]
fn friction_under_a_step_from_rest_is_ambiguous_with_the_gain() {
    let mut u = vec![0.0; N / 5];
    u.resize(N, 2.0);
    let rec = generate(
        &u,
        Hidden {
            coulomb: 0.3,
            ..Default::default()
        },
        13,
    );
    let (_, d) = run(&rec, true);
    assert!(!names(&d).contains(&"coulomb_friction"), "{:?}", names(&d));
    assert!(
        d.ambiguous
            .iter()
            .any(|a| a.name == "coulomb_friction" && a.confused_with == "gain and offset"),
        "{:?}",
        d.ambiguous
    );
}

/// Steps to -1, 0 and +1 (one magnitude about zero) through a dead band: an odd input map is a
/// gain on these levels, so the dead band is named ambiguous with the gain, not fitted.
#[test]
fn a_dead_band_under_levels_of_one_magnitude_is_ambiguous_with_the_gain() {
    let u: Vec<f64> = (0..N)
        .map(|k| [0.0, 1.0, 0.0, -1.0, 1.0, -1.0, 0.0][(k / (N / 7)).min(6)])
        .collect();
    let rec = generate(
        &u,
        Hidden {
            dz: Some(0.3),
            ..Default::default()
        },
        14,
    );
    let (_, d) = run(&rec, true);
    assert!(!names(&d).contains(&"deadzone"), "{:?}", names(&d));
    assert!(
        d.ambiguous
            .iter()
            .any(|a| a.name == "deadzone" && a.confused_with == "gain and offset"),
        "{:?}",
        d.ambiguous
    );
}

/// The benchmark zoo's saturation case 0189 (seed 44, `tests/data/README.md`): without the
/// saturation the PMSM's base fit leaves three terms undetermined (not usable), and the
/// comparison chose from usable base fits alone: a first order with the saturation, held out
/// 1.35x the truth's RMSE. The PMSM's final model, with the saturation, is usable judged at its
/// values as the report judges the model it leads with (its undetermined terms held), and is
/// chosen: within 10% of the truth's held-out RMSE (0.67885, the zoo's oracle on the same
/// samples), with the saturation kept and the final model usable. (A PMSM base fit whose second
/// term is not determined is refitted as its single fractional mode, usable on its own: that
/// reduced structure, when it is the one chosen, is the PMSM's own.)
#[test]
fn a_structure_whose_effects_mend_its_base_fit_is_chosen_on_its_final_model() {
    let r = default_run_on_fixture("zoo_seed44_0189_saturation.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    let chosen = &choice.scores[choice.chosen];
    assert!(chosen.name.starts_with("pmsm"), "{}", choice.reason);
    let mended = chosen.problems_after.as_deref() == Some(&[][..]);
    assert!(
        chosen.name.ends_with("(reduced)") || (!chosen.problems.is_empty() && mended),
        "{}",
        choice.reason
    );
    assert!(names(&dg.diagnosis).contains(&"saturation"));
    let held = r.lead.fit.validation.as_ref().unwrap().rmse;
    assert!(
        held <= 1.1 * 0.67885,
        "held-out RMSE {held}: {}",
        choice.reason
    );
    assert!(r.lead.usable, "{:?}", r.lead.problems);
}

/// The benchmark zoo's integrator case 0006 (seed 44, `tests/data/README.md`): an integrator with
/// a lag of 8.2 ms, `26.4/(s (8.2e-3 s + 1))`, under a sweep, 8.9% noise, no delay. The first
/// order, a pole short, kept a delay of 7.1 ms in the pole's stead and tied the second order,
/// which needs none, on the held-out part (0.4% behind it), with a BIC only 1.2 lower; it was
/// chosen by the lower BIC. A BIC difference under 2 is no evidence: the tie goes to the fewer
/// effects, and the report has no delay, within 10% of the truth's held-out RMSE (2.16477, the
/// zoo's oracle on the same samples).
#[test]
fn a_delay_standing_in_for_a_pole_does_not_win_an_even_tie() {
    no_delay_and_within_the_oracle("zoo_seed44_0006_integrator.csv", 2.16477);
}

/// The same record: the PMSM with an integrator has a term a position behind one lag does not
/// determine (not usable), and without `K/(s (T s + 1))` among the candidates the second order
/// stood in with a pole at 0.64 rad/s, below the excited band (2.5-45 rad/s), 10% off the
/// truth's response over it. With it, the integrator is chosen and its response is within 3% of
/// the truth's over the band.
#[test]
fn a_position_behind_one_lag_is_fitted_with_its_integrator() {
    let r = default_run_on_fixture("zoo_seed44_0006_integrator.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let choice = &dg.structures;
    assert_eq!(
        choice.scores[choice.chosen].name, "first-order + integrator",
        "{}",
        choice.reason
    );
    // the zoo's excited band of this case, 2.5 to 45 rad/s
    response_within(
        &dg.diagnosis.model,
        "26.40278798856778/(0.008203809531801673 s^2 + s)",
        &[2.512, 5.024, 10.05, 19.99, 44.93],
        0.03,
    );
}

/// The benchmark zoo's feed-through case 0055 (seed 44, `tests/data/README.md`): `0.815 + 1.92/
/// (3.7e-3 s + 1)` under a band-limited multisine, 8.2% noise. The record's feed-through screen
/// cannot tell an instant response on that input (its lag-0 change is predicted by its past):
/// the feed-through structure is compared, but its base fit is left out (not usable, or far
/// behind), and a first order kept a one-sample advance of the input (a time-stamp skew) in the
/// direct term's stead. A kept advance on a structure with no feed-through brings the general
/// structure in, whose sizes have a direct term; counted as a parameter, the advance no longer
/// wins the tie by BIC: the report ends on the general structure with no skew, within 10% of the
/// truth's held-out RMSE (2.42143, the zoo's oracle on the same samples).
#[test]
fn an_instant_response_is_not_taken_for_a_time_stamp_skew() {
    let r = no_delay_and_within_the_oracle("zoo_seed44_0055_feedthrough.csv", 2.42143);
    let choice = &r.diagnosis.as_ref().expect("a diagnosis").structures;
    assert!(
        choice
            .reason
            .contains("its output leads the recorded input"),
        "{}",
        choice.reason
    );
}

/// The value of parameter `name` in the final model of `d`.
fn final_value(d: &Diagnosis, name: &str) -> f64 {
    let i = d
        .model
        .index_of(name)
        .unwrap_or_else(|| panic!("no {name} in {}", d.final_model));
    d.model.params[i].value
}

/// A static input map behind an input offset (fixture `file`), kept with the defaults: the map
/// `effect` with its parameter `(name, truth)` and the model's input offset near `offset`, each
/// within 10%.
fn off_centre_map_kept(file: &str, effect: (&str, &str, f64), offset: f64) {
    let (effect, name, truth) = effect;
    let r = default_run_on_fixture(file);
    let d = &r.diagnosis.as_ref().expect("a diagnosis").diagnosis;
    let v = kept_effect(d, effect).params[name];
    assert!(
        (v / truth - 1.0).abs() < 0.1,
        "{file}: {name} = {v} (truth {truth})"
    );
    let c = final_value(d, "u_offset");
    assert!(
        (c / offset - 1.0).abs() < 0.1,
        "{file}: u_offset = {c} (truth {offset})"
    );
}

/// The benchmark zoo's case 0122 of seed 45 (`tests/data/README.md`): a first order behind
/// `clamp(u + 0.437, -2.273, 2.273)`, a staircase of 315 samples. Clamped about the input's
/// zero, the saturation took 75% off the estimation residual and predicted the held-out part 15%
/// worse (it clips the other side there): it was rejected. Off the centre it is kept.
#[test]
fn a_clamp_off_the_inputs_centre_is_kept_with_its_offset() {
    off_centre_map_kept(
        "zoo_seed45_0122_two_effects.csv",
        ("saturation", "level", 2.2735),
        0.43722,
    );
}

/// The benchmark zoo's case 0047 of seed 45: a PMSM behind a dead band of half width 1.961 about
/// an input offset of -1.743 under a multisine; the dead band about the input's zero was not
/// found (a friction and a dead band stood in, neither right). Off the centre it is kept.
#[test]
fn a_dead_band_off_the_inputs_centre_is_kept_with_its_offset() {
    off_centre_map_kept(
        "zoo_seed45_0047_two_effects.csv",
        ("deadzone", "width", 1.9608),
        -1.7433,
    );
}

/// The benchmark zoo's case 0236 of seed 45: the PMSM `70.49/(5.2546e-3 s^1.1457 + 0.050357
/// s^0.80235 + 1)` with Coulomb friction 1.147 under a PRBS. Its base fits, bent by the friction,
/// leave the second term undetermined, and the commensurate structure reduced to one mode was
/// chosen with the friction and a 0.16 ms delay standing in for that term. Carried to the full
/// structures, the friction is kept without a delay.
#[test]
fn an_effect_is_carried_to_a_reduced_structure_in_full() {
    let r = default_run_on_fixture("zoo_seed45_0236_friction_reversal.csv");
    let dg = r.diagnosis.as_ref().expect("a diagnosis");
    let d = &dg.diagnosis;
    assert_eq!(names(d), ["coulomb_friction"], "{}", dg.structures.reason);
    let chosen = &dg.structures.scores[dg.structures.chosen].name;
    assert!(
        !chosen.contains("reduced"),
        "{chosen}: {}",
        dg.structures.reason
    );
    let vc = param(d, "coulomb_friction", "Vc");
    assert!((vc / 1.1467 - 1.0).abs() < 0.1, "Vc = {vc} (truth 1.147)");
}
