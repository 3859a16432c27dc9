/*
 * The drive application (drive.h) in the simulator (sim.h: the real drive
 * through the sim HAL, closed on the axis models):
 *   - blocks queued right after drive_enable(true), before any tick, run;
 *   - drive_status reports the planned time still queued (planner plus the
 *     interpolator's remainder) and it falls by one tick per tick;
 *   - a job of blocks shorter than one tick keeps the interpolator fed: every
 *     block ends within one tick of the planner's estimate (plan_estimate on
 *     the same moves), the reference never stalls mid-job;
 *   - controlled stop: on the path, the path speed never rises and falls by
 *     at most the configured deceleration per tick (also when the stop comes
 *     while the plan is accelerating), ends at rest, the rest of the job is
 *     dropped and a new block starts from the stop point;
 *   - emergency stop, external faults, amplifier and following-error faults
 *     react as drive.h documents;
 *   - parameter API: ranges, busy while moving, nothing half applied, and the
 *     new limits are what the planner uses.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "calib.h"
#include "drive.h"
#include "drive_test.h"
#include "estimator.h"
#include "hal_sim.h"
#include "sim.h"
#include "unity.h"

#define TICK_NS 100000 /* 10 kHz */

static drive_status_t st;

static void start(void)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
}

void setUp(void)
{
    start();
}

void tearDown(void)
{
}

static void run(uint64_t ticks)
{
    TEST_ASSERT_TRUE(sim_run(ticks, NULL, 0, 0) >= 0);
    drive_status(&st);
}

static drive_block_t line(int64_t x, int64_t y, int64_t feed, bool stop, uint32_t tag)
{
    drive_block_t b;

    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_LINE;
    b.tag = tag;
    b.target[0] = x;
    b.target[1] = y;
    b.feed_nm_s = feed;
    b.exact_stop = stop;
    return b;
}

static drive_result_t queue_line(int64_t x, int64_t y, int64_t feed, bool stop, uint32_t tag)
{
    drive_block_t b = line(x, y, feed, stop, tag);

    return drive_queue_block(&b);
}

/* Planner estimate (ns per block) of moves from the origin, as the drive
 * would plan them with a queue kept full. */
static int64_t estimate(const plan_move_t *m, uint32_t n, int64_t *each)
{
    static plan_block_t store[PLAN_DEPTH_DEFAULT];
    static plan_est_t out[2048];
    const pos_nm_t o[CORE_AXES] = {0};
    uint32_t bad = 0, i;
    int64_t sum = 0;

    TEST_ASSERT_TRUE(n <= 2048);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_estimate(&drive_config()->plan, o, m, n, store,
                                                 PLAN_DEPTH_DEFAULT, out, &bad));
    for (i = 0; i < n; i++) {
        sum += out[i].t_total_ns;
        if (each != NULL) {
            each[i] = out[i].t_total_ns;
        }
    }
    return sum;
}

static plan_move_t move(int64_t x, int64_t y, int64_t feed, bool stop)
{
    plan_move_t m;

    memset(&m, 0, sizeof m);
    m.target[0] = x;
    m.target[1] = y;
    m.feed = feed;
    m.flags = stop ? PLAN_MOVE_EXACT_STOP : 0;
    return m;
}

/* ---- 1. enable and queue before any tick ------------------------------------ */

static void test_block_queued_right_after_enable_runs(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(1000000, 0, 20000000, true, 7));
    run(10000); /* 1 s: the move takes about 55 ms */
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(1, st.blocks_done);
    TEST_ASSERT_EQUAL_UINT32(7, st.tag);
    TEST_ASSERT_EQUAL_INT64(1000000, st.ref[0]);
    TEST_ASSERT_INT64_WITHIN(2000, 1000000, st.pos[0]);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0));
}

static void test_enable_queue_poll_before_the_first_tick(void)
{
    /* the main loop may poll before the tick applied the enable */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(500000, 500000, 10000000, false, 1));
    calib_poll();
    drive_poll();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 500000, 10000000, true, 2));
    calib_poll();
    drive_poll();
    run(20000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(2, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(0, st.ref[0]);
    TEST_ASSERT_EQUAL_INT64(500000, st.ref[1]);
}

/* The per-block S-curve (velocity_profile 0; the default is the continuous
 * S-curve), for a test of what that shape guarantees and the continuous one
 * does not (planner.h): the queued time equal to the estimate from the
 * first block on (the continuous shape's is exact for the run it has
 * planned, an estimate for runs not planned yet), each block with its own
 * projected a and j (a run takes the smallest axis limits). */
static void per_block_scurve(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE));
}

/* ---- 2. planned time queued -------------------------------------------------- */

static void test_status_reports_planned_time_queued(void)
{
    plan_move_t m[3];
    int64_t total, k;

    per_block_scurve();
    m[0] = move(1000000, 0, 20000000, true);
    m[1] = move(1000000, 2000000, 20000000, true);
    m[2] = move(0, 0, 30000000, true);
    total = estimate(m, 3, NULL);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT64(0, st.queued_time_ns);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(1000000, 0, 20000000, true, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(1000000, 2000000, 20000000, true, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 0, 30000000, true, 3));
    calib_poll();
    drive_poll(); /* hands the blocks to the planner and the interpolator */
    drive_status(&st);
    TEST_ASSERT_EQUAL_INT64(total, st.queued_time_ns);
    /* it falls by one tick per tick while the job runs */
    for (k = 1; k * TICK_NS < total; k++) {
        run(1);
        TEST_ASSERT_INT64_WITHIN(1000, total - k * TICK_NS, st.queued_time_ns);
    }
    run(2);
    TEST_ASSERT_EQUAL_INT64(0, st.queued_time_ns);
    TEST_ASSERT_EQUAL_UINT32(3, st.blocks_done);
}

