/* Instruction counts of fracfw's interrupt-time entry points, for firmware/cycles.sh.
 *
 * Runs the engine through every path a sample interrupt, a received octet and a transmitted octet
 * can take (PRBS and sine runs with streaming and the DFT, block completion and drops, keepalive
 * ramp-down, STOP, ESTOP, speed trip, every command, a maximum-length frame) and brackets each single
 * call with callgrind client requests: collection is switched on for that call only and the counts
 * are dumped under a label "entry:scenario" (entry = sample, rx or tx). Under valgrind
 * --tool=callgrind --collect-atstart=no each dump is the exact instruction count of one call.
 * Without valgrind the client requests are no-ops and the program only checks its scenarios.
 *
 * Usage: cycles SAMPLE_RATE_HZ OCTETS_PER_SAMPLE (the line's octets per sample period, each way). */
#include "fracfw.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <valgrind/callgrind.h>

static fw_t fw;
static unsigned fs_hz;
static unsigned octets_per_sample;
static uint16_t host_seq = 1;
static const char *tx_label = "tx:stream"; /* names the block size of the configuration */

/* One call, counted alone, dumped under `label`. */
#define MEASURE(label, stmt)                                                                       \
    do {                                                                                           \
        CALLGRIND_TOGGLE_COLLECT;                                                                  \
        stmt;                                                                                      \
        CALLGRIND_TOGGLE_COLLECT;                                                                  \
        CALLGRIND_DUMP_STATS_AT(label);                                                            \
    } while (0)

static void fail(const char *what)
{
    fprintf(stderr, "cycles: scenario check failed: %s\n", what);
    exit(1);
}

static void le16(fw_octet *p, unsigned v)
{
    p[0] = (fw_octet)(v & 0xFFu);
    p[1] = (fw_octet)((v >> 8) & 0xFFu);
}

static void le32(fw_octet *p, unsigned long v)
{
    le16(p, (unsigned)(v & 0xFFFFu));
    le16(p + 2, (unsigned)(v >> 16));
}

/* A host frame (body = ver, type, seq, payload, crc) fed octet by octet, each counted. */
static void send_frame(const char *label, uint16_t type, const fw_octet *payload, int plen)
{
    static fw_octet body[FW_MAX_BODY + 2], wire[FW_MAX_ENCODED + 4];
    uint16_t crc, m, k;
    uint16_t seq = host_seq++;
    int n = 0, j;
    body[n++] = FW_PROTO_VERSION;
    body[n++] = (fw_octet)type;
    body[n++] = (fw_octet)(seq & 0xFFu);
    body[n++] = (fw_octet)(seq >> 8);
    for (j = 0; j < plen; j++) {
        body[n++] = payload[j];
    }
    crc = fw_crc16(0xFFFFu, body, (uint16_t)n);
    body[n++] = (fw_octet)(crc & 0xFFu);
    body[n++] = (fw_octet)(crc >> 8);
    wire[0] = 0;
    m = fw_cobs_encode(body, (uint16_t)n, wire + 1);
    wire[m + 1u] = 0;
    for (k = 0; k < m + 2u; k++) {
        MEASURE(label, fw_rx_octet(&fw, wire[k]));
    }
}

/* The line: `octets` octets pulled from the transmitter, each counted. */
static void drain(const char *label, unsigned octets)
{
    unsigned k;
    int32_t v = 0;
    for (k = 0; k < octets; k++) {
        MEASURE(label, v = fw_tx_octet(&fw));
        if (v < 0) {
            break;
        }
    }
}

static void drain_all(void)
{
    while (fw_tx_octet(&fw) >= 0) {
    }
}

/* A first-order motor in raw units: y follows 4 u with a time constant of 8 samples; i = u / 2.
 * `boost` multiplies y (to provoke the speed trip). */
static int32_t motor_y;
static int loop_mode; /* a loop run: the speed is given at the tick, before the command */
static void sample(const char *label, int boost, unsigned line_octets)
{
    int16_t u = 0;
    int r = 0;
    int32_t y;
    CALLGRIND_TOGGLE_COLLECT;
    if (loop_mode) {
        fw_sample_measure(&fw, (int16_t)motor_y);
    }
    r = fw_sample_begin(&fw, &u);
    if (r) {
        y = motor_y * boost;
        if (y > 32767) {
            y = 32767;
        }
        fw_sample_end(&fw, (int16_t)y, (int16_t)(u / 2));
    }
    CALLGRIND_TOGGLE_COLLECT;
    CALLGRIND_DUMP_STATS_AT(label);
    motor_y += (4 * (int32_t)u - motor_y) / 8;
    drain(tx_label, line_octets);
}

static void configure(unsigned block, unsigned keepalive_ms, int u_limit, int y_limit)
{
    fw_octet p[26];
    static char label[32];
    sprintf(label, "tx:stream_block%u", block);
    tx_label = label;
    memset(p, 0, sizeof p);
    le32(p, fs_hz);
    p[4] = (fw_octet)block;
    le16(p + 6, keepalive_ms);
    le32(p + 8, 1000ul);
    le32(p + 12, 10000ul);
    le32(p + 16, 1000ul);
    le16(p + 20, (unsigned)u_limit);
    le16(p + 22, (unsigned)y_limit);
    le16(p + 24, 30000u);
    send_frame("rx:configure", FW_T_CONFIGURE, p, 26);
    drain("tx:answer", 64);
}

