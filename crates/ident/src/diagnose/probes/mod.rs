//! The effect library: one [`Probe`] per effect, one file each (docs/design.md §6).
//!
//! A probe looks at the residual of the current model ([`Look`]), tests its effect's signature,
//! and proposes [`Candidate`]s: the model extended with the effect and its parameters, started
//! where the search over its non-smooth parameters (a threshold, a delay) put them. It can also
//! report the effect as not testable ([`Findings::reject`]) or as not identifiable from these data
//! ([`Findings::ambiguous`]). The loop in [`super::diagnose`] refits every strong candidate and
//! decides; a probe also says which of a fitted model's values are its parameters
//! ([`Probe::params`]). Adding an effect is adding a file here and a line in [`library`].

mod abs_sensor;
mod deadzone;
mod delay;
mod friction;
mod initial_state;
mod input_offset;
mod off_centre;
mod output_drift;
mod output_offset;
mod periodic;
mod power_law;
mod saturation;
mod skew;

use super::residual::{analyse, explained_in, Projection, ResidualAnalysis};
use super::{Ambiguity, Ctx, KeptEffect, RejectedEffect, State};
use crate::oe::{sensitivities, Bounds, Effect, FracModel, Param};
use crate::Result;
use std::collections::BTreeMap;

/// A candidate effect: its evidence and the model(s) to refit from.
pub(crate) struct Candidate {
    /// Report name (the probe's).
    pub name: &'static str,
    /// For a negative delay: the input advance in samples.
    pub lead: Option<usize>,
    /// Key of the candidate (the name, or the name with a frequency for a periodic effect).
    pub key: String,
    /// Evidence `R^2`: the fraction of the residual's sum of squares its signature explains.
    pub r2: f64,
    /// What in the residual pointed to it.
    pub evidence: String,
    /// Extended models to refit from (their values are the starts).
    pub starts: Vec<FracModel>,
}

/// What the probes report besides their candidates.
#[derive(Default)]
pub(crate) struct Findings {
    pub candidates: Vec<Candidate>,
    /// `(key, rejection)`: the key is the candidate's (a periodic effect's carries its frequency).
    pub rejected: Vec<(String, RejectedEffect)>,
    pub ambiguous: Vec<Ambiguity>,
}

impl Findings {
    /// The effect could not be tested, or has no signature: say why.
    pub fn reject(&mut self, name: &str, reason: String) {
        self.reject_as(name, name, reason);
    }

    /// The same under another key.
    pub fn reject_as(&mut self, key: &str, name: &str, reason: String) {
        self.rejected.push((
            key.to_string(),
            RejectedEffect {
                name: name.to_string(),
                reason,
                params: BTreeMap::new(),
            },
        ));
    }

    /// The effect cannot be told from another explanation with these data.
    pub fn ambiguous(&mut self, name: &str, confused_with: &str, reason: String) {
        self.ambiguous.push(Ambiguity {
            name: name.into(),
            confused_with: confused_with.into(),
            reason,
        });
    }
}

/// How the model's speed behaves, with a dead band for noise around zero: fractions of the
/// samples above `band`, below `-band`, and within it (at rest).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Motion {
    pub pos: f64,
    pub neg: f64,
    pub rest: f64,
    pub band: f64,
}

impl Motion {
    pub fn of(y: &[f64], band: f64) -> Self {
        let n = y.len().max(1) as f64;
        let pos = y.iter().filter(|v| **v > band).count() as f64 / n;
        let neg = y.iter().filter(|v| **v < -band).count() as f64 / n;
        Motion {
            pos,
            neg,
            rest: 1.0 - pos - neg,
            band,
        }
    }

    /// Both signs in at least 2% of the samples each.
    pub fn reverses(&self) -> bool {
        self.pos.min(self.neg) >= 0.02
    }

    /// A text such as "+61% / -35% / at rest 4% (band +-0.03)".
    pub fn describe(&self) -> String {
        format!(
            "+{:.0}% / -{:.0}% / at rest {:.0}% of the samples (noise band +-{:.2e})",
            100.0 * self.pos,
            100.0 * self.neg,
            100.0 * self.rest,
            self.band
        )
    }
}

/// The noise level of a record from its first differences: `1.4826 MAD(diff y) / sqrt 2` (the
/// signal's own change between samples is small against the noise at a realistic sampling rate;
/// a robust scale ignores the jumps).
pub(crate) fn noise_level(y: &[f64]) -> f64 {
    let d: Vec<f64> = y.windows(2).map(|w| w[1] - w[0]).collect();
    robust_scale(&d) / std::f64::consts::SQRT_2
}

