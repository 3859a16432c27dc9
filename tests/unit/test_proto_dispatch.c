/* Dispatcher against the real drive inside the simulator: identify, typed
 * parameters with range checks (nothing half applied), every refusal code,
 * the replay cache, queued motion with flow control, cyclic telemetry with
 * consecutive sequence numbers, and the communication watchdog's
 * controlled stop. */
#include <string.h>

#include "drive.h"
#include "hal_sim.h"
#include "proto_dispatch.h"
#include "sim.h"
#include "unity.h"
#include "dispatch_fixture.h"

static void start(void)
{
    dispatch_fixture_start();
}

void setUp(void)
{
    start();
}

void tearDown(void)
{
}

/* Advance the simulator (and the dispatcher's clock) by ms milliseconds. */
static void run_ms(unsigned ms)
{
    TEST_ASSERT_TRUE(sim_run((uint64_t)ms * 10u, NULL, 0, 0) >= 0);
    now_us += ms * 1000u;
}

static size_t set_param(uint16_t pid, int64_t v)
{
    proto_param_set_t s = {pid, v};
    uint8_t p[16];

    return request(PROTO_MSG_PARAM_SET, p, proto_param_set_encode(&s, p, sizeof p));
}

static int64_t get_param(uint16_t pid)
{
    proto_param_get_t g = {pid};
    proto_param_value_t v;
    uint8_t p[4];
    size_t n = request(PROTO_MSG_PARAM_GET, p, proto_param_get_encode(&g, p, sizeof p));

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, out[0]);
    TEST_ASSERT_TRUE(proto_param_value_decode(out + 2, n - 2, &v));
    return v.value;
}

static proto_drive_state_t state(void)
{
    proto_drive_state_t s;
    size_t n = request(PROTO_MSG_STATUS_GET, NULL, 0);

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_DRIVE_STATE, out[0]);
    TEST_ASSERT_TRUE(proto_drive_state_decode(out + 2, n - 2, &s));
    return s;
}

static size_t queue_line(uint32_t seq, int64_t x, uint32_t feed)
{
    proto_queue_block_t q = {seq, PROTO_BLOCK_KIND_LINE, 0, feed, {x, 0, 0, 0}};
    uint8_t p[64];

    return request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, sizeof p));
}

static void enable(void)
{
    const uint8_t p[2] = {0x07, 1};

    TEST_ASSERT_TRUE(request(PROTO_MSG_ENABLE, p, 2) > 0);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, out[0]);
    run_ms(1); /* the tick applies it and publishes the status */
}

static void test_identify_reports_the_identity(void)
{
    proto_identify_reply_t r;
    size_t n = request(PROTO_MSG_IDENTIFY, NULL, 0);

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_IDENTIFY_REPLY, out[0]);
    TEST_ASSERT_EQUAL_UINT8(next_seq, out[1]);
    TEST_ASSERT_TRUE(proto_identify_reply_decode(out + 2, n - 2, &r));
    TEST_ASSERT_EQUAL_UINT16(PROTO_VERSION, r.protocol_version);
    TEST_ASSERT_EQUAL_UINT8(5, r.node_id);
    TEST_ASSERT_EQUAL_UINT8(3, r.axes);
    TEST_ASSERT_EQUAL_HEX32(0xABCDu, r.build_id);
    TEST_ASSERT_TRUE(r.planner_slots >= 2); /* read from the drive */
}

