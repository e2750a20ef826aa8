//! `fracid score MODEL FILE`: how well a given model explains a time record (MATLAB's `compare`):
//! the model's parameters held, the record's own initial state and output offset estimated.

use super::time::{read_record, score_text, ColumnArgs};
use anyhow::Result;
use ident::app::time::ScoreReport;
use ident::data::ReadOptions;
use ident::oe::{score, FracModel, InitialState};
use std::path::PathBuf;

/// Options of `fracid score`.
#[derive(Debug, clap::Args)]
pub struct ScoreArgs {
    /// The model: a transfer function such as "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
    /// or the JSON file `fracid time --json` or `fracid freq --json` wrote (its "model").
    pub model: String,
    /// CSV file with columns t, u, y.
    pub file: PathBuf,
    /// The columns of t, u and y.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Approximation of the fractional operators: refined (default), oustaloup or trigeassou.
    #[arg(long, default_value = "refined")]
    pub approx: String,
    /// Operating point removal: initial (u[0], median y before the first input change), mean, none.
    #[arg(long, default_value = "initial")]
    pub offsets: String,
    /// Initial state: estimate (the record's own, as a past held input) or rest.
    #[arg(long, default_value = "estimate")]
    pub initial: String,
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
/// Run `fracid score`.
///
/// # Errors
/// Unreadable file (exit 3), bad model, data or options (exit 2), numerical breakdown (exit 1).
pub fn run(a: ScoreArgs) -> Result<()> {
    let tf = model_tf(&a.model)?;
    let read = ReadOptions {
        columns: a.columns.columns(),
        dt: None,
    };
    let rec = read_record(&a.file, &read)?;
    let offsets = ident::app::offsets(&a.offsets)?;
    let initial: InitialState = a.initial.parse()?;
    let mut m = FracModel::from_tf(&tf, false, false);
    m.approx.method = a.approx.parse()?;
    m.with_output_offset(0.0);
    let sc = score(&m, &rec, offsets, initial)?;
    if a.json {
        let mut v = serde_json::to_value(ScoreReport::new(&a.file.display().to_string(), &sc))?;
        v["model"] = serde_json::Value::String(tf.to_string());
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("model: {tf}");
        print!(
            "{}",
            score_text(&ScoreReport::new(&a.file.display().to_string(), &sc))
        );
        for w in &sc.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}
