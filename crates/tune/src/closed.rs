//! The closed loop simulated: a reference step, then a load step at the plant's input.
//!
//! `y = P (u + d)`, `u = C (r - y)`. The plant (its delay included) and the controller are each
//! approximated and discretised exactly for a held input at a fine step `h`
//! ([`fracsim::export::discrete`]); the loop is closed at every fine step (the continuous loop,
//! up to the hold over `h`), or, for a sampled controller (period `dt = m h`), every `m` fine
//! steps with the controller's output held in between, as on the drive. An algebraic loop (both
//! with a feed-through) is solved at each step: `y = (C_p x_p + D_p (C_c x_c + D_c r + d)) /
//! (1 + D_p D_c)`.
//!
//! Anti-windup: with a voltage limit ([`LoopSetup::u_limit`], or a saturation among the input
//! effects) the controller's output is clamped and its states are conditioned on the clamp as
//! the drive's controller does (`drive::ctrl`, Hanus' conditioning): they are updated with the
//! error `(u_clamped - C_c x_c) / D_c` that gives the clamped output, or, without feed-through or
//! when that conditioning is unstable (a zero of the controller outside the unit circle, as a
//! FOPID's derivative gives), frozen while the error pushes further into the clamp.

use crate::controller::Controller;
use crate::error::{invalid, Result};
use fracsim::export::{self, StateSpace};
use fracsim::{ApproxSpec, FracTf};
use nalgebra::DVector;
use serde::Serialize;

/// What to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopSetup {
    /// The reference step's amplitude, applied at `t = 0`.
    pub step: f64,
    /// The load step's amplitude (added to the plant's input), applied at [`LoopSetup::t_load`].
    pub load: f64,
    /// When the load step comes, seconds.
    pub t_load: f64,
    /// The record's length, seconds.
    pub duration: f64,
    /// The fine step of the simulation, seconds.
    pub h: f64,
    /// The controller's sample period (a multiple of `h`); `None`: continuous.
    pub dt: Option<f64>,
    /// The voltage limit on the controller's output, input units, with anti-windup (`None`:
    /// none, unless a saturation effect sets one).
    pub u_limit: Option<f64>,
}

impl LoopSetup {
    /// The default for a crossover `wc` rad/s: unit steps, the load at `40/wc` s, twice that
    /// long, `h = 0.02/wc` (about 300 steps per crossover period), or `dt/m` for the largest
    /// such step below it when the controller is sampled every `dt`.
    pub fn for_crossover(wc: f64, dt: Option<f64>) -> Self {
        let t_load = 40.0 / wc;
        let h0 = 0.02 / wc;
        let h = match dt {
            Some(dt) => dt / (dt / h0).ceil().max(1.0),
            None => h0,
        };
        Self {
            step: 1.0,
            load: 1.0,
            t_load,
            duration: 2.0 * t_load,
            h,
            dt,
            u_limit: None,
        }
    }
}

/// A simulated closed loop, one row per fine step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopRun {
    /// Time, seconds.
    pub t: Vec<f64>,
    /// Reference.
    pub r: Vec<f64>,
    /// Load disturbance at the plant's input.
    pub d: Vec<f64>,
    /// Controller output.
    pub u: Vec<f64>,
    /// Plant output.
    pub y: Vec<f64>,
}

/// A static effect at the plant's input that `fracid time --diagnose` keeps (ident's
/// `oe::Effect`, applied in the same order and the same way: to the absolute input, friction with
/// the output extrapolated to the middle of the fine step, or decided at the controller's sample
/// instant and held over its period when the diagnosis found it so).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "name", rename_all = "snake_case")]
pub enum InputEffect {
    /// `u + u_offset`.
    InputOffset {
        /// The offset, input units.
        u_offset: f64,
    },
    /// Coulomb friction as an equivalent input: `u - Vc sign(y)`.
    CoulombFriction {
        /// `Vc`, input units.
        vc: f64,
        /// The sign decided at the controller's sample instant and held over its period (the
        /// report's `sampled`: a plant whose mechanics step once per sample, as the drive
        /// simulator's), else from the output at the middle of each fine step (a friction
        /// acting continuously).
        sampled: bool,
    },
    /// `clamp(u, -level, level)`.
    Saturation {
        /// The level, input units.
        level: f64,
    },
    /// `0` for `|u| < width`, else `u - width sign(u)`.
    Deadzone {
        /// The half width, input units.
        width: f64,
    },
    /// `sign(u) u_ref (|u| / u_ref)^exponent` (a smooth monotone actuator curve).
    PowerLaw {
        /// The exponent.
        exponent: f64,
        /// The input magnitude the map leaves unchanged, input units.
        u_ref: f64,
    },
}

fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl InputEffect {
    /// The effect of a diagnosis report's kept effect (`name` and its parameters as the report
    /// names them, `sampled` its friction's timing); `None` for an effect that is not at the
    /// input (output offset, sensor, an output sinusoid) or the delay (already in the model).
    ///
    /// # Errors
    /// A known effect without its parameter, or a non-finite one.
    pub fn from_report(
        name: &str,
        param: impl Fn(&str) -> Option<f64>,
        sampled: bool,
    ) -> Result<Option<Self>> {
        let get = |k: &str| -> Result<f64> {
            match param(k) {
                Some(v) if v.is_finite() => Ok(v),
                _ => invalid(
                    "effect",
                    format!("{name} without a finite \"{k}\" parameter"),
                ),
            }
        };
        Ok(Some(match name {
            "input_offset" => Self::InputOffset {
                u_offset: get("u_offset")?,
            },
            "coulomb_friction" => Self::CoulombFriction {
                vc: get("Vc")?,
                sampled,
            },
            "saturation" => Self::Saturation {
                level: get("level")?.abs(),
            },
            "deadzone" => Self::Deadzone {
                width: get("width")?.abs(),
            },
            "power_law" => match (get("exponent")?, get("u_ref")?.abs()) {
                (p, r) if p > 0.0 && r > 0.0 => Self::PowerLaw {
                    exponent: p,
                    u_ref: r,
                },
                (p, r) => invalid(
                    "effect",
                    format!("power_law with exponent {p} and u_ref {r}: both must be positive"),
                )?,
            },
            _ => return Ok(None),
        }))
    }

    /// The input after the effect, given the output seen at the middle of the fine step
    /// (`y_mid`) and at the controller's last sample instant (`y_sample`).
    pub fn apply(&self, u: f64, y_mid: f64, y_sample: f64) -> f64 {
        match *self {
            Self::InputOffset { u_offset } => u + u_offset,
            Self::CoulombFriction { vc, sampled } => {
                u - vc * sign(if sampled { y_sample } else { y_mid })
            }
            Self::Saturation { level } => u.clamp(-level, level),
            Self::Deadzone { width } => {
                if u.abs() < width {
                    0.0
                } else {
                    u - width * sign(u)
                }
            }
            Self::PowerLaw { exponent, u_ref } => {
                sign(u) * u_ref * (u.abs() / u_ref).powf(exponent)
            }
        }
    }
}

/// The most fine steps a simulation runs.
pub const MAX_STEPS: usize = 2_000_000;

struct Sys {
    ss: StateSpace,
    x: DVector<f64>,
}

impl Sys {
    fn new(ss: StateSpace) -> Self {
        let n = ss.order();
        Self {
            ss,
            x: DVector::zeros(n),
        }
    }
    /// `C x`.
    fn free(&self) -> f64 {
        (&self.ss.c * &self.x)[(0, 0)]
    }
    fn advance(&mut self, input: f64) {
        self.x = &self.ss.a * &self.x + &self.ss.b * input;
    }
}

