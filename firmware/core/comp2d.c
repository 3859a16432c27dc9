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
    /* x0 within the field, then nx - 1 <= 143 steps of <= 1 m: no overflow */
    if (m->x0 > hi[0] || m->y0 > hi[1]) {
        return COMP2D_E_FIELD;
    }
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

/* d (q13 of 2^shift nm) over step nm, q32, saturated at +-1/2 */
static int32_t comp2d_slope(int64_t d, unsigned shift, uint32_t step)
{
    int64_t g = d * ((int64_t)1 << (19u + shift)) / (int64_t)step; /* |d| < 2^31: no overflow */
    return g > INT32_MAX ? INT32_MAX : (g < INT32_MIN ? INT32_MIN : (int32_t)g);
}

void comp2d_linearize(const comp2d_map_t *m, const pos_nm_t p[2], const q1_30_t w[2],
                      comp2d_lin_t *out)
{
    static const q1_30_t w0[2] = {0, 0}, wxo[2] = {FX_ONE_Q30, 0}, wyo[2] = {0, FX_ONE_Q30};
    pos_nm_t v0[2], vx[2], vy[2];
    uint32_t fx, fy;
    unsigned ix, iy, a, i0, i1;
    int32_t wx = w[0] / 131072, wy = w[1] / 131072;
    bool hold_x = p[0] < m->x0 || p[0] - m->x0 >= (pos_nm_t)(m->nx - 1) * m->dx;
    bool hold_y = p[1] < m->y0 || p[1] - m->y0 >= (pos_nm_t)(m->ny - 1) * m->dy;
    comp2d_correct(m, p, w0, v0);
    comp2d_correct(m, p, wxo, vx);
    comp2d_correct(m, p, wyo, vy);
    ix = comp2d_cell(p[0], m->x0, m->dx, m->inv_dx, m->nx, &fx);
    iy = comp2d_cell(p[1], m->y0, m->dy, m->inv_dy, m->ny, &fy);
    i0 = iy * m->nx + ix;
    i1 = i0 + m->nx;
    for (a = 0; a < 2; a++) {
        const int16_t(*g)[COMP2D_NODES_MAX] = m->g[a];
        int32_t n00 = comp2d_node(g, i0, wx, wy), n10 = comp2d_node(g, i0 + 1, wx, wy);
        int32_t n01 = comp2d_node(g, i1, wx, wy), n11 = comp2d_node(g, i1 + 1, wx, wy);
        /* d/dx at fy, d/dy at fx: q13 of 2^shift nm per cell -> q32 nm/nm */
        int64_t ddx = comp2d_lerp(n10 - n00, n11 - n01, fy);
        int64_t ddy = comp2d_lerp(n01, n11, fx) - (int64_t)comp2d_lerp(n00, n10, fx);
        out->mid[a] = (int32_t)(v0[a] - p[a]);
        out->hx[a] = (int32_t)(vx[a] - v0[a]);
        out->hy[a] = (int32_t)(vy[a] - v0[a]);
        out->gx[a] = hold_x ? 0 : comp2d_slope(ddx, m->shift, m->dx);
        out->gy[a] = hold_y ? 0 : comp2d_slope(ddy, m->shift, m->dy);
    }
}

static uint32_t c2d_get32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void c2d_put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

uint32_t comp2d_encode(const comp2d_map_t *m, uint8_t *buf, uint32_t cap)
{
    uint32_t n = (uint32_t)m->nx * m->ny, len = COMP2D_RECORD_HDR + 12u * n, i, k = 0;
    unsigned a, c;
    if (n > COMP2D_NODES_MAX || len > cap) {
        return 0u;
    }
    for (i = 0; i < COMP2D_RECORD_HDR; i++) {
        buf[i] = 0u;
    }
    c2d_put32(buf, COMP2D_RECORD_MAGIC);
    buf[4] = (uint8_t)m->version;
    buf[5] = (uint8_t)(m->version >> 8);
    buf[6] = m->nx;
    buf[7] = m->ny;
    buf[8] = m->shift;
    c2d_put32(buf + 12, (uint32_t)(uint64_t)m->x0);
    c2d_put32(buf + 16, (uint32_t)((uint64_t)m->x0 >> 32));
    c2d_put32(buf + 20, (uint32_t)(uint64_t)m->y0);
    c2d_put32(buf + 24, (uint32_t)((uint64_t)m->y0 >> 32));
    c2d_put32(buf + 28, m->dx);
    c2d_put32(buf + 32, m->dy);
    for (a = 0; a < 2u; a++) {
        for (c = 0; c < 3u; c++) {
            for (i = 0; i < n; i++, k += 2u) {
                buf[COMP2D_RECORD_HDR + k] = (uint8_t)(uint16_t)m->g[a][c][i];
                buf[COMP2D_RECORD_HDR + k + 1u] = (uint8_t)((uint16_t)m->g[a][c][i] >> 8);
            }
        }
    }
    return len;
}

int comp2d_decode(const uint8_t *buf, uint32_t len, comp2d_map_t *m)
{
    uint32_t n, i, k = 0;
    unsigned a, c;
    if (len < COMP2D_RECORD_HDR || c2d_get32(buf) != COMP2D_RECORD_MAGIC || buf[9] != 0u ||
        buf[10] != 0u || buf[11] != 0u) {
        return COMP2D_E_MAGIC;
    }
    m->version = (uint16_t)(buf[4] | (buf[5] << 8));
    if (m->version != COMP2D_VERSION) {
        return COMP2D_E_VERSION;
    }
    m->nx = buf[6];
    m->ny = buf[7];
    n = (uint32_t)m->nx * m->ny;
    if (m->nx < 2u || m->ny < 2u || n > COMP2D_NODES_MAX) {
        return COMP2D_E_MEMORY;
    }
    if (len != COMP2D_RECORD_HDR + 12u * n) {
        return COMP2D_E_LENGTH;
    }
    m->shift = buf[8];
    m->x0 = (pos_nm_t)((uint64_t)c2d_get32(buf + 12) | ((uint64_t)c2d_get32(buf + 16) << 32));
    m->y0 = (pos_nm_t)((uint64_t)c2d_get32(buf + 20) | ((uint64_t)c2d_get32(buf + 24) << 32));
    m->dx = c2d_get32(buf + 28);
    m->dy = c2d_get32(buf + 32);
    for (a = 0; a < 2u; a++) {
        for (c = 0; c < 3u; c++) {
            for (i = 0; i < n; i++, k += 2u) {
                m->g[a][c][i] = (int16_t)(uint16_t)(buf[COMP2D_RECORD_HDR + k] |
                                                    (buf[COMP2D_RECORD_HDR + k + 1u] << 8));
            }
        }
    }
    return COMP2D_OK;
}
