//! Round trips: Bode data generated from known models, fitted back.

use fracsim::FracTf;
use ident::levy::{fit_bode, FreqOptions, OrderChoice, Weights};
use num_complex::Complex64;
use rand::{rngs::StdRng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// `count` log-spaced omega (rad/s) from `10^lo` to `10^hi`.
fn logspace(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|i| 10f64.powf(lo + (hi - lo) * i as f64 / (count - 1) as f64))
        .collect()
}

/// Multiplicative complex noise: `G (1 + e)`, `e` complex normal with std `sigma` per part.
fn noisy(h: &[Complex64], sigma: f64, seed: u64) -> Vec<Complex64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let nd = Normal::new(0.0, sigma).unwrap();
    h.iter()
        .map(|g| g * Complex64::new(1.0 + nd.sample(&mut rng), nd.sample(&mut rng)))
        .collect()
}

fn rel(x: f64, y: f64) -> f64 {
    ((x - y) / y).abs()
}

#[test]
fn commensurate_n2_m0_noise_free() {
    let truth: FracTf = "3/(0.01 s^1.4 + 0.2 s^0.7 + 1)".parse().unwrap();
    let omega = logspace(-1.0, 3.0, 30);
    let fit = fit_bode(&omega, &truth.bode(&omega), &FreqOptions::default()).unwrap();
    // the brief: q within 0.01, coefficients within 1 % (noise-free data; Levy is exact here)
    assert!((fit.levy.q - 0.7).abs() < 0.01, "q = {}", fit.levy.q);
    assert_eq!(fit.levy_grid.q, 0.7);
    assert!(rel(fit.levy.b[0], 3.0) < 0.01);
    assert!(rel(fit.levy.a[0], 0.2) < 0.01);
    assert!(rel(fit.levy.a[1], 0.01) < 0.01);
    assert!(fit.levy.j < 1e-12);
}

#[test]
fn commensurate_n3_m1_noise_free_uniform_weights_and_sk() {
    // (2 + 0.5 s^0.6) / (1e-3 s^1.8 + 0.05 s^1.2 + 0.4 s^0.6 + 1)
    let truth: FracTf = "(2 + 0.5 s^0.6)/(0.001 s^1.8 + 0.05 s^1.2 + 0.4 s^0.6 + 1)"
        .parse()
        .unwrap();
    let omega = logspace(-2.0, 3.0, 40);
    for (weights, sk) in [
        (Weights::Vinagre, 0),
        (Weights::Uniform, 0),
        (Weights::Vinagre, 3),
    ] {
        let opts = FreqOptions {
            n: 3,
            m: 1,
            weights,
            sk_iterations: sk,
            ..FreqOptions::default()
        };
        let fit = fit_bode(&omega, &truth.bode(&omega), &opts).unwrap();
        let f = if sk > 0 { fit.sk.unwrap() } else { fit.levy };
        assert!((f.q - 0.6).abs() < 0.01, "q = {}", f.q);
        for (got, want) in f.b.iter().zip([2.0, 0.5]) {
            assert!(rel(*got, want) < 0.01, "b: {got} vs {want}");
        }
        for (got, want) in f.a.iter().zip([0.4, 0.05, 0.001]) {
            assert!(rel(*got, want) < 0.01, "a: {got} vs {want}");
        }
    }
}

#[test]
fn order_above_one_with_wider_grid() {
    let truth: FracTf = "4/(0.02 s^1.5 + 1)".parse().unwrap();
    let omega = logspace(-1.0, 3.0, 20);
    let opts = FreqOptions {
        n: 1,
        order: OrderChoice::Search {
            step: 0.01,
            q_max: 2.0,
            refine: true,
        },
        ..FreqOptions::default()
    };
    let fit = fit_bode(&omega, &truth.bode(&omega), &opts).unwrap();
    assert!((fit.levy.q - 1.5).abs() < 0.01);
    assert!(rel(fit.levy.a[0], 0.02) < 0.01 && rel(fit.levy.b[0], 4.0) < 0.01);
}

#[test]
fn non_commensurate_pmsm_noise_free_refit_recovers_both_orders() {
    // the paper's time-domain model: zeta = 0.92, theta = 0.8252
    let truth = FracTf::pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252).unwrap();
    let omega = logspace(-0.5, 3.0, 30);
    let opts = FreqOptions {
        refine: true,
        ..FreqOptions::default()
    };
    let fit = fit_bode(&omega, &truth.bode(&omega), &opts).unwrap();
    let r = fit.refined.unwrap();
    // Levy cannot represent two orders: its J is not zero, the refit's is.
    assert!(fit.levy.j > 1e-8);
    assert!(r.j < 1e-16, "J = {}", r.j);
    assert!((r.zeta - 0.92).abs() < 0.01 && (r.theta - 0.8252).abs() < 0.01);
    assert!(rel(r.k, 6.82) < 0.01 && rel(r.a1, 0.0059) < 0.01 && rel(r.a2, 2.655e-5) < 0.01);
}

#[test]
fn noisy_commensurate_levy() {
    let truth: FracTf = "3/(0.01 s^1.4 + 0.2 s^0.7 + 1)".parse().unwrap();
    let omega = logspace(-1.0, 3.0, 40);
    let h = noisy(&truth.bode(&omega), 0.01, 7);
    let fit = fit_bode(&omega, &h, &FreqOptions::default()).unwrap();
    // 1 % noise on 40 points: q to about 0.02, coefficients to a few percent (seeded, so stable)
    assert!((fit.levy.q - 0.7).abs() < 0.03, "q = {}", fit.levy.q);
    assert!(rel(fit.levy.b[0], 3.0) < 0.02);
    assert!(rel(fit.levy.a[0], 0.2) < 0.1);
    assert!(rel(fit.levy.a[1], 0.01) < 0.15);
}

#[test]
fn noisy_pmsm_refit_with_standard_errors() {
    let truth = FracTf::pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252).unwrap();
    let omega = logspace(-0.5, 3.0, 40);
    let h = noisy(&truth.bode(&omega), 0.005, 11);
    let opts = FreqOptions {
        refine: true,
        ..FreqOptions::default()
    };
    let r = fit_bode(&omega, &h, &opts).unwrap().refined.unwrap();
    assert!(r.report.converged, "{:?}", r.report.termination);
    // 0.5 % noise: orders to a few hundredths, gain to 1 %
    assert!((r.zeta - 0.92).abs() < 0.03, "zeta = {}", r.zeta);
    assert!((r.theta - 0.8252).abs() < 0.03, "theta = {}", r.theta);
    assert!(rel(r.k, 6.82) < 0.01);
    let se = r.std_errors.unwrap();
    // the truth lies within 4 standard errors of each estimate (seeded noise)
    for (est, want, s) in [
        (r.k, 6.82, se[0]),
        (r.a1, 0.0059, se[1]),
        (r.a2, 2.655e-5, se[2]),
        (r.zeta, 0.92, se[3]),
        (r.theta, 0.8252, se[4]),
    ] {
        assert!(
            s > 0.0 && (est - want).abs() < 4.0 * s,
            "{est} vs {want} (se {s})"
        );
    }
}
