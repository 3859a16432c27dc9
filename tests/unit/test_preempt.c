/*
 * Preemption tests of the tick/main contract (docs/tick-main.md).
 *
 * Every PREEMPT_POINT() of the main context (drive commands and drive_poll,
 * the snapshot reader, the link handlers, the calibration run) is a place
 * where the tick may interrupt it on a target. The simulator runs tick and
 * poll one after the other, so this test makes the tick run there: a first
 * pass of the scenario below records every point it passes; then, for each
 * point, the scenario is replayed from a fresh drive with a hook that runs
 * one extra drive_tick() when main reaches that point (once per arming: the
 * hook is armed again every ARM_EVERY simulator ticks and before every
 * request, so a point on the usual path fires often, a rare one at its first
 * pass). After each phase the drive must have done what the host asked:
 *   A. enable and queue two blocks in one batch (no tick between): both run
 *      to their end point, the drive ends IDLE with blocks_done 2;
 *   B. a controlled stop in the middle of a long block: the drive reaches
 *      IDLE (never stuck in STOPPING or with a halted reference), the block
 *      is dropped (blocks_done unchanged), and a new block from the stop
 *      point runs to its end;
 *   C. disable, enable and queue in one batch: the block runs;
 *   D. e-stop: FAULT; fault_reset: DISABLED; enable and queue: the block runs;
 *   E. a planner parameter set while idle is accepted and read back;
 *   F. a block queued right after a stop (before any tick) is refused, not
 *      dropped by the stop; a new job after it runs;
 *   G. a calibration run of two points, one cycle: DONE with every sample;
 *   H. homing stopped, homing, a job in the new frame;
 *   I. a job of three queue_batch messages of 50 blocks (more than the
 *      host FIFO and the planner take: the rest waits in the intake ring
 *      and proto_dispatch_poll pumps it): every block runs, in order, to
 *      the last one's end point;
 *   J. a stop while the intake ring holds blocks: none of them runs after
 *      the stop, the stream answers busy, a new stream runs.
 * A failure names the point (file:line) and the phase.
 */
#include <stdio.h>
#include <string.h>

#include "calib.h"
#include "drive.h"
#include "hal_sim.h"
#include "preempt.h"
#include "proto_batch.h"
#include "proto_dispatch.h"
#include "proto_msgs.h"
#include "sim.h"
#include "unity.h"

#define ARM_EVERY  8u     /* simulator ticks between armings             */
#define WAIT_TICKS 40000u /* bound of every wait (4 s at 10 kHz)        */
#define MAX_POINTS 128u
#define FEED       20000000u /* 20 mm/s */

typedef struct {
    const char *file;
    int line;
} point_t;

static point_t pts[MAX_POINTS];
static unsigned npts;
static bool recording;
static const point_t *target;
static bool armed;
static unsigned fired;
static bool in_tick;

static proto_dispatch_t d;
static uint8_t out[PROTO_MSG_MAX];
static size_t out_len;
static uint32_t now_us;
static uint8_t next_seq;
static char where[160];
static const char *phase;

/* One control tick as a port runs it: the drive, then the calibration
 * with what the drive published. */
static void tick(void)
{
    const drive_tick_out_t *t = drive_tick(calib_sampling());
    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
    }
}

static void hook(const char *file, int line)
{
    unsigned i;
    if (in_tick) {
        return;
    }
    if (recording) {
        for (i = 0; i < npts; i++) {
            if (pts[i].line == line && strcmp(pts[i].file, file) == 0) {
                return;
            }
        }
        TEST_ASSERT_TRUE(npts < MAX_POINTS);
        pts[npts].file = file;
        pts[npts].line = line;
        npts++;
        return;
    }
    if (armed && target != NULL && target->line == line && strcmp(target->file, file) == 0) {
        armed = false;
        fired++;
        in_tick = true;
        /* 1 us after the last tick (the clock's unit): sample times must
         * advance; the next regular tick is 100 us after the last one */
        hal_sim_set_time_ns(hal_sim_time_ns() + 1000u);
        tick(); /* the tick preempts main here */
        in_tick = false;
    }
}

static void msg(void)
{
    snprintf(where, sizeof where, "tick at %s:%d, phase %s", target ? target->file : "(none)",
             target ? target->line : 0, phase);
}

static drive_status_t status(void)
{
    drive_status_t st;
    bool a = armed;
    armed = false;     /* the test's own reads are not preempted */
    drive_status(&st); /* what the host sees (main's view) */
    armed = a;
    return st;
}

