/*
 * scurve.c - closed-form single-block profiles; see scurve.h.
 *
 * Wide arithmetic: products of two 63-bit values are fixmath's 128-bit
 * product (fx_umul64), quotients its 128/64 division (fx_udiv128: the host's
 * 64-bit divider where it has one, the 32-bit-digit long division of 32-bit
 * targets otherwise; sc_muldiv_portable runs the digit code on every host
 * so that test_scurve compares the two). The reach (the highest speed a
 * distance allows) is in scurve_reach.c.
 */
#include "scurve.h"
#include "scurve_internal.h"
#include "scurve_test.h"

#include "fixmath.h"
#include "fixmath_test.h"

#include <stddef.h>

/* floor(n / d) and the remainder; *ovf when the quotient needs > 64 bits.
 * Knuth long division with 32-bit digits (fixmath's fx_udiv128_digits):
 * about 100 Cortex-M4 instructions where a bit-serial loop took 1300. */
static uint64_t sc_div_portable(fx_u128_t n, uint64_t d, uint64_t *rem, bool *ovf)
{
    *ovf = n.hi >= d;
    return fx_udiv128_digits(n.hi, n.lo, d, rem);
}

static uint64_t sc_div(fx_u128_t n, uint64_t d, uint64_t *rem, bool *ovf)
{
    *ovf = n.hi >= d;
    return fx_udiv128(n.hi, n.lo, d, rem);
}

uint64_t sc_isqrt128_ceil(fx_u128_t x)
{
    uint64_t r = fx_isqrt128(x);
    return (fx_cmp128(sc_mul(r, r), x) < 0) ? r + 1u : r;
}

static int64_t sc_sat(uint64_t q, bool ovf)
{
    return (ovf || q > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)q;
}

/* a * b / c for a, b > 0 and c > 0, rounded down or up; 0 or INT64_MAX outside. */
static int64_t sc_muldiv_round(int64_t a, int64_t b, int64_t c, bool up)
{
    uint64_t rem;
    bool ovf;
    uint64_t q;

    if (a <= 0 || b <= 0) {
        return 0;
    }
    if (c <= 0) {
        return INT64_MAX;
    }
    if ((((uint64_t)a | (uint64_t)b) >> 32) == 0u) {
        /* the product fits 64 bits (one 32 x 32 multiply): one 64/64
         * division, the same quotient and remainder */
        q = fx_udivmod64((uint64_t)(uint32_t)a * (uint32_t)b, (uint64_t)c, &rem);
        ovf = false;
    } else {
        q = sc_div(sc_mul((uint64_t)a, (uint64_t)b), (uint64_t)c, &rem, &ovf);
    }
    if (up && !ovf && rem != 0u) {
        q++;
        ovf = (q == 0u);
    }
    return sc_sat(q, ovf);
}

int64_t sc_muldiv(int64_t a, int64_t b, int64_t c)
{
    return sc_muldiv_round(a, b, c, false);
}

int64_t sc_muldiv_ceil(int64_t a, int64_t b, int64_t c)
{
    return sc_muldiv_round(a, b, c, true);
}

int64_t sc_muldiv_portable(int64_t a, int64_t b, int64_t c)
{
    uint64_t rem;
    bool ovf;
    uint64_t q;

    if (a <= 0 || b <= 0) {
        return 0;
    }
    if (c <= 0) {
        return INT64_MAX;
    }
    q = sc_div_portable(fx_umul64((uint64_t)a, (uint64_t)b), (uint64_t)c, &rem, &ovf);
    return sc_sat(q, ovf);
}

int sc_cmp_products(uint64_t a, uint64_t b, uint64_t c, uint64_t d)
{
    return fx_cmp128(sc_mul(a, b), sc_mul(c, d));
}

