//! Output-error identification of fractional transfer functions in the time domain
//! (docs/design.md §5; Poinot & Trigeassou 2004; the reference paper's eqs. 12-18).
//!
//! The residual is `e_k = y_k - yhat_k(theta)` with `yhat` the simulated output of the model on the
//! measured input; `theta` minimises `sum e_k^2` by Levenberg-Marquardt (Marquardt 1963). The
//! output sensitivities `d yhat_k / d theta` are exact for the discretised model: the simulation
//! runs with forward-mode dual numbers ([`fracsim::Dual`]), which is the paper's sensitivity
//! systems (eqs. 14-18) differentiated through the discrete recursion.
//!
//! - [`FracModel`]: a fractional transfer function whose coefficients and orders are linear
//!   expressions ([`Expr`]) of named parameters ([`Param`]), with an optional input delay and
//!   per-sample [`Effect`]s (offsets, friction, saturation, ...). Presets: [`FracModel::pmsm`]
//!   (paper eq. 10), [`FracModel::commensurate`] (eq. 20), [`FracModel::fopdt`].
//! - [`Structure`]: the extension point. Anything that can simulate its output for parameters of
//!   any [`Real`] type can be fitted by [`fit`].
//! - [`fit`]: the OE-LM fit on plain slices (deviations); [`identify`]: the whole procedure on a
//!   [`Record`] (operating point, split, automatic start, metrics).
//! - [`init`]: a start that needs no guess (the frequency response of a periodic input, then a
//!   Levy fit with an order search; a coarse search otherwise), reported in [`StartReport`].
//!
//! Bounds are kept by reparametrisation ([`Bounds`]): positive coefficients as `exp(theta)`,
//! bounded quantities (orders in `(0, 2)`, the delay) as `lo + (hi - lo) sigmoid(theta)`. Standard
//! errors come from `sigma_e^2 (J^T J)^-1` in `theta` and are carried to the parameters by the
//! delta method.
//!
//! ```no_run
//! use ident::oe::{identify, FracModel, IdentOptions};
//! let rec = ident::data::Record::parse(&std::fs::read_to_string("data.csv").unwrap(),
//!                                      &Default::default()).unwrap();
//! let id = identify(&rec, &FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9), &IdentOptions::default())
//!     .unwrap();
//! println!("{} fit {:.1}%", id.tf, id.validation.unwrap().nrmse_percent);
//! ```

pub(crate) mod band;
pub(crate) mod checks;
mod coverage;
pub(crate) mod effects;
pub(crate) mod evaluate;
mod fit;
pub mod init;
mod joint;
mod score;

pub(crate) use checks::levels_at_bound;
pub use checks::{Validation, ValidationKind};
pub use effects::Effect;
pub(crate) use fit::fit_in_unit;
pub use fit::{
    check_params, fit, fit_with_progress, identify, identify_with_progress, past_edges,
    sensitivities, FitOptions, FitReport, IdentOptions, Identification, InitialReport,
    InitialState, LeadPart, ParamEstimate, StartMode, SAMPLES_PER_PARAM,
};
pub use init::{StartMethod, StartReport};
pub use joint::{identify_joint, JointIdentification};
pub use score::{score, Scored};

use crate::{Error, Result};
use fracsim::{ApproxSpec, Dual, FracTf, Real, Simulator, Term};

/// How a parameter is kept in its range by reparametrisation (the solver works on `theta`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Bounds {
    /// Unbounded: `p = theta`.
    Free,
    /// Positive: `p = exp(theta)`.
    Positive,
    /// Open interval: `p = lo + (hi - lo) / (1 + exp(-theta))`.
    Interval(f64, f64),
}

impl Bounds {
    /// `p(theta)`.
    #[inline]
    pub fn to_param<T: Real>(self, theta: T) -> T {
        match self {
            Bounds::Free => theta,
            Bounds::Positive => theta.exp(),
            Bounds::Interval(lo, hi) => {
                // Logistic function written so that exp never overflows (a NaN derivative would).
                let s = if theta.re() >= 0.0 {
                    T::from(1.0) / ((-theta).exp() + 1.0)
                } else {
                    let e = theta.exp();
                    e / (e + 1.0)
                };
                s * (hi - lo) + lo
            }
        }
    }

    /// `theta(p)`.
    ///
    /// # Errors
    /// [`Error::Options`] when `p` is outside the open range.
    pub fn to_theta(self, p: f64, name: &str) -> Result<f64> {
        match self {
            Bounds::Free => Ok(p),
            Bounds::Positive if p > 0.0 => Ok(p.ln()),
            Bounds::Interval(lo, hi) if p > lo && p < hi => {
                let s = (p - lo) / (hi - lo);
                Ok((s / (1.0 - s)).ln())
            }
            _ => Err(Error::Options(format!(
                "starting value {p} of {name} is outside its range {self:?}"
            ))),
        }
    }

    /// Clamp a starting value strictly inside the range (1e-6 of the width from an edge).
    pub fn clamp_inside(self, p: f64) -> f64 {
        match self {
            Bounds::Free => p,
            Bounds::Positive => p.max(1e-300),
            Bounds::Interval(lo, hi) => {
                let m = 1e-6 * (hi - lo);
                p.clamp(lo + m, hi - m)
            }
        }
    }

    /// `dp/dtheta` at the parameter value `p` (`1`, `p`, or `(hi - lo) s (1 - s)` with
    /// `s = (p - lo)/(hi - lo)`): carries a sensitivity or a standard error from `theta` to `p`.
    pub fn dparam(self, p: f64) -> f64 {
        match self {
            Bounds::Free => 1.0,
            Bounds::Positive => p,
            Bounds::Interval(lo, hi) => {
                let s = (p - lo) / (hi - lo);
                (hi - lo) * s * (1.0 - s)
            }
        }
    }

    /// Whether `p` is within 0.5% of the width of an interval edge (a fit that ran to a bound).
    pub fn at_edge(self, p: f64) -> bool {
        match self {
            Bounds::Interval(lo, hi) => {
                let m = 5e-3 * (hi - lo);
                p < lo + m || p > hi - m
            }
            _ => false,
        }
    }
}

/// A named model parameter: its (starting) value, its range, and whether it is fitted.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Param {
    /// Name used in reports (`K`, `a1`, `zeta`, ...).
    pub name: String,
    /// Starting value (or the fixed value).
    pub value: f64,
    /// Range kept by reparametrisation.
    pub bounds: Bounds,
    /// Fitted (true) or held at `value`.
    pub free: bool,
}

impl Param {
    /// A free parameter.
    pub fn new(name: &str, value: f64, bounds: Bounds) -> Self {
        Self {
            name: name.into(),
            value,
            bounds,
            free: true,
        }
    }
    /// A free positive coefficient (`exp` parametrisation).
    pub fn positive(name: &str, value: f64) -> Self {
        Self::new(name, value, Bounds::Positive)
    }
    /// A free order in `(0, 2)` (`2 sigmoid` parametrisation).
    pub fn order(name: &str, value: f64) -> Self {
        Self::new(name, value, Bounds::Interval(0.0, 2.0))
    }
    /// The same parameter, held fixed.
    pub fn fixed(mut self) -> Self {
        self.free = false;
        self
    }
}

/// The range a free order `nu` of a parsed model is fitted in: `(0, 2)` for `0 < nu < 2` (the
/// fractional orders of motor models), `(nu - 1, nu + 1)` above, and the mirror image for
/// negative orders (`(-2, 0)`, `(nu - 1, nu + 1)`), so an order never changes sign.
pub fn order_range(nu: f64) -> Bounds {
    if nu > 0.0 && nu < 2.0 {
        Bounds::Interval(0.0, 2.0)
    } else if nu < 0.0 && nu > -2.0 {
        Bounds::Interval(-2.0, 0.0)
    } else {
        Bounds::Interval(nu - 1.0, nu + 1.0)
    }
}

/// An expression `(constant + sum_i c_i p_i) prod_f p_f` of the parameters, for coefficients and
/// orders: linear (the PMSM's highest order is `zeta + theta`, the commensurate model's `2 q`),
/// times a product of parameters for the coefficients of a product multiplied out (the two-mass
/// model's `a2 c2` of `(a2 s^.. + ..)(c2 s^2 + ..)`, [`FracModel::two_mass`]).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Expr {
    /// The constant part.
    pub constant: f64,
    /// `(parameter index, factor)` pairs.
    pub terms: Vec<(usize, f64)>,
    /// Parameter indices the linear part is multiplied by (empty: a linear expression). They are
    /// the dimensionless factors of a product: the units of the coefficient are those of its
    /// linear part ([`FracModel::unit_scale`]).
    pub factors: Vec<usize>,
}

impl Expr {
    /// A constant.
    pub fn cst(c: f64) -> Self {
        Self {
            constant: c,
            ..Self::default()
        }
    }
    /// Parameter `i`.
    pub fn p(i: usize) -> Self {
        Self {
            terms: vec![(i, 1.0)],
            ..Self::default()
        }
    }
    /// `sum_i c_i p_i`.
    pub fn sum(terms: &[(usize, f64)]) -> Self {
        Self {
            terms: terms.to_vec(),
            ..Self::default()
        }
    }
    /// This expression times the parameters `factors` (see [`Expr::factors`]).
    pub fn times(mut self, factors: &[usize]) -> Self {
        self.factors.extend_from_slice(factors);
        self
    }
    /// Whether parameter `i` appears in it (in the linear part or as a factor).
    pub fn has(&self, i: usize) -> bool {
        self.terms.iter().any(|&(j, _)| j == i) || self.factors.contains(&i)
    }
    /// The value for parameters `p`.
    #[inline]
    pub fn eval<T: Real>(&self, p: &[T]) -> T {
        let mut v = T::from(self.constant);
        for &(i, c) in &self.terms {
            v += p[i] * c;
        }
        for &i in &self.factors {
            v *= p[i];
        }
        v
    }
}

