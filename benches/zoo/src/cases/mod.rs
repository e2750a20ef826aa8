//! The generator of cases: seeded, by class. Case `i` of a zoo of seed `s` is class
//! `ALL_CLASSES[i % 25]`, drawn from its own generator (seeded from `s` and `i`), so a case does
//! not depend on how many others are drawn. Each case is a record fracid reads (`t,u,y`) and a
//! sidecar of its hidden truth (plant, effects, noise, class, whether it can be identified and why).
//!
//! A case: a plant of the class's families, a sample time from the plant's fastest time constant
//! (0.1 ms to 2 s), a length from its slowest (300 to 1e5 samples), an input of the class's kinds,
//! the class's effects, simulated by `truth` from rest (a record that starts in motion simulates a
//! lead-in and drops it), then noise (0.1% to 10% of the output's swing, Gaussian) and, for the
//! quantisation class, a quantiser.

pub mod band;
pub mod inputs;
pub mod plants;
pub mod rules;
pub mod write;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::truth::{self, Drive, Effects, Plant};
use inputs::{Excitation, Shape};
use plants::{log_uniform, PlantKind};
pub use rules::Verdict;

/// The classes of the zoo: a plant family, or an effect or a kind of record on common plants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// The paper's PMSM, no effect.
    Pmsm,
    /// Integer first, second and third order.
    Integer,
    /// A compliant coupling measured at the motor.
    TwoMassMotor,
    /// A compliant coupling measured at the load.
    TwoMassLoad,
    /// Two resonances.
    MultiMode,
    /// Relative degree 0.
    Feedthrough,
    /// A position output.
    Integrator,
    /// A slow thermal diffusion.
    Diffusion,
    /// A zero.
    Lead,
    /// Feed-through and an integrator and a fractional branch.
    Cell,
    /// A delay of a fractional number of samples.
    Delay,
    /// Coulomb friction, the speed reversing.
    FrictionReversal,
    /// Coulomb friction, the speed keeping one sign (not identifiable).
    FrictionOneWay,
    /// A dead band under a multi-level input.
    Deadband,
    /// A saturation under a multi-level input.
    Saturation,
    /// A static map under a two-level input (not identifiable).
    StaticMapTwoLevel,
    /// Input and output offsets.
    Offsets,
    /// A periodic output disturbance.
    Periodic,
    /// A sign-blind sensor.
    AbsSensor,
    /// A heater: power as a power of the input.
    PowerLaw,
    /// A quantised output.
    Quantisation,
    /// A slow output drift.
    Drift,
    /// Two effects at once.
    TwoEffects,
    /// A speed loop under a PI.
    ClosedLoop,
    /// A record that starts in motion or mid-transient.
    InMotion,
}

/// Every class, in the order cases cycle through them.
pub const ALL_CLASSES: [Class; 25] = [
    Class::Pmsm,
    Class::Integer,
    Class::TwoMassMotor,
    Class::TwoMassLoad,
    Class::MultiMode,
    Class::Feedthrough,
    Class::Integrator,
    Class::Diffusion,
    Class::Lead,
    Class::Cell,
    Class::Delay,
    Class::FrictionReversal,
    Class::FrictionOneWay,
    Class::Deadband,
    Class::Saturation,
    Class::StaticMapTwoLevel,
    Class::Offsets,
    Class::Periodic,
    Class::AbsSensor,
    Class::PowerLaw,
    Class::Quantisation,
    Class::Drift,
    Class::TwoEffects,
    Class::ClosedLoop,
    Class::InMotion,
];

/// Every plant family.
pub const ALL_PLANTS: [PlantKind; 12] = [
    PlantKind::Pmsm,
    PlantKind::Integer1,
    PlantKind::Integer2,
    PlantKind::Integer3,
    PlantKind::TwoMassMotor,
    PlantKind::TwoMassLoad,
    PlantKind::MultiMode,
    PlantKind::Feedthrough,
    PlantKind::Integrator,
    PlantKind::Diffusion,
    PlantKind::Lead,
    PlantKind::Cell,
];

