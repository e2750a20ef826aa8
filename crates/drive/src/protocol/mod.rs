//! Messages and their payload layouts (see the crate docs, section 3). No I/O, no framing: the
//! [`codec`](crate::codec) wraps a [`Frame`] into bytes. The layouts are described once, in
//! [`spec`], which this codec is checked against and the C firmware's header is generated from.

pub mod spec;

use spec::{end, nak, state};

pub use spec::{
    fault, ty, CTRL_FORMAT, CTRL_FORMAT_TAPS, MAX_BLOCK_SAMPLES, MAX_DFT_SAMPLES, MAX_SECTIONS,
    MAX_SECTIONS_TAPS, MAX_TAPS, N_CHANNELS, PROTO_VERSION, SINE_DFT, SINE_STREAM,
};

/// The earlier protocol versions a host probes with when a drive does not answer HELLO, to tell
/// a drive of another version ([`crate::Error::Version`]) from a silent one.
pub const OLDER_VERSIONS: [u8; 2] = [2, 1];

/// HELLO_REPLY payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HelloReply {
    /// Protocol version the drive speaks.
    pub proto_version: u8,
    /// Firmware major version.
    pub fw_major: u8,
    /// Firmware minor version.
    pub fw_minor: u8,
    /// Channels per sample (3).
    pub n_channels: u8,
    /// Largest DATA block the drive sends.
    pub max_block_samples: u8,
    /// Random id drawn at power-up; changes on every reset.
    pub boot_id: u16,
    /// Highest sample rate the drive accepts, Hz.
    pub max_sample_rate_hz: u32,
}

/// CONFIGURE payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Configure {
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Samples per DATA block.
    pub block_samples: u8,
    /// Keepalive timeout, ms.
    pub keepalive_ms: u16,
    /// Voltage channel scale, microvolts per LSB.
    pub scale_u_uv: u32,
    /// Speed channel scale, micro-rad/s per LSB.
    pub scale_y_urad_s: u32,
    /// Current channel scale, microamperes per LSB.
    pub scale_i_ua: u32,
    /// Voltage clamp, raw.
    pub u_limit: i16,
    /// Speed trip, raw.
    pub y_limit: i16,
    /// Current trip, raw.
    pub i_limit: i16,
}

impl Default for Configure {
    /// 1 kHz, 32-sample blocks, 500 ms keepalive, 1 mV / 10 mrad/s / 1 mA per LSB, limits 24 V,
    /// 300 rad/s, 30 A.
    fn default() -> Self {
        Self {
            sample_rate_hz: 1000,
            block_samples: 32,
            keepalive_ms: 500,
            scale_u_uv: 1000,
            scale_y_urad_s: 10_000,
            scale_i_ua: 1000,
            u_limit: 24_000,
            y_limit: 30_000,
            i_limit: 30_000,
        }
    }
}

impl Configure {
    /// Voltage per LSB, V.
    pub fn u_lsb(&self) -> f64 {
        self.scale_u_uv as f64 * 1e-6
    }
    /// Speed per LSB, rad/s.
    pub fn y_lsb(&self) -> f64 {
        self.scale_y_urad_s as f64 * 1e-6
    }
    /// Current per LSB, A.
    pub fn i_lsb(&self) -> f64 {
        self.scale_i_ua as f64 * 1e-6
    }
}

/// START_PRBS payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StartPrbs {
    /// LFSR length, 2..=31.
    pub order: u8,
    /// Feedback mask.
    pub taps: u32,
    /// Initial LFSR state, nonzero.
    pub seed: u32,
    /// Samples per PRBS bit.
    pub clock_samples: u16,
    /// Amplitude, raw.
    pub amplitude: i16,
    /// Offset, raw.
    pub offset: i16,
    /// Number of periods.
    pub periods: u16,
    /// Samples at the offset before the first bit.
    pub settle_samples: u32,
}

impl StartPrbs {
    /// Total samples of the run, or None if it overflows u32 or the order is out of range.
    pub fn total_samples(&self) -> Option<u32> {
        if !(2..=31).contains(&self.order) {
            return None;
        }
        let period = (1u64 << self.order) - 1;
        let n =
            self.settle_samples as u64 + self.periods as u64 * period * self.clock_samples as u64;
        u32::try_from(n).ok()
    }
}

