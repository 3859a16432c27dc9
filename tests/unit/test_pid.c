/* PID: gain conversion, step, ramp, D filter, feed-forward, saturation and
 * anti-windup, deadband, bumpless enable/reset/gain change, position reset,
 * parameter validation and extremes. */
#include "pid.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void setUp(void)
{
}

void tearDown(void)
{
}

#define Q32(x) ((q32_32_t)llround((double)(x)*4294967296.0))

__extension__ typedef __int128 i128;

/* The fast path's stated bound against the general path (pid.h): 4 F,
 * F = 2^21 U (mV * 2^-11). */
#define FAST_TOL_U ((int64_t)4 << 21)

static double coef_value(pid_coef_t c)
{
    return (double)c.m * ldexp(1.0, -c.sh);
}

static pid_params_t params(double kp, double ki, double kd, uint32_t hz)
{
    pid_params_t p;
    memset(&p, 0, sizeof p);
    p.kp = Q32(kp);
    p.ki = Q32(ki);
    p.kd = Q32(kd);
    p.out_max_mv = 160000;
    p.i_max_mv = 160000;
    p.tick_hz = hz;
    return p;
}

static void start(pid_loop_t *pid, const pid_params_t *p)
{
    memset(pid, 0, sizeof *pid);
    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(pid, p));
    pid_enable(pid, 0);
    pid_reset(pid, false); /* hard start: the first step is the plain law */
}

static void test_coef_make_matches_double(void)
{
    unsigned i;
    srand(7);
    for (i = 0; i < 20000; i++) {
        int64_t num = ((int64_t)rand() << 31 | rand()) >> (rand() % 60);
        uint32_t mul = (uint32_t)rand() >> (rand() % 31);
        uint64_t den = (((uint64_t)rand() << 31 | (uint64_t)rand()) >> (rand() % 60)) | 1u;
        double want;
        pid_coef_t c;
        if (rand() & 1) {
            num = -num;
        }
        want = (double)num * (double)mul / (double)den;
        if (!pid_coef_make(&c, num, mul, den)) {
            TEST_ASSERT_TRUE(fabs(want) >= ldexp(1.0, 61));
            continue;
        }
        if (fabs(want) < ldexp(1.0, -32)) {
            TEST_ASSERT_TRUE(fabs(coef_value(c) - want) <= ldexp(1.0, -62));
            continue;
        }
        /* 31 significant bits, rounded: relative error <= 2^-30 */
        TEST_ASSERT_TRUE(fabs(coef_value(c) - want) <= fabs(want) * ldexp(1.0, -30));
    }
}

static void test_coef_make_edges(void)
{
    pid_coef_t c;
    TEST_ASSERT_TRUE(pid_coef_make(&c, 0, 5, 3));
    TEST_ASSERT_EQUAL_INT32(0, c.m);
    TEST_ASSERT_TRUE(pid_coef_make(&c, INT64_MIN, 1, (uint64_t)1 << 32)); /* -2^31 */
    TEST_ASSERT_EQUAL_INT64(-((int64_t)1 << 31) * 5, pid_coef_apply(c, 5));
    TEST_ASSERT_FALSE(pid_coef_make(&c, INT64_MIN, 0xFFFFFFFFu, 1)); /* 2^95: too large */
    TEST_ASSERT_FALSE(pid_coef_make(&c, 1, 1, 0));
    TEST_ASSERT_FALSE(pid_coef_make(&c, 1, 1, (uint64_t)1 << 62));
    TEST_ASSERT_TRUE(pid_coef_make(&c, 3, 1, 1));
    TEST_ASSERT_EQUAL_INT64(-3000, pid_coef_apply(c, -1000));
    TEST_ASSERT_TRUE(pid_coef_make(&c, 1, 1, 3)); /* 1/3 */
    TEST_ASSERT_EQUAL_INT64(333, pid_coef_apply(c, 1000));
    TEST_ASSERT_EQUAL_INT64(-333, pid_coef_apply(c, -1000));
    /* left shifts saturate at the term limit */
    TEST_ASSERT_TRUE(pid_coef_make(&c, INT64_MAX / 4, 1, 1));
    TEST_ASSERT_TRUE(c.sh < 0);
    TEST_ASSERT_EQUAL_INT64(PID_TERM_LIM, pid_coef_apply(c, INT32_MAX));
    TEST_ASSERT_EQUAL_INT64(-PID_TERM_LIM, pid_coef_apply(c, INT32_MIN));
}

/* The thesis's gains (and the CEC's) at 333 Hz .. 20 kHz keep 30 bits. */
static void test_config_resolution_over_tick_rates(void)
{
    static const uint32_t rates[] = {333, 1000, 10000, 20000};
    static const double gains[][3] = {{1.5e3, 8e3, 5}, {4e4, 2e6, 100}, {1, 1, 1e-4}};
    unsigned r, g;
    for (r = 0; r < 4; r++) {
        for (g = 0; g < 3; g++) {
            double f = rates[r], u = ldexp(1.0, 32);
            pid_params_t p = params(gains[g][0], gains[g][1], gains[g][2], rates[r]);
            pid_loop_t pid;
            /* the gains as the q32_32 input holds them (2^-32 resolution) */
            double kp = (double)p.kp / u, ki = (double)p.ki / u, kd = (double)p.kd / u;
            p.kvff = Q32(25.0);
            p.kaff = Q32(0.05);
            start(&pid, &p);
            TEST_ASSERT_DOUBLE_WITHIN(kp * 1e-6 * u * 1e-8, kp * 1e-6 * u, coef_value(pid.cp));
            TEST_ASSERT_DOUBLE_WITHIN(ki * 1e-6 / f * u * 1e-8, ki * 1e-6 / f * u,
                                      coef_value(pid.ci));
            TEST_ASSERT_DOUBLE_WITHIN(kd * 1e-6 * f * u * 1e-8, kd * 1e-6 * f * u,
                                      coef_value(pid.cd));
            TEST_ASSERT_DOUBLE_WITHIN(25.0 * 4e-6 * u * 1e-8, 25.0 * 4e-6 * u, coef_value(pid.cv));
            TEST_ASSERT_DOUBLE_WITHIN(0.05 * 1.024e-3 * u * 1e-8, 0.05 * 1.024e-3 * u,
                                      coef_value(pid.ca));
        }
    }
}

