/*
 * enc_interp.c - an encoder's position below the count (specification in
 * enc_interp.h).
 */
#include "enc_interp.h"

#include "fixmath.h"

void enc_interp_reset(enc_interp_t *s, int64_t pos, uint32_t nedge)
{
    s->n = 0;
    s->pos = pos;
    s->nedge = nedge;
}

/* e * (a b + w) / c in 2^-16 counts, e in half counts (e 2^15). */
static int64_t enc_interp_term(int64_t e, int64_t a, int64_t b, int64_t w, int64_t c)
{
    return fx_muldiv64(e * 32768, a * b + w, c);
}

int64_t enc_interp_step(enc_interp_t *s, int64_t pos, uint32_t nedge, int8_t dir,
                        int64_t t_edge_ns, int64_t now_ns, uint32_t window_ns)
{
    int64_t lo = 2 * pos - 1, hi = 2 * pos + 1; /* half counts */
    int64_t est, m, w;
    unsigned k;

    if (nedge != s->nedge) {
        uint32_t edges = nedge - s->nedge;
        uint64_t moved = fx_uabs64(pos - s->pos);

        if (window_ns != 0u) {
            /* the cells between the two counts, and one more on each
             * side per two edges the count difference does not show */
            int64_t extra = edges > moved ? (int64_t)(edges - moved) : 0;
            lo = 2 * fx_min64(pos, s->pos) - 1 - extra;
            hi = 2 * fx_max64(pos, s->pos) + 1 + extra;
        }
        if (s->n == 0 || t_edge_ns > s->t[2]) { /* else it replaces the newest */
            s->e[0] = s->e[1];
            s->t[0] = s->t[1];
            s->e[1] = s->e[2];
            s->t[1] = s->t[2];
            s->n = (uint8_t)(s->n < 3u ? s->n + 1u : 3u);
        }
        s->e[2] = 2 * pos - (dir < 0 ? -1 : 1);
        s->t[2] = t_edge_ns;
        s->pos = pos;
        s->nedge = nedge;
    }
    /* events within the span, newest first: k of them */
    k = 0;
    while (k < s->n && now_ns - s->t[2 - k] <= ENC_INTERP_SPAN_NS) {
        k++;
    }
    if (k < 2) {
        return 0; /* no velocity known: the count */
    }
    m = now_ns - (int64_t)(window_ns / 2u) - s->t[2]; /* the window's centre */
    w = (int64_t)window_ns * window_ns / 12;
    est = s->e[2] * 32768;
    if (k == 2) {
        est += enc_interp_term(s->e[1] - s->e[2], m, 1, 0, s->t[1] - s->t[2]);
    } else {
        int64_t d1 = s->t[1] - s->t[2], d0 = s->t[0] - s->t[2];
        est = fx_sat_add64(
            est, enc_interp_term(s->e[1] - s->e[2], m, m - d0, w, d1 * (d1 - d0)));
        est = fx_sat_add64(
            est, enc_interp_term(s->e[0] - s->e[2], m, m - d1, w, d0 * (d0 - d1)));
    }
    est = fx_clamp64(est, lo * 32768, hi * 32768);
    return est - 2 * pos * 32768;
}
