/*
 * calib.c - calibration mode and compensation tables of the drive (see
 * calib.h).
 */
#include "calib.h"
#include "calib_int.h"

#include "comp_store.h"
#include "excite.h"
#include "proto_replay.h"
#include "sample_pull.h"
#include "preempt.h"
#include "proto_msgs.h"
#include "proto_reply.h"
#include "scratch.h"

typedef enum {
    PH_PRE = 0, /* start the move to the approach point        */
    PH_PRE_WAIT,
    PH_MOVE, /* start the move to the target                */
    PH_MOVE_WAIT,
    PH_DWELL,
    PH_ROOM,
    PH_SAMPLE
} phase_t;

/* Contexts (docs/tick-main.md): main runs the run's state machine and the
 * handlers; the tick samples while s_active. Main writes the sampling order
 * (s_target, s_left, s_phase and the leg fields the sample carries),
 * CORE_BARRIER(), then sets s_active; the tick clears it after the last
 * sample (main may clear it to cancel). */
static struct {
    /* run (main; axis, flags, sample_ticks and leg_point / leg_dir /
     * leg_cycle are read by the tick while s_active) */
    calib_state_t state;
    uint8_t axis;
    uint8_t flags;
    uint16_t points;
    uint8_t cycles;
    uint16_t samples;
    uint16_t sample_ticks;
    uint16_t dwell_ms;
    uint32_t overrun;
    uint32_t feed;
    pos_nm_t target[CALIB_POINTS_MAX];
    uint8_t loaded[(CALIB_POINTS_MAX + 7) / 8];
    uint16_t nloaded;
    uint32_t leg;       /* run: leg index; repeat: unused          */
    bool repeat;        /* measuring a single leg (calib_point)    */
    uint16_t leg_point; /* point, direction and cycle of the leg   */
    int8_t leg_dir;
    uint8_t leg_cycle;
    bool leg_pre; /* the leg starts with an approach move     */
    phase_t phase;
    uint32_t done_mark; /* blocks_done to reach                     */
    uint64_t dwell_end; /* tick at which the dwell ends             */
    bool host_seen;     /* a calibration request since the last poll */
    uint64_t host_tick; /* tick of the last poll that saw one        */
    uint16_t legs_done;
    uint8_t reason;
    int32_t detail;
    /* sample ring: a slot is written by the tick before seq_next covers
     * it, read by main below seq_next; while excite_owns (main), the
     * excitation's samples instead (calib_excite_take) */
    union {
        calib_sample_t ring[CALIB_RING];
        excite_sample_t ex[CALIB_EXCITE_SAMPLES];
    } buf;
    bool excite_owns;
    CORE_SHARED uint32_t seq_next; /* tick (main: calib_setup, tick idle) */
    uint32_t seq_oldest;           /* main                                 */
    /* sampling order: main writes it before s_active, the tick counts */
    CORE_SHARED bool s_active; /* main sets (and may clear), tick clears */
    uint16_t s_left;           /* tick while s_active                    */
    uint16_t s_phase;          /* tick while s_active                    */
    pos_nm_t s_target;         /* main                                   */
    pos_nm_t s_xtarget;        /* main: the cross axis's held position   */
    uint8_t s_cross;           /* main: the cross axis, 0xFF: none       */
    uint8_t s_flags;           /* main: the leg's CALIB_SAMPLE_* (no fault) */
    /* compensation */
    comp_table_t tab[CORE_AXES][2];
    uint8_t act[CORE_AXES]; /* index of the active buffer, 0xFF: none */
    uint8_t slot[CORE_AXES];
    comp_ramp_t ramp[CORE_AXES]; /* tick (calib_init: main, before the tick) */
    /* bit i: ramp[i] has a direction and w has not reached its end (tick;
     * calib_init clears it with the ramps) */
    uint8_t ramp_busy;
    /* bits 2i and 2i + 1: a negative, a positive reference velocity of
     * axis i is a turn for ramp[i] (dir >= 0, dir <= 0); written with
     * every change of a ramp's dir (tick; calib_init) */
    uint32_t turn_mask;
    /* protocol */
    calib_handler_fn next;
    proto_replay_t replay; /* state-changing requests only */
} cb;