/// A model that [`fit`] can identify: a parameter list and a simulation generic over [`Real`].
///
/// Implement this to fit any model by output error; [`FracModel`] is the fractional transfer
/// function with effects. `simulate` is called with `T = f64` for the output and with
/// `T = Dual<N>` for the output and its exact sensitivities, so it must use only [`Real`]
/// operations on parameter-dependent values, and should not allocate per sample.
pub trait Structure: Sync {
    /// All parameters (free and fixed), with starting values.
    fn params(&self) -> &[Param];
    /// Simulate the output deviation `y[k]` (same length as `u`) for the input deviation `u`,
    /// sampled every `dt` seconds from rest, for parameter values `p` (one per [`Structure::params`]).
    ///
    /// # Errors
    /// Parameter values the model cannot simulate (a simulation error, a non-finite output).
    fn simulate<T: Real>(&self, p: &[T], u: &[f64], dt: f64, y: &mut [T]) -> Result<()>;

    /// [`Structure::simulate`] in `Dual<N>` with its parts apart: the values into `yhat` (the
    /// length of `u`) and derivative part `r` into `cols[r]`, which holds the last
    /// `cols[r].len()` samples (all of the same length; those before are not stored). Default:
    /// through a record-long `Vec<Dual<N>>`; a structure can write the parts as it goes.
    ///
    /// # Errors
    /// As [`Structure::simulate`].
    fn simulate_parts<const N: usize>(
        &self,
        p: &[Dual<N>],
        u: &[f64],
        dt: f64,
        yhat: &mut [f64],
        cols: &mut [&mut [f64]],
    ) -> Result<()> {
        parts_through_vec(self, p, u, dt, yhat, cols)
    }

    /// Whether the output is linear in parameter `j` in a way
    /// [`Structure::linear_sensitivities`] computes in plain `f64` (an output offset, a gain, a
    /// level of the initial state). The fit then leaves `j` out of the dual-number simulation,
    /// which is the costly part of a Jacobian. Default: no parameter is.
    fn is_linear(&self, j: usize) -> bool {
        let _ = j;
        false
    }

    /// [`Structure::simulate`] (`T = f64`) into `yhat`, then
    /// [`Structure::linear_sensitivities`] of `which` into `out` at the same `p`. Default: the
    /// two calls; a structure can share their work (one model built for both).
    ///
    /// # Errors
    /// As the two calls.
    #[allow(clippy::too_many_arguments)]
    fn simulate_with_linear(
        &self,
        p: &[f64],
        which: &[usize],
        u: &[f64],
        dt: f64,
        yhat: &mut [f64],
        skip: usize,
        out: &mut [&mut [f64]],
    ) -> Result<()> {
        self.simulate(p, u, dt, yhat)?;
        self.linear_sensitivities(p, which, u, dt, yhat, skip, out)
    }

    /// The part parameter `j` plays when the output is linear in it ([`Structure::is_linear`]):
    /// [`fit`] then solves the gain, the initial-state levels and the output offset by linear
    /// least squares inside each step (variable projection). Default: `None` (no such part).
    fn linear_role(&self, j: usize) -> Option<LinearRole> {
        let _ = j;
        None
    }

    /// The exact sensitivities `out[i][k - skip] = d yhat_k / d p_(which[i])`, `k >= skip`, of
    /// parameters for which [`Structure::is_linear`] is true, given `yhat` (the output at `p`
    /// over the whole of `u`, as [`Structure::simulate`] wrote it). `out[i]` has
    /// `u.len() - skip` samples.
    ///
    /// # Errors
    /// A simulation error; a parameter that is not linear.
    fn linear_sensitivities(
        &self,
        p: &[f64],
        which: &[usize],
        u: &[f64],
        dt: f64,
        yhat: &[f64],
        skip: usize,
        out: &mut [&mut [f64]],
    ) -> Result<()> {
        let _ = (p, u, dt, yhat, skip, out);
        match which.first() {
            None => Ok(()),
            Some(j) => Err(Error::Options(format!(
                "parameter {j} is not linear in this structure"
            ))),
        }
    }
}

/// The part a parameter the output is linear in plays ([`Structure::linear_role`]), with
/// `yhat = K (G0 u + sum_i w_i F_i) + c`: `G0 u` the response with unit gain from the initial
/// state of the fixed levels, `F_i` level `i`'s free response with unit gain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearRole {
    /// A constant output offset `c`.
    Offset,
    /// The gain `K` (the factor of the only numerator term).
    Gain,
    /// A level `w_i` of the initial state's past input (its free response scales with `K`).
    Level,
}

/// [`Structure::simulate_parts`] through a record-long `Vec<Dual<N>>` (the default).
fn parts_through_vec<S: Structure + ?Sized, const N: usize>(
    s: &S,
    p: &[Dual<N>],
    u: &[f64],
    dt: f64,
    yhat: &mut [f64],
    cols: &mut [&mut [f64]],
) -> Result<()> {
    let mut y = vec![Dual::<N>::cst(0.0); u.len()];
    s.simulate(p, u, dt, &mut y)?;
    split_parts(&y, 0, yhat, cols);
    Ok(())
}

/// The dual outputs `y` of samples `k0..k0 + y.len()` apart: values into `yhat[k]`, derivative
/// part `r` into `cols[r][k - skip]` for `k >= skip`, `skip` the samples `cols` leave out
/// (`yhat.len() - cols[r].len()`).
fn split_parts<const N: usize>(
    y: &[Dual<N>],
    k0: usize,
    yhat: &mut [f64],
    cols: &mut [&mut [f64]],
) {
    for (v, out) in y.iter().zip(&mut yhat[k0..]) {
        *out = v.v;
    }
    let skip = yhat.len() - cols.first().map_or(0, |c| c.len());
    let from = skip.max(k0);
    for (r, col) in cols.iter_mut().enumerate() {
        let dst = &mut col[from - skip..];
        for (c, v) in dst.iter_mut().zip(&y[from - k0..]) {
            *c = v.d[r];
        }
    }
}

/// An error naming the first non-finite output of samples `k0..k0 + y.len()`, if there is one
/// (one vectorised pass; the sample is searched only when one is not finite).
fn check_output<T: Real>(y: &[T], k0: usize) -> Result<()> {
    if crate::lm::all_finite(y) {
        return Ok(());
    }
    let k = y.iter().position(|v| !v.re().is_finite()).unwrap_or(0);
    Err(Error::Numerical(format!(
        "the model output is not finite at sample {}",
        k0 + k
    )))
}

/// Samples a chunk of [`FracModel`]'s `simulate_parts` (its dual buffer stays in the L2 cache).
const PARTS_CHUNK: usize = 8192;

/// The kind of a [`FracModel`], which decides how an automatic start is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Kind {
    /// `K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`, parameters `K, a1, a2, zeta, theta`.
    Pmsm,
    /// `K / (a2 s^(2q) + a1 s^q + 1)`, parameters `K, a1, a2, q`.
    Commensurate,
    /// `K / (T s + 1)` with delay, parameters `K, T, tau`.
    Fopdt,
    /// An integer-order reference, `K / (a2 s^2 + a1 s + 1)`, parameters `K, a1, a2`: started
    /// like the FOPDT, by the coarse search at order 1.
    Integer,
    /// The two-mass drive train [`FracModel::two_mass`]: started from the frequency response
    /// (the resonance and anti-resonance located on it, [`init`]).
    TwoMass,
    /// The PMSM with a direct feed-through [`FracModel::feedthrough`], parameters
    /// `K, a1, a2, zeta, theta, D`: `D` started from the output's instant response to the input
    /// steps, the rest as the PMSM on `y - D u` ([`init`]).
    Feedthrough,
    /// A battery cell's voltage per current [`FracModel::cell`], parameters `K, a1, q, D, Ki`:
    /// started from the instant response and a regression of the rest on the integrated input
    /// and trial fractional first orders ([`init`]).
    Cell,
    /// Anything else: starts from the given values.
    General,
}

/// One factor of [`FracModel::series`]: numerator and denominator `(coefficient, order)` terms.
pub type ExprFactor = (Vec<(Expr, Expr)>, Vec<(Expr, Expr)>);

