//! `fracid tune`'s use case: one request ([`TuneRequest`], its defaults written once in its
//! `Default`, which the CLI's flags and Python's keywords take), one [`run`], one typed report
//! ([`Report`]).

use crate::closed::InputEffect;
use crate::controller::Form;
use crate::error::{invalid, Result};
use crate::report::{Report, Runs, SimOptions};
use crate::spec::{Floors, GainBound, Orders, Spec};
use fracsim::FracTf;
use serde::{Deserialize, Serialize};

/// What `fracid tune` (and Python's `fracid.tune`) is asked: the specification and the
/// simulation's options. A field left out of a JSON request takes its default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TuneRequest {
    /// The controller structure (default `fopi`).
    pub form: Form,
    /// Gain crossover in rad/s (a design needs it).
    pub wc: Option<f64>,
    /// Phase margin in degrees (a design needs it).
    pub pm: Option<f64>,
    /// Flat phase at `wc` (iso-damping).
    pub flat: bool,
    /// `|T(j w)| <= db` for every `w >= omega`.
    pub t_high: Option<GainBound>,
    /// `|S(j w)| <= db` for every `w <= omega`.
    pub s_low: Option<GainBound>,
    /// Robustness floor: the largest sensitivity peak accepted ([`Floors::ms_max`]).
    pub max_ms: f64,
    /// Robustness floor: the smallest gain margin accepted, dB ([`Floors::gm_min_db`]).
    pub min_gm: f64,
    /// Robustness floor: the smallest integrator order accepted ([`Floors::lambda_min`]).
    pub min_lambda: f64,
    /// A fixed integrator order.
    pub lambda: Option<f64>,
    /// A fixed differentiator order.
    pub mu: Option<f64>,
    /// The largest integrator order searched.
    pub max_lambda: Option<f64>,
    /// The largest differentiator order searched.
    pub max_mu: Option<f64>,
    /// The loop's sample period in seconds.
    pub dt: Option<f64>,
    /// The simulated reference step, output units (default 1).
    pub step: f64,
    /// The simulated load step at the plant's input, input units (default: `step / G(0)`).
    pub load: Option<f64>,
    /// The voltage limit on the controller's output in the simulated loops, input units.
    pub u_limit: Option<f64>,
}

impl Default for TuneRequest {
    fn default() -> Self {
        let f = Floors::default();
        Self {
            form: Form::Fopi,
            wc: None,
            pm: None,
            flat: false,
            t_high: None,
            s_low: None,
            max_ms: f.ms_max,
            min_gm: f.gm_min_db,
            min_lambda: f.lambda_min,
            lambda: None,
            mu: None,
            max_lambda: None,
            max_mu: None,
            dt: None,
            step: 1.0,
            load: None,
            u_limit: None,
        }
    }
}

impl TuneRequest {
    /// The robustness floors asked.
    pub fn floors(&self) -> Floors {
        Floors {
            ms_max: self.max_ms,
            gm_min_db: self.min_gm,
            lambda_min: self.min_lambda,
        }
    }

    /// The design's specification.
    ///
    /// # Errors
    /// [`crate::Error::Invalid`] without `wc` or `pm` (the rest is checked by the design).
    pub fn spec(&self) -> Result<Spec> {
        let (Some(wc), Some(pm_deg)) = (self.wc, self.pm) else {
            return invalid("spec", "a design needs wc and pm");
        };
        Ok(Spec {
            form: self.form,
            wc,
            pm_deg,
            flat: self.flat,
            t_high: self.t_high,
            s_low: self.s_low,
            dt: self.dt,
            lambda: self.lambda,
            floors: self.floors(),
            orders: Orders {
                mu: self.mu,
                lambda_max: self.max_lambda,
                mu_max: self.max_mu,
            },
        })
    }

    /// The simulations' options, with the model's input `effects`.
    ///
    /// # Errors
    /// [`crate::Error::Invalid`] for a voltage limit that is not a positive number.
    pub fn sim_options(&self, effects: Vec<InputEffect>) -> Result<SimOptions> {
        if self.u_limit.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
            return invalid(
                "u-limit",
                format!("must be a positive number, got {:?}", self.u_limit),
            );
        }
        Ok(SimOptions {
            step: Some(self.step),
            load: self.load,
            effects,
            u_limit: self.u_limit,
        })
    }
}

/// `fracid tune`: design on `model` as `req` asks, realise, simulate (with the model's input
/// `effects`) and compare with the integer PI.
///
/// # Errors
/// Those of [`TuneRequest::spec`], [`TuneRequest::sim_options`] and [`crate::report::tune`].
pub fn run(model: &FracTf, req: &TuneRequest, effects: Vec<InputEffect>) -> Result<(Report, Runs)> {
    let spec = req.spec()?;
    let opts = req.sim_options(effects)?;
    crate::report::tune(model, &spec, &opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_json_request_is_the_default_and_floors_are_the_designs() {
        let r: TuneRequest = serde_json::from_str("{}").unwrap();
        assert_eq!(r, TuneRequest::default());
        assert_eq!(r.floors(), Floors::default());
        assert_eq!(r.form, Form::Fopi);
        assert_eq!(r.step, 1.0);
    }

    #[test]
    fn a_json_request_takes_every_field_and_refuses_unknown_ones() {
        let r: TuneRequest = serde_json::from_str(
            r#"{"form": "fopid", "wc": 300, "pm": 60, "flat": true, "u_limit": 24,
                "t_high": {"omega": 3000, "db": -10}, "max_ms": 1.6}"#,
        )
        .unwrap();
        let s = r.spec().unwrap();
        assert_eq!(
            (s.form, s.wc, s.pm_deg, s.flat),
            (Form::Fopid, 300.0, 60.0, true)
        );
        assert_eq!(
            s.t_high,
            Some(GainBound {
                omega: 3000.0,
                db: -10.0
            })
        );
        assert_eq!(s.floors.ms_max, 1.6);
        assert_eq!(s.floors.gm_min_db, Floors::default().gm_min_db);
        assert_eq!(r.sim_options(vec![]).unwrap().u_limit, Some(24.0));
        assert!(serde_json::from_str::<TuneRequest>(r#"{"wcc": 3}"#).is_err());
        assert!(serde_json::from_str::<TuneRequest>(r#"{"form": "pd"}"#).is_err());
    }

    #[test]
    fn a_request_without_wc_or_a_bad_limit_is_invalid() {
        let r = TuneRequest {
            pm: Some(60.0),
            ..TuneRequest::default()
        };
        assert!(matches!(r.spec(), Err(crate::Error::Invalid { .. })));
        let r = TuneRequest {
            u_limit: Some(-1.0),
            ..TuneRequest::default()
        };
        assert!(matches!(
            r.sim_options(vec![]),
            Err(crate::Error::Invalid { .. })
        ));
    }
}
