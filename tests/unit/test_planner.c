/*
 * Planner: CuraEngine-style cases with times checked against closed forms,
 * the cornering rules against their formulas, the minimum block time as a
 * throughput limit, and the incremental look-ahead against a from-scratch
 * re-plan of the same queue after every push (the passes only revisit
 * blocks whose plan can change, yet must give the same speeds).
 */
#include "estimator.h"
#include "planner.h"
#include "planner_test.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

__extension__ typedef unsigned __int128 u128;

#define MM  1000000LL /* nm */
#define MMS 1000000LL /* nm/s per mm/s */

static plan_block_t store[256];
static plan_t pl;

void setUp(void)
{
}

void tearDown(void)
{
}

static plan_profile_t base_profile(uint8_t shape, uint8_t corner)
{
    plan_profile_t p;
    int i;
    memset(&p, 0, sizeof(p));
    for (i = 0; i < CORE_AXES; i++) {
        p.v_max[i] = 500 * MMS;
        p.a_max[i] = 2000 * MMS;
        p.j_max[i] = 50000 * MMS;
        p.corner_dv[i] = 5 * MMS;
        p.corner_acc[i] = 300 * MMS;
    }
    p.junction_dev_nm = 10000; /* 0.01 mm */
    p.min_block_ns = 0;
    p.mbt_window = 1;
    p.corner = corner;
    p.shape = shape;
    return p;
}

static const pos_nm_t origin[CORE_AXES] = {0, 0, 0};

static plan_move_t mv(int64_t x, int64_t y, int64_t z, int64_t feed_mm_s)
{
    plan_move_t m;
    memset(&m, 0, sizeof(m));
    m.target[0] = x;
    m.target[1] = y;
    m.target[2] = z;
    m.feed = feed_mm_s * MMS;
    return m;
}

/* run moves through plan_estimate (depth 64) */
static int64_t run(const plan_profile_t *prof, const plan_move_t *m, uint32_t n, plan_est_t *out)
{
    uint32_t bad = 0, i;
    int64_t sum = 0;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_estimate(prof, origin, m, n, store, 64, out, &bad));
    for (i = 0; i < n; i++) {
        sum += out[i].t_total_ns;
    }
    return sum;
}

/* ---- single moves ----------------------------------------------------------- */

static void test_single_move_rest_to_rest(void)
{
    plan_profile_t t = base_profile(SC_SHAPE_TRAPEZOID, PLAN_CORNER_JD);
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_move_t m = mv(100 * MM, 0, 0, 100);
    plan_est_t o[4];

    /* trapezoidal: L/v + v/A = 1 + 0.05 s */
    TEST_ASSERT_INT64_WITHIN(5, 1050000000, run(&t, &m, 1, o));
    TEST_ASSERT_EQUAL_INT64(100 * MMS, o[0].v_peak);
    TEST_ASSERT_INT64_WITHIN(2, 50000000, o[0].t_acc_ns);
    TEST_ASSERT_INT64_WITHIN(2, 50000000, o[0].t_dec_ns);
    /* S-curve: L/v + v/A + A/J = 1 + 0.05 + 0.04 s */
    TEST_ASSERT_INT64_WITHIN(5, 1090000000, run(&s, &m, 1, o));
    TEST_ASSERT_INT64_WITHIN(2, 90000000, o[0].t_acc_ns);
    /* triangular (trapezoid never reaching feed): 1 mm at 2 m/s^2, 2 sqrt(L/A) */
    m = mv(1 * MM, 0, 0, 100);
    TEST_ASSERT_INT64_WITHIN(5, 44721360, run(&t, &m, 1, o));
    TEST_ASSERT_INT64_WITHIN(3, 44721359, o[0].v_peak);
    TEST_ASSERT_TRUE(o[0].t_cruise_ns <= 5);
}

static void test_short_move_never_reaches_feed(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_move_t m = mv(0, 50000, 0, 100); /* 0.05 mm at F6000 */
    plan_est_t o[1];
    double J = 50.0, L = 50e-6; /* reduced 4-phase: L = 2 J tj^3 */
    double tj = cbrt(L / (2 * J));
    int64_t t = run(&s, &m, 1, o);
    TEST_ASSERT_TRUE(o[0].v_peak < 100 * MMS);
    /* peak from a closed-form lower bound: within 0.2 % of the optimum 4 tj */
    TEST_ASSERT_TRUE((double)t >= 4 * tj * 1e9 - 5);
    TEST_ASSERT_TRUE((double)t <= 4 * tj * 1e9 * 1.002);
}

/* ---- junctions ------------------------------------------------------------------ */

static void test_collinear_junction_keeps_speed(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_move_t m[2] = {mv(50 * MM, 0, 0, 100), mv(100 * MM, 0, 0, 100)};
    plan_move_t one = mv(100 * MM, 0, 0, 100);
    plan_est_t o[2];
    int64_t t2 = run(&s, m, 2, o), t1;
    TEST_ASSERT_EQUAL_INT64(100 * MMS, o[0].v_exit);
    TEST_ASSERT_EQUAL_INT64(100 * MMS, o[1].v_entry);
    t1 = run(&s, &one, 1, o);
    TEST_ASSERT_INT64_WITHIN(10, t1, t2);
}

static double corner_speed(uint8_t corner, int64_t dx2, int64_t dy2, int64_t len1, int64_t *entry)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, corner);
    plan_move_t m[2] = {mv(len1, 0, 0, 400), mv(len1 + dx2, dy2, 0, 400)};
    plan_est_t o[2];
    run(&s, m, 2, o);
    *entry = o[1].v_entry;
    return (double)o[1].v_entry;
}

static void test_90_degree_junction_rules(void)
{
    int64_t e;
    /* junction deviation: v^2 = a_j dev s / (1 - s), s = sin 45, a_j = 2000 sqrt 2 */
    double s = sqrt(0.5), aj = 2000e6 * sqrt(2.0);
    double ref = sqrt(aj * 10000.0 * s / (1 - s));
    corner_speed(PLAN_CORNER_JD, 0, 100 * MM, 100 * MM, &e);
    TEST_ASSERT_TRUE(fabs((double)e - ref) <= 1e-4 * ref + 2);
    /* velocity step: v = dv / |du| = 5 mm/s / 1 */
    corner_speed(PLAN_CORNER_VSTEP, 0, 100 * MM, 100 * MM, &e);
    TEST_ASSERT_INT64_WITHIN(2, 5 * MMS, e);
    /* smoothed corner: v = sqrt(a_c l / |du|), l = 100 mm, |du| = 1 */
    ref = sqrt(300e6 * 100e6 / 1.0);
    corner_speed(PLAN_CORNER_SMOOTH, 0, 100 * MM, 100 * MM, &e);
    TEST_ASSERT_TRUE(fabs((double)e - ref) <= 1e-6 * ref + 2);
    /* smoothed corner on short blocks: l = 0.1 mm, 10 degree turn */
    {
        double ang = 10.0 * M_PI / 180.0, du = 1 - cos(ang);
        int64_t l = 100000, dx = (int64_t)llround(100000 * cos(ang)),
                dy = (int64_t)llround(100000 * sin(ang));
        double dux = fabs((double)dx / hypot((double)dx, (double)dy) - 1.0);
        double duy = fabs((double)dy / hypot((double)dx, (double)dy));
        double vx = sqrt(300e6 * 1e5 / dux), vy = sqrt(300e6 * 1e5 / duy);
        (void)du;
        ref = fmin(vx, vy);
        corner_speed(PLAN_CORNER_SMOOTH, dx, dy, l, &e);
        /* the entry can also be limited by stopping at the end of block 2 */
        TEST_ASSERT_TRUE((double)e <= ref * (1 + 1e-5) + 2);
    }
    /* exact-stop rule */
    corner_speed(PLAN_CORNER_STOP, 0, 100 * MM, 100 * MM, &e);
    TEST_ASSERT_EQUAL_INT64(0, e);
}

