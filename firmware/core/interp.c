/*
 * interp.c - per-tick reference generation; see interp.h.
 */
#include "interp.h"

#if (INTERP_FIFO & (INTERP_FIFO - 1)) != 0
#error "INTERP_FIFO must be a power of two"
#endif

void interp_reset(interp_t *ip, const pos_nm_t pos[CORE_AXES])
{
    int i;

    ip->wr = 0;
    ip->rd = 0;
    ip->busy = false;
    ip->t_ns = 0;
    ip->phase = 0;
    ip->phase_t0 = 0;
    ip->corr_q32 = 0;
    ip->s_q16 = 0;
    ip->v_q16 = 0;
    ip->a_q16 = 0;
    ip->cr_ok = false;
    ip->cr_fast = false;
    ip->ref_pos_only = false;
    ip->fast_skip = 0;
    for (i = 0; i < CORE_AXES; i++) {
        ip->pos[i] = pos[i];
        ip->tan[i] = 0;
    }
}

void interp_init(interp_t *ip, int64_t tick_ns, const pos_nm_t start[CORE_AXES])
{
    interp_reset(ip, start);
    ip->tick_ns = tick_ns > 0 ? tick_ns : 1;
    ip->ticks = 0;
    ip->busy_ticks = 0;
    ip->blocks_done = 0;
    ip->underruns = 0;
    ip->tag = 0;
}

static uint16_t ip_queued(const interp_t *ip)
{
    return (uint16_t)(ip->wr - ip->rd);
}

uint16_t interp_room(const interp_t *ip)
{
    return (uint16_t)(INTERP_FIFO - ip_queued(ip));
}

unsigned interp_refill(interp_t *ip, plan_t *p)
{
    unsigned n = 0;
    plan_seg_t *slot;

    if (interp_room(ip) > 0 && plan_count(p) > 0) {
        slot = &ip->fifo[ip->wr & (INTERP_FIFO - 1)];
        if (plan_pop(p, slot) == PLAN_OK) {
            ip->wr = (uint16_t)(ip->wr + 1u);
            n = 1;
        }
    }
    return n;
}

int64_t interp_ahead_ns(const interp_t *ip)
{
    uint16_t rd = ip->rd, wr = ip->wr, i;
    int64_t sum = 0;

    if ((uint16_t)(wr - rd) > INTERP_FIFO) {
        return 0;
    }
    for (i = (uint16_t)(rd + 1u); i != wr && rd != wr; i++) {
        sum += ip->fifo[i & (INTERP_FIFO - 1)].total_ns;
    }
    return sum;
}

int64_t interp_queued_ns(const interp_t *ip, uint16_t rd, int64_t rem_rd)
{
    uint16_t wr = ip->wr, i;
    int64_t sum = 0;

    if ((uint16_t)(wr - rd) <= INTERP_FIFO) {
        for (i = rd; i != wr; i++) {
            sum += (i == rd && rem_rd >= 0) ? rem_rd : ip->fifo[i & (INTERP_FIFO - 1)].total_ns;
        }
    }
    return sum;
}

#define IP_RECIP_1E9_Q64 18446744073ull /* floor(2^64 / 1e9) */

int64_t interp_cruise_ds_q32(const interp_t *ip)
{
    int64_t ds;

    if (ip->cr_dq >= ((uint64_t)1 << 46)) {
        return -1;
    }
    /* cr_dr / 1e9 * 2^16 (< 2^16) by the reciprocal: within 1 of the exact
     * floor, 2.3e-10 nm */
    ds = (int64_t)(ip->cr_dq << 16) +
         (int64_t)fx_umulhi64((uint64_t)ip->cr_dr << 16, IP_RECIP_1E9_Q64);
    return ds + fx_mul64x32_shift(ds, (int32_t)ip->corr_q32, 32);
}

/* Positions from q62 direction ratios: round(a * r / 2^78) (shift rule),
 * fx_umul_shift_hi with t = 14; the cruise path keeps |r| and its sign. */
#define IP_RATIO_SHIFT_HI 14u

/* round(a * r / 2^78) == fx_mul64_shift(a, r, 78) for every int64 a, r */
static inline int64_t ip_scale(int64_t a, int64_t r)
{
    return fx_umul_shift_hi(fx_uabs64(a), fx_uabs64(r), (a < 0) != (r < 0), IP_RATIO_SHIFT_HI);
}

