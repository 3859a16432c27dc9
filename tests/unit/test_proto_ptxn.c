/* Parameter transactions on the wire (proto_ptxn.h) against the real drive
 * inside the simulator: staged values change nothing until the commit,
 * which applies all of them or none (a drive that moves, a value the other
 * staged values refuse), names the first refused parameter, is applied once
 * when retried, and a transaction is lost to a session_open, another begin
 * or the link timeout. */
#include <string.h>

#include "drive.h"
#include "hal_sim.h"
#include "proto_dispatch.h"
#include "sim.h"
#include "unity.h"
#include "dispatch_fixture.h"

#define VX PROTO_PARAM_MAX_VELOCITY
#define VY (PROTO_PARAM_MAX_VELOCITY + 1)

void setUp(void)
{
    dispatch_fixture_start();
}

void tearDown(void)
{
}

static void run_ms(unsigned ms)
{
    TEST_ASSERT_TRUE(sim_run((uint64_t)ms * 10u, NULL, 0, 0) >= 0);
    now_us += ms * 1000u;
}

static proto_param_txn_t expect_txn(size_t len)
{
    proto_param_txn_t t;

    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_TXN, out[0]);
    TEST_ASSERT_TRUE(proto_param_txn_decode(out + 2, len - 2, &t));
    return t;
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

static uint16_t begin(void)
{
    return expect_txn(request(PROTO_MSG_PARAM_BEGIN, NULL, 0)).txn;
}

/* param_stage of txn with k pairs (pid[i], v[i]). */
static size_t stage(uint16_t txn, const uint16_t *pid, const int64_t *v, unsigned k)
{
    uint8_t p[2 + 10 * 24];
    unsigned i;

    proto_put_le(p, txn, 2);
    for (i = 0; i < k; i++) {
        proto_put_le(p + 2 + 10 * i, pid[i], 2);
        proto_put_le(p + 4 + 10 * i, (uint64_t)v[i], 8);
    }
    return request(PROTO_MSG_PARAM_STAGE, p, 2 + 10 * k);
}

static size_t txn_req(uint8_t id, uint16_t txn)
{
    uint8_t p[2];

    proto_put_le(p, txn, 2);
    return request(id, p, 2);
}

static void session_open(void)
{
    proto_session_open_t o = {0x1234u, PROTO_VERSION};
    uint8_t p[8];

    TEST_ASSERT_TRUE(request(PROTO_MSG_SESSION_OPEN, p, proto_session_open_encode(&o, p, 8)) > 0);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_SESSION_REPLY, out[0]);
}

static void test_staged_values_change_nothing_until_the_commit_applies_all(void)
{
    const uint16_t pid[4] = {VX, VY, PROTO_PARAM_COMM_TIMEOUT_MS, PROTO_PARAM_CEC_MODE};
    const int64_t v[4] = {250000000, 100000000, 700, 2};
    int64_t vx = get_param(VX);
    uint16_t txn = begin();
    proto_param_txn_t t;

    TEST_ASSERT_TRUE(txn != 0u);
    t = expect_txn(stage(txn, pid, v, 2));
    TEST_ASSERT_EQUAL_UINT16(2, t.staged);
    t = expect_txn(stage(txn, pid + 2, v + 2, 2));
    TEST_ASSERT_EQUAL_UINT16(4, t.staged);
    TEST_ASSERT_EQUAL_INT64(vx, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(1000, get_param(PROTO_PARAM_COMM_TIMEOUT_MS));
    t = expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn));
    TEST_ASSERT_EQUAL_UINT8(1, t.committed);
    TEST_ASSERT_EQUAL_UINT16(4, t.staged);
    TEST_ASSERT_EQUAL_INT64(250000000, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(100000000, get_param(VY));
    TEST_ASSERT_EQUAL_INT64(700, get_param(PROTO_PARAM_COMM_TIMEOUT_MS));
    TEST_ASSERT_EQUAL_INT64(2, get_param(PROTO_PARAM_CEC_MODE));
    /* closed: a stage after the commit is refused */
    expect_error(stage(txn, pid, v, 1), PROTO_ERROR_CODE_TXN);
}

static void test_a_refused_pair_stages_nothing_of_its_frame(void)
{
    const uint16_t pid[3] = {VX, PROTO_PARAM_NODE_ID, 0x7777};
    const int64_t v[3] = {250000000, 3, 1};
    uint16_t txn = begin();
    proto_error_t e;

    e = expect_error(stage(txn, pid, v, 2), PROTO_ERROR_CODE_READ_ONLY);
    TEST_ASSERT_EQUAL_UINT16(PROTO_PARAM_NODE_ID, e.arg);
    e = expect_error(stage(txn, pid + 2, v + 2, 1), PROTO_ERROR_CODE_UNKNOWN_PARAM);
    {
        const uint16_t bad[1] = {VX};
        const int64_t big[1] = {-5};

        e = expect_error(stage(txn, bad, big, 1), PROTO_ERROR_CODE_OUT_OF_RANGE);
        TEST_ASSERT_EQUAL_UINT16(VX, e.arg);
    }
    TEST_ASSERT_EQUAL_UINT16(0, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).staged);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VX));
}

