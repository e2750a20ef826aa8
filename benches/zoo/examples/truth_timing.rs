//! Times the truth simulation on the zoo's largest shapes: `cargo run --release -p zoo --example
//! truth_timing`. Prints one line per case: the samples, the wall time and this process's CPU
//! time (from /proc/self/stat on Linux; the wall time alone misleads on a loaded machine).

use std::time::Instant;
use zoo::truth::{simulate, Drive, Effects, Plant, Term};

fn pmsm(delay_s: f64) -> Plant {
    // 50 / (s^0.9 (0.002 s^0.95 + 1)), corner near 690 rad/s.
    Plant {
        num: vec![Term {
            coef: 50.0,
            order: 0.0,
        }],
        den: vec![
            Term {
                coef: 1.0,
                order: 0.9,
            },
            Term {
                coef: 0.002,
                order: 1.85,
            },
        ],
        delay_s,
    }
}

fn relaxation() -> Plant {
    // 10 / (0.01 s^1.5 + 1).
    Plant {
        num: vec![Term {
            coef: 10.0,
            order: 0.0,
        }],
        den: vec![
            Term {
                coef: 1.0,
                order: 0.0,
            },
            Term {
                coef: 0.01,
                order: 1.5,
            },
        ],
        delay_s: 0.0,
    }
}

fn two_mass() -> Plant {
    // A motor-side two-mass drive: anti-resonance 80 Hz, resonance 120 Hz, an integrator.
    let (wa, wr) = (std::f64::consts::TAU * 80.0, std::f64::consts::TAU * 120.0);
    let t = |coef: f64, order: f64| Term { coef, order };
    Plant {
        num: vec![t(wa * wa, 0.0), t(0.1 * wa, 1.0), t(1.0, 2.0)],
        den: vec![t(0.01 * wr * wr, 1.0), t(0.0006 * wr, 2.0), t(0.01, 3.0)],
        delay_s: 0.0,
    }
}

fn prbs(n: usize, clock: usize) -> Vec<f64> {
    let mut state: u32 = 0xACE1;
    let mut level = 1.0;
    (0..n)
        .map(|k| {
            if k % clock == 0 {
                let bit = (state ^ (state >> 2) ^ (state >> 3) ^ (state >> 5)) & 1;
                state = (state >> 1) | (bit << 15);
                level = if bit == 1 { 1.0 } else { -1.0 };
            }
            level
        })
        .collect()
}

/// This process's user + system CPU seconds (None off Linux).
fn cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The fields after the command's closing parenthesis; utime and stime are the 12th and 13th.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn time(label: &str, n: usize, run: impl FnOnce() -> usize) {
    let (start, cpu0) = (Instant::now(), cpu_s());
    let got = run();
    assert_eq!(got, n);
    let wall = start.elapsed().as_secs_f64();
    let cpu = cpu_s()
        .zip(cpu0)
        .map_or("?".to_string(), |(b, a)| format!("{:.2}", b - a));
    println!("{label:<58} {n:>7} samples  wall {wall:>6.2} s  cpu {cpu:>6} s");
}

fn main() {
    let dt = 1e-3;
    let none = Effects::default();
    for n in [5_000usize, 100_000] {
        let u = prbs(n, 7);
        time("open loop, fractional PMSM, delay 1.37 samples", n, || {
            simulate(&pmsm(1.37e-3), &none, &Drive::Open(&u), dt)
                .expect("simulable")
                .y
                .len()
        });
        let reference: Vec<f64> = (0..n)
            .map(|k| if (k / 1000) % 2 == 0 { 100.0 } else { -100.0 })
            .collect();
        let drive = Drive::SpeedLoop {
            reference: &reference,
            kp: 0.05,
            ki: 2.0,
            u_limit: 10.0,
        };
        time(
            "speed loop under a PI, fractional PMSM, delay 1.37 samples",
            n,
            || {
                simulate(&pmsm(1.37e-3), &none, &drive, dt)
                    .expect("simulable")
                    .y
                    .len()
            },
        );
        let friction = Effects {
            coulomb: Some(0.2),
            ..Effects::default()
        };
        time(
            "open loop with Coulomb friction, fractional relaxation",
            n,
            || {
                simulate(&relaxation(), &friction, &Drive::Open(&u), dt)
                    .expect("simulable")
                    .y
                    .len()
            },
        );
        time(
            "open loop with Coulomb friction, integer two-mass (exact)",
            n,
            || {
                simulate(&two_mass(), &friction, &Drive::Open(&u), 2e-4)
                    .expect("simulable")
                    .y
                    .len()
            },
        );
    }
}
