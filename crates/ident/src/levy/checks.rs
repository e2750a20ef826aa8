//! Honest frequency-domain results: what makes a fitted model unusable (unstable, non-finite,
//! parameters the data do not determine) and what deserves a warning, as
//! [`crate::oe::Identification::problems`] does for the time-domain fit.
//!
//! Stability of a fractional model `G = N/D`, `D(s) = sum_k c_k s^(alpha_k)` (principal branch,
//! `|arg s| < pi`): the poles are the zeros of `D` on that sheet, and the model is stable when
//! none lies in the closed right half-plane (Matignon 1996 for commensurate orders: every root
//! `lambda` of `D` as a polynomial in `s^q` has `|arg lambda| > q pi/2`; the right-half-plane count
//! is the same statement without needing a commensurate base, so it also covers the refit's two
//! free orders). The count is the argument principle on the contour of the right half-plane
//! (Bode/Nyquist for fractional systems, e.g. Monje et al., "Fractional-order Systems and
//! Controls", 2010, sec. 2.4): down the imaginary axis, round a small arc at 0 and a large arc
//! through `+R`. With `theta(w)` the unwrapped `arg D(jw)` from `w -> 0` to `w -> inf`,
//! `alpha_lo`/`alpha_hi` the lowest and highest orders:
//!
//! `N_rhp = ((alpha_hi - alpha_lo) pi - 2 (theta(inf) - theta(0))) / (2 pi)`.
//!
//! `theta` is followed on a log grid in `omega` (evaluated overflow-free in logarithms), each step
//! bisected until the phase moves by less than `pi/4`, from where every term but the lowest is a
//! tenth of it to where every term but the highest is (there `arg D` is within `asin 0.1` of its
//! asymptote, so the rounded count is exact).

use fracsim::{FracTf, Term};
use num_complex::Complex64;
use std::f64::consts::{FRAC_PI_2, PI};

/// A parameter whose standard error is this many times its value is not determined by the data
/// (as the time-domain checks): the result is not usable. Between once and this, a warning.
const UNDETERMINED: f64 = 10.0;

/// The poles of a model's denominator in the closed right half-plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RhpPoles {
    /// This many poles with `Re s > 0` (0: stable, when no pole is on the axis either).
    Count(usize),
    /// A pole on the imaginary axis (`D(jw) = 0` for some `w >= 0`): marginally stable at best.
    OnAxis,
}

/// Terms with equal orders merged, zero coefficients dropped, sorted by order.
fn merged(terms: &[Term]) -> Vec<(f64, f64)> {
    let mut t: Vec<(f64, f64)> = Vec::new();
    let mut sorted: Vec<&Term> = terms.iter().collect();
    sorted.sort_by(|a, b| a.order.total_cmp(&b.order));
    for term in sorted {
        match t.last_mut() {
            Some((o, c)) if *o == term.order => *c += term.coef,
            _ => t.push((term.order, term.coef)),
        }
    }
    t.retain(|&(_, c)| c != 0.0);
    t
}

/// `D(j 10^x)` divided by a positive real (the largest term's magnitude): only its argument and
/// its distance from 0 relative to its terms are used. Overflow-free for any `x`.
fn den_scaled(t: &[(f64, f64)], x: f64) -> Complex64 {
    let ln_w = x * std::f64::consts::LN_10;
    let big = t
        .iter()
        .map(|&(o, c)| c.abs().ln() + o * ln_w)
        .fold(f64::NEG_INFINITY, f64::max);
    t.iter()
        .map(|&(o, c)| {
            let mag = (c.abs().ln() + o * ln_w - big).exp();
            Complex64::from_polar(mag * c.signum(), o * FRAC_PI_2)
        })
        .sum()
}

/// The phase step of `arg D` from `x0` to `x1` (log10 omega), bisecting until each step is below
/// `pi/4`; `None` when it cannot be resolved (a zero on the axis, at the resolution of `f64`).
fn phase_step(
    t: &[(f64, f64)],
    x0: f64,
    d0: Complex64,
    x1: f64,
    d1: Complex64,
    depth: u32,
) -> Option<f64> {
    let step = (d1 / d0).arg();
    if step.abs() < PI / 4.0 {
        return Some(step);
    }
    let xm = 0.5 * (x0 + x1);
    if depth > 60 || xm == x0 || xm == x1 {
        return None;
    }
    let dm = den_scaled(t, xm);
    if dm.norm() < 1e-12 {
        return None;
    }
    Some(phase_step(t, x0, d0, xm, dm, depth + 1)? + phase_step(t, xm, dm, x1, d1, depth + 1)?)
}