static void test_planned_time_counts_blocks_waiting_in_the_planner(void)
{
    plan_move_t m[20];
    int64_t total;
    unsigned i;

    per_block_scurve();
    for (i = 0; i < 20; i++) {
        m[i] = move((int64_t)(i + 1) * 100000, (i & 1u) ? 20000 : 0, 5000000, false);
    }
    total = estimate(m, 20, NULL);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    for (i = 0; i < 20; i++) {
        TEST_ASSERT_EQUAL_INT(DRIVE_OK,
                              queue_line(m[i].target[0], m[i].target[1], m[i].feed, false, i));
        calib_poll();
        drive_poll();
    }
    drive_status(&st);
    TEST_ASSERT_EQUAL_INT64(total, st.queued_time_ns);
    run(30000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(20, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(0, st.queued_time_ns);
}

/* ---- 3. a run of blocks shorter than a tick ---------------------------------- */

#define SHORT_N 600
static int64_t est_each[SHORT_N];
static uint64_t end_tick[SHORT_N];

/* Stream SHORT_N blocks of step nm along X (the host keeps the drive's
 * queue full before every tick) and check every block's end tick against
 * the planner's estimate. Returns the estimated total. */
static int64_t short_block_job(int64_t step, int64_t feed, unsigned *max_err_ticks)
{
    static plan_move_t m[SHORT_N];
    uint32_t queued = 0, done = 0, i;
    uint64_t t = 0, t0;
    int64_t total, cum = 0, prev_x = 0, last_move = -1, first_move = -1;
    unsigned stalls = 0;

    /* trapezoidal profiles at 50 m/s^2 (an S-curve block starts and ends
     * at zero acceleration, which keeps um blocks slow): the look-ahead of
     * 64 blocks of a few um then allows several blocks per tick */
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_plan_set(0, "shape", 1.0));
    for (i = 0; i < 3; i++) {
        TEST_ASSERT_EQUAL_INT(0, sim_plan_set(i, "a_max", 50.0));
    }
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    for (i = 0; i < SHORT_N; i++) {
        m[i] = move((int64_t)(i + 1) * step, 0, feed, i + 1 == SHORT_N);
    }
    total = estimate(m, SHORT_N, est_each);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    while (done < SHORT_N && t < 200000) {
        while (queued < SHORT_N && queue_line(m[queued].target[0], 0, feed, queued + 1 == SHORT_N,
                                              queued) == DRIVE_OK) {
            queued++;
        }
        run(1);
        t++;
        TEST_ASSERT_EQUAL_UINT32(0, st.faults);
        while (done < st.blocks_done && done < SHORT_N) {
            end_tick[done++] = t;
        }
        if (st.ref[0] != prev_x) {
            if (first_move < 0) {
                first_move = (int64_t)t;
            }
            last_move = (int64_t)t;
        } else if (first_move >= 0 && done < SHORT_N && done > 0) {
            stalls++; /* the reference stood still inside the job */
        }
        prev_x = st.ref[0];
    }
    TEST_ASSERT_EQUAL_UINT32(SHORT_N, done);
    TEST_ASSERT_EQUAL_INT64(SHORT_N * step, st.ref[0]);
    TEST_ASSERT_EQUAL_UINT(0, stalls);
    /* the first block's start: its end minus its whole ticks */
    t0 = end_tick[0] - (uint64_t)((est_each[0] + TICK_NS - 1) / TICK_NS);
    *max_err_ticks = 0;
    for (i = 0; i < SHORT_N; i++) {
        int64_t want, err;
        cum += est_each[i];
        want = (int64_t)t0 + (cum + TICK_NS - 1) / TICK_NS;
        err = (int64_t)end_tick[i] - want;
        err = err < 0 ? -err : err;
        if ((unsigned)err > *max_err_ticks) {
            *max_err_ticks = (unsigned)err;
        }
    }
    TEST_ASSERT_TRUE(last_move > first_move);
    return total;
}

static void test_short_blocks_keep_the_interpolator_fed(void)
{
    unsigned err = 99;
    int64_t total = short_block_job(2000, 100000000, &err); /* 2 um, 100 mm/s */

    printf("short blocks: %u blocks, estimate %lld ns, max end-tick error %u\n", SHORT_N,
           (long long)total, err);
    /* the blocks really are shorter than a tick (several end per tick) */
    TEST_ASSERT_TRUE(total < (int64_t)SHORT_N * TICK_NS * 3 / 4);
    TEST_ASSERT_TRUE(err <= 1);
}

/* ---- 4. controlled stop, emergency stop, faults -------------------------------- */

/* Record the path speed (nm per tick) after drive_stop() until the reference
 * is at rest; checks the reference stays on the line through the origin with
 * direction (3, 4) / 5. */
static unsigned stop_and_watch(int64_t decel_nm_s2, int64_t *v_before, unsigned *ticks_to_rest)
{
    int64_t px, py, v_prev, max_dec = decel_nm_s2 / 100000000 + 3;
    unsigned k, rises = 0, over = 0;

    drive_status(&st);
    px = st.ref[0];
    py = st.ref[1];
    run(1);
    v_prev = ((st.ref[0] - px) * 3 + (st.ref[1] - py) * 4) / 5;
    *v_before = v_prev;
    px = st.ref[0];
    py = st.ref[1];
    drive_stop();
    *ticks_to_rest = 0;
    for (k = 0; k < 100000; k++) {
        int64_t dx, dy, v;
        run(1);
        dx = st.ref[0] - px;
        dy = st.ref[1] - py;
        px = st.ref[0];
        py = st.ref[1];
        /* on the path: |4 x - 3 y| / 5 <= 2 nm */
        TEST_ASSERT_TRUE(4 * px - 3 * py <= 10 && 4 * px - 3 * py >= -10);
        v = (dx * 3 + dy * 4) / 5; /* along the path, nm per tick */
        TEST_ASSERT_TRUE(v >= -2);
        if (v > v_prev + 2) {
            rises++;
        }
        if (v_prev - v > max_dec) {
            over++;
        }
        v_prev = v;
        if (v == 0 && *ticks_to_rest == 0) {
            *ticks_to_rest = k + 1;
        }
        if (st.state != DRIVE_STOPPING && v == 0) {
            break;
        }
    }
    TEST_ASSERT_EQUAL_UINT(0, rises);
    return over;
}

static void test_stop_decelerates_on_the_path_and_drops_the_job(void)
{
    unsigned rest = 0;
    int64_t x0, y0, v0 = 0;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    /* 3-4-5 diagonal at 20 mm/s, and more blocks behind it */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, false, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(60000000, 80000000, 20000000, false, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 0, 20000000, true, 3));
    run(3000); /* cruising at 2000 nm per tick */
    TEST_ASSERT_EQUAL_INT(DRIVE_RUNNING, st.state);
    /* stop_decel 1 m/s^2 = 10 nm per tick per tick: rest after 200 ticks */
    TEST_ASSERT_EQUAL_UINT(0, stop_and_watch(1000000000, &v0, &rest));
    TEST_ASSERT_INT64_WITHIN(2, 2000, v0);
    TEST_ASSERT_UINT_WITHIN(2, 200, rest);
    run(10);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    TEST_ASSERT_EQUAL_UINT32(0, st.blocks_done); /* nothing completed */
    TEST_ASSERT_EQUAL_UINT32(DRIVE_QUEUE_DEPTH, st.queue_free);
    TEST_ASSERT_EQUAL_INT64(0, st.queued_time_ns);
    x0 = st.ref[0];
    y0 = st.ref[1];
    run(5000);
    TEST_ASSERT_EQUAL_INT64(x0, st.ref[0]); /* the rest of the job was dropped */
    TEST_ASSERT_EQUAL_INT64(y0, st.ref[1]);
    TEST_ASSERT_INT64_WITHIN(20000, x0, st.pos[0]);
    /* stopping distance v^2 / 2a = 0.2 mm along the path */
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0));
    /* the drive accepts a new job from the stop point */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 0, 20000000, true, 9));
    run(40000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(1, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(0, st.ref[0]);
    TEST_ASSERT_EQUAL_INT64(0, st.ref[1]);
}

static void test_stop_while_accelerating_never_speeds_up(void)
{
    unsigned rest = 0;
    int64_t v0 = 0;

    /* a slow planner acceleration (0.5 m/s^2) beside a 1 m/s^2 stop */
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_plan_set(0, "a_max", 0.5));
    TEST_ASSERT_EQUAL_INT(0, sim_plan_set(1, "a_max", 0.5));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 50000000, true, 1));
    run(300); /* 30 ms into the acceleration */
    TEST_ASSERT_EQUAL_UINT(0, stop_and_watch(1000000000, &v0, &rest));
    TEST_ASSERT_TRUE(v0 > 1000); /* it was still accelerating at > 10 mm/s */
    TEST_ASSERT_UINT_WITHIN(2, (unsigned)(v0 / 10), rest);
    run(10);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
}