static void test_proportional_step(void)
{
    pid_params_t p = params(1.5e3, 0, 0, 10000);
    pid_loop_t pid;
    start(&pid, &p);
    /* 1 mm * 1500 V/m = 1.5 V */
    TEST_ASSERT_EQUAL_INT32(1500, pid_step(&pid, 1000000, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(1500, pid_step(&pid, 1000000, 0, 0, 0, 0)); /* no integral */
    TEST_ASSERT_EQUAL_INT32(-1500, pid_step(&pid, 0, 1000000, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(-1000000, pid.err_nm);
    TEST_ASSERT_FALSE(pid.saturated);
    /* 1 nm gives 0.0015 mV: carried in the output's fraction */
    pid_step(&pid, 1, 0, 0, 0, 0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0015, (double)pid.out / 4294967296.0);
}

/* Integral of a constant error: Ki * e * t, at three tick rates. */
static void test_integral_ramp(void)
{
    static const uint32_t rates[] = {333, 10000, 20000};
    unsigned r;
    for (r = 0; r < 3; r++) {
        pid_params_t p = params(0, 8e3, 0, rates[r]);
        pid_loop_t pid;
        unsigned k, n = rates[r] / 4; /* 0.25 s */
        int32_t out = 0;
        start(&pid, &p);
        pid_step(&pid, 0, 0, 0, 0, 0); /* bumpless start at 0 */
        for (k = 0; k < n; k++) {
            out = pid_step(&pid, 10000, 0, 0, 0, 0); /* 10 um */
        }
        /* 8e3 V/(m s) * 1e-5 m * n / f s = 20 mV at 0.25 s */
        TEST_ASSERT_INT32_WITHIN(1, (int32_t)lround(8e3 * 1e-5 * n / rates[r] * 1e3), out);
    }
}

/* D on the error, unfiltered: Kd * de/dt exactly; filtered: first order. */
static void test_derivative_and_filter(void)
{
    pid_params_t p = params(0, 0, 5, 10000);
    pid_loop_t pid;
    double d = 0, alpha;
    unsigned k;
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    /* ramp 100 nm per tick = 1 mm/s: 5 V*s/m * 1e-3 m/s = 5 mV */
    TEST_ASSERT_EQUAL_INT32(5, pid_step(&pid, 100, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(5, pid_step(&pid, 200, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 200, 0, 0, 0, 0));

    p.d_tau_us = 1000; /* 1 ms at 10 kHz: alpha = 1/11 */
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    alpha = 1.0 / 11.0;
    for (k = 1; k <= 50; k++) {
        pid_step(&pid, (pos_nm_t)k * 1000, 0, 0, 0, 0); /* 10 mm/s: 50 mV */
        d += alpha * (50.0 - d);
        TEST_ASSERT_DOUBLE_WITHIN(1e-3, d, (double)pid.dterm / 4294967296.0);
    }
}

/* D on the measurement ignores reference steps; D on the error kicks. */
static void test_derivative_on_measurement_has_no_setpoint_kick(void)
{
    pid_params_t p = params(0, 0, 5, 10000);
    pid_loop_t pid;
    p.d_on_measurement = true;
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 1000000, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(-50, pid_step(&pid, 1000000, 1000, 0, 0, 0)); /* moving +10 mm/s */
    p.d_on_measurement = false;
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(50000, pid_step(&pid, 1000000, 0, 0, 0, 0));
}

static void test_feed_forward(void)
{
    pid_params_t p = params(0, 0, 0, 10000);
    pid_loop_t pid;
    p.kvff = Q32(20.0); /* V per m/s */
    p.kaff = Q32(0.5);  /* V per m/s^2 */
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(2000, pid_step(&pid, 0, 0, 100000000, 0, 0));   /* 0.1 m/s */
    TEST_ASSERT_EQUAL_INT32(-500, pid_step(&pid, 0, 0, 0, -1000000000, 0)); /* -1 m/s^2 */
    TEST_ASSERT_EQUAL_INT32(2500, pid_step(&pid, 0, 0, 100000000, 1000000000, 0));
    /* 5 m/s and 100 m/s^2 (beyond int32 nm units) still scale linearly */
    TEST_ASSERT_EQUAL_INT32(100000, pid_step(&pid, 0, 0, 5000000000LL, 0, 0));
    TEST_ASSERT_EQUAL_INT32(50000, pid_step(&pid, 0, 0, 0, 100000000000LL, 0));
    /* extra input (U) adds before the clamp */
    TEST_ASSERT_EQUAL_INT32(7, pid_step(&pid, 0, 0, 0, 0, (int64_t)7 << 32));
}

static void test_saturation_flag_and_counters(void)
{
    pid_params_t p = params(1.5e3, 0, 0, 10000);
    pid_loop_t pid;
    unsigned k;
    p.out_max_mv = 10000;
    start(&pid, &p);
    for (k = 0; k < 5; k++) {
        TEST_ASSERT_EQUAL_INT32(10000, pid_step(&pid, 100000000, 0, 0, 0, 0)); /* 150 V wanted */
        TEST_ASSERT_TRUE(pid.saturated);
        TEST_ASSERT_EQUAL_UINT32(k + 1, pid.sat_ticks);
    }
    TEST_ASSERT_EQUAL_INT32(-10000, pid_step(&pid, -100000000, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_UINT32(6, pid.sat_ticks);
    TEST_ASSERT_EQUAL_INT32(1500, pid_step(&pid, 1000000, 0, 0, 0, 0));
    TEST_ASSERT_FALSE(pid.saturated);
    TEST_ASSERT_EQUAL_UINT32(0, pid.sat_ticks);
    TEST_ASSERT_EQUAL_UINT32(6, pid.sat_total);
}

/* Saturate for 2.5 s with a constant error, then reverse the error: with
 * back-calculation the integrator stays near the clamp boundary and the
 * output leaves saturation quickly; without it the integrator winds up to its
 * clamp and the output stays saturated much longer. */
static unsigned windup_recovery_ticks(q32_32_t kt, int64_t *integ_after)
{
    pid_params_t p = params(1.5e3, 8e3, 0, 10000);
    pid_loop_t pid;
    unsigned k;
    p.out_max_mv = 20000;
    p.i_max_mv = 160000;
    p.kt = kt;
    start(&pid, &p);
    for (k = 0; k < 25000; k++) {
        pid_step(&pid, 10000000, 0, 0, 0, 0); /* 10 mm: P alone 15 V, I grows */
    }
    *integ_after = pid.integ;
    for (k = 0; k < 100000; k++) {
        pid_step(&pid, -1000000, 0, 0, 0, 0); /* -1 mm */
        if (!pid.saturated) {
            return k;
        }
    }
    return k;
}

static void test_anti_windup_back_calculation(void)
{
    int64_t i_bc, i_clamp;
    unsigned t_bc = windup_recovery_ticks(Q32(200.0), &i_bc);
    unsigned t_clamp = windup_recovery_ticks(0, &i_clamp);
    /* clamp only: the integrator reaches its clamp (160 V) */
    TEST_ASSERT_EQUAL_INT64((int64_t)160000 << 32, i_clamp);
    /* back-calculation: equilibrium Ki*e = Kt*(raw - u): I = u - P + Ki e / Kt
     * = 20 - 15 + 8e3 * 0.01 / 200 = 5.4 V */
    TEST_ASSERT_DOUBLE_WITHIN(0.05, 5.4, (double)i_bc / 4294967296.0 / 1000.0);
    TEST_ASSERT_TRUE(t_bc < 5);
    TEST_ASSERT_TRUE(t_clamp > 1000);
}

static void test_integrator_clamp(void)
{
    pid_params_t p = params(0, 8e6, 0, 1000);
    pid_loop_t pid;
    unsigned k;
    p.i_max_mv = 3000;
    start(&pid, &p);
    for (k = 0; k < 1000; k++) {
        pid_step(&pid, 1000000, 0, 0, 0, 0);
    }
    TEST_ASSERT_EQUAL_INT32(3000, pid.out_mv);
    TEST_ASSERT_FALSE(pid.saturated);
    for (k = 0; k < 1000; k++) {
        pid_step(&pid, -1000000, 0, 0, 0, 0);
    }
    TEST_ASSERT_EQUAL_INT32(-3000, pid.out_mv);
}

static void test_deadband_is_continuous(void)
{
    pid_params_t p = params(1e6, 1e6, 0, 10000); /* 1 mV/nm */
    pid_loop_t pid;
    unsigned k;
    p.deadband_nm = 100;
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    for (k = 0; k < 100; k++) {
        TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 100, 0, 0, 0, 0));
        TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 0, 100, 0, 0, 0));
    }
    /* just outside: e - db */
    p.ki = 0;
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(1, pid_step(&pid, 101, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(-900, pid_step(&pid, 0, 1000, 0, 0, 0));
}

static void test_bumpless_enable(void)
{
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t pid;
    int32_t a, b;
    memset(&pid, 0, sizeof pid);
    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&pid, &p));
    /* disabled: output 0 while tracking a moving axis */
    TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 5000, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT32(0, pid_step(&pid, 5000, 200, 0, 0, 0));
    pid_enable(&pid, 1234);
    a = pid_step(&pid, 5000, 200, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(1234, a);
    b = pid_step(&pid, 5000, 200, 0, 0, 0);
    /* continues smoothly: only the integral of one tick and D of no motion */
    TEST_ASSERT_INT32_WITHIN(3, 1234, b);
}

static void test_bumpless_gain_change(void)
{
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t pid;
    int32_t before, after;
    unsigned k;
    start(&pid, &p);
    for (k = 0; k < 100; k++) {
        before = pid_step(&pid, 2000000, (pos_nm_t)k * 10, 0, 0, 0);
    }
    p.kp = Q32(3e3);
    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&pid, &p));
    after = pid_step(&pid, 2000000, 1000, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT32(before, after);
    /* and then the new gain acts: a 1 mm error change moves the output by 3 V */
    before = pid_step(&pid, 2000000, 1000, 0, 0, 0);
    after = pid_step(&pid, 3000000, 1000, 0, 0, 0);
    TEST_ASSERT_INT32_WITHIN(60, 3000 + 50000, after - before); /* P + D kick (on error) */
}

static void test_reset(void)
{
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t pid;
    unsigned k;
    int32_t last = 0;
    start(&pid, &p);
    for (k = 0; k < 1000; k++) {
        last = pid_step(&pid, 1000000, 0, 0, 0, 0);
    }
    TEST_ASSERT_TRUE(pid.integ > 0);
    /* bumpless reset: the output continues */
    pid_reset(&pid, true);
    TEST_ASSERT_EQUAL_INT32(last, pid_step(&pid, 1000000, 0, 0, 0, 0));
    /* hard reset: integral and D cleared, no derivative kick on the first step */
    pid_reset(&pid, false);
    TEST_ASSERT_EQUAL_INT64(0, pid.integ);
    TEST_ASSERT_INT32_WITHIN(1, 1500 + 1, pid_step(&pid, 1000000, 0, 0, 0, 0));
    TEST_ASSERT_EQUAL_INT64(0, pid.dterm);
}

/* A homing/index reset moves measurement and reference by 1 m while the axis
 * moves at 0.1 m/s with feed-forward: the output must not jump. */
static void test_position_reset_no_spike(void)
{
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t pid, bad;
    pos_nm_t off = 0, pos = 0;
    int32_t prev = 0, out, bad_out;
    unsigned k;
    p.d_on_measurement = true;
    p.kvff = Q32(25.0);
    p.kaff = Q32(0.02);
    start(&pid, &p);
    start(&bad, &p);
    for (k = 0; k < 2000; k++) {
        pos += 10000; /* 0.1 m/s at 10 kHz */
        if (k == 1000) {
            off = 1000000000;
            pid_rebase(&pid, off);
        }
        out = pid_step(&pid, pos + 5000 + off, pos + off, 100000000, 0, 0);
        bad_out = pid_step(&bad, pos + 5000 + off, pos + off, 100000000, 0, 0);
        if (k > 10) {
            TEST_ASSERT_INT32_WITHIN(2, prev, out);
        }
        if (k == 1000) {
            /* the same loop without the rebase sees a 1 m step in 0.1 ms */
            TEST_ASSERT_TRUE(abs(bad_out - out) > 100000);
        }
        prev = out;
    }
}

static void test_config_validation_all_or_nothing(void)
{
    pid_params_t good = params(1.5e3, 8e3, 5, 10000), p;
    pid_loop_t pid;
    pid_loop_t copy;
    start(&pid, &good);
    pid_step(&pid, 1000, 0, 0, 0, 0);
    copy = pid;

    p = good;
    p.tick_hz = 99;
    TEST_ASSERT_EQUAL_INT(PID_ERR_TICK_HZ, pid_config(&pid, &p));
    p.tick_hz = 100001;
    TEST_ASSERT_EQUAL_INT(PID_ERR_TICK_HZ, pid_config(&pid, &p));
    p = good;
    p.kd = -1;
    TEST_ASSERT_EQUAL_INT(PID_ERR_GAIN, pid_config(&pid, &p));
    p = good;
    p.kvff = PID_GAIN_MAX;
    TEST_ASSERT_EQUAL_INT(PID_ERR_GAIN, pid_config(&pid, &p));
    p = good;
    p.out_max_mv = 0;
    TEST_ASSERT_EQUAL_INT(PID_ERR_OUT_MAX, pid_config(&pid, &p));
    p.out_max_mv = PID_MV_MAX + 1;
    TEST_ASSERT_EQUAL_INT(PID_ERR_OUT_MAX, pid_config(&pid, &p));
    p = good;
    p.i_max_mv = -1;
    TEST_ASSERT_EQUAL_INT(PID_ERR_I_MAX, pid_config(&pid, &p));
    p = good;
    p.deadband_nm = -5;
    TEST_ASSERT_EQUAL_INT(PID_ERR_DEADBAND, pid_config(&pid, &p));
    p = good;
    p.d_tau_us = PID_DFILT_US_MAX + 1;
    TEST_ASSERT_EQUAL_INT(PID_ERR_D_FILTER, pid_config(&pid, &p));
    TEST_ASSERT_EQUAL_INT(PID_ERR_NULL, pid_config(&pid, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&copy, &pid, sizeof pid);
}

/* Largest gains at the fastest tick with extreme inputs: no overflow (UBSan
 * runs these tests), outputs clamped. */
static void test_extremes(void)
{
    pid_params_t p = params(1.0737e9, 1.0737e9, 1.0737e9, PID_TICK_HZ_MAX);
    pid_loop_t pid;
    p.kvff = PID_GAIN_MAX - 1;
    p.kaff = PID_GAIN_MAX - 1;
    p.kt = PID_GAIN_MAX - 1;
    p.out_max_mv = PID_MV_MAX;
    p.i_max_mv = PID_MV_MAX;
    start(&pid, &p);
    TEST_ASSERT_EQUAL_INT32(PID_MV_MAX,
                            pid_step(&pid, INT64_MAX, INT64_MIN, INT64_MAX, INT64_MAX, INT64_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, pid.err_nm);
    TEST_ASSERT_EQUAL_INT32(-PID_MV_MAX,
                            pid_step(&pid, INT64_MIN, INT64_MAX, INT64_MIN, INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_INT32(PID_MV_MAX,
                            pid_step(&pid, INT64_MAX, INT64_MIN, INT64_MAX, INT64_MAX, INT64_MAX));
    TEST_ASSERT_TRUE(pid.saturated);
    /* smallest tick rate with tiny gains: nothing rounds to a wrong sign */
    p = params(1e-3, 1e-3, 1e-3, PID_TICK_HZ_MIN);
    start(&pid, &p);
    pid_step(&pid, 0, 0, 0, 0, 0);
    TEST_ASSERT_TRUE(pid_step(&pid, 1000000000, 0, 0, 0, 0) >= 0);
    TEST_ASSERT_TRUE(pid.out > 0);
}

/* The error and the derivative input are the exact difference saturated to
 * int32 (fx_sat_diff32) for any pair of int64 positions, overflowing
 * differences included, and the coefficient products with every shift
 * equal the rounded, clamped exact value (pid_coef_apply). */
static void test_error_and_products_exact(void)
{
    static const int64_t v[] = {INT64_MIN,
                                INT64_MIN + 1,
                                -((int64_t)1 << 62),
                                (int64_t)INT32_MIN - 1,
                                INT32_MIN,
                                -1,
                                0,
                                1,
                                INT32_MAX,
                                (int64_t)INT32_MAX + 1,
                                (int64_t)1 << 62,
                                INT64_MAX - 1,
                                INT64_MAX};
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t pid;
    unsigned i, j;
    int sh;

    p.d_on_measurement = true;
    start(&pid, &p);
    for (i = 0; i < 13; i++) {
        for (j = 0; j < 13; j++) {
            pid_step(&pid, v[i], v[j], 0, 0, 0);
            TEST_ASSERT_EQUAL_INT32(fx_sat_diff32(v[i], v[j]), pid.err_nm);
            TEST_ASSERT_EQUAL_INT64(v[j], pid.meas_prev);
        }
    }
    for (sh = -31; sh <= 62; sh++) {
        static const int32_t xs[] = {INT32_MIN, -3, -1, 0, 1, 2, 3, 12345, INT32_MAX};
        static const int32_t ms[] = {INT32_MIN + 1, -1, 1, 3, 1 << 30, INT32_MAX};
        for (i = 0; i < 9; i++) {
            for (j = 0; j < 6; j++) {
                pid_coef_t c = {ms[j], sh};
                i128 prod = (i128)xs[i] * ms[j], ref;
                if (sh > 0) {
                    ref = (prod + ((i128)1 << (sh - 1))) >> sh; /* half up */
                } else {
                    ref = prod * ((i128)1 << -sh);
                }
                if (ref > PID_TERM_LIM) {
                    ref = PID_TERM_LIM;
                } else if (ref < -PID_TERM_LIM) {
                    ref = -PID_TERM_LIM;
                }
                TEST_ASSERT_EQUAL_INT64((int64_t)ref, pid_coef_apply(c, xs[i]));
            }
        }
    }
}

/* The short path (pid->fast: shifts 2..31, no deadband, no feed-forward)
 * against the general one on a copy with fast cleared: every state and
 * output field equal after each step, over errors across int32 (saturated
 * differences included), measurements far apart (D input saturation),
 * extra inputs up to and beyond the term clamp, both D sources, with and
 * without the D filter, and gains that make the shifts span 2..31. */
static uint64_t lcg_state = 12345;

static int64_t rnd64(void)
{
    lcg_state = lcg_state * 6364136223846793005ull + 1442695040888963407ull;
    return (int64_t)(lcg_state ^ (lcg_state >> 29));
}

/* The D filter's product round(x * alpha / 2^30) (two 32-bit products in
 * pid.c) against the exact 128-bit value on the general path, with D inputs
 * from 1 nm to the int32 limit per tick and filter factors from 2^30 / 1001
 * to 2^30 / 2 (so |x| reaches the 2^61 of its stated range); the fast
 * path's 32-bit filter against the same exact recurrence within its stated
 * bound (4 F), the large inputs taking the general path. */
static void test_d_filter_product_exact(void)
{
    static const double kd[] = {1e-3, 5, 1e3, 2e5};
    static const uint32_t tau_us[] = {10, 100, 10000};
    size_t g, t;
    int fast, k, fast_runs = 0, fast_steps = 0;
    int64_t exact;

    for (g = 0; g < sizeof kd / sizeof kd[0]; g++) {
        for (t = 0; t < sizeof tau_us / sizeof tau_us[0]; t++) {
            for (fast = 0; fast < 2; fast++) {
                pid_params_t p = params(1e3, 1e4, kd[g], 10000);
                pid_loop_t a;
                pos_nm_t meas = 0;
                p.d_on_measurement = true;
                p.d_tau_us = tau_us[t];
                start(&a, &p);
                pid_step(&a, 0, 0, 0, 0, 0);
                if (fast && !a.fast) {
                    continue; /* shifts outside the short path's range */
                }
                TEST_ASSERT_TRUE(!fast || a.ready);
                fast_runs += fast;
                TEST_ASSERT_TRUE(a.alpha_q30 < FX_ONE_Q30);
                exact = pid_dterm(&a);
                for (k = 0; k < 300; k++) {
                    int64_t r = rnd64();
                    int sh = (int)((uint64_t)r >> 59); /* 0..31 */
                    pos_nm_t next = meas + ((r & 0xFFFFFFFF) >> sh) - ((int64_t)1 << (31 - sh));
                    int32_t de = fx_sat_diff32(meas, next);
                    int64_t draw = pid_coef_apply(a.cd, de), prev = a.dterm;
                    i128 x = (i128)draw - prev;
                    int64_t want = prev + (int64_t)((x * a.alpha_q30 + ((i128)1 << 29)) >> 30);
                    i128 xe = (i128)draw - exact;
                    exact += (int64_t)((xe * a.alpha_q30 + ((i128)1 << 29)) >> 30);
                    if (fast) {
                        pid_step(&a, next, next, 0, 0, 0);
                    } else {
                        pid_step_general(&a, fx_sat_diff32(next, next), next, 0, 0, 0);
                    }
                    TEST_ASSERT_TRUE(fast || (x <= ((i128)1 << 61) && x >= -((i128)1 << 61)));
                    if (fast) { /* 32-bit D: the stated bound against the exact filter */
                        TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, exact, pid_dterm(&a));
                        fast_steps += a.dq_live;
                    } else {
                        TEST_ASSERT_EQUAL_INT64(want, a.dterm);
                        TEST_ASSERT_EQUAL_INT64(exact, a.dterm);
                    }
                    meas = next;
                }
            }
        }
    }
    TEST_ASSERT_TRUE(fast_runs >= 6);
    TEST_ASSERT_TRUE(fast_steps >= 6 * 250); /* mostly on the fast path */
}

/* The fast path's 32-bit D filter at the smallest filter factor (the
 * longest time constant, PID_DFILT_US_MAX, at the fastest tick): its error
 * accumulates over about 1 / alpha steps, the worst case of pid.h's bound.
 * One million steps of a slowly wandering measurement against the exact
 * recurrence: within 4 F at every step. */
static void test_d_filter_bound_at_the_longest_time_constant(void)
{
    pid_params_t p = params(1e3, 1e4, 2e3, PID_TICK_HZ_MAX);
    pid_loop_t a;
    pos_nm_t meas = 0;
    int64_t exact, worst = 0;
    int32_t v = 0;
    int k, live = 0;

    p.d_on_measurement = true;
    p.d_tau_us = PID_DFILT_US_MAX;
    start(&a, &p);
    pid_step(&a, 0, 0, 0, 0, 0);
    TEST_ASSERT_TRUE(a.fast && a.alpha_q30 < 1200); /* about 2^30 / 1e6 */
    exact = pid_dterm(&a);
    for (k = 0; k < 1000000; k++) {
        int64_t r = rnd64(), d;
        pos_nm_t next;
        int32_t de;
        i128 xe;
        v += (int32_t)(r % 7) - 3; /* nm per tick, a random walk */
        if (v > 2000 || v < -2000) {
            v = 0;
        }
        next = meas + v;
        de = fx_sat_diff32(meas, next);
        xe = (i128)pid_coef_apply(a.cd, de) - exact;
        exact += (int64_t)((xe * a.alpha_q30 + ((i128)1 << 29)) >> 30);
        pid_step(&a, next, next, 0, 0, 0);
        live += a.dq_live;
        d = pid_dterm(&a) - exact;
        d = d < 0 ? -d : d;
        worst = d > worst ? d : worst;
        meas = next;
    }
    printf("D filter at alpha_q30 %d: worst %.3f F over 1e6 steps (bound 4 F)\n", (int)a.alpha_q30,
           (double)worst / (double)((int64_t)1 << 21));
    TEST_ASSERT_TRUE(live > 900000); /* on the fast path */
    TEST_ASSERT_TRUE(worst <= FAST_TOL_U);
}

/* The cached pid->ready equals fast && primed && enabled && !bumpless after
 * every call that writes one of them (config on a new and on a running loop,
 * enable, steps, both resets, disable), for a fast and a deadband (not fast)
 * configuration. */
static bool ready_expected(const pid_loop_t *pid)
{
    return pid->fast && pid->primed && pid->enabled && !pid->bumpless;
}

static void test_ready_cache_follows_inputs(void)
{
    int db, seen_ready = 0, k;

    for (db = 0; db < 2; db++) {
        pid_params_t p = params(1.5e3, 8e3, 5, 10000);
        pid_loop_t pid;
        int32_t want;
        p.deadband_nm = db ? 10 : 0;
        memset(&pid, 0, sizeof pid);
#define CHECK_READY()                                                                              \
    do {                                                                                           \
        TEST_ASSERT_TRUE(pid.ready == ready_expected(&pid));                                       \
        seen_ready += pid.ready;                                                                   \
    } while (0)
        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&pid, &p));
        TEST_ASSERT_TRUE(pid.fast == (db == 0));
        CHECK_READY();
        pid_step(&pid, 100, 0, 0, 0, 0);
        CHECK_READY();
        pid_enable(&pid, 500);
        CHECK_READY();
        for (k = 0; k < 3; k++) {
            pid_step(&pid, 100, k, 0, 0, 0);
            CHECK_READY();
        }
        pid_reset(&pid, true);
        CHECK_READY();
        pid_step(&pid, 100, 5, 0, 0, 0);
        CHECK_READY();
        p.kp = Q32(2e3);
        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&pid, &p));
        CHECK_READY();
        TEST_ASSERT_FALSE(pid.ready); /* bumpless gain change pending */
        pid_step(&pid, 100, 5, 0, 0, 0);
        CHECK_READY();
        pid_reset(&pid, false);
        CHECK_READY();
        want = pid_step(&pid, 100, 5, 0, 0, 0);
        CHECK_READY();
        TEST_ASSERT_EQUAL_INT32(want, pid.out_mv);
        pid_disable(&pid);
        CHECK_READY();
        TEST_ASSERT_FALSE(pid.ready);
        pid_step(&pid, 100, 5, 0, 0, 0);
        CHECK_READY();
#undef CHECK_READY
    }
    TEST_ASSERT_TRUE(seen_ready >= 5); /* the fast loop did become ready */
}

/* From feed-forward gains (general path, ff != 0) to a fast configuration
 * on a running loop: the short path does not write ff, so the general step
 * the bumpless change forces must leave it 0; the outputs then stay within
 * the fast path's bound of a loop stepped on the general path only. */
static void test_fast_after_feed_forward_config(void)
{
    pid_params_t p = params(1.5e3, 8e3, 5, 10000);
    pid_loop_t a, b;
    int k;
    p.kvff = Q32(20);
    start(&a, &p);
    for (k = 0; k < 5; k++) {
        pid_step(&a, 1000 + k, k, 300000000, 0, 0);
    }
    TEST_ASSERT_FALSE(a.fast);
    TEST_ASSERT_TRUE(a.ff != 0);
    p.kvff = 0;
    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
    TEST_ASSERT_TRUE(a.fast && !a.ready);
    b = a;
    for (k = 0; k < 5; k++) {
        pid_step(&a, 2000 + k * 7, k, 300000000, 0, 0);
        pid_step_general(&b, 2000 + k * 7 - k, k, 300000000, 0, 0); /* e = ref - meas */
        TEST_ASSERT_TRUE(a.ready);
        TEST_ASSERT_EQUAL_INT64(0, a.ff);
        /* the fast path's bound (pid.h): 4 F = 2^23 U */
        TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, b.out, a.out);
        TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, b.integ, a.integ);
    }
}

/* The fast path against the general (exact) path: two loops from the same
 * start, one stepped through pid_step / pid_step_fast / pid_step_fast0 (the
 * fast path wherever it applies), the other through pid_step_general only,
 * over errors across int32, measurements far apart (D inputs beyond the
 * fast range: the general fallback and the hand-back), extra inputs up to
 * and beyond the term clamp (saturation, back-calculation), both D sources,
 * with and without the D filter, and gains and tick rates whose shifts span
 * the range. Every step: out_mv within 1 mV, u (U), the integrator and the
 * D term within the stated 4 F (pid.h). */
static void test_fast_path_matches_general(void)
{
    /* Kp, Ki, Kd, tick rate: shifts from 2 (1e5, 1e7, 1e3 at 100 Hz) to
     * 28 (1e-3, 0.1, 1e-3 at 100 Hz) */
    static const double gains[][4] = {
        {1.5e3, 8e3, 5, 5000}, {1e-3, 0.1, 1e-3, 100}, {1e5, 1e7, 1e3, 100},
        {4e4, 2e6, 100, 100},  {10, 100, 0.1, 5000},   {1e3, 1e5, 1, 100000},
    };
    int fast_seen = 0, shifts[33] = {0}, fast0_runs = 0, fast_steps = 0, general_steps = 0;
    int64_t worst_u = 0, worst_i = 0, worst_d = 0;
    int worst_mv = 0;
    size_t g;
    int d, k;

    for (g = 0; g < sizeof gains / sizeof gains[0]; g++) {
        for (d = 0; d < 4; d++) {
            pid_params_t p = params(gains[g][0], gains[g][1], gains[g][2], (uint32_t)gains[g][3]);
            pid_loop_t a, b;
            pos_nm_t meas = 0;
            p.d_on_measurement = (d & 1) != 0;
            p.d_tau_us = (d & 2) ? 100u : 0u;
            p.kt = Q32(10);
            memset(&a, 0, sizeof a);
            TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
            if (!a.fast) {
                continue;
            }
            fast_seen++;
            shifts[a.cp.sh]++;
            shifts[a.ci.sh]++;
            shifts[a.cd.sh]++;
            pid_enable(&a, 0);
            b = a;
            for (k = 0; k < 2000; k++) {
                int64_t r = rnd64();
                int sel = (int)((uint64_t)r >> 60);
                /* mostly small moves (the fast range), some far jumps */
                pos_nm_t ref = meas + ((sel < 12) ? (r >> 50) : (sel < 14) ? (r >> 34) : (r >> 8));
                pos_nm_t next = (sel == 15) ? rnd64() >> (k % 40) : meas + (rnd64() >> 52);
                int64_t extra = (sel < 6) ? 0 : rnd64() >> (40 - (sel % 6) * 5);
                int32_t e = fx_sat_diff32(ref, next);
                int32_t u, ub;
                bool was_ready = a.ready;
                if (was_ready && extra == 0 && (k & 1)) {
                    u = pid_step_fast0(&a, e, next);
                    fast0_runs++;
                } else if (was_ready && (k & 2)) {
                    u = pid_step_fast(&a, e, next, extra);
                } else {
                    u = pid_step(&a, ref, next, 0, 0, extra);
                }
                fast_steps += was_ready && a.dq_live;
                general_steps += !was_ready;
                ub = pid_step_general(&b, e, next, 0, 0, extra);
                TEST_ASSERT_EQUAL_INT32(a.out_mv, u);
                TEST_ASSERT_INT_WITHIN(1, ub, u);
                TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, b.out, a.out);
                TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, b.integ, a.integ);
                TEST_ASSERT_INT64_WITHIN(FAST_TOL_U, pid_dterm(&b), pid_dterm(&a));
                TEST_ASSERT_EQUAL(b.saturated || a.saturated, a.saturated || b.saturated);
                worst_mv = abs(u - ub) > worst_mv ? abs(u - ub) : worst_mv;
                worst_u = llabs(a.out - b.out) > worst_u ? llabs(a.out - b.out) : worst_u;
                worst_i = llabs(a.integ - b.integ) > worst_i ? llabs(a.integ - b.integ) : worst_i;
                worst_d = llabs(pid_dterm(&a) - pid_dterm(&b)) > worst_d
                              ? llabs(pid_dterm(&a) - pid_dterm(&b))
                              : worst_d;
                meas = next;
            }
        }
    }
    printf("fast vs general: out %d mV, u %.3f F, I %.3f F, D %.3f F; %d fast, %d general steps\n",
           worst_mv, (double)worst_u / (1 << 21), (double)worst_i / (1 << 21),
           (double)worst_d / (1 << 21), fast_steps, general_steps);
    TEST_ASSERT_TRUE(fast0_runs >= 100);               /* extra = 0 was covered */
    TEST_ASSERT_TRUE(fast_steps >= 10000);             /* mostly on the fast path */
    TEST_ASSERT_TRUE(general_steps >= 50);             /* and the fallback */
    TEST_ASSERT_EQUAL_INT(24, fast_seen);              /* every set takes the short path */
    TEST_ASSERT_TRUE(shifts[2] > 0 && shifts[28] > 0); /* both ends of the range */
    TEST_ASSERT_TRUE(worst_u > 0);                     /* the paths do differ (by rounding) */
}

