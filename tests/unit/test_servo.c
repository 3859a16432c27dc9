/* Servo tick: states, equality with the loops it wires, the contour
 * controller inside the tick and its bumpless hand-over, fault trips and
 * their reactions (disable, controlled stop), position reset, validation. */
#include "servo.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HZ     10000
#define Q30(x) ((q1_30_t)lround((x)*1073741824.0))

static int32_t mv_log[CORE_AXES];
static bool line_log[CORE_AXES];
static unsigned enable_calls;
static bool amp_bad[CORE_AXES];

static void fake_set_mv(unsigned axis, int32_t mv)
{
    TEST_ASSERT_TRUE(axis < CORE_AXES);
    mv_log[axis] = mv;
}

static void fake_enable(unsigned axis, bool on)
{
    TEST_ASSERT_TRUE(axis < CORE_AXES);
    line_log[axis] = on;
    enable_calls++;
}

static bool fake_amp_fault(unsigned axis)
{
    return amp_bad[axis];
}

static const servo_io_t io = {fake_set_mv, fake_enable, fake_amp_fault};

void setUp(void)
{
    memset(mv_log, 0x55, sizeof mv_log);
    memset(line_log, 0, sizeof line_log);
    memset(amp_bad, 0, sizeof amp_bad);
    enable_calls = 0;
}

void tearDown(void)
{
}

static servo_t s;

static void start(servo_params_t *p, servo_fb_t *fb)
{
    unsigned i;
    memset(fb, 0, sizeof *fb);
    for (i = 0; i < CORE_AXES; i++) {
        fb->pos[i] = 1000000 * (pos_nm_t)(i + 1);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s, p, &io));
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s, fb));
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
}

/* start(), then running with the reference on the measured positions. */
static void start_running(servo_params_t *p, servo_fb_t *fb, motion_ref_t *ref)
{
    unsigned i;
    start(p, fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    memset(ref, 0, sizeof *ref);
    for (i = 0; i < CORE_AXES; i++) {
        ref->pos[i] = fb->pos[i];
    }
}

/* The reference of a straight move from the hold point at velocity v (nm/s
 * per axis), tick k. */
static void ramp_ref(motion_ref_t *ref, const servo_fb_t *fb0, const int64_t *v, unsigned k)
{
    unsigned i;
    double len = 0;
    memset(ref, 0, sizeof *ref);
    ref->active = true;
    ref->geom.kind = MOTION_GEOM_LINE;
    for (i = 0; i < CORE_AXES; i++) {
        ref->pos[i] = fb0->pos[i] + v[i] * (int64_t)k / HZ;
        ref->vel[i] = v[i];
        ref->geom.start[i] = fb0->pos[i];
        len += (double)v[i] * v[i];
    }
    for (i = 0; i < CORE_AXES; i++) {
        ref->geom.tangent[i] = Q30(v[i] / sqrt(len));
    }
}

static void test_enable_hold_is_bumpless(void)
{
    servo_params_t p;
    servo_fb_t fb;
    unsigned i;
    servo_params_default(&p, HZ);
    start(&p, &fb);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_TRUE(line_log[i]);
    }
    fb.pos[0] += 3000; /* drift between enabling and the first tick */
    servo_tick(&s, NULL, &fb);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_EQUAL_INT32(0, mv_log[i]); /* continues from 0 mV */
    }
    for (i = 0; i < 2000; i++) {
        servo_tick(&s, NULL, &fb);
    }
    TEST_ASSERT_TRUE(mv_log[0] < -4); /* then the hold pulls back (integral) */
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
    /* RUN needs HOLD and no faults */
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_STATE, servo_run(&s));
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_STATE, servo_enable(&s, &fb));
    servo_disable(&s);
    TEST_ASSERT_FALSE(line_log[0]);
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[0]);
}

/* With the CEC off the servo's commands are exactly its PIDs' with the
 * interpolator's feed-forward. */