/// START_SINE payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StartSine {
    /// Frequency, millihertz.
    pub freq_mhz: u32,
    /// Amplitude, raw.
    pub amplitude: i16,
    /// Offset, raw.
    pub offset: i16,
    /// Cycles before the measurement window.
    pub settle_cycles: u16,
    /// Cycles in the measurement window.
    pub cycles: u16,
    /// [`SINE_STREAM`] | [`SINE_DFT`].
    pub flags: u8,
}

impl StartSine {
    /// (settle samples, measurement samples) at the sample rate, as the drive computes them.
    pub fn sample_counts(&self, sample_rate_hz: u32) -> Option<(u32, u32)> {
        if self.freq_mhz == 0 {
            return None;
        }
        let f = self.freq_mhz as u64;
        let fs = sample_rate_hz as u64;
        let settle = (self.settle_cycles as u64 * fs * 1000 + f / 2) / f;
        let measure = (self.cycles as u64 * fs * 1000 + f / 2) / f;
        if settle + measure > u32::MAX as u64 {
            return None;
        }
        Some((settle as u32, measure as u32))
    }

    /// The drive's phase-accumulator increment per sample, `round(freq_mhz 2^32 / (1000 fs))`.
    pub fn phase_increment(&self, sample_rate_hz: u32) -> u32 {
        let fs = sample_rate_hz.max(1) as u128;
        ((((self.freq_mhz as u128) << 32) + 500 * fs) / (1000 * fs)) as u32
    }

    /// The frequency the drive really generates, Hz: `inc fs / 2^32` (within `fs 2^-33` of
    /// `freq_mhz / 1000`).
    pub fn applied_freq_hz(&self, sample_rate_hz: u32) -> f64 {
        self.phase_increment(sample_rate_hz) as f64 * sample_rate_hz as f64 / 4294967296.0
    }
}

/// LOAD_CTRL payload: the controller `u = d e + sum_i z_i + sum_j h_j e_(k-j)`, `z_i <- a_i z_i +
/// g_i e` (PROTOCOL.md section 3): its format, number of sections and of delay taps, and
/// feed-through; the sections, then the taps, follow in LOAD_SECTION frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadCtrl {
    /// Controller format ([`CTRL_FORMAT`]); a drive NAKs a format it does not know.
    pub format: u8,
    /// Number of sections, 0..=[`MAX_SECTIONS`] (format 1), 0..=[`MAX_SECTIONS_TAPS`] (format 2).
    pub n_sections: u8,
    /// Number of delay taps, 0..=[`MAX_TAPS`] (format 2; 0 in format 1, where this byte is
    /// reserved).
    pub n_taps: u8,
    /// Feed-through `d`, Q24 (raw voltage LSB per raw speed LSB, times 2^24).
    pub d_q24: i32,
    /// `1/d` for the anti-windup, Q16 (raw speed LSB per raw voltage LSB, times 2^16); 0 without
    /// feed-through (the sections are then frozen while the output is clamped and the error
    /// pushes further into the clamp).
    pub dinv_q16: i32,
}

/// LOAD_SECTION payload: section `index` of the controller loaded by LOAD_CTRL; from index
/// `n_sections` on (format 2), the delay taps `h_1, h_2, ...` in order (`a_q30` 0, `g_q24` the
/// tap).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadSection {
    /// Its index; sections are loaded in order (the next index expected).
    pub index: u8,
    /// Pole `a`, Q30 (`|a| <= 1`: `-2^30..=2^30`).
    pub a_q30: i32,
    /// Input gain `g`, Q24 (raw voltage LSB per raw speed LSB, times 2^24).
    pub g_q24: i32,
}

/// START_LOOP payload: the speed loop with the loaded controller, the reference `r0` for the
/// first `pre_samples` samples then `r1`, `total_samples` in all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StartLoop {
    /// Reference before the step, raw speed LSB.
    pub r0: i16,
    /// Reference from sample `pre_samples` on, raw speed LSB.
    pub r1: i16,
    /// Samples at `r0`, `<= total_samples`.
    pub pre_samples: u32,
    /// Samples of the run, `>= 1`.
    pub total_samples: u32,
}