static void test_stop_when_idle_or_disabled_changes_nothing(void)
{
    drive_stop();
    run(5);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(2);
    drive_stop();
    run(5);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(100000, 0, 10000000, true, 1));
    run(3000);
    TEST_ASSERT_EQUAL_UINT32(1, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(100000, st.ref[0]);
}

/* An e-stop that arrives together with an enable (both before the same
 * tick) wins: the motors are never switched on. */
static void test_estop_with_enable_in_the_same_tick_keeps_motors_off(void)
{
    unsigned i, k;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    drive_estop();
    for (k = 0; k < 5; k++) {
        run(1);
        TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
        TEST_ASSERT_EQUAL_HEX32(DRIVE_FAULT_ESTOP, st.faults);
        for (i = 0; i < 3; i++) {
            TEST_ASSERT_FALSE(hal_sim_motor_enabled(i));
            TEST_ASSERT_EQUAL_INT32(0, hal_sim_motor_mv(i));
        }
    }
}

static void test_estop_disables_at_once_and_needs_a_reset(void)
{
    unsigned i;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(2000);
    TEST_ASSERT_EQUAL_INT(DRIVE_RUNNING, st.state);
    drive_estop();
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_EQUAL_HEX32(DRIVE_FAULT_ESTOP, st.faults);
    for (i = 0; i < 3; i++) {
        TEST_ASSERT_FALSE(hal_sim_motor_enabled(i));
        TEST_ASSERT_EQUAL_INT32(0, hal_sim_motor_mv(i));
    }
    TEST_ASSERT_EQUAL_UINT32(DRIVE_QUEUE_DEPTH, st.queue_free);
    TEST_ASSERT_EQUAL_INT64(0, st.queued_time_ns);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_FAULTED, queue_line(0, 0, 20000000, true, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_FAULTED, drive_enable(true));
    run(1000);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    /* enabled again, the drive holds where the axes coasted to and runs */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 0, 20000000, true, 3));
    run(40000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(1, st.blocks_done);
    TEST_ASSERT_EQUAL_INT64(0, st.ref[0]);
}

static void test_external_fault_stops_in_a_controlled_way(void)
{
    int64_t x;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(2000);
    drive_raise_fault(DRIVE_FAULT_COMM);
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_EQUAL_HEX32(DRIVE_FAULT_COMM, st.faults);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0)); /* the servo ramps down */
    run(2000);
    x = st.ref[0];
    run(100);
    TEST_ASSERT_EQUAL_INT64(x, st.ref[0]); /* at rest */
    TEST_ASSERT_TRUE(x < 30000000);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_FAULTED, queue_line(0, 0, 20000000, true, 2));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
    TEST_ASSERT_FALSE(hal_sim_motor_enabled(0));
}

/* A reset requested while the servo still ramps down stays pending (the
 * tick skips apply_requests only when no request is pending) and is applied
 * once the servo has stopped; requests made between ticks all apply. */
static void test_reset_during_ramp_down_applies_once_stopped(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(2000);
    drive_raise_fault(DRIVE_FAULT_COMM);
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0)); /* still ramping down */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state); /* not yet: servo stopping */
    run(3000);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
    TEST_ASSERT_EQUAL_HEX32(0, st.faults);
    TEST_ASSERT_FALSE(hal_sim_motor_enabled(0));
    /* two requests between ticks: both apply on the next tick */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0));
    drive_estop();
    drive_raise_fault(DRIVE_FAULT_COMM);
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_EQUAL_HEX32(DRIVE_FAULT_ESTOP | DRIVE_FAULT_COMM, st.faults);
    TEST_ASSERT_FALSE(hal_sim_motor_enabled(0));
}

/* A host sends fault_reset and then enable before the tick has applied the
 * reset (a round trip shorter than a tick, or the reset deferred while the
 * servo ramps down): the enable is accepted and waits for the reset, never
 * refused as "faulted" nor dropped. */
static void test_enable_right_after_a_reset_waits_for_it(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    drive_estop();
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true)); /* no tick between */
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0));
    /* the reset deferred while the servo ramps down: the enable follows it */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(2000);
    drive_raise_fault(DRIVE_FAULT_COMM);
    run(1);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0)); /* still ramping down */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state); /* the reset is not applied yet */
    run(3000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    TEST_ASSERT_TRUE(hal_sim_motor_enabled(0));
}

