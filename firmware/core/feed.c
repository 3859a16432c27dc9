/*
 * feed.c - the drive's feed path (specification in feed.h).
 */
#include "feed.h"

static int64_t feed_tick_ns(const feed_t *f)
{
    return (int64_t)(1000000000u / f->cfg->tick_hz);
}

bool feed_init(feed_t *f, const drive_config_t *cfg, interp_t *ip, plan_block_t *store,
               uint16_t depth, const pos_nm_t origin[CORE_AXES])
{
    unsigned i;
    f->cfg = cfg;
    f->ip = ip;
    if (plan_init(&f->plan, store, depth, &cfg->plan, origin) != PLAN_OK) {
        return false;
    }
    interp_init(ip, feed_tick_ns(f), origin);
    f->hq_head = 0;
    f->hq_count = 0;
    for (i = 0; i < CORE_AXES; i++) {
        f->q_end[i] = origin[i];
    }
    f->seq_next = 0;
    f->queued_at = 0;
    f->arc_open = false;
    f->skipped = 0;
    f->queued = 0;
    return true;
}

void feed_flush(feed_t *f, const pos_nm_t pos[CORE_AXES])
{
    unsigned i;
    f->hq_count = 0;
    f->hq_head = 0;
    plan_reset(&f->plan, pos);
    interp_reset(f->ip, pos);
    f->arc_open = false;
    f->queued = 0;
    for (i = 0; i < CORE_AXES; i++) {
        f->q_end[i] = pos[i];
    }
}

/* Publish main's count for the tick (see feed_t.queued). */
static void feed_publish(feed_t *f)
{
    f->queued = (uint32_t)f->hq_count + plan_count(&f->plan);
}

/* Push the next planner block of the oldest host block. False when the
 * planner is full. */
static bool feed_one(feed_t *f)
{
    feed_block_t *h = &f->hq[f->hq_head];
    plan_move_t m = {0};
    feed_seg_t g = {0};
    plan_result_t r;
    unsigned i;
    bool last = true;

    if (plan_free_slots(&f->plan) == 0) {
        return false;
    }
    m.tag = f->seq_next;
    m.feed = h->b.feed_nm_s;
    g.host_tag = h->b.tag;
    if (h->b.kind == DRIVE_BLOCK_DWELL) {
        m.dwell_ns = (int64_t)h->b.dwell_ms * 1000000;
    } else if (h->b.kind == DRIVE_BLOCK_LINE) {
        for (i = 0; i < CORE_AXES; i++) {
            m.target[i] = h->b.target[i];
        }
        m.flags = h->b.exact_stop ? PLAN_MOVE_EXACT_STOP : 0;
    } else {
        arc_seg_chord(&h->arc, &h->b, h->arc.done_seg, m.target, &g.c);
        last = h->arc.done_seg + 1 == h->arc.n_seg;
        m.flags = (last && h->b.exact_stop) ? PLAN_MOVE_EXACT_STOP : 0;
        /* the join with the arc's previous chord, or with the last chord of
         * an arc about the same centre (the next revolution of a circle) */
        if (h->arc.done_seg > 0 ||
            (f->arc_open && f->arc_plane == h->b.plane && f->arc_cu == h->b.centre_u &&
             f->arc_cv == h->b.centre_v && f->arc_sense == h->b.sense)) {
            m.flags |= PLAN_MOVE_ARC_JOIN;
        }
        g.arc = true;
    }
    r = plan_push(&f->plan, &m);
    if (r == PLAN_E_FULL) {
        return false;
    }
    if (r == PLAN_OK || !g.arc) {
        /* a line or dwell (even a skipped one) ends any arc */
        f->arc_open = g.arc && (m.flags & PLAN_MOVE_EXACT_STOP) == 0;
        f->arc_plane = h->b.plane;
        f->arc_cu = h->b.centre_u;
        f->arc_cv = h->b.centre_v;
        f->arc_sense = h->b.sense;
    }
    if (r == PLAN_OK) {
        g.last = last;
        f->seg[f->seq_next % FEED_SEG_RING] = g;
        f->seq_next++;
    } else if (last && h->b.kind != DRIVE_BLOCK_ARC) {
        /* skipped (zero length) or refused: the block counts as done */
        f->skipped++;
    }
    if (h->b.kind == DRIVE_BLOCK_ARC) {
        h->arc.done_seg++;
    }
    if (last) {
        f->hq_head = (uint16_t)((f->hq_head + 1u) % DRIVE_QUEUE_DEPTH);
        f->hq_count--;
    }
    return true;
}

/* Every waiting host block the planner takes. */
static void feed_push_all(feed_t *f)
{
    while (f->hq_count > 0 && feed_one(f)) {
        PREEMPT_POINT();
    }
}

/* True when the oldest planner block's exit speed is final (the next
 * block's entry can no longer change, or it ends in a stop): freezing it now
 * gives the plan it would get with any later look-ahead. */
static bool oldest_final(const feed_t *f)
{
    const plan_block_t *b = plan_peek(&f->plan, 0);
    if (b == NULL) {
        return false;
    }
    if (plan_count(&f->plan) >= 2) {
        return f->plan.planned >= 2;
    }
    return (b->flags & (PLAN_BF_EXACT_STOP | PLAN_BF_DWELL)) != 0;
}

/* No input is waiting and the planner is not full: freeze a block anyway
 * only when the interpolator would otherwise run short (less than
 * FEED_AHEAD_NS beyond its current segment), or, with nothing in the
 * interpolator, when no block arrived for cfg->start_delay_ms (a job starts
 * once its look-ahead has filled or the host has paused). */
