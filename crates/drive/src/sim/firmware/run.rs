//! A run of the Rust firmware: its excitation, start, DATA blocks and end.

use super::Firmware;
use crate::codec;
use crate::prbs::Lfsr;
use crate::protocol::*;
use std::time::Instant;

pub(super) enum Excitation {
    Prbs {
        lfsr: Lfsr,
        p: StartPrbs,
        bit: bool,
    },
    Sine {
        s: StartSine,
        phase: u32,
        inc: u32,
        settle: u32,
        measure: u32,
        acc: [f64; 4],
        /// Level and ramp sums of u and y (exact integers, as the C firmware's).
        moments: crate::bode::WindowSums,
    },
    /// The speed loop: the reference step and the controller with its states.
    Loop {
        p: StartLoop,
        ctrl: crate::ctrl::FixedCtrl,
        z: Vec<i64>,
    },
}

pub(super) struct Run {
    pub(super) id: u16,
    pub(super) total: u32,
    pub(super) done: u32,
    pub(super) sent: u32,
    pub(super) dropped: u16,
    pub(super) clamped: u16,
    pub(super) start: Instant,
    pub(super) block: Vec<[i16; 3]>,
    pub(super) block_first: u32,
    pub(super) block_flags: u8,
    pub(super) exc: Excitation,
    /// Streams DATA blocks (always for PRBS; START_SINE flag bit 0).
    pub(super) stream: bool,
    pub(super) ramp: Option<(u32, u32, EndReason)>, // (samples left, ramp length, reason)
    pub(super) last_u: f64,
}

impl Firmware {
    pub(super) fn start_run(
        &mut self,
        f: &Frame,
        total: u32,
        exc: Excitation,
        stream: bool,
        now: Instant,
    ) -> Vec<u8> {
        let id = self.next_run_id;
        self.next_run_id = self.next_run_id.wrapping_add(1).max(1);
        if let Some(p) = self.plant.as_mut() {
            p.reset();
        }
        self.run = Some(Run {
            id,
            total,
            done: 0,
            sent: 0,
            dropped: 0,
            clamped: 0,
            start: now,
            block: Vec::new(),
            block_first: 0,
            block_flags: 0,
            exc,
            stream,
            ramp: None,
            last_u: 0.0,
        });
        self.last_end = None;
        self.last_keepalive = now;
        self.last_keepalive_wall = Instant::now();
        self.with_stats(|s| {
            s.runs_started += 1;
            s.truth.clear();
            s.truth_run_id = id;
        });
        self.event(format!("run {id} started, {total} samples"));
        self.ack(f, id, total)
    }

    pub(super) fn next_tx_seq(&mut self) -> u16 {
        self.tx_seq = self.tx_seq.wrapping_add(1);
        self.tx_seq
    }

    pub(super) fn end_run(&mut self, reason: EndReason) {
        let Some(mut r) = self.run.take() else { return };
        // The inverter is off from here on.
        self.with_stats(|s| s.output = 0);
        self.flush_block(&mut r);
        if let Excitation::Sine {
            acc,
            measure,
            s,
            moments,
            ..
        } = &r.exc
        {
            if s.flags & SINE_DFT != 0 && reason == EndReason::Complete {
                let n = *measure as f64;
                let q = |v: f64| {
                    (v * 2.0 / n * 256.0)
                        .round()
                        .clamp(i32::MIN as f64, i32::MAX as f64) as i32
                };
                let res = SineResult {
                    run_id: r.id,
                    n: *measure,
                    u_re: q(acc[0]),
                    u_im: q(acc[1]),
                    y_re: q(acc[2]),
                    y_im: q(acc[3]),
                    u_mean: crate::bode::q8_mean(moments.level[0], *measure),
                    u_ramp: crate::bode::q8_ramp(moments.ramp[0], *measure),
                    y_mean: crate::bode::q8_mean(moments.level[1], *measure),
                    y_ramp: crate::bode::q8_ramp(moments.ramp[1], *measure),
                };
                let seq = self.next_tx_seq();
                self.tx_data.push_back(codec::encode(&Frame {
                    seq,
                    msg: Message::SineResult(res),
                }));
            }
        }
        let end = StreamEnd {
            run_id: r.id,
            reason,
            total_samples: r.done,
            samples_sent: r.sent,
            blocks_dropped: r.dropped,
        };
        let seq = self.next_tx_seq();
        // STREAM_END always fits: it goes behind the queued DATA, never dropped.
        self.tx_data.push_back(codec::encode(&Frame {
            seq,
            msg: Message::StreamEnd(end),
        }));
        self.last_end = Some(end);
        self.last_run = Some((r.id, r.done, r.dropped, r.clamped));
        self.event(format!(
            "run {} ended: {reason:?}, {} samples, {} blocks dropped",
            r.id, r.done, r.dropped
        ));
    }

    pub(super) fn flush_block(&mut self, r: &mut Run) {
        if r.block.is_empty() {
            return;
        }
        let samples = std::mem::take(&mut r.block);
        let n = samples.len() as u32;
        if self.tx_data.len() >= self.cfg.tx_blocks.max(1) {
            r.dropped = r.dropped.saturating_add(1);
            self.with_stats(|s| s.blocks_dropped += 1);
        } else {
            let seq = self.next_tx_seq();
            let msg = Message::Data(DataBlock {
                run_id: r.id,
                first_index: r.block_first,
                flags: r.block_flags,
                samples,
            });
            self.tx_data.push_back(codec::encode(&Frame { seq, msg }));
            r.sent += n;
        }
        r.block_flags = 0;
    }
}
