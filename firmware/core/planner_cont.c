/*
 * planner_cont.c - the continuous S-curve (SC_SHAPE_SCURVE_CONTINUOUS);
 * the rules are in planner.h, "Continuous S-curve".
 *
 * A run's profile is seven phases of constant jerk like a block's
 * (scurve.h): phases 0..2 take the path from its state (v0, a0) to a speed
 * vp at a = 0 (R1), phase 3 cruises at vp, phases 4..6 change to the exit
 * speed v1 <= vp (R2). R1 from a0 != 0 is the tail of the ramp the state
 * lies on (jerk ahead keeps the sign of a0) or, when vp lies on the other
 * side of vn = v0 + a0 |a0| / 2J (the speed where a reaches 0 at once),
 * that first phase continued through a = 0 into the ramp from vn. A popped
 * block is the slice of this profile over its length: at most seven
 * phases, the same jerk per phase, the start states evaluated on the run's
 * profile, so the interpolator runs it unchanged.
 */
#include "planner_cont.h"
#include "planner_test.h"

#include "fixmath.h"

/* kept out of plan_cont_pop: the rare paths (a new plan, a queue of
 * several runs) would otherwise take registers from the usual pop */
#define PC_NOINLINE __attribute__((noinline))

#define PC_NS  ((int64_t)1000000000)
#define PC_Q16 ((int64_t)65536)

static plan_block_t *pc_at(const plan_t *p, uint16_t i)
{
    uint32_t idx = (uint32_t)p->tail + i;
    if (idx >= p->depth) {
        idx -= p->depth;
    }
    return &p->ring[idx];
}

/* A run's limits: v_max of its blocks, the smallest a and j of the axes
 * its blocks move less 2^-12 (b any block of the run: pc_joined keeps
 * one limit class per run). An axis that does not move has no path
 * acceleration or jerk; every direction of the moving axes keeps each of
 * them within its own limits, with room for the phase times' rounding to
 * whole ns. */
static void pc_limits(const plan_t *p, const plan_block_t *b, sc_limits_t *l)
{
    uint8_t c = p->same_limits ? 0u : b->cont_cls; /* plan_push's fast path: not set */

    l->v_max = b->lim.v_max;
    l->a_max = p->cont_a[c];
    l->j_max = p->cont_j[c];
    l->shape = SC_SHAPE_SCURVE;
}

/* Distance kept free at the end of a run for the rounding of the realised
 * profile (nm): 4 nm and about 7.5 ns at v, at most a quarter of it. */
static int64_t pc_margin(int64_t v, int64_t len)
{
    return fx_min64(4 + (v >> 27), len >> 2);
}

/* b continues a's run: the same speed limit and a junction that does not
 * limit it (no corner limit, stop, reversal or dwell between them, and
 * the same limit class: plan_push keeps v_junction below v_max where the
 * class changes, so a run's a and j never change while it grows and the
 * plan in force and the path state stay within them). */
static bool pc_joined(const plan_block_t *a, const plan_block_t *b)
{
    return b->lim.v_max > 0 && a->lim.v_max == b->lim.v_max && b->v_junction >= b->lim.v_max;
}

/* The run that starts at block i: index after its last block, *len its
 * length (nm). */
static uint16_t pc_run(const plan_t *p, uint16_t i, int64_t *len)
{
    const plan_block_t *a = pc_at(p, i);
    int64_t l = a->len;
    uint16_t k;

    for (k = (uint16_t)(i + 1u); k < p->count; k++) {
        const plan_block_t *b = pc_at(p, k);
        if (!pc_joined(a, b)) {
            break;
        }
        l += b->len;
        a = b;
    }
    *len = l;
    return k;
}

/* Reverse pass over the runs: the entry bound of every run but the oldest
 * (its first block's v_entry), from the queue's end at rest. From a = 0 at
 * the bound the run can cruise and then reach the next bound, or rest,
 * exactly at its end; a bound never falls (the exit bound it was computed
 * for can only have risen since: an earlier bound stays reachable). Also
 * the oldest run: index after its last block (returned), *len its length
 * (nm) and *x its exit bound (0: the queue's end). */
