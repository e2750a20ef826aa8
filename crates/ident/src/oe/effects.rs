//! Effects added around the linear fractional model, per sample and generic over [`Real`], so the
//! same output-error machinery fits their parameters with exact sensitivities (docs/design.md §6).
//!
//! Effects act on **absolute** signals: at sample `k` the input transform sees `u0 + u_k` (the
//! measured input) and the previous model output `y0 + yhat_(k-1)`; the linear model is driven by
//! the transformed input minus `u0`. The output transform sees `y0 + x_k` (the linear model's
//! output on the absolute scale) and the model output is its result minus `y0`. `(u0, y0)` is the
//! operating point removed from the data ([`crate::data::Offsets`]). Input effects are applied in
//! list order before the model's input delay, output effects in list order after the model.

use fracsim::Real;

/// Where an effect's parameters live: indices into the model's parameter vector
/// ([`super::FracModel::params`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub enum Effect {
    /// Constant input offset: `u + c` (`c` = parameter `c`).
    InputOffset {
        /// Parameter index of the offset.
        c: usize,
    },
    /// The zero of a sign-blind sensor ([`Effect::AbsSensor`]) on the deviation scale: `u + c`
    /// like an input offset, but not one the plant has (the operating point was read from the
    /// rectified data, so the deviation scale's zero is not the plant's: `c = u0 - y0 / K` with
    /// no offset at all); reported as part of the sensor.
    SensorZero {
        /// Parameter index of the offset.
        c: usize,
    },
    /// Constant output offset: `y + c`.
    OutputOffset {
        /// Parameter index of the offset.
        c: usize,
    },
    /// Coulomb friction as an equivalent input voltage: `u - vc sign(y)`, `y` the speed the
    /// plant puts out (before a sign-blind sensor) over the hold interval (see
    /// [`super::FracModel`]'s simulation): extrapolated to the interval's middle, the mean sign
    /// of a friction that acts continuously, or, `sampled`, the output at the interval's start
    /// (the sample instant), decided there and held like the input, as a simulator that steps
    /// the mechanics once per sample has it (the drive simulator, the benchmark zoo's truth).
    Coulomb {
        /// Parameter index of `Vc`.
        vc: usize,
        /// The sign decided at the sample instant and held over the interval (else at the
        /// interval's middle).
        #[serde(default)]
        sampled: bool,
    },
    /// Input clipping: `clamp(u, -level, level)`.
    Saturation {
        /// Parameter index of the level.
        level: usize,
    },
    /// Input dead band: `0` for `|u| < width`, else `u - width sign(u)`.
    Deadzone {
        /// Parameter index of the half width.
        width: usize,
    },
    /// A smooth monotone input map, a power law through the origin and `u_ref`:
    /// `u -> sign(u) u_ref (|u| / u_ref)^p` (`p` = parameter `p`, `u_ref` fixed: the record's
    /// largest input magnitude, so the map leaves `u_ref` where it is and the model's gain keeps
    /// its meaning there). `p = 1` is the identity; `p = 2` a heater whose power rises with the
    /// square of its voltage; `p < 1` a map that flattens like a soft saturation.
    PowerLaw {
        /// Parameter index of the exponent.
        p: usize,
        /// The input magnitude the map leaves unchanged (fixed).
        u_ref: f64,
    },
    /// The sensor measures the magnitude: `y -> |y|`.
    AbsSensor,
    /// A slow output drift, linear in time: `y + r t` (`r` = parameter `r`, output units per
    /// second; `t` from the record's first sample, so that it is told from the output offset):
    /// a sensor's or an amplifier's thermal drift, a battery's open-circuit voltage following
    /// its state of charge over a short record.
    OutputDrift {
        /// Parameter index of the rate.
        r: usize,
    },
    /// An additive output sinusoid `a cos(2 pi f t) + b sin(2 pi f t)` at a fixed frequency.
    Sinusoid {
        /// Frequency in Hz (fixed).
        freq_hz: f64,
        /// Parameter index of the cosine amplitude.
        a: usize,
        /// Parameter index of the sine amplitude.
        b: usize,
    },
}

