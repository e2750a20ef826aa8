//! Benchmark crate of fracid: the `[[bench]]` targets (`sim`, `oe`, `levy`, `codec`), the
//! examples (`oe_scaling`, `fit_csv`, `gen_data`) and the side-by-side comparison with a
//! numpy/scipy reference in `compare/`.
//!
//! This library holds the shared fixtures: the paper's PMSM model, the PRBS input, seeded noise.

use fracsim::{lsim, ApproxSpec, FracTf};

/// The paper's time-domain PMSM model (docs/design.md §2).
pub const PMSM: &str = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)";

/// The true PMSM parameters `[K, a1, a2, zeta, theta]` of [`PMSM`] (`zeta + theta = 1.7452`).
pub const PMSM_PARAMS: [f64; 5] = [6.82, 0.0059, 2.655e-5, 0.92, 0.8252];

/// The sampling step of the benches (seconds): 30 samples per 3 ms PRBS bit.
pub const DT: f64 = 1e-4;

/// The PMSM model as a [`FracTf`].
pub fn pmsm() -> FracTf {
    PMSM.parse().expect("the PMSM model parses")
}

/// `n` samples of the paper's PRBS (order 7, 3 ms clock, unit amplitude), repeated as needed.
pub fn prbs_input(n: usize, dt: f64) -> Vec<f64> {
    let mut p = fracsim::prbs::Prbs::paper();
    let period = p.signal(dt).expect("PRBS").len();
    p.periods = n.div_ceil(period).max(1);
    let mut u = p.signal(dt).expect("PRBS");
    u.truncate(n);
    u
}

/// `n` samples of seeded Gaussian noise with standard deviation `sigma` (xorshift64* and
/// Box-Muller: reproducible without a dependency).
pub fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        ((s.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (a, b) = (uniform(), uniform());
            sigma * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        })
        .collect()
}

/// PRBS input and the PMSM output (default approximation) plus seeded noise of standard
/// deviation `sigma`: `(u, y)`, `n` samples at step [`DT`].
pub fn pmsm_data(n: usize, sigma: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u = prbs_input(n, DT);
    let mut y = lsim(&pmsm(), &u, DT, &ApproxSpec::default()).expect("simulation");
    for (y, e) in y.iter_mut().zip(noise(n, sigma, seed)) {
        *y += e;
    }
    (u, y)
}

/// A start for the PMSM fit away from the truth (every parameter off by 10-40%).
pub fn pmsm_start() -> ident::oe::FracModel {
    ident::oe::FracModel::pmsm(5.0, 0.008, 2.0e-5, 0.8, 0.7)
}

/// Every time-domain record in `data/` (`python/tests/test_real_records.py`'s; paths under it,
/// columns `t,u,y`): the six of [`REAL_RECORDS`] first, then a low-speed PRBS, a closed speed
/// profile, TCLab's PWM steps, the CD-player arm, two battery records and an HPPC block.
pub const TIME_RECORDS: [&str; 13] = [
    "unal_dcmotor/DCmotor_prbs_open_exp.csv",
    "unal_dcmotor/DCmotor_step_open_exp.csv",
    "unal_dcmotor/DCmotor_stairs_closed_exp.csv",
    "apm_tclab/tclab_step_test.csv",
    "sysidentpy_motor_generator/motor_generator_steps.csv",
    "slicot_robot_arm/robot_arm.csv",
    "unal_undcmotor/DCmotor_prbs_open_low.csv",
    "unal_undcmotor/DCmotor_profile_closed_exp.csv",
    "apm_tclab/tclab_pwm_steps.csv",
    "slicot_cd_player_arm/cd_player_arm.csv",
    "dmegc_battery/random_current_cycle26.csv",
    "dmegc_battery/pulse_discharge.csv",
    "ornl_nissan_leaf_cell/hppc_25c_pulse4.csv",
];

/// The six real time records the performance tables were first measured on (the first six of
/// [`TIME_RECORDS`]).
pub const REAL_RECORDS: &[&str] = TIME_RECORDS.split_at(6).0;

/// The path of a file under the repository's `data/`.
pub fn data_path(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(rel)
}

/// A real record of [`REAL_RECORDS`], read as `fracid time` reads it (default options).
///
/// # Panics
/// When the file cannot be read (the benches run in the repository).
pub fn real_record(rel: &str) -> ident::data::Record {
    ident::data::Record::load(&data_path(rel), &ident::data::ReadOptions::default())
        .expect("a record of data/")
        .record
}

/// Least-squares slope of `log y` against `log x` (the scaling exponent).
pub fn loglog_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let mx = lx.iter().sum::<f64>() / n;
    let my = ly.iter().sum::<f64>() / n;
    let sxy: f64 = lx.iter().zip(&ly).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = lx.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixtures_are_consistent() {
        let (u, y) = pmsm_data(5000, 0.0, 1);
        assert_eq!(u.len(), 5000);
        assert!(y.iter().all(|v| v.is_finite()));
        let e = noise(20000, 2.0, 7);
        let m = e.iter().sum::<f64>() / e.len() as f64;
        let sd = (e.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / e.len() as f64).sqrt();
        assert!(m.abs() < 0.1 && (sd - 2.0).abs() < 0.1, "{m} {sd}");
        assert!((loglog_slope(&[1.0, 10.0, 100.0], &[2.0, 20.0, 200.0]) - 1.0).abs() < 1e-12);
        assert!((PMSM_PARAMS[3] + PMSM_PARAMS[4] - 1.7452).abs() < 1e-12);
    }
}
