/* fracfw unit tests: the shared test vectors (crates/drive/testvectors) and engine scenarios.
 * Usage: test_fw TESTVECTOR_DIR. Built by firmware/test.sh with 8-bit and 16-bit octet storage. */
#include "fracfw.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;
#define CHECK(c, ...)                                                                              \
    do {                                                                                           \
        if (!(c)) {                                                                                \
            failures++;                                                                            \
            fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                                   \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fprintf(stderr, "\n");                                                                 \
        }                                                                                          \
    } while (0)

/* Octets fed to the engine carry garbage in bits 8..15 in the 16-bit mode: they must be ignored. */
#ifdef FW_OCTET16
#define HI 0xA500u
#else
#define HI 0u
#endif

static int hexval(int c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* Parse hex ('-' = empty) into out; returns length. */
static int parse_hex(const char *s, fw_octet *out, int cap)
{
    int n = 0;
    if (strcmp(s, "-") == 0) return 0;
    while (s[0] && s[1] && n < cap) {
        out[n++] = (fw_octet)(hexval(s[0]) * 16 + hexval(s[1]));
        s += 2;
    }
    return n;
}

static FILE *open_vec(const char *dir, const char *name)
{
    char path[1024];
    FILE *f;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(3);
    }
    return f;
}

static char line[8192], a[4096], b[4096], c[4096], d[4096];
static fw_octet x[2048], y[2048], z[2048];
static fw_t fw;

static void test_crc(const char *dir)
{
    FILE *f = open_vec(dir, "crc.txt");
    int count = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned want;
        int n;
        if (line[0] == '#' || sscanf(line, "%4095s %4095s", a, b) != 2) continue;
        n = parse_hex(a, x, 2048);
        want = (unsigned)strtoul(b, 0, 16);
        CHECK(fw_crc16(0xFFFFu, x, (uint16_t)n) == want, "crc of %s", a);
        count++;
    }
    fclose(f);
    CHECK(count >= 5, "crc vectors read: %d", count);
}

static void test_cobs(const char *dir)
{
    FILE *f = open_vec(dir, "cobs.txt");
    int count = 0;
    while (fgets(line, sizeof line, f)) {
        int n, m, e, k;
        int32_t dn;
        if (line[0] == '#' || sscanf(line, "%4095s %4095s", a, b) != 2) continue;
        n = parse_hex(a, x, 2048);
        m = parse_hex(b, y, 2048);
        e = fw_cobs_encode(x, (uint16_t)n, z);
        CHECK(e == m && memcmp(z, y, (size_t)m * sizeof(fw_octet)) == 0, "cobs encode %s", a);
        for (k = 0; k < m; k++) z[k] = (fw_octet)(y[k] | HI);
        dn = fw_cobs_decode(z, (uint16_t)m);
        CHECK(dn == n, "cobs decode length %s: %ld", b, (long)dn);
        for (k = 0; k < n && dn == n; k++) CHECK((z[k] & 0xFF) == x[k], "cobs decode %s", b);
        count++;
    }
    fclose(f);
    CHECK(count >= 8, "cobs vectors read: %d", count);
    /* non-canonical and invalid encodings are rejected */
    {
        int k;
        y[0] = 0xFF;
        for (k = 1; k < 255; k++) y[k] = (fw_octet)k;
        y[255] = 0x01; /* redundant empty block after a full one */
        CHECK(fw_cobs_decode(y, 256) == -1, "non-canonical trailing 01 accepted");
        y[0] = 0x05, y[1] = 1, y[2] = 2;
        CHECK(fw_cobs_decode(y, 3) == -1, "code past the end accepted");
        y[0] = 0x03, y[1] = 0, y[2] = 2;
        CHECK(fw_cobs_decode(y, 3) == -1, "zero inside a block accepted");
    }
    /* round trip of bodies with zeros at every position mod 7 */
    {
        int n, k;
        for (n = 0; n < 600; n += 37) {
            int32_t dn;
            int e;
            for (k = 0; k < n; k++) x[k] = (fw_octet)((k % 7) ? (k * 13 + 1) & 0xFF : 0);
            e = fw_cobs_encode(x, (uint16_t)n, z);
            CHECK(e <= n + n / 254 + 1, "cobs overhead %d", n);
            dn = fw_cobs_decode(z, (uint16_t)e);
            CHECK(dn == n && memcmp(z, x, (size_t)n * sizeof(fw_octet)) == 0, "round trip %d", n);
        }
    }
}