/// The sign of the value: -1, 0 or +1 (0 at 0, unlike `f64::signum`).
pub(crate) fn sign<T: Real>(x: T) -> f64 {
    let v = x.re();
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl Effect {
    /// Transform the absolute input `u` at time `t` given the absolute model output `y_prev` over
    /// the interval the input is held (extrapolated to its middle).
    #[inline]
    pub fn input<T: Real>(&self, p: &[T], u: T, y_prev: T, _t: f64) -> T {
        match *self {
            Effect::InputOffset { c } | Effect::SensorZero { c } => u + p[c],
            Effect::Coulomb { vc, .. } => u - p[vc] * sign(y_prev),
            Effect::Saturation { level } => {
                let l = p[level];
                if u.re() > l.re() {
                    l
                } else if u.re() < -l.re() {
                    -l
                } else {
                    u
                }
            }
            Effect::Deadzone { width } => {
                let w = p[width];
                if u.re().abs() < w.re() {
                    T::from(0.0)
                } else {
                    u - w * sign(u)
                }
            }
            Effect::PowerLaw { p: i, u_ref } => {
                let x = u.re().abs() / u_ref;
                if x == 0.0 {
                    T::from(0.0)
                } else {
                    // sign(u) u_ref x^p, its derivative in u carried by `u`'s own part
                    (u.abs() * (1.0 / u_ref)).powr(p[i]) * (sign(u) * u_ref)
                }
            }
            _ => u,
        }
    }

    /// Transform the absolute output `y` at time `t`.
    #[inline]
    pub fn output<T: Real>(&self, p: &[T], y: T, t: f64) -> T {
        match *self {
            Effect::OutputOffset { c } => y + p[c],
            Effect::OutputDrift { r } => y + p[r] * t,
            Effect::AbsSensor => y.abs(),
            Effect::Sinusoid { freq_hz, a, b } => {
                let w = 2.0 * std::f64::consts::PI * freq_hz * t;
                y + p[a] * w.cos() + p[b] * w.sin()
            }
            _ => y,
        }
    }

    /// The indices of its parameters.
    pub fn params(&self) -> Vec<usize> {
        match *self {
            Effect::InputOffset { c } | Effect::SensorZero { c } | Effect::OutputOffset { c } => {
                vec![c]
            }
            Effect::Coulomb { vc, .. } => vec![vc],
            Effect::Saturation { level } => vec![level],
            Effect::Deadzone { width } => vec![width],
            Effect::PowerLaw { p, .. } => vec![p],
            Effect::OutputDrift { r } => vec![r],
            Effect::AbsSensor => vec![],
            Effect::Sinusoid { a, b, .. } => vec![a, b],
        }
    }

    /// The scale of its parameters' unit, given the input's `su` and the output's `sy`: an input
    /// effect's parameters are input levels, an output effect's output levels (a drift's rate,
    /// per second), the power law's exponent has none.
    pub fn param_scale(&self, su: f64, sy: f64) -> f64 {
        match self {
            Effect::PowerLaw { .. } => 1.0,
            e if e.is_input() => su,
            _ => sy,
        }
    }

    /// Whether this effect is a static map of the held input: an input effect that does not read
    /// the output (all but Coulomb friction, which feeds the output's sign back).
    pub fn is_static_input(&self) -> bool {
        self.is_input() && !matches!(self, Effect::Coulomb { .. })
    }

    /// Whether this effect transforms the input (else the output).
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Effect::InputOffset { .. }
                | Effect::SensorZero { .. }
                | Effect::Coulomb { .. }
                | Effect::Saturation { .. }
                | Effect::Deadzone { .. }
                | Effect::PowerLaw { .. }
        )
    }

    /// A short report name (docs/design.md §6 table).
    pub fn name(&self) -> &'static str {
        match self {
            Effect::InputOffset { .. } => "input_offset",
            Effect::OutputOffset { .. } => "output_offset",
            Effect::Coulomb { .. } => "coulomb_friction",
            Effect::Saturation { .. } => "saturation",
            Effect::Deadzone { .. } => "deadzone",
            Effect::PowerLaw { .. } => "power_law",
            Effect::SensorZero { .. } | Effect::AbsSensor => "abs_sensor",
            Effect::Sinusoid { .. } => "periodic",
            Effect::OutputDrift { .. } => "output_drift",
        }
    }
}
