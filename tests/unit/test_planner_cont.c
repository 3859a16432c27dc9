/*
 * Continuous S-curve (planner_cont.c): the optimised planner against the
 * frozen reference (ref/planner_cont_r1.c, the first version) on random
 * paths. Two planners get the same pushes; one pops with plan_pop, the
 * other with the reference. Every popped profile, the run's plan in force
 * and path state, the anchors' entry bounds and the queued time must be
 * the same, bit for bit: the optimisation changes the cost, not the plan.
 */
#include "planner.h"
#include "planner_test.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ref/planner_cont_r1.c"

#define MM  1000000LL /* nm */
#define MMS 1000000LL /* nm/s per mm/s */

static plan_block_t store_a[64], store_b[64];
static plan_t pa, pb;

void setUp(void)
{
}

void tearDown(void)
{
}

static uint64_t rng_state;

static uint32_t rnd(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(rng_state >> 33);
}

/* uniform in [lo, hi] */
static int64_t rnd_in(int64_t lo, int64_t hi)
{
    uint64_t r = ((uint64_t)rnd() << 31) ^ rnd();
    return lo + (int64_t)(r % (uint64_t)(hi - lo + 1));
}

/* plan_pop with the reference for the move blocks (the bookkeeping as
 * planner.c's plan_pop: the continuous shape never runs pl_replan) */
static void ref_pop(plan_t *p, plan_seg_t *out)
{
    plan_block_t *b = &p->ring[p->tail];

    memset(out, 0, sizeof(*out));
    if (b->dwell_ns > 0) {
        out->total_ns = b->dwell_ns;
    } else {
        ref_cont_pop(p, out);
    }
    p->tail = (uint16_t)((p->tail + 1u) % p->depth);
    p->count--;
    if (p->planned > 0) {
        p->planned--;
    }
    if (p->fresh > 0) {
        p->fresh--;
    }
    if (p->planned == 0 && p->count > 0) {
        p->planned = 1;
    }
    p->next_entry = 0;
}

static void same_profile(const sc_profile_t *a, const sc_profile_t *b)
{
    int ph;
    for (ph = 0; ph < SC_PHASES; ph++) {
        TEST_ASSERT_EQUAL_INT64(b->t_ns[ph], a->t_ns[ph]);
        TEST_ASSERT_EQUAL_INT64(b->jerk[ph], a->jerk[ph]);
        TEST_ASSERT_EQUAL_INT64(b->j6_q16[ph], a->j6_q16[ph]);
        TEST_ASSERT_EQUAL_INT64(b->start[ph].s_q16, a->start[ph].s_q16);
        TEST_ASSERT_EQUAL_INT64(b->start[ph].v_q16, a->start[ph].v_q16);
        TEST_ASSERT_EQUAL_INT64(b->start[ph].a_q16, a->start[ph].a_q16);
    }
    TEST_ASSERT_EQUAL_INT64(b->len, a->len);
    TEST_ASSERT_EQUAL_INT64(b->v0, a->v0);
    TEST_ASSERT_EQUAL_INT64(b->vp, a->vp);
    TEST_ASSERT_EQUAL_INT64(b->v1, a->v1);
    TEST_ASSERT_EQUAL_INT64(b->total_ns, a->total_ns);
    TEST_ASSERT_EQUAL_INT64(b->s_end_q16, a->s_end_q16);
}

/* what the next pop depends on: the plan in force (when there is one),
 * the path state, the first-run cache and the anchors' bounds */
static void same_state(void)
{
    uint16_t i;

    TEST_ASSERT_EQUAL_UINT16(pb.count, pa.count);
    TEST_ASSERT_EQUAL_INT64(pb.cont_rem, pa.cont_rem);
    TEST_ASSERT_EQUAL_INT64(pb.cont_x, pa.cont_x);
    TEST_ASSERT_EQUAL_INT64(pb.cont_t_ns, pa.cont_t_ns);
    TEST_ASSERT_EQUAL_INT64(pb.cont_st.s_q16, pa.cont_st.s_q16);
    TEST_ASSERT_EQUAL_INT64(pb.cont_st.v_q16, pa.cont_st.v_q16);
    TEST_ASSERT_EQUAL_INT64(pb.cont_st.a_q16, pa.cont_st.a_q16);
    TEST_ASSERT_EQUAL_UINT16(pb.cont_scan, pa.cont_scan);
    TEST_ASSERT_EQUAL_UINT16(pb.cont_run_n, pa.cont_run_n);
    TEST_ASSERT_EQUAL_INT64(pb.cont_run_len, pa.cont_run_len);
    TEST_ASSERT_EQUAL_UINT32(pb.cont_kept, pa.cont_kept);
    TEST_ASSERT_EQUAL_UINT32(pb.cont_forced, pa.cont_forced);
    if (pa.cont_rem > 0) {
        same_profile(&pa.cont_prof, &pb.cont_prof);
    }
    for (i = 0; i < pa.count; i++) {
        TEST_ASSERT_EQUAL_INT64(plan_peek(&pb, i)->v_entry, plan_peek(&pa, i)->v_entry);
    }
}

