/* The protocol engine: receiver, commands, replay cache, experiments, streaming, safety. */
#include "fracfw.h"

/* ---- little-endian packing into octet arrays (no memcpy: octets may be 16-bit words) ---- */

static void put8(fw_octet *p, uint16_t v) { p[0] = (fw_octet)(v & 0xFFu); }
static void put16(fw_octet *p, uint16_t v)
{
    p[0] = (fw_octet)(v & 0xFFu);
    p[1] = (fw_octet)((v >> 8) & 0xFFu);
}
static void put32(fw_octet *p, uint32_t v)
{
    put16(p, (uint16_t)(v & 0xFFFFul));
    put16(p + 2, (uint16_t)(v >> 16));
}
static uint16_t get8(const fw_octet *p) { return (uint16_t)(p[0] & 0xFFu); }
static uint16_t get16(const fw_octet *p)
{
    return (uint16_t)((p[0] & 0xFFu) | ((uint16_t)(p[1] & 0xFFu) << 8));
}
static uint32_t get32(const fw_octet *p)
{
    return (uint32_t)get16(p) | ((uint32_t)get16(p + 2) << 16);
}
static int16_t geti16(const fw_octet *p)
{
    uint16_t u = get16(p);
    return (u & 0x8000u) ? (int16_t)(-(int32_t)(uint16_t)(~u) - 1) : (int16_t)u;
}

static uint16_t sat_add16(uint16_t a) { return (uint16_t)(a == 0xFFFFu ? a : a + 1u); }

void fw_init(fw_t *fw, uint16_t boot_id, uint32_t max_sample_rate_hz)
{
    /* field by field would be long; a byte loop works for any CHAR_BIT */
    unsigned char *p = (unsigned char *)fw;
    uint32_t k;
    for (k = 0; k < (uint32_t)sizeof(*fw); k++) {
        p[k] = 0;
    }
    fw->boot_id = boot_id;
    fw->max_sample_rate_hz = max_sample_rate_hz;
    fw->next_run_id = 1;
}

uint32_t fw_sizeof(void) { return (uint32_t)sizeof(fw_t); }

void fw_get_counters(const fw_t *fw, fw_counters *out) { *out = fw->cnt; }

uint16_t fw_rx_errors(const fw_t *fw) { return fw->rx_errors; }

void fw_get_config(const fw_t *fw, fw_config *out) { *out = fw->conf; }

uint16_t fw_run_id(const fw_t *fw) { return fw->running ? fw->run_id : (fw->last_valid ? fw->last_id : 0u); }

int fw_running(const fw_t *fw) { return fw->running != 0u; }

int fw_loop_running(const fw_t *fw) { return fw->running != 0u && fw->kind == 3u; }

void fw_sample_measure(fw_t *fw, int16_t y_raw) { fw->loop_y = y_raw; }

uint32_t fw_sample_rate(const fw_t *fw) { return fw->configured ? fw->conf.sample_rate_hz : 0ul; }

int fw_tx_busy(const fw_t *fw) { return fw->tx_active != 0u; }

/* ---- transmit queues ---- */

static uint16_t next_tx_seq(fw_t *fw)
{
    fw->tx_seq = (uint16_t)(fw->tx_seq + 1u);
    return fw->tx_seq;
}

/* A frame body: ver, type, seq (HDR octets), then the payload (offsets FW_OFF_*, fw_protocol.h). */
#define HDR 4u

static void header(fw_octet *b, uint16_t type, uint16_t seq)
{
    put8(b, FW_PROTO_VERSION);
    put8(b + 1, type);
    put16(b + 2, seq);
}

/* Queue an answer (ahead of data) and keep it in the replay cache if `cache` is set. */
static fw_answer *answer(fw_t *fw, uint16_t type, uint16_t seq, uint16_t payload_len)
{
    fw_answer *a;
    uint16_t idx;
    if (fw->ans_count < FW_ANSWER_SLOTS) {
        idx = (uint16_t)((fw->ans_head + fw->ans_count) % FW_ANSWER_SLOTS);
        fw->ans_count++;
    } else {
        /* full (a host that does not wait): replace the newest one not being sent */
        idx = (uint16_t)((fw->ans_head + fw->ans_count - 1u) % FW_ANSWER_SLOTS);
        if (fw->tx_active == 1u && idx == fw->ans_head) {
            idx = (uint16_t)((idx + 1u) % FW_ANSWER_SLOTS);
        }
    }
    a = &fw->ans[idx];
    header(a->b, type, seq);
    a->len = (uint16_t)(HDR + payload_len);
    return a;
}

static void ack(fw_t *fw, uint16_t type, uint16_t seq, uint16_t run_id, uint32_t total)
{
    fw_answer *a = answer(fw, FW_T_ACK, seq, FW_LEN_ACK);
    put8(a->b + HDR + FW_OFF_ACK_ACKED_TYPE, type);
    put8(a->b + HDR + FW_OFF_ACK_RESERVED, 0u);
    put16(a->b + HDR + FW_OFF_ACK_RUN_ID, run_id);
    put32(a->b + HDR + FW_OFF_ACK_TOTAL_SAMPLES, total);
}

static void nak(fw_t *fw, uint16_t type, uint16_t seq, uint16_t code, uint16_t detail)
{
    fw_answer *a = answer(fw, FW_T_NAK, seq, FW_LEN_NAK);
    put8(a->b + HDR + FW_OFF_NAK_NAK_TYPE, type);
    put8(a->b + HDR + FW_OFF_NAK_CODE, code);
    put16(a->b + HDR + FW_OFF_NAK_DETAIL, detail);
}

int fw_drop_last_answer(fw_t *fw)
{
    if (fw->ans_count == 0u || (fw->tx_active == 1u && fw->ans_count == 1u)) {
        return 0;
    }
    fw->ans_count--;
    return 1;
}