/* ---- helpers ---------------------------------------------------------------- */

static uint32_t ring_used(void)
{
    return cb.seq_next - cb.seq_oldest;
}

static unsigned axes(void)
{
    const drive_config_t *c = drive_config();
    return c != NULL ? c->axes : 0u;
}

static uint32_t tick_hz(void)
{
    const drive_config_t *c = drive_config();
    return c != NULL && c->tick_hz > 0u ? c->tick_hz : CORE_TICK_HZ_DEFAULT;
}

/* ---- compensation ---------------------------------------------------------------- */

static void ramp_masks(void);

static void comp_install(unsigned axis, const comp_table_t *t, unsigned slot)
{
    uint8_t next = cb.act[axis] == 0u ? 1u : 0u;
    comp_table_t *dst = &cb.tab[axis][next];
    *dst = *t;
    dst->dir_src = &cb.ramp[axis];
    comp_ramp_set_time(&cb.ramp[axis], t->ramp_us, tick_hz());
    drive_set_comp(axis, t->n > 0u ? dst : NULL);
    cb.act[axis] = t->n > 0u ? next : 0xFFu;
    cb.slot[axis] = (uint8_t)slot;
}

/* The axis's current table from flash into its decoder (via scratch.h). */
comp_store_result_t calib_load_install(unsigned axis)
{
    comp_table_t *t = scratch_claim(SCRATCH_CALIB, sizeof *t);
    comp_store_result_t r = COMP_STORE_E_BUSY;
    unsigned slot;
    if (t != NULL) {
        r = comp_store_load(axis, t, &slot);
        if (r == COMP_STORE_OK) {
            comp_install(axis, t, slot);
        }
        scratch_release(SCRATCH_CALIB);
    }
    return r;
}

uint8_t calib_comp_slot(unsigned axis)
{
    return axis < CORE_AXES ? cb.slot[axis] : 0xFFu;
}

const comp_table_t *calib_comp_active(unsigned axis)
{
    if (axis >= CORE_AXES || cb.act[axis] > 1u) {
        return NULL;
    }
    return &cb.tab[axis][cb.act[axis]];
}

/* ---- init, tick ---------------------------------------------------------------------- */

void calib_init(void)
{
    unsigned i;
    calib_handler_fn next = cb.next;

    cb.state = CALIB_IDLE;
    cb.s_active = false;
    cb.seq_next = 0u;
    cb.seq_oldest = 0u;
    cb.points = 0u;
    cb.nloaded = 0u;
    cb.legs_done = 0u;
    cb.reason = 0u;
    cb.detail = 0;
    calib_record_reset();
    cb.excite_owns = false;
    proto_replay_reset(&cb.replay);
    cb.next = next;
    for (i = 0; i < CORE_AXES; i++) {
        cb.act[i] = 0xFFu;
        cb.slot[i] = 0xFFu;
        comp_ramp_init(&cb.ramp[i], 0u, tick_hz());
        cb.ramp_busy = 0u;
        ramp_masks();
        if (i < axes()) {
            (void)calib_load_install(i);
        }
    }
}

bool calib_sampling(void)
{
    return cb.s_active;
}

/* The turn masks of the ramps' directions (see cb.turn_neg). */
static void ramp_masks(void)
{
    unsigned i;
    uint32_t m = 0u;
    for (i = 0; i < CORE_AXES; i++) {
        if (cb.ramp[i].dir >= 0) {
            m |= 1u << (2u * i);
        }
        if (cb.ramp[i].dir <= 0) {
            m |= 2u << (2u * i);
        }
    }
    cb.turn_mask = m;
}

/* Bit 0: v < 0, bit 1: v > 0 (sign bits of v and of -v, mod 2^64; both
 * for INT64_MIN, which only sends calib_tick to the exact per-ramp test). */
static inline uint32_t sign_bits(int64_t v)
{
    uint32_t n = (uint32_t)((uint64_t)v >> 63);
    uint32_t p = (uint32_t)(((uint64_t)0 - (uint64_t)v) >> 63);
    return n | (p << 1);
}

