/*
 * proto_dispatch.c - request handling, cyclic output and communication
 * watchdog of the drive (see proto_dispatch.h).
 */
#include "proto_dispatch.h"

#include "drive.h"
#include "fixmath.h"
#include "param_store.h"
#include "preempt.h"
#include "proto_dparam.h"
#include "proto_reply.h"

#define AXES_OF(d) ((unsigned)(d)->ident.axes)

typedef struct {
    uint8_t code;
    uint16_t arg;
    int64_t lo;
    int64_t hi;
} refusal_t;

static const refusal_t OK_R = {PROTO_ERROR_CODE_NONE, 0, 0, 0};

static refusal_t refuse(uint8_t code, uint16_t arg)
{
    refusal_t r = {code, arg, 0, 0};

    return r;
}

static refusal_t range_error(uint16_t arg, int64_t lo, int64_t hi)
{
    refusal_t r = {PROTO_ERROR_CODE_OUT_OF_RANGE, arg, lo, hi};

    return r;
}

uint8_t proto_dispatch_state(const drive_status_t *st)
{
    switch (st->state) {
    case DRIVE_DISABLED:
        return PROTO_STATE_DISABLED;
    case DRIVE_IDLE:
        return PROTO_STATE_READY;
    case DRIVE_RUNNING:
        return PROTO_STATE_RUNNING;
    case DRIVE_STOPPING:
        return PROTO_STATE_STOPPING;
    case DRIVE_HOMING:
        return PROTO_STATE_HOMING;
    default:
        return (st->faults & DRIVE_FAULT_ESTOP) != 0u ? PROTO_STATE_ESTOP : PROTO_STATE_FAULT;
    }
}

static uint16_t map_faults(const drive_status_t *st)
{
    uint16_t f = 0;

    if ((st->faults & DRIVE_FAULT_COMM) != 0u) {
        f |= 1u << PROTO_FAULT_COMM_TIMEOUT;
    }
    if ((st->faults & DRIVE_FAULT_FOLLOWING) != 0u) {
        f |= 1u << PROTO_FAULT_FOLLOWING_ERROR;
    }
    if ((st->faults & DRIVE_FAULT_AMPLIFIER) != 0u) {
        f |= 1u << PROTO_FAULT_AMP_FAULT;
    }
    if ((st->faults & DRIVE_FAULT_ENCODER) != 0u) {
        f |= 1u << PROTO_FAULT_ENCODER;
    }
    if ((st->faults & DRIVE_FAULT_ESTOP) != 0u) {
        f |= 1u << PROTO_FAULT_ESTOP;
    }
    if ((st->faults & DRIVE_FAULT_SATURATION) != 0u) {
        f |= 1u << PROTO_FAULT_SATURATION;
    }
    if ((st->faults & DRIVE_FAULT_HOMING) != 0u) {
        f |= 1u << PROTO_FAULT_HOMING;
    }
    if ((st->faults & DRIVE_FAULT_OSCILLATION) != 0u) {
        f |= 1u << PROTO_FAULT_OSCILLATION;
    }
    if ((st->faults & ~(uint32_t)(DRIVE_FAULT_COMM | DRIVE_FAULT_FOLLOWING | DRIVE_FAULT_AMPLIFIER |
                                  DRIVE_FAULT_ENCODER | DRIVE_FAULT_ESTOP | DRIVE_FAULT_SATURATION |
                                  DRIVE_FAULT_HOMING | DRIVE_FAULT_OSCILLATION)) != 0u) {
        f |= 1u << PROTO_FAULT_INTERNAL;
    }
    return f;
}

static uint8_t enabled_mask(const proto_dispatch_t *d, const drive_status_t *st)
{
    if (st->state == DRIVE_DISABLED || st->state == DRIVE_FAULT) {
        return 0;
    }
    return (uint8_t)((1u << AXES_OF(d)) - 1u);
}

static refusal_t map_drive_result(drive_result_t r, const drive_status_t *st)
{
    switch (r) {
    case DRIVE_OK:
        return OK_R;
    case DRIVE_E_FULL:
        return refuse(PROTO_ERROR_CODE_QUEUE_FULL, 0);
    case DRIVE_E_INVALID:
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, 0);
    case DRIVE_E_DISABLED:
        return refuse(PROTO_ERROR_CODE_DISABLED, (uint16_t)st->state);
    case DRIVE_E_FAULTED:
        return refuse(PROTO_ERROR_CODE_FAULTED, (uint16_t)st->faults);
    case DRIVE_E_BUSY:
        return refuse(PROTO_ERROR_CODE_BUSY, (uint16_t)st->state);
    case DRIVE_E_CAUSE:
        return refuse(PROTO_ERROR_CODE_CAUSE_PRESENT, (uint16_t)st->faults);
    case DRIVE_E_UNSUPPORTED: /* the port cannot (enc_mean) */
        return refuse(PROTO_ERROR_CODE_NOT_SUPPORTED, 0);
    default:
        return refuse(PROTO_ERROR_CODE_INTERNAL, (uint16_t)r);
    }
}