static void test_prbs(const char *dir)
{
    FILE *f = open_vec(dir, "prbs.txt");
    int count = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned order;
        unsigned long taps, seed;
        uint32_t s;
        size_t k;
        if (line[0] == '#' || sscanf(line, "%u %lx %lu %4095s", &order, &taps, &seed, a) != 4)
            continue;
        s = (uint32_t)seed;
        for (k = 0; a[k]; k++) {
            uint16_t bit = fw_lfsr_next(&s, (uint32_t)taps, (uint16_t)order);
            CHECK(bit == (uint16_t)(a[k] - '0'), "prbs order %u bit %lu", order, (unsigned long)k);
        }
        count++;
    }
    fclose(f);
    CHECK(count >= 4, "prbs vectors read: %d", count);
}

/* Pull one whole frame from the transmitter; returns its length (with both delimiters) or 0. */
static int pull_frame(fw_t *e, fw_octet *out)
{
    int n = 0;
    int32_t v = fw_tx_octet(e);
    if (v < 0) return 0;
    out[n++] = (fw_octet)v;
    do {
        v = fw_tx_octet(e);
        CHECK(v >= 0, "frame ended early");
        if (v < 0) break;
        out[n++] = (fw_octet)v;
    } while (fw_tx_busy(e));
    return n;
}

static uint16_t feed(fw_t *e, const fw_octet *w, int n)
{
    uint16_t r = 0;
    int k;
    for (k = 0; k < n; k++) {
        uint16_t q = fw_rx_octet(e, (uint16_t)(w[k] | HI));
        if (q) r = q;
    }
    return r;
}

/* Decode a pulled frame into a body (without CRC); returns payload pointer via body + 4. */
static int decode_frame(const fw_octet *w, int n, fw_octet *body)
{
    int k;
    int32_t dn;
    CHECK(n >= 2 && w[0] == 0 && w[n - 1] == 0, "delimiters");
    for (k = 1; k < n - 1; k++) body[k - 1] = w[k];
    dn = fw_cobs_decode(body, (uint16_t)(n - 2));
    CHECK(dn >= 6, "decodes");
    if (dn < 6) return -1;
    CHECK(fw_crc16(0xFFFFu, body, (uint16_t)dn) == 0, "crc residue");
    return (int)dn - 2;
}

static void test_frames(const char *dir)
{
    FILE *f = open_vec(dir, "frames.txt");
    int count = 0;
    while (fgets(line, sizeof line, f)) {
        int n, len;
        unsigned seq;
        if (line[0] == '#' || sscanf(line, "%4095s %x %4095s", a, &seq, b) != 3) continue;
        n = parse_hex(b, x, 2048);
        len = decode_frame(x, n, y);
        if (len < 0) continue;
        CHECK((y[2] | (y[3] << 8)) == (int)seq, "%s seq", a);
        if ((y[1] & 0xFF) < 0x80) {
            /* host to drive: the engine accepts it as a valid frame of that type */
            fw_init(&fw, 0xBEEF, 20000);
            CHECK(feed(&fw, x, n) == (0x100u | y[1]), "%s not accepted", a);
            CHECK(fw_rx_errors(&fw) == 0, "%s counted as error", a);
        } else {
            /* drive to host: the transmitter produces these exact wire bytes from the body */
            int k, m;
            fw_init(&fw, 0xBEEF, 20000);
            if (len > (int)FW_ANSWER_BODY) {
                for (k = 0; k < len; k++) fw.slot[0].b[k] = y[k];
                fw.slot[0].len = (uint16_t)len;
                fw.data_count = 1;
            } else {
                for (k = 0; k < len; k++) fw.ans[0].b[k] = y[k];
                fw.ans[0].len = (uint16_t)len;
                fw.ans_count = 1;
            }
            m = pull_frame(&fw, z);
            CHECK(m == n && memcmp(z, x, (size_t)n * sizeof(fw_octet)) == 0, "%s wire bytes", a);
            CHECK(fw_tx_octet(&fw) == -1, "%s: nothing more to send", a);
        }
        if (strcmp(a, "HELLO") == 0) {
            /* the engine's own HELLO_REPLY for boot id 0xBEEF, 20 kHz: the HELLO_REPLY vector */
            fw_init(&fw, 0xBEEF, 20000);
            feed(&fw, x, n);
            {
                int m = pull_frame(&fw, z);
                FILE *g = open_vec(dir, "frames.txt");
                int found = 0;
                while (fgets(line, sizeof line, g)) {
                    if (sscanf(line, "%4095s %x %4095s", d, &seq, c) == 3 &&
                        strcmp(d, "HELLO_REPLY") == 0) {
                        int w = parse_hex(c, y, 2048);
                        found = 1;
                        CHECK(m == w && memcmp(z, y, (size_t)w * sizeof(fw_octet)) == 0,
                              "HELLO_REPLY differs from the vector");
                    }
                }
                fclose(g);
                CHECK(found, "HELLO_REPLY vector");
            }
        }
        count++;
    }
    fclose(f);
    CHECK(count >= 16, "frame vectors read: %d", count);
}

