/*
 * The arc reference (arc_ref.h) on its own: chords of real arcs
 * (arc_seg.h) planned and interpolated (planner.h, interp.h) as the drive
 * does, and on every tick the arc reference the drive would take against
 * the exact path (arc_ref_exact, the oracle) at the same chord point:
 *   - on the exact ticks (not a recurrence step) the fast exact path
 *     equals arc_ref_exact bit for bit (position, velocity, acceleration,
 *     tangent, geometry);
 *   - on the recurrence's steps every output is within the bound
 *     arc_ref.h states, re-anchored at least every ARC_REF_ROT_TICKS ticks;
 *   - the recurrence is in use (most cruise ticks are steps).
 * Arcs: a 5 mm helix at 20 mm/s (the firmware benchmark's), clockwise, the
 * three planes, and chords of the maximum angle at 1.9e9 nm radius.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "arc_ref.h"
#include "arc_seg.h"
#include "drive.h"
#include "interp.h"
#include "planner.h"
#include "unity.h"

#define TICK_HZ 10000u

static plan_block_t store[PLAN_DEPTH_DEFAULT];
static plan_t plan;
static interp_t ip;

typedef struct {
    uint32_t ticks, steps, exact_ticks; /* arc ticks, recurrence steps, exact ticks */
    uint32_t exact_differ;              /* exact ticks not equal to the oracle      */
    uint32_t longest_run;               /* most consecutive steps                   */
    int64_t pos, vel;                   /* largest step differences                 */
    double rel;                         /* largest step difference / its bound      */
} ar_stats_t;

static void rel(ar_stats_t *d, int64_t x, double bound)
{
    double q = (double)(x < 0 ? -x : x) / bound;
    d->rel = q > d->rel ? q : d->rel;
}

static int64_t max_abs(int64_t m, int64_t x)
{
    x = x < 0 ? -x : x;
    return x > m ? x : m;
}

/* The plane axes' outputs and the geometry of r and x are identical. */
static bool same(const motion_ref_t *r, const motion_ref_t *x, uint8_t u, uint8_t v)
{
    return r->pos[u] == x->pos[u] && r->pos[v] == x->pos[v] && r->vel[u] == x->vel[u] &&
           r->vel[v] == x->vel[v] && r->acc[u] == x->acc[u] && r->acc[v] == x->acc[v] &&
           r->geom.tangent[u] == x->geom.tangent[u] && r->geom.tangent[v] == x->geom.tangent[v] &&
           r->geom.kind == x->geom.kind && r->geom.radius == x->geom.radius &&
           r->geom.plane_u == x->geom.plane_u && r->geom.plane_v == x->geom.plane_v &&
           r->geom.centre_u == x->geom.centre_u && r->geom.centre_v == x->geom.centre_v &&
           r->geom.sense == x->geom.sense;
}

/* An arc from the origin about (-radius, 0) in `plane`, sweep_q16 / 2^16
 * turns (0: a full circle), ending at radius + dr (a spiral), climbing
 * 0.3 mm along the third axis. */