/* ---- parameters ------------------------------------------------------------ */

/* Write a drive parameter: busy while moving; a value the drive refuses
 * gets out_of_range with the range it accepts now (e.g. max_acceleration
 * narrowed by max_jerk), or bad_value when the value is in that range but
 * the whole profile is not (a profile change that breaks a / j). */
static refusal_t drive_param_write(uint16_t id, drive_param_t dp, unsigned axis, int64_t value)
{
    int64_t lo = 0, hi = 0;
    drive_status_t st;
    drive_result_t r = drive_param_set(dp, axis, value);

    if (r == DRIVE_OK) {
        return OK_R;
    }
    if (r == DRIVE_E_INVALID && drive_param_range(dp, axis, &lo, &hi) == DRIVE_OK &&
        (value < lo || value > hi)) {
        return range_error(id, lo, hi);
    }
    if (r == DRIVE_E_INVALID) {
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, id);
    }
    drive_status(&st);
    return map_drive_result(r, &st);
}

static refusal_t param_read(proto_dispatch_t *d, uint16_t id, int64_t *value)
{
    unsigned axis = 0;
    const proto_param_info_t *p = proto_param_find(id, &axis);
    drive_status_t st;

    if (p == NULL) {
        return refuse(PROTO_ERROR_CODE_UNKNOWN_PARAM, id);
    }
    if ((p->flags & PROTO_PFLAG_PER_AXIS) != 0u && axis >= AXES_OF(d)) {
        return refuse(PROTO_ERROR_CODE_BAD_AXIS, id);
    }
    drive_status(&st);
    switch (p->id) {
    case PROTO_PARAM_COMM_TIMEOUT_MS:
        *value = d->comm_timeout_ms;
        break;
    case PROTO_PARAM_STATUS_PERIOD_MS:
        *value = d->status_period_ms;
        break;
    case PROTO_PARAM_TELEM_PERIOD_MS:
        *value = d->telem_period_ms;
        break;
    case PROTO_PARAM_HEARTBEAT_PERIOD_MS:
        *value = d->heartbeat_period_ms;
        break;
    case PROTO_PARAM_NODE_ID:
        *value = d->ident.node_id;
        break;
    case PROTO_PARAM_CEC_MODE:
        *value = d->cec_mode;
        break;
    case PROTO_PARAM_AXES:
        *value = d->ident.axes;
        break;
    case PROTO_PARAM_PARAM_STORE_STATUS:
        *value = (int64_t)param_store_status();
        break;
    case PROTO_PARAM_POSITION:
        *value = axis < CORE_AXES ? st.pos[axis] : 0;
        break;
    case PROTO_PARAM_FOLLOWING_ERROR:
        *value = axis < CORE_AXES ? fx_sat_add64(st.ref[axis], -st.pos[axis]) : 0;
        break;
    default: {
        drive_param_t dp;

        if (!proto_drive_param(p->id, &dp) || drive_param_get(dp, axis, value) != DRIVE_OK) {
            return refuse(PROTO_ERROR_CODE_NOT_SUPPORTED, id);
        }
        break;
    }
    }
    return OK_R;
}

static refusal_t param_write(proto_dispatch_t *d, uint16_t id, int64_t value)
{
    unsigned axis = 0;
    const proto_param_info_t *p = proto_param_find(id, &axis);
    drive_status_t st;

    if (p == NULL) {
        return refuse(PROTO_ERROR_CODE_UNKNOWN_PARAM, id);
    }
    if ((p->flags & PROTO_PFLAG_PER_AXIS) != 0u && axis >= AXES_OF(d)) {
        return refuse(PROTO_ERROR_CODE_BAD_AXIS, id);
    }
    if ((p->flags & PROTO_PFLAG_RO) != 0u) {
        return refuse(PROTO_ERROR_CODE_READ_ONLY, id);
    }
    if (value < p->min || value > p->max) {
        return range_error(id, p->min, p->max);
    }
    switch (p->id) {
    case PROTO_PARAM_COMM_TIMEOUT_MS:
        d->comm_timeout_ms = (uint32_t)value;
        break;
    case PROTO_PARAM_STATUS_PERIOD_MS:
        d->status_period_ms = (uint16_t)value;
        break;
    case PROTO_PARAM_TELEM_PERIOD_MS:
        d->telem_period_ms = (uint16_t)value;
        break;
    case PROTO_PARAM_HEARTBEAT_PERIOD_MS:
        d->heartbeat_period_ms = (uint16_t)value;
        break;
    case PROTO_PARAM_CEC_MODE: {
        drive_result_t r = drive_set_cec_mode((drive_cec_mode_t)value);

        if (r != DRIVE_OK) {
            drive_status(&st);
            return map_drive_result(r, &st);
        }
        d->cec_mode = (uint8_t)value;
        break;
    }
    default: {
        drive_param_t dp;

        if (!proto_drive_param(p->id, &dp)) {
            return refuse(PROTO_ERROR_CODE_NOT_SUPPORTED, id);
        }
        return drive_param_write(id, dp, axis, value);
    }
    }
    return OK_R;
}

