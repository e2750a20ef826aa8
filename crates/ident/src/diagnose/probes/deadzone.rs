//! An input dead band: `0` for `|u| < w`, else `u - w sign(u)` (a drive's dead-time
//! compensation gap, static friction in voltage terms).
//!
//! Signature: `G (dz_w(u) - u)` over a grid of `w` from 3% to 36% of the largest input
//! ([`super::probe_static_map`]). Ambiguous with a gain and an offset for a two-level input.
//! Behind an input offset, about another centre: [`super::off_centre`].

use super::{named, probe_static_map, Findings, Look, Probe, StaticMap};
use crate::oe::{Bounds, Effect, FracModel};
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
        let spec = StaticMap {
            name: "deadzone",
            param: "dz_width",
            what: "half width",
            grid: (1..=12).map(|i| 0.03 * i as f64).collect(),
            scaled: true,
            bounds: Bounds::Positive,
            map: |v, w, _| dead_band(v, w),
            effect: |width, _| Effect::Deadzone { width },
        };
        probe_static_map(look, found, &spec);
        super::off_centre::offer(look, found, &spec, 1);
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("width", "dz_width")])
    }
}
