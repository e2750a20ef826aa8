/*
 * fracfw: the drive side of the fracid serial protocol (crates/drive/PROTOCOL.md), portable C99 for
 * the TI C28x (TMS320F2812) and any host.
 *
 * - No dynamic memory: one fw_t, allocated by the integrator (statically), holds everything.
 * - No floating point: the sample path is integer/fixed-point only (Q30 sine, 64-bit DFT sums).
 * - 16-bit char: an octet is stored in an fw_octet (unsigned char, which is 16 bits on the C28x)
 *   and every octet is masked with 0xFF; multi-byte fields are packed explicitly little-endian.
 *   Define FW_OCTET16 to store octets in uint16_t on a host with 8-bit char (emulates the C28x).
 * - int may be 16 bits (C28x): all arithmetic that can exceed 16 bits uses int32_t/int64_t.
 *
 * Calling contexts (see firmware/README.md): fw_rx_octet() from the SCI receive FIFO interrupt,
 * fw_sample_begin()/fw_sample_end() from the sample-rate timer interrupt, fw_tx_octet() from the SCI
 * transmit FIFO interrupt or the background loop. They must not preempt each other (C28x PIE
 * interrupts do not nest unless the integrator re-enables INTM inside an ISR).
 */
#ifndef FRACFW_H
#define FRACFW_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifdef FW_OCTET16
/** One octet in a 16-bit storage unit (host emulation of the C28x). */
typedef uint16_t fw_octet;
#else
/** One octet (in the low 8 bits; unsigned char is 16 bits wide on the C28x). */
typedef unsigned char fw_octet;
#endif

/* The protocol's constants, type codes, payload lengths and field offsets: generated from the
 * Rust description of the frames (crates/drive/src/protocol/spec.rs). */
#include <fw_protocol.h> /* <>: the generated copy ahead on the include path wins (crates/drive/build.rs) */

/** Largest frame body: ver, type, seq (4) + DATA payload 8 + 6*66 + crc (2). */
#define FW_MAX_BODY (4u + FW_LEN_DATA + FW_LEN_DATA_SAMPLE * FW_MAX_BLOCK + 2u)
/** Largest COBS-encoded body (without delimiters). */
#define FW_MAX_ENCODED (FW_MAX_BODY + FW_MAX_BODY / 254u + 1u)
/** Longest host-to-drive frame body with its CRC: CONFIGURE, 4 + 26 + 2. */
#define FW_MAX_CMD_BODY (4u + FW_LEN_CONFIGURE + 2u)
/** Receive buffer: the longest host frame, COBS-encoded. Longer frames cannot be commands: the
 * receiver stops storing them and counts them as errors at their delimiter, so the work done on
 * a received octet stays bounded by one command frame (decode and CRC of at most 33 octets). */
#define FW_RX_MAX_ENCODED (FW_MAX_CMD_BODY + 1u)
/* FW_MAX_DFT_SAMPLES (fw_protocol.h), 2^22: the ramp moment sum (2k - (n-1)) y_k of the
 * fixed-point DFT stays below 2^59 in 64 bits. */

#ifndef FW_TX_BLOCKS
/** DATA blocks the transmit buffer holds (PROTOCOL.md: at least 2). */
#define FW_TX_BLOCKS 4u
#endif
/** Data-ring slots: the queued blocks, the one being sent, the one being filled, end frames. */
#define FW_TX_SLOTS (FW_TX_BLOCKS + 5u)
/** Answers queued ahead of data (stop-and-wait: one, plus a HELLO that crosses it). */
#define FW_ANSWER_SLOTS 2u
/** Longest answer body (6 + 22; STATUS_REPLY needs 6 + 16; SINE_RESULT goes through the data ring). */
#define FW_ANSWER_BODY 28u

/* Controller formats (fw_protocol.h): FW_CTRL_FORMAT, parallel first-order sections (poles Q30,
 * gains Q24, 64-bit states Q32), at most FW_MAX_SECTIONS_V1; FW_CTRL_FORMAT_TAPS (firmware 1.2),
 * at most FW_MAX_SECTIONS sections and FW_MAX_TAPS delay taps on the past conditioned errors. */

/**
 * The speed controller (PROTOCOL.md section 3, "Speed loop"): with s = sum z_i + 2^8 sum h_j w_j,
 * u = round((2^8 d e + s) / 2^32), then z_i <- round(a_i z_i / 2^30) + 2^8 g_i e' and the delay
 * line w_j <- w_(j-1), w_1 <- e', e' the error conditioned on the voltage clamp.
 * d, g_i, h_j: Q24 raw voltage per raw speed LSB; a_i: Q30; z_i: Q32 raw voltage (64-bit,
 * saturated at +-2^56: +-2^24 raw); w_j: the past conditioned errors (raw, |w_j| <= 2^17).
 */