static void run(unsigned ticks)
{
    unsigned k;
    for (k = 0; k < ticks; k++) {
        if (sim_ticks() % ARM_EVERY == 0u) {
            armed = true;
        }
        TEST_ASSERT_TRUE(sim_run(1, NULL, 0, 0) >= 0);
        now_us += 100u;
        if (sim_ticks() % 10u == 0u) {
            proto_dispatch_poll(&d, now_us, NULL, NULL);
        }
    }
}

static size_t request(uint8_t id, const uint8_t *payload, size_t n)
{
    uint8_t m[PROTO_MSG_MAX];
    m[0] = id;
    m[1] = ++next_seq;
    if (n > 0) {
        memcpy(m + 2, payload, n);
    }
    armed = true;
    out_len = proto_dispatch_handle(&d, m, n + 2, now_us, out, sizeof out);
    return out_len;
}

static size_t calib_req(uint8_t id, const uint8_t *payload, size_t n)
{
    uint8_t m[PROTO_MSG_MAX];
    m[0] = id;
    m[1] = ++next_seq;
    if (n > 0) {
        memcpy(m + 2, payload, n);
    }
    armed = true;
    out_len = calib_handle(m, n + 2, now_us, out, sizeof out);
    return out_len;
}

static void expect_reply(uint8_t id)
{
    msg();
    if (out[0] == PROTO_MSG_ERROR) {
        proto_error_t e;
        if (proto_error_decode(out + 2, out_len - 2, &e)) {
            snprintf(where + strlen(where), sizeof where - strlen(where), ": error code %u arg %u",
                     e.code, e.arg);
        }
    }
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(id, out[0], where);
}

static void enable(bool on)
{
    const uint8_t p[2] = {0x07, on ? 1u : 0u};
    unsigned k;
    request(PROTO_MSG_ENABLE, p, 2);
    /* busy while a disable is not yet applied: the host retries (out[3]:
     * the error's code, proto_error_t) */
    for (k = 0; k < 10u && out[0] == PROTO_MSG_ERROR && out[3] == PROTO_ERROR_CODE_BUSY; k++) {
        run(1);
        request(PROTO_MSG_ENABLE, p, 2);
    }
    expect_reply(PROTO_MSG_ACK);
}

static void queue_line(uint32_t seq, int64_t x)
{
    proto_queue_block_t q = {seq, PROTO_BLOCK_KIND_LINE, 0, FEED, {x, 0, 0, 0}};
    uint8_t p[64];
    request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, sizeof p));
    expect_reply(PROTO_MSG_QUEUE_REPLY);
}

/* A queue_batch of n lines of `step` nm along X from x (an origin record
 * first); the reply into *r. */
static void batch(uint32_t first, int64_t x, unsigned n, int64_t step, bool start,
                  proto_batch_reply_t *r)
{
    proto_queue_batch_t q;
    proto_batch_block_t b;
    int64_t pt[PROTO_MAX_AXES] = {x, 0, 0, 0};
    uint64_t feed = 0;
    uint8_t p[PROTO_MSG_MAX];
    unsigned i;

    memset(&b, 0, sizeof b);
    q.first_seq = first;
    q.count = (uint8_t)n;
    q.flags = start ? (uint8_t)(1u << PROTO_BATCH_FLAG_START) : 0u;
    q.data_len = 0;
    b.kind = PROTO_BATCH_KIND_LINE;
    b.feed = FEED;
    for (i = 0; i < n; i++) {
        size_t k;

        b.target[0] = x + (int64_t)(i + 1u) * step;
        k = proto_batch_put(q.data + q.data_len, sizeof q.data - q.data_len, &b, pt, &feed,
                            i == 0u);
        TEST_ASSERT_TRUE(k > 0u);
        q.data_len = (uint16_t)(q.data_len + k);
    }
    request(PROTO_MSG_QUEUE_BATCH, p, proto_queue_batch_encode(&q, p, sizeof p));
    expect_reply(PROTO_MSG_BATCH_REPLY);
    TEST_ASSERT_TRUE(proto_batch_reply_decode(out + 2, out_len - 2, r));
}