/* The 32-bit-pieces rounding of a coefficient (what the Cortex-M4 runs)
 * and the form this host compiles give the same value: every shift 1..31,
 * extreme and random products. */
static void test_coef_pieces_equal_wide(void)
{
    static const int32_t xs[] = {0,          1,           -1,        2,         -2,
                                 3,          -3,          INT32_MAX, INT32_MIN, INT32_MIN + 1,
                                 0x40000000, -0x40000000, 12345,     -12345};
    static const int32_t ms[] = {1, -1, 0x7FFFFFFF, -0x7FFFFFFF, 0x40000000, -0x40000000, 3, -3};
    int32_t sh;
    unsigned i, j, k;

    for (sh = 1; sh <= 31; sh++) {
        for (i = 0; i < sizeof xs / sizeof xs[0]; i++) {
            for (j = 0; j < sizeof ms / sizeof ms[0]; j++) {
                pid_coef_t c = {ms[j], sh};
                TEST_ASSERT_EQUAL_INT64(pid_coef_pieces_test(c, xs[i]), pid_coef_apply(c, xs[i]));
            }
        }
        for (k = 0; k < 20000u; k++) {
            int32_t m = (int32_t)((uint64_t)rnd64() % 0x7FFFFFFFu);
            pid_coef_t c = {m, sh};
            int32_t x = (int32_t)rnd64();
            TEST_ASSERT_EQUAL_INT64(pid_coef_pieces_test(c, x), pid_coef_apply(c, x));
        }
    }
}