const OPEN: &[Excitation] = &[
    Excitation::Prbs,
    Excitation::MultiLevel,
    Excitation::StepFromRest,
    Excitation::StepsUpDown,
    Excitation::Staircase,
    Excitation::Chirp,
    Excitation::Multisine,
];
const MULTI: &[Excitation] = &[
    Excitation::MultiLevel,
    Excitation::Staircase,
    Excitation::Chirp,
    Excitation::Multisine,
];
const RICH: &[Excitation] = &[
    Excitation::Prbs,
    Excitation::MultiLevel,
    Excitation::Chirp,
    Excitation::Multisine,
];
const DRIVES: &[PlantKind] = &[PlantKind::Pmsm, PlantKind::Integer1, PlantKind::Integer2];

impl Class {
    /// The name in files and tables.
    pub fn name(self) -> &'static str {
        let i = ALL_CLASSES.iter().position(|c| *c == self).unwrap_or(0);
        NAMES[i]
    }

    /// The class of a name.
    pub fn from_name(name: &str) -> Option<Class> {
        NAMES
            .iter()
            .position(|n| *n == name)
            .map(|i| ALL_CLASSES[i])
    }

    /// The plant families a case of this class is drawn from.
    pub fn plants(self) -> &'static [PlantKind] {
        use PlantKind as P;
        match self {
            Class::Pmsm => &[P::Pmsm],
            Class::Integer => &[P::Integer1, P::Integer2, P::Integer3],
            Class::TwoMassMotor => &[P::TwoMassMotor],
            Class::TwoMassLoad => &[P::TwoMassLoad],
            Class::MultiMode => &[P::MultiMode],
            Class::Feedthrough => &[P::Feedthrough],
            Class::Integrator => &[P::Integrator],
            Class::Diffusion => &[P::Diffusion],
            Class::Lead => &[P::Lead],
            Class::Cell => &[P::Cell],
            Class::PowerLaw => &[P::Integer1, P::Diffusion],
            Class::InMotion => &[P::Pmsm, P::Integer1, P::Integer2, P::TwoMassMotor],
            _ => DRIVES,
        }
    }

    /// The inputs a case of this class is excited by.
    pub fn excitations(self) -> &'static [Excitation] {
        match self {
            Class::Integrator => &[
                Excitation::Prbs,
                Excitation::StepsUpDown,
                Excitation::Chirp,
                Excitation::Multisine,
            ],
            Class::TwoMassMotor | Class::TwoMassLoad | Class::MultiMode => RICH,
            Class::FrictionReversal | Class::AbsSensor | Class::InMotion => RICH,
            Class::FrictionOneWay => &[
                Excitation::Prbs,
                Excitation::MultiLevel,
                Excitation::Multisine,
            ],
            Class::Deadband | Class::Saturation => MULTI,
            Class::StaticMapTwoLevel => &[Excitation::Prbs],
            Class::PowerLaw => &[
                Excitation::MultiLevel,
                Excitation::Staircase,
                Excitation::StepsUpDown,
            ],
            Class::ClosedLoop => &[Excitation::ClosedLoop],
            _ => OPEN,
        }
    }
}

const NAMES: [&str; 25] = [
    "pmsm",
    "integer",
    "two_mass_motor",
    "two_mass_load",
    "multi_mode",
    "feedthrough",
    "integrator",
    "diffusion",
    "lead",
    "cell",
    "delay",
    "friction_reversal",
    "friction_one_way",
    "deadband",
    "saturation",
    "static_map_two_level",
    "offsets",
    "periodic",
    "abs_sensor",
    "power_law",
    "quantisation",
    "drift",
    "two_effects",
    "closed_loop",
    "in_motion",
];

/// How long records may be.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct Sizing {
    /// The longest ordinary record [samples].
    pub max_samples: usize,
    /// The fraction of cases drawn long (2e4 to 1e5 samples).
    pub long_fraction: f64,
}