/* ceil(sqrt(v)) for 0 <= v < 2^63 */
static int64_t sc_sqrt_ceil(int64_t v)
{
    uint64_t r;
    if (v <= 0) {
        return 0;
    }
    r = fx_isqrt64((uint64_t)v);
    return (int64_t)((r * r < (uint64_t)v) ? r + 1u : r);
}

/* ---- at-rest S-curve --------------------------------------------------------- */

/* ---- distance of a speed change --------------------------------------------- */

/* floor(A^2/J) and ceil(A^2/J) from one division */
void sc_aaj(int64_t a, int64_t j, int64_t *qf, int64_t *qc)
{
    uint64_t rem, q;
    bool ovf;

    if (a <= 0 || j <= 0) { /* as sc_muldiv / sc_muldiv_ceil */
        *qf = (a <= 0) ? 0 : INT64_MAX;
        *qc = *qf;
        return;
    }
    q = sc_div(sc_mul((uint64_t)a, (uint64_t)a), (uint64_t)j, &rem, &ovf);
    *qf = sc_sat(q, ovf);
    *qc = (ovf || rem == 0u || *qf == INT64_MAX) ? *qf : *qf + 1;
}

/* sc_dist with qc = ceil(A^2/J) supplied (< 0: computed here) */
int64_t sc_dist_q(int64_t va, int64_t vb, const sc_limits_t *lim, int64_t qc)
{
    int64_t lo = fx_min64(va, vb), hi = fx_max64(va, vb), d = hi - lo;
    int64_t a = lim->a_max, j = lim->j_max, w;
    sc_limits_t tmp;

    lim = sc_resolve(lim, lo, &tmp);
    if (d <= 0) {
        return 0;
    }
    if (lim->shape == SC_SHAPE_TRAPEZOID) {
        return sc_muldiv_ceil(lo + hi, d, 2 * a);
    }
    if (qc < 0) {
        qc = sc_muldiv_ceil(a, a, j); /* A^2/J: speed change that reaches A */
    }
    if (d >= qc) {
        return fx_sat_add64(sc_muldiv_ceil(lo + hi, d, 2 * a), sc_muldiv_ceil(lo + hi, a, 2 * j));
    }
    if (lo + hi <= SC_SQRT_INT64_MAX) {
        /* (lo + hi) sqrt(d / J) = sqrt(X), X = (lo + hi)^2 d / J: one
         * division; r = isqrt(floor(X)) = floor(sqrt(X)), and the exact
         * ceiling is r unless r^2 J < (lo + hi)^2 d (never above the
         * time-rounded form below, never below the exact distance) */
        int64_t s2 = (lo + hi) * (lo + hi);
        int64_t x = sc_muldiv(s2, d, j);
        if (x < INT64_MAX) {
            int64_t r = (int64_t)fx_isqrt64((uint64_t)x);
            return (sc_cmp_products((uint64_t)(r * r), (uint64_t)j, (uint64_t)s2, (uint64_t)d) < 0)
                       ? r + 1
                       : r;
        }
    }
    w = sc_sqrt_ceil(sc_muldiv_ceil(d, (int64_t)NS * (int64_t)NS, j)); /* sqrt(d/J), ns */
    return sc_muldiv_ceil(lo + hi, w, (int64_t)NS);
}

int64_t sc_dist(int64_t va, int64_t vb, const sc_limits_t *lim)
{
    return sc_dist_q(va, vb, lim, -1);
}

int64_t sc_mul_sat(int64_t a, int64_t b)
{
    fx_u128_t x;

    if (a <= 0 || b <= 0) {
        return 0;
    }
    x = sc_mul((uint64_t)a, (uint64_t)b);
    return sc_sat(x.lo, x.hi != 0u);
}

/* ---- one block ------------------------------------------------------------------ */