/* The lean general step (pid.h): pid_step_e with feed-forward against
 * pid_step_general on a copy, every output and state field equal after
 * every step (tolerance 0), D on the error and on the measurement, with
 * saturation and anti-windup, the extra input, a bumpless gain change and
 * a reset mid-run (those steps take the general path). */
static void test_lean_step_equals_general(void)
{
    static const double gains[][6] = {
        /* Kp, Ki, Kd, Kvff, Kaff, tick rate */
        {1300, 2e4, 2, 16.49, 0.1247, 10000},
        {1500, 8e3, 5, 16.49, 0.1078, 5000},
        {40, 100, 0.1, 1, 0.01, 1000},
        {2e4, 2e6, 0.02, 30, 0.5, 100000},
    };
    int lean_steps = 0, sat_steps = 0;
    size_t g;
    int d, k;

    for (g = 0; g < sizeof gains / sizeof gains[0]; g++) {
        for (d = 0; d < 2; d++) {
            pid_params_t p = params(gains[g][0], gains[g][1], gains[g][2], (uint32_t)gains[g][5]);
            pid_loop_t a, b;
            pos_nm_t meas = 0;
            p.kvff = Q32(gains[g][3]);
            p.kaff = Q32(gains[g][4]);
            p.d_on_measurement = d != 0;
            p.d_tau_us = 200u;
            p.kt = Q32(10);
            p.out_max_mv = 10000;
            p.i_max_mv = 8000;
            memset(&a, 0, sizeof a);
            TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
            TEST_ASSERT_TRUE(a.lean);
            pid_enable(&a, 0);
            b = a;
            for (k = 0; k < 20000; k++) {
                int64_t r = rnd64();
                int sel = (int)((uint64_t)r >> 60);
                pos_nm_t ref = meas + ((sel < 12) ? (r >> 48) : (sel < 15) ? (r >> 30) : (r >> 4));
                pos_nm_t next = meas + (rnd64() >> 50);
                /* up to about 0.5 m/s and 1 m/s^2, now and then anything */
                int64_t vel = (sel == 15) ? rnd64() >> 8 : rnd64() >> (35 + (sel & 3));
                int64_t acc = (sel == 14) ? rnd64() >> 8 : rnd64() >> (33 + (sel & 3));
                int64_t extra = (sel < 8) ? 0 : rnd64() >> (22 + 2 * (sel - 8));
                int32_t e = fx_sat_diff32(ref, next);
                int32_t u, ub;
                if (k == 7000) {
                    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
                    TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&b, &p));
                }
                if (k == 10000) { /* three disabled steps, then on again */
                    pid_disable(&a);
                    pid_disable(&b);
                }
                if (k == 10003) {
                    pid_enable(&a, 100);
                    pid_enable(&b, 100);
                }
                if (k == 14000) {
                    pid_reset(&a, false);
                    pid_reset(&b, false);
                }
                if (k == 17000) {
                    pid_reset(&a, true);
                    pid_reset(&b, true);
                }
                /* the cached flag (pid_refresh_ready) is its definition */
                TEST_ASSERT_EQUAL(a.lean && a.enabled && a.primed && !a.bumpless && !a.dq_live,
                                  a.lean_rdy);
                lean_steps += a.lean_rdy;
                u = pid_step_e(&a, e, next, vel, acc, extra);
                ub = pid_step_general(&b, e, next, vel, acc, extra);
                sat_steps += a.saturated;
                TEST_ASSERT_EQUAL_INT32(ub, u);
                TEST_ASSERT_EQUAL_INT32(b.out_mv, a.out_mv);
                TEST_ASSERT_EQUAL_INT64(b.out, a.out);
                TEST_ASSERT_EQUAL_INT64(b.integ, a.integ);
                TEST_ASSERT_EQUAL_INT64(b.dterm, a.dterm);
                TEST_ASSERT_EQUAL_INT64(b.ff, a.ff);
                TEST_ASSERT_EQUAL_INT64(b.extra, a.extra);
                TEST_ASSERT_EQUAL_INT32(b.err_nm, a.err_nm);
                TEST_ASSERT_EQUAL_INT32(b.meas_prev, a.meas_prev);
                TEST_ASSERT_EQUAL(b.saturated, a.saturated);
                TEST_ASSERT_EQUAL_UINT32(b.sat_ticks, a.sat_ticks);
                TEST_ASSERT_EQUAL_UINT32(b.sat_total, a.sat_total);
                TEST_ASSERT_EQUAL(b.ready, a.ready);
                TEST_ASSERT_EQUAL(b.primed, a.primed);
                TEST_ASSERT_EQUAL(b.bumpless, a.bumpless);
                TEST_ASSERT_EQUAL(b.dq_live, a.dq_live);
                meas = next;
            }
        }
    }
    TEST_ASSERT_TRUE(lean_steps > 150000);                    /* the lean step ran */
    TEST_ASSERT_TRUE(sat_steps > 1000 && sat_steps < 100000); /* some saturated */
}

