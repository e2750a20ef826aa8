//! Records as they come: the plant is not at rest when the record starts. Each record is cut out
//! of a longer run of the paper's PMSM ([`super::truth`], an independent Grunwald-Letnikov truth
//! with the input held, 1 ms) that began at rest before the record: the part before is the record's
//! unknown past. With the defaults (operating point from the first samples, a fitted output offset,
//! the initial state estimated) each fits at the noise floor; from rest it does not.

use super::truth::{noise, response, PMSM};
use fracsim::prbs::Prbs;
use ident::data::{OffsetMode, Record};
use ident::oe::{identify, score, FracModel, IdentOptions, Identification, InitialState};

const DT: f64 = 1e-3;
const SIGMA: f64 = 0.1;

/// The paper's PRBS (order 7, 3 ms clock) of +-3 V around `level`, three periods (1143 samples).
fn prbs_around(level: f64) -> Vec<f64> {
    Prbs {
        periods: 3,
        amplitude: 3.0,
        offset: level,
        ..Prbs::paper()
    }
    .signal(DT)
    .unwrap()
}

/// The record: `past` then `rec` run from rest, the `past` samples cut away, noise added.
/// Returns the record and its noise.
fn cut(past: &[f64], rec: &[f64], seed: u64) -> (Record, Vec<f64>) {
    let u: Vec<f64> = past.iter().chain(rec).copied().collect();
    let y = response(&PMSM, &u, DT);
    let e = noise(rec.len(), SIGMA, seed);
    let y: Vec<f64> = y[past.len()..].iter().zip(&e).map(|(y, e)| y + e).collect();
    (Record::from_samples(rec, &y, DT).unwrap(), e)
}

fn fit(rec: &Record, initial: InitialState) -> Identification {
    let opts = IdentOptions {
        initial,
        ..IdentOptions::default()
    };
    identify(rec, &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9), &opts).unwrap()
}

/// With the defaults: validation RMSE within 7% of the noise's own RMS over the validation window
/// (the floor a perfect model reaches), the gain within 2% and each order within 0.05 of the
/// truth; from rest (when `rest_fails`) the validation RMSE is at least twice sigma, so the test
/// tells the two apart. Why 7% (measured on the record in motion, the others stay within 3.5%:
/// mid-transient 3.3%, ramp 2.6%, the constant input while moving 2.0%): its true past (10 V
/// for 0.3 s after rest) is on no candidate window, and the past the data determine there is one
/// level held since before the record (`ident::oe::past`): 5.6% over the floor. A finer window
/// reaches 3.6% (T/8) to 4.3% (T/64), the true window at 0.3 s with both levels fitted 3.2%, the
/// four fixed windows of before 3.5%; but none is determined by the estimation part: the best
/// lowers its sum of squares by 0.78%, less than BIC asks even were all of its 800 residuals
/// independent (0.83%), and its older level is 0.81 +- 0.93 V (at 0.3 s: -2.93 +- 2.50 against the
/// truth's -7). The 2-point difference on the held-out part is the slow tail of a past the
/// record does not determine, not the plant (K, zeta, theta within 0.2%, 0.005, 0.002 of the
/// truth with one level or with the true window).
fn check(name: &str, (rec, noise): &(Record, Vec<f64>), rest_fails: bool) {
    let id = fit(rec, InitialState::Estimate);
    let rest = fit(rec, InitialState::Rest);
    eprintln!(
        "{name}: problems {:?}, warnings {:?}",
        id.problems, id.report.warnings
    );
    let (v, vr) = (id.validation.unwrap(), rest.validation.unwrap());
    let p = &id.report.params;
    eprintln!(
        "{name}: estimated state: validation RMSE {:.4} ({:.2}%), K {:.4} zeta {:.4} theta {:.4}; \
         from rest: RMSE {:.4} ({:.2}%), {}",
        v.rmse,
        v.nrmse_percent,
        p[0].value,
        p[3].value,
        p[4].value,
        vr.rmse,
        vr.nrmse_percent,
        rest.tf
    );
    let w = &noise[id.split..];
    let floor = (w.iter().map(|e| e * e).sum::<f64>() / w.len() as f64).sqrt();
    eprintln!("{name}: validation {:.4}, floor {floor:.4}", v.rmse);
    assert!(v.rmse <= 1.07 * floor, "{name}: {} (floor {floor})", v.rmse);
    assert!(
        (p[0].value / 6.82 - 1.0).abs() < 0.02,
        "{name}: K {}",
        p[0].value
    );
    assert!(
        (p[3].value - 0.92).abs() < 0.05,
        "{name}: zeta {}",
        p[3].value
    );
    assert!(
        (p[4].value - 0.8252).abs() < 0.05,
        "{name}: theta {}",
        p[4].value
    );
    if rest_fails {
        assert!(vr.rmse >= 2.0 * SIGMA, "{name}: from rest {}", vr.rmse);
    }
}