/* The data-ring slot being filled / next to fill. */
static fw_slot *build_slot(fw_t *fw)
{
    return &fw->slot[(fw->data_head + fw->data_count) % FW_TX_SLOTS];
}

/* Queue an unsolicited end frame (SINE_RESULT, STREAM_END): never dropped for lack of block room,
 * only if the ring itself is full (the host then asks END_QUERY). Keeps one slot for building. */
static fw_slot *end_frame(fw_t *fw, uint16_t type, uint16_t payload_len)
{
    fw_slot *s;
    if (fw->data_count + 1u >= FW_TX_SLOTS) {
        fw->cnt.end_frames_lost++;
        return 0;
    }
    s = build_slot(fw);
    header(s->b, type, next_tx_seq(fw));
    s->len = (uint16_t)(HDR + payload_len);
    fw->data_count++;
    return s;
}

/* ---- the run ---- */

static void flush_block(fw_t *fw)
{
    fw_slot *s;
    uint16_t queued;
    if (!fw->building || fw->block_n == 0u) {
        fw->building = 0;
        return;
    }
    queued = (uint16_t)(fw->data_count - (fw->tx_active == 2u ? 1u : 0u));
    if (queued >= FW_TX_BLOCKS) {
        fw->dropped = sat_add16(fw->dropped);
        fw->cnt.blocks_dropped++;
    } else {
        s = build_slot(fw);
        header(s->b, FW_T_DATA, next_tx_seq(fw));
        put16(s->b + HDR + FW_OFF_DATA_RUN_ID, fw->run_id);
        put32(s->b + HDR + FW_OFF_DATA_FIRST_INDEX, fw->block_first);
        put8(s->b + HDR + FW_OFF_DATA_N, fw->block_n);
        put8(s->b + HDR + FW_OFF_DATA_FLAGS, fw->block_flags);
        s->len = (uint16_t)(HDR + FW_LEN_DATA + FW_LEN_DATA_SAMPLE * fw->block_n);
        fw->data_count++;
        fw->sent += fw->block_n;
    }
    fw->building = 0;
    fw->block_n = 0;
    fw->block_flags = 0;
}

static int32_t q8_result(int64_t acc, uint32_t n)
{
    /* X = (2/n) sum x e^{-j theta} in Q8: acc is in units of 2^-22 LSB -> acc * 512 / (n 2^22) */
    int64_t den = (int64_t)n << 13;
    int64_t q;
    if (acc >= 0) {
        q = (acc + den / 2) / den;
    } else {
        q = -((-acc + den / 2) / den);
    }
    if (q > 2147483647ll) {
        q = 2147483647ll;
    }
    if (q < -2147483647ll - 1) {
        q = -2147483647ll - 1;
    }
    return (int32_t)q;
}

/* (1/n) sum x_k in Q8, rounded half away from zero. |sum| < 2^37, so sum * 256 fits. */
static int32_t q8_mean(int64_t sum, uint32_t n)
{
    int64_t a = sum * 256, d = (int64_t)n, q;
    q = a >= 0 ? (a + d / 2) / d : -((-a + d / 2) / d);
    return (int32_t)q;
}

/* (1/n) sum ((2k - (n-1))/n) x_k in Q8 = sum * 256 / n^2, without the 2^67 product: divide by n
 * first (truncating), keep the remainder's share (truncating), then round the last division. */
static int32_t q8_ramp(int64_t sum, uint32_t n)
{
    int64_t d = (int64_t)n, t;
    t = (sum / d) * 256 + ((sum % d) * 256) / d;
    return (int32_t)(t >= 0 ? (t + d / 2) / d : -((-t + d / 2) / d));
}