/* The rest step (pid.h): pid_step_e on a ready loop against the fast step
 * (pid_step_fast, or the general path while not ready) on a copy, every
 * output and state field equal after every step: long stretches at rest
 * (e = 0, the same measurement and extra input) broken by error bursts,
 * extra-input changes, integrator hand-overs (pid_add_integrator) and
 * saturation, D on the error and on the measurement, D filter on and off,
 * with and without an integrator. */
static void test_rest_step_equals_fast(void)
{
    static const double gains[][4] = {
        /* Kp, Ki, Kd, D filter us */
        {1300, 2e4, 2, 200},
        {1300, 2e4, 2, 0},
        {40, 0, 0.1, 1000},
        {2e4, 2e6, 0.02, 50},
    };
    uint64_t saved = lcg_state; /* the tests after this one draw as before */
    int rest_steps = 0, sat_steps = 0;
    size_t g;
    int d, k;

    for (g = 0; g < sizeof gains / sizeof gains[0]; g++) {
        for (d = 0; d < 2; d++) {
            pid_params_t p = params(gains[g][0], gains[g][1], gains[g][2], 10000);
            pid_loop_t a, b;
            pos_nm_t meas = 0;
            int64_t extra = 0;
            int burst = 0;
            p.d_on_measurement = d != 0;
            p.d_tau_us = (uint32_t)gains[g][3];
            p.kt = Q32(10);
            p.out_max_mv = 10000;
            p.i_max_mv = 8000;
            memset(&a, 0, sizeof a);
            TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
            TEST_ASSERT_TRUE(a.fast);
            pid_enable(&a, 0);
            b = a;
            for (k = 0; k < 20000; k++) {
                int64_t r = rnd64();
                int sel = (int)((uint64_t)r >> 58);
                pos_nm_t next = meas;
                int32_t e = 0, u, ub;
                if (burst > 0) {
                    burst--;
                    next = meas + (rnd64() >> ((sel & 1) ? 54 : 40));
                    e = (int32_t)(rnd64() >> ((sel & 2) ? 52 : 36));
                } else if (sel == 0) {
                    burst = 1 + (int)(((uint64_t)r >> 40) & 15u);
                } else if (sel == 1) {
                    extra = (r & 1) ? 0 : rnd64() >> 24;
                } else if (sel == 2) {
                    int64_t h = rnd64() >> 26;
                    pid_add_integrator(&a, h);
                    pid_add_integrator(&b, h);
                } else if (sel == 3) {
                    extra = rnd64() >> 1; /* beyond the clamps */
                } else if (sel == 4 && extra == fx_clamp_sym64(extra, PID_TERM_LIM)) {
                    /* integrator and extra input changed, I + extra as before */
                    int64_t before = a.integ, h = rnd64() >> 30;
                    pid_add_integrator(&a, h);
                    pid_add_integrator(&b, h);
                    extra -= a.integ - before;
                }
                if (a.ready && e == 0 && next == meas && a.err_nm == 0 && !a.saturated) {
                    rest_steps++;
                }
                u = pid_step_e(&a, e, next, 0, 0, extra);
                ub = pid_fast_ready(&b) ? pid_step_fast(&b, e, next, extra)
                                        : pid_step_general(&b, e, next, 0, 0, extra);
                sat_steps += a.saturated;
                TEST_ASSERT_EQUAL_INT32(ub, u);
                TEST_ASSERT_EQUAL_INT32(b.out_mv, a.out_mv);
                TEST_ASSERT_EQUAL_INT64(b.out, a.out);
                TEST_ASSERT_EQUAL_INT64(b.integ, a.integ);
                TEST_ASSERT_EQUAL_INT64(b.dq, a.dq);
                TEST_ASSERT_EQUAL_INT64(b.dterm, a.dterm);
                TEST_ASSERT_EQUAL_INT64(b.extra, a.extra);
                TEST_ASSERT_EQUAL_INT32(b.err_nm, a.err_nm);
                TEST_ASSERT_EQUAL_INT32(b.meas_prev, a.meas_prev);
                TEST_ASSERT_EQUAL(b.saturated, a.saturated);
                TEST_ASSERT_EQUAL_UINT32(b.sat_ticks, a.sat_ticks);
                TEST_ASSERT_EQUAL_UINT32(b.sat_total, a.sat_total);
                TEST_ASSERT_EQUAL(b.ready, a.ready);
                TEST_ASSERT_EQUAL(b.dq_live, a.dq_live);
                meas = next;
            }
        }
    }
    lcg_state = saved;
    TEST_ASSERT_TRUE(rest_steps > 60000);                    /* at rest most of the time */
    TEST_ASSERT_TRUE(sat_steps > 100 && sat_steps < 100000); /* some saturated */
}