typedef struct {
    uint32_t pops, plans, cruise_pops, accel_joins, stalls, dwells;
} eq_stats_t;

static void pop_both(eq_stats_t *st)
{
    plan_seg_t sa, sb;

    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pa, &sa));
    ref_pop(&pb, &sb);
    TEST_ASSERT_EQUAL_INT64(sb.total_ns, sa.total_ns);
    if (sa.dwell_ns == 0) {
        same_profile(&sa.prof, &sb.prof);
        st->cruise_pops += (sa.prof.t_ns[3] == sa.prof.total_ns) ? 1u : 0u;
        st->accel_joins += (pa.cont_rem > 0 && pa.cont_st.a_q16 != 0) ? 1u : 0u;
        st->plans += (pa.cont_t_ns == sa.total_ns) ? 1u : 0u;
    }
    same_state();
    st->pops++;
}

static void push_both(const plan_move_t *m)
{
    plan_result_t ra = plan_push(&pa, m), rb = plan_push(&pb, m);
    TEST_ASSERT_EQUAL_INT(rb, ra);
}

static plan_profile_t eq_profile(bool same, int corner)
{
    plan_profile_t p;
    int i;

    int64_t na = rnd_in(0, 999), nj = rnd_in(0, 999);

    memset(&p, 0, sizeof(p));
    for (i = 0; i < CORE_AXES; i++) {
        int k = same ? 0 : i;
        p.v_max[i] = (int64_t)(200 + 150 * k) * MMS;
        p.a_max[i] = (int64_t)(500 + 1700 * k) * MMS + (same ? na : rnd_in(0, 999));
        p.j_max[i] = (int64_t)(20000 + 15000 * k) * MMS + (same ? nj : rnd_in(0, 999));
        p.corner_dv[i] = 5 * MMS;
    }
    p.junction_dev_nm = rnd_in(2000, 50000);
    p.mbt_window = 1;
    p.corner = (uint8_t)corner;
    p.shape = SC_SHAPE_SCURVE_CONTINUOUS;
    return p;
}

/* n moves of a random path (seeded): smooth stretches of short chords
 * (CAM-like, the usual run), corners, reversals, exact stops, dwells and
 * feed changes, long and very short blocks; the queue refilled before
 * each pop as the drive does, and now and then drained (the feed stalls)
 * or popped twice in a row. */
