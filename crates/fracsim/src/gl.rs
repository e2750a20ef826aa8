//! Grunwald-Letnikov: the reference simulator.
//!
//! `D^nu x(t_k) ~ h^-nu sum_(j=0..k) c_j x_(k-j)`, `c_0 = 1`, `c_j = c_(j-1) (1 - (nu+1)/j)`.
//! The implicit scheme for `sum_j a_j D^(alpha_j) y = sum_i b_i D^(beta_i) u` solves for `y_k` at
//! each step with the full memory: exact in the limit `h -> 0`, first order in `h`. The memory
//! sums are `O(N^2)` by definition; here the short lags are summed directly and the long ones by
//! FFT block by block (`O(N^1.5)`-like work, the same sums to rounding).

use crate::error::{finite, invalid, Error, Result};
use crate::fft::Convolver;
use crate::lanes::dot;
use crate::tf::{FracTf, Term};
use num_complex::Complex64;

/// The Grunwald-Letnikov weights `c_0..c_(n-1)` of order `nu`.
///
/// ```
/// let c = fracsim::gl::weights(1.0, 4);
/// assert_eq!(c, vec![1.0, -1.0, 0.0, 0.0]);
/// ```
pub fn weights(nu: f64, n: usize) -> Vec<f64> {
    let mut c = Vec::with_capacity(n);
    let mut prev = 1.0;
    for j in 0..n {
        if j > 0 {
            prev *= 1.0 - (nu + 1.0) / j as f64;
        }
        c.push(prev);
    }
    c
}

fn combined(terms: &[Term], h: f64, n: usize) -> Vec<f64> {
    let mut w = vec![0.0; n];
    for t in terms {
        let scale = t.coef * h.powf(-t.order);
        for (wj, cj) in w.iter_mut().zip(weights(t.order, n)) {
            *wj += scale * cj;
        }
    }
    w
}

/// Simulate `tf` on `u` (sampled every `dt` seconds, from rest) with the implicit
/// Grunwald-Letnikov scheme. The input delay is applied to `u` by linear interpolation.
///
/// ```
/// use fracsim::{gl, FracTf};
/// let g: FracTf = "6.77/(0.0064 s^0.89 + 1)".parse().unwrap();
/// let y = gl::simulate(&g, &vec![1.0; 3000], 1e-5).unwrap();
/// assert!((y[2999] - 6.615241).abs() < 0.005 * 6.615241); // oracle at t = 0.03 s
/// ```
///
/// # Errors
/// A bad step, non-finite input, more than 2e5 samples (the memory grows with the record), a singular
/// implicit step.
pub fn simulate(tf: &FracTf, u: &[f64], dt: f64) -> Result<Vec<f64>> {
    finite("dt", dt)?;
    if dt <= 0.0 {
        return invalid("dt", format!("{dt} s must be positive"));
    }
    if u.len() > 200_000 {
        return invalid(
            "input",
            format!(
                "{} samples: Grunwald-Letnikov keeps the whole memory, use at most 200000",
                u.len()
            ),
        );
    }
    if let Some(i) = u.iter().position(|x| !x.is_finite()) {
        return invalid("input", format!("sample {i} is {}", u[i]));
    }
    let n = u.len();
    // delayed input
    // A delay longer than the record (however large, even an infinite ratio) delays everything
    // out of it: m = n gives an all-zero input without overflowing m + 1.
    let d = tf.delay / dt;
    let (m, phi) = if d < n as f64 {
        (d.floor() as usize, d - d.floor())
    } else {
        (n, 0.0)
    };
    let x: Vec<f64> = (0..n)
        .map(|k| {
            let at = |i: usize| if i <= k { u[k - i] } else { 0.0 };
            (1.0 - phi) * at(m) + phi * at(m + 1)
        })
        .collect();
    let wd = combined(&tf.den, dt, n);
    let wn = combined(&tf.num, dt, n);
    if wd[0].abs() < 1e-300 {
        return Err(Error::Numerical("singular Grunwald-Letnikov step".into()));
    }
    let y = memory_sums(&wn, &wd, &x);
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!(
            "the output is not finite at sample {i}"
        )));
    }
    Ok(y)
}

