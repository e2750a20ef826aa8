//! The experiments designed from what was measured: the identification PRBS from the probe, and
//! for each ambiguity the diagnosis names the experiment that separates it. Every level is kept
//! within [`Envelope`]: the voltage and the speed the request allows, with a margin.

use super::probe::ProbeReading;
use crate::acquire::prbs::PrbsRequest;
use serde::Serialize;

/// The share of the limits the designs use: the drive's clamp and speed trip stay as the last
/// line.
pub const LIMIT_SHARE: f64 = 0.8;

/// The levels an experiment may hold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Envelope {
    /// The largest voltage magnitude, V.
    pub u_max_v: f64,
    /// The largest speed magnitude the designs aim below, rad/s.
    pub speed_max: f64,
}

impl Envelope {
    /// The voltage that keeps the steady speed within the envelope for a plant of `gain`.
    pub fn u_for_speed(&self, gain: f64) -> f64 {
        (self.speed_max / gain.abs().max(1e-9)).min(self.u_max_v)
    }
}

/// The bit duration (in samples) of a PRBS whose spectrum is down 3 dB at `w_hi` rad/s
/// (`0.44 / Tc` Hz), at least one sample.
pub fn clock_samples(w_hi: f64, fs: f64) -> u16 {
    let f_hi = w_hi / (2.0 * std::f64::consts::PI);
    (0.44 * fs / f_hi).floor().clamp(1.0, 1000.0) as u16
}

/// The LFSR order whose period of `clock` seconds lasts at least `span_s`, within 5..=12.
pub fn order_for(span_s: f64, clock_s: f64) -> u8 {
    let bits = (span_s / clock_s + 1.0).log2().ceil();
    bits.clamp(5.0, 12.0) as u8
}

/// The duration of a PRBS request, s.
pub fn duration_s(r: &PrbsRequest) -> f64 {
    r.settle_s + f64::from(r.periods) * ((1u32 << r.order) - 1) as f64 * r.clock_s
}

/// The identification PRBS from the probe: the band up to three times the probe's bandwidth
/// (at most a fifth of the sample rate), a period of twenty settling times (at least 0.3 s), the
/// operating point `op_v` (default half the envelope's voltage for the speed) with an amplitude
/// of half of it, after five settling times at it (the step to the operating point is recorded
/// too: it shows the static gain). `span_cap_s` bounds the period (the budget).
pub fn identification(
    p: &ProbeReading,
    env: &Envelope,
    op_v: Option<f64>,
    fs: f64,
    span_cap_s: f64,
    seed: u32,
) -> PrbsRequest {
    let w_hi = (3.0 * p.bandwidth_rad_s()).min(2.0 * std::f64::consts::PI * fs / 5.0);
    let clock = f64::from(clock_samples(w_hi, fs)) / fs;
    let span = (20.0 * p.settling_s()).max(0.3).min(span_cap_s.max(0.05));
    let u_top = env.u_for_speed(p.gain);
    let offset = op_v.unwrap_or(0.5 * u_top).clamp(-u_top, u_top);
    let amplitude = (0.5 * offset.abs())
        .max(0.1 * u_top)
        .min(u_top - offset.abs());
    PrbsRequest {
        order: order_for(span, clock),
        seed,
        clock_s: clock,
        amplitude_v: amplitude.max(0.01),
        offset_v: offset,
        periods: 1,
        settle_s: (5.0 * p.settling_s()).clamp(0.05, 1.0),
    }
}

/// The experiment that separates Coulomb friction from an input offset: a zero-mean PRBS whose
/// bits last two settling times (the speed reverses with each change of sign and reaches its
/// level), at 30% of the envelope's voltage for the speed (friction is then a larger share of
/// the input: its estimate firmer), over about `span_s` seconds.
pub fn reversals(p: &ProbeReading, env: &Envelope, fs: f64, span_s: f64, seed: u32) -> PrbsRequest {
    let clock_n = (2.0 * p.settling_s() * fs).ceil().clamp(1.0, 65535.0);
    let clock = clock_n / fs;
    PrbsRequest {
        order: order_for(span_s, clock).min(8),
        seed,
        clock_s: clock,
        amplitude_v: 0.3 * env.u_for_speed(p.gain),
        offset_v: 0.0,
        periods: 1,
        settle_s: 0.0,
    }
}

/// A longer record for a slow mode: the identification PRBS with bits four times longer and a
/// period of about `span_s` seconds.
pub fn longer(base: &PrbsRequest, fs: f64, span_s: f64) -> PrbsRequest {
    let clock = ((base.clock_s * fs * 4.0).round().min(65535.0)) / fs;
    PrbsRequest {
        clock_s: clock,
        order: order_for(span_s, clock),
        seed: base.seed.wrapping_add(1).max(1),
        ..base.clone()
    }
}

/// The frequencies of a sine dwell around a suspected resonance at `f_hz`: 0.8, 0.93, 1, 1.07
/// and 1.25 times it, below a quarter of the sample rate.
pub fn dwell_frequencies(f_hz: f64, fs: f64) -> Vec<f64> {
    [0.8, 0.93, 1.0, 1.07, 1.25]
        .iter()
        .map(|k| k * f_hz)
        .filter(|f| *f < fs / 4.0)
        .collect()
}

/// Why an experiment was run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Purpose {
    /// The probe: gain, bandwidth, delay.
    Probe,
    /// The identification experiment.
    Identification,
    /// Speed reversals: friction against an input offset.
    Reversals,
    /// A multi-level input: a static input map against a gain and an offset.
    MultiLevel,
    /// A sine dwell around a suspected resonance.
    Dwell,
    /// A longer record for a slow mode.
    Longer,
    /// The tuned loop's step.
    LoopStep,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reading() -> ProbeReading {
        ProbeReading {
            level_v: 2.0,
            final_speed: 13.6,
            gain: 6.8,
            delay_s: 0.0,
            time_constant_s: 0.004,
            noise: 0.01,
            settled: true,
            peak_speed: 13.6,
        }
    }

    /// The identification PRBS covers the band, lasts its span and stays in the envelope.
    #[test]
    fn identification_prbs_in_band_and_envelope() {
        let env = Envelope {
            u_max_v: 9.6,
            speed_max: 100.0,
        };
        let r = identification(&reading(), &env, None, 1000.0, 2.0, 1);
        // 3 x 250 rad/s = 119 Hz: 0.44 * 1000 / 119 = 3.7 -> 3 samples
        assert_eq!(r.clock_s, 0.003);
        let period = ((1u32 << r.order) - 1) as f64 * r.clock_s;
        assert!((0.3..0.7).contains(&period), "{period}");
        let top = (r.offset_v + r.amplitude_v) * 6.8;
        assert!(
            top <= 100.0 + 1e-9 && r.offset_v - r.amplitude_v >= 0.0,
            "{r:?}"
        );
        let rev = reversals(&reading(), &env, 1000.0, 1.0, 1);
        assert_eq!((rev.offset_v, rev.clock_s), (0.0, 0.032));
        assert!(rev.amplitude_v * 6.8 <= 100.0);
    }
}
