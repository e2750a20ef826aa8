//! The static effects around the linear plant, applied per sample.
//!
//! Input side, in this order: `u + input_offset`, then the power law `sign(u)|u|^p`, then the
//! dead band, then the saturation (Coulomb friction is not static: it feeds back from the output
//! and lives in `run`). Output side: `|y|` if the sensor is sign-blind, then `+ output_offset +
//! A sin(2 pi f t) + drift_per_s t`, with `t = k dt` the sample instant.

use super::Effects;
use std::f64::consts::TAU;

/// The plant's input for the held command `u` (Coulomb friction excepted).
pub(crate) fn input(effects: &Effects, u: f64) -> f64 {
    let mut v = u + effects.input_offset;
    if let Some(p) = effects.power_law {
        v = v.signum() * v.abs().powf(p);
    }
    if let Some(width) = effects.deadband {
        v = if v.abs() <= width {
            0.0
        } else {
            v - v.signum() * width
        };
    }
    if let Some(level) = effects.saturation {
        v = v.clamp(-level, level);
    }
    v
}

/// The measured output for the plant's output `y` at time `t_s`.
pub(crate) fn output(effects: &Effects, y: f64, t_s: f64) -> f64 {
    let mut m = if effects.abs_sensor { y.abs() } else { y };
    m += effects.output_offset + effects.drift_per_s * t_s;
    if let Some((amplitude, freq_hz)) = effects.periodic {
        m += amplitude * (TAU * freq_hz * t_s).sin();
    }
    m
}

/// Checks the effects' parameters (finite, widths and levels >= 0, exponent > 0).
pub(crate) fn check(effects: &Effects) -> Result<(), String> {
    let finite = [
        effects.input_offset,
        effects.output_offset,
        effects.drift_per_s,
    ];
    if finite.iter().any(|v| !v.is_finite()) {
        return Err("an effect's offset or drift is not finite".into());
    }
    let nonneg = [effects.deadband, effects.saturation, effects.coulomb];
    if nonneg.iter().flatten().any(|v| !v.is_finite() || *v < 0.0) {
        return Err("a dead band, saturation or Coulomb level is negative or not finite".into());
    }
    if effects
        .power_law
        .is_some_and(|p| !p.is_finite() || p <= 0.0)
    {
        return Err("the power law's exponent must be finite and > 0".into());
    }
    if effects
        .periodic
        .is_some_and(|(a, f)| !a.is_finite() || !f.is_finite())
    {
        return Err("the periodic disturbance is not finite".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn input_side_by_hand() {
        let none = Effects::default();
        assert_eq!(input(&none, -1.25), -1.25);
        let offset = Effects {
            input_offset: 0.5,
            ..Effects::default()
        };
        assert_eq!(input(&offset, 1.0), 1.5);
        let band = Effects {
            deadband: Some(0.2),
            ..Effects::default()
        };
        assert_eq!(input(&band, 0.15), 0.0);
        assert_eq!(input(&band, -0.2), 0.0);
        assert!((input(&band, 1.0) - 0.8).abs() < 1e-15);
        assert!((input(&band, -1.0) + 0.8).abs() < 1e-15);
        let sat = Effects {
            saturation: Some(2.0),
            ..Effects::default()
        };
        assert_eq!(input(&sat, 3.0), 2.0);
        assert_eq!(input(&sat, -3.0), -2.0);
        assert_eq!(input(&sat, 1.0), 1.0);
        let square = Effects {
            power_law: Some(2.0),
            ..Effects::default()
        };
        assert_eq!(input(&square, -3.0), -9.0);
        assert_eq!(input(&square, 0.5), 0.25);
        // Order: offset, power, band, saturation: (1 + 1)^2 = 4, minus 1 = 3, clamped at 2.5.
        let all = Effects {
            input_offset: 1.0,
            power_law: Some(2.0),
            deadband: Some(1.0),
            saturation: Some(2.5),
            ..Effects::default()
        };
        assert_eq!(input(&all, 1.0), 2.5);
    }

    #[test]
    fn output_side_by_hand() {
        let abs = Effects {
            abs_sensor: true,
            output_offset: 0.1,
            ..Effects::default()
        };
        assert!((output(&abs, -2.0, 5.0) - 2.1).abs() < 1e-15);
        let drift = Effects {
            drift_per_s: 0.01,
            ..Effects::default()
        };
        assert!((output(&drift, 1.0, 3.0) - 1.03).abs() < 1e-15);
        let periodic = Effects {
            periodic: Some((0.5, 2.0)),
            ..Effects::default()
        };
        // At t = 1/8 s, 2 Hz is a quarter turn: + 0.5.
        assert!((output(&periodic, 1.0, 0.125) - 1.5).abs() < 1e-15);
        assert!(check(&Effects {
            deadband: Some(-1.0),
            ..Effects::default()
        })
        .is_err());
        assert!(check(&Effects {
            power_law: Some(0.0),
            ..Effects::default()
        })
        .is_err());
        assert!(check(&Effects::default()).is_ok());
    }
}
