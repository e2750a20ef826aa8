//! An independent truth for the time-domain tests, written here and not taken from fracsim's
//! simulators: the implicit Grunwald-Letnikov scheme of `K s^-i / sum_j a_j s^alpha_j` (`i` free
//! integrators) with the input held over each sample, at `dt/10` and `dt/20`,
//! Richardson-extrapolated (its own error is about 1e-4 of the output swing, see fracsim's test of
//! the same construction), read at the sample instants.

/// A plant: gain, denominator `(coef, order)` terms, free integrators, input delay (s).
#[derive(Clone, Copy)]
pub struct Plant<'a> {
    pub k: f64,
    pub den: &'a [(f64, f64)],
    pub integrators: u32,
    pub delay_s: f64,
}

/// The paper's PMSM `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`.
pub const PMSM: Plant<'static> = Plant {
    k: 6.82,
    den: &[(2.655e-5, 1.7452), (0.0059, 0.92), (1.0, 0.0)],
    integrators: 0,
    delay_s: 0.0,
};

/// GL at `dt/n` from rest, the input held and delayed by `plant.delay_s` (a whole number of fine
/// steps), read at the sample instants.
fn gl_held(plant: &Plant<'_>, u: &[f64], dt: f64, n: usize) -> Vec<f64> {
    let h = dt / n as f64;
    let m = u.len() * n;
    let shift = (plant.delay_s / h).round() as usize;
    let mut w = vec![0.0; m];
    for &(a, alpha) in plant.den {
        // s^-i K / D(s): the denominator D(s) s^i
        let alpha = alpha + plant.integrators as f64;
        let mut c = 1.0;
        for (j, wj) in w.iter_mut().enumerate() {
            if j > 0 {
                c *= 1.0 - (alpha + 1.0) / j as f64;
            }
            *wj += a * h.powf(-alpha) * c;
        }
    }
    let mut y = vec![0.0; m];
    for i in 0..m {
        let ui = if i >= shift { u[(i - shift) / n] } else { 0.0 };
        let mut rhs = plant.k * ui;
        for j in 1..=i {
            rhs -= w[j] * y[i - j];
        }
        y[i] = rhs / w[0];
    }
    (0..u.len()).map(|i| y[i * n]).collect()
}

/// The response to the held input `u` sampled every `dt`, from rest at `t = 0`
/// (Richardson of `dt/10` and `dt/20`).
pub fn response(plant: &Plant<'_>, u: &[f64], dt: f64) -> Vec<f64> {
    let (c, f) = (gl_held(plant, u, dt, 10), gl_held(plant, u, dt, 20));
    c.iter().zip(&f).map(|(c, f)| 2.0 * f - c).collect()
}

/// Seeded white noise.
pub fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let d = Normal::new(0.0, sigma).unwrap();
    (0..n).map(|_| d.sample(&mut rng)).collect()
}