static void test_run_equals_the_loops(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    pid_loop_t ref_pid[CORE_AXES];
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, -50000000, 20000000};
    unsigned k, i;
    servo_params_default(&p, HZ);
    for (i = 0; i < CORE_AXES; i++) {
        p.axis[i].kvff = (q32_32_t)25 << 32;
        p.axis[i].kaff = (q32_32_t)1 << 30;
    }
    start(&p, &fb);
    fb0 = fb;
    for (i = 0; i < CORE_AXES; i++) {
        memset(&ref_pid[i], 0, sizeof ref_pid[i]);
        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&ref_pid[i], &p.axis[i]));
        pid_enable(&ref_pid[i], 0);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 500; k++) {
        ramp_ref(&ref, &fb0, v, k);
        ref.acc[0] = 1000000;
        for (i = 0; i < CORE_AXES; i++) {
            fb.pos[i] = ref.pos[i] - 2000 - 7 * (pos_nm_t)i; /* lagging */
        }
        servo_tick(&s, &ref, &fb);
        for (i = 0; i < CORE_AXES; i++) {
            int32_t want = pid_step(&ref_pid[i], ref.pos[i], fb.pos[i], ref.vel[i], ref.acc[i], 0);
            TEST_ASSERT_EQUAL_INT32(want, mv_log[i]);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
}

/* CEC inside the tick: its output is added along the normal, and when the
 * path ends its integral is handed to the axis loops without a step. */
static void test_cec_in_the_tick_and_handover(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, 0, 0};
    int32_t before[CORE_AXES];
    unsigned k, i;
    servo_params_default(&p, HZ);
    p.cec.mode = CEC_MODE_TANGENT;
    p.cec.pid.kp = 0;
    p.cec.pid.kd = 0;
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 200; k++) {
        ramp_ref(&ref, &fb0, v, k);
        fb.pos[0] = ref.pos[0];
        fb.pos[1] = ref.pos[1] + 10000; /* 10 um to the left of +x travel */
        fb.pos[2] = ref.pos[2];
        servo_tick(&s, &ref, &fb);
    }
    /* the CEC pushes -y (towards the path), on top of the Y loop */
    TEST_ASSERT_TRUE(s.cec.active);
    TEST_ASSERT_EQUAL_INT32(10000, s.cec.ec_nm[0]);
    TEST_ASSERT_TRUE(s.cec.out_u[1] < 0);
    TEST_ASSERT_EQUAL_INT64(0, s.cec.out_u[0]);
    for (i = 0; i < CORE_AXES; i++) {
        before[i] = mv_log[i];
    }
    /* the move ends: geometry NONE, same positions */
    ref.geom.kind = MOTION_GEOM_NONE;
    ref.vel[0] = 0;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_FALSE(s.cec.active);
    for (i = 1; i < CORE_AXES; i++) {
        /* Y and Z: only the axis loops' own one-tick integral changes (X's D
         * term decays as X stops: not part of this check) */
        TEST_ASSERT_INT32_WITHIN(3, before[i], mv_log[i]);
    }
    /* the same without hand-over: the CEC's integral (0.4 V) is dropped */
    p.cec.handover = false;
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 200; k++) {
        ramp_ref(&ref, &fb0, v, k);
        fb.pos[0] = ref.pos[0];
        fb.pos[1] = ref.pos[1] + 10000;
        fb.pos[2] = ref.pos[2];
        servo_tick(&s, &ref, &fb);
    }
    before[1] = mv_log[1];
    ref.geom.kind = MOTION_GEOM_NONE;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_TRUE(mv_log[1] - before[1] > 300);
}

static void test_following_error_disables_everything(void)
{
    servo_params_t p;
    servo_fb_t fb;
    motion_ref_t ref;
    unsigned i;
    servo_params_default(&p, HZ);
    start_running(&p, &fb, &ref);
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    ref.pos[2] += 5000000; /* exactly at the limit: allowed */
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    ref.pos[2] += 1;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_FOLLOWING, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 2, s.fault_axes);
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_EQUAL_INT32(0, mv_log[i]); /* in the same tick */
        TEST_ASSERT_FALSE(line_log[i]);
    }
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[2]);
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_STATE, servo_enable(&s, &fb));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_clear_faults(&s));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s, &fb));
    TEST_ASSERT_TRUE(line_log[2]);
}

/* Encoder fault on Y while X and Z move: Y off at once, X and Z ramp down
 * linearly together (direction kept) over N = ceil(|v| f / a) ticks to the
 * exact stopping point, then hold. */