static void test_commit_while_moving_applies_nothing_and_names_the_parameter(void)
{
    const uint16_t pid[2] = {PROTO_PARAM_COMM_TIMEOUT_MS, VY};
    const int64_t v[2] = {700, 100000000};
    const uint8_t on[2] = {0x07, 1};
    proto_queue_block_t q = {1, PROTO_BLOCK_KIND_LINE, 0, 5000000, {2000000, 0, 0, 0}};
    uint8_t p[64];
    uint16_t txn = begin();
    proto_error_t e;

    expect_txn(stage(txn, pid, v, 2));
    /* the other session enables and starts a move between stage and commit */
    TEST_ASSERT_TRUE(request(PROTO_MSG_ENABLE, on, 2) > 0);
    run_ms(1);
    request(PROTO_MSG_QUEUE_BLOCK, p, proto_queue_block_encode(&q, p, sizeof p));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_QUEUE_REPLY, out[0]);
    run_ms(5);
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_BUSY);
    TEST_ASSERT_EQUAL_UINT16(VY, e.arg); /* the first drive parameter staged */
    TEST_ASSERT_EQUAL_INT64(PROTO_STATE_RUNNING, e.lo);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VY));
    TEST_ASSERT_EQUAL_INT64(1000, get_param(PROTO_PARAM_COMM_TIMEOUT_MS)); /* link's too */
    /* still open: committed once the move ended (within comm_timeout_ms of
     * the stage, else the link timeout lost it) */
    run_ms(800);
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    TEST_ASSERT_EQUAL_INT64(100000000, get_param(VY));
}

static void test_encoder_mean_on_an_enabled_drive_applies_nothing(void)
{
    const uint16_t pid[2] = {VX, PROTO_PARAM_ENCODER_MEAN};
    const int64_t v[2] = {250000000, 1};
    uint8_t on[2] = {0x07, 1};
    uint16_t txn = begin();
    proto_error_t e;

    expect_txn(stage(txn, pid, v, 2));
    /* another session enables the drive between stage and commit */
    TEST_ASSERT_TRUE(request(PROTO_MSG_ENABLE, on, 2) > 0);
    run_ms(1);
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_BUSY);
    TEST_ASSERT_EQUAL_UINT16(PROTO_PARAM_ENCODER_MEAN, e.arg);
    TEST_ASSERT_EQUAL_INT64(PROTO_STATE_READY, e.lo);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(0, get_param(PROTO_PARAM_ENCODER_MEAN));
    on[1] = 0;
    TEST_ASSERT_TRUE(request(PROTO_MSG_ENABLE, on, 2) > 0);
    run_ms(1);
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    TEST_ASSERT_EQUAL_INT64(250000000, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(1, get_param(PROTO_PARAM_ENCODER_MEAN));
}

static void test_a_value_the_other_staged_values_refuse_applies_nothing(void)
{
    /* S-curve: max_acceleration <= 3 s * max_jerk, with the staged jerk */
    const uint16_t pid[3] = {VX, PROTO_PARAM_MAX_ACCELERATION, PROTO_PARAM_MAX_JERK};
    const int64_t v[3] = {250000000, 20000000000, 1000000000};
    uint16_t txn = begin();
    proto_error_t e;

    expect_txn(stage(txn, pid, v, 3));
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_OUT_OF_RANGE);
    TEST_ASSERT_EQUAL_UINT16(PROTO_PARAM_MAX_ACCELERATION, e.arg);
    TEST_ASSERT_EQUAL_INT64(3000000000, e.hi);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(1000000000000, get_param(PROTO_PARAM_MAX_JERK));
    /* abort: the commit then finds nothing open */
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, (txn_req(PROTO_MSG_PARAM_ABORT, txn), out[0]));
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_TXN);
    TEST_ASSERT_EQUAL_UINT16(PROTO_TXN_STATUS_NOT_OPEN, e.arg);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VX));
}

static void test_a_retried_commit_is_applied_once(void)
{
    const uint16_t pid[1] = {VX};
    const int64_t v[1] = {250000000};
    uint16_t txn = begin();
    proto_param_set_t s = {VX, 300000000};
    uint8_t p[16];

    expect_txn(stage(txn, pid, v, 1));
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    /* another request moves the replay cache on and changes the value */
    request(PROTO_MSG_PARAM_SET, p, proto_param_set_encode(&s, p, sizeof p));
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_PARAM_VALUE, out[0]);
    /* the host's retry (its reply was lost) executes again: answered, not applied */
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    TEST_ASSERT_EQUAL_INT64(300000000, get_param(VX));
}