static void test_amplifier_fault_reset_refused_while_present(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(1000);
    hal_sim_set_amp_fault(1, true);
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_TRUE((st.faults & DRIVE_FAULT_AMPLIFIER) != 0u);
    TEST_ASSERT_FALSE(hal_sim_motor_enabled(1)); /* the faulted axis at once */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_CAUSE, drive_fault_reset());
    run(3000);
    hal_sim_set_amp_fault(1, false);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_fault_reset());
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_DISABLED, st.state);
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
}

static void test_following_error_disables(void)
{
    servo_params_t p = drive_config()->servo;

    p.ferr_limit_nm[0] = 100; /* 0.1 um: any real move exceeds it */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_servo_params(&p));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(30000000, 40000000, 20000000, true, 1));
    run(2000);
    TEST_ASSERT_EQUAL_INT(DRIVE_FAULT, st.state);
    TEST_ASSERT_TRUE((st.faults & DRIVE_FAULT_FOLLOWING) != 0u);
    TEST_ASSERT_FALSE(hal_sim_motor_enabled(0));
    TEST_ASSERT_EQUAL_INT32(0, hal_sim_motor_mv(0));
    TEST_ASSERT_EQUAL_UINT32(DRIVE_QUEUE_DEPTH, st.queue_free);
}

/* ---- 5. parameters ------------------------------------------------------------ */

static void test_parameters_are_checked_and_never_half_applied(void)
{
    int64_t v = 0, lo = 0, hi = 0;
    plan_profile_t before = drive_config()->plan;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_V_MAX, 1, &v));
    TEST_ASSERT_EQUAL_INT64(before.v_max[1], v);
    /* unknown id, axis out of range, axis on a scalar parameter */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_get(DRIVE_PARAM_COUNT, 0, &v));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_get(DRIVE_PARAM_V_MAX, 3, &v));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_CORNER, 1, 1));
    /* static ranges */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_range(DRIVE_PARAM_V_MAX, 0, &lo, &hi));
    TEST_ASSERT_EQUAL_INT64(1000, lo);
    TEST_ASSERT_EQUAL_INT64(SC_V_LIMIT, hi);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_V_MAX, 0, 999));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_V_MAX, 0, SC_V_LIMIT + 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_CORNER, 0, 4));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_MBT_WINDOW, 0, 0));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_START_DELAY_MS, 0, -1));
    /* the S-curve's a / j <= 3 s narrows the acceleration's range */
    /* 1 m/s^3 with 10 m/s^2: a / j = 10 s, refused */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_range(DRIVE_PARAM_J_MAX, 0, &lo, &hi));
    TEST_ASSERT_EQUAL_INT64(3333333334, lo);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_J_MAX, 0, 1000000000));
    TEST_ASSERT_EQUAL_INT64(before.j_max[0], drive_config()->plan.j_max[0]);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 0, 2000000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_J_MAX, 0, 1000000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_range(DRIVE_PARAM_A_MAX, 0, &lo, &hi));
    TEST_ASSERT_EQUAL_INT64(3000000000, hi);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_J_MAX, 0, 999));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 0, 3000000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_A_MAX, 0, 3000000001));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_TRAPEZOID));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 0, 9000000000));
    /* back to the S-curve would break a / j on axis 0: refused, unchanged */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE));
    /* the at-rest S-curve has the same a / j rule; past it, no shape exists */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID,
                          drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE_AT_REST));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID,
                          drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE_CONTINUOUS + 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_SHAPE, 0, &v));
    TEST_ASSERT_EQUAL_INT64(SC_SHAPE_TRAPEZOID, v);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 0, 3000000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE_AT_REST));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_range(DRIVE_PARAM_A_MAX, 0, &lo, &hi));
    TEST_ASSERT_EQUAL_INT64(3000000000, hi);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_TRAPEZOID));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 0, 9000000000));
    /* a whole profile: all or nothing */
    {
        plan_profile_t bad = before;
        bad.v_max[2] = 0;
        TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_set_plan_profile(&bad));
        TEST_ASSERT_EQUAL_INT64(9000000000, drive_config()->plan.a_max[0]);
        TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_plan_profile(&before));
        TEST_ASSERT_EQUAL_MEMORY(&before, &drive_config()->plan, sizeof before);
    }
}

static void test_parameters_are_refused_while_moving(void)
{
    int64_t v = 0;

    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_STOP_DECEL, 0, 2000000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(2000000, 0, 20000000, true, 1));
    /* queued but not yet polled: already busy */
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_param_set(DRIVE_PARAM_V_MAX, 0, 5000000));
    run(50);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_param_set(DRIVE_PARAM_V_MAX, 0, 5000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_set_plan_profile(&drive_config()->plan));
    drive_stop();
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_BUSY, drive_param_set(DRIVE_PARAM_ARC_CHORD, 0, 500));
    run(1000);
    TEST_ASSERT_EQUAL_INT(DRIVE_IDLE, st.state);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ARC_CHORD, 0, 500));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_V_MAX, 0, &v));
    TEST_ASSERT_EQUAL_INT64(1000000000, v); /* the refused values never landed */
}

static void test_new_limits_are_what_the_planner_uses(void)
{
    plan_move_t m[2];
    unsigned i;
    int64_t total, start = -1;

    per_block_scurve();
    /* 5 mm/s on X, a throughput limit of 2 ms per block, then two blocks */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_V_MAX, 0, 5000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_MIN_BLOCK_NS, 0, 2000000));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_MBT_WINDOW, 0, 4));
    m[0] = move(1000000, 0, 50000000, false);
    m[1] = move(1000000, 5000, 50000000, true);
    total = estimate(m, 2, NULL);        /* with drive_config()->plan: the new one */
    TEST_ASSERT_TRUE(total > 200000000); /* 1 mm at 5 mm/s */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(1000000, 0, 50000000, false, 1));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(1000000, 5000, 50000000, true, 2));
    calib_poll();
    drive_poll();
    drive_status(&st);
    TEST_ASSERT_EQUAL_INT64(total, st.queued_time_ns);
    for (i = 0; i < 40000 && st.blocks_done < 2; i++) {
        run(1);
        if (start < 0 && st.ref[0] != 0) {
            start = i;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(2, st.blocks_done);
    /* executed: first motion to the end, whole ticks */
    TEST_ASSERT_INT64_WITHIN(2, (total + TICK_NS - 1) / TICK_NS, (int64_t)i - start + 1);
}

/* A limit raised on one axis only is what a block along that axis gets
 * (the planner's equal-limits fast path and its other derived constants
 * follow the new profile): Y at 50 m/s^2, X and Z at the default 10, a
 * pure-Y move plans as plan_estimate with the new profile (with X's 10 m/s^2
 * it takes 14 ms longer). */
static void test_one_axis_limit_is_used_by_its_axis(void)
{
    plan_move_t m[1];
    int64_t total, slow;

    per_block_scurve();
    m[0] = move(0, 20000000, 1000000000, true); /* 20 mm at up to 1 m/s */
    slow = estimate(m, 1, NULL);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_A_MAX, 1, 50000000000));
    total = estimate(m, 1, NULL);
    TEST_ASSERT_TRUE(total + 10000000 < slow);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, queue_line(0, 20000000, 1000000000, true, 1));
    calib_poll();
    drive_poll();
    drive_status(&st);
    TEST_ASSERT_EQUAL_INT64(total, st.queued_time_ns);
}

