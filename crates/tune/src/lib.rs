//! # tune: fractional PI/PID design on an identified fractional model
//!
//! `C(s) = kp + ki / s^lambda (+ kd s^mu)` designed for a gain crossover, a phase margin and a
//! flat phase at the crossover (iso-damping), with complementary-sensitivity and sensitivity
//! bounds for the FOPID: C. A. Monje, B. M. Vinagre, V. Feliu, Y. Chen, "Tuning and auto-tuning of
//! fractional order controllers for industry applications", *Control Engineering Practice* 16
//! (2008) 798-812.
//!
//! - [`design`](mod@design): the design equations and their solution, the candidates checked on the loop;
//! - [`analysis`]: crossover, margins, sensitivity peak, Nyquist stability of `L = C P`;
//! - [`controller`] and [`plant`]: the two frequency responses with their logarithmic derivatives;
//! - [`filter`]: a notch or low-pass in series with the controller for a resonant plant.

mod error;

pub mod analysis;
pub mod argument;
mod check;
pub mod closed;
pub mod controller;
pub mod design;
pub mod filter;
pub mod given;
pub mod plant;
pub mod realise;
pub mod report;
pub mod request;
pub mod sampled;
pub mod spec;

pub use analysis::LoopMetrics;
pub use controller::{Controller, Form};
pub use design::{design, Design};
pub use error::{Error, Result};
pub use plant::Plant;
pub use request::TuneRequest;
pub use spec::{Floors, GainBound, Orders, Spec};