/* ---- engine scenarios ---- */

static uint16_t host_seq = 100;

static void send_cmd(fw_t *e, uint16_t type, const fw_octet *payload, int plen, uint16_t seq)
{
    fw_octet body[64], wire[80];
    int n = 0, k, m;
    uint16_t crc;
    body[n++] = FW_PROTO_VERSION;
    body[n++] = (fw_octet)type;
    body[n++] = (fw_octet)(seq & 0xFF);
    body[n++] = (fw_octet)(seq >> 8);
    for (k = 0; k < plen; k++) body[n++] = payload[k];
    crc = fw_crc16(0xFFFFu, body, (uint16_t)n);
    body[n++] = (fw_octet)(crc & 0xFF);
    body[n++] = (fw_octet)(crc >> 8);
    wire[0] = 0;
    m = fw_cobs_encode(body, (uint16_t)n, wire + 1);
    wire[m + 1] = 0;
    feed(e, wire, m + 2);
}

/* Send a command and return the answer's body (type at [1]); drains queued data first. */
static int command(fw_t *e, uint16_t type, const fw_octet *p, int plen, fw_octet *ans)
{
    int n;
    uint16_t seq = host_seq++;
    send_cmd(e, type, p, plen, seq);
    for (;;) {
        n = pull_frame(e, z);
        if (n == 0) return -1;
        n = decode_frame(z, n, ans);
        if (n < 0) return -1;
        if ((ans[1] & 0xFF) != FW_T_DATA && (ans[1] & 0xFF) != FW_T_STREAM_END &&
            (ans[1] & 0xFF) != FW_T_SINE_RESULT)
            return n;
    }
}

static void le16(fw_octet *p, unsigned v) { p[0] = (fw_octet)(v & 0xFF), p[1] = (fw_octet)((v >> 8) & 0xFF); }
static void le32(fw_octet *p, unsigned long v) { le16(p, (unsigned)(v & 0xFFFF)), le16(p + 2, (unsigned)(v >> 16)); }
static unsigned g16(const fw_octet *p) { return (unsigned)((p[0] & 0xFF) | ((p[1] & 0xFF) << 8)); }
static unsigned long g32(const fw_octet *p) { return g16(p) | ((unsigned long)g16(p + 2) << 16); }
static int s16(const fw_octet *p) { unsigned v = g16(p); return v >= 0x8000u ? (int)v - 0x10000 : (int)v; }

static void configure(fw_t *e, unsigned fs, unsigned block, int ulim, int ylim)
{
    fw_octet p[26], r[512];
    int n;
    memset(p, 0, sizeof p);
    le32(p, fs);
    p[4] = (fw_octet)block;
    le16(p + 6, 500);
    le32(p + 8, 1000), le32(p + 12, 10000), le32(p + 16, 1000);
    le16(p + 20, (unsigned)ulim), le16(p + 22, (unsigned)ylim), le16(p + 24, 30000);
    n = command(e, FW_T_CONFIGURE, p, 26, r);
    CHECK(n == 12 && (r[1] & 0xFF) == FW_T_ACK, "configure acked");
}