#[test]
fn a_record_that_starts_in_motion_fits_at_the_noise_floor() {
    // 0.3 s at 10 V from rest: spun up, but a fractional plant is still creeping.
    check(
        "in motion",
        &cut(&vec![10.0; 300], &prbs_around(10.0), 21),
        true,
    );
}

#[test]
fn a_record_that_starts_mid_transient_fits_at_the_noise_floor() {
    // At rest, then a 10 V step 40 ms before the record: it starts while the speed rises.
    let mut past = vec![0.0; 200];
    past.extend(vec![10.0; 40]);
    check("mid-transient", &cut(&past, &prbs_around(10.0), 22), true);
}

#[test]
fn a_record_that_starts_on_a_ramp_fits_at_the_noise_floor() {
    // The input ramps from 0 V (0.4 s before the record) to 10 V 0.2 s into it, then the PRBS.
    let ramp = |k: usize| 10.0 * k as f64 / 600.0;
    let past: Vec<f64> = (0..400).map(ramp).collect();
    let mut rec: Vec<f64> = (400..600).map(ramp).collect();
    rec.extend(prbs_around(10.0));
    // From rest it fits nearly as well here (the ramp's past is slow): only the estimate is
    // checked.
    check("ramp", &cut(&past, &rec, 23), false);
}

/// The default initial state (`auto`) tells a record that rests before its first input change
/// from one whose input stands still while the output still moves: 150 ms at 0 V then a 10 V step
/// and the PRBS is fitted from rest, at the noise floor, with no past input; the same input whose
/// record begins 40 ms after an earlier 10 V step (the speed rising during the constant part) is
/// fitted with its past estimated, at the noise floor too. Each against the GL truth's parameters.
#[test]
fn the_default_initial_state_is_rest_only_for_a_record_at_rest() {
    let mut rec = vec![0.0; 150];
    rec.extend(vec![10.0; 100]);
    rec.extend(prbs_around(10.0));
    let idle = cut(&[], &rec, 24);
    assert_eq!(idle.0.rests_until(), Some(150));
    let id = fit(&idle.0, InitialState::Auto);
    assert_eq!(id.initial.state, "rest", "{}", id.initial.reason);
    assert!(id.model.past.is_none());
    let w = &idle.1[id.split..];
    let floor = (w.iter().map(|e| e * e).sum::<f64>() / w.len() as f64).sqrt();
    let v = id.validation.unwrap();
    eprintln!("at rest: RMSE {:.4} (floor {floor:.4}), {}", v.rmse, id.tf);
    assert!(v.rmse <= 1.05 * floor, "{} (floor {floor})", v.rmse);
    assert!((id.report.params[0].value / 6.82 - 1.0).abs() < 0.02);

    let mut moving = vec![10.0; 150];
    moving.extend(vec![10.0; 100]);
    moving.extend(prbs_around(10.0));
    let mut past = vec![0.0; 200];
    past.extend(vec![10.0; 40]);
    let late = cut(&past, &moving, 25);
    assert_eq!(late.0.rests_until(), None);
    let id = fit(&late.0, InitialState::Auto);
    assert_eq!(id.initial.state, "estimate", "{}", id.initial.reason);
    check("auto, constant input while moving", &late, false);
}

/// The RMS of `y - yhat` over the first `n` samples.
fn head_rms(rec: &Record, id: &Identification, n: usize) -> f64 {
    let s: f64 = (0..n).map(|k| (rec.y[k] - id.yhat[k]).powi(2)).sum();
    (s / n as f64).sqrt()
}

