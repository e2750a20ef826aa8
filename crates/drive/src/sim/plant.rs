//! The motor with its hidden effects, stepped once per sample.
//!
//! Per sample the command goes through the input delay, then the input-side effects (offset,
//! Coulomb friction, ripple) act on the motor model; the measured speed gets the noise, then the
//! quantisation.

use super::{Effects, SimConfig};
use crate::error::{Error, Result};
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use std::collections::VecDeque;

/// A pure transport delay of a whole number of samples.
#[derive(Debug, Clone)]
pub(super) struct DelayLine {
    buf: VecDeque<f64>,
}

impl DelayLine {
    /// A delay of `samples` samples, at rest (zeros).
    pub(super) fn new(samples: usize) -> Self {
        Self {
            buf: std::iter::repeat_n(0.0, samples).collect(),
        }
    }

    /// Push this sample's input; returns the input of `samples` samples ago (0 at first).
    pub(super) fn push(&mut self, u: f64) -> f64 {
        self.buf.push_back(u);
        self.buf.pop_front().unwrap_or(u)
    }

    /// Back to rest.
    pub(super) fn clear(&mut self) {
        self.buf.iter_mut().for_each(|d| *d = 0.0);
    }
}

/// Speed below which the motor is taken to stand still (friction then holds it), rad/s.
const STANDSTILL: f64 = 1e-3;

/// The input after Coulomb friction `vc` (V, at the input) opposing the motion: `u - vc
/// sign(speed)` when turning; at standstill friction holds the motor (0) unless `|u| > vc`,
/// then it opposes the command.
pub(super) fn coulomb(u: f64, speed: f64, vc: f64) -> f64 {
    if vc <= 0.0 {
        u
    } else if speed.abs() > STANDSTILL {
        u - vc * speed.signum()
    } else if u.abs() <= vc {
        0.0
    } else {
        u - vc * u.signum()
    }
}

/// `y` rounded to the nearest multiple of `step` (none when `step` is 0).
pub(super) fn quantise(y: f64, step: f64) -> f64 {
    if step > 0.0 {
        (y / step).round() * step
    } else {
        y
    }
}

/// The motor with its hidden effects.
pub(super) struct Plant {
    sim: fracsim::Simulator<f64>,
    dc_gain: f64,
    fx: Effects,
    delay: DelayLine,
    y: f64,
    k: u64,
    dt: f64,
    noise: Normal<f64>,
}

impl Plant {
    pub(super) fn new(cfg: &SimConfig, fs: u32) -> Result<Self> {
        let dt = 1.0 / fs as f64;
        let sim = fracsim::Simulator::<f64>::new(&cfg.model, dt, &cfg.approx)
            .map_err(|e| Error::InvalidParam(format!("motor model: {e}")))?;
        let dc_gain = cfg.model.num.iter().map(|t| t.coef).sum::<f64>()
            / cfg
                .model
                .den
                .iter()
                .filter(|t| t.order == 0.0)
                .map(|t| t.coef)
                .sum::<f64>();
        let nd = (cfg.effects.delay_s.max(0.0) * fs as f64).round() as usize;
        Ok(Self {
            sim,
            dc_gain: if dc_gain.is_finite() && dc_gain != 0.0 {
                dc_gain
            } else {
                1.0
            },
            fx: cfg.effects,
            delay: DelayLine::new(nd),
            y: 0.0,
            k: 0,
            dt,
            noise: Normal::new(0.0, cfg.effects.noise_std.max(0.0))
                .unwrap_or(Normal::new(0.0, 0.0).expect("valid")),
        })
    }

    /// The voltage acting on the motor for the (delayed) command `ud`: offset, friction, ripple.
    fn input(&self, ud: f64) -> f64 {
        let fx = &self.fx;
        let mut ue = coulomb(ud + fx.offset_v, self.y, fx.coulomb_v);
        if fx.ripple_v != 0.0 {
            ue += fx.ripple_v
                * (2.0 * std::f64::consts::PI * fx.ripple_hz * self.k as f64 * self.dt).sin();
        }
        ue
    }

    /// The true speed as the sensor gives it: noise, then quantisation.
    fn sense(&mut self, y: f64, rng: &mut StdRng) -> f64 {
        let mut ym = y;
        if self.fx.noise_std > 0.0 {
            ym += self.noise.sample(rng);
        }
        quantise(ym, self.fx.speed_quant)
    }

