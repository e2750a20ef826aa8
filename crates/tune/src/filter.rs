//! A filter in series with the controller for a plant with a lightly damped resonance: a notch
//! at the resonance or a first-order low-pass below it, with real poles only, so that its
//! discrete realisation is two (or one) first-order sections the drive runs like the
//! controller's own ([`drive`'s parallel first-order sections](Filter::discrete)).
//!
//! - The notch `(s^2 + 2 zeta_z w s + w^2) / ((s + p1)(s + p2))`, `p1 p2 = w^2`,
//!   `p1 + p2 = 2 zeta_p w` with `zeta_p > 1` (real, distinct poles): its gain at `w` is
//!   `zeta_z / zeta_p`, its gain far from `w` is 1. With `zeta_z` the resonance's damping its
//!   zeros cancel the resonance's poles. Real poles make it wide: its phase lag below `w` is
//!   `atan(2 zeta_p x / (1 - x^2))` at `x = omega/w` (37 deg at a third of `w` for
//!   `zeta_p = 1`), which the design at the crossover takes into account like the plant's own.
//! - The low-pass `w / (s + w)`.
//!
//! The tuner designs on the plant times the filter ([`series_tf`]); the drive runs the filter
//! then the controller ([`then`]): the loop `C F G` is the same.

use crate::error::{invalid, Result};
use fracsim::export::StateSpace;
use fracsim::{FracTf, Term};
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;

/// A filter in series with the controller.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Filter {
    /// `(s^2 + 2 zeta_z w s + w^2) / (s^2 + 2 zeta_p w s + w^2)`, `zeta_p > 1`.
    Notch {
        /// The notch frequency `w`, rad/s.
        omega: f64,
        /// The zeros' damping (the depth at `w` is `zeta_z / zeta_p`).
        zeta_z: f64,
        /// The poles' damping, above 1 (real poles).
        zeta_p: f64,
    },
    /// `w / (s + w)`.
    LowPass {
        /// The corner frequency `w`, rad/s.
        omega: f64,
    },
}

impl Filter {
    /// Check the filter's numbers.
    ///
    /// # Errors
    /// [`crate::Error::Invalid`] for a frequency that is not positive, a zeros' damping
    /// outside `[0, zeta_p)` or a poles' damping not above 1.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Filter::Notch {
                omega,
                zeta_z,
                zeta_p,
            } => {
                if !(omega.is_finite() && omega > 0.0) {
                    return invalid("notch", format!("frequency {omega} rad/s must be positive"));
                }
                if !(zeta_p.is_finite() && zeta_p > 1.0) {
                    return invalid(
                        "notch",
                        format!("poles' damping {zeta_p} must be above 1 (real poles)"),
                    );
                }
                if !(zeta_z >= 0.0 && zeta_z < zeta_p) {
                    return invalid(
                        "notch",
                        format!("zeros' damping {zeta_z} must be in [0, {zeta_p})"),
                    );
                }
                Ok(())
            }
            Filter::LowPass { omega } if !(omega.is_finite() && omega > 0.0) => {
                invalid("low-pass", format!("corner {omega} rad/s must be positive"))
            }
            Filter::LowPass { .. } => Ok(()),
        }
    }

    /// The poles, as values of `s` (negative reals), slowest first.
    fn poles(&self) -> Vec<f64> {
        match *self {
            Filter::Notch { omega, zeta_p, .. } => {
                let r = (zeta_p * zeta_p - 1.0).sqrt();
                vec![-omega * (zeta_p - r), -omega * (zeta_p + r)]
            }
            Filter::LowPass { omega } => vec![-omega],
        }
    }

    /// The numerator `N(s)` at `s` (the denominator is `prod (s - p)`).
    fn num_at(&self, s: Complex64) -> Complex64 {
        match *self {
            Filter::Notch { omega, zeta_z, .. } => {
                s * s + s * (2.0 * zeta_z * omega) + omega * omega
            }
            Filter::LowPass { omega } => Complex64::new(omega, 0.0),
        }
    }

    /// The frequency the discretisation keeps exact (the notch's, the corner), rad/s.
    pub fn omega(&self) -> f64 {
        match *self {
            Filter::Notch { omega, .. } | Filter::LowPass { omega } => omega,
        }
    }

    /// `F(j omega)`.
    pub fn freq_response(&self, omega: f64) -> Complex64 {
        let s = Complex64::new(0.0, omega);
        self.poles()
            .iter()
            .fold(self.num_at(s), |acc, &p| acc / (s - p))
    }

    /// The filter as a transfer function (integer orders, static gain 1).
    ///
    /// # Errors
    /// A filter that does not [`Filter::validate`].
    pub fn tf(&self) -> Result<FracTf> {
        self.validate()?;
        let (num, den) = match *self {
            Filter::Notch {
                omega,
                zeta_z,
                zeta_p,
            } => {
                let w2 = omega.powi(-2);
                (
                    vec![
                        Term::new(w2, 2.0),
                        Term::new(2.0 * zeta_z / omega, 1.0),
                        Term::new(1.0, 0.0),
                    ],
                    vec![
                        Term::new(w2, 2.0),
                        Term::new(2.0 * zeta_p / omega, 1.0),
                        Term::new(1.0, 0.0),
                    ],
                )
            }
            Filter::LowPass { omega } => (
                vec![Term::new(1.0, 0.0)],
                vec![Term::new(1.0 / omega, 1.0), Term::new(1.0, 0.0)],
            ),
        };
        let num: Vec<Term> = num.into_iter().filter(|t| t.coef != 0.0).collect();
        Ok(FracTf::new(num, den, 0.0)?)
    }

    /// The discrete realisation at `dt` seconds: the bilinear (Tustin) transform prewarped at
    /// [`Filter::omega`] (the notch's frequency and depth, the corner's gain kept exactly),
    /// in parallel first-order sections, `F = D + sum_k g_k (1 + a_k)/(z - a_k)` with
    /// `a_k = (K + p_k)/(K - p_k)`, `K = omega / tan(omega dt / 2)`: `A` diagonal (real,
    /// distinct poles in `(-1, 1)`), `B` ones.
    ///
    /// # Errors
    /// A filter that does not [`Filter::validate`]; a step that is not positive or a frequency
    /// at or above the Nyquist frequency `pi/dt`.
    pub fn discrete(&self, dt: f64, like: &StateSpace) -> Result<StateSpace> {
        self.validate()?;
        let w = self.omega();
        if !(dt.is_finite() && dt > 0.0 && w * dt < std::f64::consts::PI) {
            return invalid(
                "filter",
                format!("{w} rad/s must be below the Nyquist frequency pi/dt (dt = {dt} s)"),
            );
        }
        let k = w / (w * dt / 2.0).tan();
        let poles = self.poles();
        let n = poles.len();
        // F(s) = d + sum r_k / (s - p_k): d = 1 for the notch (proper), 0 for the low-pass
        let d0 = if matches!(self, Filter::Notch { .. }) {
            1.0
        } else {
            0.0
        };
        let mut a = DMatrix::zeros(n, n);
        let mut c = DMatrix::zeros(1, n);
        let mut d = d0;
        for (i, &p) in poles.iter().enumerate() {
            let s = Complex64::new(p, 0.0);
            let others: Complex64 = poles
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .fold(Complex64::new(1.0, 0.0), |acc, (_, &q)| acc * (s - q));
            let r = (self.num_at(s) / others).re;
            // r/(s - p) with s = K (z - 1)/(z + 1): g (z + 1)/(z - a)
            let ai = (k + p) / (k - p);
            let g = r / (k - p);
            a[(i, i)] = ai;
            c[(0, i)] = g * (1.0 + ai);
            d += g;
        }
        Ok(StateSpace {
            a,
            b: DMatrix::from_element(n, 1, 1.0),
            c,
            d,
            dt: Some(dt),
            input_delay: 0.0,
            delay_states: 0,
            band: like.band,
            spec: like.spec,
        })
    }
}

