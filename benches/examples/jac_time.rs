//! Time of one simulation and one Jacobian of the model `fracid time` fits (the PMSM with an
//! output offset and four initial-state levels: 10 free parameters), best of 5, and the same
//! with every parameter carried as a dual part (the old path, forced by an inert input effect).
//!
//! `cargo run --release -p fracid-benches --example jac_time -- [samples]`

use fracid_benches::{pmsm_data, DT};
use ident::oe::{sensitivities, Effect, FracModel, Param, Structure};
use std::time::Instant;

fn best<F: FnMut()>(mut f: F) -> f64 {
    (0..5)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    let (u, _) = pmsm_data(n, 0.0, 1);
    let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.9, 0.8);
    m.with_output_offset(0.1);
    m.with_past_input(vec![0.01, 0.1, 1.0], (-3.0, 3.0));
    let p = m.values();
    let sim =
        fracsim::Simulator::<f64>::new(&fracid_benches::pmsm(), DT, &Default::default()).unwrap();
    println!(
        "PMSM modes: {} real, {} complex pairs",
        sim.model().real.len(),
        sim.model().complex.len()
    );
    let mut y = vec![0.0; n];
    let t_sim = best(|| m.simulate(&p, &u, DT, &mut y).unwrap());
    let t_jac = best(|| {
        sensitivities(&m, &p, &u, DT, ident::par::Par::available()).unwrap();
    });
    let pd: Vec<fracsim::Dual<2>> = p
        .iter()
        .enumerate()
        .map(|(i, &v)| match i {
            1 => fracsim::Dual::var(v, 0),
            3 => fracsim::Dual::var(v, 1),
            _ => fracsim::Dual::cst(v),
        })
        .collect();
    let mut yd = vec![fracsim::Dual::<2>::cst(0.0); n];
    let t_d2 = best(|| m.simulate(&pd, &u, DT, &mut yd).unwrap());
    println!("one simulation with 2 dual parts: {:.2} ms", t_d2 * 1e3);
    // An input offset fixed at 0 changes nothing but makes every parameter nonlinear.
    let mut all = m.clone();
    let c = all.add_param(Param::new("u_offset", 0.0, ident::oe::Bounds::Free).fixed());
    all.effects.insert(0, Effect::InputOffset { c });
    let pa = all.values();
    let t_all = best(|| {
        sensitivities(&all, &pa, &u, DT, ident::par::Par::available()).unwrap();
    });
    println!(
        "{n} samples, {} free parameters: simulation {:.2} ms, Jacobian {:.2} ms, Jacobian with every parameter dual {:.2} ms",
        p.len(),
        t_sim * 1e3,
        t_jac * 1e3,
        t_all * 1e3
    );
}