impl StartLoop {
    /// The reference of sample `k`, raw.
    pub fn reference(&self, k: u64) -> i16 {
        if k < self.pre_samples as u64 {
            self.r0
        } else {
            self.r1
        }
    }
}

/// ACK payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ack {
    /// The type acknowledged.
    pub acked_type: u8,
    /// Run id (START only).
    pub run_id: u16,
    /// Total samples of the run (START only).
    pub total_samples: u32,
}

/// NAK codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NakCode {
    /// 1: unknown type.
    UnknownType,
    /// 2: bad length.
    BadLength,
    /// 3: a field out of range; detail = its payload offset.
    BadValue,
    /// 4: a run is active.
    Busy,
    /// 5: no configuration yet.
    NotConfigured,
    /// 6: a fault is latched; detail = fault code.
    Fault,
    /// 7: version mismatch.
    Version,
    /// 8: START_LOOP without a complete controller (LOAD_CTRL and all its sections).
    NoController,
    /// Any other code.
    Other(u8),
}

impl NakCode {
    /// Wire value.
    pub fn code(self) -> u8 {
        match self {
            NakCode::UnknownType => nak::UNKNOWN_TYPE,
            NakCode::BadLength => nak::BAD_LENGTH,
            NakCode::BadValue => nak::BAD_VALUE,
            NakCode::Busy => nak::BUSY,
            NakCode::NotConfigured => nak::NOT_CONFIGURED,
            NakCode::Fault => nak::FAULT,
            NakCode::Version => nak::VERSION,
            NakCode::NoController => nak::NO_CONTROLLER,
            NakCode::Other(c) => c,
        }
    }
    /// From the wire value.
    pub fn from_code(c: u8) -> Self {
        match c {
            nak::UNKNOWN_TYPE => NakCode::UnknownType,
            nak::BAD_LENGTH => NakCode::BadLength,
            nak::BAD_VALUE => NakCode::BadValue,
            nak::BUSY => NakCode::Busy,
            nak::NOT_CONFIGURED => NakCode::NotConfigured,
            nak::FAULT => NakCode::Fault,
            nak::VERSION => NakCode::Version,
            nak::NO_CONTROLLER => NakCode::NoController,
            c => NakCode::Other(c),
        }
    }
}

/// NAK payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Nak {
    /// The rejected type.
    pub nak_type: u8,
    /// Why.
    pub code: NakCode,
    /// Code-specific detail.
    pub detail: u16,
}

/// Drive state in STATUS_REPLY.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveState {
    /// 0: no configuration since boot.
    Unconfigured = state::UNCONFIGURED as isize,
    /// 1: configured, idle.
    Idle = state::IDLE as isize,
    /// 2: a run is active.
    Running = state::RUNNING as isize,
    /// 3: a fault is latched.
    Fault = state::FAULT as isize,
}

impl DriveState {
    /// Wire value.
    pub fn code(self) -> u8 {
        self as u8
    }
    /// From the wire value; None for a value no state has.
    pub fn from_code(c: u8) -> Option<Self> {
        Some(match c {
            state::UNCONFIGURED => DriveState::Unconfigured,
            state::IDLE => DriveState::Idle,
            state::RUNNING => DriveState::Running,
            state::FAULT => DriveState::Fault,
            _ => return None,
        })
    }
}

/// STATUS_REPLY payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusReply {
    /// Drive state.
    pub state: DriveState,
    /// Latched fault ([`fault`]).
    pub fault: u8,
    /// Current or last run id (0 = none).
    pub run_id: u16,
    /// Samples produced in the current/last run.
    pub samples_done: u32,
    /// Blocks dropped in the current/last run.
    pub blocks_dropped: u16,
    /// Boot id.
    pub boot_id: u16,
    /// Frames discarded since boot.
    pub rx_errors: u16,
    /// Clamped samples in the current/last run.
    pub clamped: u16,
}