static void test_parameters_are_range_checked_and_never_half_applied(void)
{
    proto_error_t e;

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_COMM_TIMEOUT_MS, 250), out[0]));
    TEST_ASSERT_EQUAL_INT64(250, get_param(PROTO_PARAM_COMM_TIMEOUT_MS));
    e = expect_error(set_param(PROTO_PARAM_COMM_TIMEOUT_MS, 60001), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_INT64(0, e.lo);
    TEST_ASSERT_EQUAL_INT64(60000, e.hi);
    TEST_ASSERT_EQUAL_UINT16(PROTO_PARAM_COMM_TIMEOUT_MS, e.arg);
    expect_error(set_param(PROTO_PARAM_COMM_TIMEOUT_MS, -1), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_INT64(250, get_param(PROTO_PARAM_COMM_TIMEOUT_MS));
    expect_error(set_param(PROTO_PARAM_NODE_ID, 3), PROTO_ERROR_CODE_READ_ONLY);
    expect_error(set_param(0x7777, 3), PROTO_ERROR_CODE_UNKNOWN_PARAM);
    expect_error(set_param(PROTO_PARAM_CEC_MODE, 7), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_INT64(0, get_param(PROTO_PARAM_CEC_MODE));
    /* the history-only and second-order estimates are reachable over the link */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_CEC_MODE, 6), out[0]));
    TEST_ASSERT_EQUAL_INT64(6, get_param(PROTO_PARAM_CEC_MODE));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_CEC_MODE, 0), out[0]));
    TEST_ASSERT_EQUAL_INT64(3, get_param(PROTO_PARAM_AXES));
    {
        proto_param_get_t g = {PROTO_PARAM_POSITION + 3}; /* axis 3 of 3 */
        uint8_t p[4];

        expect_error(request(PROTO_MSG_PARAM_GET, p, proto_param_get_encode(&g, p, 4)),
                     PROTO_ERROR_CODE_BAD_AXIS);
    }
}

static void test_unknown_short_and_wrong_length_messages(void)
{
    const uint8_t junk[3] = {1, 2, 3};
    uint8_t m[2] = {PROTO_MSG_IDENTIFY, 0};
    proto_error_t e;

    expect_error(request(0xEE, NULL, 0), PROTO_ERROR_CODE_UNKNOWN_MESSAGE);
    expect_error(request(PROTO_MSG_IDENTIFY_REPLY, NULL, 0), PROTO_ERROR_CODE_UNKNOWN_MESSAGE);
    e = expect_error(request(PROTO_MSG_PARAM_GET, junk, 3), PROTO_ERROR_CODE_BAD_LENGTH);
    TEST_ASSERT_EQUAL_INT64(2, e.lo);
    TEST_ASSERT_EQUAL_INT64(2, e.hi);
    TEST_ASSERT_EQUAL_size_t(0, proto_dispatch_handle(&d, m, 1, now_us, out, sizeof out));
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.ignored);
    TEST_ASSERT_EQUAL_UINT32(2, d.stats.unknown);
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.bad_length);
}

static void test_replayed_request_is_answered_not_executed(void)
{
    uint8_t m[64];
    uint8_t first[PROTO_MSG_MAX];
    proto_queue_block_t q = {9, PROTO_BLOCK_KIND_LINE, 0, 5000000, {1000000, 0, 0, 0}};
    size_t n, r1, r2;
    proto_drive_state_t s;

    enable();
    m[0] = PROTO_MSG_QUEUE_BLOCK;
    m[1] = 200;
    n = 2 + proto_queue_block_encode(&q, m + 2, sizeof m - 2);
    r1 = proto_dispatch_handle(&d, m, n, now_us, first, sizeof first);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, first[0]);
    r2 = proto_dispatch_handle(&d, m, n, now_us, out, sizeof out);
    TEST_ASSERT_EQUAL_size_t(r1, r2);
    TEST_ASSERT_EQUAL_MEMORY(first, out, r1);
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.replayed);
    s = state();
    /* the block is planned at once (1 mm at 5 mm/s: about 0.2 s queued) */
    TEST_ASSERT_TRUE(s.queued_us > 150000 && s.queued_us < 300000);
    /* exactly one block went into the planner */
    run_ms(2000);
    s = state();
    TEST_ASSERT_EQUAL_UINT32(1, s.blocks_done);
    TEST_ASSERT_EQUAL_UINT32(9, s.last_block_seq);
}

/* A new host session whose first request repeats the last (id, seq) with
 * another payload is a new request: executed, not answered from the cache
 * (keying on (id, seq) alone once moved an axis the wrong way). */
