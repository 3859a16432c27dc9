/* The one-entry replay cache (proto_replay.h): proto_replay_answer executes
 * a request once and answers its retry (same id, seq and payload) from the
 * cache; another seq or payload is executed; a reset forgets. And one
 * handler that uses it, on the simulated drive: an excite_start retried
 * after a lost reply gets the first reply, not a second execution (which
 * the running experiment would refuse as busy). */
#include "drive_excite.h"
#include "proto_msgs.h"
#include "proto_replay.h"
#include "sim.h"
#include "unity.h"

#include <string.h>

static unsigned executed;

void setUp(void)
{
    executed = 0;
}

void tearDown(void)
{
}

/* A handler whose reply says how many times it executed: ctx is a byte
 * added to that count (the context reaches it). */
static size_t count_exec(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    const uint8_t *add = ctx;

    executed++;
    out[0] = msg[0];
    out[1] = msg[1];
    out[2] = (uint8_t)(executed + *add);
    out[3] = (uint8_t)len;
    return 4u;
}

/* A handler with no reply: nothing to cache. */
static size_t silent_exec(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    (void)ctx;
    (void)msg;
    (void)len;
    (void)out;
    executed++;
    return 0u;
}

static size_t ask(proto_replay_t *c, uint8_t seq, uint8_t payload, uint8_t *out)
{
    static uint8_t add = 100;
    uint8_t msg[3] = {0x42u, seq, payload};

    return proto_replay_answer(c, msg, sizeof msg, out, PROTO_MSG_MAX, count_exec, &add);
}

static void test_answer_executes_each_request_once(void)
{
    proto_replay_t c;
    uint8_t out[PROTO_MSG_MAX];

    proto_replay_reset(&c);
    TEST_ASSERT_EQUAL_size_t(4, ask(&c, 7, 1, out));
    TEST_ASSERT_EQUAL_UINT8(101, out[2]);
    /* the retry: the cached reply, not executed */
    memset(out, 0, sizeof out);
    TEST_ASSERT_EQUAL_size_t(4, ask(&c, 7, 1, out));
    TEST_ASSERT_EQUAL_UINT(1, executed);
    TEST_ASSERT_EQUAL_UINT8(0x42, out[0]);
    TEST_ASSERT_EQUAL_UINT8(7, out[1]);
    TEST_ASSERT_EQUAL_UINT8(101, out[2]);
    /* another seq, another payload under the same seq: executed */
    ask(&c, 8, 1, out);
    TEST_ASSERT_EQUAL_UINT8(102, out[2]);
    ask(&c, 8, 2, out);
    TEST_ASSERT_EQUAL_UINT8(103, out[2]);
    ask(&c, 8, 2, out);
    TEST_ASSERT_EQUAL_UINT(3, executed);
    /* a reset forgets the entry */
    proto_replay_reset(&c);
    ask(&c, 8, 2, out);
    TEST_ASSERT_EQUAL_UINT(4, executed);
}

static void test_no_reply_is_not_cached(void)
{
    proto_replay_t c;
    uint8_t out[PROTO_MSG_MAX];
    uint8_t msg[2] = {0x42u, 9u};

    proto_replay_reset(&c);
    TEST_ASSERT_EQUAL_size_t(0,
                             proto_replay_answer(&c, msg, 2, out, sizeof out, silent_exec, NULL));
    TEST_ASSERT_EQUAL_size_t(0,
                             proto_replay_answer(&c, msg, 2, out, sizeof out, silent_exec, NULL));
    TEST_ASSERT_EQUAL_UINT(2, executed);
}

static size_t send_start(uint8_t seq, uint8_t *out)
{
    proto_excite_start_t m;
    uint8_t msg[PROTO_MSG_HDR + PROTO_EXCITE_START_LEN];

    memset(&m, 0, sizeof m);
    m.axis = 0;
    m.bits = 7;
    m.hold = 1;
    m.windows = 1;
    m.host_timeout_ms = 1000;
    m.amp_mv = 100;
    m.n_ticks = 5000;
    m.travel_nm = 1000000;
    m.cmd_mv = 5000;
    m.vel_nm_s = 100000000;
    msg[0] = PROTO_MSG_EXCITE_START;
    msg[1] = seq;
    TEST_ASSERT_EQUAL_size_t(PROTO_EXCITE_START_LEN,
                             proto_excite_start_encode(&m, msg + PROTO_MSG_HDR, sizeof msg - 2));
    return drive_excite_handle(msg, sizeof msg, 0u, out, PROTO_MSG_MAX);
}

static void test_excite_start_retry_is_answered_not_executed(void)
{
    uint8_t first[PROTO_MSG_MAX];
    uint8_t out[PROTO_MSG_MAX];
    uint8_t abort_msg[2] = {PROTO_MSG_EXCITE_ABORT, 12u};
    size_t n;

    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 2));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(0, sim_enable(1));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
    n = send_start(10, first);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_EXCITE_STATE, first[0]);
    TEST_ASSERT_TRUE(sim_run(5, NULL, 0, 0) >= 0);
    TEST_ASSERT_EQUAL_size_t(n, send_start(10, out));
    TEST_ASSERT_EQUAL_MEMORY(first, out, n);
    /* a new request under another seq is executed: busy */
    send_start(11, out);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, out[0]);
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_EXCITE, out[3]);
    drive_excite_handle(abort_msg, sizeof abort_msg, 0u, out, sizeof out);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_EXCITE_STATE, out[0]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_answer_executes_each_request_once);
    RUN_TEST(test_no_reply_is_not_cached);
    RUN_TEST(test_excite_start_retry_is_answered_not_executed);
    return UNITY_END();
}