typedef struct {
    int32_t d_q24, dinv_q16;
    uint16_t n, loaded;   /**< sections, and sections + taps loaded */
    uint16_t n_taps, pad; /**< delay taps (format 2) */
    int32_t a_q30[FW_MAX_SECTIONS];
    int32_t g_q24[FW_MAX_SECTIONS];
    int64_t z[FW_MAX_SECTIONS];
    int32_t h_q24[FW_MAX_TAPS];
    int32_t w[FW_MAX_TAPS];
} fw_ctrl;

/** Zero the controller's states. */
void fw_ctrl_reset(fw_ctrl *c);

/**
 * One controller sample: error e = r - y (raw speed LSB), the voltage limit (raw, > 0). Returns
 * the command clamped to +-u_limit, *clamped = 1 if it was; updates the states (anti-windup:
 * with the output clamped, the states take the error that gives the clamped output, or, without
 * feed-through, are frozen while the error pushes further into the clamp). Per section one
 * 32x64 product (two 32x32->64) and one 32x32->64, no division.
 */
int16_t fw_ctrl_step(fw_ctrl *c, int32_t e, int16_t u_limit, uint16_t *clamped);

/** A frame body being queued or sent (not yet COBS-encoded; the CRC is added when sending). */
typedef struct {
    fw_octet b[FW_MAX_BODY];
    uint16_t len; /**< body length without the CRC */
} fw_slot;

/** A short answer body. */
typedef struct {
    fw_octet b[FW_ANSWER_BODY];
    uint16_t len; /**< body length without the CRC */
} fw_answer;

/** CONFIGURE payload, decoded. */
typedef struct {
    uint32_t sample_rate_hz;
    uint16_t block_samples;
    uint16_t keepalive_ms;
    uint32_t scale_u_uv, scale_y_urad_s, scale_i_ua;
    int16_t u_limit, y_limit, i_limit;
} fw_config;

/** Counters for tests and diagnostics (not on the wire except rx_errors). */
typedef struct {
    uint32_t frames_received; /**< valid frames */
    uint32_t replays;         /**< commands answered from the replay cache */
    uint32_t runs_started;
    uint32_t blocks_dropped; /**< since boot */
    uint32_t end_frames_lost; /**< STREAM_END/SINE_RESULT that found no slot (END_QUERY recovers) */
    uint32_t configs;         /**< accepted CONFIGUREs */
    uint32_t keepalives;      /**< KEEPALIVEs of the running run (each reset its timer) */
} fw_counters;

/** The whole drive-side state. Allocate one (statically) and call fw_init(). */
typedef struct {
    /* identity and configuration */
    uint16_t boot_id;
    uint32_t max_sample_rate_hz;
    uint16_t configured;
    fw_config conf;
    uint16_t fault;
    uint16_t rx_errors;
    uint16_t next_run_id;
    uint16_t tx_seq;
    fw_counters cnt;
    /* receiver: the encoded frame since the last 0x00 */
    fw_octet rx[FW_RX_MAX_ENCODED];
    uint16_t rx_len;
    uint16_t rx_overflow;
    /* replay cache: the last answer and the (seq, type) it answered */
    uint16_t cache_valid, cache_seq, cache_type;
    fw_answer cache;
    /* answers, sent before data */
    fw_answer ans[FW_ANSWER_SLOTS];
    uint16_t ans_head, ans_count;
    /* data ring: DATA, SINE_RESULT, STREAM_END */
    fw_slot slot[FW_TX_SLOTS];
    uint16_t data_head, data_count;
    /* transmitter: streaming COBS of the current frame */
    uint16_t tx_active;   /* 0 idle, 1 answer, 2 data slot */
    uint16_t tx_phase;    /* 0 leading 0x00, 1 block start, 2 in block, 3 trailing 0x00 */
    uint16_t tx_pos, tx_len, tx_left, tx_pending, tx_run;
    const fw_octet *tx_src;
    fw_octet tx_crc[2];
    /* the run */
    uint16_t running;
    uint16_t run_id;
    uint16_t kind; /* 1 PRBS, 2 sine, 3 speed loop */
    uint32_t total, done, sent;
    uint16_t dropped, clamped;
    uint16_t stream;
    uint16_t building; /* a block is being filled in slot (data_head + data_count) */
    uint16_t block_n;
    uint16_t block_flags;
    uint32_t block_first;
    int16_t last_u;
    int16_t cur_u; /* command of the sample in progress */
    uint16_t cur_flags;
    uint16_t ramp_left, ramp_len, ramp_reason, ramping;
    uint32_t quiet_samples, keepalive_samples;
    uint16_t end_pending; /* reason + 1 when the run must end at the next sample */
    /* PRBS */
    uint32_t lfsr, lfsr_seed, lfsr_taps, lfsr_mask, lfsr_period, prbs_bit_index;
    uint16_t lfsr_order, prbs_bit;
    uint32_t prbs_settle, prbs_clock, prbs_clock_count;
    int16_t prbs_amp, prbs_off;
    /* sine */
    uint32_t phase, inc, sine_settle, sine_measure;
    int16_t sine_amp, sine_off;
    uint16_t sine_flags;
    int32_t cur_cos, cur_sin;
    uint16_t measuring;
    int64_t acc[4];
    /* level and ramp sums of u and y over the window: sum x_k, sum (2k - (n-1)) x_k */
    int64_t lvl[2], rmp[2];
    int32_t win_k2; /* 2k - (n-1) of the sample in progress */
    /* the speed loop: the downloaded controller, the reference step, the speed measured */
    fw_ctrl ctrl;
    uint16_t ctrl_ready;
    int16_t loop_r0, loop_r1;
    uint32_t loop_pre;
    int16_t loop_y;
    /* last run, for STATUS and END_QUERY */
    uint16_t last_valid;
    uint16_t last_id;
    uint32_t last_done;
    uint16_t last_dropped, last_clamped;
    uint16_t end_valid;
    fw_octet end_payload[FW_LEN_STREAM_END];
} fw_t;

