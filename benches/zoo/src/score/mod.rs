//! The scoreboard of one case on one path (plain or diagnosed): fracid's exit code, the effects it
//! kept against the hidden ones, the recommended model's frequency-response error against the
//! truth over the excited band, its held-out error against the oracle's, its time, and whether the
//! answer is right.
//!
//! Definitions:
//! - FRF error: `sqrt(mean_w |G_fit(jw) - G_true(jw)|^2 / |G_true(jw)|^2)` over the band's
//!   frequencies (`cases::band`); with a sign-blind sensor the sign of `G_fit` that fits better;
//!   with a power-law input map in the truth and the diagnosis, `G_fit` in the truth's convention
//!   (the map through 1 at `|u| = 1`, see [`power_law_scale`]).
//! - Held-out ratio: fracid's held-out RMSE (the report's `fit.validation.rmse`) over the oracle's,
//!   the RMS of (measured - noise-free truth) on the same samples (`validated_by.blocks` when the
//!   record was held out in blocks, else `validated_by.first`,
//!   `split.validation_samples`). 1 is the noise floor.
//! - Effects kept: the diagnosis's effects, the model's effects and `delay` when the model has one;
//!   `output_offset` (always fitted) is not counted. Spurious: kept, neither expected nor tolerated;
//!   missed: expected, not kept (`cases::rules`).
//! - Right answer: on an identifiable case, exit 0 with an FRF error <= `FRF_OK`; on a case that is
//!   not identifiable, a non-zero exit, or a confounded effect named among the diagnosis's
//!   ambiguous ones and none of them kept.

pub mod floors;
pub mod table;

use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::cases::{Class, Truth};
use crate::truth::Term;

/// The FRF error at or below which a model is right (20%).
pub const FRF_OK: f64 = 0.2;

/// Which command made the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Path {
    /// `fracid time DIR` with the defaults.
    Plain,
    /// `fracid time DIR --diagnose`.
    Diagnose,
}

impl Path {
    /// Both, in table order.
    pub const BOTH: [Path; 2] = [Path::Plain, Path::Diagnose];
    /// The name in files and tables.
    pub fn name(self) -> &'static str {
        match self {
            Path::Plain => "plain",
            Path::Diagnose => "diagnose",
        }
    }
}

/// A fitted model: `sum num / sum den * exp(-delay s)`, as the report's `model` holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fitted {
    /// Numerator terms.
    pub num: Vec<Term>,
    /// Denominator terms.
    pub den: Vec<Term>,
    /// Input delay [s].
    pub delay: f64,
}

fn poly_at(p: &[Term], omega: f64) -> Complex64 {
    p.iter()
        .map(|t| {
            // (j w)^q = w^q e^(j q pi/2)
            Complex64::from_polar(
                t.coef * omega.powf(t.order),
                t.order * std::f64::consts::FRAC_PI_2,
            )
        })
        .sum()
}

impl Fitted {
    /// The frequency response at `omega` [rad/s].
    pub fn response(&self, omega: f64) -> Complex64 {
        poly_at(&self.num, omega) / poly_at(&self.den, omega)
            * Complex64::from_polar(1.0, -omega * self.delay)
    }

    /// The model of a report (`model.num`, `model.den`, `model.delay`).
    pub fn from_report(report: &Value) -> Option<Fitted> {
        let model = report.get("model")?;
        let terms = |key: &str| -> Option<Vec<Term>> {
            model
                .get(key)?
                .as_array()?
                .iter()
                .map(|t| {
                    Some(Term {
                        coef: t.get("coef")?.as_f64()?,
                        order: t.get("order")?.as_f64()?,
                    })
                })
                .collect()
        };
        Some(Fitted {
            num: terms("num")?,
            den: terms("den")?,
            delay: model.get("delay").and_then(Value::as_f64).unwrap_or(0.0),
        })
    }
}