/// DATA payload: one block of samples.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DataBlock {
    /// Run id.
    pub run_id: u16,
    /// Sample index of the first sample.
    pub first_index: u32,
    /// Bit 0: a sample was clamped.
    pub flags: u8,
    /// Samples, raw `[u, y, i]`.
    pub samples: Vec<[i16; 3]>,
}

/// STREAM_END reasons.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum EndReason {
    /// 0: ran to the end.
    Complete,
    /// 1: host STOP.
    Stopped,
    /// 2: ESTOP.
    Estop,
    /// 3: keepalive expired.
    Keepalive,
    /// 4: speed or current trip.
    Limit,
    /// Any other code.
    Other(u8),
}

impl EndReason {
    /// Wire value.
    pub fn code(self) -> u8 {
        match self {
            EndReason::Complete => end::COMPLETE,
            EndReason::Stopped => end::STOPPED,
            EndReason::Estop => end::ESTOP,
            EndReason::Keepalive => end::KEEPALIVE,
            EndReason::Limit => end::LIMIT,
            EndReason::Other(c) => c,
        }
    }
    /// From the wire value.
    pub fn from_code(c: u8) -> Self {
        match c {
            end::COMPLETE => EndReason::Complete,
            end::STOPPED => EndReason::Stopped,
            end::ESTOP => EndReason::Estop,
            end::KEEPALIVE => EndReason::Keepalive,
            end::LIMIT => EndReason::Limit,
            c => EndReason::Other(c),
        }
    }
}

/// STREAM_END payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamEnd {
    /// Run id.
    pub run_id: u16,
    /// Why the run ended.
    pub reason: EndReason,
    /// Samples produced (indices 0..total_samples).
    pub total_samples: u32,
    /// Samples in transmitted blocks.
    pub samples_sent: u32,
    /// Blocks dropped by the drive.
    pub blocks_dropped: u16,
}

/// SINE_RESULT payload: single-bin DFT, raw LSB in Q8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SineResult {
    /// Run id.
    pub run_id: u16,
    /// Samples in the measurement window.
    pub n: u32,
    /// Re U, Q8 raw.
    pub u_re: i32,
    /// Im U, Q8 raw.
    pub u_im: i32,
    /// Re Y, Q8 raw.
    pub y_re: i32,
    /// Im Y, Q8 raw.
    pub y_im: i32,
    /// Level of u over the window, `(1/n) sum u_k`, Q8 raw.
    pub u_mean: i32,
    /// Ramp moment of u, `(1/n) sum r_k u_k` with `r_k = (2k - (n-1))/n`, Q8 raw.
    pub u_ramp: i32,
    /// Level of y over the window, Q8 raw.
    pub y_mean: i32,
    /// Ramp moment of y, Q8 raw.
    pub y_ramp: i32,
}

/// A protocol message.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Message {
    /// HELLO.
    Hello,
    /// CONFIGURE.
    Configure(Configure),
    /// START_PRBS.
    StartPrbs(StartPrbs),
    /// START_SINE.
    StartSine(StartSine),
    /// STOP.
    Stop,
    /// ESTOP.
    Estop,
    /// STATUS.
    Status,
    /// KEEPALIVE of a run id: keeps that run alive (protocol 3).
    Keepalive(u16),
    /// END_QUERY for a run id.
    EndQuery(u16),
    /// LOAD_CTRL.
    LoadCtrl(LoadCtrl),
    /// LOAD_SECTION.
    LoadSection(LoadSection),
    /// START_LOOP.
    StartLoop(StartLoop),
    /// ACK.
    Ack(Ack),
    /// HELLO_REPLY.
    HelloReply(HelloReply),
    /// STATUS_REPLY.
    StatusReply(StatusReply),
    /// NAK.
    Nak(Nak),
    /// DATA.
    Data(DataBlock),
    /// STREAM_END.
    StreamEnd(StreamEnd),
    /// SINE_RESULT.
    SineResult(SineResult),
}

/// A frame: seq plus message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Sequence number.
    pub seq: u16,
    /// The message.
    pub msg: Message,
}

/// Little-endian writer.
struct W<'a>(&'a mut Vec<u8>);
impl W<'_> {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u16(&mut self, v: u16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i16(&mut self, v: i16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
}

