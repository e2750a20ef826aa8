//! Grunwald-Letnikov: the reference simulator.
//!
//! `D^nu x(t_k) ~ h^-nu sum_(j=0..k) c_j x_(k-j)`, `c_0 = 1`, `c_j = c_(j-1) (1 - (nu+1)/j)`.
//! The implicit scheme for `sum_j a_j D^(alpha_j) y = sum_i b_i D^(beta_i) u` solves for `y_k` at
//! each step with the full memory: exact in the limit `h -> 0`, first order in `h`, `O(N^2)` work.

use crate::error::{finite, invalid, Error, Result};
use crate::lanes::dot;
use crate::tf::{FracTf, Term};

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
/// A bad step, non-finite input, more than 2e5 samples (the scheme is quadratic), a singular
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
                "{} samples: Grunwald-Letnikov is O(N^2), use at most 200000",
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
    // The memory sums `sum_j w_j x_(k-j)` run over the signals stored back to front
    // (`rev[n-1-i] = x_i`), so each is a forward dot product of two contiguous slices
    // ([`crate::lanes::dot`], eight partial sums): the same sums, about 4x faster than one chain.
    let x_rev: Vec<f64> = x.iter().rev().copied().collect();
    let mut y_rev = vec![0.0; n];
    for k in 0..n {
        let rhs = dot(&wn[..=k], &x_rev[n - 1 - k..]) - dot(&wd[1..=k], &y_rev[n - k..]);
        y_rev[n - 1 - k] = rhs / wd[0];
    }
    y_rev.reverse();
    let y = y_rev;
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!(
            "the output is not finite at sample {i}"
        )));
    }
    Ok(y)
}

/// The substeps per sample of [`simulate_held`] as `fracid sim --method gl` uses them: Richardson
/// from `dt/10` and `dt/20`.
pub const HELD_SUBSTEPS: usize = 10;

/// The most fine-grid samples [`simulate_held`] runs (its cost is quadratic in them).
pub const HELD_MAX_FINE: usize = 200_000;

/// Simulate `tf` on a held (zero-order-hold) input: `u_k` acts on `[t_k, t_(k+1))` and `y_k` is the
/// output at `t_k`. Grunwald-Letnikov ([`simulate`]) runs at `h = dt/n` and `h = dt/(2n)` on the
/// input held over each sample, and the two are Richardson-extrapolated, `y = 2 y_(h/2) - y_h`,
/// which cancels the scheme's first-order error.
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
                 the reference is O(N^2), use a shorter record or another method",
                u.len()
            ),
        );
    }
    Ok(())
}

/// Grunwald-Letnikov at `h = dt/m` on `u` held over each sample, read at the sample instants.
fn run_held(tf: &FracTf, u: &[f64], dt: f64, m: usize) -> Result<Vec<f64>> {
    let held: Vec<f64> = u.iter().flat_map(|&x| std::iter::repeat_n(x, m)).collect();
    let y = simulate(tf, &held, dt / m as f64)?;
    Ok((0..u.len()).map(|k| y[k * m]).collect())
}
