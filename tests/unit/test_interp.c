/*
 * Interpolator: per-tick references from the planner's frozen segments.
 *
 * The random path test runs 100 000 random blocks (lengths 0.02-3 mm, random
 * directions, feeds 10-300 mm/s, some exact stops, S-curve and trapezoid
 * halves) through the planner and the interpolator exactly as the drive's
 * main loop does (push until full before each pop), and checks on every tick:
 *   - per-axis speed by differencing positions: |dp| <= v_i h + 1 nm;
 *   - per-axis acceleration by second differences inside a block:
 *     |d2p| <= a_i h^2 + 2 nm (rounding of the positions to 1 nm);
 *   - per-axis jerk from the acceleration feed-forward (closed form, not
 *     rounded to nm): |d acc| <= j_i h + 1 nm/s^2 inside S-curve blocks
 *     (at-rest shape: blocks whose estimated entry or exit speed is 0);
 *   - feed-forward speed and acceleration within the axis limits;
 *   - every block ends within one tick of the sum of the estimated block
 *     times (plan_estimate() on the same moves, the job-time estimator's
 *     entry point): |end tick * h - cumulative estimate| < h;
 *   - the final position is the last target, exactly; no underrun.
 * Under ASan the unit test uses a 1 ms tick (1.6 million ticks); the same
 * check at 10 kHz (16 million ticks) runs unsanitized in bench-planner.sh
 * (`interp_random_path_*` figures).
 */
#include "estimator.h"
#include "interp.h"
#include "planner.h"
#include "unity.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "path_check.h"

void setUp(void)
{
}

void tearDown(void)
{
}

static void test_single_block_lands_exactly(void)
{
    static plan_block_t store[8];
    plan_profile_t prof = pc_profile(SC_SHAPE_SCURVE);
    plan_t p;
    interp_t ip;
    motion_ref_t ref;
    plan_move_t m;
    plan_seg_t seg;
    const pos_nm_t o[CORE_AXES] = {1, 2, 3};
    uint64_t n = 0;
    int64_t total;

    memset(&m, 0, sizeof(m));
    m.target[0] = 12345679;
    m.target[1] = -7654321;
    m.target[2] = 3;
    m.feed = 50000000;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&p, store, 8, &prof, o));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&p, &m));
    total = plan_queued_ns(&p);
    interp_init(&ip, 100000, o);
    TEST_ASSERT_EQUAL_UINT(1, interp_refill(&ip, &p));
    seg = ip.fifo[0];
    TEST_ASSERT_EQUAL_INT64(total, seg.total_ns);
    do {
        interp_tick(&ip, &ref);
        n++;
        TEST_ASSERT_TRUE(n < 10000000);
    } while (!interp_idle(&ip));
    TEST_ASSERT_EQUAL_UINT64((uint64_t)((total + 99999) / 100000), n);
    TEST_ASSERT_EQUAL_INT64(12345679, ref.pos[0]);
    TEST_ASSERT_EQUAL_INT64(-7654321, ref.pos[1]);
    TEST_ASSERT_EQUAL_INT64(3, ref.pos[2]);
    TEST_ASSERT_EQUAL_INT64(0, ref.vel[0]);
    /* idle afterwards: holds, inactive */
    interp_tick(&ip, &ref);
    TEST_ASSERT_FALSE(ref.active);
    TEST_ASSERT_EQUAL_INT64(12345679, ref.pos[0]);
    TEST_ASSERT_EQUAL_INT(MOTION_GEOM_NONE, ref.geom.kind);
}

static void test_geometry_and_feed_forward(void)
{
    static plan_block_t store[8];
    plan_profile_t prof = pc_profile(SC_SHAPE_TRAPEZOID);
    plan_t p;
    interp_t ip;
    motion_ref_t ref;
    plan_move_t m;
    const pos_nm_t o[CORE_AXES] = {0, 0, 0};
    int k;

    memset(&m, 0, sizeof(m));
    m.target[0] = 30000000; /* 3-4-5 triangle: tangent (0.6, 0.8) */
    m.target[1] = 40000000;
    m.feed = 50000000;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&p, store, 8, &prof, o));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&p, &m));
    interp_init(&ip, 100000, o);
    interp_refill(&ip, &p);
    for (k = 0; k < 3000; k++) {
        interp_tick(&ip, &ref);
    }
    TEST_ASSERT_EQUAL_INT(MOTION_GEOM_LINE, ref.geom.kind);
    TEST_ASSERT_INT_WITHIN(2, (int32_t)(0.6 * (1 << 30)), ref.geom.tangent[0]);
    TEST_ASSERT_INT_WITHIN(2, (int32_t)(0.8 * (1 << 30)), ref.geom.tangent[1]);
    TEST_ASSERT_EQUAL_INT64(0, ref.geom.start[0]);
    /* cruising at 50 mm/s: feed-forward 30 and 40 mm/s, no acceleration */
    TEST_ASSERT_INT64_WITHIN(2, 30000000, ref.vel[0]);
    TEST_ASSERT_INT64_WITHIN(2, 40000000, ref.vel[1]);
    TEST_ASSERT_EQUAL_INT64(0, ref.acc[0]);
    TEST_ASSERT_TRUE(ref.active);
}

