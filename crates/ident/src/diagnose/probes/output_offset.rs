//! A constant output offset, `y + c_y` (a sensor bias). Part of the base model by default
//! (`IdentOptions::fit_offset`); probed only when the base model has none.
//!
//! Signature: the constant `1` at the output.

use super::{named, Candidate, Findings, Look, Probe};
use crate::oe::{Bounds, Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct OutputOffset;

impl Probe for OutputOffset {
    fn name(&self) -> &'static str {
        "output_offset"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("y_offset") {
            return Ok(());
        }
        let s = look.s();
        let mean = look.e.iter().sum::<f64>() / s as f64;
        let (r2, beta) = look.direct(&[vec![1.0; s]]);
        let mut m = look.st.model.clone();
        let c = m.add_param(Param::new("y_offset", beta[0], Bounds::Free));
        m.effects.push(Effect::OutputOffset { c });
        let sd = (look.ee / s as f64).sqrt().max(1e-300);
        found.candidates.push(Candidate {
            lead: None,
            name: "output_offset",
            key: "output_offset".into(),
            r2,
            evidence: format!(
                "residual mean {mean:.3e} ({:.1} standard errors); a constant at the output \
                 explains {:.1}% of the residual sum of squares",
                mean / sd * (s as f64).sqrt(),
                100.0 * r2
            ),
            starts: vec![m],
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("y_offset", "y_offset")])
    }
}
