//! The simulated drive runs the models the identification returns, over the protocol: a
//! two-mass resonance measured at the load, written as people write it (a product of factors),
//! with a hidden delay, stepped through a PRBS run's settling phase (the offset held from sample
//! 0: a step), against its exact response written here.

use super::e2e::{lock, vclient, vspawn};
use drive::client::{NullSink, PrbsTest};
use drive::sim::{Effects, SimConfig};
use num_complex::Complex64 as C;

const BAUD: u32 = 921_600;

/// `K/((T s + 1)(s^2/wr^2 + 2 z s/wr + 1))`: the exact step response by residues,
/// `y(t) = K + r1 e^(p1 t) + 2 Re(r2 e^(p2 t))`, `p1 = -1/T`, `p2 = -z wr + i wr sqrt(1 - z^2)`.
fn two_mass_step(k: f64, t_s: f64, wr: f64, z: f64, t: f64) -> f64 {
    if t < 0.0 {
        return 0.0;
    }
    let p1 = -1.0 / t_s;
    let p2 = C::new(-z * wr, wr * (1.0 - z * z).sqrt());
    let quad = |s: f64| s * s + 2.0 * z * wr * s + wr * wr;
    let r1 = k * wr * wr / (t_s * p1 * quad(p1));
    let r2 = k * wr * wr / ((p2 * t_s + 1.0) * p2 * (p2 - p2.conj()));
    k + r1 * (p1 * t).exp() + 2.0 * (r2 * (p2 * t).exp()).re
}

on_both_firmwares! {
/// 45 Hz, damping 0.05, a 4 ms motor lag, K = 2.5 rad/s/V, a 3 ms hidden delay; a 2 V step for
/// 0.4 s at 1 kHz. Every speed sample within half the channel's LSB (5 mrad/s) of the exact
/// response delayed by 3 samples.
fn a_load_side_resonance_steps_through_the_drive_as_its_exact_response(fw) {
    let _g = lock();
    let (k, t_s, wr, z) = (2.5, 0.004, std::f64::consts::TAU * 45.0, 0.05);
    let text = format!(
        "{k}/(({t_s} s + 1)({:e} s^2 + {:e} s + 1))",
        1.0 / (wr * wr),
        2.0 * z / wr
    );
    let s = vspawn(SimConfig {
        firmware: fw,
        baud: BAUD,
        model: text.parse().expect("the product parses"),
        effects: Effects {
            delay_s: 0.003,
            ..Effects::default()
        },
        ..SimConfig::default()
    });
    let mut c = vclient(&s, BAUD);
    let test = PrbsTest {
        order: 3,
        seed: 1,
        clock_s: 0.001,
        amplitude_v: 0.5,
        offset_v: 2.0,
        periods: 1,
        settle_s: 0.4,
    };
    let acq = c.run_prbs(&test, &mut NullSink).expect("the run");
    assert!(acq.complete, "{:?}", acq.problems);
    let y_lsb = drive::protocol::Configure::default().y_lsb();
    let mut worst = 0.0f64;
    for n in 0..400 {
        assert_eq!(acq.u[n], 2.0, "the step's command at sample {n}");
        let truth = 2.0 * two_mass_step(k, t_s, wr, z, (n as f64 - 3.0) * 1e-3);
        worst = worst.max((acq.y[n] - truth).abs());
    }
    eprintln!("{fw:?}: worst speed error {worst:.2e} rad/s (LSB {y_lsb})");
    assert!(worst <= 0.5 * y_lsb + 1e-9, "worst {worst}");
    let peak = acq.y[..400].iter().fold(0.0f64, |m, &v| m.max(v));
    assert!(peak > 1.3 * 2.0 * k, "the resonance rings: peak {peak}");
}
}
