//! The answer of a report: the model a report leads with and its verdict, found by one rule for
//! every reader (`fracid tune`, `compare`, `export`, the fleet's summary row, Python's results).
//!
//! A `fracid time` report leads with its top-level `model` (the diagnosis's final model with
//! `--diagnose`, which `diagnosis.model` repeats); a `fracid freq` report with the diagnosed model
//! when it was diagnosed, else `best_model` (the best by `J` among Levy's fit, the
//! Sanathanan-Koerner fit and the refit, [`crate::levy::FreqFit::best_model`]): its top-level
//! `model` is Levy's, kept for the scripts that read Levy's fit. A bare model object
//! `{"num", "den", "delay"}` is its own answer. The verdict (`usable`, `problems`) is the
//! report's own, computed on that model ([`super::verdict`]).

use serde_json::Value;

/// Where a report keeps the model it leads with, the first found first: the diagnosed model, the
/// best of a frequency-domain fit, the top-level model.
pub const LEAD_MODEL: [&str; 3] = ["/diagnosis/model", "/best_model", "/model"];

/// The model a report leads with, where it was found, and its verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer<'a> {
    /// The model object (`{"num", "den", "delay", "text"}`).
    pub model: &'a Value,
    /// Its JSON pointer in the report (`""` for a bare model).
    pub pointer: &'static str,
    /// Whether it can be used (`true` for a bare model, which carries no verdict).
    pub usable: bool,
    /// Why not.
    pub problems: Vec<String>,
}

/// The answer of `report` (a `fracid time` or `fracid freq` JSON report, or a bare model).
///
/// ```
/// let m = |k: f64| serde_json::json!({"num": [{"coef": k, "order": 0.0}],
///                                     "den": [{"coef": 1.0, "order": 0.0}]});
/// let freq = serde_json::json!({"model": m(1.0), "best_model": m(2.0), "usable": true,
///                               "problems": []});
/// let a = ident::app::answer::of_report(&freq);
/// assert_eq!((a.model, a.pointer, a.usable), (&m(2.0), "/best_model", true));
/// ```
pub fn of_report(report: &Value) -> Answer<'_> {
    let found = LEAD_MODEL.iter().find_map(|p| {
        report
            .pointer(p)
            .filter(|m| m.get("den").is_some())
            .map(|m| (m, *p))
    });
    let Some((model, pointer)) = found else {
        return Answer {
            model: report,
            pointer: "",
            usable: true,
            problems: vec![],
        };
    };
    let problems: Vec<String> = report
        .get("problems")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .map(|p| p.as_str().map_or_else(|| p.to_string(), String::from))
                .collect()
        })
        .unwrap_or_default();
    let usable = report
        .get("usable")
        .and_then(Value::as_bool)
        .unwrap_or(problems.is_empty());
    Answer {
        model,
        pointer,
        usable: usable && problems.is_empty(),
        problems,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn m(k: f64) -> Value {
        json!({"num": [{"coef": k, "order": 0.0}], "den": [{"coef": 1.0, "order": 0.0}]})
    }

    #[test]
    fn the_diagnosed_model_then_the_best_then_the_top_level_one() {
        let dc = |v: &Value| of_report(v).model["num"][0]["coef"].as_f64().unwrap();
        assert_eq!(dc(&json!({"model": m(1.0)})), 1.0);
        // a refit worse than Levy's by J is not the answer: the best is
        let r = json!({"model": m(1.0), "refined": {"model": m(2.0)}, "best_model": m(3.0)});
        assert_eq!(dc(&r), 3.0);
        let d = json!({"model": m(1.0), "best_model": m(3.0), "diagnosis": {"model": m(4.0)}});
        assert_eq!(dc(&d), 4.0);
        assert_eq!(dc(&m(5.0)), 5.0);
        assert_eq!(of_report(&m(5.0)).pointer, "");
    }

    #[test]
    fn the_verdict_is_the_reports_own() {
        let mut r = json!({"model": m(1.0), "usable": false, "problems": ["unstable"]});
        let a = of_report(&r);
        assert_eq!(
            (a.usable, a.problems),
            (false, vec!["unstable".to_string()])
        );
        r["usable"] = json!(true);
        r["problems"] = json!([]);
        assert!(of_report(&r).usable);
    }
}