/* The reference of one tick recomputed from the segment with the closed
 * form and the 128-bit helpers (what interp_tick computed before its cruise
 * increments and inline products): every field must be equal, bit for bit. */
static void ref_closed_form(const interp_t *ip, motion_ref_t *out)
{
    const plan_seg_t *s = &ip->fifo[ip->rd & (INTERP_FIFO - 1)];
    int64_t tau = ip->t_ns - ip->phase_t0, sq, lq = s->len * 65536;
    sc_state_t st;
    int i;

    if (tau > s->prof.t_ns[ip->phase]) {
        tau = s->prof.t_ns[ip->phase];
    }
    sc_eval_phase(&s->prof, ip->phase, tau, &st);
    sq = st.s_q16 + fx_mul64_shift(st.s_q16, ip->corr_q32, 32);
    sq = sq < 0 ? 0 : (sq > lq ? lq : sq);
    for (i = 0; i < CORE_AXES; i++) {
        out->pos[i] = s->start[i] + fx_mul64_shift(sq, s->ratio_q62[i], 78);
        out->vel[i] = fx_mul64_shift(st.v_q16, s->ratio_q62[i], 78);
        out->acc[i] = fx_mul64_shift(st.a_q16, s->ratio_q62[i], 78);
        out->geom.tangent[i] = (q1_30_t)(s->ratio_q62[i] / ((int64_t)1 << 32));
    }
}

/* Cruise phases advance by exact quotient and remainder increments; fast
 * moves, long cruises (many remainder carries), an odd tick period and a
 * tick period that changes on the way (as the drive's stop ramp does) must
 * give exactly the closed form on every tick. */
static void test_cruise_increments_equal_closed_form(void)
{
    static plan_block_t store[16];
    plan_profile_t prof = pc_profile(SC_SHAPE_SCURVE);
    plan_t p;
    interp_t ip;
    motion_ref_t ref, chk;
    plan_move_t m;
    const pos_nm_t o[CORE_AXES] = {-5, 7, 11};
    static const int64_t tgt[][3] = {{400000000, 3, -1},
                                     {400000123, 250000007, 9999},
                                     {-1234567, 250000007, 20000000},
                                     {0, 0, 0}};
    static const int64_t feed[] = {499999999, 123456789, 77777777, 300000000};
    uint32_t checked = 0, cruise = 0, fast = 0;
    int k, n = 0;

    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&p, store, 16, &prof, o));
    for (k = 0; k < 4; k++) {
        memset(&m, 0, sizeof(m));
        m.target[0] = tgt[k][0];
        m.target[1] = tgt[k][1];
        m.target[2] = tgt[k][2];
        m.feed = feed[k];
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&p, &m));
    }
    interp_init(&ip, 100003, o);
    while (interp_refill(&ip, &p) != 0) {
    }
    do {
        n++;
        if (n % 20000 == 0) { /* an odd step for a while, then back */
            interp_set_tick_ns(&ip, (n / 20000) % 2 ? 33331 : 100003);
        }
        fast += ip.cr_fast ? 1u : 0u; /* this tick may take the fast path */
        interp_tick(&ip, &ref);
        if (interp_busy(&ip) && ip.fifo[ip.rd & (INTERP_FIFO - 1)].dwell_ns == 0) {
            ref_closed_form(&ip, &chk);
            TEST_ASSERT_EQUAL_INT(MOTION_GEOM_LINE, ref.geom.kind);
            TEST_ASSERT_TRUE(ref.active);
            for (k = 0; k < CORE_AXES; k++) {
                TEST_ASSERT_EQUAL_INT64(chk.pos[k], ref.pos[k]);
                TEST_ASSERT_EQUAL_INT64(chk.vel[k], ref.vel[k]);
                TEST_ASSERT_EQUAL_INT64(chk.acc[k], ref.acc[k]);
                TEST_ASSERT_EQUAL_INT32(chk.geom.tangent[k], ref.geom.tangent[k]);
                TEST_ASSERT_EQUAL_INT64(ip.fifo[ip.rd & (INTERP_FIFO - 1)].start[k],
                                        ref.geom.start[k]);
            }
            checked++;
            cruise += ip.cr_ok ? 1u : 0u;
        }
        TEST_ASSERT_TRUE(n < 10000000);
    } while (!interp_idle(&ip));
    TEST_ASSERT_TRUE(cruise > 10000); /* the increments are exercised */
    TEST_ASSERT_TRUE(fast > 10000);   /* and the cruise fast path */
    TEST_ASSERT_TRUE(checked > cruise + 100);
    TEST_ASSERT_EQUAL_INT64(0, ref.pos[0]);
    TEST_ASSERT_EQUAL_INT64(0, ref.pos[2]);
}