/* ---- requests ---------------------------------------------------------------- */

static bool pos_ok(int64_t v)
{
    return v >= -PROTO_POS_LIMIT_NM && v <= PROTO_POS_LIMIT_NM;
}

/* Field index of the first target out of range, or -1. */
static int check_targets(const proto_dispatch_t *d, const int64_t *target, unsigned first_field)
{
    unsigned i;

    for (i = 0; i < PROTO_MAX_AXES; i++) {
        if (i >= AXES_OF(d) && target[i] != 0) {
            return (int)(first_field + i);
        }
        if (!pos_ok(target[i])) {
            return (int)(first_field + i);
        }
    }
    return -1;
}

static void copy_targets(drive_block_t *b, const int64_t *target)
{
    unsigned i;

    for (i = 0; i < CORE_AXES; i++) {
        b->target[i] = i < PROTO_MAX_AXES ? target[i] : 0;
    }
}

/* Queue b; a target outside the soft travel limits is out_of_range with
 * the field index of that axis's target (first_field + axis, or
 * first_field for a jog) and the axis's limits. */
static refusal_t do_queue(const drive_block_t *b, drive_status_t *st, unsigned first_field,
                          bool per_axis)
{
    drive_result_t r = drive_queue_block(b);

    PREEMPT_POINT();
    drive_status(st);
    if (r == DRIVE_E_LIMIT) {
        unsigned axis;
        int64_t lo, hi;

        drive_soft_limit_refused(&axis, &lo, &hi);
        return range_error((uint16_t)(first_field + (per_axis ? axis : 0u)), lo, hi);
    }
    return map_drive_result(r, st);
}

static refusal_t req_queue_block(proto_dispatch_t *d, const proto_queue_block_t *q,
                                 drive_status_t *st)
{
    drive_block_t b = {0};
    int bad;

    if (q->flags & ~(1u << PROTO_BLOCK_FLAG_EXACT_STOP)) {
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, 2);
    }
    b.tag = q->block_seq;
    b.exact_stop = (q->flags & (1u << PROTO_BLOCK_FLAG_EXACT_STOP)) != 0u;
    switch (q->kind) {
    case PROTO_BLOCK_KIND_LINE:
        if (q->feed == 0u) {
            return range_error(3, 1, UINT32_MAX);
        }
        b.kind = DRIVE_BLOCK_LINE;
        b.feed_nm_s = q->feed;
        break;
    case PROTO_BLOCK_KIND_RAPID:
        b.kind = DRIVE_BLOCK_LINE;
        b.feed_nm_s = PROTO_RAPID_FEED_NM_S;
        break;
    case PROTO_BLOCK_KIND_DWELL:
        if (q->feed > PROTO_DWELL_MAX_MS) {
            return range_error(3, 0, PROTO_DWELL_MAX_MS);
        }
        b.kind = DRIVE_BLOCK_DWELL;
        b.dwell_ms = q->feed;
        break;
    default:
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, 1);
    }
    if (q->kind != PROTO_BLOCK_KIND_DWELL) {
        bad = check_targets(d, q->target, 4);
        if (bad >= 0) {
            return range_error((uint16_t)bad, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
        }
        copy_targets(&b, q->target);
    }
    return do_queue(&b, st, 4, true);
}

