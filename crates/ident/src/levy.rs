//! Frequency-domain identification of fractional transfer functions from Bode data.
//!
//! The model (commensurate order `q`):
//!
//! `Ghat(jw) = N(jw)/D(jw)`, `N = sum_{u=0..m} b_u (jw)^(u q)`, `D = 1 + sum_{p=1..n} a_p (jw)^(p q)`,
//!
//! with `omega` in rad/s and `(jw)^a = w^a (cos(a pi/2) + j sin(a pi/2))`.
//!
//! - [`levy_fixed_q`]: Levy's (1959) linearised least squares for a fixed `q`: minimise
//!   `sum_g w_g |G(jw_g) D(jw_g) - N(jw_g)|^2`, linear in `(b, a)`, solved as the stacked real and
//!   imaginary system with column scaling by Householder QR, never by the normal
//!   equations (their condition number is about 3e7 on the paper's Table 1).
//! - Weights ([`Weights`]): Vinagre's (2001, the paper's eq. 29)
//!   `w_1 = (w_2 - w_1)/(2 w_1^2)`, `w_g = (w_{g+1} - w_{g-1})/(2 w_g^2)`, `w_f = (w_f - w_{f-1})/(2 w_f^2)`
//!   ([`vinagre_weights`]), none, or per point.
//! - Sanathanan & Koerner (1963) iterations: refit with weights `w_g / |D_prev(jw_g)|^2`, which
//!   removes the `|D|^2` bias of Levy's linearisation; at most the number asked, stopped once
//!   converged ([`SK_PARAM_TOL`], [`SK_COST_TOL`]).
//! - [`search_q`]: the order `q` on a grid over `(0, q_max]` (step 0.01, as the paper) then a
//!   golden-section refinement of `J(q)` around the best grid point; the `J(q)` curve is kept.
//! - [`refine::refine_pmsm`]: a nonlinear least-squares refit (Levenberg-Marquardt, [`crate::lm`])
//!   of the PMSM structure with two free orders `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)` started
//!   from a Levy fit, minimising the complex output error.
//! - [`fit_bode`]: all of the above in one call, as `fracid freq` and the Python bindings use it.
//!
//! Every fit is scored by the error index of the paper's eq. 30 ([`error_index`]):
//! `J = (1/f) sum_g |G(jw_g) - Ghat(jw_g)|^2`, omega in rad/s.
//!
//! ```
//! use ident::levy::{fit_bode, FreqOptions};
//! use fracsim::FracTf;
//! let truth = FracTf::pmsm(3.0, 0.05, 0.002, 0.8, 0.8).unwrap();
//! let omega: Vec<f64> = (0..30).map(|i| 10f64.powf(-1.0 + 4.0 * i as f64 / 29.0)).collect();
//! let h = truth.bode(&omega);
//! let fit = fit_bode(&omega, &h, &FreqOptions::default()).unwrap();
//! assert!((fit.levy.q - 0.8).abs() < 1e-3);
//! assert!(fit.levy.j < 1e-10);
//! ```

pub mod checks;
pub mod refine;

use crate::linalg::LstsqWork;
use crate::numeric::dot;
use crate::{Error, Result};
use fracsim::{FracTf, Term};
use num_complex::Complex64;
use std::f64::consts::FRAC_PI_2;

pub use refine::{refine_pmsm, PmsmFit, RefineOptions};

/// Weights of the Levy least squares.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Weights {
    /// Vinagre's weights, the paper's eq. 29 ([`vinagre_weights`]). The default.
    #[default]
    Vinagre,
    /// All weights 1 (Levy's original method).
    Uniform,
    /// One non-negative weight per point.
    PerPoint(Vec<f64>),
}

impl Weights {
    /// The weight of each point for `omega` (rad/s, validated).
    ///
    /// # Errors
    /// [`Error::Data`] for per-point weights of the wrong length, negative or non-finite, or all zero.
    pub fn values(&self, omega_rad_s: &[f64]) -> Result<Vec<f64>> {
        match self {
            Self::Vinagre => Ok(vinagre_weights(omega_rad_s)),
            Self::Uniform => Ok(vec![1.0; omega_rad_s.len()]),
            Self::PerPoint(w) => {
                if w.len() != omega_rad_s.len() {
                    return Err(Error::Data(format!(
                        "{} weights for {} frequency points",
                        w.len(),
                        omega_rad_s.len()
                    )));
                }
                if let Some(i) = w.iter().position(|v| !v.is_finite() || *v < 0.0) {
                    return Err(Error::Data(format!(
                        "weight {} (point {}) must be finite and >= 0",
                        w[i],
                        i + 1
                    )));
                }
                if w.iter().all(|v| *v == 0.0) {
                    return Err(Error::Data("all weights are zero".into()));
                }
                Ok(w.clone())
            }
        }
    }
}

/// Vinagre's weights (Vinagre 2001; the paper's eq. 29), omega in rad/s, sorted increasing:
///
/// `w_1 = (w_2 - w_1)/(2 w_1^2)`, `w_g = (w_{g+1} - w_{g-1})/(2 w_g^2)` for `1 < g < f`,
/// `w_f = (w_f - w_{f-1})/(2 w_f^2)`.
///
/// They approximate `integral |e|^2 d(omega)/omega^2`. One point gets weight `1/omega^2`.
///
/// ```
/// let w = ident::levy::vinagre_weights(&[1.0, 2.0, 4.0]);
/// assert_eq!(w, vec![0.5, 3.0 / 8.0, 2.0 / 32.0]);
/// ```
pub fn vinagre_weights(omega_rad_s: &[f64]) -> Vec<f64> {
    let f = omega_rad_s.len();
    let w = omega_rad_s;
    if f == 1 {
        return vec![1.0 / (w[0] * w[0])];
    }
    (0..f)
        .map(|g| {
            let (lo, hi) = (g.saturating_sub(1), (g + 1).min(f - 1));
            (w[hi] - w[lo]) / (2.0 * w[g] * w[g])
        })
        .collect()
}

