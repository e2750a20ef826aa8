//! Input clipping, `clamp(u, -L, L)` (the drive's voltage limit).
//!
//! Signature: `G (clamp(u, -L, L) - u)` over a grid of `L` from 45% to 100% of the largest input
//! ([`super::probe_static_map`]). With a two-level input any static input map is affine (a gain
//! and an offset): then it is reported as ambiguous, never fitted.
//! Behind an input offset, about another centre: [`super::off_centre`].

use super::{named, probe_static_map, Findings, Look, Probe, StaticMap};
use crate::oe::{Bounds, Effect, FracModel};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Saturation;

impl Probe for Saturation {
    fn name(&self) -> &'static str {
        "saturation"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let spec = StaticMap {
            name: "saturation",
            param: "sat_level",
            what: "level",
            grid: (0..12).map(|i| 0.45 + 0.05 * i as f64).collect(),
            scaled: true,
            bounds: Bounds::Positive,
            map: |v, l, _| v.clamp(-l, l),
            effect: |level, _| Effect::Saturation { level },
        };
        probe_static_map(look, found, &spec);
        super::off_centre::offer(look, found, &spec, 0);
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("level", "sat_level")])
    }
}
