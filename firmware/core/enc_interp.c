/*
 * enc_interp.c - an encoder's position below the count (specification in
 * enc_interp.h).
 */
#include "enc_interp.h"

#include "fixmath.h"

#define HALF 32768 /* half a count in 2^-16 counts */

#define EV_MASK (ENC_INTERP_EVENTS - 1u)

void enc_interp_reset(enc_interp_t *s, int64_t pos, uint32_t nedge)
{
    s->n = 0;
    s->head = 0;
    s->pos = pos;
    s->prev = pos;
    s->nedge = nedge;
    s->back = false;
    s->edged = false;
}

void enc_interp_update(enc_interp_t *s, int64_t pos, uint32_t nedge, int8_t dir, int64_t t_edge_ns)
{
    s->prev = s->pos;
    s->back = false;
    s->edged = nedge != s->nedge;
    if (s->edged) {
        uint32_t edges = nedge - s->nedge;

        s->back = edges > fx_uabs64(pos - s->pos);
        if (s->n == 0 || t_edge_ns > s->t[s->head]) { /* else it replaces the newest */
            s->head = (uint8_t)((s->head + 1u) & EV_MASK);
            s->n = (uint8_t)(s->n < ENC_INTERP_EVENTS ? s->n + 1u : ENC_INTERP_EVENTS);
        }
        s->e[s->head] = 2 * pos - (dir < 0 ? -1 : 1);
        s->t[s->head] = t_edge_ns;
        s->nedge = nedge;
    }
    s->pos = pos;
}

/* fx_muldiv64(e 2^15, a, c) (enc_interp.h, enc_interp_muldiv). */
static inline int64_t enc_interp_term(int64_t e, int64_t a, int64_t c)
{
    uint64_t ue = fx_uabs64(e), ua = fx_uabs64(a), d = fx_uabs64(c), u, q;
    int64_t r;

    /* the short form: |e| < 2^16, |a| < 2^47, |e a| < 2^48 (u = |e| 2^15
     * |a| < 2^63), 0 < d < 2^56, the quotient below 2^32 */
    if (ue >= 65536u || (ua >> 47) != 0u || d - 1u >= ((uint64_t)1 << 56) - 1u) {
        return fx_muldiv64(e * HALF, a, c);
    }
    u = ua * ue;
    if ((u >> 48) != 0u || ((u << 15) >> 32) >= d) {
        return fx_muldiv64(e * HALF, a, c);
    }
    u <<= 15;
    {
        /* d normalised to dt in [2^31, 2^32), u with it (exact for d <
         * 2^32, else both truncated: ut / dt within (-2^-31, q 2^-30] of
         * u / d); x ~ 2^63 / dt from a 16-bit hardware quotient and one
         * Newton step (from below, relative error below 2^-28), so the
         * estimate floor(ut x / 2^63) lies within [q - 15, q + 2] of q =
         * floor(u / d) (q < 2^32; q - 1 .. q where q < 2^27) */
        uint64_t ut, p, err;
        uint32_t dt, x;

        if ((d >> 32) != 0u) {
            unsigned sh = 32u - fx_clz32((uint32_t)(d >> 32));

            dt = (uint32_t)(d >> sh);
            ut = u >> sh;
        } else {
            unsigned ls = fx_clz32((uint32_t)d);

            dt = (uint32_t)d << ls;
            ut = u << ls; /* < dt 2^32: the quotient is below 2^32 */
        }
        x = (0xFFFFFFFFu / ((dt >> 16) + 1u)) << 15;
        p = (uint64_t)dt * x;                  /* <= 2^63 */
        err = (((uint64_t)1 << 63) - p) >> 17; /* < 2^32 */
        x += (uint32_t)(((uint64_t)x * (uint32_t)err) >> 46);
        q = (((ut >> 32) * x) + ((((uint64_t)(uint32_t)ut) * x) >> 32)) >> 31;
    }
    /* the remainder, exact: |q - floor(u / d)| <= 15 and d < 2^56 */
    r = (int64_t)(u - q * d);
    while (r < 0) {
        q--;
        r += (int64_t)d;
    }
    while ((uint64_t)r >= d) {
        q++;
        r -= (int64_t)d;
    }
    if ((uint64_t)r >= d - (uint64_t)r) {
        q++; /* ties away from zero, as fx_muldiv64 */
    }
    return (((e < 0) != (a < 0)) != (c < 0)) ? -(int64_t)q : (int64_t)q;
}

int64_t enc_interp_muldiv(int64_t e, int64_t ab, int64_t c)
{
    return enc_interp_term(e, ab, c);
}

/* The events' quadratic (or line) at t_ns, in 2^-16 counts relative to
 * the count; false when fewer than two events lie within the span before
 * the sample now_ns. The nodes: the newest event, the oldest one k3 of
 * the newest that lie within the span, moved back from the third newest
 * until it lies at least twice the extrapolation (t_ns - the newest)
 * before the newest (or no older one is in the span), and between them
 * the one nearest the middle of the two. */