static void test_random_path_100k(void)
{
    pc_result_t r;
    pc_run(100000, 1000000, 12345u, SC_SHAPE_SCURVE, &r); /* 1 ms tick under ASan */
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_1khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(100000, r.blocks);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
    TEST_ASSERT_TRUE(r.max_block_err_ns < 1000000);
}

static void test_random_path_trapezoid(void)
{
    pc_result_t r;
    pc_run(20000, 250000, 777u, SC_SHAPE_TRAPEZOID, &r);
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_trapezoid_4khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
}

/* At-rest S-curve: blocks that start or end at rest are jerk-limited S-curves
 * (checked against the jerk limit on every tick), the others trapezoids; the
 * shape is decided from the final speeds at pop, so execution still equals
 * the estimate within one tick per block. */
static void test_random_path_scurve_at_rest(void)
{
    pc_result_t r;
    pc_run(20000, 250000, 999u, SC_SHAPE_SCURVE_AT_REST, &r);
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_at_rest_4khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_TRUE(r.jerk_checks > 10000); /* S-curve blocks are exercised */
    TEST_ASSERT_TRUE(r.max_j_ratio > 0.5);   /* and reach their jerk limit */
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
}

/* Continuous S-curve: blocks joined at non-zero path acceleration (many
 * block ends passed while accelerating), the path's acceleration and jerk
 * within the smallest axis limits on every tick, block ends included, the
 * axis references within their limits, and execution equal to the
 * estimate (the same pops). */
static void test_random_path_scurve_continuous(void)
{
    pc_result_t r;
    pc_run(20000, 250000, 1234u, SC_SHAPE_SCURVE_CONTINUOUS, &r); /* the rough paths */
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_continuous_rough_4khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_EQUAL_UINT32(0, r.cont_forced);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
    pc_smooth_paths = true;
    pc_run(20000, 250000, 31337u, SC_SHAPE_SCURVE_CONTINUOUS, &r);
    pc_smooth_paths = false;
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_continuous_4khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_TRUE(r.joins_accel > 1000); /* continuity is used */
    TEST_ASSERT_TRUE(r.max_j_ratio > 0.5);  /* the jerk limit is reached */
    TEST_ASSERT_TRUE(r.max_path_a_ratio > 0.5);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_EQUAL_UINT32(0, r.cont_forced);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
}

/* The same when the feed stops every 700 blocks: the drive comes to rest
 * at the end of what it has queued (the last queued block ends at rest)
 * within every limit, and goes on when blocks come again. */
static void test_random_path_scurve_continuous_stalls(void)
{
    pc_result_t r;
    pc_stall_every = 700;
    pc_smooth_paths = true;
    pc_run(20000, 250000, 4711u, SC_SHAPE_SCURVE_CONTINUOUS, &r);
    pc_smooth_paths = false;
    pc_stall_every = 0;
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_continuous_stalls_4khz", &r);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_TRUE(r.stalls >= 28);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_EQUAL_UINT32(0, r.cont_forced);
    TEST_ASSERT_TRUE(r.final_exact);
}

/* Axis limits by the axes a run moves: CAM-like paths on the test
 * machine (Y at half of X and Z's a, 0.4 of their j) that stay in the XZ
 * plane every other 200 blocks. Those runs take X and Z's limits (the
 * path's |a| above Y's a), every other run Y's; each axis within its own
 * v, a and j on every tick, the path's a and j within the limits of the
 * axes its block moves, execution equal to the estimate. */
static void test_random_path_scurve_continuous_axis_limits(void)
{
    pc_result_t r;
    pc_smooth_paths = true;
    pc_planar_xz = true;
    pc_run(20000, 250000, 2718u, SC_SHAPE_SCURVE_CONTINUOUS, &r);
    pc_planar_xz = false;
    pc_smooth_paths = false;
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_scurve_continuous_xz_4khz", &r);
    }
    printf("planar XZ stretches: path |a| up to %.3f of the smallest axis a\n",
           r.max_path_a_min_ratio);
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_TRUE(r.max_path_a_min_ratio > 1.2); /* above Y's a: X and Z's limits */
    TEST_ASSERT_TRUE(r.max_j_ratio > 0.5);
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_EQUAL_UINT32(0, r.cont_forced);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
}

