//! The transfer function's algebra: product, frequency response, and the checks and summaries
//! the simulators need (validity, integer orders, feed-through).

use super::{Error, Plant, Term};
use num_complex::Complex64;
use std::f64::consts::FRAC_PI_2;

/// Orders closer than this are the same order.
pub(crate) const ORDER_EPS: f64 = 1e-9;

/// The product of two transfer functions: every pair of terms multiplied (coefficients
/// multiplied, orders added), equal orders merged, delays added.
pub(crate) fn product(a: &Plant, b: &Plant) -> Plant {
    Plant {
        num: multiply(&a.num, &b.num),
        den: multiply(&a.den, &b.den),
        delay_s: a.delay_s + b.delay_s,
    }
}

fn multiply(a: &[Term], b: &[Term]) -> Vec<Term> {
    let mut out: Vec<Term> = Vec::new();
    for x in a {
        for y in b {
            let order = x.order + y.order;
            let coef = x.coef * y.coef;
            match out.iter_mut().find(|t| (t.order - order).abs() < ORDER_EPS) {
                Some(t) => t.coef += coef,
                None => out.push(Term { coef, order }),
            }
        }
    }
    out.sort_by(|p, q| p.order.total_cmp(&q.order));
    out
}

/// `(j omega)^order = |omega|^order (cos(order pi/2) + j sign(omega) sin(order pi/2))`.
pub(crate) fn s_power(omega: f64, order: f64) -> Complex64 {
    if order == 0.0 {
        return Complex64::new(1.0, 0.0);
    }
    Complex64::from_polar(omega.abs().powf(order), order * FRAC_PI_2 * omega.signum())
}

fn evaluate(terms: &[Term], omega: f64) -> Complex64 {
    terms.iter().map(|t| t.coef * s_power(omega, t.order)).sum()
}

/// `G(j omega)`, the delay included.
pub(crate) fn response(plant: &Plant, omega: f64) -> Complex64 {
    let delay = Complex64::from_polar(1.0, -omega * plant.delay_s);
    evaluate(&plant.num, omega) / evaluate(&plant.den, omega) * delay
}

/// The terms with a non-zero coefficient.
pub(crate) fn nonzero(terms: &[Term]) -> Vec<Term> {
    terms.iter().copied().filter(|t| t.coef != 0.0).collect()
}

fn top_order(terms: &[Term]) -> Option<f64> {
    terms.iter().map(|t| t.order).reduce(f64::max)
}

/// Checks that the plant can be simulated: finite coefficients, orders >= 0, a non-zero
/// denominator, proper (the highest numerator order at most the highest denominator order), a
/// finite delay >= 0.
pub(crate) fn check(plant: &Plant) -> Result<(), Error> {
    let bad = |msg: &str| Err(Error::Plant(msg.to_string()));
    for t in plant.num.iter().chain(&plant.den) {
        if !t.coef.is_finite() || !t.order.is_finite() || t.order < 0.0 {
            return bad(
                "a term's coefficient is not finite or its order is negative or not finite",
            );
        }
    }
    if !plant.delay_s.is_finite() || plant.delay_s < 0.0 {
        return bad("the delay must be finite and >= 0");
    }
    let Some(den_top) = top_order(&nonzero(&plant.den)) else {
        return bad("the denominator has no non-zero term");
    };
    if let Some(num_top) = top_order(&nonzero(&plant.num)) {
        if num_top > den_top + ORDER_EPS {
            return bad("improper: the numerator's highest order exceeds the denominator's");
        }
    }
    Ok(())
}

/// Whether every order (of a non-zero term) is an integer.
pub(crate) fn is_integer(plant: &Plant) -> bool {
    nonzero(&plant.num)
        .iter()
        .chain(&nonzero(&plant.den))
        .all(|t| (t.order - t.order.round()).abs() < ORDER_EPS)
}

