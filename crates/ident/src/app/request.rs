//! The typed words of the requests: the structure ([`Structure`], its named ones from the one
//! catalogue [`crate::catalogue::Preset`]), the parameters held ([`Held`]) and fitted ([`Names`]), and serde
//! through the words the CLI and Python use ([`words`]), so that a request is parsed once, where
//! it enters (the CLI's flags, Python's JSON), and `run` receives enums.

pub use crate::catalogue::Preset;
use crate::diagnose::general::{GeneralRequest, Size};
use crate::oe::FracModel;
use crate::{Error, Result};
use fracsim::FracTf;
use std::fmt;
use std::str::FromStr;

/// The structure of a time-domain request: a named one, `auto`, the general structure, or a
/// transfer function.
///
/// ```
/// use ident::app::request::{Preset, Structure};
/// let s: Structure = "Second order".parse().unwrap();
/// assert_eq!((s.clone(), s.to_string()), (Structure::Named(Preset::SecondOrder), "second-order".into()));
/// assert_eq!("general:1/4".parse::<Structure>().unwrap().to_string(), "general:1/4");
/// assert!("arx".parse::<Structure>().is_err());
/// ```
#[derive(Debug, Clone)]
pub enum Structure {
    /// A structure of the catalogue.
    Named(Preset),
    /// The data choose among the catalogue's structures
    /// ([`crate::diagnose::structures::fit_best`]; with the diagnosis, its own comparison from
    /// the PMSM).
    Auto,
    /// The general structure ([`crate::diagnose::general`]): sized by the data, or of that size.
    General(Option<Size>),
    /// A transfer function whose every coefficient and order is fitted from its values.
    Model {
        /// The words it was given in (trimmed), as the request reports it.
        text: String,
        /// The transfer function.
        tf: FracTf,
    },
}

impl PartialEq for Structure {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Named(a), Self::Named(b)) => a == b,
            (Self::Auto, Self::Auto) => true,
            (Self::General(a), Self::General(b)) => a == b,
            (Self::Model { text: a, .. }, Self::Model { text: b, .. }) => a == b,
            _ => false,
        }
    }
}

impl Default for Structure {
    fn default() -> Self {
        Self::Named(Preset::Pmsm)
    }
}

impl Structure {
    /// Its model, and whether it starts from a transfer function's values (`true` for
    /// [`Structure::Model`]). `auto` is the PMSM (its first candidate), `general` the general
    /// structure's template ([`crate::diagnose::general::template`]); `max_delay_s` as
    /// [`Preset::model`].
    pub fn model(&self, max_delay_s: f64) -> (FracModel, bool) {
        match self {
            Self::Named(p) => (p.model(max_delay_s), false),
            Self::Auto => (Preset::Pmsm.model(max_delay_s), false),
            Self::General(_) => (crate::diagnose::general::template(), false),
            Self::Model { tf, .. } => (FracModel::from_tf(tf, true, true), true),
        }
    }

    /// Whether the data choose the structure (`auto`).
    pub fn is_auto(&self) -> bool {
        matches!(self, Self::Auto)
    }

    /// Its label in the structure comparison: the PMSM for `auto`, else its own words.
    pub fn label(&self) -> String {
        match self {
            Self::Auto => Preset::Pmsm.name().to_string(),
            s => s.to_string(),
        }
    }

    /// The general structure's request when it is the general structure.
    pub fn general(&self) -> Option<GeneralRequest> {
        match self {
            Self::General(size) => Some(GeneralRequest {
                size: *size,
                ..GeneralRequest::default()
            }),
            _ => None,
        }
    }
}

impl fmt::Display for Structure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Named(p) => f.write_str(p.name()),
            Self::Auto => f.write_str("auto"),
            Self::General(None) => f.write_str("general"),
            Self::General(Some(size)) => write!(f, "general:{size}"),
            Self::Model { text, .. } => f.write_str(text),
        }
    }
}

impl FromStr for Structure {
    type Err = Error;
    fn from_str(spec: &str) -> Result<Self> {
        let s = spec.trim().to_ascii_lowercase();
        if s == "auto" {
            return Ok(Self::Auto);
        }
        if let Some(p) = Preset::find(&s) {
            return Ok(Self::Named(p));
        }
        if let Some(g) = crate::diagnose::general::requested(&s) {
            return Ok(Self::General(g?.size));
        }
        let tf: FracTf = s.parse().map_err(|e| {
            Error::Options(format!(
                "structure '{spec}' is not {}, auto, general, general:N/D or a model: {e}",
                Preset::names()
            ))
        })?;
        Ok(Self::Model {
            text: spec.trim().to_string(),
            tf,
        })
    }
}

/// One parameter held: its name, at its value when given.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldParam {
    /// The parameter's name (as the report prints it).
    pub name: String,
    /// The value it is held at (`None`: its start value).
    pub value: Option<f64>,
}

