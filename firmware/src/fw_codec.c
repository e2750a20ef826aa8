/* CRC-16/MCRF4XX, COBS, the PRBS LFSR and the Q30 sine: the pure building blocks of fracfw. */
#include "fracfw.h"
#include "fw_sine_table.h"

/* CRC-16/MCRF4XX (reflected poly 0x8408), one nibble at a time: 16 table words. */
static const uint16_t crc_nibble[16] = {0x0000u, 0x1081u, 0x2102u, 0x3183u, 0x4204u, 0x5285u,
                                        0x6306u, 0x7387u, 0x8408u, 0x9489u, 0xA50Au, 0xB58Bu,
                                        0xC60Cu, 0xD68Du, 0xE70Eu, 0xF78Fu};

uint16_t fw_crc16(uint16_t crc, const fw_octet *p, uint16_t n)
{
    uint16_t k;
    for (k = 0; k < n; k++) {
        crc = (uint16_t)(crc ^ (uint16_t)(p[k] & 0xFFu));
        crc = (uint16_t)((crc >> 4) ^ crc_nibble[crc & 0xFu]);
        crc = (uint16_t)((crc >> 4) ^ crc_nibble[crc & 0xFu]);
    }
    return crc;
}

uint16_t fw_cobs_encode(const fw_octet *in, uint16_t n, fw_octet *out)
{
    uint16_t pos = 0, o = 0, pending = 1;
    for (;;) {
        uint16_t run = 0, k;
        if (pos == n && !pending) {
            break;
        }
        while (pos + run < n && run < 254u && (in[pos + run] & 0xFFu) != 0u) {
            run++;
        }
        out[o++] = (fw_octet)(run + 1u);
        for (k = 0; k < run; k++) {
            out[o++] = (fw_octet)(in[pos + k] & 0xFFu);
        }
        pos = (uint16_t)(pos + run);
        if (run == 254u) {
            pending = 0; /* no implied zero after a full block */
        } else if (pos < n) {
            pos++; /* the zero this block ends with */
            pending = 1;
        } else {
            pending = 0;
        }
    }
    return o;
}

int32_t fw_cobs_decode(fw_octet *buf, uint16_t n)
{
    uint16_t r = 0, w = 0;
    uint16_t prev_full = 0;
    while (r < n) {
        uint16_t code = (uint16_t)(buf[r] & 0xFFu), k;
        if (code == 0u || (uint32_t)r + code > n) {
            return -1;
        }
        if (code == 1u && r + 1u == n && prev_full) {
            return -1; /* redundant empty block after a full one: not canonical */
        }
        r++;
        for (k = 1; k < code; k++) {
            uint16_t v = (uint16_t)(buf[r++] & 0xFFu);
            if (v == 0u) {
                return -1;
            }
            buf[w++] = (fw_octet)v;
        }
        prev_full = (uint16_t)(code == 0xFFu);
        if (code != 0xFFu && r < n) {
            buf[w++] = 0;
        }
    }
    return (int32_t)w;
}

uint16_t fw_lfsr_next(uint32_t *state, uint32_t taps, uint16_t order)
{
    uint32_t s = *state;
    uint32_t x = s & taps;
    uint32_t mask = (order >= 32u) ? 0xFFFFFFFFul : ((1ul << order) - 1ul);
    uint16_t out = (uint16_t)((s >> (order - 1u)) & 1ul);
    /* parity of x */
    x ^= x >> 16;
    x ^= x >> 8;
    x ^= x >> 4;
    x ^= x >> 2;
    x ^= x >> 1;
    *state = ((s << 1) | (x & 1ul)) & mask;
    return out;
}

/* 2 pi * 2^29, rounded: converts the 22-bit phase remainder to Q30 radians (rem * this >> 31). */
#define TWO_PI_Q29 3373259426ull

void fw_sincos_q30(uint32_t phase, int32_t *s, int32_t *c)
{
    uint16_t i = (uint16_t)(phase >> 22);
    uint32_t rem = phase & 0x3FFFFFul;
    int64_t d = (int64_t)(((uint64_t)rem * TWO_PI_Q29) >> 31); /* Q30 rad, < 0.0062 */
    int64_t d2h = (d * d) >> 31;                                /* d^2 / 2, Q30 */
    int64_t s0 = fw_sin_table[i];
    int64_t c0 = fw_sin_table[(uint16_t)((i + 256u) & 1023u)];
    /* sin(a + d) = sin a (1 - d^2/2) + cos a d,  cos(a + d) = cos a (1 - d^2/2) - sin a d */
    int64_t sv = s0 - ((s0 * d2h) >> 30) + ((c0 * d) >> 30);
    int64_t cv = c0 - ((c0 * d2h) >> 30) - ((s0 * d) >> 30);
    *s = (int32_t)sv;
    *c = (int32_t)cv;
}

int32_t fw_sine_command(uint32_t phase, int16_t amplitude, int16_t offset)
{
    int32_t s, c;
    int64_t p;
    int32_t r;
    fw_sincos_q30(phase, &s, &c);
    p = (int64_t)amplitude * s;
    /* round half away from zero, Q30 -> integer */
    if (p >= 0) {
        r = (int32_t)((p + (1ll << 29)) >> 30);
    } else {
        r = -(int32_t)((-p + (1ll << 29)) >> 30);
    }
    return (int32_t)offset + r;
}
