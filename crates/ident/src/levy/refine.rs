//! Nonlinear least-squares refit of the PMSM structure (the paper's eq. 10) in the frequency domain:
//!
//! `Ghat(s) = K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`, two free orders,
//!
//! minimising the complex output error, i.e. the paper's eq. 30
//! `J = (1/f) sum_g |G(jw_g) - Ghat(jw_g)|^2` (omega in rad/s), by Levenberg-Marquardt
//! ([`crate::lm`], Marquardt 1963) with an analytic Jacobian.
//!
//! Parametrisation: `p = (ln|K|, ln a1, ln a2, u_zeta, u_theta)` with
//! `zeta = 2/(1 + exp(-u_zeta))` (and the same for theta), so the coefficients stay positive and the
//! orders inside `(0, 2)` whatever step LM takes. The sign of `K` is kept from the start.

use super::{check_bode, error_index, LevyFit};
use crate::lm::Mat;
use crate::lm::{minimize, LmOptions, LmReport, Problem};
use crate::{Error, Result};
use fracsim::{jw_pow, FracTf};
use num_complex::Complex64;
use std::f64::consts::FRAC_PI_2;

/// Options of [`refine_pmsm`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RefineOptions {
    /// Options of the Levenberg-Marquardt solver.
    pub lm: LmOptions,
    /// The standard deviation of each point's complex error, per real component (`sigma_g`:
    /// `Re` and `Im` of `G(j w_g)` each carry about this much), e.g. from the measured spread of
    /// repeats. With it the refit minimises `sum_g |Ghat - G|^2 / sigma_g^2` (maximum likelihood for
    /// independent Gaussian errors) and the standard errors come from that weighting; without it,
    /// the paper's `J` (every point alike).
    pub point_std: Option<Vec<f64>>,
}

/// The refitted PMSM model `K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`.
#[derive(Debug, Clone, PartialEq)]
pub struct PmsmFit {
    /// The model as a transfer function.
    pub model: FracTf,
    /// Static gain `K` (`1/C_e`).
    pub k: f64,
    /// `a1 = T_m`.
    pub a1: f64,
    /// `a2 = T_m T_l`.
    pub a2: f64,
    /// Order of the electrical store (`s^zeta` term).
    pub zeta: f64,
    /// Order of the mechanical store (`s^(zeta+theta)` is the leading term).
    pub theta: f64,
    /// The error index `J` (eq. 30) on the data.
    pub j: f64,
    /// Standard errors of `(K, a1, a2, zeta, theta)` by the delta method from the LM covariance
    /// (meaningful when the residuals are noise-like; `None` if the Jacobian is singular).
    pub std_errors: Option<[f64; 5]>,
    /// The solver's report (parameters in the internal log/logistic coordinates).
    pub report: LmReport,
}

fn order_of(u: f64) -> f64 {
    2.0 / (1.0 + (-u).exp())
}

fn u_of(order: f64) -> f64 {
    let z = order.clamp(1e-6, 2.0 - 1e-6) / 2.0;
    (z / (1.0 - z)).ln()
}

struct PmsmProblem<'a> {
    omega: &'a [f64],
    h: &'a [Complex64],
    sign: f64,
    /// Per-point residual scale: `1/sigma_g`, or `1/sqrt(f)` so that `sum r^2 = J`.
    scale: Vec<f64>,
}

