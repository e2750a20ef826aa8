//! `fracid score MODEL FILE`: how well a given model explains a time record (MATLAB's `compare`):
//! the model's parameters held, the record's own initial state and output offset estimated.

use super::time::{read_record, score_text, ColumnArgs};
use anyhow::Result;
use fracsim::approx::Method;
use ident::app::score::ScoreReport;
use ident::data::{OffsetMode, ReadOptions};
use ident::oe::{score, FracModel, InitialState};
use std::path::PathBuf;

/// Options of `fracid score`.
#[derive(Debug, clap::Args)]
pub struct ScoreArgs {
    /// The model: a transfer function such as "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
    /// or the JSON file `fracid freq --json` wrote (its "model"). A `fracid time --json` report
    /// is scored as its own run scored it: its models (the leading one, effects included, and
    /// the base fit after a diagnosis) with every plant parameter held, the record's offset and
    /// initial state estimated on the estimation part of the same split; the figures on FILE
    /// (the record the report was made from gives the report's own).
    pub model: String,
    /// CSV file with columns t, u, y.
    pub file: PathBuf,
    /// The columns of t, u and y.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Approximation of the fractional operators: refined (default), oustaloup or trigeassou.
    #[arg(long, value_parser = crate::cmd::parse_word::<Method>, default_value_t = Method::default())]
    pub approx: Method,
    /// Operating point removal: initial (u[0], median y before the first input change), mean, none.
    #[arg(long, value_parser = crate::cmd::parse_word::<OffsetMode>,
          default_value_t = OffsetMode::default())]
    pub offsets: OffsetMode,
    /// Initial state: estimate (the record's own, as a past held input) or rest.
    #[arg(long, value_parser = crate::cmd::parse_word::<InitialState>,
          default_value_t = InitialState::Estimate)]
    pub initial: InitialState,
    /// With a `fracid time --json` report: which of its models to score, `lead` (the one it
    /// recommends: after a diagnosis the final model, effects included) or `base` (the base fit
    /// of a diagnosis).
    #[arg(long, default_value = "lead")]
    pub which: String,
    /// With a `fracid time --json` report: score its models as its own run did (its request:
    /// the same operating point and split, the record's offset and initial state estimated on
    /// the estimation part), both the leading model and the base fit; on the record the report
    /// was made from this gives the report's own figures.
    #[arg(long)]
    pub as_fitted: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The model of `MODEL`: a transfer function, or the "model" of a fracid JSON report.
fn model_tf(s: &str) -> Result<fracsim::FracTf> {
    let path = std::path::Path::new(s);
    if s.ends_with(".json") || path.is_file() {
        let text = super::read_text(path)?;
        let v: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| super::BadInput(format!("{s} is not JSON: {e}")))?;
        let m: ident::app::ModelReport = serde_json::from_value(v["model"].clone())
            .map_err(|e| super::BadInput(format!("{s}: no usable \"model\": {e}")))?;
        return Ok(m.tf()?);
    }
    Ok(s.parse()?)
}
/// A `fracid time --json` report (it has the request it ran and its models' `spec`), or `None`
/// for a model or another JSON.
fn time_report(s: &str) -> Result<Option<serde_json::Value>> {
    let path = std::path::Path::new(s);
    if !(s.ends_with(".json") || path.is_file()) {
        return Ok(None);
    }
    let text = super::read_text(path)?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| super::BadInput(format!("{s} is not JSON: {e}")))?;
    Ok((v.get("request").is_some() && v.get("spec").is_some()).then_some(v))
}