static void test_reversal_stops(void)
{
    int rules[3] = {PLAN_CORNER_JD, PLAN_CORNER_VSTEP, PLAN_CORNER_SMOOTH}, i;
    for (i = 0; i < 3; i++) {
        plan_profile_t s = base_profile(SC_SHAPE_SCURVE, (uint8_t)rules[i]);
        /* X reverses while Y keeps going: a stop on the reversing axis */
        plan_move_t m[2] = {mv(10 * MM, 10 * MM, 0, 100), mv(9 * MM, 20 * MM, 0, 100)};
        plan_est_t o[2];
        run(&s, m, 2, o);
        TEST_ASSERT_EQUAL_INT64(0, o[0].v_exit);
        TEST_ASSERT_EQUAL_INT64(0, o[1].v_entry);
    }
}

static void test_exact_stop_vs_continuous(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_move_t m[3] = {mv(10 * MM, 0, 0, 100), mv(20 * MM, 1 * MM, 0, 100),
                        mv(30 * MM, 1 * MM, 0, 100)};
    plan_est_t o[3];
    int64_t cont = run(&s, m, 3, o), stop;
    TEST_ASSERT_TRUE(o[0].v_exit > 0);
    m[0].flags = PLAN_MOVE_EXACT_STOP;
    m[1].flags = PLAN_MOVE_EXACT_STOP;
    stop = run(&s, m, 3, o);
    TEST_ASSERT_EQUAL_INT64(0, o[0].v_exit);
    TEST_ASSERT_EQUAL_INT64(0, o[1].v_exit);
    TEST_ASSERT_EQUAL_INT64(0, o[2].v_entry);
    TEST_ASSERT_TRUE(stop > cont + 50000000); /* each stop costs > 25 ms here */
}

static plan_move_t moves[4096];
static plan_est_t outs[4096];

/* ---- smoothed corner: block speed capped by its corner speeds --------------------- */

static plan_profile_t smooth_profile(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_TRAPEZOID, PLAN_CORNER_SMOOTH);
    s.corner_acc[0] = 186 * MMS;
    s.corner_acc[1] = 57 * MMS;
    s.corner_acc[2] = 186 * MMS;
    return s;
}

/* A staircase of 0.3 mm X and Y blocks (90 degree corners, no reversal):
 * both corners of every inner block have v_c = min_i sqrt(a_c,i l / |du_i|)
 * = sqrt(57 mm/s^2 * 0.3 mm), so the block runs at v_c end to end, t = l /
 * v_c (without the cap it accelerates in its middle at 2 m/s^2). */
static void test_smooth_cap_staircase(void)
{
    plan_profile_t s = smooth_profile();
    double vc = sqrt(57e6 * 300000.0), t = 300000.0 / vc * 1e9;
    int i;
    for (i = 0; i < 200; i++) {
        int64_t x = ((i + 2) / 2) * 300000, y = ((i + 1) / 2) * 300000;
        moves[i] = mv(x, y, 0, 250);
    }
    run(&s, moves, 200, outs);
    for (i = 1; i < 199; i++) {
        TEST_ASSERT_TRUE(fabs((double)outs[i].v_max - vc) <= 2);
        TEST_ASSERT_TRUE(fabs((double)outs[i].v_peak - vc) <= 2);
        TEST_ASSERT_TRUE(fabs((double)outs[i].t_total_ns - t) <= 1e-6 * t);
        TEST_ASSERT_TRUE(outs[i].flags & PLAN_BF_CORNER);
        TEST_ASSERT_EQUAL_INT64(0, outs[i].t_acc_ns);
    }
    /* the first block (start of the job) and the last (no next block) have
     * one corner that adds no cap: they keep the feed */
    TEST_ASSERT_EQUAL_INT64(250 * MMS, outs[0].v_max);
    TEST_ASSERT_EQUAL_INT64(250 * MMS, outs[199].v_max);
    TEST_ASSERT_FALSE(outs[0].flags & PLAN_BF_CORNER);
    TEST_ASSERT_TRUE((double)outs[0].v_peak > 2 * vc);
}

/* The cap is the LARGER of the two corner speeds: a block after a 90 degree
 * corner from a long block (l = (5 + 0.3) / 2 mm) followed by a 10 degree
 * corner (l = 0.3 mm) runs at the first corner's speed in its middle. */
static void test_smooth_cap_is_larger_corner(void)
{
    plan_profile_t s = smooth_profile();
    double a = 10.0 * M_PI / 180.0;
    int64_t dx = (int64_t)llround(300000 * sin(a)), dy = (int64_t)llround(300000 * cos(a));
    plan_move_t m[4] = {mv(5 * MM, 0, 0, 250), mv(5 * MM, 300000, 0, 250),
                        mv(5 * MM + dx, 300000 + dy, 0, 250),
                        mv(5 * MM + dx, 300000 + dy + 5 * MM, 0, 250)};
    plan_est_t o[4];
    double ux = dx / hypot((double)dx, (double)dy), uy = dy / hypot((double)dx, (double)dy);
    double vin = sqrt(57e6 * 2650000.0); /* Y turned fully: |du_y| = 1 (a_c,Y) */
    double vout = fmin(sqrt(186e6 * 300000.0 / ux), sqrt(57e6 * 300000.0 / (1 - uy)));
    TEST_ASSERT_TRUE(vin > vout * 1.05 || vout > vin * 1.05);
    run(&s, m, 4, o);
    TEST_ASSERT_TRUE(fabs((double)o[1].v_max - fmax(vin, vout)) <= 1e-5 * fmax(vin, vout) + 2);
    TEST_ASSERT_TRUE(o[1].flags & PLAN_BF_CORNER);
    /* (the min of the two would be vin: at least 5 % lower) */
    TEST_ASSERT_TRUE((double)o[1].v_max > 1.05 * fmin(vin, vout));
}

/* Junctions that add no cap, and the cap arriving with the next block. */
static void test_smooth_cap_rules(void)
{
    plan_profile_t s = smooth_profile();
    plan_move_t a = mv(10 * MM, 0, 0, 250), b = mv(10 * MM, 300000, 0, 250),
                c = mv(10 * MM + 300000, 300000, 0, 250);
    plan_seg_t seg;
    const plan_block_t *q;
    double vc = sqrt(57e6 * 300000.0);

    /* the cap of a queued block falls when the next block is pushed */
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 8, &s, origin));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &a));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &b));
    q = plan_peek(&pl, 1);
    TEST_ASSERT_EQUAL_INT64(250 * MMS, q->lim.v_max); /* no next block yet */
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &c));
    TEST_ASSERT_TRUE(fabs((double)q->lim.v_max - sqrt(57e6 * 5150000.0)) <= 3);
    TEST_ASSERT_TRUE(q->flags & PLAN_BF_CORNER);
    TEST_ASSERT_TRUE(plan_peek(&pl, 1)->v_entry <= q->lim.v_max);

    /* popped before its next block is known: its plan is final, uncapped */
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 8, &s, origin));
    plan_push(&pl, &a);
    plan_push(&pl, &b);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
    TEST_ASSERT_TRUE((double)seg.prof.vp > 2 * vc);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &c)); /* nothing to cap */
    TEST_ASSERT_EQUAL_INT64(250 * MMS, plan_peek(&pl, 0)->lim.v_max);

    /* collinear entry (0.3 mm X after X), exact stop, reversal: no cap */
    {
        plan_move_t m[4] = {mv(10 * MM, 0, 0, 250), mv(10 * MM + 300000, 0, 0, 250),
                            mv(10 * MM + 300000, 300000, 0, 250),
                            mv(10 * MM + 600000, 300000, 0, 250)};
        plan_est_t o[4];
        run(&s, m, 4, o);
        TEST_ASSERT_EQUAL_INT64(250 * MMS, o[1].v_max); /* collinear in, corner out */
        TEST_ASSERT_TRUE(o[2].flags & PLAN_BF_CORNER);  /* corner in and out */
        m[2].flags = PLAN_MOVE_EXACT_STOP;
        run(&s, m, 4, o);
        TEST_ASSERT_EQUAL_INT64(250 * MMS, o[2].v_max); /* corner in, stop out */
        m[2].flags = 0;
        m[3] = mv(10 * MM + 300000, 0, 0, 250); /* Y reverses */
        run(&s, m, 4, o);
        TEST_ASSERT_EQUAL_INT64(250 * MMS, o[2].v_max); /* corner in, reversal out */
        TEST_ASSERT_EQUAL_INT64(0, o[2].v_exit);
    }
    /* other rules never cap */
    {
        plan_profile_t j = base_profile(SC_SHAPE_TRAPEZOID, PLAN_CORNER_JD);
        int i;
        for (i = 0; i < 40; i++) {
            moves[i] = mv(((i + 2) / 2) * 300000, ((i + 1) / 2) * 300000, 0, 250);
        }
        run(&j, moves, 40, outs);
        for (i = 0; i < 40; i++) {
            TEST_ASSERT_EQUAL_INT64(250 * MMS, outs[i].v_max);
        }
    }
}