static void test_same_id_and_seq_with_another_payload_is_executed(void)
{
    uint8_t m[64];
    proto_queue_block_t q1 = {9, PROTO_BLOCK_KIND_LINE, 0, 5000000, {1000000, 0, 0, 0}};
    proto_queue_block_t q2 = {10, PROTO_BLOCK_KIND_LINE, 0, 5000000, {2000000, 0, 0, 0}};
    proto_queue_reply_t r;
    proto_drive_state_t s;
    size_t n, rl;

    enable();
    m[0] = PROTO_MSG_QUEUE_BLOCK;
    m[1] = 77;
    n = 2 + proto_queue_block_encode(&q1, m + 2, sizeof m - 2);
    TEST_ASSERT_TRUE(proto_dispatch_handle(&d, m, n, now_us, out, sizeof out) > 0);
    /* the next session starts its seq where the last one stopped */
    n = 2 + proto_queue_block_encode(&q2, m + 2, sizeof m - 2);
    rl = proto_dispatch_handle(&d, m, n, now_us, out, sizeof out);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, out[0]);
    TEST_ASSERT_TRUE(proto_queue_reply_decode(out + 2, rl - 2, &r));
    TEST_ASSERT_EQUAL_UINT32(10, r.block_seq);
    TEST_ASSERT_EQUAL_UINT32(0, d.stats.replayed);
    run_ms(3000);
    s = state();
    TEST_ASSERT_EQUAL_UINT32(2, s.blocks_done);
    TEST_ASSERT_EQUAL_UINT32(10, s.last_block_seq);
}

static void test_blocks_are_checked_before_queueing(void)
{
    proto_queue_block_t q = {1, PROTO_BLOCK_KIND_LINE, 0, 0, {1000, 0, 0, 0}};
    uint8_t p[64];
    proto_error_t e;

    expect_error(queue_line(1, 1000, 1000000), PROTO_ERROR_CODE_DISABLED);
    enable();
    e = expect_error(request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, 64)),
                     PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(3, e.arg); /* feed */
    q.feed = 1000;
    q.kind = 9;
    expect_error(request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, 64)),
                 PROTO_ERROR_CODE_BAD_VALUE);
    q.kind = PROTO_BLOCK_KIND_LINE;
    q.target[3] = 5; /* the fourth axis does not exist */
    e = expect_error(request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, 64)),
                     PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(7, e.arg);
    q.target[3] = 0;
    q.target[1] = PROTO_POS_LIMIT_NM + 1;
    expect_error(request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, 64)),
                 PROTO_ERROR_CODE_OUT_OF_RANGE);
    q.flags = 0x80;
    expect_error(request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, 64)),
                 PROTO_ERROR_CODE_BAD_VALUE);
    TEST_ASSERT_EQUAL_UINT32(0, state().blocks_done);
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_READY, state().state);
}

static void test_queue_full_is_a_specific_refusal(void)
{
    proto_queue_reply_t q;
    uint32_t i;
    uint32_t last_free = 0xFFFFu;
    size_t n = 0;

    enable();
    for (i = 0; i < 1000; i++) {
        n = queue_line(i, (int64_t)(i + 1) * 1000000, 1000000);
        if (out[0] != PROTO_MSG_QUEUE_REPLY) {
            break;
        }
        TEST_ASSERT_TRUE(proto_queue_reply_decode(out + PROTO_MSG_HDR, n - PROTO_MSG_HDR, &q));
        TEST_ASSERT_EQUAL_UINT32(i, q.block_seq);
        TEST_ASSERT_TRUE(q.free_slots <= last_free); /* no tick: nothing frees a slot */
        last_free = q.free_slots;
    }
    TEST_ASSERT_TRUE(i > 1 && i < 1000);
    /* refused exactly when the last accepted block reported no free slot (the
     * planner's ring fills first, then the host-block queue) */
    TEST_ASSERT_EQUAL_UINT32(0, last_free);
    expect_error(n, PROTO_ERROR_CODE_QUEUE_FULL);
}

static struct {
    unsigned n;
    uint8_t ids[64];
    uint16_t seqs[64];
} em;

static bool capture(void *ctx, const uint8_t *msg, size_t len, uint8_t can_func)
{
    (void)ctx;
    (void)can_func;
    if (em.n < 64 && len >= 4) {
        em.ids[em.n] = msg[0];
        em.seqs[em.n] = (uint16_t)(msg[2] | (msg[3] << 8));
        em.n++;
    }
    return true;
}