/* Step the ramps that turn or still move (the rest would not change). */
static void ramp_tick(const int64_t *vel_ref)
{
    unsigned i;
    for (i = 0; i < CORE_AXES; i++) {
        comp_ramp_t *r = &cb.ramp[i];
        int64_t v = vel_ref[i];
        bool turn = r->dir > 0 ? v < 0 : (r->dir < 0 ? v > 0 : v != 0);
        /* settled (the usual case: moving on in the same direction, or at
         * rest, with w at that direction's end): comp_ramp_step would
         * change nothing */
        if (turn || (cb.ramp_busy & (1u << i)) != 0u) {
            comp_ramp_step(r, v);
            if (r->dir != 0 && r->w_q30 != (r->dir > 0 ? COMP_W_ONE : -COMP_W_ONE)) {
                cb.ramp_busy |= (uint8_t)(1u << i);
            } else {
                cb.ramp_busy &= (uint8_t) ~(1u << i);
            }
        }
    }
    ramp_masks();
}

#if defined(__GNUC__)
#define CALIB_NOINLINE __attribute__((noinline))
#else
#define CALIB_NOINLINE
#endif

static CALIB_NOINLINE void calib_tick_work(const drive_status_t *st,
                                           const int64_t vel_ref[CORE_AXES], uint32_t turn);

void calib_tick(const drive_status_t *st, const int64_t vel_ref[CORE_AXES])
{
    uint32_t sb = 0u, turn;
    unsigned i;
    if (st == NULL || vel_ref == NULL) {
        return;
    }
    /* the usual tick: no axis turns, every ramp is settled and nothing
     * samples (the signs of the velocities against the turn mask of the
     * ramps' directions); the rest out of line */
#if CORE_AXES == 3
    sb = sign_bits(vel_ref[0]) | (sign_bits(vel_ref[1]) << 2) | (sign_bits(vel_ref[2]) << 4);
    (void)i;
#else
    for (i = 0; i < CORE_AXES; i++) {
        sb |= sign_bits(vel_ref[i]) << (2u * i);
    }
#endif
    turn = (sb & cb.turn_mask) | cb.ramp_busy;
    if ((turn | (uint32_t)cb.s_active) != 0u) {
        calib_tick_work(st, vel_ref, turn);
    }
}

static void calib_tick_work(const drive_status_t *st, const int64_t vel_ref[CORE_AXES],
                            uint32_t turn)
{
    if (turn != 0u) {
        ramp_tick(vel_ref);
    }
    if (!cb.s_active) {
        return;
    }
    if (++cb.s_phase < cb.sample_ticks) {
        return;
    }
    cb.s_phase = 0u;
    {
        uint32_t seq = cb.seq_next;
        calib_sample_t *s = &cb.buf.ring[seq % CALIB_RING];
        uint8_t a = cb.axis;
        s->seq = seq;
        s->point = cb.leg_point;
        s->cycle = cb.leg_cycle;
        uint8_t c = cb.s_cross;
        s->flags = (uint8_t)(cb.s_flags | (st->faults != 0u ? CALIB_SAMPLE_FAULT : 0u));
        s->enc = fx_sat_diff32(st->pos_raw[a], cb.s_target);
        s->comp = fx_sat_diff32(st->pos[a], cb.s_target);
        s->ref =
            (cb.s_flags & CALIB_SAMPLE_NO_REF) ? 0 : fx_sat_diff32(st->refscale[a], cb.s_target);
        if (c < CORE_AXES) {
            s->xenc = fx_sat_diff32(st->pos_raw[c], cb.s_xtarget);
            s->xcomp = fx_sat_diff32(st->pos[c], cb.s_xtarget);
            s->xref = fx_sat_diff32(st->refscale[c], cb.s_xtarget);
        } else {
            s->xenc = s->xcomp = s->xref = 0;
        }
        cb.seq_next = seq + 1u;
    }
    if (--cb.s_left == 0u) {
        cb.s_active = false;
    }
}

