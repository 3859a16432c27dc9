/*
 * drive_excite.c - the commissioning excitation on the drive (see
 * drive_excite.h).
 */
#include "drive_excite.h"

#include "calib.h"
#include "hal.h"
#include "proto_msgs.h"
#include "proto_replay.h"
#include "proto_reply.h"
#include "sample_pull.h"

CORE_SHARED bool drive_excite_armed;

static struct {
    excite_t ex;    /* excite.h says who writes what */
    bool owns;      /* main: the calibration's buffer is ours */
    bool give_back; /* main: give it back once the run stopped */
    drive_excite_handler_fn next;
    proto_replay_t replay; /* main: excite_start, excite_abort */
} dx;

void drive_excite_init(void)
{
    drive_excite_handler_fn next = dx.next;

    drive_excite_armed = false;
    excite_init(&dx.ex);
    dx.owns = false;
    dx.give_back = false;
    proto_replay_reset(&dx.replay);
    dx.next = next;
}

void drive_excite_set_next_handler(drive_excite_handler_fn fn)
{
    dx.next = fn;
}

const excite_t *drive_excite_state(void)
{
    return &dx.ex;
}

/* ---- tick ----------------------------------------------------------------- */

void drive_excite_tick(const drive_status_t *st)
{
    const unsigned a = dx.ex.cfg.axis;
    excite_in_t in;
    int32_t u;

    in.pos_nm = st->pos[a];
    in.cmd_mv = st->motor_mv[a];
    in.fault = st->faults != 0u;
    in.estop = (st->faults & DRIVE_FAULT_ESTOP) != 0u;
    in.idle = st->state == DRIVE_IDLE;
    u = excite_tick(&dx.ex, &in);
    if (u != 0) {
        /* the servo wrote its outputs in drive_tick: this replaces one */
        hal_motor_set_mv(a, st->motor_mv[a] + u);
    }
}

/* ---- main ----------------------------------------------------------------- */

/* Started and not yet seen stopped by the tick. */
static bool running(void)
{
    return dx.ex.req_start != dx.ex.ack_start || dx.ex.state == EXCITE_RUNNING;
}

void drive_excite_poll(void)
{
    if (running()) {
        return;
    }
    drive_excite_armed = false;
    if (dx.give_back && dx.owns) {
        calib_excite_give();
        dx.owns = false;
    }
    dx.give_back = false;
}

void drive_excite_host_gone(uint32_t reason)
{
    if (running()) {
        excite_abort(&dx.ex, reason);
    }
}

static size_t refuse(uint8_t *out, const uint8_t *msg, uint16_t why, int64_t detail)
{
    return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_EXCITE, why, detail, 0);
}

static size_t bad_length(uint8_t *out, const uint8_t *msg, size_t plen)
{
    return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH,
                             (uint16_t)plen, 0, 0);
}

static size_t reply_state(uint8_t *out, uint8_t seq)
{
    proto_excite_state_t s;
    const excite_t *e = &dx.ex;

    /* a start the tick has not taken yet is already RUNNING for the host */
    s.state = (uint8_t)(running() ? EXCITE_RUNNING : e->state);
    s.axis = e->cfg.axis;
    s.reason = (uint8_t)(e->req_start != e->ack_start ? EXCITE_REASON_NONE : e->reason);
    s.owner = dx.owns ? 1u : 0u;
    s.windows = e->cfg.windows;
    s.windows_done = (uint16_t)(e->req_start != e->ack_start ? 0u : e->windows_done);
    s.period = e->period;
    s.written = e->req_start != e->ack_start ? 0u : e->written;
    s.released = e->req_start != e->ack_start ? 0u : e->released;
    s.ticks = e->req_start != e->ack_start ? 0u : e->k;
    out[0] = (uint8_t)PROTO_MSG_EXCITE_STATE;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_excite_state_encode(&s, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

/* The checks of excite_start's fields the generator does not make (its
 * own: excite_setup): 0 or the field index (excite_refusal bad_setup). */
static unsigned start_field_check(const proto_excite_start_t *m)
{
    if (m->host_timeout_ms == 0u || m->host_timeout_ms > DRIVE_EXCITE_HOST_TIMEOUT_MS) {
        return 5u;
    }
    if (m->travel_nm == 0u) {
        return 9u;
    }
    if (m->vel_nm_s == 0u) {
        return 11u;
    }
    return 0u;
}

static size_t h_start(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_excite_start_t m;
    excite_cfg_t c;
    drive_status_t st;
    const drive_config_t *dc = drive_config();
    excite_sample_t *buf;
    unsigned bad;

    if (!proto_excite_start_decode(msg + PROTO_MSG_HDR, plen, &m) ||
        plen != PROTO_EXCITE_START_LEN) {
        return bad_length(out, msg, plen);
    }
    if (dc == NULL || m.axis >= dc->axes) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_BAD_AXIS, m.axis);
    }
    if (running()) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_BUSY, 0);
    }
    bad = start_field_check(&m);
    if (bad != 0u) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_BAD_SETUP, bad);
    }
    drive_snapshot(&st);
    if (st.state != DRIVE_IDLE || st.faults != 0u) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_DRIVE_STATE, st.state);
    }
    c.axis = m.axis;
    c.bits = m.bits;
    c.hold = m.hold;
    c.windows = m.windows;
    c.amp_mv = m.amp_mv;
    c.skip_ticks = m.skip_ticks;
    c.n_ticks = m.n_ticks;
    c.travel_nm = (int64_t)m.travel_nm;
    c.cmd_mv = m.cmd_mv;
    c.vel_dpos_nm = (int64_t)m.vel_nm_s * EXCITE_VEL_TICKS / (int64_t)dc->tick_hz;
    if (c.vel_dpos_nm < 1) {
        c.vel_dpos_nm = 1;
    }
    c.host_timeout_ticks = (uint32_t)((uint64_t)m.host_timeout_ms * dc->tick_hz / 1000u);
    buf = calib_excite_take();
    if (buf == NULL) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_CALIBRATION, 0);
    }
    dx.owns = true;
    dx.give_back = false;
    if (!excite_setup(&dx.ex, &c, buf, CALIB_EXCITE_SAMPLES)) {
        calib_excite_give();
        dx.owns = false;
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_BAD_SETUP, 0);
    }
    excite_start(&dx.ex);
    drive_excite_armed = true;
    return reply_state(out, msg[1]);
}