/* Every field the steps compare (not the caches ready, lean_rdy, rest). */

static void assert_loops_equal(const pid_loop_t *b, const pid_loop_t *a)
{
    TEST_ASSERT_EQUAL_INT32(b->out_mv, a->out_mv);
    TEST_ASSERT_EQUAL_INT64(b->out, a->out);
    TEST_ASSERT_EQUAL_INT64(b->integ, a->integ);
    TEST_ASSERT_EQUAL_INT64(b->dq, a->dq);
    TEST_ASSERT_EQUAL_INT64(b->dterm, a->dterm);
    TEST_ASSERT_EQUAL_INT64(b->extra, a->extra);
    TEST_ASSERT_EQUAL_INT32(b->err_nm, a->err_nm);
    TEST_ASSERT_EQUAL_INT64(b->meas_prev, a->meas_prev);
    TEST_ASSERT_EQUAL(b->saturated, a->saturated);
    TEST_ASSERT_EQUAL_UINT32(b->sat_ticks, a->sat_ticks);
    TEST_ASSERT_EQUAL_UINT32(b->sat_total, a->sat_total);
    TEST_ASSERT_EQUAL(b->ready, a->ready);
    TEST_ASSERT_EQUAL(b->dq_live, a->dq_live);
    TEST_ASSERT_EQUAL(b->bumpless, a->bumpless);
    TEST_ASSERT_EQUAL_INT32(b->hold_mv, a->hold_mv);
}

