//! fracsim against independent truth: the Mittag-Leffler oracle and Grunwald-Letnikov at a fine step.

use fracsim::special::step_response_first_order;
use fracsim::{gl, lsim, ApproxSpec, FracTf, Method, Simulator};

const K: f64 = 6.77;
const A: f64 = 0.0064;
const Q: f64 = 0.89;
/// docs/design.md §3: the oracle values at 1, 3, 10 and 30 ms.
const ORACLE: [(f64, f64); 4] = [
    (0.001, 1.958077),
    (0.003, 3.943589),
    (0.010, 6.018918),
    (0.030, 6.615241),
];

fn first_order() -> FracTf {
    format!("{K}/({A} s^{Q} + 1)").parse().unwrap()
}

/// Worst relative error at the oracle times of a step response sampled at `dt` (y[k] is t = k dt).
fn worst_oracle_error(y: &[f64], dt: f64) -> f64 {
    ORACLE
        .iter()
        .map(|&(t, exact)| {
            let k = (t / dt).round() as usize;
            ((y[k] - exact) / exact).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn mittag_leffler_oracle_for_every_method() {
    let dt = 1e-4;
    let u = vec![1.0; 400];
    for (method, tol) in [
        // Measured worst relative errors over the four oracle points (dt = 1e-4, the band then
        // [1e-3, 30 pi/dt] rad/s, now the default [1e-6/dt, 30 pi/dt] within the same bounds; N = 8, exact discretisation for the held step): Oustaloup and
        // Poinot-Trigeassou 4.4e-4, refined 2.4e-5. The promise is 0.5% for every option; the
        // bounds sit at about twice the measured values, so a regression shows.
        (Method::Oustaloup, 1e-3),
        (Method::Refined, 5e-5),
        (Method::Trigeassou, 1e-3),
    ] {
        let spec = ApproxSpec {
            method,
            order: 8,
            band: None,
        };
        let y = lsim(&first_order(), &u, dt, &spec).unwrap();
        let err = worst_oracle_error(&y, dt);
        eprintln!("{method:?}: worst relative error {err:.2e}");
        assert!(err < tol, "{method:?}: {err}");
    }
    let y = gl::simulate_held(&first_order(), &u, dt, gl::HELD_SUBSTEPS).unwrap();
    let err = worst_oracle_error(&y, dt);
    eprintln!("gl (held, Richardson of dt/10 and dt/20): worst relative error {err:.2e}");
    // Measured 8.2e-6.
    assert!(err < 5e-5, "gl: {err}");
}

#[test]
fn default_method_follows_the_oracle_over_the_whole_step() {
    // Between the four tabulated points, the series/asymptotic Mittag-Leffler function (checked
    // against the tabulated values in fracsim's unit tests) is the truth, every 0.5 ms to 50 ms.
    let dt = 1e-4;
    let y = lsim(&first_order(), &vec![1.0; 501], dt, &ApproxSpec::default()).unwrap();
    let worst = (1..=100)
        .map(|i| {
            let t = i as f64 * 5e-4;
            let exact = step_response_first_order(K, A, Q, t);
            ((y[i * 5] - exact) / exact).abs()
        })
        .fold(0.0, f64::max);
    eprintln!("default method, worst relative error over 0.5..50 ms: {worst:.2e}");
    // Measured 3.5e-5 (refined Oustaloup, exact for the held step); 1e-4 bound.
    assert!(worst < 1e-4, "{worst}");
}

#[test]
fn grunwald_letnikov_converges_to_the_oracle() {
    // GL is first order in h: the error at 1 ms halves with h.
    let err_at = |dt: f64| {
        let n = (0.03 / dt).round() as usize + 1;
        let y = gl::simulate(&first_order(), &vec![1.0; n], dt).unwrap();
        // GL's y[k] is t = k dt (the step is applied at k = 0)
        ORACLE
            .iter()
            .map(|&(t, exact)| ((y[(t / dt).round() as usize] - exact) / exact).abs())
            .fold(0.0, f64::max)
    };
    let (e1, e2) = (err_at(2e-5), err_at(1e-5));
    eprintln!("GL worst relative error: h=2e-5 {e1:.2e}, h=1e-5 {e2:.2e}");
    // Measured: 1.13e-2 at h = 2e-5, 5.65e-3 at h = 1e-5, both at t = 1 ms (first order in h).
    assert!(e2 < 7e-3, "{e2}");
    assert!(e2 < 0.6 * e1, "not converging: {e1} -> {e2}");
}

/// An independent reference for a held input, written here and not in fracsim: the implicit
/// Grunwald-Letnikov scheme for `sum_j a_j D^(alpha_j) y = b u` (numerator of order 0) at the fine
/// step `h = dt/n`, the input held over each sample of `dt`, read at the sample instants.
fn gl_held_reference(b: f64, den: &[(f64, f64)], u: &[f64], dt: f64, n: usize) -> Vec<f64> {
    let h = dt / n as f64;
    let m = u.len() * n;
    // combined weights w_j = sum_j a h^-alpha c_j(alpha), c_0 = 1, c_j = c_(j-1) (1 - (alpha+1)/j)
    let mut w = vec![0.0; m];
    for &(a, alpha) in den {
        let mut c = 1.0;
        for (j, wj) in w.iter_mut().enumerate() {
            if j > 0 {
                c *= 1.0 - (alpha + 1.0) / j as f64;
            }
            *wj += a * h.powf(-alpha) * c;
        }
    }
    let mut y = vec![0.0; m];
    for k in 0..m {
        let mut rhs = b * u[k / n];
        for j in 1..=k {
            rhs -= w[j] * y[k - j];
        }
        y[k] = rhs / w[0];
    }
    (0..u.len()).map(|k| y[k * n]).collect()
}

/// The paper's PRBS (order 7, 3 ms clock) of +-3 V, two periods, sampled at 0.5 ms and held.
fn paper_prbs_record() -> (Vec<f64>, f64) {
    let dt = 5e-4;
    let prbs = fracsim::prbs::Prbs {
        periods: 2,
        amplitude: 3.0,
        ..fracsim::prbs::Prbs::paper()
    };
    (prbs.signal(dt).unwrap(), dt)
}

/// RMS of `a - b` over the swing (max - min) of `b`.
fn rms_of_swing(a: &[f64], b: &[f64]) -> f64 {
    let rms = (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
    let (lo, hi) = b
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    rms / (hi - lo)
}

#[test]
fn pmsm_on_a_held_prbs_matches_an_independent_reference() {
    // The paper's time-domain model; truth: GL at dt/20 and dt/40, Richardson-extrapolated. The
    // reference's own error is bounded by comparing it with the extrapolation of dt/10 and dt/20.
    let den = [(2.655e-5, 1.7452), (0.0059, 0.92), (1.0, 0.0)];
    let g: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"
        .parse()
        .unwrap();
    let (u, dt) = paper_prbs_record();
    let gl_n = |n| gl_held_reference(6.82, &den, &u, dt, n);
    let (y10, y20, y40) = (gl_n(10), gl_n(20), gl_n(40));
    let rich =
        |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(c, f)| 2.0 * f - c).collect() };
    let truth = rich(&y20, &y40);
    let truth_err = rms_of_swing(&rich(&y10, &y20), &truth);
    eprintln!(
        "reference: GL dt/20 alone {:.2e}, Richardson(dt/10, dt/20) {truth_err:.2e} of the swing",
        rms_of_swing(&y20, &truth)
    );
    assert!(
        truth_err < 1e-4,
        "the reference itself is not converged: {truth_err}"
    );
    for (name, method, tol) in [
        // Measured 5.0e-5 (refined), 3.9e-4 (Oustaloup, Poinot-Trigeassou), 9.3e-5 (gl); the
        // promise: the default within 0.05% (5e-4), every option within 0.5%. The default's bound
        // is 2e-4 so that a regression to Oustaloup's level fails.
        ("refined (default)", Method::Refined, 2e-4),
        ("oustaloup", Method::Oustaloup, 5e-3),
        ("trigeassou", Method::Trigeassou, 5e-3),
    ] {
        let spec = ApproxSpec {
            method,
            ..ApproxSpec::default()
        };
        let y = lsim(&g, &u, dt, &spec).unwrap();
        let err = rms_of_swing(&y, &truth);
        eprintln!("{name}: RMS error {err:.2e} of the swing");
        assert!(err < tol, "{name}: {err}");
    }
    let y = gl::simulate_held(&g, &u, dt, gl::HELD_SUBSTEPS).unwrap();
    let err = rms_of_swing(&y, &truth);
    eprintln!("gl (library, held): RMS error {err:.2e} of the swing");
    assert!(err < 5e-3, "gl: {err}");
}

#[test]
fn simulator_steps_match_lsim_and_reset() {
    let g: FracTf = "(0.5 s^0.3 + 2)/(0.01 s^1.5 + 0.1 s^0.7 + 1) exp(-0.00035 s)"
        .parse()
        .unwrap();
    let u: Vec<f64> = (0..500).map(|k| ((k as f64) * 0.05).sin()).collect();
    let y = lsim(&g, &u, 1e-4, &ApproxSpec::default()).unwrap();
    let mut sim = Simulator::<f64>::new(&g, 1e-4, &ApproxSpec::default()).unwrap();
    let _ = sim.simulate(&[3.0; 50]);
    sim.reset();
    // The block kernel fuses multiply-adds (FMA) and sums the modes in another order than the
    // per-sample step: equal to rounding, not bit for bit.
    let scale = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for (k, &x) in u.iter().enumerate() {
        let s = sim.step(x);
        assert!((s - y[k]).abs() <= 1e-13 * scale, "k={k}: {s} vs {}", y[k]);
    }
}

#[test]
fn delay_shifts_the_response() {
    let g: FracTf = "1/(0.01 s^0.8 + 1)".parse().unwrap();
    let d = g.clone().with_delay(0.003).unwrap();
    let u = vec![1.0; 200];
    let spec = ApproxSpec::default();
    let y = lsim(&g, &u, 1e-4, &spec).unwrap();
    let yd = lsim(&d, &u, 1e-4, &spec).unwrap();
    for k in 0..30 {
        assert_eq!(yd[k], 0.0);
    }
    for k in 30..200 {
        approx::assert_abs_diff_eq!(yd[k], y[k - 30], epsilon = 1e-12);
    }
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let g = first_order();
    let spec = ApproxSpec::default();
    assert!(lsim(&g, &[1.0, f64::NAN], 1e-3, &spec).is_err());
    assert!(lsim(&g, &[1.0], 0.0, &spec).is_err());
    assert!(lsim(&g, &[1.0], f64::NAN, &spec).is_err());
    let bad_band = ApproxSpec {
        band: Some((10.0, 1.0)),
        ..spec
    };
    assert!(lsim(&g, &[1.0], 1e-3, &bad_band).is_err());
    assert!(gl::simulate(&g, &[1.0], -1.0).is_err());
    assert!(FracTf::pmsm(1.0, f64::INFINITY, 1.0, 0.9, 0.9).is_err());
    assert!("1/(0 s + 0)".parse::<FracTf>().is_err());
}

#[test]
fn extreme_settings_are_errors_not_panics_or_hangs() {
    let g = first_order();
    // A delay of 1e300 s: delay/dt saturated usize and the interpolation index overflowed.
    let far = g.clone().with_delay(1e300).unwrap();
    for dt in [1e-3, 1e-300] {
        assert_eq!(gl::simulate(&far, &[1.0; 50], dt).unwrap(), vec![0.0; 50]);
    }
    // a delay just past the record, with a fractional part
    let past = g.clone().with_delay(0.0505).unwrap();
    assert_eq!(
        gl::simulate(&past, &[1.0; 50], 1e-3).unwrap(),
        vec![0.0; 50]
    );
    // N = 1e8 built 2e8 cells (minutes and gigabytes); usize::MAX overflowed 2N + 1.
    for method in [Method::Oustaloup, Method::Refined, Method::Trigeassou] {
        for order in [100_000_000, usize::MAX] {
            let spec = ApproxSpec {
                method,
                order,
                ..ApproxSpec::default()
            };
            let err = lsim(&g, &[1.0; 10], 1e-3, &spec).unwrap_err().to_string();
            assert!(err.contains("order N"), "{method:?} N = {order}: {err}");
        }
    }
    // ...while N = 0 (one cell) still simulates
    let one_cell = ApproxSpec {
        order: 0,
        ..ApproxSpec::default()
    };
    assert!(lsim(&g, &[1.0; 10], 1e-3, &one_cell).is_ok());
    // dt = 1e300 s: the default band scales with the step ([1e-306, 9.4e-299] rad/s, once it
    // was absolute and empty there); the cells' products underflow, and the error says what
    // failed in a short message, not a panic or 300 digits.
    match lsim(&g, &[1.0; 10], 1e300, &ApproxSpec::default()) {
        Ok(y) => assert!(y.iter().all(|v| v.is_finite()), "{y:?}"),
        Err(e) => assert!(e.to_string().len() < 200, "{e}"),
    }
}

/// `g` with its time axis multiplied by `c` (a record written in other units: `c = 1000` from
/// seconds to milliseconds): `G'(s') = G(c s')`, each coefficient times `c^order`, the delay
/// times `c`.
fn time_scaled(g: &FracTf, c: f64) -> FracTf {
    let scale = |t: &[fracsim::Term]| -> Vec<fracsim::Term> {
        t.iter()
            .map(|t| fracsim::Term {
                coef: t.coef * c.powf(t.order),
                order: t.order,
            })
            .collect()
    };
    FracTf::new(scale(&g.num), scale(&g.den), g.delay * c).unwrap()
}

/// A record's time unit does not change its simulation: the paper's PMSM on a PRBS, sampled at
/// 1 ms in seconds, and the same written in milliseconds, in samples, in microseconds and in
/// hours (the model's coefficients scaled as `a c^nu`, the default band following the step) gives
/// the same samples, for every method. Tolerance 1e-9 of the swing: the approximations are
/// exactly scaled copies of each other (cells at `w/c`, gain `c^-nu`), so only rounding differs;
/// the band's lower edge once sat at 1e-3 rad/s whatever the step, and Xue's correction had a
/// pole at `0.9 f (1 rad/s)^2/w_h`: with the time in samples both moved into the record's band
/// and the step response of the same model was off by up to 75% of its swing.
#[test]
fn the_time_unit_of_a_record_does_not_change_its_simulation() {
    let g: FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
        .parse()
        .unwrap();
    let dt = 1e-3;
    let u = fracsim::prbs::Prbs {
        periods: 5,
        ..fracsim::prbs::Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    for method in [Method::Refined, Method::Oustaloup, Method::Trigeassou] {
        let spec = ApproxSpec {
            method,
            ..ApproxSpec::default()
        };
        let y = lsim(&g, &u, dt, &spec).unwrap();
        let swing = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for c in [1e3, 1.0 / dt, 1e6, 1.0 / 3600.0] {
            let yc = lsim(&time_scaled(&g, c), &u, c * dt, &spec).unwrap();
            let worst = y
                .iter()
                .zip(&yc)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-9 * swing,
                "{method:?}, c = {c}: {worst} of {swing}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests: the model parser and `Display` as a codec, and the invariants of the simulator.

use fracsim::Term;
use num_complex::Complex64;
use proptest::prelude::*;

/// Tokens of the model grammar and near misses, glued into arbitrary sequences.
fn model_ish() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("s".to_string()),
        Just("^".to_string()),
        Just("exp(".to_string()),
        Just("(".to_string()),
        Just(")".to_string()),
        Just("[".to_string()),
        Just("]".to_string()),
        Just("+".to_string()),
        Just("-".to_string()),
        Just("*".to_string()),
        Just("/".to_string()),
        Just(" ".to_string()),
        Just(".".to_string()),
        Just("e".to_string()),
        Just("0".to_string()),
        Just("1e400".to_string()),
        Just("1e-400".to_string()),
        Just("nan".to_string()),
        Just("é".to_string()),
        (0.0f64..1e3).prop_map(|x| x.to_string()),
        (-30.0f64..30.0).prop_map(|x| format!("{x:e}")),
        (0u32..100).prop_map(|x| x.to_string()),
    ];
    prop::collection::vec(token, 0..40).prop_map(|t| t.concat())
}

/// `coef * s^order` terms with positive coefficients and orders in [0, 2], some of them the
/// special cases `Display` writes differently (order 0 and 1, coefficient 1).
fn terms(max: usize) -> impl Strategy<Value = Vec<Term>> {
    let coef = prop_oneof![1 => Just(1.0), 4 => 1e-6f64..1e4];
    let order = prop_oneof![1 => Just(0.0), 1 => Just(1.0), 1 => Just(2.0), 5 => 0.0f64..=2.0];
    prop::collection::vec((coef, order).prop_map(|(c, o)| Term::new(c, o)), 1..=max)
}

fn delay() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), 1e-6f64..1.0]
}

/// `G(j w)` from the terms directly, with num-complex's own complex power.
fn direct(num: &[Term], den: &[Term], delay: f64, w: f64) -> Complex64 {
    let jw = Complex64::new(0.0, w);
    let poly = |t: &[Term]| -> Complex64 { t.iter().map(|t| jw.powf(t.order) * t.coef).sum() };
    poly(num) / poly(den) * (-jw * delay).exp()
}

/// A model written the way the test (not `Display`) spells it.
fn spell(num: &[Term], den: &[Term], delay: f64) -> String {
    let poly = |t: &[Term]| {
        t.iter()
            .map(|t| format!("{:e}*s^{}", t.coef, t.order))
            .collect::<Vec<_>>()
            .join(" + ")
    };
    format!("({}) / ({}) * exp(-{delay:e} s)", poly(num), poly(den))
}

proptest! {
    #[test]
    fn parser_never_panics_on_arbitrary_text(src in ".*") {
        let _ = src.parse::<FracTf>();
    }

    #[test]
    fn parser_never_panics_on_token_soup(src in model_ish()) {
        if let Err(e) = src.parse::<FracTf>() {
            // messages in words, never the lexer's token names
            let m = e.to_string();
            for name in ["RParen", "LParen", "Star", "Caret", "Slash", "Num(", "Plus", "Minus"] {
                prop_assert!(!m.contains(name), "{}: {}", src, m);
            }
        }
        if let Ok(g) = src.parse::<FracTf>() {
            // whatever parses is a valid model: it displays and parses back to itself
            let again: FracTf = g.to_string().parse().unwrap();
            prop_assert_eq!(again, g);
        }
    }

    #[test]
    fn display_then_parse_is_the_identity(num in terms(4), den in terms(4), tau in delay()) {
        let g = FracTf::new(num, den, tau).unwrap();
        let text = g.to_string();
        let again: FracTf = text.parse().unwrap();
        prop_assert_eq!(&again, &g, "{}", text);
    }

    #[test]
    fn parsed_frequency_response_is_the_direct_evaluation(
        num in terms(3),
        den in terms(3),
        tau in delay(),
        w in 1e-3f64..1e5,
    ) {
        let g: FracTf = spell(&num, &den, tau).parse().unwrap();
        let (h, exact) = (g.freq_response(w), direct(&num, &den, tau, w));
        // The parser merges and reorders terms: the rounding is a few ulps of the largest term,
        // relative to the sum it cancels down to (its condition number), in each polynomial.
        let one = [Term::new(1.0, 0.0)];
        let cond = |t: &[Term]| {
            t.iter().map(|t| t.coef * w.powf(t.order)).sum::<f64>() / direct(t, &one, 0.0, w).norm()
        };
        let tol = 1e-12 * exact.norm() * cond(&num) * cond(&den);
        prop_assert!((h - exact).norm() <= tol.max(1e-300), "{h} vs {exact} (tol {tol})");
    }
}

/// Stable models for simulation: `(K + sum b_i s^beta_i) / (1 + sum a_j s^alpha_j) exp(-tau s)`
/// with positive coefficients (`a_j` and `b_i / K` at most `small`), denominator orders in
/// `[lo, 1.9]` (no poles in the closed right half-plane) and numerator orders in `[lo, top]`, `top`
/// the highest order of the denominator.
fn stable_model(lo: f64, small: f64) -> impl Strategy<Value = FracTf> {
    let den = prop::collection::vec((1e-4..small, lo..1.9), 1..=3);
    let num = prop::collection::vec((1e-3..small, 0.0f64..=1.0), 0..=1);
    (den, 0.1f64..10.0, num, 0.0f64..5e-3).prop_map(move |(den, k, num, tau)| {
        let top = den.iter().map(|d| d.1).fold(0.0, f64::max);
        let mut d: Vec<Term> = den.into_iter().map(|(c, o)| Term::new(c, o)).collect();
        d.push(Term::new(1.0, 0.0));
        let mut n = vec![Term::new(k, 0.0)];
        n.extend(
            num.into_iter()
                .map(|(c, f)| Term::new(c * k, lo + f * (top - lo))),
        );
        FracTf::new(n, d, tau).unwrap()
    })
}

fn signal(len: usize) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-10.0f64..10.0, len)
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn simulation_is_linear(
        g in stable_model(0.05, 0.1),
        u1 in signal(300),
        u2 in signal(300),
        a in -5.0f64..5.0,
        b in -5.0f64..5.0,
    ) {
        let (dt, spec) = (1e-3, ApproxSpec::default());
        let mix: Vec<f64> = u1.iter().zip(&u2).map(|(x, y)| a * x + b * y).collect();
        let y1 = lsim(&g, &u1, dt, &spec).unwrap();
        let y2 = lsim(&g, &u2, dt, &spec).unwrap();
        let y = lsim(&g, &mix, dt, &spec).unwrap();
        let scale = a.abs() * max_abs(&y1) + b.abs() * max_abs(&y2);
        for k in 0..y.len() {
            let want = a * y1[k] + b * y2[k];
            prop_assert!((y[k] - want).abs() <= 1e-9 * scale, "{g}: sample {k}: {} vs {want}", y[k]);
        }
    }

    #[test]
    fn simulation_is_time_invariant(g in stable_model(0.05, 0.1), u in signal(200), shift in 1usize..100) {
        let (dt, spec) = (1e-3, ApproxSpec::default());
        let mut shifted = vec![0.0; shift];
        shifted.extend_from_slice(&u);
        let y = lsim(&g, &u, dt, &spec).unwrap();
        let ys = lsim(&g, &shifted, dt, &spec).unwrap();
        // From rest, zeros in give exact zeros out: the states after the shift are the same.
        prop_assert!(ys[..shift].iter().all(|&v| v == 0.0), "{g}: output before the input");
        prop_assert_eq!(&ys[shift..], &y[..], "{}", g);
    }

    /// The poles of a model found from the poles of a nearby one (the cache's hint: every value
    /// within 5%, here each coefficient and order moved by up to 1%) give the same model as the
    /// poles found cold: the frequency responses agree to 1e-9 relative across the band (the
    /// expansion check allows 1e-6; two root sets of the same `H` differ by rounding, or by modes
    /// of a near-cancelling pole-zero pair whose weight is at rounding).
    #[test]
    fn poles_from_a_nearby_model_give_the_cold_model(
        g in stable_model(0.05, 0.1),
        moves in prop::collection::vec((-0.01f64..0.01, -0.01f64..0.01), 4),
    ) {
        use fracsim::modal::{pole_residue, RootsCache};
        let pairs = |t: &[Term]| t.iter().map(|t| (t.coef, t.order)).collect::<Vec<_>>();
        let (num, den) = (pairs(&g.num), pairs(&g.den));
        let near: Vec<(f64, f64)> = den
            .iter()
            .zip(&moves)
            .map(|(&(c, o), &(mc, mo))| (c * (1.0 + mc), if o == 0.0 { 0.0 } else { o * (1.0 + mo) }))
            .collect();
        let (band, spec) = ((1e-3, 30.0 * std::f64::consts::PI / 1e-3), ApproxSpec::default());
        let cold = pole_residue::<f64>(&num, &den, band, &spec);
        let (nearby, warm) = RootsCache::new().enter(|| {
            let nearby = pole_residue::<f64>(&num, &near, band, &spec);
            (nearby, pole_residue::<f64>(&num, &den, band, &spec))
        });
        match (cold, warm) {
            (Ok(cold), Ok(warm)) => {
                for i in 0..40 {
                    let w = band.0 * (band.1 / band.0).powf(i as f64 / 39.0);
                    let (a, b) = (cold.freq_response(w), warm.freq_response(w));
                    prop_assert!((a - b).norm() <= 1e-9 * a.norm(), "{g} (nearby {near:?}: {}): at {w} rad/s {a} cold, {b} warm", nearby.is_ok());
                }
            }
            (Err(_), Err(_)) => {}
            (c, w) => prop_assert!(false, "{g}: cold {c:?}, warm {w:?}"),
        }
    }

    #[test]
    fn step_response_settles_at_the_dc_gain(g in stable_model(0.7, 0.03)) {
        // 20 s at 1 ms. Each term c s^a (a >= 0.7, c <= 0.03 relative) leaves a tail
        // c t^-a / Gamma(1 - a) <= 1.3e-3 at 20 s, at most four of them; the default band's lower
        // edge, 1e-3 rad/s, costs c 1e-3^a < 3e-4 each.
        let y = lsim(&g, &vec![1.0; 20_001], 1e-3, &ApproxSpec::default()).unwrap();
        let (end, dc) = (y[20_000], g.dc_gain());
        prop_assert!(((end - dc) / dc).abs() < 1e-2, "{g}: step ends at {end}, DC gain {dc}");
    }
}