static void test_encoder_fault_controlled_stop(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, 30000000, 50000000};
    pos_nm_t p0[CORE_AXES], prev[CORE_AXES];
    unsigned k, i;
    servo_params_default(&p, HZ);
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 100; k++) {
        ramp_ref(&ref, &fb0, v, k);
        for (i = 0; i < CORE_AXES; i++) {
            fb.pos[i] = ref.pos[i];
        }
        servo_tick(&s, &ref, &fb);
    }
    for (i = 0; i < CORE_AXES; i++) {
        p0[i] = ref.pos[i];
        prev[i] = p0[i];
    }
    fb.enc_fault = 1u << 1;
    ramp_ref(&ref, &fb0, v, k);
    servo_tick(&s, &ref, &fb); /* first ramp tick */
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_ENCODER, s.faults);
    TEST_ASSERT_EQUAL_INT(SERVO_STOPPING, s.state);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[1]);
    TEST_ASSERT_FALSE(line_log[1]);
    TEST_ASSERT_TRUE(line_log[0] && line_log[2]);
    /* |v| = 0.1 m/s on X at 1 m/s^2: N = 1000 ticks */
    TEST_ASSERT_EQUAL_UINT32(1000, s.stop_n);
    for (k = 1; k <= 1000; k++) {
        if (k > 1) {
            servo_tick(&s, &ref, &fb);
        }
        TEST_ASSERT_EQUAL_INT64(v[0] * (1000 - (int64_t)k) / 1000, s.ref_vel[0]);
        TEST_ASSERT_EQUAL_INT64(v[2] * (1000 - (int64_t)k) / 1000, s.ref_vel[2]);
        TEST_ASSERT_TRUE(s.ref_pos[0] >= prev[0]);
        TEST_ASSERT_EQUAL_INT64(p0[1], s.ref_pos[1]); /* Y disabled: no ramp */
        for (i = 0; i < CORE_AXES; i++) {
            prev[i] = s.ref_pos[i];
            fb.pos[i] = s.ref_pos[i];
        }
        TEST_ASSERT_EQUAL_INT32(0, mv_log[1]);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
    /* sum of v0 (N-j)/(N f), j = 1..N = v0 (N-1) / (2 f) */
    TEST_ASSERT_EQUAL_INT64(p0[0] + 4995000, s.ref_pos[0]);
    TEST_ASSERT_EQUAL_INT64(p0[2] + 2497500, s.ref_pos[2]);
    TEST_ASSERT_EQUAL_INT64(s.ref_pos[0], servo_hold_pos(&s, 0));
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_INT64(p0[0] + 4995000, s.ref_pos[0]);
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_STATE, servo_run(&s));
}

static void test_amplifier_fault(void)
{
    servo_params_t p;
    servo_fb_t fb;
    servo_params_default(&p, HZ);
    start(&p, &fb);
    servo_tick(&s, NULL, &fb);
    amp_bad[CORE_AXES - 1] = true;
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_AMPLIFIER, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << (CORE_AXES - 1), s.fault_axes);
    TEST_ASSERT_FALSE(line_log[CORE_AXES - 1]);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[CORE_AXES - 1]);
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state); /* was holding: keeps holding */
}

/* Saturated longer than the limit: STOP (default) or DISABLE; during the
 * stop, twice the limit disables. */
static void test_saturation_fault(void)
{
    servo_params_t p;
    servo_fb_t fb;
    motion_ref_t ref;
    unsigned k;
    servo_params_default(&p, HZ);
    p.sat_limit_ticks = 10;
    p.ferr_limit_nm[0] = 0; /* following error check off on X */
    start_running(&p, &fb, &ref);
    servo_tick(&s, &ref, &fb); /* the bumpless first tick */
    ref.pos[0] += 200000000;   /* 200 mm: 300 V wanted */
    for (k = 1; k <= 10; k++) {
        servo_tick(&s, &ref, &fb);
        TEST_ASSERT_EQUAL_INT32(160000, mv_log[0]);
    }
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_SATURATION, s.faults);
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state); /* at rest: the stop is immediate */
    /* the hold point is the last reference: still saturated; at twice the
     * limit (more than 20 ticks) it escalates to DISABLE */
    for (k = 0; k < 9; k++) {
        servo_tick(&s, &ref, &fb);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
    TEST_ASSERT_EQUAL_UINT32(20, s.pid[0].sat_ticks);
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[0]);

    p.on_saturation = SERVO_REACT_DISABLE;
    start(&p, &fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    servo_tick(&s, NULL, &fb);
    for (k = 1; k <= 11; k++) {
        servo_tick(&s, &ref, &fb);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[0]);
    TEST_ASSERT_FALSE(line_log[0]);
}

/* servo_tick checks every axis's following error in one pass with the
 * reference and reacts after it, in axis order: what each fault does must
 * still depend on the faults of the axes before it, and a controlled stop
 * must start from this tick's reference of every axis. */
static void test_following_errors_of_several_axes_in_one_tick(void)
{
    servo_params_t p;
    servo_fb_t fb;
    motion_ref_t ref;
    unsigned i;
    servo_params_default(&p, HZ);
    /* DISABLE: the first axis over the limit switches everything off; the
     * later ones are no longer checked (OFF) */
    start_running(&p, &fb, &ref);
    servo_tick(&s, &ref, &fb);
    ref.pos[1] += 6000000;
    ref.pos[2] -= 7000000;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_FOLLOWING, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 1, s.fault_axes);
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    TEST_ASSERT_EQUAL_INT32(6000000, s.ferr_nm[1]);
    TEST_ASSERT_EQUAL_INT32(-7000000, s.ferr_nm[2]);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_EQUAL_INT32(0, mv_log[i]);
    }
    /* STOP: both axes raise (the first stop does not end the checks), the
     * ramp starts from this tick's reference of every axis (moving, so the
     * stop is not immediate), and the outputs of this tick are the loops' */
    p.on_following = SERVO_REACT_STOP;
    start(&p, &fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    memset(&ref, 0, sizeof ref);
    for (i = 0; i < CORE_AXES; i++) {
        ref.pos[i] = fb.pos[i];
        ref.vel[i] = 1000000;
    }
    servo_tick(&s, &ref, &fb);
    ref.pos[0] += 100;
    ref.pos[1] += 6000000;
    ref.pos[2] -= 7000000;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_FOLLOWING, s.faults);
    TEST_ASSERT_EQUAL_UINT32((1u << 1) | (1u << 2), s.fault_axes);
    TEST_ASSERT_EQUAL_INT(SERVO_STOPPING, s.state);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_EQUAL_INT64(ref.pos[i], servo_hold_pos(&s, i));
        TEST_ASSERT_EQUAL_INT64(1000000, s.stop_v0[i]);
        TEST_ASSERT_EQUAL_INT32(s.pid[i].out_mv, mv_log[i]);
    }
    TEST_ASSERT_TRUE(mv_log[1] > 0 && mv_log[2] < 0);
}