/// The factor that puts a report's linear part in the convention of a truth with a power-law
/// input map: fracid's map `sign(u) u_ref (|u| / u_ref)^p` is the truth's `sign(u) |u|^p` times
/// `u_ref^(1 - p)`, so the same input-output model has its numerator that much larger (1 without
/// a power law in the diagnosis). A truth without the map has no convention to meet: its model is
/// compared as reported.
fn power_law_scale(report: &Value) -> f64 {
    let params = report
        .pointer("/diagnosis/effects")
        .and_then(Value::as_array)
        .and_then(|a| {
            a.iter()
                .find(|e| e.get("name").and_then(Value::as_str) == Some("power_law"))
        })
        .and_then(|e| e.get("params"));
    let get = |key: &str| params.and_then(|p| p.get(key)).and_then(Value::as_f64);
    match (get("exponent"), get("u_ref")) {
        (Some(p), Some(u_ref)) if u_ref > 0.0 && p.is_finite() => u_ref.powf(1.0 - p),
        _ => 1.0,
    }
}

/// The FRF error of `fitted` against `truth` over `band` [rad/s] (None for an empty band or a
/// response that is not finite); `sign_blind`: the better of `+-G_fit`.
pub fn frf_error(
    truth: &crate::truth::Plant,
    fitted: &Fitted,
    band: &[f64],
    sign_blind: bool,
) -> Option<f64> {
    if band.is_empty() {
        return None;
    }
    let rms = |sign: f64| {
        let sum: f64 = band
            .iter()
            .map(|&w| {
                let g = truth.response(w);
                ((fitted.response(w) * sign - g) / g).norm_sqr()
            })
            .sum();
        (sum / band.len() as f64).sqrt()
    };
    let e = if sign_blind {
        rms(1.0).min(rms(-1.0))
    } else {
        rms(1.0)
    };
    e.is_finite().then_some(e)
}

/// One row of fracid's fleet summary.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The process's exit code for this file.
    pub exit_code: i32,
    /// The fit's time [s] (the summary's `seconds`: one file on one thread).
    pub seconds: Option<f64>,
    /// The error, when the file failed.
    pub error: Option<String>,
}

/// The score of one case on one path.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The case.
    pub name: String,
    /// Its class.
    pub class: Class,
    /// The path.
    pub path: Path,
    /// Whether the case is identifiable.
    pub identifiable: bool,
    /// fracid's exit code (None: no row for the file).
    pub exit_code: Option<i32>,
    /// Effects kept.
    pub kept: Vec<String>,
    /// Kept, neither expected nor tolerated.
    pub spurious: Vec<String>,
    /// Expected, not kept.
    pub missed: Vec<String>,
    /// Confounded effects named among the ambiguous ones.
    pub named_ambiguous: Vec<String>,
    /// FRF error over the band.
    pub frf_error: Option<f64>,
    /// fracid's held-out RMSE.
    pub heldout_rmse: Option<f64>,
    /// The oracle's RMSE on the same samples.
    pub oracle_rmse: Option<f64>,
    /// The fit's time [s].
    pub seconds: Option<f64>,
    /// The model's text.
    pub model: Option<String>,
    /// Whether the answer is right.
    pub right: bool,
}

impl Outcome {
    /// Whether the kept effects are exactly the expected ones (tolerated aside).
    pub fn effects_exact(&self) -> bool {
        self.spurious.is_empty() && self.missed.is_empty()
    }
    /// fracid's held-out RMSE over the oracle's.
    pub fn heldout_ratio(&self) -> Option<f64> {
        match (self.heldout_rmse, self.oracle_rmse) {
            (Some(a), Some(b)) if b > 0.0 => Some(a / b),
            _ => None,
        }
    }
}

fn names(v: Option<&Value>) -> Vec<String> {
    v.and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|x| x.get("name").and_then(Value::as_str).or_else(|| x.as_str()))
                .map(str::to_string)
                .collect()
        })
        .unwrap_or_default()
}

/// The effects a report kept (see the module's definitions).
pub fn kept_effects(report: &Value) -> Vec<String> {
    let mut kept = names(report.pointer("/diagnosis/effects"));
    kept.extend(names(report.pointer("/model/effects")));
    if report
        .pointer("/model/delay")
        .and_then(Value::as_f64)
        .unwrap_or(0.0)
        > 0.0
    {
        kept.push("delay".into());
    }
    kept.retain(|k| k != "output_offset");
    kept.sort();
    kept.dedup();
    kept
}