/* ---- minimum block time ----------------------------------------------------------- */

/* Trapezoidal mode: in S-curve mode the acceleration is zero at every block
 * boundary, so 0.01 mm blocks cannot reach 22 mm/s within a 64-block
 * look-ahead (see test_scurve_micro_blocks_are_slow below). */
static void test_tiny_blocks_at_min_block_time(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_TRAPEZOID, PLAN_CORNER_JD);
    int i;
    s.min_block_ns = 450000; /* 0.45 ms */
    s.mbt_window = 8;
    /* 2000 collinear 0.01 mm blocks at F15000 (0.04 ms each kinematically) */
    for (i = 0; i < 2000; i++) {
        moves[i] = mv((i + 1) * 10000, 0, 0, 250);
    }
    run(&s, moves, 2000, outs);
    /* steady state: every block exactly the minimum time */
    for (i = 100; i < 1900; i++) {
        TEST_ASSERT_INT64_WITHIN(2, 450000, outs[i].t_total_ns);
        TEST_ASSERT_TRUE(outs[i].flags & PLAN_BF_MBT);
        TEST_ASSERT_EQUAL_INT64(outs[i].t_total_ns, outs[i].t_mbt_ns);
    }
    /* any run of n >= 8 consecutive blocks takes at least n * 0.45 ms */
    {
        int64_t run8 = 0;
        for (i = 0; i < 2000; i++) {
            run8 += outs[i].t_total_ns - (i >= 8 ? outs[i - 8].t_total_ns : 0);
            if (i >= 7) {
                TEST_ASSERT_TRUE(run8 >= 8 * 450000 - 16);
            }
        }
    }
}

/* Documented limitation of the per-block S-curve (acceleration zero at each
 * block end): the same micro-blocks settle far below the throughput speed. */
static void test_scurve_micro_blocks_are_slow(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    int i;
    s.min_block_ns = 450000;
    s.mbt_window = 8;
    for (i = 0; i < 1000; i++) {
        moves[i] = mv((i + 1) * 10000, 0, 0, 250);
    }
    run(&s, moves, 1000, outs);
    TEST_ASSERT_TRUE(outs[500].v_peak < 22222222 / 2);
    TEST_ASSERT_TRUE(outs[500].t_total_ns > 2 * 450000);
}

static void test_short_block_between_long_ones_not_slowed(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_est_t o[3];
    plan_move_t m[3] = {mv(10 * MM, 0, 0, 100), mv(10 * MM + 20000, 0, 0, 100),
                        mv(20 * MM, 0, 0, 100)};
    s.min_block_ns = 450000;
    s.mbt_window = 8; /* throughput */
    run(&s, m, 3, o);
    TEST_ASSERT_EQUAL_INT64(100 * MMS, o[1].v_peak); /* 0.02 mm in 0.2 ms */
    TEST_ASSERT_INT64_WITHIN(2, 200000, o[1].t_total_ns);
    TEST_ASSERT_FALSE(o[1].flags & PLAN_BF_MBT);
    s.mbt_window = 1; /* per-block cap: the short block takes 0.45 ms */
    run(&s, m, 3, o);
    TEST_ASSERT_TRUE(o[1].flags & PLAN_BF_MBT);
    TEST_ASSERT_TRUE(o[1].t_total_ns >= 450000 - 2);
}

/* ---- look-ahead: incremental passes == from-scratch plan ------------------------- */

static uint64_t rs = 0x2545F4914F6CDD1Dull;
static uint64_t rnd(void)
{
    rs ^= rs << 13;
    rs ^= rs >> 7;
    rs ^= rs << 17;
    return rs;
}

static void check_against_scratch(const plan_t *p)
{
    int64_t ent[256];
    int n = plan_count(p), i;
    /* reverse from rest at the end, forward from the fixed oldest entry */
    int64_t exit = 0;
    for (i = n - 1; i >= 1; i--) {
        const plan_block_t *b = plan_peek(p, (uint16_t)i);
        int64_t e = sc_reach(exit, b->len, &b->lim);
        ent[i] = e < b->v_junction ? e : b->v_junction;
        exit = ent[i];
    }
    ent[0] = plan_peek(p, 0)->v_entry;
    for (i = 0; i + 1 < n; i++) {
        const plan_block_t *b = plan_peek(p, (uint16_t)i);
        if (ent[i] < ent[i + 1]) {
            int64_t r = sc_reach(ent[i], b->len, &b->lim);
            if (r < ent[i + 1]) {
                ent[i + 1] = r;
            }
        }
    }
    for (i = 0; i < n; i++) {
        TEST_ASSERT_EQUAL_INT64(ent[i], plan_peek(p, (uint16_t)i)->v_entry);
    }
}

static void test_incremental_equals_scratch(void)
{
    int corner;
    for (corner = 0; corner < 3; corner++) {
        plan_profile_t s = base_profile((uint8_t)(corner == 1), (uint8_t)corner);
        plan_seg_t seg;
        pos_nm_t pos[3] = {0, 0, 0};
        int k, pushed = 0;
        int64_t last_exit = 0;
        s.min_block_ns = corner == 2 ? 450000 : 0;
        s.mbt_window = 4;
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 64, &s, origin));
        for (k = 0; k < 3000; k++) {
            plan_move_t m;
            int ax;
            /* mostly small steps in a wandering direction, sometimes long */
            int64_t scale = (rnd() % 10 == 0) ? 20 * MM : (int64_t)(rnd() % 500000) + 1000;
            for (ax = 0; ax < 3; ax++) {
                pos[ax] += (int64_t)(rnd() % 2001) * scale / 1000 - scale;
            }
            m = mv(pos[0], pos[1], pos[2], 20 + (int64_t)(rnd() % 300));
            m.flags = (rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
            if (plan_free_slots(&pl) == 0) {
                TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
                TEST_ASSERT_EQUAL_INT64(last_exit, seg.prof.v0);
                last_exit = seg.prof.v1;
                TEST_ASSERT_TRUE(seg.prof.vp <= seg.prof.len * 0 + 500 * MMS * 2);
            }
            if (plan_push(&pl, &m) == PLAN_OK) {
                pushed++;
            }
            check_against_scratch(&pl);
        }
        TEST_ASSERT_TRUE(pushed > 2900);
    }
}

/* The same with the trapezoid (monotone reach) for every rule, long runs,
 * immediate and deferred passes; deferred: compared every 7th push only
 * (after plan_update), so passes run over batches of new blocks and pops
 * happen on stale queues in between. */
static void test_incremental_equals_scratch_trapezoid(void)
{
    int corner, deferred;
    for (deferred = 0; deferred < 2; deferred++) {
        for (corner = 0; corner < 4; corner++) {
            plan_profile_t s = base_profile(SC_SHAPE_TRAPEZOID, (uint8_t)corner);
            plan_seg_t seg;
            pos_nm_t pos[3] = {0, 0, 0};
            int k;
            s.min_block_ns = (corner & 1) ? 450000 : 0;
            s.mbt_window = 16;
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 64, &s, origin));
            plan_set_deferred(&pl, deferred != 0);
            for (k = 0; k < 8000; k++) {
                plan_move_t m;
                int ax;
                int64_t scale = (rnd() % 10 == 0) ? 20 * MM : (int64_t)(rnd() % 500000) + 1000;
                for (ax = 0; ax < 3; ax++) {
                    pos[ax] += (int64_t)(rnd() % 2001) * scale / 1000 - scale;
                }
                m = mv(pos[0], pos[1], pos[2], 20 + (int64_t)(rnd() % 300));
                m.flags = (rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
                if (plan_free_slots(&pl) == 0) {
                    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
                }
                (void)plan_push(&pl, &m);
                if (!deferred || k % 7 == 0) {
                    plan_update(&pl);
                    check_against_scratch(&pl);
                }
            }
        }
    }
}

/* Deferred passes (what plan_estimate uses) freeze exactly the segments of
 * the immediate passes (what the drive uses), on long random trapezoid paths
 * with every rule and depths 64 and 256; an S-curve profile ignores the
 * option (its reach is not monotone: planner.h). */
