//! Scale invariance of the time-domain identification (issue 12): the same record in other units
//! (input and output scaled by 1e-20, 1e-170 or 1e+20) gives the same orders and a gain scaled as
//! the data are. Without the internal scaling, 1e-170 data underflow in the squared residuals.

use fracsim::prbs::Prbs;
use fracsim::{lsim, ApproxSpec, FracTf};
use ident::data::Record;
use ident::oe::{identify, FracModel, IdentOptions};

const DT: f64 = 5e-4;

fn record() -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = Prbs {
        periods: 2,
        amplitude: 3.0,
        ..Prbs::paper()
    }
    .signal(DT)
    .unwrap();
    let g: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"
        .parse()
        .unwrap();
    let mut y = lsim(&g, &u, DT, &ApproxSpec::default()).unwrap();
    // Seeded, deterministic "noise" (a fixed pseudo-random sequence, sigma about 0.1).
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    for v in &mut y {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *v += 0.1 * 3f64.sqrt() * (2.0 * ((s >> 11) as f64 / (1u64 << 53) as f64) - 1.0);
    }
    (u, y)
}

#[test]
fn scaled_data_give_the_same_orders_and_a_scaled_gain() {
    let (u, y) = record();
    let start = FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9);
    let fit = |su: f64, sy: f64| {
        let us: Vec<f64> = u.iter().map(|v| v * su).collect();
        let ys: Vec<f64> = y.iter().map(|v| v * sy).collect();
        let rec = Record::from_samples(&us, &ys, DT).unwrap();
        identify(&rec, &start, &IdentOptions::default()).unwrap()
    };
    let base = fit(1.0, 1.0);
    let k0 = base.report.values[0];
    assert!((k0 - 6.82).abs() < 0.1, "base gain {k0}");
    for (su, sy) in [(1.0, 1e-20), (1e-170, 1e-170), (1e20, 1.0), (1e-20, 1e20)] {
        let id = fit(su, sy);
        let v = &id.report.values;
        // The same fit in other units: the optimiser sees data differing only by rounding, so the
        // estimates agree to far better than their standard errors (about 1e-2 relative).
        let k_want = k0 * sy / su;
        assert!(
            ((v[0] - k_want) / k_want).abs() < 1e-6,
            "su {su:e} sy {sy:e}: K {} vs {k_want}",
            v[0]
        );
        for j in 1..5 {
            let b = base.report.values[j];
            assert!(
                ((v[j] - b) / b).abs() < 1e-6,
                "su {su:e} sy {sy:e}: {} = {} vs {b}",
                id.model.params[j].name,
                v[j]
            );
        }
        let rmse_ratio = id.estimation.rmse / (base.estimation.rmse * sy);
        assert!((rmse_ratio - 1.0).abs() < 1e-6, "rmse ratio {rmse_ratio}");
        assert!(id.yhat.iter().all(|v| v.is_finite()));
        let se = id.report.params[3].std_error.unwrap();
        let se0 = base.report.params[3].std_error.unwrap();
        assert!(
            ((se - se0) / se0).abs() < 1e-4,
            "zeta standard error {se} vs {se0}"
        );
    }
}

/// Issue 31, item 9: the parameters the fit adds (the output offset, the initial state's levels
/// `u_past*`) were left at the scaled record's values (with y x 1e10, `y_offset` -0.16 where the
/// truth is about -5.6e9). Every parameter of a fit of the record in other units (y x 1e10,
/// u x 1e-12, and both x 1e-12) must be the unscaled fit's in those units: `y_offset` times the
/// output's factor, `u_past*` times the input's, `K` times their ratio, the rest equal. The
/// optimiser sees data differing only by rounding (powers of two), so the tolerance is 1e-6 of
/// the value plus its standard error (a level near 0 has no relative precision of its own).
#[test]
fn every_parameter_is_scaled_back_offsets_and_initial_state_included() {
    let (u, y) = record();
    // an output offset the fit has to find: y + 2 on the estimation part's mean removed
    let y: Vec<f64> = y.iter().map(|v| v + 2.0).collect();
    let start = FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9);
    let fit = |su: f64, sy: f64| {
        let us: Vec<f64> = u.iter().map(|v| v * su).collect();
        let ys: Vec<f64> = y.iter().map(|v| v * sy).collect();
        let rec = Record::from_samples(&us, &ys, DT).unwrap();
        identify(&rec, &start, &IdentOptions::default()).unwrap()
    };
    let base = fit(1.0, 1.0);
    let names: Vec<&str> = base.model.params.iter().map(|p| p.name.as_str()).collect();
    assert!(names.contains(&"y_offset"), "{names:?}");
    assert!(names.iter().any(|n| n.starts_with("u_past")), "{names:?}");
    let yo = base.report.values[names.iter().position(|n| *n == "y_offset").unwrap()];
    assert!(yo.abs() > 1e-3, "a real offset to scale: {yo}");
    for (su, sy) in [(1.0, 1e10), (1e-12, 1.0), (1e-12, 1e-12)] {
        let id = fit(su, sy);
        assert_eq!(id.model.params.len(), names.len());
        for (j, name) in names.iter().enumerate() {
            let f = match *name {
                "K" => sy / su,
                "y_offset" => sy,
                n if n.starts_with("u_past") => su,
                _ => 1.0,
            };
            let (b, v) = (base.report.values[j], id.report.values[j]);
            let se = base.report.params[j].std_error.unwrap_or(0.0);
            assert!(
                (v / f - b).abs() <= 1e-6 * (b.abs() + se),
                "su {su:e} sy {sy:e}: {name} = {v:e}, want {:e}",
                b * f
            );
            assert_eq!(
                id.model.params[j].value, v,
                "{name}: model and report agree"
            );
        }
        assert!(((id.offsets.y0 / sy - base.offsets.y0) / base.offsets.y0).abs() < 1e-9);
    }
}

