//! The Rust firmware's command dispatch: frames decoded from the FIFO, answers, the replay
//! cache, each command's checks.

use super::run::Excitation;
use super::Firmware;
use crate::codec;
use crate::prbs::Lfsr;
use crate::protocol::spec::{FW_MAJOR, FW_MINOR};
use crate::protocol::*;
use crate::sim::plant::Plant;
use std::sync::atomic::Ordering;
use std::time::Instant;

impl Firmware {
    pub(super) fn service_fifo(&mut self, now: Instant) {
        if self.rx_fifo.is_empty() {
            return;
        }
        if self.c.is_some() {
            return self.c_service_fifo(now);
        }
        let bytes: Vec<u8> = self.rx_fifo.drain(..).collect();
        let before = self.dec.stats().errors;
        let frames = self.dec.push(&bytes);
        let errs = self.dec.stats().errors - before;
        if errs > 0 {
            self.rx_errors = self.rx_errors.saturating_add(errs as u16);
            self.with_stats(|s| s.rx_errors += errs);
        }
        for f in frames {
            self.with_stats(|s| s.frames_received += 1);
            self.handle(f, now);
        }
    }

    pub(super) fn reply(&mut self, seq: u16, msg: Message) -> Vec<u8> {
        let name = msg.name();
        let bytes = codec::encode(&Frame { seq, msg });
        self.push_answer(bytes.clone(), name, seq);
        bytes
    }

    /// Queue an answer ahead of DATA, unless it is to be lost ([`DriveSim::lose_next_answer`]).
    pub(super) fn push_answer(&mut self, bytes: Vec<u8>, name: &str, seq: u16) {
        if std::mem::take(&mut self.losing) {
            self.with_stats(|s| s.answers_lost += 1);
            self.event(format!("answer {name} (seq {seq}) lost on the line"));
        } else {
            self.tx_prio.push_back(bytes);
        }
    }

    pub(super) fn nak(&mut self, f: &Frame, code: NakCode, detail: u16) -> Vec<u8> {
        self.reply(
            f.seq,
            Message::Nak(Nak {
                nak_type: f.msg.type_code(),
                code,
                detail,
            }),
        )
    }

    pub(super) fn ack(&mut self, f: &Frame, run_id: u16, total_samples: u32) -> Vec<u8> {
        self.reply(
            f.seq,
            Message::Ack(Ack {
                acked_type: f.msg.type_code(),
                run_id,
                total_samples,
            }),
        )
    }

    pub(super) fn handle(&mut self, f: Frame, now: Instant) {
        let t = f.msg.type_code();
        let lose = 0x100 | t as u16;
        self.losing = self
            .lose_answer
            .compare_exchange(lose, 0, Ordering::Relaxed, Ordering::Relaxed)
            .is_ok();
        self.handle_command(f, now);
        self.losing = false;
    }

    pub(super) fn handle_command(&mut self, f: Frame, now: Instant) {
        let t = f.msg.type_code();
        match f.msg {
            Message::Keepalive(id) => {
                // Only a KEEPALIVE of the running run keeps it alive (PROTOCOL.md, section 7):
                // not any valid frame, such as another program's STATUS.
                if self.run.as_ref().is_some_and(|r| r.id == id) {
                    self.last_keepalive = now;
                    self.last_keepalive_wall = Instant::now();
                }
                return;
            }
            Message::Hello => {
                self.cache = None;
                let r = Message::HelloReply(HelloReply {
                    proto_version: PROTO_VERSION,
                    fw_major: FW_MAJOR,
                    fw_minor: FW_MINOR,
                    n_channels: N_CHANNELS as u8,
                    max_block_samples: MAX_BLOCK_SAMPLES,
                    boot_id: self.boot_id,
                    max_sample_rate_hz: self.cfg.max_sample_rate_hz,
                });
                self.reply(f.seq, r);
                return;
            }
            _ => {}
        }
        if t >= 0x80 {
            return; // drive-to-host types are ignored by the drive
        }
        if let Some((seq, ty, bytes)) = &self.cache {
            if *seq == f.seq && *ty == t {
                let b = bytes.clone();
                self.push_answer(b, "replay", f.seq);
                self.with_stats(|s| s.replays += 1);
                return;
            }
        }
        let answer = self.execute(&f, now);
        self.cache = Some((f.seq, t, answer));
    }

    pub(super) fn status(&self) -> StatusReply {
        let (state, run_id, done, dropped, clamped) = match (&self.run, self.last_run) {
            (Some(r), _) => (DriveState::Running, r.id, r.done, r.dropped, r.clamped),
            (None, Some((id, d, dr, c))) => (self.idle_state(), id, d, dr, c),
            (None, None) => (self.idle_state(), 0, 0, 0, 0),
        };
        StatusReply {
            state,
            fault: self.fault,
            run_id,
            samples_done: done,
            blocks_dropped: dropped,
            boot_id: self.boot_id,
            rx_errors: self.rx_errors,
            clamped,
        }
    }

