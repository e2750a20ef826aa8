//! The plants of the zoo: the families drives (and a few neighbours) show, drawn at random over the
//! ranges issue 44 names, each as a `truth::Plant` with its time scales.

use rand::rngs::StdRng;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::truth::{Plant, Term};

/// The family a plant is drawn from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    /// The paper's PMSM: `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)`, total order 1.1-2, corners
    /// 0.3-50 ms, gain 1-100.
    Pmsm,
    /// `K/(tau s + 1)`.
    Integer1,
    /// Two real poles or an underdamped pair.
    Integer2,
    /// Three real poles.
    Integer3,
    /// A compliant coupling measured at the motor: a rigid first order times an anti-resonance
    /// then a resonance (20-150 Hz, damping 0.02-0.2).
    TwoMassMotor,
    /// The same coupling measured at the load: the resonance alone.
    TwoMassLoad,
    /// A rigid first order and two resonances (measured at the load).
    MultiMode,
    /// `D + K/(tau s + 1)`: relative degree 0.
    Feedthrough,
    /// `K/(s (tau s + 1))`: a position output.
    Integrator,
    /// A slow diffusion (thermal): `K/(tau s^alpha + 1)`, alpha 0.3-0.7.
    Diffusion,
    /// A lead: `K (tz s + 1)/((t1 s + 1)(t2 s + 1))`.
    Lead,
    /// An electrochemical cell: `R0 + 1/(C s) + R1/(tau s^alpha + 1)`.
    Cell,
}

/// A drawn plant with the time scales the record is sized on.
#[derive(Clone, Debug)]
pub struct Drawn {
    /// The transfer function.
    pub plant: Plant,
    /// The fastest time constant that matters [s] (sets the sample time).
    pub fast_s: f64,
    /// The slowest time constant [s] (sets the record's length and the input's clock).
    pub slow_s: f64,
    /// The static gain (None for an integrator).
    pub dc_gain: Option<f64>,
    /// One line on what was drawn (for the sidecar).
    pub about: String,
}

/// `coef s^order`.
pub fn term(coef: f64, order: f64) -> Term {
    Term { coef, order }
}

/// The product of two polynomials in fractional powers of s (equal orders merged).
pub fn poly_mul(a: &[Term], b: &[Term]) -> Vec<Term> {
    let mut out = Vec::with_capacity(a.len() * b.len());
    for x in a {
        for y in b {
            out.push(term(x.coef * y.coef, x.order + y.order));
        }
    }
    merge(out)
}

/// The sum of two polynomials (equal orders merged).
pub fn poly_add(a: &[Term], b: &[Term]) -> Vec<Term> {
    merge(a.iter().chain(b).copied().collect())
}

fn merge(mut terms: Vec<Term>) -> Vec<Term> {
    terms.sort_by(|x, y| y.order.total_cmp(&x.order));
    let mut out: Vec<Term> = Vec::with_capacity(terms.len());
    for t in terms {
        match out.last_mut() {
            Some(last) if (last.order - t.order).abs() < 1e-12 => last.coef += t.coef,
            _ => out.push(t),
        }
    }
    out.retain(|t| t.coef != 0.0);
    out
}

/// `(tau s + 1)`.
fn first(tau: f64) -> Vec<Term> {
    vec![term(tau, 1.0), term(1.0, 0.0)]
}

/// `s^2/w^2 + 2 z s/w + 1`.
fn second(omega: f64, damping: f64) -> Vec<Term> {
    vec![
        term(1.0 / (omega * omega), 2.0),
        term(2.0 * damping / omega, 1.0),
        term(1.0, 0.0),
    ]
}

/// Log-uniform in `[lo, hi]`.
pub fn log_uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    (rng.gen_range(lo.ln()..=hi.ln())).exp()
}

fn gain(rng: &mut StdRng) -> f64 {
    log_uniform(rng, 1.0, 100.0)
}

fn plant(num: Vec<Term>, den: Vec<Term>) -> Plant {
    Plant {
        num,
        den,
        delay_s: 0.0,
    }
}

/// Draws a plant of `kind`.
pub fn draw(kind: PlantKind, rng: &mut StdRng) -> Drawn {
    match kind {
        PlantKind::Pmsm => pmsm(rng),
        PlantKind::Integer1 | PlantKind::Integer2 | PlantKind::Integer3 => integer(kind, rng),
        PlantKind::TwoMassMotor | PlantKind::TwoMassLoad | PlantKind::MultiMode => {
            compliant(kind, rng)
        }
        PlantKind::Feedthrough => feedthrough(rng),
        PlantKind::Integrator => integrator(rng),
        PlantKind::Diffusion => diffusion(rng),
        PlantKind::Lead => lead(rng),
        PlantKind::Cell => cell(rng),
    }
}

