//! Input clipping, `clamp(u, -L, L)` (the drive's voltage limit).
//!
//! Signature: `G (clamp(u, -L, L) - u)` over a grid of `L` from 45% to 100% of the largest input;
//! the coefficient must be positive. With a two-level input any static input map is affine (a
//! gain and an offset): then it is reported as ambiguous, never fitted.

use super::{input_levels, named, static_map_search, Candidate, Findings, Look, Probe};
use crate::oe::{Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Saturation;

impl Probe for Saturation {
    fn name(&self) -> &'static str {
        "saturation"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("sat_level") {
            return Ok(());
        }
        let (levels, umax) = input_levels(&look.ua);
        if levels <= 2 {
            found.ambiguous(
                "saturation",
                "gain and offset",
                super::two_levels(levels, "saturation"),
            );
            return Ok(());
        }
        let grid: Vec<f64> = (0..12).map(|i| umax * (0.45 + 0.05 * i as f64)).collect();
        let Some((r2, l, coef)) = static_map_search(look, &grid, |v, l| v.clamp(-l, l)) else {
            return Ok(());
        };
        let mut m = look.st.model.clone();
        let i = m.add_param(Param::positive("sat_level", l));
        m.effects.insert(0, Effect::Saturation { level: i });
        found.candidates.push(Candidate {
            lead: None,
            name: "saturation",
            key: "saturation".into(),
            r2,
            evidence: format!(
                "the saturation signature at level = {l:.3e} (grid over {} values, linear \
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
        named(model, values, &[("level", "sat_level")])
    }
}
