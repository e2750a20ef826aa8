//! Simulation throughput of the PMSM model `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`
//! (default `ApproxSpec`: refined Oustaloup, N = 8, the whole model discretised exactly for the held
//! input and run in modal form), against the number of samples and against the approximation order
//! N; the cost of building the modal form (poles, residues, discretisation), which every
//! output-error evaluation pays once; Grunwald-Letnikov for reference.
//!
//! `cargo bench -p fracid-benches --bench sim`

use divan::counter::ItemsCount;
use divan::{black_box, Bencher};
use fracid_benches::{pmsm, prbs_input, DT};
use fracsim::{lsim, ApproxSpec, Dual, Simulator};

fn main() {
    divan::main();
}

/// `lsim` of the PMSM model, default approximation, `n` samples (items = samples).
#[divan::bench(args = [1_000, 10_000, 100_000, 1_000_000], sample_count = 10, sample_size = 1)]
fn samples(b: Bencher<'_, '_>, n: usize) {
    let (g, u) = (pmsm(), prbs_input(n, DT));
    b.counter(ItemsCount::new(n))
        .bench(|| lsim(black_box(&g), black_box(&u), DT, &ApproxSpec::default()).unwrap());
}

/// `lsim` of the PMSM model, 100k samples, Oustaloup order `N` (2N+1 cells per operator).
#[divan::bench(args = [2, 4, 6, 8, 10], sample_count = 10, sample_size = 1)]
fn order(b: Bencher<'_, '_>, n: usize) {
    let (g, u) = (pmsm(), prbs_input(100_000, DT));
    let spec = ApproxSpec {
        order: n,
        ..ApproxSpec::default()
    };
    b.counter(ItemsCount::new(u.len()))
        .bench(|| lsim(black_box(&g), black_box(&u), DT, &spec).unwrap());
}

/// The simulation with 5 dual parts (output and its 5 sensitivities, what one OE-LM Jacobian
/// costs), 100k samples.
#[divan::bench(sample_count = 10, sample_size = 1)]
fn dual5(b: Bencher<'_, '_>) {
    let (g, u) = (pmsm(), prbs_input(100_000, DT));
    let spec = ApproxSpec::default();
    b.counter(ItemsCount::new(u.len())).bench(|| {
        let mut sim = Simulator::<Dual<5>>::new(&g, DT, &spec).unwrap();
        black_box(sim.simulate(black_box(&u)))
    });
}

/// Building the simulator: the approximated model's poles and residues and their exact
/// discretisation, in `f64` and with 5 dual parts (one output-error Jacobian's worth).
#[divan::bench(sample_count = 20, sample_size = 1)]
fn build(b: Bencher<'_, '_>) {
    let g = pmsm();
    b.bench(|| Simulator::<f64>::new(black_box(&g), DT, &ApproxSpec::default()).unwrap());
}

/// As [`build`], with 5 dual parts.
#[divan::bench(sample_count = 20, sample_size = 1)]
fn build_dual5(b: Bencher<'_, '_>) {
    let g = pmsm();
    b.bench(|| Simulator::<Dual<5>>::new(black_box(&g), DT, &ApproxSpec::default()).unwrap());
}

/// Grunwald-Letnikov (the O(n^2) reference), 10k samples.
#[divan::bench(sample_count = 3, sample_size = 1)]
fn grunwald_letnikov(b: Bencher<'_, '_>) {
    let (g, u) = (pmsm(), prbs_input(10_000, DT));
    b.counter(ItemsCount::new(u.len()))
        .bench(|| fracsim::gl::simulate(black_box(&g), black_box(&u), DT).unwrap());
}
