//! The application layer shared by the CLI, the Python bindings, the fleet and the demo: the
//! use cases ([`time`]: request, `run`, report), their observer ([`observe`]), the typed words
//! of the requests ([`request`]: the structure catalogue, the parameters held and fitted) and the model's report type, so that the same words give the same model
//! everywhere.

pub mod answer;
pub mod freq;
pub mod observe;
pub mod request;
pub mod score;
pub mod time;
pub mod verdict;

use crate::oe::FracModel;
use crate::{Error, Result};
pub use request::{Held, Names, Preset, Structure};

/// The largest input delay searched when none is given: a fifth of the record, at most 1000
/// samples of `dt_s` (1 s at 1 ms; once 1 s whatever the step, one sample of a record logged every
/// second, a hundredth of one with the time in units of 100 samples).
pub fn default_max_delay(duration_s: f64, dt_s: f64) -> f64 {
    (0.2 * duration_s).min(1000.0 * dt_s)
}

/// The model named by `spec` ([`Structure`]: a name of the catalogue [`Preset`], `auto`,
/// `general` or `general:N/D`, or a transfer function whose every coefficient and order is fitted
/// from its values: then `general` is true, it starts from them), with `max_delay_s` the largest
/// delay of `fopdt`. Returns `(model, general)`.
///
/// ```
/// let (m, general) = ident::app::structure("pmsm", 0.2).unwrap();
/// assert_eq!((m.params.len(), general), (5, false));
/// let (g, general) = ident::app::structure("2/(0.1 s^0.8 + 1)", 0.2).unwrap();
/// assert!(general && g.params.iter().filter(|p| p.free).count() == 3);
/// ```
///
/// # Errors
/// [`Error::Options`] for a name that is no preset and no model.
pub fn structure(spec: &str, max_delay_s: f64) -> Result<(FracModel, bool)> {
    Ok(spec.parse::<Structure>()?.model(max_delay_s))
}

/// An approximation band `"w_b,w_h"` in rad/s: exactly two numbers, every field checked.
///
/// ```
/// assert_eq!(ident::app::band("1e-3, 3000").unwrap(), (1e-3, 3000.0));
/// assert!(ident::app::band("1e-3,abc,3000").is_err());
/// ```
///
/// # Errors
/// [`Error::Options`] for anything else, or a band fracsim refuses.
pub fn band(s: &str) -> Result<(f64, f64)> {
    let fields: Vec<&str> = s.split(',').map(str::trim).collect();
    let nums: Vec<f64> = fields.iter().filter_map(|f| f.parse().ok()).collect();
    if fields.len() != 2 || nums.len() != 2 {
        return Err(Error::Options(format!(
            "band must be two numbers \"w_b,w_h\" in rad/s, got '{s}'"
        )));
    }
    fracsim::approx::check_band(nums[0], nums[1])?;
    Ok((nums[0], nums[1]))
}

/// The model JSON's form, shared with the tuner and Python ([`fracsim::json`]).
pub use fracsim::json::{ModelReport, TermReport};

/// Fix and free parameters by name: `fix` held (at its value when given), `free` fitted.
///
/// ```
/// let (mut m, _) = ident::app::structure("pmsm", 0.2).unwrap();
/// ident::app::fix_free(&mut m, &"zeta=0.9,theta".parse().unwrap(), &Default::default()).unwrap();
/// assert!(!m.params[3].free && m.params[3].value == 0.9 && !m.params[4].free);
/// assert!(ident::app::fix_free(&mut m, &"nope".parse().unwrap(), &Default::default()).is_err());
/// ```
///
/// # Errors
/// [`Error::Options`] for an unknown name, a value out of range, a name both fixed and freed.
pub fn fix_free(m: &mut FracModel, fix: &Held, free: &Names) -> Result<()> {
    if let Some(both) = fix.0.iter().find(|p| free.0.contains(&p.name)) {
        return Err(Error::Options(format!(
            "'{}' is both held (fix) and fitted (free): name it once",
            crate::files::shorten(&both.name)
        )));
    }
    for p in &fix.0 {
        m.set_fixed(&p.name, true, p.value)?;
    }
    for name in &free.0 {
        m.set_fixed(name, false, None)?;
    }
    Ok(())
}