/* The chords of the drive's arc blocks join at the arc's centripetal limit
 * (PLAN_MOVE_ARC_JOIN), also where a second arc about the same centre
 * continues the first: two quarter circles of R 20 mm at 0.5 m/s (20
 * chords each at 10 kHz) plan exactly as plan_estimate of the same chords
 * with every join but the first flagged, at sqrt(a R) = 0.447 m/s instead of
 * the junction-deviation rule's 0.36 m/s at the chord corners (196.4 ms
 * instead of 214.4 ms). */
static void test_arc_chords_join_at_the_arc_limit(void)
{
    static plan_move_t m[128];
    drive_block_t b[2];
    pos_nm_t start[CORE_AXES] = {0, 0, 0}, ends[64][CORE_AXES];
    const pos_nm_t tgt[2][2] = {{-20000000, 20000000}, {-40000000, 0}};
    uint32_t n = 0, c, k, i;
    int64_t with, without;

    /* at-rest S-curve: the per-block S-curve's own look-ahead limit
     * (docs/planner.md) would hide the joins' speed on 20 chords */
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SHAPE, 0, SC_SHAPE_SCURVE_AT_REST));
    for (k = 0; k < 2; k++) {
        memset(&b[k], 0, sizeof b[k]);
        b[k].kind = DRIVE_BLOCK_ARC;
        b[k].tag = k + 1;
        b[k].target[0] = tgt[k][0];
        b[k].target[1] = tgt[k][1];
        b[k].feed_nm_s = 500000000;
        b[k].plane = DRIVE_PLANE_XY;
        b[k].centre_u = -20000000;
        b[k].centre_v = 0;
        b[k].sense = 1;
        b[k].exact_stop = k == 1;
        c = drive_arc_chords(&b[k], start, 3, drive_config()->tick_hz, drive_config()->arc_chord_nm,
                             &ends[0][0], 64);
        TEST_ASSERT_TRUE(c > 10 && n + c <= 64);
        for (i = 0; i < c; i++) {
            m[n] = move(ends[i][0], ends[i][1], 500000000, k == 1 && i + 1 == c);
            n++;
        }
        start[0] = tgt[k][0];
        start[1] = tgt[k][1];
    }
    without = estimate(m, n, NULL);
    for (i = 1; i < n; i++) {
        m[i].flags |= PLAN_MOVE_ARC_JOIN;
    }
    with = estimate(m, n, NULL);
    TEST_ASSERT_TRUE(with + 10000000 < without);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    run(1);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_queue_block(&b[0]));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_queue_block(&b[1]));
    calib_poll();
    drive_poll();
    drive_status(&st);
    TEST_ASSERT_EQUAL_INT64(with, st.queued_time_ns);
}

/* The arc overlay's chord fraction: fx_div_q30_rec (reciprocal, two
 * 32 x 32 products, exact remainder correction) equals the 64-bit division
 * round(n * 2^30 / d) it replaces over its whole stated range, 0 <= n <= d,
 * 1 <= d < 2^32: edges of every divisor size and 10^6 random pairs. */
static void test_reciprocal_fraction_equals_the_division(void)
{
    uint64_t x = 88172645463325252u; /* xorshift64 */
    uint32_t k, bad = 0;
    unsigned b;

    for (k = 0; k < 1000000u + 32u * 8u; k++) {
        uint32_t d, n;
        if (k < 32u * 8u) { /* every bit length, edge numerators */
            b = k / 8u;
            d = (k % 2u) ? (uint32_t)((((uint64_t)1 << (b + 1)) - 1u)) : ((uint32_t)1 << b);
            switch ((k / 2u) % 4u) {
            case 0:
                n = 0;
                break;
            case 1:
                n = d;
                break;
            case 2:
                n = d - 1u;
                break;
            default:
                n = d / 2u + (d & 1u);
                break;
            }
        } else {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            b = (unsigned)(x >> 59) + 1u; /* divisor bit length 1..32 */
            d = (uint32_t)(x >> 8) >> (32u - b);
            if (d == 0u) {
                d = 1u;
            }
            n = (uint32_t)(((x & 0xFFFFFFFFu) * ((uint64_t)d + 1u)) >> 32);
        }
        if ((int64_t)fx_div_q30_rec(n, d, fx_recip62(d)) !=
            fx_div_round64((int64_t)n << 30, (int64_t)d)) {
            bad++;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, bad);
    TEST_ASSERT_EQUAL_UINT32(1u << 30,
                             fx_div_q30_rec(0xFFFFFFFFu, 0xFFFFFFFFu, fx_recip62(0xFFFFFFFFu)));
    TEST_ASSERT_EQUAL_UINT32(1u << 29, fx_div_q30_rec(1, 2, fx_recip62(2)));
    TEST_ASSERT_EQUAL_UINT32(357913941u, fx_div_q30_rec(1, 3, fx_recip62(3))); /* 2^30 / 3 */
}

/* Reference scales (drive_status_t.refscale): the tick reads the counters
 * on every DRIVE_REF_SAMPLE_TICKS-th tick and on the tick after a
 * drive_status() call. With the counter moving at the largest speed the
 * wrap guard allows (2^31 - 64 counts per sampling period: it wraps about
 * every period), every published value is exact: the sample of the last
 * sampling tick, or of this tick after a drive_status(). Fails when the
 * period is longer than stated (a wrong wrap), when there is no periodic
 * sample or when drive_status() does not request one. */
static void test_reference_scale_samples_and_wrap_guard(void)
{
    const uint32_t raw0 = 0xFFFFFF00u;
    const uint32_t step = (1u << 31) / DRIVE_REF_SAMPLE_TICKS - 1u;
    drive_config_t cfg;
    drive_status_t s;
    uint64_t t = 1000000;
    uint32_t raw = raw0, k;
    int64_t cnt = (int32_t)raw0, sampled;

    drive_config_default(&cfg, 10000, 1);
    cfg.ref_nm_per_count_num[0] = 5;
    cfg.ref_nm_per_count_den[0] = 1;
    hal_sim_set_time_ns(t);
    hal_sim_set_counter(1, raw0, true);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_init(&cfg));
    calib_init();
    TEST_ASSERT_TRUE(drive_has_refscale(0));
    sampled = 5 * cnt; /* set by the first tick (k = 0) */
    for (k = 0; k < 12u * DRIVE_REF_SAMPLE_TICKS; k++) {
        bool status = k >= 6u * DRIVE_REF_SAMPLE_TICKS; /* a status every tick */
        raw += step;
        cnt += step;
        t += TICK_NS;
        hal_sim_set_time_ns(t);
        hal_sim_set_counter(1, raw, true);
        /* tick number k since drive_init */
        {
            const drive_tick_out_t *t = drive_tick(calib_sampling());
            if (t != NULL) {
                calib_tick(t->st, t->vel_ref);
            }
        }
        if (k % DRIVE_REF_SAMPLE_TICKS == 0u || (status && k > 6u * DRIVE_REF_SAMPLE_TICKS)) {
            sampled = 5 * cnt;
        }
        if (status) {
            drive_status(&s);
        } else {
            drive_snapshot(&s);
        }
        TEST_ASSERT_EQUAL_INT64(sampled, s.refscale[0]);
    }
    TEST_ASSERT_TRUE(cnt > 4 * ((int64_t)1 << 32)); /* wrapped several times */
}