/// A two-mass drive train (the paper's motor through a compliant coupling with viscoelastic
/// damping, resonance near 41 Hz, damping ratio about 0.05), simulated as the series connection
/// of its two factors (`Simulator::from_factors`: the motor's and the coupling's pole-residue
/// forms multiplied) on a PRBS, against Grunwald-Letnikov with the input held (`dt/10`, `dt/20`,
/// Richardson) on the product multiplied out (nine denominator terms), which uses no rational
/// approximation.
#[test]
fn a_two_mass_drive_train_simulates_like_grunwald_letnikov() {
    let g: FracTf = "6.77*(3.1663e-5 s^2 + 2.34e-3 s^0.7 + 1)/((0.000028 s^1.78 + 0.0064 s^0.89 + 1)*(1.5831e-5 s^2 + 2.34e-3 s^0.7 + 1))"
        .parse()
        .unwrap();
    assert_eq!(g.den.len(), 9);
    let motor = (
        vec![(6.77, 0.0)],
        vec![(0.000028, 1.78), (0.0064, 0.89), (1.0, 0.0)],
    );
    let pair = (
        vec![(3.1663e-5, 2.0), (2.34e-3, 0.7), (1.0, 0.0)],
        vec![(1.5831e-5, 2.0), (2.34e-3, 0.7), (1.0, 0.0)],
    );
    let p = fracsim::prbs::Prbs {
        order: 9,
        clock: 0.002,
        ..fracsim::prbs::Prbs::paper()
    };
    let dt = 1e-3;
    let u = p.signal(dt).unwrap();
    // The lightly damped resonance needs a finer reference than the PMSM: Richardson of dt/10
    // and dt/20 (error O(h^2)) against that of dt/20 and dt/40, extrapolated once more,
    // `(4 y_20 - y_10)/3`. Measured: the two levels differ by 1.6e-3 of the swing.
    let (t10, t20) = (
        gl::simulate_held(&g, &u, dt, 10).unwrap(),
        gl::simulate_held(&g, &u, dt, 20).unwrap(),
    );
    let truth: Vec<f64> = t10
        .iter()
        .zip(&t20)
        .map(|(a, b)| (4.0 * b - a) / 3.0)
        .collect();
    let mut sim =
        Simulator::<f64>::from_factors(&[motor, pair], 0.0, dt, &ApproxSpec::default()).unwrap();
    let y = sim.simulate(&u);
    let err = rms_of_swing(&y, &truth);
    eprintln!(
        "two-mass, refined Oustaloup factors against GL: RMS error {err:.2e} of the swing \
         (the reference's levels differ by {:.2e})",
        rms_of_swing(&t10, &t20)
    );
    // Measured 1.1e-4; the bound is the PMSM's promise for the default method (0.05%).
    assert!(err < 5e-4, "{err}");
    // The text of the product: its multiplied-out form fails the pole search (the nine terms'
    // cells crowd), so the simulator uses the factors the parser read from the text's top-level
    // product, and the output is the same.
    let two = format!(
        "{} * {}",
        FracTf::new(
            vec![fracsim::Term::new(6.77, 0.0)],
            vec![
                fracsim::Term::new(0.000028, 1.78),
                fracsim::Term::new(0.0064, 0.89),
                fracsim::Term::new(1.0, 0.0)
            ],
            0.0
        )
        .unwrap(),
        "(3.1663e-5 s^2 + 2.34e-3 s^0.7 + 1)/(1.5831e-5 s^2 + 2.34e-3 s^0.7 + 1)"
    );
    let parsed: FracTf = two.parse().unwrap();
    assert_eq!(parsed.factors().len(), 2, "{two}");
    let y2 = lsim(&parsed, &u, dt, &ApproxSpec::default()).unwrap();
    let same = y
        .iter()
        .zip(&y2)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(same < 1e-12 * 70.0, "{same}");
    // The product's frequency response is the product of the factors' exact ones within the
    // approximation's error (refined Oustaloup: about 1e-3 relative inside the band).
    for f_hz in [1.0, 10.0, 28.0, 41.0, 80.0] {
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let (a, b) = (sim.model().freq_response(w), g.freq_response(w));
        assert!((a - b).norm() < 5e-3 * b.norm(), "{f_hz} Hz: {a} vs {b}");
    }
}

