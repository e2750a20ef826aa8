//! `simulate`: the plant's input is held over each sample, so it is a sum of steps at known
//! instants and the output at the sample instants is exact superposition of step responses
//! sampled on two lattices: the command's steps arrive `delay_s` after the sample instants, the
//! Coulomb friction's (which acts on the mechanics, not through the input delay) at them.
//!
//! Open loop without friction: the static input effects applied to `u`, one convolution (FFT),
//! the output effects after. With an output that feeds back (Coulomb friction, the speed loop):
//! step by step (`series::online`, the past's effect gathered by FFT in blocks), each sample's
//! output just before the new input (`y(t_k^-)`) deciding the friction's sign and the
//! controller's output, then the recorded `y(t_k^+)` (which differs only by a feed-through's
//! jump). The friction is decided at the sample instants and held, like the input.

use super::effects;
use super::lattice::StepResponse;
use super::plant::{self, feedthrough};
use super::series::{self, convolve};
use super::{Drive, Effects, Error, Plant, Record};

/// The step responses per lag `l` (samples since the step's sample instant).
struct Lags {
    /// A unit step of the command at sample 0, seen at sample `l` (`delay_s` included).
    command: Vec<f64>,
    /// The lag at which a command step arrives exactly at a sample instant (whole-sample delay).
    command_on_sample: Option<usize>,
    /// A unit step of the plant's input at sample 0 without the delay (friction).
    friction: Vec<f64>,
}

impl Lags {
    fn new(
        step: &StepResponse,
        delay_s: f64,
        dt: f64,
        n: usize,
        with_friction: bool,
    ) -> Result<Lags, Error> {
        let ratio = delay_s / dt;
        let whole = (ratio + 1e-9).floor();
        let frac = if ratio - whole < 1e-9 {
            0.0
        } else {
            ratio - whole
        };
        let whole = whole as usize;
        let mut command = vec![0.0; n];
        // The lattices: at the sample instants (a whole-sample delay, and the friction), and
        // (1 - frac) dt after them (a fractional delay's command steps).
        let first = if frac == 0.0 { whole } else { whole + 1 };
        let mut wanted = vec![(
            if frac == 0.0 { 0.0 } else { (1.0 - frac) * dt },
            n.saturating_sub(first),
        )];
        if with_friction {
            wanted.push((0.0, n));
        }
        let mut lattices = step.lattices(&wanted, dt)?.into_iter();
        let shifted = lattices.next().unwrap_or_default();
        if first < n {
            command[first..].copy_from_slice(&shifted[..n - first]);
        }
        let command_on_sample = (frac == 0.0).then_some(whole);
        let at_samples = lattices.next().unwrap_or_default();
        Ok(Lags {
            command,
            command_on_sample,
            friction: if with_friction { at_samples } else { vec![] },
        })
    }
}

fn check_drive(drive: &Drive<'_>, dt: f64) -> Result<usize, Error> {
    let bad = |msg: &str| Err(Error::Drive(msg.to_string()));
    if !dt.is_finite() || dt <= 0.0 {
        return bad("the sample time must be finite and > 0");
    }
    match drive {
        Drive::Open(u) => {
            if u.iter().any(|v| !v.is_finite()) {
                return bad("the input has a non-finite value");
            }
            Ok(u.len())
        }
        Drive::SpeedLoop {
            reference,
            kp,
            ki,
            u_limit,
        } => {
            if reference.iter().any(|v| !v.is_finite()) {
                return bad("the reference has a non-finite value");
            }
            if !kp.is_finite() || !ki.is_finite() || !u_limit.is_finite() || *u_limit < 0.0 {
                return bad("the PI's gains must be finite and its limit finite and >= 0");
            }
            Ok(reference.len())
        }
    }
}