/// A robust scale of `x`: `1.4826 MAD(x)` (the standard deviation of normal samples; a few large
/// values, such as a missing effect's spikes, do not move it). Of the current model's residual, a
/// second measure of the noise beside [`noise_level`]'s: each is too large in its own case (the
/// first differences of a record sampled near its time constant carry the signal's own steps:
/// the zoo's friction case 0186 (seed 44), a PRBS at 0.4 of its time constant, gave 4.97 against
/// its noise's 0.86, and every sample of its speed looked at rest; a residual carries what the
/// model misses), so the smaller stands.
pub(crate) fn robust_scale(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let med = median(&mut x.to_vec());
    1.4826 * median(&mut x.iter().map(|v| (v - med).abs()).collect())
}

/// The sign with a dead band: 0 within `+-band`.
pub(crate) fn sign_band(x: f64, band: f64) -> f64 {
    if x > band {
        1.0
    } else if x < -band {
        -1.0
    } else {
        0.0
    }
}

/// What a probe sees: the record, the current model and its residual on the estimation part.
pub(crate) struct Look<'a> {
    pub ctx: &'a Ctx<'a>,
    pub st: &'a State,
    pub kept: &'a [KeptEffect],
    /// Estimation residual (deviation scale).
    pub e: Vec<f64>,
    /// Its sum of squares.
    pub ee: f64,
    /// Its tests ([`analyse`]), made once per round for every probe (and the report).
    pub analysis: ResidualAnalysis,
    /// The current model's output sensitivities on the estimation part, factored once for the
    /// projections of every probe's signatures ([`explained_in`]).
    pub sens: Projection,
    /// Model output, absolute scale, whole record.
    pub ya: Vec<f64>,
    /// Input, absolute scale, whole record.
    pub ua: Vec<f64>,
    /// Noise level of the measured output: the smaller of [`noise_level`] and the residual's
    /// [`robust_scale`].
    pub noise: f64,
    /// The model speed's signs, with a band of three noise levels.
    pub motion: Motion,
    /// The input's best two-sided clips ([`off_centre::clips`]), found once for the clamp's and
    /// the dead band's probes.
    clips: std::cell::OnceCell<[Option<off_centre::Clip>; 2]>,
}

impl<'a> Look<'a> {
    pub fn new(ctx: &'a Ctx<'a>, st: &'a State, kept: &'a [KeptEffect]) -> Result<Self> {
        let s = ctx.split;
        let e: Vec<f64> = (0..s).map(|k| ctx.y[k] - st.yhat[k]).collect();
        let ee = e.iter().map(|v| v * v).sum();
        let analysis = analyse(&e, &ctx.u[..s], ctx.dt);
        let (_, sens) = sensitivities(
            &st.model,
            &st.values,
            &ctx.u[..s],
            ctx.dt,
            ctx.opts.fit.lm.par,
        )?;
        let ya: Vec<f64> = st.yhat.iter().map(|v| v + ctx.y0).collect();
        let ua: Vec<f64> = ctx.u.iter().map(|v| v + ctx.u0).collect();
        let noise = noise_level(&ctx.rec.y).min(robust_scale(&e));
        let motion = Motion::of(&ya, 3.0 * noise);
        Ok(Look {
            ctx,
            st,
            kept,
            e,
            ee,
            analysis,
            sens: Projection::of(&sens),
            ya,
            ua,
            noise,
            motion,
            clips: std::cell::OnceCell::new(),
        })
    }

    /// The input's best two-sided clip with a positive coefficient (a clamp, `[0]`) and with a
    /// negative one (a dead band, `[1]`), off the centre ([`off_centre::clips`]).
    pub(crate) fn clips(&self) -> [Option<off_centre::Clip>; 2] {
        *self.clips.get_or_init(|| off_centre::clips(self))
    }

    /// Estimation samples.
    pub fn s(&self) -> usize {
        self.ctx.split
    }

    /// Whether the current model has a parameter of that name.
    pub fn has(&self, name: &str) -> bool {
        self.st.model.index_of(name).is_some()
    }

    /// Whether an effect of that name was kept in an earlier round.
    pub fn kept(&self, name: &str) -> bool {
        self.kept.iter().any(|k| k.name == name)
    }

    /// The linear part of the current model driven by `x` (whole record, deviation scale), then
    /// the evidence of that signature: `(R^2, beta)` of [`explained_in`] on the estimation part.
    pub fn through_model(&self, x: &[f64]) -> Option<(f64, Vec<f64>)> {
        let g = self.ctx.lin(self.st, x)?;
        Some(explained_in(&self.e, &[g[..self.s()].to_vec()], &self.sens))
    }

    /// The evidence of output-side signature columns (estimation part).
    pub fn direct(&self, cols: &[Vec<f64>]) -> (f64, Vec<f64>) {
        explained_in(&self.e, cols, &self.sens)
    }
}