/* One sample in the excite_samples layout: i32 cmd_mv, i32 pos_nm. */
static void encode_sample(const void *src, uint32_t seq, uint8_t *dst)
{
    excite_sample_t s;
    (void)excite_sample(src, seq, &s);
    proto_put_le(dst, (uint64_t)(uint32_t)s.cmd_mv, 4u);
    proto_put_le(dst + 4u, (uint64_t)(uint32_t)s.pos_nm, 4u);
}

/* excite_read: sample_pull.h (the tick advances written: read once). */
static size_t h_read(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_excite_read_t m;
    const excite_t *e = &dx.ex;
    uint32_t written = e->written;

    if (!proto_excite_read_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_EXCITE_READ_LEN) {
        return bad_length(out, msg, plen);
    }
    if (m.max < 1u || m.max > DRIVE_EXCITE_READ_MAX) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_OUT_OF_RANGE, 1u, 0,
                                 0);
    }
    if (!dx.owns || !sample_pull_seq_ok(e->released, written, m.from_seq)) {
        return refuse(out, msg, PROTO_EXCITE_REFUSAL_SEQ, e->released);
    }
    excite_release(&dx.ex, m.from_seq);
    return sample_pull_reply(out, (uint8_t)PROTO_MSG_EXCITE_SAMPLES, msg[1], m.from_seq, m.max,
                             written, 8u, encode_sample, e);
}

static size_t h_abort(const uint8_t *msg, size_t plen, uint8_t *out)
{
    if (plen != 0u) {
        return bad_length(out, msg, plen);
    }
    if (running()) {
        excite_abort(&dx.ex, EXCITE_REASON_ABORTED);
    }
    dx.give_back = true;
    drive_excite_poll(); /* at once when nothing runs */
    return reply_state(out, msg[1]);
}

/* One request of the excitation's range (proto_replay_exec_t). */
static size_t execute(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    const size_t plen = len - PROTO_MSG_HDR;

    (void)ctx;
    switch (msg[0]) {
    case PROTO_MSG_EXCITE_START:
        return h_start(msg, plen, out);
    case PROTO_MSG_EXCITE_STATUS:
        return plen == 0u ? reply_state(out, msg[1]) : bad_length(out, msg, plen);
    case PROTO_MSG_EXCITE_READ:
        return h_read(msg, plen, out);
    case PROTO_MSG_EXCITE_ABORT:
        return h_abort(msg, plen, out);
    default:
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u,
                                 0, 0);
    }
}

size_t drive_excite_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                           size_t cap)
{
    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        return 0;
    }
    if (msg[0] < 0xD0u || msg[0] > 0xDFu) {
        if (dx.next != NULL) {
            return dx.next(msg, len, now_us, out, cap);
        }
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u,
                                 0, 0);
    }
    excite_host_alive(&dx.ex);
    if (msg[0] == PROTO_MSG_EXCITE_START || msg[0] == PROTO_MSG_EXCITE_ABORT) {
        return proto_replay_answer(&dx.replay, msg, len, out, cap, execute, NULL);
    }
    return execute(NULL, msg, len, out);
}