pub(crate) fn simulate(
    plant: &Plant,
    effects: &Effects,
    drive: &Drive<'_>,
    dt: f64,
) -> Result<Record, Error> {
    plant::check(plant)?;
    effects::check(effects).map_err(Error::Drive)?;
    let n = check_drive(drive, dt)?;
    let step = StepResponse::new(plant);
    let feedback = effects.coulomb.is_some() || matches!(drive, Drive::SpeedLoop { .. });
    let lags = Lags::new(&step, plant.delay_s, dt, n, feedback)?;
    match drive {
        Drive::Open(u) if !feedback => Ok(open_loop(&lags, effects, u, dt)),
        _ => Ok(stepwise(&lags, feedthrough(plant), effects, drive, dt, n)),
    }
}

fn open_loop(lags: &Lags, effects: &Effects, u: &[f64], dt: f64) -> Record {
    let mut last = 0.0;
    let steps: Vec<f64> = u
        .iter()
        .map(|&v| {
            let held = effects::input(effects, v);
            let step = held - last;
            last = held;
            step
        })
        .collect();
    let plant_out = convolve(&steps, &lags.command, u.len());
    let y = plant_out
        .iter()
        .enumerate()
        .map(|(k, &v)| effects::output(effects, v, k as f64 * dt))
        .collect();
    Record { u: u.to_vec(), y }
}

/// A discrete PI with anti-windup by conditional integration (the sum stops growing while the
/// output is clamped and the error pushes further into the clamp).
struct Pi {
    kp: f64,
    ki_dt: f64,
    limit: f64,
    sum: f64,
}

impl Pi {
    fn output(&mut self, error: f64) -> f64 {
        let next = self.sum + self.ki_dt * error;
        let raw = self.kp * error + next;
        let winding = (raw > self.limit && error > 0.0) || (raw < -self.limit && error < 0.0);
        if !winding {
            self.sum = next;
        }
        (self.kp * error + self.sum).clamp(-self.limit, self.limit)
    }
}

fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

