//! Progress and cancellation of a use case ([`super::time::run`]): one observer trait instead of
//! paired `*_with_progress` functions (after argmin's `Observe`).

/// What a use case is doing, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Stage {
    /// Fitting the requested structure (simulations are reported by [`Observe::simulation`]).
    Fit,
    /// Fitting every candidate structure and keeping the one the data support
    /// (`structure = "auto"`, on all cores): `n` candidates.
    Structures {
        /// The number of candidate structures.
        n: usize,
    },
    /// Comparing the structures, each fitted and diagnosed (on all cores): `n` candidates.
    Diagnose {
        /// The number of candidate structures.
        n: usize,
    },
    /// Scoring the models on a separate validation record.
    Validate,
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stage::Fit => write!(f, "fitting"),
            Stage::Structures { n } => {
                write!(f, "fitting the {n} candidate structures (on all cores)")
            }
            Stage::Diagnose { n } => {
                write!(
                    f,
                    "diagnosing: {n} structures fitted and diagnosed (on all cores)"
                )
            }
            Stage::Validate => write!(f, "scoring on the validation record"),
        }
    }
}

/// An observer of a use case: told each stage as it starts and each simulation of the plain
/// fit, and asked between stages whether to go on. Every method has a default that does nothing,
/// so an observer implements only what it shows.
///
/// ```
/// use ident::app::observe::{Observe, Stage};
/// struct Count(usize);
/// impl Observe for Count {
///     fn stage(&mut self, _stage: Stage) {
///         self.0 += 1;
///     }
/// }
/// let mut c = Count(0);
/// c.stage(Stage::Fit);
/// assert_eq!(c.0, 1);
/// assert!(!c.cancelled());
/// ```
pub trait Observe {
    /// A stage starts.
    fn stage(&mut self, _stage: Stage) {}
    /// The plain fit's `simulations`-th simulation ended with this RMSE (of the output the fit
    /// sees: scaled when the record's magnitude was scaled).
    fn simulation(&mut self, _simulations: usize, _rmse: f64) {}
    /// Whether the user asked to stop: checked before each stage; the use case then returns
    /// [`crate::Error::Cancelled`].
    fn cancelled(&self) -> bool {
        false
    }
}

/// The observer that shows nothing and never cancels.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;

impl Observe for Quiet {}

/// Start `stage` unless the observer asks to stop.
///
/// # Errors
/// [`crate::Error::Cancelled`] when [`Observe::cancelled`] says so.
pub(crate) fn enter(obs: &mut dyn Observe, stage: Stage) -> crate::Result<()> {
    if obs.cancelled() {
        return Err(crate::Error::Cancelled(format!("before {stage}")));
    }
    obs.stage(stage);
    Ok(())
}