    pub(super) fn idle_state(&self) -> DriveState {
        if self.fault != fault::NONE {
            DriveState::Fault
        } else if self.conf.is_some() {
            DriveState::Idle
        } else {
            DriveState::Unconfigured
        }
    }

    pub(super) fn execute(&mut self, f: &Frame, now: Instant) -> Vec<u8> {
        match &f.msg {
            Message::Status => {
                let s = self.status();
                self.reply(f.seq, Message::StatusReply(s))
            }
            Message::Configure(c) => {
                if self.run.is_some() {
                    return self.nak(f, NakCode::Busy, 0);
                }
                if let Some(off) = check_configure(c, self.cfg.max_sample_rate_hz) {
                    return self.nak(f, NakCode::BadValue, off);
                }
                match Plant::new(&self.cfg, c.sample_rate_hz) {
                    Ok(p) => self.plant = Some(p),
                    Err(_) => return self.nak(f, NakCode::BadValue, 0),
                }
                self.conf = Some(*c);
                self.fault = fault::NONE;
                // the controller's gains are in the channel units, its poles at the rate
                self.ctrl_load = None;
                self.ack(f, 0, 0)
            }
            Message::LoadCtrl(c) => self.load_ctrl(f, c),
            Message::LoadSection(c) => self.load_section(f, c),
            Message::StartLoop(l) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let ctrl = match &self.ctrl_load {
                    Some((h, s)) if s.len() == h.n_sections as usize + h.n_taps as usize => {
                        crate::ctrl::FixedCtrl::from_messages(h, s)
                    }
                    _ => return self.nak(f, NakCode::NoController, 0),
                };
                if l.pre_samples > l.total_samples {
                    return self.nak(f, NakCode::BadValue, off(ty::START_LOOP, "pre_samples"));
                }
                if l.total_samples == 0 {
                    return self.nak(f, NakCode::BadValue, off(ty::START_LOOP, "total_samples"));
                }
                let z = vec![0; ctrl.n_states()];
                let exc = Excitation::Loop { p: *l, ctrl, z };
                self.start_run(f, l.total_samples, exc, true, now)
            }
            Message::StartPrbs(p) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let Some(total) = p.total_samples() else {
                    return self.nak(f, NakCode::BadValue, off(ty::START_PRBS, "order"));
                };
                let Some(lfsr) = Lfsr::new(p.order, p.taps, p.seed) else {
                    return self.nak(f, NakCode::BadValue, off(ty::START_PRBS, "taps"));
                };
                if p.clock_samples == 0 || p.periods == 0 || p.amplitude < 0 || total == 0 {
                    return self.nak(f, NakCode::BadValue, off(ty::START_PRBS, "clock_samples"));
                }
                let exc = Excitation::Prbs {
                    lfsr,
                    p: *p,
                    bit: false,
                };
                self.start_run(f, total, exc, true, now)
            }
            Message::StartSine(s) => {
                if let Some(a) = self.start_check(f) {
                    return a;
                }
                let fs = self.conf.map(|c| c.sample_rate_hz).unwrap_or(1);
                let counts = s.sample_counts(fs);
                let bad = s.freq_mhz == 0
                    || s.freq_mhz as u64 > fs as u64 * 500
                    || s.amplitude < 0
                    || s.cycles == 0
                    || s.flags & (SINE_STREAM | SINE_DFT) == 0;
                let Some((settle, measure)) = counts.filter(|c| !bad && c.1 > 0) else {
                    return self.nak(f, NakCode::BadValue, off(ty::START_SINE, "freq_mhz"));
                };
                if s.flags & SINE_DFT != 0 && measure > MAX_DFT_SAMPLES {
                    return self.nak(f, NakCode::BadValue, off(ty::START_SINE, "cycles"));
                }
                let inc = (((s.freq_mhz as u128) << 32) + 500 * fs as u128) / (1000 * fs as u128);
                let exc = Excitation::Sine {
                    s: *s,
                    phase: 0,
                    inc: inc as u32,
                    settle,
                    measure,
                    acc: [0.0; 4],
                    moments: crate::bode::WindowSums::default(),
                };
                let stream = s.flags & SINE_STREAM != 0;
                self.start_run(f, settle + measure, exc, stream, now)
            }
            Message::Stop => {
                if let Some(r) = self.run.as_mut() {
                    if r.ramp.is_none() {
                        r.ramp = Some((1, 1, EndReason::Stopped));
                    }
                }
                self.ack(f, 0, 0)
            }
            Message::Estop => {
                if self.run.is_some() {
                    self.end_run(EndReason::Estop);
                }
                self.fault = fault::ESTOP;
                self.ack(f, 0, 0)
            }
            Message::EndQuery(id) => match self.last_end {
                Some(e) if e.run_id == *id && self.run.as_ref().is_none_or(|r| r.id != *id) => {
                    self.reply(f.seq, Message::StreamEnd(e))
                }
                _ => self.nak(f, NakCode::BadValue, 0),
            },
            _ => self.nak(f, NakCode::UnknownType, 0),
        }
    }

    pub(super) fn load_ctrl(&mut self, f: &Frame, c: &LoadCtrl) -> Vec<u8> {
        if self.run.is_some() {
            return self.nak(f, NakCode::Busy, 0);
        }
        if self.conf.is_none() {
            return self.nak(f, NakCode::NotConfigured, 0);
        }
        let (max_sections, max_taps) = match c.format {
            CTRL_FORMAT => (MAX_SECTIONS, 0),
            CTRL_FORMAT_TAPS => (MAX_SECTIONS_TAPS, MAX_TAPS),
            _ => return self.nak(f, NakCode::BadValue, off(ty::LOAD_CTRL, "format")),
        };
        if c.n_sections > max_sections {
            return self.nak(f, NakCode::BadValue, off(ty::LOAD_CTRL, "n_sections"));
        }
        if c.n_taps > max_taps {
            return self.nak(f, NakCode::BadValue, off(ty::LOAD_CTRL, "n_taps"));
        }
        self.ctrl_load = Some((*c, Vec::new()));
        self.ack(f, 0, 0)
    }

    pub(super) fn load_section(&mut self, f: &Frame, c: &LoadSection) -> Vec<u8> {
        if self.run.is_some() {
            return self.nak(f, NakCode::Busy, 0);
        }
        if self.conf.is_none() {
            return self.nak(f, NakCode::NotConfigured, 0);
        }
        let next = match &self.ctrl_load {
            Some((h, s)) if s.len() < h.n_sections as usize + h.n_taps as usize => {
                (s.len() as u8, s.len() >= h.n_sections as usize)
            }
            _ => return self.nak(f, NakCode::BadValue, 0),
        };
        if c.index != next.0 {
            return self.nak(f, NakCode::BadValue, off(ty::LOAD_SECTION, "index"));
        }
        // a pole within the unit circle; a tap's pole field 0
        if c.a_q30.unsigned_abs() > 1 << 30 || (next.1 && c.a_q30 != 0) {
            return self.nak(f, NakCode::BadValue, off(ty::LOAD_SECTION, "a_q30"));
        }
        if let Some((_, s)) = self.ctrl_load.as_mut() {
            s.push(*c);
        }
        self.ack(f, 0, 0)
    }

    pub(super) fn start_check(&mut self, f: &Frame) -> Option<Vec<u8>> {
        if self.run.is_some() {
            return Some(self.nak(f, NakCode::Busy, 0));
        }
        if self.fault != fault::NONE {
            let d = self.fault as u16;
            return Some(self.nak(f, NakCode::Fault, d));
        }
        if self.conf.is_none() {
            return Some(self.nak(f, NakCode::NotConfigured, 0));
        }
        None
    }
}