/* Run until the drive is in state `want` with blocks_done `done` (< 0: any). */
static drive_status_t wait_for(drive_state_t want, long done)
{
    drive_status_t st = status();
    unsigned k;
    for (k = 0; k < WAIT_TICKS; k++) {
        if (st.state == want && (done < 0 || st.blocks_done == (uint32_t)done)) {
            break;
        }
        run(1);
        st = status();
    }
    msg();
    snprintf(where + strlen(where), sizeof where - strlen(where),
             " (state %d faults 0x%x blocks_done %u ref %lld)", (int)st.state, st.faults,
             st.blocks_done, (long long)st.ref[0]);
    TEST_ASSERT_EQUAL_INT_MESSAGE(want, st.state, where);
    if (done >= 0) {
        TEST_ASSERT_EQUAL_UINT32_MESSAGE((uint32_t)done, st.blocks_done, where);
    }
    return st;
}

/* The job of one block to x runs: IDLE, blocks_done `done`, at x. */
static void job(uint32_t seq, int64_t x, uint32_t done)
{
    drive_status_t st;
    queue_line(seq, x);
    st = wait_for(DRIVE_IDLE, done);
    msg();
    TEST_ASSERT_EQUAL_INT64_MESSAGE(x, st.ref[0], where);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, st.faults, where);
}

static void calibrate(void)
{
    static const int64_t t[2] = {-200000, 200000};
    proto_calib_setup_t m;
    proto_calib_targets_t tg;
    proto_calib_state_t cs;
    uint8_t p[PROTO_CALIB_TARGETS_MAX_LEN];
    unsigned i, b, k;

    memset(&m, 0, sizeof m);
    m.axis = 1;
    m.points = 2;
    m.cycles = 1;
    m.samples = 5;
    m.sample_ticks = 1;
    m.dwell_ms = 2;
    m.overrun = 100000;
    m.feed = FEED;
    calib_req(PROTO_MSG_CALIB_SETUP, p, proto_calib_setup_encode(&m, p, sizeof p));
    expect_reply(PROTO_MSG_CALIB_STATE);
    tg.first = 0;
    tg.data_len = 16;
    for (i = 0; i < 2; i++) {
        for (b = 0; b < 8; b++) {
            tg.data[8 * i + b] = (uint8_t)((uint64_t)t[i] >> (8 * b));
        }
    }
    calib_req(PROTO_MSG_CALIB_TARGETS, p, proto_calib_targets_encode(&tg, p, sizeof p));
    expect_reply(PROTO_MSG_CALIB_STATE);
    calib_req(PROTO_MSG_CALIB_START, NULL, 0);
    expect_reply(PROTO_MSG_CALIB_STATE);
    for (k = 0; k < WAIT_TICKS && calib_state() == CALIB_RUNNING; k++) {
        run(1);
    }
    msg();
    TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_DONE, calib_state(), where);
    calib_req(PROTO_MSG_CALIB_STATUS, NULL, 0);
    expect_reply(PROTO_MSG_CALIB_STATE);
    TEST_ASSERT_TRUE(proto_calib_state_decode(out + 2, out_len - 2, &cs));
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(4u * 5u, cs.seq_next, where);
}

/* Home X (switch at -21.3 mm, index at -20 mm: the simulator's defaults)
 * to -21 mm; the drive is HOMING at once (main's view). */
static void home_x(void)
{
    proto_home_t h = {1u, 1u, 1u, 50000000u, 10000000u, 100000000u, {-21000000, 0, 0, 0}};
    uint8_t p[64];
    request(PROTO_MSG_HOME, p, proto_home_encode(&h, p, sizeof p));
    expect_reply(PROTO_MSG_ACK);
    msg();
    TEST_ASSERT_EQUAL_INT_MESSAGE(DRIVE_HOMING, status().state, where);
}

