//! The controller `C(s) = kp + ki / s^lambda + kd s^mu` and its forms.

use crate::error::{invalid, Result};
use fracsim::{jw_pow, FracTf, Term};
use num_complex::Complex64;
use serde::Serialize;

/// The controller structures `fracid tune` designs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Form {
    /// `kp + ki / s^lambda` (fractional PI, Podlubny's `PI^lambda`).
    Fopi,
    /// `kp + ki / s^lambda + kd s^mu` (Podlubny's `PI^lambda D^mu`).
    Fopid,
    /// `kp + kd s^mu` (fractional PD, Podlubny's `PD^mu`): no integral action.
    Fopd,
    /// `kp + ki / s` (integer PI).
    Pi,
    /// `kp + ki / s + kd s` (integer PID, ideal form).
    Pid,
}

impl Form {
    /// The name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Form::Fopi => "fopi",
            Form::Fopid => "fopid",
            Form::Fopd => "fopd",
            Form::Pi => "pi",
            Form::Pid => "pid",
        }
    }

    /// Whether the form has a derivative term.
    pub fn has_derivative(self) -> bool {
        matches!(self, Form::Fopid | Form::Pid | Form::Fopd)
    }

    /// Whether the form has an integral term.
    pub fn has_integrator(self) -> bool {
        !matches!(self, Form::Fopd)
    }
}

impl std::str::FromStr for Form {
    type Err = crate::Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "fopi" => Ok(Form::Fopi),
            "fopid" => Ok(Form::Fopid),
            "fopd" => Ok(Form::Fopd),
            "pi" => Ok(Form::Pi),
            "pid" => Ok(Form::Pid),
            _ => invalid(
                "form",
                format!("'{s}' (expected fopi, fopid, fopd, pi or pid)"),
            ),
        }
    }
}

/// `C(s) = kp + ki / s^lambda + kd s^mu` (`kd = 0` for the PI forms, `lambda = mu = 1` for the
/// integer forms).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct Controller {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain.
    pub ki: f64,
    /// Order of the integrator, in (0, 2).
    pub lambda: f64,
    /// Derivative gain (0 without a derivative term).
    pub kd: f64,
    /// Order of the differentiator, in (0, 2) (1 without a derivative term).
    pub mu: f64,
}

impl Controller {
    /// `C(j omega)`, omega in rad/s, with `(j w)^a = w^a e^(j a pi/2)`.
    pub fn freq_response(&self, omega: f64) -> Complex64 {
        let mut c = Complex64::new(self.kp, 0.0) + self.ki / jw_pow(omega, self.lambda);
        if self.kd != 0.0 {
            c += self.kd * jw_pow(omega, self.mu);
        }
        c
    }

    /// `d C(j omega) / d ln omega = -lambda ki (j w)^-lambda + mu kd (j w)^mu`.
    pub fn dlog_omega(&self, omega: f64) -> Complex64 {
        let mut d = -self.lambda * self.ki / jw_pow(omega, self.lambda);
        if self.kd != 0.0 {
            d += self.mu * self.kd * jw_pow(omega, self.mu);
        }
        d
    }

    /// The controller a transfer function is, when it has this form:
    /// `(kd s^(lambda+mu) + kp s^lambda + ki) / (a s^lambda)` with `0 < lambda < 2` (the text
    /// `fracid tune` prints for `C(s)`), no delay; `None` otherwise.
    pub fn from_tf(tf: &FracTf) -> Option<Self> {
        let [den] = tf.den.as_slice() else {
            return None;
        };
        let lambda = den.order;
        if !(lambda > 0.0 && lambda < 2.0 && den.coef != 0.0 && tf.delay == 0.0) {
            return None;
        }
        let mut c = Controller {
            kp: 0.0,
            ki: 0.0,
            lambda,
            kd: 0.0,
            mu: 1.0,
        };
        for t in &tf.num {
            let k = t.coef / den.coef;
            if t.order.abs() < 1e-12 {
                c.ki = k;
            } else if (t.order - lambda).abs() < 1e-12 {
                c.kp = k;
            } else if t.order > lambda && t.order - lambda < 2.0 && c.kd == 0.0 {
                c.kd = k;
                c.mu = t.order - lambda;
            } else {
                return None;
            }
        }
        (c.ki != 0.0).then_some(c)
    }

    /// `C(s) = (kd s^(lambda+mu) + kp s^lambda + ki) / s^lambda` as a [`FracTf`] (no delay);
    /// `kp + kd s^mu` without integral action (`ki = 0`).
    ///
    /// # Errors
    /// Non-finite gains or orders (from [`FracTf::new`]).
    pub fn tf(&self) -> Result<FracTf> {
        if self.ki == 0.0 {
            // kp + kd s^mu
            return Ok(FracTf::new(
                vec![Term::new(self.kd, self.mu), Term::new(self.kp, 0.0)],
                vec![Term::new(1.0, 0.0)],
                0.0,
            )?);
        }
        Ok(FracTf::new(
            vec![
                Term::new(self.kd, self.lambda + self.mu),
                Term::new(self.kp, self.lambda),
                Term::new(self.ki, 0.0),
            ],
            vec![Term::new(1.0, self.lambda)],
            0.0,
        )?)
    }
}

/// The orders of a candidate, for the messages.
pub(crate) fn label(c: &Controller) -> String {
    if c.ki == 0.0 {
        format!("mu = {:.3}", c.mu)
    } else if c.kd > 0.0 {
        format!("lambda = {:.3}, mu = {:.3}", c.lambda, c.mu)
    } else {
        format!("lambda = {:.3}", c.lambda)
    }
}
