//! `autotune::tuner::run` end to end on the drive simulator in virtual time, with hidden effects
//! the autotune is not told of (settings used by no other test).

use autotune::tuner::{self, AutotuneRequest, Quiet};
use drive::client::{Client, ClientConfig};
use drive::sim::{DriveSim, Effects, SimClock, SimConfig};
use std::time::Instant;

fn sim(model: &str, effects: Effects, seed: u64) -> DriveSim {
    let cfg = SimConfig {
        model: model.parse().unwrap(),
        effects,
        clock: SimClock::Virtual,
        faults: drive::sim::Faults {
            seed,
            ..Default::default()
        },
        ..SimConfig::default()
    };
    DriveSim::spawn(cfg).unwrap()
}

fn client(s: &DriveSim) -> Client {
    Client::open(
        s.port_path(),
        ClientConfig {
            clock: s.virtual_clock(),
            keepalive: std::time::Duration::from_millis(5),
            ..ClientConfig::default()
        },
    )
    .unwrap()
}

/// Must-show (a): Coulomb friction at an operating point where the identification record
/// cannot separate it from an input offset (the speed never reverses): the autotune designs a
/// reversal experiment and reports the friction within 15% of the truth.
#[test]
fn friction_separated_by_reversals() {
    let vc = 0.37;
    let s = sim(
        "5.3/(1.9e-5 s^1.81 + 0.0071 s^0.95 + 1)",
        Effects {
            coulomb_v: vc,
            noise_std: 0.03,
            ..Effects::default()
        },
        7,
    );
    let mut c = client(&s);
    let t0 = Instant::now();
    let r = tuner::run(&mut c, 1000, &AutotuneRequest::default(), &mut Quiet).unwrap();
    println!("{}", r.text());
    println!("wall {:.2} s", t0.elapsed().as_secs_f64());
    let first = &r.rounds[0];
    assert!(
        first.ambiguous.iter().any(|a| a.name == "coulomb_friction"),
        "{:?}",
        first.ambiguous
    );
    assert!(r.rounds.iter().any(|x| x.experiment == "reversals"));
    let got = r.model.as_ref().and_then(|m| m.friction_v).expect("friction reported");
    assert!((got - vc).abs() <= 0.15 * vc, "friction {got} V against {vc} V");
}