/// The unit step response of `K/(a2 s^2 + a1 s + 1)` at `t`, analytic and stable for any pair of
/// poles, however close: with the poles `p_(1,2) = pbar +- h` (`h` real, imaginary, or zero),
/// `y(t) = K (1 + e^(pbar t) (pbar t sinh(h t)/(h t) - cosh(h t)))`, `sinh(x)/x` and `cosh(x)` by
/// their series for a small `|x|` (the closed form with `1/(p1 - p2)` loses everything there).
fn second_order_step(k: f64, a1: f64, a2: f64, t: f64) -> f64 {
    use num_complex::Complex64;
    let pbar = -a1 / (2.0 * a2);
    // h^2 = pbar^2 - 1/a2 = (a1^2 - 4 a2)/(4 a2^2)
    let h2 = (a1 * a1 - 4.0 * a2) / (4.0 * a2 * a2);
    let h = Complex64::new(h2, 0.0).sqrt();
    let x = h * t;
    if x.norm() < 1e-3 {
        let x2 = x * x;
        let sinhc = 1.0 + x2 / 6.0 + x2 * x2 / 120.0;
        let cosh = 1.0 + x2 / 2.0 + x2 * x2 / 24.0;
        return k * (1.0 + (pbar * t).exp() * (pbar * t * sinhc - cosh).re);
    }
    // Far apart: e^(pbar t) cosh(h t) and e^(pbar t) sinh(h t) from e^(p1 t) and e^(p2 t) (no
    // overflow of cosh(h t) times an underflowing e^(pbar t)).
    let (e1, e2) = (((pbar + h) * t).exp(), ((pbar - h) * t).exp());
    k * (1.0 + (pbar * (e1 - e2) / (2.0 * h) - (e1 + e2) / 2.0).re)
}