static PC_NOINLINE uint16_t pc_anchors(plan_t *p, int64_t *len, int64_t *x)
{
    int64_t ex = 0, l = 0;
    uint16_t i, e = p->count;
    uint32_t k = (uint32_t)p->tail + p->count - 1u; /* ring index of block i */
    plan_block_t *b, *a;

    if (k >= p->depth) {
        k -= p->depth;
    }
    b = &p->ring[k];
    for (i = (uint16_t)(p->count - 1u); i >= 1u; i--) {
        k = (k == 0u) ? p->depth - 1u : k - 1u;
        a = &p->ring[k];
        l += b->len;
        if (!pc_joined(a, b)) {
            sc_limits_t lim;
            /* twice the solver's margin: sc_dist may round a reach's
             * distance up past it by a few nm */
            int64_t v = 0, d = l - 2 * pc_margin(b->lim.v_max, l);
            pc_limits(p, b, &lim);
            if (d > 0) {
                d = fx_min64(d, SC_LEN_MAX);
                v = fx_max64(sc_reach(ex, d, &lim), sc_reach(0, d, &lim));
            }
            v = fx_min64(v, b->v_junction);
            b->v_entry = fx_max64(v, b->v_entry);
            ex = b->v_entry;
            l = 0;
            e = i;
        }
        b = a;
    }
    *len = l + b->len;
    *x = (e < p->count) ? ex : 0;
    return e;
}

/* pc_anchors, skipped while the whole queue is one run (the usual CAM
 * path): then only the blocks queued since the last pop need a look. */
static void pc_first_run(plan_t *p, int64_t *len, int64_t *x)
{
    uint16_t i = p->cont_scan;

    if (i > 0u && p->cont_run_n == i && i <= p->count) {
        int64_t l = p->cont_run_len;
        const plan_block_t *a = pc_at(p, (uint16_t)(i - 1u));
        for (; i < p->count; i++) {
            const plan_block_t *b = pc_at(p, i);
            if (!pc_joined(a, b)) {
                break;
            }
            l += b->len;
            a = b;
        }
        if (i == p->count) {
            p->cont_scan = i;
            p->cont_run_n = i;
            p->cont_run_len = l;
            *len = l;
            *x = 0;
            return;
        }
    }
    p->cont_run_n = pc_anchors(p, len, x);
    p->cont_scan = p->count;
    p->cont_run_len = *len;
}

/* The plan cruising at vp on to R2 as before, over the longer run len:
 * what pc_plan_run gives from the state (vp, a = 0) when R2 stays. */
static void pc_recruise(sc_profile_t *P, int64_t len)
{
    int64_t vq = P->vp * PC_Q16, s2 = P->s_end_q16 - P->start[4].s_q16;
    int64_t rest = len * PC_Q16 - s2, sh;
    sc_state_t c;
    int ph;

    for (ph = 0; ph <= 3; ph++) {
        P->start[ph].s_q16 = 0;
        P->start[ph].v_q16 = vq;
        P->start[ph].a_q16 = 0;
        P->t_ns[ph] = 0;
    }
    if (rest > 0 && vq > 0) {
        P->t_ns[3] = sc_muldiv(2 * rest, PC_NS, vq);
        P->t_ns[3] = P->t_ns[3] / 2 + (P->t_ns[3] & 1);
    }
    sc_eval_phase(P, 3, P->t_ns[3], &c);
    sh = c.s_q16 - P->start[4].s_q16;
    P->start[4].s_q16 += sh;
    P->start[5].s_q16 += sh;
    P->start[6].s_q16 += sh;
    P->s_end_q16 += sh;
    P->total_ns = P->t_ns[3] + P->t_ns[4] + P->t_ns[5] + P->t_ns[6];
    P->len = len;
    P->v0 = P->vp;
}

/* Phase times of a speed change dv >= 0 between a = 0 and a = 0. */
static void pc_seg(int64_t dv, const sc_limits_t *l, int64_t *tj, int64_t *ta)
{
    *tj = 0;
    *ta = 0;
    if (dv <= 0) {
        return;
    }
    if (sc_cmp_products((uint64_t)dv, (uint64_t)l->j_max, (uint64_t)l->a_max, (uint64_t)l->a_max) >=
        0) {
        *tj = sc_muldiv(l->a_max, PC_NS, l->j_max);
        *ta = fx_max64(0, sc_muldiv(dv, PC_NS, l->a_max) - *tj);
    } else {
        *tj = (int64_t)fx_isqrt64((uint64_t)sc_muldiv(dv, PC_NS * PC_NS, l->j_max));
    }
}