/// The number of poles of `1/D(s)` (`D = sum terms`, orders >= 0) in the closed right half-plane
/// of the principal sheet, by the argument principle (see the [module docs](self)).
///
/// ```
/// use fracsim::Term;
/// use ident::levy::checks::{rhp_poles, RhpPoles};
/// // the paper's PMSM denominator: stable
/// let d = [Term::new(1.0, 0.0), Term::new(0.0059, 0.92), Term::new(0.00002655, 1.7452)];
/// assert_eq!(rhp_poles(&d), RhpPoles::Count(0));
/// // 1 + s^2.5: s = e^(+-j 0.4 pi), two poles in the right half-plane
/// assert_eq!(rhp_poles(&[Term::new(1.0, 0.0), Term::new(1.0, 2.5)]), RhpPoles::Count(2));
/// // s^2 + 1: poles at +-j
/// assert_eq!(rhp_poles(&[Term::new(1.0, 0.0), Term::new(1.0, 2.0)]), RhpPoles::OnAxis);
/// ```
pub fn rhp_poles(den: &[Term]) -> RhpPoles {
    let t = merged(den);
    if t.len() < 2 {
        // a constant (no pole) or c s^a (a pole at 0 when a > 0, on the axis)
        return match t.first() {
            Some(&(o, _)) if o > 0.0 => RhpPoles::OnAxis,
            _ => RhpPoles::Count(0),
        };
    }
    let (lo, hi) = (t[0], t[t.len() - 1]);
    // from where every other term is below 0.1/(K-1) of the lowest one, to where every other
    // term is below that of the highest one (log10 omega)
    let share = (0.1 / (t.len() - 1) as f64).log10();
    let l = |c: f64| c.abs().log10();
    let x_lo = t[1..]
        .iter()
        .map(|&(o, c)| (share - (l(c) - l(lo.1))) / (o - lo.0))
        .fold(f64::INFINITY, f64::min);
    let x_hi = t[..t.len() - 1]
        .iter()
        .map(|&(o, c)| ((l(c) - l(hi.1)) - share) / (hi.0 - o))
        .fold(f64::NEG_INFINITY, f64::max);
    let (x_lo, x_hi) = (x_lo.min(x_hi) - 1.0, x_hi.max(x_lo) + 1.0);
    if !(x_lo.is_finite() && x_hi.is_finite()) {
        return RhpPoles::OnAxis;
    }
    let steps = (((x_hi - x_lo) / 0.02).ceil() as usize).clamp(100, 200_000);
    let h = (x_hi - x_lo) / steps as f64;
    let mut x0 = x_lo;
    let mut d0 = den_scaled(&t, x0);
    let mut dtheta = 0.0;
    for i in 1..=steps {
        let x1 = x_lo + h * i as f64;
        let d1 = den_scaled(&t, x1);
        if d0.norm() < 1e-12 || d1.norm() < 1e-12 {
            return RhpPoles::OnAxis;
        }
        match phase_step(&t, x0, d0, x1, d1, 0) {
            Some(s) => dtheta += s,
            None => return RhpPoles::OnAxis,
        }
        (x0, d0) = (x1, d1);
    }
    if lo.0 > 0.0 {
        return RhpPoles::OnAxis; // no constant term: a pole at s = 0
    }
    let n = ((hi.0 - lo.0) * PI - 2.0 * dtheta) / (2.0 * PI);
    RhpPoles::Count(n.round().max(0.0) as usize)
}

