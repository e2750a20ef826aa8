//! The serial line: baud-rate pacing both ways, the receive FIFO, line faults, the link state.

use super::vtime::VIRTUAL_QUIET_READ;
use super::Firmware;
use crate::sim::pty::{open_pty, retarget_link, watch_pty};
use crate::sim::SimClock;
use rand::Rng;
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::time::Instant;

impl Firmware {
    pub(super) fn byte_rate(&self) -> f64 {
        self.cfg.baud as f64 / 10.0
    }

    pub(super) fn line_state(&mut self, now: Instant) {
        if let Some(t) = self.stall_until {
            if now >= t {
                self.stall_until = None;
                self.event("stall ends".into());
            }
        }
        if let Some(t) = self.dead_until {
            if now >= t {
                self.dead_until = None;
                self.event("line back".into());
            }
        }
        if let Some(t) = self.reopen_at {
            if now >= t {
                self.reopen_at = None;
                match (open_pty(), &self.cfg.link) {
                    (Ok((m, name)), Some(link)) => {
                        if self.cfg.clock == SimClock::Virtual {
                            self.slave = watch_pty(&m, &name).ok();
                            self.unread_settled = false;
                        }
                        if retarget_link(link, &name).is_ok() {
                            self.master = Some(m);
                            self.event(format!("reconnected as {name}"));
                        }
                    }
                    _ => self.event("reconnect failed".into()),
                }
            }
        }
    }

    pub(super) fn drain_input_lost(&mut self) {
        if let Some(m) = self.master.as_mut() {
            let mut buf = [0u8; 512];
            let _ = m.read(&mut buf);
        }
    }