static void test_deferred_pops_equal_immediate(void)
{
    static plan_block_t sa[256], sb[256];
    int corner, depth;
    for (depth = 64; depth <= 256; depth *= 4) {
        for (corner = 0; corner < 4; corner++) {
            plan_profile_t s = base_profile(SC_SHAPE_TRAPEZOID, (uint8_t)corner);
            plan_t a, b;
            plan_seg_t ga, gb;
            pos_nm_t pos[3] = {0, 0, 0};
            int k, pops = 0;
            s.min_block_ns = (corner & 1) ? 0 : 450000;
            s.mbt_window = 16;
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&a, sa, (uint16_t)depth, &s, origin));
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&b, sb, (uint16_t)depth, &s, origin));
            plan_set_deferred(&b, true);
            for (k = 0; k < 12000 + depth; k++) {
                plan_move_t m;
                int ax;
                int64_t scale = (rnd() % 10 == 0) ? 20 * MM : (int64_t)(rnd() % 500000) + 1000;
                if (k % 3000 < 1500) {
                    scale = 100000; /* runs of collinear 0.1 mm blocks */
                    pos[0] += scale;
                } else {
                    for (ax = 0; ax < 3; ax++) {
                        pos[ax] += (int64_t)(rnd() % 2001) * scale / 1000 - scale;
                    }
                }
                m = mv(pos[0], pos[1], pos[2], 20 + (int64_t)(rnd() % 300));
                m.flags = (rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
                if (k >= 12000 || plan_free_slots(&a) == 0) {
                    TEST_ASSERT_EQUAL_INT(plan_pop(&a, &ga), plan_pop(&b, &gb));
                    TEST_ASSERT_EQUAL_INT64(ga.prof.v0, gb.prof.v0);
                    TEST_ASSERT_EQUAL_INT64(ga.prof.vp, gb.prof.vp);
                    TEST_ASSERT_EQUAL_INT64(ga.prof.v1, gb.prof.v1);
                    TEST_ASSERT_EQUAL_INT64(ga.total_ns, gb.total_ns);
                    pops++;
                }
                if (k < 12000) {
                    TEST_ASSERT_EQUAL_INT(plan_push(&a, &m), plan_push(&b, &m));
                }
            }
            TEST_ASSERT_TRUE(pops > 11000);
        }
    }
    /* S-curve: the option is ignored, every push re-plans at once */
    {
        plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
        plan_move_t m1 = mv(10 * MM, 0, 0, 100), m2 = mv(20 * MM, 0, 0, 100);
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 8, &s, origin));
        plan_set_deferred(&pl, true);
        plan_push(&pl, &m1);
        plan_push(&pl, &m2);
        TEST_ASSERT_EQUAL_INT64(100 * MMS, plan_peek(&pl, 1)->v_entry);
        s.shape = SC_SHAPE_TRAPEZOID; /* trapezoid: entries wait for the passes */
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 8, &s, origin));
        plan_set_deferred(&pl, true);
        plan_push(&pl, &m1);
        plan_push(&pl, &m2);
        TEST_ASSERT_EQUAL_INT64(0, plan_peek(&pl, 1)->v_entry);
        plan_update(&pl);
        TEST_ASSERT_EQUAL_INT64(100 * MMS, plan_peek(&pl, 1)->v_entry);
    }
}

/* ---- at-rest S-curve -------------------------------------------------------------- */

/* time of one block planned with an explicit shape (X-axis limits of
 * base_profile) */
static int64_t block_ns(uint8_t shape, int64_t len, int64_t v0, int64_t v1, int64_t vmax)
{
    sc_limits_t l = {vmax, 2000 * MMS, 50000 * MMS, shape};
    sc_profile_t pr;
    sc_plan(&pr, len, v0, v1, &l);
    return pr.total_ns;
}

/* Rest to rest the at-rest shape is the S-curve (1.09 s, not the
 * trapezoid's 1.05 s); so is every block of a reversal chain (each starts
 * and ends at rest) and the first and last blocks of a collinear chain of
 * micro-blocks, while the blocks between run as trapezoids: they settle at
 * the throughput speed like the trapezoid (the plain S-curve crawls, see
 * test_scurve_micro_blocks_are_slow). */
static void test_scurve_at_rest_single_and_reversal(void)
{
    plan_profile_t a = base_profile(SC_SHAPE_SCURVE_AT_REST, PLAN_CORNER_JD);
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_move_t m = mv(100 * MM, 0, 0, 100);
    int64_t ts = run(&s, &m, 1, outs), i;

    TEST_ASSERT_EQUAL_INT64(ts, run(&a, &m, 1, outs));
    TEST_ASSERT_INT64_WITHIN(5, 1090000000, ts);
    /* reversal chain: +1 mm / -1 mm, each block an S-curve from and to rest */
    for (i = 0; i < 20; i++) {
        moves[i] = mv((i % 2 == 0) ? MM : 0, 0, 0, 100);
    }
    run(&a, moves, 20, outs);
    ts = block_ns(SC_SHAPE_SCURVE, MM, 0, 0, 100 * MMS);
    TEST_ASSERT_TRUE(ts > block_ns(SC_SHAPE_TRAPEZOID, MM, 0, 0, 100 * MMS) + 1000000);
    for (i = 0; i < 20; i++) {
        TEST_ASSERT_EQUAL_INT64(0, outs[i].v_entry);
        TEST_ASSERT_EQUAL_INT64(0, outs[i].v_exit);
        TEST_ASSERT_EQUAL_INT64(ts, outs[i].t_total_ns);
    }
}

/* Continuous S-curve on the tuned machine (10 m/s^2, 1000 m/s^3): a circle
 * of 0.05 mm chords at F10000 through a 64-block ring, popped as the
 * drive pops (push until full, then pop). Blocks run at the programmed
 * feed (0.3 ms per chord) once up to speed; the path's speed and
 * acceleration at the end of each block are those at the start of the
 * next (joined at non-zero acceleration while the speed changes); the
 * speed never goes negative and the last block ends at rest. The
 * per-block S-curve (shape 0) takes far longer on the same job. */
static void cont_circle(uint8_t shape, uint32_t n, int64_t *total, int64_t *mid_ns,
                        uint32_t *joins_acc, int64_t *max_dv, int64_t *max_da)
{
    static plan_block_t ring[PLAN_DEPTH_DEFAULT];
    static plan_seg_t seg;
    plan_profile_t a = base_profile(shape, PLAN_CORNER_JD);
    const pos_nm_t o[CORE_AXES] = {20000000, 0, 0};
    sc_state_t end = {0, 0, 0};
    plan_t p;
    uint32_t next = 0, popped = 0;
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        a.a_max[i] = 10000 * MMS;
        a.j_max[i] = 1000000 * MMS;
    }
    *total = 0;
    *joins_acc = 0;
    *max_dv = 0;
    *max_da = 0;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&p, ring, PLAN_DEPTH_DEFAULT, &a, o));
    while (popped < n) {
        while (next < n && plan_free_slots(&p) > 0) {
            double ang = 2.0 * M_PI * (double)(next + 1) * 0.05 / (2.0 * M_PI * 20.0);
            plan_move_t m;
            memset(&m, 0, sizeof(m));
            m.target[0] = (int64_t)llround(20000000.0 * cos(ang));
            m.target[1] = (int64_t)llround(20000000.0 * sin(ang));
            m.feed = 10000 * MMS / 60;
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&p, &m));
            next++;
        }
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&p, &seg));
        {
            sc_state_t st0, st1;
            sc_eval(&seg.prof, 0, &st0);
            sc_eval(&seg.prof, seg.total_ns, &st1);
            if (popped > 0) {
                int64_t dv = st0.v_q16 - end.v_q16, da = (st0.a_q16 - end.a_q16) / 65536;
                *max_dv = fx_max64(*max_dv, dv < 0 ? -dv : dv);
                *max_da = fx_max64(*max_da, da < 0 ? -da : da);
                if ((st0.a_q16 < 0 ? -st0.a_q16 : st0.a_q16) / 65536 >= 1000 * MMS) {
                    (*joins_acc)++;
                }
            }
            TEST_ASSERT_TRUE(st0.v_q16 >= 0 && st1.v_q16 >= -65536);
            for (i = 0; i < SC_PHASES; i++) {
                TEST_ASSERT_TRUE(seg.prof.start[i].v_q16 >= -65536);
            }
            end = st1;
        }
        *total += seg.total_ns;
        if (popped == n / 2) {
            *mid_ns = seg.total_ns;
        }
        popped++;
    }
    TEST_ASSERT_EQUAL_INT64(0, seg.prof.v1);
}