static void pc_jerk(sc_profile_t *P, int ph, int64_t j)
{
    int64_t j6 = (j < 0 ? -j : j) * (PC_Q16 / 2) / 3; /* |j| 2^16 / 6 */
    P->jerk[ph] = j;
    P->j6_q16[ph] = (j < 0) ? -j6 : j6;
}

/* Start states of phases first+1 .. last+1 (last+1 <= 6; 7: *end). */
static void pc_chain(sc_profile_t *P, int first, int last, sc_state_t *end)
{
    int ph;
    for (ph = first; ph <= last; ph++) {
        sc_eval_phase(P, ph, P->t_ns[ph], (ph < SC_PHASES - 1) ? &P->start[ph + 1] : end);
    }
}

/* R1: phases 0..2 of *P from (v0q, a0q) (q16) to vp (nm/s) at a = 0, and
 * start[0..3] (start[3] the realised end of R1, not yet snapped). */
static void pc_r1(sc_profile_t *P, int64_t v0q, int64_t a0q, int64_t vp, const sc_limits_t *l)
{
    int64_t j = l->j_max, v0 = v0q / PC_Q16, a0 = a0q / PC_Q16;
    int64_t aa = (a0 < 0) ? -a0 : a0;
    int64_t tau = sc_muldiv(aa, PC_NS, j), h = sc_muldiv(aa, aa, 2 * j);
    int64_t vn = (a0 >= 0) ? v0 + h : v0 - h, tj, ta, t0, js;

    if (vp >= vn) {
        js = j;
        if (a0 >= 0) { /* the rest of the rising ramp from v0 - h */
            pc_seg(vp - (v0 - h), l, &tj, &ta);
            t0 = fx_max64(0, tj - tau);
        } else { /* through a = 0 at vn, then up */
            pc_seg(vp - vn, l, &tj, &ta);
            t0 = tau + tj;
        }
    } else {
        js = -j;
        if (a0 <= 0) {
            pc_seg((v0 + h) - vp, l, &tj, &ta);
            t0 = fx_max64(0, tj - tau);
        } else {
            pc_seg(vn - vp, l, &tj, &ta);
            t0 = tau + tj;
        }
    }
    P->t_ns[0] = t0;
    P->t_ns[1] = ta;
    P->t_ns[2] = tj;
    pc_jerk(P, 0, js);
    pc_jerk(P, 1, 0);
    pc_jerk(P, 2, -js);
    P->start[0].s_q16 = 0;
    P->start[0].v_q16 = v0q;
    P->start[0].a_q16 = a0q;
    pc_chain(P, 0, 2, NULL);
}

/* R1 to vp and R2 to v1 fit in lq (q16 nm, the margin taken off); v1 the
 * exit bound x (or vp below it), else rest. */
static bool pc_fits(sc_profile_t *P, int64_t v0q, int64_t a0q, int64_t vp, int64_t x, int64_t lq,
                    const sc_limits_t *l, int64_t *v1)
{
    int64_t s1;

    pc_r1(P, v0q, a0q, vp, l);
    s1 = P->start[3].s_q16;
    if (P->start[3].v_q16 < 0 || s1 > lq) {
        return false;
    }
    *v1 = fx_min64(vp, x);
    if (s1 + sc_mul_sat(sc_dist(vp, *v1, l), PC_Q16) <= lq) {
        return true;
    }
    *v1 = 0;
    return *v1 < vp && s1 + sc_mul_sat(sc_dist(vp, 0, l), PC_Q16) <= lq;
}

/* The whole profile over len nm: R1 to vp already in P (pc_r1), the
 * cruise, R2 to v1. */
