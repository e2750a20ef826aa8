//! What a design is asked: the crossover, margin and form ([`Spec`]), the robustness floors
//! ([`Floors`]), the band bounds ([`GainBound`]) and the orders allowed ([`Orders`]), with their
//! validation.

use crate::controller::Form;
use crate::error::{invalid, Result};
use serde::Serialize;
use std::f64::consts::PI;

/// A bound on a closed-loop gain over a band: `|T(j w)| <= db` for every `w >= omega` (noise),
/// or `|S(j w)| <= db` for every `w <= omega` (disturbances).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GainBound {
    /// The band's edge in rad/s.
    pub omega: f64,
    /// The largest gain allowed over the band, dB.
    pub db: f64,
}

/// The robustness every design must have unless the request relaxes it: a design that misses
/// one is refused, the floor it misses named.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Floors {
    /// The largest sensitivity peak `Ms` allowed (default 2: the Nyquist curve stays at least
    /// `1/Ms = 0.5` from `-1`, which alone guarantees 6 dB of gain margin and 29 deg of phase).
    pub ms_max: f64,
    /// The smallest gain margin in dB, up and (for a conditionally stable loop) down (default 6).
    pub gm_min_db: f64,
    /// The smallest integrator order (default 0.5): integral action, a step's error dying out
    /// like `t^-lambda` at least as fast as `t^-0.5` and the low-frequency sensitivity falling at
    /// `20 lambda` dB a decade. 0 accepts any.
    pub lambda_min: f64,
}

impl Default for Floors {
    fn default() -> Self {
        Self {
            ms_max: 2.0,
            gm_min_db: 6.0,
            lambda_min: 0.5,
        }
    }
}

/// What the loop must do.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spec {
    /// The controller structure.
    pub form: Form,
    /// Gain crossover in rad/s.
    pub wc: f64,
    /// Phase margin in degrees, in (0, 180).
    pub pm_deg: f64,
    /// Flat phase at `wc` (`d arg L / d ln omega = 0`, iso-damping).
    pub flat: bool,
    /// `|T(j omega_h)| <= db` (noise rejection), FOPID and the searched forms.
    pub t_high: Option<GainBound>,
    /// `|S(j omega_l)| <= db` (disturbance rejection), FOPID and the searched forms.
    pub s_low: Option<GainBound>,
    /// The sample period of the loop in seconds: the hold's half-sample delay joins the plant.
    pub dt: Option<f64>,
    /// A fixed integrator order (fopi without `--flat`, fopid); otherwise searched.
    pub lambda: Option<f64>,
    /// The robustness floors.
    pub floors: Floors,
    /// Fixed or capped orders.
    pub orders: Orders,
}

/// The crossovers accepted, rad/s: beyond, the analysis's grid (`wc 1e-6` to `wc 1e5`) leaves
/// the floating-point range a drive's model is written in.
pub(crate) const WC_MIN: f64 = 1e-6;
pub(crate) const WC_MAX: f64 = 1e9;
/// The grid of fractional orders searched, `(0, 2)` exclusive.
pub(crate) const ORDER_MIN: f64 = 0.02;
pub(crate) const ORDER_MAX: f64 = 1.98;

