//! The checks every candidate passes before it is returned: a stable loop on its specification
//! (continuous, and sampled with `dt`), the robustness floors, the bounds over their bands.

use crate::analysis::{s_db, t_db, LoopMetrics};
use crate::controller::{label, Controller, Form};
use crate::plant::Plant;
use crate::spec::{Floors, Spec};

/// Tolerances of the final check: the design equations are solved to rounding, so these only
/// guard against a solver that went wrong.
const TOL_GAIN: f64 = 1e-3;
const TOL_PM_DEG: f64 = 0.1;
const TOL_SLOPE: f64 = 1e-3;

/// Whether the loop meets every specification and floor; the reason otherwise.
pub(crate) fn check(
    plant: &Plant,
    wc: f64,
    spec: &Spec,
    c: &Controller,
    m: &LoopMetrics,
) -> Result<(), String> {
    stable_and_on_spec(wc, spec, &label(c), m)?;
    floors_met(spec, c, m).map_err(|e| format!("{}: {e}", label(c)))?;
    bounds_met(plant, spec, c).map_err(|e| format!("{}: {e}", label(c)))
}

/// How far the sampled loop may cross from `wc` (relative) and its margin from the one asked
/// (deg): the design accounts for the hold's half-sample delay, not for the realisation's own
/// lags nor the hold's aliasing, which cost a few tenths to a few degrees below a tenth of the
/// Nyquist frequency.
const TOL_SAMPLED_WC: f64 = 0.05;
const TOL_SAMPLED_PM_DEG: f64 = 3.0;

/// The sampled loop: stable, crossing once near `wc` with nearly the margin asked, the floors.
pub(crate) fn check_sampled(spec: &Spec, c: &Controller, m: &LoopMetrics) -> Result<(), String> {
    let name = format!(
        "{} sampled every {} s",
        label(c),
        spec.dt.unwrap_or(f64::NAN)
    );
    let loose = Spec {
        flat: false,
        ..spec.clone()
    };
    match stable_and_on_spec(spec.wc, &loose, &name, m) {
        Err(e) if !e.contains("crosses at") => return Err(e),
        _ => {}
    }
    if (m.wc / spec.wc - 1.0).abs() > TOL_SAMPLED_WC
        || (m.pm_deg - spec.pm_deg).abs() > TOL_SAMPLED_PM_DEG
    {
        return Err(format!(
            "{name}: the sampled loop crosses at {:.4} rad/s with pm {:.2} deg (asked {} rad/s, \
             {} deg; accepted within {}% and {} deg)",
            m.wc,
            m.pm_deg,
            spec.wc,
            spec.pm_deg,
            TOL_SAMPLED_WC * 100.0,
            TOL_SAMPLED_PM_DEG
        ));
    }
    floors_met(spec, c, m).map_err(|e| format!("{name}: {e}"))
}

