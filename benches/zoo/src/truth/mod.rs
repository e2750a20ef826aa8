//! The independent truth: a simulator of fractional and integer transfer functions with the
//! effects a real drive adds, sharing no code with fracsim.
//!
//! INTERFACE AGREED BETWEEN THE ZOO'S BRANCHES (zoo-truth implements it, zoo-cases uses it):
//! the names and signatures below stay; bodies are zoo-truth's.

#[cfg(test)]
mod accuracy;
mod effects;
mod exact;
mod gl;
mod lattice;
pub mod mittag_leffler;
mod plant;
mod run;
mod series;

/// One term `coef * s^order` of a numerator or denominator.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Term {
    /// The coefficient.
    pub coef: f64,
    /// The order (>= 0; non-integer for a fractional store).
    pub order: f64,
}

/// `G(s) = (sum num) / (sum den) * exp(-delay_s s)`, proper (the highest numerator order <= the
/// highest denominator order); a denominator term of order 0 with coefficient 0 (or none) is an
/// integrator's place (`den` without an order-0 term: G(0) infinite).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Plant {
    /// Numerator terms.
    pub num: Vec<Term>,
    /// Denominator terms.
    pub den: Vec<Term>,
    /// Input delay [s].
    pub delay_s: f64,
}

impl Plant {
    /// The product of two transfer functions (terms multiplied out, orders added, delays added).
    pub fn product(&self, other: &Plant) -> Plant {
        plant::product(self, other)
    }

    /// The frequency response at `omega` [rad/s], the delay included.
    pub fn response(&self, omega: f64) -> num_complex::Complex64 {
        plant::response(self, omega)
    }
}

/// The effects a drive adds around the linear plant; every field `None`/0 is "absent".
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Effects {
    /// Added to the input before the plant.
    pub input_offset: f64,
    /// Dead band half-width: |u| below it gives 0, above it u - sign(u) * width.
    pub deadband: Option<f64>,
    /// Symmetric input saturation level.
    pub saturation: Option<f64>,
    /// Coulomb friction, in input units: the plant's input is u - coulomb * sign(y) (y = speed).
    pub coulomb: Option<f64>,
    /// A static map on the input: u -> sign(u) |u|^p (a heater's power goes as V^2: p = 2).
    pub power_law: Option<f64>,
    /// Added to the output.
    pub output_offset: f64,
    /// The sensor reports |y| (a sign-blind speed sensor).
    pub abs_sensor: bool,
    /// A periodic output disturbance: (amplitude, frequency [Hz]).
    pub periodic: Option<(f64, f64)>,
    /// A slow output drift [output units per second].
    pub drift_per_s: f64,
}

/// How the plant is driven.
#[derive(Clone, Debug, PartialEq)]
pub enum Drive<'a> {
    /// The input sequence itself, held over each sample (zero-order hold).
    Open(&'a [f64]),
    /// A speed loop under a discrete PI on the measured output: `u = kp e + ki dt sum e`,
    /// `e = reference - y`, clamped to +-u_limit; the record is (u, y).
    SpeedLoop {
        /// The reference per sample.
        reference: &'a [f64],
        /// Proportional gain.
        kp: f64,
        /// Integral gain [1/s].
        ki: f64,
        /// The controller's output limit.
        u_limit: f64,
    },
}

/// What the truth simulation returns: the plant's input and noise-free output per sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// The input as recorded (the controller's output in a loop), per sample.
    pub u: Vec<f64>,
    /// The noise-free measured output per sample (effects applied).
    pub y: Vec<f64>,
}

/// Errors of the truth simulation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The plant cannot be simulated (improper, empty denominator, ...).
    #[error("plant not simulable: {0}")]
    Plant(String),
    /// The drive or the sample time cannot be simulated (non-finite values, dt <= 0, ...).
    #[error("drive not simulable: {0}")]
    Drive(String),
}

/// Simulates `plant` with `effects` under `drive` at sample time `dt` [s], from rest, the input
/// held over each sample; the output sampled at the sample instants.
pub fn simulate(
    plant: &Plant,
    effects: &Effects,
    drive: &Drive<'_>,
    dt: f64,
) -> Result<Record, Error> {
    run::simulate(plant, effects, drive, dt)
}
