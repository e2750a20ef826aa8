/* The speed controller: parallel first-order sections in Q-format (PROTOCOL.md section 3,
 * "Speed loop"; the Rust twin is crates/drive/src/ctrl.rs, bit-identical, tested). */
#include "fracfw.h"

/* round(p / 2^s), half away from zero (no right shift of a negative number: C99 leaves it
 * implementation-defined). */
static int64_t round_shift(int64_t p, unsigned s)
{
    int64_t h = (int64_t)1 << (s - 1u);
    return p >= 0 ? (p + h) >> s : -((-p + h) >> s);
}

static int32_t sat32(int64_t v)
{
    if (v > 2147483647ll) return 2147483647l;
    if (v < -2147483647ll - 1) return -2147483647l - 1;
    return (int32_t)v;
}

void fw_ctrl_reset(fw_ctrl *c)
{
    uint16_t i;
    for (i = 0; i < FW_MAX_SECTIONS; i++) {
        c->z[i] = 0;
    }
}

int16_t fw_ctrl_step(fw_ctrl *c, int32_t e, int16_t u_limit, uint16_t *clamped)
{
    int64_t zsum = 0, v, u, lim = u_limit > 0 ? u_limit : 1, us, e_upd;
    uint16_t i, cl;
    for (i = 0; i < c->n; i++) {
        zsum += c->z[i];
    }
    v = (int64_t)c->d_q16 * e + zsum;
    u = round_shift(v, 16u);
    cl = (uint16_t)(u > lim || u < -lim);
    us = u > lim ? lim : (u < -lim ? -lim : u);
    *clamped = cl;
    if (!cl) {
        e_upd = e;
    } else if (c->dinv_q16 != 0) {
        /* Hanus: the error that gives the clamped output, d e' + sum z = 2^16 u */
        int64_t diff = us * 65536 - zsum;
        if (diff > 2147483647ll) diff = 2147483647ll;
        if (diff < -2147483647ll - 1) diff = -2147483647ll - 1;
        e_upd = round_shift(diff * c->dinv_q16, 32u);
    } else if ((u > lim && e > 0) || (u < -lim && e < 0)) {
        return (int16_t)us; /* conditional integration: frozen while pushing into the clamp */
    } else {
        e_upd = e;
    }
    for (i = 0; i < c->n; i++) {
        c->z[i] = sat32(round_shift((int64_t)c->a_q30[i] * c->z[i], 30u) +
                        (int64_t)c->g_q16[i] * e_upd);
    }
    return (int16_t)us;
}