/// The lags summed directly; longer ones by FFT (see [`memory_sums`]).
const NEAR: usize = 2048;

/// The implicit scheme's recursion `wd_0 y_k = sum_(j=0..k) wn_j x_(k-j) - sum_(j=1..k) wd_j y_(k-j)`.
///
/// The lags `j < NEAR` are summed directly, over the signals stored back to front
/// (`rev[n-1-i] = x_i`) so that each sum is a forward dot product of two contiguous slices
/// ([`crate::lanes::dot`]). The longer lags of the known input are one linear convolution by
/// FFT; those of the output, block by block: for the `NEAR` outputs from `k0` on, the lags
/// `j >= NEAR` reach only `y_0..y_(k0-1)`, already computed, so one convolution of them per
/// block serves the whole block. Work `O(n NEAR + (n/NEAR) n log n)` instead of `O(n^2)`; the
/// FFT's rounding is relative to the long lags' weights, which decay as `j^-(1+nu)`.
fn memory_sums(wn: &[f64], wd: &[f64], x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let x_rev: Vec<f64> = x.iter().rev().copied().collect();
    let mut y_rev = vec![0.0; n];
    let mut fft = Convolver::new();
    // The input's long lags, all at once.
    let far_x = if n > NEAR {
        let size = (2 * n).next_power_of_two();
        let (sx, sw) = (fft.spectrum(x, size), fft.spectrum(&long_lags(wn, n), size));
        fft.convolve(&sx, &sw, size)
    } else {
        vec![0.0; n]
    };
    // The output's long-lag weights' spectra, one per transform size.
    let mut weights: Vec<(usize, Vec<Complex64>)> = Vec::new();
    let mut far_y = vec![0.0; NEAR.min(n)];
    for k0 in (0..n).step_by(NEAR) {
        let end = (k0 + NEAR).min(n);
        if k0 > 0 {
            // Outputs k0..end from y_0..y_(k0-1): no product wraps if size >= end.
            let size = end.next_power_of_two();
            let at = match weights.iter().position(|(s, _)| *s == size) {
                Some(at) => at,
                None => {
                    let w = long_lags(wd, size.min(n));
                    weights.push((size, fft.spectrum(&w, size)));
                    weights.len() - 1
                }
            };
            let sw = &weights[at].1;
            let y_known: Vec<f64> = y_rev[n - k0..].iter().rev().copied().collect();
            let sy = fft.spectrum(&y_known, size);
            let c = fft.convolve(&sy, sw, size);
            far_y[..end - k0].copy_from_slice(&c[k0..end]);
        }
        for k in k0..end {
            let m = k.min(NEAR - 1);
            let near = dot(&wn[..=m], &x_rev[n - 1 - k..]) - dot(&wd[1..=m], &y_rev[n - k..]);
            y_rev[n - 1 - k] = (near + far_x[k] - far_y[k - k0]) / wd[0];
        }
    }
    y_rev.reverse();
    y_rev
}

/// `w_j` for the lags `j >= NEAR` (zero below), the first `len` of them.
fn long_lags(w: &[f64], len: usize) -> Vec<f64> {
    let mut v = w[..len].to_vec();
    v[..NEAR.min(len)].fill(0.0);
    v
}

/// The substeps per sample of [`simulate_held`] as `fracid sim --method gl` uses them: Richardson
/// from `dt/10` and `dt/20`.
pub const HELD_SUBSTEPS: usize = 10;

/// The most fine-grid samples [`simulate_held`] runs (its cost grows faster than linearly in them).
pub const HELD_MAX_FINE: usize = 200_000;

