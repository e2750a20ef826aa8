//! One verdict for every report: whether the model a report leads with can be used (`usable`,
//! `problems`, and so the exit code), computed once, from that model's own figures.
//!
//! A model's own problems are those of the rules it was judged by where it was made (a
//! time-domain model: [`crate::oe::Identification::problems`], the rules of `oe::checks`, which a
//! diagnosis's final model and a joint fit are judged by too; a frequency-domain model:
//! [`crate::levy::FreqFit::problems`]); [`verdict`] adds the rule on the data it was not fitted
//! to: a separate validation record predicted worse than that record's own mean. The plain fit,
//! `structure = "auto"`, the diagnosis's final model, `--validate`, `--joint` and `fracid freq`
//! all state the verdict [`verdict`] gives, and the CLI's exit code, the fleet's rows and
//! Python's results read it from the report ([`super::answer`]).

use super::score::ScoreReport;
use serde::Serialize;

/// Whether a model can be used, and why not.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Verdict {
    /// No problem.
    pub usable: bool,
    /// Why it cannot be used.
    pub problems: Vec<String>,
}

/// The verdict on a model with its own `problems` (see the module's documentation), scored on
/// the separate validation records `files`.
///
/// ```
/// use ident::app::verdict::verdict;
/// assert!(verdict(vec![], None).usable);
/// let v = verdict(vec!["the model is unstable".into()], None);
/// assert_eq!((v.usable, v.problems.len()), (false, 1));
/// ```
pub fn verdict(problems: Vec<String>, file: Option<&ScoreReport>) -> Verdict {
    let mut problems = problems;
    problems.extend(file.and_then(worse_than_the_mean_on_file));
    Verdict {
        usable: problems.is_empty(),
        problems,
    }
}

/// A separate validation record that the model predicts worse than the record's own mean (NRMSE
/// below 0, or not finite): the model does not describe that record of the same plant, whatever
/// its fit of the record it was fitted on.
fn worse_than_the_mean_on_file(file: &ScoreReport) -> Option<String> {
    (!(file.nrmse_percent >= 0.0)).then(|| {
        format!(
            "the model predicts the validation record {} worse than its mean (NRMSE {:.1}%, RMSE \
             {:.4e}): it does not describe that record of the plant (another structure, a delay: \
             try --diagnose; or the records are not of the same plant)",
            file.file, file.nrmse_percent, file.rmse
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scored(nrmse_percent: f64) -> ScoreReport {
        ScoreReport {
            file: "v.csv".into(),
            rmse: 1.0,
            nrmse_percent,
            offsets: crate::data::Offsets { u0: 0.0, y0: 0.0 },
            record_params: vec![],
            warnings: vec![],
        }
    }

    #[test]
    fn a_validation_record_predicted_worse_than_its_mean_is_a_problem() {
        assert!(verdict(vec![], Some(&scored(12.0))).usable);
        for bad in [-150.0, f64::NAN] {
            let v = verdict(vec![], Some(&scored(bad)));
            assert!(!v.usable && v.problems[0].contains("v.csv"), "{v:?}");
        }
        // the model's own problems come first
        let v = verdict(vec!["own".into()], Some(&scored(-1.0)));
        assert_eq!(v.problems.len(), 2);
        assert_eq!(v.problems[0], "own");
    }
}
