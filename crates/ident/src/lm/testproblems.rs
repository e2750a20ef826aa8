//! Problems and data the solvers' tests share.

use super::problem::{Mat, Problem};
use crate::Result;

/// A seeded generator of uniform numbers in [-0.5, 0.5) (a 64-bit LCG).
pub(super) fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut next = crate::testdata::lcg(seed);
    move || (next() >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// `y = a exp(-b t)` with deterministic "noise", counting Jacobians.
pub(super) struct NoisyExp {
    pub(super) t: Vec<f64>,
    pub(super) y: Vec<f64>,
    pub(super) jacobians: usize,
}
impl NoisyExp {
    pub(super) fn new() -> Self {
        let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.02).collect();
        let y = t
            .iter()
            .enumerate()
            .map(|(i, t)| 2.0 * (-0.5 * t).exp() + 0.01 * (((i * 37) % 11) as f64 - 5.0))
            .collect();
        Self { t, y, jacobians: 0 }
    }
}
impl Problem for NoisyExp {
    fn n_params(&self) -> usize {
        2
    }
    fn n_residuals(&self) -> usize {
        self.t.len()
    }
    fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
        for (i, (&t, &y)) in self.t.iter().zip(&self.y).enumerate() {
            r[i] = p[0] * (-p[1] * t).exp() - y;
        }
        if let Some(j) = jac {
            self.jacobians += 1;
            for (i, &t) in self.t.iter().enumerate() {
                j[(i, 0)] = (-p[1] * t).exp();
                j[(i, 1)] = -p[0] * t * (-p[1] * t).exp();
            }
        }
        Ok(())
    }
}
