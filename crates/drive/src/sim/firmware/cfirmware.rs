//! The C firmware of `firmware/` behind the line model ([`crate::sim::FirmwareKind::C`]).

use super::Firmware;
use crate::sim::plant::Plant;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// The C engine and what the simulator tracks around it.
pub(super) struct CState {
    pub(super) eng: crate::cfw::CEngine,
    /// Wall-clock start of the current run and the samples produced in it.
    pub(super) start: Instant,
    pub(super) ticks: u64,
    /// Counters already added to [`SimStats`].
    pub(super) seen: crate::cfw::CCounters,
    pub(super) seen_rx_errors: u16,
}

/// The C firmware behind the line model ([`FirmwareKind::C`]).
impl Firmware {
    /// Feed the receive FIFO to the C engine; mirror its events into the stats and the plant.
    pub(super) fn c_service_fifo(&mut self, now: Instant) {
        let bytes: Vec<u8> = self.rx_fifo.drain(..).collect();
        let Some(mut c) = self.c.take() else { return };
        for b in bytes {
            let Some(t) = c.eng.rx(b) else { continue };
            self.with_stats(|s| s.frames_received += 1);
            let lose = 0x100 | t as u16;
            if self
                .lose_answer
                .compare_exchange(lose, 0, Ordering::Relaxed, Ordering::Relaxed)
                .is_ok()
                && c.eng.drop_last_answer()
            {
                self.with_stats(|s| s.answers_lost += 1);
                self.event(format!("answer to type {t:#04x} lost on the line"));
            }
            let k = c.eng.counters();
            if k.keepalives != c.seen.keepalives || k.runs_started != c.seen.runs_started {
                // the engine's keepalive timer was reset (a KEEPALIVE of its run, a START)
                self.last_keepalive = now;
                self.last_keepalive_wall = Instant::now();
            }
            if k.configs != c.seen.configs {
                // a CONFIGURE was accepted: a motor at its sample rate
                self.plant = c
                    .eng
                    .config()
                    .and_then(|cc| Plant::new(&self.cfg, cc.sample_rate_hz).ok());
            }
            if k.runs_started != c.seen.runs_started {
                if let Some(p) = self.plant.as_mut() {
                    p.reset();
                }
                c.start = now;
                c.ticks = 0;
                let id = c.eng.run_id();
                self.with_stats(|s| {
                    s.truth.clear();
                    s.truth_run_id = id;
                });
                self.event(format!("run {id} started (C firmware)"));
            }
            self.c_sync(&mut c, k);
        }
        self.c = Some(c);
    }

    /// Add the C engine's counter increments to the stats.
    pub(super) fn c_sync(&mut self, c: &mut CState, k: crate::cfw::CCounters) {
        let e = c.eng.rx_errors();
        let d_err = e.wrapping_sub(c.seen_rx_errors) as u64;
        self.rx_errors = e;
        let s0 = c.seen;
        self.with_stats(|s| {
            s.rx_errors += d_err;
            s.replays += (k.replays - s0.replays) as u64;
            s.runs_started += (k.runs_started - s0.runs_started) as u64;
            s.blocks_dropped += (k.blocks_dropped - s0.blocks_dropped) as u64;
        });
        c.seen = k;
        c.seen_rx_errors = e;
    }

    /// Run the C engine's samples due by the wall clock, with the simulator's motor.
    pub(super) fn c_control(&mut self, now: Instant) {
        let Some(mut c) = self.c.take() else { return };
        let mut reset = false;
        if let (Some(cc), true) = (c.eng.config(), c.eng.running()) {
            let fs = cc.sample_rate_hz as f64;
            let lsb = cc.scales.map(|v| v as f64 * 1e-6);
            let mut wall = (now.duration_since(c.start).as_secs_f64() * fs) as u64;
            // This thread can fall behind the wall clock on a loaded machine; a real drive does
            // not (its sample and receive interrupts interleave). Catching up a long backlog at
            // once would run its samples without the frames that arrived meanwhile, and the C
            // engine, which counts its keepalive in samples, would expire. So a backlog beyond
            // 20 ms is dropped: the run goes on later, the same sample for sample.
            let max_behind = (fs / 50.0).ceil() as u64;
            if wall > c.ticks + max_behind {
                let skip = wall - c.ticks - max_behind;
                c.start += Duration::from_secs_f64(skip as f64 / fs);
                wall = c.ticks + max_behind;
            }
            let sat = |v: f64| v.round().clamp(-32767.0, 32767.0) as i16;
            while c.ticks < wall {
                // a loop run: the speed at the tick, before the command
                let loop_y = c.eng.loop_running().then(|| {
                    let y = self
                        .plant
                        .as_mut()
                        .map_or(0.0, |p| p.measure(&mut self.rng));
                    let y_raw = sat(y / lsb[1]);
                    c.eng.sample_measure(y_raw);
                    y_raw
                });
                let Some(u_raw) = c.eng.sample_begin() else {
                    break;
                };
                let (y, i) = match self.plant.as_mut() {
                    Some(p) => p.step(u_raw as f64 * lsb[0], &mut self.rng),
                    None => (0.0, 0.0),
                };
                let raw = [
                    u_raw,
                    loop_y.unwrap_or_else(|| sat(y / lsb[1])),
                    sat(i / lsb[2]),
                ];
                c.eng.sample_end(raw[1], raw[2]);
                c.ticks += 1;
                self.run_samples_total += 1;
                self.with_stats(|s| {
                    s.truth.push(raw);
                    s.output = raw[0];
                });
                if self.check_faults(now) {
                    reset = true;
                    break;
                }
            }
        }
        if !reset && !c.eng.running() {
            self.with_stats(|s| s.output = 0);
        }
        let k = c.eng.counters();
        self.c_sync(&mut c, k);
        if reset {
            // Firmware::reset re-initialised self.c, which is taken: do it here.
            c.eng.init(self.boot_id, self.cfg.max_sample_rate_hz);
            c.seen = Default::default();
            c.seen_rx_errors = 0;
        }
        self.c = Some(c);
    }
}