impl Sizing {
    /// The full zoo: records to 8000 samples, 4% of them 2e4-1e5.
    pub const ZOO: Sizing = Sizing {
        max_samples: 8000,
        long_fraction: 0.04,
    };
    /// The CI subset: short records only.
    pub const CI: Sizing = Sizing {
        max_samples: 2500,
        long_fraction: 0.0,
    };
}

/// The PI of a closed-loop record.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PiLoop {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain [1/s].
    pub ki: f64,
    /// Output limit.
    pub u_limit: f64,
}

/// The hidden truth of a case: the sidecar JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// The case's name (its files' stem).
    pub name: String,
    /// The zoo's seed.
    pub seed: u64,
    /// The case's index in the zoo.
    pub index: usize,
    /// The class.
    pub class: Class,
    /// The plant's family.
    pub plant_kind: PlantKind,
    /// What was drawn, in words.
    pub about: String,
    /// The plant (its delay included).
    pub plant: Plant,
    /// The effects.
    pub effects: Effects,
    /// The input.
    pub excitation: Excitation,
    /// The PI of a closed-loop record.
    pub pi: Option<PiLoop>,
    /// Sample time [s].
    pub dt: f64,
    /// Samples in the record.
    pub samples: usize,
    /// Samples simulated before the record and dropped (a record that starts in motion).
    pub lead_in_samples: usize,
    /// The noise-free output's swing (max - min).
    pub swing: f64,
    /// The noise's standard deviation as a fraction of the swing.
    pub noise_fraction: f64,
    /// The noise's RMS as added (quantisation included).
    pub noise_rms: f64,
    /// The quantiser's step, if any.
    pub quantisation_step: Option<f64>,
    /// The band the record excites [rad/s] (see `band`).
    pub band_omega: Vec<f64>,
    /// The static gain (None: an integrator).
    pub dc_gain: Option<f64>,
    /// Whether the truth can be identified from this record, and which effects a right answer keeps.
    pub verdict: Verdict,
}

/// A case: its truth and its record.
#[derive(Clone, Debug)]
pub struct Case {
    /// The hidden truth.
    pub truth: Truth,
    /// The input.
    pub u: Vec<f64>,
    /// The measured output (noise and quantisation added).
    pub y: Vec<f64>,
    /// The noise-free output.
    pub y_clean: Vec<f64>,
}

/// Errors of the generator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The truth refused a plant.
    #[error(transparent)]
    Truth(#[from] truth::Error),
    /// No draw gave a usable record.
    #[error("case {0}: no usable record in {1} draws (last: {2})")]
    NoRecord(usize, usize, String),
    /// A file could not be written or read.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    /// A sidecar could not be parsed.
    #[error("{0}: {1}")]
    Json(String, serde_json::Error),
}

/// Draws before a case gives up.
const ATTEMPTS: usize = 12;

/// The class of case `index`.
pub fn class_of(index: usize) -> Class {
    ALL_CLASSES[index % ALL_CLASSES.len()]
}

/// Case `index` of the zoo of `seed`.
pub fn generate(seed: u64, index: usize, sizing: Sizing) -> Result<Case, Error> {
    let class = class_of(index);
    let mut last = String::new();
    for attempt in 0..ATTEMPTS {
        let mix = seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((index as u64) << 8)
            .wrapping_add(attempt as u64);
        let mut rng = StdRng::seed_from_u64(mix);
        match draw(seed, index, class, sizing, &mut rng)? {
            Ok(case) => return Ok(case),
            Err(why) => last = why,
        }
    }
    Err(Error::NoRecord(index, ATTEMPTS, last))
}

/// Cases `0..count` of the zoo of `seed`.
pub fn generate_zoo(seed: u64, count: usize, sizing: Sizing) -> Result<Vec<Case>, Error> {
    (0..count).map(|i| generate(seed, i, sizing)).collect()
}