fn pmsm(rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let zeta = rng.gen_range(0.7..=1.0);
    let total = rng.gen_range((zeta + 0.1_f64).max(1.1)..=2.0);
    let theta = total - zeta;
    let tau1 = log_uniform(rng, 2e-3, 50e-3);
    let tau2 = log_uniform(rng, 0.3e-3, tau1 / 4.0);
    let a1 = tau1.powf(zeta);
    let a2 = a1 * tau2.powf(theta);
    Drawn {
        plant: plant(
            vec![term(k, 0.0)],
            vec![term(a2, total), term(a1, zeta), term(1.0, 0.0)],
        ),
        fast_s: tau2,
        slow_s: tau1,
        dc_gain: Some(k),
        about: format!(
            "pmsm: order {total:.3} (zeta {zeta:.3}), corners {tau1:.3e} s and {tau2:.3e} s"
        ),
    }
}

fn integer(kind: PlantKind, rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let tau1 = log_uniform(rng, 2e-3, 0.2);
    let (den, fast, about) = match kind {
        PlantKind::Integer1 => (first(tau1), tau1, format!("first order, tau {tau1:.3e} s")),
        PlantKind::Integer2 if rng.gen_bool(0.5) => {
            let damping = rng.gen_range(0.25..=0.8);
            let omega = 1.0 / tau1;
            (
                second(omega, damping),
                tau1,
                format!("second order, underdamped: w_n {omega:.3e} rad/s, damping {damping:.2}"),
            )
        }
        PlantKind::Integer2 => {
            let tau2 = log_uniform(rng, tau1 / 30.0, tau1 / 2.0);
            (
                poly_mul(&first(tau1), &first(tau2)),
                tau2,
                format!("second order, poles at tau {tau1:.3e}, {tau2:.3e} s"),
            )
        }
        _ => {
            let tau2 = log_uniform(rng, tau1 / 20.0, tau1 / 2.0);
            let tau3 = log_uniform(rng, tau2 / 10.0, tau2 / 1.5);
            (
                poly_mul(&poly_mul(&first(tau1), &first(tau2)), &first(tau3)),
                tau3,
                format!("third order, poles at tau {tau1:.3e}, {tau2:.3e}, {tau3:.3e} s"),
            )
        }
    };
    Drawn {
        plant: plant(vec![term(k, 0.0)], den),
        fast_s: fast,
        slow_s: tau1,
        dc_gain: Some(k),
        about,
    }
}

fn compliant(kind: PlantKind, rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let tau_m = log_uniform(rng, 10e-3, 0.2);
    let f_r = log_uniform(rng, 20.0, 150.0);
    let omega_r = std::f64::consts::TAU * f_r;
    let z_r = log_uniform(rng, 0.02, 0.2);
    let rigid = first(tau_m);
    let (num, den, fast, about) = match kind {
        PlantKind::TwoMassMotor => {
            let ratio = rng.gen_range(1.3..=3.0);
            let omega_a = omega_r / ratio;
            let z_a = log_uniform(rng, 0.02, 0.2);
            (
                poly_mul(&[term(k, 0.0)], &second(omega_a, z_a)),
                poly_mul(&rigid, &second(omega_r, z_r)),
                1.0 / omega_r,
                format!(
                    "two-mass at the motor: tau_m {tau_m:.3e} s, anti-resonance {:.1} Hz (damping {z_a:.3}), resonance {f_r:.1} Hz (damping {z_r:.3})",
                    f_r / ratio
                ),
            )
        }
        PlantKind::TwoMassLoad => (
            vec![term(k, 0.0)],
            poly_mul(&rigid, &second(omega_r, z_r)),
            1.0 / omega_r,
            format!(
                "two-mass at the load: tau_m {tau_m:.3e} s, resonance {f_r:.1} Hz (damping {z_r:.3})"
            ),
        ),
        _ => {
            let f_2 = f_r * rng.gen_range(2.0..=4.0);
            let z_2 = log_uniform(rng, 0.02, 0.2);
            let omega_2 = std::f64::consts::TAU * f_2;
            (
                vec![term(k, 0.0)],
                poly_mul(&poly_mul(&rigid, &second(omega_r, z_r)), &second(omega_2, z_2)),
                1.0 / omega_2,
                format!(
                    "two modes at the load: tau_m {tau_m:.3e} s, {f_r:.1} Hz (damping {z_r:.3}), {f_2:.1} Hz (damping {z_2:.3})"
                ),
            )
        }
    };
    Drawn {
        plant: plant(num, den),
        fast_s: fast,
        slow_s: tau_m,
        dc_gain: Some(k),
        about,
    }
}

fn feedthrough(rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let tau = log_uniform(rng, 2e-3, 0.2);
    let d = k * rng.gen_range(0.05..=0.5);
    Drawn {
        plant: plant(vec![term(d * tau, 1.0), term(d + k, 0.0)], first(tau)),
        fast_s: tau,
        slow_s: tau,
        dc_gain: Some(d + k),
        about: format!("feed-through D {d:.3e} + first order K {k:.3e}, tau {tau:.3e} s"),
    }
}