/* One job (line, helix arc, line; friction feed-forward on X or none; a
 * controlled stop during the second line) with the drive's pos-only reference copy on
 * the interpolator's fast-path ticks or with the full copy every tick
 * (drive_test_full_ref): reference, feed-forward velocity and motor
 * voltages of every tick. */
#define FR_TICKS 4500u
static int64_t fr_out[2][FR_TICKS][3 * CORE_AXES];
static bool fr_cec; /* contour error control on (reads the arc geometry) */

static void full_ref_job(int full, bool friction)
{
    const int64_t a[CORE_AXES] = {2000000, 0, 0};
    const int64_t b[CORE_AXES] = {2000000, 0, 400000}; /* a full circle, up 0.4 mm */
    const int64_t c[CORE_AXES] = {0, 1000000, 400000};
    uint32_t k;
    int r, i;

    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(0, "kaff", 0.002));
    /* robust CEC gains (default.toml): the servo's defaults are the thesis's,
     * which limit-cycle at 10 kHz and now fault (oscillation) */
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kp", 2000.0));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "ki", 2e5));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kd", 2.0));
    TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "d_tau", 1e-3));
    if (friction) {
        TEST_ASSERT_EQUAL_INT(0, sim_servo_set(0, "friction_ff", 0.3));
    }
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    if (fr_cec) {
        TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_cec_mode(DRIVE_CEC_EXACT));
    }
    drive_test_full_ref(full != 0);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(a, 30000000, 1, 0, &r));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, r);
    TEST_ASSERT_EQUAL_INT(0, sim_queue_arc(b, 30000000, DRIVE_PLANE_XY, 1000000, 0, 1, 2, &r));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, r);
    TEST_ASSERT_EQUAL_INT(0, sim_queue_line(c, 30000000, 3, 1, &r));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, r);
    for (k = 0; k < FR_TICKS; k++) {
        if (k == 3300u) {
            drive_stop();
        }
        TEST_ASSERT_TRUE(sim_run(1, NULL, 0, 0) >= 0);
        drive_snapshot(&st);
        for (i = 0; i < CORE_AXES; i++) {
            fr_out[full][k][i] = st.ref[i];
            fr_out[full][k][CORE_AXES + i] = st.vel_ref[i];
            fr_out[full][k][2 * CORE_AXES + i] = st.motor_mv[i];
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
}

/* The pos-only copy gives the same outputs as the full copy on every tick
 * (fails e.g. when the arc overlay reads its own output of the last tick
 * or the friction feed-forward is added again to an uncopied acceleration). */
static void pos_only_vs_full(bool friction)
{
    uint32_t k, bad = 0, first = FR_TICKS;
    unsigned i;

    full_ref_job(1, friction);
    full_ref_job(0, friction);
    for (k = 0; k < FR_TICKS; k++) {
        for (i = 0; i < 3 * CORE_AXES; i++) {
            if (fr_out[0][k][i] != fr_out[1][k][i]) {
                bad++;
                first = k < first ? k : first;
            }
        }
    }
    if (bad != 0) {
        printf("first difference at tick %u\n", first);
    }
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, bad, "pos-only copy differs");
    TEST_ASSERT_TRUE(fr_out[0][2500][1] != 0);                 /* on the arc */
    TEST_ASSERT_TRUE(fr_out[0][2500][2] != 0);                 /* climbing */
    TEST_ASSERT_TRUE(fr_out[0][3299][1] > fr_out[0][3000][1]); /* last line */
    TEST_ASSERT_TRUE(fr_out[0][FR_TICKS - 1][1] < 1000000);    /* stopped on it */
    TEST_ASSERT_EQUAL_INT64(0, fr_out[0][FR_TICKS - 1][CORE_AXES + 1]);
}

static void test_pos_only_reference_copy_equals_the_full_copy(void)
{
    pos_only_vs_full(false);
    pos_only_vs_full(true);
    /* the arc's geometry (kept from the last tick on a pos-only copy) is
     * what contour error control reads */
    fr_cec = true;
    pos_only_vs_full(false);
    fr_cec = false;
}

/* The arc overlay's cruise recurrence (arc_ref.h, "Arc overlay on cruise
 * ticks") against the exact overlay (drive_test_arc_exact, the oracle) on
 * the same job: the reference of every tick (position, velocity,
 * acceleration, tangent, radius of the two plane axes) within the bounds
 * drive.h states. Two jobs: a helix like the firmware benchmark's (5 mm
 * radius, short chords) and three chords of the maximum angle
 * DRIVE_ARC_SEG_MAX_ANGLE at a radius near the fast path's 2^31 nm limit,
 * each thousands of ticks long (re-anchoring every ARC_REF_ROT_TICKS).
 * Fails with a wrong step (e.g. without the interpolator's length
 * correction or the remainder of the step), a drifting rotation, or when
 * the recurrence is not in use at all. */