/// An integer second-order model is simulated exactly for a held input (no approximation): its
/// held-step response equals the analytic one at every sample, to 1e-9 of the gain, for poles far
/// apart (a slow pole at 1e-5 rad/s beside one at 100 rad/s; TCLab's fitted 0.0074 and 0.068
/// rad/s), complex (the UNAL records' fitted values) and close (1e-2 to 1e-6 apart, relative).
/// Measured worst errors (of the gain): 6e-15 on the fitted values, 3.6e-11 slow and fast
/// (2e5 samples), and for close poles about `eps/delta` (residues `1/delta` times the gain
/// cancel): 2.5e-12, 2.3e-11, 2.0e-10, 9.6e-10 at 1e-3..1e-6 apart (5.3e-9 at 1e-7: outside the
/// bound, so not listed). Before the residues of a rational model were taken on the product of
/// its pole differences they were off by `eps/delta^2` (4e-10 at 1e-3 apart, a failed expansion
/// at 1e-5). An exactly repeated pole (critical damping) is a clear error naming it, not a wrong
/// model.
#[test]
fn integer_second_order_equals_the_analytic_step_response() {
    let cases: &[(&str, f64, f64, f64, f64)] = &[
        // (what, K, a1, a2, dt)
        ("TCLab's fitted", 0.3675, 149.96, 1981.7, 1.0),
        ("UNAL stairs' fitted", 0.99109, 0.103223, 0.0059798, 0.02),
        ("UNAL PRBS' fitted", 159.95, 0.053394, 8.3248e-4, 0.02),
        // poles -1e-5 and -100 rad/s: (s/1e-5 + 1)(s/100 + 1)
        ("slow and fast", 2.0, 1e5 + 1e-2, 1e3, 0.05),
        (
            "1e-2 apart",
            1.0,
            0.2 * (1.0 - 0.005),
            0.01 * (1.0 - 0.005),
            1e-3,
        ),
    ];
    let mut all: Vec<(String, f64, f64, f64, f64)> = cases
        .iter()
        .map(|&(w, k, a1, a2, dt)| (w.to_string(), k, a1, a2, dt))
        .collect();
    // Poles at -p and -p (1 + delta): a2 = 1/(p^2 (1 + delta)), a1 = (2 + delta)/(p (1 + delta)).
    for delta in [1e-3, 1e-4, 1e-5, 1e-6] {
        let p = 3.7;
        all.push((
            format!("{delta:.0e} apart"),
            1.5,
            (2.0 + delta) / (p * (1.0 + delta)),
            1.0 / (p * p * (1.0 + delta)),
            0.01,
        ));
    }
    for (what, k, a1, a2, dt) in &all {
        let g: FracTf = format!("{k}/({a2} s^2 + {a1} s + 1)").parse().unwrap();
        let mut sim = Simulator::<f64>::new(&g, *dt, &ApproxSpec::default())
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        // Out to where the slowest pole has settled (at most 2e5 samples).
        let tau_slow = a1.max(a2 / a1);
        let n = ((20.0 * tau_slow / dt) as usize).clamp(200, 200_000);
        let y = sim.simulate(&vec![1.0; n]);
        let worst = y
            .iter()
            .enumerate()
            .map(|(i, v)| (v - second_order_step(*k, *a1, *a2, i as f64 * dt)).abs() / k)
            .fold(0.0, f64::max);
        eprintln!("{what}: {n} samples, worst error {worst:.1e} of the gain");
        assert!(worst <= 1e-9, "{what}: {worst:e}");
    }
    // Critical damping, (s/3.7 + 1)^2: a repeated pole, named.
    let g: FracTf = format!("1/({} s^2 + {} s + 1)", 1.0 / 3.7 / 3.7, 2.0 / 3.7)
        .parse()
        .unwrap();
    match Simulator::<f64>::new(&g, 0.01, &ApproxSpec::default()) {
        Ok(mut sim) => {
            eprintln!("critical damping: simulated");
            // If rounding separates the pair enough for a modal form that passes its check, the
            // response must still be the analytic one.
            let y = sim.simulate(&vec![1.0; 500]);
            for (i, v) in y.iter().enumerate() {
                let want = second_order_step(1.0, 2.0 / 3.7, 1.0 / 3.7 / 3.7, i as f64 * 0.01);
                assert!(
                    (v - want).abs() <= 1e-9,
                    "critical damping at {i}: {v} vs {want}"
                );
            }
        }
        Err(e) => {
            eprintln!("critical damping: {e}");
            assert!(e.to_string().contains("repeated pole"), "{e}")
        }
    }
}