/// A fractional transfer function
/// `sum_i b_i s^beta_i / sum_j a_j s^alpha_j * exp(-tau s)` whose coefficients and orders are
/// [`Expr`]essions of [`Param`]s, with per-sample [`Effect`]s, simulated with the
/// [`ApproxSpec`] approximation (Oustaloup, refined Oustaloup or Poinot-Trigeassou).
///
/// ```
/// use ident::oe::{Effect, FracModel, Param};
/// let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
/// m.with_delay(0.0005, 0.01);
/// let vc = m.add_param(Param::positive("Vc", 0.1));
/// m.effects.push(Effect::Coulomb { vc, sampled: false });
/// assert_eq!(m.params.len(), 7);
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FracModel {
    /// The parameters.
    pub params: Vec<Param>,
    /// Numerator terms `(coefficient, order)`.
    pub num: Vec<(Expr, Expr)>,
    /// Denominator terms `(coefficient, order)`.
    pub den: Vec<(Expr, Expr)>,
    /// Parameter index of the input delay (seconds), if any.
    pub delay: Option<usize>,
    /// Effects around the linear part, see [`effects`](Effect).
    pub effects: Vec<Effect>,
    /// The approximation of the fractional operators.
    #[serde(with = "approx_serde")]
    pub approx: ApproxSpec,
    /// The operating point `(u0, y0)` the effects see (set by [`identify`]).
    pub operating_point: crate::data::Offsets,
    /// The kind (for the automatic start and reports).
    pub kind: Kind,
    /// The initial state, as a past held input (`None`: the record starts from rest).
    pub past: Option<PastInput>,
    /// Whether the model has a free integrator `1/s`: put in series
    /// ([`FracModel::with_integrator`]), or beside the rest in the cell structure
    /// ([`FracModel::cell`], whose start is its own). Either way the input has no operating point
    /// and an input offset is its own parameter.
    pub integrator: bool,
    /// When not empty, the linear part is the series connection of these factors, each
    /// `(numerator, denominator)` terms, and is simulated factor by factor
    /// ([`fracsim::Simulator::from_factors`]); `num` and `den` hold the product multiplied out
    /// (the transfer function of reports). A free integrator ([`FracModel::integrator`]) is in
    /// `den`, not here: the simulation adds it to the first factor.
    pub series: Vec<ExprFactor>,
}

/// The range of the past input's levels, as deviations from `u0`, for a record whose input spans
/// `[lo, hi]`: that span widened by twice its width on each side (a past the plant could have
/// been driven with; unbounded levels let a poor base fit explain what an effect left with a
/// huge, slowly decaying free response).
pub fn past_range(u: &[f64], u0: f64) -> (f64, f64) {
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let span = (hi - lo).max(1e-12 * hi.abs().max(lo.abs()).max(1.0));
    (lo - 2.0 * span - u0, hi + 2.0 * span - u0)
}

/// The initial state of a record as the state a past held input left (MATLAB's `oe` and `compare`
/// estimate an initial state; this is a low-dimensional, well-conditioned way to do so for a model
/// with tens of modes): the input deviation was `params[levels[0]]` on `[-edges[0], 0)`,
/// `params[levels[j]]` on `[-edges[j], -edges[j-1])`, and the last level before `-edges[last]`
/// (see [`fracsim::Simulator::set_past_input`]). A record that starts in motion, mid-transient or
/// on a ramp is then simulated from the state its own past left, not from rest.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PastInput {
    /// Window edges in seconds before the first sample, increasing.
    pub edges: Vec<f64>,
    /// Parameter indices of the levels (one more than the edges).
    pub levels: Vec<usize>,
}

impl FracModel {
    /// The PMSM structure (paper eq. 10) `K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`; `K, a1, a2`
    /// positive, `zeta, theta` in `(0, 2)`.
    pub fn pmsm(k: f64, a1: f64, a2: f64, zeta: f64, theta: f64) -> Self {
        Self {
            params: vec![
                Param::positive("K", k),
                Param::positive("a1", a1),
                Param::positive("a2", a2),
                Param::order("zeta", zeta),
                Param::order("theta", theta),
            ],
            num: vec![(Expr::p(0), Expr::cst(0.0))],
            den: vec![
                (Expr::p(2), Expr::sum(&[(3, 1.0), (4, 1.0)])),
                (Expr::p(1), Expr::p(3)),
                (Expr::cst(1.0), Expr::cst(0.0)),
            ],
            delay: None,
            effects: vec![],
            approx: ApproxSpec::default(),
            operating_point: Default::default(),
            kind: Kind::Pmsm,
            past: None,
            integrator: false,
            series: vec![],
        }
    }

    /// The commensurate structure (paper eq. 20) `K / (a2 s^(2q) + a1 s^q + 1)`, `q` in `(0, 1)`.
    pub fn commensurate(k: f64, a1: f64, a2: f64, q: f64) -> Self {
        Self {
            params: vec![
                Param::positive("K", k),
                Param::positive("a1", a1),
                Param::positive("a2", a2),
                Param::new("q", q, Bounds::Interval(0.0, 1.0)),
            ],
            num: vec![(Expr::p(0), Expr::cst(0.0))],
            den: vec![
                (Expr::p(2), Expr::sum(&[(3, 2.0)])),
                (Expr::p(1), Expr::p(3)),
                (Expr::cst(1.0), Expr::cst(0.0)),
            ],
            kind: Kind::Commensurate,
            ..Self::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        }
    }

    /// The integer first-order-plus-delay model `K e^(-tau s) / (T s + 1)`, `tau` in
    /// `(0, max_delay)` seconds.
    pub fn fopdt(k: f64, t: f64, tau: f64, max_delay: f64) -> Self {
        let mut m = Self {
            params: vec![Param::positive("K", k), Param::positive("T", t)],
            num: vec![(Expr::p(0), Expr::cst(0.0))],
            den: vec![
                (Expr::p(1), Expr::cst(1.0)),
                (Expr::cst(1.0), Expr::cst(0.0)),
            ],
            kind: Kind::Fopdt,
            ..Self::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        };
        m.with_delay(tau, max_delay);
        m
    }

    /// The integer second-order reference `K / (a2 s^2 + a1 s + 1)` (real or complex poles): the
    /// model a fractional one is compared with ([`crate::diagnose::structures`]).
    ///
    /// ```
    /// let m = ident::oe::FracModel::second_order(2.0, 0.01, 1e-4);
    /// let tf = m.tf(&m.values()).unwrap();
    /// assert_eq!(tf.to_string(), "2/(0.0001 s^2 + 0.01 s + 1)");
    /// ```
    pub fn second_order(k: f64, a1: f64, a2: f64) -> Self {
        Self {
            params: vec![
                Param::positive("K", k),
                Param::positive("a1", a1),
                Param::positive("a2", a2),
            ],
            num: vec![(Expr::p(0), Expr::cst(0.0))],
            den: vec![
                (Expr::p(2), Expr::cst(2.0)),
                (Expr::p(1), Expr::cst(1.0)),
                (Expr::cst(1.0), Expr::cst(0.0)),
            ],
            kind: Kind::Integer,
            ..Self::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        }
    }

    /// The integer third-order reference `K / (a3 s^3 + a2 s^2 + a1 s + 1)`, started like the
    /// second order.
    ///
    /// ```
    /// let m = ident::oe::FracModel::third_order(2.0, 0.0175, 8.75e-5, 1.25e-7);
    /// let tf = m.tf(&m.values()).unwrap();
    /// assert_eq!(tf.to_string(), "2/(0.000000125 s^3 + 0.0000875 s^2 + 0.0175 s + 1)");
    /// ```
    pub fn third_order(k: f64, a1: f64, a2: f64, a3: f64) -> Self {
        let mut m = Self::second_order(k, a1, a2);
        let i = m.add_param(Param::positive("a3", a3));
        m.den.insert(0, (Expr::p(i), Expr::cst(3.0)));
        m
    }