impl Problem for PmsmProblem<'_> {
    fn n_params(&self) -> usize {
        5
    }
    fn n_residuals(&self) -> usize {
        2 * self.omega.len()
    }
    fn eval(&mut self, p: &[f64], r: &mut [f64], jac: Option<&mut Mat<f64>>) -> Result<()> {
        let k = self.sign * p[0].exp();
        let (a1, a2) = (p[1].exp(), p[2].exp());
        let (zeta, theta) = (order_of(p[3]), order_of(p[4]));
        // d order / d u = 2 sig (1 - sig) = order (1 - order/2)
        let (dz, dt) = (zeta * (1.0 - zeta / 2.0), theta * (1.0 - theta / 2.0));
        let mut jac = jac;
        for (g, (&w, &hg)) in self.omega.iter().zip(self.h).enumerate() {
            let scale = self.scale[g];
            let s1 = jw_pow(w, zeta) * a1;
            let s2 = jw_pow(w, zeta + theta) * a2;
            let d = s2 + s1 + 1.0;
            let ghat = k / d;
            let e = (ghat - hg) * scale;
            r[2 * g] = e.re;
            r[2 * g + 1] = e.im;
            if let Some(jm) = jac.as_deref_mut() {
                let ln_jw = Complex64::new(w.ln(), FRAC_PI_2);
                let dg_dd = -ghat / d * scale;
                let cols = [
                    ghat * scale,                   // d/d ln K
                    dg_dd * s1,                     // d/d ln a1
                    dg_dd * s2,                     // d/d ln a2
                    dg_dd * (s1 + s2) * ln_jw * dz, // d/d u_zeta
                    dg_dd * s2 * ln_jw * dt,        // d/d u_theta
                ];
                for (c, z) in cols.iter().enumerate() {
                    jm[(2 * g, c)] = z.re;
                    jm[(2 * g + 1, c)] = z.im;
                }
            }
        }
        Ok(())
    }
}

