//! A slow output drift, linear in time: `y + r t` (a sensor's or an amplifier's thermal drift, a
//! battery's open-circuit voltage following its state of charge over a short record).
//!
//! Signature: the ramp `t` at the output (from the record's first sample), regressed with the
//! model's sensitivities (the output offset's among them: only what of the ramp no offset or
//! plant parameter explains counts). Through a free integrator a constant input offset is a ramp
//! at the output too: that structure's own input offset is the drift's other explanation
//! (ambiguous, not probed).

use super::{named, Candidate, Findings, Look, Probe};
use crate::oe::{Bounds, Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct OutputDrift;

impl Probe for OutputDrift {
    fn name(&self) -> &'static str {
        "output_drift"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("y_drift") {
            return Ok(());
        }
        if look.st.model.integrator {
            found.ambiguous(
                "output_drift",
                "input offset",
                "through the free integrator a constant input offset is a ramp at the output: \
                 an output drift and an input offset cannot be told apart (the structure's input \
                 offset stands for both)"
                    .into(),
            );
            return Ok(());
        }
        let (s, dt) = (look.s(), look.ctx.dt);
        let ramp: Vec<f64> = (0..s).map(|k| k as f64 * dt).collect();
        let (r2, beta) = look.direct(&[ramp]);
        let mut m = look.st.model.clone();
        let r = m.add_param(Param::new("y_drift", beta[0], Bounds::Free));
        m.effects.push(Effect::OutputDrift { r });
        found.candidates.push(Candidate {
            lead: None,
            name: "output_drift",
            key: "output_drift".into(),
            r2,
            evidence: format!(
                "a ramp at the output, {:.3e} per second ({:.3e} over the estimation part), \
                 explains {:.1}% of the residual sum of squares",
                beta[0],
                beta[0] * s as f64 * dt,
                100.0 * r2
            ),
            starts: vec![m],
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("rate_per_s", "y_drift")])
    }
}
