//! A smooth monotone input map, the power law `u -> sign(u) u_ref (|u| / u_ref)^p` (a heater whose
//! power rises with the square of its command, `p = 2`; an actuator that flattens at large
//! commands, `p < 1`), `u_ref` the record's largest input magnitude, so that the model's gain
//! keeps its meaning there.
//!
//! Signature: `G (map_p(u) - u)` over a grid of exponents ([`super::probe_static_map`]). With a
//! two-level input any static input map is affine (a gain and an offset): ambiguous, never fitted.

use super::{named, probe_static_map, Findings, Look, Probe, StaticMap};
use crate::oe::{Bounds, Effect, FracModel};
use crate::Result;
use std::collections::BTreeMap;

pub(crate) struct PowerLaw;

/// Exponents the refit may reach: a map flatter than `u^(1/4)` or steeper than `u^4` is not a
/// smooth actuator curve but a switch, which the dead band and saturation describe better.
pub(crate) const EXPONENT_RANGE: (f64, f64) = (0.25, 4.0);

/// The map at exponent `p` (0 at 0).
pub(crate) fn power_map(v: f64, p: f64, u_ref: f64) -> f64 {
    if v == 0.0 || u_ref <= 0.0 {
        return 0.0;
    }
    v.signum() * u_ref * (v.abs() / u_ref).powf(p)
}

impl Probe for PowerLaw {
    fn name(&self) -> &'static str {
        "power_law"
    }

    fn probe(&self, look: &Look<'_>, found: &mut Findings) -> Result<()> {
        let spec = StaticMap {
            name: "power_law",
            param: "map_p",
            what: "exponent",
            grid: vec![0.4, 0.5, 0.6, 0.7, 0.8, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0],
            scaled: false,
            bounds: Bounds::Interval(EXPONENT_RANGE.0, EXPONENT_RANGE.1),
            map: power_map,
            effect: |p, u_ref| Effect::PowerLaw { p, u_ref },
        };
        probe_static_map(look, found, &spec);
        Ok(())
    }

    fn params(&self, model: &FracModel, values: &[f64]) -> BTreeMap<String, f64> {
        let mut out = named(model, values, &[("exponent", "map_p")]);
        if let Some(u_ref) = model.effects.iter().find_map(|e| match e {
            Effect::PowerLaw { u_ref, .. } => Some(*u_ref),
            _ => None,
        }) {
            out.insert("u_ref".into(), u_ref);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Param;
    use fracsim::Dual;

    #[test]
    fn the_map_is_odd_fixes_u_ref_and_is_the_identity_at_p_1() {
        for v in [-3.0, -0.5, 0.0, 0.25, 2.0, 4.0] {
            assert!((power_map(v, 1.0, 4.0) - v).abs() < 1e-15);
            assert!((power_map(-v, 2.0, 4.0) + power_map(v, 2.0, 4.0)).abs() < 1e-15);
        }
        assert!((power_map(4.0, 2.7, 4.0) - 4.0).abs() < 1e-12);
        assert!((power_map(2.0, 2.0, 4.0) - 1.0).abs() < 1e-15); // 4 (1/2)^2
    }

    #[test]
    fn the_effect_gives_the_map_and_its_exact_derivatives() {
        // The effect through dual numbers against the map and central differences in p and u.
        let mut m = crate::app::structure("pmsm", 0.01).unwrap().0;
        let i = m.add_param(Param::new("map_p", 1.7, Bounds::Interval(0.25, 4.0)));
        let e = Effect::PowerLaw { p: i, u_ref: 3.0 };
        let n = m.params.len();
        let at = |p: f64, u: f64| {
            let mut v: Vec<Dual<2>> = m.params.iter().map(|q| Dual::from(q.value)).collect();
            v[i] = Dual::var(p, 0);
            e.input(&v, Dual::var(u, 1), Dual::from(0.0), 0.0)
        };
        assert!(n > i);
        for u in [-2.5, -0.3, 0.7, 3.0, 5.0] {
            let d = at(1.7, u);
            assert!((d.v - power_map(u, 1.7, 3.0)).abs() < 1e-14);
            let h = 1e-6;
            let dp = (power_map(u, 1.7 + h, 3.0) - power_map(u, 1.7 - h, 3.0)) / (2.0 * h);
            let du = (power_map(u + h, 1.7, 3.0) - power_map(u - h, 1.7, 3.0)) / (2.0 * h);
            assert!(
                (d.d[0] - dp).abs() < 1e-7 * (1.0 + dp.abs()),
                "{u}: {} {dp}",
                d.d[0]
            );
            assert!(
                (d.d[1] - du).abs() < 1e-7 * (1.0 + du.abs()),
                "{u}: {} {du}",
                d.d[1]
            );
        }
        assert_eq!(at(1.7, 0.0).v, 0.0);
    }
}