/// `G(infinity)`: the step response's jump at the step (0 for a strictly proper plant).
pub(crate) fn feedthrough(plant: &Plant) -> f64 {
    let (num, den) = (nonzero(&plant.num), nonzero(&plant.den));
    let den_top = top_order(&den).unwrap_or(0.0);
    let at = |terms: &[Term]| -> f64 {
        terms
            .iter()
            .filter(|t| (t.order - den_top).abs() < ORDER_EPS)
            .map(|t| t.coef)
            .sum()
    };
    at(&num) / at(&den)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn term(coef: f64, order: f64) -> Term {
        Term { coef, order }
    }

    #[test]
    fn response_matches_hand_values() {
        // 2 / (0.5 s + 1) at omega = 2: 2 / (1 + j) = 1 - j.
        let p = Plant {
            num: vec![term(2.0, 0.0)],
            den: vec![term(1.0, 0.0), term(0.5, 1.0)],
            delay_s: 0.0,
        };
        let g = p.response(2.0);
        assert!((g - Complex64::new(1.0, -1.0)).norm() < 1e-14, "{g}");
        // A delay of 0.25 s at omega = 2 turns it by -0.5 rad.
        let pd = Plant {
            delay_s: 0.25,
            ..p.clone()
        };
        let expect = Complex64::new(1.0, -1.0) * Complex64::from_polar(1.0, -0.5);
        assert!((pd.response(2.0) - expect).norm() < 1e-14);
        // 1 / s^0.5 at omega = 4: 4^-0.5 e^{-j pi/4} = 0.5 (cos 45 - j sin 45).
        let h = Plant {
            num: vec![term(1.0, 0.0)],
            den: vec![term(1.0, 0.5)],
            delay_s: 0.0,
        };
        let r = std::f64::consts::FRAC_1_SQRT_2 * 0.5;
        assert!((h.response(4.0) - Complex64::new(r, -r)).norm() < 1e-14);
        // Negative frequency: the conjugate.
        assert!((h.response(-4.0) - Complex64::new(r, r)).norm() < 1e-14);
        // 1 / (s^1.5 + 1) at omega = 1: 1 / (1 + cos(135) + j sin(135)).
        let q = Plant {
            num: vec![term(1.0, 0.0)],
            den: vec![term(1.0, 0.0), term(1.0, 1.5)],
            delay_s: 0.0,
        };
        let c = (3.0 * std::f64::consts::FRAC_PI_4).cos();
        let s = (3.0 * std::f64::consts::FRAC_PI_4).sin();
        let expect = Complex64::new(1.0, 0.0) / Complex64::new(1.0 + c, s);
        assert!((q.response(1.0) - expect).norm() < 1e-14);
    }

    #[test]
    fn product_multiplies_out_and_merges() {
        // (s + 1) / (s^0.5 + 2) times 3 / (s^0.5 + 1), delays 0.1 and 0.2.
        let a = Plant {
            num: vec![term(1.0, 0.0), term(1.0, 1.0)],
            den: vec![term(2.0, 0.0), term(1.0, 0.5)],
            delay_s: 0.1,
        };
        let b = Plant {
            num: vec![term(3.0, 0.0)],
            den: vec![term(1.0, 0.0), term(1.0, 0.5)],
            delay_s: 0.2,
        };
        let p = a.product(&b);
        assert_eq!(p.num, vec![term(3.0, 0.0), term(3.0, 1.0)]);
        // (s^0.5 + 2)(s^0.5 + 1) = s + 3 s^0.5 + 2.
        assert_eq!(p.den, vec![term(2.0, 0.0), term(3.0, 0.5), term(1.0, 1.0)]);
        assert!((p.delay_s - 0.3).abs() < 1e-15);
        for w in [0.1, 1.0, 7.0] {
            let e = a.response(w) * b.response(w);
            assert!((p.response(w) - e).norm() < 1e-12 * e.norm());
        }
    }

    #[test]
    fn checks_and_summaries() {
        let ok = Plant {
            num: vec![term(2.0, 1.0)],
            den: vec![term(1.0, 0.0), term(4.0, 1.0)],
            delay_s: 0.0,
        };
        assert!(check(&ok).is_ok());
        assert!(is_integer(&ok));
        assert!((feedthrough(&ok) - 0.5).abs() < 1e-15);
        let improper = Plant {
            num: vec![term(1.0, 2.0)],
            den: vec![term(1.0, 1.5)],
            delay_s: 0.0,
        };
        assert!(check(&improper).is_err());
        assert!(!is_integer(&improper));
        let empty = Plant {
            num: vec![term(1.0, 0.0)],
            den: vec![term(0.0, 0.0)],
            delay_s: 0.0,
        };
        assert!(check(&empty).is_err());
        let neg_delay = Plant {
            delay_s: -1.0,
            ..ok.clone()
        };
        assert!(check(&neg_delay).is_err());
        let strictly = Plant {
            num: vec![term(1.0, 0.0)],
            den: vec![term(1.0, 0.7)],
            delay_s: 0.0,
        };
        assert_eq!(feedthrough(&strictly), 0.0);
    }
}
