/*
 * Axis encoders read as hardware counters (drive_config_t.enc_counter):
 *   - drive_tick polls hal_encoder_counter(axis) and the decoded count
 *     follows the counter from 0 at drive_init, in both directions, across
 *     the 32-bit wrap (up and down), scaled to nm with the axis scale;
 *   - drive_encoder_edge on a counter axis is ignored, while an edge axis
 *     next to it still decodes edges;
 *   - drive_init refuses a counter axis whose port has no counter;
 *   - a tick without a counter snapshot keeps the position.
 * Runs the drive directly on the sim HAL (no plant: the drive stays
 * disabled, the decoders are sampled at every tick all the same).
 */
#include <string.h>

#include "calib.h"
#include "drive.h"
#include "hal_sim.h"
#include "unity.h"

#include "drive_tick_fixture.h"

static void config(drive_config_t *cfg, uint32_t raw0)
{
    drive_config_default(cfg, 10000, 2);
    cfg->enc_counter[0] = true;
    cfg->nm_per_count_num[0] = 1250; /* 5 mm per 4000 counts */
    cfg->nm_per_count_den[0] = 1;
    hal_sim_set_counter(0, raw0, true);
}

static pos_nm_t pos_nm(unsigned axis)
{
    drive_status_t st;

    drive_snapshot(&st);
    return st.pos[axis];
}

static void test_default_is_edges(void)
{
    drive_config_t cfg;
    unsigned i;

    drive_config_default(&cfg, 10000, CORE_AXES);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_FALSE(cfg.enc_counter[i]);
    }
}

static void test_counter_follows_across_wrap(void)
{
    drive_config_t cfg;
    const uint32_t raw0 = 0xFFFFFF00u; /* 256 counts below the wrap */
    int64_t expect = 0;
    uint32_t raw = raw0;
    int k;

    config(&cfg, raw0);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    tick();
    TEST_ASSERT_EQUAL_INT64(0, drive_encoder_count(0));
    TEST_ASSERT_EQUAL_INT64(0, pos_nm(0));
    /* up through the wrap in steps of 100 counts */
    for (k = 0; k < 10; k++) {
        raw += 100u;
        expect += 100;
        hal_sim_set_counter(0, raw, true);
        tick();
        TEST_ASSERT_EQUAL_INT64(expect, drive_encoder_count(0));
        TEST_ASSERT_EQUAL_INT64(expect * 1250, pos_nm(0));
    }
    TEST_ASSERT_TRUE(raw < raw0); /* wrapped */
    /* large steps (1e6 counts per tick, within QDEC_MAX_DELTA(32) / 2) back
     * down through the wrap and far into negative positions */
    for (k = 0; k < 50; k++) {
        raw -= 1000000u;
        expect -= 1000000;
        hal_sim_set_counter(0, raw, true);
        tick();
        TEST_ASSERT_EQUAL_INT64(expect, drive_encoder_count(0));
    }
    TEST_ASSERT_EQUAL_INT64(1000 - 50000000, expect);
    TEST_ASSERT_EQUAL_INT64(expect * 1250, pos_nm(0));
    {
        drive_status_t st;
        drive_snapshot(&st);
        TEST_ASSERT_EQUAL_UINT32(0, st.faults & DRIVE_FAULT_ENCODER);
    }
}

static void test_edges_ignored_on_counter_axis(void)
{
    drive_config_t cfg;
    /* forward x4 sequence: 00 -> A -> AB -> B -> 00 */
    static const uint32_t fwd[4] = {1, 3, 2, 0};
    unsigned k;

    config(&cfg, 7u);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    tick();
    for (k = 0; k < 8; k++) {
        uint32_t t = (uint32_t)(t_ns + 1000u * (k + 1));
        drive_encoder_edge(0, fwd[k & 3u], t); /* counter axis: ignored */
        drive_encoder_edge(1, fwd[k & 3u], t); /* edge axis: counts     */
    }
    tick();
    TEST_ASSERT_EQUAL_INT64(0, drive_encoder_count(0));
    TEST_ASSERT_EQUAL_INT64(8, drive_encoder_count(1));
    hal_sim_set_counter(0, 7u - 3u, true);
    tick();
    TEST_ASSERT_EQUAL_INT64(-3, drive_encoder_count(0));
    TEST_ASSERT_EQUAL_INT64(-3 * 1250, pos_nm(0));
    TEST_ASSERT_EQUAL_INT64(8, drive_encoder_count(1));
    /* runs of edges (drive_encoder_run): the edge axis only, not the
     * counter axis nor a channel beyond the configured axes */
    TEST_ASSERT_FALSE(drive_encoder_run(0, 5, (uint32_t)(t_ns + 9000u)));
    TEST_ASSERT_TRUE(drive_encoder_run(1, 5, (uint32_t)(t_ns + 9000u)));
    TEST_ASSERT_FALSE(drive_encoder_run(2, 5, (uint32_t)(t_ns + 9000u)));
    TEST_ASSERT_FALSE(drive_encoder_run(CORE_AXES, 5, (uint32_t)(t_ns + 9000u)));
    TEST_ASSERT_FALSE(drive_encoder_run(40, 5, (uint32_t)(t_ns + 9000u)));
    drive_encoder_edge(2, fwd[0], (uint32_t)(t_ns + 9500u));
    drive_encoder_edge(40, fwd[0], (uint32_t)(t_ns + 9500u));
    tick();
    TEST_ASSERT_EQUAL_INT64(-3, drive_encoder_count(0));
    TEST_ASSERT_EQUAL_INT64(13, drive_encoder_count(1));
    /* a drive_init that fails after taking the configuration: not ready,
     * no channel takes edges */
    cfg.servo.axis[0].out_max_mv = 0;
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_init(&cfg));
    TEST_ASSERT_FALSE(drive_encoder_run(1, 5, (uint32_t)(t_ns + 9900u)));
}

static void test_missing_snapshot_keeps_position(void)
{
    drive_config_t cfg;

    config(&cfg, 100u);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    hal_sim_set_counter(0, 150u, true);
    tick();
    TEST_ASSERT_EQUAL_INT64(50, drive_encoder_count(0));
    hal_sim_set_counter(0, 999u, false); /* port reports no snapshot */
    tick();
    TEST_ASSERT_EQUAL_INT64(50, drive_encoder_count(0));
    hal_sim_set_counter(0, 90u, true);
    tick();
    TEST_ASSERT_EQUAL_INT64(-10, drive_encoder_count(0));
}

static void test_init_refuses_missing_counter(void)
{
    drive_config_t cfg;

    config(&cfg, 0u);
    hal_sim_set_counter(0, 0u, false);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_init(&cfg));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_default_is_edges);
    RUN_TEST(test_counter_follows_across_wrap);
    RUN_TEST(test_edges_ignored_on_counter_axis);
    RUN_TEST(test_missing_snapshot_keeps_position);
    RUN_TEST(test_init_refuses_missing_counter);
    return UNITY_END();
}