/* Smoothed-corner rule with its block cap (each block capped by the larger
 * of its two corner speeds, known only once the next block is queued): the
 * drive-style push-before-pop loop still executes exactly the estimate. */
static void test_random_path_smooth_corner(void)
{
    pc_result_t r;
    plan_profile_t prof = pc_profile(SC_SHAPE_TRAPEZOID);
    int i;
    prof.corner = PLAN_CORNER_SMOOTH;
    for (i = 0; i < CORE_AXES; i++) {
        prof.corner_acc[i] = 150000000; /* 150 mm/s^2 */
    }
    pc_run_profile(20000, 250000, 4242u, &prof, &r);
    if (getenv("INTERP_REPORT")) {
        pc_print("interp_smooth_trapezoid_4khz", &r);
        printf("interp_smooth_corner_capped: %u blocks\n", r.corner_capped);
    }
    TEST_ASSERT_EQUAL_UINT32(20000, r.blocks);
    TEST_ASSERT_TRUE(r.corner_capped > 2000); /* the cap is exercised */
    TEST_ASSERT_EQUAL_UINT32(0, r.limit_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.time_violations);
    TEST_ASSERT_EQUAL_UINT32(0, r.underruns);
    TEST_ASSERT_TRUE(r.final_exact);
    TEST_ASSERT_TRUE(r.total_ticks_ok);
}

/* interp_t.fast_skip (the drive's arc recurrence rewrites the plane axes):
 * set again after every tick, a fast-path tick leaves the skipped axis of
 * the reference unwritten and gives the others exactly; every other tick
 * clears it and writes every axis exactly, and the job ends exactly on its
 * end point (the hold position is written where it is read). Fails when a
 * skipped axis is written, or a general tick keeps skipping. */
static void test_fast_skip_leaves_only_the_skipped_axes(void)
{
    static plan_block_t store[16];
    plan_profile_t prof = pc_profile(SC_SHAPE_SCURVE);
    plan_t p;
    interp_t ip;
    motion_ref_t ref, chk;
    plan_move_t m;
    const pos_nm_t o[CORE_AXES] = {-5, 7, 11};
    static const int64_t tgt[][3] = {{40000000, 3, -1}, {400123, 25000007, 9999}};
    uint32_t skipped = 0, general = 0;
    int k, n = 0;

    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&p, store, 16, &prof, o));
    for (k = 0; k < 2; k++) {
        memset(&m, 0, sizeof(m));
        m.target[0] = tgt[k][0];
        m.target[1] = tgt[k][1];
        m.target[2] = tgt[k][2];
        m.feed = 100000000;
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&p, &m));
    }
    interp_init(&ip, 100000, o);
    while (interp_refill(&ip, &p) != 0) {
    }
    memset(&ref, 0, sizeof(ref));
    do {
        int64_t before = ref.pos[1];
        n++;
        interp_tick(&ip, &ref);
        if (interp_busy(&ip) && ip.fifo[ip.rd & (INTERP_FIFO - 1)].dwell_ns == 0) {
            ref_closed_form(&ip, &chk);
            TEST_ASSERT_EQUAL_INT64(chk.pos[0], ref.pos[0]);
            TEST_ASSERT_EQUAL_INT64(chk.pos[2], ref.pos[2]);
            if (interp_pos_only(&ip)) {
                TEST_ASSERT_EQUAL_INT64(before, ref.pos[1]);
                skipped += chk.pos[1] != before ? 1u : 0u;
            } else {
                TEST_ASSERT_EQUAL_INT64(chk.pos[1], ref.pos[1]);
                general++;
            }
        }
        interp_set_fast_skip(&ip, 2u); /* axis 1, for the next fast-path ticks */
        TEST_ASSERT_TRUE(n < 1000000);
    } while (!interp_idle(&ip));
    interp_tick(&ip, &ref); /* idle: the hold position */
    TEST_ASSERT_TRUE(skipped > 1000u);
    TEST_ASSERT_TRUE(general > 10u);
    for (k = 0; k < CORE_AXES; k++) {
        TEST_ASSERT_EQUAL_INT64(tgt[1][k], ref.pos[k]);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_single_block_lands_exactly);
    RUN_TEST(test_geometry_and_feed_forward);
    RUN_TEST(test_cruise_increments_equal_closed_form);
    RUN_TEST(test_fast_skip_leaves_only_the_skipped_axes);
    RUN_TEST(test_random_path_100k);
    RUN_TEST(test_random_path_trapezoid);
    RUN_TEST(test_random_path_smooth_corner);
    RUN_TEST(test_random_path_scurve_at_rest);
    RUN_TEST(test_random_path_scurve_continuous);
    RUN_TEST(test_random_path_scurve_continuous_stalls);
    RUN_TEST(test_random_path_scurve_continuous_axis_limits);
    return UNITY_END();
}