static void start_prbs(unsigned periods, unsigned long settle)
{
    fw_octet p[22];
    memset(p, 0, sizeof p);
    p[0] = 7;
    le32(p + 2, 0x60ul);
    le32(p + 6, 1ul);
    le16(p + 10, 3u);
    le16(p + 12, 2000u);
    le16(p + 14, 3000u);
    le16(p + 16, periods);
    le32(p + 18, settle);
    send_frame("rx:start_prbs", FW_T_START_PRBS, p, 22);
    drain("tx:answer", 64);
    if (!fw_running(&fw)) {
        fail("PRBS run started");
    }
}

static void start_sine(unsigned long freq_mhz, unsigned settle_cycles, unsigned cycles)
{
    fw_octet p[14];
    memset(p, 0, sizeof p);
    le32(p, freq_mhz);
    le16(p + 4, 2000u);
    le16(p + 6, 3000u);
    le16(p + 8, settle_cycles);
    le16(p + 10, cycles);
    p[12] = 3; /* stream and DFT */
    send_frame("rx:start_sine", FW_T_START_SINE, p, 14);
    drain("tx:answer", 64);
    if (!fw_running(&fw)) {
        fail("sine run started");
    }
}

/* The speed loop's controller, `n` sections and `taps` delay taps (format 2): d = 0.5, an
 * integrator, leaky sections with poles from 0.5 to 1 - 2^-20, taps alternating in sign (a
 * derivative's differences). */
static void load_ctrl(unsigned n, unsigned taps)
{
    fw_octet p[12];
    unsigned i;
    memset(p, 0, sizeof p);
    p[0] = FW_CTRL_FORMAT_TAPS;
    p[1] = (fw_octet)n;
    p[2] = (fw_octet)taps;
    le32(p + 4, 1ul << 23);   /* d = 0.5, Q24 */
    le32(p + 8, 2ul << 16);   /* 1/d = 2, Q16 */
    send_frame("rx:load_ctrl", FW_T_LOAD_CTRL, p, 12);
    drain("tx:answer", 64);
    for (i = 0; i < n + taps; i++) {
        unsigned long a = i == 0 ? (1ul << 30) : (1ul << 30) - ((1ul << 29) >> ((i - 1u) % 21u));
        memset(p, 0, sizeof p);
        p[0] = (fw_octet)i;
        if (i < n) {
            le32(p + 2, a);
            le32(p + 6, i == 0 ? 838861ul : 1000ul * (i + 1u)); /* 0.05 for the integrator, Q24 */
        } else {
            le32(p + 6, (i - n) % 2u ? 0xFFF00000ul : 0x00100000ul); /* -+1/16, Q24 */
        }
        send_frame("rx:load_section", FW_T_LOAD_SECTION, p, 10);
        drain("tx:answer", 64);
    }
    if (!fw.ctrl_ready) {
        fail("controller loaded");
    }
}

static void start_loop(unsigned long pre, unsigned long total)
{
    fw_octet p[12];
    memset(p, 0, sizeof p);
    le16(p, 0u);
    le16(p + 2, 20000u);
    le32(p + 4, pre);
    le32(p + 8, total);
    send_frame("rx:start_loop", FW_T_START_LOOP, p, 12);
    drain("tx:answer", 64);
    if (!fw_loop_running(&fw)) {
        fail("loop run started");
    }
}

/* Samples until the run ends; a KEEPALIVE every `ka` samples (0: none). */
static unsigned run(const char *label, unsigned max, unsigned ka, int boost, unsigned line)
{
    unsigned k;
    for (k = 0; k < max && fw_running(&fw); k++) {
        if (ka && k % ka == ka - 1u) {
            fw_octet id[2]; /* the run's id: only its own KEEPALIVE keeps it alive */
            le16(id, fw_run_id(&fw));
            send_frame("rx:keepalive", FW_T_KEEPALIVE, id, 2);
        }
        sample(label, boost, line);
    }
    return k;
}