#define IP_NS ((uint64_t)1000000000u)

static const plan_seg_t *ip_cur(const interp_t *ip)
{
    return &ip->fifo[ip->rd & (INTERP_FIFO - 1)];
}

static void ip_begin(interp_t *ip)
{
    const plan_seg_t *s = ip_cur(ip);
    int64_t diff;
    int i;

    ip->busy = true;
    ip->phase = 0;
    ip->phase_t0 = 0;
    ip->corr_q32 = 0;
    ip->cr_ok = false;
    ip->cr_fast = false;
    ip->tag = s->tag;
    for (i = 0; i < CORE_AXES; i++) {
        ip->tan[i] = (q1_30_t)(s->ratio_q62[i] / ((int64_t)1 << 32));
    }
    if (s->dwell_ns > 0 || s->prof.s_end_q16 <= 0) {
        return;
    }
    diff = s->len * 65536 - s->prof.s_end_q16;
    if (diff > 0) {
        ip->corr_q32 = sc_muldiv(diff, (int64_t)1 << 32, s->prof.s_end_q16);
    } else if (diff < 0) {
        ip->corr_q32 = -sc_muldiv(-diff, (int64_t)1 << 32, s->prof.s_end_q16);
    }
}

/* The arc fields of a reference that is not on an arc (G17 plane, no centre). */
static void interp_geom_no_arc(motion_geom_t *g)
{
    g->plane_u = 0;
    g->plane_v = 1;
    g->centre_u = 0;
    g->centre_v = 0;
    g->radius = 0;
    g->sense = 0;
}

static void ip_out_rest(interp_t *ip, motion_ref_t *ref, bool active)
{
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        ref->pos[i] = ip->pos[i];
        ref->vel[i] = 0;
        ref->acc[i] = 0;
        ref->geom.tangent[i] = 0;
        ref->geom.start[i] = ip->pos[i];
    }
    ref->geom.kind = MOTION_GEOM_NONE;
    interp_geom_no_arc(&ref->geom);
    ref->active = active;
    ip->s_q16 = 0;
    ip->v_q16 = 0;
    ip->a_q16 = 0;
}

/* The closed-form state at time tau into phase ph: sc_eval_phase, with
 * cruise phases advanced tick by tick as an exact quotient and remainder
 * (floor(v * tau / 1e9), the same value) while tau grows by whole steps. */
static void ip_eval(interp_t *ip, const sc_profile_t *p, int ph, int64_t tau, sc_state_t *st)
{
    const sc_state_t *s0 = &p->start[ph];
    uint64_t v, q, r;

    /* the cache is of this segment (ip_begin clears it) and phase, whose
     * cruise conditions were checked when it was filled */
    if (ip->cr_ok && ip->cr_phase == ph && tau - ip->cr_tau == ip->cr_h) {
        q = ip->cr_q + ip->cr_dq;
        r = (uint64_t)ip->cr_r + ip->cr_dr;
        if (r >= IP_NS) {
            r -= IP_NS;
            q++;
        }
    } else {
        int64_t h = ip->tick_ns;
        int i;

        if (p->jerk[ph] != 0 || s0->a_q16 != 0 || s0->v_q16 < 0 || tau < 0 || h <= 0) {
            ip->cr_ok = false;
            sc_eval_phase(p, ph, tau, st);
            return;
        }
        v = (uint64_t)s0->v_q16;

        q = (uint64_t)sc_muldiv(s0->v_q16, tau, (int64_t)IP_NS);
        r = v * (uint64_t)tau - q * IP_NS; /* exact modulo 2^64, < 1e9 */
        ip->cr_dq = (uint64_t)sc_muldiv(s0->v_q16, h, (int64_t)IP_NS);
        ip->cr_dr = (uint32_t)(v * (uint64_t)h - ip->cr_dq * IP_NS); /* < 1e9 */
        /* saturated quotients (v * tau >= 2^63 * 1e9) are never cached */
        ip->cr_ok = q < (uint64_t)INT64_MAX / 2 && ip->cr_dq < (uint64_t)INT64_MAX / 2;
        ip->cr_phase = ph;
        ip->cr_h = h;
        for (i = 0; i < CORE_AXES; i++) {
            int64_t rq = ip_cur(ip)->ratio_q62[i];

            ip->cr_vel[i] = ip_scale(s0->v_q16, rq);
            ip->cr_ur[i] = (rq < 0) ? (uint64_t)0 - (uint64_t)rq : (uint64_t)rq;
            ip->cr_neg[i] = rq < 0;
        }
    }
    ip->cr_tau = tau;
    ip->cr_q = q;
    ip->cr_r = (uint32_t)r; /* < 1e9 */
    st->s_q16 = s0->s_q16 + (int64_t)q;
    st->v_q16 = s0->v_q16;
    st->a_q16 = 0;
}