#define RC_TICKS 40000u
typedef struct {
    int64_t pos[2], vel[2], acc[2], tan[2], rad;
} rc_out_t;
static rc_out_t rc_out[RC_TICKS];

typedef struct {
    int64_t pos, vel, acc, tan; /* largest differences                    */
    double rel;                 /* largest difference / its bound         */
    uint32_t differ, ticks;     /* ticks with some difference, arc ticks */
} rc_diff_t;

/* |x| / bound, kept in d->rel when larger */
static void rc_rel(rc_diff_t *d, int64_t x, double bound)
{
    double q = (double)(x < 0 ? -x : x) / bound;
    d->rel = q > d->rel ? q : d->rel;
}

/* The arc of rc_job: plane (u, v, w axes) and sense (+1 ccw, -1 cw). */
static drive_plane_t rc_plane = DRIVE_PLANE_XY;
static int rc_sense = 1;

static void rc_job(bool exact, int64_t radius, int64_t feed, int64_t chord_nm, uint32_t sweep_q16,
                   uint32_t ticks, rc_diff_t *d)
{
    /* start at the origin, centre (-radius, 0) in the plane; end after
     * sweep_q16 / 2^16 turns (0: a full circle), climbing 0.3 mm along w */
    static const uint8_t uvw[3][3] = {{0, 1, 2}, {2, 0, 1}, {1, 2, 0}}; /* XY, ZX, YZ */
    const uint8_t *ax = uvw[rc_plane];
    int64_t end[CORE_AXES] = {0, 0, 0};
    const motion_ref_t *r = drive_test_ref();
    uint32_t k;
    int res, i;

    end[ax[2]] = 300000;
    if (sweep_q16 != 0) {
        double a = 6.283185307179586 * sweep_q16 / 65536.0;
        end[ax[0]] = (int64_t)(radius * cos(a)) - radius;
        end[ax[1]] = (int64_t)(rc_sense * radius * sin(a));
    }
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_ARC_CHORD, 0, chord_nm));
    drive_test_arc_exact(exact);
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_EQUAL_INT(0, sim_queue_arc(end, feed, rc_plane, -radius, 0, rc_sense, 2, &res));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, res);
    for (k = 0; k < ticks; k++) {
        rc_out_t *o = &rc_out[k];
        TEST_ASSERT_TRUE(sim_run(1, NULL, 0, 0) >= 0);
        if (exact) {
            for (i = 0; i < 2; i++) {
                o->pos[i] = r->pos[ax[i]];
                o->vel[i] = r->vel[ax[i]];
                o->acc[i] = r->acc[ax[i]];
                o->tan[i] = r->geom.tangent[ax[i]];
            }
            o->rad = r->geom.kind == MOTION_GEOM_ARC ? r->geom.radius : -1;
            continue;
        }
        if (o->rad != (r->geom.kind == MOTION_GEOM_ARC ? r->geom.radius : -1)) {
            d->differ++; /* counted, and the radius must agree below */
        }
        TEST_ASSERT_INT64_WITHIN(1, o->rad, r->geom.kind == MOTION_GEOM_ARC ? r->geom.radius : -1);
        if (o->rad < 0) {
            continue;
        }
        d->ticks++;
        {
            bool diff = false;
            /* arc_ref.h's bounds: eps = (2 nm + r 2^-28) / r */
            double eps = (2.0 + (double)o->rad / (1 << 28)) / (double)o->rad;
            double vm = hypot((double)o->vel[0], (double)o->vel[1]);
            double am = hypot((double)o->acc[0], (double)o->acc[1]);
            for (i = 0; i < 2; i++) {
                int64_t dp = o->pos[i] - r->pos[ax[i]], dv = o->vel[i] - r->vel[ax[i]];
                int64_t da = o->acc[i] - r->acc[ax[i]], dt = o->tan[i] - r->geom.tangent[ax[i]];
                rc_rel(d, dp, eps * (double)o->rad);
                rc_rel(d, dv, 2.0 + eps * vm);
                rc_rel(d, da, 2.0 + eps * am);
                rc_rel(d, dt, 2.0 + eps * (double)(1 << 30));
                diff = diff || dp != 0 || dv != 0 || da != 0 || dt != 0;
                d->pos = dp < 0 && -dp > d->pos ? -dp : (dp > d->pos ? dp : d->pos);
                d->vel = dv < 0 && -dv > d->vel ? -dv : (dv > d->vel ? dv : d->vel);
                d->acc = da < 0 && -da > d->acc ? -da : (da > d->acc ? da : d->acc);
                d->tan = dt < 0 && -dt > d->tan ? -dt : (dt > d->tan ? dt : d->tan);
            }
            d->differ += diff ? 1u : 0u;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, st.faults);
    drive_test_arc_exact(false);
}

static void rc_compare(int64_t radius, int64_t feed, int64_t chord_nm, uint32_t sweep_q16,
                       uint32_t ticks, rc_diff_t *d)
{
    memset(d, 0, sizeof *d);
    rc_job(true, radius, feed, chord_nm, sweep_q16, ticks, d);
    rc_job(false, radius, feed, chord_nm, sweep_q16, ticks, d);
    printf("arc recurrence r=%lld: %u arc ticks, %u differ; max |dpos| %lld nm, |dvel| %lld "
           "nm/s, |dacc| %lld nm/s^2, |dtan| %lld q30; worst %.3f of the bound\n",
           (long long)radius, d->ticks, d->differ, (long long)d->pos, (long long)d->vel,
           (long long)d->acc, (long long)d->tan, d->rel);
}

