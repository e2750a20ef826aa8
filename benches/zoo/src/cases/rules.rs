//! Whether a record can tell its hidden truth, and which of fracid's effect names a right answer
//! keeps. The rules (also in benches/README.md, "The benchmark zoo"):
//!
//! - The plant is identifiable over the band the record excites (`band`); a band narrower than
//!   half a decade (fewer than 3 bins) is not enough: the case is not identifiable.
//! - A delay of one sample or more is expected as `delay`; below one sample it is not told from the
//!   plant's phase (either answer is accepted).
//! - Coulomb friction is expected as `coulomb_friction` when the speed reverses (at least 5% of the
//!   samples beyond +-5% of its swing on each side); without a reversal `Vc sign(y)` is a constant
//!   input offset: confounded (not identifiable).
//! - A dead band, a saturation or a static power map needs an input with 3 levels or more (in
//!   magnitude): with two levels every static map is a gain and an offset: confounded. A
//!   saturation the input never reaches (fewer than 2% of the samples) is inert: keeping it is
//!   spurious.
//! - An input offset through a plant with a finite static gain is an output offset, which fracid
//!   always fits: either answer is accepted; through an integrator (a drift) it is expected.
//! - An output offset is always fitted: not scored.
//! - A sign-blind sensor is expected as `abs_sensor` when the true output reverses; else inert.
//! - A periodic disturbance is expected as `periodic` with 3 periods or more in the record, below
//!   0.4 of the sample rate and at least twice the noise's RMS in amplitude; else either answer.
//! - A slow output drift is expected as `output_drift` when it moves the output by twice the
//!   noise's RMS or more over the record; through a plant that integrates it is an input offset
//!   (either answer); keeping `input_offset` for a drift is accepted.
//! - Quantisation has no effect name in fracid: scored by the held-out error alone.
//! - `initial_state` is about the record, not the plant: never expected, never spurious.
//!
//! A case is identifiable when its band is wide enough and no hidden effect is confounded. Where it
//! is not, the right answer is exit 1, or (with `--diagnose`) the confounded effect named among the
//! ambiguous ones and not kept.

use serde::{Deserialize, Serialize};

use crate::truth::Effects;

/// The judgement of one case.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// Whether the right answer is a model (exit 0).
    pub identifiable: bool,
    /// Why (one sentence per rule that applied).
    pub reasons: Vec<String>,
    /// fracid effect names a right answer keeps.
    pub expected_effects: Vec<String>,
    /// fracid effect names a right answer may keep or not.
    pub tolerated_effects: Vec<String>,
    /// fracid effect names this record cannot tell (the right answer names them as ambiguous).
    pub confounded_effects: Vec<String>,
}

/// What the rules look at.
pub struct Facts<'a> {
    /// The hidden effects.
    pub effects: &'a Effects,
    /// The input delay [s].
    pub delay_s: f64,
    /// The sample time [s].
    pub dt: f64,
    /// The plant's static gain (None: an integrator).
    pub dc_gain: Option<f64>,
    /// The recorded input.
    pub u: &'a [f64],
    /// The plant's output before the sensor and the output effects.
    pub y_plant: &'a [f64],
    /// The noise's RMS (quantisation included).
    pub noise_rms: f64,
    /// The band's frequencies [rad/s].
    pub band: &'a [f64],
}

/// Distinct values of `x` (to a relative 1e-9), counted up to `cap`.
pub fn levels(x: impl Iterator<Item = f64>, cap: usize) -> usize {
    let mut seen: Vec<f64> = Vec::new();
    for v in x {
        if !seen.iter().any(|s| (s - v).abs() <= 1e-9 * (1.0 + v.abs())) {
            seen.push(v);
            if seen.len() >= cap {
                break;
            }
        }
    }
    seen.len()
}

/// Whether `y` takes both signs: at least 5% of the samples beyond +-5% of its swing on each side.
pub fn reverses(y: &[f64]) -> bool {
    let (lo, hi) = y
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let band = 0.05 * (hi - lo);
    let n = y.len() as f64;
    let pos = y.iter().filter(|&&v| v > band).count() as f64 / n;
    let neg = y.iter().filter(|&&v| v < -band).count() as f64 / n;
    pos >= 0.05 && neg >= 0.05
}