    /// A two-mass drive train: a motor (the PMSM structure, paper eq. 10) driving a load through a
    /// compliant coupling whose damping is fractional,
    ///
    /// `G(s) = K (b2 s^2 + d s^mu + 1) / ((a2 s^(zeta+theta) + a1 s^zeta + 1) (c2 s^2 + d s^mu + 1))`.
    ///
    /// For a motor of inertia `J_m` and a load `J_l` on a shaft of stiffness `c` and damping torque
    /// `c d D^mu` of the twist (viscous for `mu = 1`, viscoelastic for `0 < mu < 1`), the motor
    /// speed per torque is exactly the rigid drive's times
    /// `(J_l s^2 + c d s^mu + c) / (J_m J_l/(J_m + J_l) s^2 + c d s^mu + c)`: an anti-resonance at
    /// `omega_a = b2^-1/2 = (c/J_l)^1/2` (the zeros) below the resonance at
    /// `omega_r = c2^-1/2 = (c (J_m + J_l)/(J_m J_l))^1/2` (the poles), both damped by the same
    /// `d s^mu`. Here the rigid drive is the PMSM's fractional model. Parameters
    /// `K, a1, a2, zeta, theta` as [`FracModel::pmsm`], `b2, c2, d` positive, `mu` in `(0, 2)`:
    /// `motor = [K, a1, a2, zeta, theta]`, `pair = [b2, c2, d, mu]`. `num` and `den` hold the
    /// product multiplied out (nine denominator terms; coefficients that are products of
    /// parameters, [`Expr::factors`]); it is simulated as motor times pair
    /// ([`FracModel::series`]).
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let w = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
    /// let m = FracModel::two_mass([6.77, 0.0064, 2.8e-5, 0.89, 0.89], [w(28.0), w(40.0), 2e-3, 0.7]);
    /// let tf = m.tf(&m.values()).unwrap();
    /// assert_eq!((tf.num.len(), tf.den.len()), (3, 9));
    /// assert!((tf.dc_gain() - 6.77).abs() < 1e-12);
    /// // The resonance: the response at 40 Hz is several times the motor's alone.
    /// let motor = fracsim::FracTf::pmsm(6.77, 0.0064, 2.8e-5, 0.89, 0.89).unwrap();
    /// let w40 = 2.0 * std::f64::consts::PI * 40.0;
    /// assert!(tf.freq_response(w40).norm() > 5.0 * motor.freq_response(w40).norm());
    /// ```
    pub fn two_mass(motor: [f64; 5], pair: [f64; 4]) -> Self {
        let [k, a1, a2, zeta, theta] = motor;
        let [b2, c2, d, mu] = pair;
        let mut m = Self::pmsm(k, a1, a2, zeta, theta);
        let (ik, ia1, ia2, iz, it) = (0, 1, 2, 3, 4);
        let ib2 = m.add_param(Param::positive("b2", b2));
        let ic2 = m.add_param(Param::positive("c2", c2));
        let id = m.add_param(Param::positive("d", d));
        let imu = m.add_param(Param::order("mu", mu));
        let order = |c: f64, t: &[usize]| Expr {
            constant: c,
            terms: t.iter().map(|&i| (i, 1.0)).collect(),
            factors: vec![],
        };
        m.num = vec![
            (Expr::p(ik).times(&[ib2]), Expr::cst(2.0)),
            (Expr::p(ik).times(&[id]), Expr::p(imu)),
            (Expr::p(ik), Expr::cst(0.0)),
        ];
        // (a2 s^(zeta+theta) + a1 s^zeta + 1) (c2 s^2 + d s^mu + 1), term by term.
        let motor_terms = [
            (Some(ia2), vec![iz, it]),
            (Some(ia1), vec![iz]),
            (None, vec![]),
        ];
        let pair_terms = [
            (Some(ic2), 2.0, None),
            (Some(id), 0.0, Some(imu)),
            (None, 0.0, None),
        ];
        // Simulated as motor times pair (one eigenvalue problem over every cell of the product
        // loses poles).
        m.series = vec![
            (vec![(Expr::p(ik), Expr::cst(0.0))], m.den.clone()),
            (
                vec![
                    (Expr::p(ib2), Expr::cst(2.0)),
                    (Expr::p(id), Expr::p(imu)),
                    (Expr::cst(1.0), Expr::cst(0.0)),
                ],
                vec![
                    (Expr::p(ic2), Expr::cst(2.0)),
                    (Expr::p(id), Expr::p(imu)),
                    (Expr::cst(1.0), Expr::cst(0.0)),
                ],
            ),
        ];
        m.den = vec![];
        for (mc, mo) in &motor_terms {
            for &(pc, po, pmu) in &pair_terms {
                let coef = match (mc, pc) {
                    (Some(a), Some(c)) => Expr::p(*a).times(&[c]),
                    (Some(a), None) => Expr::p(*a),
                    (None, Some(c)) => Expr::p(c),
                    (None, None) => Expr::cst(1.0),
                };
                let mut o = mo.clone();
                o.extend(pmu);
                m.den.push((coef, order(po, &o)));
            }
        }
        m.kind = Kind::TwoMass;
        m
    }

    /// The PMSM structure (paper eq. 10) with a direct feed-through `D`:
    ///
    /// `G(s) = D + K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`,
    ///
    /// an output that responds at once to the input (a battery cell's ohmic drop `R i` beside its
    /// polarisation, a current-loop output, a sensor that sees the command) plus the PMSM's
    /// dynamics. `a1, a2, zeta, theta` as [`FracModel::pmsm`]; `K` and `D` (output over input)
    /// are unbounded in sign: the dynamic path may invert the instant one (`D > 0 > K`: the
    /// output jumps one way and settles the other, a non-minimum-phase-like response). Its transfer function is the sum as one fraction,
    /// `(D a2 s^(zeta+theta) + D a1 s^zeta + D + K) / (a2 s^(zeta+theta) + a1 s^zeta + 1)` (the
    /// numerator's coefficients are products of parameters, [`Expr::factors`]), simulated on the
    /// exact sampled-data path with its feed-through: `y_k = D u_k + (the PMSM's output at t_k)`
    /// for the input held over each step. The high-frequency gain is `D`, the static gain `D + K`.
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let m = FracModel::feedthrough([6.8, 0.006, 2.7e-5, 0.9, 0.8], 0.5);
    /// let tf = m.tf(&m.values()).unwrap();
    /// assert!((tf.dc_gain() - 7.3).abs() < 1e-12);
    /// assert!((tf.freq_response(1e12).re - 0.5).abs() < 1e-6);
    /// ```
    pub fn feedthrough(pmsm: [f64; 5], d: f64) -> Self {
        let [k, a1, a2, zeta, theta] = pmsm;
        let mut m = Self::pmsm(k, a1, a2, zeta, theta);
        let (ik, ia1, ia2) = (0, 1, 2);
        m.params[ik].bounds = Bounds::Free;
        let id = m.add_param(Param::new("D", d, Bounds::Free));
        // D times each denominator term, K added to the constant one. D is the linear part of
        // each product (its unit is that of the coefficient), a1 and a2 its factors.
        m.num = vec![
            (Expr::p(id).times(&[ia2]), m.den[0].1.clone()),
            (Expr::p(id).times(&[ia1]), m.den[1].1.clone()),
            (Expr::sum(&[(ik, 1.0), (id, 1.0)]), Expr::cst(0.0)),
        ];
        m.kind = Kind::Feedthrough;
        m
    }

    /// A battery cell's terminal voltage per current: an ohmic drop, the charge a capacity
    /// integrates, and a polarisation with a constant-phase element (the fractional Randles
    /// circuit, e.g. Zou et al., "A review of fractional-order techniques applied to lithium-ion
    /// batteries", 2018):
    ///
    /// `G(s) = D + Ki/s + K/(a1 s^q + 1)`
    ///
    /// (`D = R0`, `Ki = 1/C`, `K = R1`, `a1 = tau^q`, `q` in `(0, 1)`). `D`, `Ki` and `K` are
    /// unbounded in sign (a discharge current counted positive lowers the voltage). Its transfer
    /// function is the sum as one fraction over `s (a1 s^q + 1)`,
    /// `(D a1 s^(1+q) + (D + K) s + Ki a1 s^q + Ki) / (a1 s^(1+q) + s)`, with a free integrator
    /// ([`FracModel::integrator`]): the input has no operating point and an input offset (a
    /// current sensor's) is its own parameter, the drift it makes.
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let m = FracModel::cell(0.03, 20.0, 0.6, 0.05, 1e-4);
    /// let tf = m.tf(&m.values()).unwrap();
    /// let w = 1e-3;
    /// let want: fracsim::FracTf = "0.05 + 1e-4/s + 0.03/(20 s^0.6 + 1)".parse().unwrap();
    /// assert!((tf.freq_response(w) - want.freq_response(w)).norm() < 1e-12);
    /// ```
    pub fn cell(k: f64, a1: f64, q: f64, d: f64, ki: f64) -> Self {
        let params = vec![
            Param::new("K", k, Bounds::Free),
            Param::positive("a1", a1),
            Param::new("q", q, Bounds::Interval(0.0, 1.0)),
            Param::new("D", d, Bounds::Free),
            Param::new("Ki", ki, Bounds::Free),
        ];
        let (ik, ia1, iq, id, iki) = (0, 1, 2, 3, 4);
        let one_plus_q = Expr {
            constant: 1.0,
            terms: vec![(iq, 1.0)],
            factors: vec![],
        };
        Self {
            params,
            num: vec![
                (Expr::p(id).times(&[ia1]), one_plus_q.clone()),
                (Expr::sum(&[(ik, 1.0), (id, 1.0)]), Expr::cst(1.0)),
                (Expr::p(iki).times(&[ia1]), Expr::p(iq)),
                (Expr::p(iki), Expr::cst(0.0)),
            ],
            den: vec![(Expr::p(ia1), one_plus_q), (Expr::cst(1.0), Expr::cst(1.0))],
            kind: Kind::Cell,
            integrator: true,
            ..Self::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        }
    }

    /// Any fractional transfer function; `free_coefs` and `free_orders` say which of its
    /// coefficients and orders are fitted (coefficients keep their sign: a negative one is
    /// parametrised as `-exp(theta)`; a free order keeps its sign and its neighbourhood, see
    /// [`order_range`]; order-zero terms keep order zero). The delay is fixed at its
    /// value unless [`FracModel::with_delay`] is called.
    pub fn from_tf(tf: &FracTf, free_coefs: bool, free_orders: bool) -> Self {
        let mut m = Self {
            params: vec![],
            num: vec![],
            den: vec![],
            kind: Kind::General,
            ..Self::pmsm(1.0, 1.0, 1.0, 1.0, 1.0)
        };
        let add = |m: &mut Self, terms: &[Term], tag: &str, is_num: bool| {
            for (j, t) in terms.iter().enumerate() {
                let c = m.add_param(Param {
                    name: format!("{tag}{j}"),
                    value: t.coef.abs(),
                    bounds: Bounds::Positive,
                    free: free_coefs && t.coef != 0.0,
                });
                let mut ce = Expr::p(c);
                if t.coef < 0.0 {
                    ce.terms[0].1 = -1.0;
                }
                let oe = if t.order == 0.0 || !free_orders {
                    Expr::cst(t.order)
                } else {
                    let name = format!("{tag}{j}_order");
                    Expr::p(m.add_param(Param::new(&name, t.order, order_range(t.order))))
                };
                if is_num {
                    m.num.push((ce, oe));
                } else {
                    m.den.push((ce, oe));
                }
            }
        };
        add(&mut m, &tf.num, "b", true);
        add(&mut m, &tf.den, "a", false);
        // The denominator's scale is not identifiable together with the numerator's: hold the
        // lowest-order denominator coefficient fixed.
        if let Some((Expr { terms, .. }, _)) = m.den.last() {
            let i = terms[0].0;
            m.params[i].free = false;
        }
        if tf.delay > 0.0 {
            let i = m.add_param(Param::new("tau", tf.delay, Bounds::Positive).fixed());
            m.delay = Some(i);
        }
        m
    }

