//! A general fractional structure whose size the data choose (docs/design.md §5, "structures
//! chosen by the data"):
//!
//! `G(s) = (b_0 + b_1 s^q + ... + b_m s^(m q)) / (s^i (1 + a_1 s^q + ... + a_n s^(n q))) e^(-tau s)`
//!
//! with a commensurate order `q` (1 for an integer-order model, searched on a grid otherwise, and
//! optionally fitted), a free integrator `s^i` (`i = 1` when the data call for it), a
//! feed-through when `m q = n q + i` (the numerator as high as the denominator), and an input
//! delay as an option. The relative degree is `(n - m) q + i`. A resonance with or without an
//! anti-resonance, several modes, a lead, a non-minimum-phase zero (a numerator coefficient of
//! either sign), a feed-through and a feed-through beside an integrator are all of this form.
//!
//! - [`start`]: the frequency response of the estimation part (periodic averages for a periodic
//!   input, Welch's H1 estimate otherwise), fitted for each size by weighted Levy least squares
//!   and Sanathanan-Koerner iterations ([`crate::levy`]); an unstable start is made stable (the
//!   poles reflected into the left half-plane, the numerator refitted).
//! - [`search`]: the sizes the frequency-domain information criterion ranks first are each
//!   fitted by output error ([`crate::oe::identify`]), and the size chosen by held-out RMSE, then
//!   BIC among ties ([`crate::diagnose::choice::TIE`]).
//!
//! - [`hook`]: the general structure compared with the named ones in the diagnosis when they
//!   fit poorly.
//!
//! Each coefficient is written `p_k w0^(-k q)` with `w0` the start's characteristic frequency,
//! so the fitted parameters `p_k` are of order one whatever the time unit and the degree.

pub mod hook;
pub mod search;
pub mod start;

pub use search::{candidate, fit, GeneralFit};

use crate::oe::{Bounds, Expr, FracModel, Kind, Param};
use crate::{Error, Result};

/// The largest denominator degree (in powers of `q`) of an integer-order general structure: six
/// modes.
pub const MAX_DEN_INTEGER: usize = 12;

/// The largest denominator degree of a fractional one (each term of a fractional order is
/// approximated by its own cells: the model grows by 17 states a term).
pub const MAX_DEN_FRACTIONAL: usize = 4;

/// The most free parameters a fit of the general structure may have, offsets and initial-state
/// levels included ([`Budget`]).
pub const MAX_FREE: usize = 16;

/// Estimation samples per free parameter a fit needs at least ([`Budget`]): the fit's own rule
/// ([`crate::oe::identify`]).
pub use crate::oe::SAMPLES_PER_PARAM;

/// How many coefficients (plus a searched delay) a size may have: at most [`MAX_FREE`] free
/// parameters in all, those the fit adds beside the structure included (the output offset, an
/// integrator's input offset, the initial state's levels, a free order `q`, the template's own
/// delay), and at least [`SAMPLES_PER_PARAM`] estimation samples for each parameter the fit
/// counts when it checks the record's length ([`crate::oe::identify`]: the structure's, the
/// output offset), so that no size is proposed that the fit would refuse or the record cannot
/// determine, and the search never ends in a refusal where a smaller size fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Budget {
    /// Free parameters of a size without an integrator: `b_0 .. b_num`, `a_1 .. a_den`, a
    /// searched delay.
    pub plain: usize,
    /// The same with a free integrator.
    pub integrator: usize,
}

impl Budget {
    /// No cap.
    pub const UNLIMITED: Budget = Budget {
        plain: usize::MAX,
        integrator: usize::MAX,
    };

    /// The budget of an estimation part of `samples` samples with `beside` free parameters
    /// beside the structure (`beside_integrator` with a free integrator), `counted` of them
    /// counted by the fit's length check.
    ///
    /// Every free parameter needs [`SAMPLES_PER_PARAM`] samples (as the final model's own
    /// evaluation asks, the levels included); when that leaves fewer than a first order's two
    /// coefficients, a first order is still allowed if the fit's length check (`counted` beside
    /// it) passes.
    pub fn new(samples: usize, beside: usize, beside_integrator: usize, counted: usize) -> Budget {
        let free = MAX_FREE.min(samples / SAMPLES_PER_PARAM);
        let smallest = 2.min((samples / SAMPLES_PER_PARAM).saturating_sub(counted));
        Budget {
            plain: free.saturating_sub(beside).max(smallest),
            integrator: free.saturating_sub(beside_integrator).max(smallest),
        }
    }

