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
    for (i = 0; i < CORE_AXES; i++) {
        ip->pos[i] = pos[i];
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

bool interp_load(interp_t *ip, const plan_seg_t *seg)
{
    if (interp_room(ip) == 0) {
        return false;
    }
    ip->fifo[ip->wr & (INTERP_FIFO - 1)] = *seg;
    ip->wr = (uint16_t)(ip->wr + 1u); /* publish after the slot is written */
    return true;
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

bool interp_idle(const interp_t *ip)
{
    return !ip->busy && ip_queued(ip) == 0;
}

/* round(a * r / 2^78), ties toward +inf: fx_mul64_shift(a, r, 78) for every
 * int64 a and r (|a * r| < 2^126, so the result is below 2^48 and never
 * saturates), inline: four 32 x 32 -> 64 products and the high word. */
static inline int64_t ip_scale(int64_t a, int64_t r)
{
    uint64_t ua = (a < 0) ? (uint64_t)0 - (uint64_t)a : (uint64_t)a;
    uint64_t ur = (r < 0) ? (uint64_t)0 - (uint64_t)r : (uint64_t)r;
    uint64_t al = (uint32_t)ua, ah = ua >> 32, bl = (uint32_t)ur, bh = ur >> 32;
    uint64_t p0 = al * bl, p1 = al * bh, p2 = ah * bl, p3 = ah * bh;
    uint64_t mid = (p0 >> 32) + (uint32_t)p1 + (uint32_t)p2;
    uint64_t hi = p3 + (p1 >> 32) + (p2 >> 32) + (mid >> 32);
    uint32_t lo_zero = ((uint32_t)p0 | (uint32_t)mid) == 0u;

    if ((a < 0) != (r < 0)) { /* -floor((|p| + 2^77 - 1) / 2^78) */
        return -(int64_t)((hi + ((uint64_t)1 << 13) - lo_zero) >> 14);
    }
    return (int64_t)((hi + ((uint64_t)1 << 13)) >> 14);
}

static const plan_seg_t *ip_cur(const interp_t *ip)
{
    return &ip->fifo[ip->rd & (INTERP_FIFO - 1)];
}

static void ip_begin(interp_t *ip)
{
    const plan_seg_t *s = ip_cur(ip);
    int64_t diff;

    ip->busy = true;
    ip->phase = 0;
    ip->phase_t0 = 0;
    ip->corr_q32 = 0;
    ip->tag = s->tag;
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
}

void interp_tick(interp_t *ip, motion_ref_t *ref)
{
    const plan_seg_t *s;
    sc_state_t st;
    int64_t sq, lq, tau;
    int i;

    ip->ticks++;
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
        s = ip_cur(ip);
        for (i = 0; i < CORE_AXES; i++) {
            ip->pos[i] = s->end[i];
        }
        ip->t_ns -= s->total_ns;
        ip->blocks_done++;
        ip->rd = (uint16_t)(ip->rd + 1u);
        if (ip_queued(ip) > 0) {
            ip_begin(ip);
        } else {
            ip->busy = false;
            if (s->dwell_ns == 0 && s->prof.v1 > 0) {
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
    sc_eval_phase(&s->prof, ip->phase, tau, &st);
    lq = s->len * 65536;
    if (s->prof.s_end_q16 > 0) {
        sq = st.s_q16 + fx_mul64_shift(st.s_q16, ip->corr_q32, 32);
    } else {
        sq = sc_muldiv(lq, ip->t_ns, s->total_ns); /* degenerate: linear in time */
    }
    if (sq < 0) {
        sq = 0;
    }
    if (sq > lq) {
        sq = lq;
    }
    for (i = 0; i < CORE_AXES; i++) {
        ip->pos[i] = s->start[i] + ip_scale(sq, s->ratio_q62[i]);
        ref->pos[i] = ip->pos[i];
        ref->vel[i] = ip_scale(st.v_q16, s->ratio_q62[i]);
        ref->acc[i] = ip_scale(st.a_q16, s->ratio_q62[i]);
        ref->geom.tangent[i] = (q1_30_t)(s->ratio_q62[i] / ((int64_t)1 << 32));
        ref->geom.start[i] = s->start[i];
    }
    ref->geom.kind = MOTION_GEOM_LINE;
    interp_geom_no_arc(&ref->geom);
    ref->active = true;
}