/// Refit `K / (a2 s^(zeta+theta) + a1 s^zeta + 1)` to Bode data by Levenberg-Marquardt on the
/// complex error (minimising the paper's eq. 30 `J`), started from a Levy fit with `n = 2`,
/// `m = 0`: `K = b_0`, `a1`, `a2` from the fit (absolute values), `zeta = theta = q`.
///
/// With [`RefineOptions::point_std`] the residuals are weighted by `1/sigma_g` and the standard
/// errors are those of the weighted problem (`s^2 (J'J)^-1` with `s^2` the weighted residual
/// variance, near 1 when the spread describes the errors).
///
/// Several starts are tried (`zeta = q` and `q +- 0.1` with `theta = 2 q - zeta`) and the best
/// kept, since `J` can have shallow side valleys in the order split.
///
/// ```
/// use ident::levy::{levy_fixed_q, refine_pmsm, vinagre_weights, RefineOptions};
/// let truth = fracsim::FracTf::pmsm(6.8, 0.006, 2.6e-5, 0.92, 0.83).unwrap();
/// let omega: Vec<f64> = (0..25).map(|i| 10f64.powf(-0.5 + 3.5 * i as f64 / 24.0)).collect();
/// let h = truth.bode(&omega);
/// let start = levy_fixed_q(&omega, &h, 0.88, 0, 2, &vinagre_weights(&omega), 0).unwrap();
/// let fit = refine_pmsm(&omega, &h, &start, &RefineOptions::default()).unwrap();
/// assert!((fit.zeta - 0.92).abs() < 1e-4 && (fit.theta - 0.83).abs() < 1e-4);
/// ```
///
/// # Errors
/// [`Error::Data`] for bad data; [`Error::Options`] if `start` is not `n = 2`, `m = 0`;
/// [`Error::NotEnoughData`] with fewer than 3 points (6 real residuals for 5 parameters);
/// [`Error::Numerical`] if every start breaks down.
pub fn refine_pmsm(
    omega_rad_s: &[f64],
    h: &[Complex64],
    start: &LevyFit,
    opts: &RefineOptions,
) -> Result<PmsmFit> {
    check_bode(omega_rad_s, h)?;
    if start.b.len() != 1 || start.a.len() != 2 {
        return Err(Error::Options(format!(
            "the PMSM refit starts from a Levy fit with n = 2, m = 0 (got n = {}, m = {})",
            start.a.len(),
            start.b.len().saturating_sub(1)
        )));
    }
    if omega_rad_s.len() < 3 {
        return Err(Error::NotEnoughData(format!(
            "{} frequency points for 5 parameters (need at least 3)",
            omega_rad_s.len()
        )));
    }
    let k0 = start.b[0];
    if k0 == 0.0 || !k0.is_finite() {
        return Err(Error::Numerical(format!("start gain K = {k0} is unusable")));
    }
    let sign = k0.signum();
    // a coefficient that came out <= 0 in Levy: start it small but positive
    let pos = |x: f64, fallback: f64| if x > 0.0 { x } else { x.abs().max(fallback) };
    let a1 = pos(start.a[0], 1e-6);
    let a2 = pos(start.a[1], 1e-9);
    let q = start.q;
    let scale = match &opts.point_std {
        None => vec![1.0 / (omega_rad_s.len() as f64).sqrt(); omega_rad_s.len()],
        Some(sd) => {
            if sd.len() != omega_rad_s.len() {
                return Err(Error::Data(format!(
                    "{} point standard deviations for {} frequency points",
                    sd.len(),
                    omega_rad_s.len()
                )));
            }
            if let Some(i) = sd.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(Error::Data(format!(
                    "point standard deviation {} (point {}) must be positive and finite",
                    sd[i],
                    i + 1
                )));
            }
            sd.iter().map(|v| 1.0 / v).collect()
        }
    };
    let mut problem = PmsmProblem {
        omega: omega_rad_s,
        h,
        sign,
        scale,
    };
    let mut best: Option<LmReport> = None;
    let mut last_err = None;
    for dz in [0.0, -0.1, 0.1] {
        let zeta = (q + dz).clamp(0.02, 1.98);
        let theta = (2.0 * q - zeta).clamp(0.02, 1.98);
        let p0 = [k0.abs().ln(), a1.ln(), a2.ln(), u_of(zeta), u_of(theta)];
        match minimize(&mut problem, &p0, &opts.lm) {
            Ok(rep) => {
                if !matches!(&best, Some(b) if b.cost <= rep.cost) {
                    best = Some(rep);
                }
            }
            Err(e) => last_err = Some(e),
        }
    }
    let report = match best {
        Some(r) => r,
        None => {
            return Err(
                last_err.unwrap_or_else(|| Error::Numerical("the PMSM refit broke down".into()))
            )
        }
    };
    let p = &report.params;
    let (k, a1, a2) = (sign * p[0].exp(), p[1].exp(), p[2].exp());
    let (zeta, theta) = (order_of(p[3]), order_of(p[4]));
    let model = FracTf::pmsm(k, a1, a2, zeta, theta)?;
    let j = error_index(omega_rad_s, h, &model);
    // delta method: d(natural)/d(internal) is diagonal
    let std_errors = report.std_errors.as_ref().map(|se| {
        [
            k.abs() * se[0],
            a1 * se[1],
            a2 * se[2],
            zeta * (1.0 - zeta / 2.0) * se[3],
            theta * (1.0 - theta / 2.0) * se[4],
        ]
    });
    Ok(PmsmFit {
        model,
        k,
        a1,
        a2,
        zeta,
        theta,
        j,
        std_errors,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lm::FiniteDiff;

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let omega = [0.5, 3.0, 20.0, 150.0];
        let h: Vec<Complex64> = FracTf::pmsm(5.0, 0.01, 1e-4, 0.9, 0.7)
            .unwrap()
            .bode(&omega);
        let p = [1.5, -4.0, -9.5, 0.3, -0.2];
        // unequal per-point scales: the weighted problem's Jacobian is checked too
        let scale = vec![0.5, 1.0, 2.0, 0.25];
        let mut a = PmsmProblem {
            omega: &omega,
            h: &h,
            sign: 1.0,
            scale: scale.clone(),
        };
        let mut ja = Mat::<f64>::zeros(8, 5);
        let mut r = vec![0.0; 8];
        a.eval(&p, &mut r, Some(&mut ja)).unwrap();
        let mut fd = FiniteDiff::new(PmsmProblem {
            omega: &omega,
            h: &h,
            sign: 1.0,
            scale,
        });
        let mut jf = Mat::<f64>::zeros(8, 5);
        fd.eval(&p, &mut r, Some(&mut jf)).unwrap();
        for i in 0..8 {
            for c in 0..5 {
                // 1e-6 absolute + relative: central differences with h ~ 6e-6 are accurate to ~1e-9
                // here; the margin covers the largest entries.
                assert!(
                    (ja[(i, c)] - jf[(i, c)]).abs() < 1e-6 * (1.0 + ja[(i, c)].abs()),
                    "({i},{c}): {} vs {}",
                    ja[(i, c)],
                    jf[(i, c)]
                );
            }
        }
    }

    #[test]
    fn logistic_round_trip() {
        for o in [0.1, 0.89, 1.0, 1.7] {
            assert!((order_of(u_of(o)) - o).abs() < 1e-12);
        }
    }
}