/// `first` followed by `next` (the output of one the input of the other), both discrete at the
/// same step: `A = [A1 0; B2 C1 A2]`, lower (block) triangular when both are; `next`'s states
/// last, so a state that feeds none in `next` still feeds none.
pub fn then(first: &StateSpace, next: &StateSpace) -> StateSpace {
    let (n1, n2) = (first.a.nrows(), next.a.nrows());
    let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
    a.view_mut((0, 0), (n1, n1)).copy_from(&first.a);
    a.view_mut((n1, n1), (n2, n2)).copy_from(&next.a);
    a.view_mut((n1, 0), (n2, n1))
        .copy_from(&(&next.b * &first.c));
    let mut b = DMatrix::zeros(n1 + n2, 1);
    b.view_mut((0, 0), (n1, 1)).copy_from(&first.b);
    b.view_mut((n1, 0), (n2, 1)).copy_from(&(&next.b * first.d));
    let mut c = DMatrix::zeros(1, n1 + n2);
    c.view_mut((0, 0), (1, n1)).copy_from(&(&first.c * next.d));
    c.view_mut((0, n1), (1, n2)).copy_from(&next.c);
    StateSpace {
        a,
        b,
        c,
        d: first.d * next.d,
        delay_states: 0,
        ..next.clone()
    }
}

/// The product of two terms' lists, equal orders merged.
fn times(a: &[Term], b: &[Term]) -> Vec<Term> {
    let mut out: Vec<Term> = vec![];
    for x in a {
        for y in b {
            let o = x.order + y.order;
            match out.iter_mut().find(|t| (t.order - o).abs() < 1e-12) {
                Some(t) => t.coef += x.coef * y.coef,
                None => out.push(Term::new(x.coef * y.coef, o)),
            }
        }
    }
    out.sort_by(|p, q| q.order.total_cmp(&p.order));
    out
}