/* A saturation fault that disables, raised by the last axis, zeroes the
 * commands of the axes before it in the same tick (the outputs are written
 * after every loop has run). */
static void test_saturation_disable_of_a_later_axis_zeroes_all(void)
{
    servo_params_t p;
    servo_fb_t fb;
    motion_ref_t ref;
    unsigned k, i;
    servo_params_default(&p, HZ);
    p.sat_limit_ticks = 3;
    p.on_saturation = SERVO_REACT_DISABLE;
    p.ferr_limit_nm[2] = 0;
    start_running(&p, &fb, &ref);
    servo_tick(&s, &ref, &fb);
    ref.pos[0] += 1000;      /* X: a small, unsaturated command */
    ref.pos[2] += 200000000; /* Z saturates */
    for (k = 0; k < 3; k++) {
        servo_tick(&s, &ref, &fb);
        TEST_ASSERT_TRUE(mv_log[0] > 0);
        TEST_ASSERT_EQUAL_INT32(160000, mv_log[2]);
    }
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_SATURATION, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 2, s.fault_axes);
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_EQUAL_INT32(0, mv_log[i]);
        TEST_ASSERT_EQUAL_INT32(0, s.out_mv[i]);
    }
}

static void test_stop_command_and_resume(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {-20000000, 0, 0};
    unsigned k;
    servo_params_default(&p, HZ);
    p.stop_decel_nm_s2[0] = 200000000; /* 0.2 m/s^2: N = 1000 */
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 10; k++) {
        ramp_ref(&ref, &fb0, v, k);
        fb.pos[0] = ref.pos[0];
        servo_tick(&s, &ref, &fb);
    }
    servo_stop(&s);
    TEST_ASSERT_EQUAL_INT(SERVO_STOPPING, s.state);
    TEST_ASSERT_EQUAL_UINT32(1000, s.stop_n);
    for (k = 0; k < 1000; k++) {
        servo_tick(&s, &ref, &fb);
        fb.pos[0] = s.ref_pos[0];
    }
    TEST_ASSERT_EQUAL_INT(SERVO_HOLD, s.state);
    TEST_ASSERT_EQUAL_INT64(ref.pos[0] - 999000, s.ref_pos[0]);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
}

/* Homing shifts the feedback frame by 1 m mid-move: no output step. */
static void test_position_reset_no_spike(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, 0, 0};
    pos_nm_t off = 0;
    int32_t prev = 0;
    unsigned k, i;
    servo_params_default(&p, HZ);
    p.axis[0].kvff = (q32_32_t)25 << 32;
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 400; k++) {
        if (k == 200) {
            off = 1000000000;
            TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_rebase(&s, 0, off));
        }
        ramp_ref(&ref, &fb0, v, k);
        ref.pos[0] += off;
        ref.geom.start[0] += off;
        for (i = 0; i < CORE_AXES; i++) {
            fb.pos[i] = ref.pos[i] - ((i == 0) ? 3000 : 0);
        }
        servo_tick(&s, &ref, &fb);
        if (k > 50) {
            TEST_ASSERT_INT32_WITHIN(2, prev, mv_log[0]);
        }
        prev = mv_log[0];
    }
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_AXIS, servo_rebase(&s, CORE_AXES, 1));
}

