//! The Rust firmware's sample loop: the command of each sample (excitation, speed loop or
//! ramp-down), the motor, the channels, the trips.

use super::run::{Excitation, Run};
use super::Firmware;
use crate::prbs::Lfsr;
use crate::protocol::*;
use std::time::{Duration, Instant};

/// One sample's command, before the inverter's limit.
struct Command {
    /// The voltage command, raw.
    u_raw: f64,
    /// A sine being measured: its phase at this sample, rad.
    phase: Option<f64>,
    /// A speed loop: the speed measured at the tick, before the command was computed, raw.
    loop_y: Option<i16>,
    /// The speed loop's controller clamped its output.
    ctrl_clamped: bool,
}

/// A channel value in raw units, rounded and saturated to the 16-bit channel.
pub(super) fn sat(v: f64) -> i16 {
    v.round().clamp(-32767.0, 32767.0) as i16
}

/// The PRBS command of sample `k`, raw: the offset while settling, then offset +- amplitude
/// with the sequence's next bit every `clock_samples`, the sequence restarted every period.
fn prbs_command(lfsr: &mut Lfsr, p: &StartPrbs, bit: &mut bool, k: u32) -> f64 {
    if k < p.settle_samples {
        return p.offset as f64;
    }
    let j = k - p.settle_samples;
    if j.is_multiple_of(p.clock_samples as u32) {
        let b = j / p.clock_samples as u32;
        if (b as u64).is_multiple_of(lfsr.period()) {
            lfsr.restart();
        }
        *bit = lfsr.next_bit();
    }
    if *bit {
        p.offset as f64 + p.amplitude as f64
    } else {
        p.offset as f64 - p.amplitude as f64
    }
}

impl Firmware {
    /// Produce the samples due by now.
    pub(super) fn control(&mut self, now: Instant) {
        if self.c.is_some() {
            return self.c_control(now);
        }
        let Some(conf) = self.conf else { return };
        let Some(mut r) = self.run.take() else { return };
        let fs = conf.sample_rate_hz as f64;
        // Samples due by the wall clock; the planned run stops at `total`, a ramp-down may run on.
        let wall = (now.duration_since(r.start).as_secs_f64() * fs) as u64;
        let due = wall.min(r.total as u64);
        let keepalive = Duration::from_millis(conf.keepalive_ms as u64);
        let end = loop {
            if r.ramp.is_none() && now.duration_since(self.last_keepalive) > keepalive {
                let n = (fs * 0.05).ceil().max(1.0) as u32;
                r.ramp = Some((n, n, EndReason::Keepalive));
                self.fault = fault::KEEPALIVE;
                self.event(format!(
                    "keepalive expired at sample {}: ramping down",
                    r.done
                ));
            }
            if let Some((0, _, reason)) = r.ramp {
                break Some(reason);
            }
            // A ramp-down is paced like the run: one sample per sample period.
            if r.done as u64 >= if r.ramp.is_some() { wall } else { due } {
                break None;
            }
            let cmd = self.command(&mut r, &conf);
            if let Some(reason) = self.sample(&mut r, &conf, cmd) {
                break Some(reason);
            }
            if self.check_faults(now) {
                // reset: the run is gone
                return;
            }
        };
        self.run = Some(r);
        if let Some(reason) = end {
            self.end_run(reason);
        }
    }

    /// The command of the run's next sample: the ramp-down's, or the excitation's.
    fn command(&mut self, r: &mut Run, conf: &Configure) -> Command {
        let mut cmd = Command {
            u_raw: 0.0,
            phase: None,
            loop_y: None,
            ctrl_clamped: false,
        };
        if let Some((left, len, _)) = &mut r.ramp {
            *left -= 1;
            let v = r.last_u * (*left as f64) / (*len as f64);
            cmd.u_raw = (v / conf.u_lsb()).round();
            return cmd;
        }
        let k = r.done;
        match &mut r.exc {
            Excitation::Prbs { lfsr, p, bit } => cmd.u_raw = prbs_command(lfsr, p, bit, k),
            Excitation::Sine {
                s,
                phase,
                inc,
                settle,
                ..
            } => {
                // the firmware's Q30 sine table (as the C firmware): same samples
                cmd.u_raw = crate::cfw::sine_command_rs(*phase, s.amplitude, s.offset) as f64;
                let th = *phase as f64 / 4294967296.0 * std::f64::consts::TAU;
                cmd.phase = (k >= *settle).then_some(th);
                *phase = phase.wrapping_add(*inc);
            }
            Excitation::Loop { p, ctrl, z } => {
                let y = self
                    .plant
                    .as_mut()
                    .map_or(0.0, |pl| pl.measure(&mut self.rng));
                let y_raw = sat(y / conf.y_lsb());
                let e = p.reference(k as u64) as i32 - y_raw as i32;
                let (u, c) = ctrl.step(z, e, conf.u_limit);
                cmd.loop_y = Some(y_raw);
                cmd.ctrl_clamped = c;
                cmd.u_raw = u as f64;
            }
        }
        cmd
    }