/// The input's range for the class (zero-mean where the output must reverse).
fn input_range(class: Class, rng: &mut StdRng) -> (f64, f64) {
    let a = log_uniform(rng, 0.5, 10.0);
    match class {
        Class::FrictionReversal | Class::AbsSensor | Class::Integrator => (-a, a),
        Class::FrictionOneWay => (a * rng.gen_range(0.4..=0.7), a),
        Class::PowerLaw => (0.0, a),
        Class::TwoEffects => (-a, a),
        _ if rng.gen_bool(0.5) => (-a, a),
        _ => (0.0, a),
    }
}

/// The sample time and length for a plant.
fn timing(d: &plants::Drawn, sizing: Sizing, rng: &mut StdRng) -> (f64, usize) {
    let dt = (d.fast_s / log_uniform(rng, 2.0, 8.0)).clamp(1e-4, 2.0);
    let record_s = d.slow_s * log_uniform(rng, 20.0, 100.0);
    let least = log_uniform(rng, 300.0, 3000.0);
    let mut n = ((record_s / dt).max(least) as usize).clamp(300, sizing.max_samples.max(300));
    if sizing.long_fraction > 0.0 && rng.gen_bool(sizing.long_fraction) {
        n = log_uniform(rng, 2e4, 1e5) as usize;
    }
    (dt, n)
}

/// One draw: Ok(Err(why)) when the record is unusable (another draw is tried).
fn draw(
    seed: u64,
    index: usize,
    class: Class,
    sizing: Sizing,
    rng: &mut StdRng,
) -> Result<Result<Case, String>, Error> {
    let kinds = class.plants();
    let plant_kind = kinds[rng.gen_range(0..kinds.len())];
    let drawn = plants::draw(plant_kind, rng);
    let (dt, n) = timing(&drawn, sizing, rng);
    let excitations = class.excitations();
    let excitation = excitations[rng.gen_range(0..excitations.len())];
    let (low, high) = input_range(class, rng);
    let shape = Shape {
        low,
        high,
        dt,
        fast_s: drawn.fast_s,
        slow_s: drawn.slow_s,
    };
    let lead_in = if class == Class::InMotion {
        (n as f64 * rng.gen_range(0.2..=0.5)) as usize
    } else {
        0
    };
    let mut plant = drawn.plant.clone();
    let (mut effects, pending) = input_effects(class, &shape, rng);
    if class == Class::Delay || (class == Class::TwoEffects && rng.gen_bool(0.3)) {
        plant.delay_s = dt * rng.gen_range(0.3..=8.0);
    }
    let input = inputs::make(excitation, n + lead_in, &shape, rng);
    let pi = (excitation == Excitation::ClosedLoop).then(|| {
        let k = drawn.dc_gain.unwrap_or(1.0);
        let kp = rng.gen_range(0.3..=1.5) / k;
        PiLoop {
            kp,
            ki: kp / drawn.slow_s * rng.gen_range(0.3..=1.0),
            u_limit: 3.0 * high.abs().max(low.abs()),
        }
    });
    let reference: Vec<f64>;
    let drive = match pi {
        Some(p) => {
            reference = input
                .iter()
                .map(|r| r * drawn.dc_gain.unwrap_or(1.0))
                .collect();
            Drive::SpeedLoop {
                reference: &reference,
                kp: p.kp,
                ki: p.ki,
                u_limit: p.u_limit,
            }
        }
        None => Drive::Open(&input),
    };
    // The plant's own output first (the output effects sized on its swing), then the record.
    let plant_only = truth::simulate(&plant, &effects, &drive, dt)?;
    let checked = usable(
        &plant_only.y[lead_in..],
        &plant,
        &plant_only.u,
        effects.power_law,
        dt,
    );
    if let Err(why) = checked {
        return Ok(Err(why));
    }
    let y_plant = plant_only.y[lead_in..].to_vec();
    let plant_swing = swing(&y_plant);
    output_effects(
        class,
        pending,
        &mut effects,
        plant_swing,
        n as f64 * dt,
        dt,
        rng,
    );
    let record = if effects_on_output(&effects) {
        truth::simulate(&plant, &effects, &drive, dt)?
    } else {
        plant_only
    };
    let head = Head {
        seed,
        index,
        class,
        plant_kind,
        about: drawn.about,
        plant,
        excitation,
        pi,
        dt,
        lead_in,
        dc_gain: drawn.dc_gain,
    };
    Ok(finish(head, effects, record, y_plant, rng))
}

