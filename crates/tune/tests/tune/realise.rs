//! The controller's discrete realisation against the exact fractional controller: at
//! frequencies well inside the band and below Nyquist, the held-input (step-invariant) integrator
//! is `(j w)^-lambda e^(-j w dt/2)` and each backward difference `j w e^(-j w dt/2)`, to
//! `O((w dt)^2)`; the approximation adds its own small ripple (well under 1% inside the band).

use fracsim::ApproxSpec;
use tune::realise::{discrete, discrete_response};
use tune::Controller;

/// `kp + ki (j w)^-lambda e^(-j w dt/2) + kd (j w)^mu e^(-j w k dt/2)`, `k` the half-sample
/// lags of the derivative's chain (`ceil(mu)` differences, one more for its integrator).
fn reference(c: &Controller, w: f64, dt: f64) -> num_complex::Complex64 {
    let lag = |halves: f64| num_complex::Complex64::from_polar(1.0, -w * dt * halves / 2.0);
    let mut v = c.kp + c.ki / fracsim::jw_pow(w, c.lambda) * lag(1.0);
    if c.kd != 0.0 {
        let n = c.mu.ceil();
        let halves = n + if n > c.mu { 1.0 } else { 0.0 };
        v += c.kd * fracsim::jw_pow(w, c.mu) * lag(halves);
    }
    v
}

fn check(c: Controller, dt: f64, tol: f64) {
    let ss = discrete(&c, dt, &ApproxSpec::default()).unwrap();
    for w in [1.0, 10.0, 100.0, 300.0] {
        let exact = reference(&c, w, dt);
        let got = discrete_response(&ss, w);
        let err = ((got - exact) / exact).norm();
        assert!(err < tol, "{c:?} at {w} rad/s: relative error {err}");
    }
}

#[test]
fn fractional_and_integer_controllers_are_realised() {
    let dt = 1e-4;
    for lambda in [0.5, 0.9, 1.0, 1.3, 1.577] {
        check(
            Controller {
                kp: 0.3,
                ki: 100.0,
                lambda,
                kd: 0.0,
                mu: 1.0,
            },
            dt,
            0.02,
        );
    }
    for (lambda, mu) in [(1.0, 1.0), (1.2, 0.6), (0.8, 1.3)] {
        check(
            Controller {
                kp: 0.3,
                ki: 100.0,
                lambda,
                kd: 1e-3,
                mu,
            },
            dt,
            0.02,
        );
    }
}

/// The realisation really is discrete-time at `dt`: the held integrator's lag shows at
/// `w dt = 0.3`, and the reference with it holds.
#[test]
fn a_coarser_sample_period_shows_its_hold() {
    let c = Controller {
        kp: 0.3,
        ki: 100.0,
        lambda: 1.2,
        kd: 0.0,
        mu: 1.0,
    };
    let ss = discrete(&c, 1e-3, &ApproxSpec::default()).unwrap();
    let w = 300.0;
    let with_hold = reference(&c, w, 1e-3);
    let without = c.freq_response(w);
    let got = discrete_response(&ss, w);
    let (e_with, e_without) = (
        ((got - with_hold) / with_hold).norm(),
        ((got - without) / without).norm(),
    );
    assert!(
        e_with < 0.01 && e_without > 3.0 * e_with,
        "{e_with} {e_without}"
    );
}

/// The realisation's step response against the exact one in the time domain: `kp + ki s^-lambda`
/// answers a unit step with `kp + ki t^lambda / Gamma(lambda + 1)`, and a held-input
/// discretisation is exact at the samples for the approximated operator, so the difference is the
/// approximation's alone (refined Oustaloup over [1e-6/dt, 30 pi/dt] rad/s, [1e-3, 30 pi/dt] at this 1 ms step: 1e-4 to 4.2e-4 relative
/// from the fifth sample to 1 s as measured; tolerance 2e-3).
#[test]
fn step_response_is_the_fractional_integral() {
    let dt = 1e-3;
    for lambda in [0.5, 0.9, 1.3, 1.577] {
        let c = Controller {
            kp: 0.3,
            ki: 100.0,
            lambda,
            kd: 0.0,
            mu: 1.0,
        };
        let ss = discrete(&c, dt, &ApproxSpec::default()).unwrap();
        let n = ss.order();
        let mut x = vec![0.0; n];
        let g = fracsim::special::gamma(lambda + 1.0);
        let mut worst: f64 = 0.0;
        for k in 0..=1000 {
            let y: f64 = (0..n).map(|i| ss.c[(0, i)] * x[i]).sum::<f64>() + ss.d;
            let t = k as f64 * dt;
            let exact = 0.3 + 100.0 * t.powf(lambda) / g;
            if k >= 5 {
                worst = worst.max((y / exact - 1.0).abs());
            }
            x = (0..n)
                .map(|i| (0..n).map(|j| ss.a[(i, j)] * x[j]).sum::<f64>() + ss.b[(i, 0)])
                .collect();
        }
        assert!(worst < 2e-3, "lambda = {lambda}: {worst}");
    }
}