/// What makes a frequency-domain model unusable (the first list; empty when usable) and what
/// deserves a warning (the second): non-finite coefficients, poles in the closed right
/// half-plane ([`rhp_poles`]), no finite static gain (a negative one is a warning).
pub fn model_problems(g: &FracTf) -> (Vec<String>, Vec<String>) {
    let (mut problems, mut warnings) = (vec![], vec![]);
    let finite = g
        .num
        .iter()
        .chain(&g.den)
        .all(|t| t.coef.is_finite() && t.order.is_finite())
        && g.delay.is_finite();
    if !finite {
        problems.push("the model has non-finite coefficients".into());
        return (problems, warnings);
    }
    match rhp_poles(&g.den) {
        RhpPoles::Count(0) => {}
        RhpPoles::Count(n) => problems.push(format!(
            "the model is unstable: {n} pole(s) in the right half-plane (its denominator \
             {} has zeros with Re s > 0)",
            den_text(&g.den)
        )),
        RhpPoles::OnAxis => problems.push(format!(
            "the model is not stable: a pole on the imaginary axis (its denominator {} vanishes \
             at some s = jw)",
            den_text(&g.den)
        )),
    }
    let dc = g.dc_gain();
    if !dc.is_finite() {
        problems.push("the model has no finite static gain".into());
    } else if dc < 0.0 {
        warnings.push(format!(
            "the static gain G(0) = {dc:.4e} is negative: the output falls when the input rises"
        ));
    }
    (problems, warnings)
}

/// The denominator for a message: `c s^a` terms by decreasing order, 5 significant digits.
fn den_text(den: &[Term]) -> String {
    let mut t = merged(den);
    t.reverse();
    let mut out = String::new();
    for (k, &(o, c)) in t.iter().enumerate() {
        let sign = if c < 0.0 { "-" } else { "+" };
        if k == 0 {
            out.push_str(if c < 0.0 { "-" } else { "" });
        } else {
            out.push_str(&format!(" {sign} "));
        }
        if o == 0.0 && c.abs() == 1.0 {
            out.push('1');
        } else if o == 0.0 {
            out.push_str(&format!("{:.4e}", c.abs()));
        } else {
            out.push_str(&format!("{:.4e} s^{:.4}", c.abs(), o));
        }
    }
    out
}