static void prbs_payload(fw_octet *p, unsigned periods, int amp, int off, unsigned long settle)
{
    memset(p, 0, 22);
    p[0] = 7;
    le32(p + 2, 0x60), le32(p + 6, 1), le16(p + 10, 2), le16(p + 12, (unsigned)amp);
    le16(p + 14, (unsigned)off), le16(p + 16, periods), le32(p + 18, settle);
}

/* Run samples with a plant y = u/2 (i = u/4), collecting DATA into u/y arrays; returns when the
 * run ended (STREAM_END seen) or after max samples. */
static int16_t got_u[4096];
static int got_n, end_reason, end_total, end_sent;

static void run_samples(fw_t *e, int max, int drain)
{
    int k;
    got_n = 0, end_reason = -1;
    for (k = 0; k < max; k++) {
        int16_t u;
        int n;
        if (fw_sample_begin(e, &u)) fw_sample_end(e, (int16_t)(u / 2), (int16_t)(u / 4));
        while (drain && (n = pull_frame(e, z)) > 0) {
            fw_octet body[512];
            int len = decode_frame(z, n, body);
            if (len < 0) continue;
            if ((body[1] & 0xFF) == FW_T_DATA) {
                unsigned long first = g32(body + 6);
                int cnt = body[10] & 0xFF, j;
                CHECK((int)first == got_n, "DATA first_index %lu, expected %d", first, got_n);
                for (j = 0; j < cnt && got_n < 4096; j++) {
                    got_u[got_n++] = (int16_t)s16(body + 12 + 6 * j);
                    CHECK(s16(body + 14 + 6 * j) == s16(body + 12 + 6 * j) / 2, "y sample");
                }
            } else if ((body[1] & 0xFF) == FW_T_STREAM_END) {
                end_reason = body[6] & 0xFF;
                end_total = (int)g32(body + 8);
                end_sent = (int)g32(body + 12);
            }
        }
    }
}

/* Run up to max samples with a plant y = u/2 while other frames arrive: a STATUS every 200
 * samples and a HELLO every 250 (another program polling the drive), and with ka_every > 0 a
 * KEEPALIVE of run ka_id every ka_every samples. Returns the samples the run produced; *reason is
 * its STREAM_END's reason (-1: none). */
static int run_with_frames(fw_t *e, int max, unsigned ka_id, int ka_every, int *reason)
{
    int k, produced = 0;
    fw_octet ka[2];
    *reason = -1;
    le16(ka, ka_id);
    for (k = 0; k < max; k++) {
        int16_t u;
        int n;
        if (k % 200 == 100) send_cmd(e, FW_T_STATUS, 0, 0, host_seq++);
        if (k % 250 == 50) send_cmd(e, FW_T_HELLO, 0, 0, host_seq++);
        if (ka_every > 0 && k % ka_every == 0) send_cmd(e, FW_T_KEEPALIVE, ka, 2, host_seq++);
        if (fw_sample_begin(e, &u)) {
            fw_sample_end(e, (int16_t)(u / 2), (int16_t)(u / 4));
            produced++;
        }
        while ((n = pull_frame(e, z)) > 0) {
            fw_octet body[512];
            int len = decode_frame(z, n, body);
            if (len >= 0 && (body[1] & 0xFF) == FW_T_STREAM_END) *reason = body[6] & 0xFF;
        }
    }
    return produced;
}

/* The keepalive is the run's own (protocol 3): another program's STATUS and HELLO, and a
 * KEEPALIVE of another run id, do not keep a run alive (it ends KEEPALIVE after 500 + 50
 * samples, as without any frame: an orphaned run stops); a KEEPALIVE of its run id every 300
 * samples does (the run completes). */