/// Issue 29 leftover: a record's time unit does not change the fit. The paper's PMSM
/// `K/(a2 s^(zeta+theta) + a1 s^zeta + 1)` (its time-domain model) on its PRBS (order 7, 3 ms clock,
/// four periods at `dt` = 0.5 ms), truth by Grunwald-Letnikov with the input held (10 and 20
/// substeps, Richardson; no rational approximation), seeded Gaussian noise of 0.13 (the paper's
/// PMSM tests' noise). The record is written with its time in seconds, in milliseconds and in
/// samples, and fitted with the defaults (the PMSM structure, its automatic start, the default
/// approximation band): the held-out NRMSE is the same within 0.001 percentage points, `K` and the
/// orders are the same and the coefficients transform as `a1' = a1 c^zeta`,
/// `a2' = a2 c^(zeta+theta)` within 0.01 of their standard errors. The simulated outputs of the
/// scaled models agree to rounding (`fracsim`'s test of the time unit); what is left is the
/// optimiser: its log-coefficients move with the orders by `zeta ln c`, so its path differs and it
/// stops at the same optimum within its stopping rule (relative cost change, small steps), far
/// inside the noise's standard errors. Before the band and Xue's correction followed the step,
/// the record in samples fitted another model (time in source samples of the motor/generator
/// record: held-out NRMSE -15.9% against 39.8% with its time in seconds).
#[test]
fn the_time_unit_of_a_record_does_not_change_the_fit() {
    let dt = 5e-4;
    let u = Prbs {
        periods: 4,
        ..Prbs::paper()
    }
    .signal(dt)
    .unwrap();
    let g: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"
        .parse()
        .unwrap();
    let y10 = fracsim::gl::simulate_held(&g, &u, dt, 10).unwrap();
    let y20 = fracsim::gl::simulate_held(&g, &u, dt, 20).unwrap();
    let noise = super::truth::noise(u.len(), 0.13, 29);
    let y: Vec<f64> = y10
        .iter()
        .zip(&y20)
        .zip(&noise)
        .map(|((a, b), e)| (4.0 * b - a) / 3.0 + e)
        .collect();
    let (model, _) = ident::app::structure("pmsm", 0.2).unwrap();
    let fit = |c: f64| {
        let rec = Record::from_samples(&u, &y, dt * c).unwrap();
        identify(&rec, &model, &IdentOptions::default()).unwrap()
    };
    let base = fit(1.0);
    let at = |id: &ident::oe::Identification, name: &str| {
        let i = id.model.index_of(name).unwrap();
        (id.report.values[i], id.report.params[i].std_error.unwrap())
    };
    let (zeta, theta) = (at(&base, "zeta").0, at(&base, "theta").0);
    let nrmse0 = base.validation.unwrap().nrmse_percent;
    eprintln!("s: {} (held-out {nrmse0:.4}%)", base.tf);
    assert!(nrmse0 > 90.0, "the base fit itself: {nrmse0}");
    for c in [1e3, 1.0 / dt] {
        let id = fit(c);
        let nrmse = id.validation.unwrap().nrmse_percent;
        eprintln!("c = {c}: {} (held-out {nrmse:.4}%)", id.tf);
        assert!(
            (nrmse - nrmse0).abs() < 1e-3,
            "c = {c}: {nrmse} vs {nrmse0}"
        );
        for (name, factor) in [
            ("K", 1.0),
            ("zeta", 1.0),
            ("theta", 1.0),
            ("a1", c.powf(zeta)),
            ("a2", c.powf(zeta + theta)),
        ] {
            let ((b, se), (v, _)) = (at(&base, name), at(&id, name));
            assert!(
                (v / factor - b).abs() < 0.01 * se,
                "c = {c}: {name} = {v:e} / {factor:e} vs {b:e} +- {se:e}"
            );
        }
    }
}
