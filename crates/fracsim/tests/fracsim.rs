//! fracsim against independent truth: the Mittag-Leffler oracle and Grunwald-Letnikov at a fine step.

use fracsim::special::step_response_first_order;
use fracsim::{gl, lsim, ApproxSpec, Discretization, FracTf, Method, Simulator};

const K: f64 = 6.77;
const A: f64 = 0.0064;
const Q: f64 = 0.89;
/// DESIGN §3: the oracle values at 1, 3, 10 and 30 ms.
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
    for (method, disc, order, tol) in [
        // Measured worst relative errors over the four oracle points (dt = 1e-4, default band
        // [1e-3, 30 pi/dt] rad/s, N = 8): Oustaloup 1.9e-4, refined 5.9e-4, Poinot-Trigeassou
        // 2.0e-4; all at t = 1 ms. Bound 1e-3; the CLI promises 0.5%.
        (Method::Oustaloup, Discretization::Bilinear, 8, 1e-3),
        (Method::Refined, Discretization::Bilinear, 8, 1e-3),
        (Method::Trigeassou, Discretization::Bilinear, 8, 1e-3),
    ] {
        let spec = ApproxSpec {
            method,
            discretization: disc,
            order,
            band: None,
        };
        let y = lsim(&first_order(), &u, dt, &spec).unwrap();
        let err = worst_oracle_error(&y, dt);
        eprintln!("{method:?}/{disc:?}: worst relative error {err:.2e}");
        assert!(err < tol, "{method:?}/{disc:?}: {err}");
    }
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
    // Measured 6.3e-4 (the largest at the first samples); 1e-3 bound.
    assert!(worst < 1e-3, "{worst}");
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

#[test]
fn pmsm_oustaloup_cascade_agrees_with_grunwald_letnikov() {
    // The paper's time-domain model on a PRBS, 2 periods at 3 ms clock.
    let g: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"
        .parse()
        .unwrap();
    let dt = 1e-4;
    let fine = 10;
    let prbs = fracsim::prbs::Prbs {
        periods: 1,
        ..fracsim::prbs::Prbs::paper()
    };
    let u = prbs.signal(dt).unwrap();
    let u_fine = prbs.signal(dt / fine as f64).unwrap();
    let y_gl_fine = gl::simulate(&g, &u_fine, dt / fine as f64).unwrap();
    // sample the fine reference at the coarse instants t = k dt
    let y_ref: Vec<f64> = (0..u.len()).map(|k| y_gl_fine[k * fine]).collect();
    let y = lsim(&g, &u, dt, &ApproxSpec::default()).unwrap();
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let diff: Vec<f64> = y.iter().zip(&y_ref).map(|(a, b)| a - b).collect();
    let rel = rms(&diff) / rms(&y_ref);
    eprintln!("PMSM Oustaloup vs GL(dt/10): relative RMS difference {rel:.2e}");
    // Measured 3.3e-3: GL's own O(h) error at h = 1e-5 is of the same size (see above).
    assert!(rel < 6e-3, "{rel}");
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
    for (k, &x) in u.iter().enumerate() {
        assert_eq!(sim.step(x), y[k]);
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
