//! The C drive firmware (`firmware/`, the fracfw library) linked into this crate.
//!
//! [`CEngine`] owns one `fw_t` and calls the library's entry points: octets in, octets out, and
//! the two halves of a sample. The simulator ([`crate::sim`] with
//! [`FirmwareKind::C`](crate::sim::FirmwareKind::C)) puts it behind the same pty, line model,
//! motor and fault injection as the Rust firmware, so `fracid drive` and the Python client can be
//! tested against the C code that runs on the F2812.

use std::os::raw::c_int;

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
struct FwCounters {
    frames_received: u32,
    replays: u32,
    runs_started: u32,
    blocks_dropped: u32,
    end_frames_lost: u32,
    configs: u32,
    keepalives: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
struct FwConfig {
    sample_rate_hz: u32,
    block_samples: u16,
    keepalive_ms: u16,
    scale_u_uv: u32,
    scale_y_urad_s: u32,
    scale_i_ua: u32,
    u_limit: i16,
    y_limit: i16,
    i_limit: i16,
}

/// `FW_MAX_SECTIONS` of `fracfw.h`.
const FW_MAX_SECTIONS: usize = 48;
/// `FW_MAX_TAPS` of `fracfw.h`.
const FW_MAX_TAPS: usize = 8;

/// `fw_ctrl` of `fracfw.h`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct FwCtrl {
    d_q24: i32,
    dinv_q16: i32,
    n: u16,
    loaded: u16,
    n_taps: u16,
    pad: u16,
    a_q30: [i32; FW_MAX_SECTIONS],
    g_q24: [i32; FW_MAX_SECTIONS],
    z: [i64; FW_MAX_SECTIONS],
    h_q24: [i32; FW_MAX_TAPS],
    w: [i32; FW_MAX_TAPS],
}

/// The C firmware's controller (`fw_ctrl_step`) run on `ctrl` from the states `z` (as
/// [`crate::ctrl::FixedCtrl::step`]: the sections', then the delay line; at most 48 sections and
/// 8 taps are used): the command, whether it was clamped, and the states after. For the
/// bit-identity tests against [`crate::ctrl::FixedCtrl::step`].
pub fn ctrl_step(
    ctrl: &crate::ctrl::FixedCtrl,
    z: &mut [i64],
    e: i32,
    u_limit: i16,
) -> (i16, bool) {
    let n = ctrl.sections.len().min(FW_MAX_SECTIONS);
    let m = ctrl.taps.len().min(FW_MAX_TAPS);
    let mut c = FwCtrl {
        d_q24: ctrl.d_q24,
        dinv_q16: ctrl.dinv_q16,
        n: n as u16,
        loaded: (n + m) as u16,
        n_taps: m as u16,
        pad: 0,
        a_q30: [0; FW_MAX_SECTIONS],
        g_q24: [0; FW_MAX_SECTIONS],
        z: [0; FW_MAX_SECTIONS],
        h_q24: [0; FW_MAX_TAPS],
        w: [0; FW_MAX_TAPS],
    };
    for (i, s) in ctrl.sections.iter().take(n).enumerate() {
        c.a_q30[i] = s.a_q30;
        c.g_q24[i] = s.g_q24;
        c.z[i] = z.get(i).copied().unwrap_or(0);
    }
    for (j, h) in ctrl.taps.iter().take(m).enumerate() {
        c.h_q24[j] = *h;
        c.w[j] = z.get(ctrl.sections.len() + j).copied().unwrap_or(0) as i32;
    }
    let mut cl = 0u16;
    // SAFETY: a valid fw_ctrl with n <= FW_MAX_SECTIONS, n_taps <= FW_MAX_TAPS, valid out
    // pointer.
    let u = unsafe { fw_ctrl_step(&mut c, e, u_limit, &mut cl) };
    for (zi, v) in z.iter_mut().zip(c.z.iter().take(n)) {
        *zi = *v;
    }
    for (j, v) in c.w.iter().take(m).enumerate() {
        if let Some(zi) = z.get_mut(ctrl.sections.len() + j) {
            *zi = *v as i64;
        }
    }
    (u, cl != 0)
}