/// What a draw settled before the noise.
struct Head {
    seed: u64,
    index: usize,
    class: Class,
    plant_kind: PlantKind,
    about: String,
    plant: Plant,
    excitation: Excitation,
    pi: Option<PiLoop>,
    dt: f64,
    lead_in: usize,
    dc_gain: Option<f64>,
}

/// Drops the lead-in, adds the noise (and the quantiser), finds the band and judges the case.
fn finish(
    h: Head,
    effects: Effects,
    record: truth::Record,
    y_plant: Vec<f64>,
    rng: &mut StdRng,
) -> Result<Case, String> {
    let u = record.u[h.lead_in..].to_vec();
    let y_clean = record.y[h.lead_in..].to_vec();
    let n = u.len();
    let out_swing = swing(&y_clean);
    if !(out_swing > 0.0) || y_clean.iter().any(|v| !v.is_finite()) {
        return Err("the record's output is flat or not finite".into());
    }
    let noise_fraction = log_uniform(rng, 1e-3, 0.1);
    let quantisation_step =
        (h.class == Class::Quantisation).then(|| out_swing / log_uniform(rng, 20.0, 300.0));
    let y = noisy(&y_clean, noise_fraction * out_swing, quantisation_step, rng);
    let noise: Vec<f64> = y.iter().zip(&y_clean).map(|(a, b)| a - b).collect();
    let noise_rms = (noise.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    let band_input: Vec<f64> = match effects.power_law {
        Some(p) => u.iter().map(|x| x.signum() * x.abs().powf(p)).collect(),
        None => u.clone(),
    };
    let band_omega = band::excited(&h.plant, &band_input, &noise, h.dt);
    let verdict = rules::judge(&rules::Facts {
        effects: &effects,
        delay_s: h.plant.delay_s,
        dt: h.dt,
        dc_gain: h.dc_gain,
        u: &u,
        y_plant: &y_plant,
        noise_rms,
        band: &band_omega,
    });
    let truth = Truth {
        name: format!("{:04}_{}", h.index, h.class.name()),
        seed: h.seed,
        index: h.index,
        class: h.class,
        plant_kind: h.plant_kind,
        about: h.about,
        plant: h.plant,
        effects,
        excitation: h.excitation,
        pi: h.pi,
        dt: h.dt,
        samples: n,
        lead_in_samples: h.lead_in,
        swing: out_swing,
        noise_fraction,
        noise_rms,
        quantisation_step,
        band_omega,
        dc_gain: h.dc_gain,
        verdict,
    };
    Ok(Case {
        truth,
        u,
        y,
        y_clean,
    })
}

fn swing(y: &[f64]) -> f64 {
    let (lo, hi) = y
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    hi - lo
}

/// A record is usable when finite, not flat and not blown up: its swing at most 20 times the
/// largest input times the largest |G(jw)| from 1/T to the Nyquist frequency (a closed loop that
/// went unstable, or a simulation that diverged).
fn usable(y: &[f64], plant: &Plant, u: &[f64], power: Option<f64>, dt: f64) -> Result<(), String> {
    if y.iter().any(|v| !v.is_finite()) {
        return Err("not finite".into());
    }
    let s = swing(y);
    if !(s > 0.0) {
        return Err("flat output".into());
    }
    let u_max = u.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let u_max = u_max.max(power.map_or(0.0, |p| u_max.powf(p)));
    let (lo, hi) = (1.0 / (y.len() as f64 * dt), std::f64::consts::PI / dt);
    let points = (10.0 * (hi / lo).log10()).ceil().max(1.0) as usize;
    let g_max = (0..=points)
        .map(|i| {
            plant
                .response(lo * (hi / lo).powf(i as f64 / points as f64))
                .norm()
        })
        .fold(0.0_f64, f64::max);
    if !(s <= 20.0 * g_max * u_max) {
        return Err(format!(
            "output swing {s:.3e} beyond 20 max|G| max|u| = {:.3e}: diverged",
            20.0 * g_max * u_max
        ));
    }
    Ok(())
}

/// Output effects drawn with the input ones, sized once the plant's swing is known.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    periodic: bool,
    abs_sensor: bool,
}