/* The reference of a cruise tick at path distance sq (q16 nm, >= 0):
 * constant velocity, no acceleration; ip_scale(sq, ratio_q62[i]) with the
 * ratio's magnitude and sign from the cache. */
static inline void ip_out_cruise(interp_t *ip, const plan_seg_t *s, int64_t sq, motion_ref_t *ref)
{
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        ip->pos[i] = s->start[i] +
                     fx_umul_shift_hi((uint64_t)sq, ip->cr_ur[i], ip->cr_neg[i], IP_RATIO_SHIFT_HI);
        ref->pos[i] = ip->pos[i];
        ref->vel[i] = ip->cr_vel[i];
        ref->acc[i] = 0;
        ref->geom.tangent[i] = ip->tan[i];
        ref->geom.start[i] = s->start[i];
    }
    ref->geom.kind = MOTION_GEOM_LINE;
    interp_geom_no_arc(&ref->geom);
    ref->active = true;
}

/* A tick of the cruise fast path (see interp_t.cr_fast): what the general
 * path computes for a cache hit, without its checks. False (nothing
 * changed) when the tick leaves the fast path's conditions. */
static bool ip_tick_cruise(interp_t *ip, motion_ref_t *ref)
{
    int64_t t = ip->t_ns + ip->cr_h;
    uint64_t q;
    uint32_t r;
    int64_t sq;

    if (ip->tick_ns != ip->cr_h || t >= ip->cr_tend) {
        return false;
    }
    ip->t_ns = t;
    ip->busy_ticks++;
    q = ip->cr_q + ip->cr_dq;
    r = ip->cr_r + ip->cr_dr; /* < 2e9: 32 bits */
    if (r >= (uint32_t)IP_NS) {
        r -= (uint32_t)IP_NS;
        q++;
    }
    ip->cr_q = q; /* cr_tau: set when the fast path ends (interp_tick) */
    ip->cr_r = (uint32_t)r;
    sq = ip->cr_s0 + (int64_t)q;
    sq += fx_mul64x32_shift32(sq, (int32_t)ip->corr_q32);
    if (sq < 0) {
        sq = 0;
    }
    if (sq > ip->cr_lq) {
        sq = ip->cr_lq;
    }
    ip->s_q16 = sq;
    /* only the positions change: the other fields are those the general
     * path's ip_out_cruise() wrote (see interp_t.ref_pos_only) */
    {
        const plan_seg_t *s = ip_cur(ip);
        unsigned skip = ip->fast_skip;
        int i;

        /* ip->pos (the hold position) is not needed here: every tick
         * that reads it (end of segment, dwell, idle) writes it first */
        for (i = 0; i < CORE_AXES; i++) {
            if ((skip & (1u << i)) == 0u) {
                ref->pos[i] = s->start[i] + fx_umul_shift_hi((uint64_t)sq, ip->cr_ur[i],
                                                             ip->cr_neg[i], IP_RATIO_SHIFT_HI);
            }
        }
    }
    ip->ref_pos_only = true;
    return true;
}

/* Out of line, so that the cruise fast path in interp_tick() keeps a small
 * frame. */
#if defined(__GNUC__)
#define IP_NOINLINE __attribute__((noinline))
#else
#define IP_NOINLINE
#endif