impl Spec {
    pub(crate) fn validate(&self) -> Result<()> {
        if !(self.wc.is_finite() && self.wc > 0.0) {
            return invalid("wc", format!("{} rad/s must be positive", self.wc));
        }
        if !(WC_MIN..=WC_MAX).contains(&self.wc) {
            return invalid(
                "wc",
                format!(
                    "{:e} rad/s is outside [{WC_MIN:e}, {WC_MAX:e}] rad/s, the crossovers the \
                     analysis covers",
                    self.wc
                ),
            );
        }
        let f = self.floors;
        if !(f.ms_max.is_finite() && f.ms_max >= 1.0) {
            return invalid("max-ms", format!("{} must be a number >= 1", f.ms_max));
        }
        if !(f.gm_min_db.is_finite() && f.gm_min_db >= 0.0) {
            return invalid("min-gm", format!("{} dB must be >= 0", f.gm_min_db));
        }
        if !(f.lambda_min.is_finite() && (0.0..2.0).contains(&f.lambda_min)) {
            return invalid("min-lambda", format!("{} must be in [0, 2)", f.lambda_min));
        }
        if !(self.pm_deg > 0.0 && self.pm_deg < 180.0) {
            return invalid("pm", format!("{} deg must be in (0, 180)", self.pm_deg));
        }
        if let Some(dt) = self.dt {
            if !(dt.is_finite() && dt > 0.0) {
                return invalid("dt", format!("{dt} s must be positive"));
            }
            if self.wc * dt >= PI {
                return invalid(
                    "wc",
                    format!(
                        "{} rad/s is above the Nyquist frequency pi/dt = {:.4} rad/s",
                        self.wc,
                        PI / dt
                    ),
                );
            }
        }
        for (name, b) in [("t-high", self.t_high), ("s-low", self.s_low)] {
            if let Some(b) = b {
                if !(b.omega.is_finite() && b.omega > 0.0 && b.db.is_finite()) {
                    return invalid(
                        if name == "t-high" { "t-high" } else { "s-low" },
                        format!("need a positive frequency and a finite dB, got {b:?}"),
                    );
                }
            }
        }
        self.orders.validate(self.form, self.flat, self.lambda)?;
        match (self.form, self.flat) {
            (Form::Fopid, false) => invalid(
                "form",
                "fopid has five parameters: give --flat (with --t-high and --s-low if wanted)",
            ),
            _ => Ok(()),
        }
    }
}

/// The orders a design may use: fixed (`Spec::lambda`, [`Orders::mu`]) or capped.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Orders {
    /// A fixed differentiator order (fopid, fopd).
    pub mu: Option<f64>,
    /// The largest integrator order searched (fopi, fopid).
    pub lambda_max: Option<f64>,
    /// The largest differentiator order searched (fopid, fopd).
    pub mu_max: Option<f64>,
}

impl Orders {
    fn validate(&self, form: Form, flat: bool, lambda: Option<f64>) -> Result<()> {
        let in_range = |v: Option<f64>| v.is_none_or(|v| v > 0.0 && v < 2.0);
        if !(in_range(lambda) && in_range(self.mu)) {
            return invalid(
                "order",
                format!("fixed orders must be in (0, 2): {lambda:?}, {:?}", self.mu),
            );
        }
        if !(self.lambda_max.is_none_or(|v| v > ORDER_MIN && v <= 2.0)
            && self.mu_max.is_none_or(|v| v > ORDER_MIN && v <= 2.0))
        {
            return invalid(
                "order",
                format!("caps must be in ({ORDER_MIN}, 2]: {self:?}"),
            );
        }
        let (takes_lambda, takes_mu) = match form {
            Form::Fopi => (true, false),
            Form::Fopid => (true, true),
            Form::Fopd => (false, true),
            Form::Pi | Form::Pid => (false, false),
        };
        if (lambda.is_some() || self.lambda_max.is_some()) && !takes_lambda {
            return invalid(
                "lambda",
                format!("a {} has no fractional integrator", form.name()),
            );
        }
        if (self.mu.is_some() || self.mu_max.is_some()) && !takes_mu {
            return invalid(
                "mu",
                format!("a {} has no fractional differentiator", form.name()),
            );
        }
        if flat && form != Form::Fopid && (lambda.is_some() || self.mu.is_some()) {
            return invalid(
                "order",
                "with --flat the order is what the flatness decides",
            );
        }
        for (name, v, cap) in [
            ("lambda", lambda, self.lambda_max),
            ("mu", self.mu, self.mu_max),
        ] {
            if let (Some(v), Some(c)) = (v, cap) {
                if v > c {
                    return invalid(name, format!("{v} above its cap {c}"));
                }
            }
        }
        Ok(())
    }

    /// The orders to try: `fixed`, else a grid of `n` steps over (0, 2) up to the cap.
    pub(crate) fn grid(fixed: Option<f64>, cap: Option<f64>, n: usize) -> Vec<f64> {
        match fixed {
            Some(v) => vec![v],
            None => order_grid(n)
                .filter(|&v| cap.is_none_or(|c| v <= c))
                .collect(),
        }
    }
}

/// `n + 1` orders evenly over `[ORDER_MIN, ORDER_MAX]`.
pub(crate) fn order_grid(n: usize) -> impl Iterator<Item = f64> + Clone {
    (0..=n).map(move |i| ORDER_MIN + (ORDER_MAX - ORDER_MIN) * i as f64 / n as f64)
}
