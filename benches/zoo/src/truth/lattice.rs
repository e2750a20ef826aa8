//! The plant's step response (no delay) on a lattice of times `t0 + j dt`: exact for integer
//! plants, Grunwald-Letnikov with Richardson extrapolation for fractional ones. Every simulation
//! is built from these lattices, since a held input is a sum of steps at known instants.
//!
//! Fractional: the extrapolated response on the fine grid `h = dt / FINE_PER_SAMPLE`; a lattice
//! time off that grid (a delay of fractional samples puts the whole lattice off it) is
//! interpolated by an 8-point Lagrange polynomial, which needs `t >= dt` (the response is smooth
//! there: its 8th derivative is of order `t^-8` times its size, `(h / t)^8 <= 1e-8`); the one
//! lattice time below `dt` gets its own aligned grid of `EARLY_STEPS` steps.

use super::exact::{self, StateSpace};
use super::gl;
use super::plant::{feedthrough, is_integer};
use super::Plant;

/// The fine GL steps per sample (the coarser of the two Richardson grids).
pub(crate) const FINE_PER_SAMPLE: usize = 10;
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
        /// Fine steps per sample.
        fine_per_sample: usize,
    },
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
                fine_per_sample: FINE_PER_SAMPLE,
            }
        }
    }

    /// `S(t0 + j dt)` for `j = 0..count`, `t0 >= 0`, with `S(0) = G(infinity)` (just after the
    /// step).
    pub(crate) fn lattice(&self, t0: f64, dt: f64, count: usize) -> Vec<f64> {
        match self {
            StepResponse::Exact(ss) => ss.step_lattice(t0, dt, count),
            StepResponse::Gl {
                plant,
                feedthrough,
                fine_per_sample,
            } => gl_lattice(plant, *feedthrough, *fine_per_sample, t0, dt, count),
        }
    }
}

fn gl_lattice(
    plant: &Plant,
    d: f64,
    per_sample: usize,
    t0: f64,
    dt: f64,
    count: usize,
) -> Vec<f64> {
    if count == 0 {
        return vec![];
    }
    let h = dt / per_sample as f64;
    let t_last = t0 + (count - 1) as f64 * dt;
    let len = (t_last / h).ceil() as usize + 8;
    let grid = gl::richardson_grid(plant, h, len);
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
                lagrange8(&grid, u)
            }
        })
        .collect()
}

/// `S(t)` for `0 < t < dt` on its own grid ending at `t`.
fn early(plant: &Plant, t: f64) -> f64 {
    gl::richardson_grid(plant, t / EARLY_STEPS as f64, EARLY_STEPS + 1)[EARLY_STEPS]
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