/* jerk and plateau times (ns) of a speed change dv >= 0 */
static void sc_seg_times(int64_t dv, const sc_limits_t *lim, int64_t *tj, int64_t *ta)
{
    int64_t a = lim->a_max, j = lim->j_max;

    *tj = 0;
    *ta = 0;
    if (dv <= 0) {
        return;
    }
    if (lim->shape == SC_SHAPE_TRAPEZOID) {
        *ta = sc_muldiv(dv, (int64_t)NS, a);
        return;
    }
    if (dv >= sc_muldiv_ceil(a, a, j)) {
        *tj = sc_muldiv(a, (int64_t)NS, j);
        *ta = fx_max64(0, sc_muldiv(dv, (int64_t)NS, a) - *tj);
    } else {
        *tj = (int64_t)fx_isqrt64((uint64_t)sc_muldiv(dv, (int64_t)NS * (int64_t)NS, j));
    }
}

void sc_eval_phase(const sc_profile_t *p, int ph, int64_t t_ns, sc_state_t *out)
{
    const sc_state_t *s0 = &p->start[ph];
    int64_t j = p->jerk[ph];
    int64_t tq, in_s, in_v;

    if (t_ns == 0) { /* the phase start itself (every product below is 0) */
        *out = *s0;
        return;
    }
    if (j == 0 && s0->a_q16 == 0) {
        /* cruise: exact, any duration */
        out->a_q16 = 0;
        out->v_q16 = s0->v_q16;
        if (s0->v_q16 >= 0) {
            out->s_q16 = s0->s_q16 + sc_muldiv(s0->v_q16, t_ns, (int64_t)NS);
        } else {
            out->s_q16 = s0->s_q16 - sc_muldiv(-s0->v_q16, t_ns, (int64_t)NS);
        }
        return;
    }
    /* time in seconds * 2^40 (phases with acceleration last < 2^52 ns) */
    tq = fx_mul64_shift(t_ns, SC_NS_TO_Q40, 32);
    out->a_q16 = s0->a_q16 + fx_mul64_shift(j, tq, 24);
    in_v = s0->a_q16 + fx_mul64_shift(j, tq, 25);
    out->v_q16 = s0->v_q16 + fx_mul64_shift(in_v, tq, 40);
    in_s = fx_round_shift64(s0->a_q16, 1) + fx_mul64_shift(p->j6_q16[ph], tq, 40);
    in_s = s0->v_q16 + fx_mul64_shift(in_s, tq, 40);
    out->s_q16 = s0->s_q16 + fx_mul64_shift(in_s, tq, 40);
}

/* start states of phases first+1..last from the state at the start of
 * `first` (evaluating phases first..last-1); `set_acc` gives each phase's
 * acceleration in trapezoidal mode (set for phases first..last; NULL:
 * S-curve, nothing set) */
static void sc_chain(sc_profile_t *p, int first, int last, const int64_t *set_acc)
{
    int ph;
    for (ph = first; ph <= last; ph++) {
        if (set_acc != NULL) {
            p->start[ph].a_q16 = set_acc[ph];
        }
        if (ph == last) {
            break;
        }
        sc_eval_phase(p, ph, p->t_ns[ph], &p->start[ph + 1]);
    }
}

/* floor(x / 3) for any x < 2^64: the high word of x * ceil(2^65 / 3) over
 * 2 (exact for every 64-bit x), four 32 x 32 multiplies instead of a
 * 64-bit division call */
static int64_t sc_third(uint64_t x)
{
    return (int64_t)(fx_umulhi64(x, 0xAAAAAAAAAAAAAAABu) >> 1);
}

/* jerk of each phase and its evaluation constant (the division truncates,
 * so -x / 6 = -(x / 6)) */
static inline void sc_set_jerk(sc_profile_t *p, int64_t j)
{
    /* signs +, 0, -, 0, -, 0, + written out (no multiplies) */
    int64_t j6 = sc_third((uint64_t)j * 32768u); /* (j 2^16) / 6, j >= 0 */

    p->jerk[0] = j;
    p->jerk[1] = 0;
    p->jerk[2] = -j;
    p->jerk[3] = 0;
    p->jerk[4] = -j;
    p->jerk[5] = 0;
    p->jerk[6] = j;
    p->j6_q16[0] = j6;
    p->j6_q16[1] = 0;
    p->j6_q16[2] = -j6;
    p->j6_q16[3] = 0;
    p->j6_q16[4] = -j6;
    p->j6_q16[5] = 0;
    p->j6_q16[6] = j6;
}