static void eq_run(uint32_t seed, uint32_t n, uint16_t depth, bool same, int corner, eq_stats_t *st)
{
    const pos_nm_t o[CORE_AXES] = {0, 0, 0};
    plan_profile_t prof;
    int64_t x = 0, y = 0, z = 0, dir = 0, feed = 100 * MMS, seglen = 50000;
    uint32_t k;

    rng_state = seed;
    prof = eq_profile(same, corner);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pa, store_a, depth, &prof, o));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pb, store_b, depth, &prof, o));
    ref_cont_reset(&pb);
    for (k = 0; k < n; k++) {
        plan_move_t m;
        uint32_t r = rnd() % 1000u;

        memset(&m, 0, sizeof(m));
        if (r < 3) {
            m.dwell_ns = rnd_in(1, 5000000);
            st->dwells++;
        } else {
            /* direction in 1/4096 turns */
            if (r < 40) {
                dir += rnd_in(-1024, 1024); /* a corner, or a reversal */
            } else {
                dir += rnd_in(-12, 12); /* a smooth path */
            }
            if (r % 97u == 5u) {
                feed = rnd_in(5, 400) * MMS + rnd_in(0, 999999);
            }
            if (r % 89u == 7u) {
                seglen = (rnd() % 4u == 0u) ? rnd_in(1000, 20 * MM) : rnd_in(5000, 300000);
            }
            {
                double t = (double)dir * 6.283185307179586 / 4096.0;
                int64_t dx = (int64_t)((double)seglen * cos(t));
                int64_t dy = (int64_t)((double)seglen * sin(t));
                int64_t dz = (r % 5u == 0u) ? rnd_in(-2000, 2000) : 0;
                if (!same) {
                    /* axes with different limits: every block moves every
                     * axis, so the run's limits are the smallest axis a and
                     * j as in the reference (test_cont_axis_limits takes
                     * the axes a block moves) */
                    dx += (dx == 0) ? 1 : 0;
                    dy += (dy == 0) ? 1 : 0;
                    dz += (dz == 0) ? 1 - 2 * (int64_t)(k & 1u) : 0;
                }
                x += dx;
                y += dy;
                z += dz;
            }
            m.target[0] = x;
            m.target[1] = y;
            m.target[2] = z;
            m.feed = feed;
            m.flags = (r % 211u == 3u) ? PLAN_MOVE_EXACT_STOP : 0u;
        }
        if (plan_free_slots(&pa) == 0u) {
            pop_both(st);
        }
        push_both(&m);
        if (rnd() % 53u == 0u && pa.count > 1u) {
            pop_both(st); /* the host fell behind a little */
        }
        if (rnd() % 701u == 0u) {
            while (pa.count > 0u) { /* the feed stalls: the queue drains */
                pop_both(st);
            }
            st->stalls++;
        }
        if (k % 64u == 0u) {
            TEST_ASSERT_EQUAL_INT64(ref_cont_queued_ns(&pb), plan_queued_ns(&pa));
        }
    }
    while (pa.count > 0u) {
        pop_both(st);
    }
}

static void test_cont_equals_reference_random_paths(void)
{
    eq_stats_t st;
    uint32_t s;

    memset(&st, 0, sizeof(st));
    for (s = 0; s < 6u; s++) {
        eq_run(1000u + s, 8000,
               (s % 3u == 0u)   ? 64
               : (s % 3u == 1u) ? 16
                                : 5,
               s % 2u == 0u, (s == 5u) ? PLAN_CORNER_VSTEP : PLAN_CORNER_JD, &st);
    }
    printf("planner_cont equivalence: %u pops, %u new plans, %u cruise-only, %u joins "
           "accelerating, %u stalls, %u dwells\n",
           st.pops, st.plans, st.cruise_pops, st.accel_joins, st.stalls, st.dwells);
    /* every path of plan_cont_pop is exercised */
    TEST_ASSERT_TRUE(st.cruise_pops > 5000);
    TEST_ASSERT_TRUE(st.accel_joins > 1000);
    TEST_ASSERT_TRUE(st.stalls > 20);
    TEST_ASSERT_TRUE(st.dwells > 20);
}

/* The bench's and the CAM cases: long chains of short chords at
 * feed (0.05 mm at 10 m/min; 0.2 mm at 50 mm/s), the ring full; again
 * with Z's a and j at half of X/Y's (bench_mps2.c's *_unequal figures:
 * plan_push's exact limit path; every chord moves every axis, so the
 * reference's run limits, the smallest of all axes, are the class's). */
static void test_cont_equals_reference_cam_chords(void)
{
    const pos_nm_t o[CORE_AXES] = {0, 0, 0};
    plan_profile_t prof;
    eq_stats_t st;
    int run;

    memset(&st, 0, sizeof(st));
    rng_state = 77u;
    for (run = 0; run < 4; run++) {
        int64_t x = 5000000, y = 0;
        uint32_t k;
        prof = eq_profile(true, PLAN_CORNER_JD);
        if (run >= 2) {
            prof.a_max[2] /= 2;
            prof.j_max[2] /= 2;
        }
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pa, store_a, 64, &prof, o));
        TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pb, store_b, 64, &prof, o));
        ref_cont_reset(&pb);
        for (k = 0; k < 6000u; k++) {
            plan_move_t m;
            int64_t nx, ny;
            memset(&m, 0, sizeof(m));
            if (run % 2 == 0) { /* 0.2 mm chords, ~2.3 degrees, feed 50 mm/s */
                nx = x - y / 25;
                ny = y + x / 25;
                m.feed = 50 * MMS;
            } else { /* 0.05 mm chords of a 40 mm radius, 10 m/min */
                nx = x - y / 800;
                ny = y + x / 800;
                m.feed = 10000 * MMS / 60;
            }
            x = nx;
            y = ny;
            m.target[0] = x;
            m.target[1] = y;
            m.target[2] = (int64_t)k * 1000 + ((run >= 2) ? 1000 : 0); /* Z moves from the first */
            if (plan_free_slots(&pa) == 0u) {
                pop_both(&st);
            }
            push_both(&m);
        }
        while (pa.count > 0u) {
            pop_both(&st);
        }
    }
    TEST_ASSERT_TRUE(st.cruise_pops > 20000);
}

