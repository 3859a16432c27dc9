/*
 * planner_lim.c - the planner's block limits by axis (axes with different
 * limits, or components of 2^31 nm and more: plan_push's exact path) and
 * the join of two chords of one arc; see planner_lim.h. Main context.
 */
#include "planner_lim.h"

#include "fixmath.h"

/* sc_muldiv(a, b, c) (floor(a b / c), 0 for a <= 0 or b <= 0, saturated),
 * with one 64/64 division when a b fits 64 bits (both factors below 2^32,
 * one 32 x 32 multiply; or an exact 64 x 64 product without overflow), a
 * 64/32 one when the quotient fits 32 bits: the same quotient the 128-bit
 * path gives. */
int64_t plan_lim_muldiv(int64_t a, int64_t b, int64_t c)
{
    uint64_t n, q, rem;

    if (a <= 0 || b <= 0) {
        return 0;
    }
    if (c <= 0) {
        return INT64_MAX;
    }
    if ((((uint64_t)a | (uint64_t)b) >> 32) == 0u) {
        n = (uint64_t)(uint32_t)a * (uint32_t)b;
    } else if (__builtin_mul_overflow((uint64_t)a, (uint64_t)b, &n)) {
        return sc_muldiv(a, b, c);
    }
    if (((uint64_t)c >> 32) == 0u && (n >> 32) < (uint64_t)c) {
        return (int64_t)fx_udiv64by32(n, (uint32_t)c); /* the quotient fits 32 bits */
    }
    q = fx_udivmod64(n, (uint64_t)c, &rem);
    return (q > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)q;
}

/* min over the axes with d_i != 0 of floor(lim_i * len / |d_i|) (sc_muldiv,
 * INT64_MAX when no axis moves): the axis with the smallest lim_i / |d_i| is
 * found by comparing exact products, then one division gives its value,
 * the same as the minimum of every axis's quotient (the floor is monotone).
 * lim_i > 0, |d_i| < 2^63, len >= 0. */
int64_t plan_axis_limit(const int64_t *lim, const int64_t *d, int64_t len)
{
    int i, best = -1;
    bool same = true; /* equal limits: the longest component decides */

    for (i = 1; i < CORE_AXES; i++) {
        same = same && lim[i] == lim[0];
    }
    for (i = 0; i < CORE_AXES; i++) {
        uint64_t ad = fx_uabs64(d[i]);
        if (ad == 0u) {
            continue;
        }
        if (best < 0) {
            best = i;
        } else if (same) {
            if (ad > fx_uabs64(d[best])) {
                best = i;
            }
        } else if (sc_cmp_products((uint64_t)lim[i], fx_uabs64(d[best]), (uint64_t)lim[best], ad) <
                   0) {
            /* lim_i / ad_i < lim_b / ad_b  <=>  lim_i * ad_b < lim_b * ad_i */
            best = i;
        }
    }
    return (best < 0) ? INT64_MAX : plan_lim_muldiv(lim[best], len, (int64_t)fx_uabs64(d[best]));
}

/* The block limits of a move d of length len > 0 by plan_axis_limit, exact, when plan_push's fast
 * path does not apply: returns v_max (at most feed), lim[0..1] = a and j (at most SC_A_LIMIT,
 * SC_J_LIMIT). A feed at most every axis's speed limit is the block's (len / |d_i| >= 1: no
 * division). Equal speed limits: the longest component decides (what plan_axis_limit picks), one
 * division. The continuous S-curve with axes of different limits reads neither a nor j (a run takes
 * its class's, b->cont_cls set here: plan_cont_class sets them; j at an arc's join,
 * plan_arc_corner): a 0, j -1. Called, not inlined: plan_push's usual path keeps its registers. */
int64_t plan_limits_exact(const plan_t *p, plan_block_t *b, const int64_t *d, int64_t len,
                          int64_t feed, int64_t *lim)
{
    int64_t vmin = p->prof.v_max[0], v = feed;
    int i;

    for (i = 1; i < CORE_AXES; i++) {
        vmin = fx_min64(vmin, p->prof.v_max[i]);
    }
    if (feed > vmin && p->v_same) {
        uint64_t dm = 0; /* the longest component */
        for (i = 0; i < CORE_AXES; i++) {
            dm = (fx_uabs64(d[i]) > dm) ? fx_uabs64(d[i]) : dm;
        }
        v = fx_min64(feed, plan_lim_muldiv(vmin, len, (int64_t)dm));
    } else if (feed > vmin) {
        v = fx_min64(feed, plan_axis_limit(p->prof.v_max, d, len));
    }
    if (!p->same_limits && p->prof.shape == SC_SHAPE_SCURVE_CONTINUOUS) {
        unsigned mask = 0;
        for (i = 0; i < CORE_AXES; i++) {
            mask |= (d[i] != 0) ? (1u << i) : 0u;
        }
        b->cont_cls = p->cont_cls[mask]; /* the axes it moves */
        lim[0] = 0;
        lim[1] = -1;
    } else {
        lim[0] = fx_min64(SC_A_LIMIT, plan_axis_limit(p->prof.a_max, d, len));
        lim[1] = fx_min64(SC_J_LIMIT, plan_axis_limit(p->prof.j_max, d, len));
    }
    return v;
}