    /// Whether `size` (with an integrator, with a searched delay) fits in the budget.
    pub fn allows(&self, size: Size, integrator: bool, delay: bool) -> bool {
        let k = size.num + 1 + size.den + usize::from(delay);
        k <= if integrator {
            self.integrator
        } else {
            self.plain
        }
    }
}

/// A size: numerator degree `num` and denominator degree `den`, in powers of `q`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Size {
    /// Highest numerator power (`b_0 .. b_num`).
    pub num: usize,
    /// Highest denominator power (`a_1 .. a_den`; the constant term is 1).
    pub den: usize,
}

impl std::fmt::Display for Size {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.num, self.den)
    }
}

/// What the user asked of the general structure (`--structure general` or `general:N/D`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct GeneralRequest {
    /// A fixed size, or `None`: chosen by the data.
    pub size: Option<Size>,
    /// A free integrator: `Some(true)` always (`--integrator`), `None` when the data call for it.
    pub integrator: Option<bool>,
    /// Whether `q` is fitted with the coefficients (else held at its grid value).
    pub free_q: bool,
}

/// Whether `spec` names the general structure: `general` (size chosen by the data) or
/// `general:N/D` (numerator degree `N`, denominator degree `D`); `None` for another spec.
///
/// ```
/// use ident::diagnose::general::{requested, Size};
/// assert_eq!(requested("General").unwrap().unwrap().size, None);
/// let g = requested("general:1/4").unwrap().unwrap();
/// assert_eq!(g.size, Some(Size { num: 1, den: 4 }));
/// assert!(requested("general:6/4").unwrap().is_err());
/// assert!(requested("pmsm").is_none());
/// ```
///
/// # Errors
/// [`Error::Options`] for a size that is not two integers `N/D` with `1 <= D <= 12` and
/// `N <= D + 1`.
pub fn requested(spec: &str) -> Option<Result<GeneralRequest>> {
    let s = spec.trim().to_ascii_lowercase();
    let rest = s.strip_prefix("general")?;
    if rest.is_empty() {
        return Some(Ok(GeneralRequest::default()));
    }
    let size = rest.strip_prefix(':')?;
    Some(parse_size(size).map(|size| GeneralRequest {
        size: Some(size),
        ..GeneralRequest::default()
    }))
}

fn parse_size(s: &str) -> Result<Size> {
    let bad = || {
        Error::Options(format!(
            "general structure size '{s}' must be N/D: numerator and denominator degrees, \
             1 <= D <= {MAX_DEN_INTEGER}, N <= D + 1 (a feed-through beside an integrator)"
        ))
    };
    let (n, d) = s.split_once('/').ok_or_else(bad)?;
    let num: usize = n.trim().parse().map_err(|_| bad())?;
    let den: usize = d.trim().parse().map_err(|_| bad())?;
    if den == 0 || den > MAX_DEN_INTEGER || num > den + 1 {
        return Err(bad());
    }
    Ok(Size { num, den })
}

/// The general structure's template: the first order `b0/(a1 s + 1)` (the options of a request,
/// its approximation, delay and integrator, are put on it; its sizes take them, [`fit`]).
pub fn template() -> FracModel {
    GeneralStart {
        size: Size { num: 0, den: 1 },
        q: 1.0,
        integrator: false,
        b: vec![1.0],
        a: vec![0.01],
        delay_samples: 0,
        frf_error: f64::NAN,
        criterion: f64::NAN,
    }
    .model(false)
}

/// A start of the general structure: its size, order, integrator and coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneralStart {
    /// The size.
    pub size: Size,
    /// The commensurate order.
    pub q: f64,
    /// A free integrator `1/s` in series.
    pub integrator: bool,
    /// `b_0 .. b_num`.
    pub b: Vec<f64>,
    /// `a_1 .. a_den`.
    pub a: Vec<f64>,
    /// The whole-sample input delay the response calls for ([`start::ranked_delayed`]; 0:
    /// none).
    pub delay_samples: usize,
    /// Weighted relative error of the start on the frequency response
    /// (`oe::init::frf_error`).
    pub frf_error: f64,
    /// The frequency-domain information criterion it was ranked by ([`start::criterion`]).
    pub criterion: f64,
}