/* floor(x / 10^9) for x < 2^48: (x m) >> 78 with m = ceil(2^78 / 10^9),
 * exact because x (m 10^9 - 2^78) < 2^48 10^9 < 2^78 (four 32 x 32
 * multiplies, no division) */
static uint64_t sc_div_ns48(uint64_t x)
{
    return fx_umulhi64(x, 302231454903658u) >> 14; /* m = 0x112E0BE826D6A */
}

static inline void sc_state_set(sc_state_t *st, int64_t s, int64_t v, int64_t a)
{
    st->s_q16 = s;
    st->v_q16 = v;
    st->a_q16 = a;
}

/* sc_plan of a block entered and left at its cruise speed v >= 1 (sc_plan
 * comes here too): only phase 3 lasts, every other phase of zero duration
 * is its start state (in trapezoidal mode phases 1 and 5 still carry their
 * set acceleration) */

void sc_plan_cruise_rec(sc_profile_t *p, int64_t len, int64_t v, const sc_limits_t *lim,
                        uint64_t rec)
{
    int64_t vq = v * 65536, t3 = 0, off = 0, a = lim->a_max, j;
    bool trap = lim->shape != SC_SHAPE_SCURVE; /* v > 0: the at-rest shape too */

    if (v < 1 || v < lim->v_max) {
        sc_plan(p, len, v, v, lim);
        return;
    }
    j = trap ? 0 : lim->j_max;
    len = fx_max64(len, 0);
    sc_set_jerk(p, j);
    if (len > 0 && len < ((int64_t)1 << 32) && v <= (int64_t)UINT32_MAX) {
        /* the same values without a 128-bit product: t3 = round(len NS / v)
         * from one 64/32 division (2 len NS < 2^63), and with the exact
         * residual e = v t3 - len NS (|e| <= v / 2 < 2^31),
         * off = floor(vq t3 / NS) = len 2^16 + floor(e 2^16 / NS) */
        uint64_t rem, n = 2u * (uint64_t)len * NS, q;
        int64_t e;
        if (rec != 0u) {
            /* q = floor(n rec / 2^64) is floor(n / v) or one less (rec =
             * floor((2^64 - 1) / v): n (2^64 / v - rec) / 2^64 < 1); the
             * remainder decides */
            q = fx_umulhi64(n, rec);
            q += (n - q * (uint64_t)v >= (uint64_t)v) ? 1u : 0u;
        } else {
            uint32_t q32 = fx_udiv64by32(n, (uint32_t)v); /* UINT32_MAX: too long */
            q = (q32 != UINT32_MAX) ? q32 : fx_udivmod64(n, (uint64_t)v, &rem);
        }
        t3 = (int64_t)((q + 1u) / 2u);
        e = (int64_t)((uint64_t)v * (uint64_t)t3 - (uint64_t)len * NS);
        if (e >= 0) {
            off = len * 65536 + (int64_t)sc_div_ns48((uint64_t)e << 16);
        } else {
            off = len * 65536 - (int64_t)sc_div_ns48(((uint64_t)-e << 16) + (NS - 1u));
        }
    } else if (len > 0) {
        /* (2 len 2^16 NS / vq + 1) / 2 with the 2^16 cancelled (the same
         * floor; a one-word divisor v < 2^32) */
        t3 = (sc_muldiv(2 * len, (int64_t)NS, v) + 1) / 2;
        off = sc_muldiv(vq, t3, (int64_t)NS);
    }
    a = trap ? a * 65536 : 0;
    /* every field written once, straight-line (the values of the loop
     * form: phase 3 lasts t3, phases 4..6 start at off, 1 and 5 carry the
     * set acceleration) */
    p->t_ns[0] = 0;
    p->t_ns[1] = 0;
    p->t_ns[2] = 0;
    p->t_ns[3] = t3;
    p->t_ns[4] = 0;
    p->t_ns[5] = 0;
    p->t_ns[6] = 0;
    sc_state_set(&p->start[0], 0, vq, 0);
    sc_state_set(&p->start[1], 0, vq, a);
    sc_state_set(&p->start[2], 0, vq, 0);
    sc_state_set(&p->start[3], 0, vq, 0);
    sc_state_set(&p->start[4], off, vq, 0);
    sc_state_set(&p->start[5], off, vq, -a);
    sc_state_set(&p->start[6], off, vq, 0);
    p->s_end_q16 = off;
    p->total_ns = t3;
    p->len = len;
    p->v0 = v;
    p->v1 = v;
    p->vp = v;
}