static void test_telemetry_cycles_share_one_consecutive_seq(void)
{
    unsigned i;

    memset(&em, 0, sizeof em);
    set_param(PROTO_PARAM_TELEM_PERIOD_MS, 10);
    proto_dispatch_poll(&d, now_us, capture, NULL);
    TEST_ASSERT_EQUAL_UINT(0, em.n);
    run_ms(10);
    proto_dispatch_poll(&d, now_us, capture, NULL);
    run_ms(10);
    proto_dispatch_poll(&d, now_us, capture, NULL);
    TEST_ASSERT_EQUAL_UINT(2 * (3 + 2 * 3), em.n); /* status, progress, path, 3 pos, 3 ferr */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_STATUS, em.ids[0]);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_STATUS, em.ids[9]);
    for (i = 0; i < 9; i++) {
        TEST_ASSERT_EQUAL_UINT16(em.seqs[0], em.seqs[i]);
        TEST_ASSERT_EQUAL_UINT16(em.seqs[0] + 1u, em.seqs[9 + i]);
    }
    /* heartbeat only where the link asks for it */
    d.heartbeat_on = true;
    em.n = 0;
    set_param(PROTO_PARAM_TELEM_PERIOD_MS, 0);
    run_ms(1000);
    proto_dispatch_poll(&d, now_us, capture, NULL);
    TEST_ASSERT_EQUAL_UINT(1, em.n);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_HEARTBEAT, em.ids[0]);
}

static void test_watchdog_stops_in_a_controlled_way(void)
{
    proto_drive_state_t s;
    unsigned ms;

    memset(&em, 0, sizeof em);
    set_param(PROTO_PARAM_COMM_TIMEOUT_MS, 100);
    enable();
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (queue_line(1, 50000000, 20000000), out[0]));
    for (ms = 0; ms < 90; ms += 10) { /* host alive: keeps running */
        run_ms(10);
        (void)state();
        proto_dispatch_poll(&d, now_us, capture, NULL);
    }
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_RUNNING, state().state);
    for (ms = 0; ms < 99; ms += 1) { /* silent, but not yet for 100 ms */
        run_ms(1);
        proto_dispatch_poll(&d, now_us, capture, NULL);
    }
    TEST_ASSERT_EQUAL_UINT32(0, d.stats.watchdog_stops);
    for (ms = 0; ms < 3000; ms += 1) {
        run_ms(1);
        proto_dispatch_poll(&d, now_us, capture, NULL);
    }
    TEST_ASSERT_EQUAL_UINT32(1, d.stats.watchdog_stops);
    s = state();
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_FAULT, s.state);
    TEST_ASSERT_EQUAL_HEX16(1u << PROTO_FAULT_COMM_TIMEOUT, s.faults);
    TEST_ASSERT_TRUE(s.pos[0] > 100000 && s.pos[0] < 45000000);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, (request(PROTO_MSG_FAULT_RESET, NULL, 0), out[0]));
    run_ms(1);
    TEST_ASSERT_EQUAL_HEX16(0, state().faults);
}

static void test_watchdog_leaves_an_idle_drive_alone(void)
{
    set_param(PROTO_PARAM_COMM_TIMEOUT_MS, 50);
    enable();
    run_ms(1000);
    proto_dispatch_poll(&d, now_us, capture, NULL);
    TEST_ASSERT_EQUAL_UINT32(0, d.stats.watchdog_stops);
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_READY, state().state);
}

/* Enable and queue in one batch (no tick between them): the block runs. */
static void test_enable_and_queue_in_one_batch_runs_the_block(void)
{
    const uint8_t on[2] = {0x07, 1};
    proto_queue_reply_t q;
    proto_drive_state_t s;
    size_t n;

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, (request(PROTO_MSG_ENABLE, on, 2), out[0]));
    n = queue_line(5, 2000000, 20000000);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, out[0]);
    TEST_ASSERT_TRUE(proto_queue_reply_decode(out + 2, n - 2, &q));
    TEST_ASSERT_EQUAL_UINT32(5, q.block_seq);
    run_ms(2000);
    s = state();
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_READY, s.state);
    TEST_ASSERT_EQUAL_UINT32(1, s.blocks_done);
    TEST_ASSERT_EQUAL_UINT32(5, s.last_block_seq);
    TEST_ASSERT_INT64_WITHIN(5000, 2000000, s.pos[0]);
}

/* Flow control by time: the planned time queued is reported, and it falls
 * as the job runs. The job starts once no block came for the start delay
 * (50 ms: with the continuous S-curve the oldest block's plan depends on
 * the blocks after it, drive.h "Feeding"); the queued time stays until
 * then. */