/* The cruise's time and distance without a 128-bit division, against
 * sc_muldiv_ceil and sc_muldiv (what the reference computes), at the
 * boundaries where the ceiling steps: dq = floor(v tau / 1e9) and one
 * more, speeds from 1 nm/s to the limit, times from 1 ns to hours. */
static void test_cont_cruise_time_exact(void)
{
    uint32_t k, fast = 0;

    rng_state = 99u;
    for (k = 0; k < 400000u; k++) {
        int64_t w = (k % 4u == 0u) ? rnd_in(1, 70000) : rnd_in(1, SC_V_LIMIT);
        int64_t v = w * 65536, tmax = sc_muldiv((int64_t)1 << 42, 1000000000, v);
        int64_t tau0 = rnd_in(1, fx_min64(tmax + 2, (k % 3u == 0u) ? 1000000 : 4000000000000LL));
        int64_t dq0 = sc_muldiv(v, tau0, 1000000000), i;
        for (i = -1; i <= 1; i++) {
            int64_t dq = dq0 + i, t = -1, ds = -1, t2 = -1, ds2 = -1;
            if (plan_test_cont_cruise_time(v, dq, true, &t, &ds)) {
                TEST_ASSERT_EQUAL_INT64(sc_muldiv_ceil(dq, 1000000000, v), t);
                TEST_ASSERT_EQUAL_INT64(sc_muldiv(v, t, 1000000000), ds);
                TEST_ASSERT_TRUE(plan_test_cont_cruise_time(v, dq, false, &t2, &ds2));
                TEST_ASSERT_EQUAL_INT64(t, t2);
                TEST_ASSERT_EQUAL_INT64(ds, ds2);
                fast++;
            } else {
                TEST_ASSERT_TRUE(dq <= 0 || dq >= ((int64_t)1 << 42));
            }
        }
    }
    TEST_ASSERT_TRUE(fast > 600000u);
    /* outside its range: the caller divides */
    {
        int64_t t, ds;
        TEST_ASSERT_FALSE(plan_test_cont_cruise_time(65536 + 1, 1000, true, &t, &ds));
        TEST_ASSERT_FALSE(plan_test_cont_cruise_time((int64_t)1 << 48, 1000, true, &t, &ds));
        TEST_ASSERT_FALSE(plan_test_cont_cruise_time(65536, (int64_t)1 << 42, true, &t, &ds));
        TEST_ASSERT_FALSE(plan_test_cont_cruise_time(65536, 0, true, &t, &ds));
        TEST_ASSERT_TRUE(plan_test_cont_cruise_time(65536, ((int64_t)1 << 42) - 1, true, &t, &ds));
    }
}

/* Axis limits by the axes a run moves: X and Y at a and j, Z at a tenth
 * of them (a slow Z), every v equal. */
static plan_profile_t slow_z_profile(int64_t za, int64_t zj)
{
    plan_profile_t p;
    int i;

    memset(&p, 0, sizeof(p));
    for (i = 0; i < CORE_AXES; i++) {
        p.v_max[i] = 500 * MMS;
        p.a_max[i] = 2000 * MMS;
        p.j_max[i] = 50000 * MMS;
        p.corner_dv[i] = 5 * MMS;
    }
    p.a_max[2] = za;
    p.j_max[2] = zj;
    p.junction_dev_nm = 10000;
    p.mbt_window = 1;
    p.corner = PLAN_CORNER_JD;
    p.shape = SC_SHAPE_SCURVE_CONTINUOUS;
    return p;
}

