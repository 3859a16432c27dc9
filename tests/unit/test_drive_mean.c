/*
 * The mean measurement (drive.h enc_mean, issue 21):
 *   - off by default; a port whose hal_encoder_mean cannot answer refuses
 *     it: drive_init and the parameter (alone or in a set_all) return
 *     DRIVE_E_UNSUPPORTED and nothing changes; a port that can takes it;
 *   - the mean reading: with it on, the loops see the decoder's position
 *     plus hal_encoder_mean's lag scaled to nm (an axis holding still,
 *     P-only gains: the command is -Kp times the lag), the status keeps
 *     the decoder's own position; off, the lag is not read;
 *   - the reference alignment (drive_ff_step): on a line the position is
 *     moved to the mean over the tick, p - v T / 2 + a T^2 / 6; on an arc
 *     (both senses) the point and the tangent are those of the arc half a
 *     tick back, and a measured point at the tick's mean of the circle is
 *     moved back onto the circle; the feed-forward stays the command's;
 *     off, the reference itself is handed on;
 *   - the simulator's reading (sim.c): 0 at rest, and on an axis at
 *     constant speed half the counts of a tick behind the count (within a
 *     count's rounding).
 * The drive runs on the sim HAL without a plant (as test_drive_counter.c).
 */
#include <math.h>
#include <string.h>

#include "calib.h"
#include "drive.h"
#include "drive_ff.h"
#include "drive_inputs.h"
#include "drive_int.h"
#include "drive_test.h"
#include "hal_sim.h"
#include "sim.h"
#include "unity.h"

#include "drive_tick_fixture.h"

static void config(drive_config_t *cfg)
{
    unsigned i;
    drive_config_default(cfg, 10000, 2);
    for (i = 0; i < 2; i++) {
        cfg->nm_per_count_num[i] = 1250; /* 5 mm per 4000 counts */
        cfg->nm_per_count_den[i] = 1;
        /* P only, no feed-forward: the command is Kp times the error */
        cfg->servo.axis[i].kp = (q32_32_t)1000 << 32; /* 1000 V/m = 1 mV/um */
        cfg->servo.axis[i].ki = 0;
        cfg->servo.axis[i].kd = 0;
        cfg->servo.axis[i].kvff = 0;
        cfg->servo.axis[i].kaff = 0;
    }
}

static void test_off_by_default(void)
{
    drive_config_t cfg;
    int64_t v = -1;

    config(&cfg);
    TEST_ASSERT_FALSE(cfg.enc_mean);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_ENC_MEAN, 0, &v));
    TEST_ASSERT_EQUAL_INT64(0, v);
}

static void test_port_without_the_mean_refuses_it(void)
{
    drive_config_t cfg;
    drive_param_value_t set[2] = {{DRIVE_PARAM_FF_ADVANCE, 0, 50000}, {DRIVE_PARAM_ENC_MEAN, 0, 1}};
    int64_t v = -1;

    hal_sim_set_mean_port(false);
    config(&cfg);
    cfg.enc_mean = true;
    TEST_ASSERT_EQUAL_INT(DRIVE_E_UNSUPPORTED, drive_init(&cfg));
    cfg.enc_mean = false;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_UNSUPPORTED, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_ENC_MEAN, 0, &v));
    TEST_ASSERT_EQUAL_INT64(0, v);
    /* all or nothing: the advance in the same set is not taken either */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_UNSUPPORTED, drive_param_set_all(set, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_FF_ADVANCE, 0, &v));
    TEST_ASSERT_EQUAL_INT64(0, v);
    TEST_ASSERT_FALSE(drive_config()->enc_mean);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 0));
    /* a port that provides it takes it */
    hal_sim_set_mean_port(true);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set_all(set, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_ENC_MEAN, 0, &v));
    TEST_ASSERT_EQUAL_INT64(1, v);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 2));
}

/* The command of axis 0 after one tick with the mean reading lag_q16. */
static int32_t command_with_lag(int64_t lag_q16)
{
    drive_status_t st;
    hal_sim_set_encoder_mean(0, lag_q16);
    tick();
    drive_snapshot(&st);
    TEST_ASSERT_EQUAL_INT64(0, st.pos[0]); /* the decoder's own position */
    return st.motor_mv[0];
}