/// Simulate the loop of `model` and the controller `c` (its realisation by
/// [`crate::realise::discrete`] with `spec`), the `effects` applied in order to the controller's
/// output before the load adds to it: `u_plant = effects(u) + d`. The controller's output is
/// clamped to the tightest of [`LoopSetup::u_limit`] and the saturation effects' levels, with
/// anti-windup (module docs).
///
/// # Errors
/// A bad setup (non-positive step or duration, more than [`MAX_STEPS`] steps, `dt` not a
/// multiple of `h`), effects on a model with feed-through, the errors of the approximations and
/// discretisations, a non-finite response (a loop that diverges numerically).
pub fn simulate(
    model: &FracTf,
    c: &Controller,
    setup: &LoopSetup,
    spec: &ApproxSpec,
    effects: &[InputEffect],
) -> Result<LoopRun> {
    let h = setup.h;
    if !(h > 0.0 && setup.duration > 0.0 && setup.duration.is_finite()) {
        return invalid("loop", format!("need h > 0 and a duration > 0: {setup:?}"));
    }
    let n = (setup.duration / h).round() as usize + 1;
    if n > MAX_STEPS {
        return invalid(
            "loop",
            format!("{n} steps of {h:e} s (at most {MAX_STEPS})"),
        );
    }
    let m = match setup.dt {
        Some(dt) => {
            let m = (dt / h).round();
            if !(m >= 1.0 && (m * h - dt).abs() < 1e-9 * dt) {
                return invalid(
                    "loop",
                    format!("dt = {dt} s is not a multiple of h = {h} s"),
                );
            }
            m as usize
        }
        None => 1,
    };
    let mut plant = Sys::new(export::discrete(model, h, spec)?);
    let css = crate::realise::discrete(c, h * m as f64, spec)?;
    let mut ctrl = Sys::new(css);
    let (dp, dc) = (plant.ss.d, ctrl.ss.d);
    let hanus = hanus_is_stable(&ctrl.ss)?;
    if !effects.is_empty() && dp != 0.0 {
        return invalid(
            "effects",
            "input effects on a model with a direct feed-through (no delay, proper but not \
             strictly): the loop would be implicit through a nonlinearity",
        );
    }
    let limit = effects
        .iter()
        .filter_map(|e| match e {
            InputEffect::Saturation { level } => Some(*level),
            _ => None,
        })
        .chain(setup.u_limit)
        .fold(f64::INFINITY, f64::min);
    if limit.is_nan() || limit <= 0.0 {
        return invalid("u_limit", format!("{limit} must be positive"));
    }
    let (mut y_prev, mut y_sample) = (0.0, 0.0);
    let mut run = LoopRun {
        t: Vec::with_capacity(n),
        r: Vec::with_capacity(n),
        d: Vec::with_capacity(n),
        u: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
    };
    let mut u = 0.0;
    for k in 0..n {
        let t = k as f64 * h;
        let r = setup.step;
        let d = if t >= setup.t_load - 0.5 * h {
            setup.load
        } else {
            0.0
        };
        let y;
        if k % m == 0 {
            let (cp, cc) = (plant.free(), ctrl.free());
            let y_free = (cp + dp * (cc + dc * r + d)) / (1.0 + dp * dc);
            let v = cc + dc * (r - y_free);
            u = v.clamp(-limit, limit);
            y = if u == v { y_free } else { cp + dp * (u + d) };
            y_sample = y;
            let e = r - y;
            if u == v {
                ctrl.advance(e);
            } else if hanus {
                // Hanus: the error that gives the clamped output
                ctrl.advance((u - cc) / dc);
            } else if !((v > limit && e > 0.0) || (v < -limit && e < 0.0)) {
                ctrl.advance(e);
            }
        } else {
            y = plant.free() + dp * (u + d);
        }
        // the output over the hold interval, extrapolated to its middle (as ident does)
        let seen = if k > 0 { y + 0.5 * (y - y_prev) } else { y };
        y_prev = y;
        let v = effects.iter().fold(u, |v, e| e.apply(v, seen, y_sample));
        plant.advance(v + d);
        if !(y.is_finite() && u.is_finite()) {
            return Err(fracsim::Error::Numerical(format!(
                "the closed loop's response is not finite at t = {t} s"
            ))
            .into());
        }
        run.t.push(t);
        run.r.push(r);
        run.d.push(d);
        run.u.push(u);
        run.y.push(y);
    }
    Ok(run)
}

/// Whether Hanus' conditioning is stable for the controller `ss`: while clamped its states
/// evolve as `x <- (A - B C / D) x + B u_clamped / D`, whose eigenvalues are its zeros; right
/// when they are within the unit circle (spectral radius at most `1 + 1e-6`), wrong otherwise (a
/// FOPID's derivative puts a zero near `z = -20`: the states run away). `false` without
/// feed-through. The drive makes the same choice (`drive::ctrl::hanus_is_stable`). The
/// eigenvalues by QR iteration with an iteration limit (`fracsim::eig`; nalgebra's has none and
/// never ends on poles at `z = -1`).
///
/// # Errors
/// The QR iteration did not converge (numerical, exit 1).
fn hanus_is_stable(ss: &StateSpace) -> Result<bool> {
    if ss.d == 0.0 || !ss.d.is_finite() {
        return Ok(false);
    }
    let mut m = &ss.a - &ss.b * &ss.c / ss.d;
    let n = m.nrows();
    if m.iter().any(|v| !v.is_finite()) {
        return Err(
            fracsim::Error::Numerical("the controller's realisation is not finite".into()).into(),
        );
    }
    nalgebra::linalg::balancing::balance_parlett_reinsch(&mut m);
    let zeros = fracsim::eig::eigenvalues_only(m, 100 * n.max(1)).ok_or_else(|| {
        fracsim::Error::Numerical(
            "the controller's zeros (for its anti-windup) did not converge".into(),
        )
    })?;
    Ok(zeros.iter().all(|z| z.norm() <= 1.0 + 1e-6))
}

