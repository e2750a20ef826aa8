//! The plant as the design sees it: the model's exact frequency response and its logarithmic
//! derivative, with the hold's half-sample delay of a sampled loop.

use fracsim::{jw_pow, FracTf, Term};
use num_complex::Complex64;

/// The model `G(s)` and, for a loop sampled every `dt`, the zero-order hold's average delay
/// `exp(-s dt/2)` (Franklin, Powell & Workman, *Digital Control of Dynamic Systems*, §6.2).
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    /// The model, its input delay included.
    pub tf: FracTf,
    /// The hold's delay `dt/2` in seconds (0 for a continuous loop).
    pub hold_delay: f64,
}

fn poly(terms: &[Term], omega: f64) -> (Complex64, Complex64) {
    // value and d/d ln omega: d (j w)^a / d ln w = a (j w)^a
    terms.iter().fold(
        (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0)),
        |(v, d), t| {
            let p = jw_pow(omega, t.order) * t.coef;
            (v + p, d + p * t.order)
        },
    )
}

impl Plant {
    /// The plant of a continuous loop (`dt = None`) or of a loop sampled every `dt` seconds.
    pub fn new(tf: FracTf, dt: Option<f64>) -> Self {
        Self {
            tf,
            hold_delay: dt.map_or(0.0, |dt| dt / 2.0),
        }
    }

    /// The total delay in seconds: the model's and the hold's.
    pub fn delay(&self) -> f64 {
        self.tf.delay + self.hold_delay
    }

    /// `P(j omega) = G(j omega) exp(-j omega dt/2)`, omega in rad/s.
    pub fn freq_response(&self, omega: f64) -> Complex64 {
        let (n, _) = poly(&self.tf.num, omega);
        let (d, _) = poly(&self.tf.den, omega);
        n / d * Complex64::from_polar(1.0, -omega * self.delay())
    }

    /// `d ln P(j omega) / d ln omega = N'/N - D'/D - j omega tau`: its real part is the slope of
    /// `ln |P|`, its imaginary part the slope of the phase (rad per unit of `ln omega`).
    pub fn dlog(&self, omega: f64) -> Complex64 {
        let (n, dn) = poly(&self.tf.num, omega);
        let (d, dd) = poly(&self.tf.den, omega);
        dn / n - dd / d - Complex64::new(0.0, omega * self.delay())
    }

    /// The low-frequency order `n` of the plant, `P(s) ~ K s^-n` as `s -> 0`: the lowest
    /// denominator order minus the lowest numerator order.
    pub fn low_order(&self) -> f64 {
        let lowest = |t: &[Term]| t.iter().map(|t| t.order).fold(f64::INFINITY, f64::min);
        lowest(&self.tf.den) - lowest(&self.tf.num)
    }

    /// The phase of `P(j omega)` in radians, unwrapped: the delay-free part followed continuously
    /// from `omega 1e-6`, where it starts from its asymptote `-n pi/2` (`P ~ K s^-n`) plus the
    /// principal phase of `P / s^-n` (0 for `K > 0`), 100 points per decade, minus `omega tau`.
    pub fn phase_unwrapped(&self, omega: f64) -> f64 {
        let free = |w: f64| {
            let (n, _) = poly(&self.tf.num, w);
            let (d, _) = poly(&self.tf.den, w);
            n / d
        };
        let n = self.low_order();
        let w0 = omega * 1e-6;
        let steps = 600;
        let mut prev = free(w0);
        let mut phase = (prev * jw_pow(w0, n)).arg() - n * std::f64::consts::FRAC_PI_2;
        for i in 1..=steps {
            let w = omega * 10f64.powf(-6.0 + 6.0 * i as f64 / steps as f64);
            let v = free(w);
            phase += (v / prev).arg();
            prev = v;
        }
        phase - omega * self.delay()
    }
}