/// The error index of the paper's eq. 30: `J = (1/f) sum_g |G(jw_g) - Ghat(jw_g)|^2`, omega in rad/s.
///
/// ```
/// let g: fracsim::FracTf = "2/(s + 1)".parse().unwrap();
/// let omega = [1.0, 10.0];
/// let h = g.bode(&omega);
/// assert_eq!(ident::levy::error_index(&omega, &h, &g), 0.0);
/// ```
pub fn error_index(omega_rad_s: &[f64], h: &[Complex64], model: &FracTf) -> f64 {
    let f = omega_rad_s.len().min(h.len());
    if f == 0 {
        return f64::NAN;
    }
    omega_rad_s
        .iter()
        .zip(h)
        .map(|(&w, &g)| (g - model.freq_response(w)).norm_sqr())
        .sum::<f64>()
        / f as f64
}

/// Check Bode data: same lengths, at least one point, omega finite, > 0 and strictly increasing,
/// responses finite.
///
/// # Errors
/// [`Error::Data`] naming the first bad point (1-based).
pub fn check_bode(omega_rad_s: &[f64], h: &[Complex64]) -> Result<()> {
    if omega_rad_s.len() != h.len() {
        return Err(Error::Data(format!(
            "{} frequencies but {} responses",
            omega_rad_s.len(),
            h.len()
        )));
    }
    if omega_rad_s.is_empty() {
        return Err(Error::Data("no frequency points".into()));
    }
    for (i, (&w, g)) in omega_rad_s.iter().zip(h).enumerate() {
        if !w.is_finite() || w <= 0.0 {
            return Err(Error::Data(format!(
                "frequency {w} at point {} must be finite and > 0",
                i + 1
            )));
        }
        if !g.re.is_finite() || !g.im.is_finite() {
            return Err(Error::Data(format!(
                "response {g} at point {} is not finite",
                i + 1
            )));
        }
        if i > 0 {
            let prev = omega_rad_s[i - 1];
            if w == prev {
                return Err(Error::Data(format!(
                    "frequency {w} is repeated (points {} and {})",
                    i,
                    i + 1
                )));
            }
            if w < prev {
                return Err(Error::Data(format!(
                    "frequencies must increase: {w} at point {} follows {prev}",
                    i + 1
                )));
            }
        }
    }
    Ok(())
}

/// A fitted commensurate-order model `N(jw)/D(jw)` (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct LevyFit {
    /// The commensurate order `q`.
    pub q: f64,
    /// Numerator coefficients `b_0..b_m` (of `(jw)^(u q)`).
    pub b: Vec<f64>,
    /// Denominator coefficients `a_1..a_n` (of `(jw)^(p q)`); `a_0 = 1`.
    pub a: Vec<f64>,
    /// The model as a fractional transfer function.
    pub model: FracTf,
    /// The error index `J` (eq. 30) on the data.
    pub j: f64,
    /// The weighted Levy cost `sum_g w_g |G D - N|^2` that was minimised (last iteration's weights).
    pub levy_cost: f64,
    /// Sanathanan-Koerner iterations done after the first Levy solve (at most the number asked:
    /// they stop once converged, [`SK_PARAM_TOL`], [`SK_COST_TOL`]).
    pub sk_iterations: usize,
    /// Whether the Sanathanan-Koerner iterations converged (true without them).
    pub sk_converged: bool,
}

/// Sanathanan-Koerner iterations stop when no coefficient changed by more than this fraction of
/// its value in the last iteration (far below any standard error a Bode table supports: the
/// fixed point is reached to the precision that matters, further iterations only cost time).
pub const SK_PARAM_TOL: f64 = 1e-8;

/// ... or when the error index `J` changed by less than this fraction (the cost no longer moves).
pub const SK_COST_TOL: f64 = 1e-10;

/// The model `(sum_u b_u s^(u q)) / (1 + sum_p a_p s^(p q))` as a [`FracTf`].
///
/// # Errors
/// Non-finite coefficients or an order above 20 (from [`FracTf::new`]).
pub fn commensurate_tf(q: f64, b: &[f64], a: &[f64]) -> Result<FracTf> {
    let num = b
        .iter()
        .enumerate()
        .map(|(u, &c)| Term::new(c, u as f64 * q))
        .collect();
    let mut den = vec![Term::new(1.0, 0.0)];
    den.extend(
        a.iter()
            .enumerate()
            .map(|(p, &c)| Term::new(c, (p + 1) as f64 * q)),
    );
    Ok(FracTf::new(num, den, 0.0)?)
}

/// Levy's weighted linear least squares (Levy 1959) at a fixed order `q`, with at most
/// `sk_iterations` Sanathanan-Koerner (1963) reweightings `w_g / |D_prev(jw_g)|^2`, stopped when
/// the coefficients or `J` no longer change ([`SK_PARAM_TOL`], [`SK_COST_TOL`]).
///
/// Unknowns `x = (b_0..b_m, a_1..a_n)`; each point gives the complex equation
/// `sum_p a_p G s^(p q) - sum_u b_u s^(u q) = -G`, weighted by `sqrt(w_g)`, split into its real
/// and imaginary rows; columns are scaled to unit norm and the system is solved by column-pivoted
/// Householder QR.
///
/// ```
/// use ident::levy::{levy_fixed_q, vinagre_weights};
/// let g: fracsim::FracTf = "5/(0.01 s^1.6 + 0.2 s^0.8 + 1)".parse().unwrap();
/// let omega = [0.1, 1.0, 3.0, 10.0, 30.0, 100.0];
/// let fit = levy_fixed_q(&omega, &g.bode(&omega), 0.8, 0, 2, &vinagre_weights(&omega), 0).unwrap();
/// assert!((fit.b[0] - 5.0).abs() < 1e-9 && (fit.a[1] - 0.01).abs() < 1e-12);
/// ```
///
/// # Errors
/// [`Error::Data`] for bad data ([`check_bode`]) or weights; [`Error::NotEnoughData`] with fewer
/// points than unknowns `m + 1 + n`; [`Error::Options`] for `q` outside `(0, 2]`;
/// [`Error::Numerical`] if the least-squares solution is not finite (a rank-deficient system).
pub fn levy_fixed_q(
    omega_rad_s: &[f64],
    h: &[Complex64],
    q: f64,
    m: usize,
    n: usize,
    weights: &[f64],
    sk_iterations: usize,
) -> Result<LevyFit> {
    check_bode(omega_rad_s, h)?;
    check_sizes(omega_rad_s.len(), m, n)?;
    let mut kernel = LevyKernel::new(omega_rad_s, h, m, n, weights);
    let eval = kernel.eval(q, sk_iterations)?;
    kernel.to_fit(q, eval)
}

