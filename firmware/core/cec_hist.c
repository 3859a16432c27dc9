/*
 * cec_hist.c - the contour error controller's reference history and the
 * circle through three points (specification in cec.h, "Reference
 * history"; split from cec.c for its length).
 */
#include "cec_hist.h"

#define CIRCLE3_LIM   ((int64_t)1 << 20) /* components scaled below this      */
#define CIRCLE3_SHIFT 20                 /* q of |b-a| |c-b| / (2 |cross|)     */

pos_nm_t cec_circle3(const pos_nm_t a[2], const pos_nm_t b[2], const pos_nm_t c[2], int8_t *s)
{
    int64_t d1u = b[0] - a[0], d1v = b[1] - a[1], d2u = c[0] - b[0], d2v = c[1] - b[1];
    int64_t cr, l1, l2, l3, q;
    unsigned sh = 0;

    *s = 0;
    while (fx_sat_abs64(d1u) >= CIRCLE3_LIM || fx_sat_abs64(d1v) >= CIRCLE3_LIM ||
           fx_sat_abs64(d2u) >= CIRCLE3_LIM || fx_sat_abs64(d2v) >= CIRCLE3_LIM) {
        d1u /= 2;
        d1v /= 2;
        d2u /= 2;
        d2v /= 2;
        sh++;
    }
    cr = d1u * d2v - d1v * d2u; /* below 2^41 */
    l1 = fx_hypot2(d1u, d1v);
    l2 = fx_hypot2(d2u, d2v);
    l3 = fx_hypot2(d1u + d2u, d1v + d2v);
    if (cr == 0 || l1 == 0 || l2 == 0 || l3 == 0) {
        return 0;
    }
    /* q = |b-a| |c-b| / (2 |cross|) = 1 / (2 sin(turn)), q20; r = q |c-a| */
    q = fx_div_round64((l1 * l2) << CIRCLE3_SHIFT, 2 * fx_sat_abs64(cr));
    if (sh > 40 || q > ((CEC_CURV_R_MAX << CIRCLE3_SHIFT) >> sh) / l3) {
        return 0; /* straight */
    }
    *s = (int8_t)((cr > 0) ? -1 : 1);
    return (pos_nm_t)(((q * l3) >> CIRCLE3_SHIFT) << sh);
}

/* Sample the reference into the history (see cec.h) and, with a new
 * sample, the circle through the last three. */
void cec_hist_step(cec_t *c, const motion_ref_t *ref, unsigned w)
{
    unsigned u = (w + 1u) % 3u, v = (w + 2u) % 3u;
    pos_nm_t pu = (u < CORE_AXES) ? ref->pos[u] : 0, pv = (v < CORE_AXES) ? ref->pos[v] : 0;
    int64_t span = (c->p.curv_span_nm > 0) ? c->p.curv_span_nm : CEC_CURV_SPAN_NM;
    int64_t du, dv;

    if (c->hist_n == 0 || c->hist_w != w) {
        c->hist_n = 1;
        c->hist_w = (uint8_t)w;
        c->hist_r = 0;
        c->hist[0][0] = pu;
        c->hist[0][1] = pv;
        return;
    }
    du = pu - c->hist[0][0];
    dv = pv - c->hist[0][1];
    if (fx_sat_abs64(du) < span && fx_sat_abs64(dv) < span && du * du + dv * dv < span * span) {
        return;
    }
    c->hist[2][0] = c->hist[1][0];
    c->hist[2][1] = c->hist[1][1];
    c->hist[1][0] = c->hist[0][0];
    c->hist[1][1] = c->hist[0][1];
    c->hist[0][0] = pu;
    c->hist[0][1] = pv;
    if (c->hist_n < 3) {
        c->hist_n++;
    }
    if (c->hist_n == 3) {
        c->hist_r = cec_circle3(c->hist[2], c->hist[1], c->hist[0], &c->hist_s);
    }
}