fn input_effects(class: Class, shape: &Shape, rng: &mut StdRng) -> (Effects, Pending) {
    let a = shape.high.abs().max(shape.low.abs());
    let mut e = Effects::default();
    let mut pending = Pending::default();
    let add = |e: &mut Effects, which: usize, rng: &mut StdRng| match which {
        0 => e.coulomb = Some(a * rng.gen_range(0.05..=0.25)),
        1 => e.deadband = Some(a * rng.gen_range(0.1..=0.3)),
        2 => e.saturation = Some(a * rng.gen_range(0.5..=0.85)),
        3 => e.power_law = Some(rng.gen_range(1.5..=2.5)),
        4 => {
            e.input_offset =
                a * rng.gen_range(0.05..=0.3) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 }
        }
        _ => {}
    };
    match class {
        Class::FrictionReversal => add(&mut e, 0, rng),
        Class::FrictionOneWay => e.coulomb = Some(shape.low * rng.gen_range(0.2..=0.6)),
        Class::Deadband => add(&mut e, 1, rng),
        Class::Saturation => add(&mut e, 2, rng),
        Class::StaticMapTwoLevel => add(&mut e, rng.gen_range(1..=3), rng),
        Class::PowerLaw => add(&mut e, 3, rng),
        Class::Offsets => add(&mut e, 4, rng),
        Class::TwoEffects => {
            // Two of: friction, dead band, saturation, input offset, periodic, sign-blind sensor
            // (the output ones are drawn in `output_effects`, the delay in `draw`).
            let first = rng.gen_range(0..6);
            let second = (first + rng.gen_range(1..6)) % 6;
            for which in [first, second] {
                match which {
                    0 => add(&mut e, 0, rng),
                    1 => add(&mut e, 1, rng),
                    2 => add(&mut e, 2, rng),
                    3 => add(&mut e, 4, rng),
                    4 => pending.periodic = true,
                    _ => pending.abs_sensor = true,
                }
            }
        }
        _ => {}
    }
    (e, pending)
}

/// Sizes the output effects on the plant's swing.
fn output_effects(
    class: Class,
    pending: Pending,
    e: &mut Effects,
    swing: f64,
    record_s: f64,
    dt: f64,
    rng: &mut StdRng,
) {
    let periodic = |rng: &mut StdRng| {
        let amplitude = swing * log_uniform(rng, 0.02, 0.2);
        let freq_hz = log_uniform(rng, 5.0 / record_s, 0.3 / dt);
        Some((amplitude, freq_hz))
    };
    match class {
        Class::Periodic => e.periodic = periodic(rng),
        Class::AbsSensor => e.abs_sensor = true,
        Class::Offsets => {
            e.output_offset =
                swing * rng.gen_range(0.1..=1.0) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 }
        }
        Class::Drift => {
            e.drift_per_s = swing * rng.gen_range(0.05..=0.3) / record_s
                * if rng.gen_bool(0.5) { 1.0 } else { -1.0 }
        }
        _ => {}
    }
    if pending.periodic {
        e.periodic = periodic(rng);
    }
    e.abs_sensor |= pending.abs_sensor;
}

