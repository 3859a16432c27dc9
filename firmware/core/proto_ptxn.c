/*
 * proto_ptxn.c - parameter transactions on the wire (see proto_ptxn.h).
 * Main context only.
 */
#include "proto_ptxn.h"

#include "drive.h"
#include "proto_dispatch.h"
#include "proto_dparam.h"
#include "proto_reply.h"

#define PAIR_LEN 10u /* u16 id, i64 value */

typedef struct {
    uint8_t code; /* PROTO_ERROR_CODE_*, NONE: accepted */
    uint16_t arg;
    int64_t lo;
    int64_t hi;
} ptxn_refusal_t;

static ptxn_refusal_t refusal(uint8_t code, uint16_t arg, int64_t lo, int64_t hi)
{
    ptxn_refusal_t r = {code, arg, lo, hi};

    return r;
}

void proto_ptxn_reset(proto_ptxn_t *t)
{
    t->id = 0;
    t->state = PROTO_PTXN_NONE;
    t->lost_why = 0;
    t->lost_id = 0;
    t->n = 0;
    t->done_id = 0;
    t->done_n = 0;
    t->last_us = 0;
}

void proto_ptxn_lose(proto_ptxn_t *t, uint8_t reason)
{
    if (t->state != PROTO_PTXN_OPEN) {
        return;
    }
    t->lost_id = t->id;
    t->lost_why = reason;
    t->state = PROTO_PTXN_NONE;
    t->n = 0;
}

void proto_ptxn_poll(struct proto_dispatch *d, uint32_t now_us)
{
    proto_ptxn_t *t = &d->ptxn;

    if (t->state == PROTO_PTXN_OPEN && d->comm_timeout_ms != 0u &&
        (uint32_t)(now_us - t->last_us) / 1000u >= d->comm_timeout_ms) {
        proto_ptxn_lose(t, PROTO_TXN_STATUS_LINK_TIMEOUT);
    }
}