/* ---- run state machine (main) ------------------------------------------------------------ */

static void fail(uint8_t reason, int32_t detail)
{
    cb.s_active = false;
    cb.state = CALIB_ERROR;
    cb.reason = reason;
    cb.detail = detail;
}

/* Leg k of the run: point, direction, cycle and whether it starts with an
 * approach move (the first leg of each pass). */
static void leg_of(uint32_t k)
{
    uint32_t per = 2u * cb.points;
    uint32_t j = k % per;
    cb.leg_cycle = (uint8_t)(k / per);
    if (j < cb.points) {
        cb.leg_point = (uint16_t)j;
        cb.leg_dir = 1;
        cb.leg_pre = j == 0u;
    } else {
        cb.leg_point = (uint16_t)(per - 1u - j);
        cb.leg_dir = -1;
        cb.leg_pre = j == cb.points;
    }
    cb.phase = cb.leg_pre ? PH_PRE : PH_MOVE;
}

/* Queue one exact-stop move of the calibrated axis to pos. */
static bool start_move(pos_nm_t pos)
{
    drive_status_t st;
    drive_block_t b;
    drive_result_t r;
    unsigned i;

    drive_snapshot(&st);
    PREEMPT_POINT();
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = st.ref[i];
    }
    b.kind = DRIVE_BLOCK_LINE;
    b.tag = 0xCA1B0000u | (cb.leg & 0xFFFFu);
    b.target[cb.axis] = pos;
    b.feed_nm_s = cb.feed;
    b.exact_stop = true;
    b.plane = DRIVE_PLANE_XY;
    b.centre_u = 0;
    b.centre_v = 0;
    b.sense = 1;
    b.dwell_ms = 0u;
    r = drive_queue_block(&b);
    PREEMPT_POINT();
    if (r == DRIVE_E_FULL) {
        return false; /* try again at the next poll */
    }
    if (r != DRIVE_OK) {
        fail(PROTO_CALIB_STATUS_MOTION, (int32_t)r);
        return false;
    }
    cb.done_mark = st.blocks_done + 1u;
    return true;
}

static bool move_done(const drive_status_t *st)
{
    return (int32_t)(st->blocks_done - cb.done_mark) >= 0 && st->state == DRIVE_IDLE;
}

static void leg_finished(void)
{
    cb.legs_done++;
    if (cb.repeat) {
        cb.repeat = false;
        cb.state = CALIB_DONE;
        return;
    }
    cb.leg++;
    if (cb.leg >= 2u * (uint32_t)cb.points * cb.cycles) {
        cb.state = CALIB_DONE;
        return;
    }
    leg_of(cb.leg);
}

/* The sample's fixed flags and the cross axis of the leg (calib.h): the
 * other XY axis when it has a reference scale, held where it is now. */
static void arm_cross(const drive_status_t *st)
{
    unsigned c = cb.axis == 0u ? 1u : (cb.axis == 1u ? 0u : 0xFFu);
    bool host = (cb.flags & CALIB_FLAG_HOST_REFERENCE) != 0u;
    uint8_t f =
        (uint8_t)((cb.leg_dir < 0 ? CALIB_SAMPLE_NEG : 0u) | (host ? CALIB_SAMPLE_NO_REF : 0u));
    if (host || c >= CORE_AXES || !drive_has_refscale(c)) {
        f |= CALIB_SAMPLE_NO_XREF;
        c = 0xFFu;
    }
    cb.s_cross = (uint8_t)c;
    cb.s_xtarget = c < CORE_AXES ? st->ref[c] : 0;
    cb.s_flags = f;
}

void calib_host_gone(uint8_t reason)
{
    if (cb.state == CALIB_RUNNING) {
        drive_stop();
        PREEMPT_POINT();
        fail(reason, 0);
    }
}