    /// Add a parameter, returning its index (for [`Expr`]s and [`Effect`]s).
    pub fn add_param(&mut self, p: Param) -> usize {
        self.params.push(p);
        self.params.len() - 1
    }

    /// Add (or reset) a fitted input delay `tau` in `(0, max_delay)` seconds.
    pub fn with_delay(&mut self, tau: f64, max_delay: f64) -> &mut Self {
        let p = Param::new("tau", tau, Bounds::Interval(0.0, max_delay));
        match self.delay {
            Some(i) => self.params[i] = p,
            None => self.delay = Some(self.add_param(p)),
        }
        self
    }

    /// Put a first-order lag `1/(T s + 1)` in series with the linear part, `T` a new positive
    /// parameter started at `t` seconds (returns its index; named `T_lag`, the second `T_lag2`
    /// and so on): the lag becomes a factor of [`FracModel::series`] (the linear part so far the
    /// first, when there was none) and `num`/`den` hold the product multiplied out. `None` (the
    /// model unchanged) for the feed-through and cell structures, whose linear part is written as
    /// a sum.
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
    /// let i = m.with_lag(1e-3).unwrap();
    /// let p = m.values();
    /// let (w, tf) = (300.0, m.tf(&p).unwrap());
    /// let pmsm = fracsim::FracTf::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82).unwrap();
    /// let lag = 1.0 / num_complex::Complex64::new(1.0, w * p[i]);
    /// assert!((tf.freq_response(w) - pmsm.freq_response(w) * lag).norm() < 1e-12);
    /// ```
    pub fn with_lag(&mut self, t: f64) -> Option<usize> {
        if matches!(self.kind, Kind::Feedthrough | Kind::Cell) {
            return None;
        }
        let it = self.add_param(Param::positive(&self.next_name("T_lag"), t));
        self.with_all_pole_factor(&[(Some(it), 1.0), (None, 0.0)]);
        Some(it)
    }

    /// Put a resonant pair `1/(a s^2 + b s + 1)` in series with the linear part (a mode the
    /// structure lacks: `a = 1/w_n^2`, `b = 2 zeta/w_n`), `a` and `b` new positive parameters
    /// started at the values given (returns their indices; named `a_mode`, `b_mode`, the second
    /// `a_mode2`, `b_mode2` and so on), as [`FracModel::with_lag`] puts a lag. `None` (the model
    /// unchanged) for the feed-through and cell structures.
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
    /// let (ia, ib) = m.with_mode(1e-6, 4e-4).unwrap();
    /// let p = m.values();
    /// let (w, tf) = (300.0, m.tf(&p).unwrap());
    /// let pmsm = fracsim::FracTf::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82).unwrap();
    /// let mode = 1.0 / num_complex::Complex64::new(1.0 - p[ia] * w * w, p[ib] * w);
    /// assert!((tf.freq_response(w) - pmsm.freq_response(w) * mode).norm() < 1e-12);
    /// ```
    pub fn with_mode(&mut self, a: f64, b: f64) -> Option<(usize, usize)> {
        if matches!(self.kind, Kind::Feedthrough | Kind::Cell) {
            return None;
        }
        let ia = self.add_param(Param::positive(&self.next_name("a_mode"), a));
        let ib = self.add_param(Param::positive(&self.next_name("b_mode"), b));
        self.with_all_pole_factor(&[(Some(ia), 2.0), (Some(ib), 1.0), (None, 0.0)]);
        Some((ia, ib))
    }

    /// `stem` for the first parameter so named, then `stem2`, `stem3` and so on.
    fn next_name(&self, stem: &str) -> String {
        let n = 1 + self
            .params
            .iter()
            .filter(|p| p.name.starts_with(stem))
            .count();
        if n == 1 {
            stem.to_string()
        } else {
            format!("{stem}{n}")
        }
    }

    /// Put the all-pole factor `1/sum_k c_k s^(n_k)` in series with the linear part, each term
    /// `(c_k, n_k)` a parameter's index (`None`: the constant 1) and an integer order: the factor
    /// joins [`FracModel::series`] (the linear part so far the first, without the integrator,
    /// which the simulation adds to it, when there was none) and `den` holds the product
    /// multiplied out.
    fn with_all_pole_factor(&mut self, factor: &[(Option<usize>, f64)]) {
        if self.series.is_empty() {
            let lowered = if self.integrator { 1.0 } else { 0.0 };
            let den = self
                .den
                .iter()
                .map(|(c, o)| {
                    let mut o = o.clone();
                    o.constant -= lowered;
                    (c.clone(), o)
                })
                .collect();
            self.series.push((self.num.clone(), den));
        }
        let coef = |k: Option<usize>| k.map_or(Expr::cst(1.0), Expr::p);
        self.series.push((
            vec![(Expr::cst(1.0), Expr::cst(0.0))],
            factor
                .iter()
                .map(|&(k, n)| (coef(k), Expr::cst(n)))
                .collect(),
        ));
        let mut den = Vec::with_capacity(factor.len() * self.den.len());
        for (c, o) in &self.den {
            for &(k, n) in factor {
                let mut raised = o.clone();
                raised.constant += n;
                let c = match k {
                    Some(i) => c.clone().times(&[i]),
                    None => c.clone(),
                };
                den.push((c, raised));
            }
        }
        self.den = den;
    }

    /// Estimate the initial state as a past held input on windows ending `edges` seconds before
    /// the first sample ([`PastInput`]): the levels `u_past0 ..`, input deviations kept within
    /// `range` (a past the input could have had: see [`past_range`]), start at 0; levels already
    /// present are reset to 0 with the new range (and the new edges when their number matches).
    pub fn with_past_input(&mut self, edges: Vec<f64>, range: (f64, f64)) -> &mut Self {
        let bounds = Bounds::Interval(range.0, range.1);
        if let Some(mut old) = self.past.take() {
            for &i in &old.levels {
                self.params[i].value = 0.0;
                self.params[i].bounds = bounds;
            }
            if old.levels.len() == edges.len() + 1 {
                old.edges = edges;
            }
            self.past = Some(old);
            return self;
        }
        let levels = (0..=edges.len())
            .map(|j| self.add_param(Param::new(&format!("u_past{j}"), 0.0, bounds)))
            .collect();
        self.past = Some(PastInput { edges, levels });
        self
    }

    /// Put a free integrator in series, `G(s)/s`, for an output that integrates (a position
    /// measured where the model is of the speed): every denominator order is raised by one.
    /// Idempotent.
    ///
    /// ```
    /// use ident::oe::FracModel;
    /// let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.92, 0.82);
    /// m.with_integrator();
    /// assert_eq!(m.tf(&m.values()).unwrap().to_string().contains("s^1.92"), true);
    /// ```
    pub fn with_integrator(&mut self) -> &mut Self {
        if !self.integrator {
            for (_, o) in &mut self.den {
                o.constant += 1.0;
            }
            self.integrator = true;
        }
        self
    }

    /// Whether parameter `i` describes the record (its initial state) rather than the plant.
    pub fn is_initial_state(&self, i: usize) -> bool {
        self.past.as_ref().is_some_and(|p| p.levels.contains(&i))
    }

    /// The model without its effect `k` (an index into [`FracModel::effects`]) and that effect's
    /// parameters, every other parameter renumbered; beside it, the old index of each parameter
    /// left (`values[kept[i]]` is the new model's parameter `i`).
    pub fn without_effect(&self, k: usize) -> (FracModel, Vec<usize>) {
        let mut m = self.clone();
        let gone = m.effects.remove(k).params();
        m.without_params(&gone)
    }

    /// The model without the parameters `gone`, which nothing in it refers to any more (a term or
    /// an effect removed first), every other parameter renumbered; beside it, the old index of
    /// each parameter left (`values[kept[i]]` is the new model's parameter `i`).
    ///
    /// # Panics
    /// When a parameter of `gone` is still referred to.
    pub fn without_params(&self, gone: &[usize]) -> (FracModel, Vec<usize>) {
        let kept: Vec<usize> = (0..self.params.len())
            .filter(|i| !gone.contains(i))
            .collect();
        let to = |i: usize| {
            kept.iter()
                .position(|&o| o == i)
                .expect("a removed parameter still referred to")
        };
        let expr = |e: &Expr| Expr {
            constant: e.constant,
            terms: e.terms.iter().map(|&(i, f)| (to(i), f)).collect(),
            factors: e.factors.iter().map(|&i| to(i)).collect(),
        };
        let terms = |t: &[(Expr, Expr)]| -> Vec<(Expr, Expr)> {
            t.iter().map(|(c, o)| (expr(c), expr(o))).collect()
        };
        let mut m = self.clone();
        m.params = kept.iter().map(|&o| self.params[o].clone()).collect();
        m.num = terms(&self.num);
        m.den = terms(&self.den);
        m.series = self
            .series
            .iter()
            .map(|(n, d)| (terms(n), terms(d)))
            .collect();
        m.delay = self.delay.map(to);
        m.effects = self.effects.iter().map(|e| e.renumbered(to)).collect();
        if let Some(p) = &mut m.past {
            p.levels = p.levels.iter().map(|&i| to(i)).collect();
        }
        (m, kept)
    }