static void test_keepalive_is_the_runs_own(void)
{
    fw_octet p[32], r[512];
    int n, produced, reason;
    unsigned id;
    fw_counters cnt;
    fw_init(&fw, 0x4321, 20000);
    configure(&fw, 1000, 32, 3500, 30000);
    prbs_payload(p, 4, 1000, 3000, 10); /* 10 + 4 * 254 = 1026 samples */
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    CHECK(n == 12 && (r[1] & 0xFF) == FW_T_ACK, "start");
    id = g16(r + 6);
    produced = run_with_frames(&fw, 1500, id + 1u, 100, &reason);
    CHECK(reason == FW_END_KEEPALIVE && produced == 501 + 50,
          "polled, another run's keepalive: reason %d after %d samples", reason, produced);
    fw_get_counters(&fw, &cnt);
    CHECK(cnt.keepalives == 0, "no keepalive of the run counted: %lu", (unsigned long)cnt.keepalives);
    configure(&fw, 1000, 32, 3500, 30000); /* clears the latched KEEPALIVE fault */
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    CHECK(n == 12 && (r[1] & 0xFF) == FW_T_ACK, "start again");
    id = g16(r + 6);
    produced = run_with_frames(&fw, 1500, id, 300, &reason);
    CHECK(reason == FW_END_COMPLETE && produced == 1026,
          "the run's keepalive: reason %d after %d samples", reason, produced);
    fw_get_counters(&fw, &cnt);
    CHECK(cnt.keepalives == 4, "keepalives of the run: %lu", (unsigned long)cnt.keepalives);
}

static void test_engine(void)
{
    fw_octet p[32], r[512];
    int n, k;
    uint32_t s = 1;
    uint16_t bit = 0;
    fw_init(&fw, 0x1234, 20000);
    /* unconfigured: START is refused */
    prbs_payload(p, 1, 1000, 3000, 10);
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    CHECK(n == 8 && (r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_NOT_CONFIGURED, "nak");
    configure(&fw, 1000, 32, 3500, 30000);
    /* a PRBS run: 10 settle + 127 * 2 samples, u = 3000 +- 1000 clamped to 3500 */
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    CHECK(n == 12 && (r[1] & 0xFF) == FW_T_ACK && g32(r + 8) == 264, "start acked, total 264");
    run_samples(&fw, 400, 1);
    CHECK(got_n == 264 && end_reason == 0 && end_total == 264 && end_sent == 264,
          "complete run: %d samples, reason %d", got_n, end_reason);
    for (k = 0; k < got_n; k++) {
        int want;
        if (k < 10) {
            want = 3000;
        } else {
            if ((k - 10) % 2 == 0) bit = fw_lfsr_next(&s, 0x60, 7);
            want = bit ? 3500 : 2000; /* 4000 clamped */
        }
        CHECK(got_u[k] == want, "u[%d] = %d, want %d", k, got_u[k], want);
    }
    /* STATUS: idle, run 1, 264 done, clamped = number of 1 bits * 2 = 64 * 2 */
    n = command(&fw, FW_T_STATUS, 0, 0, r);
    CHECK(n == 20 && (r[4] & 0xFF) == 1 && g16(r + 6) == 1 && g32(r + 8) == 264 &&
              g16(r + 14) == 0x1234 && g16(r + 18) == 128,
          "status after the run (clamped %u)", g16(r + 18));
    /* a duplicated START (same seq) is answered from the cache and never runs twice */
    {
        fw_counters cnt;
        uint16_t seq = host_seq++;
        send_cmd(&fw, FW_T_START_PRBS, p, 22, seq);
        send_cmd(&fw, FW_T_START_PRBS, p, 22, seq);
        fw_get_counters(&fw, &cnt);
        CHECK(cnt.runs_started == 2 && cnt.replays == 1, "replay: runs %lu replays %lu",
              (unsigned long)cnt.runs_started, (unsigned long)cnt.replays);
        n = pull_frame(&fw, z), n = decode_frame(z, n, r);
        n = pull_frame(&fw, z), n = decode_frame(z, n, y);
        CHECK(memcmp(r, y, 14 * sizeof(fw_octet)) == 0, "replayed ACK identical");
        /* ESTOP: run aborted, fault latched, START refused with FAULT until CONFIGURE */
        run_samples(&fw, 20, 1);
        n = command(&fw, FW_T_ESTOP, 0, 0, r);
        CHECK((r[1] & 0xFF) == FW_T_ACK && !fw_running(&fw), "estop");
        n = command(&fw, FW_T_START_PRBS, p, 22, r);
        CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_FAULT && g16(r + 6) == 1,
              "start after estop: fault");
        le16(p + 30 - 30, 2); /* END_QUERY of run 2 */
        n = command(&fw, FW_T_END_QUERY, p, 2, r);
        CHECK((r[1] & 0xFF) == FW_T_STREAM_END && (r[6] & 0xFF) == FW_END_ESTOP, "end query");
    }
    /* keepalive: 500 ms at 1 kHz without frames ramps down over 50 samples, reason KEEPALIVE */
    configure(&fw, 1000, 32, 3500, 30000);
    prbs_payload(p, 40, 1000, 3000, 10);
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK, "start");
    run_samples(&fw, 700, 1);
    CHECK(end_reason == FW_END_KEEPALIVE && got_n == 501 + 50, "keepalive: reason %d after %d",
          end_reason, got_n);
    CHECK(got_u[got_n - 1] == 0, "ramped to zero");
    /* speed trip: y = u/2 beyond 1400 trips at the first sample with u = 3000 */
    configure(&fw, 1000, 32, 3500, 1400);
    prbs_payload(p, 1, 1000, 3000, 10);
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    run_samples(&fw, 50, 1);
    CHECK(end_reason == FW_END_LIMIT && got_n == 1, "trip: reason %d after %d", end_reason, got_n);
    n = command(&fw, FW_T_STATUS, 0, 0, r);
    CHECK((r[4] & 0xFF) == 3 && (r[5] & 0xFF) == FW_FAULT_SPEED, "speed fault latched");
    /* a corrupted frame is counted and not answered */
    {
        fw_octet w[] = {0, 0x04, 0x01, 0x07, 0x07, 0x03, 0x97, 0xDF, 0};
        uint16_t before = fw_rx_errors(&fw);
        feed(&fw, w, 9);
        CHECK(fw_rx_errors(&fw) == before + 1 && fw_tx_octet(&fw) == -1, "crc error counted");
    }
    /* a frame longer than any command is refused as one error without being decoded, even a
     * well-formed one (a 5-sample DATA frame echoed back: 44-octet body, valid CRC, which a
     * decoding receiver accepts); the receiver recovers at its delimiter */
    {
        fw_octet lp[38];
        uint16_t before = fw_rx_errors(&fw);
        for (k = 0; k < 38; k++) lp[k] = (fw_octet)(k + 1);
        lp[6] = 5, lp[7] = 0;
        send_cmd(&fw, FW_T_DATA, lp, 38, host_seq++);
        CHECK(fw_rx_errors(&fw) == before + 1 && fw_tx_octet(&fw) == -1, "long frame refused");
        n = command(&fw, FW_T_STATUS, 0, 0, r);
        CHECK(n == 20 && (r[1] & 0xFF) == FW_T_STATUS_REPLY, "status after a long frame");
    }
    /* blocks dropped when nobody drains the line: whole blocks, counted in STREAM_END */
    configure(&fw, 1000, 10, 3500, 30000);
    prbs_payload(p, 1, 1000, 3000, 6);
    n = command(&fw, FW_T_START_PRBS, p, 22, r);
    run_samples(&fw, 300, 0);
    run_samples(&fw, 1, 1);
    CHECK(end_reason == 0 && end_total == 260 && end_sent == (int)FW_TX_BLOCKS * 10,
          "drops: sent %d", end_sent);
}