/// [`levy_fixed_q`] at each order of `qs` in turn, on one set of buffers (the powers, the
/// system): `visit(q, b, a, err)` gets the coefficients `b_0..b_m`, `a_1..a_n` of each order that
/// solves and their weighted relative error `sum w |G - N/D|^2 / sum w |G|^2` on the data (the
/// error of [`crate::oe::init::frf_error`], on the same powers as the solve). An order whose
/// system is rank deficient is skipped.
///
/// # Errors
/// As [`levy_fixed_q`] for the data and `q` (an order outside `(0, 2]`).
pub(crate) fn levy_orders(
    omega_rad_s: &[f64],
    h: &[Complex64],
    (m, n): (usize, usize),
    weights: &[f64],
    sk_iterations: usize,
    qs: impl IntoIterator<Item = f64>,
    mut visit: impl FnMut(f64, &[f64], &[f64], f64),
) -> Result<()> {
    check_bode(omega_rad_s, h)?;
    check_sizes(omega_rad_s.len(), m, n)?;
    let mut kernel = LevyKernel::new(omega_rad_s, h, m, n, weights);
    for q in qs {
        match kernel.eval(q, sk_iterations) {
            Ok(_) => {}
            Err(Error::Numerical(_)) | Err(Error::Sim(_)) => continue,
            Err(e) => return Err(e),
        }
        let err = kernel.weighted_rel_error();
        let (b, a) = kernel.x.split_at(m + 1);
        visit(q, b, a, err);
    }
    Ok(())
}

fn check_sizes(f: usize, m: usize, n: usize) -> Result<()> {
    let unknowns = m + 1 + n;
    if f < unknowns.max(2) {
        return Err(Error::NotEnoughData(format!(
            "{f} frequency points for {unknowns} unknowns (m = {m}, n = {n}); need at least {}",
            unknowns.max(2)
        )));
    }
    Ok(())
}

/// The scores of one Levy (plus Sanathanan-Koerner) solve at one `q`; the coefficients stay in
/// [`LevyKernel::x`].
#[derive(Debug, Clone, Copy)]
struct QEval {
    /// The error index `J` (eq. 30).
    j: f64,
    /// The weighted Levy cost of the last solve.
    levy_cost: f64,
    /// Sanathanan-Koerner iterations done.
    sk_done: usize,
    /// Whether they converged (true without them).
    sk_converged: bool,
}

/// Levy's problem on one (validated) data set, solved at many orders `q`.
///
/// What does not depend on `q` is computed once (`ln omega`), and every buffer (the powers
/// `(jw)^(k q)`, the effective weights, the stacked real/imaginary system) is reused from one `q`
/// to the next. Per `q` and point the powers cost one `exp`: `(jw)^q = exp(q ln w) e^(j q pi/2)`
/// (the rotation once per `q`), and `(jw)^(k q)` by repeated complex multiplication (relative
/// error about `k` ulps; `k` is a model degree, a few in practice). The error index
/// `J` is evaluated on the same powers, without building a [`FracTf`].
struct LevyKernel<'a> {
    omega: &'a [f64],
    h: &'a [Complex64],
    weights: &'a [f64],
    m: usize,
    n: usize,
    /// `ln omega_g`.
    ln_w: Vec<f64>,
    /// `(jw_g)^(k q)` for `k = 0..=max(m, n)`, point-major (`kmax + 1` per point).
    pows: Vec<Complex64>,
    /// Weights of the current solve (Sanathanan-Koerner reweights them).
    w_eff: Vec<f64>,
    /// `sqrt` of the effective weights.
    sw: Vec<f64>,
    /// The stacked system `2f x (m + 1 + n)`, column-major, reused.
    a: Vec<f64>,
    /// Its right-hand side (`2f`), reused.
    rhs: Vec<f64>,
    /// The QR's memory (faer's block reflectors and scratch), reused.
    qr: LstsqWork,
    /// The diagonal of the last solve's `R`.
    r_diag: Vec<f64>,
    /// The column scales.
    scale: Vec<f64>,
    /// The solution `(b_0..b_m, a_1..a_n)` of the last solve.
    x: Vec<f64>,
}

impl<'a> LevyKernel<'a> {
    /// Data already checked by [`check_bode`] and [`check_sizes`]; the weights are checked by
    /// [`Self::eval`] (as [`levy_fixed_q`] always did, after the order).
    fn new(omega: &'a [f64], h: &'a [Complex64], m: usize, n: usize, weights: &'a [f64]) -> Self {
        let f = omega.len();
        let k = m + 1 + n;
        Self {
            omega,
            h,
            weights,
            m,
            n,
            ln_w: omega.iter().map(|w| w.ln()).collect(),
            pows: vec![Complex64::new(1.0, 0.0); f * (m.max(n) + 1)],
            w_eff: vec![0.0; f],
            sw: vec![0.0; f],
            a: vec![0.0; 2 * f * k],
            rhs: vec![0.0; 2 * f],
            qr: LstsqWork::new(),
            r_diag: vec![0.0; k],
            scale: vec![1.0; k],
            x: vec![0.0; k],
        }
    }

    /// Levy at order `q` with `sk_iterations` Sanathanan-Koerner reweightings; the coefficients
    /// are left in `self.x`.
    ///
    /// # Errors
    /// As [`levy_fixed_q`] after its data checks.
    fn eval(&mut self, q: f64, sk_iterations: usize) -> Result<QEval> {
        if !(q > 0.0 && q <= 2.0) {
            return Err(Error::Options(format!("order q = {q} must be in (0, 2]")));
        }
        if self.weights.len() != self.omega.len() {
            return Err(Error::Data(format!(
                "{} weights for {} points",
                self.weights.len(),
                self.omega.len()
            )));
        }
        let (m, kp) = (self.m, self.m.max(self.n) + 1);
        // (jw)^(k q): the rotation e^(j q pi/2) once, w^q = exp(q ln w) once per point
        let rot = Complex64::from_polar(1.0, q * FRAC_PI_2);
        for (pw, &lw) in self.pows.chunks_exact_mut(kp).zip(&self.ln_w) {
            let z = rot * (q * lw).exp();
            pw[0] = Complex64::new(1.0, 0.0);
            for k in 1..kp {
                pw[k] = if k == 1 { z } else { pw[k - 1] * z };
            }
        }
        self.w_eff.copy_from_slice(self.weights);
        let (mut sk_done, mut sk_converged) = (0, sk_iterations == 0);
        let mut prev: Option<(Vec<f64>, f64)> = None;
        for it in 0..=sk_iterations {
            if it > 0 {
                // Sanathanan-Koerner: divide by |D_prev|^2
                for ((we, &w), pw) in self
                    .w_eff
                    .iter_mut()
                    .zip(self.weights)
                    .zip(self.pows.chunks_exact(kp))
                {
                    let d = den_at(pw, &self.x[m + 1..]);
                    *we = w / d.norm_sqr().max(f64::MIN_POSITIVE);
                }
            }
            self.solve()?;
            if sk_iterations == 0 {
                break;
            }
            let j = self.scores().j;
            if let Some((px, pj)) = &prev {
                sk_done = it;
                if sk_settled(px, &self.x, *pj, j) {
                    sk_converged = true;
                    break;
                }
            }
            prev = Some((self.x.clone(), j));
        }
        if self.m.max(self.n) as f64 * q > 20.0 {
            // FracTf::new rejects orders above 20: the same error as building the model
            commensurate_tf(q, &self.x[..=m], &self.x[m + 1..])?;
        }
        Ok(QEval {
            sk_done,
            sk_converged,
            ..self.scores()
        })
    }

