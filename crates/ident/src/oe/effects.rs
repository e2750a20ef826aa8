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

    /// The same effect with each parameter index `i` renumbered to `to(i)`.
    pub fn renumbered(&self, to: impl Fn(usize) -> usize) -> Self {
        let mut e = self.clone();
        match &mut e {
            Effect::InputOffset { c } | Effect::SensorZero { c } | Effect::OutputOffset { c } => {
                *c = to(*c)
            }
            Effect::Coulomb { vc, .. } => *vc = to(*vc),
            Effect::Saturation { level } => *level = to(*level),
            Effect::Deadzone { width } => *width = to(*width),
            Effect::PowerLaw { p, .. } => *p = to(*p),
            Effect::OutputDrift { r } => *r = to(*r),
            Effect::AbsSensor => {}
            Effect::Sinusoid { a, b, .. } => {
                *a = to(*a);
                *b = to(*b);
            }
        }
        e
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

#[cfg(test)]
mod tests {
    use super::Effect;
    use crate::oe::{FracModel, Param};

    /// A model with a delay and four effects after it (one of two parameters), as a diagnosis
    /// builds it.
    fn with_effects(power_law: bool) -> FracModel {
        let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
        m.with_delay(5e-4, 0.01);
        if power_law {
            let p = m.add_param(Param::positive("exponent", 1.7));
            m.effects.push(Effect::PowerLaw { p, u_ref: 3.0 });
        }
        let width = m.add_param(Param::positive("width", 0.4));
        m.effects.push(Effect::Deadzone { width });
        let a = m.add_param(Param::positive("a", 0.1));
        let b = m.add_param(Param::positive("b", 0.2));
        m.effects.push(Effect::Sinusoid { freq_hz: 5.0, a, b });
        m.with_output_offset(0.3);
        m
    }

    #[test]
    fn a_model_without_an_effect_is_the_model_built_without_it() {
        let m = with_effects(true);
        let (without, kept) = m.without_effect(0);
        assert_eq!(without, with_effects(false));
        // the exponent (index 6) is gone; every other parameter keeps its order
        let expected: Vec<usize> = (0..m.params.len()).filter(|&i| i != 6).collect();
        assert_eq!(kept, expected);
        let (no_sine, kept) = m.without_effect(2);
        assert_eq!(no_sine.params.len(), m.params.len() - 2);
        assert_eq!(no_sine.effects[2], Effect::OutputOffset { c: 8 });
        assert_eq!(kept[8], 10);
    }
}
