/* The speed controller: parallel first-order sections in Q-format and a short delay chain
 * (PROTOCOL.md section 3, "Speed loop"; the Rust twin is crates/drive/src/ctrl.rs,
 * bit-identical, tested).
 *
 * States z_i: 64-bit, Q32 raw voltage, saturated at +-2^56 (so that the sum of 48, with 8 taps
 * of at most 2^56 each, stays below 2^62). Poles a_i: Q30, |a_i| <= 1. Gains d, g_i, taps h_j:
 * Q24 raw voltage per raw speed LSB; the delay line w_j: the past conditioned errors,
 * |w_j| <= 2^17.
 * No right shift of a negative number (C99 leaves it implementation-defined), no left shift of
 * a negative number (undefined): magnitudes are shifted, or multiplied by powers of two. */
#include "fracfw.h"

#define Z_MAX ((int64_t)1 << 56)

/* round(p / 2^s), half away from zero, |p| < 2^63 */
static int64_t round_shift(int64_t p, unsigned s)
{
    int64_t h = (int64_t)1 << (s - 1u);
    return p >= 0 ? (p + h) >> s : -((-p + h) >> s);
}

/* round(a z / 2^30), half away from zero, for |a| <= 2^30 and |z| <= 2^56: the 86-bit product
 * as two 32x32 -> 64 products of the magnitudes (z = zh 2^32 + zl). */
static int64_t mul_q30(int64_t z, int32_t a)
{
    uint64_t m = (uint64_t)(z < 0 ? -z : z);
    uint64_t aa = (uint64_t)(a < 0 ? -(int64_t)a : (int64_t)a);
    uint64_t r = (aa * (m >> 32)) * 4u + ((aa * (m & 0xFFFFFFFFull) + ((uint64_t)1 << 29)) >> 30);
    return ((z < 0) != (a < 0)) ? -(int64_t)r : (int64_t)r;
}

static int64_t clamp64(int64_t v, int64_t lim) { return v > lim ? lim : (v < -lim ? -lim : v); }

void fw_ctrl_reset(fw_ctrl *c)
{
    uint16_t i;
    for (i = 0; i < FW_MAX_SECTIONS; i++) {
        c->z[i] = 0;
    }
    for (i = 0; i < FW_MAX_TAPS; i++) {
        c->w[i] = 0;
    }
}

int16_t fw_ctrl_step(fw_ctrl *c, int32_t e, int16_t u_limit, uint16_t *clamped)
{
    int64_t zsum = 0, v, u, lim = u_limit > 0 ? u_limit : 1, us, e_upd;
    uint16_t i, cl;
    for (i = 0; i < c->n; i++) {
        zsum += c->z[i];
    }
    for (i = 0; i < c->n_taps; i++) {
        zsum += (int64_t)c->h_q24[i] * c->w[i] * 256;
    }
    v = (int64_t)c->d_q24 * e * 256 + zsum;
    u = round_shift(v, 32u);
    cl = (uint16_t)(u > lim || u < -lim);
    us = clamp64(u, lim);
    *clamped = cl;
    if (!cl) {
        e_upd = e;
    } else if (c->dinv_q16 != 0) {
        /* Hanus: the error that gives the clamped output, d e' + sum z = u (Q16 difference) */
        int64_t diff = clamp64(round_shift(us * ((int64_t)1 << 32) - zsum, 16u), 2147483647ll);
        e_upd = clamp64(round_shift(diff * c->dinv_q16, 32u), 131072);
    } else if ((u > lim && e > 0) || (u < -lim && e < 0)) {
        return (int16_t)us; /* conditional integration: frozen while pushing into the clamp */
    } else {
        e_upd = e;
    }
    for (i = 0; i < c->n; i++) {
        c->z[i] = clamp64(mul_q30(c->z[i], c->a_q30[i]) + (int64_t)c->g_q24[i] * e_upd * 256, Z_MAX);
    }
    for (i = c->n_taps; i > 1u; i--) {
        c->w[i - 1u] = c->w[i - 2u];
    }
    if (c->n_taps > 0u) {
        c->w[0] = (int32_t)e_upd;
    }
    return (int16_t)us;
}