uint64_t sc_cruise_recip(int64_t v)
{
    uint64_t rem;

    return (v >= 1 && v <= (int64_t)UINT32_MAX) ? fx_udivmod64(UINT64_MAX, (uint64_t)v, &rem) : 0u;
}

void sc_plan(sc_profile_t *p, int64_t len, int64_t v0, int64_t v1, const sc_limits_t *lim)
{
    sc_limits_t tmp;
    bool trap;
    int64_t a, j;
    int64_t set_acc[SC_PHASES];
    int64_t vc, vp, tj, ta, s_acc, s_dec, rest, len_q16;
    sc_state_t e, dec5, dec6, dec_end;
    int ph;

    if (v0 == v1 && v0 >= 1 && v0 >= lim->v_max) {
        /* cruise only (the usual block of a path at its feed): only phase
         * 3 lasts (v0 > 0: the at-rest S-curve is the trapezoid here) */
        sc_plan_cruise_rec(p, len, v0, lim, 0u);
        return;
    }
    v0 = fx_max64(v0, 0);
    v1 = fx_max64(v1, 0);
    lim = sc_resolve(lim, fx_min64(v0, v1), &tmp); /* at rest at either end */
    trap = lim->shape == SC_SHAPE_TRAPEZOID;
    a = lim->a_max;
    j = trap ? 0 : lim->j_max;
    len = fx_max64(len, 0);
    vc = fx_max64(lim->v_max, fx_max64(v0, v1));

    /* peak speed */
    if (fx_sat_add64(sc_dist(v0, vc, lim), sc_dist(vc, v1, lim)) <= len) {
        vp = vc;
    } else if (trap) {
        /* vp^2 = (2 A len + v0^2 + v1^2) / 2, exact */
        fx_u128_t x = fx_add128(
            fx_add128(sc_mul((uint64_t)(2 * a), (uint64_t)len), sc_mul((uint64_t)v0, (uint64_t)v0)),
            sc_mul((uint64_t)v1, (uint64_t)v1));
        x.lo = (x.lo >> 1) | (x.hi << 63);
        x.hi >>= 1;
        vp = fx_min64(vc, fx_max64((int64_t)fx_isqrt128(x), fx_max64(v0, v1)));
    } else {
        int64_t vm = fx_max64(v0, v1), rem = len - sc_dist(v0, v1, lim);
        vp = (rem > 0) ? sc_reach_q16(vm, rem * 32768, lim, -1, -1, true) : vm; /* half of rem */
        vp = fx_min64(vc, vp);
    }
    if (vp < 1) {
        vp = 1;
    }

    /* every phase duration and start state is written below (start 0 here,
     * the others by the chains) */
    sc_set_jerk(p, j);
    p->start[0].s_q16 = 0;
    p->start[0].a_q16 = 0;
    if (trap) {
        for (ph = 0; ph < SC_PHASES; ph++) {
            set_acc[ph] = 0;
        }
        set_acc[1] = a * 65536;
        set_acc[5] = -a * 65536;
    }
    sc_seg_times(vp - v0, lim, &tj, &ta);
    p->t_ns[0] = tj;
    p->t_ns[1] = ta;
    p->t_ns[2] = tj;
    sc_seg_times(vp - v1, lim, &tj, &ta);
    p->t_ns[4] = tj;
    p->t_ns[5] = ta;
    p->t_ns[6] = tj;

    /* realised accel distance and peak speed: phases 0..2 (their start
     * states are final: they do not depend on the cruise time) */
    p->start[0].v_q16 = v0 * 65536;
    sc_chain(p, 0, 3, trap ? set_acc : NULL);
    s_acc = p->start[3].s_q16;
    /* realised decel distance from the realised peak */
    e = p->start[3];
    p->start[4].s_q16 = 0;
    p->start[4].v_q16 = e.v_q16;
    p->start[4].a_q16 = 0;
    sc_chain(p, 4, 6, trap ? set_acc : NULL);
    sc_eval_phase(p, 6, p->t_ns[6], &dec_end);
    s_dec = dec_end.s_q16;
    dec5 = p->start[5];
    dec6 = p->start[6];
    /* cruise covers the rest (rounded to the nearest ns) */
    len_q16 = len * 65536;
    rest = len_q16 - s_acc - s_dec;
    p->t_ns[3] = 0;
    if (rest > 0 && e.v_q16 > 0) {
        p->t_ns[3] = sc_muldiv(2 * rest, (int64_t)NS, e.v_q16);
        /* (t + 1) / 2 without overflow when sc_muldiv saturated */
        p->t_ns[3] = p->t_ns[3] / 2 + (p->t_ns[3] & 1);
    }
    /* final states from phase 3 on. With no acceleration left at the peak
     * (always in trapezoidal mode, and whenever the S-curve's rounding
     * leaves none) phase 3 is a pure cruise: phase 4 starts at the decel
     * chain's state moved by the cruise end point, and since a phase's
     * evaluation does not depend on its start distance, so do phases 5, 6
     * and the end (the same values as chaining them again). */
    sc_eval_phase(p, 3, p->t_ns[3], &p->start[4]);
    if (p->start[4].a_q16 == 0 && p->start[4].v_q16 == e.v_q16) {
        int64_t off = p->start[4].s_q16;
        p->start[5] = dec5;
        p->start[5].s_q16 += off;
        p->start[6] = dec6;
        p->start[6].s_q16 += off;
        e = dec_end;
        e.s_q16 += off;
    } else {
        sc_chain(p, 4, 6, trap ? set_acc : NULL);
        sc_eval_phase(p, 6, p->t_ns[6], &e);
    }
    p->s_end_q16 = e.s_q16;
    p->total_ns = 0;
    for (ph = 0; ph < SC_PHASES; ph++) {
        p->total_ns += p->t_ns[ph];
    }
    p->len = len;
    p->v0 = v0;
    p->v1 = v1;
    p->vp = p->start[3].v_q16 >> 16;
}

void sc_eval(const sc_profile_t *p, int64_t t_ns, sc_state_t *out)
{
    int ph = 0;

    if (t_ns < 0) {
        t_ns = 0;
    }
    while (ph < SC_PHASES - 1 && t_ns > p->t_ns[ph]) {
        t_ns -= p->t_ns[ph];
        ph++;
    }
    if (t_ns > p->t_ns[ph]) {
        t_ns = p->t_ns[ph];
    }
    sc_eval_phase(p, ph, t_ns, out);
}

int64_t sc_time_accel(const sc_profile_t *p)
{
    return p->t_ns[0] + p->t_ns[1] + p->t_ns[2];
}

int64_t sc_time_cruise(const sc_profile_t *p)
{
    return p->t_ns[3];
}

int64_t sc_time_decel(const sc_profile_t *p)
{
    return p->t_ns[4] + p->t_ns[5] + p->t_ns[6];
}
