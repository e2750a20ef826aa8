//! Special functions for exact reference solutions: the gamma function and the one-parameter
//! Mittag-Leffler function `E_q(z) = sum_k z^k / Gamma(q k + 1)`.

use std::f64::consts::PI;

/// The gamma function (Lanczos approximation, g = 7, n = 9; reflection for `x < 0.5`).
/// Relative accuracy about 1e-15 for moderate arguments.
///
/// ```
/// assert!((fracsim::special::gamma(5.0) - 24.0).abs() < 1e-12);
/// assert!((fracsim::special::gamma(0.5) - std::f64::consts::PI.sqrt()).abs() < 1e-14);
/// ```
pub fn gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return PI / ((PI * x).sin() * gamma(1.0 - x));
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    (2.0 * PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
}

/// The Mittag-Leffler function `E_q(z)` for real `z <= 0` and `0 < q <= 1`.
///
/// For `|z| <= 15` the power series is summed (cancellation costs at most about 8 digits there);
/// beyond, the asymptotic expansion `E_q(z) ~ -sum_(k=1..K) z^-k / Gamma(1 - q k)` is used, whose
/// error is below 1e-8 for `|z| > 15`, `q <= 0.95`.
///
/// ```
/// use fracsim::special::mittag_leffler;
/// // E_1(z) = e^z
/// assert!((mittag_leffler(1.0, -2.0) - (-2f64).exp()).abs() < 1e-12);
/// ```
pub fn mittag_leffler(q: f64, z: f64) -> f64 {
    if z.abs() <= 15.0 || q >= 0.999 && z.abs() < 30.0 {
        let mut sum = 0.0;
        let mut zk = 1.0;
        for k in 0..400 {
            let term = zk / gamma(q * k as f64 + 1.0);
            sum += term;
            if k > 5 && term.abs() < 1e-17 * sum.abs().max(1e-300) {
                break;
            }
            zk *= z;
            if !zk.is_finite() {
                break;
            }
        }
        sum
    } else {
        let mut sum = 0.0;
        let mut zk = 1.0;
        for k in 1..=8 {
            zk /= z;
            let arg = 1.0 - q * k as f64;
            if arg.fract() == 0.0 && arg <= 0.0 {
                continue; // 1/Gamma at a pole is zero
            }
            sum -= zk / gamma(arg);
        }
        sum
    }
}

/// The exact step response of `K/(a s^q + 1)`: `K (1 - E_q(-t^q / a))` at time `t` seconds.
///
/// ```
/// let y = fracsim::special::step_response_first_order(6.77, 0.0064, 0.89, 0.003);
/// assert!((y - 3.943589).abs() < 1e-5);
/// ```
pub fn step_response_first_order(k: f64, a: f64, q: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    k * (1.0 - mittag_leffler(q, -t.powf(q) / a))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oracle_values_from_the_design() {
        // docs/design.md §3: K = 6.77, a = 0.0064, q = 0.89
        for (t, y) in [
            (0.001, 1.958077),
            (0.003, 3.943589),
            (0.010, 6.018918),
            (0.030, 6.615241),
        ] {
            let v = step_response_first_order(6.77, 0.0064, 0.89, t);
            assert!((v - y).abs() < 2e-6, "t={t}: {v} vs {y}");
        }
    }

    #[test]
    fn series_and_asymptotic_agree_at_the_switch() {
        let a = mittag_leffler(0.89, -14.999);
        let b = mittag_leffler(0.89, -15.001);
        assert!((a - b).abs() < 1e-6, "{a} {b}");
    }
}