/// Problems and warnings of the refit's estimates: a standard error of 10 times the value or more
/// makes the result unusable (the data do not determine that parameter), above the value a
/// warning; so do standard errors that cannot be computed at all (a singular Jacobian: some
/// parameter, or combination, has no effect on the fit, as when the orders run to 0 on a table
/// of noise); no convergence is a warning.
pub(crate) fn refit_problems(
    r: &super::PmsmFit,
    problems: &mut Vec<String>,
    warnings: &mut Vec<String>,
) {
    if r.std_errors.is_none() {
        problems.push(format!(
            "refit: the standard errors cannot be computed (the Jacobian is singular): the data \
             do not determine K, a1, a2, zeta, theta (zeta = {:.4e}, theta = {:.4e})",
            r.zeta, r.theta
        ));
    }
    if let Some(se) = r.std_errors {
        let vals = [r.k, r.a1, r.a2, r.zeta, r.theta];
        for ((name, v), s) in ["K", "a1", "a2", "zeta", "theta"].iter().zip(vals).zip(se) {
            if !s.is_finite() || s > UNDETERMINED * v.abs() {
                problems.push(format!(
                    "refit: {name} = {v:.4e} +- {s:.2e} is not determined by these data (standard \
                     error {UNDETERMINED} times the value or more)"
                ));
            } else if s > v.abs() {
                warnings.push(format!(
                    "refit: {name} = {v:.4e} +- {s:.2e} is poorly identifiable from these data \
                     (standard error larger than the value)"
                ));
            }
        }
    }
    if !r.report.converged {
        warnings.push(format!(
            "refit: did not converge ({:?}, {} iterations): the parameters may not be at the \
             optimum",
            r.report.termination, r.report.iterations
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn den(t: &[(f64, f64)]) -> Vec<Term> {
        t.iter().map(|&(c, o)| Term::new(c, o)).collect()
    }

    /// `1 + a s^alpha`: its zeros `s = a^(-1/alpha) e^(j (2k+1) pi/alpha)` on the principal sheet;
    /// in the right half-plane those with `|(2k+1)/alpha| < 1/2` (closed form, independent).
    #[test]
    fn one_plus_s_to_the_alpha_against_the_closed_form() {
        for &a in &[1e-4, 0.3, 1.0, 250.0] {
            for i in 1..80 {
                let alpha = 0.05 * i as f64 + 0.013; // never an odd multiple of... on the axis
                let want = (-40i32..40)
                    .filter(|k| ((2 * k + 1) as f64 / alpha).abs() < 0.5)
                    .count();
                assert_eq!(
                    rhp_poles(&den(&[(1.0, 0.0), (a, alpha)])),
                    RhpPoles::Count(want),
                    "a = {a}, alpha = {alpha}"
                );
                // 1 - a s^alpha: a positive real zero besides
                let want_neg = (-40i32..40)
                    .filter(|k| ((2 * k) as f64 / alpha).abs() < 0.5)
                    .count();
                assert_eq!(
                    rhp_poles(&den(&[(1.0, 0.0), (-a, alpha)])),
                    RhpPoles::Count(want_neg),
                    "a = -{a}, alpha = {alpha}"
                );
            }
        }
    }

    /// Commensurate quadratics `a2 l^2 + a1 l + 1`, `l = s^q`: Matignon's count of the roots
    /// with `|arg l| < q pi/2` (quadratic formula), against the argument principle.
    #[test]
    fn commensurate_quadratics_against_matignon() {
        let mut next = crate::testdata::lcg(12);
        let mut rnd = || (next() >> 11) as f64 / (1u64 << 53) as f64;
        let mut unstable = 0;
        for _ in 0..400 {
            let q = 0.05 + 1.9 * rnd();
            let a1 = (rnd() * 2.0 - 1.0) * 10f64.powf(-3.0 + 4.0 * rnd());
            let a2 = (rnd() * 2.0 - 1.0) * 10f64.powf(-5.0 + 4.0 * rnd());
            let disc = Complex64::new(a1 * a1 - 4.0 * a2, 0.0).sqrt();
            let roots = [(-a1 + disc) / (2.0 * a2), (-a1 - disc) / (2.0 * a2)];
            let margin = roots
                .iter()
                .map(|l| (l.arg().abs() - q * FRAC_PI_2).abs())
                .fold(f64::INFINITY, f64::min);
            if margin < 1e-3 {
                continue; // too close to the boundary for either method to call
            }
            let want = roots
                .iter()
                .filter(|l| l.arg().abs() < q * FRAC_PI_2)
                .count();
            unstable += usize::from(want > 0);
            let d = den(&[(1.0, 0.0), (a1, q), (a2, 2.0 * q)]);
            assert_eq!(
                rhp_poles(&d),
                RhpPoles::Count(want),
                "q {q} a1 {a1} a2 {a2}"
            );
        }
        assert!(unstable > 100, "both kinds drawn: {unstable} unstable");
    }

    #[test]
    fn poles_on_the_axis_and_at_zero() {
        assert_eq!(rhp_poles(&den(&[(1.0, 0.0), (1.0, 2.0)])), RhpPoles::OnAxis);
        assert_eq!(rhp_poles(&den(&[(1.0, 1.0), (1.0, 2.0)])), RhpPoles::OnAxis);
        assert_eq!(rhp_poles(&den(&[(1.0, 0.0)])), RhpPoles::Count(0));
        assert_eq!(
            rhp_poles(&den(&[(1.0, 0.0), (2.0, 1.0), (1.0, 2.0)])),
            RhpPoles::Count(0)
        );
        // (s - 1)(s + 2) = s^2 + s - 2: one, merged from split terms
        assert_eq!(
            rhp_poles(&den(&[(-2.0, 0.0), (0.5, 1.0), (0.5, 1.0), (1.0, 2.0)])),
            RhpPoles::Count(1)
        );
    }

    #[test]
    fn model_problems_name_the_instability() {
        let g: FracTf = "-0.08446/(0.14191 s^0.4895 - 0.81346 s^0.2448 + 1)"
            .parse()
            .unwrap();
        let (p, w) = model_problems(&g);
        assert!(p[0].contains("unstable: 2 pole(s)"), "{p:?}");
        assert!(w[0].contains("negative"), "{w:?}");
        let g: FracTf = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)"
            .parse()
            .unwrap();
        assert_eq!(model_problems(&g), (vec![], vec![]));
    }
}
