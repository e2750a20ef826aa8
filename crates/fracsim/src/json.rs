//! The JSON forms every report shares, written once: a model as its terms ([`ModelReport`],
//! `{num, den, delay, text, effects}`) and an exported state space ([`StateSpaceJson`], what
//! `fracid export --format json`, Python's `StateSpace.to_dict` and a tune report's realisation
//! give).

use crate::error::Result;
use crate::export::{method_name, StateSpace};
use crate::tf::{FracTf, Term};
use serde::{Deserialize, Serialize};

/// One `(coefficient, order)` term of a reported model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TermReport {
    /// The coefficient.
    pub coef: f64,
    /// The order of `s`.
    pub order: f64,
}

/// A model as reports give it (DESIGN section 7): `num`, `den`, `delay` (s) and its `text`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelReport {
    /// Numerator terms.
    pub num: Vec<TermReport>,
    /// Denominator terms.
    pub den: Vec<TermReport>,
    /// Input delay in seconds.
    #[serde(default)]
    pub delay: f64,
    /// The model as text (read back by the parser).
    #[serde(default)]
    pub text: String,
    /// The names of the effects around the linear model (a final model after the diagnosis;
    /// empty for a linear one).
    #[serde(default)]
    pub effects: Vec<String>,
}

impl From<&FracTf> for ModelReport {
    fn from(g: &FracTf) -> Self {
        let terms = |t: &[Term]| {
            t.iter()
                .map(|t| TermReport {
                    coef: t.coef,
                    order: t.order,
                })
                .collect()
        };
        Self {
            num: terms(&g.num),
            den: terms(&g.den),
            delay: g.delay,
            text: g.to_string(),
            effects: Vec::new(),
        }
    }
}

impl ModelReport {
    /// The transfer function back.
    ///
    /// # Errors
    /// As [`FracTf::new`].
    pub fn tf(&self) -> Result<FracTf> {
        let terms = |t: &[TermReport]| t.iter().map(|t| Term::new(t.coef, t.order)).collect();
        FracTf::new(terms(&self.num), terms(&self.den), self.delay)
    }
}

/// The approximation a state space was made with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ApproxJson {
    /// The band `[w_b, w_h]`, rad/s.
    pub band: [f64; 2],
    /// `refined`, `oustaloup` or `trigeassou`.
    pub method: String,
    /// The order `N` (2N+1 cells per operator).
    pub order: usize,
}

/// An exported state space as JSON (the fields in the order a JSON object map sorts them, the
/// order `fracid export` has always written).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateSpaceJson {
    /// `A`, by rows.
    pub a: Vec<Vec<f64>>,
    /// The approximation of the fractional operators.
    pub approximation: ApproxJson,
    /// `B`, a column (`n` rows of one).
    pub b: Vec<Vec<f64>>,
    /// `C`, one row.
    pub c: Vec<Vec<f64>>,
    /// `D`, `[[d]]`.
    pub d: Vec<Vec<f64>>,
    /// How many of the last states are the input delay line (discrete).
    pub delay_states: usize,
    /// The sample period in seconds (`None`: continuous).
    pub dt: Option<f64>,
    /// `zoh` when discrete (the input held over each period).
    pub hold: Option<String>,
    /// A continuous model's input delay in seconds, not in the matrices.
    pub input_delay: f64,
    /// The model the approximation stands for, as text.
    pub model: String,
    /// The number of states.
    pub states: usize,
    /// `discrete` or `continuous`.
    pub time: String,
}

impl StateSpace {
    /// The JSON form of this state space, standing for `model` (its text).
    pub fn to_json(&self, model: &str) -> StateSpaceJson {
        StateSpaceJson {
            a: self.a_rows(),
            approximation: ApproxJson {
                band: [self.band.0, self.band.1],
                method: method_name(self.spec.method).to_string(),
                order: self.spec.order,
            },
            b: self.b_col().iter().map(|v| vec![*v]).collect(),
            c: vec![self.c_row()],
            d: vec![vec![self.d]],
            delay_states: self.delay_states,
            dt: self.dt,
            hold: self.dt.map(|_| "zoh".to_string()),
            input_delay: self.input_delay,
            model: model.to_string(),
            states: self.order(),
            time: if self.dt.is_some() {
                "discrete"
            } else {
                "continuous"
            }
            .to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ApproxSpec;

    #[test]
    fn a_model_round_trips_through_its_report() {
        let g: FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)"
            .parse()
            .unwrap();
        let r = ModelReport::from(&g);
        assert_eq!(
            r.den[1],
            TermReport {
                coef: 0.0064,
                order: 0.89
            }
        );
        assert_eq!(r.delay, 0.001);
        assert_eq!(r.tf().unwrap(), g);
    }

    #[test]
    fn a_discrete_state_space_as_json_holds_its_matrices() {
        let g: FracTf = "1/(0.1 s + 1)".parse().unwrap();
        let ss = crate::export::discrete(&g, 0.01, &ApproxSpec::default()).unwrap();
        let j = ss.to_json("1/(0.1 s + 1)");
        assert_eq!(
            (j.states, j.time.as_str(), j.dt),
            (1, "discrete", Some(0.01))
        );
        assert_eq!(j.hold.as_deref(), Some("zoh"));
        assert_eq!(j.a, vec![vec![(-0.1f64).exp()]]);
        assert_eq!(j.b.len(), 1);
        assert_eq!(j.c[0].len(), 1);
        assert_eq!(j.approximation.method, "refined");
    }
}
