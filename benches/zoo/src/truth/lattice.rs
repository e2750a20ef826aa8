//! The plant's step response (no delay) on a lattice of times `t0 + j dt`: exact for integer
//! plants, Grunwald-Letnikov with Richardson extrapolation for fractional ones. Every simulation
//! is built from these lattices, since a held input is a sum of steps at known instants.
//!
//! Fractional: the response extrapolated from three GL grids (`gl::extrapolated_grid`) on the
//! fine grid `h`, the largest step with `h <= dt / 10` and, at every corner of the numerator and
//! the denominator (where the dominant term passes from `c_i s^o_i` to `c_j s^o_j`, `omega_c =
//! |c_i / c_j|^{1/(o_j - o_i)}`), `h omega_c <= k(o_j - o_i)`: `k = 0.1` for an order step up to 1, falling to 0.0075 at 1.9
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

/// The largest fine step the corners of `terms` allow [s] (infinite without a corner). The
/// corners are where the dominant term changes (the upper envelope of the lines `ln|c_i| + o_i
/// ln omega`, the Newton polygon, whose slopes give the roots' magnitudes): a term that never
/// dominates makes no corner.
fn corner_step(terms: &[Term]) -> f64 {
    let t: Vec<(f64, f64)> = nonzero(terms)
        .iter()
        .map(|t| (t.order, t.coef.abs().ln()))
        .collect();
    let Some(mut cur) = t.iter().copied().reduce(|a, b| {
        if b.0 < a.0 - ORDER_EPS || (b.0 - a.0).abs() <= ORDER_EPS && b.1 > a.1 {
            b
        } else {
            a
        }
    }) else {
        return f64::INFINITY;
    };
    let mut allowed = f64::INFINITY;
    loop {
        // The next line to overtake the current one: the smallest crossing (the highest order
        // among equal crossings).
        let next = t
            .iter()
            .filter(|p| p.0 > cur.0 + ORDER_EPS)
            .map(|&p| ((cur.1 - p.1) / (p.0 - cur.0), p))
            .reduce(|a, b| {
                if b.0 < a.0 || (b.0 == a.0 && b.1 .0 > a.1 .0) {
                    b
                } else {
                    a
                }
            });
        let Some((x, p)) = next else { return allowed };
        allowed = allowed.min(corner_factor(p.0 - cur.0) / x.exp());
        cur = p;
    }
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

    fn terms(list: &[(f64, f64)]) -> Vec<Term> {
        list.iter()
            .map(|&(coef, order)| Term { coef, order })
            .collect()
    }

    /// The GL method forced on `plant` with the fine step the rule picks at `dt` divided by
    /// `finer`.
    fn gl_with(plant: &Plant, dt: f64, finer: f64) -> StepResponse {
        let rule = StepResponse::Gl {
            plant: Plant {
                delay_s: 0.0,
                ..plant.clone()
            },
            feedthrough: feedthrough(plant),
            plant_step_s: corner_step(&plant.den).min(corner_step(&plant.num)),
        };
        let h = dt / rule.fine_per_sample(dt).unwrap() as f64;
        match rule {
            StepResponse::Gl {
                plant, feedthrough, ..
            } => StepResponse::Gl {
                plant,
                feedthrough,
                plant_step_s: h / finer * (1.0 + 1e-9),
            },
            StepResponse::Exact(_) => unreachable!("built as GL"),
        }
    }

    fn max_gap(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
    }

    fn swing(a: &[f64]) -> f64 {
        a.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    #[test]
    fn the_fine_step_rule_is_converged() {
        // Halving the fine step the corners ask for moves the lattice by < 1e-5 of the swing, for
        // the zoo's fractional shapes: a PMSM 50 / (s^0.9 (0.002 s^0.95 + 1)) at 1 ms, a thermal
        // diffusion 1 / (20 s^0.5 + 1)(5 s^0.6 + 1) at 0.5 s, a cell 0.05 + 1 / (3 s^0.7) at 10 ms,
        // a near-resonant 1 / (1e-4 s^1.8 + 0.01 s^0.9 + 1) at 5 ms; a delay of 1.37 samples.
        let cases = [
            (
                terms(&[(50.0, 0.0)]),
                terms(&[(1.0, 0.9), (0.002, 1.85)]),
                1e-3,
            ),
            (
                terms(&[(1.0, 0.0)]),
                terms(&[(1.0, 0.0), (25.0, 0.5), (5.0, 0.6), (100.0, 1.1)]),
                0.5,
            ),
            (
                terms(&[(1.0, 0.0), (0.15, 0.7)]),
                terms(&[(3.0, 0.7)]),
                1e-2,
            ),
            (
                terms(&[(1.0, 0.0)]),
                terms(&[(1.0, 0.0), (0.01, 0.9), (1e-4, 1.8)]),
                5e-3,
            ),
        ];
        for (num, den, dt) in cases {
            let plant = Plant {
                num,
                den,
                delay_s: 0.0,
            };
            let wanted = [(0.0, 300), (0.63 * dt, 300)];
            let base = gl_with(&plant, dt, 1.0).lattices(&wanted, dt).unwrap();
            let finer = gl_with(&plant, dt, 2.0).lattices(&wanted, dt).unwrap();
            for (a, b) in base.iter().zip(&finer) {
                let gap = max_gap(a, b) / swing(a);
                assert!(gap < 1e-5, "{:?} dt {dt}: {gap:e}", plant.den);
            }
        }
    }

    #[test]
    fn gl_agrees_with_the_exact_integer_solution() {
        // Two independent methods on integer plants: a motor-side two-mass drive (anti-resonance
        // 80 Hz, resonance 120 Hz, damping 0.05 and 0.03, an integrator) at 0.2 ms, and a third
        // order with a zero at 1 ms: GL extrapolated against the matrix exponential, 1e-4 of the
        // swing (measured 5e-6: at order 3 the fine grid's rounding, amplified by the recursion's
        // near-triple pole at z = 1, is what is left, not the discretisation).
        let (wa, wr) = (std::f64::consts::TAU * 80.0, std::f64::consts::TAU * 120.0);
        let (za, zr) = (0.05, 0.03);
        let motor_side = Plant {
            num: terms(&[(wa * wa, 0.0), (2.0 * za * wa, 1.0), (1.0, 2.0)]),
            den: terms(&[
                (wr * wr * 0.01, 1.0),
                (2.0 * zr * wr * 0.01, 2.0),
                (0.01, 3.0),
            ]),
            delay_s: 0.0,
        };
        let third = Plant {
            num: terms(&[(2.0, 0.0), (0.1, 1.0)]),
            den: terms(&[(1.0, 0.0), (0.3, 1.0), (0.02, 2.0), (0.001, 3.0)]),
            delay_s: 0.0,
        };
        for (plant, dt) in [(motor_side, 2e-4), (third, 1e-3)] {
            let wanted = [(0.0, 400), (0.4 * dt, 400)];
            let exact = StepResponse::new(&plant).lattices(&wanted, dt).unwrap();
            assert!(matches!(StepResponse::new(&plant), StepResponse::Exact(_)));
            let gl = gl_with(&plant, dt, 1.0).lattices(&wanted, dt).unwrap();
            for (a, b) in exact.iter().zip(&gl) {
                let gap = max_gap(a, b) / swing(a);
                assert!(gap < 1e-4, "dt {dt}: {gap:e}");
            }
        }
    }
}