/// The initial state's past is chosen by what the record determines (docs/design.md §5,
/// `ident::oe::past`). A record that starts 40 ms after a 10 V step (the speed still rising fast:
/// the GL truth's output moves by about 10 sigma over the first 20 samples) needs a finer past
/// than one level held since before the record, and gets it: more than one window, every level
/// determined (finite standard error, none at an edge of its range), every plant parameter
/// determined too and within 3 standard errors (and 2%/0.05) of the truth, and the estimated
/// state reproduces the first 20 samples to the noise (their RMS error within 1.5 sigma; from
/// rest it is many sigma). The same input from true rest (a past of zeros), fitted with
/// `--initial estimate`, keeps one level (the data pay for no finer window) and that level is
/// within 3 standard errors of the truth (the input 0, `-u0` as a deviation).
#[test]
fn the_past_has_the_windows_the_record_determines() {
    let mut past = vec![0.0; 200];
    past.extend(vec![10.0; 40]);
    let (rec, _) = cut(&past, &prbs_around(10.0), 26);
    let id = fit(&rec, InitialState::Estimate);
    let rest = fit(&rec, InitialState::Rest);
    let state = id.model.past.clone().expect("an estimated past");
    let (head, head_rest) = (head_rms(&rec, &id, 20), head_rms(&rec, &rest, 20));
    let levels: Vec<_> = state.levels.iter().map(|&i| &id.report.params[i]).collect();
    eprintln!(
        "moving: edges {:?}, levels {:?}, head RMS {head:.4} (from rest {head_rest:.4}), \
         validation {:.4}",
        state.edges,
        levels
            .iter()
            .map(|p| (p.value, p.std_error))
            .collect::<Vec<_>>(),
        id.validation.as_ref().unwrap().rmse
    );
    assert!(!state.edges.is_empty(), "one level: {:?}", state.edges);
    for p in &levels {
        assert!(
            p.std_error.is_some_and(f64::is_finite) && !p.at_bound,
            "{} = {} +- {:?} (at bound {})",
            p.name,
            p.value,
            p.std_error,
            p.at_bound
        );
    }
    let truth = [("K", 6.82), ("zeta", 0.92), ("theta", 0.8252)];
    for p in id.report.params.iter().filter(|p| p.free) {
        let se = p.std_error.unwrap_or(f64::NAN);
        assert!(se.is_finite() && !p.at_bound, "{} +- {se}", p.name);
        if let Some(&(_, t)) = truth.iter().find(|(n, _)| *n == p.name) {
            assert!(
                (p.value - t).abs() <= 3.0 * se + 0.02 * t,
                "{} = {} +- {se}, truth {t}",
                p.name,
                p.value
            );
        }
    }
    assert!(head <= 1.5 * SIGMA, "first samples: {head}");
    assert!(head_rest >= 5.0 * SIGMA, "from rest: {head_rest}");

    let (still, _) = cut(&[], &prbs_around(10.0), 27);
    let id = fit(&still, InitialState::Estimate);
    let state = id.model.past.clone().expect("an estimated past");
    let p = &id.report.params[state.levels[0]];
    eprintln!(
        "at rest: edges {:?}, level {} +- {:?}",
        state.edges, p.value, p.std_error
    );
    assert!(state.edges.is_empty(), "{:?}", state.edges);
    // At rest at the input 0: the past's deviation from the operating point is -u0.
    let (se, truth) = (p.std_error.expect("a standard error"), -id.offsets.u0);
    assert!(
        (p.value - truth).abs() <= 3.0 * se,
        "{} +- {se}, truth {truth}",
        p.value
    );
}

