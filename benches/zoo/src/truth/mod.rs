//! The independent truth: a simulator of fractional and integer transfer functions with the
//! effects a real drive adds, sharing no code with fracsim (this crate depends on neither fracsim
//! nor ident).
//!
//! INTERFACE AGREED BETWEEN THE ZOO'S BRANCHES (zoo-truth implements it, zoo-cases uses it):
//! the names and signatures below stay; bodies are zoo-truth's.
//!
//! # Method
//! The held input is a sum of steps at known instants, so the output at the sample instants is a
//! superposition of the plant's step response on lattices of times (`lattice`):
//! - integer orders: exact, from a controllable-canonical realisation in a frequency-scaled
//!   variable and the matrix exponential of `[[A, B], [0, 0]]` (`exact`);
//! - fractional orders: Grunwald-Letnikov for the general fractional transfer function (the
//!   pseudo-state scheme `sum a_j D^alpha_j x = w`, `y = sum b_i D^beta_i x`, solved for `y`
//!   directly, one implicit step per point) on three fine grids `h`, `h/2`, `h/4`,
//!   `h <= dt / 10` and finer where the plant's corners ask, extrapolated by two Richardson
//!   stages: the scheme's error is `c1 h + c2 h^2 + c3 h^3 + ...` (its symbol `(1 - e^{-sh})/h`
//!   expands in whole powers of `h`), so the result is third order (`gl`); the recursion solved
//!   by divide and conquer with FFT products, O(n log^2 n) (`series`);
//! - a delay of fractional samples reads the step response off the grid (8-point Lagrange for
//!   `t >= dt`, an aligned grid of its own for the one time below `dt`);
//! - open loop: the static input effects, one FFT convolution, the output effects; with Coulomb
//!   friction or the speed loop: step by step through the same superposition (`run`).
//!
//! # Conventions
//! - Input effects in order: `+ input_offset`, power law, dead band, saturation; Coulomb friction
//!   `- coulomb * sign(y)` (sign(0) = 0) acts on the plant without the input delay, decided from
//!   the plant's output at each sample instant and held over the sample.
//! - Output effects: `|y|` if sign-blind, then `+ output_offset + drift_per_s t + A sin(2 pi f t)`.
//! - The record's `y_k` is the output just after the sample instant (a feed-through's jump from
//!   `u_k` included); the friction and the PI read it just before (`y(t_k^-)`, without `u_k`'s
//!   jump), so a feed-through makes no algebraic loop. The PI stops integrating while its output
//!   is clamped and the error pushes further into the clamp.
//! - A fractional plant whose finest grid would exceed 2^24 points is an `Error::Plant`. The fine
//!   grid's rounding is amplified by the recursion's poles near `z = 1`, about as `steps^(order -
//!   1)`: negligible for the zoo's fractional orders (<= 2; 1e-8 measured), 5e-6 of the swing at
//!   order 3 over 4e4 steps.
//!
//! # The truth's own tests and their tolerances
//! - Mittag-Leffler `E_alpha` (`mittag_leffler`): `E_1(z) = e^z`, `E_2(-z^2) = cos z`,
//!   `E_1/2(-z) = e^{z^2} erfc(z)` to 1e-12; its series and integral forms agree to 1e-11 for
//!   alpha 0.3..1.9; the large-argument asymptote to 1e-10.
//! - Fractional steps: `K / (a s^alpha + 1)` against `K (1 - E_alpha(-t^alpha / a))` for alpha
//!   0.3, 0.5, ..., 1.9 at dt a fifth of and twice the time constant: 1e-4 of the swing.
//! - Fractional integrators: `1 / s^0.7` against `t^0.7 / Gamma(1.7)`, a cell `R + 1 / (C s^0.6)`
//!   against `R + t^0.6 / (C Gamma(1.6))`: 1e-4 of the swing.
//! - The extrapolation's orders: doubling the fine steps divides the error by 1.8-2.2 (raw GL),
//!   3.4-4.6 (one Richardson stage), 6.5-9.5 (two).
//! - The fine-step rule: halving the step it picks moves the step-response lattices by < 1e-5 of
//!   the swing (measured <= 1e-8) on a fractional PMSM, a thermal diffusion, a cell, a
//!   near-resonant order 1.8.
//! - GL against the exact solution on integer plants (a motor-side two-mass drive with its
//!   integrator, a third order with a zero): 1e-4 of the swing (measured 5e-6).
//! - Integer steps (exact path) against closed forms written in the test: first order,
//!   underdamped second order, third order, an integrator, a lead with a zero, a feed-through
//!   with an integrator, a pure gain: 1e-4 of the swing (1e-14 for the gain); stiff ones (a
//!   0.3 ms lag at 2 s; a 150 Hz resonance behind a 0.3 ms lag at 10 ms and 0.1 s, against its
//!   residues): 1e-9.
//! - Delays of 2.3 and 3 samples (first order) and 1.37, 0.93, 2 samples (order 0.7) against the
//!   shifted exact / Mittag-Leffler response: 1e-4 of the swing.
//! - The fast paths against the recursions: the divide-and-conquer GL step response against the
//!   direct O(n^2) pseudo-state recursion (1e-9 of the largest value, orders up to 1.9, 8192
//!   steps); the lattice-and-convolution output of an irregular held input against GL run on the
//!   fine grids with that input (1e-10 relative); the open-loop convolution against the
//!   step-by-step loop (1e-10 relative).
//! - Effects by hand on a first order (hand ZOH recursion, 1e-12): dead band (below it: exactly
//!   0), saturation, input offset, power law, sign-blind sensor, output offset + drift +
//!   periodic, Coulomb friction above and below the breakaway and behind half a sample of input
//!   delay (1e-9), the PI loop with its clamp, a feed-through inside the loop; `Plant::response`
//!   against hand values (1e-14); bad input is an `Error`, never a panic.
//!
//! Timings: `cargo run --release -p zoo --example truth_timing`.

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
    /// Coulomb friction, in input units: the plant's input is u - coulomb * sign(y) (y = speed;
    /// the friction acts without the input delay, decided at each sample instant and held).
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