/* The fast step's range test of its D input (|de| <= de_max, pid.h Fast
 * path) at its edges, D on the error and on the measurement, both signs:
 * at de_max the step equals the fast formula (a copy whose de_max admits
 * any input), one beyond it equals the general step on a copy. */
static void test_fast_d_input_range_edges(void)
{
    int d, sgn, k;

    for (d = 0; d < 2; d++) {
        for (sgn = -1; sgn <= 1; sgn += 2) {
            for (k = 0; k < 2; k++) {
                pid_params_t p = params(1300, 2e4, 2e3, 10000); /* de_max about 2^18 */
                pid_loop_t a, b;
                int64_t de;
                int32_t e = 1000;
                pos_nm_t meas = 5000;

                p.d_on_measurement = d != 0;
                p.d_tau_us = 200;
                start(&a, &p);
                pid_step_e(&a, e, meas, 0, 0, 0); /* primed: fast from here */
                pid_step_e(&a, e, meas, 0, 0, 0);
                TEST_ASSERT_TRUE(a.ready);
                TEST_ASSERT_TRUE(a.de_max < 0x7FFFFFFFu);
                de = sgn * ((int64_t)a.de_max + k);
                b = a;
                if (k == 0) {
                    b.de_max = 0x7FFFFFFFu;
                }
                if (d != 0) { /* de = meas_prev - meas */
                    pid_step_e(&a, e, meas - de, 0, 0, 0);
                    if (k == 0) {
                        pid_step_fast(&b, e, meas - de, 0);
                    } else {
                        pid_step_general(&b, e, meas - de, 0, 0, 0);
                    }
                } else { /* de = e - e_prev */
                    pid_step_e(&a, (int32_t)(e + de), meas, 0, 0, 0);
                    if (k == 0) {
                        pid_step_fast(&b, (int32_t)(e + de), meas, 0);
                    } else {
                        pid_step_general(&b, (int32_t)(e + de), meas, 0, 0, 0);
                    }
                }
                b.de_max = a.de_max;
                assert_loops_equal(&b, &a);
            }
        }
    }
}