    /// Add a fitted constant output offset (returns its parameter index).
    pub fn with_output_offset(&mut self, c: f64) -> usize {
        let i = self.add_param(Param::new("y_offset", c, Bounds::Free));
        self.effects.push(Effect::OutputOffset { c: i });
        i
    }

    /// Hold the parameter `name` fixed (at `value` when given), or free it (`fixed = false`).
    ///
    /// # Errors
    /// [`Error::Options`] for no parameter of that name (the message lists them), or a value
    /// outside its range.
    pub fn set_fixed(&mut self, name: &str, fixed: bool, value: Option<f64>) -> Result<()> {
        let Some(i) = self.index_of(name) else {
            let names: Vec<&str> = self.params.iter().map(|p| p.name.as_str()).collect();
            return Err(Error::Options(format!(
                "no parameter '{name}': the model has {}",
                names.join(", ")
            )));
        };
        let p = &mut self.params[i];
        if let Some(v) = value {
            p.bounds.to_theta(v, name)?;
            p.value = v;
        }
        p.free = !fixed;
        Ok(())
    }

    /// Index of the parameter called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }

    /// The linear part as a [`FracTf`] for parameter values `p` (effects not included).
    ///
    /// # Errors
    /// As [`FracTf::new`].
    pub fn tf(&self, p: &[f64]) -> Result<FracTf> {
        let terms = |t: &[(Expr, Expr)]| -> Vec<Term> {
            t.iter()
                .map(|(c, o)| Term::new(c.eval(p), o.eval(p)))
                .collect()
        };
        let delay = self.delay.map_or(0.0, |i| p[i]);
        let whole = FracTf::new(terms(&self.num), terms(&self.den), delay)?;
        if self.kind == Kind::Feedthrough && !self.integrator {
            // Written `D + K/(..)` (the parser reads it back as the fraction).
            if let Some(i) = self.index_of("D") {
                return Ok(whole.clone().with_direct(p[i]).unwrap_or(whole));
            }
        }
        if self.series.is_empty() {
            return Ok(whole);
        }
        // Known as its factors (the simulators' way when the product multiplied out fails, and
        // the text written), the integrator in the first.
        let mut factors = vec![];
        for (i, (n, d)) in self.series.iter().enumerate() {
            let mut d = terms(d);
            if i == 0 && self.integrator {
                d.iter_mut().for_each(|t| t.order += 1.0);
            }
            factors.push(FracTf::new(terms(n), d, 0.0)?);
        }
        Ok(whole.clone().with_factors(factors).unwrap_or(whole))
    }

    /// The current parameter values.
    pub fn values(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.value).collect()
    }

    /// The non-integer orders of the linear part with the Poinot-Trigeassou `(alpha, eta)` of
    /// the integrator `I_(1-f)` of their fractional part `f` (Poinot & Trigeassou 2004), for the
    /// band and order of [`FracModel::approx`] at step `dt`.
    pub fn alpha_eta(&self, p: &[f64], dt: f64) -> Vec<(f64, f64, f64)> {
        let Ok((w_b, w_h)) = self.approx.band_for(dt) else {
            return vec![];
        };
        let n = self.approx.order.max(1);
        let mut out = vec![];
        for (_, o) in self.num.iter().chain(&self.den) {
            let nu = o.eval(p);
            let f = nu - nu.floor();
            if f > 1e-12 {
                if let Ok((a, e)) = fracsim::approx::alpha_eta(1.0 - f, w_b, w_h, n) {
                    out.push((nu, a, e));
                }
            }
        }
        out
    }
}

/// How the output of a [`FracModel`] is linear in a parameter ([`Structure::is_linear`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Linear {
    /// A constant output offset: `d yhat/d c = 1`.
    Offset,
    /// The factor of the only numerator term: `yhat - offsets = K G0(u, past)`, so
    /// `d yhat/d K = (yhat - offsets)/K`.
    Gain,
    /// Level `i` of the initial state: its free response (input zero, that level one).
    Level(usize),
}

impl FracModel {
    /// How many times parameter `j` appears in the model (coefficients, orders, delay, effects,
    /// initial state).
    fn uses(&self, j: usize) -> usize {
        let expr = |e: &Expr| {
            e.terms.iter().filter(|&&(i, _)| i == j).count()
                + e.factors.iter().filter(|&&i| i == j).count()
        };
        let terms: usize = self
            .num
            .iter()
            .chain(&self.den)
            .map(|(c, o)| expr(c) + expr(o))
            .sum();
        let effects = self
            .effects
            .iter()
            .filter(|e| e.params().contains(&j))
            .count();
        let past = self
            .past
            .as_ref()
            .map_or(0, |p| p.levels.iter().filter(|&&i| i == j).count());
        terms + effects + past + usize::from(self.delay == Some(j))
    }

    /// How the output is linear in parameter `j`, if it is in a way computed without duals. Only
    /// for models whose effects are all output offsets (the default `fracid time` model): any
    /// other effect may couple the output back into the input.
    fn linearity(&self, j: usize) -> Option<Linear> {
        if !self
            .effects
            .iter()
            .all(|e| matches!(e, Effect::OutputOffset { .. }))
            || self.uses(j) != 1
        {
            return None;
        }
        if self
            .effects
            .iter()
            .any(|e| matches!(*e, Effect::OutputOffset { c } if c == j))
        {
            return Some(Linear::Offset);
        }
        if let Some(i) = self
            .past
            .as_ref()
            .and_then(|p| p.levels.iter().position(|&l| l == j))
        {
            return Some(Linear::Level(i));
        }
        match self.num.as_slice() {
            [(c, _)]
                if c.constant == 0.0
                    && c.terms.len() == 1
                    && c.terms[0].0 == j
                    && c.factors.is_empty() =>
            {
                Some(Linear::Gain)
            }
            _ => None,
        }
    }

    /// The simulator of the linear part at `p` (from rest): of `num/den`, or of the factors of
    /// [`FracModel::series`].
    pub(crate) fn simulator<T: Real>(&self, p: &[T], dt: f64) -> Result<Simulator<T>> {
        let terms = |t: &[(Expr, Expr)]| -> Vec<(T, T)> {
            t.iter().map(|(c, o)| (c.eval(p), o.eval(p))).collect()
        };
        let delay = self.delay.map_or(T::from(0.0), |i| p[i]);
        if !self.series.is_empty() {
            let mut factors: Vec<fracsim::discrete::Factor<T>> = self
                .series
                .iter()
                .map(|(n, d)| (terms(n), terms(d)))
                .collect();
            if self.integrator {
                for (_, o) in &mut factors[0].1 {
                    *o += T::from(1.0);
                }
            }
            return Ok(Simulator::from_factors(&factors, delay, dt, &self.approx)?);
        }
        Ok(Simulator::from_terms(
            &terms(&self.num),
            &terms(&self.den),
            delay,
            dt,
            &self.approx,
        )?)
    }

    /// The factor parameter `j` takes when the input is scaled by `su` and the output by `sy`
    /// (its unit): `sy/su` for a numerator coefficient, `su` for an input level (input offset,
    /// friction, saturation, dead zone, initial-state level), `sy` for an output one (output
    /// offset, ripple amplitudes, drift rate; [`Effect::param_scale`]), 1 for denominator
    /// coefficients (the denominator's constant is fixed), orders, the delay and the power law's
    /// exponent; `None` when it plays parts of different units.
    pub fn unit_scale(&self, j: usize, su: f64, sy: f64) -> Option<f64> {
        let mut f: Vec<f64> = vec![];
        let has = |e: &Expr| e.terms.iter().any(|&(i, _)| i == j);
        for (c, o) in &self.num {
            if has(c) {
                f.push(sy / su);
            }
            // A factor of a product is dimensionless (see `Expr::factors`).
            if has(o) || c.factors.contains(&j) {
                f.push(1.0);
            }
        }
        for (c, o) in &self.den {
            if c.has(j) || has(o) {
                f.push(1.0);
            }
        }
        if self.delay == Some(j) {
            f.push(1.0);
        }
        if self.is_initial_state(j) {
            f.push(su);
        }
        for e in self.effects.iter().filter(|e| e.params().contains(&j)) {
            f.push(e.param_scale(su, sy));
        }
        match f.first() {
            None => Some(1.0),
            Some(&x) if f.iter().all(|&v| v == x) => Some(x),
            Some(_) => None,
        }
    }