/// Applies the rules.
pub fn judge(f: &Facts<'_>) -> Verdict {
    let mut v = Verdict {
        identifiable: true,
        tolerated_effects: vec!["initial_state".into(), "output_offset".into()],
        ..Verdict::default()
    };
    let input_levels = levels(f.u.iter().map(|x| x.abs()), 3);
    let speed_reverses = reverses(f.y_plant);
    if f.band.len() < 3 {
        v.identifiable = false;
        v.reasons.push(format!(
            "the input excites {} bin(s) above the noise (fewer than 3, half a decade): the plant cannot be told",
            f.band.len()
        ));
    }
    if f.delay_s >= f.dt {
        expect(
            &mut v,
            "delay",
            format!("a delay of {:.2} samples", f.delay_s / f.dt),
        );
    } else if f.delay_s > 0.0 {
        tolerate(
            &mut v,
            "delay",
            format!(
                "a delay of {:.2} samples (below one: not told from the phase)",
                f.delay_s / f.dt
            ),
        );
    }
    input_maps(f, &mut v, input_levels, speed_reverses);
    output_effects(f, &mut v, speed_reverses);
    v
}

/// The rules of the effects at the input: friction and the static maps (dead band, saturation,
/// power law), which a two-level input or a speed that never reverses cannot tell apart.
fn input_maps(f: &Facts<'_>, v: &mut Verdict, input_levels: usize, speed_reverses: bool) {
    let e = f.effects;
    if e.coulomb.is_some() {
        if speed_reverses {
            expect(
                v,
                "coulomb_friction",
                "Coulomb friction with speed reversals".into(),
            );
        } else {
            confound(
                v,
                "coulomb_friction",
                "Coulomb friction without a speed reversal is a constant input offset".into(),
            );
            tolerate(v, "input_offset", String::new());
        }
    }
    let two_levels = "the input has two levels: a static map is then a gain and an offset";
    if e.deadband.is_some() {
        if input_levels >= 3 {
            expect(
                v,
                "deadzone",
                "a dead band under a multi-level input".into(),
            );
        } else {
            confound(v, "deadzone", format!("a dead band: {two_levels}"));
        }
    }
    if let Some(level) = e.saturation {
        let beyond =
            f.u.iter()
                .filter(|x| (*x + e.input_offset).abs() > level)
                .count();
        if (beyond as f64) < 0.02 * f.u.len() as f64 {
            v.reasons
                .push("a saturation the input never reaches: inert".into());
        } else if input_levels >= 3 {
            expect(
                v,
                "saturation",
                "a saturation reached by a multi-level input".into(),
            );
        } else {
            confound(v, "saturation", format!("a saturation: {two_levels}"));
        }
    }
    if e.power_law.is_some() {
        if input_levels >= 3 {
            expect(
                v,
                "power_law",
                "a static power map under a multi-level input".into(),
            );
        } else {
            confound(v, "power_law", format!("a static power map: {two_levels}"));
        }
    }
}