static void test_config_validation(void)
{
    servo_params_t good, p;
    servo_fb_t fb;
    servo_t copy;
    servo_params_default(&good, HZ);
    start(&good, &fb);
    copy = s;
    p = good;
    p.axes = 0;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_AXES, servo_config(&s, &p));
    p.axes = CORE_AXES + 1;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_AXES, servo_config(&s, &p));
    p = good;
    p.tick_hz = 50;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_TICK_HZ, servo_config(&s, &p));
    p = good;
    p.axis[1].ki = -5;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_AXIS_PID, servo_config(&s, &p));
    TEST_ASSERT_EQUAL_UINT(1, s.err_axis);
    TEST_ASSERT_EQUAL_INT(PID_ERR_GAIN, s.pid_err);
    p = good;
    p.cec.pid.out_max_mv = 0;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_CEC_PID, servo_config(&s, &p));
    TEST_ASSERT_EQUAL_INT(PID_ERR_OUT_MAX, s.pid_err);
    p = good;
    p.cec.mode = (cec_mode_t)9;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_CEC_MODE, servo_config(&s, &p));
    p = good;
    p.ferr_limit_nm[0] = -1;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_LIMIT, servo_config(&s, &p));
    p = good;
    p.stop_decel_nm_s2[2] = 0;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_DECEL, servo_config(&s, &p));
    p = good;
    p.on_following = (servo_reaction_t)3;
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_REACTION, servo_config(&s, &p));
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_NULL, servo_config(&s, NULL));
    /* nothing was applied (the error detail fields aside) */
    s.err_axis = copy.err_axis;
    s.pid_err = copy.pid_err;
    TEST_ASSERT_EQUAL_MEMORY(&copy, &s, sizeof s);
    TEST_ASSERT_EQUAL_INT(SERVO_ERR_CEC_MODE, servo_set_cec_mode(&s, CEC_MODE_COUNT));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_set_cec_mode(&s, CEC_MODE_EXACT));
}

static void test_feedback_from_decoders(void)
{
    qdec_t q0, q1;
    qdec_config_t cfg;
    const qdec_t *enc[CORE_AXES] = {0};
    servo_fb_t fb;
    qdec_config_default(&cfg);
    cfg.nm_per_count_num = 500;
    TEST_ASSERT_TRUE(qdec_init(&q0, &cfg, 0, 0));
    TEST_ASSERT_TRUE(qdec_init(&q1, &cfg, 0, 0));
    qdec_edge(&q0, QDEC_LINE_A, 10);
    qdec_edge(&q0, QDEC_LINE_A | QDEC_LINE_B, 20);
    qdec_sample(&q0, 100000);
    qdec_sample(&q1, 100000);
    q1.out.faults = QDEC_FAULT_ILLEGAL;
    enc[0] = &q0;
    enc[1] = &q1;
    servo_fb_from_qdec(&fb, enc, CORE_AXES);
    TEST_ASSERT_EQUAL_INT64(1000, fb.pos[0]);
    TEST_ASSERT_EQUAL_UINT32(1u << 1, fb.enc_fault);
    servo_fb_from_qdec(&fb, enc, 1);
    TEST_ASSERT_EQUAL_UINT32(0, fb.enc_fault);
}

/* Closed loop on a simple plant (each axis an integrator, dx/dt = Kv u,
 * X and Y gains 25 % apart, as unequal axes): a 20 mm circle at 10 m/min.
 * Returns the largest |radial deviation| over the second revolution, nm.
 * The CEC's sign and distribution are right only if it cuts that error. */