static void test_scurve_continuous_cam_circle(void)
{
    int64_t total, mid = 0, dv, da, total0, mid0 = 0;
    uint32_t joins;
    double ideal = 2000 * 0.05 / (10000.0 / 60.0); /* s */

    cont_circle(SC_SHAPE_SCURVE_CONTINUOUS, 2000, &total, &mid, &joins, &dv, &da);
    printf("continuous: %.4f s (ideal %.4f s), mid block %lld ns, %u joins accelerating, "
           "max step v %lld q16, a %lld nm/s^2\n",
           (double)total * 1e-9, ideal, (long long)mid, joins, (long long)dv, (long long)da);
    TEST_ASSERT_INT64_WITHIN(300, 300000, mid);            /* at feed: 0.3 ms +- 0.1 % */
    TEST_ASSERT_TRUE((double)total * 1e-9 < ideal + 0.04); /* start and stop: ~33 ms */
    TEST_ASSERT_TRUE(joins > 20);                          /* joined while accelerating */
    TEST_ASSERT_TRUE(dv < 16 * 65536);                     /* speed continuous (rounding) */
    TEST_ASSERT_TRUE(da < 4000);                           /* acceleration continuous */
    cont_circle(SC_SHAPE_SCURVE, 2000, &total0, &mid0, &joins, &dv, &da);
    TEST_ASSERT_TRUE(total0 > 3 * total);
    TEST_ASSERT_EQUAL_UINT32(0, joins); /* a = 0 at every block end */
}

static void test_scurve_continuous_profile_rules(void)
{
    plan_profile_t a = base_profile(SC_SHAPE_SCURVE_CONTINUOUS, PLAN_CORNER_JD);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&a));
    a.corner = PLAN_CORNER_SMOOTH; /* the corner cap would cut a run under way */
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&a));
    a.corner = PLAN_CORNER_STOP;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&a));
    a.j_max[2] = 100 * MMS; /* a/j = 20 s > 3 s: jerk used */
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&a));
}

static void test_scurve_at_rest_micro_blocks(void)
{
    plan_profile_t a = base_profile(SC_SHAPE_SCURVE_AT_REST, PLAN_CORNER_JD);
    int i;
    a.min_block_ns = 450000;
    a.mbt_window = 8;
    for (i = 0; i < 1000; i++) {
        moves[i] = mv((i + 1) * 10000, 0, 0, 250);
    }
    run(&a, moves, 1000, outs);
    for (i = 100; i < 900; i++) { /* throughput speed, as the trapezoid */
        TEST_ASSERT_INT64_WITHIN(2, 450000, outs[i].t_total_ns);
    }
    /* the first block (from rest) and the last (to rest) are S-curves */
    TEST_ASSERT_EQUAL_INT64(0, outs[0].v_entry);
    TEST_ASSERT_EQUAL_INT64(
        block_ns(SC_SHAPE_SCURVE, outs[0].len_nm, 0, outs[0].v_exit, outs[0].v_max),
        outs[0].t_total_ns);
    TEST_ASSERT_TRUE(outs[0].t_total_ns > block_ns(SC_SHAPE_TRAPEZOID, outs[0].len_nm, 0,
                                                   outs[0].v_exit, outs[0].v_max));
    TEST_ASSERT_EQUAL_INT64(0, outs[999].v_exit);
    TEST_ASSERT_EQUAL_INT64(
        block_ns(SC_SHAPE_SCURVE, outs[999].len_nm, outs[999].v_entry, 0, outs[999].v_max),
        outs[999].t_total_ns);
}

/* Random paths (junction deviation and smoothed corner, exact stops,
 * reversals): every block's estimated time is the S-curve profile when its
 * final entry or exit is 0 and the trapezoid otherwise, both kinds occur,
 * and the S-curve reach from rest keeps every S-curve block feasible (its
 * distance fits the block). */
static void test_scurve_at_rest_block_shapes(void)
{
    int corner;
    for (corner = 0; corner < 3; corner += 2) {
        plan_profile_t a = base_profile(SC_SHAPE_SCURVE_AT_REST, (uint8_t)corner);
        pos_nm_t pos[3] = {0, 0, 0};
        int n = 4000, k, nrest = 0, nmid = 0;
        for (k = 0; k < n; k++) {
            int ax;
            int64_t scale = (rnd() % 10 == 0) ? 20 * MM : (int64_t)(rnd() % 500000) + 1000;
            if (k % 1000 < 400) { /* gentle staircase: corners, no reversals */
                pos[k % 2] += 100000 + (int64_t)(rnd() % 200000);
            } else {
                for (ax = 0; ax < 3; ax++) {
                    pos[ax] += (int64_t)(rnd() % 2001) * scale / 1000 - scale;
                }
            }
            moves[k] = mv(pos[0], pos[1], pos[2], 20 + (int64_t)(rnd() % 300));
            moves[k].flags = (rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
        }
        run(&a, moves, (uint32_t)n, outs);
        for (k = 0; k < n; k++) {
            plan_block_t b; /* the block's limits, recomputed by the planner */
            plan_t one;
            plan_seg_t seg;
            plan_move_t m = moves[k];
            const pos_nm_t *st = (k == 0) ? origin : moves[k - 1].target;
            sc_limits_t l;
            sc_profile_t pr;
            bool rest = outs[k].v_entry == 0 || outs[k].v_exit == 0;
            if (outs[k].flags & PLAN_EST_SKIPPED) {
                continue;
            }
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&one, &b, 1, &a, st));
            m.flags = 0;
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&one, &m));
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&one, &seg));
            l = b.lim;
            l.v_max = outs[k].v_max;
            l.shape = rest ? SC_SHAPE_SCURVE : SC_SHAPE_TRAPEZOID;
            sc_plan(&pr, outs[k].len_nm, outs[k].v_entry, outs[k].v_exit, &l);
            TEST_ASSERT_EQUAL_INT64(pr.total_ns, outs[k].t_total_ns);
            TEST_ASSERT_TRUE(sc_dist(outs[k].v_entry, outs[k].v_exit, &l) <= outs[k].len_nm);
            if (rest) {
                nrest++;
            } else {
                nmid++;
            }
        }
        TEST_ASSERT_TRUE(nrest > 50);
        TEST_ASSERT_TRUE(nmid > 1000);
    }
}

/* The at-rest reach is monotone in the start speed, so the incremental
 * passes give the from-scratch plan and deferred passes (which it allows)
 * freeze the segments of the immediate passes. */
static void test_scurve_at_rest_incremental_and_deferred(void)
{
    static plan_block_t sa[64], sb[64];
    int corner;
    for (corner = 0; corner < 3; corner += 2) {
        plan_profile_t s = base_profile(SC_SHAPE_SCURVE_AT_REST, (uint8_t)corner);
        plan_t a, b;
        plan_seg_t ga, gb;
        pos_nm_t pos[3] = {0, 0, 0};
        int k, pops = 0;
        s.min_block_ns = 450000;
        s.mbt_window = 16;
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&a, sa, 64, &s, origin));
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&b, sb, 64, &s, origin));
        plan_set_deferred(&b, true);
        for (k = 0; k < 6000; k++) {
            plan_move_t m;
            int ax;
            int64_t scale = (rnd() % 10 == 0) ? 20 * MM : (int64_t)(rnd() % 500000) + 1000;
            if (k % 2000 < 700) {
                pos[0] += 100000; /* runs of collinear 0.1 mm blocks */
            } else {
                for (ax = 0; ax < 3; ax++) {
                    pos[ax] += (int64_t)(rnd() % 2001) * scale / 1000 - scale;
                }
            }
            m = mv(pos[0], pos[1], pos[2], 20 + (int64_t)(rnd() % 300));
            m.flags = (rnd() % 50 == 0) ? PLAN_MOVE_EXACT_STOP : 0;
            if (plan_free_slots(&a) == 0) {
                TEST_ASSERT_EQUAL_INT(plan_pop(&a, &ga), plan_pop(&b, &gb));
                TEST_ASSERT_EQUAL_INT64(ga.prof.v0, gb.prof.v0);
                TEST_ASSERT_EQUAL_INT64(ga.prof.vp, gb.prof.vp);
                TEST_ASSERT_EQUAL_INT64(ga.prof.v1, gb.prof.v1);
                TEST_ASSERT_EQUAL_INT64(ga.total_ns, gb.total_ns);
                pops++;
            }
            TEST_ASSERT_EQUAL_INT(plan_push(&a, &m), plan_push(&b, &m));
            check_against_scratch(&a);
        }
        TEST_ASSERT_TRUE(pops > 5000);
    }
}