/// One effect of the library.
pub(crate) trait Probe {
    /// Report name (docs/design.md §6 table).
    fn name(&self) -> &'static str;
    /// Test the signature on the current residual; propose candidates, or say why not.
    ///
    /// # Errors
    /// Simulation errors of the current model.
    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()>;
    /// The effect's fitted parameters in a model that has it.
    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64>;
    /// Another model that takes the place of `kept`, the round's kept refit with this effect of
    /// the current model `before`, and the effect's rejection: a delay's lag
    /// ([`super::lag::in_place`]). Default: none.
    fn in_place_of(
        &self,
        ctx: &Ctx<'_>,
        before: &State,
        kept: &State,
    ) -> Option<(State, RejectedEffect)> {
        let _ = (ctx, before, kept);
        None
    }
}

/// The effect library, in the order the probes run.
pub(crate) fn library() -> Vec<Box<dyn Probe>> {
    vec![
        Box::new(delay::Delay),
        Box::new(skew::Skew),
        Box::new(friction::Friction),
        Box::new(input_offset::InputOffset),
        Box::new(initial_state::InitialState),
        Box::new(output_offset::OutputOffset),
        Box::new(output_drift::OutputDrift),
        Box::new(periodic::Periodic),
        Box::new(abs_sensor::AbsSensor),
        Box::new(saturation::Saturation),
        Box::new(deadzone::Deadzone),
        Box::new(power_law::PowerLaw),
    ]
}

/// Named parameter values of a model, those that exist.
pub(crate) fn named(
    model: &FracModel,
    values: &[f64],
    names: &[(&str, &str)],
) -> BTreeMap<String, f64> {
    names
        .iter()
        .filter_map(|(report, name)| {
            model
                .index_of(name)
                .map(|i| (report.to_string(), values[i]))
        })
        .collect()
}

/// A static input map `u -> map(u, g)` with one parameter `g` (a saturation's level, a dead
/// band's half width, a power law's exponent).
pub(crate) struct StaticMap {
    /// Report name.
    pub name: &'static str,
    /// Parameter name in the model.
    pub param: &'static str,
    /// What the parameter is, in words.
    pub what: &'static str,
    /// Values of the parameter searched: thresholds as fractions of the largest input magnitude
    /// (`scaled`), else the values themselves (exponents).
    pub grid: Vec<f64>,
    /// Whether the grid is in fractions of the largest input magnitude.
    pub scaled: bool,
    /// The range the refit keeps the parameter in.
    pub bounds: Bounds,
    /// The map of the absolute input `v` at `g`, given the largest input magnitude `umax`.
    pub map: fn(v: f64, g: f64, umax: f64) -> f64,
    /// The effect with its parameter index, given the largest input magnitude.
    pub effect: fn(usize, f64) -> Effect,
}

/// Probe a static input map: ambiguous with a gain and an offset for a two-level input;
/// otherwise the signature `G (map(u, g) - u)` over the grid of `g`, regressed with the model's
/// sensitivities, the coefficient positive (the effect enters with coefficient 1); the best
/// value starts the refit.
pub(crate) fn probe_static_map(look: &Look<'_>, found: &mut Findings, sm: &StaticMap) {
    if look.has(sm.param) {
        return;
    }
    let (levels, umax) = input_levels(&look.ua);
    if let Some(why) = affine_levels(&levels) {
        found.ambiguous(
            sm.name,
            "gain and offset",
            format!(
                "{why}, so a {} cannot be identified; a multi-level input separates them",
                sm.name
            ),
        );
        return;
    }
    let s = look.s();
    let mut best: Option<(f64, f64, f64)> = None;
    let scale = if sm.scaled { umax } else { 1.0 };
    for g in sm.grid.iter().map(|f| f * scale) {
        let d: Vec<f64> = look.ua.iter().map(|&v| (sm.map)(v, g, umax) - v).collect();
        if d[..s].iter().all(|v| *v == 0.0) {
            continue;
        }
        if let Some((r2, beta)) = look.through_model(&d) {
            if beta[0] > 0.0 && best.is_none_or(|b| r2 > b.0) {
                best = Some((r2, g, beta[0]));
            }
        }
    }
    let Some((r2, l, coef)) = best else {
        return;
    };
    let mut m = look.st.model.clone();
    let i = m.add_param(Param::new(sm.param, l, sm.bounds));
    m.effects.insert(0, (sm.effect)(i, umax));
    found.candidates.push(Candidate {
        lead: None,
        name: sm.name,
        key: sm.name.into(),
        r2,
        evidence: format!(
            "the {} signature at the grid value {} = {l:.3e} (grid over {} values, linear parameters refitted) \
             explains {:.1}% of the residual sum of squares (coefficient {coef:.2})",
            sm.name,
            sm.what,
            sm.grid.len(),
            100.0 * r2
        ),
        starts: vec![m],
    });
}