    /// The sum of squares of `y - yhat` over the samples of `y`, `yhat` the model output at `p`
    /// on `u` ([`Structure::simulate`]), or `None` when it is at least `limit` or the output is not
    /// finite. For a search that keeps the smallest sum (the delay probe's grid): the output is
    /// simulated [`PARTS_CHUNK`] samples at a time (the simulator runs on from its state, the
    /// output effects by sample index: the same outputs as one run) and the sum, accumulated in
    /// sample order as a plain sum is, given up as soon as it reaches `limit` (its terms are not
    /// negative, so it cannot end below). A model with input effects is simulated whole.
    ///
    /// # Errors
    /// As [`Structure::simulate`], when the model cannot be simulated at all.
    pub fn ssr_below(
        &self,
        p: &[f64],
        u: &[f64],
        y: &[f64],
        dt: f64,
        limit: f64,
    ) -> Result<Option<f64>> {
        let n = y.len().min(u.len());
        let mut acc = 0.0;
        if self.effects.iter().any(|e| e.is_input()) {
            let mut whole = vec![0.0; n];
            if self.simulate(p, &u[..n], dt, &mut whole).is_err() {
                return Ok(None);
            }
            for (a, b) in y.iter().zip(&whole) {
                acc += (a - b) * (a - b);
            }
            return Ok((acc < limit).then_some(acc));
        }
        let sim = self.sim_at_start(p, dt)?;
        Ok(self.ssr_chunked(sim, p, u, y, dt, limit))
    }

    /// The linear part's modal form at `p` ([`FracModel::simulator`]'s poles and residues, the
    /// same whatever the delay): built once for a grid of sums ([`FracModel::ssr_below_on`]).
    ///
    /// # Errors
    /// As [`FracModel::simulator`].
    pub(crate) fn plant(&self, p: &[f64], dt: f64) -> Result<fracsim::modal::PoleResidue<f64>> {
        Ok(self.simulator(p, dt)?.model().clone())
    }

    /// [`FracModel::ssr_below`] with the linear part's modal form `plant` given
    /// ([`FracModel::plant`] of a model that differs from `self` at most in its delay): only the
    /// held input's weights for the delay `p[tau]` and the initial state are computed, the
    /// discretisation being the one [`FracModel::simulator`] makes of the same modal form, so the
    /// sum is the same bit for bit. A model with input effects is simulated whole, as there.
    ///
    /// # Errors
    /// As [`FracModel::ssr_below`].
    pub(crate) fn ssr_below_on(
        &self,
        plant: &fracsim::modal::PoleResidue<f64>,
        p: &[f64],
        u: &[f64],
        y: &[f64],
        dt: f64,
        limit: f64,
    ) -> Result<Option<f64>> {
        if self.effects.iter().any(|e| e.is_input()) {
            return self.ssr_below(p, u, y, dt, limit);
        }
        let delay = self.delay.map_or(0.0, |i| p[i]);
        let mut sim = Simulator::from_pole_residue(plant.clone(), delay, dt)?;
        self.set_start(&mut sim, p)?;
        Ok(self.ssr_chunked(sim, p, u, y, dt, limit))
    }

    /// The chunked, given-up-early sum of [`FracModel::ssr_below`] from the simulator `sim` at
    /// the start (a model without input effects).
    fn ssr_chunked(
        &self,
        mut sim: Simulator<f64>,
        p: &[f64],
        u: &[f64],
        y: &[f64],
        dt: f64,
        limit: f64,
    ) -> Option<f64> {
        let n = y.len().min(u.len());
        let mut yhat = vec![0.0; n.min(PARTS_CHUNK)];
        let mut acc = 0.0;
        let mut k0 = 0;
        while k0 < n {
            let k1 = (k0 + PARTS_CHUNK).min(n);
            let part = &mut yhat[..k1 - k0];
            sim.run_into(&u[k0..k1], part);
            self.output_effects(p, dt, k0, part);
            if check_output(part, k0).is_err() {
                return None;
            }
            for (a, b) in y[k0..k1].iter().zip(part.iter()) {
                acc += (a - b) * (a - b);
            }
            if acc >= limit {
                return None;
            }
            k0 = k1;
        }
        (acc < limit).then_some(acc)
    }

    /// The simulator at `p` in the initial state (the past input's, or rest).
    fn sim_at_start<T: Real>(&self, p: &[T], dt: f64) -> Result<Simulator<T>> {
        let mut sim = self.simulator(p, dt)?;
        self.set_start(&mut sim, p)?;
        Ok(sim)
    }

    /// `sim` (at rest) put in the initial state at `p`: the past input's, if any.
    fn set_start<T: Real>(&self, sim: &mut Simulator<T>, p: &[T]) -> Result<()> {
        if let Some(past) = &self.past {
            let levels: Vec<T> = past.levels.iter().map(|&i| p[i]).collect();
            sim.set_past_input(&levels, &past.edges)?;
        }
        Ok(())
    }

    /// The output effects (none of them an input effect) applied to the linear part's outputs
    /// `y` of samples `k0..k0 + y.len()`.
    fn output_effects<T: Real>(&self, p: &[T], dt: f64, k0: usize, y: &mut [T]) {
        if self.effects.is_empty() {
            return;
        }
        let y0 = self.operating_point.y0;
        if self
            .effects
            .iter()
            .all(|e| matches!(e, Effect::OutputOffset { .. }))
        {
            // Output offsets only (the fitted constant): one addition a sample.
            let c = self.effects.iter().fold(T::from(0.0), |a, e| match *e {
                Effect::OutputOffset { c } => a + p[c],
                _ => a,
            });
            y.iter_mut().for_each(|yk| *yk += c);
            return;
        }
        for (k, yk) in (k0..).zip(y.iter_mut()) {
            let t = k as f64 * dt;
            let mut ya = *yk + y0;
            for e in &self.effects {
                ya = e.output(p, ya, t);
            }
            *yk = ya - y0;
        }
    }

    /// Whether the model has input effects and every one is a static map of the held input
    /// ([`Effect::is_static_input`]): nothing feeds the output back into the input.
    fn static_input(&self) -> bool {
        let mut inputs = self.effects.iter().filter(|e| e.is_input()).peekable();
        inputs.peek().is_some() && inputs.all(Effect::is_static_input)
    }

    /// The input of a model whose input effects are static maps of the held input
    /// ([`FracModel::static_input`]: offsets, saturation, dead zone, power law): nothing feeds
    /// the output back, so the linear part runs in the vectorised kernel on the mapped input's
    /// values `map(u0 + u_k) - u0` (rounded as the per-sample path rounds them), and each
    /// derivative part of the mapped input (the maps' dual parameters) adds the value model's
    /// response from rest to that part's series: `y` is linear in the input, and the maps act
    /// from `t_0 = 0` (the initial state's past input has parameters of its own). A part that is
    /// the same at every sample (an offset's) is that constant times the unit step response.
    fn mapped_input<T: Real>(&self, p: &[T], u: &[f64], dt: f64) -> Result<MappedInput> {
        let u0 = self.operating_point.u0;
        let parts = T::derivs_of(()).as_ref().len();
        let mut input = Vec::with_capacity(u.len());
        let mut series: Vec<Vec<f64>> = vec![Vec::with_capacity(u.len()); parts];
        for (k, &uk) in u.iter().enumerate() {
            let t = k as f64 * dt;
            let ua = self
                .effects
                .iter()
                .fold(T::from(u0 + uk), |a, e| e.input(p, a, T::from(0.0), t));
            input.push(ua.re() - u0);
            for (s, &d) in series.iter_mut().zip(ua.derivs().as_ref()) {
                s.push(d);
            }
        }
        let values: Vec<f64> = p.iter().map(|v| v.re()).collect();
        let rest = || self.simulator::<f64>(&values, dt);
        let mut step: Option<Vec<f64>> = None;
        let mut responses = vec![];
        for (r, s) in series.iter().enumerate() {
            let Some(&first) = s.first() else { continue };
            if s.iter().all(|&d| d == 0.0) {
                continue;
            }
            let response = if s.iter().all(|&d| d == first) {
                if step.is_none() {
                    let mut y = vec![0.0; u.len()];
                    rest()?.run_into(&vec![1.0; u.len()], &mut y);
                    step = Some(y);
                }
                step.as_ref()
                    .map_or_else(Vec::new, |y| y.iter().map(|v| first * v).collect())
            } else {
                let mut y = vec![0.0; u.len()];
                rest()?.run_into(s, &mut y);
                y
            };
            responses.push((r, response));
        }
        Ok(MappedInput { input, responses })
    }

