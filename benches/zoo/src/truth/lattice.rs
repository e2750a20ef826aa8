//! The plant's step response (no delay) on a lattice of times `t0 + j dt`: exact for integer
//! plants, Grunwald-Letnikov with Richardson extrapolation for fractional ones. Every simulation
//! is built from these lattices, since a held input is a sum of steps at known instants.
//!
//! Fractional: the response extrapolated from three GL grids (`gl::extrapolated_grid`) on the
//! fine grid `h`, the largest step with `h <= dt / 10` and, at every corner of the plant (where two
//! consecutive terms `c_i s^o_i`, `c_j s^o_j` balance, `omega_c = |c_i / c_j|^{1/(o_j - o_i)}`),
//! `h omega_c <= k(o_j - o_i)`: `k = 0.1` for an order step up to 1, falling to 0.0075 at 1.9
//! (`0.1 * 10^{-1.25 (step - 1)}`, floor 0.005), from the measured error of `1 / (s^alpha + 1)`
//! against Mittag-Leffler (third order in `h omega_c`, the constant largest as alpha nears 2).
//! A lattice time off the grid (a delay of fractional samples puts the whole lattice off it) is
//! interpolated by an 8-point Lagrange polynomial, which needs `t >= dt` (the response is smooth
//! there: its 8th derivative is of order `t^-8` times its size, `(h / t)^8 <= 1e-8`); the one
//! lattice time below `dt` gets its own aligned grid of `EARLY_STEPS` steps.

use super::exact::{self, StateSpace};
use super::gl;
use super::plant::{feedthrough, is_integer, nonzero, ORDER_EPS};
use super::{Error, Plant, Term};

/// The fine GL steps per sample at least (the coarsest of the three grids).
pub(crate) const MIN_FINE_PER_SAMPLE: usize = 10;
/// The finest grid's length at most (memory: a few vectors of this many f64).
pub(crate) const MAX_FINEST_POINTS: usize = 1 << 24;
/// The steps of the aligned grid for a lattice time below one sample.
const EARLY_STEPS: usize = 256;

/// How the step response is computed.
#[derive(Clone, Debug)]
pub(crate) enum StepResponse {
    /// Integer orders: the exact solution.
    Exact(StateSpace),
    /// Fractional orders: GL with Richardson extrapolation (the plant without its delay).
    Gl {
        /// The plant, delay removed.
        plant: Plant,
        /// `G(infinity)`, the response at `0+`.
        feedthrough: f64,
        /// The largest fine step the plant's corners allow [s].
        plant_step_s: f64,
    },
}

/// `k(step)`: the fine step times the corner frequency allowed for a corner of order `step`.
fn corner_factor(step: f64) -> f64 {
    (0.1 * 10f64.powf(-1.25 * (step - 1.0).max(0.0))).max(0.005)
}

/// The largest fine step the corners of `terms` allow [s] (infinite without a corner).
fn corner_step(terms: &[Term]) -> f64 {
    let mut t: Vec<Term> = nonzero(terms);
    t.sort_by(|p, q| p.order.total_cmp(&q.order));
    t.windows(2)
        .filter(|w| w[1].order - w[0].order > ORDER_EPS)
        .map(|w| {
            let step = w[1].order - w[0].order;
            let omega = (w[0].coef / w[1].coef).abs().powf(1.0 / step);
            corner_factor(step) / omega
        })
        .fold(f64::INFINITY, f64::min)
}

impl StepResponse {
    /// The method for `plant` (checked already).
    pub(crate) fn new(plant: &Plant) -> StepResponse {
        if is_integer(plant) {
            StepResponse::Exact(exact::realise(plant))
        } else {
            StepResponse::Gl {
                plant: Plant {
                    delay_s: 0.0,
                    ..plant.clone()
                },
                feedthrough: feedthrough(plant),
                plant_step_s: corner_step(&plant.den).min(corner_step(&plant.num)),
            }
        }
    }

    /// The fine GL steps per sample at `dt` (None for an exact solution).
    pub(crate) fn fine_per_sample(&self, dt: f64) -> Option<usize> {
        match self {
            StepResponse::Exact(_) => None,
            StepResponse::Gl { plant_step_s, .. } => {
                let wanted = (dt / plant_step_s).ceil();
                Some(if wanted.is_finite() {
                    (wanted as usize).max(MIN_FINE_PER_SAMPLE)
                } else {
                    MIN_FINE_PER_SAMPLE
                })
            }
        }
    }

