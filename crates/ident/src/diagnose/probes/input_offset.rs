//! A constant input offset, `u + c_u` (a drive's voltage offset, or a load torque that never
//! changes sign): it acts through the model's dynamics, unlike an output offset.
//!
//! Signature: `G 1` (the model's step response), regressed with the model's sensitivities.
//!
//! Identifiability: through a linear model whose initial state is estimated (a past held input),
//! an input offset over the record is exactly an output offset `K c_u` plus a shift of the past
//! levels, so the data cannot tell them apart. Through a linear model fitted from the rest the
//! record shows before its first input change, an input offset is invisible where it was there
//! before the record (the rest is then at `u0 + c_u`): what the signature finds is the step
//! response from the first sample, `c_u G 1`, which with the output offset fitted is exactly the
//! state a past input `-c_u` held until the first sample leaves: the record was not at rest at
//! its start (a step logged from its first sample, the input before it another level), which is
//! the initial-state probe's question, asked there. It is told apart when the model integrates
//! (a constant input is then a drift) or has a nonlinear effect that acts after it (friction's
//! sign, a clamp, a dead band, a sign-blind sensor).

use super::{named, Candidate, Findings, Look, Probe};
use crate::oe::{Bounds, Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct InputOffset;

impl Probe for InputOffset {
    fn name(&self) -> &'static str {
        "input_offset"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("u_offset") {
            return Ok(());
        }
        let m = &look.st.model;
        let linear = !m.integrator
            && m.effects
                .iter()
                .all(|e| matches!(e, Effect::OutputOffset { .. } | Effect::Sinusoid { .. }));
        if linear && look.has("y_offset") && super::initial_state::asks(look) {
            found.reject(
                "input_offset",
                "not tested: through the linear model fitted from rest, a constant input offset \
                 is a step at the first sample, with the output offset the state a past input \
                 held until then leaves: the initial state's question (initial_state)"
                    .into(),
            );
            return Ok(());
        }
        if m.past.is_some() && linear {
            let why =
                "with the initial state estimated, a constant input offset through the linear \
                       model is a constant output offset (K c_u) and a shift of the past input";
            if look.has("y_offset") {
                found.reject(
                    "input_offset",
                    format!("not tested: {why}, and the model already fits an output offset"),
                );
            } else {
                found.ambiguous(
                    "input_offset",
                    "output offset",
                    format!(
                        "{why}: the output-offset candidate stands for both; a record that starts \
                         from rest (--initial rest) separates them"
                    ),
                );
            }
            return Ok(());
        }
        let ones = vec![1.0; look.ctx.u.len()];
        let Some((r2, beta)) = look.through_model(&ones) else {
            return Ok(());
        };
        let mut m = look.st.model.clone();
        let c = m.add_param(Param::new("u_offset", beta[0], Bounds::Free));
        m.effects.insert(0, Effect::InputOffset { c });
        found.candidates.push(Candidate {
            lead: None,
            name: "input_offset",
            key: "input_offset".into(),
            r2,
            evidence: format!(
                "a constant input {:.3e} through the model explains {:.1}% of the residual sum of \
                 squares",
                beta[0],
                100.0 * r2
            ),
            starts: vec![m],
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("u_offset", "u_offset")])
    }
}