fn integrator(rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let tau = log_uniform(rng, 2e-3, 0.1);
    Drawn {
        plant: plant(vec![term(k, 0.0)], vec![term(tau, 2.0), term(1.0, 1.0)]),
        fast_s: tau,
        slow_s: tau * 5.0,
        dc_gain: None,
        about: format!("integrator (position): K {k:.3e}, tau {tau:.3e} s"),
    }
}

fn diffusion(rng: &mut StdRng) -> Drawn {
    let k = log_uniform(rng, 0.5, 20.0);
    let alpha = rng.gen_range(0.3..=0.7);
    // The corner time t_c: tau = t_c^alpha.
    let t_c = log_uniform(rng, 5.0, 200.0);
    Drawn {
        plant: plant(
            vec![term(k, 0.0)],
            vec![term(t_c.powf(alpha), alpha), term(1.0, 0.0)],
        ),
        fast_s: t_c / 10.0,
        slow_s: t_c,
        dc_gain: Some(k),
        about: format!("diffusion: order {alpha:.3}, corner {t_c:.3e} s"),
    }
}

fn lead(rng: &mut StdRng) -> Drawn {
    let k = gain(rng);
    let tau1 = log_uniform(rng, 5e-3, 0.2);
    let tau2 = log_uniform(rng, tau1 / 30.0, tau1 / 3.0);
    let tz = log_uniform(rng, tau2 * 1.5, tau1 * 2.0);
    Drawn {
        plant: plant(
            vec![term(k * tz, 1.0), term(k, 0.0)],
            poly_mul(&first(tau1), &first(tau2)),
        ),
        fast_s: tau2,
        slow_s: tau1,
        dc_gain: Some(k),
        about: format!("lead: zero at tau {tz:.3e} s, poles at tau {tau1:.3e}, {tau2:.3e} s"),
    }
}

fn cell(rng: &mut StdRng) -> Drawn {
    let r0 = log_uniform(rng, 0.01, 0.1);
    let r1 = r0 * rng.gen_range(0.5..=3.0);
    let alpha = rng.gen_range(0.5..=0.9);
    let t_c = log_uniform(rng, 5.0, 100.0);
    let tau = t_c.powf(alpha);
    // The integrator's ramp over 10 corner times stays about the size of the resistive drop.
    let c = 10.0 * t_c / (r0 + r1) * rng.gen_range(1.0..=5.0);
    // R0 + 1/(C s) + R1/(tau s^a + 1) over the common denominator s (tau s^a + 1).
    let frac_den = vec![term(tau, alpha), term(1.0, 0.0)];
    let den = poly_mul(&frac_den, &[term(1.0, 1.0)]);
    let num = poly_add(
        &poly_add(
            &poly_mul(&[term(r0, 0.0)], &den),
            &poly_mul(&[term(1.0 / c, 0.0)], &frac_den),
        ),
        &[term(r1, 1.0)],
    );
    Drawn {
        plant: plant(num, den),
        fast_s: t_c / 10.0,
        slow_s: t_c,
        dc_gain: None,
        about: format!(
            "cell: R0 {r0:.3e}, C {c:.3e}, R1 {r1:.3e} over order {alpha:.3}, corner {t_c:.3e} s"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn polynomials_multiply_and_merge() {
        // (s + 1)(s + 1) = s^2 + 2 s + 1
        let p = poly_mul(&first(1.0), &first(1.0));
        assert_eq!(p, vec![term(1.0, 2.0), term(2.0, 1.0), term(1.0, 0.0)]);
        // (s^0.5 + 1) + (-1) = s^0.5
        assert_eq!(
            poly_add(&[term(1.0, 0.5), term(1.0, 0.0)], &[term(-1.0, 0.0)]),
            vec![term(1.0, 0.5)]
        );
    }

    #[test]
    fn every_kind_is_proper_and_in_range() {
        let mut rng = StdRng::seed_from_u64(5);
        for kind in crate::cases::ALL_PLANTS {
            for _ in 0..20 {
                let d = draw(kind, &mut rng);
                let top = |p: &[Term]| p.iter().map(|t| t.order).fold(f64::MIN, f64::max);
                assert!(
                    top(&d.plant.num) <= top(&d.plant.den) + 1e-12,
                    "{kind:?} improper"
                );
                assert!(d.fast_s > 0.0 && d.fast_s <= d.slow_s, "{kind:?} {d:?}");
                if kind == PlantKind::Pmsm {
                    let total = top(&d.plant.den);
                    assert!((1.1..=2.0).contains(&total), "{total}");
                }
            }
        }
    }
}