static double circle_max_radial_error(cec_mode_t mode, int dir)
{
    const double kv[2] = {0.010, 0.008}; /* m/s per V */
    const double r = 2e7, v = 10.0 / 60.0 * 1e9, w = v / r;
    const unsigned rev = (unsigned)(2 * M_PI / w * HZ);
    servo_params_t p;
    servo_fb_t fb;
    motion_ref_t ref;
    double x[2] = {r, 0}, worst = 0;
    unsigned k, i;
    servo_params_default(&p, HZ);
    for (i = 0; i < CORE_AXES; i++) {
        p.axis[i].kp = (q32_32_t)100000 << 32; /* 1e5 V/m: ~1000/s loops */
        p.axis[i].ki = 0;
        p.axis[i].kd = 0;
        p.ferr_limit_nm[i] = 0;
    }
    p.cec.mode = mode;
    p.cec.pid.kp = (q32_32_t)400000 << 32;
    p.cec.pid.ki = (q32_32_t)40000000 << 32;
    p.cec.pid.kd = 0;
    memset(&fb, 0, sizeof fb);
    fb.pos[0] = (pos_nm_t)r;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s, &p, NULL));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s, &fb));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 1; k <= 2 * rev; k++) {
        double th = dir * w * k / HZ;
        memset(&ref, 0, sizeof ref);
        ref.active = true;
        ref.pos[0] = llround(r * cos(th));
        ref.pos[1] = llround(r * sin(th));
        ref.geom.kind = MOTION_GEOM_ARC;
        ref.geom.tangent[0] = Q30(-dir * sin(th));
        ref.geom.tangent[1] = Q30(dir * cos(th));
        ref.geom.plane_v = 1;
        ref.geom.radius = (pos_nm_t)r;
        ref.geom.sense = (int8_t)dir;
        fb.pos[0] = llround(x[0]);
        fb.pos[1] = llround(x[1]);
        servo_tick(&s, &ref, &fb);
        for (i = 0; i < 2; i++) {
            x[i] += kv[i] * s.out_mv[i] * 1e-3 * 1e9 / HZ;
        }
        if (k > rev) {
            worst = fmax(worst, fabs(hypot(x[0], x[1]) - r));
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    return worst;
}

static void test_closed_loop_cec_cuts_contour_error(void)
{
    int dir;
    for (dir = -1; dir <= 1; dir += 2) {
        double off = circle_max_radial_error(CEC_MODE_OFF, dir);
        double tan = circle_max_radial_error(CEC_MODE_TANGENT, dir);
        double cur = circle_max_radial_error(CEC_MODE_CURVATURE, dir);
        double ex = circle_max_radial_error(CEC_MODE_EXACT, dir);
        printf("closed loop dir %+d: max radial error off %.0f nm, tangent %.0f, curvature %.0f, "
               "exact %.0f\n",
               dir, off, tan, cur, ex);
        TEST_ASSERT_TRUE(off > 10000.0);
        TEST_ASSERT_TRUE(cur * 5 < off);
        TEST_ASSERT_TRUE(ex * 5 < off);
        TEST_ASSERT_TRUE(tan * 5 < off);
    }
}

/* Step 1 reads the encoder fault mask and the amplifier callback once per
 * tick: an encoder fault is raised without an amplifier callback (io
 * without amp_fault), and both sources of the same tick are raised, on
 * their axes, in axis order (the last disables every axis). */
static void test_input_faults_without_and_with_callback(void)
{
    static const servo_io_t io_no_amp = {fake_set_mv, fake_enable, NULL};
    servo_params_t p;
    servo_fb_t fb;
    unsigned i;

    servo_params_default(&p, 5000);
    memset(&fb, 0, sizeof fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s, &p, &io_no_amp));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s, &fb));
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    fb.enc_fault = 1u << 2;
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_ENCODER, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 2, s.fault_axes);
    TEST_ASSERT_EQUAL_UINT32(1u << 2, s.off_mask);
    TEST_ASSERT_FALSE(line_log[2]);

    memset(&fb, 0, sizeof fb);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s, &p, &io));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s, &fb));
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    fb.enc_fault = 1u << 0;
    amp_bad[1] = true;
    amp_bad[2] = true;
    servo_tick(&s, NULL, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_ENCODER | SERVO_FAULT_AMPLIFIER, s.faults);
    TEST_ASSERT_EQUAL_UINT32(7u, s.fault_axes);
    TEST_ASSERT_EQUAL_INT(SERVO_OFF, s.state);
    for (i = 0; i < CORE_AXES; i++) {
        TEST_ASSERT_FALSE(line_log[i]);
        TEST_ASSERT_EQUAL_INT32(0, mv_log[i]);
    }
}

static int32_t mv_all_log[CORE_AXES];
static unsigned mv_all_calls, mask_calls;

static void fake_set_mv_all(const int32_t *mv, unsigned n)
{
    unsigned i;
    TEST_ASSERT_TRUE(n <= CORE_AXES);
    for (i = 0; i < n; i++) {
        mv_all_log[i] = mv[i];
    }
    mv_all_calls++;
}

static uint32_t fake_amp_fault_mask(unsigned n)
{
    uint32_t m = 0;
    unsigned i;
    for (i = 0; i < n; i++) {
        m |= amp_bad[i] ? 1u << i : 0u;
    }
    mask_calls++;
    return m;
}

/* The usual tick (fast loops: default gains, no feed-forward, CEC off):
 * every output equals the same loops stepped on their own through pid_step
 * (the PID's fast path inline in the tick is the same code), some ticks
 * saturating; a second servo with the one-call outputs and fault inputs
 * (servo_set_io_all) gives the same commands with one call of each per tick,
 * and the same amplifier fault reaction. */