static void test_another_session_or_a_silent_host_loses_the_transaction(void)
{
    const uint16_t pid[1] = {VX};
    const int64_t v[1] = {250000000};
    uint16_t txn = begin();
    uint16_t second;
    proto_error_t e;

    expect_txn(stage(txn, pid, v, 1));
    session_open(); /* another host */
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_TXN);
    TEST_ASSERT_EQUAL_UINT16(PROTO_TXN_STATUS_NEW_SESSION, e.arg);
    TEST_ASSERT_EQUAL_INT64(txn, e.lo);
    e = expect_error(stage(txn, pid, v, 1), PROTO_ERROR_CODE_TXN);
    TEST_ASSERT_EQUAL_UINT16(PROTO_TXN_STATUS_NEW_SESSION, e.arg);
    /* a begin of another session */
    txn = begin();
    expect_txn(stage(txn, pid, v, 1));
    second = begin();
    TEST_ASSERT_TRUE(second != txn);
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, txn), PROTO_ERROR_CODE_TXN);
    TEST_ASSERT_EQUAL_UINT16(PROTO_TXN_STATUS_SUPERSEDED, e.arg);
    /* the link timeout: no request of it for comm_timeout_ms (1000) */
    expect_txn(stage(second, pid, v, 1));
    now_us += 1000000u;
    proto_dispatch_poll(&d, now_us, NULL, NULL);
    e = expect_error(txn_req(PROTO_MSG_PARAM_COMMIT, second), PROTO_ERROR_CODE_TXN);
    TEST_ASSERT_EQUAL_UINT16(PROTO_TXN_STATUS_LINK_TIMEOUT, e.arg);
    TEST_ASSERT_EQUAL_INT64(1000000000, get_param(VX));
}

/* The commit's reply is lost; before the host's retry another session
 * begins a transaction of its own. The retry must not say "not open"
 * (the host reports "nothing written") for a transaction that was applied. */
static void test_a_retried_commit_after_another_begin_still_reports_it_applied(void)
{
    const uint16_t pid[1] = {VX};
    const int64_t v[1] = {250000000};
    uint16_t txn = begin();
    proto_param_txn_t t;

    expect_txn(stage(txn, pid, v, 1));
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    TEST_ASSERT_EQUAL_INT64(250000000, get_param(VX));
    (void)begin(); /* the other session */
    t = expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn));
    TEST_ASSERT_EQUAL_UINT16(txn, t.txn);
    TEST_ASSERT_EQUAL_UINT8(1, t.committed);
    TEST_ASSERT_EQUAL_UINT16(1, t.staged);
}

/* One parameter twice in a frame: staged once, the later value wins; a
 * refused second copy stages nothing of the frame. */
static void test_a_parameter_twice_in_a_frame_is_staged_once_with_the_later_value(void)
{
    const uint16_t pid[3] = {VX, VX, VY};
    const int64_t v[3] = {250000000, 300000000, 100000000};
    const int64_t bad[2] = {200000000, -1};
    uint16_t txn = begin();
    proto_param_txn_t t;

    t = expect_txn(stage(txn, pid, v, 3));
    TEST_ASSERT_EQUAL_UINT16(2, t.staged);
    expect_error(stage(txn, pid, bad, 2), PROTO_ERROR_CODE_OUT_OF_RANGE);
    t = expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn));
    TEST_ASSERT_EQUAL_UINT16(2, t.staged);
    TEST_ASSERT_EQUAL_INT64(300000000, get_param(VX));
    TEST_ASSERT_EQUAL_INT64(100000000, get_param(VY));
}

/* 65535 begins later the ids wrap to the committed one: that new
 * transaction is committed for real, not answered as the old one. */
static void test_an_id_reused_after_the_wrap_is_not_taken_for_the_committed_one(void)
{
    const uint16_t pid[1] = {VX};
    const int64_t v[2] = {250000000, 300000000};
    uint16_t txn = begin();
    uint16_t again;
    unsigned k;

    expect_txn(stage(txn, pid, v, 1));
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, txn)).committed);
    for (k = 0; k < 65534u; k++) {
        (void)begin();
    }
    again = begin();
    TEST_ASSERT_EQUAL_UINT16(txn, again);
    expect_txn(stage(again, pid, v + 1, 1));
    TEST_ASSERT_EQUAL_UINT8(1, expect_txn(txn_req(PROTO_MSG_PARAM_COMMIT, again)).committed);
    TEST_ASSERT_EQUAL_INT64(300000000, get_param(VX));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_staged_values_change_nothing_until_the_commit_applies_all);
    RUN_TEST(test_a_refused_pair_stages_nothing_of_its_frame);
    RUN_TEST(test_commit_while_moving_applies_nothing_and_names_the_parameter);
    RUN_TEST(test_encoder_mean_on_an_enabled_drive_applies_nothing);
    RUN_TEST(test_a_value_the_other_staged_values_refuse_applies_nothing);
    RUN_TEST(test_a_retried_commit_is_applied_once);
    RUN_TEST(test_another_session_or_a_silent_host_loses_the_transaction);
    RUN_TEST(test_a_retried_commit_after_another_begin_still_reports_it_applied);
    RUN_TEST(test_a_parameter_twice_in_a_frame_is_staged_once_with_the_later_value);
    RUN_TEST(test_an_id_reused_after_the_wrap_is_not_taken_for_the_committed_one);
    return UNITY_END();
}