/// A stable closed loop crossing once, at `wc` with the margin asked (and flat if asked).
pub(crate) fn stable_and_on_spec(
    wc: f64,
    spec: &Spec,
    label: &str,
    m: &LoopMetrics,
) -> Result<(), String> {
    if let Some(note) = &m.stability_note {
        return Err(format!("{label}: the closed loop is not stable ({note})"));
    }
    if m.unstable_poles != 0 {
        return Err(format!(
            "{label}: the closed loop is unstable ({} poles in the right half-plane{})",
            m.unstable_poles,
            match m.plant_unstable_poles {
                p if p > 0 => format!("; the model has {p} of its own"),
                _ => String::new(),
            }
        ));
    }
    if m.crossovers != 1 {
        return Err(format!(
            "{label}: |L| crosses 0 dB {} times (at {})",
            m.crossovers,
            m.crossover_omegas
                .iter()
                .map(|w| format!("{w:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if (m.wc / wc - 1.0).abs() > TOL_GAIN || (m.pm_deg - spec.pm_deg).abs() > TOL_PM_DEG {
        return Err(format!(
            "{label}: the loop crosses at {:.4} rad/s with pm {:.3} deg",
            m.wc, m.pm_deg
        ));
    }
    if spec.flat && m.phase_slope.abs() > TOL_SLOPE {
        return Err(format!(
            "{label}: phase slope {:.2e} rad at wc{}",
            m.phase_slope,
            if spec.form == Form::Pi {
                " (a PI has only kp and ki, taken by wc and pm: a flat phase needs --form fopi)"
            } else {
                ""
            }
        ));
    }
    Ok(())
}

/// The robustness floors ([`Floors`]), each named with the option that relaxes it.
pub(crate) fn floors_met(spec: &Spec, c: &Controller, m: &LoopMetrics) -> Result<(), String> {
    spec.floors.met(spec.form.has_integrator(), c, m)
}

impl Floors {
    /// Whether the loop `m` of `c` meets the floors (the integral action's only when
    /// `integral`); the first one missed, named with the option that relaxes it, otherwise.
    ///
    /// # Errors
    /// The floor missed.
    pub fn met(&self, integral: bool, c: &Controller, m: &LoopMetrics) -> Result<(), String> {
        floors_of(self, integral, c, m)
    }
}

fn floors_of(f: &Floors, integral: bool, c: &Controller, m: &LoopMetrics) -> Result<(), String> {
    if m.ms > f.ms_max {
        return Err(format!(
            "sensitivity peak Ms = {:.3} at {:.4} rad/s above the floor {} (--max-ms)",
            m.ms, m.ms_omega, f.ms_max
        ));
    }
    if let Some(g) = m.gm_db.filter(|&g| g < f.gm_min_db) {
        return Err(format!(
            "gain margin {g:.2} dB below the floor {} dB (--min-gm)",
            f.gm_min_db
        ));
    }
    if let Some(g) = m.gm_low_db.filter(|&g| g < f.gm_min_db) {
        return Err(format!(
            "the loop turns unstable if its gain falls by {g:.2} dB, below the floor {} dB \
             (--min-gm)",
            f.gm_min_db
        ));
    }
    if integral && !(c.ki > 0.0 && c.lambda >= f.lambda_min) {
        return Err(format!(
            "no integral action: integrator order lambda = {:.3} below the floor {} \
             (--min-lambda)",
            c.lambda, f.lambda_min
        ));
    }
    Ok(())
}

/// The bounds over their bands: `|T| <= db` for every `w >= omega_h`, `|S| <= db` for every
/// `w <= omega_l` (on the analysis's refined grid, each local peak refined by golden section).
pub(crate) fn bounds_met(p: &Plant, spec: &Spec, c: &Controller) -> Result<(), String> {
    let grid = crate::analysis::loop_grid(p, c, spec.wc);
    bounds_on(p, spec, c, |lo, hi, f| band_peak(&grid, lo, hi, f))
}

/// The bounds at their bands' own edges, `omega_h` and `omega_l`: a necessary condition of
/// [`bounds_met`] (its bands include their edges) at two evaluations of the loop, checked before
/// a candidate's full analysis. The verdict is the same; a candidate refused here is refused for
/// its bound, where the full check would name the first of its failures.
pub(crate) fn bounds_met_at_edges(p: &Plant, spec: &Spec, c: &Controller) -> Result<(), String> {
    bounds_on(p, spec, c, |lo, hi, f| {
        let edge = if lo > 0.0 { lo } else { hi };
        (edge, f(edge))
    })
}

/// Each bound checked on the peak `peak(lo, hi, f)` gives over its band.
fn bounds_on(
    p: &Plant,
    spec: &Spec,
    c: &Controller,
    peak: impl Fn(f64, f64, &dyn Fn(f64) -> f64) -> (f64, f64),
) -> Result<(), String> {
    if let Some(b) = spec.t_high {
        let (w, v) = peak(b.omega, f64::INFINITY, &|w| t_db(p, c, w));
        if v > b.db {
            return Err(format!(
                "|T| = {v:.2} dB at {w:.4} rad/s > {} dB (asked above {} rad/s)",
                b.db, b.omega
            ));
        }
    }
    if let Some(b) = spec.s_low {
        let (w, v) = peak(0.0, b.omega, &|w| s_db(p, c, w));
        if v > b.db {
            return Err(format!(
                "|S| = {v:.2} dB at {w:.4} rad/s > {} dB (asked below {} rad/s)",
                b.db, b.omega
            ));
        }
    }
    Ok(())
}

/// The largest value of `f` over `[lo, hi]` rad/s: on the grid's points inside and the band's
/// finite edges, each local maximum refined by golden section between its neighbours.
pub(crate) fn band_peak(grid: &[f64], lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
    let mut w: Vec<f64> = grid
        .iter()
        .copied()
        .filter(|&x| x >= lo && x <= hi)
        .collect();
    for e in [lo, hi] {
        if e > 0.0 && e.is_finite() {
            w.push(e);
        }
    }
    w.sort_by(f64::total_cmp);
    w.dedup();
    let v: Vec<f64> = w.iter().map(|&x| f(x)).collect();
    let mut best = (f64::NAN, f64::NEG_INFINITY);
    for i in 0..w.len() {
        let left = if i > 0 { v[i - 1] } else { f64::NEG_INFINITY };
        let right = if i + 1 < v.len() {
            v[i + 1]
        } else {
            f64::NEG_INFINITY
        };
        let mut cand = (w[i], v[i]);
        if v[i] >= left && v[i] >= right && i > 0 && i + 1 < w.len() {
            let (x, y) = crate::analysis::golden_max(w[i - 1].ln(), w[i + 1].ln(), |x| f(x.exp()));
            if y > cand.1 {
                cand = (x.exp(), y);
            }
        }
        if cand.1 > best.1 {
            best = cand;
        }
    }
    best
}