static void pc_build(sc_profile_t *P, int64_t vp, int64_t v1, int64_t len, const sc_limits_t *l)
{
    int64_t vq = vp * PC_Q16, tj, ta, rest, s3;
    sc_state_t end;

    s3 = P->start[3].s_q16;
    /* phase 3 starts exactly at vp with a = 0: a pure cruise (the
     * interpolator's fast path); the step is the rounding of R1 */
    P->start[3].v_q16 = vq;
    P->start[3].a_q16 = 0;
    pc_seg(vp - v1, l, &tj, &ta);
    P->t_ns[3] = 0;
    P->t_ns[4] = tj;
    P->t_ns[5] = ta;
    P->t_ns[6] = tj;
    pc_jerk(P, 3, 0);
    pc_jerk(P, 4, -l->j_max);
    pc_jerk(P, 5, 0);
    pc_jerk(P, 6, l->j_max);
    /* R2 from s = 0 (a phase's evaluation does not depend on its start
     * distance: shifted below), then the cruise covers the rest */
    P->start[4] = P->start[3];
    P->start[4].s_q16 = 0;
    pc_chain(P, 4, 6, &end);
    rest = len * PC_Q16 - s3 - end.s_q16;
    if (rest > 0 && vq > 0) {
        P->t_ns[3] = sc_muldiv(2 * rest, PC_NS, vq);
        P->t_ns[3] = P->t_ns[3] / 2 + (P->t_ns[3] & 1);
    }
    {
        sc_state_t c;
        sc_eval_phase(P, 3, P->t_ns[3], &c); /* cruise: v and a unchanged */
        P->start[4].s_q16 = c.s_q16;
        P->start[5].s_q16 += c.s_q16;
        P->start[6].s_q16 += c.s_q16;
        end.s_q16 += c.s_q16;
    }
    P->s_end_q16 = end.s_q16;
    P->total_ns =
        P->t_ns[0] + P->t_ns[1] + P->t_ns[2] + P->t_ns[3] + P->t_ns[4] + P->t_ns[5] + P->t_ns[6];
    P->len = len;
    P->v0 = P->start[0].v_q16 / PC_Q16;
    P->vp = vp;
    P->v1 = v1;
}

/* Bisection for the highest speed that fits in [lo, hi) (lo fits, hi does
 * not), to within 2^-12 of hi; *last the speed P holds R1 for. */