void calib_poll(void)
{
    drive_status_t st;
    pos_nm_t t;

    if (cb.state != CALIB_RUNNING) {
        return;
    }
    drive_snapshot(&st);
    PREEMPT_POINT();
    if (st.state == DRIVE_FAULT) {
        drive_stop();
        fail(PROTO_CALIB_STATUS_DRIVE_FAULT, (int32_t)st.faults);
        return;
    }
    if (st.state == DRIVE_DISABLED) {
        fail(PROTO_CALIB_STATUS_DRIVE_DISABLED, 0);
        return;
    }
    if (cb.host_seen) {
        cb.host_seen = false;
        cb.host_tick = st.tick;
    } else if (st.tick - cb.host_tick > (uint64_t)CALIB_HOST_TIMEOUT_MS * tick_hz() / 1000u) {
        calib_host_gone(PROTO_CALIB_STATUS_HOST_SILENT);
        return;
    }
    t = cb.target[cb.leg_point];
    switch (cb.phase) {
    case PH_PRE:
        if (start_move(t - (pos_nm_t)cb.leg_dir * (pos_nm_t)cb.overrun)) {
            cb.phase = PH_PRE_WAIT;
        }
        break;
    case PH_PRE_WAIT:
        if (move_done(&st)) {
            cb.phase = PH_MOVE;
        }
        break;
    case PH_MOVE:
        if (start_move(t)) {
            cb.phase = PH_MOVE_WAIT;
        }
        break;
    case PH_MOVE_WAIT:
        if (move_done(&st)) {
            cb.dwell_end = st.tick + (uint64_t)cb.dwell_ms * tick_hz() / 1000u;
            cb.phase = PH_DWELL;
        }
        break;
    case PH_DWELL:
        if (st.tick >= cb.dwell_end) {
            cb.phase = PH_ROOM;
        }
        break;
    case PH_ROOM:
        if (CALIB_RING - ring_used() >= cb.samples) {
            arm_cross(&st);
            cb.s_target = t;
            cb.s_left = cb.samples;
            cb.s_phase = 0u;
            cb.phase = PH_SAMPLE;
            PREEMPT_POINT();
            CORE_BARRIER();
            cb.s_active = true; /* hand over to the tick (last store) */
        }
        break;
    case PH_SAMPLE:
        if (!cb.s_active) {
            leg_finished();
        }
        break;
    default:
        break;
    }
}

/* ---- read-outs ------------------------------------------------------------------------------ */

calib_state_t calib_state(void)
{
    return cb.state;
}

void calib_sample_encode(const calib_sample_t *s, uint8_t *b)
{
    proto_put_le(b, s->seq, 4u);
    proto_put_le(b + 4, s->point, 2u);
    b[6] = s->cycle;
    b[7] = s->flags;
    proto_put_le(b + 8, (uint32_t)s->enc, 4u);
    proto_put_le(b + 12, (uint32_t)s->comp, 4u);
    proto_put_le(b + 16, (uint32_t)s->ref, 4u);
    proto_put_le(b + 20, (uint32_t)s->xenc, 4u);
    proto_put_le(b + 24, (uint32_t)s->xcomp, 4u);
    proto_put_le(b + 28, (uint32_t)s->xref, 4u);
}

/* ---- protocol ----------------------------------------------------------------------------------
 */

static size_t reply_error(uint8_t *out, uint8_t req, uint8_t seq, uint8_t code, uint16_t arg,
                          int64_t lo)
{
    return proto_reply_error(out, seq, req, code, arg, lo, 0);
}

static size_t refuse(uint8_t *out, const uint8_t *msg, uint8_t status, int64_t detail)
{
    return reply_error(out, msg[0], msg[1], (uint8_t)PROTO_ERROR_CODE_CALIB, status, detail);
}

static size_t reply_state(uint8_t *out, uint8_t seq)
{
    proto_calib_state_t s;
    s.state = (uint8_t)cb.state;
    s.axis = cb.axis;
    s.reason = cb.reason;
    s.flags = cb.flags;
    s.points = cb.points;
    s.targets_loaded = cb.nloaded;
    s.point = cb.leg_point;
    s.dir = cb.leg_dir;
    s.cycle = cb.leg_cycle;
    s.legs_done = cb.legs_done;
    s.legs_total = (uint16_t)(2u * (uint32_t)cb.points * cb.cycles);
    s.seq_next = cb.seq_next;
    s.seq_oldest = cb.seq_oldest;
    s.detail = cb.detail;
    out[0] = (uint8_t)PROTO_MSG_CALIB_STATE;
    out[1] = seq;
    return PROTO_MSG_HDR + proto_calib_state_encode(&s, out + PROTO_MSG_HDR, PROTO_MAX_PAYLOAD);
}

