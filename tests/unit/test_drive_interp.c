/*
 * The interpolated measurement in the drive (drive.h enc_interp, issue 21):
 *   - drive_init refuses it when an axis is read as a counter (no edge
 *     times), takes it on edge axes;
 *   - alone, the loops see the decoder's count plus enc_interp_pos (the
 *     edge model at the sample); with enc_mean, the count's mean over the
 *     tick (hal_encoder_mean) plus enc_interp_mean_residual; off, the
 *     count. An axis with P-only gains at rest: the command is -Kp times
 *     the feedback.
 * The drive runs on the sim HAL without a plant (as test_drive_mean.c).
 */
#include "calib.h"
#include "drive.h"
#include "drive_inputs.h"
#include "fixmath.h"
#include "hal_sim.h"
#include "unity.h"

#include "drive_tick_fixture.h"

static void config(drive_config_t *cfg)
{
    unsigned i;
    drive_config_default(cfg, 10000, 2);
    for (i = 0; i < 2; i++) {
        cfg->nm_per_count_num[i] = 1250; /* 5 mm per 4000 counts */
        cfg->nm_per_count_den[i] = 1;
        /* P only, no feed-forward: 1e5 V/m = 0.1 mV/nm */
        cfg->servo.axis[i].kp = (q32_32_t)100000 << 32;
        cfg->servo.axis[i].ki = 0;
        cfg->servo.axis[i].kd = 0;
        cfg->servo.axis[i].kvff = 0;
        cfg->servo.axis[i].kaff = 0;
    }
}

static void test_counter_axis_refuses_it(void)
{
    drive_config_t cfg;

    hal_sim_set_counter(1, 0, true);
    config(&cfg);
    cfg.enc_interp = true;
    cfg.enc_counter[1] = true;
    TEST_ASSERT_EQUAL_INT(DRIVE_E_UNSUPPORTED, drive_init(&cfg));
    cfg.enc_counter[1] = false;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    TEST_ASSERT_TRUE(drive_config()->enc_interp);
}

/* Axis 0 moves forward one count per 400 us, edges at 30, 430 and 830 us
 * after the enable (x = 0.5, 1.5, 2.5 counts); the command of axis 0 at
 * 1100 us, where x = 3.175 counts: count 3, 0.175 above it. */
static int32_t command_after_edges(bool interp, bool mean)
{
    static const uint32_t fwd[4] = {0u, 1u, 3u, 2u}; /* A leading B */
    drive_config_t cfg;
    drive_status_t st;
    uint64_t start;
    unsigned k, e = 0;

    config(&cfg);
    cfg.enc_interp = interp;
    cfg.enc_mean = mean;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    tick();
    start = t_ns;
    for (k = 1; k <= 11; k++) {
        while (e < 3 && start + 30000u + 400000u * e <= start + k * TICK_NS) {
            drive_encoder_edge(0, fwd[(e + 1u) & 3u], (uint32_t)(start + 30000u + 400000u * e));
            e++;
        }
        tick();
    }
    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT64(3 * 1250, st.pos[0]); /* the decoder's own position */
    return st.motor_mv[0];
}

static void test_alone_the_loops_see_the_position_at_the_sample(void)
{
    /* 3.175 counts = 3968.75 nm: -396.875 mV */
    TEST_ASSERT_EQUAL_INT32(-397, command_after_edges(true, false));
}

static void test_with_the_mean_the_count_mean_plus_the_residual(void)
{
    /* the port's mean reading 0 (the count over the tick) plus the model's
     * mean in count 3 over [1000, 1100] us, from 2.925 to 3.175: +0.05,
     * 3812.5 nm: -381.25 mV */
    TEST_ASSERT_EQUAL_INT32(-381, command_after_edges(true, true));
}

static void test_off_the_count(void)
{
    TEST_ASSERT_EQUAL_INT32(-375, command_after_edges(false, false));
}

/* drive_inputs_lag_nm is fx_muldiv64(lag, num, den 2^16): ties (lag num
 * an odd multiple of 2^15) of either sign, random lags and scales, den 1
 * and not, lags past 2^31 */
static void test_lag_nm_is_fx_muldiv64(void)
{
    static const int32_t nums[] = {1250, -1250, 1, -1, 7, 2147483647, -2147483647 - 1};
    static const int32_t dens[] = {1, 3, 1000};
    uint64_t x = 12345u;
    unsigned i, j, k;

    for (i = 0; i < sizeof nums / sizeof nums[0]; i++) {
        for (j = 0; j < sizeof dens / sizeof dens[0]; j++) {
            for (k = 0; k < 20000u; k++) {
                int64_t lag;
                x = x * 6364136223846793005ull + 1442695040888963407ull;
                lag = (int64_t)(x >> (k % 38u + 24u)) - (int64_t)(x >> (k % 38u + 25u)) * 2;
                if (k < 64u) {
                    lag = (int64_t)k * 32768 - 1048576; /* odd multiples of 2^15: ties */
                }
                TEST_ASSERT_EQUAL_INT64(fx_muldiv64(lag, nums[i], (int64_t)dens[j] * 65536),
                                        drive_inputs_lag_nm(lag, nums[i], dens[j]));
            }
        }
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_counter_axis_refuses_it);
    RUN_TEST(test_alone_the_loops_see_the_position_at_the_sample);
    RUN_TEST(test_with_the_mean_the_count_mean_plus_the_residual);
    RUN_TEST(test_off_the_count);
    RUN_TEST(test_lag_nm_is_fx_muldiv64);
    return UNITY_END();
}