int main(int argc, char **argv)
{
    fw_counters c;
    fw_octet big[FW_MAX_BODY];
    unsigned ka, k;
    if (argc != 3) {
        fprintf(stderr, "usage: cycles SAMPLE_RATE_HZ OCTETS_PER_SAMPLE\n");
        return 2;
    }
    fs_hz = (unsigned)strtoul(argv[1], 0, 10);
    octets_per_sample = (unsigned)strtoul(argv[2], 0, 10);
    if (fs_hz == 0u || fs_hz > 20000u || octets_per_sample == 0u) {
        fprintf(stderr, "cycles: bad arguments\n");
        return 2;
    }
    ka = 50u; /* a KEEPALIVE every 50 samples (keepalive_ms = 500) */
    fw_init(&fw, 0x1234u, 20000ul);
    send_frame("rx:hello", FW_T_HELLO, 0, 0);
    drain("tx:answer", 64);
    sample("sample:idle", 1, 0);

    /* PRBS, largest blocks (the longest DATA frames: the transmitter's CRC over 408 octets). */
    configure(FW_MAX_BLOCK, 500u, 30000, 32000);
    start_prbs(1, 40);
    run("sample:prbs", 100000u, ka, 1, octets_per_sample);
    send_frame("rx:status", FW_T_STATUS, 0, 0);
    drain("tx:answer", 64);
    {
        fw_octet q[2];
        le16(q, fw_run_id(&fw));
        send_frame("rx:end_query", FW_T_END_QUERY, q, 2);
        drain("tx:answer", 64);
    }
    drain_all();

    /* PRBS, 16-sample blocks (DATA frames of 108 octets). */
    configure(16, 500u, 30000, 32000);
    start_prbs(1, 40);
    run("sample:prbs", 100000u, ka, 1, octets_per_sample);
    drain_all();

    /* Sine with streaming and the DFT: the last sample ends the run (SINE_RESULT + STREAM_END). */
    configure(32, 500u, 30000, 32000);
    start_sine(47000ul * (fs_hz / 1000u ? fs_hz / 1000u : 1u), 2, 4);
    run("sample:sine", 100000u, ka, 1, octets_per_sample);
    drain_all();

    /* Blocks dropped: nobody drains the line while a PRBS streams. */
    configure(8, 500u, 30000, 32000);
    start_prbs(1, 0);
    run("sample:prbs_line_full", 400u, ka, 1, 0);
    fw_get_counters(&fw, &c);
    if (c.blocks_dropped == 0u) {
        fail("blocks dropped while the line is full");
    }
    send_frame("rx:stop", FW_T_STOP, 0, 0);
    drain_all();
    run("sample:stop", 10u, 0, 1, octets_per_sample);
    if (fw_running(&fw)) {
        fail("STOP ends the run");
    }
    drain_all();

    /* Keepalive expiry: no frames from the host; the ramp-down samples and the end. */
    configure(32, 50u, 30000, 32000);
    start_prbs(50, 0);
    run("sample:keepalive_ramp", 100000u, 0, 1, octets_per_sample);
    drain_all();

    /* Speed trip. */
    configure(32, 500u, 30000, 32000);
    start_prbs(1, 10);
    run("sample:trip", 100000u, ka, 8, octets_per_sample);
    send_frame("rx:status", FW_T_STATUS, 0, 0);
    drain_all();

    /* ESTOP during a run. */
    configure(32, 500u, 30000, 32000);
    start_prbs(1, 10);
    run("sample:prbs", 20u, ka, 1, octets_per_sample);
    send_frame("rx:estop", FW_T_ESTOP, 0, 0);
    drain_all();
    if (fw_running(&fw)) {
        fail("ESTOP ends the run");
    }

    /* The speed loop with the most sections and taps (48 + 8), then with the FOPID's 30 + 3
     * (`fracid tune` --form fopid --wc 50 --pm 60 --flat --dt 0.001 on the paper's PMSM): the
     * command clamped at first (the anti-windup's conditioned update), then in the linear range;
     * the run's last sample. */
    {
        static const unsigned sizes[2][2] = {{FW_MAX_SECTIONS, FW_MAX_TAPS}, {30u, 3u}};
        static const char *const labels[2] = {"sample:loop", "sample:loop_fopid"};
        unsigned v;
        for (v = 0; v < 2u; v++) {
            configure(32, 500u, 6000, 32000);
            load_ctrl(sizes[v][0], sizes[v][1]);
            motor_y = 0;
            loop_mode = 1;
            start_loop(20ul, 300ul);
            run(labels[v], 100000u, ka, 1, octets_per_sample);
            loop_mode = 0;
            /* the anti-windup path was taken, and the linear one */
            if (fw.last_clamped == 0u || fw.last_clamped >= 300u) {
                fail("the loop run is clamped in some samples, not all");
            }
            drain_all();
        }
    }

    /* A frame longer than any command (a DATA frame echoed back, valid CRC): the receiver stops
     * storing it at FW_RX_MAX_ENCODED octets and counts one error at its delimiter. */
    memset(big, 0, sizeof big);
    le16(big, 1u);
    le32(big + 2, 0ul);
    big[6] = FW_MAX_BLOCK;
    for (k = 8; k < 8u + 6u * FW_MAX_BLOCK; k++) {
        big[k] = (fw_octet)(k * 37u + 1u);
    }
    send_frame("rx:max_frame", FW_T_DATA, big, (int)(8u + 6u * FW_MAX_BLOCK));
    fw_get_counters(&fw, &c);
    if (fw_rx_errors(&fw) != 1u) {
        fail("the long frame is one receive error");
    }
    send_frame("rx:status", FW_T_STATUS, 0, 0);
    if (fw_rx_errors(&fw) != 1u || fw_tx_octet(&fw) < 0) {
        fail("a command after the long frame is answered");
    }
    printf("cycles: scenarios done at %u Hz, %u octets per sample; %lu runs\n", fs_hz,
           octets_per_sample, (unsigned long)c.runs_started);
    return 0;
}