static void run_arc(drive_plane_t plane, int sense, int64_t radius, int64_t dr, int64_t feed,
                    int64_t chord_nm, uint32_t sweep_q16, ar_stats_t *d)
{
    static const uint8_t uvw[3][3] = {{0, 1, 2}, {2, 0, 1}, {1, 2, 0}}; /* XY, ZX, YZ */
    const uint8_t *ax = uvw[plane];
    const pos_nm_t origin[CORE_AXES] = {0, 0, 0};
    static arc_ref_t ar, oracle;
    drive_config_t cfg;
    drive_block_t b;
    arc_seg_t seg;
    motion_ref_t ch, ref, x;
    uint32_t pushed = 0, k, run = 0;

    memset(d, 0, sizeof *d);
    memset(&b, 0, sizeof b);
    memset(&ch, 0, sizeof ch);
    memset(&ref, 0, sizeof ref);
    b.kind = DRIVE_BLOCK_ARC;
    b.feed_nm_s = feed;
    b.plane = plane;
    b.centre_u = -radius;
    b.centre_v = 0;
    b.sense = (int8_t)sense;
    b.target[ax[2]] = 300000;
    if (sweep_q16 != 0) {
        double a = 6.283185307179586 * sweep_q16 / 65536.0;
        b.target[ax[0]] = (int64_t)((radius + dr) * cos(a)) - radius;
        b.target[ax[1]] = (int64_t)(sense * (radius + dr) * sin(a));
    }
    TEST_ASSERT_TRUE(arc_seg_setup(&seg, &b, origin, 3, TICK_HZ, chord_nm));
    drive_config_default(&cfg, TICK_HZ, 3);
    TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_init(&plan, store, PLAN_DEPTH_DEFAULT, &cfg.plan, origin));
    interp_init(&ip, 1000000000 / TICK_HZ, origin);
    arc_ref_reset(&ar);
    arc_ref_reset(&oracle);
    ar.exact = false;
    for (k = 0; k < 200000u; k++) {
        arc_chord_t g;
        /* the feed path: every chord the planner takes, then one pop per
         * free FIFO slot once the planner is full or has every chord */
        while (pushed < seg.n_seg && plan_free_slots(&plan) > 0) {
            plan_move_t m;
            memset(&m, 0, sizeof m);
            arc_seg_chord(&seg, &b, pushed, m.target, NULL);
            m.feed = feed;
            m.tag = pushed;
            TEST_ASSERT_EQUAL_INT(PLAN_OK, plan_push(&plan, &m));
            pushed++;
        }
        while (interp_room(&ip) > 0 && plan_count(&plan) > 0 &&
               (pushed == seg.n_seg || plan_free_slots(&plan) == 0)) {
            TEST_ASSERT_EQUAL_UINT(1, interp_refill(&ip, &plan));
        }
        if (pushed == seg.n_seg && interp_idle(&ip)) {
            break;
        }
        interp_tick(&ip, &ch);
        if (!interp_busy(&ip) || !ch.active) {
            continue;
        }
        {
            pos_nm_t end[CORE_AXES];
            arc_seg_chord(&seg, &b, interp_tag(&ip), end, &g);
        }
        /* the oracle at this chord point */
        x = ch;
        arc_ref_exact(&oracle, &x, &ch, &g);
        d->ticks++;
        if (!interp_pos_only(&ip)) {
            arc_ref_stop(&ar);
        }
        if (arc_ref_stepping(&ar)) {
            /* ref: the last tick's reference of the same segment */
            double eps, vm, am;
            int i;
            (void)arc_ref_step(&ar, &ref, true);
            d->steps++;
            run++;
            d->longest_run = run > d->longest_run ? run : d->longest_run;
            /* arc_ref.h's bounds: eps = (2 nm + r 2^-28) / r */
            eps = (2.0 + (double)x.geom.radius / (1 << 28)) / (double)x.geom.radius;
            vm = hypot((double)x.vel[g.u], (double)x.vel[g.v]);
            am = hypot((double)x.acc[g.u], (double)x.acc[g.v]);
            TEST_ASSERT_INT64_WITHIN(1, x.geom.radius, ref.geom.radius);
            for (i = 0; i < 2; i++) {
                uint8_t a = i == 0 ? g.u : g.v;
                rel(d, ref.pos[a] - x.pos[a], eps * (double)x.geom.radius);
                rel(d, ref.vel[a] - x.vel[a], 2.0 + eps * vm);
                rel(d, ref.acc[a] - x.acc[a], 2.0 + eps * am);
                rel(d, ref.geom.tangent[a] - x.geom.tangent[a], 2.0 + eps * (double)(1 << 30));
                d->pos = max_abs(d->pos, ref.pos[a] - x.pos[a]);
                d->vel = max_abs(d->vel, ref.vel[a] - x.vel[a]);
            }
        } else {
            run = 0;
            ref = ch;
            (void)arc_ref_tick(&ar, &ref, &ch, &g, interp_tag(&ip), false, &ip);
            d->exact_ticks++;
            d->exact_differ += same(&ref, &x, g.u, g.v) ? 0u : 1u;
        }
    }
    TEST_ASSERT_TRUE(pushed == seg.n_seg && interp_idle(&ip)); /* the arc ran to its end */
    printf("arc r=%lld plane %d sense %d: %u chords, %u arc ticks, %u steps (run <= %u), %u exact "
           "(%u differ); max |dpos| %lld nm, |dvel| %lld nm/s; worst %.3f of the bound\n",
           (long long)radius, (int)plane, sense, seg.n_seg, d->ticks, d->steps, d->longest_run,
           d->exact_ticks, d->exact_differ, (long long)d->pos, (long long)d->vel, d->rel);
}

void setUp(void)
{
}

void tearDown(void)
{
}