/* ctrl.txt: fw_ctrl_step against the shared fixed-point steps (the Rust FixedCtrl made them) */
static void test_ctrl(const char *dir)
{
    FILE *f = open_vec(dir, "ctrl.txt");
    static fw_ctrl k;
    int16_t lim = 1;
    int steps = 0, ctrls = 0;
    while (fgets(line, sizeof line, f)) {
        char *p = line, *q;
        long long v[160];
        int nv = 0;
        if (line[0] == '#') continue;
        if (strncmp(line, "CTRL", 4) == 0) {
            p += 4;
            while (*p == ' ') p++;
            while (*p && *p != ' ') p++; /* the name */
        } else if (strncmp(line, "STEP", 4) == 0) {
            p += 4;
        } else {
            continue;
        }
        while (nv < 160) {
            long long t = strtoll(p, &q, 10);
            if (q == p) break;
            v[nv++] = t;
            p = q;
        }
        if (line[0] == 'C') {
            int i;
            k.d_q24 = (int32_t)v[0];
            k.dinv_q16 = (int32_t)v[1];
            lim = (int16_t)v[2];
            k.n = (uint16_t)v[3];
            k.loaded = k.n;
            for (i = 0; i < k.n; i++) {
                k.a_q30[i] = (int32_t)v[4 + 2 * i];
                k.g_q24[i] = (int32_t)v[5 + 2 * i];
            }
            k.n_taps = (uint16_t)v[4 + 2 * k.n];
            for (i = 0; i < k.n_taps; i++) {
                k.h_q24[i] = (int32_t)v[5 + 2 * k.n + i];
            }
            k.loaded = (uint16_t)(k.n + k.n_taps);
            fw_ctrl_reset(&k);
            ctrls++;
        } else {
            uint16_t cl;
            int16_t u = fw_ctrl_step(&k, (int32_t)v[0], lim, &cl);
            int i, same = 1;
            for (i = 0; i < k.n; i++) same &= k.z[i] == (int64_t)v[3 + i];
            for (i = 0; i < k.n_taps; i++) same &= k.w[i] == (int32_t)v[3 + k.n + i];
            same &= nv == 3 + k.n + k.n_taps;
            CHECK(u == v[1] && cl == v[2] && same, "ctrl step %d (e %lld): u %d clamped %u", steps,
                  v[0], u, cl);
            steps++;
        }
    }
    fclose(f);
    CHECK(ctrls == 4 && steps >= 360, "ctrl vectors read: %d controllers, %d steps", ctrls, steps);
}