/// A step response's figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepMetrics {
    /// Overshoot above the final value, percent of the step.
    pub overshoot_percent: f64,
    /// Time from 10% to 90% of the final value, seconds (`None`: never reached).
    pub rise_time: Option<f64>,
    /// Time after which `y` stays within 2% of the step of the final value, seconds.
    pub settling_time: Option<f64>,
    /// The largest deviation of `y` after the load step from its value just before, in units of
    /// the output.
    pub load_peak: f64,
    /// The deviation left at the end of the record, units of the output.
    pub load_residual: f64,
}

/// The figures of a [`LoopRun`] made by [`simulate`] with `setup`: the reference step measured
/// on `[0, t_load)` against the reference (the final value of a loop with integral action), the
/// load step after it.
pub fn metrics(run: &LoopRun, setup: &LoopSetup) -> StepMetrics {
    let split = run
        .t
        .iter()
        .position(|&t| t >= setup.t_load - 0.5 * setup.h)
        .unwrap_or(run.t.len());
    let (t, y) = (&run.t[..split], &run.y[..split]);
    let a = setup.step;
    let (overshoot_percent, rise_time, settling_time) = step_figures(t, y, a);
    let before = if split > 0 { run.y[split - 1] } else { 0.0 };
    let after = &run.y[split..];
    let load_peak =
        after
            .iter()
            .map(|v| v - before)
            .fold(0.0, |m: f64, v| if v.abs() > m.abs() { v } else { m });
    StepMetrics {
        overshoot_percent,
        rise_time,
        settling_time,
        load_peak,
        load_residual: after.last().map_or(0.0, |v| v - before),
    }
}

/// The figures of a step response `y(t)` to a step of `a` at `t[0]` from 0 (the final value
/// taken as `a`, a loop with integral action): the overshoot `100 (max y - a)/a` percent (0 if
/// none), the 10-90% rise time (levels crossed first, linearly interpolated between samples;
/// `None` if never reached), the 2% settling time (`None` if not settled within the record).
pub fn step_figures(t: &[f64], y: &[f64], a: f64) -> (f64, Option<f64>, Option<f64>) {
    let at = |frac: f64| {
        y.iter().position(|&v| v >= frac * a).map(|i| {
            if i == 0 {
                t[0]
            } else {
                // linear interpolation between the samples around the level
                let (y0, y1) = (y[i - 1], y[i]);
                t[i - 1] + (t[i] - t[i - 1]) * (frac * a - y0) / (y1 - y0)
            }
        })
    };
    let rise_time = match (at(0.1), at(0.9)) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let peak = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let settling_time = y
        .iter()
        .rposition(|&v| (v - a).abs() > 0.02 * a.abs())
        .and_then(|i| (i + 1 < t.len()).then(|| t[i + 1] - t[0]));
    ((100.0 * (peak - a) / a).max(0.0), rise_time, settling_time)
}

#[cfg(test)]
mod tests {
    /// Issue 46, item 6: a closed realisation `A - B C / D` (poles at `z = -1` and a chain at the
    /// origin) that nalgebra's QR iteration, without an iteration limit, never reduced: the check
    /// hung. Now it ends at once (an error: the iteration does not converge).
    #[test]
    fn hanus_check_ends_on_poles_at_minus_one() {
        let a = nalgebra::DMatrix::from_row_slice(
            4,
            4,
            &[
                -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0,
            ],
        );
        let ss = super::StateSpace {
            a,
            b: nalgebra::DMatrix::from_column_slice(4, 1, &[-1.0, 0.0, -1.0, 0.0]),
            c: nalgebra::DMatrix::from_row_slice(1, 4, &[1.0, 0.0, 0.0, -1.0]),
            d: 1.0,
            dt: Some(1e-3),
            input_delay: 0.0,
            delay_states: 0,
            band: (1e-3, 1e3),
            spec: fracsim::ApproxSpec::default(),
        };
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(super::hanus_is_stable(&ss).map_err(|e| e.to_string()));
        });
        let r = rx
            .recv_timeout(std::time::Duration::from_secs(20))
            .expect("the check hangs");
        assert!(r.unwrap_err().contains("did not converge"));
    }
}
