//! Exact truth for integer-order plants, shared by the test binaries of `ident` and `fracid` (the
//! latter includes this file with `#[path]`): a polynomial ratio simulated for the input held over
//! each step by its own state-space realisation and matrix exponential, with no code shared with
//! fracsim or ident (std only), so that it can judge their simulators and fits; and the seeded
//! random binary input the records are driven by.
//!
//! One file included by both binaries rather than a module of the library behind a feature (the
//! library would carry test code, and `ident` would be built twice, with and without the feature)
//! or a crate of its own (a workspace member for two functions).

/// `exp(M)` by scaling and squaring with a 20-term Taylor series (`M` small after scaling).
fn expm(m: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = m.len();
    let norm: f64 = m
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let s = (norm.max(1e-300).log2().ceil() + 1.0).max(0.0) as i32;
    let f = 0.5f64.powi(s);
    let a: Vec<Vec<f64>> = m
        .iter()
        .map(|r| r.iter().map(|v| v * f).collect())
        .collect();
    let mul = |x: &[Vec<f64>], y: &[Vec<f64>]| -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (0..n).map(|k| x[i][k] * y[k][j]).sum())
                    .collect()
            })
            .collect()
    };
    let mut term: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    let mut sum = term.clone();
    for k in 1..=20 {
        term = mul(&term, &a);
        term.iter_mut()
            .for_each(|r| r.iter_mut().for_each(|v| *v /= k as f64));
        for i in 0..n {
            for j in 0..n {
                sum[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..s {
        sum = mul(&sum, &sum);
    }
    sum
}

/// The exact response of `(b_0 + b_1 s + ..)/(a_0 + a_1 s + .. + a_n s^n)` (proper, `a_n != 0`)
/// to `u` held over each step of `dt`, from rest: controllable canonical form, `y_k = C x_k +
/// D u_k`, `x_(k+1) = Phi x_k + Gamma u_k` with `[Phi Gamma] = exp([A B; 0 0] dt)`.
pub fn simulate(b: &[f64], a: &[f64], u: &[f64], dt: f64) -> Vec<f64> {
    let n = a.len() - 1;
    let an = a[n];
    let a: Vec<f64> = a.iter().map(|v| v / an).collect();
    let mut b: Vec<f64> = b.iter().map(|v| v / an).collect();
    b.resize(n + 1, 0.0);
    let d = b[n];
    // C_k = b_k - d a_k
    let c: Vec<f64> = (0..n).map(|k| b[k] - d * a[k]).collect();
    let mut m = vec![vec![0.0; n + 1]; n + 1];
    for i in 0..n - 1 {
        m[i][i + 1] = dt;
    }
    for k in 0..n {
        m[n - 1][k] = -a[k] * dt;
    }
    m[n - 1][n] = dt;
    let e = expm(&m);
    let mut x = vec![0.0; n];
    u.iter()
        .map(|&uk| {
            let y = c.iter().zip(&x).map(|(c, x)| c * x).sum::<f64>() + d * uk;
            x = (0..n)
                .map(|i| (0..n).map(|j| e[i][j] * x[j]).sum::<f64>() + e[i][n] * uk)
                .collect();
            y
        })
        .collect()
}

/// A seeded uniform generator on `[0, 1)` (a 64-bit linear congruential generator, Knuth's
/// MMIX constants, the top 53 bits).
pub struct Lcg(pub u64);

impl Lcg {
    /// The next number in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random binary input of `n` samples at +-1, starting at 1, switching with probability
/// `p_switch` at each sample.
pub fn random_binary(rng: &mut Lcg, n: usize, p_switch: f64) -> Vec<f64> {
    let mut level = 1.0;
    (0..n)
        .map(|_| {
            if rng.uniform() < p_switch {
                level = -level;
            }
            level
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::simulate;

    /// The exact simulation here is right: a first order's step response is `K (1 - e^(-t/T))`.
    #[test]
    fn the_truth_simulation_is_exact() {
        let dt = 0.01;
        let y = simulate(&[2.0], &[1.0, 0.1], &[1.0; 50], dt);
        for (k, v) in y.iter().enumerate() {
            let t = k as f64 * dt;
            assert!(
                (v - 2.0 * (1.0 - (-t / 0.1).exp())).abs() < 1e-12,
                "{k} {v}"
            );
        }
        // a feed-through: (0.5 s + 20)/s on a unit step is 0.5 + 20 t
        let y = simulate(&[20.0, 0.5], &[0.0, 1.0], &[1.0; 10], dt);
        for (k, v) in y.iter().enumerate() {
            assert!((v - (0.5 + 20.0 * k as f64 * dt)).abs() < 1e-12, "{k} {v}");
        }
    }
}