/// Little-endian reader over an exactly-sized payload (lengths are checked before reading).
struct R<'a>(&'a [u8], usize);
impl R<'_> {
    fn u8(&mut self) -> u8 {
        let v = self.0[self.1];
        self.1 += 1;
        v
    }
    fn u16(&mut self) -> u16 {
        let v = u16::from_le_bytes([self.0[self.1], self.0[self.1 + 1]]);
        self.1 += 2;
        v
    }
    fn i16(&mut self) -> i16 {
        self.u16() as i16
    }
    fn u32(&mut self) -> u32 {
        let b = &self.0[self.1..self.1 + 4];
        self.1 += 4;
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    fn i32(&mut self) -> i32 {
        self.u32() as i32
    }
}

impl Message {
    /// The type code.
    pub fn type_code(&self) -> u8 {
        match self {
            Message::Hello => ty::HELLO,
            Message::Configure(_) => ty::CONFIGURE,
            Message::StartPrbs(_) => ty::START_PRBS,
            Message::StartSine(_) => ty::START_SINE,
            Message::Stop => ty::STOP,
            Message::Estop => ty::ESTOP,
            Message::Status => ty::STATUS,
            Message::Keepalive(_) => ty::KEEPALIVE,
            Message::EndQuery(_) => ty::END_QUERY,
            Message::LoadCtrl(_) => ty::LOAD_CTRL,
            Message::LoadSection(_) => ty::LOAD_SECTION,
            Message::StartLoop(_) => ty::START_LOOP,
            Message::Ack(_) => ty::ACK,
            Message::HelloReply(_) => ty::HELLO_REPLY,
            Message::StatusReply(_) => ty::STATUS_REPLY,
            Message::Nak(_) => ty::NAK,
            Message::Data(_) => ty::DATA,
            Message::StreamEnd(_) => ty::STREAM_END,
            Message::SineResult(_) => ty::SINE_RESULT,
        }
    }

    /// Short upper-case name, as in the specification.
    pub fn name(&self) -> &'static str {
        type_name(self.type_code())
    }

    /// The exact payload length for a type, given the first payload bytes where it depends on
    /// them (DATA: n at offset 6). None for unknown types.
    pub fn payload_len(ty: u8, payload: &[u8]) -> Option<usize> {
        spec::message(ty)?.payload_len(payload)
    }

    /// Append the payload bytes.
    pub fn write_payload(&self, out: &mut Vec<u8>) {
        let mut w = W(out);
        match self {
            Message::Hello | Message::Stop | Message::Estop | Message::Status => {}
            Message::Keepalive(run_id) => w.u16(*run_id),
            Message::Configure(_)
            | Message::StartPrbs(_)
            | Message::StartSine(_)
            | Message::EndQuery(_) => write_run_command(self, &mut w),
            Message::LoadCtrl(_) | Message::LoadSection(_) | Message::StartLoop(_) => {
                write_loop_command(self, &mut w)
            }
            Message::Ack(_)
            | Message::HelloReply(_)
            | Message::StatusReply(_)
            | Message::Nak(_) => write_reply(self, &mut w),
            Message::Data(_) | Message::StreamEnd(_) | Message::SineResult(_) => {
                write_stream(self, &mut w)
            }
        }
    }

    /// Parse a payload of type `ty`. Checks the exact length and reserved fields; never panics.
    pub fn parse(ty: u8, p: &[u8]) -> Result<Message, FrameError> {
        let want = Message::payload_len(ty, p).ok_or(if matches!(ty, ty::DATA) {
            FrameError::Length { ty, len: p.len() }
        } else {
            FrameError::UnknownType(ty)
        })?;
        if p.len() != want {
            return Err(FrameError::Length { ty, len: p.len() });
        }
        let mut r = R(p, 0);
        match ty {
            ty::HELLO => Ok(Message::Hello),
            ty::STOP => Ok(Message::Stop),
            ty::ESTOP => Ok(Message::Estop),
            ty::STATUS => Ok(Message::Status),
            ty::KEEPALIVE => Ok(Message::Keepalive(r.u16())),
            ty::CONFIGURE | ty::START_PRBS | ty::START_SINE | ty::END_QUERY => {
                parse_run_command(ty, &mut r)
            }
            ty::LOAD_CTRL | ty::LOAD_SECTION | ty::START_LOOP => parse_loop_command(ty, &mut r),
            ty::ACK | ty::HELLO_REPLY | ty::STATUS_REPLY | ty::NAK => parse_reply(ty, &mut r),
            ty::DATA | ty::STREAM_END | ty::SINE_RESULT => parse_stream(ty, &mut r),
            other => Err(FrameError::UnknownType(other)),
        }
    }
}