/// The distinct levels of the input (to within 1e-9 of its range), ascending, and its largest
/// magnitude.
pub(crate) fn input_levels(ua: &[f64]) -> (Vec<f64>, f64) {
    let mut lv: Vec<f64> = ua.to_vec();
    lv.sort_by(f64::total_cmp);
    let range = lv[lv.len() - 1] - lv[0];
    lv.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * range.max(1e-300));
    (lv, ua.iter().fold(0.0f64, |m, v| m.max(v.abs())))
}

/// Why every odd static map of the input `levels` (ascending, [`input_levels`]) is affine on
/// them, a gain and an offset the model already has, or `None` when the levels separate it: two
/// levels or fewer (any map through two points), or one magnitude besides zero (`-a, 0, a`: an
/// odd map, `f(-v) = -f(v)` as the dead band, the saturation and the power law are, is a gain
/// there).
pub(crate) fn affine_levels(levels: &[f64]) -> Option<String> {
    if levels.len() <= 2 {
        return Some(format!(
            "the input takes {} levels: any static input map is then affine (a gain and an offset)",
            levels.len()
        ));
    }
    let range = levels[levels.len() - 1] - levels[0];
    let tol = 1e-9 * range.max(1e-300);
    let mut mags: Vec<f64> = levels
        .iter()
        .map(|v| v.abs())
        .filter(|m| *m > tol)
        .collect();
    mags.sort_by(f64::total_cmp);
    mags.dedup_by(|a, b| (*a - *b).abs() <= tol);
    (mags.len() <= 1).then(|| {
        format!(
            "the input takes the levels -{a:.4e}, 0 and +{a:.4e}: an odd static input map (one \
             that turns -u into minus its value at u) is then a gain",
            a = mags.first().copied().unwrap_or(0.0)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two levels, or one magnitude about zero, give every odd map as a gain and an offset; a
    /// third magnitude, or a level on one side only, separates a map from a gain.
    #[test]
    fn odd_maps_are_affine_on_two_levels_and_on_one_magnitude_about_zero() {
        let levels = |u: &[f64]| input_levels(u).0;
        assert!(affine_levels(&levels(&[0.0, 2.0, 2.0, 0.0])).is_some());
        assert!(affine_levels(&levels(&[-1.5, 1.5, 1.5])).is_some());
        let sym = affine_levels(&levels(&[0.0, 1.102, -1.102, 0.0, 1.102]));
        assert!(sym.is_some_and(|w| w.contains("a gain")));
        assert!(affine_levels(&levels(&[0.0, 1.0, 2.0])).is_none());
        assert!(affine_levels(&levels(&[-1.0, 1.0, 2.0])).is_none());
        assert!(affine_levels(&levels(&[-2.0, -1.0, 0.0, 1.0, 2.0])).is_none());
        // a dead band of half width 0.5 on -a, 0, a is the gain (a - 0.5)/a there
        let dz = |v: f64| v.signum() * (v.abs() - 0.5).max(0.0);
        let a = 1.102;
        let g = dz(a) / a;
        assert!([-a, 0.0, a].iter().all(|&v| (dz(v) - g * v).abs() < 1e-15));
    }

    /// The robust scale of normal samples is their standard deviation, and a few large values do
    /// not move it; the noise level of a fast signal's first differences carries the signal's
    /// steps, its residual's scale does not.
    #[test]
    fn the_noise_is_the_residuals_scale_where_the_signal_steps_between_samples() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let normal = Normal::new(0.0, 0.5).unwrap();
        let mut noise: Vec<f64> = (0..4000).map(|_| normal.sample(&mut rng)).collect();
        let scale = robust_scale(&noise);
        assert!((scale - 0.5).abs() < 0.03, "{scale}");
        for k in (0..4000).step_by(100) {
            noise[k] += 40.0;
        }
        let spiked = robust_scale(&noise);
        assert!((spiked - scale).abs() < 0.05 * scale, "{spiked} vs {scale}");
        // a sine of amplitude 10 and 8 samples a period, with that noise: the first differences
        // see its steps, the residual of the sine does not
        let y: Vec<f64> = noise
            .iter()
            .enumerate()
            .map(|(k, e)| 10.0 * (std::f64::consts::TAU * k as f64 / 8.0).sin() + e)
            .collect();
        assert!(noise_level(&y) > 4.0 * 0.5, "{}", noise_level(&y));
        assert!(robust_scale(&noise) < 1.2 * 0.5);
    }
}