    /// One weighted, column-scaled QR least-squares solve into `self.x`.
    fn solve(&mut self) -> Result<()> {
        let (m, kp) = (self.m, self.m.max(self.n) + 1);
        for (s, &w) in self.sw.iter_mut().zip(&self.w_eff) {
            *s = w.sqrt();
        }
        fill_system(
            &mut self.a,
            &mut self.scale,
            &self.pows,
            self.h,
            &self.sw,
            m,
            kp,
        );
        for ((pair, &hg), &sw) in self.rhs.chunks_exact_mut(2).zip(self.h).zip(&self.sw) {
            pair[0] = -hg.re * sw;
            pair[1] = -hg.im * sw;
        }
        // Householder QR of the scaled, weighted system: an orthogonal factorisation, never the
        // normal equations.
        let (pows, h, sw, scale) = (&self.pows, self.h, &self.sw, &mut self.scale);
        lstsq_checked(
            &mut self.qr,
            &mut self.a,
            &mut self.rhs,
            &mut self.r_diag,
            &mut self.x,
            &mut |a| fill_system(a, scale, pows, h, sw, m, kp),
        )?;
        for (x, s) in self.x.iter_mut().zip(&self.scale) {
            *x /= s;
        }
        if self.x.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical(
                "the Levy least-squares system is rank deficient".into(),
            ));
        }
        Ok(())
    }

    /// `J` (eq. 30) and the weighted Levy cost `sum_g w_g |G D - N|^2` at `self.x`, on the powers.
    fn scores(&self) -> QEval {
        let (m, kp) = (self.m, self.m.max(self.n) + 1);
        let (b, a) = self.x.split_at(m + 1);
        let (mut j, mut cost) = (0.0, 0.0);
        for ((pw, &hg), &w) in self.pows.chunks_exact(kp).zip(self.h).zip(&self.w_eff) {
            let (num, den) = num_den(pw, b, a);
            // the Levy residual e = G D - N; G - N/D = e/D
            let e2 = (hg * den - num).norm_sqr();
            j += e2 / den.norm_sqr();
            cost += w * e2;
        }
        QEval {
            j: j / self.omega.len() as f64,
            levy_cost: cost,
            sk_done: 0,
            sk_converged: true,
        }
    }

    /// The weighted relative error `sum_g w_g |G_g - N_g/D_g|^2 / sum_g w_g |G_g|^2` of the
    /// coefficients in `self.x`, with the data's weights, on the powers of the last `q`.
    fn weighted_rel_error(&self) -> f64 {
        let (m, kp) = (self.m, self.m.max(self.n) + 1);
        let (b, a) = self.x.split_at(m + 1);
        let (mut num_err, mut total) = (0.0, 0.0);
        for ((pw, &hg), &w) in self.pows.chunks_exact(kp).zip(self.h).zip(self.weights) {
            let (num, den) = num_den(pw, b, a);
            num_err += w * (hg - num / den).norm_sqr();
            total += w * hg.norm_sqr();
        }
        num_err / total.max(f64::MIN_POSITIVE)
    }

    /// The [`LevyFit`] of the last [`Self::eval`] (at `q`, with its scores `e`).
    fn to_fit(&self, q: f64, e: QEval) -> Result<LevyFit> {
        let b = self.x[..=self.m].to_vec();
        let a = self.x[self.m + 1..].to_vec();
        let model = commensurate_tf(q, &b, &a)?;
        Ok(LevyFit {
            q,
            b,
            a,
            model,
            j: e.j,
            levy_cost: e.levy_cost,
            sk_iterations: e.sk_done,
            sk_converged: e.sk_converged,
        })
    }
}

/// Levy's stacked system, column-major `2f x k` into `a` (`f = h.len()`, `k = scale.len()`):
/// unknown `c` is `-(jw)^(c q)` for `c <= m` (`b_c`), `G (jw)^((c - m) q)` for `c > m`
/// (`a_(c-m)`), each row pair weighted by `sw`, from the powers `pows` (`kp` per point); each
/// column scaled to unit norm, its norm into `scale` (1 for a zero column).
fn fill_system(
    a: &mut [f64],
    scale: &mut [f64],
    pows: &[Complex64],
    h: &[Complex64],
    sw: &[f64],
    m: usize,
    kp: usize,
) {
    for (c, col) in a.chunks_exact_mut(2 * h.len()).enumerate() {
        for (((pair, pw), &hg), &sw) in col
            .chunks_exact_mut(2)
            .zip(pows.chunks_exact(kp))
            .zip(h)
            .zip(sw)
        {
            let z = if c <= m { -pw[c] } else { hg * pw[c - m] } * sw;
            pair[0] = z.re;
            pair[1] = z.im;
        }
        // column scaling to unit norm: the columns differ by orders of magnitude (w^(pq))
        let nrm = dot(col, col).sqrt();
        scale[c] = 1.0;
        if nrm > 0.0 && nrm.is_finite() {
            scale[c] = nrm;
            let inv = 1.0 / nrm;
            for v in col.iter_mut() {
                *v *= inv;
            }
        }
    }
}

