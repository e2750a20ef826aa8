//! A model named on the command line, read one way for every command that takes one
//! (`compare`, `export`, `tune`, the demo): a transfer function's text (`exp(-tau s)` and products
//! `F1 * F2` allowed), a file holding that text, or the JSON report of `fracid time` /
//! `fracid freq`, whose answer is taken: the model the report leads with, by the library's one
//! rule (`ident::app::answer`: `diagnosis.model`, else `best_model`, else `model`; docs/design.md
//! §7). A bare `{"num", "den", "delay"}` object is a model too.

use crate::bad_input;
use anyhow::{Context, Result};
use fracsim::{FracTf, Term};
use ident::app::ModelReport;
use serde_json::Value;
use std::path::Path;

/// A model argument read: the transfer function, and the report it came from (a JSON file).
#[derive(Debug)]
pub struct Loaded {
    /// The final model.
    pub tf: FracTf,
    /// The whole JSON report, when the argument was one.
    pub report: Option<Value>,
}

/// Read `arg`: an existing file (JSON by its content, else the text of a model) or a model's
/// text; a `.json` name that does not exist is an I/O error.
///
/// # Errors
/// Bad input for text that is not a model, JSON that is not a report or model, a model that
/// [`FracTf::new`] refuses; I/O errors reading the file.
pub fn load(arg: &str) -> Result<Loaded> {
    let path = Path::new(arg);
    if !path.exists() {
        let tf = match arg.parse::<FracTf>() {
            Ok(tf) => tf,
            // a file's name that is missing is an I/O error, not a model written wrong
            Err(_)
                if path
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("json")) =>
            {
                return Err(crate::cmd::read_text(path)
                    .err()
                    .unwrap_or_else(|| anyhow::anyhow!("{arg} appeared while it was read")));
            }
            Err(e) => bad_input!("{arg:?} is neither a model nor an existing file: {e}"),
        };
        return Ok(Loaded { tf, report: None });
    }
    let text = crate::cmd::read_text(path)?;
    if !text.trim_start().starts_with('{') {
        let tf = match text.trim().parse::<FracTf>() {
            Ok(tf) => tf,
            Err(e) => bad_input!("{}: not a model: {e}", path.display()),
        };
        return Ok(Loaded { tf, report: None });
    }
    let v: Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => bad_input!("{}: not valid JSON: {e}", path.display()),
    };
    refuse_unusable(&v, path)?;
    let tf = from_json(final_model(&v)).with_context(|| format!("model of {}", path.display()))?;
    Ok(Loaded {
        tf,
        report: Some(v),
    })
}

/// A report that marks its model unusable (`"usable": false`, with its `problems`) is refused
/// as bad input: a design, an export or a comparison on it would look like a result.
///
/// # Errors
/// Bad input naming the report's problems.
fn refuse_unusable(v: &Value, path: &Path) -> Result<()> {
    if v.get("usable").and_then(Value::as_bool) != Some(false) {
        return Ok(());
    }
    let problems: Vec<&str> = v
        .get("problems")
        .and_then(Value::as_array)
        .map(|p| p.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    bad_input!(
        "{}: the report marks its model unusable ({}); refit or fix the record first",
        path.display(),
        if problems.is_empty() {
            "no problem named".to_string()
        } else {
            problems.join("; ")
        }
    )
}

/// The report's answer (see the module's documentation), or `v` itself when it is a bare
/// model.
#[must_use]
pub fn final_model(v: &Value) -> &Value {
    ident::app::answer::of_report(v).model
}

/// A model object `{"num": [{"coef", "order"}], "den": [...], "delay", "text"}` as a
/// [`FracTf`]. When its `text` is the same model written as a product (a two-mass drive
/// train's `motor * pair`), the product is kept: its factors are what the simulator and the
/// export need when the multiplied-out form cannot be expanded.
///
/// # Errors
/// Bad input for an object that is not a model, a model [`FracTf::new`] refuses.
pub fn from_json(m: &Value) -> Result<FracTf> {
    let report = match serde_json::from_value::<ModelReport>(m.clone()) {
        Ok(r) => r,
        Err(e) => bad_input!(
            "not a model {{\"num\": [{{\"coef\", \"order\"}}], \"den\": [...], \"delay\"}}: {e}"
        ),
    };
    let tf = report.tf()?;
    match report.text.parse::<FracTf>() {
        Ok(g) if !g.factors().is_empty() && same_model(&g, &tf) => Ok(g),
        _ => Ok(tf),
    }
}

/// Whether two models have the same terms and delay to within the decimal text's rounding.
fn same_model(a: &FracTf, b: &FracTf) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * x.abs().max(y.abs());
    let terms = |s: &[Term], t: &[Term]| {
        s.len() == t.len()
            && s.iter()
                .zip(t)
                .all(|(x, y)| close(x.coef, y.coef) && close(x.order, y.order))
    };
    terms(&a.num, &b.num) && terms(&a.den, &b.den) && close(a.delay, b.delay)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_final_model_of_a_report_is_taken() {
        let m = |k: f64| json!({"num": [{"coef": k, "order": 0.0}], "den": [{"coef": 1.0, "order": 0.0}, {"coef": 0.1, "order": 0.9}]});
        let dc = |v: &Value| from_json(final_model(v)).unwrap().num[0].coef;
        let levy = json!({"model": m(1.0)});
        assert_eq!(dc(&levy), 1.0);
        // the best by J, not the refit because it is one (a refit worse than Levy's is not it)
        let refined = json!({"model": m(1.0), "refined": {"model": m(2.0)}, "best_model": m(1.0)});
        assert_eq!(dc(&refined), 1.0);
        let diagnosed = json!({"model": m(1.0), "refined": {"model": m(2.0)},
            "best_model": m(2.0), "diagnosis": {"model": m(3.0)}});
        assert_eq!(dc(&diagnosed), 3.0);
        assert_eq!(dc(&m(4.0)), 4.0);
    }

    #[test]
    fn a_product_is_kept_only_when_its_text_is_the_same_model() {
        let text = "(2/(0.01 s + 1)) * (1/(0.001 s^2 + 0.01 s^0.8 + 1))";
        let g: FracTf = text.parse().unwrap();
        assert!(!g.factors().is_empty());
        // A report writes the terms multiplied out and the product as its text.
        let mut v = serde_json::to_value(ModelReport::from(&g)).unwrap();
        v["text"] = json!(text);
        let back = from_json(&v).unwrap();
        assert_eq!(back.factors().len(), g.factors().len());
        assert!(same_model(&back, &g));
        v["den"][0]["coef"] = json!(7.0);
        let other = from_json(&v).unwrap();
        assert!(other.factors().is_empty() && !same_model(&other, &g));
    }

    #[test]
    fn what_is_not_a_model_is_refused() {
        for bad in [
            json!({"num": [{"coef": 1.0}], "den": [{"coef": 1.0, "order": 0.0}]}),
            json!({"den": [{"coef": 1.0, "order": 0.0}]}),
            json!({"num": [], "den": [], "delay": "x"}),
        ] {
            assert!(from_json(&bad).is_err(), "{bad}");
        }
    }
}