/// The RMS of `y - y_clean` over `first..first + count`.
fn oracle(y: &[f64], y_clean: &[f64], first: usize, count: usize) -> Option<f64> {
    let end = first.checked_add(count)?;
    oracle_on(y, y_clean, &[(first, end)])
}

/// [`oracle`] on the held-out blocks `start..end` (`validated_by.blocks` of a record held out
/// in blocks spread over it, a sweep).
fn oracle_on(y: &[f64], y_clean: &[f64], blocks: &[(usize, usize)]) -> Option<f64> {
    let n = y.len().min(y_clean.len());
    let (mut ss, mut count) = (0.0, 0usize);
    for &(a, b) in blocks {
        let b = b.min(n);
        for k in a.min(b)..b {
            ss += (y[k] - y_clean[k]).powi(2);
            count += 1;
        }
    }
    (count > 0).then(|| (ss / count as f64).sqrt())
}

/// The held-out blocks a report names (`validated_by.blocks`, pairs `[start, end]`); `None`
/// when it names none (the held-out part is the tail).
fn held_blocks(report: &Value) -> Option<Vec<(usize, usize)>> {
    let blocks = report.pointer("/validated_by/blocks")?.as_array()?;
    let pair = |b: &Value| {
        let (a, e) = (b.get(0)?.as_u64()?, b.get(1)?.as_u64()?);
        Some((a as usize, e as usize))
    };
    blocks.iter().map(pair).collect()
}