static void test_queued_time_is_reported(void)
{
    proto_queue_reply_t q;
    proto_drive_state_t s0, s1, s2;
    size_t n;

    enable();
    queue_line(1, 1000000, 10000000); /* ~0.1 s */
    n = queue_line(2, 3000000, 10000000);
    TEST_ASSERT_TRUE(proto_queue_reply_decode(out + 2, n - 2, &q));
    run_ms(1);
    s0 = state();
    TEST_ASSERT_TRUE(s0.queued_us > 250000 && s0.queued_us < 400000);
    run_ms(59);
    s1 = state(); /* moving since the start delay */
    TEST_ASSERT_TRUE(s1.queued_us < s0.queued_us - 1000 && s1.queued_us > s0.queued_us - 20000);
    run_ms(100);
    s2 = state();
    TEST_ASSERT_UINT32_WITHIN(1000, s1.queued_us - 100000, s2.queued_us);
    run_ms(1000);
    TEST_ASSERT_EQUAL_UINT32(0, state().queued_us);
}

static proto_error_t set_param_error(uint16_t pid, int64_t v, uint8_t code)
{
    return expect_error(set_param(pid, v), code);
}

static void test_planner_parameters_over_the_link(void)
{
    proto_error_t e;

    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(PROTO_PARAM_MAX_VELOCITY + 1));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_MAX_VELOCITY + 1, 250000000), out[0]));
    TEST_ASSERT_EQUAL_INT64(250000000, get_param(PROTO_PARAM_MAX_VELOCITY + 1));
    TEST_ASSERT_EQUAL_INT64(250000000, drive_config()->plan.v_max[1]);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(PROTO_PARAM_MAX_VELOCITY + 0));
    /* the table's range, then the drive's: jerk too small for the
     * acceleration (a / j <= 3 s) */
    e = set_param_error(PROTO_PARAM_MAX_VELOCITY, 999, PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_INT64(1000, e.lo);
    e = set_param_error(PROTO_PARAM_MAX_JERK + 2, 1000000000, PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(PROTO_PARAM_MAX_JERK + 2, e.arg);
    TEST_ASSERT_EQUAL_INT64(3333333334, e.lo);
    expect_error(set_param(PROTO_PARAM_MAX_VELOCITY + 3, 5000000), PROTO_ERROR_CODE_BAD_AXIS);
    expect_error(set_param(PROTO_PARAM_CORNER_RULE, 4), PROTO_ERROR_CODE_OUT_OF_RANGE);
    /* the smoothed corner is refused with the default continuous S-curve
     * (its cap would cut a run under way), taken with the per-block one */
    TEST_ASSERT_EQUAL_INT64(3, get_param(PROTO_PARAM_VELOCITY_PROFILE));
    set_param_error(PROTO_PARAM_CORNER_RULE, 2, PROTO_ERROR_CODE_BAD_VALUE);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_VELOCITY_PROFILE, 0), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_CORNER_RULE, 2), out[0]));
    TEST_ASSERT_EQUAL_INT64(2, get_param(PROTO_PARAM_CORNER_RULE));
    /* trapezoid, a high acceleration, then back to the S-curve: bad_value */
    set_param(PROTO_PARAM_VELOCITY_PROFILE, 1);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_MAX_ACCELERATION, 900000000000), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_MAX_JERK, 100000000000), out[0]));
    set_param_error(PROTO_PARAM_VELOCITY_PROFILE, 0, PROTO_ERROR_CODE_BAD_VALUE);
    TEST_ASSERT_EQUAL_INT64(1, get_param(PROTO_PARAM_VELOCITY_PROFILE));
    /* busy while a block is queued or executing; nothing changed */
    enable();
    queue_line(1, 5000000, 10000000);
    set_param_error(PROTO_PARAM_MAX_VELOCITY, 5000000, PROTO_ERROR_CODE_BUSY);
    set_param_error(PROTO_PARAM_STOP_DECELERATION, 5000000, PROTO_ERROR_CODE_BUSY);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(PROTO_PARAM_MAX_VELOCITY));
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(PROTO_PARAM_STOP_DECELERATION));
}

/* encoder_mean (drive.h enc_mean): taken on a port that measures the mean
 * (the simulator), refused as not_supported on one that cannot, never
 * ignored: the value stays 0. */