/// The least-squares solution `x` of `A x = b` by faer's Householder QR in the reused memory
/// `work`, `A` column-major `rows x k` with `k = x.len()` (columns scaled to unit norm by the
/// caller), `A` and `b` overwritten, the diagonal of `R` into `r_diag` (length `k`); `refill`
/// writes `A` again ([`LstsqWork::solve`]).
///
/// # Errors
/// [`Error::Numerical`] when a column is (to rounding) a combination of the ones before it: a
/// diagonal of `R` under `1e-13` (of a unit column), or a non-finite value.
fn lstsq_checked(
    work: &mut LstsqWork,
    a: &mut [f64],
    b: &mut [f64],
    r_diag: &mut [f64],
    x: &mut [f64],
    refill: &mut dyn FnMut(&mut [f64]),
) -> Result<()> {
    let k = x.len();
    let rows = b.len();
    let deficient = || Error::Numerical("the Levy least-squares system is rank deficient".into());
    if rows < k || a.len() != rows * k || r_diag.len() != k {
        return Err(deficient());
    }
    work.solve(a, b, r_diag, refill);
    if r_diag.iter().any(|d| !(d.abs() > 1e-13 && d.is_finite())) {
        return Err(deficient());
    }
    x.copy_from_slice(&b[..k]);
    if x.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(deficient())
    }
}

/// `N = sum_u b_u z_u` and `D = 1 + sum_p a_p z_p` at one point from its powers
/// `z_k = (jw)^(k q)` (`z_0 = 1`).
fn num_den(pw: &[Complex64], b: &[f64], a: &[f64]) -> (Complex64, Complex64) {
    let mut num = Complex64::new(0.0, 0.0);
    for (z, &bu) in pw.iter().zip(b) {
        num += z * bu;
    }
    (num, den_at(pw, a))
}

/// Whether a Sanathanan-Koerner iteration changed nothing that matters: every coefficient moved
/// by at most [`SK_PARAM_TOL`] of its size, or `J` by at most [`SK_COST_TOL`] of its value.
fn sk_settled(prev: &[f64], x: &[f64], prev_j: f64, j: f64) -> bool {
    let params = prev
        .iter()
        .zip(x)
        .all(|(a, b)| (a - b).abs() <= SK_PARAM_TOL * a.abs().max(b.abs()));
    let cost = (j - prev_j).abs() <= SK_COST_TOL * j.abs().max(prev_j.abs());
    params || cost
}

fn den_at(pows: &[Complex64], a: &[f64]) -> Complex64 {
    let mut d = Complex64::new(1.0, 0.0);
    for (p, &ap) in a.iter().enumerate() {
        d += pows[p + 1] * ap;
    }
    d
}

/// How the commensurate order `q` is chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum OrderChoice {
    /// Use this `q` (in `(0, 2]`).
    Fixed(f64),
    /// Grid `q = step, 2 step, ..., <= q_max`, then (if `refine`) a golden-section search of
    /// `J(q)` on `[q* - step, q* + step]` around the best grid point `q*`.
    Search {
        /// Grid step (the paper: 0.01).
        step: f64,
        /// Largest `q` of the grid (the paper: 1).
        q_max: f64,
        /// Refine the best grid point by golden-section search.
        refine: bool,
    },
}

impl Default for OrderChoice {
    fn default() -> Self {
        Self::Search {
            step: 0.01,
            q_max: 1.0,
            refine: true,
        }
    }
}

/// One point of the `J(q)` curve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct QPoint {
    /// The order.
    pub q: f64,
    /// The error index `J` (eq. 30) of the fit at this `q` (`inf` where the solve broke down).
    pub j: f64,
}

/// The result of [`search_q`].
#[derive(Debug, Clone, PartialEq)]
pub struct QSearch {
    /// The best fit (after refinement if asked).
    pub best: LevyFit,
    /// The best fit on the grid (the paper's answer).
    pub grid_best: LevyFit,
    /// `J(q)` on the grid, increasing `q` (a single point for a fixed `q`).
    pub curve: Vec<QPoint>,
}

/// Levy (plus `sk_iterations` Sanathanan-Koerner steps) at every `q` of the grid, the best by `J`
/// (eq. 30), then a golden-section refinement of `J(q)`.
///
/// # Errors
/// As [`levy_fixed_q`]; [`Error::Options`] for a bad grid; [`Error::Numerical`] when no `q`
/// of the grid gives a finite fit.
pub fn search_q(
    omega_rad_s: &[f64],
    h: &[Complex64],
    m: usize,
    n: usize,
    weights: &[f64],
    sk_iterations: usize,
    order: &OrderChoice,
) -> Result<QSearch> {
    check_bode(omega_rad_s, h)?;
    check_sizes(omega_rad_s.len(), m, n)?;
    // data checked once; ln omega and the buffers shared by every q
    let mut kernel = LevyKernel::new(omega_rad_s, h, m, n, weights);
    match *order {
        OrderChoice::Fixed(q) => {
            let e = kernel.eval(q, sk_iterations)?;
            let best = kernel.to_fit(q, e)?;
            Ok(QSearch {
                grid_best: best.clone(),
                curve: vec![QPoint { q, j: best.j }],
                best,
            })
        }
        OrderChoice::Search {
            step,
            q_max,
            refine,
        } => {
            if !(step > 0.0 && step.is_finite() && q_max > 0.0 && q_max <= 2.0 && step <= q_max) {
                return Err(Error::Options(format!(
                    "q grid step {step} and maximum {q_max} must satisfy 0 < step <= q_max <= 2"
                )));
            }
            // q_k = k step, k = 1..K, with a tolerance so that 1.0 is on a 0.01 grid
            let count = ((q_max / step) * (1.0 + 1e-12)).floor() as usize;
            if count > 100_000 {
                return Err(Error::Options(format!(
                    "q grid of {count} points is too fine"
                )));
            }
            let mut curve = Vec::with_capacity(count);
            // the best grid point: (q, scores, coefficients); the fit is built once at the end
            let mut grid_best: Option<(f64, QEval)> = None;
            let mut best_x = vec![0.0; kernel.x.len()];
            for k in 1..=count {
                // round to 12 digits so that 0.91 prints and compares as 0.91
                let q = ((k as f64 * step) * 1e12).round() / 1e12;
                match kernel.eval(q, sk_iterations) {
                    Ok(e) if e.j.is_finite() => {
                        curve.push(QPoint { q, j: e.j });
                        if !matches!(&grid_best, Some((_, b)) if b.j <= e.j) {
                            grid_best = Some((q, e));
                            best_x.copy_from_slice(&kernel.x);
                        }
                    }
                    Ok(_) | Err(Error::Numerical(_)) | Err(Error::Sim(_)) => curve.push(QPoint {
                        q,
                        j: f64::INFINITY,
                    }),
                    Err(e) => return Err(e),
                }
            }
            let (qb, eb) = grid_best.ok_or_else(|| {
                Error::Numerical("no order q on the grid gives a finite Levy fit".into())
            })?;
            kernel.x.copy_from_slice(&best_x);
            let grid_best = kernel.to_fit(qb, eb)?;
            let mut best = grid_best.clone();
            if refine {
                let lo = (grid_best.q - step).max(step * 1e-3);
                let hi = (grid_best.q + step).min(q_max.max(grid_best.q));
                let jq = |q: f64| {
                    kernel
                        .eval(q, sk_iterations)
                        .map(|e| e.j)
                        .unwrap_or(f64::INFINITY)
                };
                let qr = golden_section(jq, lo, hi, 1e-7);
                if let Ok(er) = kernel.eval(qr, sk_iterations) {
                    if er.j < best.j {
                        best = kernel.to_fit(qr, er)?;
                    }
                }
            }
            Ok(QSearch {
                best,
                grid_best,
                curve,
            })
        }
    }
}