/// The inverse Laplace transform of `f` at `t` by the fixed Talbot contour (Abate and Valko 2004,
/// "Multi-precision Laplace transform inversion", with `r = 2M/(5t)`): independent of every
/// simulator here, converged when two `m` agree.
fn talbot(f: impl Fn(Complex64) -> Complex64, t: f64, m: usize) -> f64 {
    let r = 2.0 * m as f64 / (5.0 * t);
    let mut sum = 0.5 * (f(Complex64::new(r, 0.0)) * (r * t).exp()).re;
    for k in 1..m {
        let th = k as f64 * std::f64::consts::PI / m as f64;
        let cot = th.cos() / th.sin();
        let s = Complex64::new(r * th * cot, r * th);
        let sigma = th + (th * cot - 1.0) * cot;
        sum += ((s * t).exp() * f(s) * Complex64::new(1.0, sigma)).re;
    }
    r / m as f64 * sum
}

/// A drive train written as people write it, the motor's fractional stores and a load resonance
/// (40 Hz, damping 0.05) as two groups of one denominator: the parser keeps the two groups as
/// factors, so the model simulates (its nine-term denominator multiplied out failed with a
/// numerical breakdown), and its step equals the exact one (Talbot's inversion of `G(s)/s`) within
/// the refined Oustaloup approximation's error.
#[test]
fn a_product_in_the_denominator_is_simulated_as_its_factors() {
    let text = "6.82/((2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1) (1.6e-5 s^2 + 4e-4 s + 1))";
    let g: FracTf = text.parse().unwrap();
    assert_eq!(g.factors().len(), 2, "{text}");
    assert!((g.dc_gain() - 6.82).abs() < 1e-12);
    // The same model with `*` between the groups or two quotients, and a numerator's group joined
    // to a factor: each factor proper.
    for other in [
        "6.82/((2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1) * (1.6e-5 s^2 + 4e-4 s + 1))",
        "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)/(1.6e-5 s^2 + 4e-4 s + 1)",
        "6.82 (0.001 s + 1)/((2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)(1.6e-5 s^2 + 4e-4 s + 1))",
    ] {
        let h: FracTf = other.parse().unwrap();
        assert_eq!(h.factors().len(), 2, "{other}");
        for f in h.factors() {
            f.check_proper().unwrap();
        }
    }
    let (dt, n) = (1e-4, 301);
    let y = lsim(&g, &vec![1.0; n], dt, &ApproxSpec::default()).unwrap();
    let step = |s: Complex64| {
        let p = |c: f64, a: f64| c * s.powf(a);
        6.82 / ((p(2.655e-5, 1.7452) + p(0.0059, 0.92) + 1.0)
            * (p(1.6e-5, 2.0) + p(4e-4, 1.0) + 1.0))
            / s
    };
    let swing = 9.7;
    for k in (10..n).step_by(10) {
        let t = k as f64 * dt;
        let (a, b) = (talbot(step, t, 24), talbot(step, t, 32));
        assert!(
            (a - b).abs() < 1e-5 * swing,
            "Talbot not converged at {t}: {a} vs {b}"
        );
        assert!(
            (y[k] - b).abs() < 1e-3 * swing,
            "t = {t}: {} vs exact {b}",
            y[k]
        );
    }
    // Not a product: one group, no factors; an improper numerator for every group: none either.
    let one: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"
        .parse()
        .unwrap();
    assert!(one.factors().is_empty());
    let imp: FracTf = "(s^3 + 1)/((s + 1)(s + 2))".parse().unwrap();
    assert!(imp.factors().is_empty());
}