/* ---- queue accounting and errors -------------------------------------------------- */

static void test_queue_time_slots_and_errors(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_profile_t bad;
    plan_move_t m;
    plan_seg_t seg;
    int64_t q, sum = 0;
    int i;

    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 4, &s, origin));
    TEST_ASSERT_EQUAL_UINT16(4, plan_free_slots(&pl));
    for (i = 0; i < 4; i++) {
        m = mv((i + 1) * 10 * MM, (i % 2) * MM, 0, 100);
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &m));
    }
    TEST_ASSERT_EQUAL_UINT16(0, plan_free_slots(&pl));
    m.target[2] = MM;
    TEST_ASSERT_EQUAL_INT(PLAN_E_FULL, plan_push(&pl, &m));
    m.target[2] = 0;
    q = plan_queued_ns(&pl);
    while (plan_pop(&pl, &seg) == PLAN_OK) {
        sum += seg.total_ns;
    }
    TEST_ASSERT_EQUAL_INT64(sum, q); /* queued time == executed plan (nothing changed) */
    TEST_ASSERT_EQUAL_INT(PLAN_E_EMPTY, plan_pop(&pl, &seg));
    /* zero-length move: skipped, nothing queued */
    TEST_ASSERT_EQUAL_INT(PLAN_SKIPPED, plan_push(&pl, &m));
    TEST_ASSERT_EQUAL_UINT16(0, plan_count(&pl));
    /* bad feed, range, dwell */
    m = mv(0, 0, 0, 100);
    m.feed = 0;
    TEST_ASSERT_EQUAL_INT(PLAN_E_FEED, plan_push(&pl, &m));
    m = mv((int64_t)1 << 50, 0, 0, 100);
    TEST_ASSERT_EQUAL_INT(PLAN_E_RANGE, plan_push(&pl, &m));
    m.dwell_ns = -1;
    TEST_ASSERT_EQUAL_INT(PLAN_E_ARG, plan_push(&pl, &m));
    TEST_ASSERT_EQUAL_UINT16(0, plan_count(&pl));
    /* dwell: a stop and its time */
    m = mv(0, 0, 0, 0);
    m.dwell_ns = 250000000;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &m));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
    TEST_ASSERT_EQUAL_INT64(250000000, seg.total_ns);
    /* profiles */
    bad = s;
    bad.a_max[1] = 0;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&bad));
    bad = s;
    bad.j_max[0] = 100 * MMS; /* a/j = 20 s > 3 s */
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&bad));
    bad.shape = SC_SHAPE_SCURVE_AT_REST; /* jerk used at rest: refused too */
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&bad));
    bad.shape = SC_SHAPE_TRAPEZOID; /* jerk unused: fine */
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&bad));
    bad = s;
    bad.shape = SC_SHAPE_SCURVE_AT_REST;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&bad));
    bad.shape = SC_SHAPE_SCURVE_CONTINUOUS + 1;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&bad));
    bad = s;
    bad.mbt_window = 0;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&bad));
    bad = s;
    bad.corner = 9;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_init(&pl, store, 4, &bad, origin));
    TEST_ASSERT_EQUAL_INT(PLAN_E_ARG, plan_init(&pl, store, 0, &s, origin));
}

/* the axis limits are projected: a diagonal block is limited by each axis */
/* Chords of one arc (PLAN_MOVE_ARC_JOIN): the joins and the blocks run at
 * the arc's centripetal limit, not at the corner rule's speed. 64 chords of
 * an R 10 mm circle at 500 mm/s, equal axis limits: block k (its entry
 * join at the angle th = 2 pi k / 64, normal n, chord direction u) gets
 * v_max = min(sqrt(a R / max_i |n_i|), cbrt(j R^2 / max_i |u_i|)), a_max
 * 2000 mm/s^2 (141-168 mm/s), then j_max 2000 mm/s^3 (58.5-62.6 mm/s);
 * its entry is at most that (and above 80 % of it with a_max alone: the
 * per-block S-curve between changing limits; with j_max 2000 the look-ahead
 * of 64 blocks, (3/4 64 j l^2)^(1/3) = 45 mm/s, is the lower limit). Without
 * the flag the junction-deviation rule (0.01 mm) gives 47 mm/s. */
static void test_arc_chord_joins_use_the_arc_limit(void)
{
    static plan_move_t m[200];
    static plan_est_t out[200];
    const int64_t r = 10000000;
    const double pi = 3.14159265358979, rmm = 10.0;
    plan_profile_t prof = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    int pass, k;

    for (pass = 0; pass < 3; pass++) {
        double j = 50000.0;
        if (pass == 1) {
            j = 2000.0;
            for (k = 0; k < CORE_AXES; k++) {
                prof.j_max[k] = 2000 * MMS;
            }
        }
        for (k = 0; k < 192; k++) {
            double th = 2.0 * pi * (k + 1) / 64.0;
            m[k] = mv((int64_t)llround(r * cos(th)) - r, (int64_t)llround(r * sin(th)), 0, 500);
            m[k].flags = (k > 0 && pass < 2) ? PLAN_MOVE_ARC_JOIN : 0;
        }
        run(&prof, m, 192, out);
        for (k = 64; k < 128; k++) {
            /* every join and block of the middle revolution */
            double th = 2.0 * pi * k / 64.0, tu = th + pi / 64.0 + pi / 2.0;
            double nmax = fmax(fabs(cos(th)), fabs(sin(th)));
            double umax = fmax(fabs(cos(tu)), fabs(sin(tu)));
            double va = sqrt(2000.0 * rmm / nmax), vj = cbrt(j * rmm * rmm / umax);
            double vmax = (double)out[k].v_max / MMS, ve = (double)out[k].v_entry / MMS;
            if (pass < 2) {
                TEST_ASSERT_DOUBLE_WITHIN(fmin(va, vj) * 2e-3, fmin(va, vj), vmax);
                TEST_ASSERT_TRUE(ve <= vmax && (pass == 1 || ve > 0.8 * vmax));
            } else {
                TEST_ASSERT_TRUE(ve < 50.0);
            }
        }
    }
}

static void test_axis_limits_projected(void)
{
    plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
    plan_est_t o[1];
    plan_move_t m = mv(300 * MM, 400 * MM, 0, 2000);
    s.v_max[1] = 100 * MMS; /* Y: 100 mm/s, u_y = 0.8: path 125 mm/s */
    run(&s, &m, 1, o);
    TEST_ASSERT_INT64_WITHIN(1, 125 * MMS, o[0].v_max);
    TEST_ASSERT_INT64_WITHIN(1, 125 * MMS, o[0].v_peak);
}

/* block limits (one division for the limiting axis, found by comparing
 * products) equal the minimum over the axes of every axis's quotient, with
 * equal and with different per-axis limits (all three, or a and j only:
 * Z at half, as a real machine's), feeds above and below the smallest
 * axis speed limit; with the continuous S-curve the same v_max, and a and
 * j those of the class of the axes the block moves (what its run takes) */