/// Append the payload bytes of a run command from the host:
/// CONFIGURE, START_PRBS, START_SINE, END_QUERY.
/// Messages of other families write nothing here; [`Message::write_payload`] dispatches.
fn write_run_command(msg: &Message, w: &mut W<'_>) {
    match msg {
        Message::Configure(c) => {
            w.u32(c.sample_rate_hz);
            w.u8(c.block_samples);
            w.u8(0);
            w.u16(c.keepalive_ms);
            w.u32(c.scale_u_uv);
            w.u32(c.scale_y_urad_s);
            w.u32(c.scale_i_ua);
            w.i16(c.u_limit);
            w.i16(c.y_limit);
            w.i16(c.i_limit);
        }
        Message::StartPrbs(p) => {
            w.u8(p.order);
            w.u8(0);
            w.u32(p.taps);
            w.u32(p.seed);
            w.u16(p.clock_samples);
            w.i16(p.amplitude);
            w.i16(p.offset);
            w.u16(p.periods);
            w.u32(p.settle_samples);
        }
        Message::StartSine(s) => {
            w.u32(s.freq_mhz);
            w.i16(s.amplitude);
            w.i16(s.offset);
            w.u16(s.settle_cycles);
            w.u16(s.cycles);
            w.u8(s.flags);
            w.u8(0);
        }
        Message::EndQuery(r) => w.u16(*r),
        _ => {}
    }
}

/// Append the payload bytes of a closed-loop command from the host:
/// LOAD_CTRL, LOAD_SECTION, START_LOOP.
/// Messages of other families write nothing here; [`Message::write_payload`] dispatches.
fn write_loop_command(msg: &Message, w: &mut W<'_>) {
    match msg {
        Message::LoadCtrl(c) => {
            w.u8(c.format);
            w.u8(c.n_sections);
            w.u8(c.n_taps);
            w.u8(0);
            w.i32(c.d_q24);
            w.i32(c.dinv_q16);
        }
        Message::LoadSection(c) => {
            w.u8(c.index);
            w.u8(0);
            w.i32(c.a_q30);
            w.i32(c.g_q24);
        }
        Message::StartLoop(l) => {
            w.i16(l.r0);
            w.i16(l.r1);
            w.u32(l.pre_samples);
            w.u32(l.total_samples);
        }
        _ => {}
    }
}

/// Append the payload bytes of a reply from the drive: ACK, HELLO_REPLY, STATUS_REPLY, NAK.
/// Messages of other families write nothing here; [`Message::write_payload`] dispatches.
fn write_reply(msg: &Message, w: &mut W<'_>) {
    match msg {
        Message::Ack(a) => {
            w.u8(a.acked_type);
            w.u8(0);
            w.u16(a.run_id);
            w.u32(a.total_samples);
        }
        Message::HelloReply(h) => {
            w.u8(h.proto_version);
            w.u8(h.fw_major);
            w.u8(h.fw_minor);
            w.u8(h.n_channels);
            w.u8(h.max_block_samples);
            w.u8(0);
            w.u16(h.boot_id);
            w.u32(h.max_sample_rate_hz);
        }
        Message::StatusReply(s) => {
            w.u8(s.state.code());
            w.u8(s.fault);
            w.u16(s.run_id);
            w.u32(s.samples_done);
            w.u16(s.blocks_dropped);
            w.u16(s.boot_id);
            w.u16(s.rx_errors);
            w.u16(s.clamped);
        }
        Message::Nak(n) => {
            w.u8(n.nak_type);
            w.u8(n.code.code());
            w.u16(n.detail);
        }
        _ => {}
    }
}