// The fw_t is opaque here: a buffer of fw_sizeof() bytes, 8-byte aligned.
extern "C" {
    fn fw_sizeof() -> u32;
    fn fw_init(fw: *mut u64, boot_id: u16, max_sample_rate_hz: u32);
    fn fw_rx_octet(fw: *mut u64, octet: u16) -> u16;
    fn fw_tx_octet(fw: *mut u64) -> i32;
    fn fw_tx_busy(fw: *const u64) -> c_int;
    fn fw_sample_begin(fw: *mut u64, u_raw: *mut i16) -> c_int;
    fn fw_sample_end(fw: *mut u64, y_raw: i16, i_raw: i16);
    fn fw_running(fw: *const u64) -> c_int;
    fn fw_loop_running(fw: *const u64) -> c_int;
    fn fw_sample_measure(fw: *mut u64, y_raw: i16);
    fn fw_ctrl_step(c: *mut FwCtrl, e: i32, u_limit: i16, clamped: *mut u16) -> i16;
    fn fw_drop_last_answer(fw: *mut u64) -> c_int;
    fn fw_get_counters(fw: *const u64, out: *mut FwCounters);
    fn fw_get_config(fw: *const u64, out: *mut FwConfig);
    fn fw_rx_errors(fw: *const u64) -> u16;
    fn fw_run_id(fw: *const u64) -> u16;
    fn fw_sincos_q30(phase: u32, s: *mut i32, c: *mut i32);
    fn fw_sine_command(phase: u32, amplitude: i16, offset: i16) -> i32;
}

/// Counters of the C engine since its last init.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CCounters {
    /// Valid frames received.
    pub frames_received: u32,
    /// Commands answered from the replay cache.
    pub replays: u32,
    /// Runs started.
    pub runs_started: u32,
    /// DATA blocks dropped for lack of transmit room.
    pub blocks_dropped: u32,
    /// Accepted CONFIGUREs.
    pub configs: u32,
    /// KEEPALIVEs of the running run (each reset its keepalive timer).
    pub keepalives: u32,
}

/// The scaling and rate of the engine's active configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CConfig {
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Channel scales, micro-units per LSB: voltage, speed, current.
    pub scales: [u32; 3],
    /// Keepalive interval, ms (the engine counts it in samples).
    pub keepalive_ms: u16,
}

/// One instance of the C firmware's protocol engine.
#[derive(Debug)]
pub struct CEngine {
    mem: Vec<u64>,
}

impl CEngine {
    /// Power-up state: unconfigured, `boot_id`, accepting rates up to `max_sample_rate_hz`.
    pub fn new(boot_id: u16, max_sample_rate_hz: u32) -> Self {
        // SAFETY: fw_sizeof has no preconditions.
        let bytes = unsafe { fw_sizeof() } as usize;
        let mut e = Self {
            mem: vec![0u64; bytes.div_ceil(8)],
        };
        e.init(boot_id, max_sample_rate_hz);
        e
    }

    fn p(&mut self) -> *mut u64 {
        self.mem.as_mut_ptr()
    }

    fn cp(&self) -> *const u64 {
        self.mem.as_ptr()
    }

    /// Reset (a drive reset): everything lost, a new boot id.
    pub fn init(&mut self, boot_id: u16, max_sample_rate_hz: u32) {
        // SAFETY: mem holds fw_sizeof() bytes, 8-byte aligned (fw_t needs at most that).
        unsafe { fw_init(self.p(), boot_id, max_sample_rate_hz) }
    }

    /// One received octet; `Some(type)` when it completed a valid frame of that type.
    pub fn rx(&mut self, octet: u8) -> Option<u8> {
        // SAFETY: initialised engine.
        let r = unsafe { fw_rx_octet(self.p(), octet as u16) };
        (r & 0x100 != 0).then_some((r & 0xFF) as u8)
    }