/// Simulate `tf` on a held (zero-order-hold) input: `u_k` acts on `[t_k, t_(k+1))` and `y_k` is the
/// output at `t_k` (for a strictly proper model the output just before the input changes there:
/// it has not moved with `u_k`). Grunwald-Letnikov ([`simulate`]) runs at `h = dt/n` and
/// `h = dt/(2n)` on the input held over each sample, and the two are Richardson-extrapolated,
/// `y = 2 y_(h/2) - y_h`, which cancels the scheme's first-order error.
///
/// ```
/// use fracsim::{gl, FracTf};
/// let g: FracTf = "6.77/(0.0064 s^0.89 + 1)".parse().unwrap();
/// let y = gl::simulate_held(&g, &vec![1.0; 31], 1e-3, 10).unwrap();
/// assert!((y[30] - 6.615241).abs() < 1e-3 * 6.615241); // oracle at t = 0.03 s
/// ```
///
/// # Errors
/// As [`simulate`]; `n = 0`; more than [`HELD_MAX_FINE`] fine samples.
pub fn simulate_held(tf: &FracTf, u: &[f64], dt: f64, n: usize) -> Result<Vec<f64>> {
    check_held(u, dt, n, 2)?;
    let (coarse, fine) = (run_held(tf, u, dt, n)?, run_held(tf, u, dt, 2 * n)?);
    Ok(fine.iter().zip(&coarse).map(|(f, c)| 2.0 * f - c).collect())
}

/// As [`simulate_held`], extrapolated once more: Grunwald-Letnikov at `h = dt/n`, `dt/(2n)` and
/// `dt/(4n)` on the held input, the two first-order Richardson values `2 y_(h/2) - y_h` and
/// `2 y_(h/4) - y_(h/2)` combined as `(4 b - a)/3`, which is
/// `y = (8 y_(h/4) - 6 y_(h/2) + y_h)/3`: the reference for lightly damped or fast models, where
/// one extrapolation leaves about 1e-3 of the swing. Three runs (the middle one shared).
///
/// ```
/// use fracsim::{gl, FracTf};
/// let g: FracTf = "6.77/(0.0064 s^0.89 + 1)".parse().unwrap();
/// let y = gl::simulate_held_twice(&g, &vec![1.0; 31], 1e-3, 5).unwrap();
/// assert!((y[30] - 6.615241).abs() < 2e-4 * 6.615241); // oracle at t = 0.03 s
/// ```
///
/// # Errors
/// As [`simulate_held`], with `4 n` fine samples per sample counted against [`HELD_MAX_FINE`].
pub fn simulate_held_twice(tf: &FracTf, u: &[f64], dt: f64, n: usize) -> Result<Vec<f64>> {
    check_held(u, dt, n, 4)?;
    let y1 = run_held(tf, u, dt, n)?;
    let y2 = run_held(tf, u, dt, 2 * n)?;
    let y4 = run_held(tf, u, dt, 4 * n)?;
    let y = y1.iter().zip(&y2).zip(&y4);
    Ok(y.map(|((a, b), c)| (8.0 * c - 6.0 * b + a) / 3.0).collect())
}

/// The step, the substeps and the finest grid's size (`u.len() * finest * n`) of the held runs.
fn check_held(u: &[f64], dt: f64, n: usize, finest: usize) -> Result<()> {
    finite("dt", dt)?;
    if dt <= 0.0 {
        return invalid("dt", format!("{dt} s must be positive"));
    }
    if n == 0 {
        return invalid("substeps", "need at least one substep per sample");
    }
    let fine = u.len().saturating_mul(finest * n);
    if fine > HELD_MAX_FINE {
        return invalid(
            "input",
            format!(
                "{} samples need {fine} Grunwald-Letnikov steps (at most {HELD_MAX_FINE}): \
                 the reference keeps the whole memory, use a shorter record or another method",
                u.len()
            ),
        );
    }
    Ok(())
}