/* The cached rest step (pid_rest_cached, 64-bit hosts) as the servo's axis
 * step takes it: a loop stepped by "pid_rest_cached ? out_mv : pid_step_e"
 * against a copy stepped by pid_step_e alone, through rest stretches broken
 * by every other writer of a loop (integrator hand-overs, fast steps with
 * and without the extra input, rebases, bumpless and hard resets,
 * disable/enable, gain changes, general steps) and by error bursts and
 * extra-input changes: every output and state field equal. */
static void test_rest_cached_equals_step(void)
{
    static const double gains[][4] = {
        /* Kp, Ki, Kd, D filter us */
        {1300, 2e4, 2, 200},
        {1300, 2e4, 2, 0},
        {2e4, 2e6, 0.02, 50},
    };
    uint64_t saved = lcg_state; /* the tests after this one draw as before */
    long hits = 0, writes = 0;
    size_t g;
    int d, k;

    for (g = 0; g < sizeof gains / sizeof gains[0]; g++) {
        for (d = 0; d < 2; d++) {
            pid_params_t p = params(gains[g][0], gains[g][1], gains[g][2], 10000);
            pid_loop_t a, b;
            pos_nm_t meas = 0;
            int64_t extra = 0;
            int burst = 0;
            p.d_on_measurement = d != 0;
            p.d_tau_us = (uint32_t)gains[g][3];
            p.kt = Q32(10);
            p.out_max_mv = 10000;
            p.i_max_mv = 8000;
            memset(&a, 0, sizeof a);
            TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &p));
            pid_enable(&a, 0);
            b = a;
            for (k = 0; k < 40000; k++) {
                int64_t r = rnd64();
                int sel = (int)((uint64_t)r >> 58);
                pos_nm_t next = meas;
                int32_t e = 0, u, ub;
                bool was_rest = a.rest;

                if (burst > 0) { /* the error, the measurement or both move */
                    burst--;
                    next = (sel & 4) ? meas : meas + (rnd64() >> ((sel & 1) ? 54 : 40));
                    e = (sel & 8) ? 0 : (int32_t)(rnd64() >> ((sel & 2) ? 52 : 36));
                } else if (sel == 0) {
                    burst = 1 + (int)(((uint64_t)r >> 40) & 3u);
                } else if (sel == 1) {
                    extra = (r & 1) ? 0 : rnd64() >> 24;
                } else if (sel == 2) {
                    extra = rnd64() >> 1; /* beyond the clamps */
                }
                if (sel >= 3 && sel <= 11) {
                    /* one write to both loops between two steps */
                    int64_t h = rnd64() >> 30;
                    writes += was_rest;
                    switch (sel) {
                    case 3:
                        pid_add_integrator(&a, h);
                        pid_add_integrator(&b, h);
                        break;
                    case 4: /* the servo's quiet fast step: no extra input */
                        if (a.ready) {
                            TEST_ASSERT_EQUAL_INT32(pid_step_fast0(&b, 0, meas),
                                                    pid_step_fast0(&a, 0, meas));
                        }
                        break;
                    case 5:
                        if (a.ready) {
                            TEST_ASSERT_EQUAL_INT32(pid_step_fast(&b, 0, meas, h),
                                                    pid_step_fast(&a, 0, meas, h));
                        }
                        break;
                    case 6:
                        pid_rebase(&a, h >> 8);
                        pid_rebase(&b, h >> 8);
                        next = meas + (h >> 8); /* at rest in the new frame */
                        break;
                    case 7:
                        pid_reset(&a, (r & 1) != 0);
                        pid_reset(&b, (r & 1) != 0);
                        break;
                    case 8:
                        pid_disable(&a);
                        pid_disable(&b);
                        pid_enable(&a, (int32_t)(h >> 20));
                        pid_enable(&b, (int32_t)(h >> 20));
                        break;
                    case 9: {
                        pid_params_t q = p;
                        q.kp = (r & 1) ? p.kp : p.kp / 2;
                        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&a, &q));
                        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&b, &q));
                        break;
                    }
                    case 10:
                        TEST_ASSERT_EQUAL_INT32(pid_step_general(&b, 0, meas, 0, 0, extra),
                                                pid_step_general(&a, 0, meas, 0, 0, extra));
                        break;
                    default: /* a fast step's end, saturated or not */
                        TEST_ASSERT_EQUAL_INT32(pid_fast_saturated(&b, r >> 17, b.integ),
                                                pid_fast_saturated(&a, r >> 17, a.integ));
                        break;
                    }
                    assert_loops_equal(&b, &a);
                }
                if (pid_rest_cached(&a, e, next, extra)) {
                    hits++;
                    u = a.out_mv;
                } else {
                    u = pid_step_e(&a, e, next, 0, 0, extra);
                }
                ub = pid_step_e(&b, e, next, 0, 0, extra);
                TEST_ASSERT_EQUAL_INT32(ub, u);
                assert_loops_equal(&b, &a);
                meas = next;
            }
        }
    }
    lcg_state = saved;
    printf("rest cached: %ld hits, %ld writes at rest\n", hits, writes);
    if (PID_REST) {
        /* long rest stretches, and writes in the middle of them */
        TEST_ASSERT_TRUE(hits > 50000);
        TEST_ASSERT_TRUE(writes > 5000);
    } else {
        TEST_ASSERT_EQUAL_INT32(0, hits);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_error_and_products_exact);
    RUN_TEST(test_coef_pieces_equal_wide);
    RUN_TEST(test_coef_make_matches_double);
    RUN_TEST(test_coef_make_edges);
    RUN_TEST(test_config_resolution_over_tick_rates);
    RUN_TEST(test_proportional_step);
    RUN_TEST(test_integral_ramp);
    RUN_TEST(test_derivative_and_filter);
    RUN_TEST(test_derivative_on_measurement_has_no_setpoint_kick);
    RUN_TEST(test_feed_forward);
    RUN_TEST(test_saturation_flag_and_counters);
    RUN_TEST(test_anti_windup_back_calculation);
    RUN_TEST(test_integrator_clamp);
    RUN_TEST(test_deadband_is_continuous);
    RUN_TEST(test_bumpless_enable);
    RUN_TEST(test_bumpless_gain_change);
    RUN_TEST(test_reset);
    RUN_TEST(test_position_reset_no_spike);
    RUN_TEST(test_config_validation_all_or_nothing);
    RUN_TEST(test_extremes);
    RUN_TEST(test_ready_cache_follows_inputs);
    RUN_TEST(test_fast_after_feed_forward_config);
    RUN_TEST(test_fast_path_matches_general);
    RUN_TEST(test_lean_step_equals_general);
    RUN_TEST(test_rest_step_equals_fast);
    RUN_TEST(test_rest_cached_equals_step);
    RUN_TEST(test_fast_d_input_range_edges);
    RUN_TEST(test_d_filter_product_exact);
    RUN_TEST(test_d_filter_bound_at_the_longest_time_constant);
    return UNITY_END();
}
