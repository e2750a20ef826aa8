//! A static input map about another centre than the input's zero: `map(u + c)`, an input offset
//! before a clamp or a dead band (a drive whose command has an offset, a limit or a gap that is
//! not symmetric). Fitted about zero, a clamp that clips one side of the input in the
//! estimation part and the other side in the held-out part predicts the held-out part worse than
//! no clamp at all (the zoo's 45/0122: -75% of the estimation residual, +15% held out).
//!
//! Both maps act at two thresholds of the input, `U` above and `-D` below: the clamp
//! `clamp(u + c, -L, L)` clips at `U = L - c` and `-D = -L - c`; the dead band of half width
//! `w` about `-c` is closed between the same `-D = -w - c` and `U = w - c`. Their signatures are
//! one two-sided clip with opposite signs: `clamp(u + c, -L, L) - u` is, but for a constant,
//! `(min(u, U) - u) + (max(u, -D) - u)`, and `dz_w(u + c) - u = -clamp(u, -D, U)`, that same sum
//! less `u` (the model's own input, whose response its gain already spans). The model is linear
//! in its input, so each side is simulated once per threshold of the grid, and every pair
//! `(U, D)` is regressed ([`crate::diagnose::residual::explained_in`]) at the cost of two grids:
//! a positive coefficient is a clamp, a negative one a dead band. The best pair of each sign is
//! offered ([`offer`]) as a start of the map's refit beside the symmetric one when it explains
//! more than the symmetric grid's best; its refit is the candidate's only when it pays over the
//! symmetric refit, and over the symmetric structure refitted from its values, by the rules an
//! effect meets (the offset is an effect of its own: [`crate::diagnose`]'s `best_refit`).
//!
//! Identifiability: the input must take more distinct levels than the map, its centre, the gain
//! and the output offset have parameters (four): on fewer, any such map is matched by some
//! clamp or dead band with an offset, and none is told from another.

use super::{input_levels, Candidate, Findings, Look, StaticMap};
use crate::diagnose::residual::explained_in;
use crate::oe::{Bounds, Effect, FracModel, Param};

/// The input offset's parameter name (the input-offset probe's).
pub(crate) const OFFSET: &str = "u_offset";

/// The thresholds searched, as fractions of the largest input magnitude, on each side.
const GRID: [f64; 16] = [
    0.03, 0.06, 0.09, 0.12, 0.15, 0.2, 0.25, 0.3, 0.36, 0.45, 0.55, 0.65, 0.75, 0.85, 0.95, 1.0,
];

/// The smallest threshold of a clamp, as a fraction of the largest input magnitude: the
/// symmetric clamp's smallest level ([`super::saturation`]). A clamp nearer the centre on one side
/// is a rectifier of the input, not a limit: on the zoo's sign-blind sensor 44/0247 (a periodic
/// disturbance beside it, so the data take both signs) a clamp at +3% and -100% of the input
/// stood in for the sensor.
const CLAMP_FROM: f64 = 0.45;

/// The fewest distinct input levels on which a map off the centre is offered (module
/// documentation): one more than its parameters with the gain and the output offset.
const MIN_LEVELS: usize = 5;

/// The best pair of thresholds of one sign: its evidence `R^2` and `(U, D)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Clip {
    pub r2: f64,
    pub upper: f64,
    pub lower: f64,
}

/// The best two-sided clip with a positive coefficient (a clamp, both thresholds at least
/// [`CLAMP_FROM`]) and with a negative one (a dead band), over the pairs of [`GRID`] off the
/// diagonal (the diagonal is the symmetric probes'),
/// or `None` for each when the input has too few levels or no pair clips the estimation part.
pub(crate) fn clips(look: &Look<'_>) -> [Option<Clip>; 2] {
    let (levels, umax) = input_levels(&look.ua);
    if levels.len() < MIN_LEVELS || umax <= 0.0 {
        return [None, None];
    }
    let s = look.s();
    let through = |d: Vec<f64>| -> Option<Vec<f64>> {
        if d[..s].iter().all(|v| *v == 0.0) {
            return None;
        }
        let g = look.ctx.lin(look.st, &d)?;
        Some(g[..s].to_vec())
    };
    let side = |upper: bool| -> Vec<Option<Vec<f64>>> {
        GRID.iter()
            .map(|f| {
                let t = f * umax;
                through(
                    look.ua
                        .iter()
                        .map(|&v| if upper { v.min(t) - v } else { v.max(-t) - v })
                        .collect(),
                )
            })
            .collect()
    };
    let (ups, lows) = (side(true), side(false));
    let mut best: [Option<(f64, usize, usize)>; 2] = [None, None];
    for (i, up) in ups.iter().enumerate() {
        for (j, low) in lows.iter().enumerate() {
            if i == j {
                continue;
            }
            let col: Vec<f64> = match (up, low) {
                (Some(a), Some(b)) => a.iter().zip(b).map(|(x, y)| x + y).collect(),
                (Some(a), None) | (None, Some(a)) => a.clone(),
                (None, None) => continue,
            };
            let (r2, beta) = explained_in(&look.e, &[col], &look.sens);
            let sign = usize::from(beta[0] < 0.0);
            let limit = GRID[i].min(GRID[j]) >= CLAMP_FROM;
            if beta[0] != 0.0 && (sign == 1 || limit) && best[sign].is_none_or(|b| r2 > b.0) {
                best[sign] = Some((r2, i, j));
            }
        }
    }
    best.map(|b| {
        b.map(|(r2, i, j)| Clip {
            r2,
            upper: GRID[i] * umax,
            lower: GRID[j] * umax,
        })
    })
}

/// Offer the static map `sm` off the centre, its best pair of thresholds the clip of sign
/// `sign` ([`Look::clips`]: 0 a clamp, 1 a dead band): its start (an input offset
/// `c = (D - U)/2` before the map at `(U + D)/2`) is added to the symmetric candidate's starts
/// when it explains more than it, or proposed alone when the symmetric probe proposed none.
/// Nothing (and no clip searched) when the model has the map or an input offset already.
pub(crate) fn offer(look: &Look<'_>, found: &mut Findings, sm: &StaticMap, sign: usize) {
    if look.has(sm.param) || look.has(OFFSET) {
        return;
    }
    let Some(Clip { r2, upper, lower }) = look.clips()[sign] else {
        return;
    };
    let mut m: FracModel = look.st.model.clone();
    let g = m.add_param(Param::new(sm.param, 0.5 * (upper + lower), sm.bounds));
    let c = m.add_param(Param::new(OFFSET, 0.5 * (lower - upper), Bounds::Free));
    m.effects.insert(0, (sm.effect)(g, 0.0));
    m.effects.insert(0, Effect::InputOffset { c });
    let words = format!(
        "at +{upper:.3e} and -{lower:.3e} (an input offset before the {}) it explains {:.1}%",
        sm.name,
        100.0 * r2
    );
    match found.candidates.iter_mut().find(|c| c.name == sm.name) {
        Some(c) if c.r2 < r2 => {
            c.starts.push(m);
            c.evidence = format!("{}; {words}", c.evidence);
        }
        Some(_) => {}
        None => found.candidates.push(Candidate {
            lead: None,
            name: sm.name,
            key: sm.name.into(),
            r2,
            evidence: format!(
                "the {} signature {words} of the residual sum of squares",
                sm.name
            ),
            starts: vec![m],
        }),
    }
}
