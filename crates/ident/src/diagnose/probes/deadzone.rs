//! An input dead band: `0` for `|u| < w`, else `u - w sign(u)` (a drive's dead time
//! compensation gap, static friction in voltage terms).
//!
//! Signature: `G (dz_w(u) - u)` over a grid of `w` from 3% to 36% of the largest input; the
//! coefficient must be positive. Ambiguous with a gain and an offset for a two-level input.

use super::{input_levels, named, static_map_search, Candidate, Findings, Look, Probe};
use crate::oe::{Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Deadzone;

fn dead_band(v: f64, w: f64) -> f64 {
    if v.abs() < w {
        0.0
    } else {
        v - w * v.signum()
    }
}

impl Probe for Deadzone {
    fn name(&self) -> &'static str {
        "deadzone"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("dz_width") {
            return Ok(());
        }
        let (levels, umax) = input_levels(&look.ua);
        if levels <= 2 {
            found.ambiguous(
                "deadzone",
                "gain and offset",
                super::two_levels(levels, "deadzone"),
            );
            return Ok(());
        }
        let grid: Vec<f64> = (1..=12).map(|i| umax * 0.03 * i as f64).collect();
        let Some((r2, w, coef)) = static_map_search(look, &grid, dead_band) else {
            return Ok(());
        };
        let mut m = look.st.model.clone();
        let i = m.add_param(Param::positive("dz_width", w));
        m.effects.insert(0, Effect::Deadzone { width: i });
        found.candidates.push(Candidate {
            lead: None,
            name: "deadzone",
            key: "deadzone".into(),
            r2,
            evidence: format!(
                "the deadzone signature at half width = {w:.3e} (grid over {} values, linear \
                 parameters refitted) explains {:.1}% of the residual sum of squares \
                 (coefficient {coef:.2})",
                grid.len(),
                100.0 * r2
            ),
            starts: vec![m],
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("width", "dz_width")])
    }
}