static void test_encoder_mean_is_refused_by_a_port_without_it(void)
{
    TEST_ASSERT_EQUAL_INT64(0, get_param(PROTO_PARAM_ENCODER_MEAN));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_ENCODER_MEAN, 1), out[0]));
    TEST_ASSERT_EQUAL_INT64(1, get_param(PROTO_PARAM_ENCODER_MEAN));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_ENCODER_MEAN, 0), out[0]));
    hal_sim_set_mean_port(false);
    set_param_error(PROTO_PARAM_ENCODER_MEAN, 1, PROTO_ERROR_CODE_NOT_SUPPORTED);
    TEST_ASSERT_EQUAL_INT64(0, get_param(PROTO_PARAM_ENCODER_MEAN));
    TEST_ASSERT_FALSE(drive_config()->enc_mean);
}

static size_t jog(uint8_t axis, int64_t dist, uint32_t feed)
{
    proto_jog_t j = {axis, feed, dist};
    uint8_t p[16];

    return request(PROTO_MSG_JOG, p, proto_jog_encode(&j, p, sizeof p));
}

/* Gains, feed-forward and the following-error limit reach the servo through
 * the tick's gains request: a 1 um limit trips on a jog that the default
 * 5 mm limit lets run; zero gains leave the axis where it was. */
static void test_servo_parameters_reach_the_servo(void)
{
    proto_error_t e;
    proto_drive_state_t s;

    TEST_ASSERT_EQUAL_INT64(5000000, get_param(PROTO_PARAM_FOLLOWING_ERROR_LIMIT + 0));
    TEST_ASSERT_EQUAL_INT64(drive_config()->servo.axis[1].kp, get_param(PROTO_PARAM_PID_KP + 1));
    e = set_param_error(PROTO_PARAM_PID_KP, -1, PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_INT64(0, e.lo);
    TEST_ASSERT_EQUAL_INT64(((int64_t)1 << 62) - 1, e.hi);
    set_param_error(PROTO_PARAM_FOLLOWING_ERROR_LIMIT, (int64_t)1 << 31,
                    PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_VELOCITY_FEEDFORWARD + 2, 12345), out[0]));
    TEST_ASSERT_EQUAL_INT64(12345, drive_config()->servo.axis[2].kvff);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_FOLLOWING_ERROR_LIMIT + 0, 1000), out[0]));
    TEST_ASSERT_EQUAL_INT64(1000, get_param(PROTO_PARAM_FOLLOWING_ERROR_LIMIT + 0));
    enable();
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(0, 2000000, 50000000), out[0]));
    run_ms(200);
    s = state();
    TEST_ASSERT_TRUE((s.faults & (1u << PROTO_FAULT_FOLLOWING_ERROR)) != 0u);

    /* zero gains on Y: it does not follow a jog */
    start();
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_PID_KP + 1, 0), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_PID_KI + 1, 0), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, (set_param(PROTO_PARAM_PID_KD + 1, 0), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_VELOCITY_FEEDFORWARD + 1, 0), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_ACCELERATION_FEEDFORWARD + 1, 0), out[0]));
    enable();
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(1, 10000000, 10000000), out[0]));
    run_ms(100);
    TEST_ASSERT_INT64_WITHIN(1000, 0, get_param(PROTO_PARAM_POSITION + 1));
    /* busy while moving */
    set_param_error(PROTO_PARAM_PID_KP + 1, 1, PROTO_ERROR_CODE_BUSY);
}

/* Soft travel limits: off at 0 / 0; a jog or block ending outside is
 * refused with out_of_range and the limits before anything moves; an
 * axis that does not move is not checked. */