static void test_block_limits_are_axis_minimum(void)
{
    int run, k, i, aaj_lo = 0, below = 0, above = 0;
    for (run = 0; run < 5; run++) {
        uint8_t shape = (run >= 3) ? SC_SHAPE_SCURVE_CONTINUOUS : SC_SHAPE_SCURVE;
        plan_profile_t s = base_profile(shape, PLAN_CORNER_JD);
        pos_nm_t pos[CORE_AXES] = {0, 0, 0};
        if (run == 1 || run == 3) {
            s.v_max[1] = 170 * MMS;
            s.a_max[0] = 700 * MMS;
            s.a_max[2] = 3100 * MMS;
            s.j_max[1] = 9000 * MMS;
            s.j_max[2] = 77777 * MMS;
        } else if (run == 2 || run == 4) {
            s.a_max[2] /= 2; /* a slower Z */
            s.j_max[2] /= 2;
        }
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 256, &s, origin));
        for (k = 0; k < 3000; k++) {
            plan_move_t m = mv(0, 0, 0, (run == 0) ? 4000 : 50 + (int64_t)(rnd() % 600));
            int64_t d[CORE_AXES], len = 0, ev = m.feed, ea = SC_A_LIMIT, ej = SC_J_LIMIT;
            int64_t vmin = s.v_max[0];
            unsigned mask = 0;
            const plan_block_t *b;
            for (i = 0; i < CORE_AXES; i++) {
                int64_t step = (int64_t)(rnd() % 2000001) - 1000000;
                step >>= (rnd() % 16);
                if (rnd() % 5 == 0) {
                    step = 0;
                }
                if (k % 4 == 3) {
                    step *= 4300; /* up to 4.3 m: components of 2^31 nm and more */
                }
                m.target[i] = pos[i] + step;
                vmin = (s.v_max[i] < vmin) ? s.v_max[i] : vmin;
            }
            if (plan_free_slots(&pl) == 0) {
                plan_seg_t seg;
                TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &seg));
            }
            if (plan_push(&pl, &m) != PLAN_OK) {
                continue; /* zero-length move */
            }
            below += (m.feed <= vmin) ? 1 : 0;
            above += (m.feed > vmin) ? 1 : 0;
            b = plan_peek(&pl, (uint16_t)(plan_count(&pl) - 1));
            len = b->len;
            for (i = 0; i < CORE_AXES; i++) {
                d[i] = m.target[i] - pos[i];
                d[i] = d[i] < 0 ? -d[i] : d[i];
                pos[i] = m.target[i];
                if (d[i] != 0) {
                    int64_t v = sc_muldiv(s.v_max[i], len, d[i]);
                    int64_t a = sc_muldiv(s.a_max[i], len, d[i]);
                    int64_t j = sc_muldiv(s.j_max[i], len, d[i]);
                    ev = v < ev ? v : ev;
                    ea = a < ea ? a : ea;
                    ej = j < ej ? j : ej;
                    mask |= 1u << i;
                }
            }
            if (run == 0) {
                /* equal limits: one factor len / dm in q31, rounded down:
                 * at most the exact floor, at most lim / 2^30 + 1 below */
                TEST_ASSERT_TRUE(b->lim.v_max <= ev && b->lim.v_max >= ev - (ev >> 30) - 1);
                TEST_ASSERT_TRUE(b->lim.a_max <= ea && b->lim.a_max >= ea - (ea >> 30) - 1);
                TEST_ASSERT_TRUE(b->lim.j_max <= ej && b->lim.j_max >= ej - (ej >> 30) - 1);
                /* the A^2/J kept for the reach is a lower bound of its floor */
                if (b->rk.qc < 0) {
                    u128 aa = (u128)b->lim.a_max * (u128)b->lim.a_max;
                    TEST_ASSERT_TRUE(b->rk.q > 0);
                    TEST_ASSERT_TRUE((u128)b->rk.q <= aa / (u128)b->lim.j_max);
                    TEST_ASSERT_TRUE((u128)b->rk.q + 32 >= aa / (u128)b->lim.j_max);
                    aaj_lo++;
                }
            } else if (run <= 2) {
                TEST_ASSERT_EQUAL_INT64(ev, b->lim.v_max);
                TEST_ASSERT_EQUAL_INT64(ea, b->lim.a_max);
                TEST_ASSERT_EQUAL_INT64(ej, b->lim.j_max);
            } else {
                uint8_t c = pl.cont_cls[mask];
                TEST_ASSERT_EQUAL_INT64(ev, b->lim.v_max);
                TEST_ASSERT_EQUAL_UINT8(c, b->cont_cls);
                TEST_ASSERT_EQUAL_INT64(pl.cont_a[c], b->lim.a_max);
                TEST_ASSERT_EQUAL_INT64(pl.cont_j[c], b->lim.j_max);
            }
        }
    }
    TEST_ASSERT_TRUE(aaj_lo > 1000);                /* the lower-bound path is exercised */
    TEST_ASSERT_TRUE(below > 1000 && above > 1000); /* feeds on both sides */
}

/* The continuous S-curve with axes of different limits leaves the
 * projected a and j out of plan_push: the junctions must be those the
 * per-block S-curve computes on the same path (arc joins read the block's
 * projected j), but for the class anchors (v_junction 1 nm/s below v_max
 * where the moving axes' class changes). Random paths of short chords,
 * arc joins, corners and Z moves; both limit sets of a slower Z. */
static void test_cont_junctions_match_per_block(void)
{
    static plan_block_t st2[64];
    plan_t q;
    int run, k, i, arcs = 0, anchors = 0;

    for (run = 0; run < 4; run++) {
        plan_profile_t s =
            base_profile(SC_SHAPE_SCURVE, (run & 1) ? PLAN_CORNER_VSTEP : PLAN_CORNER_JD);
        plan_profile_t c;
        pos_nm_t pos[CORE_AXES] = {0, 0, 0};
        int64_t dir = 0;
        s.a_max[2] /= 2;
        s.j_max[2] /= 2;
        if (run >= 2) {
            s.v_max[2] = 200 * MMS;
        }
        c = s;
        c.shape = SC_SHAPE_SCURVE_CONTINUOUS;
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 64, &s, origin));
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&q, st2, 64, &c, origin));
        for (k = 0; k < 4000; k++) {
            plan_move_t m = mv(0, 0, 0, 20 + (int64_t)(rnd() % 500));
            const plan_block_t *a, *b;
            int64_t seg = 20000 + (int64_t)(rnd() % 300000);
            double t;
            uint32_t r = rnd() % 100u;
            dir += (r < 5) ? (int64_t)(rnd() % 2049) - 1024 : (int64_t)(rnd() % 41) - 20;
            t = (double)dir * 6.283185307179586 / 4096.0;
            pos[0] += (int64_t)((double)seg * cos(t));
            pos[1] += (int64_t)((double)seg * sin(t));
            pos[2] += (r % 3u == 0u) ? (int64_t)(rnd() % 40001) - 20000 : 0;
            for (i = 0; i < CORE_AXES; i++) {
                m.target[i] = pos[i];
            }
            m.flags = (r >= 50) ? PLAN_MOVE_ARC_JOIN : 0u;
            if (plan_free_slots(&pl) == 0) {
                plan_seg_t sg;
                TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pl, &sg));
                TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&q, &sg));
            }
            TEST_ASSERT_EQUAL_INT(plan_push(&pl, &m), plan_push(&q, &m));
            a = plan_peek(&pl, (uint16_t)(plan_count(&pl) - 1));
            b = plan_peek(&q, (uint16_t)(plan_count(&q) - 1));
            TEST_ASSERT_EQUAL_INT64(a->lim.v_max, b->lim.v_max);
            TEST_ASSERT_EQUAL_INT64(a->v_corner_in, b->v_corner_in);
            TEST_ASSERT_EQUAL_UINT8(a->flags, b->flags);
            if (b->v_junction != a->v_junction) {
                TEST_ASSERT_TRUE(a->v_junction >= a->lim.v_max);
                TEST_ASSERT_EQUAL_INT64(a->lim.v_max - 1, b->v_junction);
                anchors++;
            }
            arcs += (m.flags != 0u && a->v_junction > 0 && a->v_junction < a->lim.v_max) ? 1 : 0;
        }
    }
    TEST_ASSERT_TRUE(arcs > 1000);   /* arc joins that limit the junction */
    TEST_ASSERT_TRUE(anchors > 100); /* class changes */
}

/* The junction-deviation early exit (pl_jd_above) must give exactly the
 * junction speed of the full computation: random corners (mostly shallow,
 * as on segmented arcs, where the exit applies), random per-axis
 * accelerations, deviations and feeds; both outcomes (capped by v_max and
 * limited by the corner) must occur. */