/// The plant `g` in series with the filter `f`: the product multiplied out, known as its factors
/// (`g`'s own, or `g`, then `f`) so that the simulators take them one by one, `g`'s delay.
///
/// # Errors
/// A filter that does not [`Filter::validate`]; a product the model type refuses.
pub fn series_tf(g: &FracTf, f: &Filter) -> Result<FracTf> {
    let ft = f.tf()?;
    let whole = FracTf::new(times(&g.num, &ft.num), times(&g.den, &ft.den), g.delay)?;
    let mut factors: Vec<FracTf> = if g.factors().is_empty() {
        vec![g.clone()]
    } else {
        g.factors().to_vec()
    };
    factors.push(ft);
    Ok(whole.clone().with_factors(factors).unwrap_or(whole))
}

#[cfg(test)]
mod tests {
    use super::*;
    use fracsim::ApproxSpec;

    fn like(dt: f64) -> StateSpace {
        StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 1),
            c: DMatrix::zeros(1, 0),
            d: 1.0,
            dt: Some(dt),
            input_delay: 0.0,
            delay_states: 0,
            band: (1e-3, 1e4),
            spec: ApproxSpec::default(),
        }
    }

    /// `C (z I - A)^-1 B + D` for a diagonal or triangular `A`, by forward substitution.
    fn response(ss: &StateSpace, omega: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, omega * ss.dt.unwrap());
        let n = ss.a.nrows();
        let mut x = vec![Complex64::new(0.0, 0.0); n];
        for i in 0..n {
            let s: Complex64 = (0..i).map(|j| x[j] * ss.a[(i, j)]).sum();
            x[i] = (s + ss.b[(i, 0)]) / (z - ss.a[(i, i)]);
        }
        (0..n).map(|i| x[i] * ss.c[(0, i)]).sum::<Complex64>() + ss.d
    }

    #[test]
    fn the_notch_is_deep_at_its_frequency_and_flat_away() {
        let w = 2.0 * std::f64::consts::PI * 45.0;
        let f = Filter::Notch {
            omega: w,
            zeta_z: 0.05,
            zeta_p: 1.2,
        };
        // continuous: depth zeta_z / zeta_p at w (the transfer function and the direct form)
        let tf = f.tf().unwrap();
        for x in [w, 0.1 * w, 10.0 * w] {
            assert!((tf.freq_response(x) - f.freq_response(x)).norm() < 1e-12);
        }
        assert!((f.freq_response(w).norm() - 0.05 / 1.2).abs() < 1e-12);
        assert!((f.freq_response(1e-3).norm() - 1.0).abs() < 1e-6);
        // discrete at 1 kHz: the same depth at w (prewarped), close to the continuous below it
        let dt = 1e-3;
        let d = f.discrete(dt, &like(dt)).unwrap();
        assert!(
            (response(&d, w).norm() - 0.05 / 1.2).abs() < 1e-9,
            "{}",
            response(&d, w)
        );
        for x in [1.0, 30.0, 100.0] {
            let e = (response(&d, x) - f.freq_response(x)).norm();
            assert!(e < 0.01, "{x}: {e}");
        }
        // real, distinct poles inside the unit circle: the drive's sections
        let (a1, a2) = (d.a[(0, 0)], d.a[(1, 1)]);
        assert!(a1 > 0.0 && a1 < 1.0 && a2 > 0.0 && a2 < 1.0 && (a1 - a2).abs() > 1e-3);
    }

    #[test]
    fn the_low_pass_and_a_cascade() {
        let dt = 1e-3;
        let f = Filter::LowPass { omega: 150.0 };
        let d = f.discrete(dt, &like(dt)).unwrap();
        assert!((response(&d, 150.0) - f.freq_response(150.0)).norm() < 1e-9);
        assert!((response(&d, 1e-4).norm() - 1.0).abs() < 1e-6);
        // the notch then the low-pass: the product of the responses
        let n = Filter::Notch {
            omega: 300.0,
            zeta_z: 0.1,
            zeta_p: 1.5,
        };
        let dn = n.discrete(dt, &like(dt)).unwrap();
        let both = then(&dn, &d);
        for x in [10.0, 300.0, 1000.0] {
            let e = (response(&both, x) - response(&dn, x) * response(&d, x)).norm();
            assert!(e < 1e-12, "{x}: {e}");
        }
        // lower triangular
        assert!(both.a[(0, 2)] == 0.0 && both.a[(2, 0)] != 0.0);
        let g: FracTf = "2/(0.01 s + 1)".parse().unwrap();
        let gf = series_tf(&g, &n).unwrap();
        for x in [1.0, 300.0, 3000.0] {
            let e = (gf.freq_response(x) - g.freq_response(x) * n.freq_response(x)).norm();
            assert!(e < 1e-12 * g.freq_response(x).norm().max(1.0), "{x}: {e}");
        }
        assert_eq!(gf.factors().len(), 2);
    }

    #[test]
    fn bad_filters_are_refused() {
        for f in [
            Filter::Notch {
                omega: 100.0,
                zeta_z: 0.1,
                zeta_p: 0.7,
            },
            Filter::Notch {
                omega: -1.0,
                zeta_z: 0.1,
                zeta_p: 1.5,
            },
            Filter::LowPass { omega: 0.0 },
        ] {
            assert!(f.validate().is_err(), "{f:?}");
        }
        let f = Filter::LowPass { omega: 4000.0 };
        assert!(f.discrete(1e-3, &like(1e-3)).is_err());
    }
}