/// The parameters held: `NAME` or `NAME=VALUE`, comma-separated.
///
/// ```
/// use ident::app::request::Held;
/// let h: Held = " zeta=0.9, theta".parse().unwrap();
/// assert_eq!((h.0.len(), h.0[0].value, h.to_string()), (2, Some(0.9), "zeta=0.9,theta".into()));
/// assert!("K=abc".parse::<Held>().is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Held(pub Vec<HeldParam>);

impl FromStr for Held {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let mut held = Vec::new();
        for item in s.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = match item.split_once('=') {
                Some((n, v)) => {
                    let v: f64 = v.trim().parse().map_err(|_| {
                        Error::Options(format!("fix '{item}': '{}' is not a number", v.trim()))
                    })?;
                    (n.trim(), Some(v))
                }
                None => (item, None),
            };
            if name.is_empty() {
                return Err(Error::Options(format!(
                    "fix '{item}' must be NAME or NAME=VALUE"
                )));
            }
            held.push(HeldParam {
                name: name.to_string(),
                value,
            });
        }
        Ok(Self(held))
    }
}

impl fmt::Display for Held {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, p) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(",")?;
            }
            match p.value {
                Some(v) => write!(f, "{}={v}", p.name)?,
                None => f.write_str(&p.name)?,
            }
        }
        Ok(())
    }
}

/// Parameter names, comma-separated (the parameters a structure holds that are fitted).
///
/// ```
/// use ident::app::request::Names;
/// let n: Names = "K, a1,".parse().unwrap();
/// assert_eq!((n.0.clone(), n.to_string()), (vec!["K".to_string(), "a1".into()], "K,a1".into()));
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Names(pub Vec<String>);

impl FromStr for Names {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(Self(
            s.split(',')
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect(),
        ))
    }
}

impl fmt::Display for Names {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0.join(","))
    }
}

/// serde through a type's words: written with its `Display`, read with its `FromStr` (the
/// request's JSON holds the words the CLI's flags and Python's keywords take), for
/// `#[serde(with = "words")]`.
pub mod words {
    use serde::{de, Deserialize, Deserializer, Serializer};
    use std::fmt::Display;
    use std::str::FromStr;

    /// Write `v` as its words.
    ///
    /// # Errors
    /// The serializer's.
    pub fn serialize<T: Display, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(v)
    }

    /// Read a value from its words.
    ///
    /// # Errors
    /// Words the type does not take (its `FromStr` error, as it says it).
    pub fn deserialize<'de, T, D>(d: D) -> Result<T, D::Error>
    where
        T: FromStr,
        T::Err: Display,
        D: Deserializer<'de>,
    {
        String::deserialize(d)?.parse().map_err(de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_named_structure_round_trips_in_every_spelling() {
        for p in Preset::ALL {
            let s: Structure = p.to_string().parse().unwrap();
            assert_eq!(
                (s.to_string(), s.clone()),
                (p.name().into(), Structure::Named(p))
            );
            for w in [
                p.name().replace('-', " "),
                p.name().replace('-', "_"),
                p.name().to_ascii_uppercase(),
            ] {
                assert_eq!(w.parse::<Structure>().unwrap(), Structure::Named(p), "{w}");
            }
        }
    }

    #[test]
    fn every_structure_round_trips() {
        for w in ["auto", "general", "general:1/4", "pmsm", "2/(0.2 s + 1)"] {
            let s: Structure = w.parse().unwrap();
            assert_eq!(s.to_string(), w);
            assert_eq!(s.to_string().parse::<Structure>().unwrap(), s);
        }
        assert_eq!(" Auto".parse::<Structure>().unwrap(), Structure::Auto);
        assert_eq!(Structure::Auto.label(), "pmsm");
        let m: Structure = " 2/(0.2 S + 1) ".parse().unwrap();
        assert_eq!(m.to_string(), "2/(0.2 S + 1)");
        assert!(m.model(1.0).1);
        let e = "arx".parse::<Structure>().unwrap_err().to_string();
        assert!(
            e.contains("structure 'arx' is not pmsm, commensurate, first-order")
                && e.contains("unknown name 'arx'"),
            "{e}"
        );
        let e = "general:6/4".parse::<Structure>().unwrap_err().to_string();
        assert!(e.contains("general structure size '6/4'"), "{e}");
    }

    #[test]
    fn held_and_names_round_trip() {
        for w in ["", "K", "zeta=0.9,theta", "K=-2.5,tau=0.001"] {
            let h: Held = w.parse().unwrap();
            assert_eq!(h.to_string(), w);
            assert_eq!(h.to_string().parse::<Held>().unwrap(), h);
            let n: Names = w.replace(['=', '.', '-'], "").parse().unwrap();
            assert_eq!(n.to_string().parse::<Names>().unwrap(), n);
        }
        let e = "K=abc".parse::<Held>().unwrap_err().to_string();
        assert!(e.contains("fix 'K=abc': 'abc' is not a number"), "{e}");
        let e = "=3".parse::<Held>().unwrap_err().to_string();
        assert!(e.contains("must be NAME or NAME=VALUE"), "{e}");
    }
}
