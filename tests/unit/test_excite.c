/* Excitation experiment (excite.h): the PRBS, the user's limits, abort on
 * fault, estop and a silent host, sample continuity and the full ring. */
#include "excite.h"
#include "unity.h"

static excite_t ex;

void setUp(void)
{
    excite_init(&ex);
}

void tearDown(void)
{
}

static excite_cfg_t cfg(void)
{
    excite_cfg_t c = {
        .axis = 0,
        .bits = 7,
        .hold = 1,
        .amp_mv = 1000,
        .n_ticks = 500,
        .travel_nm = 1000000,
        .vel_nm_s = 50000000,
        .cmd_mv = 5000,
        .host_timeout_ticks = 100,
    };
    return c;
}

static excite_in_t at_rest(void)
{
    excite_in_t in = {0};
    return in;
}

/* Runs until not RUNNING or `max` ticks, the host alive every tick and
 * every sample released; returns the ticks run. */
static uint32_t run(excite_in_t in, uint32_t max)
{
    uint32_t k = 0;
    while (k < max) {
        excite_host_alive(&ex);
        in.cmd_mv = excite_tick(&ex, &in);
        excite_release(&ex, ex.written);
        k++;
        if (ex.state != EXCITE_RUNNING) {
            break;
        }
    }
    return k;
}

static void test_prbs_is_maximal_length_and_bounded(void)
{
    for (uint8_t bits = 7; bits <= 16; bits++) {
        excite_cfg_t c = cfg();
        uint32_t period = (1u << bits) - 1u;
        c.bits = bits;
        c.n_ticks = 2u * period;
        c.host_timeout_ticks = 1u << 20;
        excite_init(&ex);
        TEST_ASSERT_TRUE(excite_setup(&ex, &c));
        excite_start(&ex);
        excite_in_t in = at_rest();
        uint32_t first = 0, ones = 0;
        for (uint32_t k = 0; k < c.n_ticks; k++) {
            excite_host_alive(&ex);
            int32_t u = excite_tick(&ex, &in);
            excite_release(&ex, ex.written);
            TEST_ASSERT_TRUE(u == c.amp_mv || u == -c.amp_mv);
            if (k + 1u < period && ex.lfsr == 1u) {
                TEST_FAIL_MESSAGE("LFSR period shorter than 2^bits - 1");
            }
            if (k == period - 1u) {
                first = ex.lfsr;
            }
            ones += u > 0;
        }
        TEST_ASSERT_EQUAL_UINT32(1u, first); /* back to the seed after one period */
        TEST_ASSERT_EQUAL_UINT32(2u * (period + 1u) / 2u, ones); /* 2^(n-1) ones per period */
    }
}

static void test_runs_to_done_with_one_sample_per_tick(void)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    excite_in_t in = at_rest();
    uint32_t seq = 0;
    for (uint32_t k = 0; k <= c.n_ticks; k++) {
        excite_host_alive(&ex);
        in.pos_nm = 1000 + (int64_t)k; /* pos0 is 1000 */
        int32_t u = excite_tick(&ex, &in);
        excite_sample_t s;
        while (excite_sample(&ex, seq, &s)) {
            TEST_ASSERT_EQUAL_UINT32(seq, s.seq);
            TEST_ASSERT_EQUAL_INT32(in.cmd_mv, s.cmd_mv);
            TEST_ASSERT_EQUAL_INT64((int64_t)seq + 1, s.pos_nm);
            seq++;
        }
        excite_release(&ex, seq);
        in.cmd_mv = u;
    }
    TEST_ASSERT_EQUAL_UINT32(EXCITE_DONE, ex.state);
    TEST_ASSERT_EQUAL_UINT32(c.n_ticks, seq);
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &in));
}

static void check_abort(excite_in_t in, uint32_t at, uint32_t reason)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    excite_in_t rest = at_rest();
    run(rest, at);
    TEST_ASSERT_EQUAL_UINT32(EXCITE_RUNNING, ex.state);
    excite_host_alive(&ex);
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &in));
    TEST_ASSERT_EQUAL_UINT32(EXCITE_ABORTED, ex.state);
    TEST_ASSERT_EQUAL_UINT32(reason, ex.reason);
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &rest)); /* and stays off */
}