    /// The next whole frame to transmit (with both delimiters), if any.
    pub fn tx_frame(&mut self) -> Option<Vec<u8>> {
        // SAFETY: initialised engine.
        let first = unsafe { fw_tx_octet(self.p()) };
        if first < 0 {
            return None;
        }
        let mut out = vec![first as u8];
        // SAFETY: as above.
        while unsafe { fw_tx_busy(self.cp()) } != 0 {
            let v = unsafe { fw_tx_octet(self.p()) };
            if v < 0 {
                break;
            }
            out.push(v as u8);
        }
        Some(out)
    }

    /// Start a sample: the clamped voltage command (raw) when a run is active.
    pub fn sample_begin(&mut self) -> Option<i16> {
        let mut u = 0i16;
        // SAFETY: initialised engine, valid out pointer.
        (unsafe { fw_sample_begin(self.p(), &mut u) } != 0).then_some(u)
    }

    /// Finish the sample with the measured speed and current (raw).
    pub fn sample_end(&mut self, y_raw: i16, i_raw: i16) {
        // SAFETY: initialised engine.
        unsafe { fw_sample_end(self.p(), y_raw, i_raw) }
    }

    /// Whether a run is active.
    pub fn running(&self) -> bool {
        // SAFETY: initialised engine.
        unsafe { fw_running(self.cp()) != 0 }
    }

    /// Whether a loop run is active (the speed must be given before each sample).
    pub fn loop_running(&self) -> bool {
        // SAFETY: initialised engine.
        unsafe { fw_loop_running(self.cp()) != 0 }
    }

    /// The speed measured at this sample's tick (raw), before [`CEngine::sample_begin`].
    pub fn sample_measure(&mut self, y_raw: i16) {
        // SAFETY: initialised engine.
        unsafe { fw_sample_measure(self.p(), y_raw) }
    }

    /// Discard the newest queued answer (it stays cached for a replay). True if one was.
    pub fn drop_last_answer(&mut self) -> bool {
        // SAFETY: initialised engine.
        unsafe { fw_drop_last_answer(self.p()) != 0 }
    }

    /// The engine's counters.
    pub fn counters(&self) -> CCounters {
        let mut c = FwCounters::default();
        // SAFETY: initialised engine, valid out pointer of the C layout.
        unsafe { fw_get_counters(self.cp(), &mut c) };
        CCounters {
            frames_received: c.frames_received,
            replays: c.replays,
            runs_started: c.runs_started,
            blocks_dropped: c.blocks_dropped,
            configs: c.configs,
            keepalives: c.keepalives,
        }
    }

    /// The active configuration, if any.
    pub fn config(&self) -> Option<CConfig> {
        let mut c = FwConfig::default();
        // SAFETY: initialised engine, valid out pointer of the C layout.
        unsafe { fw_get_config(self.cp(), &mut c) };
        (c.sample_rate_hz != 0).then_some(CConfig {
            sample_rate_hz: c.sample_rate_hz,
            scales: [c.scale_u_uv, c.scale_y_urad_s, c.scale_i_ua],
            keepalive_ms: c.keepalive_ms,
        })
    }

    /// Frames discarded since boot (saturating).
    pub fn rx_errors(&self) -> u16 {
        // SAFETY: initialised engine.
        unsafe { fw_rx_errors(self.cp()) }
    }

    /// The current or last run id (0: none).
    pub fn run_id(&self) -> u16 {
        // SAFETY: initialised engine.
        unsafe { fw_run_id(self.cp()) }
    }
}

/// The firmware's Q30 `(sin, cos)` of `2 pi phase / 2^32` (for tests against the Rust copy).
pub fn sincos_q30(phase: u32) -> (i32, i32) {
    let (mut s, mut c) = (0, 0);
    // SAFETY: pure function, valid out pointers.
    unsafe { fw_sincos_q30(phase, &mut s, &mut c) };
    (s, c)
}

/// The firmware's sine command `offset + round(amplitude sin(2 pi phase / 2^32))`.
pub fn sine_command(phase: u32, amplitude: i16, offset: i16) -> i32 {
    // SAFETY: pure function.
    unsafe { fw_sine_command(phase, amplitude, offset) }
}