/* floor(cbrt(j r^2)) or a little less, j >= 0, r >= 0: r is cut by 3t
 * bits until j r^2 fits 63 bits, then the root is scaled back by 2^(2t)
 * (the cut only lowers it). */
static int64_t pl_cbrt_jr2(int64_t j, int64_t r)
{
    unsigned t = 0, bj = fx_bitlen64((uint64_t)j);
    uint64_t rs = (uint64_t)r;

    while (rs != 0u && bj + 2u * fx_bitlen64(rs) > 63u) {
        rs >>= 3;
        t++;
    }
    return (int64_t)((uint64_t)fx_icbrt64((uint64_t)j * rs * rs) << (2u * t));
}

/* Join of two chords of one arc (PLAN_MOVE_ARC_JOIN): the arc's own
 * centripetal limits at the radius of the join, v^2 / R <= a_n and (jerk
 * shapes) v^3 / R^2 <= j_n, a_n and j_n the axis limits projected on the
 * normal e = u2 - u1 (as the junction-deviation rule's a_j) and j_n = jt,
 * the block's own jerk limit (the jerk of uniform circular motion, v^3/R^2,
 * is along the tangent: the chord's direction). R = l / |e|
 * with l the mean chord length: two chords of length l = 2 R sin(th/2)
 * turning by th have |u2 - u1| = 2 sin(th/2). de, e: u2 - u1 and its
 * length in q30. INT64_MAX when e = 0. */
static int64_t pl_arc_join(const plan_t *p, const int64_t *de, int64_t e, int64_t l, int64_t jt)
{
    int64_t an, r, v;

    if (e <= 0) {
        return INT64_MAX;
    }
    an = plan_axis_limit(p->prof.a_max, de, e);
    r = sc_muldiv(l, (int64_t)1 << 30, e);
    /* an < 2^41, r < 2^63: the root is below 2^52 */
    v = (int64_t)fx_isqrt128(fx_umul64((uint64_t)an, (uint64_t)r));
    if (p->prof.shape != SC_SHAPE_TRAPEZOID) {
        v = fx_min64(v, pl_cbrt_jr2(jt, r));
    }
    return v;
}

/* The join of two chords of one arc (PLAN_MOVE_ARC_JOIN; jt the new
 * block's j_max, or -1 when plan_limits_exact left it out: then found
 * from its move d): an axis reversal or PLAN_CORNER_STOP stops, as in
 * planner.c's pl_corner; otherwise pl_arc_join. Called, not inlined:
 * plan_push's usual path (lines) does not pay for it. */
int64_t plan_arc_corner(const plan_t *p, const int32_t *w2, const int64_t *d, int64_t len2,
                        int64_t jt)
{
    const int32_t *w1 = p->last_q30;
    int64_t de[CORE_AXES], e2 = 0;
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        if ((w1[i] ^ w2[i]) < 0) {
            int32_t a1 = (w1[i] < 0) ? -w1[i] : w1[i], a2 = (w2[i] < 0) ? -w2[i] : w2[i];
            if (a1 >= PLAN_REVERSAL_MIN_Q30 && a2 >= PLAN_REVERSAL_MIN_Q30) {
                return 0; /* axis reversal: stop */
            }
        }
        de[i] = (int64_t)w2[i] - w1[i]; /* below 2^31: not a reversal */
        e2 += de[i] * de[i];
    }
    if (p->prof.corner == PLAN_CORNER_STOP) {
        return 0;
    }
    if (jt < 0) {
        jt = fx_min64(SC_J_LIMIT, plan_axis_limit(p->prof.j_max, d, len2));
    }
    return pl_arc_join(p, de, (int64_t)fx_isqrt64((uint64_t)e2), (p->last_len + len2) / 2, jt);
}