static inline bool enc_interp_eval(const enc_interp_t *s, int64_t now_ns, int64_t t_ns, int64_t *x)
{
    int64_t m, est, a, b, d1, t2, e2;
    unsigned h = s->head, i0, i1;

    if (s->n < 2u || now_ns - s->t[h] > ENC_INTERP_SPAN_NS ||
        now_ns - s->t[(h - 1u) & EV_MASK] > ENC_INTERP_SPAN_NS) {
        return false;
    }
    t2 = s->t[h];
    e2 = s->e[h];
    m = t_ns - t2;
    est = (e2 - 2 * s->pos) * HALF;
    i1 = (h - 1u) & EV_MASK;
    i0 = (h - 2u) & EV_MASK;
    if (s->n < 3u || now_ns - s->t[i0] > ENC_INTERP_SPAN_NS) {
        d1 = s->t[i1] - t2;
        a = enc_interp_term(s->e[i1] - e2, m, d1);
        b = 0;
    } else {
        int64_t d0;
        unsigned k = 2u;

        /* the oldest node: at least 2 m before the newest, within the span */
        while (t2 - s->t[i0] < ENC_INTERP_REACH * m && k + 1u < s->n &&
               now_ns - s->t[(h - k - 1u) & EV_MASK] <= ENC_INTERP_SPAN_NS) {
            k++;
            i0 = (h - k) & EV_MASK;
        }
        if (k > 2u) {
            /* the middle node: the one nearest (t2 + t0) / 2 */
            int64_t mid = t2 - (t2 - s->t[i0]) / 2, best = -1;
            unsigned j;

            for (j = 1u; j < k; j++) {
                unsigned ij = (h - j) & EV_MASK;
                int64_t dist = s->t[ij] > mid ? s->t[ij] - mid : mid - s->t[ij];

                if (best < 0 || dist < best) {
                    best = dist;
                    i1 = ij;
                }
            }
        }
        d1 = s->t[i1] - t2;
        d0 = s->t[i0] - t2;
        a = enc_interp_term(s->e[i1] - e2, m * (m - d0), d1 * (d1 - d0));
        b = enc_interp_term(s->e[i0] - e2, m * (m - d1), d0 * (d0 - d1));
    }
    if (fx_uabs64(a) < ((uint64_t)1 << 40) && fx_uabs64(b) < ((uint64_t)1 << 40)) {
        est += a + b; /* no saturation possible: est is +-2^15 */
    } else {
        est = fx_sat_add64(fx_sat_add64(est, a), b);
    }
    *x = est;
    return true;
}

int64_t enc_interp_pos(const enc_interp_t *s, int64_t now_ns)
{
    int64_t x;

    if (!enc_interp_eval(s, now_ns, now_ns, &x)) {
        return 0; /* no velocity known: the count */
    }
    return x < -HALF ? -HALF : x > HALF ? HALF : x;
}

/* Integral of the centred count floor(y + 1/2) from 0 to y (y in 2^-16
 * counts; the result in 2^-16 counts^2): G(y + 1/2) - G(1/2) with
 * G(z) = n (n - 1) / 2 + n (z - n), n = floor(z), the integral of floor
 * from 0 to z, and G(1/2) = 0. */
static int64_t enc_interp_cells(int64_t y)
{
    int64_t z = y + HALF;
    int64_t n = z >> 16; /* floor */

    return n * (n - 1) / 2 * 65536 + n * (z - n * 65536);
}

/* The integral over a segment of d ns along the line from y0 to y1 (2^-16
 * counts) of y - floor(y + 1/2), in 2^-16 counts ns. */
static int64_t enc_interp_saw(int64_t y0, int64_t y1, int64_t d)
{
    int64_t c0 = (y0 + HALF) >> 16, c1 = (y1 + HALF) >> 16;
    int64_t cells;

    if (c0 == c1) {
        cells = c0 * 65536;
    } else {
        cells = fx_div_shift64(enc_interp_cells(y1) - enc_interp_cells(y0), y1 - y0, 16);
    }
    return ((y0 + y1) / 2 - cells) * d;
}

int64_t enc_interp_mean_residual(const enc_interp_t *s, int64_t now_ns, uint32_t tick_ns)
{
    int64_t t0 = now_ns - (int64_t)tick_ns, x0, x1, sum;
    int64_t c0 = 2 * (s->prev - s->pos) * HALF; /* the previous count's centre */

    if (s->back || fx_uabs64(s->prev - s->pos) > ENC_INTERP_MOVE_MAX ||
        !enc_interp_eval(s, now_ns, t0, &x0) || !enc_interp_eval(s, now_ns, now_ns, &x1)) {
        return 0; /* the count's mean alone (past the move limit: exact) */
    }
    /* each end inside the cell its sample's count proves, [n - 1/2,
     * n + 1/2): n + 1/2 is the next count's (round would read it -1/2) */
    x0 = fx_clamp64(x0, c0 - HALF, c0 + HALF - 1);
    x1 = fx_clamp64(x1, -HALF, HALF - 1);
    if (s->edged && s->t[s->head] > t0) {
        /* through the tick's last edge, which is exact: the line crosses
         * it when the axis did */
        int64_t xe = (s->e[s->head] - 2 * s->pos) * HALF;
        int64_t te = s->t[s->head] < now_ns ? s->t[s->head] : now_ns; /* stamped after the sample */
        sum = enc_interp_saw(x0, xe, te - t0) + enc_interp_saw(xe, x1, now_ns - te);
    } else {
        sum = enc_interp_saw(x0, x1, (int64_t)tick_ns);
    }
    return fx_div_round64(sum, (int64_t)tick_ns);
}