    /// One sample: command u (V) -> (measured speed rad/s, current A).
    pub(super) fn step(&mut self, u: f64, rng: &mut StdRng) -> (f64, f64) {
        let ud = self.delay.push(u);
        let ue = self.input(ud);
        self.k += 1;
        let y = self.sim.step(ue);
        self.y = if y.is_finite() { y } else { 0.0 };
        let ym = self.sense(self.y, rng);
        let i = (ue - self.y / self.dc_gain) / self.fx.r_ohm.max(1e-6);
        (ym, i)
    }

    /// The speed measured at the tick, before this sample's command: the output at `t_k`
    /// ([`fracsim::Simulator::next_output`]; the last output for a model that feeds its input
    /// through), with the measurement noise and quantisation.
    pub(super) fn measure(&mut self, rng: &mut StdRng) -> f64 {
        let y = self
            .sim
            .next_output()
            .filter(|v| v.is_finite())
            .unwrap_or(self.y);
        self.sense(y, rng)
    }

    pub(super) fn reset(&mut self) {
        self.sim.reset();
        self.delay.clear();
        self.y = 0.0;
        self.k = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    const FS: u32 = 1000;
    const DT: f64 = 1e-3;

    /// `K/(T s + 1)`, K = 2, T = 20 ms, with the given effects.
    fn first_order(fx: Effects) -> Plant {
        let cfg = SimConfig {
            model: "2/(0.02 s + 1)".parse().expect("model"),
            effects: fx,
            ..SimConfig::default()
        };
        Plant::new(&cfg, FS).expect("plant")
    }

    fn run(p: &mut Plant, u: impl Fn(usize) -> f64, n: usize) -> Vec<(f64, f64)> {
        let mut rng = StdRng::seed_from_u64(1);
        (0..n).map(|k| p.step(u(k), &mut rng)).collect()
    }

    #[test]
    fn first_order_step_is_the_exact_exponential() {
        // Zero-order hold, y_k at t_k: y_k = K (1 - exp(-k dt / T)) exactly.
        let mut p = first_order(Effects::default());
        let y = run(&mut p, |_| 1.0, 200);
        let worst = (0..200)
            .map(|k| (y[k].0 - 2.0 * (1.0 - (-(k as f64) * DT / 0.02).exp())).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "worst error {worst}");
        // the current: what drives the motor beyond its back-EMF, over R = 1 ohm
        assert!((y[0].1 - 1.0).abs() < 1e-12);
        assert!(
            y[199].1.abs() < 1e-3,
            "current at steady state {}",
            y[199].1
        );
    }

    #[test]
    fn measure_gives_the_output_at_the_tick_before_the_command() {
        let mut p = first_order(Effects::default());
        let mut rng = StdRng::seed_from_u64(1);
        for k in 0..50 {
            let before = p.measure(&mut rng);
            let want = 2.0 * (1.0 - (-(k as f64) * DT / 0.02).exp());
            assert!((before - want).abs() < 1e-9, "k {k}: {before} vs {want}");
            p.step(1.0, &mut rng);
        }
    }

    #[test]
    fn coulomb_friction_opposes_the_motion() {
        assert_eq!(coulomb(3.0, 1.0, 0.5), 2.5);
        assert_eq!(coulomb(3.0, -1.0, 0.5), 3.5);
        assert_eq!(coulomb(-3.0, -1.0, 0.5), -2.5);
        // at standstill it holds a small command, opposes a large one
        assert_eq!(coulomb(0.4, 0.0, 0.5), 0.0);
        assert_eq!(coulomb(-0.4, 0.0, 0.5), 0.0);
        assert_eq!(coulomb(-0.7, 0.0, 0.5), -0.7 + 0.5);
        assert_eq!(coulomb(0.7, 0.0, 0.0), 0.7);
    }

    #[test]
    fn coulomb_friction_lowers_the_steady_speed_by_k_vc_either_way() {
        // K (u - Vc sign(u)): +-3 V against 1 V of friction ends at +-2 K = +-4 rad/s.
        for (u, want) in [(3.0, 4.0), (-3.0, -4.0), (0.9, 0.0)] {
            let fx = Effects {
                coulomb_v: 1.0,
                ..Effects::default()
            };
            let mut p = first_order(fx);
            let y = run(&mut p, |_| u, 400);
            assert!((y[399].0 - want).abs() < 1e-6, "u {u}: {}", y[399].0);
        }
    }

    #[test]
    fn input_offset_adds_to_the_command() {
        let fx = Effects {
            offset_v: 0.25,
            ..Effects::default()
        };
        let mut p = first_order(fx);
        let y = run(&mut p, |_| 0.0, 400);
        assert!((y[399].0 - 0.5).abs() < 1e-6, "{}", y[399].0);
    }

    #[test]
    fn delay_shifts_the_response_by_exactly_the_delay_in_samples() {
        let mut plain = first_order(Effects::default());
        let mut late = first_order(Effects {
            delay_s: 0.007,
            ..Effects::default()
        });
        let u = |k: usize| {
            if (k / 13).is_multiple_of(2) {
                1.0
            } else {
                -0.5
            }
        };
        let y0 = run(&mut plain, u, 300);
        let y1 = run(&mut late, u, 300);
        assert!(y1[..7].iter().all(|v| v.0 == 0.0));
        for k in 7..300 {
            assert_eq!(y1[k].0, y0[k - 7].0, "sample {k}");
        }
    }

    #[test]
    fn delay_line_returns_the_input_n_samples_ago() {
        let mut d = DelayLine::new(3);
        let out: Vec<f64> = (1..=6).map(|k| d.push(k as f64)).collect();
        assert_eq!(out, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
        d.clear();
        assert_eq!(d.push(9.0), 0.0);
        let mut none = DelayLine::new(0);
        assert_eq!(none.push(5.0), 5.0);
    }

    #[test]
    fn quantisation_rounds_to_the_nearest_step() {
        assert!((quantise(0.26, 0.1) - 0.3).abs() < 1e-15);
        assert!((quantise(-0.24, 0.1) + 0.2).abs() < 1e-15);
        assert_eq!(quantise(0.123, 0.0), 0.123);
        let q = 0.05;
        let mut p = first_order(Effects {
            speed_quant: q,
            ..Effects::default()
        });
        let y = run(&mut p, |_| 1.0, 100);
        for (k, v) in y.iter().enumerate() {
            let exact = 2.0 * (1.0 - (-(k as f64) * DT / 0.02).exp());
            let steps = v.0 / q;
            assert!(
                (steps - steps.round()).abs() < 1e-9,
                "{} not on the grid",
                v.0
            );
            assert!((v.0 - exact).abs() <= q / 2.0 + 1e-9);
        }
    }

    #[test]
    fn ripple_is_a_sine_at_its_frequency_at_the_input() {
        // no command: the motor sees only the ripple, so the current at sample k (back-EMF
        // subtracted) is the ripple itself, A sin(2 pi f k dt) at R = 1 ohm, once y is known
        let mut p = first_order(Effects {
            ripple_v: 0.3,
            ripple_hz: 50.0,
            ..Effects::default()
        });
        let y = run(&mut p, |_| 0.0, 100);
        for (k, (_, i)) in y.iter().enumerate().skip(1) {
            let ue = i + y[k].0 / 2.0;
            let want = 0.3 * (std::f64::consts::TAU * 50.0 * k as f64 * DT).sin();
            assert!((ue - want).abs() < 1e-12, "sample {k}: {ue} vs {want}");
        }
    }

    #[test]
    fn noise_has_its_standard_deviation_and_no_bias() {
        let mut p = first_order(Effects {
            noise_std: 0.2,
            ..Effects::default()
        });
        let n = 20_000;
        let y = run(&mut p, |_| 0.0, n);
        let mean = y.iter().map(|v| v.0).sum::<f64>() / n as f64;
        let var = y.iter().map(|v| (v.0 - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        // standard errors: mean 0.2/sqrt(n) = 1.4e-3, std about 0.2/sqrt(2n) = 1e-3
        assert!(mean.abs() < 6e-3, "mean {mean}");
        assert!((var.sqrt() - 0.2).abs() < 6e-3, "std {}", var.sqrt());
    }

    /// `K/((T s + 1)(s^2/wr^2 + 2 z s/wr + 1))`, its exact step response by residues:
    /// `y(t) = K + r1 e^(p1 t) + 2 Re(r2 e^(p2 t))` with `p1 = -1/T`, `p2 = -z wr + i wr
    /// sqrt(1 - z^2)`.
    fn two_mass_step(k: f64, t_s: f64, wr: f64, z: f64, t: f64) -> f64 {
        use num_complex::Complex64 as C;
        let p1 = -1.0 / t_s;
        let p2 = C::new(-z * wr, wr * (1.0 - z * z).sqrt());
        let quad = |s: f64| s * s + 2.0 * z * wr * s + wr * wr;
        let r1 = k * wr * wr / (t_s * p1 * quad(p1));
        let r2 = k * wr * wr / ((p2 * t_s + 1.0) * p2 * (p2 - p2.conj()));
        k + r1 * (p1 * t).exp() + 2.0 * (r2 * (p2 * t).exp()).re
    }

    #[test]
    fn a_two_mass_resonance_written_as_a_product_steps_as_its_exact_response() {
        // measured at the load: 45 Hz, damping 0.05, behind a 5 ms motor lag; K = 3 rad/s/V
        let (k, t_s, wr, z) = (3.0, 0.005, std::f64::consts::TAU * 45.0, 0.05);
        let text = format!(
            "{k}/(({t_s} s + 1)({:e} s^2 + {:e} s + 1))",
            1.0 / (wr * wr),
            2.0 * z / wr
        );
        let model: fracsim::FracTf = text.parse().expect("a product as people write it");
        assert_eq!(model.factors().len(), 2, "kept as its two factors: {text}");
        let cfg = SimConfig {
            model,
            ..SimConfig::default()
        };
        let mut p = Plant::new(&cfg, FS).expect("plant");
        let y = run(&mut p, |_| 1.0, 600);
        // a held step is exactly the continuous step at the samples (zero-order hold)
        let peak = y.iter().map(|v| v.0).fold(0.0, f64::max);
        let worst = (0..600)
            .map(|k_| (y[k_].0 - two_mass_step(k, t_s, wr, z, k_ as f64 * DT)).abs())
            .fold(0.0, f64::max);
        eprintln!("two-mass step: worst error {worst:.3e} rad/s over 0.6 s, peak {peak:.4}");
        assert!(worst < 1e-9 * k, "worst error {worst} (peak {peak})");
        // the resonance rings: the response overshoots the gain
        assert!(peak > 1.2 * k, "peak {peak}");
    }

    #[test]
    fn every_structure_the_identification_returns_runs_with_its_effects() {
        // pmsm, commensurate, second- and third-order, two-mass (a product), feed-through,
        // fopdt (a delay in the model), a general fractional model
        for text in [
            "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
            "6.8/(1e-4 s^1.8 + 0.01 s^0.9 + 1)",
            "6.8/(1e-4 s^2 + 0.01 s + 1)",
            "6.8/(1.25e-7 s^3 + 8.75e-5 s^2 + 0.0175 s + 1)",
            "6.8 (1e-4 s^2 + 0.002 s^0.9 + 1)/((2.8e-5 s^1.78 + 0.0064 s^0.89 + 1)(5e-5 s^2 + 0.001 s^0.9 + 1))",
            "0.5 + 6.77/(2.8e-5 s^1.78 + 0.0064 s^0.89 + 1)",
            "6.8/(0.02 s + 1) exp(-0.003 s)",
            "2.5 (0.001 s^0.5 + 1)/(3e-4 s^1.3 + 0.002 s^0.9 + 1)",
        ] {
            let model: fracsim::FracTf = text.parse().expect(text);
            let dc = model.dc_gain();
            let cfg = SimConfig {
                model,
                effects: Effects {
                    coulomb_v: 0.1,
                    delay_s: 0.002,
                    ripple_v: 0.05,
                    ripple_hz: 30.0,
                    noise_std: 0.01,
                    speed_quant: 0.005,
                    offset_v: 0.2,
                    ..Effects::default()
                },
                ..SimConfig::default()
            };
            let mut p = Plant::new(&cfg, FS).unwrap_or_else(|e| panic!("{text}: {e}"));
            let y = run(&mut p, |_| 1.0, 3000);
            // at rest after 3 s: the gain times (1 V + 0.2 V offset - 0.1 V friction), within
            // the ripple's, the noise's and the quantisation's share
            let tail = &y[2500..];
            let mean = tail.iter().map(|v| v.0).sum::<f64>() / tail.len() as f64;
            assert!(
                (mean - 1.1 * dc).abs() < 0.02 * dc.abs() + 0.01,
                "{text}: {mean} vs {}",
                1.1 * dc
            );
        }
    }
}