static void end_run(fw_t *fw, uint16_t reason)
{
    fw_slot *s;
    if (!fw->running) {
        return;
    }
    flush_block(fw);
    if (fw->kind == 2u && (fw->sine_flags & FW_SINE_DFT) && reason == FW_END_COMPLETE) {
        s = end_frame(fw, FW_T_SINE_RESULT, FW_LEN_SINE_RESULT);
        if (s) {
            fw_octet *q = s->b + HDR;
            put16(q + FW_OFF_SINE_RESULT_RUN_ID, fw->run_id);
            put32(q + FW_OFF_SINE_RESULT_N, fw->sine_measure);
            put32(q + FW_OFF_SINE_RESULT_U_RE, (uint32_t)q8_result(fw->acc[0], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_U_IM, (uint32_t)q8_result(fw->acc[1], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_Y_RE, (uint32_t)q8_result(fw->acc[2], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_Y_IM, (uint32_t)q8_result(fw->acc[3], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_U_MEAN, (uint32_t)q8_mean(fw->lvl[0], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_U_RAMP, (uint32_t)q8_ramp(fw->rmp[0], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_Y_MEAN, (uint32_t)q8_mean(fw->lvl[1], fw->sine_measure));
            put32(q + FW_OFF_SINE_RESULT_Y_RAMP, (uint32_t)q8_ramp(fw->rmp[1], fw->sine_measure));
        }
    }
    put16(fw->end_payload + FW_OFF_STREAM_END_RUN_ID, fw->run_id);
    put8(fw->end_payload + FW_OFF_STREAM_END_REASON, reason);
    put8(fw->end_payload + FW_OFF_STREAM_END_RESERVED, 0u);
    put32(fw->end_payload + FW_OFF_STREAM_END_TOTAL_SAMPLES, fw->done);
    put32(fw->end_payload + FW_OFF_STREAM_END_SAMPLES_SENT, fw->sent);
    put16(fw->end_payload + FW_OFF_STREAM_END_BLOCKS_DROPPED, fw->dropped);
    fw->end_valid = 1;
    s = end_frame(fw, FW_T_STREAM_END, FW_LEN_STREAM_END);
    if (s) {
        uint16_t k;
        for (k = 0; k < FW_LEN_STREAM_END; k++) {
            s->b[HDR + k] = fw->end_payload[k];
        }
    }
    fw->last_valid = 1;
    fw->last_id = fw->run_id;
    fw->last_done = fw->done;
    fw->last_dropped = fw->dropped;
    fw->last_clamped = fw->clamped;
    fw->running = 0;
    fw->cur_u = 0;
}

static void begin_run(fw_t *fw, uint16_t kind, uint32_t total, uint16_t stream)
{
    fw->running = 1;
    fw->kind = kind;
    fw->run_id = fw->next_run_id;
    fw->next_run_id = (uint16_t)(fw->next_run_id + 1u);
    if (fw->next_run_id == 0u) {
        fw->next_run_id = 1;
    }
    fw->total = total;
    fw->done = 0;
    fw->sent = 0;
    fw->dropped = 0;
    fw->clamped = 0;
    fw->stream = stream;
    fw->building = 0;
    fw->block_n = 0;
    fw->block_flags = 0;
    fw->last_u = 0;
    fw->ramping = 0;
    fw->ramp_left = 0;
    fw->quiet_samples = 0;
    fw->keepalive_samples =
        (uint32_t)(((uint64_t)fw->conf.keepalive_ms * fw->conf.sample_rate_hz) / 1000u);
    fw->end_valid = 0;
    fw->cnt.runs_started++;
}

int fw_sample_begin(fw_t *fw, int16_t *u_raw)
{
    int32_t v;
    int32_t lim;
    uint16_t ctrl_clamped = 0;
    *u_raw = 0;
    if (!fw->running) {
        return 0;
    }
    if (!fw->ramping && fw->quiet_samples > fw->keepalive_samples) {
        uint16_t n = (uint16_t)((fw->conf.sample_rate_hz + 19ul) / 20ul); /* 50 ms */
        fw->ramping = 1;
        fw->ramp_left = n ? n : 1u;
        fw->ramp_len = fw->ramp_left;
        fw->ramp_reason = FW_END_KEEPALIVE;
        fw->fault = FW_FAULT_KEEPALIVE;
    }
    if (fw->ramping && fw->ramp_left == 0u) {
        end_run(fw, fw->ramp_reason);
        return 0;
    }
    fw->measuring = 0;
    if (fw->ramping) {
        int64_t p;
        fw->ramp_left--;
        /* round(last_u * left / len), half away from zero */
        p = (int64_t)fw->last_u * fw->ramp_left * 2;
        if (p >= 0) {
            v = (int32_t)((p + fw->ramp_len) / (2 * (int64_t)fw->ramp_len));
        } else {
            v = -(int32_t)((-p + fw->ramp_len) / (2 * (int64_t)fw->ramp_len));
        }
    } else if (fw->kind == 1u) {
        if (fw->done < fw->prbs_settle) {
            v = fw->prbs_off;
        } else {
            if (fw->prbs_clock_count == 0u) {
                if (fw->prbs_bit_index == fw->lfsr_period) {
                    fw->lfsr = fw->lfsr_seed;
                    fw->prbs_bit_index = 0;
                }
                fw->prbs_bit = fw_lfsr_next(&fw->lfsr, fw->lfsr_taps, fw->lfsr_order);
                fw->prbs_bit_index++;
            }
            fw->prbs_clock_count++;
            if (fw->prbs_clock_count >= fw->prbs_clock) {
                fw->prbs_clock_count = 0;
            }
            v = fw->prbs_bit ? (int32_t)fw->prbs_off + fw->prbs_amp
                             : (int32_t)fw->prbs_off - fw->prbs_amp;
        }
    } else if (fw->kind == 3u) {
        int16_t r = fw->done < fw->loop_pre ? fw->loop_r0 : fw->loop_r1;
        v = fw_ctrl_step(&fw->ctrl, (int32_t)r - fw->loop_y, fw->conf.u_limit, &ctrl_clamped);
    } else {
        v = fw_sine_command(fw->phase, fw->sine_amp, fw->sine_off);
        if (fw->done >= fw->sine_settle) {
            fw->measuring = 1;
            fw->win_k2 = (int32_t)(2u * (fw->done - fw->sine_settle)) - (int32_t)(fw->sine_measure - 1u);
            fw_sincos_q30(fw->phase, &fw->cur_sin, &fw->cur_cos);
        }
        fw->phase += fw->inc;
    }
    lim = fw->conf.u_limit;
    fw->cur_flags = 0;
    if (v > lim || v < -lim || ctrl_clamped) {
        fw->clamped = sat_add16(fw->clamped);
        fw->cur_flags = 1;
        v = v > lim ? lim : (v < -lim ? -lim : v);
    }
    fw->cur_u = (int16_t)v;
    if (!fw->ramping) {
        fw->last_u = fw->cur_u;
    }
    if (fw->quiet_samples != 0xFFFFFFFFul) {
        fw->quiet_samples++;
    }
    *u_raw = fw->cur_u;
    return 1;
}

void fw_sample_end(fw_t *fw, int16_t y_raw, int16_t i_raw)
{
    int32_t ya, ia;
    if (!fw->running) {
        return;
    }
    if (fw->measuring) {
        fw->acc[0] += ((int64_t)fw->cur_u * fw->cur_cos) >> 8;
        fw->acc[1] -= ((int64_t)fw->cur_u * fw->cur_sin) >> 8;
        fw->acc[2] += ((int64_t)y_raw * fw->cur_cos) >> 8;
        fw->acc[3] -= ((int64_t)y_raw * fw->cur_sin) >> 8;
        fw->lvl[0] += fw->cur_u;
        fw->lvl[1] += y_raw;
        fw->rmp[0] += (int64_t)fw->win_k2 * fw->cur_u;
        fw->rmp[1] += (int64_t)fw->win_k2 * y_raw;
    }
    if (fw->kind == 3u) {
        fw->loop_y = y_raw; /* for a next sample without fw_sample_measure() */
    }
    if (fw->stream) {
        fw_slot *s = build_slot(fw);
        fw_octet *p;
        if (!fw->building) {
            fw->building = 1;
            fw->block_n = 0;
            fw->block_first = fw->done;
        }
        p = s->b + HDR + FW_LEN_DATA + FW_LEN_DATA_SAMPLE * fw->block_n;
        put16(p + FW_OFF_DATA_SAMPLE_U, (uint16_t)fw->cur_u);
        put16(p + FW_OFF_DATA_SAMPLE_Y, (uint16_t)y_raw);
        put16(p + FW_OFF_DATA_SAMPLE_I, (uint16_t)i_raw);
        fw->block_n++;
        fw->block_flags |= fw->cur_flags;
    }
    fw->done++;
    ya = y_raw < 0 ? -(int32_t)y_raw : y_raw;
    ia = i_raw < 0 ? -(int32_t)i_raw : i_raw;
    if (!fw->ramping && (ya > fw->conf.y_limit || ia > fw->conf.i_limit)) {
        fw->fault = ya > fw->conf.y_limit ? FW_FAULT_SPEED : FW_FAULT_CURRENT;
        end_run(fw, FW_END_LIMIT);
        return;
    }
    if (fw->block_n >= fw->conf.block_samples) {
        flush_block(fw);
    }
    if (!fw->ramping && fw->done >= fw->total) {
        end_run(fw, FW_END_COMPLETE);
    }
}

/* ---- commands ---- */

static int start_check(fw_t *fw, uint16_t type, uint16_t seq)
{
    if (fw->running) {
        nak(fw, type, seq, FW_NAK_BUSY, 0);
        return 0;
    }
    if (fw->fault != FW_FAULT_NONE) {
        nak(fw, type, seq, FW_NAK_FAULT, fw->fault);
        return 0;
    }
    if (!fw->configured) {
        nak(fw, type, seq, FW_NAK_NOT_CONFIGURED, 0);
        return 0;
    }
    return 1;
}

static void cmd_configure(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    fw_config c;
    uint16_t bad = 0xFFFFu;
    c.sample_rate_hz = get32(p + FW_OFF_CONFIGURE_SAMPLE_RATE_HZ);
    c.block_samples = get8(p + FW_OFF_CONFIGURE_BLOCK_SAMPLES);
    c.keepalive_ms = get16(p + FW_OFF_CONFIGURE_KEEPALIVE_MS);
    c.scale_u_uv = get32(p + FW_OFF_CONFIGURE_SCALE_U_UV);
    c.scale_y_urad_s = get32(p + FW_OFF_CONFIGURE_SCALE_Y_URAD_S);
    c.scale_i_ua = get32(p + FW_OFF_CONFIGURE_SCALE_I_UA);
    c.u_limit = geti16(p + FW_OFF_CONFIGURE_U_LIMIT);
    c.y_limit = geti16(p + FW_OFF_CONFIGURE_Y_LIMIT);
    c.i_limit = geti16(p + FW_OFF_CONFIGURE_I_LIMIT);
    if (fw->running) {
        nak(fw, FW_T_CONFIGURE, seq, FW_NAK_BUSY, 0);
        return;
    }
    if (c.sample_rate_hz == 0ul || c.sample_rate_hz > fw->max_sample_rate_hz) {
        bad = FW_OFF_CONFIGURE_SAMPLE_RATE_HZ;
    } else if (c.block_samples == 0u || c.block_samples > FW_MAX_BLOCK) {
        bad = FW_OFF_CONFIGURE_BLOCK_SAMPLES;
    } else if (c.keepalive_ms < 50u || c.keepalive_ms > 5000u) {
        bad = FW_OFF_CONFIGURE_KEEPALIVE_MS;
    } else if (c.scale_u_uv == 0ul) {
        bad = FW_OFF_CONFIGURE_SCALE_U_UV;
    } else if (c.scale_y_urad_s == 0ul) {
        bad = FW_OFF_CONFIGURE_SCALE_Y_URAD_S;
    } else if (c.scale_i_ua == 0ul) {
        bad = FW_OFF_CONFIGURE_SCALE_I_UA;
    } else if (c.u_limit <= 0) {
        bad = FW_OFF_CONFIGURE_U_LIMIT;
    } else if (c.y_limit <= 0) {
        bad = FW_OFF_CONFIGURE_Y_LIMIT;
    } else if (c.i_limit <= 0) {
        bad = FW_OFF_CONFIGURE_I_LIMIT;
    }
    if (bad != 0xFFFFu) {
        nak(fw, FW_T_CONFIGURE, seq, FW_NAK_BAD_VALUE, bad);
        return;
    }
    fw->conf = c;
    fw->configured = 1;
    /* the controller's gains are in the channel units and its poles at the sample rate */
    fw->ctrl.n = 0;
    fw->ctrl.n_taps = 0;
    fw->ctrl.loaded = 0;
    fw->ctrl_ready = 0;
    fw->fault = FW_FAULT_NONE;
    fw->cnt.configs++;
    ack(fw, FW_T_CONFIGURE, seq, 0, 0);
}

static void cmd_prbs(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    uint16_t order = get8(p + FW_OFF_START_PRBS_ORDER);
    uint32_t taps = get32(p + FW_OFF_START_PRBS_TAPS), seed = get32(p + FW_OFF_START_PRBS_SEED);
    uint16_t clock = get16(p + FW_OFF_START_PRBS_CLOCK_SAMPLES);
    int16_t amp = geti16(p + FW_OFF_START_PRBS_AMPLITUDE);
    int16_t off = geti16(p + FW_OFF_START_PRBS_OFFSET);
    uint16_t periods = get16(p + FW_OFF_START_PRBS_PERIODS);
    uint32_t settle = get32(p + FW_OFF_START_PRBS_SETTLE_SAMPLES);
    uint32_t mask;
    uint64_t total;
    if (!start_check(fw, FW_T_START_PRBS, seq)) {
        return;
    }
    if (order < 2u || order > 31u) {
        nak(fw, FW_T_START_PRBS, seq, FW_NAK_BAD_VALUE, FW_OFF_START_PRBS_ORDER);
        return;
    }
    mask = (1ul << order) - 1ul;
    total = (uint64_t)settle + (uint64_t)periods * mask * clock;
    if (total > 0xFFFFFFFFull) {
        nak(fw, FW_T_START_PRBS, seq, FW_NAK_BAD_VALUE, FW_OFF_START_PRBS_ORDER);
        return;
    }
    if (seed == 0ul || (seed & ~mask) != 0ul || (taps & (1ul << (order - 1u))) == 0ul ||
        (taps & ~mask) != 0ul) {
        nak(fw, FW_T_START_PRBS, seq, FW_NAK_BAD_VALUE, FW_OFF_START_PRBS_TAPS);
        return;
    }
    if (clock == 0u || periods == 0u || amp < 0 || total == 0u) {
        nak(fw, FW_T_START_PRBS, seq, FW_NAK_BAD_VALUE, FW_OFF_START_PRBS_CLOCK_SAMPLES);
        return;
    }
    begin_run(fw, 1u, (uint32_t)total, 1u);
    fw->lfsr_order = order;
    fw->lfsr_taps = taps;
    fw->lfsr_seed = seed;
    fw->lfsr = seed;
    fw->lfsr_mask = mask;
    fw->lfsr_period = mask;
    fw->prbs_bit_index = 0;
    fw->prbs_bit = 0;
    fw->prbs_settle = settle;
    fw->prbs_clock = clock;
    fw->prbs_clock_count = 0;
    fw->prbs_amp = amp;
    fw->prbs_off = off;
    ack(fw, FW_T_START_PRBS, seq, fw->run_id, fw->total);
}

static void cmd_sine(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    uint32_t f = get32(p + FW_OFF_START_SINE_FREQ_MHZ);
    int16_t amp = geti16(p + FW_OFF_START_SINE_AMPLITUDE);
    int16_t off = geti16(p + FW_OFF_START_SINE_OFFSET);
    uint16_t settle_c = get16(p + FW_OFF_START_SINE_SETTLE_CYCLES);
    uint16_t cycles = get16(p + FW_OFF_START_SINE_CYCLES);
    uint16_t flags = get8(p + FW_OFF_START_SINE_FLAGS);
    uint64_t fs, settle, measure;
    if (!start_check(fw, FW_T_START_SINE, seq)) {
        return;
    }
    fs = fw->conf.sample_rate_hz;
    if (f == 0ul || (uint64_t)f > fs * 500u || amp < 0 || cycles == 0u || (flags & (FW_SINE_STREAM | FW_SINE_DFT)) == 0u) {
        nak(fw, FW_T_START_SINE, seq, FW_NAK_BAD_VALUE, FW_OFF_START_SINE_FREQ_MHZ);
        return;
    }
    settle = ((uint64_t)settle_c * fs * 1000u + f / 2u) / f;
    measure = ((uint64_t)cycles * fs * 1000u + f / 2u) / f;
    if (settle + measure > 0xFFFFFFFFull || measure == 0u) {
        nak(fw, FW_T_START_SINE, seq, FW_NAK_BAD_VALUE, FW_OFF_START_SINE_FREQ_MHZ);
        return;
    }
    if ((flags & FW_SINE_DFT) && measure > FW_MAX_DFT_SAMPLES) {
        nak(fw, FW_T_START_SINE, seq, FW_NAK_BAD_VALUE, FW_OFF_START_SINE_CYCLES);
        return;
    }
    begin_run(fw, 2u, (uint32_t)(settle + measure), (uint16_t)(flags & FW_SINE_STREAM));
    fw->phase = 0;
    fw->inc = (uint32_t)((((uint64_t)f << 32) + 500u * fs) / (1000u * fs));
    fw->sine_settle = (uint32_t)settle;
    fw->sine_measure = (uint32_t)measure;
    fw->sine_amp = amp;
    fw->sine_off = off;
    fw->sine_flags = flags;
    fw->acc[0] = fw->acc[1] = fw->acc[2] = fw->acc[3] = 0;
    fw->lvl[0] = fw->lvl[1] = fw->rmp[0] = fw->rmp[1] = 0;
    ack(fw, FW_T_START_SINE, seq, fw->run_id, fw->total);
}

static void cmd_load_ctrl(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    uint16_t format = get8(p + FW_OFF_LOAD_CTRL_FORMAT), n = get8(p + FW_OFF_LOAD_CTRL_N_SECTIONS);
    uint16_t taps = get8(p + FW_OFF_LOAD_CTRL_N_TAPS);
    if (fw->running) {
        nak(fw, FW_T_LOAD_CTRL, seq, FW_NAK_BUSY, 0);
        return;
    }
    if (!fw->configured) {
        nak(fw, FW_T_LOAD_CTRL, seq, FW_NAK_NOT_CONFIGURED, 0);
        return;
    }
    if (format != FW_CTRL_FORMAT && format != FW_CTRL_FORMAT_TAPS) {
        nak(fw, FW_T_LOAD_CTRL, seq, FW_NAK_BAD_VALUE, FW_OFF_LOAD_CTRL_FORMAT);
        return;
    }
    if (n > (format == FW_CTRL_FORMAT ? FW_MAX_SECTIONS_V1 : FW_MAX_SECTIONS)) {
        nak(fw, FW_T_LOAD_CTRL, seq, FW_NAK_BAD_VALUE, FW_OFF_LOAD_CTRL_N_SECTIONS);
        return;
    }
    if (taps > (format == FW_CTRL_FORMAT ? 0u : FW_MAX_TAPS)) {
        nak(fw, FW_T_LOAD_CTRL, seq, FW_NAK_BAD_VALUE, FW_OFF_LOAD_CTRL_N_TAPS);
        return;
    }
    fw->ctrl.n = n;
    fw->ctrl.n_taps = taps;
    fw->ctrl.loaded = 0;
    fw->ctrl.d_q24 = (int32_t)get32(p + FW_OFF_LOAD_CTRL_D_Q24);
    fw->ctrl.dinv_q16 = (int32_t)get32(p + FW_OFF_LOAD_CTRL_DINV_Q16);
    fw->ctrl_ready = (uint16_t)(n + taps == 0u);
    ack(fw, FW_T_LOAD_CTRL, seq, 0, 0);
}

static void cmd_load_section(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    uint16_t i = get8(p + FW_OFF_LOAD_SECTION_INDEX);
    int32_t a = (int32_t)get32(p + FW_OFF_LOAD_SECTION_A_Q30);
    if (fw->running) {
        nak(fw, FW_T_LOAD_SECTION, seq, FW_NAK_BUSY, 0);
        return;
    }
    if (!fw->configured) {
        nak(fw, FW_T_LOAD_SECTION, seq, FW_NAK_NOT_CONFIGURED, 0);
        return;
    }
    if (i != fw->ctrl.loaded || i >= fw->ctrl.n + fw->ctrl.n_taps) {
        nak(fw, FW_T_LOAD_SECTION, seq, FW_NAK_BAD_VALUE, FW_OFF_LOAD_SECTION_INDEX);
        return;
    }
    /* a pole within the unit circle; a tap's pole field 0 */
    if (a > 1073741824l || a < -1073741824l || (i >= fw->ctrl.n && a != 0)) {
        nak(fw, FW_T_LOAD_SECTION, seq, FW_NAK_BAD_VALUE, FW_OFF_LOAD_SECTION_A_Q30);
        return;
    }
    if (i < fw->ctrl.n) {
        fw->ctrl.a_q30[i] = a;
        fw->ctrl.g_q24[i] = (int32_t)get32(p + FW_OFF_LOAD_SECTION_G_Q24);
    } else {
        fw->ctrl.h_q24[i - fw->ctrl.n] = (int32_t)get32(p + FW_OFF_LOAD_SECTION_G_Q24);
    }
    fw->ctrl.loaded++;
    fw->ctrl_ready = (uint16_t)(fw->ctrl.loaded == fw->ctrl.n + fw->ctrl.n_taps);
    ack(fw, FW_T_LOAD_SECTION, seq, 0, 0);
}

static void cmd_loop(fw_t *fw, uint16_t seq, const fw_octet *p)
{
    uint32_t pre = get32(p + FW_OFF_START_LOOP_PRE_SAMPLES);
    uint32_t total = get32(p + FW_OFF_START_LOOP_TOTAL_SAMPLES);
    if (!start_check(fw, FW_T_START_LOOP, seq)) {
        return;
    }
    if (!fw->ctrl_ready) {
        nak(fw, FW_T_START_LOOP, seq, FW_NAK_NO_CONTROLLER, 0);
        return;
    }
    if (pre > total) {
        nak(fw, FW_T_START_LOOP, seq, FW_NAK_BAD_VALUE, FW_OFF_START_LOOP_PRE_SAMPLES);
        return;
    }
    if (total == 0ul) {
        nak(fw, FW_T_START_LOOP, seq, FW_NAK_BAD_VALUE, FW_OFF_START_LOOP_TOTAL_SAMPLES);
        return;
    }
    begin_run(fw, 3u, total, 1u);
    fw->loop_r0 = geti16(p + FW_OFF_START_LOOP_R0);
    fw->loop_r1 = geti16(p + FW_OFF_START_LOOP_R1);
    fw->loop_pre = pre;
    fw->loop_y = 0;
    fw_ctrl_reset(&fw->ctrl);
    ack(fw, FW_T_START_LOOP, seq, fw->run_id, fw->total);
}

static void cmd_status(fw_t *fw, uint16_t seq)
{
    fw_answer *a = answer(fw, FW_T_STATUS_REPLY, seq, FW_LEN_STATUS_REPLY);
    uint16_t state, id = 0, dropped = 0, clamped = 0;
    uint32_t done = 0;
    if (fw->running) {
        state = FW_STATE_RUNNING;
        id = fw->run_id;
        done = fw->done;
        dropped = fw->dropped;
        clamped = fw->clamped;
    } else {
        state = fw->fault != FW_FAULT_NONE ? FW_STATE_FAULT
                                           : (fw->configured ? FW_STATE_IDLE : FW_STATE_UNCONFIGURED);
        if (fw->last_valid) {
            id = fw->last_id;
            done = fw->last_done;
            dropped = fw->last_dropped;
            clamped = fw->last_clamped;
        }
    }
    put8(a->b + HDR + FW_OFF_STATUS_REPLY_STATE, state);
    put8(a->b + HDR + FW_OFF_STATUS_REPLY_FAULT, fw->fault);
    put16(a->b + HDR + FW_OFF_STATUS_REPLY_RUN_ID, id);
    put32(a->b + HDR + FW_OFF_STATUS_REPLY_SAMPLES_DONE, done);
    put16(a->b + HDR + FW_OFF_STATUS_REPLY_BLOCKS_DROPPED, dropped);
    put16(a->b + HDR + FW_OFF_STATUS_REPLY_BOOT_ID, fw->boot_id);
    put16(a->b + HDR + FW_OFF_STATUS_REPLY_RX_ERRORS, fw->rx_errors);
    put16(a->b + HDR + FW_OFF_STATUS_REPLY_CLAMPED, clamped);
}

static void execute(fw_t *fw, uint16_t type, uint16_t seq, const fw_octet *p)
{
    switch (type) {
    case FW_T_STATUS:
        cmd_status(fw, seq);
        break;
    case FW_T_CONFIGURE:
        cmd_configure(fw, seq, p);
        break;
    case FW_T_START_PRBS:
        cmd_prbs(fw, seq, p);
        break;
    case FW_T_START_SINE:
        cmd_sine(fw, seq, p);
        break;
    case FW_T_LOAD_CTRL:
        cmd_load_ctrl(fw, seq, p);
        break;
    case FW_T_LOAD_SECTION:
        cmd_load_section(fw, seq, p);
        break;
    case FW_T_START_LOOP:
        cmd_loop(fw, seq, p);
        break;
    case FW_T_STOP:
        if (fw->running && !fw->ramping) {
            fw->ramping = 1;
            fw->ramp_left = 1;
            fw->ramp_len = 1;
            fw->ramp_reason = FW_END_STOPPED;
        }
        ack(fw, type, seq, 0, 0);
        break;
    case FW_T_ESTOP:
        end_run(fw, FW_END_ESTOP);
        fw->fault = FW_FAULT_ESTOP;
        ack(fw, type, seq, 0, 0);
        break;
    case FW_T_END_QUERY: {
        uint16_t id = get16(p + FW_OFF_END_QUERY_RUN_ID);
        if (fw->end_valid && get16(fw->end_payload + FW_OFF_STREAM_END_RUN_ID) == id &&
            !(fw->running && fw->run_id == id)) {
            fw_answer *a = answer(fw, FW_T_STREAM_END, seq, FW_LEN_STREAM_END);
            uint16_t k;
            for (k = 0; k < FW_LEN_STREAM_END; k++) {
                a->b[HDR + k] = fw->end_payload[k];
            }
        } else {
            nak(fw, type, seq, FW_NAK_BAD_VALUE, 0);
        }
        break;
    }
    default:
        nak(fw, type, seq, FW_NAK_UNKNOWN_TYPE, 0);
        break;
    }
}

/* Payload length of a type, -1 if unknown; DATA is checked separately. */
static int32_t payload_len(uint16_t type)
{
    switch (type) {
    case FW_T_HELLO:
        return FW_LEN_HELLO;
    case FW_T_STOP:
        return FW_LEN_STOP;
    case FW_T_ESTOP:
        return FW_LEN_ESTOP;
    case FW_T_STATUS:
        return FW_LEN_STATUS;
    case FW_T_KEEPALIVE:
        return FW_LEN_KEEPALIVE;
    case FW_T_CONFIGURE:
        return FW_LEN_CONFIGURE;
    case FW_T_START_PRBS:
        return FW_LEN_START_PRBS;
    case FW_T_START_SINE:
        return FW_LEN_START_SINE;
    case FW_T_END_QUERY:
        return FW_LEN_END_QUERY;
    case FW_T_LOAD_CTRL:
        return FW_LEN_LOAD_CTRL;
    case FW_T_START_LOOP:
        return FW_LEN_START_LOOP;
    case FW_T_LOAD_SECTION:
        return FW_LEN_LOAD_SECTION;
    case FW_T_ACK:
        return FW_LEN_ACK;
    case FW_T_HELLO_REPLY:
        return FW_LEN_HELLO_REPLY;
    case FW_T_STATUS_REPLY:
        return FW_LEN_STATUS_REPLY;
    case FW_T_NAK:
        return FW_LEN_NAK;
    case FW_T_STREAM_END:
        return FW_LEN_STREAM_END;
    case FW_T_SINE_RESULT:
        return FW_LEN_SINE_RESULT;
    default:
        return -1;
    }
}

static void rx_error(fw_t *fw) { fw->rx_errors = sat_add16(fw->rx_errors); }

/* A decoded body: validate, then execute or replay. Returns 0x100 | type for a valid frame. */
static uint16_t handle_body(fw_t *fw, const fw_octet *b, uint16_t len)
{
    uint16_t type, seq, plen;
    int32_t want;
    const fw_octet *p;
    if (len < 6u || len > FW_MAX_BODY || fw_crc16(0xFFFFu, b, len) != 0u) {
        rx_error(fw);
        return 0;
    }
    if (get8(b) != FW_PROTO_VERSION) {
        rx_error(fw);
        return 0;
    }
    type = get8(b + 1);
    seq = get16(b + 2);
    p = b + 4;
    plen = (uint16_t)(len - 6u);
    want = payload_len(type);
    if (type == FW_T_DATA) {
        uint16_t n = plen >= FW_LEN_DATA ? get8(p + FW_OFF_DATA_N) : 0u;
        want = (n >= 1u && n <= FW_MAX_BLOCK) ? (int32_t)(FW_LEN_DATA + FW_LEN_DATA_SAMPLE * n) : -2;
    }
    if (want == -1 && type >= 0x80u) {
        rx_error(fw); /* unknown drive-to-host type */
        return 0;
    }
    if (want >= 0 && (uint16_t)want != plen) {
        rx_error(fw); /* wrong length: discarded */
        return 0;
    }
    if (want == -2) {
        rx_error(fw);
        return 0;
    }
    /* reserved fields must be zero */
    if ((type == FW_T_CONFIGURE && get8(p + FW_OFF_CONFIGURE_RESERVED) != 0u) ||
        (type == FW_T_START_PRBS && get8(p + FW_OFF_START_PRBS_RESERVED) != 0u) ||
        (type == FW_T_START_SINE &&
         (get8(p + FW_OFF_START_SINE_RESERVED) != 0u ||
          (get8(p + FW_OFF_START_SINE_FLAGS) & ~(FW_SINE_STREAM | FW_SINE_DFT)) != 0u)) ||
        (type == FW_T_LOAD_CTRL && get8(p + FW_OFF_LOAD_CTRL_RESERVED) != 0u) ||
        (type == FW_T_LOAD_SECTION && get8(p + FW_OFF_LOAD_SECTION_RESERVED) != 0u)) {
        rx_error(fw);
        return 0;
    }
    /* a valid frame */
    fw->cnt.frames_received++;
    if (type == FW_T_KEEPALIVE) {
        /* Only a KEEPALIVE of the running run resets its keepalive timer (PROTOCOL.md,
         * section 7): any other frame (another program's HELLO and STATUS, a KEEPALIVE of
         * another run) leaves it running, so a run whose host is gone ends. */
        if (fw->running && get16(p + FW_OFF_KEEPALIVE_RUN_ID) == fw->run_id) {
            fw->quiet_samples = 0;
            fw->cnt.keepalives++;
        }
        return (uint16_t)(0x100u | type);
    }
    if (type >= 0x80u) {
        return (uint16_t)(0x100u | type);
    }
    if (type == FW_T_HELLO) {
        fw_answer *a;
        fw->cache_valid = 0;
        a = answer(fw, FW_T_HELLO_REPLY, seq, FW_LEN_HELLO_REPLY);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_PROTO_VERSION, FW_PROTO_VERSION);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_FW_MAJOR, FW_MAJOR);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_FW_MINOR, FW_MINOR);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_N_CHANNELS, FW_N_CHANNELS);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_MAX_BLOCK_SAMPLES, FW_MAX_BLOCK);
        put8(a->b + HDR + FW_OFF_HELLO_REPLY_RESERVED, 0u);
        put16(a->b + HDR + FW_OFF_HELLO_REPLY_BOOT_ID, fw->boot_id);
        put32(a->b + HDR + FW_OFF_HELLO_REPLY_MAX_SAMPLE_RATE_HZ, fw->max_sample_rate_hz);
        return (uint16_t)(0x100u | type);
    }
    if (fw->cache_valid && fw->cache_seq == seq && fw->cache_type == type) {
        fw_answer *a = answer(fw, 0, 0, 0);
        *a = fw->cache;
        fw->cnt.replays++;
        return (uint16_t)(0x100u | type);
    }
    execute(fw, type, seq, p);
    /* the answer just queued is the newest one */
    fw->cache = fw->ans[(fw->ans_head + fw->ans_count - 1u) % FW_ANSWER_SLOTS];
    fw->cache_valid = 1;
    fw->cache_seq = seq;
    fw->cache_type = type;
    return (uint16_t)(0x100u | type);
}

uint16_t fw_rx_octet(fw_t *fw, uint16_t octet)
{
    uint16_t o = (uint16_t)(octet & 0xFFu);
    int32_t n;
    uint16_t r;
    if (o != 0u) {
        if (fw->rx_len < FW_RX_MAX_ENCODED) {
            fw->rx[fw->rx_len++] = (fw_octet)o;
        } else {
            fw->rx_overflow = 1;
        }
        return 0;
    }
    if (fw->rx_overflow) {
        rx_error(fw);
        r = 0;
    } else if (fw->rx_len == 0u) {
        r = 0; /* empty frame: ignored */
    } else {
        n = fw_cobs_decode(fw->rx, fw->rx_len);
        if (n < 0) {
            rx_error(fw);
            r = 0;
        } else {
            r = handle_body(fw, fw->rx, (uint16_t)n);
        }
    }
    fw->rx_len = 0;
    fw->rx_overflow = 0;
    return r;
}

/* ---- transmitter: COBS on the fly, CRC computed at the start of the frame ---- */

static uint16_t tx_at(const fw_t *fw, uint16_t i)
{
    uint16_t body = (uint16_t)(fw->tx_len - 2u);
    return (uint16_t)((i < body ? fw->tx_src[i] : fw->tx_crc[i - body]) & 0xFFu);
}

static void tx_block_end(fw_t *fw)
{
    if (fw->tx_run == 254u) {
        fw->tx_pending = 0;
    } else if (fw->tx_pos < fw->tx_len) {
        fw->tx_pos++; /* the zero ending this block */
        fw->tx_pending = 1;
    } else {
        fw->tx_pending = 0;
    }
    fw->tx_phase = 1;
}

int32_t fw_tx_octet(fw_t *fw)
{
    uint16_t v;
    if (!fw->tx_active) {
        uint16_t len, crc;
        if (fw->ans_count) {
            fw->tx_active = 1;
            fw->tx_src = fw->ans[fw->ans_head].b;
            len = fw->ans[fw->ans_head].len;
        } else if (fw->data_count) {
            fw->tx_active = 2;
            fw->tx_src = fw->slot[fw->data_head].b;
            len = fw->slot[fw->data_head].len;
        } else {
            return -1;
        }
        crc = fw_crc16(0xFFFFu, fw->tx_src, len);
        fw->tx_crc[0] = (fw_octet)(crc & 0xFFu);
        fw->tx_crc[1] = (fw_octet)(crc >> 8);
        fw->tx_len = (uint16_t)(len + 2u);
        fw->tx_pos = 0;
        fw->tx_pending = 1;
        fw->tx_phase = 0;
    }
    switch (fw->tx_phase) {
    case 0:
        fw->tx_phase = 1;
        return 0;
    case 1:
        if (fw->tx_pos == fw->tx_len && !fw->tx_pending) {
            /* trailing delimiter: the frame is done */
            if (fw->tx_active == 1u) {
                fw->ans_head = (uint16_t)((fw->ans_head + 1u) % FW_ANSWER_SLOTS);
                fw->ans_count--;
            } else {
                fw->data_head = (uint16_t)((fw->data_head + 1u) % FW_TX_SLOTS);
                fw->data_count--;
            }
            fw->tx_active = 0;
            return 0;
        }
        fw->tx_run = 0;
        while (fw->tx_pos + fw->tx_run < fw->tx_len && fw->tx_run < 254u &&
               tx_at(fw, (uint16_t)(fw->tx_pos + fw->tx_run)) != 0u) {
            fw->tx_run++;
        }
        fw->tx_left = fw->tx_run;
        if (fw->tx_run == 0u) {
            tx_block_end(fw);
        } else {
            fw->tx_phase = 2;
        }
        return (int32_t)(fw->tx_run + 1u);
    default:
        v = tx_at(fw, fw->tx_pos);
        fw->tx_pos++;
        fw->tx_left--;
        if (fw->tx_left == 0u) {
            tx_block_end(fw);
        }
        return (int32_t)v;
    }
}