/* A slow acceleration with a fast speed puts a run's candidate distances
 * beyond q16 (3 v^2 / (2 a) > 2^44 nm: UBSan in pc_r1 before the check):
 * the continuous shape refuses the profile, the per-block S-curve takes
 * it; the boundary is the stated one. */
static void test_cont_refuses_a_profile_beyond_its_range(void)
{
    plan_profile_t p = slow_z_profile(10000, 1000000); /* Z: 10 um/s^2, 1 mm/s^3 */
    int64_t v;

    p.v_max[0] = SC_V_LIMIT;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&p));
    p.shape = SC_SHAPE_SCURVE;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&p));
    p.shape = SC_SHAPE_SCURVE_CONTINUOUS;
    /* v^2 / a at 2^45 / 3: v = sqrt(2^45 / 3 * 1e4) ~ 3.4e8 nm/s */
    v = (int64_t)sqrt(((double)((int64_t)1 << 45) / 3.0) * 10000.0);
    p.v_max[0] = p.v_max[1] = p.v_max[2] = v - 1000;
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_check_profile(&p));
    p.v_max[1] = v + 1000;
    TEST_ASSERT_EQUAL_INT(PLAN_E_PROFILE, plan_check_profile(&p));
}

typedef struct {
    int64_t total_ns;
    double max_a_xy, max_a_z; /* the largest |a| of blocks without and with
                               * Z motion, of the smallest limit they move */
    double max_j_xy, max_j_z;
} axis_job_t;

/* 0.2 mm chords around a circle of R 5 mm in XY at 200 mm/s, from rest to
 * rest; chords from z_from to z_to (indices) also move Z by 1 um (a helix
 * stretch whose joins limit no speed). The queue refilled before each
 * pop. Every popped segment's |a| (at its phase ends: a is linear in a
 * phase) and |j| (phases that last) against the smallest a and j of the
 * axes its block moves. */
static void axis_job(const plan_profile_t *prof, uint32_t n, uint32_t z_from, uint32_t z_to,
                     axis_job_t *r)
{
    const pos_nm_t o[CORE_AXES] = {5000000, 0, 0};
    int64_t x = 5000000, y = 0, z = 0;
    uint32_t k, popped = 0;
    plan_seg_t seg;

    memset(r, 0, sizeof(*r));
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&pa, store_a, 64, prof, o));
    for (k = 0; k < n || pa.count > 0u; k++) {
        if (k < n) {
            plan_move_t m;
            int64_t nx = x - y / 25, ny = y + x / 25;
            memset(&m, 0, sizeof(m));
            x = nx;
            y = ny;
            z += (k >= z_from && k < z_to) ? 1000 : 0;
            m.target[0] = x;
            m.target[1] = y;
            m.target[2] = z;
            m.feed = 200 * MMS;
            if (plan_free_slots(&pa) > 0u) {
                TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pa, &m));
                continue;
            }
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pa, &seg));
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&pa, &m));
        } else {
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_pop(&pa, &seg));
        }
        popped++;
        {
            int64_t amin = INT64_MAX, jmin = INT64_MAX, am = 0, jm = 0;
            bool zm = seg.end[2] != seg.start[2];
            int i, ph;
            for (i = 0; i < CORE_AXES; i++) {
                if (seg.end[i] != seg.start[i]) {
                    amin = (prof->a_max[i] < amin) ? prof->a_max[i] : amin;
                    jmin = (prof->j_max[i] < jmin) ? prof->j_max[i] : jmin;
                }
            }
            for (ph = 0; ph < SC_PHASES; ph++) {
                sc_state_t e;
                if (seg.prof.t_ns[ph] <= 0) {
                    continue;
                }
                sc_eval_phase(&seg.prof, ph, seg.prof.t_ns[ph], &e);
                am = fx_max64(am, fx_max64(seg.prof.start[ph].a_q16 < 0 ? -seg.prof.start[ph].a_q16
                                                                        : seg.prof.start[ph].a_q16,
                                           e.a_q16 < 0 ? -e.a_q16 : e.a_q16) /
                                      65536);
                jm = fx_max64(jm, seg.prof.jerk[ph] < 0 ? -seg.prof.jerk[ph] : seg.prof.jerk[ph]);
            }
            if (zm) {
                r->max_a_z = fmax(r->max_a_z, (double)am / (double)amin);
                r->max_j_z = fmax(r->max_j_z, (double)jm / (double)jmin);
            } else {
                r->max_a_xy = fmax(r->max_a_xy, (double)am / (double)amin);
                r->max_j_xy = fmax(r->max_j_xy, (double)jm / (double)jmin);
            }
        }
        r->total_ns += seg.total_ns;
    }
    TEST_ASSERT_EQUAL_UINT32(n, popped);
    TEST_ASSERT_EQUAL_UINT32(0, pa.cont_forced);
}