static void run_mean_reading(bool on)
{
    drive_config_t cfg;

    config(&cfg);
    cfg.enc_mean = on;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    tick();
    tick();
    TEST_ASSERT_EQUAL_INT32(0, command_with_lag(0));
    /* the mean 8 counts behind (10 um): the loop sees the axis 10 um back
     * and pushes forward by 10 mV; 3.2 counts ahead: 4 um, -4 mV */
    TEST_ASSERT_EQUAL_INT32(on ? 10 : 0, command_with_lag(-8 * 65536));
    TEST_ASSERT_EQUAL_INT32(on ? -4 : 0, command_with_lag((int64_t)(3.2 * 65536.0)));
}

static void test_loops_see_the_mean_reading(void)
{
    run_mean_reading(true);
}

static void test_off_the_mean_reading_is_not_read(void)
{
    run_mean_reading(false);
}

/* ---- the reference alignment ---------------------------------------------- */

static servo_t servo; /* drive_ff_step's servo: only the friction terms use it */

static void ff_config(drive_ff_t *f, uint32_t hz, bool mean)
{
    drive_config_t cfg;
    memset(f, 0, sizeof *f);
    drive_config_default(&cfg, hz, 3);
    cfg.enc_mean = mean;
    drive_ff_config(f, &cfg, 3);
    TEST_ASSERT_EQUAL(mean, f->on);
}

static void test_line_reference_moved_to_the_mean(void)
{
    static drive_ff_t f;
    motion_ref_t ref = {0};
    servo_fb_t fb = {{1, 2, 3}, 0};
    const motion_ref_t *m;
    const double hz = 333.0;
    unsigned i;

    ff_config(&f, 333, true);
    ref.active = true;
    ref.geom.kind = MOTION_GEOM_LINE;
    ref.geom.tangent[0] = 1 << 30;
    ref.pos[0] = 1000000;
    ref.pos[1] = -2000000;
    ref.pos[2] = 7;
    ref.vel[0] = 300000000; /* 0.3 m/s */
    ref.vel[1] = -100000000;
    ref.acc[0] = 5000000000; /* 5 m/s^2 */
    ref.acc[1] = -2000000000;
    m = drive_ff_step(&f, &servo, &ref, &fb, 3);
    TEST_ASSERT_TRUE(m != &ref);
    for (i = 0; i < 3; i++) {
        double want =
            (double)ref.pos[i] - (double)ref.vel[i] / (2 * hz) + (double)ref.acc[i] / (6 * hz * hz);
        TEST_ASSERT_DOUBLE_WITHIN(1.0, want, (double)m->pos[i]);
        TEST_ASSERT_EQUAL_INT64(ref.vel[i], m->vel[i]); /* feed-forward: the command's */
        TEST_ASSERT_EQUAL_INT64(ref.acc[i], m->acc[i]);
        TEST_ASSERT_EQUAL_INT32(ref.geom.tangent[i], m->geom.tangent[i]);
    }
    TEST_ASSERT_EQUAL_INT64(1000000, ref.pos[0]); /* ref itself keeps t_k */
    TEST_ASSERT_EQUAL_INT64(1, fb.pos[0]);        /* a line: fb untouched */
    TEST_ASSERT_EQUAL_INT(MOTION_GEOM_LINE, m->geom.kind);
    /* off: the reference itself */
    ff_config(&f, 333, false);
    f.on = true; /* as with an advance: the step runs, the mean part not */
    TEST_ASSERT_TRUE(drive_ff_step(&f, &servo, &ref, &fb, 3) == &ref);
}

/* r nm at 20 m/min; tol nm on the point (the straight shift beyond
 * R 2^31 nm: sagitta (v T / 2)^2 / (2 r)) */