/// A report's past goes with it (`fracid score`, the JSON report's `spec`): the record of
/// [`the_past_has_the_windows_the_record_determines`] (its fit's past on more than one window)
/// fitted, its model through JSON and back, has the same windows; rescored as `fracid score
/// --as-fitted` does (`ident::app::time::rescore`: the plant held, only the record's output offset
/// and levels refitted, from the given values) it keeps them and reproduces the fit's estimation
/// RMSE (relative 1e-6: the same levels at the same plant); scored on the whole record
/// (`ident::oe::score`) its levels are estimated on those windows too. A model fitted from rest
/// on a record that rests for 150 ms before a 10 V step and the PRBS, scored there with the
/// initial state estimated, gets the windows that record determines as a fit does: one level
/// (the four fixed windows of before were not determined there), within 3 standard errors of the
/// truth (0: at rest at the operating point).
#[test]
fn a_report_keeps_its_past_and_a_score_chooses_one_as_a_fit_does() {
    let mut past = vec![0.0; 200];
    past.extend(vec![10.0; 40]);
    let (rec, _) = cut(&past, &prbs_around(10.0), 26);
    let id = fit(&rec, InitialState::Estimate);
    let windows = id.model.past.clone().expect("an estimated past");
    assert!(!windows.edges.is_empty(), "{:?}", windows.edges);
    let text = serde_json::to_string(&id.model).unwrap();
    let back: FracModel = serde_json::from_str(&text).unwrap();
    assert_eq!(back.past, id.model.past);

    let mut held = back.clone();
    for (i, p) in held.params.iter_mut().enumerate() {
        p.free = p.name == "y_offset" || windows.levels.contains(&i);
    }
    let opts = IdentOptions {
        initial: InitialState::Estimate,
        start: ident::oe::StartMode::Given,
        ..IdentOptions::default()
    };
    let again = identify(&rec, &held, &opts).unwrap();
    let edges = |p: &Option<ident::oe::PastInput>| p.as_ref().map(|p| p.edges.clone());
    assert_eq!(edges(&again.model.past), Some(windows.edges.clone()));
    let (a, b) = (again.estimation.rmse, id.estimation.rmse);
    eprintln!("rescored estimation RMSE {a:.8} vs fitted {b:.8}");
    assert!((a / b - 1.0).abs() < 1e-6, "{a} vs {b}");
    let scored = score(&back, &rec, OffsetMode::Initial, InitialState::Estimate).unwrap();
    assert_eq!(edges(&scored.past), Some(windows.edges.clone()));

    let mut u = vec![0.0; 150];
    u.extend(vec![10.0; 100]);
    u.extend(prbs_around(10.0));
    let (idle, _) = cut(&[], &u, 24);
    let rest = fit(&idle, InitialState::Rest);
    assert!(rest.model.past.is_none());
    let s = score(
        &rest.model,
        &idle,
        OffsetMode::Initial,
        InitialState::Estimate,
    )
    .unwrap();
    let names: Vec<&str> = s.record_params.iter().map(|p| p.name.as_str()).collect();
    eprintln!(
        "scored from a model without past: {:?} {names:?}",
        edges(&s.past)
    );
    assert_eq!(edges(&s.past), Some(vec![]));
    let level = s
        .record_params
        .iter()
        .find(|p| p.name == "u_past0")
        .expect("a level");
    let (se, truth) = (level.std_error.expect("a standard error"), -s.offsets.u0);
    assert!(
        (level.value - truth).abs() <= 3.0 * se,
        "{} +- {se}, truth {truth}",
        level.value
    );
}

/// Records fitted jointly each get the windows of the past their data determine: the record that
/// starts 40 ms after a step (the first: its fit's windows, more than one) with a record that
/// truly rests (the second: the linear screen at the first record's model keeps one level, which
/// ends determined, within 3 standard errors of its truth `-u0`); the plant within 2% (gain) and
/// 0.05 (orders) of the GL truth. With the four fixed windows the resting record's older levels
/// were not determined.
#[test]
fn records_fitted_jointly_each_get_the_windows_their_data_determine() {
    let mut past = vec![0.0; 200];
    past.extend(vec![10.0; 40]);
    let (moving, _) = cut(&past, &prbs_around(10.0), 26);
    let (still, _) = cut(&[], &prbs_around(10.0), 27);
    let opts = IdentOptions {
        initial: InitialState::Estimate,
        ..IdentOptions::default()
    };
    let j = ident::oe::identify_joint(
        &[moving, still.clone()],
        &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9),
        &opts,
    )
    .unwrap();
    let first = j.model.past.clone().expect("the first record's past");
    assert!(!first.edges.is_empty(), "{:?}", first.edges);
    let second: Vec<_> = j
        .report
        .params
        .iter()
        .filter(|p| p.name.starts_with("u_past") && p.name.ends_with("@2"))
        .collect();
    eprintln!(
        "joint: first {:?}, second {:?}",
        first.edges,
        second
            .iter()
            .map(|p| (&p.name, p.value, p.std_error))
            .collect::<Vec<_>>()
    );
    assert_eq!(second.len(), 1);
    let (se, truth) = (
        second[0].std_error.expect("a standard error"),
        -j.records[1].0.u0,
    );
    assert!(!second[0].at_bound);
    assert!(
        (second[0].value - truth).abs() <= 3.0 * se,
        "{} +- {se}, truth {truth}",
        second[0].value
    );
    let v = |n: &str| j.report.params[j.model.index_of(n).unwrap()].value;
    assert!((v("K") / 6.82 - 1.0).abs() < 0.02, "K {}", v("K"));
    assert!((v("zeta") - 0.92).abs() < 0.05, "zeta {}", v("zeta"));
    assert!((v("theta") - 0.8252).abs() < 0.05, "theta {}", v("theta"));
}