static void test_jd_early_exit_matches_full(void)
{
    int64_t vj[2];
    int capped = 0, limited = 0, n, k, i;

    for (n = 0; n < 4000; n++) {
        plan_profile_t s = base_profile(SC_SHAPE_SCURVE, PLAN_CORNER_JD);
        plan_move_t m1, m2;
        int64_t len1 = 1000 + (int64_t)(rnd() % (20 * MM));
        int64_t turn = (int64_t)(rnd() % 4096) >> (rnd() % 12); /* of 4096 */
        for (i = 0; i < CORE_AXES; i++) {
            s.a_max[i] = SC_A_MIN + (int64_t)(rnd() % (uint64_t)(50000 * MMS));
        }
        s.junction_dev_nm = (int64_t)(rnd() % 100000) >> (rnd() % 16);
        m1 = mv(len1, (int64_t)(rnd() % 1000), 0, 1 + (int64_t)(rnd() % 2000));
        m2 = mv(len1 + len1, m1.target[1] + len1 * turn / 4096,
                (rnd() % 2) ? (int64_t)(rnd() % (uint64_t)len1) >> (rnd() % 20) : 0,
                1 + (int64_t)(rnd() % 2000));
        for (k = 0; k < 2; k++) {
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pl, store, 8, &s, origin));
            plan_test_jd_fast(&pl, k == 0);
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &m1));
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pl, &m2));
            vj[k] = plan_peek(&pl, 1)->v_junction;
        }
        TEST_ASSERT_EQUAL_INT64(vj[1], vj[0]);
        {
            int64_t cap = plan_peek(&pl, 0)->lim.v_max;
            int64_t c2 = plan_peek(&pl, 1)->lim.v_max;
            cap = c2 < cap ? c2 : cap;
            if (vj[0] == cap) {
                capped++;
            } else {
                limited++;
            }
        }
    }
    TEST_ASSERT_TRUE(capped > 200);
    TEST_ASSERT_TRUE(limited > 200);
}

/* the block limits' 64-bit multiply-divide and the direction ratio's one
 * 128/64 division equal sc_muldiv over their whole input range: factors
 * of every bit length (products below and above 2^64, at the 2^32 split),
 * ratios with a <= len and a up to 4 len (saturation included) */
static void test_limit_and_ratio_divisions(void)
{
    int i, fast = 0;
    TEST_ASSERT_EQUAL_INT64(0, plan_test_muldiv(0, 5, 7));
    TEST_ASSERT_EQUAL_INT64(0, plan_test_muldiv(5, -1, 7));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, plan_test_muldiv(5, 1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, plan_test_muldiv((int64_t)1 << 40, (int64_t)1 << 23, 1));
    TEST_ASSERT_EQUAL_INT64(sc_muldiv(4294967295LL, 4294967295LL, 3),
                            plan_test_muldiv(4294967295LL, 4294967295LL, 3));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, plan_test_ratio(12345, 12345));
    TEST_ASSERT_EQUAL_INT64(0, plan_test_ratio(0, 12345));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, plan_test_ratio(4 * 12345, 12345));
    for (i = 0; i < 200000; i++) {
        int64_t a = (int64_t)(rnd() >> (1 + rnd() % 63)), b = (int64_t)(rnd() >> (1 + rnd() % 63));
        int64_t c = (int64_t)(rnd() >> (1 + rnd() % 63)) + 1, len, x;
        TEST_ASSERT_EQUAL_INT64(sc_muldiv(a, b, c), plan_test_muldiv(a, b, c));
        fast += (a > 0 && b > 0 && (uint64_t)a * (uint64_t)b / (uint64_t)b == (uint64_t)a) ? 1 : 0;
        len = (int64_t)(rnd() >> (1 + rnd() % 63)) + 1;
        x = (int64_t)(rnd() % (uint64_t)len);
        if (rnd() % 4 == 0 && len < ((int64_t)1 << 60)) {
            x += (int64_t)(rnd() % (3 * (uint64_t)len + 1)); /* above len: saturates at 4 len */
        }
        TEST_ASSERT_EQUAL_INT64(sc_muldiv(x, (int64_t)1 << 62, len), plan_test_ratio(x, len));
        TEST_ASSERT_EQUAL_INT64(sc_muldiv(len, (int64_t)1 << 62, len), plan_test_ratio(len, len));
    }
    TEST_ASSERT_TRUE(fast > 50000); /* the 64-bit path is exercised */
}

/* the direction ratio from one reciprocal per block (plan_push): the exact
 * floor (plan_test_ratio, the oracle) or one less, for every length up to
 * SC_LEN_MAX = 2^40 and 0 <= a <= len; a == len gives 2^62 exactly */
static void test_ratio_reciprocal(void)
{
    int i, below = 0;
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, plan_test_ratio_rec(12345, 12345));
    TEST_ASSERT_EQUAL_INT64(0, plan_test_ratio_rec(0, 12345));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, plan_test_ratio_rec(1, 1));
    for (i = 0; i < 300000; i++) {
        int64_t len = (int64_t)(rnd() >> (24 + rnd() % 40)) + 1, x, e, r;
        if (i % 7 == 0) {
            len = (int64_t)1 << (rnd() % 41); /* powers of two, 2^40 included */
        }
        x = (int64_t)(rnd() % (uint64_t)(len + 1));
        e = plan_test_ratio(x, len);
        r = plan_test_ratio_rec(x, len);
        TEST_ASSERT_TRUE(r == e || r == e - 1);
        below += (r != e) ? 1 : 0;
    }
    printf("ratio from the reciprocal one below the exact floor: %d of 300000\n", below);
}

/* the equal-limits factor len / dm in q31 (one reciprocal step and an
 * exact remainder correction, no division helper) is the exact floor of
 * l 2^31 / d with the operands cut to 31 bits as specified */
static void test_len_factor_exact(void)
{
    int i;
    for (i = 0; i < 300000; i++) {
        int64_t dm = (int64_t)(rnd() >> (23 + rnd() % 40)) + 1, len, l, d;
        unsigned b = 0;
        u128 e;
        if (i % 11 == 0) {
            dm = (int64_t)1 << (rnd() % 40); /* powers of two */
        }
        len = dm + (int64_t)(rnd() % (uint64_t)(dm * 3 / 4 + 1)); /* dm <= len < 1.75 dm */
        if (i % 13 == 0) {
            len = dm;
        }
        while ((dm >> b) >= ((int64_t)1 << 31)) {
            b++;
        }
        l = len >> b;
        d = (b > 0) ? (dm >> b) + 1 : dm;
        e = ((u128)l << 31) / (u128)d;
        TEST_ASSERT_EQUAL_UINT32((uint32_t)e, plan_test_len_factor(len, dm));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_single_move_rest_to_rest);
    RUN_TEST(test_short_move_never_reaches_feed);
    RUN_TEST(test_collinear_junction_keeps_speed);
    RUN_TEST(test_90_degree_junction_rules);
    RUN_TEST(test_reversal_stops);
    RUN_TEST(test_exact_stop_vs_continuous);
    RUN_TEST(test_smooth_cap_staircase);
    RUN_TEST(test_smooth_cap_is_larger_corner);
    RUN_TEST(test_smooth_cap_rules);
    RUN_TEST(test_tiny_blocks_at_min_block_time);
    RUN_TEST(test_scurve_micro_blocks_are_slow);
    RUN_TEST(test_short_block_between_long_ones_not_slowed);
    RUN_TEST(test_incremental_equals_scratch);
    RUN_TEST(test_incremental_equals_scratch_trapezoid);
    RUN_TEST(test_deferred_pops_equal_immediate);
    RUN_TEST(test_scurve_at_rest_single_and_reversal);
    RUN_TEST(test_scurve_at_rest_micro_blocks);
    RUN_TEST(test_scurve_continuous_cam_circle);
    RUN_TEST(test_scurve_continuous_profile_rules);
    RUN_TEST(test_scurve_at_rest_block_shapes);
    RUN_TEST(test_scurve_at_rest_incremental_and_deferred);
    RUN_TEST(test_queue_time_slots_and_errors);
    RUN_TEST(test_arc_chord_joins_use_the_arc_limit);
    RUN_TEST(test_axis_limits_projected);
    RUN_TEST(test_block_limits_are_axis_minimum);
    RUN_TEST(test_cont_junctions_match_per_block);
    RUN_TEST(test_jd_early_exit_matches_full);
    RUN_TEST(test_limit_and_ratio_divisions);
    RUN_TEST(test_ratio_reciprocal);
    RUN_TEST(test_len_factor_exact);
    return UNITY_END();
}
