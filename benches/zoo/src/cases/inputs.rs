//! The records' inputs: a random binary sequence at a clock, random multi-level, a step from rest,
//! steps up and down, a staircase, a chirp, a multisine, and the reference of a closed speed loop.

use rand::rngs::StdRng;
use rand::Rng;
use serde::{Deserialize, Serialize};

use super::plants::log_uniform;

/// How a record is excited.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Excitation {
    /// A random binary sequence held over a clock of several samples (two levels).
    Prbs,
    /// Five levels, random order, random hold times.
    MultiLevel,
    /// Rest, then one step.
    StepFromRest,
    /// Rest, up, back, down (or to the low level), up.
    StepsUpDown,
    /// Rest, five levels up and back down.
    Staircase,
    /// A logarithmic sine sweep.
    Chirp,
    /// A sum of log-spaced sines with random phases, periodic in the record.
    Multisine,
    /// A speed loop under a PI: the reference is random multi-level, the record is (u, y).
    ClosedLoop,
}

/// The input's range and the time scales it is shaped on.
#[derive(Clone, Copy, Debug)]
pub struct Shape {
    /// The lowest level.
    pub low: f64,
    /// The highest level.
    pub high: f64,
    /// Sample time [s].
    pub dt: f64,
    /// The plant's fastest time constant [s].
    pub fast_s: f64,
    /// The plant's slowest time constant [s].
    pub slow_s: f64,
}

impl Shape {
    fn span(&self) -> f64 {
        self.high - self.low
    }
    fn samples(&self, seconds: f64) -> usize {
        ((seconds / self.dt).round() as usize).max(1)
    }
}

/// `n` samples of `kind` (for `ClosedLoop`: the reference, in input units; scale it).
pub fn make(kind: Excitation, n: usize, shape: &Shape, rng: &mut StdRng) -> Vec<f64> {
    match kind {
        Excitation::Prbs => prbs(n, shape, rng),
        Excitation::MultiLevel | Excitation::ClosedLoop => multi_level(n, shape, rng),
        Excitation::StepFromRest => {
            let rest = (n as f64 * rng.gen_range(0.05..=0.2)) as usize;
            segments(n, &[0.0, shape.high], Some(rest))
        }
        Excitation::StepsUpDown => {
            let levels = if shape.low < 0.0 {
                vec![0.0, shape.high, 0.0, shape.low, 0.0, shape.high]
            } else {
                vec![0.0, shape.high, shape.low, shape.high, 0.0]
            };
            segments(n, &levels, None)
        }
        Excitation::Staircase => {
            let mut levels = vec![0.0];
            let step = |i: usize| shape.low + shape.span() * i as f64 / 4.0;
            levels.extend((0..5).map(step));
            levels.extend((0..4).rev().map(step));
            segments(n, &levels, None)
        }
        Excitation::Chirp => chirp(n, shape),
        Excitation::Multisine => multisine(n, shape, rng),
    }
}

/// The band a sweep or a multisine covers [Hz]: from a third of the slow corner to three times
/// the fast one, below a quarter of the sample rate.
fn sweep_band(n: usize, shape: &Shape) -> (f64, f64) {
    let record_s = n as f64 * shape.dt;
    let lo = (0.3 / (std::f64::consts::TAU * shape.slow_s)).max(4.0 / record_s);
    let hi = (3.0 / (std::f64::consts::TAU * shape.fast_s)).min(0.25 / shape.dt);
    (lo, hi.max(lo * 4.0))
}

fn prbs(n: usize, shape: &Shape, rng: &mut StdRng) -> Vec<f64> {
    let clock = shape.samples(log_uniform(rng, 0.1, 1.0) * shape.slow_s);
    let mut out = Vec::with_capacity(n);
    let mut level = shape.high;
    while out.len() < n {
        if rng.gen_bool(0.5) {
            level = if level == shape.high {
                shape.low
            } else {
                shape.high
            };
        }
        out.extend(std::iter::repeat_n(level, clock.min(n - out.len())));
    }
    out
}