impl GeneralStart {
    /// Its name in reports: `general N/D`, with the order when it is not 1, `+ integrator` and
    /// `+ delay`.
    pub fn name(&self) -> String {
        let q = if (self.q - 1.0).abs() < 1e-12 {
            String::new()
        } else {
            format!(" q={:.3}", self.q)
        };
        let i = if self.integrator { " + integrator" } else { "" };
        let d = if self.delay_samples > 0 {
            " + delay"
        } else {
            ""
        };
        format!("general {}{q}{i}{d}", self.size)
    }

    /// The characteristic frequency `w0` (rad/s) the coefficients are normalised by: the
    /// highest denominator coefficient's, `a_n^(-1/(n q))`.
    fn w0(&self) -> f64 {
        let n = self.a.len();
        let an = self.a.last().copied().unwrap_or(1.0).abs();
        let w = an.powf(-1.0 / (n as f64 * self.q));
        if w.is_finite() && w > 0.0 {
            w
        } else {
            1.0
        }
    }

    /// The structure as a [`FracModel`] ([`Kind::General`]: it starts from these values): each
    /// coefficient `c_k` of `s^(k q)` written `p_k w0^(-k q)`, `p_k` free (the denominator's
    /// positive ones kept positive, `exp` parametrisation), the denominator's constant 1; `q` a
    /// parameter in `(0, 1]`'s neighbourhood fitted when `free_q`.
    pub fn model(&self, free_q: bool) -> FracModel {
        let w0 = self.w0();
        let mut m = FracModel {
            params: vec![],
            num: vec![],
            den: vec![],
            kind: Kind::General,
            ..FracModel::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        };
        let iq = m.add_param(Param {
            name: "q".into(),
            value: self.q,
            bounds: Bounds::Interval(0.0, 2.0),
            free: free_q,
        });
        let order = |k: usize| {
            if free_q {
                Expr::sum(&[(iq, k as f64)])
            } else {
                Expr::cst(k as f64 * self.q)
            }
        };
        let scale = |k: usize| w0.powf(-(k as f64) * self.q);
        for (k, &c) in self.b.iter().enumerate() {
            let i = m.add_param(Param::new(&format!("b{k}"), c / scale(k), Bounds::Free));
            m.num.push((Expr::sum(&[(i, scale(k))]), order(k)));
        }
        m.den.push((Expr::cst(1.0), Expr::cst(0.0)));
        for (k, &c) in self.a.iter().enumerate() {
            let k = k + 1;
            let bounds = if c > 0.0 {
                Bounds::Positive
            } else {
                Bounds::Free
            };
            let i = m.add_param(Param::new(&format!("a{k}"), c / scale(k), bounds));
            m.den.push((Expr::sum(&[(i, scale(k))]), order(k)));
        }
        // Highest order first, as reports write a polynomial.
        m.num.reverse();
        m.den.reverse();
        if self.integrator {
            m.with_integrator();
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_becomes_the_model_it_describes() {
        // (0.5 s + 2) / (s (1e-4 s^2 + 0.01 s + 1))
        let s = GeneralStart {
            size: Size { num: 1, den: 2 },
            q: 1.0,
            integrator: true,
            b: vec![2.0, 0.5],
            a: vec![0.01, 1e-4],
            delay_samples: 0,
            frf_error: 0.0,
            criterion: 0.0,
        };
        let m = s.model(false);
        let tf = m.tf(&m.values()).unwrap();
        let want: fracsim::FracTf = "(0.5 s + 2)/(1e-4 s^3 + 0.01 s^2 + s)".parse().unwrap();
        for w in [0.1, 10.0, 100.0, 1e3] {
            let (a, b) = (tf.freq_response(w), want.freq_response(w));
            assert!((a - b).norm() < 1e-12 * b.norm(), "{w}: {a} {b}");
        }
        // normalised: w0 = 100 rad/s, a2 w0^2 = 1
        let a2 = m.index_of("a2").unwrap();
        assert!((m.params[a2].value - 1.0).abs() < 1e-12);
        assert_eq!(s.name(), "general 1/2 + integrator");
        // a free order is one parameter of every order
        let f = s.model(true);
        let p = f.values();
        assert!(f.params[0].free, "{:?}", f.params[0]);
        assert!((f.den[0].1.eval(&p) - 3.0).abs() < 1e-12, "{:?}", f.den);
    }

    #[test]
    fn sizes_parse_and_refuse() {
        assert_eq!(parse_size(" 2 / 3").unwrap(), Size { num: 2, den: 3 });
        for bad in ["2", "a/3", "1/0", "1/13", "4/2", "-1/2"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert!(requested("generalx").is_none());
    }
}