/* interp_tick() after ticks++, except for the fast path. */
static IP_NOINLINE void ip_tick_general(interp_t *ip, motion_ref_t *ref)
{
    const plan_seg_t *s;
    sc_state_t st;
    int64_t sq, lq, tau;
    int i;

    ip->ref_pos_only = false;
    ip->fast_skip = 0;
    if (ip->cr_fast) {
        ip->cr_tau = ip->t_ns - ip->phase_t0; /* the last tick's tau */
        ip->cr_fast = false;
    }
    if (ip->busy) {
        ip->t_ns += ip->tick_ns;
    } else if (ip_queued(ip) > 0) {
        ip_begin(ip);
        ip->t_ns = ip->tick_ns;
    } else {
        ip_out_rest(ip, ref, false);
        return;
    }
    /* finish every segment this tick passes the end of */
    while (ip->busy && ip->t_ns >= ip_cur(ip)->total_ns) {
        bool moving;

        s = ip_cur(ip);
        for (i = 0; i < CORE_AXES; i++) {
            ip->pos[i] = s->end[i];
        }
        ip->t_ns -= s->total_ns;
        /* read before rd moves: main may refill the slot from then on */
        moving = s->dwell_ns == 0 && s->prof.v1 > 0;
        ip->blocks_done++;
        ip->rd = (uint16_t)(ip->rd + 1u);
        if (ip_queued(ip) > 0) {
            ip_begin(ip);
        } else {
            ip->busy = false;
            if (moving) {
                ip->underruns++;
            }
        }
    }
    if (!ip->busy) {
        ip->t_ns = 0;
        ip_out_rest(ip, ref, true);
        return;
    }
    ip->busy_ticks++;
    s = ip_cur(ip);
    if (s->dwell_ns > 0) {
        ip_out_rest(ip, ref, true);
        return;
    }
    /* phase and closed-form state */
    while (ip->phase < SC_PHASES - 1 && ip->t_ns - ip->phase_t0 >= s->prof.t_ns[ip->phase]) {
        ip->phase_t0 += s->prof.t_ns[ip->phase];
        ip->phase++;
    }
    tau = ip->t_ns - ip->phase_t0;
    if (tau > s->prof.t_ns[ip->phase]) {
        tau = s->prof.t_ns[ip->phase];
    }
    ip_eval(ip, &s->prof, ip->phase, tau, &st);
    lq = s->len * 65536;
    if (s->prof.s_end_q16 > 0) {
        if (ip->corr_q32 == (int32_t)ip->corr_q32) {
            sq = st.s_q16 + fx_mul64x32_shift32(st.s_q16, (int32_t)ip->corr_q32);
        } else {
            sq = st.s_q16 + fx_mul64_shift(st.s_q16, ip->corr_q32, 32);
        }
    } else {
        sq = sc_muldiv(lq, ip->t_ns, s->total_ns); /* degenerate: linear in time */
    }
    if (sq < 0) {
        sq = 0;
    }
    if (sq > lq) {
        sq = lq;
    }
    ip->s_q16 = sq;
    ip->v_q16 = st.v_q16;
    ip->a_q16 = st.a_q16;
    if (ip->cr_ok) { /* cruise: constant velocity, no acceleration */
        ip_out_cruise(ip, s, sq, ref);
        /* the next ticks of this phase may take the fast path */
        if (s->prof.s_end_q16 > 0 && ip->corr_q32 == (int32_t)ip->corr_q32) {
            ip->cr_fast = true;
            ip->cr_tend = ip->phase_t0 + s->prof.t_ns[ip->phase];
            if (ip->cr_tend > s->total_ns) {
                ip->cr_tend = s->total_ns;
            }
            ip->cr_s0 = s->prof.start[ip->phase].s_q16;
            ip->cr_lq = lq;
        }
        return;
    }
    for (i = 0; i < CORE_AXES; i++) {
        ip->pos[i] = s->start[i] + ip_scale(sq, s->ratio_q62[i]);
        ref->pos[i] = ip->pos[i];
        ref->vel[i] = ip_scale(st.v_q16, s->ratio_q62[i]);
        ref->acc[i] = ip_scale(st.a_q16, s->ratio_q62[i]);
        ref->geom.tangent[i] = ip->tan[i];
        ref->geom.start[i] = s->start[i];
    }
    ref->geom.kind = MOTION_GEOM_LINE;
    interp_geom_no_arc(&ref->geom);
    ref->active = true;
}

void interp_tick(interp_t *ip, motion_ref_t *ref)
{
    ip->ticks++;
    if (ip->cr_fast && ip_tick_cruise(ip, ref)) {
        return;
    }
    ip_tick_general(ip, ref);
}