    /// Apply one command: the limit, the motor, the channels, the sine's sums, the block; then
    /// the trips, a full block, the run's end. Returns why the run ends here, if it does.
    fn sample(&mut self, r: &mut Run, conf: &Configure, cmd: Command) -> Option<EndReason> {
        let lim = conf.u_limit as f64;
        let mut flags = 0;
        let u_raw = if cmd.u_raw.abs() > lim || cmd.ctrl_clamped {
            r.clamped = r.clamped.saturating_add(1);
            flags |= 1;
            cmd.u_raw.clamp(-lim, lim)
        } else {
            cmd.u_raw
        };
        let u = u_raw * conf.u_lsb();
        if r.ramp.is_none() {
            r.last_u = u;
        }
        let (y, i) = match self.plant.as_mut() {
            Some(p) => p.step(u, &mut self.rng),
            None => (0.0, 0.0),
        };
        let raw = [
            sat(u_raw),
            cmd.loop_y.unwrap_or_else(|| sat(y / conf.y_lsb())),
            sat(i / conf.i_lsb()),
        ];
        if let (
            Some(th),
            Excitation::Sine {
                acc,
                moments,
                settle,
                measure,
                ..
            },
        ) = (cmd.phase, &mut r.exc)
        {
            moments.add(r.done - *settle, *measure, raw[0], raw[1]);
            acc[0] += raw[0] as f64 * th.cos();
            acc[1] -= raw[0] as f64 * th.sin();
            acc[2] += raw[1] as f64 * th.cos();
            acc[3] -= raw[1] as f64 * th.sin();
        }
        if r.stream {
            if r.block.is_empty() {
                r.block_first = r.done;
            }
            r.block.push(raw);
            r.block_flags |= flags;
        }
        r.done += 1;
        self.run_samples_total += 1;
        self.with_stats(|s| {
            s.truth.push(raw);
            s.output = raw[0];
        });
        let speed_trip = raw[1].unsigned_abs() > conf.y_limit.unsigned_abs();
        let current_trip = raw[2].unsigned_abs() > conf.i_limit.unsigned_abs();
        if (speed_trip || current_trip) && r.ramp.is_none() {
            self.fault = if speed_trip {
                fault::SPEED_LIMIT
            } else {
                fault::CURRENT_LIMIT
            };
            self.flush_block(r);
            return Some(EndReason::Limit);
        }
        if r.block.len() >= conf.block_samples as usize {
            self.flush_block(r);
        }
        (r.done >= r.total && r.ramp.is_none()).then_some(EndReason::Complete)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prbs(settle: u32, clock: u16, order: u8) -> StartPrbs {
        StartPrbs {
            order,
            taps: crate::prbs::default_taps(order).expect("order in 2..=16"),
            seed: 1,
            clock_samples: clock,
            periods: 2,
            amplitude: 100,
            offset: 10,
            settle_samples: settle,
        }
    }

    #[test]
    fn sat_rounds_and_saturates_to_the_channel() {
        assert_eq!(sat(1.4), 1);
        assert_eq!(sat(-1.6), -2);
        assert_eq!(sat(1e9), 32767);
        assert_eq!(sat(-1e9), -32767);
    }

    #[test]
    fn prbs_command_holds_the_offset_then_each_bit_for_its_clock() {
        let p = prbs(5, 3, 4);
        let mut lfsr = Lfsr::new(p.order, p.taps, p.seed).expect("order 4");
        // the bits the LFSR gives on its own, one per clock period
        let mut twin = Lfsr::new(p.order, p.taps, p.seed).expect("order 4");
        let bits: Vec<bool> = (0..15).map(|_| twin.next_bit()).collect();
        let mut bit = false;
        let u: Vec<f64> = (0..5 + 3 * 15)
            .map(|k| prbs_command(&mut lfsr, &p, &mut bit, k))
            .collect();
        assert!(u[..5].iter().all(|&v| v == 10.0));
        for (j, &b) in bits.iter().enumerate() {
            let want = if b { 110.0 } else { -90.0 };
            assert_eq!(&u[5 + 3 * j..8 + 3 * j], &[want; 3], "bit {j}");
        }
    }

    #[test]
    fn prbs_command_repeats_the_sequence_every_period() {
        let p = prbs(0, 1, 4);
        let mut lfsr = Lfsr::new(p.order, p.taps, p.seed).expect("order 4");
        let n = lfsr.period() as u32;
        let mut bit = false;
        let u: Vec<f64> = (0..3 * n)
            .map(|k| prbs_command(&mut lfsr, &p, &mut bit, k))
            .collect();
        assert_eq!(u[..n as usize], u[n as usize..2 * n as usize]);
        assert_eq!(u[..n as usize], u[2 * n as usize..]);
    }
}
