/*
 * co_pp.c - profile position and homing (co_pp.h is the specification).
 */
#include "co_pp.h"

#define MODE_PP   1
#define MODE_HOME 6

uint32_t co_pp_check_method(int32_t method)
{
    return (method == 1 || method == 2 || method == 17 || method == 18) ? 0u : CO_ABORT_VALUE;
}

static bool pp_start(co_pp_t *p, co_t *co, const co_pp_cmd_t *c)
{
    drive_status_t st;
    drive_block_t b = {0};
    unsigned i;

    drive_snapshot(&st);
    if (st.state == DRIVE_IDLE && st.queued_time_ns == 0) {
        p->last = st.ref[p->axis]; /* at rest: from where the axis is */
    }
    b.kind = DRIVE_BLOCK_LINE;
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = st.ref[i];
    }
    b.target[p->axis] = (c->cw & 0x40u) != 0u ? p->last + c->target : (pos_nm_t)c->target;
    b.feed_nm_s = co->od.profile_velocity;
    b.exact_stop = true;
    if (drive_queue_block(&b) != DRIVE_OK) {
        return false;
    }
    p->last = b.target[p->axis];
    return true;
}

static bool home_start(co_t *co)
{
    drive_home_t h = {0};
    int8_t m = co->od.homing_method;

    if (co_pp_check_method(m) != 0u) {
        return false;
    }
    h.axes = 1u;
    h.negative = (m == 1 || m == 17) ? 1u : 0u;
    h.index = m < 17 ? 1u : 0u;
    h.search_nm_s = co->od.homing_search;
    h.latch_nm_s = co->od.homing_latch;
    h.max_dist_nm = CO_PP_HOME_MAX_NM;
    h.home_pos[0] = co->od.home_offset;
    return drive_home(&h) == DRIVE_OK;
}

void co_pp_controlword(co_pp_t *p, co_t *co, bool enabled, const co_pp_cmd_t *c)
{
    bool bit4 = (c->cw & 0x10u) != 0u;
    bool rise = bit4 && !p->bit4;

    p->bit4 = bit4;
    if (!bit4) {
        p->ack = false;
    }
    if (!rise || !enabled) {
        return;
    }
    if (c->mode == MODE_PP) {
        p->ack = pp_start(p, co, c);
        p->refused += p->ack ? 0u : 1u;
    } else if (c->mode == MODE_HOME && p->axis == 0u) {
        p->home_failed = !home_start(co);
        p->refused += p->home_failed ? 1u : 0u;
    }
}

uint16_t co_pp_status(const co_pp_t *p, int8_t mode, const drive_status_t *st)
{
    uint16_t sw = 0;

    if (mode == MODE_PP && p->ack) {
        sw |= 0x1000u;
    } else if (mode == MODE_HOME) {
        if ((st->homed & (1u << p->axis)) != 0u && st->state == DRIVE_IDLE) {
            sw |= 0x1000u;
        }
        if (p->home_failed || (st->faults & DRIVE_FAULT_HOMING) != 0u) {
            sw |= 0x2000u;
        }
    }
    return sw;
}