    /// [`Structure::linear_sensitivities`], the levels' free responses from `rest` (the model
    /// at `p` from rest) when given.
    #[allow(clippy::too_many_arguments)]
    fn linear_sensitivities_with(
        &self,
        p: &[f64],
        which: &[usize],
        u: &[f64],
        dt: f64,
        yhat: &[f64],
        skip: usize,
        out: &mut [&mut [f64]],
        rest: Option<Simulator<f64>>,
    ) -> Result<()> {
        // The levels' columns: free responses, all in one pass.
        let mut levels: Vec<Vec<f64>> = vec![];
        let mut level_cols: Vec<&mut [f64]> = vec![];
        for (&j, col) in which.iter().zip(out.iter_mut()) {
            match self.linearity(j) {
                None => {
                    return Err(Error::Options(format!(
                        "the output is not linear in {}",
                        self.params[j].name
                    )))
                }
                Some(Linear::Offset) => col.iter_mut().for_each(|v| *v = 1.0),
                Some(Linear::Gain) if p[j] != 0.0 => {
                    let (c, k) = (self.offsets_sum(p), p[j]);
                    for (v, &yk) in col.iter_mut().zip(&yhat[skip..]) {
                        *v = (yk - c) / k;
                    }
                }
                Some(Linear::Gain) => {
                    let mut q = p.to_vec();
                    q[j] = 1.0;
                    let mut y = vec![0.0; u.len()];
                    self.simulate(&q, u, dt, &mut y)?;
                    let c = self.offsets_sum(p);
                    for (v, yk) in col.iter_mut().zip(&y[skip..]) {
                        *v = yk - c;
                    }
                }
                Some(Linear::Level(i)) => {
                    let Some(past) = &self.past else {
                        unreachable!("a level is a level of the past input")
                    };
                    let mut unit = vec![0.0; past.levels.len()];
                    unit[i] = 1.0;
                    levels.push(unit);
                    level_cols.push(&mut **col);
                }
            }
        }
        if let (Some(past), false) = (&self.past, levels.is_empty()) {
            let mut rest = match rest {
                Some(sim) => sim,
                None => self.simulator(p, dt)?,
            };
            rest.free_responses(&levels, &past.edges, skip, &mut level_cols)?;
        }
        Ok(())
    }

    /// The sum of the output offsets at `p`.
    fn offsets_sum(&self, p: &[f64]) -> f64 {
        self.effects
            .iter()
            .map(|e| match *e {
                Effect::OutputOffset { c } => p[c],
                _ => 0.0,
            })
            .sum()
    }
}

/// The mapped input of a model whose input effects are static maps
/// ([`FracModel::mapped_input`]).
struct MappedInput {
    /// `map(u0 + u_k) - u0` (values).
    input: Vec<f64>,
    /// Per derivative part with a nonzero series: its index and the value model's response to it.
    responses: Vec<(usize, Vec<f64>)>,
}

impl MappedInput {
    /// Add the maps' derivative parts to the outputs `y` of samples `k0..k0 + y.len()`.
    fn add_parts<T: Real>(&self, k0: usize, y: &mut [T]) {
        for (r, response) in &self.responses {
            for (yk, &sk) in y.iter_mut().zip(&response[k0..]) {
                let mut d = yk.derivs();
                d.as_mut()[*r] += sk;
                *yk = T::from_parts(yk.re(), d);
            }
        }
    }
}

impl Structure for FracModel {
    fn params(&self) -> &[Param] {
        &self.params
    }

    fn is_linear(&self, j: usize) -> bool {
        self.linearity(j).is_some()
    }

    fn linear_role(&self, j: usize) -> Option<LinearRole> {
        self.linearity(j).map(|l| match l {
            Linear::Offset => LinearRole::Offset,
            Linear::Gain => LinearRole::Gain,
            Linear::Level(_) => LinearRole::Level,
        })
    }

    fn linear_sensitivities(
        &self,
        p: &[f64],
        which: &[usize],
        u: &[f64],
        dt: f64,
        yhat: &[f64],
        skip: usize,
        out: &mut [&mut [f64]],
    ) -> Result<()> {
        self.linear_sensitivities_with(p, which, u, dt, yhat, skip, out, None)
    }

    fn simulate_with_linear(
        &self,
        p: &[f64],
        which: &[usize],
        u: &[f64],
        dt: f64,
        yhat: &mut [f64],
        skip: usize,
        out: &mut [&mut [f64]],
    ) -> Result<()> {
        if self.effects.iter().any(|e| e.is_input()) {
            self.simulate(p, u, dt, yhat)?;
            return self.linear_sensitivities(p, which, u, dt, yhat, skip, out);
        }
        // As `simulate` without input effects, the model built once for the output and the
        // levels' free responses.
        let rest = self.simulator(p, dt)?;
        let mut sim = rest.clone();
        if let Some(past) = &self.past {
            let levels: Vec<f64> = past.levels.iter().map(|&i| p[i]).collect();
            sim.set_past_input(&levels, &past.edges)?;
        }
        sim.run_into(u, yhat);
        self.output_effects(p, dt, 0, yhat);
        check_output(yhat, 0)?;
        self.linear_sensitivities_with(p, which, u, dt, yhat, skip, out, Some(rest))
    }

    fn simulate_parts<const N: usize>(
        &self,
        p: &[Dual<N>],
        u: &[f64],
        dt: f64,
        yhat: &mut [f64],
        cols: &mut [&mut [f64]],
    ) -> Result<()> {
        let mapped = if self.effects.iter().all(|e| !e.is_input()) {
            None
        } else if self.static_input() {
            Some(self.mapped_input(p, u, dt)?)
        } else {
            return parts_through_vec(self, p, u, dt, yhat, cols);
        };
        // As `simulate` without input effects (or with static input maps only, on the mapped
        // input), a chunk of samples at a time into a small buffer, whose parts go straight to
        // `yhat` and `cols` (no record-long dual output).
        let mut sim = self.sim_at_start(p, dt)?;
        let mut buf = vec![Dual::<N>::cst(0.0); PARTS_CHUNK.min(u.len())];
        let mut k0 = 0;
        while k0 < u.len() {
            let k1 = (k0 + PARTS_CHUNK).min(u.len());
            let y = &mut buf[..k1 - k0];
            match &mapped {
                None => sim.run_into(&u[k0..k1], y),
                Some(m) => {
                    sim.run_into(&m.input[k0..k1], y);
                    m.add_parts(k0, y);
                }
            }
            self.output_effects(p, dt, k0, y);
            check_output(y, k0)?;
            split_parts(y, k0, yhat, cols);
            k0 = k1;
        }
        Ok(())
    }

    fn simulate<T: Real>(&self, p: &[T], u: &[f64], dt: f64, y: &mut [T]) -> Result<()> {
        let mapped = if self.static_input() {
            Some(self.mapped_input(p, u, dt)?)
        } else {
            None
        };
        let mut sim = self.sim_at_start(p, dt)?;
        let (u0, y0) = (self.operating_point.u0, self.operating_point.y0);
        if let Some(m) = &mapped {
            // Static input maps only: the linear part runs on the mapped input at once.
            sim.run_into(&m.input, y);
            m.add_parts(0, y);
            self.output_effects(p, dt, 0, y);
        } else if self.effects.iter().all(|e| !e.is_input()) {
            // No input effect: nothing feeds the output back, so the linear part runs on the
            // whole input at once (the vectorised kernel) and the output effects follow.
            sim.run_into(u, y);
            self.output_effects(p, dt, 0, y);
        } else {
            // Input effects that depend on the output (friction) see the speed the plant puts
            // out (the output effects before a sign-blind sensor, which rectifies the speed the
            // friction acts on): at `t_k` (known before `u_k` acts when the model has no
            // feed-through) for a friction decided at the sample instant, or extrapolated to the
            // middle of the hold interval, `y_k + (y_k - y_(k-1))/2`; without the output at
            // `t_k` (a feed-through), `y_(k-1)`.
            let sensor = self.effects.iter().position(|e| *e == Effect::AbsSensor);
            let upto = |ya: T, t: f64, n: usize| {
                let mut ya = ya;
                for e in &self.effects[..n] {
                    ya = e.output(p, ya, t);
                }
                ya
            };
            let out = |ya: T, t: f64| upto(ya, t, self.effects.len());
            let speed = |ya: T, t: f64| upto(ya, t, sensor.unwrap_or(self.effects.len()));
            let mut y_prev = T::from(y0);
            for (k, (yk, &uk)) in y.iter_mut().zip(u).enumerate() {
                let t = k as f64 * dt;
                let (at_sample, middle) = match sim.next_output() {
                    Some(now) if k > 0 => {
                        let now = speed(now + y0, t);
                        (now, now + (now - y_prev) * 0.5)
                    }
                    Some(now) => {
                        let now = speed(now + y0, t);
                        (now, now)
                    }
                    None => (y_prev, y_prev),
                };
                let mut ua = T::from(u0 + uk);
                for e in &self.effects {
                    let seen = match e {
                        Effect::Coulomb { sampled: true, .. } => at_sample,
                        _ => middle,
                    };
                    ua = e.input(p, ua, seen, t);
                }
                let x = sim.step(ua - u0) + y0;
                let ya = out(x, t);
                y_prev = if sensor.is_some() { speed(x, t) } else { ya };
                *yk = ya - y0;
            }
        }
        check_output(y, 0)
    }
}

/// [`ApproxSpec`] (fracsim's types have no serde) as `{"method": "refined", "band": [lo, hi] | null,
/// "order": 8}`, so that a [`FracModel`] round-trips through a report's JSON.
mod approx_serde {
    use fracsim::ApproxSpec;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    struct Spec {
        method: String,
        band: Option<(f64, f64)>,
        order: usize,
    }

    pub(super) fn serialize<S: Serializer>(a: &ApproxSpec, s: S) -> Result<S::Ok, S::Error> {
        Spec {
            method: a.method.to_string(),
            band: a.band,
            order: a.order,
        }
        .serialize(s)
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<ApproxSpec, D::Error> {
        let spec = Spec::deserialize(d)?;
        Ok(ApproxSpec {
            method: spec.method.parse().map_err(serde::de::Error::custom)?,
            band: spec.band,
            order: spec.order,
        })
    }
}