/* The speed loop through the protocol: a PI on a plant y_(k+1) = y_k + (u_k - y_k)/8 (raw), the
 * command computed from the speed given by fw_sample_measure() at each tick. */
static void test_loop(void)
{
    fw_octet p[32], r[512];
    int n, k, clamped = 0;
    int32_t y = 0, yref = 0, zref = 0;
    fw_init(&fw, 0x4242, 20000);
    memset(p, 0, sizeof p);
    le16(p, 0), le16(p + 2, 1000), le32(p + 4, 10), le32(p + 8, 300);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_NOT_CONFIGURED, "loop unconfigured");
    configure(&fw, 1000, 32, 3000, 30000);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_NO_CONTROLLER, "no controller");
    /* LOAD_CTRL: format 3 refused; then d = 2, dinv = 1/2, one integrator g = 0.25 */
    memset(p, 0, sizeof p);
    p[0] = 3, p[1] = 1;
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 0,
          "unknown controller format");
    p[0] = FW_CTRL_FORMAT, p[1] = 1;
    le32(p + 4, 2ul << 24), le32(p + 8, 32768ul);
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK, "load ctrl");
    memset(p, 0, sizeof p);
    p[0] = 1;
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE, "section out of order");
    p[0] = 0;
    le32(p + 2, 1ul << 30), le32(p + 6, 1ul << 22);
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK, "load section");
    memset(p, 0, sizeof p);
    le16(p, 0), le16(p + 2, 2000), le32(p + 4, 11), le32(p + 8, 10);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 4,
          "pre > total");
    le32(p + 4, 10), le32(p + 8, 300);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK(n == 12 && (r[1] & 0xFF) == FW_T_ACK && g32(r + 8) == 300, "loop started");
    got_n = 0, end_reason = -1;
    for (k = 0; k < 400; k++) {
        int16_t u;
        CHECK(fw_loop_running(&fw) == (k < 300), "loop running at %d", k);
        fw_sample_measure(&fw, (int16_t)y);
        if (fw_sample_begin(&fw, &u)) {
            /* independent PI in exact integers: S = sum of the errors so far, u = round(2 e +
             * S/4); clamped at 3000, S takes e' = round((4 * 3000 - S)/8), the error that gives
             * 3000 (Hanus), instead of e */
            int32_t e = (k < 10 ? 0 : 2000) - yref, v4 = 8 * e + zref, want;
            want = v4 >= 0 ? (v4 + 2) / 4 : -((-v4 + 2) / 4);
            if (want > 3000) {
                int32_t t = 12000 - zref;
                want = 3000, clamped++;
                e = t >= 0 ? (t + 4) / 8 : -((-t + 4) / 8);
            }
            zref += e;
            CHECK(u == want, "loop u[%d] = %d, want %ld", k, u, (long)want);
            fw_sample_end(&fw, (int16_t)y, 0);
            y += (u - y) / 8;
            yref = y;
        }
        while ((n = pull_frame(&fw, z)) > 0) {
            fw_octet body[512];
            if (decode_frame(z, n, body) >= 0 && (body[1] & 0xFF) == FW_T_STREAM_END)
                end_reason = body[6] & 0xFF, end_total = (int)g32(body + 8);
        }
    }
    CHECK(end_reason == FW_END_COMPLETE && end_total == 300, "loop run complete");
    CHECK(clamped > 0 && y > 1950 && y < 2050, "loop: clamped %d samples, y = %ld", clamped, (long)y);
    /* CONFIGURE clears the controller */
    configure(&fw, 1000, 32, 3000, 30000);
    memset(p, 0, sizeof p);
    le32(p + 8, 10);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_NO_CONTROLLER, "cleared by CONFIGURE");
    /* format 1: at most 24 sections and no taps; format 2: 48 sections and 8 taps */
    memset(p, 0, sizeof p);
    p[0] = FW_CTRL_FORMAT, p[1] = 25;
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 1,
          "format 1: 25 sections");
    p[1] = 1, p[2] = 1;
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 2,
          "format 1: a tap");
    p[0] = FW_CTRL_FORMAT_TAPS, p[1] = 49, p[2] = 0;
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 1,
          "format 2: 49 sections");
    p[1] = 1, p[2] = 9;
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 2,
          "format 2: 9 taps");
    p[1] = 1, p[2] = 2;
    le32(p + 4, 2ul << 24), le32(p + 8, 32768ul);
    n = command(&fw, FW_T_LOAD_CTRL, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK && fw.ctrl.n == 1 && fw.ctrl.n_taps == 2, "format 2 header");
    memset(p, 0, sizeof p);
    le32(p + 2, 1ul << 29), le32(p + 6, 1ul << 22);
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK && fw.ctrl.loaded == 1u, "format 2 section");
    p[0] = 1;
    le32(p + 2, 5), le32(p + 6, 7ul << 20);
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_BAD_VALUE && g16(r + 6) == 2,
          "a tap with a pole");
    le32(p + 2, 0);
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK && fw.ctrl.h_q24[0] == (int32_t)(7ul << 20), "tap 1");
    memset(p, 0, sizeof p);
    le32(p + 8, 10);
    n = command(&fw, FW_T_START_LOOP, p, 12, r);
    CHECK((r[1] & 0xFF) == FW_T_NAK && (r[5] & 0xFF) == FW_NAK_NO_CONTROLLER, "a tap missing");
    memset(p, 0, sizeof p);
    p[0] = 2;
    le32(p + 6, (uint32_t)-(3l << 20));
    n = command(&fw, FW_T_LOAD_SECTION, p, 10, r);
    CHECK((r[1] & 0xFF) == FW_T_ACK && fw.ctrl.h_q24[1] == -(3l << 20) && fw.ctrl_ready == 1u,
          "tap 2");
}

