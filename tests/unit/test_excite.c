/* Excitation experiment (excite.h): the PRBS, the user's limits, abort on
 * fault, estop, drive state and a silent host, whole-period windows only
 * with room in the buffer, the duration limit. */
#include "excite.h"
#include "unity.h"

static excite_t ex;
static excite_sample_t buf[1024];

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
        .windows = 3,
        .amp_mv = 1000,
        .skip_ticks = 0,
        .n_ticks = 5000,
        .travel_nm = 1000000,
        .vel_dpos_nm = 20000, /* 50 mm/s over 4 ticks at 10 kHz */
        .cmd_mv = 5000,
        .host_timeout_ticks = 100,
    };
    return c;
}

static excite_in_t at_rest(void)
{
    excite_in_t in = {0};
    in.idle = true;
    return in;
}

/* Runs until not RUNNING or `max` ticks, the host alive every tick and
 * every sample released; returns the ticks run. */
static uint32_t run(excite_in_t in, uint32_t max)
{
    uint32_t k = 0;
    while (k < max) {
        excite_host_alive(&ex);
        (void)excite_tick(&ex, &in);
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
        c.windows = 1000;
        c.host_timeout_ticks = 1u << 20;
        excite_init(&ex);
        static excite_sample_t big[1u << 16];
        TEST_ASSERT_TRUE(excite_setup(&ex, &c, big, 1u << 16));
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

/* Whole periods only, from skip_ticks on, when the buffer has room: the
 * sample of tick k is (drive command + excitation of tick k, pos - pos0). */
static void test_records_whole_periods_with_room(void)
{
    excite_cfg_t c = cfg();
    const uint32_t P = 127;
    c.skip_ticks = 200; /* first window at k = 254 */
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 256u));
    excite_start(&ex);
    excite_in_t in = at_rest();
    uint32_t seq = 0, k = 0, starts[3] = {0}, nw = 0;
    while ((k == 0u || ex.state == EXCITE_RUNNING) && k < 5000u) {
        excite_host_alive(&ex);
        in.pos_nm = 1000 + (int64_t)k;
        in.cmd_mv = (int32_t)(k % 7);
        uint32_t w0 = ex.written;
        int32_t u = excite_tick(&ex, &in);
        if (ex.written != w0) {
            excite_sample_t s;
            TEST_ASSERT_TRUE(excite_sample(&ex, w0, &s));
            TEST_ASSERT_EQUAL_INT32(in.cmd_mv + u, s.cmd_mv);
            TEST_ASSERT_EQUAL_INT32((int32_t)k, s.pos_nm);
            if (w0 % P == 0u && nw < 3u) {
                starts[nw++] = k;
            }
        }
        /* the host frees the first window only at k = 1000 */
        if (k == 1000u) {
            excite_release(&ex, ex.written);
            seq = ex.written;
        }
        k++;
    }
    TEST_ASSERT_EQUAL_UINT32(EXCITE_DONE, ex.state);
    TEST_ASSERT_EQUAL_UINT32(3u * P, ex.written);
    TEST_ASSERT_EQUAL_UINT32(2u * P, starts[0]);
    TEST_ASSERT_EQUAL_UINT32(3u * P, starts[1]); /* 2 windows fit 256 */
    TEST_ASSERT_EQUAL_UINT32(8u * P, starts[2]); /* next boundary after 1000 */
    TEST_ASSERT_TRUE(seq > 0u);
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &in));
}

static void test_duration_aborts(void)
{
    excite_cfg_t c = cfg();
    c.n_ticks = 300; /* 3 windows of 127 need 381 */
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
    excite_start(&ex);
    TEST_ASSERT_EQUAL_UINT32(301u, run(at_rest(), 10000));
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_DURATION, ex.reason);
}

static void check_abort(excite_in_t in, uint32_t at, uint32_t reason)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
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
    in.pos_nm = -20001; /* 4 ticks ago: 0 */
    check_abort(in, 10, EXCITE_REASON_VELOCITY);
    excite_init(&ex);
    in = at_rest();
    in.cmd_mv = 4001; /* + or - 1000 of the PRBS: 5001 or 3001 */
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
    excite_start(&ex);
    uint32_t k = run(in, 1000);
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_COMMAND, ex.reason);
    TEST_ASSERT_EQUAL_UINT32(1u, k); /* the LFSR's first chip is 1 */
}

static void test_within_limits_runs(void)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
    excite_start(&ex);
    excite_in_t in = at_rest();
    in.pos_nm = 1000000;
    in.cmd_mv = 4000;
    TEST_ASSERT_EQUAL_UINT32(3u * 127u, run(in, 10000));
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
    in = at_rest();
    in.idle = false;
    check_abort(in, 5, EXCITE_REASON_DRIVE_STATE);
    excite_init(&ex);
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
    excite_start(&ex);
    run(at_rest(), 5);
    excite_abort(&ex, EXCITE_REASON_NEW_SESSION);
    in = at_rest();
    TEST_ASSERT_EQUAL_INT32(0, excite_tick(&ex, &in));
    TEST_ASSERT_EQUAL_UINT32(EXCITE_REASON_NEW_SESSION, ex.reason);
}

static void test_silent_host_aborts(void)
{
    excite_cfg_t c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
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

static void test_setup_refuses_bad_config_and_running(void)
{
    excite_cfg_t c = cfg();
    c.amp_mv = c.cmd_mv + 1;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u));
    c = cfg();
    c.bits = 17;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u));
    c = cfg();
    c.travel_nm = 0;
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u));
    c = cfg();
    c.bits = 11; /* 2047 ticks: more than the buffer */
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u));
    c = cfg();
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1000u)); /* not a power of two */
    c = cfg();
    TEST_ASSERT_TRUE(excite_setup(&ex, &c, buf, 1024u));
    excite_start(&ex);
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u)); /* start requested */
    excite_in_t in = at_rest();
    (void)excite_tick(&ex, &in);
    TEST_ASSERT_FALSE(excite_setup(&ex, &c, buf, 1024u)); /* running */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_prbs_is_maximal_length_and_bounded);
    RUN_TEST(test_records_whole_periods_with_room);
    RUN_TEST(test_duration_aborts);
    RUN_TEST(test_limits_abort_at_once);
    RUN_TEST(test_within_limits_runs);
    RUN_TEST(test_fault_estop_and_request_abort);
    RUN_TEST(test_silent_host_aborts);
    RUN_TEST(test_setup_refuses_bad_config_and_running);
    return UNITY_END();
}