static void scenario(void)
{
    proto_identity_t id = {0x000100u, 0xABCDu, 7u, 10000u, 1u, 0u, 5u, 3u};
    proto_param_set_t ps = {PROTO_PARAM_STOP_DECELERATION, 2000000000};
    uint8_t p[16];
    drive_status_t st;
    int64_t stop_at;

    fired = 0;
    now_us = 0;
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    armed = true; /* sim_start sets the CEC mode after drive_init */
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_TRUE(proto_dispatch_init(&d, &id, now_us));
    calib_set_next_handler(NULL);
    /* no link watchdog: a job that hangs shows as hanging, not as a
     * watchdog stop (its points are passed all the same) */
    ps.param = PROTO_PARAM_COMM_TIMEOUT_MS;
    ps.value = 0;
    request(PROTO_MSG_PARAM_SET, p, proto_param_set_encode(&ps, p, sizeof p));
    expect_reply(PROTO_MSG_PARAM_VALUE);
    ps.param = PROTO_PARAM_STOP_DECELERATION;
    ps.value = 2000000000;

    phase = "A enable + queue in one batch";
    enable(true);
    queue_line(1, 200000);
    queue_line(2, 400000);
    st = wait_for(DRIVE_IDLE, 2);
    msg();
    TEST_ASSERT_EQUAL_INT64_MESSAGE(400000, st.ref[0], where);

    phase = "B stop mid-move, then a new job";
    queue_line(3, 5000000);
    run(800);
    request(PROTO_MSG_STOP, NULL, 0);
    expect_reply(PROTO_MSG_ACK);
    st = wait_for(DRIVE_IDLE, 2);
    stop_at = st.ref[0];
    msg();
    TEST_ASSERT_TRUE_MESSAGE(stop_at > 400000 && stop_at < 5000000, where);
    job(4, 600000, 3);

    phase = "C disable, enable + queue";
    enable(false);
    (void)wait_for(DRIVE_DISABLED, 3);
    enable(true);
    job(5, 800000, 4);

    phase = "D estop, fault reset, enable + queue";
    request(PROTO_MSG_ESTOP, NULL, 0);
    expect_reply(PROTO_MSG_ACK);
    (void)wait_for(DRIVE_FAULT, -1);
    request(PROTO_MSG_FAULT_RESET, NULL, 0);
    expect_reply(PROTO_MSG_ACK);
    (void)wait_for(DRIVE_DISABLED, -1);
    enable(true);
    job(6, 1000000, 5);

    phase = "E parameter set while idle";
    request(PROTO_MSG_PARAM_SET, p, proto_param_set_encode(&ps, p, sizeof p));
    expect_reply(PROTO_MSG_PARAM_VALUE);
    msg();
    TEST_ASSERT_EQUAL_INT64_MESSAGE(2000000000, drive_config()->stop_decel_nm_s2, where);
    job(7, 1200000, 6);

    phase = "F stop right after a block, a block right after the stop";
    queue_line(8, 3000000);
    request(PROTO_MSG_STOP, NULL, 0);
    expect_reply(PROTO_MSG_ACK);
    {
        /* refused while the stop is pending or running (it would drop it) */
        proto_queue_block_t q = {9, PROTO_BLOCK_KIND_LINE, 0, FEED, {1400000, 0, 0, 0}};
        uint8_t qb[64];
        request(PROTO_MSG_QUEUE_BLOCK, qb, proto_queue_block_encode(&q, qb, sizeof qb));
        expect_reply(PROTO_MSG_ERROR);
        msg();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(PROTO_ERROR_CODE_BUSY, out[3], where);
    }
    st = wait_for(DRIVE_IDLE, -1);
    msg();
    TEST_ASSERT_TRUE_MESSAGE(st.blocks_done <= 7u, where);
    job(10, 1400000, st.blocks_done + 1u);

    phase = "G calibration run";
    calibrate();
    st = wait_for(DRIVE_IDLE, -1);
    msg();
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, st.faults, where);

    phase = "H homing stopped, homing, then a job in the new frame";
    home_x();
    run(500);
    request(PROTO_MSG_STOP, NULL, 0);
    expect_reply(PROTO_MSG_ACK);
    st = wait_for(DRIVE_IDLE, -1);
    msg();
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, st.homed, where);
    home_x();
    st = wait_for(DRIVE_IDLE, -1);
    msg();
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, st.faults, where);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(1u, st.homed, where);
    /* the index at -20 mm reads -21 mm now (the drive started in the
     * table's frame) */
    TEST_ASSERT_INT64_WITHIN_MESSAGE(1250, -1000000, st.home_shift[0], where);
    job(30, -15000000, st.blocks_done + 1u);

    phase = "I a job of three batches through the intake ring";
    {
        proto_batch_reply_t r;
        uint32_t done0 = st.blocks_done + 1u;
        unsigned i;

        for (i = 0; i < 3u; i++) {
            batch(100u + 50u * i, -15000000 + 500000 * (int64_t)i, 50, 10000, i == 0u, &r);
            msg();
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(50, r.accepted, where);
            TEST_ASSERT_EQUAL_UINT32_MESSAGE(150u + 50u * i, r.next_seq, where);
        }
        st = wait_for(DRIVE_IDLE, (long)(done0 + 150u));
        msg();
        TEST_ASSERT_EQUAL_INT64_MESSAGE(-13500000, st.ref[0], where);
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(249u, st.tag, where);

        phase = "J stop with blocks in the intake ring";
        batch(300u, -13500000, 50, 10000, true, &r);
        batch(350u, -13000000, 50, 10000, false, &r);
        msg();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(50, r.accepted, where);
        TEST_ASSERT_TRUE_MESSAGE(d.batch.used > 0u, where); /* the ring holds some */
        run(20);
        request(PROTO_MSG_STOP, NULL, 0);
        expect_reply(PROTO_MSG_ACK);
        /* to rest without a link poll: the ring must not wait for the
         * pump to find the drive stopping */
        for (i = 0; i < WAIT_TICKS && status().state != DRIVE_IDLE; i++) {
            TEST_ASSERT_TRUE(sim_run(1, NULL, 0, 0) >= 0);
            now_us += 100u;
        }
        run(2000); /* nothing left to run */
        st = wait_for(DRIVE_IDLE, (long)st.blocks_done);
        msg();
        TEST_ASSERT_TRUE_MESSAGE(st.blocks_done < done0 + 250u, where);
        TEST_ASSERT_TRUE_MESSAGE(st.ref[0] < -12500000, where);
        batch(400u, -12500000, 1, 10000, false, &r);
        msg();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(0, r.accepted, where);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(PROTO_ERROR_CODE_BUSY, r.status, where);
        batch(500u, st.ref[0], 2, 10000, true, &r);
        msg();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(2, r.accepted, where);
        st = wait_for(DRIVE_IDLE, (long)(st.blocks_done + 2u));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(501u, st.tag, where);
    }
}