static void test_limits_abort_at_once(void)
{
    excite_in_t in = at_rest();
    in.pos_nm = 1000001;
    check_abort(in, 10, EXCITE_REASON_TRAVEL);
    excite_init(&ex);
    in = at_rest();
    in.pos_nm = -1000001;
    check_abort(in, 10, EXCITE_REASON_TRAVEL);
    excite_init(&ex);
    in = at_rest();
    in.vel_nm_s = -50000001;
    check_abort(in, 10, EXCITE_REASON_VELOCITY);
    excite_init(&ex);
    in = at_rest();
    in.cmd_mv = 5001;
    check_abort(in, 10, EXCITE_REASON_COMMAND);
}

static void test_within_limits_runs(void)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    excite_in_t in = at_rest();
    in.pos_nm = 1000000;
    in.vel_nm_s = -50000000;
    TEST_ASSERT_EQUAL_UINT32(c.n_ticks + 1u, run(in, 10000));
    TEST_ASSERT_EQUAL_UINT32(EXCITE_DONE, ex.state);
}

static void test_fault_estop_and_request_abort(void)
{
    excite_in_t in = at_rest();
    in.fault = true;
    check_abort(in, 5, EXCITE_REASON_FAULT);
    excite_init(&ex);
    in = at_rest();
    in.estop = true;
    check_abort(in, 5, EXCITE_REASON_ESTOP);
    excite_init(&ex);
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    run(at_rest(), 5);
    excite_abort(&ex);
    in = at_rest();
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &in));
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_ABORTED, ex.reason);
}

static void test_silent_host_aborts(void)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    excite_in_t in = at_rest();
    run(in, 3);
    uint32_t k = 0;
    while (ex.state == EXCITE_RUNNING && k < 1000) {
        (void)excite_tick(&ex, &in);
        excite_release(&ex, ex.written);
        k++;
    }
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_HOST_SILENT, ex.reason);
    TEST_ASSERT_EQUAL_UINT32(c.host_timeout_ticks, k);
}

static void test_full_ring_aborts_instead_of_overwriting(void)
{
    excite_cfg_t c = cfg();
    c.n_ticks = 3u * EXCITE_RING;
    c.host_timeout_ticks = 1u << 20;
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    excite_in_t in = at_rest();
    uint32_t k = 0;
    do {
        excite_host_alive(&ex);
        (void)excite_tick(&ex, &in);
        k++;
    } while (ex.state == EXCITE_RUNNING);
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_OVERRUN, ex.reason);
    TEST_ASSERT_EQUAL_UINT32(EXCITE_RING, ex.written);
    TEST_ASSERT_EQUAL_UINT32(EXCITE_RING + 2u, k);
    excite_sample_t s;
    TEST_ASSERT_TRUE(excite_sample(&ex, 0, &s));
    TEST_ASSERT_EQUAL_UINT32(0u, s.seq);
    TEST_ASSERT_FALSE(excite_sample(&ex, EXCITE_RING, &s));
}

static void test_setup_refuses_bad_config_and_running(void)
{
    excite_cfg_t c = cfg();
    c.amp_mv = c.cmd_mv + 1;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c));
    c = cfg();
    c.bits = 17;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c));
    c = cfg();
    c.travel_nm = 0;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c));
    c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c));
    excite_start(&ex);
    TEST_ASSERT_FALSE(excite_setup(&ex, &c)); /* start requested */
    excite_in_t in = at_rest();
    (void)excite_tick(&ex, &in);
    TEST_ASSERT_FALSE(excite_setup(&ex, &c)); /* running */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_prbs_is_maximal_length_and_bounded);
    RUN_TEST(test_runs_to_done_with_one_sample_per_tick);
    RUN_TEST(test_limits_abort_at_once);
    RUN_TEST(test_within_limits_runs);
    RUN_TEST(test_fault_estop_and_request_abort);
    RUN_TEST(test_silent_host_aborts);
    RUN_TEST(test_full_ring_aborts_instead_of_overwriting);
    RUN_TEST(test_setup_refuses_bad_config_and_running);
    return UNITY_END();
}
