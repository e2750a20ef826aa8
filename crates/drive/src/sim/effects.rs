//! The hidden physical effects of the simulated motor and their ranges.

use crate::error::{Error, Result};

/// Hidden physical effects of the simulated drive (all off by default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects {
    /// Coulomb friction as a voltage equivalent at the input, V (`Vc sign(speed)`).
    pub coulomb_v: f64,
    /// Input (transport) delay, s.
    pub delay_s: f64,
    /// Periodic disturbance (torque ripple) as a voltage at the input: amplitude, V.
    pub ripple_v: f64,
    /// Ripple frequency, Hz.
    pub ripple_hz: f64,
    /// Gaussian measurement noise on the speed, standard deviation in rad/s.
    pub noise_std: f64,
    /// Speed quantisation step (encoder resolution), rad/s; 0 = none beyond the channel LSB.
    pub speed_quant: f64,
    /// Winding resistance for the indicative current channel, ohm.
    pub r_ohm: f64,
    /// A constant voltage added to the command at the input (an inverter or current-sensor
    /// offset), V; it acts before the friction.
    pub offset_v: f64,
}

impl Default for Effects {
    fn default() -> Self {
        Self {
            coulomb_v: 0.0,
            delay_s: 0.0,
            ripple_v: 0.0,
            ripple_hz: 0.0,
            noise_std: 0.0,
            speed_quant: 0.0,
            r_ohm: 1.0,
            offset_v: 0.0,
        }
    }
}

impl Effects {
    /// Check the ranges: every value finite; friction, ripple frequency, noise and quantisation
    /// not negative (the ripple amplitude and the input offset may be); the delay in
    /// `0..=MAX_DELAY_S` (the simulator holds the delayed commands in memory); the winding
    /// resistance positive.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming the first bad value.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("coulomb friction (V)", self.coulomb_v),
            ("ripple frequency (Hz)", self.ripple_hz),
            ("speed noise (rad/s)", self.noise_std),
            ("speed quantisation (rad/s)", self.speed_quant),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidParam(format!(
                    "{name} must be a finite number >= 0, got {v}"
                )));
            }
        }
        for (name, v) in [
            ("ripple amplitude", self.ripple_v),
            ("input offset", self.offset_v),
        ] {
            if !v.is_finite() {
                return Err(Error::InvalidParam(format!(
                    "{name} must be finite, got {v} V"
                )));
            }
        }
        if !(self.delay_s.is_finite() && (0.0..=MAX_DELAY_S).contains(&self.delay_s)) {
            return Err(Error::InvalidParam(format!(
                "input delay must be in [0, {MAX_DELAY_S}] s, got {}",
                self.delay_s
            )));
        }
        if !(self.r_ohm.is_finite() && self.r_ohm > 0.0) {
            return Err(Error::InvalidParam(format!(
                "winding resistance must be finite and > 0 ohm, got {}",
                self.r_ohm
            )));
        }
        Ok(())
    }
}

/// Longest input delay the simulator accepts, s.
pub const MAX_DELAY_S: f64 = 10.0;