/// `fracid score REPORT.json FILE`: the report's models (the leading one and, after a diagnosis,
/// the base fit) scored as the report's own run scored them (`ident::app::time::rescore`).
fn rescore_report(a: &ScoreArgs, v: &serde_json::Value, rec: ident::data::Record) -> Result<()> {
    use ident::app::time::{rescore, TimeData, TimeRequest};
    let bad =
        |what: &str, e: serde_json::Error| super::BadInput(format!("{}: {what}: {e}", a.model));
    let req: TimeRequest =
        serde_json::from_value(v["request"].clone()).map_err(|e| bad("request", e))?;
    let spec: FracModel = serde_json::from_value(v["spec"].clone()).map_err(|e| bad("spec", e))?;
    let data = TimeData {
        record: rec,
        validation: None,
        joint: Vec::new(),
        reader_warnings: Vec::new(),
    };
    let lead = rescore(&req, &spec, &data)?;
    let base = match v.pointer("/base/spec") {
        Some(b) => {
            let spec: FracModel =
                serde_json::from_value(b.clone()).map_err(|e| bad("base.spec", e))?;
            Some(rescore(&req, &spec, &data)?)
        }
        None => None,
    };
    if a.json {
        let out = RescoredJson {
            file: a.file.display().to_string(),
            model_is: &v["model_is"],
            fit: &lead,
            base: base.as_ref().map(|fit| BaseJson { fit }),
        };
        // through a JSON value: the keys sorted as always
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(&out)?)?
        );
        return Ok(());
    }
    let line = |name: &str, f: &ident::app::time::FitFigures| {
        let val = f.validation.map_or("-".to_string(), |v| {
            format!("NRMSE {:.2}%, RMSE {:.5}", v.nrmse_percent, v.rmse)
        });
        println!(
            "{name}: estimation NRMSE {:.2}%, RMSE {:.5}; validation {val}",
            f.estimation.nrmse_percent, f.estimation.rmse
        );
    };
    println!(
        "scored as the report's run scored it (its request; the record's offset and initial \
         state estimated on the estimation part)"
    );
    line(
        &format!(
            "the report's model ({})",
            v["model_is"].as_str().unwrap_or("lead")
        ),
        &lead,
    );
    if let Some(b) = &base {
        line("its base fit", b);
    }
    Ok(())
}

/// Run `fracid score`.
///
/// # Errors
/// Unreadable file (exit 3), bad model, data or options (exit 2), numerical breakdown (exit 1).
pub fn run(a: ScoreArgs) -> Result<()> {
    let read = ReadOptions {
        columns: a.columns.columns(),
        dt: None,
    };
    let report = time_report(&a.model)?;
    if a.as_fitted {
        let Some(v) = &report else {
            crate::bad_input!("--as-fitted scores a `fracid time --json` report, not a model");
        };
        return rescore_report(&a, v, read_record(&a.file, &read)?);
    }
    let (offsets, initial) = (a.offsets, a.initial);
    if let Some(v) = &report {
        // the report's whole model (effects included), with its own approximation
        let key = match a.which.trim() {
            "lead" => "/spec",
            "base" => "/base/spec",
            w => crate::bad_input!("--which must be lead or base, got '{w}'"),
        };
        let Some(spec) = v.pointer(key) else {
            crate::bad_input!("{}: no base fit (the report has no diagnosis)", a.model);
        };
        let m: FracModel = serde_json::from_value(spec.clone())
            .map_err(|e| super::BadInput(format!("{}: {key}: {e}", a.model)))?;
        let text = m.tf(&m.values())?.to_string();
        let effects: Vec<&str> = m.effects.iter().map(|e| e.name()).collect();
        let rec = read_record(&a.file, &read)?;
        let sc = score(&m, &rec, offsets, initial)?;
        let words = if effects.is_empty() {
            text
        } else {
            format!("{text} with {}", effects.join(", "))
        };
        return print_scored(&a, &sc, &words);
    }
    let tf = model_tf(&a.model)?;
    let rec = read_record(&a.file, &read)?;
    let mut m = FracModel::from_tf(&tf, false, false);
    m.approx.method = a.approx;
    m.with_output_offset(0.0);
    let sc = score(&m, &rec, offsets, initial)?;
    print_scored(&a, &sc, &tf.to_string())
}

/// `fracid score --json` of a model: the library's report with the model scored, in words.
#[derive(serde::Serialize)]
struct ScoredJson<'a> {
    #[serde(flatten)]
    report: &'a ScoreReport,
    model: &'a str,
}

/// `fracid score REPORT.json FILE --json`: the report's models rescored.
#[derive(serde::Serialize)]
struct RescoredJson<'a> {
    file: String,
    model_is: &'a serde_json::Value,
    fit: &'a ident::app::time::FitFigures,
    base: Option<BaseJson<'a>>,
}

/// The base fit rescored.
#[derive(serde::Serialize)]
struct BaseJson<'a> {
    fit: &'a ident::app::time::FitFigures,
}

/// A model (`model` in words) scored on FILE, as text or JSON.
fn print_scored(a: &ScoreArgs, sc: &ident::oe::Scored, model: &str) -> Result<()> {
    let r = ScoreReport::new(&a.file.display().to_string(), sc);
    if a.json {
        let out = ScoredJson { report: &r, model };
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(&out)?)?
        );
    } else {
        println!("model: {model}");
        print!("{}", score_text(&r));
    }
    for w in &sc.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}