/// Golden-section minimisation of `f` on `[a, b]` down to an interval of width `tol`.
fn golden_section(mut f: impl FnMut(f64) -> f64, mut a: f64, mut b: f64, tol: f64) -> f64 {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..200 {
        if (b - a).abs() <= tol {
            break;
        }
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        c
    } else {
        d
    }
}

/// Options of [`fit_bode`].
#[derive(Debug, Clone, PartialEq)]
pub struct FreqOptions {
    /// Denominator degree `n` (in powers of `s^q`). Default 2.
    pub n: usize,
    /// Numerator degree `m`. Default 0.
    pub m: usize,
    /// The order `q`: fixed or searched. Default: grid step 0.01 on `(0, 1]`, refined.
    pub order: OrderChoice,
    /// Weights of the Levy least squares. Default Vinagre.
    pub weights: Weights,
    /// Sanathanan-Koerner iterations (0: none). Default 0. With `> 0` the result has an `sk` fit.
    pub sk_iterations: usize,
    /// Refit the PMSM structure with two free orders by Levenberg-Marquardt (needs `n = 2`,
    /// `m = 0`). Default false.
    pub refine: bool,
    /// The standard deviation of each point's complex error per real component (e.g. from the
    /// measured spread, [`point_std_from_spread`]): the refit weights by its inverse variance and
    /// its standard errors reflect it ([`RefineOptions::point_std`]). Default none.
    pub point_std: Option<Vec<f64>>,
}

impl Default for FreqOptions {
    fn default() -> Self {
        Self {
            n: 2,
            m: 0,
            order: OrderChoice::default(),
            weights: Weights::Vinagre,
            sk_iterations: 0,
            refine: false,
            point_std: None,
        }
    }
}

/// The standard deviation per real component of each point's complex error, from the spread of
/// its magnitude and phase: `sigma_g = |G_g| sqrt((s_m^2 + s_p^2)/2)`, with `s_m` the relative
/// magnitude error (`gain_db_se ln(10)/20`) and `s_p` the phase error in rad. For errors that
/// are isotropic in the complex plane (additive noise on the output) `s_m = s_p` and this is
/// exact; otherwise it is the average of the two directions.
///
/// ```
/// use num_complex::Complex64;
/// let s = ident::levy::point_std_from_spread(&[Complex64::new(2.0, 0.0)], &[0.0], &[0.5f64.to_degrees()]);
/// assert!((s[0] - 2.0 * 0.5 / 2f64.sqrt()).abs() < 1e-12);
/// ```
pub fn point_std_from_spread(
    h: &[Complex64],
    gain_db_se: &[f64],
    phase_deg_se: &[f64],
) -> Vec<f64> {
    h.iter()
        .zip(gain_db_se.iter().zip(phase_deg_se))
        .map(|(hg, (g, p))| {
            let sm = g * std::f64::consts::LN_10 / 20.0;
            let sp = p.to_radians();
            hg.norm() * ((sm * sm + sp * sp) / 2.0).sqrt()
        })
        .collect()
}

/// Levy weights that combine Vinagre's with the measured spread: `w_g = v_g / r_g^2` normalised
/// to the mean of `v_g`, `v_g` Vinagre's weight (which offsets the `|D|^2` growth of Levy's
/// equation error) and `r_g = sigma_g/|G_g|` the point's relative error. Levy's equation error
/// `G D - N = D (G - Ghat)` has variance `|D|^2 sigma_g^2`; with Vinagre standing in for
/// `1/|D|^2 ~ 1/|G|^2`-like scaling, dividing by `r_g^2` makes the sum an inverse-variance one.
///
/// # Errors
/// [`Error::Data`] for a non-positive or non-finite relative error.
pub fn spread_levy_weights(
    omega_rad_s: &[f64],
    h: &[Complex64],
    point_std: &[f64],
) -> Result<Vec<f64>> {
    let v = vinagre_weights(omega_rad_s);
    let mut w = Vec::with_capacity(v.len());
    for (g, ((vg, hg), sg)) in v.iter().zip(h).zip(point_std).enumerate() {
        let r = sg / hg.norm();
        if !(r.is_finite() && r > 0.0) {
            return Err(Error::Data(format!(
                "point {}: relative spread {r} must be positive and finite",
                g + 1
            )));
        }
        w.push(vg / (r * r));
    }
    let mean_v = v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mean_w = w.iter().sum::<f64>() / w.len().max(1) as f64;
    Ok(w.iter().map(|x| x * mean_v / mean_w).collect())
}

/// The result of [`fit_bode`].
#[derive(Debug, Clone, PartialEq)]
pub struct FreqFit {
    /// Levy's fit (weighted, no SK) at the chosen `q` (refined `q` if the search refines).
    pub levy: LevyFit,
    /// Levy's fit at the best grid `q` (the paper's procedure); equal to `levy` for a fixed `q`.
    pub levy_grid: LevyFit,
    /// `J(q)` of the Levy fit on the grid.
    pub curve: Vec<QPoint>,
    /// The Sanathanan-Koerner fit (its own `q` search), if `sk_iterations > 0`.
    pub sk: Option<LevyFit>,
    /// `J(q)` of the SK fit on the grid (empty without SK).
    pub sk_curve: Vec<QPoint>,
    /// The nonlinear PMSM refit, if asked.
    pub refined: Option<PmsmFit>,
    /// Why the best model ([`FreqFit::best_model`]) cannot be used (empty when it can):
    /// unstable, a pole on the imaginary axis, non-finite, no finite static gain, a refit whose
    /// parameters the data do not determine ([`checks`]).
    pub problems: Vec<String>,
    /// What the user should know but does not make the model unusable: a negative static gain,
    /// a poorly determined refit parameter, no convergence (the refit's or Sanathanan-Koerner's).
    pub warnings: Vec<String>,
}