void setUp(void)
{
    preempt_hook = hook;
}

void tearDown(void)
{
    preempt_hook = NULL;
    target = NULL;
}

static unsigned points_in(const char *file)
{
    unsigned i, n = 0;
    for (i = 0; i < npts; i++) {
        n += strstr(pts[i].file, file) != NULL;
    }
    return n;
}

/* The scenario passes the points of every main-context module (a point
 * that no phase reaches would go untested). */
static void test_scenario_reaches_the_points_of_every_module(void)
{
    recording = true;
    npts = 0;
    target = NULL;
    scenario();
    recording = false;
    printf("preempt: %u points: drive.c %u, drive_req.c %u, feed.c %u, proto_dispatch.c %u, "
           "calib.c %u, proto_batch.c %u\n",
           npts, points_in("drive.c"), points_in("drive_req.c"), points_in("feed.c"),
           points_in("proto_dispatch.c"), points_in("calib.c"), points_in("proto_batch.c"));
    TEST_ASSERT_TRUE(points_in("drive.c") + points_in("drive_req.c") >= 10u);
    TEST_ASSERT_TRUE(points_in("drive_req.c") >= 3u);
    TEST_ASSERT_TRUE(points_in("feed.c") >= 3u);
    TEST_ASSERT_TRUE(points_in("proto_dispatch.c") >= 3u);
    TEST_ASSERT_TRUE(points_in("calib.c") >= 4u);
    TEST_ASSERT_TRUE(points_in("proto_batch.c") >= 2u);
}

/* The scenario's invariants hold with the tick run at each point. */
static void test_tick_at_every_point(void)
{
    static unsigned i, bad; /* static: kept across a failure's longjmp */
    bad = 0;
    if (npts == 0u) {
        recording = true;
        scenario();
        recording = false;
    }
    for (i = 0; i < npts; i++) {
        target = &pts[i];
        /* every failing point is reported (a failure returns here) */
        if (TEST_PROTECT()) {
            scenario();
            msg();
            TEST_ASSERT_TRUE_MESSAGE(fired > 0u, where);
        } else {
            bad++;
            printf("preempt: failed with the %s\n", where);
            Unity.CurrentTestFailed = 0; /* go on with the next point */
        }
    }
    target = NULL;
    printf("preempt: %u points, each run with a tick there; %u failed\n", npts, bad);
    /* a new frame: the runner's was replaced by the loop's TEST_PROTECT */
    if (TEST_PROTECT()) {
        TEST_ASSERT_EQUAL_UINT_MESSAGE(0, bad, "points where a tick breaks the scenario");
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_scenario_reaches_the_points_of_every_module);
    RUN_TEST(test_tick_at_every_point);
    return UNITY_END();
}