static void check(const ar_stats_t *d)
{
    TEST_ASSERT_EQUAL_UINT32(0, d->exact_differ);
    TEST_ASSERT_TRUE(d->steps > d->ticks / 2u); /* the recurrence is in use */
    TEST_ASSERT_TRUE(d->longest_run <= ARC_REF_ROT_TICKS);
    TEST_ASSERT_TRUE(d->rel <= 1.0);
}

static void test_helix_recurrence_within_bound_and_fast_path_exact(void)
{
    ar_stats_t d;
    run_arc(DRIVE_PLANE_XY, 1, 5000000, 0, 20000000, 100, 0, &d);
    check(&d);
    TEST_ASSERT_TRUE(d.ticks > 15000u);
}

static void test_large_radius_chords_of_the_maximum_angle(void)
{
    ar_stats_t d;
    /* three chords of DRIVE_ARC_SEG_MAX_ANGLE (chord tolerance above the
     * radius), 1.9e9 nm at 150 mm/s: about 12000 ticks each, so the
     * recurrence is re-anchored many times inside one cruise phase */
    run_arc(DRIVE_PLANE_XY, 1, 1900000000, 0, 150000000, 1000000000, 3u * 65536u / 64u, &d);
    check(&d);
    TEST_ASSERT_TRUE(d.ticks > 35000u);
    TEST_ASSERT_TRUE(d.longest_run == ARC_REF_ROT_TICKS);
}

static void test_clockwise_the_other_planes_and_spirals(void)
{
    ar_stats_t d;
    run_arc(DRIVE_PLANE_XY, -1, 5000000, 0, 20000000, 100, 65536u / 4u, &d);
    check(&d);
    run_arc(DRIVE_PLANE_ZX, 1, 5000000, 0, 20000000, 100, 65536u / 4u, &d);
    check(&d);
    run_arc(DRIVE_PLANE_YZ, -1, 5000000, 0, 20000000, 100, 65536u / 4u, &d);
    check(&d);
    /* spirals (the radius steps along the chord), both ways */
    run_arc(DRIVE_PLANE_XY, 1, 5000000, 4000, 20000000, 100, 65536u / 4u, &d);
    check(&d);
    run_arc(DRIVE_PLANE_ZX, -1, 5000000, -4000, 20000000, 100, 65536u / 4u, &d);
    check(&d);
}

/* Arcs with centripetal accelerations the recurrence took only since
 * ARC_REF_AC_MAX was raised from 2^29 nm/s^2: the HIL bench circle (R 20 mm
 * at 10 m/min: 1.39 m/s^2) and 5 mm at 100 mm/s (2.0 m/s^2, 93 % of the
 * limit); 5 mm at 110 mm/s (2.42 m/s^2) stays on the exact path. Fails with
 * the old limit (no steps) and with a limit above INT32_MAX (steps at
 * 2.42 m/s^2, whose acceleration factor wraps). */
static void test_fast_arcs_up_to_the_acceleration_limit(void)
{
    ar_stats_t d;
    run_arc(DRIVE_PLANE_XY, 1, 20000000, 0, 166666667, 100, 0, &d);
    check(&d);
    TEST_ASSERT_TRUE(d.ticks > 7000u);
    /* (half a turn, much of it accelerating: fewer steps) */
    run_arc(DRIVE_PLANE_XY, -1, 5000000, 0, 100000000, 100, 65536u / 2u, &d);
    TEST_ASSERT_EQUAL_UINT32(0, d.exact_differ);
    TEST_ASSERT_TRUE(d.steps > d.ticks / 3u);
    TEST_ASSERT_TRUE(d.rel <= 1.0);
    TEST_ASSERT_TRUE(d.ticks > 1000u);
    /* 110 mm/s: 2.42 m/s^2, above the limit: the exact path only */
    run_arc(DRIVE_PLANE_XY, 1, 5000000, 0, 110000000, 100, 65536u / 2u, &d);
    TEST_ASSERT_EQUAL_UINT32(0, d.exact_differ);
    TEST_ASSERT_EQUAL_UINT32(0, d.steps);
    TEST_ASSERT_TRUE(d.ticks > 1000u);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_helix_recurrence_within_bound_and_fast_path_exact);
    RUN_TEST(test_large_radius_chords_of_the_maximum_angle);
    RUN_TEST(test_clockwise_the_other_planes_and_spirals);
    RUN_TEST(test_fast_arcs_up_to_the_acceleration_limit);
    return UNITY_END();
}
