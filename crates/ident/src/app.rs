//! The application layer shared by the CLI, the Python bindings, the fleet and the demo: the
//! use cases ([`time`]: request, `run`, report), their observer ([`observe`]), structure presets,
//! option parsing and the model's report type, so that the same words give the same model
//! everywhere.

pub mod answer;
pub mod freq;
pub mod observe;
pub mod score;
pub mod time;
pub mod verdict;

use crate::data::OffsetMode;
use crate::oe::FracModel;
use crate::{Error, Result};
use fracsim::FracTf;

/// The largest input delay searched when none is given: a fifth of the record, at most 1000
/// samples of `dt_s` (1 s at 1 ms; once 1 s whatever the step, one sample of a record logged every
/// second, a hundredth of one with the time in units of 100 samples).
pub fn default_max_delay(duration_s: f64, dt_s: f64) -> f64 {
    (0.2 * duration_s).min(1000.0 * dt_s)
}

/// The model named by `spec`: `pmsm` (`K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`), `commensurate`
/// (`K/(a2 s^(2q) + a1 s^q + 1)`), `second-order` and `third-order` (the integer
/// `K/(a2 s^2 + a1 s + 1)`, `K/(a3 s^3 + a2 s^2 + a1 s + 1)`), `two-mass` (the PMSM times a
/// resonant pair, `K (b2 s^2 + b1 s^mu + 1) / ((a2 s^(zeta+theta) + a1 s^zeta + 1)
/// (c2 s^2 + c1 s^mu + 1))`, [`FracModel::two_mass`]), `feedthrough` (the PMSM with a direct
/// feed-through, `D + K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`, [`FracModel::feedthrough`]),
/// `fopdt` (`K e^(-tau s)/(T s + 1)`, `tau` up to `max_delay_s`), `general` or `general:N/D`
/// (the general structure sized by the data or of that size, [`crate::diagnose::general`]: here its
/// template, a first order), or a transfer function whose every coefficient and order is fitted from its values (then
/// `general` is true: it starts from them). Returns `(model, general)`.
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
    Ok(match spec.trim().to_ascii_lowercase().as_str() {
        // `auto` chooses among the structures (ident::diagnose::structures::fit_best); its model
        // is the PMSM, the first candidate.
        "pmsm" | "auto" => (FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9), false),
        "commensurate" => (FracModel::commensurate(1.0, 0.01, 1e-4, 0.9), false),
        "second-order" | "second_order" => (FracModel::second_order(1.0, 0.01, 1e-4), false),
        "third-order" | "third_order" => {
            (FracModel::third_order(1.0, 0.0175, 8.75e-5, 1.25e-7), false)
        }
        "two-mass" | "two_mass" => (crate::diagnose::structures::two_mass(), false),
        "feedthrough" | "feed-through" | "feed_through" => (
            FracModel::feedthrough([1.0, 0.01, 1e-4, 0.9, 0.9], 0.0),
            false,
        ),
        "fopdt" => (
            FracModel::fopdt(1.0, 0.1, 0.05 * max_delay_s, max_delay_s),
            false,
        ),
        // `general` or `general:N/D`: sized by the data ([`crate::diagnose::general`]); this is the
        // template whose options (approximation, delay, integrator) its sizes take.
        s if s.starts_with("general") && crate::diagnose::general::requested(s).is_some() => {
            crate::diagnose::general::requested(s).transpose()?;
            (crate::diagnose::general::template(), false)
        }
        s => {
            let tf: FracTf = s.parse().map_err(|e| {
                Error::Options(format!(
                    "structure '{spec}' is not pmsm, commensurate, second-order, third-order, \
                     two-mass, feedthrough, fopdt, auto, general, general:N/D or a model: {e}"
                ))
            })?;
            (FracModel::from_tf(&tf, true, true), true)
        }
    })
}

/// Whether `spec` asks the data to choose the structure (`auto`:
/// [`crate::diagnose::structures::fit_best`] for a plain fit; with the diagnosis, its own
/// comparison from the PMSM). Returns the structure's label for the comparison: the PMSM for
/// `auto`, else `spec` itself.
///
/// ```
/// assert_eq!(ident::app::auto_label(" Auto"), (true, "pmsm"));
/// assert_eq!(ident::app::auto_label("commensurate"), (false, "commensurate"));
/// ```
pub fn auto_label(spec: &str) -> (bool, &str) {
    if spec.trim().eq_ignore_ascii_case("auto") {
        (true, "pmsm")
    } else {
        (false, spec)
    }
}

/// `initial`, `mean` or `none` ([`OffsetMode`]).
///
/// # Errors
/// [`Error::Options`] for another word.
pub fn offsets(s: &str) -> Result<OffsetMode> {
    match s.trim().to_ascii_lowercase().as_str() {
        "initial" => Ok(OffsetMode::Initial),
        "mean" => Ok(OffsetMode::Mean),
        "none" => Ok(OffsetMode::None),
        _ => Err(Error::Options(format!(
            "offsets '{s}' must be initial, mean or none"
        ))),
    }
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

/// Fix and free parameters by name: `fix` is a comma-separated list of `NAME` or `NAME=VALUE`
/// (held, at that value when given), `free` a list of names (fitted).
///
/// ```
/// let (mut m, _) = ident::app::structure("pmsm", 0.2).unwrap();
/// ident::app::fix_free(&mut m, "zeta=0.9,theta", "").unwrap();
/// assert!(!m.params[3].free && m.params[3].value == 0.9 && !m.params[4].free);
/// assert!(ident::app::fix_free(&mut m, "nope", "").is_err());
/// ```
///
/// # Errors
/// [`Error::Options`] for an unknown name, a value that is not a number or is out of range, a
/// name both fixed and freed.
pub fn fix_free(m: &mut FracModel, fix: &str, free: &str) -> Result<()> {
    let names = |list: &str| -> Vec<String> {
        list.split(',')
            .map(|s| s.split('=').next().unwrap_or("").trim().to_string())
            .filter(|s| !s.is_empty())
            .collect()
    };
    let freed = names(free);
    if let Some(both) = names(fix).into_iter().find(|n| freed.contains(n)) {
        return Err(Error::Options(format!(
            "'{}' is both held (fix) and fitted (free): name it once",
            crate::files::shorten(&both)
        )));
    }
    for item in fix.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (name, value) = match item.split_once('=') {
            Some((n, v)) => {
                let v: f64 = v.trim().parse().map_err(|_| {
                    Error::Options(format!("fix '{item}': '{}' is not a number", v.trim()))
                })?;
                (n.trim(), Some(v))
            }
            None => (item, None),
        };
        m.set_fixed(name, true, value)?;
    }
    for name in free.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        m.set_fixed(name, false, None)?;
    }
    Ok(())
}