impl FreqFit {
    /// The best model by `J` among Levy, SK and the refit.
    pub fn best_model(&self) -> &FracTf {
        best_of(&self.levy, self.sk.as_ref(), self.refined.as_ref()).0
    }

    /// The error index `J` of [`FreqFit::best_model`].
    pub fn best_j(&self) -> f64 {
        let mut j = self.levy.j;
        for other in [
            self.sk.as_ref().map(|s| s.j),
            self.refined.as_ref().map(|r| r.j),
        ] {
            if let Some(o) = other.filter(|&o| o < j) {
                j = o;
            }
        }
        j
    }

    /// True when the best model can be used: no [`FreqFit::problems`].
    pub fn usable(&self) -> bool {
        self.problems.is_empty()
    }
}

/// The best model by `J` (and whether it is the refit's).
fn best_of<'a>(
    levy: &'a LevyFit,
    sk: Option<&'a LevyFit>,
    refined: Option<&'a PmsmFit>,
) -> (&'a FracTf, bool) {
    let mut best = (&levy.model, levy.j, false);
    if let Some(s) = sk {
        if s.j < best.1 {
            best = (&s.model, s.j, false);
        }
    }
    if let Some(r) = refined {
        if r.j < best.1 {
            best = (&r.model, r.j, true);
        }
    }
    (best.0, best.2)
}

/// The problems and warnings of a fit (see [`FreqFit::problems`]).
fn assess(
    levy: &LevyFit,
    sk: Option<&LevyFit>,
    refined: Option<&PmsmFit>,
    sk_asked: usize,
) -> (Vec<String>, Vec<String>) {
    let (best, is_refit) = best_of(levy, sk, refined);
    let (mut problems, mut warnings) = checks::model_problems(best);
    let j = [Some(levy.j), sk.map(|s| s.j), refined.map(|r| r.j)];
    if j.iter().flatten().all(|j| !j.is_finite()) {
        problems.push("the error index J is not finite".into());
    }
    if let Some(r) = refined {
        let (mut p, mut w) = (vec![], vec![]);
        checks::refit_problems(r, &mut p, &mut w);
        if is_refit {
            problems.extend(p);
        } else {
            w.extend(p.into_iter().map(|m| m + " (not the model kept)"));
        }
        warnings.extend(w);
    }
    if let Some(s) = sk.filter(|s| !s.sk_converged) {
        warnings.push(format!(
            "Sanathanan-Koerner: not converged after {sk_asked} iterations (the coefficients still \
             change by more than {SK_PARAM_TOL:e} of their value and J by more than \
             {SK_COST_TOL:e}): try more (--sk), J = {:.4e}",
            s.j
        ));
    }
    (problems, warnings)
}