/// Append the payload bytes of a stream message from the drive: DATA, STREAM_END, SINE_RESULT.
/// Messages of other families write nothing here; [`Message::write_payload`] dispatches.
fn write_stream(msg: &Message, w: &mut W<'_>) {
    match msg {
        Message::Data(d) => {
            w.u16(d.run_id);
            w.u32(d.first_index);
            w.u8(d.samples.len() as u8);
            w.u8(d.flags);
            for s in &d.samples {
                for &c in s {
                    w.i16(c);
                }
            }
        }
        Message::StreamEnd(e) => {
            w.u16(e.run_id);
            w.u8(e.reason.code());
            w.u8(0);
            w.u32(e.total_samples);
            w.u32(e.samples_sent);
            w.u16(e.blocks_dropped);
        }
        Message::SineResult(s) => {
            w.u16(s.run_id);
            w.u32(s.n);
            w.i32(s.u_re);
            w.i32(s.u_im);
            w.i32(s.y_re);
            w.i32(s.y_im);
            w.i32(s.u_mean);
            w.i32(s.u_ramp);
            w.i32(s.y_mean);
            w.i32(s.y_ramp);
        }
        _ => {}
    }
}

/// Parse a run command from the host: CONFIGURE, START_PRBS, START_SINE, END_QUERY.
/// The length is already checked by [`Message::parse`]; reserved fields are checked here.
fn parse_run_command(ty: u8, r: &mut R<'_>) -> Result<Message, FrameError> {
    let bad = FrameError::Field(ty);
    Ok(match ty {
        ty::CONFIGURE => {
            let sample_rate_hz = r.u32();
            let block_samples = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::Configure(Configure {
                sample_rate_hz,
                block_samples,
                keepalive_ms: r.u16(),
                scale_u_uv: r.u32(),
                scale_y_urad_s: r.u32(),
                scale_i_ua: r.u32(),
                u_limit: r.i16(),
                y_limit: r.i16(),
                i_limit: r.i16(),
            })
        }
        ty::START_PRBS => {
            let order = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::StartPrbs(StartPrbs {
                order,
                taps: r.u32(),
                seed: r.u32(),
                clock_samples: r.u16(),
                amplitude: r.i16(),
                offset: r.i16(),
                periods: r.u16(),
                settle_samples: r.u32(),
            })
        }
        ty::START_SINE => {
            let s = StartSine {
                freq_mhz: r.u32(),
                amplitude: r.i16(),
                offset: r.i16(),
                settle_cycles: r.u16(),
                cycles: r.u16(),
                flags: r.u8(),
            };
            if r.u8() != 0 || s.flags & !(SINE_STREAM | SINE_DFT) != 0 {
                return Err(bad);
            }
            Message::StartSine(s)
        }
        ty::END_QUERY => Message::EndQuery(r.u16()),
        other => return Err(FrameError::UnknownType(other)),
    })
}

/// Parse a closed-loop command from the host: LOAD_CTRL, LOAD_SECTION, START_LOOP.
/// The length is already checked by [`Message::parse`]; reserved fields are checked here.
fn parse_loop_command(ty: u8, r: &mut R<'_>) -> Result<Message, FrameError> {
    let bad = FrameError::Field(ty);
    Ok(match ty {
        ty::LOAD_CTRL => {
            let format = r.u8();
            let n_sections = r.u8();
            let n_taps = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::LoadCtrl(LoadCtrl {
                format,
                n_sections,
                n_taps,
                d_q24: r.i32(),
                dinv_q16: r.i32(),
            })
        }
        ty::LOAD_SECTION => {
            let index = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::LoadSection(LoadSection {
                index,
                a_q30: r.i32(),
                g_q24: r.i32(),
            })
        }
        ty::START_LOOP => Message::StartLoop(StartLoop {
            r0: r.i16(),
            r1: r.i16(),
            pre_samples: r.u32(),
            total_samples: r.u32(),
        }),
        other => return Err(FrameError::UnknownType(other)),
    })
}