static bool run_busy(void)
{
    return cb.state == CALIB_RUNNING;
}

static size_t h_setup(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_calib_setup_t m;
    const drive_config_t *c = drive_config();
    unsigned i;
    if (!proto_calib_setup_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_CALIB_SETUP_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_CALIB_SETUP_LEN);
    }
    if (run_busy()) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BUSY, 0);
    }
    if (c == NULL || m.axis >= c->axes) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_AXIS, m.axis);
    }
    if ((m.flags & ~CALIB_FLAG_HOST_REFERENCE) != 0u) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 1);
    }
    if (!(m.flags & CALIB_FLAG_HOST_REFERENCE) && !drive_has_refscale(m.axis)) {
        return refuse(out, msg, PROTO_CALIB_STATUS_NO_REFERENCE, m.axis);
    }
    if (m.points < 1u || m.points > CALIB_POINTS_MAX) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 2);
    }
    if (m.cycles < 1u || m.cycles > CALIB_CYCLES_MAX) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 3);
    }
    if (m.samples < 1u || m.samples > CALIB_RING) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 5);
    }
    if (m.sample_ticks < 1u) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 6);
    }
    if (m.dwell_ms > CALIB_DWELL_MAX_MS) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 7);
    }
    if (m.overrun > CALIB_OVERRUN_MAX) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 8);
    }
    if (m.feed < 1u) {
        return refuse(out, msg, PROTO_CALIB_STATUS_BAD_SETUP, 9);
    }
    cb.state = CALIB_SETUP;
    cb.axis = m.axis;
    cb.flags = m.flags;
    cb.points = m.points;
    cb.cycles = m.cycles;
    cb.samples = m.samples;
    cb.sample_ticks = m.sample_ticks;
    cb.dwell_ms = m.dwell_ms;
    cb.overrun = m.overrun;
    cb.feed = m.feed;
    cb.nloaded = 0u;
    for (i = 0; i < sizeof cb.loaded; i++) {
        cb.loaded[i] = 0u;
    }
    cb.leg = 0u;
    cb.repeat = false;
    cb.leg_point = 0u;
    cb.leg_dir = 0;
    cb.leg_cycle = 0u;
    cb.legs_done = 0u;
    cb.reason = 0u;
    cb.detail = 0;
    cb.s_active = false;
    cb.seq_next = 0u;
    cb.seq_oldest = 0u;
    return reply_state(out, msg[1]);
}

static size_t h_targets(const uint8_t *msg, size_t plen, uint8_t *out)
{
    static proto_calib_targets_t m;
    size_t i, n;
    if (!proto_calib_targets_decode(msg + PROTO_MSG_HDR, plen, &m) || m.data_len % 8u != 0u) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_CALIB_TARGETS_LEN);
    }
    if (cb.state != CALIB_SETUP) {
        return refuse(out, msg, run_busy() ? PROTO_CALIB_STATUS_BUSY : PROTO_CALIB_STATUS_NOT_READY,
                      0);
    }
    n = m.data_len / 8u;
    if ((size_t)m.first + n > cb.points) {
        return refuse(out, msg, PROTO_CALIB_STATUS_TARGETS, (int64_t)m.first + (int64_t)n);
    }
    for (i = 0; i < n; i++) {
        pos_nm_t p = (pos_nm_t)proto_get_le(m.data + 8u * i, 8u);
        if (p > CALIB_POS_LIMIT_NM || p < -CALIB_POS_LIMIT_NM) {
            return refuse(out, msg, PROTO_CALIB_STATUS_TARGETS, (int64_t)(m.first + i));
        }
    }
    for (i = 0; i < n; i++) {
        size_t k = m.first + i;
        cb.target[k] = (pos_nm_t)proto_get_le(m.data + 8u * i, 8u);
        if (!(cb.loaded[k / 8u] & (1u << (k % 8u)))) {
            cb.loaded[k / 8u] = (uint8_t)(cb.loaded[k / 8u] | (1u << (k % 8u)));
            cb.nloaded++;
        }
    }
    return reply_state(out, msg[1]);
}