    /// `S(t0 + j dt)` for `j = 0..count`, per `(t0, count)` wanted, `t0 >= 0`, with `S(0) =
    /// G(infinity)` (just after the step); a fractional plant's fine grid computed once for all.
    /// Errors when the fractional plant's finest grid would exceed `MAX_FINEST_POINTS`.
    pub(crate) fn lattices(
        &self,
        wanted: &[(f64, usize)],
        dt: f64,
    ) -> Result<Vec<Vec<f64>>, Error> {
        match self {
            StepResponse::Exact(ss) => Ok(wanted
                .iter()
                .map(|&(t0, count)| ss.step_lattice(t0, dt, count))
                .collect()),
            StepResponse::Gl {
                plant, feedthrough, ..
            } => {
                let per_sample = self.fine_per_sample(dt).unwrap_or(MIN_FINE_PER_SAMPLE);
                let h = dt / per_sample as f64;
                let t_last = wanted
                    .iter()
                    .filter(|w| w.1 > 0)
                    .map(|&(t0, count)| t0 + (count - 1) as f64 * dt)
                    .fold(0.0, f64::max);
                let len = (t_last / h).ceil() as usize + 8;
                if 4 * len > MAX_FINEST_POINTS {
                    return Err(Error::Plant(format!(
                        "the fractional plant needs {per_sample} fine steps per sample over {:.0} \
                         samples ({} points on the finest grid, at most {MAX_FINEST_POINTS}): a \
                         shorter record, a longer sample time or slower corners",
                        t_last / dt,
                        4 * len
                    )));
                }
                let grid = gl::extrapolated_grid(plant, h, len);
                Ok(wanted
                    .iter()
                    .map(|&(t0, count)| sample(&grid, plant, *feedthrough, h, t0, dt, count))
                    .collect())
            }
        }
    }
}

/// The lattice `t0 + j dt` read from the extrapolated fine grid of step `h`.
fn sample(grid: &[f64], plant: &Plant, d: f64, h: f64, t0: f64, dt: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|j| {
            let t = t0 + j as f64 * dt;
            let u = t / h;
            let k = u.round();
            if t <= 0.0 {
                d
            } else if (u - k).abs() <= 1e-9 * u.max(1.0) && k >= 1.0 {
                grid[k as usize]
            } else if t < dt {
                early(plant, t)
            } else {
                lagrange8(grid, u)
            }
        })
        .collect()
}

/// `S(t)` for `0 < t < dt` on its own grid ending at `t`.
fn early(plant: &Plant, t: f64) -> f64 {
    gl::extrapolated_grid(plant, t / EARLY_STEPS as f64, EARLY_STEPS + 1)[EARLY_STEPS]
}

/// The 8-point Lagrange interpolant of `grid` (unit spacing) at `u >= 3`.
fn lagrange8(grid: &[f64], u: f64) -> f64 {
    let first = u.floor() as usize - 3;
    let nodes: Vec<f64> = (first..first + 8).map(|i| i as f64).collect();
    (0..8)
        .map(|i| {
            let w: f64 = (0..8)
                .filter(|&m| m != i)
                .map(|m| (u - nodes[m]) / (nodes[i] - nodes[m]))
                .product();
            w * grid[first + i]
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::mittag_leffler::mittag_leffler;

    fn relaxation(alpha: f64, a: f64) -> Plant {
        Plant {
            num: vec![Term {
                coef: 1.0,
                order: 0.0,
            }],
            den: vec![
                Term {
                    coef: 1.0,
                    order: 0.0,
                },
                Term {
                    coef: a,
                    order: alpha,
                },
            ],
            delay_s: 0.0,
        }
    }

    /// The largest error at the samples `j dt`, `j = 1..count`, of grid values read every `per`.
    fn worst(grid: &[f64], per: usize, truth: &[f64]) -> f64 {
        (1..truth.len())
            .map(|j| (grid[j * per] - truth[j]).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn extrapolation_orders_are_one_two_three() {
        // 1 / (s^alpha + 1) against Mittag-Leffler over 50 samples, fine grids of 10 and 20 steps
        // per sample: doubling the steps divides the raw GL error by 2, after one Richardson stage
        // by 4, after two by 8 (at h omega_c = 0.1 and 0.05 for alpha = 0.9, 0.03 and 0.015 for
        // alpha = 1.5, where the errors stand well above rounding).
        for (alpha, dt) in [(0.9, 1.0), (1.5, 0.3)] {
            let plant = relaxation(alpha, 1.0);
            let count = 50;
            let truth: Vec<f64> = (0..count)
                .map(|j| 1.0 - mittag_leffler(alpha, -f64::powf(j as f64 * dt, alpha)))
                .collect();
            let errors = |per: usize| -> [f64; 3] {
                let h = dt / per as f64;
                let len = (count - 1) * per + 1;
                let g1 = gl::step_grid(&plant, h, len);
                let g2 = gl::step_grid(&plant, h / 2.0, 2 * len);
                let r1: Vec<f64> = (0..len).map(|j| 2.0 * g2[2 * j] - g1[j]).collect();
                let r2 = gl::extrapolated_grid(&plant, h, len);
                [
                    worst(&g1, per, &truth),
                    worst(&r1, per, &truth),
                    worst(&r2, per, &truth),
                ]
            };
            let (coarse, fine) = (errors(10), errors(20));
            let ratios: Vec<f64> = coarse.iter().zip(&fine).map(|(c, f)| c / f).collect();
            assert!(
                (1.8..2.2).contains(&ratios[0]),
                "alpha {alpha}: raw {ratios:?}"
            );
            assert!(
                (3.4..4.6).contains(&ratios[1]),
                "alpha {alpha}: one stage {ratios:?}"
            );
            assert!(
                (6.5..9.5).contains(&ratios[2]),
                "alpha {alpha}: two stages {ratios:?}"
            );
        }
    }
}