static bool interp_needs_block(const feed_t *f, uint32_t now)
{
    uint32_t delay;
    if (!interp_idle(f->ip)) {
        return interp_ahead_ns(f->ip) < FEED_AHEAD_NS;
    }
    delay = (uint32_t)(((uint64_t)f->cfg->start_delay_ms * f->cfg->tick_hz + 999u) / 1000u);
    return (uint32_t)(now - f->queued_at) >= delay;
}

void feed_poll(feed_t *f, uint32_t now)
{
    /* Push every waiting block before each pop (interp_refill pops one), so
     * that a block is frozen with the look-ahead plan_estimate() gives it;
     * pop while the interpolator has room and the planner is full, or the
     * oldest block's plan is final, or the interpolator runs short. */
    for (;;) {
        feed_push_all(f);
        PREEMPT_POINT();
        if (interp_room(f->ip) == 0 || plan_count(&f->plan) == 0 ||
            !(plan_free_slots(&f->plan) == 0 || oldest_final(f) || interp_needs_block(f, now))) {
            break;
        }
        if (interp_refill(f->ip, &f->plan) == 0) {
            break;
        }
        PREEMPT_POINT();
    }
    feed_publish(f);
}

/* Soft limits of an arc: its end point, then every extreme point of the
 * plane (centre +- radius along u or v) its sweep passes; the larger of
 * the two radii (they differ by at most DRIVE_ARC_RADIUS_TOL_NM). */
static drive_result_t arc_limits(const feed_block_t *h, const pos_nm_t from[CORE_AXES])
{
    const arc_seg_t *a = &h->arc;
    pos_nm_t p[CORE_AXES];
    pos_nm_t rad = a->r_s > a->r_e ? a->r_s : a->r_e;
    unsigned k, i;
    if (drive_soft_limit_check(h->b.target, from) != DRIVE_OK) {
        return DRIVE_E_LIMIT;
    }
    for (k = 0; k < 4u; k++) {
        fx_angle_t phi = (fx_angle_t)k << 30; /* +u, +v, -u, -v */
        uint32_t d = a->sweep > 0 ? (uint32_t)(phi - a->th_s) : (uint32_t)(a->th_s - phi);
        int64_t sw = a->sweep > 0 ? a->sweep : -a->sweep;
        if ((int64_t)d > sw) {
            continue;
        }
        for (i = 0; i < CORE_AXES; i++) {
            p[i] = from[i];
        }
        if ((k & 1u) == 0u) {
            p[a->u] = h->b.centre_u + (k == 0u ? rad : -rad);
        } else {
            p[a->v] = h->b.centre_v + (k == 1u ? rad : -rad);
        }
        if (drive_soft_limit_check(p, from) != DRIVE_OK) {
            return DRIVE_E_LIMIT;
        }
    }
    return DRIVE_OK;
}

drive_result_t feed_queue(feed_t *f, const drive_block_t *b, uint32_t now)
{
    feed_block_t h;
    feed_block_t zero = {0};
    unsigned i;
    h = zero;
    h.b = *b;
    for (i = f->cfg->axes; i < CORE_AXES; i++) {
        h.b.target[i] = f->q_end[i];
    }
    switch (b->kind) {
    case DRIVE_BLOCK_DWELL:
        if (b->dwell_ms == 0 || b->dwell_ms > 86400000u) {
            return DRIVE_E_INVALID;
        }
        break;
    case DRIVE_BLOCK_LINE:
        if (b->feed_nm_s <= 0 || b->feed_nm_s > SC_V_LIMIT) {
            return DRIVE_E_INVALID;
        }
        for (i = 0; i < CORE_AXES; i++) {
            if (fx_sat_abs64(h.b.target[i] - f->q_end[i]) >= SC_LEN_MAX) {
                return DRIVE_E_INVALID;
            }
        }
        if (drive_soft_limit_check(h.b.target, f->q_end) != DRIVE_OK) {
            return DRIVE_E_LIMIT;
        }
        break;
    case DRIVE_BLOCK_ARC:
        if (!arc_seg_setup(&h.arc, &h.b, f->q_end, f->cfg->axes, f->cfg->tick_hz,
                           f->cfg->arc_chord_nm)) {
            return DRIVE_E_INVALID;
        }
        if (arc_limits(&h, f->q_end) != DRIVE_OK) {
            return DRIVE_E_LIMIT;
        }
        break;
    default:
        return DRIVE_E_INVALID;
    }
    if (f->hq_count >= DRIVE_QUEUE_DEPTH) {
        return DRIVE_E_FULL;
    }
    f->hq[(f->hq_head + f->hq_count) % DRIVE_QUEUE_DEPTH] = h;
    PREEMPT_POINT();
    f->hq_count++;
    f->queued_at = now;
    /* plan it now: the caller's status then counts its planned time;
     * feed_poll decides when it is frozen */
    feed_push_all(f);
    if (b->kind != DRIVE_BLOCK_DWELL) {
        for (i = 0; i < CORE_AXES; i++) {
            f->q_end[i] = h.b.target[i];
        }
    }
    PREEMPT_POINT();
    feed_publish(f); /* the tick makes the drive RUNNING */
    return DRIVE_OK;
}

bool feed_idle(const feed_t *f)
{
    return interp_idle(f->ip) && plan_count(&f->plan) == 0 && f->hq_count == 0;
}

int64_t feed_queued_ns(const feed_t *f, uint16_t rd, int64_t rem_rd)
{
    return plan_queued_ns(&f->plan) + interp_queued_ns(f->ip, rd, rem_rd);
}

void feed_set_profile(feed_t *f, const plan_profile_t *prof)
{
    (void)plan_set_profile(&f->plan, prof); /* checked by drive_apply_config */
    f->arc_open = false;
}