/// Scores one case on one path: `row` from the fleet summary (None: fracid wrote none), `report`
/// the per-file report (None: none written).
pub fn score(
    truth: &Truth,
    y: &[f64],
    y_clean: &[f64],
    path: Path,
    row: Option<&Row>,
    report: Option<&Value>,
) -> Outcome {
    let v = &truth.verdict;
    let kept = report.map(kept_effects).unwrap_or_default();
    let spurious: Vec<String> = kept
        .iter()
        .filter(|k| !v.expected_effects.contains(k) && !v.tolerated_effects.contains(k))
        .cloned()
        .collect();
    let missed: Vec<String> = v
        .expected_effects
        .iter()
        .filter(|e| !kept.contains(e))
        .cloned()
        .collect();
    let ambiguous = report
        .map(|r| names(r.pointer("/diagnosis/ambiguous")))
        .unwrap_or_default();
    let named_ambiguous: Vec<String> = v
        .confounded_effects
        .iter()
        .filter(|c| ambiguous.contains(c))
        .cloned()
        .collect();
    let fitted = report.and_then(Fitted::from_report).map(|mut f| {
        if truth.effects.power_law.is_some() {
            let scale = report.map_or(1.0, power_law_scale);
            f.num.iter_mut().for_each(|t| t.coef *= scale);
        }
        f
    });
    let frf = fitted
        .as_ref()
        .and_then(|f| frf_error(&truth.plant, f, &truth.band_omega, truth.effects.abs_sensor));
    let heldout_rmse = report
        .and_then(|r| r.pointer("/fit/validation/rmse"))
        .and_then(Value::as_f64);
    let first = report
        .and_then(|r| r.pointer("/validated_by/first"))
        .and_then(Value::as_u64);
    let count = report
        .and_then(|r| r.pointer("/split/validation_samples"))
        .and_then(Value::as_u64);
    let oracle_rmse = match (report.and_then(held_blocks), first, count) {
        (Some(blocks), _, _) => oracle_on(y, y_clean, &blocks),
        (None, Some(f), Some(c)) => oracle(y, y_clean, f as usize, c as usize),
        _ => None,
    };
    let exit_code = row.map(|r| r.exit_code);
    let right = if v.identifiable {
        exit_code == Some(0) && frf.is_some_and(|e| e <= FRF_OK)
    } else {
        let named =
            !named_ambiguous.is_empty() && !v.confounded_effects.iter().any(|c| kept.contains(c));
        exit_code.is_some_and(|c| c != 0) || (exit_code == Some(0) && named)
    };
    Outcome {
        name: truth.name.clone(),
        class: truth.class,
        path,
        identifiable: v.identifiable,
        exit_code,
        kept,
        spurious,
        missed,
        named_ambiguous,
        frf_error: frf,
        heldout_rmse,
        oracle_rmse,
        seconds: row.and_then(|r| r.seconds),
        model: report
            .and_then(|r| r.pointer("/model/text"))
            .and_then(Value::as_str)
            .map(str::to_string),
        right,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases::{generate, Sizing, ALL_CLASSES};
    use serde_json::json;

    fn report_of(f: &Fitted, effects: &[&str], ambiguous: &[&str]) -> Value {
        let terms = |p: &[Term]| {
            p.iter()
                .map(|t| json!({"coef": t.coef, "order": t.order}))
                .collect::<Vec<_>>()
        };
        json!({
            "model": {"num": terms(&f.num), "den": terms(&f.den), "delay": f.delay, "effects": ["output_offset"], "text": "m"},
            "diagnosis": {
                "effects": effects.iter().map(|e| json!({"name": e})).collect::<Vec<_>>(),
                "ambiguous": ambiguous.iter().map(|e| json!({"name": e, "confused_with": "x"})).collect::<Vec<_>>()
            },
            "fit": {"validation": {"rmse": 0.5}},
            "validated_by": {"first": 10},
            "split": {"validation_samples": 20}
        })
    }

    fn case_of(class: crate::cases::Class) -> crate::cases::Case {
        let i = ALL_CLASSES.iter().position(|c| *c == class).unwrap();
        generate(21, i, Sizing::CI).unwrap()
    }

    fn as_fitted(p: &crate::truth::Plant) -> Fitted {
        Fitted {
            num: p.num.clone(),
            den: p.den.clone(),
            delay: p.delay_s,
        }
    }

    #[test]
    fn the_true_model_scores_zero_and_a_wrong_one_does_not() {
        for class in [
            crate::cases::Class::Pmsm,
            crate::cases::Class::TwoMassMotor,
            crate::cases::Class::Cell,
        ] {
            let case = case_of(class);
            let t = &case.truth;
            assert!(t.band_omega.len() >= 3, "{}", t.name);
            let exact = as_fitted(&t.plant);
            // The truth's response and this module's are written apart: they agree.
            let e = frf_error(&t.plant, &exact, &t.band_omega, false).unwrap();
            assert!(e < 1e-9, "{}: {e}", t.name);
            let mut gain = exact.clone();
            gain.num.iter_mut().for_each(|x| x.coef *= 1.3);
            let e = frf_error(&t.plant, &gain, &t.band_omega, false).unwrap();
            assert!((e - 0.3).abs() < 1e-9, "{}: {e}", t.name);
            let mut late = exact.clone();
            late.delay += 0.1 / t.band_omega.last().unwrap();
            let e = frf_error(&t.plant, &late, &t.band_omega, false).unwrap();
            assert!(e > 0.01 && e < 0.1, "{}: {e}", t.name);
            // A sign-blind sensor cannot tell G from -G; otherwise -G is 200% wrong.
            let mut neg = exact.clone();
            neg.num.iter_mut().for_each(|x| x.coef = -x.coef);
            assert!(frf_error(&t.plant, &neg, &t.band_omega, true).unwrap() < 1e-9);
            assert!((frf_error(&t.plant, &neg, &t.band_omega, false).unwrap() - 2.0).abs() < 1e-9);
        }
    }

    #[test]
    fn a_power_law_gain_is_compared_in_the_truths_convention() {
        // fracid's map through u_ref: the same input-output model has the truth's numerator
        // times u_ref^(p - 1) (u^p = u_ref^(p - 1) * u_ref (u / u_ref)^p).
        let case = case_of(crate::cases::Class::PowerLaw);
        let t = &case.truth;
        let p = t.effects.power_law.unwrap();
        let u_ref = 2.5_f64;
        let mut f = as_fitted(&t.plant);
        f.num.iter_mut().for_each(|x| x.coef *= u_ref.powf(p - 1.0));
        let mut r = report_of(&f, &["power_law"], &[]);
        let ok = Row {
            exit_code: 0,
            seconds: Some(0.1),
            error: None,
        };
        let frf = |r: &Value| {
            score(
                t,
                &case.y,
                &case.y_clean,
                Path::Diagnose,
                Some(&ok),
                Some(r),
            )
            .frf_error
            .unwrap()
        };
        let e = frf(&r);
        assert!((e - (u_ref.powf(p - 1.0) - 1.0)).abs() < 1e-9, "{e}");
        r["diagnosis"]["effects"][0]["params"] = json!({"exponent": p, "u_ref": u_ref});
        let e = frf(&r);
        assert!(e < 1e-9, "{e}");
        // A truth without the map: the model as reported.
        let lead = case_of(crate::cases::Class::Lead);
        let exact = report_of(&as_fitted(&lead.truth.plant), &["power_law"], &[]);
        let mut with_params = exact.clone();
        with_params["diagnosis"]["effects"][0]["params"] = json!({"exponent": p, "u_ref": u_ref});
        let o = score(
            &lead.truth,
            &lead.y,
            &lead.y_clean,
            Path::Diagnose,
            Some(&ok),
            Some(&with_params),
        );
        assert!(o.frf_error.unwrap() < 1e-9, "{o:?}");
    }

    #[test]
    fn effects_and_right_answers_are_scored() {
        let case = case_of(crate::cases::Class::Delay);
        let t = &case.truth;
        assert_eq!(t.verdict.expected_effects, ["delay"]);
        let fitted = as_fitted(&t.plant);
        let ok = Row {
            exit_code: 0,
            seconds: Some(0.1),
            error: None,
        };
        let r = report_of(&fitted, &["delay"], &[]);
        let o = score(
            t,
            &case.y,
            &case.y_clean,
            Path::Diagnose,
            Some(&ok),
            Some(&r),
        );
        assert!(o.right && o.effects_exact(), "{o:?}");
        assert_eq!(o.kept, ["delay"]);
        let expect_oracle = (10..30)
            .map(|k| (case.y[k] - case.y_clean[k]).powi(2))
            .sum::<f64>()
            / 20.0;
        assert!((o.oracle_rmse.unwrap() - expect_oracle.sqrt()).abs() < 1e-12);
        // No delay in the model: missed; friction kept: spurious.
        let mut slow = fitted.clone();
        slow.delay = 0.0;
        let r = report_of(&slow, &["coulomb_friction"], &[]);
        let o = score(
            t,
            &case.y,
            &case.y_clean,
            Path::Diagnose,
            Some(&ok),
            Some(&r),
        );
        assert_eq!(
            (o.missed.as_slice(), o.spurious.as_slice()),
            (
                &["delay".to_string()][..],
                &["coulomb_friction".to_string()][..]
            )
        );
        // Exit 1 on an identifiable case is wrong, whatever the model.
        let failed = Row {
            exit_code: 1,
            seconds: None,
            error: Some("x".into()),
        };
        let r = report_of(&fitted, &["delay"], &[]);
        assert!(
            !score(
                t,
                &case.y,
                &case.y_clean,
                Path::Diagnose,
                Some(&failed),
                Some(&r)
            )
            .right
        );

        // Not identifiable: exit 1 is right, the ambiguity named is right, a guess kept is wrong.
        let case = case_of(crate::cases::Class::FrictionOneWay);
        let t = &case.truth;
        assert!(!t.verdict.identifiable);
        let fitted = as_fitted(&t.plant);
        let s = |row: &Row, effects: &[&str], amb: &[&str]| {
            let r = report_of(&fitted, effects, amb);
            score(
                t,
                &case.y,
                &case.y_clean,
                Path::Diagnose,
                Some(row),
                Some(&r),
            )
            .right
        };
        assert!(s(&failed, &[], &[]));
        assert!(s(&ok, &[], &["coulomb_friction"]));
        assert!(!s(&ok, &[], &[]));
        assert!(!s(&ok, &["coulomb_friction"], &["coulomb_friction"]));
    }
}