static void test_fast_tick_and_one_call_io(void)
{
    static servo_t s2;
    servo_params_t p;
    servo_fb_t fb, fb0;
    pid_loop_t ref_pid[CORE_AXES];
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, -50000000, 20000000};
    unsigned k, i, ready_ticks = 0, sat_ticks = 0;

    servo_params_default(&p, HZ);
    p.sat_limit_ticks = 0; /* saturation supervised elsewhere */
    for (i = 0; i < CORE_AXES; i++) {
        p.ferr_limit_nm[i] = 0; /* lags that saturate the outputs */
    }
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s2, &p, &io));
    servo_set_io_all(&s2, fake_set_mv_all, fake_amp_fault_mask);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s2, &fb));
    for (i = 0; i < CORE_AXES; i++) {
        memset(&ref_pid[i], 0, sizeof ref_pid[i]);
        TEST_ASSERT_EQUAL_INT(PID_OK, pid_config(&ref_pid[i], &p.axis[i]));
        pid_enable(&ref_pid[i], 0);
    }
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s2));
    mv_all_calls = 0;
    mask_calls = 0;
    for (k = 0; k < 600; k++) {
        ramp_ref(&ref, &fb0, v, k);
        for (i = 0; i < CORE_AXES; i++) {
            /* lagging, with jumps that saturate the outputs now and then */
            pos_nm_t lag = (k % 97 < 3) ? 150000000 : 2000 + (pos_nm_t)((k * 37 + i * 11) % 500);
            fb.pos[i] = ref.pos[i] - lag;
        }
        if (k == 500) {
            amp_bad[1] = true;
        }
        servo_tick(&s, &ref, &fb);
        servo_tick(&s2, &ref, &fb);
        TEST_ASSERT_EQUAL_UINT32(k + 1, mv_all_calls);
        TEST_ASSERT_EQUAL_UINT32(k + 1, mask_calls);
        TEST_ASSERT_EQUAL_UINT32(s.faults, s2.faults);
        TEST_ASSERT_EQUAL_INT(s.state, s2.state);
        for (i = 0; i < CORE_AXES; i++) {
            TEST_ASSERT_EQUAL_INT32(mv_log[i], mv_all_log[i]);
            TEST_ASSERT_EQUAL_INT32(s.out_mv[i], s2.out_mv[i]);
            if (k < 500) {
                int32_t want = pid_step(&ref_pid[i], ref.pos[i], fb.pos[i], 0, 0, 0);
                TEST_ASSERT_EQUAL_INT32(want, mv_log[i]);
                sat_ticks += s.pid[i].saturated;
            }
        }
        ready_ticks += s.pid[0].ready && s.pid[1].ready && s.pid[2].ready;
    }
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_AMPLIFIER, s.faults);
    TEST_ASSERT_EQUAL_INT32(0, mv_all_log[1]);
    TEST_ASSERT_TRUE(ready_ticks >= 450); /* the fast path ran (until the fault) */
    TEST_ASSERT_TRUE(sat_ticks > 0);      /* and saturated */
}

/* The axis steps of a tick with the contour error controller active (the
 * host's inline lean and cached rest steps, PID_HOST_INLINE) against
 * copies of the loops stepped by pid_step_e from the same inputs: X and Y
 * with feed-forward (the lean step), Z at rest with a nudge now and then,
 * lags that saturate the outputs now and then; every output and state
 * field equal on every tick. */
static void test_cec_tick_axis_steps_equal_pid_step_e(void)
{
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, 0, 0};
    unsigned k, i, lean = 0, rest = 0, sat = 0;

    servo_params_default(&p, HZ);
    p.cec.mode = CEC_MODE_TANGENT;
    p.sat_limit_ticks = 0;
    for (i = 0; i < 2; i++) {
        p.axis[i].kvff = (q32_32_t)16 << 32;
        p.axis[i].kaff = (q32_32_t)1 << 29;
        p.ferr_limit_nm[i] = 0;
    }
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    for (k = 0; k < 3000; k++) {
        pid_loop_t copy[CORE_AXES];
        ramp_ref(&ref, &fb0, v, k);
        for (i = 0; i < 2; i++) {
            ref.acc[i] = (int64_t)((k * 7919u) % 2001u) * 1000 - 1000000;
        }
        fb.pos[0] = ref.pos[0] - 3000 - (pos_nm_t)((k * 37) % 500);
        fb.pos[1] = ref.pos[1] + 10000 + (pos_nm_t)(k % 1000) / 10;
        if (k % 211 < 3) {
            fb.pos[0] -= 20000000; /* saturates X (the D term) */
        }
        /* Z: a nudge of the measurement, the reference, or both */
        ref.pos[2] += (k % 401 == 0 || k % 409 == 0) ? 5 : 0;
        fb.pos[2] = fb0.pos[2] + ((k % 397 == 0 || k % 409 == 0) ? 5 : 0);
        memcpy(copy, s.pid, sizeof copy);
        servo_tick(&s, &ref, &fb);
        TEST_ASSERT_TRUE(s.cec.active);
        TEST_ASSERT_EQUAL_INT(SERVO_RUN, s.state);
        for (i = 0; i < CORE_AXES; i++) {
            pid_loop_t *a = &s.pid[i], *b = &copy[i];
            int32_t want;
            lean += b->lean_rdy;
            rest += b->rest && a->rest;
            TEST_ASSERT_EQUAL_INT64(0, s.cec.handover_u[i]);
            want = pid_step_e(b, s.ferr_nm[i], fb.pos[i], ref.vel[i], ref.acc[i], s.cec.out_u[i]);
            TEST_ASSERT_EQUAL_INT32(want, s.out_mv[i]);
            TEST_ASSERT_EQUAL_INT32(b->out_mv, a->out_mv);
            TEST_ASSERT_EQUAL_INT64(b->out, a->out);
            TEST_ASSERT_EQUAL_INT64(b->integ, a->integ);
            TEST_ASSERT_EQUAL_INT64(b->dterm, a->dterm);
            TEST_ASSERT_EQUAL_INT64(b->dq, a->dq);
            TEST_ASSERT_EQUAL_INT64(b->ff, a->ff);
            TEST_ASSERT_EQUAL_INT64(b->extra, a->extra);
            TEST_ASSERT_EQUAL_INT32(b->err_nm, a->err_nm);
            TEST_ASSERT_EQUAL_INT64(b->meas_prev, a->meas_prev);
            TEST_ASSERT_EQUAL(b->saturated, a->saturated);
            TEST_ASSERT_EQUAL_UINT32(b->sat_ticks, a->sat_ticks);
            TEST_ASSERT_EQUAL_UINT32(b->sat_total, a->sat_total);
            sat += a->saturated;
        }
    }
    TEST_ASSERT_TRUE(lean > 5900); /* X and Y took the lean step */
    TEST_ASSERT_TRUE(sat > 10);
    if (PID_REST) {
        TEST_ASSERT_TRUE(rest > 2700); /* Z the cached rest step */
    }
}