/// Parse a reply from the drive: ACK, HELLO_REPLY, STATUS_REPLY, NAK.
/// The length is already checked by [`Message::parse`]; reserved fields are checked here.
fn parse_reply(ty: u8, r: &mut R<'_>) -> Result<Message, FrameError> {
    let bad = FrameError::Field(ty);
    Ok(match ty {
        ty::ACK => {
            let acked_type = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::Ack(Ack {
                acked_type,
                run_id: r.u16(),
                total_samples: r.u32(),
            })
        }
        ty::HELLO_REPLY => {
            let proto_version = r.u8();
            let fw_major = r.u8();
            let fw_minor = r.u8();
            let n_channels = r.u8();
            let max_block_samples = r.u8();
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::HelloReply(HelloReply {
                proto_version,
                fw_major,
                fw_minor,
                n_channels,
                max_block_samples,
                boot_id: r.u16(),
                max_sample_rate_hz: r.u32(),
            })
        }
        ty::STATUS_REPLY => Message::StatusReply(StatusReply {
            state: DriveState::from_code(r.u8()).ok_or(bad)?,
            fault: r.u8(),
            run_id: r.u16(),
            samples_done: r.u32(),
            blocks_dropped: r.u16(),
            boot_id: r.u16(),
            rx_errors: r.u16(),
            clamped: r.u16(),
        }),
        ty::NAK => Message::Nak(Nak {
            nak_type: r.u8(),
            code: NakCode::from_code(r.u8()),
            detail: r.u16(),
        }),
        other => return Err(FrameError::UnknownType(other)),
    })
}

/// Parse a stream message from the drive: DATA, STREAM_END, SINE_RESULT.
/// The length is already checked by [`Message::parse`]; reserved fields are checked here.
fn parse_stream(ty: u8, r: &mut R<'_>) -> Result<Message, FrameError> {
    let bad = FrameError::Field(ty);
    Ok(match ty {
        ty::DATA => {
            let run_id = r.u16();
            let first_index = r.u32();
            let n = r.u8();
            let flags = r.u8();
            if n == 0 || n > MAX_BLOCK_SAMPLES || flags & !1 != 0 {
                return Err(bad);
            }
            let samples = (0..n).map(|_| [r.i16(), r.i16(), r.i16()]).collect();
            Message::Data(DataBlock {
                run_id,
                first_index,
                flags,
                samples,
            })
        }
        ty::STREAM_END => {
            let run_id = r.u16();
            let reason = EndReason::from_code(r.u8());
            if r.u8() != 0 {
                return Err(bad);
            }
            Message::StreamEnd(StreamEnd {
                run_id,
                reason,
                total_samples: r.u32(),
                samples_sent: r.u32(),
                blocks_dropped: r.u16(),
            })
        }
        ty::SINE_RESULT => Message::SineResult(SineResult {
            run_id: r.u16(),
            n: r.u32(),
            u_re: r.i32(),
            u_im: r.i32(),
            y_re: r.i32(),
            y_im: r.i32(),
            u_mean: r.i32(),
            u_ramp: r.i32(),
            y_mean: r.i32(),
            y_ramp: r.i32(),
        }),
        other => return Err(FrameError::UnknownType(other)),
    })
}

/// The specification's name of a type code ("?" if unknown).
pub fn type_name(t: u8) -> &'static str {
    spec::message(t).map_or("?", |m| m.name)
}

/// Why a received frame was discarded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    /// The bytes between two delimiters are not valid (canonical) COBS.
    #[error("invalid COBS encoding")]
    Cobs,
    /// The frame exceeded the maximum body length.
    #[error("frame too long")]
    TooLong,
    /// The body is shorter than header plus CRC.
    #[error("frame too short")]
    TooShort,
    /// CRC mismatch.
    #[error("CRC mismatch")]
    Crc,
    /// Unsupported version or reserved bits set.
    #[error("unsupported version/flags byte {0:#04x}")]
    Version(u8),
    /// Unknown message type.
    #[error("unknown message type {0:#04x}")]
    UnknownType(u8),
    /// The payload length does not match the message type.
    #[error("bad payload length {len} for type {ty:#04x}")]
    Length {
        /// Message type.
        ty: u8,
        /// Payload length received.
        len: usize,
    },
    /// A field has an impossible value (reserved bits set, n out of range).
    #[error("bad field in type {0:#04x}")]
    Field(u8),
}