static size_t h_start(const uint8_t *msg, size_t plen, uint8_t *out)
{
    drive_status_t st;
    uint16_t i;
    if (plen != 0u) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen, 0);
    }
    if (cb.state != CALIB_SETUP) {
        return refuse(out, msg, run_busy() ? PROTO_CALIB_STATUS_BUSY : PROTO_CALIB_STATUS_NOT_READY,
                      0);
    }
    if (cb.nloaded != cb.points) {
        return refuse(out, msg, PROTO_CALIB_STATUS_TARGETS, cb.nloaded);
    }
    for (i = 0; i < cb.points; i++) {
        pos_nm_t t = cb.target[i];
        if ((i > 0u && t <= cb.target[i - 1u]) || t - (pos_nm_t)cb.overrun < -CALIB_POS_LIMIT_NM ||
            t + (pos_nm_t)cb.overrun > CALIB_POS_LIMIT_NM) {
            return refuse(out, msg, PROTO_CALIB_STATUS_TARGETS, i);
        }
    }
    drive_snapshot(&st);
    PREEMPT_POINT();
    if (st.state != DRIVE_IDLE) {
        return refuse(out, msg, PROTO_CALIB_STATUS_DRIVE_DISABLED, st.state);
    }
    cb.leg = 0u;
    cb.repeat = false;
    leg_of(0u);
    cb.host_seen = true; /* the watchdog counts from the next poll */
    cb.state = CALIB_RUNNING;
    return reply_state(out, msg[1]);
}

static size_t h_point(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_calib_point_t m;
    drive_status_t st;
    if (!proto_calib_point_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_CALIB_POINT_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_CALIB_POINT_LEN);
    }
    if (cb.state != CALIB_DONE) {
        return refuse(out, msg, run_busy() ? PROTO_CALIB_STATUS_BUSY : PROTO_CALIB_STATUS_NOT_READY,
                      0);
    }
    if (m.point >= cb.points || (m.dir != 1 && m.dir != -1) || m.cycle >= cb.cycles) {
        return refuse(out, msg, PROTO_CALIB_STATUS_NOT_READY, m.point);
    }
    drive_snapshot(&st);
    if (st.state != DRIVE_IDLE) {
        return refuse(out, msg, PROTO_CALIB_STATUS_DRIVE_DISABLED, st.state);
    }
    cb.repeat = true;
    cb.leg_point = m.point;
    cb.leg_dir = m.dir;
    cb.leg_cycle = m.cycle;
    cb.leg_pre = true;
    cb.phase = PH_PRE;
    cb.host_seen = true;
    cb.state = CALIB_RUNNING;
    return reply_state(out, msg[1]);
}

static size_t h_abort(const uint8_t *msg, size_t plen, uint8_t *out)
{
    if (plen != 0u) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen, 0);
    }
    calib_host_gone(PROTO_CALIB_STATUS_ABORTED);
    return reply_state(out, msg[1]);
}

static void encode_ring(const void *src, uint32_t seq, uint8_t *dst)
{
    (void)src;
    calib_sample_encode(&cb.buf.ring[seq % CALIB_RING], dst);
}