/// `sin(2 pi i / 1024)` in Q30, rounded: the firmware's table (`firmware/src/fw_sine_table.h`),
/// recomputed; [`tests`] check it is bit-identical to the C one.
fn sine_table() -> &'static [i32; 1024] {
    static T: std::sync::OnceLock<[i32; 1024]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        std::array::from_fn(|i| {
            ((i as f64 * std::f64::consts::TAU / 1024.0).sin() * 1073741824.0).round() as i32
        })
    })
}

/// Rust copy of the firmware's `fw_sincos_q30`: table value at the top 10 phase bits, corrected
/// to second order in the remainder `d`: `sin(a+d) = sin a (1 - d^2/2) + cos a d` (error below
/// 1e-7). Bit-identical to the C function (tested).
pub fn sincos_q30_rs(phase: u32) -> (i32, i32) {
    const TWO_PI_Q29: u64 = 3373259426;
    let t = sine_table();
    let i = (phase >> 22) as usize;
    let rem = (phase & 0x3F_FFFF) as u64;
    let d = ((rem * TWO_PI_Q29) >> 31) as i64;
    let d2h = (d * d) >> 31;
    let s0 = t[i] as i64;
    let c0 = t[(i + 256) & 1023] as i64;
    let s = s0 - ((s0 * d2h) >> 30) + ((c0 * d) >> 30);
    let c = c0 - ((c0 * d2h) >> 30) - ((s0 * d) >> 30);
    (s as i32, c as i32)
}

/// Rust copy of the firmware's sine command: `offset + round(amplitude sin)` with the Q30 sine,
/// rounding half away from zero. The simulator's Rust firmware uses it so that both firmwares
/// produce the same samples.
pub fn sine_command_rs(phase: u32, amplitude: i16, offset: i16) -> i32 {
    let (s, _) = sincos_q30_rs(phase);
    let p = amplitude as i64 * s as i64;
    let r = if p >= 0 {
        (p + (1 << 29)) >> 30
    } else {
        -((-p + (1 << 29)) >> 30)
    };
    offset as i32 + r as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rust_sine_is_the_firmware_sine() {
        let mut ph = 0u32;
        for k in 0..200_000u32 {
            assert_eq!(sincos_q30_rs(ph), sincos_q30(ph), "phase {ph:#x}");
            let (a, o) = ((k % 32768) as i16, (k % 7000) as i16 - 3500);
            assert_eq!(sine_command_rs(ph, a, o), sine_command(ph, a, o));
            ph = ph.wrapping_add(0x0001_5F3B).wrapping_add(k);
        }
        for i in 0..1024u32 {
            assert_eq!(
                sincos_q30_rs(i << 22),
                sincos_q30(i << 22),
                "table entry {i}"
            );
            let (s, c) = sincos_q30(i << 22);
            let th = i as f64 * std::f64::consts::TAU / 1024.0;
            assert!((s as f64 / 1073741824.0 - th.sin()).abs() < 1e-9);
            assert!((c as f64 / 1073741824.0 - th.cos()).abs() < 1e-9);
        }
    }

    #[test]
    fn engine_answers_hello() {
        // HELLO seq 1 and HELLO_REPLY (boot 0xBEEF, 20 kHz) from testvectors/frames.txt
        let mut e = CEngine::new(0xBEEF, 20_000);
        let hello = [0x00, 0x04, 0x03, 0x01, 0x01, 0x03, 0xE8, 0x65, 0x00];
        let got: Vec<_> = hello.iter().filter_map(|&b| e.rx(b)).collect();
        assert_eq!(got, [0x01]);
        let want = [
            0x00, 0x04, 0x03, 0x81, 0x01, 0x06, 0x03, 0x01, 0x03, 0x03, 0x42, 0x05, 0xEF, 0xBE,
            0x20, 0x4E, 0x01, 0x03, 0xD5, 0xC4, 0x00,
        ];
        assert_eq!(e.tx_frame().as_deref(), Some(&want[..]));
        assert_eq!(e.tx_frame(), None);
        assert!(e.config().is_none() && !e.running());
    }
}