/// The rules of the offsets, the sensor, a periodic disturbance and a drift.
fn output_effects(f: &Facts<'_>, v: &mut Verdict, speed_reverses: bool) {
    let e = f.effects;
    if e.input_offset != 0.0 {
        if f.dc_gain.is_none() {
            expect(
                v,
                "input_offset",
                "an input offset through an integrator (a drift)".into(),
            );
        } else {
            tolerate(
                v,
                "input_offset",
                "an input offset through a finite static gain is an output offset".into(),
            );
        }
    }
    if e.abs_sensor {
        if speed_reverses {
            expect(
                v,
                "abs_sensor",
                "a sign-blind sensor on an output that reverses".into(),
            );
        } else {
            v.reasons
                .push("a sign-blind sensor on an output that keeps one sign: inert".into());
        }
    }
    if let Some((amplitude, freq_hz)) = e.periodic {
        let periods = freq_hz * f.u.len() as f64 * f.dt;
        if periods >= 3.0 && freq_hz < 0.4 / f.dt && amplitude >= 2.0 * f.noise_rms {
            expect(
                v,
                "periodic",
                format!("a periodic disturbance at {freq_hz:.3e} Hz, {periods:.0} periods"),
            );
        } else {
            tolerate(v, "periodic", format!("a periodic disturbance at {freq_hz:.3e} Hz too weak or too few periods to require"));
        }
    }
    if e.drift_per_s != 0.0 {
        let swing = (e.drift_per_s * f.u.len() as f64 * f.dt).abs();
        let why = format!("a slow output drift of {swing:.3e} over the record");
        if f.dc_gain.is_none() {
            tolerate(
                v,
                "output_drift",
                format!("{why}, through a plant that integrates: an input offset"),
            );
        } else if swing >= 2.0 * f.noise_rms {
            expect(v, "output_drift", why);
        } else {
            tolerate(v, "output_drift", format!("{why}, within the noise"));
        }
        tolerate(v, "input_offset", String::new());
    }
}

fn expect(v: &mut Verdict, name: &str, why: String) {
    v.expected_effects.push(name.into());
    v.reasons.push(format!("{why}: expected as {name}"));
}

fn tolerate(v: &mut Verdict, name: &str, why: String) {
    if !v.tolerated_effects.iter().any(|t| t == name) {
        v.tolerated_effects.push(name.into());
    }
    if !why.is_empty() {
        v.reasons.push(format!("{why}: {name} kept or not"));
    }
}

fn confound(v: &mut Verdict, name: &str, why: String) {
    v.identifiable = false;
    v.confounded_effects.push(name.into());
    v.reasons.push(format!(
        "{why}: {name} cannot be identified from this record"
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn facts<'a>(effects: &'a Effects, u: &'a [f64], y: &'a [f64], band: &'a [f64]) -> Facts<'a> {
        Facts {
            effects,
            delay_s: 0.0,
            dt: 1e-3,
            dc_gain: Some(1.0),
            u,
            y_plant: y,
            noise_rms: 0.01,
            band,
        }
    }

    #[test]
    fn friction_needs_a_reversal_and_static_maps_three_levels() {
        let band = [1.0, 2.0, 3.0, 4.0];
        let friction = Effects {
            coulomb: Some(0.1),
            ..Effects::default()
        };
        let u: Vec<f64> = (0..100)
            .map(|k| if k % 20 < 10 { 1.0 } else { -1.0 })
            .collect();
        let both: Vec<f64> = u.iter().map(|x| 3.0 * x).collect();
        let v = judge(&facts(&friction, &u, &both, &band));
        assert!(v.identifiable);
        assert_eq!(v.expected_effects, ["coulomb_friction"]);
        let one_way: Vec<f64> = u.iter().map(|x| 3.0 + x).collect();
        let v = judge(&facts(&friction, &u, &one_way, &band));
        assert!(!v.identifiable);
        assert_eq!(v.confounded_effects, ["coulomb_friction"]);

        let sat = Effects {
            saturation: Some(0.5),
            ..Effects::default()
        };
        let v = judge(&facts(&sat, &u, &both, &band));
        assert_eq!((v.identifiable, v.confounded_effects.len()), (false, 1));
        let three: Vec<f64> = (0..99).map(|k| [0.0, 0.4, 1.0][k % 3]).collect();
        let v = judge(&facts(&sat, &three, &both, &band));
        assert!(v.identifiable);
        assert_eq!(v.expected_effects, ["saturation"]);
        let low: Vec<f64> = three.iter().map(|x| 0.4 * x).collect();
        let v = judge(&facts(&sat, &low, &both, &band));
        assert!(v.identifiable && v.expected_effects.is_empty(), "{v:?}");
    }

    #[test]
    fn a_narrow_band_is_not_identifiable() {
        let none = Effects::default();
        let u = [0.0, 1.0, 1.0];
        let v = judge(&facts(&none, &u, &u, &[1.0, 2.0]));
        assert!(!v.identifiable && v.confounded_effects.is_empty());
    }
}