/* calib_read: sample_pull.h (the tick advances seq_next: read once). */
static size_t h_read(const uint8_t *msg, size_t plen, uint8_t *out)
{
    proto_calib_read_t m;
    uint32_t next = cb.seq_next;
    if (!proto_calib_read_decode(msg + PROTO_MSG_HDR, plen, &m) || plen != PROTO_CALIB_READ_LEN) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen,
                           PROTO_CALIB_READ_LEN);
    }
    if (m.max < 1u || m.max > CALIB_READ_MAX) {
        return reply_error(out, msg[0], msg[1], PROTO_ERROR_CODE_OUT_OF_RANGE, 1u, 1);
    }
    if (!sample_pull_seq_ok(cb.seq_oldest, next, m.from_seq)) {
        return refuse(out, msg, PROTO_CALIB_STATUS_SEQ, cb.seq_oldest);
    }
    cb.seq_oldest = m.from_seq; /* release everything before */
    return sample_pull_reply(out, (uint8_t)PROTO_MSG_CALIB_SAMPLES, msg[1], m.from_seq, m.max, next,
                             CALIB_SAMPLE_BYTES, encode_ring, NULL);
}

static bool mutating(uint8_t id)
{
    return id == PROTO_MSG_CALIB_SETUP || id == PROTO_MSG_CALIB_TARGETS ||
           id == PROTO_MSG_CALIB_START || id == PROTO_MSG_CALIB_POINT ||
           id == PROTO_MSG_CALIB_ABORT || id == PROTO_MSG_COMP_WRITE ||
           id == PROTO_MSG_COMP_COMMIT || id == PROTO_MSG_COMP_CLEAR;
}

void calib_set_next_handler(calib_handler_fn fn)
{
    cb.next = fn;
}

/* One request of the calibration's range (proto_replay_exec_t). */
static size_t execute(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    const size_t plen = len - PROTO_MSG_HDR;
    const uint8_t id = msg[0];

    (void)ctx;
    switch (id) {
    case PROTO_MSG_CALIB_SETUP:
        return h_setup(msg, plen, out);
    case PROTO_MSG_CALIB_TARGETS:
        return h_targets(msg, plen, out);
    case PROTO_MSG_CALIB_START:
        return h_start(msg, plen, out);
    case PROTO_MSG_CALIB_STATUS:
        return plen == 0u
                   ? reply_state(out, msg[1])
                   : reply_error(out, id, msg[1], PROTO_ERROR_CODE_BAD_LENGTH, (uint16_t)plen, 0);
    case PROTO_MSG_CALIB_READ:
        return h_read(msg, plen, out);
    case PROTO_MSG_CALIB_POINT:
        return h_point(msg, plen, out);
    case PROTO_MSG_CALIB_ABORT:
        return h_abort(msg, plen, out);
    case PROTO_MSG_COMP_WRITE:
        return calib_h_comp_write(msg, plen, out);
    case PROTO_MSG_COMP_COMMIT:
        return calib_h_comp_commit(msg, plen, out);
    case PROTO_MSG_COMP_GET:
        return calib_h_comp_get(msg, plen, out);
    case PROTO_MSG_COMP_CLEAR:
        return calib_h_comp_clear(msg, plen, out);
    default:
        return reply_error(out, id, msg[1], PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u, 0);
    }
}

size_t calib_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out, size_t cap)
{
    uint8_t id;

    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        return 0;
    }
    id = msg[0];
    if (id < 0xA0u || id > 0xBFu) {
        if (cb.next != NULL) {
            return cb.next(msg, len, now_us, out, cap);
        }
        return reply_error(out, id, msg[1], PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u, 0);
    }
    if (cb.excite_owns && id <= PROTO_MSG_CALIB_POINT && id != PROTO_MSG_CALIB_STATUS) {
        return refuse(out, msg, PROTO_CALIB_STATUS_EXCITE, 0); /* the ring holds its samples */
    }
    cb.host_seen = true; /* the host is there (calib_poll's watchdog) */
    if (mutating(id)) {
        return proto_replay_answer(&cb.replay, msg, len, out, cap, execute, NULL);
    }
    return execute(NULL, msg, len, out);
}

excite_sample_t *calib_excite_take(void)
{
    if (cb.state == CALIB_SETUP || cb.state == CALIB_RUNNING || cb.s_active) {
        return NULL;
    }
    cb.state = CALIB_IDLE; /* a finished run's samples are gone */
    cb.seq_next = 0u;
    cb.seq_oldest = 0u;
    cb.excite_owns = true;
    return cb.buf.ex;
}

void calib_excite_give(void)
{
    cb.excite_owns = false;
}