    /// Read what the host sent, pace it to the line rate, pass it through the FIFO model.
    pub(super) fn receive(&mut self, elapsed: f64, now: Instant) {
        let mut buf = [0u8; 1024];
        let virtual_time = self.cfg.clock == SimClock::Virtual;
        if virtual_time && self.line_quiet() && self.quiet_steps < VIRTUAL_QUIET_READ {
            // Nothing on the line either way: the master is read every few steps only.
            self.quiet_steps += 1;
        } else if let Some(m) = self.master.as_mut() {
            self.quiet_steps = 0;
            let got = if virtual_time {
                // The master is non-blocking in virtual time: one read, no poll first.
                // SAFETY: reads into a valid buffer of `buf.len()` bytes from a descriptor we own.
                let n = unsafe { libc::read(m.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
                usize::try_from(n).map_err(|_| std::io::Error::last_os_error())
            } else {
                m.read(&mut buf)
            };
            match got {
                Ok(n) if n > 0 => {
                    let dead = self.dead_until.is_some();
                    if !dead {
                        for &b in &buf[..n] {
                            self.rx_pending.push_back(b);
                        }
                    }
                }
                _ => {}
            }
        }
        // Bytes arrive at the line rate.
        self.rx_budget = (self.rx_budget + elapsed * self.byte_rate()).min(4096.0);
        let stalled = self.stall_until.is_some();
        while self.rx_budget >= 1.0 {
            let Some(mut b) = self.rx_pending.pop_front() else {
                self.rx_budget = self.rx_budget.min(1.0);
                break;
            };
            self.rx_budget -= 1.0;
            // Line faults, host -> drive.
            let f = self.cfg.faults;
            if f.drop_rate > 0.0 && self.rng.gen_bool(f.drop_rate.min(1.0)) {
                continue;
            }
            b = self.flip_bits(b);
            if self.rx_fifo.len() < self.cfg.rx_fifo.max(1) {
                self.rx_fifo.push_back(b);
            } else {
                self.with_stats(|s| s.rx_overruns += 1);
            }
            if !stalled {
                self.service_fifo(now);
            }
        }
        if !stalled {
            self.service_fifo(now);
        }
    }

    pub(super) fn flip_bits(&mut self, mut b: u8) -> u8 {
        let ber = self.cfg.faults.bit_error_rate;
        if ber > 0.0 {
            let p_byte = 1.0 - (1.0 - ber.min(1.0)).powi(8);
            if self.rng.gen_bool(p_byte) {
                b ^= 1 << self.rng.gen_range(0..8);
            }
        }
        b
    }

    /// Send bytes at the line rate; responses go before queued DATA.
    pub(super) fn transmit(&mut self, elapsed: f64, _now: Instant) {
        if self.stall_until.is_some() {
            return;
        }
        self.tx_budget =
            (self.tx_budget + elapsed * self.byte_rate()).min(self.byte_rate() * 0.01 + 64.0);
        let mut out = Vec::new();
        while self.tx_budget >= 1.0 {
            if self.tx_bytes.is_empty() {
                let next = match self.c.as_mut() {
                    Some(c) => c.eng.tx_frame(),
                    None => self
                        .tx_prio
                        .pop_front()
                        .or_else(|| self.tx_data.pop_front()),
                };
                let Some(frame) = next else {
                    self.tx_budget = self.tx_budget.min(1.0);
                    break;
                };
                let damaged = self.damage_frame(frame);
                self.tx_bytes.extend(damaged);
            }
            if let Some(b) = self.tx_bytes.pop_front() {
                out.push(b);
                self.tx_budget -= 1.0;
            }
        }
        if out.is_empty() {
            return;
        }
        let n = out.len() as u64;
        self.with_stats(|s| s.bytes_sent += n);
        if self.dead_until.is_some() {
            return;
        }
        if self.cfg.clock == SimClock::Virtual {
            // What the pty cannot take now waits (the clock waits with it).
            self.out_backlog.extend(out);
            self.flush_out();
        } else if let Some(m) = self.master.as_mut() {
            // A full pty buffer or an absent host loses the bytes, as a real line would.
            let _ = m.write_all(&out);
        }
    }

    /// Apply line faults to one outgoing frame.
    pub(super) fn damage_frame(&mut self, frame: Vec<u8>) -> Vec<u8> {
        let f = self.cfg.faults;
        let mut out = Vec::with_capacity(frame.len());
        let mut damaged = false;
        for b in frame {
            if self.burst_left > 0 {
                self.burst_left -= 1;
                out.push(self.rng.gen());
                damaged = true;
                continue;
            }
            if f.burst_rate > 0.0 && self.rng.gen_bool(f.burst_rate.min(1.0)) {
                self.burst_left = f.burst_len.max(1);
            }
            if f.drop_rate > 0.0 && self.rng.gen_bool(f.drop_rate.min(1.0)) {
                damaged = true;
                continue;
            }
            let c = self.flip_bits(b);
            damaged |= c != b;
            out.push(c);
        }
        if f.frame_corrupt_rate > 0.0
            && !out.is_empty()
            && self.rng.gen_bool(f.frame_corrupt_rate.min(1.0))
        {
            let flips = self.rng.gen_range(1..=3);
            for _ in 0..flips {
                let i = self.rng.gen_range(0..out.len());
                out[i] ^= 1 << self.rng.gen_range(0..8);
            }
            damaged = true;
        }
        self.with_stats(|s| {
            s.frames_sent += 1;
            if damaged {
                s.frames_damaged += 1;
            }
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::pty::open_pty;
    use crate::sim::{SimConfig, SimStats};
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    fn firmware(baud: u32) -> (Firmware, Arc<Mutex<SimStats>>) {
        let (master, _slave) = open_pty().expect("pty");
        let stats = Arc::new(Mutex::new(SimStats::default()));
        let cfg = SimConfig {
            baud,
            ..SimConfig::default()
        };
        let fw = Firmware::new(cfg, master, stats.clone()).expect("firmware");
        (fw, stats)
    }

    #[test]
    fn transmit_sends_at_the_baud_rate_and_bursts_at_most_10_ms_plus_64_bytes() {
        // 9600 baud, 8N1: 960 bytes/s
        let (mut fw, stats) = firmware(9600);
        fw.tx_prio.push_back(vec![0x55; 400]);
        let now = Instant::now();
        fw.transmit(0.010, now);
        assert_eq!(stats.lock().unwrap().bytes_sent, 9); // 9.6 bytes due
        fw.transmit(0.100, now);
        // 0.6 + 96 due, but the budget holds at most 10 ms of line time plus 64 bytes: 73.6
        assert_eq!(stats.lock().unwrap().bytes_sent, 9 + 73);
        assert_eq!(stats.lock().unwrap().frames_sent, 1);
    }

    #[test]
    fn a_stalled_drive_overruns_its_receive_fifo_at_the_line_rate() {
        let (mut fw, stats) = firmware(9600);
        let now = Instant::now();
        fw.stall_until = Some(now + Duration::from_secs(1));
        fw.rx_pending.extend([0x11; 100]);
        // 50 ms at 960 bytes/s: 48 bytes arrive, the 16-byte FIFO keeps 16
        fw.receive(0.050, now);
        assert_eq!(fw.rx_fifo.len(), 16);
        assert_eq!(stats.lock().unwrap().rx_overruns, 48 - 16);
        assert_eq!(fw.rx_pending.len(), 100 - 48);
    }

    #[test]
    fn bit_flips_change_one_bit_per_damaged_byte_at_the_rate_asked() {
        let (mut fw, _) = firmware(9600);
        fw.cfg.faults.bit_error_rate = 0.01;
        let n = 20_000;
        let flipped: Vec<u32> = (0..n).map(|_| fw.flip_bits(0).count_ones()).collect();
        assert!(flipped.iter().all(|&c| c <= 1));
        let hits = flipped.iter().filter(|&&c| c == 1).count() as f64;
        // P(byte damaged) = 1 - 0.99^8 = 0.0773; sd of the count sqrt(n p (1-p)) = 38
        let want = n as f64 * (1.0 - 0.99f64.powi(8));
        assert!((hits - want).abs() < 5.0 * 38.0, "{hits} vs {want}");
    }
}