/// The payload offset of a field (the detail of a BAD_VALUE NAK), from the description of the
/// frames.
fn off(ty: u8, field: &str) -> u16 {
    crate::protocol::spec::message(ty)
        .and_then(|m| m.offset(field))
        .expect("a field of the table") as u16
}

/// Offset of the first invalid CONFIGURE field, if any.
pub(super) fn check_configure(c: &Configure, max_fs: u32) -> Option<u16> {
    if c.sample_rate_hz == 0 || c.sample_rate_hz > max_fs {
        return Some(off(ty::CONFIGURE, "sample_rate_hz"));
    }
    if c.block_samples == 0 || c.block_samples > MAX_BLOCK_SAMPLES {
        return Some(off(ty::CONFIGURE, "block_samples"));
    }
    if !(50..=5000).contains(&c.keepalive_ms) {
        return Some(off(ty::CONFIGURE, "keepalive_ms"));
    }
    if c.scale_u_uv == 0 {
        return Some(off(ty::CONFIGURE, "scale_u_uv"));
    }
    if c.scale_y_urad_s == 0 {
        return Some(off(ty::CONFIGURE, "scale_y_urad_s"));
    }
    if c.scale_i_ua == 0 {
        return Some(off(ty::CONFIGURE, "scale_i_ua"));
    }
    if c.u_limit <= 0 {
        return Some(off(ty::CONFIGURE, "u_limit"));
    }
    if c.y_limit <= 0 {
        return Some(off(ty::CONFIGURE, "y_limit"));
    }
    if c.i_limit <= 0 {
        return Some(off(ty::CONFIGURE, "i_limit"));
    }
    None
}