static void arc_case_r(int sense, double r, double tol)
{
    static drive_ff_t f;
    const double hz = 333.0, v = 1e9 / 3.0; /* 20 m/min (nm/s) */
    const double cu = 3e6, cv = -1e6, th0 = 0.7;
    const double w = sense * v / r;        /* rad/s, signed */
    const double thm = th0 - w / (2 * hz); /* half a tick back */
    const double half = fabs(w) / (2 * hz);
    const double rmean = r * sin(half) / half; /* the mean of the circle over the tick */
    motion_ref_t ref = {0};
    servo_fb_t fb = {{0}, 0};
    const motion_ref_t *m;
    double du, dv;

    ff_config(&f, 333, true);
    ref.active = true;
    ref.geom.kind = MOTION_GEOM_ARC;
    ref.geom.plane_u = 0;
    ref.geom.plane_v = 1;
    ref.geom.centre_u = (pos_nm_t)cu;
    ref.geom.centre_v = (pos_nm_t)cv;
    ref.geom.radius = (pos_nm_t)r;
    ref.geom.sense = (int8_t)sense;
    ref.pos[0] = (pos_nm_t)llround(cu + r * cos(th0));
    ref.pos[1] = (pos_nm_t)llround(cv + r * sin(th0));
    ref.vel[0] = (int64_t)llround(-w * r * sin(th0));
    ref.vel[1] = (int64_t)llround(w * r * cos(th0));
    ref.acc[0] = (int64_t)llround(-w * w * r * cos(th0));
    ref.acc[1] = (int64_t)llround(-w * w * r * sin(th0));
    ref.geom.tangent[0] = (q1_30_t)llround(-sense * sin(th0) * 1073741824.0);
    ref.geom.tangent[1] = (q1_30_t)llround(sense * cos(th0) * 1073741824.0);
    /* the machine on the contour: its mean over the tick */
    fb.pos[0] = (pos_nm_t)llround(cu + rmean * cos(thm));
    fb.pos[1] = (pos_nm_t)llround(cv + rmean * sin(thm));
    m = drive_ff_step(&f, &servo, &ref, &fb, 3);
    TEST_ASSERT_DOUBLE_WITHIN(tol, cu + r * cos(thm), (double)m->pos[0]);
    TEST_ASSERT_DOUBLE_WITHIN(tol, cv + r * sin(thm), (double)m->pos[1]);
    if (r >= 2147483647.0) {
        return; /* the mean of the circle is within tol of it */
    }
    TEST_ASSERT_DOUBLE_WITHIN(2e-6, -sense * sin(thm), m->geom.tangent[0] / 1073741824.0);
    TEST_ASSERT_DOUBLE_WITHIN(2e-6, sense * cos(thm), m->geom.tangent[1] / 1073741824.0);
    TEST_ASSERT_EQUAL_INT64(ref.vel[0], m->vel[0]);
    TEST_ASSERT_EQUAL_INT64(ref.acc[1], m->acc[1]);
    TEST_ASSERT_EQUAL_INT64(ref.geom.radius, m->geom.radius); /* the CEC's segment key */
    /* the mean point is back on the circle (EXACT's radial deviation 0) */
    du = (double)fb.pos[0] - cu;
    dv = (double)fb.pos[1] - cv;
    TEST_ASSERT_TRUE(r - rmean > 2000.0); /* 2.1 um inside before */
    TEST_ASSERT_DOUBLE_WITHIN(2.0, r, sqrt(du * du + dv * dv));
}

static void arc_case(int sense)
{
    arc_case_r(sense, 20e6, 2.0);
}

/* R 4 m: radius^2 does not fit int64 (UBSan), the straight shift is
 * within its sagitta, 31 nm */
static void test_arc_of_a_radius_beyond_2e31_nm_shifts_straight(void)
{
    arc_case_r(1, 4e9, 40.0);
    arc_case_r(-1, 4.3e9, 40.0);
}

/* The measured position moves by half a tick's travel when it is switched:
 * only with the power stage off (a FAULT may still run the stop ramp). */
static void test_mean_switches_only_with_the_power_stage_off(void)
{
    drive_config_t cfg;
    int64_t v = -1;

    config(&cfg);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    tick();
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 0)); /* no change */
    drive_raise_fault(DRIVE_FAULT_COMM);
    tick();
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_ENC_MEAN, 0, &v));
    TEST_ASSERT_EQUAL_INT64(0, v);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg)); /* power stage off */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ENC_MEAN, 0, 1));
}