fn multi_level(n: usize, shape: &Shape, rng: &mut StdRng) -> Vec<f64> {
    let mut out = Vec::with_capacity(n);
    let mut last = usize::MAX;
    while out.len() < n {
        let mut pick = rng.gen_range(0..5);
        if pick == last {
            pick = (pick + 1 + rng.gen_range(0..4)) % 5;
        }
        last = pick;
        let level = shape.low + shape.span() * pick as f64 / 4.0;
        let hold = shape.samples(rng.gen_range(0.3..=2.0) * shape.slow_s);
        out.extend(std::iter::repeat_n(level, hold.min(n - out.len())));
    }
    out
}

/// The levels over equal segments (the first `first` samples long when given).
fn segments(n: usize, levels: &[f64], first: Option<usize>) -> Vec<f64> {
    let mut out = Vec::with_capacity(n);
    let (head, rest) = match first {
        Some(k) => (k.min(n), &levels[1..]),
        None => (0, levels),
    };
    out.extend(std::iter::repeat_n(levels[0], head));
    let each = (n - head) / rest.len();
    for (i, level) in rest.iter().enumerate() {
        let len = if i + 1 == rest.len() {
            n - out.len()
        } else {
            each
        };
        out.extend(std::iter::repeat_n(*level, len));
    }
    out
}

fn chirp(n: usize, shape: &Shape) -> Vec<f64> {
    let (f0, f1) = sweep_band(n, shape);
    let record_s = n as f64 * shape.dt;
    let rate = (f1 / f0).ln() / record_s;
    let mid = 0.5 * (shape.low + shape.high);
    let half = 0.5 * shape.span();
    (0..n)
        .map(|k| {
            let t = k as f64 * shape.dt;
            // phase = 2 pi f0 (e^(rate t) - 1) / rate: the instantaneous frequency f0 e^(rate t)
            let phase = std::f64::consts::TAU * f0 * ((rate * t).exp() - 1.0) / rate;
            mid + half * phase.sin()
        })
        .collect()
}

fn multisine(n: usize, shape: &Shape, rng: &mut StdRng) -> Vec<f64> {
    let (f0, f1) = sweep_band(n, shape);
    let record_s = n as f64 * shape.dt;
    let lines = rng.gen_range(8..=20);
    let mut bins: Vec<usize> = (0..lines)
        .map(|i| {
            let f = f0 * (f1 / f0).powf(i as f64 / (lines - 1) as f64);
            ((f * record_s).round() as usize).max(1)
        })
        .collect();
    bins.dedup();
    let phases: Vec<f64> = bins
        .iter()
        .map(|_| rng.gen_range(0.0..std::f64::consts::TAU))
        .collect();
    let raw: Vec<f64> = (0..n)
        .map(|k| {
            let x = k as f64 / n as f64;
            bins.iter()
                .zip(&phases)
                .map(|(&b, &p)| (std::f64::consts::TAU * b as f64 * x + p).sin())
                .sum()
        })
        .collect();
    let peak = raw.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1e-12);
    let mid = 0.5 * (shape.low + shape.high);
    let half = 0.5 * shape.span();
    raw.iter().map(|v| mid + half * v / peak).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    const ALL: [Excitation; 8] = [
        Excitation::Prbs,
        Excitation::MultiLevel,
        Excitation::StepFromRest,
        Excitation::StepsUpDown,
        Excitation::Staircase,
        Excitation::Chirp,
        Excitation::Multisine,
        Excitation::ClosedLoop,
    ];

    #[test]
    fn every_input_has_its_length_and_stays_in_range() {
        let shape = Shape {
            low: -2.0,
            high: 3.0,
            dt: 1e-3,
            fast_s: 2e-3,
            slow_s: 20e-3,
        };
        let mut rng = StdRng::seed_from_u64(9);
        for kind in ALL {
            for n in [300, 1001, 5000] {
                let u = make(kind, n, &shape, &mut rng);
                assert_eq!(u.len(), n, "{kind:?}");
                assert!(
                    u.iter().all(|v| (-2.0 - 1e-9..=3.0 + 1e-9).contains(v)),
                    "{kind:?}"
                );
                let distinct = u.iter().any(|v| (v - u[0]).abs() > 1e-9);
                assert!(distinct, "{kind:?} is constant");
            }
        }
        let u = make(Excitation::Prbs, 2000, &shape, &mut rng);
        assert!(u.iter().all(|&v| v == -2.0 || v == 3.0));
        let u = make(Excitation::StepFromRest, 1000, &shape, &mut rng);
        assert_eq!((u[0], u[999]), (0.0, 3.0));
    }
}
