//! Grunwald-Letnikov on a fine grid of step `h`, for the plant as a general fractional transfer
//! function: the pseudo-state `x` with `sum_j a_j D^{alpha_j} x = w` (one implicit GL step solved
//! for `x_k`) and `y = sum_i b_i D^{beta_i} x`, from rest; the fast path solves the same scheme
//! for `y` directly (`step_grid`).
//!
//! `D^alpha f(t_k) ~ h^-alpha sum_{i=0..k} g_i f_{k-i}`, `g_0 = 1`, `g_i = g_{i-1} (1 - (alpha+1)/i)`
//! (the coefficients of `(1 - z)^alpha`). The scheme replaces `s` by `(1 - e^{-s h}) / h =
//! s (1 - s h / 2 + s^2 h^2 / 6 - ...)`: first order, and for an input that jumps only at grid
//! points its error at a fixed time is an expansion in integer powers of `h` (`c1 h + c2 h^2 +
//! c3 h^3 + ...`: the symbol's expansion, applied to each power `s^-mu` of the response's
//! expansion, gives whole powers; for `1/s^mu` it is `Gamma(k + mu) / Gamma(k)` against `k^mu`,
//! whose expansion is in whole powers of `1 / k`). So Richardson with ratio 2 removes the `h`
//! term (`R = 2 S_{h/2} - S_h`, order 2) and a second stage the `h^2` term (`(4 R_{h/2} - R_h) /
//! 3`, order 3). Measured against Mittag-Leffler (`lattice`'s tests): the error halves with `h`,
//! falls by 4 after one stage and by 8 after two.
//!
//! The input on the grid is its left limit `w_k = w(t_k^-)` (the value held over `(t_{k-1},
//! t_k]`): a held input that jumps at `t_k` acts from `t_{k+1}` on, as backward Euler integrates.

use super::plant::nonzero;
use super::series;
use super::Plant;

/// The GL coefficients of `(1 - z)^alpha`, `len` of them.
pub(crate) fn weights(alpha: f64, len: usize) -> Vec<f64> {
    let mut g = Vec::with_capacity(len);
    let mut last = 1.0;
    for i in 0..len {
        if i > 0 {
            last *= 1.0 - (alpha + 1.0) / i as f64;
        }
        g.push(last);
    }
    g
}

/// The scheme's symbol as two power series in `z`: `den(z) = sum_j a_j h^-alpha_j (1 - z)^alpha_j`
/// and `num(z)` likewise, each `len` long.
#[derive(Clone, Debug)]
pub(crate) struct Kernels {
    pub(crate) den: Vec<f64>,
    pub(crate) num: Vec<f64>,
}

/// The kernels of `plant` at step `h`, normalised so that `den[0] = 1`.
pub(crate) fn kernels(plant: &Plant, h: f64, len: usize) -> Kernels {
    let sum = |terms: &[super::Term]| -> Vec<f64> {
        let mut out = vec![0.0; len];
        for t in terms {
            let scale = t.coef * h.powf(-t.order);
            for (o, g) in out.iter_mut().zip(weights(t.order, len)) {
                *o += scale * g;
            }
        }
        out
    };
    let mut den = sum(&nonzero(&plant.den));
    let mut num = sum(&nonzero(&plant.num));
    let d0 = den[0];
    den.iter_mut().for_each(|v| *v /= d0);
    num.iter_mut().for_each(|v| *v /= d0);
    // Integer orders' weights end (a constant numerator is one coefficient): a short numerator
    // makes the output's product direct.
    let used = num.iter().rposition(|v| *v != 0.0).map_or(0, |i| i + 1);
    num.truncate(used);
    Kernels { den, num }
}

/// The step-by-step recursion: the pseudo-state from the implicit step
/// `x_k = w_k - sum_{i>=1} den_i x_{k-i}` (den_0 = 1), the output `y_k = sum_i num_i x_{k-i}`.
/// O(len^2): the reference the fast path is tested against.
#[cfg(test)]
pub(crate) fn direct(k: &Kernels, w: &[f64]) -> Vec<f64> {
    let len = w.len();
    let mut x = vec![0.0; len];
    let mut y = vec![0.0; len];
    for n in 0..len {
        let history: f64 = (1..=n).map(|i| k.den[i] * x[n - i]).sum();
        x[n] = w[n] - history;
        y[n] = k
            .num
            .iter()
            .take(n + 1)
            .enumerate()
            .map(|(i, b)| b * x[n - i])
            .sum();
    }
    y
}

