//! The catalogue of named structures: one table of names (as `--structure` and Python's
//! `structure=` take them, the structure comparison and the reports print them, the help and the
//! errors list them), the spellings also accepted, what each is, and its model.

use crate::oe::FracModel;
use crate::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// A named structure: the one catalogue of names, as `--structure` and `structure=` take them,
/// the structure comparison and the reports print them, and the errors list them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Preset {
    /// `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`.
    Pmsm,
    /// `K/(a2 s^(2q) + a1 s^q + 1)`.
    Commensurate,
    /// `K/(T s + 1)`.
    FirstOrder,
    /// `K/(a2 s^2 + a1 s + 1)`.
    SecondOrder,
    /// `K/(a3 s^3 + a2 s^2 + a1 s + 1)`.
    ThirdOrder,
    /// The PMSM times a resonant pair ([`FracModel::two_mass`]).
    TwoMass,
    /// The PMSM with a direct feed-through ([`FracModel::feedthrough`]).
    Feedthrough,
    /// `K e^(-tau s)/(T s + 1)`.
    Fopdt,
    /// `D + Ki/s + K/(a1 s^q + 1)` ([`FracModel::cell`]).
    Cell,
}

/// One row of the catalogue.
struct Entry {
    preset: Preset,
    /// The name (kebab-case, as the CLI takes it and the reports print it).
    name: &'static str,
    /// Other spellings accepted (beside `_` or a space for `-`, always accepted).
    aliases: &'static [&'static str],
    /// What it is, for the help and the docs.
    formula: &'static str,
}

/// The catalogue, in the order the help lists it.
const CATALOGUE: [Entry; 9] = [
    Entry {
        preset: Preset::Pmsm,
        name: "pmsm",
        aliases: &[],
        formula: "K/(a2 s^(zeta+theta) + a1 s^zeta + 1)",
    },
    Entry {
        preset: Preset::Commensurate,
        name: "commensurate",
        aliases: &[],
        formula: "K/(a2 s^(2q) + a1 s^q + 1)",
    },
    Entry {
        preset: Preset::FirstOrder,
        name: "first-order",
        aliases: &[],
        formula: "the integer K/(T s + 1)",
    },
    Entry {
        preset: Preset::SecondOrder,
        name: "second-order",
        aliases: &[],
        formula: "the integer K/(a2 s^2 + a1 s + 1)",
    },
    Entry {
        preset: Preset::ThirdOrder,
        name: "third-order",
        aliases: &[],
        formula: "the integer K/(a3 s^3 + a2 s^2 + a1 s + 1)",
    },
    Entry {
        preset: Preset::TwoMass,
        name: "two-mass",
        aliases: &[],
        formula: "pmsm times (b2 s^2 + d s^mu + 1)/(c2 s^2 + d s^mu + 1): a compliant coupling",
    },
    Entry {
        preset: Preset::Feedthrough,
        name: "feedthrough",
        aliases: &["feed-through"],
        formula: "D + pmsm: an output that responds at once to the input, D its instant response",
    },
    Entry {
        preset: Preset::Fopdt,
        name: "fopdt",
        aliases: &[],
        formula: "K e^(-tau s)/(T s + 1), tau up to the largest delay",
    },
    Entry {
        preset: Preset::Cell,
        name: "cell",
        aliases: &[],
        formula: "D + Ki/s + K/(a1 s^q + 1): a battery cell's voltage per current (ohmic drop, \
                  charge, constant-phase polarisation)",
    },
];

impl Preset {
    /// Every named structure, in the catalogue's order.
    pub const ALL: [Preset; 9] = [
        Preset::Pmsm,
        Preset::Commensurate,
        Preset::FirstOrder,
        Preset::SecondOrder,
        Preset::ThirdOrder,
        Preset::TwoMass,
        Preset::Feedthrough,
        Preset::Fopdt,
        Preset::Cell,
    ];

    fn entry(self) -> &'static Entry {
        CATALOGUE
            .iter()
            .find(|e| e.preset == self)
            .expect("every preset is in the catalogue")
    }

    /// Its name, as the options take it and the reports print it (`second-order`).
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// What it is, in a few words (its transfer function).
    pub fn formula(self) -> &'static str {
        self.entry().formula
    }

    /// The preset a word names: its name or an alias, any case, `_` or a space for `-`
    /// (`Second_Order`, `second order`).
    pub fn find(word: &str) -> Option<Preset> {
        let w = word.trim().to_ascii_lowercase().replace(['_', ' '], "-");
        CATALOGUE
            .iter()
            .find(|e| e.name == w || e.aliases.contains(&w.as_str()))
            .map(|e| e.preset)
    }

    /// The catalogue's names, comma-separated (for the help and the errors).
    pub fn names() -> String {
        Self::ALL.map(Preset::name).join(", ")
    }

    /// The catalogue as the help lists it: `name (formula)`, comma-separated.
    pub fn described() -> String {
        Self::ALL
            .map(|p| format!("{} ({})", p.name(), p.formula()))
            .join(", ")
    }

    /// Its model with neutral start values (the automatic start replaces them); `max_delay_s` is
    /// the largest input delay of [`Preset::Fopdt`] (the others have none).
    pub fn model(self, max_delay_s: f64) -> FracModel {
        // K, a1, a2, zeta, theta: the paper's orders, a neutral gain and time constants
        let pmsm = [1.0, 0.01, 1e-4, 0.9, 0.9];
        match self {
            Preset::Pmsm => {
                let [k, a1, a2, zeta, theta] = pmsm;
                FracModel::pmsm(k, a1, a2, zeta, theta)
            }
            Preset::Commensurate => FracModel::commensurate(1.0, 0.01, 1e-4, 0.9),
            Preset::FirstOrder => {
                let mut m = FracModel::fopdt(1.0, 0.1, 0.01, 1.0);
                m.delay = None;
                m.params.retain(|p| p.name != "tau");
                m
            }
            Preset::SecondOrder => FracModel::second_order(1.0, 0.01, 1e-4),
            Preset::ThirdOrder => FracModel::third_order(1.0, 0.0175, 8.75e-5, 1.25e-7),
            Preset::TwoMass => {
                // the pair at 40 and 30 Hz
                let inv_w2 = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
                FracModel::two_mass(pmsm, [inv_w2(30.0), inv_w2(40.0), 1e-3, 1.0])
            }
            Preset::Feedthrough => FracModel::feedthrough(pmsm, 0.0),
            Preset::Fopdt => FracModel::fopdt(1.0, 0.1, 0.05 * max_delay_s, max_delay_s),
            Preset::Cell => FracModel::cell(1.0, 1.0, 0.7, 0.0, 0.0),
        }
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Self::find(s)
            .ok_or_else(|| Error::Options(format!("structure '{s}' is none of {}", Self::names())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_round_trips_and_its_spellings_are_one() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>().unwrap(), p);
            assert_eq!(p.to_string(), p.name());
            // the other spellings users type
            for w in [
                p.name().replace('-', " "),
                p.name().replace('-', "_"),
                p.name().to_ascii_uppercase(),
            ] {
                assert_eq!(w.parse::<Preset>().unwrap(), p, "{w}");
            }
        }
        assert_eq!(Preset::find("feed-through"), Some(Preset::Feedthrough));
        assert_eq!(Preset::ALL.len(), CATALOGUE.len());
        let e = "arx".parse::<Preset>().unwrap_err().to_string();
        assert!(e.contains("'arx'") && e.contains(&Preset::names()), "{e}");
    }
}