fn stepwise(
    lags: &Lags,
    d: f64,
    effects: &Effects,
    drive: &Drive<'_>,
    dt: f64,
    n: usize,
) -> Record {
    let mut pi = match drive {
        Drive::SpeedLoop {
            kp, ki, u_limit, ..
        } => Some(Pi {
            kp: *kp,
            ki_dt: ki * dt,
            limit: *u_limit,
            sum: 0.0,
        }),
        Drive::Open(_) => None,
    };
    let with_friction = !lags.friction.is_empty();
    let mut command_steps = vec![0.0; n];
    let (mut last_held, mut last_friction) = (0.0, 0.0);
    let mut record = Record {
        u: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
    };
    let kernels: Vec<&[f64]> = if with_friction {
        vec![&lags.command, &lags.friction]
    } else {
        vec![&lags.command]
    };
    // `before`: the output at t_k from every step before sample k.
    series::online(kernels, n, |k, before, decided| {
        let t = k as f64 * dt;
        let arriving = match lags.command_on_sample {
            Some(l) if l >= 1 && k >= l => d * command_steps[k - l],
            _ => 0.0,
        };
        let y_minus = before - arriving;
        let u = match (drive, pi.as_mut()) {
            (Drive::SpeedLoop { reference, .. }, Some(pi)) => {
                pi.output(reference[k] - effects::output(effects, y_minus, t))
            }
            (Drive::Open(u), _) => u[k],
            _ => unreachable!("a speed loop has its PI"),
        };
        let held = effects::input(effects, u);
        command_steps[k] = held - last_held;
        last_held = held;
        decided[0] = command_steps[k];
        let mut y_plus = before + lags.command[0] * command_steps[k];
        if with_friction {
            let friction = effects.coulomb.map_or(0.0, |c| -c * sign(y_minus));
            decided[1] = friction - last_friction;
            last_friction = friction;
            y_plus += lags.friction[0] * decided[1];
        }
        record.u.push(u);
        record.y.push(effects::output(effects, y_plus, t));
    });
    record
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::Term;

    fn gain(k: f64) -> Plant {
        Plant {
            num: vec![Term {
                coef: k,
                order: 0.0,
            }],
            den: vec![Term {
                coef: 1.0,
                order: 0.0,
            }],
            delay_s: 0.0,
        }
    }

    #[test]
    fn a_feedthrough_in_the_loop_sees_the_previous_input() {
        // A gain of 2 under the PI: the controller reads y(t_k^-) = 2 u_{k-1} (the new input not
        // yet applied), the record holds y(t_k^+) = 2 u_k.
        let (kp, ki, dt) = (0.2, 5.0, 0.01);
        let reference = vec![1.0; 200];
        let drive = Drive::SpeedLoop {
            reference: &reference,
            kp,
            ki,
            u_limit: 10.0,
        };
        let rec = simulate(&gain(2.0), &Effects::default(), &drive, dt).unwrap();
        let (mut last_u, mut sum) = (0.0, 0.0);
        for k in 0..200 {
            let e = 1.0 - 2.0 * last_u;
            sum += ki * dt * e;
            let u = kp * e + sum;
            assert!((rec.u[k] - u).abs() < 1e-12, "u at {k}");
            assert!((rec.y[k] - 2.0 * u).abs() < 1e-12, "y at {k}");
            last_u = u;
        }
        assert!((rec.y[199] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = gain(1.0);
        let none = Effects::default();
        assert!(matches!(
            simulate(&p, &none, &Drive::Open(&[1.0, f64::NAN]), 0.1),
            Err(Error::Drive(_))
        ));
        assert!(matches!(
            simulate(&p, &none, &Drive::Open(&[1.0]), 0.0),
            Err(Error::Drive(_))
        ));
        let bad_fx = Effects {
            saturation: Some(-1.0),
            ..Effects::default()
        };
        assert!(matches!(
            simulate(&p, &bad_fx, &Drive::Open(&[1.0]), 0.1),
            Err(Error::Drive(_))
        ));
        let improper = Plant {
            num: vec![Term {
                coef: 1.0,
                order: 1.0,
            }],
            ..gain(1.0)
        };
        assert!(matches!(
            simulate(&improper, &none, &Drive::Open(&[1.0]), 0.1),
            Err(Error::Plant(_))
        ));
        let drive = Drive::SpeedLoop {
            reference: &[1.0],
            kp: 1.0,
            ki: f64::INFINITY,
            u_limit: 1.0,
        };
        assert!(matches!(
            simulate(&p, &none, &drive, 0.1),
            Err(Error::Drive(_))
        ));
        // A corner far faster than the sample time over a long record: the fine grid would be
        // too long, an error before anything is allocated.
        let fast = Plant {
            num: vec![Term {
                coef: 1.0,
                order: 0.0,
            }],
            den: vec![
                Term {
                    coef: 1.0,
                    order: 0.0,
                },
                Term {
                    coef: 1e-8,
                    order: 1.9,
                },
            ],
            delay_s: 0.0,
        };
        let u = vec![1.0; 1000];
        assert!(matches!(
            simulate(&fast, &none, &Drive::Open(&u), 1.0),
            Err(Error::Plant(_))
        ));
        // Empty records are records.
        assert!(simulate(&p, &none, &Drive::Open(&[]), 0.1)
            .unwrap()
            .y
            .is_empty());
    }

    #[test]
    fn a_delay_longer_than_the_record_gives_silence() {
        let p = Plant {
            delay_s: 5.0,
            ..gain(3.0)
        };
        let rec = simulate(&p, &Effects::default(), &Drive::Open(&[1.0; 20]), 0.1).unwrap();
        assert!(rec.y.iter().all(|v| *v == 0.0));
        let fx = Effects {
            coulomb: Some(0.1),
            ..Effects::default()
        };
        let rec = simulate(&p, &fx, &Drive::Open(&[1.0; 20]), 0.1).unwrap();
        assert!(rec.y.iter().all(|v| *v == 0.0));
    }
}