/// The scheme's step response on the grid, `S(j h)` for `j = 0..len` (the step at `t = 0`, so
/// `w = 0, 1, 1, ...` and `S_0 = 0`), solved for the output itself: `den(z) y = num(z) w`, one
/// implicit step per point, `y_k = (num * w)_k - sum_{i>=1} den_i y_{k-i}` — the pseudo-state
/// scheme's output exactly (the same `num / den`), without its pseudo-state, which grows as
/// `t^order` when the denominator has no order-0 term and whose numerator differences then
/// cancel. The recursion by divide and conquer with FFT products (`series::recursion`).
pub(crate) fn step_grid(plant: &Plant, h: f64, len: usize) -> Vec<f64> {
    let k = kernels(plant, h, len);
    // (num * w)_j = sum_{i < j} num_i for the step.
    let mut forcing = Vec::with_capacity(len);
    let mut acc = 0.0;
    for i in 0..len {
        forcing.push(acc);
        if let Some(b) = k.num.get(i) {
            acc += b;
        }
    }
    series::recursion(&k.den, &forcing)
}

/// The step response extrapolated from the grids `h`, `h/2`, `h/4` (two Richardson stages,
/// third order) at `j h`, `j = 0..len`.
pub(crate) fn extrapolated_grid(plant: &Plant, h: f64, len: usize) -> Vec<f64> {
    let s1 = step_grid(plant, h, len);
    let s2 = step_grid(plant, h / 2.0, 2 * len);
    let s4 = step_grid(plant, h / 4.0, 4 * len);
    (0..len)
        .map(|j| {
            let r1 = 2.0 * s2[2 * j] - s1[j];
            let r2 = 2.0 * s4[4 * j] - s2[2 * j];
            (4.0 * r2 - r1) / 3.0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::Term;

    #[test]
    fn weights_are_binomial() {
        // (1 - z)^2 = 1 - 2 z + z^2; (1 - z)^0.5 = 1 - z/2 - z^2/8 - z^3/16.
        assert_eq!(weights(2.0, 4), vec![1.0, -2.0, 1.0, 0.0]);
        let half = weights(0.5, 4);
        for (g, w) in half.iter().zip([1.0, -0.5, -0.125, -0.0625]) {
            assert!((g - w).abs() < 1e-15);
        }
    }

    #[test]
    fn fast_path_equals_the_recursion() {
        let t = |coef: f64, order: f64| Term { coef, order };
        // (1 + 2 s^0.6) / (1 + 0.3 s^0.8 + 0.05 s^1.7) at h = 1e-3, and the lightly damped
        // 1 / (1 + s^1.9) at h = 1.25e-3 (where Newton's series division diverged), 8192 steps.
        let cases = [
            (
                Plant {
                    num: vec![t(1.0, 0.0), t(2.0, 0.6)],
                    den: vec![t(1.0, 0.0), t(0.3, 0.8), t(0.05, 1.7)],
                    delay_s: 0.0,
                },
                1e-3,
            ),
            (
                Plant {
                    num: vec![t(1.0, 0.0)],
                    den: vec![t(1.0, 0.0), t(1.0, 1.9)],
                    delay_s: 0.0,
                },
                1.25e-3,
            ),
        ];
        for (plant, h) in cases {
            let len = 8192;
            let k = kernels(&plant, h, len);
            let step: Vec<f64> = (0..len).map(|i| if i == 0 { 0.0 } else { 1.0 }).collect();
            let slow = direct(&k, &step);
            let fast = step_grid(&plant, h, len);
            let scale = slow.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = slow
                .iter()
                .zip(&fast)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst < 1e-9 * scale, "worst {worst:e} of {scale:e}");
        }
    }
}
