//! Integer-order plants solved exactly: a controllable-canonical state-space realisation (in a
//! frequency-scaled variable, so its coefficients stay near 1) and the matrix exponential of the
//! augmented matrix `[[A, B], [0, 0]]`, which gives `e^{A t}` and `int_0^t e^{A s} ds B` at once.
//! The step response at any time is then `D + C int_0^t e^{A s} ds B`, exact to rounding.

use super::plant::{feedthrough, nonzero};
use super::Plant;

/// `x' = A x + B u`, `y = C x + D u`; `a` is n x n row-major.
#[derive(Clone, Debug)]
pub(crate) struct StateSpace {
    n: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    d: f64,
}

/// The realisation of an integer-order plant (orders rounded to integers; the plant checked).
pub(crate) fn realise(plant: &Plant) -> StateSpace {
    let den_terms = nonzero(&plant.den);
    let num_terms = nonzero(&plant.num);
    let n = den_terms
        .iter()
        .map(|t| t.order.round() as usize)
        .max()
        .unwrap_or(0);
    let mut den = vec![0.0; n + 1];
    let mut num = vec![0.0; n + 1];
    for t in &den_terms {
        den[t.order.round() as usize] += t.coef;
    }
    for t in &num_terms {
        num[t.order.round() as usize] += t.coef;
    }
    let d = feedthrough(plant);
    if n == 0 {
        return StateSpace {
            n,
            a: vec![],
            b: vec![],
            c: vec![],
            d,
        };
    }
    // s = w p with w the geometric mean of the poles' magnitudes (from the lowest non-zero
    // coefficient): the polynomial in p has its extreme coefficients equal in magnitude.
    let low = (0..n).find(|&k| den[k] != 0.0).unwrap_or(n);
    let w = if low < n {
        (den[low] / den[n]).abs().powf(1.0 / (n - low) as f64)
    } else {
        1.0
    };
    let lead = den[n] * w.powi(n as i32);
    let abar: Vec<f64> = (0..=n).map(|k| den[k] * w.powi(k as i32) / lead).collect();
    let bbar: Vec<f64> = (0..=n).map(|k| num[k] * w.powi(k as i32) / lead).collect();
    // Companion form in the scaled time w t: x_i' = x_{i+1}, x_n' = -sum abar_k x_{k+1} + u.
    let mut a = vec![0.0; n * n];
    for i in 0..n - 1 {
        a[i * n + i + 1] = w;
    }
    for k in 0..n {
        a[(n - 1) * n + k] = -abar[k] * w;
    }
    let mut b = vec![0.0; n];
    b[n - 1] = w;
    let c: Vec<f64> = (0..n).map(|k| bbar[k] - d * abar[k]).collect();
    StateSpace { n, a, b, c, d }
}

impl StateSpace {
    /// `(e^{A t}, int_0^t e^{A s} ds B)`.
    fn propagators(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.n;
        let m = n + 1;
        let mut aug = vec![0.0; m * m];
        for i in 0..n {
            for j in 0..n {
                aug[i * m + j] = self.a[i * n + j] * t;
            }
            aug[i * m + n] = self.b[i] * t;
        }
        let e = expm(&aug, m);
        let phi = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| e[i * m + j])
            .collect();
        let gamma = (0..n).map(|i| e[i * m + n]).collect();
        (phi, gamma)
    }

    /// The step response `S(t0 + j dt)`, `j = 0..count`, with `S(0) = D` (the value just after
    /// the step).
    pub(crate) fn step_lattice(&self, t0: f64, dt: f64, count: usize) -> Vec<f64> {
        let n = self.n;
        if n == 0 {
            return vec![self.d; count];
        }
        let (_, mut x) = if t0 > 0.0 {
            self.propagators(t0)
        } else {
            (vec![], vec![0.0; n])
        };
        let (phi, gamma) = self.propagators(dt);
        let mut out = Vec::with_capacity(count);
        for _ in 0..count {
            out.push(self.d + dot(&self.c, &x));
            let next: Vec<f64> = (0..n)
                .map(|i| dot(&phi[i * n..(i + 1) * n], &x) + gamma[i])
                .collect();
            x = next;
        }
        out
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn matmul(a: &[f64], b: &[f64], m: usize) -> Vec<f64> {
    let mut c = vec![0.0; m * m];
    for i in 0..m {
        for k in 0..m {
            let aik = a[i * m + k];
            if aik != 0.0 {
                for j in 0..m {
                    c[i * m + j] += aik * b[k * m + j];
                }
            }
        }
    }
    c
}

/// `e^M` (m x m row-major) by scaling and squaring with a Taylor series: `M / 2^s` has norm
/// <= 1/2, where 30 terms are exact to rounding (1/2^30 / 30! is far below 1e-16).
pub(crate) fn expm(mat: &[f64], m: usize) -> Vec<f64> {
    let norm = (0..m)
        .map(|i| mat[i * m..(i + 1) * m].iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let squarings = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let scale = 0.5f64.powi(squarings);
    let scaled: Vec<f64> = mat.iter().map(|v| v * scale).collect();
    let mut result = vec![0.0; m * m];
    let mut term = vec![0.0; m * m];
    for i in 0..m {
        result[i * m + i] = 1.0;
        term[i * m + i] = 1.0;
    }
    for k in 1..30 {
        term = matmul(&term, &scaled, m);
        term.iter_mut().for_each(|v| *v /= k as f64);
        result.iter_mut().zip(&term).for_each(|(r, t)| *r += t);
    }
    for _ in 0..squarings {
        result = matmul(&result, &result, m);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expm_of_a_rotation_and_a_decay() {
        // [[0, w], [-w, 0]] t: cos and sin.
        let w = 3.0;
        let t = 2.5;
        let e = expm(&[0.0, w * t, -w * t, 0.0], 2);
        let (c, s) = ((w * t).cos(), (w * t).sin());
        for (got, want) in e.iter().zip([c, s, -s, c]) {
            assert!((got - want).abs() < 1e-13, "{got} {want}");
        }
        let d = expm(&[-40.0], 1);
        assert!((d[0] - (-40.0f64).exp()).abs() < 1e-25);
    }
}