static void test_arc_reference_turned_back_ccw(void)
{
    arc_case(1);
}

static void test_arc_reference_turned_back_cw(void)
{
    arc_case(-1);
}

static void test_sim_provides_the_mean_of_the_count(void)
{
    int64_t target[3] = {60000000, 0, 0}; /* X 60 mm at 6 m/min */
    int64_t lag = 1, c0, c1;
    int res = -1, k, n = 0;

    TEST_ASSERT_EQUAL_INT(0, sim_setup(333.0, 2));
    TEST_ASSERT_EQUAL_INT(0, sim_servo_set(0, "enc_mean", 1.0));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_TRUE(drive_config()->enc_mean);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    sim_run(50, NULL, 0, 1);
    TEST_ASSERT_TRUE(hal_encoder_mean(0, &lag));
    TEST_ASSERT_EQUAL_INT64(0, lag); /* at rest */
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(target, 100000000, 1, 1, &res));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, res);
    sim_run(100, NULL, 0, 1); /* 0.3 s: cruising (a_max 10 m/s^2) */
    c0 = drive_encoder_count(0);
    for (k = 0; k < 30; k++) {
        sim_run(1, NULL, 0, 1);
        c1 = drive_encoder_count(0);
        TEST_ASSERT_TRUE(hal_encoder_mean(0, &lag));
        /* 0.1 m/s over 3 ms: 240 counts a tick, the mean 120 behind */
        TEST_ASSERT_INT64_WITHIN(5, 240, c1 - c0);
        TEST_ASSERT_DOUBLE_WITHIN(0.75, -0.5 * (double)(c1 - c0), (double)lag / 65536.0);
        n += lag != 0;
        c0 = c1;
    }
    TEST_ASSERT_EQUAL_INT(30, n);
}

/* The tick's inline sample (edges, no counter, no mean) is the slow
 * sample's edge case: on the same decoder states, ticks of a moving
 * simulated axis give the same feedback and leave the same states. */
static void test_inline_sample_equals_the_slow_one(void)
{
    static drive_inputs_t a, b;
    int64_t target[3] = {20000000, -5000000, 0};
    servo_fb_t fa, fb;
    int res = -1, k, moved = 0;

    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 2));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_FALSE(drv.in.slow);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, sim_enable(1));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(target, 100000000, 1, 1, &res));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, res);
    for (k = 0; k < 400; k++) {
        uint32_t now = (uint32_t)(1000000u + 100000u * (uint32_t)k);
        sim_run(1, NULL, 0, 1);
        a = drv.in;
        b = drv.in;
        memset(&fa, 0x5a, sizeof(fa));
        memset(&fb, 0x5a, sizeof(fb));
        drive_inputs_sample(&a, drive_config(), now, &fa);
        drive_inputs_sample_slow(&b, drive_config(), now, &fb);
        TEST_ASSERT_EQUAL_MEMORY(&fb, &fa, sizeof(fa));
        TEST_ASSERT_EQUAL_MEMORY(&b, &a, sizeof(a));
        moved += fa.pos[0] != 0;
    }
    TEST_ASSERT_TRUE(moved > 300);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_off_by_default);
    RUN_TEST(test_port_without_the_mean_refuses_it);
    RUN_TEST(test_loops_see_the_mean_reading);
    RUN_TEST(test_off_the_mean_reading_is_not_read);
    RUN_TEST(test_line_reference_moved_to_the_mean);
    RUN_TEST(test_arc_reference_turned_back_ccw);
    RUN_TEST(test_arc_reference_turned_back_cw);
    RUN_TEST(test_sim_provides_the_mean_of_the_count);
    RUN_TEST(test_arc_of_a_radius_beyond_2e31_nm_shifts_straight);
    RUN_TEST(test_mean_switches_only_with_the_power_stage_off);
    RUN_TEST(test_inline_sample_equals_the_slow_one);
    return UNITY_END();
}