/// Grunwald-Letnikov at `h = dt/m` on `u` held over each sample, read at the sample instants.
fn run_held(tf: &FracTf, u: &[f64], dt: f64, m: usize) -> Result<Vec<f64>> {
    // A strictly proper model's output at `t_k` has not moved with `u_k` (it is continuous); the
    // implicit scheme's sample at `t_k` would, by its lag-0 weight, which is large for a low
    // order (`K/(a h^-q + 1)`: a quarter of `K` for `K/(1.7 s^0.3 + 1)` at `h` = 4.6 ms). The
    // held input then starts one fine step later, so that the sample at `t_k` sees the level
    // before the instant, as [`crate::Simulator`] feeds such a model
    // ([`crate::modal::PoleResidue::strictly_proper`]); the shift, one step `h` of each run, is
    // a first-order error the Richardson extrapolation cancels with the scheme's own.
    let lag = usize::from(tf.is_strictly_proper());
    let held: Vec<f64> = std::iter::repeat_n(0.0, lag)
        .chain(u.iter().flat_map(|&x| std::iter::repeat_n(x, m)))
        .take(u.len() * m)
        .collect();
    let y = simulate(tf, &held, dt / m as f64)?;
    Ok((0..u.len()).map(|k| y[k * m]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strictly proper model of low order, `K/(a s^0.3 + 1)`, on a step held from sample 10:
    /// its output follows the Mittag-Leffler step response within 1e-4 of `K` (measured 5.5e-6),
    /// 0 at the step's own sample. Sampled with the input of the instant, the extrapolated
    /// output jumped there by 0.083 `K` (the implicit scheme's lag-0 weight at the fine steps).
    #[test]
    fn a_strictly_proper_model_held_does_not_see_the_input_at_its_instant() {
        let (k, a, q) = (2.5, 1.7, 0.3);
        let g: FracTf = format!("{k}/({a} s^{q} + 1)").parse().unwrap();
        let dt = 0.09;
        let u: Vec<f64> = (0..200).map(|j| if j >= 10 { 1.0 } else { 0.0 }).collect();
        let y = simulate_held(&g, &u, dt, HELD_SUBSTEPS).unwrap();
        for (j, &yj) in y.iter().enumerate() {
            let t = (j as f64 - 10.0) * dt;
            let want = crate::special::step_response_first_order(k, a, q, t);
            assert!((yj - want).abs() < 1e-4 * k, "k={j}: {yj} vs {want}");
        }
        assert!(y[10].abs() < 1e-12, "{}", y[10]);
    }

    /// The recursion summed term by term, every lag directly: the definition.
    fn direct(wn: &[f64], wd: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for k in 0..x.len() {
            let mut rhs = 0.0;
            for j in 0..=k {
                rhs += wn[j] * x[k - j];
            }
            for j in 1..=k {
                rhs -= wd[j] * y[k - j];
            }
            y[k] = rhs / wd[0];
        }
        y
    }

    /// The blocked sums (direct below `NEAR` lags, FFT beyond) equal the definition on records
    /// within the first block, on a block's edge, just past it and ending inside a block, for a
    /// model with fractional terms on both sides whose long memory matters (weights decaying as
    /// `j^-1.4` to `j^-2.5`), at a step where the scheme is well conditioned: to 1e-11 of the
    /// output's swing (rounding: about `n eps` for the direct sums, `log n eps` of the long lags'
    /// weights for the FFT; a long lag off by one shifts the output by about 1e-6).
    #[test]
    fn blocked_sums_equal_the_direct_ones() {
        let g: FracTf = "2*(0.3 s^0.4 + 1)/(0.05 s^1.5 + 0.2 s^0.6 + 1)"
            .parse()
            .unwrap();
        let h = 1e-3;
        for n in [700, 2 * NEAR, 2 * NEAR + 1, 5 * NEAR + 333] {
            let x: Vec<f64> = (0..n)
                .map(|k| {
                    if (k / 97 + k / 401) % 2 == 0 {
                        1.0
                    } else {
                        -0.5
                    }
                })
                .collect();
            let (wn, wd) = (combined(&g.num, h, n), combined(&g.den, h, n));
            let (fast, slow) = (memory_sums(&wn, &wd, &x), direct(&wn, &wd, &x));
            let swing = slow.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(swing > 1.0, "{swing}");
            let worst = fast
                .iter()
                .zip(&slow)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-11 * swing, "n = {n}: {worst} of {swing}");
        }
    }
}