static void test_soft_limits_refuse_before_motion(void)
{
    proto_error_t e;

    TEST_ASSERT_EQUAL_INT64(5000, get_param(PROTO_PARAM_IN_POSITION_WINDOW + 2));
    set_param_error(PROTO_PARAM_IN_POSITION_WINDOW, 0, PROTO_ERROR_CODE_OUT_OF_RANGE);
    enable();
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(0, 3000000, 50000000), out[0]));
    run_ms(400);
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_READY, state().state);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_SOFT_LIMIT_MIN + 0, -1000000), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_SOFT_LIMIT_MAX + 0, 4000000), out[0]));
    /* X at 3 mm: +2 mm ends at 5 mm, outside */
    e = expect_error(jog(0, 2000000, 50000000), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(2, e.arg);
    TEST_ASSERT_EQUAL_INT64(-1000000, e.lo);
    TEST_ASSERT_EQUAL_INT64(4000000, e.hi);
    e = expect_error(queue_line(7, -2000000, 50000000), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(4, e.arg);
    run_ms(50);
    TEST_ASSERT_EQUAL_UINT8(PROTO_STATE_READY, state().state);
    TEST_ASSERT_INT64_WITHIN(100000, 3000000, get_param(PROTO_PARAM_POSITION + 0));
    /* inside: accepted; Y has no limits */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(0, 500000, 50000000), out[0]));
    run_ms(200);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(1, 9000000, 50000000), out[0]));
    run_ms(500);
    /* an arc whose end point is inside but whose bulge is not: Y from y0
     * to y0 over (X+10 mm, centre X+5 mm): counter-clockwise passes
     * y0 - 5 mm (refused, Y limits y0 - 1 .. y0 + 10 mm), clockwise
     * y0 + 5 mm */
    {
        drive_status_t st;
        proto_queue_arc_t q = {8, 0, 0, 1, 20000000, {0, 0, 0, 0}, 0, 0};
        uint8_t p[80];

        drive_status(&st);
        TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                               (set_param(PROTO_PARAM_SOFT_LIMIT_MAX + 0, 100000000), out[0]));
        TEST_ASSERT_EQUAL_HEX8(
            PROTO_MSG_PARAM_VALUE,
            (set_param(PROTO_PARAM_SOFT_LIMIT_MIN + 1, st.ref[1] - 1000000), out[0]));
        TEST_ASSERT_EQUAL_HEX8(
            PROTO_MSG_PARAM_VALUE,
            (set_param(PROTO_PARAM_SOFT_LIMIT_MAX + 1, st.ref[1] + 10000000), out[0]));
        q.target[0] = st.ref[0] + 10000000;
        q.target[1] = st.ref[1];
        q.centre_u = st.ref[0] + 5000000;
        q.centre_v = st.ref[1];
        e = expect_error(request(PROTO_MSG_QUEUE_ARC, p, proto_queue_arc_encode(&q, p, sizeof p)),
                         PROTO_ERROR_CODE_OUT_OF_RANGE);
        TEST_ASSERT_EQUAL_UINT16(5 + 1, e.arg);
        TEST_ASSERT_EQUAL_INT64(st.ref[1] - 1000000, e.lo);
        q.sense = -1;
        TEST_ASSERT_EQUAL_HEX8(
            PROTO_MSG_QUEUE_REPLY,
            (request(PROTO_MSG_QUEUE_ARC, p, proto_queue_arc_encode(&q, p, sizeof p)), out[0]));
        run_ms(2000);
    }
    /* off again: min >= max */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_SOFT_LIMIT_MAX + 0, 4000000), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE,
                           (set_param(PROTO_PARAM_SOFT_LIMIT_MAX + 0, -1000000), out[0]));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, (jog(0, 2000000, 50000000), out[0]));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_identify_reports_the_identity);
    RUN_TEST(test_parameters_are_range_checked_and_never_half_applied);
    RUN_TEST(test_unknown_short_and_wrong_length_messages);
    RUN_TEST(test_replayed_request_is_answered_not_executed);
    RUN_TEST(test_same_id_and_seq_with_another_payload_is_executed);
    RUN_TEST(test_blocks_are_checked_before_queueing);
    RUN_TEST(test_queue_full_is_a_specific_refusal);
    RUN_TEST(test_telemetry_cycles_share_one_consecutive_seq);
    RUN_TEST(test_watchdog_stops_in_a_controlled_way);
    RUN_TEST(test_watchdog_leaves_an_idle_drive_alone);
    RUN_TEST(test_enable_and_queue_in_one_batch_runs_the_block);
    RUN_TEST(test_queued_time_is_reported);
    RUN_TEST(test_planner_parameters_over_the_link);
    RUN_TEST(test_encoder_mean_is_refused_by_a_port_without_it);
    RUN_TEST(test_servo_parameters_reach_the_servo);
    RUN_TEST(test_soft_limits_refuse_before_motion);
    return UNITY_END();
}