static void test_sine(void)
{
    /* the Q30 sine is within 1e-7 of sin() over the circle (checked on a grid) */
    int32_t s, c;
    uint32_t ph;
    int worst = 0;
    for (ph = 0; ph < 0xFFFFF000u; ph += 0x000FF0F1u) {
        double t = (double)ph / 4294967296.0 * 6.283185307179586;
        double es, ec;
        fw_sincos_q30(ph, &s, &c);
        es = s / 1073741824.0 - __builtin_sin(t);
        ec = c / 1073741824.0 - __builtin_cos(t);
        if (es < 0) es = -es;
        if (ec < 0) ec = -ec;
        if (es > 1e-7 || ec > 1e-7) worst++;
    }
    CHECK(worst == 0, "sine error above 1e-7 at %d points", worst);
}

int main(int argc, char **argv)
{
    const char *dir = argc > 1 ? argv[1] : "../crates/drive/testvectors";
    test_crc(dir);
    test_cobs(dir);
    test_prbs(dir);
    test_frames(dir);
    test_engine();
    test_keepalive_is_the_runs_own();
    test_ctrl(dir);
    test_loop();
    test_sine();
#ifdef FW_OCTET16
    printf("fracfw tests (16-bit octet storage, sizeof(fw_t) = %lu): %s\n",
           (unsigned long)sizeof(fw_t), failures ? "FAILED" : "ok");
#else
    printf("fracfw tests (8-bit octets, sizeof(fw_t) = %lu): %s\n", (unsigned long)sizeof(fw_t),
           failures ? "FAILED" : "ok");
#endif
    return failures ? 1 : 0;
}