static refusal_t req_queue_arc(proto_dispatch_t *d, const proto_queue_arc_t *q, drive_status_t *st)
{
    drive_block_t b = {0};
    int bad;

    if (q->flags & ~(1u << PROTO_BLOCK_FLAG_EXACT_STOP)) {
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, 1);
    }
    if (q->plane > 2u) {
        return range_error(2, 0, 2);
    }
    if (q->sense != 1 && q->sense != -1) {
        return refuse(PROTO_ERROR_CODE_BAD_VALUE, 3);
    }
    if (q->feed == 0u) {
        return range_error(4, 1, UINT32_MAX);
    }
    bad = check_targets(d, q->target, 5);
    if (bad >= 0) {
        return range_error((uint16_t)bad, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
    }
    if (!pos_ok(q->centre_u)) {
        return range_error(9, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
    }
    if (!pos_ok(q->centre_v)) {
        return range_error(10, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
    }
    b.kind = DRIVE_BLOCK_ARC;
    b.tag = q->block_seq;
    b.exact_stop = (q->flags & (1u << PROTO_BLOCK_FLAG_EXACT_STOP)) != 0u;
    b.feed_nm_s = q->feed;
    b.plane = (drive_plane_t)q->plane;
    b.sense = q->sense;
    b.centre_u = q->centre_u;
    b.centre_v = q->centre_v;
    copy_targets(&b, q->target);
    return do_queue(&b, st, 5, true);
}

static refusal_t req_jog(proto_dispatch_t *d, const proto_jog_t *j, drive_status_t *st)
{
    drive_block_t b = {0};
    unsigned i;

    if (j->axis >= AXES_OF(d) || j->axis >= CORE_AXES) {
        return refuse(PROTO_ERROR_CODE_BAD_AXIS, j->axis);
    }
    if (j->feed == 0u) {
        return range_error(1, 1, UINT32_MAX);
    }
    if (j->distance == 0 || !pos_ok(j->distance)) {
        return range_error(2, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
    }
    drive_status(st);
    if (st->state == DRIVE_RUNNING || st->state == DRIVE_STOPPING) {
        return refuse(PROTO_ERROR_CODE_BUSY, (uint16_t)st->state);
    }
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = st->ref[i];
    }
    if (!pos_ok(fx_sat_add64(b.target[j->axis], j->distance))) {
        return range_error(2, -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
    }
    b.target[j->axis] += j->distance;
    b.kind = DRIVE_BLOCK_LINE;
    b.feed_nm_s = j->feed;
    b.exact_stop = true;
    return do_queue(&b, st, 2, false);
}

static refusal_t req_home(proto_dispatch_t *d, const proto_home_t *h, drive_status_t *st)
{
    uint8_t all = (uint8_t)((1u << AXES_OF(d)) - 1u);
    drive_home_t q = {0};
    drive_result_t dr;
    unsigned i;

    if (h->axis_mask == 0u || (h->axis_mask & (uint8_t)~all) != 0u) {
        return refuse(PROTO_ERROR_CODE_BAD_AXIS, h->axis_mask);
    }
    if (h->search_feed == 0u) {
        return range_error(3, 1, UINT32_MAX);
    }
    if (h->latch_feed == 0u || h->latch_feed > h->search_feed) {
        return range_error(4, 1, h->search_feed);
    }
    if (h->max_distance == 0u) {
        return range_error(5, 1, UINT32_MAX);
    }
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        if (!pos_ok(h->home_pos[i])) {
            return range_error((uint16_t)(6 + i), -PROTO_POS_LIMIT_NM, PROTO_POS_LIMIT_NM);
        }
        if (i < CORE_AXES) {
            q.home_pos[i] = h->home_pos[i];
        }
    }
    q.axes = h->axis_mask;
    q.negative = h->negative_mask & all;
    q.index = h->index_mask & all;
    q.search_nm_s = h->search_feed;
    q.latch_nm_s = h->latch_feed;
    q.max_dist_nm = h->max_distance;
    dr = drive_home(&q);
    PREEMPT_POINT();
    drive_status(st);
    return map_drive_result(dr, st);
}

static size_t put_error(uint8_t *out, uint8_t seq, uint8_t req, const refusal_t *r)
{
    return proto_reply_error(out, seq, req, r->code, r->arg, r->lo, r->hi);
}

static size_t put_queue_reply(uint8_t *out, uint8_t seq, uint32_t block_seq,
                              const drive_status_t *st)
{
    proto_queue_reply_t q;

    q.block_seq = block_seq;
    q.free_slots = fx_sat_u16(st->queue_free);
    q.queued_us = fx_sat_u32(st->queued_time_ns / 1000);
    out[0] = PROTO_MSG_QUEUE_REPLY;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_queue_reply_encode(&q, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

static size_t put_drive_state(const proto_dispatch_t *d, uint8_t *out, uint8_t seq)
{
    proto_drive_state_t s;
    drive_status_t st;
    unsigned i;

    drive_status(&st);
    s.state = proto_dispatch_state(&st);
    s.enabled = enabled_mask(d, &st);
    s.faults = map_faults(&st);
    s.free_slots = fx_sat_u16(st.queue_free);
    s.queued_us = fx_sat_u32(st.queued_time_ns / 1000);
    s.blocks_done = st.blocks_done;
    s.last_block_seq = st.tag;
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        s.pos[i] = (i < CORE_AXES && i < AXES_OF(d)) ? st.pos[i] : 0;
    }
    s.rx_errors = fx_sat_u16(d->rx_errors);
    s.replayed = fx_sat_u16(d->stats.replayed);
    s.homed = (uint8_t)(st.homed & 0xFFu);
    for (i = 0; i < PROTO_MAX_AXES; i++) {
        s.home_shift[i] = (i < CORE_AXES && i < AXES_OF(d)) ? st.home_shift[i] : 0;
    }
    out[0] = PROTO_MSG_DRIVE_STATE;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_drive_state_encode(&s, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

static size_t put_identify(const proto_dispatch_t *d, uint8_t *out, uint8_t seq)
{
    proto_identify_reply_t r;

    r.fw_version = d->ident.fw_version;
    r.build_id = d->ident.build_id;
    r.protocol_version = PROTO_VERSION;
    r.axes = d->ident.axes;
    r.node_id = d->ident.node_id;
    r.capabilities = d->ident.capabilities;
    r.tick_hz = d->ident.tick_hz;
    r.planner_slots = d->ident.planner_slots;
    r.max_payload = PROTO_MAX_PAYLOAD;
    r.board_id = d->ident.board_id;
    out[0] = PROTO_MSG_IDENTIFY_REPLY;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_identify_reply_encode(&r, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

static size_t put_param(uint8_t *out, uint8_t seq, uint16_t id, int64_t value)
{
    proto_param_value_t v;

    v.param = id;
    v.value = value;
    out[0] = PROTO_MSG_PARAM_VALUE;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_param_value_encode(&v, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* Execute a request whose length has been checked; returns the reply length. */
static size_t execute(proto_dispatch_t *d, uint8_t id, uint8_t seq, const uint8_t *p, size_t n,
                      uint8_t *out)
{
    refusal_t r = OK_R;
    drive_status_t st;
    drive_result_t dr;
    int64_t value = 0;
    uint32_t block_seq = 0;

    switch (id) {
    case PROTO_MSG_SESSION_OPEN: {
        proto_session_open_t o;
        proto_session_reply_t rep;

        (void)proto_session_open_decode(p, n, &o);
        if (o.protocol_version != PROTO_VERSION) {
            r = range_error(PROTO_VERSION, PROTO_VERSION, PROTO_VERSION);
            r.code = PROTO_ERROR_CODE_NOT_SUPPORTED;
            break;
        }
        /* nothing of an earlier session is replayed; the block stream goes
         * on (a second host may watch a job: status, monitor) */
        proto_replay_reset(&d->replay);
        proto_ptxn_lose(&d->ptxn, PROTO_TXN_STATUS_NEW_SESSION); /* proto_ptxn.h */
        d->sessions++;
        rep.nonce = o.nonce;
        rep.sessions = d->sessions;
        rep.protocol_version = PROTO_VERSION;
        out[0] = PROTO_MSG_SESSION_REPLY;
        out[1] = seq;
        return PROTO_MSG_HDR +
               proto_session_reply_encode(&rep, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
    }
    case PROTO_MSG_IDENTIFY:
        return put_identify(d, out, seq);
    case PROTO_MSG_STATUS_GET:
        return put_drive_state(d, out, seq);
    case PROTO_MSG_PARAM_GET: {
        proto_param_get_t g;

        (void)proto_param_get_decode(p, n, &g);
        r = param_read(d, g.param, &value);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return put_param(out, seq, g.param, value);
        }
        break;
    }
    case PROTO_MSG_PARAM_SET: {
        proto_param_set_t s;

        (void)proto_param_set_decode(p, n, &s);
        r = param_write(d, s.param, s.value);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            r = param_read(d, s.param, &value);
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return put_param(out, seq, s.param, value);
        }
        break;
    }
    case PROTO_MSG_ENABLE: {
        proto_enable_t e;
        uint8_t all = (uint8_t)((1u << AXES_OF(d)) - 1u);

        (void)proto_enable_decode(p, n, &e);
        if (e.on > 1u) {
            r = range_error(1, 0, 1);
        } else if ((e.axis_mask & (uint8_t)~all) != 0u) {
            r = refuse(PROTO_ERROR_CODE_BAD_AXIS, e.axis_mask);
        } else if (e.axis_mask != all) {
            /* the amplifiers of one drive are switched together */
            r = refuse(PROTO_ERROR_CODE_NOT_SUPPORTED, e.axis_mask);
        } else {
            dr = drive_enable(e.on != 0u);
            PREEMPT_POINT();
            drive_status(&st);
            r = map_drive_result(dr, &st);
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return proto_reply_ack(out, seq, id);
        }
        break;
    }
    case PROTO_MSG_JOG: {
        proto_jog_t j;

        (void)proto_jog_decode(p, n, &j);
        r = req_jog(d, &j, &st);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            d->stream_owns_motion = false; /* the motion is this request's */
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return put_queue_reply(out, seq, st.tag, &st);
        }
        break;
    }
    case PROTO_MSG_QUEUE_BLOCK: {
        proto_queue_block_t q;

        (void)proto_queue_block_decode(p, n, &q);
        block_seq = q.block_seq;
        r = req_queue_block(d, &q, &st);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            d->stream_owns_motion = false; /* the motion is this request's */
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return put_queue_reply(out, seq, block_seq, &st);
        }
        break;
    }
    case PROTO_MSG_QUEUE_ARC: {
        proto_queue_arc_t q;

        (void)proto_queue_arc_decode(p, n, &q);
        block_seq = q.block_seq;
        r = req_queue_arc(d, &q, &st);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            d->stream_owns_motion = false; /* the motion is this request's */
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return put_queue_reply(out, seq, block_seq, &st);
        }
        break;
    }
    case PROTO_MSG_QUEUE_BATCH: {
        uint32_t before = d->batch.next_seq;
        bool started = d->batch.started;
        size_t len = proto_batch_request(&d->batch, AXES_OF(d), seq, p, n, out);

        if (d->batch.next_seq != before || d->batch.started != started) {
            d->stream_owns_motion = true; /* it took blocks (or began a stream) */
        }
        return len;
    }
    case PROTO_MSG_HOME: {
        proto_home_t h;

        (void)proto_home_decode(p, n, &h);
        r = req_home(d, &h, &st);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            d->stream_owns_motion = false; /* the motion is this request's */
        }
        if (r.code == PROTO_ERROR_CODE_NONE) {
            return proto_reply_ack(out, seq, id);
        }
        break;
    }
    case PROTO_MSG_STOP:
        proto_batch_flush(&d->batch, PROTO_ERROR_CODE_BUSY); /* nothing of it after the stop */
        drive_stop();
        return proto_reply_ack(out, seq, id);
    case PROTO_MSG_ESTOP:
        proto_batch_flush(&d->batch, PROTO_ERROR_CODE_BUSY);
        drive_estop();
        return proto_reply_ack(out, seq, id);
    case PROTO_MSG_PARAM_BEGIN:
    case PROTO_MSG_PARAM_STAGE:
    case PROTO_MSG_PARAM_COMMIT:
    case PROTO_MSG_PARAM_ABORT: {
        size_t len = proto_ptxn_request(d, id, seq, p, n, d->last_rx_us, out);

        if (out[0] == PROTO_MSG_ERROR) {
            d->stats.refused++;
        }
        return len;
    }
    case PROTO_MSG_PARAM_SAVE: {
        uint32_t detail = 0u;
        param_store_result_t ps = param_store_save(NULL, &detail);

        if (ps == PARAM_STORE_OK) {
            return proto_reply_ack(out, seq, id);
        }
        drive_status(&st);
        r = ps == PARAM_STORE_E_STATE
                ? refuse(PROTO_ERROR_CODE_BAD_STATE, proto_dispatch_state(&st))
                : refuse(PROTO_ERROR_CODE_INTERNAL, (uint16_t)detail);
        break;
    }
    case PROTO_MSG_FAULT_RESET:
        dr = drive_fault_reset();
        PREEMPT_POINT();
        drive_status(&st);
        r = map_drive_result(dr, &st);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            d->wd_stopping = false;
            return proto_reply_ack(out, seq, id);
        }
        break;
    default:
        d->stats.unknown++;
        r = refuse(PROTO_ERROR_CODE_UNKNOWN_MESSAGE, id);
        break;
    }
    d->stats.refused++;
    return put_error(out, seq, id, &r);
}

bool proto_dispatch_init(proto_dispatch_t *d, const proto_identity_t *ident, uint32_t now_us)
{
    proto_dispatch_stats_t zero = {0};

    if (ident == NULL || ident->node_id < 1u || ident->node_id > PROTO_CAN_NODE_MAX ||
        ident->axes < 1u || ident->axes > PROTO_MAX_AXES || ident->axes > CORE_AXES) {
        return false;
    }
    d->ident = *ident;
    if (d->ident.planner_slots == 0u) {
        drive_status_t st;

        drive_status(&st); /* at start-up the queue is empty: free = depth */
        d->ident.planner_slots = fx_sat_u16(st.queue_free);
    }
    d->comm_timeout_ms = (uint32_t)proto_param_find(PROTO_PARAM_COMM_TIMEOUT_MS, NULL)->def;
    d->status_period_ms = (uint16_t)proto_param_find(PROTO_PARAM_STATUS_PERIOD_MS, NULL)->def;
    d->telem_period_ms = (uint16_t)proto_param_find(PROTO_PARAM_TELEM_PERIOD_MS, NULL)->def;
    d->heartbeat_period_ms = (uint16_t)proto_param_find(PROTO_PARAM_HEARTBEAT_PERIOD_MS, NULL)->def;
    d->heartbeat_on = false;
    d->cec_mode = 0;
    proto_replay_reset(&d->replay);
    proto_batch_reset(&d->batch);
    proto_ptxn_reset(&d->ptxn);
    d->sessions = 0;
    d->last_rx_us = now_us;
    d->stream_rx_us = now_us;
    d->stream_owns_motion = false;
    d->wd_stopping = false;
    d->cycle_seq = 0;
    d->tx_seq = 0;
    d->last_cycle_us = now_us;
    d->last_hb_us = now_us;
    d->rx_errors = 0;
    d->stats = zero;
    return true;
}

size_t proto_dispatch_handle(proto_dispatch_t *d, const uint8_t *msg, size_t len, uint32_t now_us,
                             uint8_t *out, size_t cap)
{
    const proto_msg_info_t *info;
    uint8_t id;
    uint8_t seq;
    size_t n;
    size_t rlen;
    proto_replay_key_t key;

    if (len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        d->stats.ignored++;
        return 0;
    }
    id = msg[0];
    seq = msg[1];
    n = len - PROTO_MSG_HDR;
    d->last_rx_us = now_us; /* a well-formed frame: the host is alive */
    if (id == PROTO_MSG_QUEUE_BATCH) {
        d->stream_rx_us = now_us; /* the streaming host is */
    }

    proto_replay_key(&key, msg, len);
    rlen = proto_replay_lookup(&d->replay, &key, out, cap);
    if (rlen != 0u) {
        d->stats.replayed++;
        return rlen;
    }

    info = proto_msg_info(id);
    if (info == NULL || info->dir != PROTO_DIR_H2D) {
        refusal_t r = refuse(PROTO_ERROR_CODE_UNKNOWN_MESSAGE, id);

        d->stats.unknown++;
        d->stats.refused++;
        rlen = put_error(out, seq, id, &r);
    } else if (id == PROTO_MSG_SESSION_OPEN && n == 4u) {
        /* a host of protocol 1 (no version): refused, it says not_supported */
        refusal_t r = range_error(PROTO_VERSION, PROTO_VERSION, PROTO_VERSION);

        r.code = PROTO_ERROR_CODE_NOT_SUPPORTED;
        d->stats.refused++;
        rlen = put_error(out, seq, id, &r);
    } else if (n < info->min_len || n > info->max_len) {
        refusal_t r = range_error(0, info->min_len, info->max_len);

        r.code = PROTO_ERROR_CODE_BAD_LENGTH;
        r.arg = (uint16_t)n;
        d->stats.bad_length++;
        d->stats.refused++;
        rlen = put_error(out, seq, id, &r);
    } else {
        rlen = execute(d, id, seq, msg + PROTO_MSG_HDR, n, out);
    }
    d->stats.requests++;
    proto_replay_store(&d->replay, &key, out, rlen);
    return rlen;
}

/* ---- cyclic output ------------------------------------------------------------ */

static bool emit_msg(proto_dispatch_t *d, uint8_t id, uint8_t can_func, const uint8_t *payload,
                     size_t n, proto_emit_fn emit, void *ctx)
{
    uint8_t m[PROTO_MSG_HDR + 8];
    size_t i;

    m[0] = id;
    m[1] = d->tx_seq++;
    for (i = 0; i < n && i < 8u; i++) {
        m[PROTO_MSG_HDR + i] = payload[i];
    }
    return emit(ctx, m, PROTO_MSG_HDR + n, can_func);
}

static void emit_cycle(proto_dispatch_t *d, bool full, proto_emit_fn emit, void *ctx)
{
    drive_status_t st;
    uint8_t buf[8];
    size_t n;
    unsigned i;
    uint16_t seq = d->cycle_seq++;

    drive_status(&st);
    {
        proto_status_t s;

        s.seq = seq;
        s.state = proto_dispatch_state(&st);
        s.enabled = enabled_mask(d, &st);
        s.faults = map_faults(&st);
        s.free_slots = fx_sat_u16(st.queue_free);
        n = proto_status_encode(&s, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_STATUS, PROTO_CAN_FUNC_STATUS, buf, n, emit, ctx);
    }
    {
        proto_progress_t p;

        p.seq = seq;
        p.queued_us = fx_sat_u32(st.queued_time_ns / 1000);
        p.blocks_done = (uint16_t)st.blocks_done;
        n = proto_progress_encode(&p, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_PROGRESS, PROTO_CAN_FUNC_PROGRESS, buf, n, emit, ctx);
    }
    d->stats.cycles++;
    if (!full) {
        return;
    }
    {
        proto_path_t p;
        int64_t v = 0;

        for (i = 0; i < AXES_OF(d) && i < CORE_AXES; i++) {
            v = fx_hypot2(v, st.vel_ref[i]);
        }
        p.seq = seq;
        p.contour_err = fx_sat32(st.contour_error_nm);
        if (v > ((int64_t)1 << 50)) {
            v = (int64_t)1 << 50;
        }
        p.feed = fx_sat_u16(fx_sat_u32(v * 3 / 50000)); /* nm/s -> mm/min */
        n = proto_path_encode(&p, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_PATH, PROTO_CAN_FUNC_PATH, buf, n, emit, ctx);
    }
    for (i = 0; i < AXES_OF(d) && i < CORE_AXES; i++) {
        proto_pos_t p;
        proto_ferr_t f;
        int32_t cmd = st.motor_mv[i] / 10;

        p.seq = seq;
        p.pos = fx_clamp_sym64(st.pos[i], ((int64_t)1 << 47) - 1);
        n = proto_pos_encode(&p, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_POS(i), (uint8_t)PROTO_CAN_FUNC_POS(i), buf, n, emit, ctx);
        f.seq = seq;
        f.ferr = fx_sat32(fx_sat_add64(st.ref[i], -st.pos[i]));
        f.cmd = (int16_t)(cmd > 32767 ? 32767 : (cmd < -32767 ? -32767 : cmd));
        n = proto_ferr_encode(&f, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_FERR(i), (uint8_t)PROTO_CAN_FUNC_FERR(i), buf, n, emit, ctx);
    }
}

static void watchdog(proto_dispatch_t *d, uint32_t now_us)
{
    drive_status_t st;
    uint32_t last;

    drive_status(&st);
    PREEMPT_POINT();
    if (d->wd_stopping) {
        if (st.state == DRIVE_STOPPING || st.state == DRIVE_RUNNING || st.state == DRIVE_HOMING) {
            return; /* still decelerating */
        }
        d->wd_stopping = false;
        if (st.state != DRIVE_FAULT) {
            drive_raise_fault(DRIVE_FAULT_COMM);
        }
        return;
    }
    if (st.state != DRIVE_RUNNING && st.state != DRIVE_HOMING) {
        /* the stream's motion ended: the next motion (a calibration run,
         * CANopen) is watched by any request again */
        d->stream_owns_motion = false;
        return;
    }
    if (d->comm_timeout_ms == 0u) {
        return; /* homing too: a host that died does not leave the axes homing */
    }
    last = d->stream_owns_motion ? d->stream_rx_us : d->last_rx_us;
    if ((uint32_t)(now_us - last) / 1000u >= d->comm_timeout_ms) {
        d->stats.watchdog_stops++;
        d->wd_stopping = true;
        proto_batch_flush(&d->batch, PROTO_ERROR_CODE_BUSY);
        drive_stop();
    }
}

void proto_dispatch_poll(proto_dispatch_t *d, uint32_t now_us, proto_emit_fn emit, void *ctx)
{
    uint32_t since = now_us - d->last_cycle_us;

    proto_batch_pump(&d->batch); /* the host FIFO takes from the intake ring */
    watchdog(d, now_us);
    proto_ptxn_poll(d, now_us);
    if (d->telem_period_ms != 0u && since >= (uint32_t)d->telem_period_ms * 1000u) {
        d->last_cycle_us = now_us;
        emit_cycle(d, true, emit, ctx);
    } else if (d->telem_period_ms == 0u && d->status_period_ms != 0u &&
               since >= (uint32_t)d->status_period_ms * 1000u) {
        d->last_cycle_us = now_us;
        emit_cycle(d, false, emit, ctx);
    } else if (d->telem_period_ms == 0u && d->status_period_ms == 0u) {
        d->last_cycle_us = now_us;
    }
    if (d->heartbeat_on && d->heartbeat_period_ms != 0u &&
        (uint32_t)(now_us - d->last_hb_us) >= (uint32_t)d->heartbeat_period_ms * 1000u) {
        proto_heartbeat_t h;
        drive_status_t st;
        uint8_t buf[8];
        size_t n;

        d->last_hb_us = now_us;
        drive_status(&st);
        h.state = proto_dispatch_state(&st);
        h.axes = d->ident.axes;
        h.protocol_version = PROTO_VERSION;
        h.fw_version = d->ident.fw_version;
        n = proto_heartbeat_encode(&h, buf, sizeof(buf));
        (void)emit_msg(d, PROTO_MSG_HEARTBEAT, PROTO_CAN_FUNC_HEARTBEAT, buf, n, emit, ctx);
    }
}
