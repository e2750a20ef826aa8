//! Grunwald-Letnikov on a fine grid of step `h`, for the plant as a general fractional transfer
//! function: the pseudo-state `x` with `sum_j a_j D^{alpha_j} x = w` (one implicit GL step solved
//! for `x_k`) and `y = sum_i b_i D^{beta_i} x`, from rest.
//!
//! `D^alpha f(t_k) ~ h^-alpha sum_{i=0..k} g_i f_{k-i}`, `g_0 = 1`, `g_i = g_{i-1} (1 - (alpha+1)/i)`
//! (the coefficients of `(1 - z)^alpha`). The scheme replaces `s` by `(1 - e^{-s h}) / h =
//! s (1 - s h / 2 + O(h^2))`: first order, its error an expansion in integer powers of `h` for an
//! input that jumps only at grid points, so one Richardson step `2 S_{h/2} - S_h` leaves `O(h^2)`
//! (checked in `lattice`'s tests: the error halves with `h` before the extrapolation and falls by
//! about four after it).
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
    Kernels { den, num }
}

/// The step-by-step recursion: the pseudo-state from the implicit step
/// `x_k = w_k - sum_{i>=1} den_i x_{k-i}` (den_0 = 1), the output `y_k = sum_i num_i x_{k-i}`.
/// O(len^2): the reference the fast path is tested against.
pub(crate) fn direct(k: &Kernels, w: &[f64]) -> Vec<f64> {
    let len = w.len();
    let mut x = vec![0.0; len];
    let mut y = vec![0.0; len];
    for n in 0..len {
        let history: f64 = (1..=n).map(|i| k.den[i] * x[n - i]).sum();
        x[n] = w[n] - history;
        y[n] = (0..=n).map(|i| k.num[i] * x[n - i]).sum();
    }
    y
}

/// The scheme's step response on the grid, `S(j h)` for `j = 0..len` (the step at `t = 0`, so
/// `w = 0, 1, 1, ...` and `S_0 = 0`): the running sum, shifted by one, of the impulse response
/// `num(z) / den(z)`. Long grids use the FFT (series division by Newton's iteration); short ones
/// the recursion.
pub(crate) fn step_grid(plant: &Plant, h: f64, len: usize) -> Vec<f64> {
    let k = kernels(plant, h, len);
    let impulse = if len <= DIRECT_MAX {
        let mut unit = vec![0.0; len];
        unit[0] = 1.0;
        direct(&k, &unit)
    } else {
        series::divide(&k.num, &k.den, len)
    };
    let mut out = Vec::with_capacity(len);
    let mut acc = 0.0;
    for i in 0..len {
        out.push(acc);
        acc += impulse[i];
    }
    out
}

/// Grids up to this long use the O(len^2) recursion.
const DIRECT_MAX: usize = 2048;

/// The Richardson-extrapolated step response `2 S_{h/2}(j h) - S_h(j h)`, `j = 0..len`.
pub(crate) fn richardson_grid(plant: &Plant, h: f64, len: usize) -> Vec<f64> {
    let coarse = step_grid(plant, h, len);
    let fine = step_grid(plant, h / 2.0, 2 * len);
    (0..len).map(|j| 2.0 * fine[2 * j] - coarse[j]).collect()
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
    fn series_division_equals_the_recursion() {
        // 1 + 2 s^0.6 over 1 + 0.3 s^0.8 + 0.05 s^1.7 at h = 1e-3, 5000 steps.
        let plant = Plant {
            num: vec![
                Term {
                    coef: 1.0,
                    order: 0.0,
                },
                Term {
                    coef: 2.0,
                    order: 0.6,
                },
            ],
            den: vec![
                Term {
                    coef: 1.0,
                    order: 0.0,
                },
                Term {
                    coef: 0.3,
                    order: 0.8,
                },
                Term {
                    coef: 0.05,
                    order: 1.7,
                },
            ],
            delay_s: 0.0,
        };
        let len = 5000;
        let k = kernels(&plant, 1e-3, len);
        let mut unit = vec![0.0; len];
        unit[0] = 1.0;
        let slow = direct(&k, &unit);
        let fast = series::divide(&k.num, &k.den, len);
        let scale = slow.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = slow
            .iter()
            .zip(&fast)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst < 1e-11 * scale, "worst {worst:e} of {scale:e}");
    }
}
