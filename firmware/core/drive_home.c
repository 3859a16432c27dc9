/*
 * drive_home.c - the homing sequence (specification in drive_home.h).
 */
#include "drive_home.h"

#include "hal.h"

bool home_check(const drive_home_t *req, const drive_config_t *cfg)
{
    unsigned i;
    if (req->axes == 0u || cfg->axes > 31u || (req->axes & ~((1u << cfg->axes) - 1u)) != 0u ||
        req->search_nm_s <= 0 || req->latch_nm_s <= 0 || req->latch_nm_s > req->search_nm_s ||
        req->max_dist_nm <= 0) {
        return false;
    }
    for (i = 0; i < cfg->axes; i++) {
        if ((req->axes & (1u << i)) != 0u && req->search_nm_s > cfg->plan.v_max[i]) {
            return false;
        }
    }
    return true;
}

void home_start(home_t *h, const drive_home_t *req, const pos_nm_t ref_pos[CORE_AXES],
                const int64_t a_max[CORE_AXES], uint32_t tick_hz)
{
    unsigned i;
    h->req = *req;
    h->fault_axes = 0;
    h->done = 0;
    h->aborting = false;
    for (i = 0; i < CORE_AXES; i++) {
        h->phase[i] = (req->axes & (1u << i)) != 0u ? HOME_SEARCH : HOME_IDLE;
        h->v[i] = 0;
        h->rem[i] = 0;
        h->dv[i] = a_max[i] / (int64_t)tick_hz;
        if (h->dv[i] < 1) {
            h->dv[i] = 1;
        }
        h->pos[i] = ref_pos[i];
        h->start[i] = ref_pos[i];
        h->mark[i] = 0;
        h->idx_ev[i] = 0;
    }
}

void home_abort(home_t *h)
{
    h->aborting = true;
}

static int64_t dist(pos_nm_t a, pos_nm_t b)
{
    return a > b ? a - b : b - a;
}

/* The velocity one ramp step toward target. */
static int64_t ramp(int64_t v, int64_t target, int64_t dv)
{
    if (v < target) {
        return (target - v > dv) ? v + dv : target;
    }
    return (v - target > dv) ? v - dv : target;
}

/* The phase's velocity target of axis i, and its transitions. False: the
 * axis travelled more than max_dist_nm in the phase. */
static bool phase_step(home_t *h, unsigned i, const qdec_t *q, const servo_fb_t *fb,
                       int64_t *target)
{
    int64_t s = (h->req.negative & (1u << i)) != 0u ? -1 : 1;
    bool sw = hal_home_switch(i);
    switch (h->phase[i]) {
    case HOME_SEARCH:
        if (sw) {
            h->phase[i] = HOME_TOUCHED;
        } else if (dist(h->pos[i], h->start[i]) > h->req.max_dist_nm) {
            return false;
        } else {
            *target = s * h->req.search_nm_s;
            return true;
        }
        /* fall through */
    case HOME_TOUCHED:
        *target = 0;
        if (h->v[i] == 0) {
            h->phase[i] = HOME_BACKOFF;
            h->start[i] = h->pos[i];
        }
        return true;
    case HOME_BACKOFF:
        *target = -s * h->req.latch_nm_s;
        if (!sw) {
            /* the switch edge */
            if ((h->req.index & (1u << i)) != 0u) {
                h->phase[i] = HOME_INDEX;
                h->idx_ev[i] = q->out.index_events;
            } else {
                h->mark[i] = fb->pos[i];
                h->phase[i] = HOME_STOP;
            }
        }
        break;
    case HOME_INDEX:
        *target = -s * h->req.latch_nm_s;
        if (q->out.index_events != h->idx_ev[i]) {
            h->mark[i] = qdec_counts_to_nm_any(q, q->out.index_pos);
            h->phase[i] = HOME_STOP;
        }
        break;
    default: /* HOME_STOP */
        *target = 0;
        return true;
    }
    if (h->phase[i] != HOME_STOP && dist(h->pos[i], h->start[i]) > h->req.max_dist_nm) {
        return false;
    }
    if (h->phase[i] == HOME_STOP) {
        *target = 0;
    }
    return true;
}

/* The axis is at rest on its reference: move its frame so that the
 * reference point reads home_pos (decoder, this tick's feedback, servo,
 * reference: together, no step). */
static void rebase(home_t *h, unsigned i, qdec_t *q, servo_fb_t *fb, servo_t *servo)
{
    pos_nm_t delta = h->req.home_pos[i] - h->mark[i];
    qdec_set_offset_nm(q, q->cfg.offset_nm + delta); /* the next sample on */
    fb->pos[i] += delta;                             /* this tick */
    (void)servo_rebase(servo, i, delta);
    h->pos[i] += delta;
    h->phase[i] = HOME_IDLE;
    h->done |= 1u << i;
    h->shift[i] = delta;
}

home_result_t home_tick(home_t *h, uint32_t tick_hz, qdec_t enc[CORE_AXES], servo_fb_t *fb,
                        servo_t *servo, motion_ref_t *ref)
{
    unsigned i;
    bool busy = false;
    for (i = 0; i < CORE_AXES; i++) {
        int64_t target = 0, v, step;
        if (h->phase[i] == HOME_IDLE) {
            ref->pos[i] = h->pos[i];
            ref->vel[i] = 0;
            ref->acc[i] = 0;
            continue;
        }
        if (!h->aborting && !phase_step(h, i, &enc[i], fb, &target)) {
            h->fault_axes |= 1u << i;
        }
        v = ramp(h->v[i], target, h->dv[i]);
        ref->acc[i] = (v - h->v[i]) * (int64_t)tick_hz;
        h->v[i] = v;
        h->rem[i] += v;
        step = h->rem[i] / (int64_t)tick_hz;
        h->rem[i] -= step * (int64_t)tick_hz;
        h->pos[i] += step;
        if (v == 0 && target == 0) {
            if (h->aborting) {
                h->phase[i] = HOME_IDLE;
            } else if (h->phase[i] == HOME_STOP) {
                rebase(h, i, &enc[i], fb, servo);
            }
        }
        busy = busy || h->phase[i] != HOME_IDLE;
        ref->pos[i] = h->pos[i];
        ref->vel[i] = v;
    }
    ref->active = busy;
    ref->geom.kind = MOTION_GEOM_NONE;
    if (h->fault_axes != 0u) {
        return HOME_FAULT;
    }
    if (busy) {
        return HOME_MOVING;
    }
    return h->aborting ? HOME_ABORTED : HOME_DONE;
}