fn effects_on_output(e: &Effects) -> bool {
    e.output_offset != 0.0 || e.abs_sensor || e.periodic.is_some() || e.drift_per_s != 0.0
}

/// The measured output: Gaussian noise of standard deviation `sigma`, then the quantiser.
fn noisy(y: &[f64], sigma: f64, step: Option<f64>, rng: &mut StdRng) -> Vec<f64> {
    y.iter()
        .map(|v| {
            let z: f64 = StandardNormal.sample(rng);
            let m = v + sigma * z;
            match step {
                Some(q) => q * (m / q).round(),
                None => m,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: Sizing = Sizing {
        max_samples: 1500,
        long_fraction: 0.0,
    };

    #[test]
    fn a_seed_gives_the_same_cases_and_another_seed_others() {
        for index in [0, 12, 24, 47] {
            let a = generate(7, index, SMALL).unwrap();
            let b = generate(7, index, SMALL).unwrap();
            assert_eq!(a.truth, b.truth);
            assert_eq!((&a.u, &a.y, &a.y_clean), (&b.u, &b.y, &b.y_clean));
            let c = generate(8, index, SMALL).unwrap();
            assert_ne!(a.y, c.y, "case {index}: seeds 7 and 8 drew the same record");
        }
    }

    #[test]
    fn every_class_is_present_in_range_and_judged() {
        let zoo = generate_zoo(3, ALL_CLASSES.len(), SMALL).unwrap();
        for (case, class) in zoo.iter().zip(ALL_CLASSES) {
            let t = &case.truth;
            assert_eq!(t.class, class);
            assert_eq!(Class::from_name(class.name()), Some(class));
            assert!(t.name.ends_with(class.name()));
            assert!((1e-4..=2.0).contains(&t.dt), "{}: dt {}", t.name, t.dt);
            assert!((300..=SMALL.max_samples).contains(&t.samples), "{}", t.name);
            assert_eq!(
                (case.u.len(), case.y.len(), case.y_clean.len()),
                (t.samples, t.samples, t.samples)
            );
            assert!(
                class.plants().contains(&t.plant_kind)
                    && class.excitations().contains(&t.excitation)
            );
            assert!(t.noise_fraction >= 1e-3 && t.noise_fraction <= 0.1);
            let rms = (case
                .y
                .iter()
                .zip(&case.y_clean)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / t.samples as f64)
                .sqrt();
            assert!(
                (rms - t.noise_rms).abs() <= 1e-9 * (1.0 + rms),
                "{}",
                t.name
            );
        }
        let by = |c: Class| &zoo[ALL_CLASSES.iter().position(|x| *x == c).unwrap()].truth;
        // The classes built not to be identifiable are not, and name their confounded effect.
        assert!(!by(Class::FrictionOneWay).verdict.identifiable);
        assert_eq!(
            by(Class::FrictionOneWay).verdict.confounded_effects,
            ["coulomb_friction"]
        );
        assert!(!by(Class::StaticMapTwoLevel).verdict.identifiable);
        assert!(
            by(Class::Pmsm).verdict.identifiable
                && by(Class::Pmsm).verdict.expected_effects.is_empty()
        );
        assert!(by(Class::Delay).plant.delay_s > 0.0);
        let motion = by(Class::InMotion);
        assert!(motion.lead_in_samples > 0);
        assert!(by(Class::Quantisation).quantisation_step.is_some());
    }

    #[test]
    fn a_record_in_motion_does_not_start_at_rest() {
        let index = ALL_CLASSES
            .iter()
            .position(|c| *c == Class::InMotion)
            .unwrap();
        let case = generate(11, index, SMALL).unwrap();
        // From rest the first noise-free output would be 0 (no offset in this class).
        assert!(
            case.y_clean[0].abs() > 1e-3 * case.truth.swing,
            "{}",
            case.y_clean[0]
        );
    }
}
