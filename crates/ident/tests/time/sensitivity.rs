//! Exact sensitivities (dual numbers through the discrete simulation) against central finite
//! differences.

use ident::oe::{sensitivities, Effect, FracModel, Param, Structure};

#[test]
fn dual_sensitivities_match_central_differences() {
    let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.9, 0.8);
    m.with_delay(3.3e-4, 0.01);
    let c = m.add_param(Param::new("c", 0.2, ident::oe::Bounds::Free));
    m.effects.push(Effect::OutputOffset { c });
    let p = m.values();
    let dt = 1e-3;
    let u: Vec<f64> = (0..300)
        .map(|k| if (k / 7) % 3 == 0 { 1.0 } else { -0.5 })
        .collect();
    let (y, s) = sensitivities(&m, &p, &u, dt).unwrap();
    assert_eq!(s.ncols(), 7);
    for j in 0..p.len() {
        // Step 1e-6 relative: central differences then carry ~1e-12 truncation and ~1e-10
        // rounding error relative to the output scale (about 7).
        let h = 1e-6 * p[j].abs().max(1e-3);
        let (mut pp, mut pm) = (p.clone(), p.clone());
        pp[j] += h;
        pm[j] -= h;
        let (mut yp, mut ym) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        m.simulate(&pp, &u, dt, &mut yp).unwrap();
        m.simulate(&pm, &u, dt, &mut ym).unwrap();
        let scale = (0..u.len())
            .map(|k| s[(k, j)].abs())
            .fold(0.0, f64::max)
            .max(1e-12);
        for k in 0..u.len() {
            let fd = (yp[k] - ym[k]) / (2.0 * h);
            assert!(
                (fd - s[(k, j)]).abs() < 1e-5 * scale,
                "param {} sample {k}: dual {} fd {fd}",
                m.params[j].name,
                s[(k, j)]
            );
        }
        assert!(y.iter().all(|v| v.is_finite()));
    }
}