static size_t put_txn(uint8_t *out, uint8_t seq, uint16_t txn, uint16_t n, bool committed)
{
    proto_param_txn_t r;

    r.txn = txn;
    r.staged = n;
    r.committed = committed ? 1u : 0u;
    out[0] = PROTO_MSG_PARAM_TXN;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_param_txn_encode(&r, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* Why txn is not the open transaction. */
static ptxn_refusal_t not_open(const proto_ptxn_t *t, uint16_t txn)
{
    uint8_t why = PROTO_TXN_STATUS_NOT_OPEN;

    if (txn != 0u && txn == t->lost_id) {
        why = t->lost_why;
    }
    return refusal(PROTO_ERROR_CODE_TXN, why, txn, 0);
}

static int find(const proto_ptxn_t *t, uint16_t pid)
{
    unsigned k;

    for (k = 0; k < t->n; k++) {
        if (t->param[k] == pid) {
            return (int)k;
        }
    }
    return -1;
}

/* One pair as param_set checks its value (proto_dispatch.c param_write). */
static ptxn_refusal_t check_pair(const struct proto_dispatch *d, uint16_t pid, int64_t v)
{
    unsigned axis = 0;
    const proto_param_info_t *p = proto_param_find(pid, &axis);

    if (p == NULL) {
        return refusal(PROTO_ERROR_CODE_UNKNOWN_PARAM, pid, 0, 0);
    }
    if ((p->flags & PROTO_PFLAG_PER_AXIS) != 0u && axis >= d->ident.axes) {
        return refusal(PROTO_ERROR_CODE_BAD_AXIS, pid, 0, 0);
    }
    if ((p->flags & PROTO_PFLAG_RO) != 0u) {
        return refusal(PROTO_ERROR_CODE_READ_ONLY, pid, 0, 0);
    }
    if (v < p->min || v > p->max) {
        return refusal(PROTO_ERROR_CODE_OUT_OF_RANGE, pid, p->min, p->max);
    }
    return refusal(PROTO_ERROR_CODE_NONE, 0, 0, 0);
}

static ptxn_refusal_t stage(struct proto_dispatch *d, const uint8_t *p, size_t n, uint32_t now_us)
{
    proto_ptxn_t *t = &d->ptxn;
    uint16_t txn = (uint16_t)proto_get_le(p, 2);
    const uint8_t *data = p + 2;
    size_t pairs = (n - 2u) / PAIR_LEN;
    unsigned fresh = 0;
    size_t k;

    if (t->state != PROTO_PTXN_OPEN || txn != t->id) {
        return not_open(t, txn);
    }
    if (pairs == 0u || (n - 2u) % PAIR_LEN != 0u) {
        return refusal(PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)n, 2u + PAIR_LEN,
                       PROTO_PARAM_STAGE_MAX_LEN);
    }
    for (k = 0; k < pairs; k++) {
        uint16_t pid = (uint16_t)proto_get_le(data + k * PAIR_LEN, 2);
        ptxn_refusal_t r = check_pair(d, pid, (int64_t)proto_get_le(data + k * PAIR_LEN + 2u, 8));

        if (r.code != PROTO_ERROR_CODE_NONE) {
            return r;
        }
        fresh += find(t, pid) < 0 ? 1u : 0u; /* a pair twice in a frame: counted twice */
    }
    if (t->n + fresh > PROTO_PTXN_MAX) {
        return refusal(PROTO_ERROR_CODE_TXN, PROTO_TXN_STATUS_FULL, txn, PROTO_PTXN_MAX);
    }
    for (k = 0; k < pairs; k++) {
        uint16_t pid = (uint16_t)proto_get_le(data + k * PAIR_LEN, 2);
        int at = find(t, pid);

        if (at < 0) {
            at = (int)t->n++;
            t->param[at] = pid;
        }
        t->value[at] = (int64_t)proto_get_le(data + k * PAIR_LEN + 2u, 8);
    }
    t->last_us = now_us;
    return refusal(PROTO_ERROR_CODE_NONE, 0, 0, 0);
}

/* Servo parameters (drive.h): the ones servo_config may refuse together. */
static bool is_servo(drive_param_t dp)
{
    return (dp >= DRIVE_PARAM_KP && dp <= DRIVE_PARAM_FERR_LIMIT) ||
           (dp >= DRIVE_PARAM_CEC_KP && dp <= DRIVE_PARAM_CEC_KD) || dp == DRIVE_PARAM_FFL_RATE;
}

/* Checks 1..4 of proto_ptxn.h; on success everything staged is applied. */
static ptxn_refusal_t commit(struct proto_dispatch *d)
{
    const proto_ptxn_t *t = &d->ptxn;
    const uint16_t no = 0xFFFFu;
    uint16_t first_drive = no, first_plan = no, first_servo = no, mean = no;
    int64_t mean_value = 0, now_value = 0;
    drive_status_t st;
    drive_result_t r;
    drive_param_t dp;
    unsigned k, axis;
    uint8_t state;

    drive_status(&st);
    state = proto_dispatch_state(&st);
    for (k = 0; k < t->n; k++) {
        const proto_param_info_t *p = proto_param_find(t->param[k], &axis);

        if (p->owner == PROTO_POWNER_DRIVE && first_drive == no) {
            first_drive = t->param[k];
        }
    }
    if (first_drive != no &&
        (st.state == DRIVE_RUNNING || st.state == DRIVE_STOPPING || st.state == DRIVE_HOMING)) {
        return refusal(PROTO_ERROR_CODE_BUSY, first_drive, state, 0);
    }
    if (first_drive != no && drive_param_begin() != DRIVE_OK) {
        return refusal(PROTO_ERROR_CODE_INTERNAL, first_drive, 0, 0);
    }
    for (k = 0; k < t->n; k++) {
        const proto_param_info_t *p = proto_param_find(t->param[k], &axis);

        if (proto_drive_param(p->id, &dp) && drive_param_stage(dp, axis, t->value[k]) != DRIVE_OK) {
            return refusal(PROTO_ERROR_CODE_OUT_OF_RANGE, t->param[k], p->min, p->max);
        }
    }
    for (k = 0; k < t->n; k++) {
        const proto_param_info_t *p = proto_param_find(t->param[k], &axis);
        int64_t lo = 0, hi = 0;

        if (!proto_drive_param(p->id, &dp)) {
            continue;
        }
        if (drive_param_staged_range(dp, axis, &lo, &hi) != DRIVE_OK || t->value[k] < lo ||
            t->value[k] > hi) {
            return refusal(PROTO_ERROR_CODE_OUT_OF_RANGE, t->param[k], lo, hi);
        }
        if (dp <= DRIVE_PARAM_MBT_WINDOW && first_plan == no) {
            first_plan = t->param[k];
        }
        if (is_servo(dp) && first_servo == no) {
            first_servo = t->param[k];
        }
        if (dp == DRIVE_PARAM_ENC_MEAN) {
            mean = t->param[k];
            mean_value = t->value[k];
        }
    }
    if (mean != no && drive_param_get(DRIVE_PARAM_ENC_MEAN, 0, &now_value) == DRIVE_OK &&
        now_value != mean_value && st.state != DRIVE_DISABLED) {
        return refusal(PROTO_ERROR_CODE_BUSY, mean, state, 0);
    }
    if (first_drive != no) {
        /* cec_mode alone stages nothing here: commit then re-applies the
         * configuration in use, harmless while not moving */
        r = drive_param_commit();
        if (r == DRIVE_E_BUSY) {
            return refusal(PROTO_ERROR_CODE_BUSY, first_drive, state, 0);
        }
        if (r == DRIVE_E_UNSUPPORTED) {
            return refusal(PROTO_ERROR_CODE_NOT_SUPPORTED, mean != no ? mean : first_drive, 0, 0);
        }
        if (r == DRIVE_E_INVALID) {
            return refusal(PROTO_ERROR_CODE_BAD_VALUE,
                           first_plan != no ? first_plan
                                            : (first_servo != no ? first_servo : first_drive),
                           0, 0);
        }
        if (r != DRIVE_OK) {
            return refusal(PROTO_ERROR_CODE_INTERNAL, first_drive, r, 0);
        }
    }
    /* applied: what is left cannot be refused (ranges checked at stage,
     * cec_mode's busy by check 1 with nothing posted since) */
    for (k = 0; k < t->n; k++) {
        const proto_param_info_t *p = proto_param_find(t->param[k], &axis);
        int64_t v = t->value[k];

        switch (p->id) {
        case PROTO_PARAM_COMM_TIMEOUT_MS:
            d->comm_timeout_ms = (uint32_t)v;
            break;
        case PROTO_PARAM_STATUS_PERIOD_MS:
            d->status_period_ms = (uint16_t)v;
            break;
        case PROTO_PARAM_TELEM_PERIOD_MS:
            d->telem_period_ms = (uint16_t)v;
            break;
        case PROTO_PARAM_HEARTBEAT_PERIOD_MS:
            d->heartbeat_period_ms = (uint16_t)v;
            break;
        case PROTO_PARAM_CEC_MODE:
            if (drive_set_cec_mode((drive_cec_mode_t)v) == DRIVE_OK) {
                d->cec_mode = (uint8_t)v;
            }
            break;
        default:
            break;
        }
    }
    return refusal(PROTO_ERROR_CODE_NONE, 0, 0, 0);
}

size_t proto_ptxn_request(struct proto_dispatch *d, uint8_t id, uint8_t seq, const uint8_t *p,
                          size_t n, uint32_t now_us, uint8_t *out)
{
    proto_ptxn_t *t = &d->ptxn;
    uint16_t txn = n >= 2u ? (uint16_t)proto_get_le(p, 2) : 0u;
    ptxn_refusal_t r;

    proto_ptxn_poll(d, now_us); /* a timeout the main loop has not seen yet */
    switch (id) {
    case PROTO_MSG_PARAM_BEGIN:
        proto_ptxn_lose(t, PROTO_TXN_STATUS_SUPERSEDED);
        t->id = (uint16_t)(t->id + 1u == 0x10000u ? 1u : t->id + 1u);
        if (t->id == t->done_id) {
            t->done_id = 0; /* the ids wrapped: this one is not committed */
        }
        t->state = PROTO_PTXN_OPEN;
        t->n = 0;
        t->last_us = now_us;
        return put_txn(out, seq, t->id, 0, false);
    case PROTO_MSG_PARAM_STAGE:
        r = stage(d, p, n, now_us);
        break;
    case PROTO_MSG_PARAM_COMMIT:
        if (txn != 0u && txn == t->done_id) {
            /* a retry: applied once (another begin may have come since) */
            return put_txn(out, seq, txn, t->done_n, true);
        }
        r = t->state == PROTO_PTXN_OPEN && txn == t->id ? commit(d) : not_open(t, txn);
        if (r.code == PROTO_ERROR_CODE_NONE) {
            t->state = PROTO_PTXN_COMMITTED;
            t->done_id = t->id;
            t->done_n = t->n;
        }
        break;
    default: /* PROTO_MSG_PARAM_ABORT */
        if (t->state == PROTO_PTXN_OPEN && txn == t->id) {
            t->state = PROTO_PTXN_NONE;
            t->n = 0;
        }
        return proto_reply_ack(out, seq, id);
    }
    if (r.code == PROTO_ERROR_CODE_NONE) {
        return put_txn(out, seq, t->id, t->n, t->state == PROTO_PTXN_COMMITTED);
    }
    return proto_reply_error(out, seq, id, r.code, r.arg, r.lo, r.hi);
}
