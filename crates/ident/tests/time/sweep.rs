//! A sine sweep through a lightly damped resonance (issue 47): its last 30% holds frequencies
//! the rest never excites, so the validation holds out short blocks spread over the record
//! (`ValidationKind::HeldOutBlocks`) instead of the tail, and the held-out figure is the noise's.
//!
//! The truth is independent of the identifier's simulator: the exact zero-order-hold
//! discretisation of `K wn^2/(s^2 + 2 zeta wn s + wn^2)` (its transition matrix in closed form).

use super::truth::noise;
use ident::data::Record;
use ident::oe::{identify, FracModel, IdentOptions, InitialState, ValidationKind};

const DT: f64 = 1e-4;
const SIGMA: f64 = 0.05;
/// Gain, natural frequency (rad/s: 300 Hz, swept in the record's last quarter), damping ratio.
const K: f64 = 2.0;
const WN: f64 = 2.0 * std::f64::consts::PI * 300.0;
const ZETA: f64 = 0.05;

/// The resonance's output for the input `u` held over each sample of `dt`, from rest: the
/// state `(y, y')` stepped by `e^(A dt)` (`e^(-s t) (cos(wd t) I + sin(wd t)/wd (A + s I))`,
/// `s = zeta wn`, `wd = wn sqrt(1 - zeta^2)`) and `A^-1 (e^(A dt) - I) B`.
fn resonance(u: &[f64], dt: f64) -> Vec<f64> {
    let (s, wd) = (ZETA * WN, WN * (1.0 - ZETA * ZETA).sqrt());
    let a = [[0.0, 1.0], [-WN * WN, -2.0 * ZETA * WN]];
    let (e, c, sn) = ((-s * dt).exp(), (wd * dt).cos(), (wd * dt).sin() / wd);
    let phi = [
        [e * (c + sn * (a[0][0] + s)), e * sn * a[0][1]],
        [e * sn * a[1][0], e * (c + sn * (a[1][1] + s))],
    ];
    // A^-1 = [[a11, -a01], [-a10, a00]] / det, det = wn^2; B = (0, K wn^2).
    let det = WN * WN;
    let m = [[phi[0][0] - 1.0, phi[0][1]], [phi[1][0], phi[1][1] - 1.0]];
    let mb = [m[0][1] * K * WN * WN, m[1][1] * K * WN * WN];
    let gamma = [
        (a[1][1] * mb[0] - a[0][1] * mb[1]) / det,
        (-a[1][0] * mb[0] + a[0][0] * mb[1]) / det,
    ];
    let mut x = [0.0, 0.0];
    u.iter()
        .map(|&uk| {
            let y = x[0];
            x = [
                phi[0][0] * x[0] + phi[0][1] * x[1] + gamma[0] * uk,
                phi[1][0] * x[0] + phi[1][1] * x[1] + gamma[1] * uk,
            ];
            y
        })
        .collect()
}

/// A linear sweep from 1 to 400 Hz over `n` samples.
fn sweep(n: usize) -> Vec<f64> {
    let t_end = n as f64 * DT;
    (0..n)
        .map(|k| {
            let t = k as f64 * DT;
            (2.0 * std::f64::consts::PI * (t + 399.0 * t * t / (2.0 * t_end))).sin()
        })
        .collect()
}

/// The sweep's resonance (300 Hz, reached at 75% of the record) lies in the tail a plain split
/// would hold out. Held out in blocks instead: ten blocks of 3% each, every block between
/// estimation samples, and the held-out RMSE of the second-order fit within 10% of the noise's
/// standard deviation (measured 1.00x; with the tail held out, before, it was not a block split
/// at all). The truth's gain, damping and natural frequency within 2%.
#[test]
fn a_sweep_is_held_out_in_blocks_spread_over_it() {
    let n = 4000;
    let u = sweep(n);
    let clean = resonance(&u, DT);
    let y: Vec<f64> = clean
        .iter()
        .zip(noise(n, SIGMA, 47))
        .map(|(a, e)| a + e)
        .collect();
    let rec = Record::from_samples(&u, &y, DT).unwrap();
    let m = FracModel::second_order(1.0, 1e-3, 1e-7);
    // (from rest, as the truth starts: an estimated initial state is another question)
    let opts = IdentOptions {
        initial: InitialState::Rest,
        ..IdentOptions::default()
    };
    let id = identify(&rec, &m, &opts).unwrap();
    let v = &id.validated_by;
    assert_eq!(v.kind, ValidationKind::HeldOutBlocks, "{}", v.note);
    assert_eq!(v.blocks.len(), 10, "{:?}", v.blocks);
    let held: usize = v.blocks.iter().map(|(a, b)| b - a).sum();
    assert!((held as f64 - 0.3 * n as f64).abs() <= 10.0, "{held}");
    assert!(v.blocks[0].0 > 0 && v.blocks[9].1 < n, "{:?}", v.blocks);
    assert!(v.blocks.windows(2).all(|w| w[0].1 < w[1].0));
    // no warning that the held-out part lies beyond the fitted band
    assert!(
        !id.report
            .warnings
            .iter()
            .any(|w| w.contains("beyond the band")),
        "{:?}",
        id.report.warnings
    );
    let val = id.validation.unwrap();
    eprintln!("{} held out {val:?} estimation {:?}", id.tf, id.estimation);
    assert!(val.rmse <= 1.1 * SIGMA, "held out {val:?}");
    assert!(
        id.estimation.rmse <= 1.1 * SIGMA,
        "estimation {:?}",
        id.estimation
    );
    // the figures are those of the blocks: recomputed here from the model's output
    let (mut ss, mut count) = (0.0, 0);
    for &(a, b) in &v.blocks {
        for k in a..b {
            ss += (y[k] - id.yhat[k]).powi(2);
            count += 1;
        }
    }
    let rms = (ss / count as f64).sqrt();
    assert!(
        (rms - val.rmse).abs() <= 1e-12 * rms,
        "{rms} vs {}",
        val.rmse
    );
    let p = |name: &str| id.report.values[id.model.index_of(name).unwrap()];
    let (k, a1, a2) = (p("K"), p("a1"), p("a2"));
    let (wn, zeta) = (1.0 / a2.sqrt(), 0.5 * a1 / a2.sqrt());
    for (got, want) in [(k, K), (wn, WN), (zeta, ZETA)] {
        assert!((got - want).abs() <= 0.02 * want, "{got} vs {want}");
    }
}