static void test_arc_recurrence_stays_within_its_bound_of_the_exact_overlay(void)
{
    rc_diff_t d;

    /* the benchmark's helix: 5 mm at 20 mm/s, chords of a few tens of ticks */
    rc_compare(5000000, 20000000, 100, 0, 17000u, &d);
    TEST_ASSERT_TRUE(d.ticks > 15000u);
    TEST_ASSERT_TRUE(d.differ > d.ticks / 4u); /* the recurrence is in use */
    TEST_ASSERT_TRUE(d.rel <= 1.0);
    /* the HIL bench circle, R 20 mm at 10 m/min: v^2/r 1.39 m/s^2, on the
     * recurrence since ARC_REF_AC_MAX (arc_ref.h) */
    rc_compare(20000000, 166666667, 100, 0, 9000u, &d);
    TEST_ASSERT_TRUE(d.ticks > 7000u);
    TEST_ASSERT_TRUE(d.differ > d.ticks / 4u);
    TEST_ASSERT_TRUE(d.rel <= 1.0);
    /* three chords of the maximum angle (the chord tolerance above the
     * radius), 1.9e9 nm radius at 150 mm/s: about 12000 ticks each */
    rc_compare(1900000000, 150000000, 1000000000, 3u * 65536u / 64u, RC_TICKS, &d);
    TEST_ASSERT_TRUE(d.ticks > 35000u);
    TEST_ASSERT_TRUE(d.differ > d.ticks / 4u);
    TEST_ASSERT_TRUE(d.rel <= 1.0);
    /* clockwise, and the other two planes (the signs of the step and of the
     * tangent, other axis mappings): a quarter of the helix each */
    rc_sense = -1;
    rc_compare(5000000, 20000000, 100, 65536u / 4u, 5000u, &d);
    TEST_ASSERT_TRUE(d.ticks > 3500u && d.differ > d.ticks / 4u && d.rel <= 1.0);
    rc_plane = DRIVE_PLANE_ZX;
    rc_compare(5000000, 20000000, 100, 65536u / 4u, 5000u, &d);
    TEST_ASSERT_TRUE(d.ticks > 3500u && d.differ > d.ticks / 4u && d.rel <= 1.0);
    rc_sense = 1;
    rc_plane = DRIVE_PLANE_YZ;
    rc_compare(5000000, 20000000, 100, 65536u / 4u, 5000u, &d);
    TEST_ASSERT_TRUE(d.ticks > 3500u && d.differ > d.ticks / 4u && d.rel <= 1.0);
    rc_plane = DRIVE_PLANE_XY;
}

/* drive_trace_read (the simulator's trace rows) against drive_snapshot on
 * every tick of a job with the exact CEC (line, arc, line, a stop, then
 * a fault), three axes and two: the same state, faults, contour error,
 * reference and measured positions (fails when a field is read from the
 * published status instead of the live state, or the other way round). */
static void test_trace_read_equals_the_snapshot(void)
{
    const int64_t a[CORE_AXES] = {2000000, 0, 0};
    const int64_t b[CORE_AXES] = {2000000, 0, 400000};
    unsigned axes, i;
    uint32_t k;
    int r;

    for (axes = 2; axes <= 3; axes++) {
        int ce = 0, moving = 0;
        pos_nm_t last = 0;
        TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, axes));
        TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kp", 2000.0));
        TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "ki", 2e5));
        TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "kd", 2.0));
        TEST_ASSERT_EQUAL_INT(0, sim_gain_set(-1, "d_tau", 1e-3));
        TEST_ASSERT_EQUAL_INT(0, sim_start());
        TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_cec_mode(DRIVE_CEC_EXACT));
        TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
        TEST_ASSERT_EQUAL_INT(0, sim_queue_line(a, 30000000, 1, 0, &r));
        TEST_ASSERT_EQUAL_INT(0, sim_queue_arc(b, 30000000, DRIVE_PLANE_XY, 1000000, 0, 1, 2, &r));
        TEST_ASSERT_EQUAL_INT(0, sim_queue_line(a, 30000000, 3, 0, &r));
        for (k = 0; k < 4000u; k++) {
            drive_trace_t t;
            if (k == 3000u) {
                drive_stop();
            }
            if (k == 3600u) {
                drive_raise_fault(DRIVE_FAULT_COMM);
            }
            TEST_ASSERT_TRUE(sim_run(1, NULL, 0, 0) >= 0);
            drive_snapshot(&st);
            drive_trace_read(&t);
            TEST_ASSERT_EQUAL_INT(st.state, t.state);
            TEST_ASSERT_EQUAL_UINT32(st.faults, t.faults);
            TEST_ASSERT_EQUAL_INT64(st.contour_error_nm, t.contour_error_nm);
            for (i = 0; i < CORE_AXES; i++) {
                TEST_ASSERT_EQUAL_INT64(st.ref[i], t.ref[i]);
                TEST_ASSERT_EQUAL_INT64(st.pos[i], t.pos[i]);
            }
            ce += t.contour_error_nm != 0;
            moving += t.ref[0] != last;
            last = t.ref[0];
        }
        TEST_ASSERT_TRUE(ce > 1000);       /* the CEC ran */
        TEST_ASSERT_TRUE(moving > 1000);   /* the axes moved */
        TEST_ASSERT_TRUE(st.faults != 0u); /* and the fault was seen */
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_block_queued_right_after_enable_runs);
    RUN_TEST(test_reciprocal_fraction_equals_the_division);
    RUN_TEST(test_reference_scale_samples_and_wrap_guard);
    RUN_TEST(test_arc_recurrence_stays_within_its_bound_of_the_exact_overlay);
    RUN_TEST(test_pos_only_reference_copy_equals_the_full_copy);
    RUN_TEST(test_trace_read_equals_the_snapshot);
    RUN_TEST(test_enable_queue_poll_before_the_first_tick);
    RUN_TEST(test_status_reports_planned_time_queued);
    RUN_TEST(test_planned_time_counts_blocks_waiting_in_the_planner);
    RUN_TEST(test_short_blocks_keep_the_interpolator_fed);
    RUN_TEST(test_stop_decelerates_on_the_path_and_drops_the_job);
    RUN_TEST(test_stop_while_accelerating_never_speeds_up);
    RUN_TEST(test_stop_when_idle_or_disabled_changes_nothing);
    RUN_TEST(test_estop_disables_at_once_and_needs_a_reset);
    RUN_TEST(test_estop_with_enable_in_the_same_tick_keeps_motors_off);
    RUN_TEST(test_external_fault_stops_in_a_controlled_way);
    RUN_TEST(test_enable_right_after_a_reset_waits_for_it);
    RUN_TEST(test_amplifier_fault_reset_refused_while_present);
    RUN_TEST(test_reset_during_ramp_down_applies_once_stopped);
    RUN_TEST(test_following_error_disables);
    RUN_TEST(test_parameters_are_checked_and_never_half_applied);
    RUN_TEST(test_parameters_are_refused_while_moving);
    RUN_TEST(test_new_limits_are_what_the_planner_uses);
    RUN_TEST(test_one_axis_limit_is_used_by_its_axis);
    RUN_TEST(test_arc_chords_join_at_the_arc_limit);
    return UNITY_END();
}