static int64_t pc_bisect(sc_profile_t *P, int64_t v0q, int64_t a0q, int64_t lo, int64_t hi,
                         int64_t x, int64_t lq, const sc_limits_t *l, int64_t *last)
{
    int64_t v1;

    while (hi - lo > fx_max64(1, hi >> 12)) {
        int64_t mid = lo + (hi - lo) / 2;
        *last = mid;
        if (pc_fits(P, v0q, a0q, mid, x, lq, l, &v1)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

/* Plan the run (len nm, exit bound x) from the state (v0q, a0q): the
 * highest vp that fits, R1 and R2 included. False when none fits. */
static PC_NOINLINE bool pc_plan_run(sc_profile_t *P, int64_t v0q, int64_t a0q, int64_t len,
                                    int64_t x, const sc_limits_t *l)
{
    int64_t vmax = l->v_max, v0 = v0q / PC_Q16, a0 = a0q / PC_Q16, aa = (a0 < 0) ? -a0 : a0;
    int64_t h = sc_muldiv(aa, aa, 2 * l->j_max), vn = (a0 >= 0) ? v0 + h : v0 - h;
    int64_t lq = (len - pc_margin(vmax, len)) * PC_Q16, vp, v1 = 0, v1t, last;
    int k;

    if (vn < 0 || v0 < 0 || lq <= 0) {
        return false;
    }
    vn = fx_min64(vn, vmax);
    last = vn;
    if (pc_fits(P, v0q, a0q, vn, x, lq, l, &v1)) {
        vp = vn; /* cruising at the limit: the usual block */
        if (vn < vmax) {
            last = vmax;
            vp = pc_fits(P, v0q, a0q, vmax, x, lq, l, &v1t)
                     ? vmax
                     : pc_bisect(P, v0q, a0q, vn, vmax, x, lq, l, &last);
        }
    } else {
        /* slow down below vn: the distance is not monotone in vp there,
         * so the highest of sixteen steps that fits, then bisection */
        vp = 0;
        for (k = 15; k >= 1 && vp == 0; k--) {
            int64_t c = vn * k / 16;
            last = c;
            if (c > 0 && pc_fits(P, v0q, a0q, c, x, lq, l, &v1t)) {
                vp = pc_bisect(P, v0q, a0q, c, vn * (k + 1) / 16, x, lq, l, &last);
            }
        }
        if (vp == 0) {
            return false;
        }
    }
    if (last != vp || vp != vn) {
        (void)pc_fits(P, v0q, a0q, vp, x, lq, l, &v1); /* R1 of vp in P, its v1 */
    }
    pc_build(P, vp, v1, len, l);
    return true;
}

/* The cruise at v_q16 = W 2^16 (W < 2^32, the run's phase 3) from s0:
 * the smallest tau with s0 + floor(v tau / 1e9) >= s0 + dq, and that
 * distance, for 0 < dq < 2^42 (q16: 64 m). The same tau as
 * sc_muldiv_ceil(dq, 1e9, v) and the same distance as sc_eval_phase's
 * cruise at tau, from 64-bit products and two 64-bit divisions by
 * invariant divisors: tau = ceil(m / W), m = ceil(dq 1e9 / 2^16) = ceil(dq
 * 1953125 / 2^7) < 2^57, with rec = floor((2^64 - 1) / W) (0: divided;
 * fixmath divides by 1e9 with its reciprocal); and v tau - dq 1e9 lies in
 * [0, v) (tau is the ceiling), so floor(v tau / 1e9) = dq + floor((v tau -
 * dq 1e9) / 1e9), the difference exact modulo 2^64. False outside that
 * range (then the caller divides). */
static bool pc_cruise_time(int64_t v_q16, int64_t dq, uint64_t rec, int64_t *tau, int64_t *ds)
{
    uint64_t w = (uint64_t)v_q16 >> 16, m, t, rem, r;

    if (dq <= 0 || dq >= ((int64_t)1 << 42) || (v_q16 & 0xFFFF) != 0 || w == 0u ||
        (w >> 32) != 0u) {
        return false;
    }
    m = ((uint64_t)dq * 1953125u + 127u) >> 7;
    if (rec != 0u) {
        /* floor(m rec / 2^64) is floor(m / w) or one less (as in
         * scurve.c's sc_plan_cruise_rec); the remainder decides */
        t = fx_umulhi64(m, rec);
        rem = m - t * w;
        if (rem >= w) {
            t++;
            rem -= w;
        }
    } else {
        t = fx_udivmod64(m, w, &rem);
    }
    t += (rem != 0u) ? 1u : 0u;
    r = (uint64_t)v_q16 * t - (uint64_t)dq * (uint64_t)PC_NS; /* in [0, v) */
    *tau = (int64_t)t;
    *ds = dq + (int64_t)fx_udivmod64(r, (uint64_t)PC_NS, &rem);
    return true;
}

bool plan_test_cont_cruise_time(int64_t v_q16, int64_t dq, bool recip, int64_t *tau, int64_t *ds)
{
    return pc_cruise_time(v_q16, dq, recip ? sc_cruise_recip(v_q16 >> 16) : 0u, tau, ds);
}

/* Smallest t in [t0, total] with s(t) >= sq (total if none), P = the
 * run's plan; *e the state there (what sc_eval(P, t) gives) when *known,
 * else the caller evaluates. Keeps the reciprocal of the cruise speed
 * (p->cruise_v, p->cruise_rec: unused by the other shapes). */
static int64_t pc_time_at(plan_t *p, int64_t t0, int64_t sq, sc_state_t *e, bool *known)
{
    const sc_profile_t *P = &p->cont_prof;
    int64_t T = 0;
    int ph;

    *known = false;
    for (ph = 0; ph < SC_PHASES; ph++) {
        int64_t end = (ph < SC_PHASES - 1) ? P->start[ph + 1].s_q16 : P->s_end_q16;
        if (T + P->t_ns[ph] > t0 && end >= sq) {
            const sc_state_t *s0 = &P->start[ph];
            int64_t lo = fx_max64(0, t0 - T), hi = P->t_ns[ph];
            sc_state_t st;
            if (P->jerk[ph] == 0 && s0->a_q16 == 0 && s0->v_q16 > 0) {
                /* cruise: s0 + floor(v tau / 1e9) >= sq, exactly */
                int64_t t, ds, w = s0->v_q16 >> 16;
                if (p->cruise_v != w) {
                    p->cruise_v = w;
                    p->cruise_rec = sc_cruise_recip(w);
                }
                if (pc_cruise_time(s0->v_q16, sq - s0->s_q16, p->cruise_rec, &t, &ds)) {
                    if (t > lo && t <= hi) {
                        /* inside this phase (t > 0): sc_eval's state */
                        e->s_q16 = s0->s_q16 + ds;
                        e->v_q16 = s0->v_q16;
                        e->a_q16 = 0;
                        *known = true;
                    }
                } else {
                    t = sc_muldiv_ceil(sq - s0->s_q16, PC_NS, s0->v_q16);
                }
                return T + fx_min64(hi, fx_max64(lo, t));
            }
            while (lo < hi) {
                int64_t mid = lo + (hi - lo) / 2;
                sc_eval_phase(P, ph, mid, &st);
                if (st.s_q16 >= sq) {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            return T + lo;
        }
        T += P->t_ns[ph];
    }
    return P->total_ns;
}

/* The block's profile: P over [ta, tb] (ta <= tb), sa P's state at ta,
 * *e its state at tb (set by the caller). A phase outside the slice
 * starts where the slice starts (it ends by ta: the phases before ph_a)
 * or ends (it starts at tb or later: from ph_b on), so sc_eval of the
 * slice agrees at 0 and at its end. */
static void pc_slice(const sc_profile_t *P, int64_t ta, const sc_state_t *sa, int64_t tb,
                     int64_t len, sc_profile_t *o, const sc_state_t *e)
{
    int64_t T = 0, Ta, s0 = sa->s_q16, vp = fx_max64(sa->v_q16, e->v_q16);
    int ph, ph_a, ph_b;

    for (ph_a = 0; ph_a < SC_PHASES && T + P->t_ns[ph_a] <= ta; ph_a++) {
        T += P->t_ns[ph_a];
    }
    Ta = T; /* the phase ends only grow: none after ph_a ends by ta */
    for (ph_b = ph_a; ph_b < SC_PHASES && T < tb; ph_b++) {
        T += P->t_ns[ph_b];
    }
    T = Ta;
    for (ph = 0; ph < SC_PHASES; ph++) {
        const sc_state_t *src = sa;
        int64_t t = 0;
        if (ph >= ph_b) {
            src = e;
        } else if (ph >= ph_a) {
            /* [max(T, ta), min(Tn, tb)]: the phase starts in the slice
             * (its start state), or ta falls in it (sa is its state) */
            int64_t Tn = T + P->t_ns[ph];
            t = ((Tn <= tb) ? Tn : tb) - ((T >= ta) ? T : ta);
            src = (T >= ta) ? &P->start[ph] : sa;
            if (t > 0 && src->v_q16 > vp) {
                vp = src->v_q16;
            }
            T = Tn;
        }
        o->t_ns[ph] = t;
        o->jerk[ph] = P->jerk[ph];
        o->j6_q16[ph] = P->j6_q16[ph];
        o->start[ph].s_q16 = src->s_q16 - s0;
        o->start[ph].v_q16 = src->v_q16;
        o->start[ph].a_q16 = src->a_q16;
    }
    o->s_end_q16 = e->s_q16 - s0;
    o->total_ns = tb - ta;
    o->len = len;
    o->v0 = sa->v_q16 / PC_Q16;
    o->v1 = e->v_q16 / PC_Q16;
    o->vp = vp / PC_Q16;
}

/* pc_time_at and pc_slice for a block that starts in the cruise (phase
 * 3 of P, a = 0) at ta = p->cont_t_ns and ends in it (by start[4]),
 * without their searches over the phases: phases 0..2 end by T3 <= ta,
 * so pc_time_at takes phase 3 (its end start[4].s >= sq), where
 * pc_cruise_time gives tb = T3 + tau (tau in (ta - T3, t_ns[3]]: else
 * false and the general path) and the state there; the slice's phase
 * range is then [3, 4): phases 0..2 start at sa, 4..6 at e, phase 3 lasts
 * tb - ta from start[3] (ta = T3) or sa. Fills o, *tb and *e as they do. */
static bool pc_cruise_slice(plan_t *p, int64_t len, sc_profile_t *o, int64_t *tb, sc_state_t *e)
{
    const sc_profile_t *P = &p->cont_prof;
    const sc_state_t *sa = &p->cont_st, *s3 = &P->start[3], *src;
    int64_t T3 = P->t_ns[0] + P->t_ns[1] + P->t_ns[2], ta = p->cont_t_ns, s0 = sa->s_q16;
    int64_t sq = s0 + len * PC_Q16, w = s3->v_q16 >> 16, tau, ds, vp;
    int ph;

    if (ta < T3 || ta - T3 >= P->t_ns[3] || P->jerk[3] != 0 || s3->a_q16 != 0 || s3->v_q16 <= 0 ||
        P->start[4].s_q16 < sq) {
        return false;
    }
    if (p->cruise_v != w) {
        p->cruise_v = w;
        p->cruise_rec = sc_cruise_recip(w);
    }
    if (!pc_cruise_time(s3->v_q16, sq - s3->s_q16, p->cruise_rec, &tau, &ds) || tau <= ta - T3 ||
        tau > P->t_ns[3]) {
        return false;
    }
    *tb = T3 + tau;
    e->s_q16 = s3->s_q16 + ds;
    e->v_q16 = s3->v_q16;
    e->a_q16 = 0;
    src = (T3 >= ta) ? s3 : sa;
    vp = fx_max64(fx_max64(sa->v_q16, e->v_q16), src->v_q16); /* tb > ta */
    for (ph = 0; ph < SC_PHASES; ph++) {
        o->t_ns[ph] = 0;
        o->jerk[ph] = P->jerk[ph];
        o->j6_q16[ph] = P->j6_q16[ph];
    }
    for (ph = 0; ph < 3; ph++) {
        o->start[ph].s_q16 = 0;
        o->start[ph].v_q16 = sa->v_q16;
        o->start[ph].a_q16 = sa->a_q16;
    }
    o->t_ns[3] = *tb - ta;
    o->start[3].s_q16 = src->s_q16 - s0;
    o->start[3].v_q16 = src->v_q16;
    o->start[3].a_q16 = src->a_q16;
    for (ph = 4; ph < SC_PHASES; ph++) {
        o->start[ph].s_q16 = e->s_q16 - s0;
        o->start[ph].v_q16 = e->v_q16;
        o->start[ph].a_q16 = 0;
    }
    o->s_end_q16 = e->s_q16 - s0;
    o->total_ns = *tb - ta;
    o->len = len;
    o->v0 = sa->v_q16 / PC_Q16;
    o->v1 = e->v_q16 / PC_Q16;
    o->vp = vp / PC_Q16;
    return true;
}

bool plan_cont_profile_ok(const plan_profile_t *prof)
{
    int64_t v = prof->v_max[0], a = prof->a_max[0];
    int i;

    for (i = 1; i < CORE_AXES; i++) {
        v = fx_max64(v, prof->v_max[i]);
        a = fx_min64(a, prof->a_max[i]);
    }
    return sc_muldiv(v, v, a) <= ((int64_t)1 << 45) / 3;
}

int64_t plan_cont_derive(plan_t *p)
{
    int64_t amin = INT64_MAX;
    unsigned mask, k;
    int i;

    for (mask = 0; mask < (1u << CORE_AXES); mask++) {
        int64_t a = INT64_MAX, j = INT64_MAX;
        for (i = 0; i < CORE_AXES; i++) {
            if (mask == 0u || (mask & (1u << i)) != 0u) { /* 0: every axis */
                a = fx_min64(a, p->prof.a_max[i]);
                j = fx_min64(j, p->prof.j_max[i]);
            }
        }
        amin = (mask == 0u) ? a : amin;
        p->cont_a[mask] = a - (a >> 12);
        p->cont_j[mask] = j - (j >> 12);
        p->cont_cls[mask] = (uint8_t)mask;
        for (k = 0; k < mask; k++) { /* the smallest mask with these limits */
            if (p->cont_a[k] == p->cont_a[mask] && p->cont_j[k] == p->cont_j[mask]) {
                p->cont_cls[mask] = (uint8_t)k;
                break;
            }
        }
    }
    return amin;
}

/* Out of line: plan_push's usual path (equal limits) keeps its registers. */
PC_NOINLINE void plan_cont_class(plan_t *p, plan_block_t *b)
{
    uint8_t c = b->cont_cls;

    b->lim.a_max = p->cont_a[c]; /* (plan_push leaves them unset) */
    b->lim.j_max = p->cont_j[c];
    if (c != p->last_cls && b->v_junction >= b->lim.v_max) {
        b->v_junction = b->lim.v_max - 1; /* pc_joined: an anchor */
    }
    p->last_cls = c;
}

void plan_cont_reset(plan_t *p)
{
    p->last_cls = 0;
    p->cont_t_ns = 0;
    p->cont_rem = 0;
    p->cont_x = 0;
    p->cont_st.s_q16 = 0;
    p->cont_st.v_q16 = 0;
    p->cont_st.a_q16 = 0;
    p->cont_kept = 0;
    p->cont_forced = 0;
    p->cont_scan = 0;
    p->cont_run_n = 0;
    p->cont_run_len = 0;
}

void plan_cont_pop(plan_t *p, plan_seg_t *out)
{
    plan_block_t *b = &p->ring[p->tail];
    sc_profile_t *P = &p->cont_prof;
    sc_limits_t l;
    sc_state_t e;
    int64_t len, x, tb;
    bool known;

    pc_first_run(p, &len, &x);
    if (p->cont_rem != len || p->cont_x != x) {
        /* the run grew or its exit bound rose: a new plan from the state */
        sc_state_t st = p->cont_st;
        sc_profile_t np;
        bool cruise = p->cont_rem > 0 && len > p->cont_rem && x == p->cont_x && st.a_q16 == 0 &&
                      P->vp == b->lim.v_max && st.v_q16 == P->vp * PC_Q16 &&
                      P->v1 == fx_min64(P->vp, x);
        if (cruise && b->len < p->cont_rem && st.s_q16 + b->len * PC_Q16 <= P->start[4].s_q16) {
            /* cruising at the limit and still before R2: the plan in force
             * gives this block what a new one would (a longer run only
             * moves R2 on); planned again when a block reaches R2 */
            len = p->cont_rem;
        } else if (cruise) {
            pc_recruise(P, len); /* cruising at the limit: R2 moves on */
            p->cont_t_ns = 0;
        } else {
            pc_limits(p, b, &l); /* only a new plan needs them */
            if (pc_plan_run(&np, st.v_q16, st.a_q16, len, x, &l)) {
                *P = np;
                p->cont_t_ns = 0;
            } else if (p->cont_rem > 0) {
                p->cont_kept++; /* the plan in force still ends within limits */
                len = p->cont_rem;
                x = p->cont_x;
            } else {
                /* no plan from this state (never seen: the tests count it) */
                int64_t v = fx_max64(1, fx_min64(l.v_max, st.v_q16 / PC_Q16));
                p->cont_forced++;
                pc_r1(P, st.v_q16, st.a_q16, v, &l);
                pc_build(P, v, 0, len, &l);
                p->cont_t_ns = 0;
            }
        }
        p->cont_st.s_q16 = (p->cont_t_ns == 0) ? 0 : p->cont_st.s_q16;
        p->cont_rem = len;
        p->cont_x = x;
    }
    /* the block's end tb on the plan, the state e there and its slice
     * (pc_cruise_slice does all three for a block inside the cruise) */
    if (b->len >= p->cont_rem) {
        tb = P->total_ns;
        known = false;
    } else if (pc_cruise_slice(p, b->len, &out->prof, &tb, &e)) {
        known = true;
    } else {
        tb = pc_time_at(p, p->cont_t_ns, p->cont_st.s_q16 + b->len * PC_Q16, &e, &known);
        if (known) {
            pc_slice(P, p->cont_t_ns, &p->cont_st, tb, b->len, &out->prof, &e);
        }
    }
    if (!known) {
        sc_eval(P, tb, &e);
        pc_slice(P, p->cont_t_ns, &p->cont_st, tb, b->len, &out->prof, &e);
    }
    out->total_ns = out->prof.total_ns;
    p->cont_rem -= b->len;
    if (p->cont_scan > 0u) { /* the first-run cache, one block on */
        p->cont_scan--;
        p->cont_run_n = (p->cont_run_n > 0u) ? (uint16_t)(p->cont_run_n - 1u) : 0u;
        p->cont_run_len -= b->len;
    }
    if (p->cont_rem <= 0) {
        /* the plan's end: its exit speed at a = 0 */
        out->prof.v1 = P->v1;
        p->cont_rem = 0;
        p->cont_t_ns = 0;
        p->cont_st.s_q16 = 0;
        p->cont_st.v_q16 = P->v1 * PC_Q16;
        p->cont_st.a_q16 = 0;
    } else {
        p->cont_t_ns = tb;
        p->cont_st = e;
    }
}

int64_t plan_cont_queued_ns(const plan_t *p)
{
    int64_t sum = 0;
    uint16_t i = 0;

    while (i < p->count) {
        const plan_block_t *b = pc_at(p, i);
        int64_t len, x, v0;
        uint16_t e;
        sc_limits_t l;
        sc_profile_t pr;

        if (b->dwell_ns > 0) {
            sum += b->dwell_ns;
            i++;
            continue;
        }
        e = pc_run(p, i, &len);
        x = (e < p->count) ? pc_at(p, e)->v_entry : 0;
        if (i == 0 && p->cont_rem == len && p->cont_x == x) {
            sum += p->cont_prof.total_ns - p->cont_t_ns; /* the plan in force */
        } else {
            v0 = (i == 0) ? p->cont_st.v_q16 / PC_Q16 : b->v_entry;
            pc_limits(p, b, &l);
            sc_plan(&pr, fx_min64(len, SC_LEN_MAX), v0, x, &l);
            sum += pr.total_ns;
        }
        i = e;
    }
    return sum;
}
