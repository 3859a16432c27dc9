/* 2-D compensation map: comp2d.h. */
#include "comp2d.h"

int comp2d_check(const comp2d_map_t *m, const pos_nm_t lo[2], const pos_nm_t hi[2])
{
    if (m->version != COMP2D_VERSION) {
        return COMP2D_E_VERSION;
    }
    if (m->nx < 2 || m->ny < 2 || (unsigned)m->nx * m->ny > COMP2D_NODES_MAX) {
        return COMP2D_E_MEMORY;
    }
    if (m->dx <= COMP2D_STEP_MIN_NM || m->dy <= COMP2D_STEP_MIN_NM || m->dx > COMP2D_STEP_MAX_NM ||
        m->dy > COMP2D_STEP_MAX_NM || m->shift > COMP2D_SHIFT_MAX) {
        return COMP2D_E_STEP;
    }
    /* nx - 1 <= 143 steps of <= 1 m: no overflow in 64 bits */
    if (m->x0 < lo[0] || m->x0 + (pos_nm_t)(m->nx - 1) * m->dx > hi[0] || m->y0 < lo[1] ||
        m->y0 + (pos_nm_t)(m->ny - 1) * m->dy > hi[1]) {
        return COMP2D_E_FIELD;
    }
    return COMP2D_OK;
}

void comp2d_prepare(comp2d_map_t *m)
{
    m->inv_dx = (uint32_t)(((uint64_t)1 << 48) / m->dx);
    m->inv_dy = (uint32_t)(((uint64_t)1 << 48) / m->dy);
}

/* Cell and q16 fraction of p on a grid axis, clamped to its ends. */
static unsigned comp2d_cell(pos_nm_t p, pos_nm_t p0, uint32_t d, uint32_t inv, unsigned n,
                            uint32_t *frac)
{
    uint64_t span = (uint64_t)(n - 1) * d;
    uint32_t u, i, r;
    if (p <= p0) {
        *frac = 0;
        return 0;
    }
    if ((uint64_t)(p - p0) >= span) {
        *frac = 65536u;
        return n - 2;
    }
    u = (uint32_t)(p - p0); /* < 143 m: fits */
    i = u / d;
    r = u - i * d;
    *frac = (uint32_t)(((uint64_t)r * inv) >> 32); /* r / d in q16, < 2^16 */
    return i;
}

/* a + (b - a) * f, f q16: one 32 x 32 -> 64 multiply */
static int32_t comp2d_lerp(int32_t a, int32_t b, uint32_t f)
{
    return a + (int32_t)(((int64_t)(b - a) * (int32_t)f) >> 16);
}

/* Node i of axis a with the direction terms weighted, q13 of 2^shift nm:
 * |value| <= 3 * 2^15 * 2^13 < 2^30, differences of two fit int32. */
static int32_t comp2d_node(const int16_t (*g)[COMP2D_NODES_MAX], unsigned i, int32_t wx, int32_t wy)
{
    return (int32_t)g[COMP2D_MID][i] * 8192 + (int32_t)g[COMP2D_HX][i] * wx +
           (int32_t)g[COMP2D_HY][i] * wy;
}

void comp2d_correct(const comp2d_map_t *m, const pos_nm_t raw[2], const q1_30_t w[2],
                    pos_nm_t out[2])
{
    uint32_t fx, fy;
    unsigned ix, iy, a, i0, i1;
    int32_t wx, wy;
    if (m == 0) {
        out[0] = raw[0];
        out[1] = raw[1];
        return;
    }
    ix = comp2d_cell(raw[0], m->x0, m->dx, m->inv_dx, m->nx, &fx);
    iy = comp2d_cell(raw[1], m->y0, m->dy, m->inv_dy, m->ny, &fy);
    i0 = iy * m->nx + ix;
    i1 = i0 + m->nx;
    wx = w[0] / 131072; /* q1_30 -> q13 (|w| <= 1) */
    wy = w[1] / 131072;
    for (a = 0; a < 2; a++) {
        const int16_t(*g)[COMP2D_NODES_MAX] = m->g[a];
        int32_t b0 = comp2d_lerp(comp2d_node(g, i0, wx, wy), comp2d_node(g, i0 + 1, wx, wy), fx);
        int32_t b1 = comp2d_lerp(comp2d_node(g, i1, wx, wy), comp2d_node(g, i1 + 1, wx, wy), fx);
        int64_t c = (int64_t)comp2d_lerp(b0, b1, fy) * ((int64_t)1 << m->shift);
        out[a] = raw[a] + ((c + 4096) >> 13);
    }
}