/// Identify a fractional model from Bode data: Levy with an order search, optionally
/// Sanathanan-Koerner iterations and the nonlinear PMSM refit (started from the better of Levy
/// and SK by `J`). The single entry point of `fracid freq` and the Python bindings.
///
/// `omega_rad_s` strictly increasing, > 0; `h[g] = G(j omega_g)` (complex, linear gain).
///
/// # Errors
/// As [`check_bode`], [`search_q`], [`refine_pmsm`]; [`Error::Options`] for `refine` with a
/// structure other than `n = 2`, `m = 0`.
pub fn fit_bode(omega_rad_s: &[f64], h: &[Complex64], opts: &FreqOptions) -> Result<FreqFit> {
    check_bode(omega_rad_s, h)?;
    check_sizes(omega_rad_s.len(), opts.m, opts.n)?;
    if opts.refine && (opts.n != 2 || opts.m != 0) {
        return Err(Error::Options(format!(
            "the refit is of the PMSM structure K/(a2 s^(zeta+theta) + a1 s^zeta + 1): needs n = 2, \
             m = 0 (got n = {}, m = {})",
            opts.n, opts.m
        )));
    }
    let w = opts.weights.values(omega_rad_s)?;
    let levy = search_q(omega_rad_s, h, opts.m, opts.n, &w, 0, &opts.order)?;
    let (sk, sk_curve) = if opts.sk_iterations > 0 {
        let s = search_q(
            omega_rad_s,
            h,
            opts.m,
            opts.n,
            &w,
            opts.sk_iterations,
            &opts.order,
        )?;
        (Some(s.best), s.curve)
    } else {
        (None, Vec::new())
    };
    let refined = if opts.refine {
        let start = match &sk {
            Some(s) if s.j < levy.best.j => s,
            _ => &levy.best,
        };
        Some(refine_pmsm(
            omega_rad_s,
            h,
            start,
            &RefineOptions {
                point_std: opts.point_std.clone(),
                ..RefineOptions::default()
            },
        )?)
    } else {
        None
    };
    let (problems, warnings) = assess(
        &levy.best,
        sk.as_ref(),
        refined.as_ref(),
        opts.sk_iterations,
    );
    Ok(FreqFit {
        levy: levy.best,
        levy_grid: levy.grid_best,
        curve: levy.curve,
        sk,
        sk_curve,
        refined,
        problems,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lstsq_is_the_least_squares_solution_and_finds_dependent_columns() {
        // A deterministic 40 x 4 system, columns scaled to unit norm as `solve` does.
        let (rows, k) = (40, 4);
        let mut a: Vec<f64> = (0..rows * k)
            .map(|i| {
                ((i * 7919) % 101) as f64 / 50.0 - 1.0 + if i % (rows + 1) == 0 { 2.0 } else { 0.0 }
            })
            .collect();
        for col in a.chunks_exact_mut(rows) {
            let n = dot(col, col).sqrt();
            col.iter_mut().for_each(|v| *v /= n);
        }
        let b: Vec<f64> = (0..rows).map(|i| (i as f64 * 0.37).sin()).collect();
        let am = nalgebra::DMatrix::from_column_slice(rows, k, &a);
        let bm = nalgebra::DMatrix::from_column_slice(rows, 1, &b);
        // The reference: nalgebra's SVD least squares (a different factorisation).
        let want = am.svd(true, true).solve(&bm, 0.0).unwrap();
        let mut x = vec![0.0; k];
        let (mut work, mut diag) = (LstsqWork::new(), vec![0.0; k]);
        let mut refill = |dst: &mut [f64]| dst.copy_from_slice(&a);
        let (mut a1, mut b1) = (a.clone(), b.clone());
        lstsq_checked(&mut work, &mut a1, &mut b1, &mut diag, &mut x, &mut refill).unwrap();
        for i in 0..k {
            // Both are backward stable on a system of condition about 10: 1e-12 is rounding.
            assert!(
                (x[i] - want[(i, 0)]).abs() < 1e-12,
                "x[{i}] = {} against {}",
                x[i],
                want[(i, 0)]
            );
        }
        // The residual is orthogonal to every column (the normal equations hold).
        let r: Vec<f64> = (0..rows)
            .map(|i| b[i] - (0..k).map(|c| a[c * rows + i] * x[c]).sum::<f64>())
            .collect();
        for col in a.chunks_exact(rows) {
            assert!(dot(col, &r).abs() < 1e-13);
        }
        // A column that repeats another is reported, not solved into huge values.
        let err = with_column_repeated(&a, &b, rows, &mut work).unwrap_err();
        assert!(err.to_string().contains("rank deficient"), "{err}");
    }

    /// [`lstsq_checked`] on `a` (`rows` rows) with its third column replaced by its first.
    fn with_column_repeated(a: &[f64], b: &[f64], rows: usize, work: &mut LstsqWork) -> Result<()> {
        let k = a.len() / rows;
        let (mut diag, mut x) = (vec![0.0; k], vec![0.0; k]);
        let mut dep = a.to_vec();
        dep.copy_within(0..rows, 2 * rows);
        let orig = dep.clone();
        let mut refill = |dst: &mut [f64]| dst.copy_from_slice(&orig);
        lstsq_checked(
            work,
            &mut dep,
            &mut b.to_vec(),
            &mut diag,
            &mut x,
            &mut refill,
        )
    }

    /// A tall system (2000 rows, where faer's plain QR takes a part under `16 m eps = 7e-12` of
    /// a column for dependent) whose column 2 is column 0 plus `1e-12` of another: the system is
    /// built again (once) and factored by the pivoted QR, the pivot stays `1e-12`, above the
    /// `1e-13` cut, and the solution is the least-squares one (the normal equations hold to
    /// rounding). An exactly repeated column is still rank deficient.
    #[test]
    fn a_nearly_dependent_column_of_a_tall_system_is_solved() {
        let (rows, k) = (2000, 3);
        let mut base: Vec<f64> = (0..rows * 3)
            .map(|i| ((i * 7919) % 1009) as f64 / 500.0 - 1.0)
            .collect();
        for col in base.chunks_exact_mut(rows) {
            let n = dot(col, col).sqrt();
            col.iter_mut().for_each(|v| *v /= n);
        }
        let mut a = base.clone();
        for i in 0..rows {
            a[2 * rows + i] = base[i] + 1e-12 * base[2 * rows + i];
        }
        let n2 = dot(&a[2 * rows..], &a[2 * rows..]).sqrt();
        a[2 * rows..].iter_mut().for_each(|v| *v /= n2);
        let b: Vec<f64> = (0..rows).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut work, mut diag, mut x) = (LstsqWork::new(), vec![0.0; k], vec![0.0; k]);
        let mut calls = 0;
        let mut refill = |dst: &mut [f64]| {
            calls += 1;
            dst.copy_from_slice(&a);
        };
        let (mut a1, mut b1) = (a.clone(), b.clone());
        lstsq_checked(&mut work, &mut a1, &mut b1, &mut diag, &mut x, &mut refill).unwrap();
        assert_eq!(calls, 1);
        assert!(diag[2].abs() > 1e-13 && diag[2].abs() < 1e-11, "{diag:?}");
        // |A^T r| against |A| |r| / pivot: the normal equations to rounding.
        let r: Vec<f64> = (0..rows)
            .map(|i| b[i] - (0..k).map(|c| a[c * rows + i] * x[c]).sum::<f64>())
            .collect();
        for col in a.chunks_exact(rows) {
            assert!(
                dot(col, &r).abs() < 1e-13 * dot(&r, &r).sqrt() / 1e-12,
                "{x:?}"
            );
        }
        assert!(with_column_repeated(&a, &b, rows, &mut work).is_err());
    }

    #[test]
    fn vinagre_ends_and_middle() {
        let w = vinagre_weights(&[1.0, 3.0, 4.0, 10.0]);
        assert_eq!(w[0], 2.0 / 2.0);
        assert_eq!(w[1], 3.0 / 18.0);
        assert_eq!(w[2], 7.0 / 32.0);
        assert_eq!(w[3], 6.0 / 200.0);
    }

    #[test]
    fn golden_finds_parabola_minimum() {
        let x = golden_section(|x| (x - 0.3).powi(2), 0.0, 1.0, 1e-9);
        assert!((x - 0.3).abs() < 1e-8);
    }

    #[test]
    fn grid_includes_q_max() {
        let g = FracTf::pmsm(2.0, 0.1, 0.01, 0.5, 0.5).unwrap();
        let omega: Vec<f64> = (0..8).map(|i| 10f64.powi(i - 2)).collect();
        let s = search_q(
            &omega,
            &g.bode(&omega),
            0,
            2,
            &vinagre_weights(&omega),
            0,
            &OrderChoice::default(),
        )
        .unwrap();
        assert_eq!(s.curve.len(), 100);
        assert_eq!(s.curve[99].q, 1.0);
        assert_eq!(s.grid_best.q, 0.5);
    }

    #[test]
    fn sizes_checked() {
        let omega = [1.0, 2.0];
        let h = [Complex64::new(1.0, 0.0); 2];
        assert!(matches!(
            levy_fixed_q(&omega, &h, 0.5, 0, 2, &[1.0, 1.0], 0),
            Err(Error::NotEnoughData(_))
        ));
        assert!(matches!(
            levy_fixed_q(&omega, &h, 0.0, 0, 1, &[1.0, 1.0], 0),
            Err(Error::Options(_))
        ));
    }
}