/* A slow Z (a tenth of X/Y's a and j) does not slow an XY contour: a
 * circle of chords runs with X/Y's limits, in the time of the machine
 * whose axes all have X/Y's limits, not in that of Z's; and every block
 * stays within the a and j of the axes it moves. */
static void test_cont_axis_limits_xy_circle(void)
{
    plan_profile_t slow = slow_z_profile(200 * MMS, 5000 * MMS);
    plan_profile_t fast = slow_z_profile(2000 * MMS, 50000 * MMS);
    plan_profile_t allz = slow_z_profile(200 * MMS, 5000 * MMS);
    axis_job_t rs, rf, rz;
    int i;

    for (i = 0; i < CORE_AXES; i++) {
        allz.a_max[i] = 200 * MMS;
        allz.j_max[i] = 5000 * MMS;
    }
    axis_job(&slow, 400, 0, 0, &rs);
    axis_job(&fast, 400, 0, 0, &rf);
    axis_job(&allz, 400, 0, 0, &rz);
    printf("xy circle: slow Z %.4f s, all axes X/Y's limits %.4f s, all Z's %.4f s; "
           "a %.4f j %.4f of the limit\n",
           (double)rs.total_ns * 1e-9, (double)rf.total_ns * 1e-9, (double)rz.total_ns * 1e-9,
           rs.max_a_xy, rs.max_j_xy);
    TEST_ASSERT_TRUE((double)rs.total_ns <= 1.001 * (double)rf.total_ns);
    TEST_ASSERT_TRUE((double)rs.total_ns < 0.8 * (double)rz.total_ns);
    TEST_ASSERT_TRUE(rs.max_a_xy <= 1.0 && rs.max_j_xy <= 1.0);
    TEST_ASSERT_TRUE(rs.max_a_xy > 0.5 && rs.max_j_xy > 0.5); /* X/Y's limits are used */
}

/* A run that moves Z takes Z's limits: a helix stretch right after the
 * start (from rest: the path accelerates over it, and would reach X/Y's a
 * if the stretch joined the first XY chords' run) and a whole helix, on
 * the slow-Z machine. */
static void test_cont_axis_limits_z_run(void)
{
    plan_profile_t slow = slow_z_profile(200 * MMS, 5000 * MMS);
    axis_job_t r;

    axis_job(&slow, 400, 2, 60, &r);
    printf("xy circle with a helix stretch: a %.4f j %.4f (Z blocks), a %.4f j %.4f (XY)\n",
           r.max_a_z, r.max_j_z, r.max_a_xy, r.max_j_xy);
    TEST_ASSERT_TRUE(r.max_a_z <= 1.0 && r.max_j_z <= 1.0);
    TEST_ASSERT_TRUE(r.max_a_xy <= 1.0 && r.max_j_xy <= 1.0);
    TEST_ASSERT_TRUE(r.max_a_z > 0.5 && r.max_a_xy > 0.5); /* both accelerate */
    axis_job(&slow, 200, 0, 200, &r);
    printf("helix: a %.4f j %.4f of Z's limits\n", r.max_a_z, r.max_j_z);
    TEST_ASSERT_TRUE(r.max_a_z <= 1.0 && r.max_j_z <= 1.0);
    TEST_ASSERT_TRUE(r.max_a_z > 0.5);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cont_equals_reference_random_paths);
    RUN_TEST(test_cont_equals_reference_cam_chords);
    RUN_TEST(test_cont_cruise_time_exact);
    RUN_TEST(test_cont_axis_limits_xy_circle);
    RUN_TEST(test_cont_axis_limits_z_run);
    RUN_TEST(test_cont_refuses_a_profile_beyond_its_range);
    return UNITY_END();
}