/* A tick with the contour error controller on (tick_cec_on on 64-bit
 * hosts) counts itself and takes step 1 as every tick does: an encoder
 * fault and an amplifier fault (the per-axis callback and, on a second
 * servo, the one-call mask) are raised in the tick they come in. */
static void test_cec_on_tick_counts_and_input_faults(void)
{
    static servo_t s2;
    servo_params_t p;
    servo_fb_t fb, fb0;
    motion_ref_t ref;
    const int64_t v[CORE_AXES] = {100000000, 0, 0};
    unsigned k;

    servo_params_default(&p, HZ);
    p.cec.mode = CEC_MODE_TANGENT;
    start(&p, &fb);
    fb0 = fb;
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_init(&s2, &p, &io));
    servo_set_io_all(&s2, fake_set_mv_all, fake_amp_fault_mask);
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_enable(&s2, &fb));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s));
    TEST_ASSERT_EQUAL_INT(SERVO_OK, servo_run(&s2));
    mask_calls = 0;
    for (k = 0; k < 100; k++) {
        ramp_ref(&ref, &fb0, v, k);
        memcpy(fb.pos, ref.pos, sizeof fb.pos);
        fb.pos[1] += 10000;
        servo_tick(&s, &ref, &fb);
        servo_tick(&s2, &ref, &fb);
    }
    TEST_ASSERT_TRUE(s.cec.active);
    TEST_ASSERT_EQUAL_UINT64(100, s.ticks);
    TEST_ASSERT_EQUAL_UINT64(100, s2.ticks);
    TEST_ASSERT_EQUAL_UINT32(100, mask_calls);
    TEST_ASSERT_EQUAL_UINT32(0, s.faults);
    fb.enc_fault = 1u << 2;
    servo_tick(&s, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_ENCODER, s.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 2, s.fault_axes);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[2]);
    fb.enc_fault = 0;
    amp_bad[1] = true;
    servo_tick(&s, &ref, &fb);
    servo_tick(&s2, &ref, &fb);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_ENCODER | SERVO_FAULT_AMPLIFIER, s.faults);
    TEST_ASSERT_EQUAL_UINT32(SERVO_FAULT_AMPLIFIER, s2.faults);
    TEST_ASSERT_EQUAL_UINT32(1u << 1, s2.fault_axes);
    TEST_ASSERT_EQUAL_INT32(0, mv_log[1]);
    TEST_ASSERT_EQUAL_INT32(0, mv_all_log[1]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_enable_hold_is_bumpless);
    RUN_TEST(test_input_faults_without_and_with_callback);
    RUN_TEST(test_run_equals_the_loops);
    RUN_TEST(test_fast_tick_and_one_call_io);
    RUN_TEST(test_cec_in_the_tick_and_handover);
    RUN_TEST(test_cec_tick_axis_steps_equal_pid_step_e);
    RUN_TEST(test_cec_on_tick_counts_and_input_faults);
    RUN_TEST(test_following_error_disables_everything);
    RUN_TEST(test_encoder_fault_controlled_stop);
    RUN_TEST(test_amplifier_fault);
    RUN_TEST(test_saturation_fault);
    RUN_TEST(test_following_errors_of_several_axes_in_one_tick);
    RUN_TEST(test_saturation_disable_of_a_later_axis_zeroes_all);
    RUN_TEST(test_stop_command_and_resume);
    RUN_TEST(test_position_reset_no_spike);
    RUN_TEST(test_config_validation);
    RUN_TEST(test_feedback_from_decoders);
    RUN_TEST(test_closed_loop_cec_cuts_contour_error);
    return UNITY_END();
}
