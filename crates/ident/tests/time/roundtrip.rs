//! Round trip against an independent truth: data from the Grunwald-Letnikov reference simulator
//! (fracsim::gl, implicit, at a step ten times finer, then decimated) of the paper's time-domain
//! model, PRBS input, 1% noise; fitted by output error with the Oustaloup-approximated simulator.
//!
//! Measured (0.2 ms, seed 7, fracsim's default band): from the poor start and from the automatic
//! (Levy) start alike K -0.01%, a1 -0.6%, a2 -0.2%, zeta +0.002, theta -0.002, validation fit
//! 98.98% (7 iterations from the Levy start, 20 from the poor one). The Levy start alone:
//! K +0.1%, zeta 0.916, theta 0.821, a1 +1.9%, a2 +6.5%, its simulated output fits 98.98%.

use fracsim::prbs::Prbs;
use fracsim::FracTf;
use ident::data::{OffsetMode, Record};
use ident::oe::init::auto_start;
use ident::oe::{identify, FracModel, IdentOptions, StartMethod, StartMode};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Decimation factor of the GL truth.
const FINE: usize = 10;

/// The paper's time-domain model `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`.
const TRUTH: (f64, f64, f64, f64, f64) = (6.82, 0.0059, 2.655e-5, 0.92, 1.7452 - 0.92);

/// PRBS order 7, 3 ms clock, 4 periods, sampled at `dt`; GL truth at `dt/10`; 1% noise (of the
/// output's standard deviation), seeded.
pub fn paper_record(dt: f64, periods: usize, seed: u64) -> Record {
    let (k, a1, a2, z, th) = TRUTH;
    let g = FracTf::pmsm(k, a1, a2, z, th).unwrap();
    let fine = dt / FINE as f64;
    let prbs = Prbs {
        periods,
        ..Prbs::paper()
    };
    let uf = prbs.signal(fine).unwrap();
    // The implicit GL scheme lets the input sample j act on ((j-1) h, j h]; the identifier (like a
    // drive's PWM) takes sample k as held over [k dt, (k+1) dt). Delaying the GL input by one fine
    // step makes the two agree; without it the truth leads by h, which moved a2 by 20% (see
    // `ident::oe::identify`).
    let mut ug = uf.clone();
    ug.insert(0, 0.0);
    ug.pop();
    let yf = fracsim::gl::simulate(&g, &ug, fine).unwrap();
    let u: Vec<f64> = uf.iter().step_by(FINE).copied().collect();
    let mut y: Vec<f64> = yf.iter().step_by(FINE).copied().collect();
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let sd = (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64).sqrt();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.01 * sd).unwrap();
    for v in &mut y {
        *v += noise.sample(&mut rng);
    }
    Record::from_samples(&u, &y, dt).unwrap()
}

/// The record both tests use (generated once): 0.2 ms sampling, GL at 20 us, 4 PRBS periods.
/// 0.2 ms puts the model's corners (265 and 700 rad/s) below a tenth of the sampling frequency, and
/// GL's first-order error at 20 us (about `nu w h / 2` = 1.2% phase at 700 rad/s) below the
/// tolerances; at 0.5 ms with GL at 50 us the truth itself moves `a2` by 30%.
fn record() -> &'static Record {
    static REC: std::sync::OnceLock<Record> = std::sync::OnceLock::new();
    REC.get_or_init(|| paper_record(2e-4, 4, 7))
}

fn check(id: &ident::oe::Identification, label: &str) {
    let v = &id.report.values;
    let (k, a1, a2, z, th) = TRUTH;
    let val = id.validation.unwrap();
    eprintln!(
        "{label}: K {:.4} a1 {:.5} a2 {:.4e} zeta {:.4} theta {:.4} | est {:.2}% val {:.2}% | iters {} {:?} {:?}",
        v[0], v[1], v[2], v[3], v[4], id.estimation.nrmse_percent, val.nrmse_percent,
        id.report.iterations, id.report.termination, id.report.elapsed
    );
    // Tolerances of the issue: K 2%, orders 0.03, a1 and a2 10%, validation fit >= 95%.
    assert!((v[0] / k - 1.0).abs() < 0.02, "{label}: K = {}", v[0]);
    assert!((v[1] / a1 - 1.0).abs() < 0.10, "{label}: a1 = {}", v[1]);
    assert!((v[2] / a2 - 1.0).abs() < 0.10, "{label}: a2 = {}", v[2]);
    assert!((v[3] - z).abs() < 0.03, "{label}: zeta = {}", v[3]);
    assert!((v[4] - th).abs() < 0.03, "{label}: theta = {}", v[4]);
    assert!(
        val.nrmse_percent >= 95.0,
        "{label}: validation {}",
        val.nrmse_percent
    );
}

#[test]
fn paper_model_from_a_poor_start() {
    let rec = record();
    let opts = IdentOptions {
        start: StartMode::Given,
        offsets: OffsetMode::None,
        fit_offset: false,
        ..Default::default()
    };
    // Poor start: K half, a1 3x, a2 4x, orders 0.7 and 0.6.
    let start = FracModel::pmsm(3.4, 0.018, 1e-4, 0.7, 0.6);
    let id = identify(rec, &start, &opts).unwrap();
    check(&id, "poor start");
}

#[test]
fn paper_model_from_the_automatic_start() {
    let rec = record();
    let opts = IdentOptions {
        offsets: OffsetMode::None,
        fit_offset: false,
        ..Default::default()
    };
    let id = identify(rec, &FracModel::pmsm(1.0, 1.0, 1.0, 1.0, 1.0), &opts).unwrap();
    eprintln!("start {:?} {:?}", id.start, id.start_report);
    assert_eq!(id.start_report.method, StartMethod::Levy);
    check(&id, "auto start");
}

/// The Levy start alone, on the estimation part (2 whole periods: 1 averaged after the transient)
/// and on the whole record (3 averaged, so the noise is measured across periods).
#[test]
fn levy_start_lands_close() {
    let rec = record();
    let (k, _, _, z, th) = TRUTH;
    for (label, n) in [
        ("estimation part", rec.split_index(0.3).unwrap()),
        ("whole record", rec.len()),
    ] {
        let mut m = FracModel::pmsm(1.0, 1.0, 1.0, 1.0, 1.0);
        let r = auto_start(
            &mut m,
            &rec.u[..n],
            &rec.y[..n],
            rec.dt,
            ident::par::Par::available(),
        )
        .unwrap();
        let v = m.values();
        eprintln!("{label}: {v:?} {r:?}");
        assert_eq!(r.method, StartMethod::Levy, "{label}: {r:?}");
        // A start, not a fit: K within 5%, orders within 0.1 (the OE fit then meets the issue's
        // tolerances). Measured: see the note in the module documentation.
        assert!((v[0] / k - 1.0).abs() < 0.05, "{label}: K = {}", v[0]);
        assert!((v[3] - z).abs() < 0.1, "{label}: zeta = {}", v[3]);
        assert!((v[4] - th).abs() < 0.1, "{label}: theta = {}", v[4]);
    }
}