/** Reset everything (power-up): no configuration, no run, empty buffers, the given boot id. */
void fw_init(fw_t *fw, uint16_t boot_id, uint32_t max_sample_rate_hz);

/**
 * One received octet (low 8 bits of `octet`; higher bits are ignored). Returns 0, or, when the
 * octet completed a valid frame, 0x100 | its type (for test hooks such as fw_drop_last_answer).
 */
uint16_t fw_rx_octet(fw_t *fw, uint16_t octet);

/**
 * The next octet to transmit, or -1 when there is nothing to send. Answers go before queued
 * data, between frames. The CRC of a data frame is computed when it starts (background work).
 */
int32_t fw_tx_octet(fw_t *fw);

/** Whether a frame is in the middle of being transmitted. */
int fw_tx_busy(const fw_t *fw);

/**
 * Start one sample (sample-rate interrupt). Returns 1 with *u_raw = the voltage command (raw
 * channel-0 LSBs, already clamped) when a run is active: apply it, measure, call fw_sample_end().
 * Returns 0 (and *u_raw = 0: the inverter command is zero) when no run is active.
 */
int fw_sample_begin(fw_t *fw, int16_t *u_raw);

/** Finish the sample started by fw_sample_begin() with the measured speed and current (raw). */
void fw_sample_end(fw_t *fw, int16_t y_raw, int16_t i_raw);

/**
 * The speed measured at this sample's tick, before fw_sample_begin(): a loop run's controller
 * computes this sample's command from it (u_k from y_k, no sample of delay). Other runs ignore
 * it. Without it a loop run uses the speed of the previous fw_sample_end() (one sample later).
 */
void fw_sample_measure(fw_t *fw, int16_t y_raw);

/** Whether a loop run (START_LOOP) is active: call fw_sample_measure() before each sample. */
int fw_loop_running(const fw_t *fw);

/** Whether a run is active. */
int fw_running(const fw_t *fw);

/** The sample rate of the configuration (0 when unconfigured): program the timer with it. */
uint32_t fw_sample_rate(const fw_t *fw);

/**
 * Test hook (host fault injection): discard the answer queued last if it is not being sent yet.
 * It stays in the replay cache, as if the line had lost it. Returns 1 if one was discarded.
 */
int fw_drop_last_answer(fw_t *fw);

/** CRC-16/MCRF4XX of n octets, continuing from crc (start with 0xFFFF). */
uint16_t fw_crc16(uint16_t crc, const fw_octet *p, uint16_t n);

/** COBS-encode n octets (canonical); returns the encoded length (out: n + n/254 + 1 octets). */
uint16_t fw_cobs_encode(const fw_octet *in, uint16_t n, fw_octet *out);

/**
 * COBS-decode n octets in place (canonical encodings only); returns the decoded length, or -1 if
 * the input is not a canonical COBS encoding (a zero octet, a code past the end, a redundant
 * trailing empty block).
 */
int32_t fw_cobs_decode(fw_octet *buf, uint16_t n);

/** Fibonacci LFSR step as in PROTOCOL.md section 5: returns the output bit, updates *state. */
uint16_t fw_lfsr_next(uint32_t *state, uint32_t taps, uint16_t order);

/** sin and cos of 2 pi phase / 2^32 in Q30 (table + second-order correction, error < 1e-7). */
void fw_sincos_q30(uint32_t phase, int32_t *s, int32_t *c);

/** The sine command: offset + round(amplitude * sin(2 pi phase / 2^32)), before clamping. */
int32_t fw_sine_command(uint32_t phase, int16_t amplitude, int16_t offset);

/** Copy the diagnostic counters. */
void fw_get_counters(const fw_t *fw, fw_counters *out);

/** Frames discarded since boot (saturating), as STATUS_REPLY reports. */
uint16_t fw_rx_errors(const fw_t *fw);

/** The active configuration (all zero when unconfigured). */
void fw_get_config(const fw_t *fw, fw_config *out);

/** Id of the current run, or of the last one (0: none since boot). */
uint16_t fw_run_id(const fw_t *fw);

/** Number of bytes (host octets) of fw_t, for a host that allocates it opaquely. */
uint32_t fw_sizeof(void);

#ifdef __cplusplus
}
#endif
#endif
