//! Coulomb friction as an equivalent input voltage, `u - Vc sign(y_prev)`.
//!
//! Signature: `G (-sign(y_prev))`, with the sign taken with a dead band of three noise levels
//! (a speed at rest is neither sign: friction then holds, it does not push). Identifiable when
//! the data contain what separates it from a constant input offset: speed reversals, or rest
//! intervals between motion (friction vanishes at rest, an offset does not). Otherwise it is
//! reported as ambiguous with the input offset, whose own probe tests the alternative; and with
//! a gain and an offset when the output does not reverse under a two-level input (a step from
//! rest: the output rests or moves as the input's level says, and so does the friction).

use super::{named, sign_band, Candidate, Findings, Look, Probe};
use crate::oe::{Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct Friction;

impl Probe for Friction {
    fn name(&self) -> &'static str {
        "coulomb_friction"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        if look.has("Vc") {
            return Ok(());
        }
        let (ctx, st, mo) = (look.ctx, look.st, look.motion);
        let moving = mo.pos + mo.neg;
        let rests = mo.rest >= 0.05 && moving >= 0.05;
        if !mo.reverses() && !rests {
            found.ambiguous(
                "coulomb_friction",
                "input offset",
                format!(
                    "the model output y is {} ({}): sign(y) is constant, so Vc sign(y) is a \
                     constant input offset (see input_offset for that alternative); reversals of \
                     y (a zero-mean PRBS) or rests between motion separate them",
                    if mo.pos >= mo.neg {
                        "positive"
                    } else {
                        "negative"
                    },
                    mo.describe()
                ),
            );
            return Ok(());
        }
        let levels = super::input_levels(&look.ua).0.len();
        if !mo.reverses() && levels <= 2 {
            found.ambiguous(
                "coulomb_friction",
                "gain and offset",
                format!(
                    "the input takes {levels} levels and the model output y does not reverse \
                     ({}): y rests or moves as the input's level says, so Vc sign(y) follows that \
                     level, a change of the gain and the offset; reversals of y (a zero-mean \
                     PRBS) separate them",
                    mo.describe()
                ),
            );
            return Ok(());
        }
        let x: Vec<f64> = (0..ctx.u.len())
            .map(|k| {
                let prev = if k == 0 { ctx.y0 } else { look.ya[k - 1] };
                -sign_band(prev, mo.band)
            })
            .collect();
        let Some((r2, beta)) = look.through_model(&x) else {
            return Ok(());
        };
        // The signature is regressed with the model's sensitivities projected out; the gain
        // fitted without friction has taken up part of it (friction lowers the response to the
        // input's swings, which a lower gain mimics), so the coefficient left can come out with
        // the wrong sign. A signature that strong (its `R^2` at the floor or above) with the
        // wrong sign is left to the refit, not the sign, to decide: proposed at the floor (the
        // `R^2` of the wrong sign ranks nothing), started at the coefficient's magnitude.
        let wrong_sign = beta[0] <= 0.0;
        if wrong_sign && r2 < ctx.opts.min_r2 {
            return Ok(());
        }
        let r2 = if wrong_sign { ctx.opts.min_r2 } else { r2 };
        // Two starts, the friction's sign over the hold interval taken at its middle (a friction
        // acting continuously) and at its start (decided at the sample instant and held): the
        // two discretisations differ by up to a sample's timing at each reversal, which on a
        // plant fast against the sampling moves the response by more than the friction's own
        // share; the refit's screen keeps the one the record follows.
        let starts = [false, true]
            .into_iter()
            .map(|sampled| {
                let mut m = st.model.clone();
                let vc = m.add_param(Param::positive("Vc", beta[0].abs()));
                m.effects.insert(0, Effect::Coulomb { vc, sampled });
                m
            })
            .collect();
        found.candidates.push(Candidate {
            lead: None,
            name: "coulomb_friction",
            key: "coulomb_friction".into(),
            r2,
            evidence: if wrong_sign {
                format!(
                    "the friction signature G(-sign(y)) fits the residual with the wrong sign \
                     (coefficient {:.3e}: the gain fitted without friction took it up); refitted \
                     from Vc = {:.3e}; model output {}",
                    beta[0],
                    beta[0].abs(),
                    mo.describe()
                )
            } else {
                format!(
                    "the friction signature G(-sign(y)) (a force opposing the output's sign: \
                     Coulomb friction on a speed) explains {:.1}% of the residual sum of squares \
                     (coefficient {:.3e}); model output {}",
                    100.0 * r2,
                    beta[0],
                    mo.describe()
                )
            },
            starts,
        });
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        named(model, values, &[("Vc", "Vc")])
    }
}
