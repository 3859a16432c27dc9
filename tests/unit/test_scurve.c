/*
 * Single-block profiles (scurve.c): closed forms against exact references.
 *
 * - wide arithmetic: sc_muldiv (native and portable paths) and the 128-bit
 *   square root against __int128 references;
 * - sc_dist against the analytic distance (double);
 * - sc_reach: never above the exact reachable speed (bisection on the
 *   analytic distance, double) and within 0.5 % of its speed gain;
 * - sc_plan on every case (full 7 phases, reduced without the acceleration
 *   plateau, peak speed not reached with and without plateau, accel-only,
 *   decel-only, constant speed, trapezoidal triangle and trapezoid): the
 *   profile integrated by brute force (explicit time stepping of the jerk,
 *   10^5 steps) ends at the block length with the exit speed, and never
 *   exceeds v_max, a_max or j_max; sc_eval agrees with the integration;
 * - time optimality: against the exact minimum-time solution found by
 *   bisection (same boundary conditions), the closed-form peak speed costs
 *   at most 0.5 % when v0 == v1 (3 % below 1 um, where the 1 nm/s speed
 *   resolution shows) and at most 5 % otherwise (set
 *   SCURVE_REPORT=1 for the measured worst cases).
 */
#include "fixmath.h"
#include "scurve.h"
#include "scurve_test.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

__extension__ typedef unsigned __int128 u128;

void setUp(void)
{
}

void tearDown(void)
{
}

static uint64_t rng_state = 88172645463325252ull;

static uint64_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

/* uniform in [lo, hi] on a log scale */
static int64_t rlog(int64_t lo, int64_t hi)
{
    double u = (double)(rng() >> 11) / 9007199254740992.0;
    return (int64_t)exp(log((double)lo) + u * (log((double)hi) - log((double)lo)));
}

static bool report(void)
{
    return getenv("SCURVE_REPORT") != NULL;
}

/* ---- exact references ------------------------------------------------------ */

static double dist_exact(double va, double vb, const sc_limits_t *l)
{
    double lo = fmin(va, vb), hi = fmax(va, vb), d = hi - lo, A = (double)l->a_max,
           J = (double)l->j_max;
    if (d <= 0) {
        return 0;
    }
    if (l->shape == SC_SHAPE_TRAPEZOID) {
        return (lo + hi) * d / (2 * A);
    }
    if (d >= A * A / J) {
        return (lo + hi) / 2 * (d / A + A / J);
    }
    return (lo + hi) * sqrt(d / J);
}

static double seg_time_exact(double d, const sc_limits_t *l)
{
    double A = (double)l->a_max, J = (double)l->j_max;
    if (d <= 0) {
        return 0;
    }
    if (l->shape == SC_SHAPE_TRAPEZOID) {
        return d / A;
    }
    return (d >= A * A / J) ? d / A + A / J : 2 * sqrt(d / J);
}

static double reach_exact(double v, double d, const sc_limits_t *l)
{
    double lo = v, hi = (double)l->v_max;
    int i;
    if (dist_exact(v, hi, l) <= d) {
        return hi;
    }
    for (i = 0; i < 200; i++) {
        double m = 0.5 * (lo + hi);
        if (dist_exact(v, m, l) <= d) {
            lo = m;
        } else {
            hi = m;
        }
    }
    return lo;
}

/* minimum time of a block: best peak speed by bisection on the exact
 * distance equation */
static double time_optimal(double len, double v0, double v1, const sc_limits_t *l)
{
    double vm = fmax(v0, v1), lo = vm, hi = (double)l->v_max, vp;
    int i;
    if (dist_exact(v0, hi, l) + dist_exact(hi, v1, l) <= len) {
        vp = hi;
    } else {
        for (i = 0; i < 200; i++) {
            double m = 0.5 * (lo + hi);
            if (dist_exact(v0, m, l) + dist_exact(m, v1, l) <= len) {
                lo = m;
            } else {
                hi = m;
            }
        }
        vp = lo;
    }
    return seg_time_exact(vp - v0, l) + seg_time_exact(vp - v1, l) +
           (len - dist_exact(v0, vp, l) - dist_exact(vp, v1, l)) / vp;
}

/* brute-force integration of the profile's jerk sequence */
typedef struct {
    double s, v, vmax, amax, jmax, a;
} integ_t;

static integ_t integrate(const sc_profile_t *p, bool trap, long steps)
{
    integ_t r = {0, (double)p->v0, (double)p->v0, 0, 0, 0};
    int ph;
    double total = (double)p->total_ns * 1e-9, dt = total / (double)steps;
    for (ph = 0; ph < SC_PHASES; ph++) {
        double T = (double)p->t_ns[ph] * 1e-9, t = 0, j = (double)p->jerk[ph];
        if (trap) {
            r.a = (double)p->start[ph].a_q16 / 65536.0;
        }
        if (fabs(j) > r.jmax && T > 0) {
            r.jmax = fabs(j);
        }
        while (t < T) {
            double h = fmin(dt, T - t);
            /* explicit steps, midpoint for the position */
            double a1 = r.a + j * h;
            double v1 = r.v + 0.5 * (r.a + a1) * h;
            r.s += 0.5 * (r.v + v1) * h;
            r.v = v1;
            r.a = a1;
            t += h;
            if (fabs(r.a) > r.amax) {
                r.amax = fabs(r.a);
            }
            if (r.v > r.vmax) {
                r.vmax = r.v;
            }
        }
    }
    return r;
}

/* ---- tests ---------------------------------------------------------------- */

static void test_muldiv_and_sqrt(void)
{
    int i;
    TEST_ASSERT_EQUAL_INT64(0, sc_muldiv(0, 5, 3));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, sc_muldiv(5, 5, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, sc_muldiv(INT64_MAX, INT64_MAX, 1));
    TEST_ASSERT_EQUAL_INT64(3, sc_muldiv_ceil(5, 1, 2));
    for (i = 0; i < 200000; i++) {
        int64_t a = (int64_t)(rng() >> (1 + rng() % 63)), b = (int64_t)(rng() >> (1 + rng() % 63));
        int64_t c = (int64_t)(rng() >> (1 + rng() % 63)) | 1;
        u128 q = (u128)(uint64_t)a * (uint64_t)b / (uint64_t)c;
        int64_t ref = q > (u128)INT64_MAX ? INT64_MAX : (int64_t)q;
        u128 x = ((u128)rng() << 64 | rng()) >> (rng() % 128);
        fx_u128_t xw = {(uint64_t)(x >> 64), (uint64_t)x};
        uint64_t r = fx_isqrt128(xw);
        TEST_ASSERT_EQUAL_INT64(ref, sc_muldiv(a, b, c));
        TEST_ASSERT_EQUAL_INT64(ref, sc_muldiv_portable(a, b, c));
        /* the ceiling (both the 64-bit and the 128-bit path) */
        TEST_ASSERT_EQUAL_INT64((ref < INT64_MAX && a > 0 && b > 0 &&
                                 (u128)(uint64_t)a * (uint64_t)b % (uint64_t)c != 0)
                                    ? ref + 1
                                    : ref,
                                sc_muldiv_ceil(a, b, c));
        TEST_ASSERT_TRUE((u128)r * r <= x);
        TEST_ASSERT_TRUE(r == UINT64_MAX || (u128)(r + 1) * (r + 1) > x);
    }
}

static sc_limits_t random_limits(uint8_t shape)
{
    sc_limits_t l;
    l.shape = shape;
    l.v_max = rlog(10000, SC_V_LIMIT);
    l.a_max = rlog(1000000, 100000000000);
    /* a/j between 1 ms and 3 s */
    l.j_max = l.a_max * 1000 / rlog(1, 3000);
    if (l.j_max > SC_J_LIMIT) {
        l.j_max = SC_J_LIMIT;
    }
    return l;
}

static void test_dist_matches_closed_form(void)
{
    int i;
    for (i = 0; i < 100000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i & 1));
        int64_t va = (int64_t)(rng() % (uint64_t)l.v_max),
                vb = (int64_t)(rng() % (uint64_t)l.v_max);
        double ref = dist_exact((double)va, (double)vb, &l);
        int64_t d = sc_dist(va, vb, &l);
        TEST_ASSERT_TRUE_MESSAGE((double)d >= ref - 1e-6 * ref - 1, "sc_dist below exact");
        TEST_ASSERT_TRUE_MESSAGE((double)d <= ref + 1e-6 * ref + 3, "sc_dist above exact");
    }
}

static void test_reach_is_tight_lower_bound(void)
{
    int i;
    double worst = 1;
    for (i = 0; i < 100000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 3 == 0));
        int64_t v = (rng() & 3) == 0 ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        int64_t d = rlog(1, 1000000000);
        int64_t r = sc_reach(v, d, &l);
        double re = reach_exact((double)v, (double)d, &l);
        TEST_ASSERT_TRUE(r >= v && r <= l.v_max);
        TEST_ASSERT_TRUE_MESSAGE((double)r <= re + 1e-9 * re + 1, "sc_reach above exact");
        TEST_ASSERT_TRUE_MESSAGE(sc_dist(v, r, &l) <= d + 3, "sc_reach infeasible");
        if (re - (double)v > 1000) {
            double gain = ((double)r - (double)v) / (re - (double)v);
            if (gain < worst) {
                worst = gain;
            }
            if (gain < 0.995) {
                printf("v=%lld d=%lld A=%lld J=%lld vmax=%lld shape=%d r=%lld re=%.1f\n",
                       (long long)v, (long long)d, (long long)l.a_max, (long long)l.j_max,
                       (long long)l.v_max, l.shape, (long long)r, re);
            }
            TEST_ASSERT_TRUE_MESSAGE(gain >= 0.995, "sc_reach loses more than 0.5 %");
        }
    }
    if (report()) {
        printf("sc_reach worst speed gain vs exact: %.6f\n", worst);
    }
}

/* one profile: checks against integration and limits, returns time ratio to
 * the optimum */
static double check_profile(int64_t len, int64_t v0, int64_t v1, const sc_limits_t *l)
{
    sc_profile_t p;
    integ_t r;
    double tol_s, tol_v;
    int k;
    bool trap = l->shape == SC_SHAPE_TRAPEZOID;

    sc_plan(&p, len, v0, v1, l);
    r = integrate(&p, trap, 100000);
    tol_s = 1e-6 * (double)len + 2.0;
    /* speeds: integration error, plus the evaluation's time resolution
     * (2^-40 s: a_max * 0.001 ns) */
    tol_v = 1e-6 * (double)l->v_max + 2.0 + (double)l->a_max * 1e-12;
    if (fabs(r.s - (double)len) > tol_s) {
        printf("len=%lld v0=%lld v1=%lld A=%lld J=%lld vmax=%lld shape=%d: s=%.3f v=%.3f "
               "s_end=%.3f\n",
               (long long)len, (long long)v0, (long long)v1, (long long)l->a_max,
               (long long)l->j_max, (long long)l->v_max, l->shape, r.s, r.v,
               (double)p.s_end_q16 / 65536.0);
    }
    TEST_ASSERT_TRUE_MESSAGE(fabs(r.s - (double)len) <= tol_s, "integrated distance != len");
    TEST_ASSERT_TRUE_MESSAGE(fabs((double)p.s_end_q16 / 65536.0 - (double)len) <= tol_s,
                             "realised distance != len");
    /* exit speed: phase times are whole ns, so a speed change is realised
     * to within a_max * 1 ns per phase */
    TEST_ASSERT_TRUE_MESSAGE(fabs(r.v - (double)v1) <=
                                 1e-6 * (double)l->v_max + 2.0 + 3e-9 * (double)l->a_max,
                             "exit speed");
    TEST_ASSERT_TRUE_MESSAGE(r.vmax <= (double)l->v_max * (1 + 1e-9) + 1, "v_max exceeded");
    TEST_ASSERT_TRUE_MESSAGE(r.amax <= (double)l->a_max * (1 + 1e-9) + 1, "a_max exceeded");
    if (!trap) {
        TEST_ASSERT_TRUE_MESSAGE(r.jmax <= (double)l->j_max, "j_max exceeded");
        TEST_ASSERT_TRUE_MESSAGE(fabs(r.a) <= 1e-6 * (double)l->a_max + 1, "a != 0 at the end");
    }
    /* closed-form evaluation against the same integration at a few times */
    for (k = 1; k < 8; k++) {
        sc_state_t st;
        sc_profile_t cut = p;
        int64_t t = p.total_ns * k / 8;
        integ_t ri;
        int ph;
        /* integrate the profile truncated at t */
        for (ph = 0; ph < SC_PHASES; ph++) {
            int64_t before = 0;
            int q;
            for (q = 0; q < ph; q++) {
                before += p.t_ns[q];
            }
            if (before >= t) {
                cut.t_ns[ph] = 0;
            } else if (before + p.t_ns[ph] > t) {
                cut.t_ns[ph] = t - before;
            }
        }
        cut.total_ns = t;
        ri = integrate(&cut, trap, 20000);
        sc_eval(&p, t, &st);
        if (fabs((double)st.v_q16 / 65536.0 - ri.v) > tol_v) {
            printf("k=%d t=%lld len=%lld v0=%lld v1=%lld A=%lld J=%lld vmax=%lld shape=%d: "
                   "eval v=%.3f s=%.3f integ v=%.3f s=%.3f\n",
                   k, (long long)t, (long long)len, (long long)v0, (long long)v1,
                   (long long)l->a_max, (long long)l->j_max, (long long)l->v_max, l->shape,
                   (double)st.v_q16 / 65536.0, (double)st.s_q16 / 65536.0, ri.v, ri.s);
        }
        TEST_ASSERT_TRUE_MESSAGE(fabs((double)st.s_q16 / 65536.0 - ri.s) <= tol_s,
                                 "sc_eval position vs integration");
        TEST_ASSERT_TRUE_MESSAGE(fabs((double)st.v_q16 / 65536.0 - ri.v) <= tol_v,
                                 "sc_eval speed vs integration");
    }
    {
        /* ratio to the optimum; the 1 ns rounding of each phase is allowed */
        double opt = time_optimal((double)len, (double)v0, (double)v1, l) * 1e9;
        double t_ns = (double)p.total_ns;
        if (t_ns + 7.0 < opt * (1 - 1e-6)) {
            printf("len=%lld v0=%lld v1=%lld A=%lld J=%lld vmax=%lld shape=%d t=%.1f opt=%.1f\n",
                   (long long)len, (long long)v0, (long long)v1, (long long)l->a_max,
                   (long long)l->j_max, (long long)l->v_max, l->shape, t_ns, opt);
        }
        TEST_ASSERT_TRUE_MESSAGE(t_ns + 7.0 >= opt * (1 - 1e-6), "faster than the optimum");
        return (t_ns - 7.0 > opt) ? (t_ns - 7.0) / opt : 1.0;
    }
}

/* At-rest S-curve: the shape follows the speeds. From or to rest every
 * function is the S-curve's, between two moving speeds the trapezoid's,
 * bit for bit (the other two shapes are unchanged by it). */
static void test_at_rest_follows_speeds(void)
{
    sc_limits_t s = {100000000, 2000000000, 50000000000, SC_SHAPE_SCURVE};
    sc_limits_t t = s, r = s;
    sc_profile_t pr, ps, pt;
    static const int64_t v[][2] = {{0, 0}, {0, 30000000}, {60000000, 0}, {1, 0}};
    int k;

    t.shape = SC_SHAPE_TRAPEZOID;
    r.shape = SC_SHAPE_SCURVE_AT_REST;
    /* reach: from rest the S-curve, from any speed > 0 the trapezoid */
    TEST_ASSERT_EQUAL_INT64(sc_reach(0, 1000000, &s), sc_reach(0, 1000000, &r));
    TEST_ASSERT_TRUE(sc_reach(0, 1000000, &r) < sc_reach(0, 1000000, &t));
    TEST_ASSERT_EQUAL_INT64(sc_reach(5000000, 1000000, &t), sc_reach(5000000, 1000000, &r));
    TEST_ASSERT_TRUE(sc_reach(1, 1000000, &r) >= sc_reach(0, 1000000, &r)); /* monotone */
    /* distance: S-curve when the lower speed is 0 */
    TEST_ASSERT_EQUAL_INT64(sc_dist(40000000, 0, &s), sc_dist(40000000, 0, &r));
    TEST_ASSERT_EQUAL_INT64(sc_dist(10000000, 40000000, &t), sc_dist(10000000, 40000000, &r));
    TEST_ASSERT_TRUE(sc_dist(40000000, 0, &r) > sc_dist(40000000, 0, &t));
    /* block: S-curve if it starts or ends at rest */
    for (k = 0; k < 4; k++) {
        sc_plan(&pr, 30000000, v[k][0], v[k][1], &r);
        sc_plan(&ps, 30000000, v[k][0], v[k][1], &s);
        TEST_ASSERT_EQUAL_MEMORY(&ps, &pr, sizeof(pr));
        check_profile(30000000, v[k][0], v[k][1], &s);
    }
    sc_plan(&pr, 30000000, 20000000, 50000000, &r);
    sc_plan(&pt, 30000000, 20000000, 50000000, &t);
    TEST_ASSERT_EQUAL_MEMORY(&pt, &pr, sizeof(pr));
    TEST_ASSERT_EQUAL_INT64(0, pr.jerk[0]);
    sc_plan(&pr, 30000000, 0, 50000000, &r);
    TEST_ASSERT_TRUE(pr.jerk[0] > 0 && pr.t_ns[0] > 0);
}

static void test_named_cases(void)
{
    sc_limits_t s = {100000000, 2000000000, 50000000000, SC_SHAPE_SCURVE}; /* 100 mm/s, 2 m/s^2 */
    sc_limits_t t = {100000000, 2000000000, 0, SC_SHAPE_TRAPEZOID};
    sc_profile_t p;

    /* full 7 phases: 100 mm rest to rest */
    sc_plan(&p, 100000000, 0, 0, &s);
    TEST_ASSERT_TRUE(p.t_ns[0] > 0 && p.t_ns[1] > 0 && p.t_ns[3] > 0 && p.t_ns[5] > 0);
    TEST_ASSERT_EQUAL_INT64(40000000, p.t_ns[0]); /* A/J = 40 ms */
    TEST_ASSERT_EQUAL_INT64(10000000, p.t_ns[1]); /* dv/A - A/J = 10 ms */
    TEST_ASSERT_INT64_WITHIN(5, 910000000, p.t_ns[3]);
    TEST_ASSERT_INT64_WITHIN(5, 1090000000, p.total_ns);
    check_profile(100000000, 0, 0, &s);
    /* reduced: A not reached (dv = 50 mm/s < A^2/J = 80 mm/s), cruise */
    s.v_max = 50000000;
    sc_plan(&p, 100000000, 0, 0, &s);
    TEST_ASSERT_EQUAL_INT64(0, p.t_ns[1]);
    TEST_ASSERT_EQUAL_INT64(31622776, p.t_ns[0]); /* sqrt(dv/J) */
    TEST_ASSERT_TRUE(p.t_ns[3] > 0);
    check_profile(100000000, 0, 0, &s);
    /* feed not reached, with plateau (long enough) and without (short) */
    s.v_max = 1000000000;
    sc_plan(&p, 20000000, 0, 0, &s);
    TEST_ASSERT_TRUE(p.vp < 1000000000 && p.t_ns[1] > 0);
    check_profile(20000000, 0, 0, &s);
    sc_plan(&p, 100000, 0, 0, &s); /* 0.1 mm */
    TEST_ASSERT_TRUE(p.t_ns[1] == 0 && p.vp < 80000000);
    check_profile(100000, 0, 0, &s);
    /* accel-only, decel-only, constant speed */
    s.v_max = 100000000;
    check_profile(30000000, 0, 100000000, &s);
    check_profile(30000000, 100000000, 0, &s);
    sc_plan(&p, 1000000, 20000000, 20000000, &s);
    check_profile(1000000, 20000000, 20000000, &s);
    /* trapezoid: triangle and trapezoid, exact peak */
    sc_plan(&p, 1000000, 0, 0, &t); /* 1 mm at 2 m/s^2: vp = sqrt(A L) = 44.72 mm/s */
    TEST_ASSERT_INT64_WITHIN(3, 44721359, p.vp);
    TEST_ASSERT_EQUAL_INT64(0, p.t_ns[0]);
    TEST_ASSERT_INT64_WITHIN(2, 44721359, p.total_ns); /* 2 sqrt(L/A) = 44.7 ms */
    check_profile(1000000, 0, 0, &t);
    sc_plan(&p, 100000000, 0, 0, &t);
    TEST_ASSERT_INT64_WITHIN(5, 1050000000, p.total_ns); /* L/v + v/A */
    check_profile(100000000, 0, 0, &t);
}

static void test_random_profiles_and_optimality(void)
{
    int i;
    double worst_sym = 1, worst = 1;
    for (i = 0; i < 1500; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 4 == 0));
        int64_t len = rlog(1, 1000000000);
        int64_t v0 = (rng() & 1) ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        int64_t v1 = (i % 3 == 0) ? v0 : (int64_t)(rng() % (uint64_t)l.v_max);
        double ratio;
        /* feasible boundary speeds, as the planner guarantees */
        if (v1 > v0) {
            v1 = sc_reach(v0, len, &l) < v1 ? sc_reach(v0, len, &l) : v1;
        } else {
            v0 = sc_reach(v1, len, &l) < v0 ? sc_reach(v1, len, &l) : v0;
        }
        ratio = check_profile(len, v0, v1, &l);
        if (v0 == v1) {
            worst_sym = fmax(worst_sym, ratio);
            if (ratio > 1.005) {
                printf("len=%lld v=%lld A=%lld J=%lld vmax=%lld shape=%d ratio=%.6f\n",
                       (long long)len, (long long)v0, (long long)l.a_max, (long long)l.j_max,
                       (long long)l.v_max, l.shape, ratio);
            }
            /* sub-micrometre blocks: 1 nm/s speed resolution costs up to ~2 % */
            TEST_ASSERT_TRUE_MESSAGE(ratio <= (len >= 1000 ? 1.005 : 1.03),
                                     "symmetric block more than 0.5 % slow");
        } else {
            worst = fmax(worst, ratio);
            TEST_ASSERT_TRUE_MESSAGE(ratio <= 1.05, "block more than 5 % slow");
        }
    }
    if (report()) {
        printf("time / optimum, worst: v0 == v1 %.6f, v0 != v1 %.6f\n", worst_sym, worst);
    }
}

/* the estimate-and-check reach against the bracketing path it replaces
 * (both lower bounds; the estimate within 0.03 % of its speed gain or
 * better), sc_reach_pre with the cached A^2/J, and the wide helpers */
static void test_reach_paths_and_helpers(void)
{
    int i, differ = 0;
    for (i = 0; i < 50000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 3));
        int64_t v = (rng() & 1) ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        int64_t d = rlog(1, 1000000000), q, qc, r, rb;
        u128 aa = (u128)l.a_max * (u128)l.a_max;
        sc_limits_aaj(&l, &q, &qc);
        TEST_ASSERT_EQUAL_INT64((int64_t)(aa / (u128)l.j_max), q);
        TEST_ASSERT_EQUAL_INT64(q + (aa % (u128)l.j_max != 0 ? 1 : 0), qc);
        r = sc_reach(v, d, &l);
        TEST_ASSERT_EQUAL_INT64(r, sc_reach_pre(v, d, &l, q, qc));
        rb = sc_reach_bracket(v, d, &l);
        TEST_ASSERT_TRUE_MESSAGE(sc_dist(v, rb, &l) <= d + 3, "bracket reach infeasible");
        TEST_ASSERT_TRUE_MESSAGE(r - v >= (rb - v) - (rb - v) / 3000 - 3,
                                 "estimate loses against the bracket");
        differ += (r != rb) ? 1 : 0;
    }
    printf("sc_reach estimate != bracket in %d of 50000 cases\n", differ);
    TEST_ASSERT_TRUE(differ > 1000); /* the two paths are distinct */
    for (i = 0; i < 100000; i++) {
        uint64_t a = rng() >> (rng() % 64), b = rng() >> (rng() % 64);
        uint64_t c = rng() >> (rng() % 64), e = rng() >> (rng() % 64);
        u128 x = (u128)a * b, y = (u128)c * e;
        int64_t sa = (int64_t)(a >> 1), sb = (int64_t)(b >> 1);
        TEST_ASSERT_EQUAL_INT(x < y ? -1 : (x > y ? 1 : 0), sc_cmp_products(a, b, c, e));
        TEST_ASSERT_EQUAL_INT(0, sc_cmp_products(a, b, b, a));
        TEST_ASSERT_EQUAL_INT64(sc_muldiv(sa, sb, 1), sc_mul_sat(sa, sb));
    }
    TEST_ASSERT_EQUAL_INT64(0, sc_mul_sat(-5, 7));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, sc_mul_sat(INT64_MAX, 2));
}

/* sc_plan builds the decel phases once and moves them by the cruise end
 * point: every start state is still the previous phase evaluated at its
 * full duration (acceleration set, not chained, in trapezoidal mode) */
static void test_plan_states_chain(void)
{
    int i, ph;
    for (i = 0; i < 30000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 3));
        int64_t len = rlog(1, 1000000000);
        int64_t v0 = (rng() & 3) == 0 ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        int64_t v1 = (rng() & 3) == 0 ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        sc_profile_t p;
        sc_state_t e;
        v1 = (rng() & 1) ? sc_reach(v0, len, &l) : v1;
        if (sc_dist(v0, v1, &l) > len) {
            v1 = v0;
        }
        sc_plan(&p, len, v0, v1, &l);
        for (ph = 0; ph + 1 < SC_PHASES; ph++) {
            sc_eval_phase(&p, ph, p.t_ns[ph], &e);
            TEST_ASSERT_EQUAL_INT64(e.s_q16, p.start[ph + 1].s_q16);
            TEST_ASSERT_EQUAL_INT64(e.v_q16, p.start[ph + 1].v_q16);
            if (p.jerk[0] != 0 || p.jerk[6] != 0) { /* S-curve: continuous */
                TEST_ASSERT_EQUAL_INT64(e.a_q16, p.start[ph + 1].a_q16);
            }
        }
        sc_eval_phase(&p, SC_PHASES - 1, p.t_ns[SC_PHASES - 1], &e);
        TEST_ASSERT_EQUAL_INT64(e.s_q16, p.s_end_q16);
    }
}

/* The reduced S-curve distance (speed change below A^2/J) is
 * ceil(sqrt(ceil(S^2 dv / J))) with S = va + vb when S^2 fits int64 (one
 * division), else through the half-segment time: it must be an upper bound
 * of the exact S sqrt(dv / J), at most 2 nm above it on the one-division
 * path (checked with exact
 * 128-bit integers). */
static void test_dist_reduced_exact_bound(void)
{
    int i, small = 0;
    const uint64_t saved = rng_state; /* own sequence: later tests unchanged */

    rng_state = 0x9E3779B97F4A7C15ull;
    for (i = 0; i < 200000; i++) {
        sc_limits_t l = random_limits(SC_SHAPE_SCURVE);
        int64_t q = sc_muldiv(l.a_max, l.a_max, l.j_max);
        int64_t va = (int64_t)(rng() % (uint64_t)l.v_max), dv, vb, d;
        u128 s2dv;
        bool one;
        dv = 1 + (int64_t)(rng() % (uint64_t)(q > 1 ? q - 1 : 1));
        if (dv >= q || va + dv > SC_V_LIMIT) {
            continue;
        }
        vb = va + dv;
        d = sc_dist(vb, va, &l);
        s2dv = (u128)(uint64_t)(va + vb) * (uint64_t)(va + vb) * (u128)(uint64_t)dv;
        /* d >= S sqrt(dv / J)  <=>  d^2 J >= S^2 dv */
        TEST_ASSERT_TRUE((u128)(uint64_t)d * (uint64_t)d * (u128)(uint64_t)l.j_max >= s2dv);
        one = va + vb <= (int64_t)3037000499 &&
              (s2dv + (u128)(uint64_t)(l.j_max - 1)) / (u128)(uint64_t)l.j_max < (u128)INT64_MAX;
        TEST_ASSERT_TRUE(!one || d < 2 ||
                         (u128)(uint64_t)(d - 1) * (uint64_t)(d - 1) * (u128)(uint64_t)l.j_max <
                             s2dv);
        small += one;
    }
    rng_state = saved;
    TEST_ASSERT_TRUE(small > 1000);
}

/* the reach's one-comparison distance checks (sc_test_dist_fits) give the
 * same speeds and profiles as sc_dist deciding every check: random
 * distances and distances at the boundary (sc_dist(v, w) - 1 .. + 1 with
 * v_max = w, where the exact comparison decides between equal and one
 * nm short), every shape, from rest and from speed */
static void test_dist_fits_matches_dist(void)
{
    int i, k, reached = 0;
    for (i = 0; i < 60000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 3));
        int64_t v = (i & 2) ? 0 : (int64_t)(rng() % (uint64_t)l.v_max), d, w, r_on, r_off;
        sc_profile_t p_on, p_off;
        if (i & 4) {
            w = v + 1 + (int64_t)(rng() % (uint64_t)(l.v_max - v));
            l.v_max = w;
            d = sc_dist(v, w, &l) - 1 + (int64_t)(rng() % 3);
        } else {
            d = rlog(1, 1000000000);
        }
        for (k = 0; k < 2; k++) {
            int64_t dd = (k == 0) ? d : d / 3;
            sc_test_dist_fits(false);
            r_off = sc_reach(v, dd, &l);
            sc_plan(&p_off, dd, v, v / 2, &l);
            sc_test_dist_fits(true);
            r_on = sc_reach(v, dd, &l);
            sc_plan(&p_on, dd, v, v / 2, &l);
            TEST_ASSERT_EQUAL_INT64(r_off, r_on);
            TEST_ASSERT_EQUAL_INT64(p_off.total_ns, p_on.total_ns);
            TEST_ASSERT_EQUAL_INT64(p_off.s_end_q16, p_on.s_end_q16);
            TEST_ASSERT_EQUAL_INT64(p_off.vp, p_on.vp);
            reached += (v > 0 && r_on == l.v_max && sc_dist(v, l.v_max, &l) == dd) ? 1 : 0;
        }
    }
    printf("reach exactly at the cap's distance: %d cases\n", reached);
    TEST_ASSERT_TRUE(reached > 500); /* the equality boundary is exercised */
    /* exact equality D = (lo + hi) sqrt(dv / J) = d: J = dv g^2 and g
     * divides lo + hi, so D = (lo + hi) / g; the cap is reachable in d and
     * not in d - 1 */
    for (i = 0; i < 20000; i++) {
        int64_t g = 1 + (int64_t)(rng() % 3000), dv = rlog(1, 10000000), lo, hi, d;
        sc_limits_t l;
        l.shape = (uint8_t)SC_SHAPE_SCURVE;
        l.j_max = dv * g * g;
        if (l.j_max < SC_J_MIN || l.j_max > SC_J_LIMIT) {
            continue;
        }
        l.a_max = SC_A_LIMIT; /* A^2 / J > dv: the reduced case */
        if ((u128)l.a_max * (u128)l.a_max <= (u128)l.j_max * (u128)(dv + 1)) {
            continue;
        }
        lo = g * (1 + (int64_t)(rng() % (uint64_t)(200000000 / g))); /* lo + hi */
        if (((lo - dv) & 1) != 0) {
            lo += g;
        }
        if (((lo - dv) & 1) != 0 || lo <= dv) {
            continue;
        }
        lo = (lo - dv) / 2;
        hi = lo + dv;
        l.v_max = hi;
        d = (lo + hi) / g;
        for (k = 0; k < 2; k++) {
            sc_test_dist_fits(k == 0);
            TEST_ASSERT_EQUAL_INT64(d, sc_dist(lo, hi, &l));
            TEST_ASSERT_EQUAL_INT64(hi, sc_reach(lo, d, &l));
            TEST_ASSERT_TRUE(sc_reach(lo, d - 1, &l) < hi);
        }
        sc_test_dist_fits(true);
    }
}

/* the reduced S-curve reach's closed form (cube root from rest, Pade and
 * one Newton step from v > 0): where it applies, feasible by the exact
 * distance (sc_dist <= d, no slack), never above the exact reach, its gain
 * at least (1 - 2^-14 - 2e-5) of the exact gain minus 3 nm/s, and what
 * sc_reach returns; the planner's bench chords (0.2 mm, J 1.2e12 nm/s^3)
 * among the cases */
static void test_reach_closed_form(void)
{
    int i, used = 0, used_v = 0;
    double worst = 1;
    for (i = 0; i < 200000; i++) {
        sc_limits_t l = random_limits(SC_SHAPE_SCURVE);
        int64_t v, d, rc;
        double re;
        if (i % 5 == 0) { /* the bench's chords */
            l.v_max = 50000000;
            l.a_max = 10000000000 + (int64_t)(rng() % 7320000000u);
            l.j_max = l.a_max * 100;
            d = 200000 + (int64_t)(rng() % 10000);
        } else {
            d = rlog(8192, 2147483647);
        }
        v = (i % 4 == 0) ? 0 : (int64_t)(rng() % (uint64_t)l.v_max);
        {
            /* the per-block constants give sc_reach_pre's result, with the
             * exact A^2/J and with a lower bound of it */
            int64_t q, qc, ql;
            sc_reach_k_t rk;
            sc_limits_aaj(&l, &q, &qc);
            sc_reach_k_init(&rk, d, &l, q, qc);
            TEST_ASSERT_EQUAL_INT64(sc_reach_pre(v, d, &l, q, qc), sc_reach_k(v, &l, &rk));
            ql = q - (int64_t)(rng() % 33);
            sc_reach_k_init(&rk, d, &l, ql, -1);
            TEST_ASSERT_EQUAL_INT64(sc_reach_pre(v, d, &l, ql, -1), sc_reach_k(v, &l, &rk));
        }
        rc = sc_test_reach_closed_only(v, d, &l);
        if (rc < 0) {
            continue;
        }
        used++;
        used_v += (v > 0) ? 1 : 0;
        re = reach_exact((double)v, (double)d, &l);
        TEST_ASSERT_TRUE(rc >= v && rc <= l.v_max);
        TEST_ASSERT_TRUE_MESSAGE(sc_dist(v, rc, &l) <= d, "closed-form reach infeasible");
        TEST_ASSERT_TRUE_MESSAGE((double)rc <= re + 1e-9 * re + 1, "closed-form reach above exact");
        TEST_ASSERT_EQUAL_INT64(rc, sc_reach(v, d, &l));
        if (re - (double)v > 1000) {
            double gain = ((double)rc - (double)v) / (re - (double)v);
            worst = fmin(worst, gain);
            TEST_ASSERT_TRUE_MESSAGE((double)(rc - v) >=
                                         (re - (double)v) * (1 - 1.0 / 16384 - 2e-5) - 3,
                                     "closed-form reach loses more than its margin");
        }
    }
    printf("closed-form reach used in %d of 200000 cases (%d from v > 0), worst gain %.7f\n", used,
           used_v, worst);
    TEST_ASSERT_TRUE(used > 40000 && used_v > 20000);
}

/* a cruise-only block (entered and left at its cap): cruise time and end
 * distance without a 128-bit product (one 64/32 division, the exact
 * residual, a multiply for the division by 10^9) equal the multiply-divide
 * forms t3 = round(len NS / v), s_end = floor(v 2^16 t3 / NS) */
static void test_cruise_block_time_and_distance(void)
{
    int i;
    for (i = 0; i < 200000; i++) {
        sc_limits_t l = random_limits((uint8_t)(i % 3));
        int64_t len = rlog(1, (i % 4 == 0) ? ((int64_t)1 << 40) : 10000000000), t3;
        sc_profile_t p;
        l.v_max = (i % 7 == 0) ? SC_V_LIMIT - (int64_t)(rng() % 1000) : rlog(1000, SC_V_LIMIT);
        sc_plan(&p, len, l.v_max, l.v_max, &l);
        t3 = (sc_muldiv(2 * len, 1000000000, l.v_max) + 1) / 2;
        TEST_ASSERT_EQUAL_INT64(t3, p.t_ns[3]);
        TEST_ASSERT_EQUAL_INT64(t3, p.total_ns);
        TEST_ASSERT_EQUAL_INT64(sc_muldiv(l.v_max * 65536, t3, 1000000000), p.s_end_q16);
        TEST_ASSERT_EQUAL_INT64(p.s_end_q16, p.start[6].s_q16);
        {
            /* the planner's form with the kept reciprocal of the speed */
            sc_profile_t r;
            int ph;
            sc_plan_cruise_rec(&r, len, l.v_max, &l, sc_cruise_recip(l.v_max));
            TEST_ASSERT_EQUAL_INT64(p.total_ns, r.total_ns);
            TEST_ASSERT_EQUAL_INT64(p.s_end_q16, r.s_end_q16);
            TEST_ASSERT_EQUAL_INT64(p.vp, r.vp);
            for (ph = 0; ph < SC_PHASES; ph++) {
                TEST_ASSERT_EQUAL_INT64(p.t_ns[ph], r.t_ns[ph]);
                TEST_ASSERT_EQUAL_INT64(p.jerk[ph], r.jerk[ph]);
                TEST_ASSERT_EQUAL_INT64(p.j6_q16[ph], r.j6_q16[ph]);
                TEST_ASSERT_EQUAL_INT64(p.start[ph].s_q16, r.start[ph].s_q16);
                TEST_ASSERT_EQUAL_INT64(p.start[ph].v_q16, r.start[ph].v_q16);
                TEST_ASSERT_EQUAL_INT64(p.start[ph].a_q16, r.start[ph].a_q16);
            }
        }
    }
}

/* fixmath's fx_udiv64by32 (appended for the planner): floor(n / d) when it
 * fits 32 bits, UINT32_MAX otherwise, against the host's division */
static void test_udiv64by32(void)
{
    int i;
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_udiv64by32(5, 0));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_udiv64by32((uint64_t)7 << 32, 7));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_udiv64by32(UINT64_MAX, UINT32_MAX));
    TEST_ASSERT_EQUAL_UINT32(4294967295u, fx_udiv64by32(UINT64_MAX - UINT32_MAX - 1u, UINT32_MAX));
    TEST_ASSERT_EQUAL_UINT32(
        4294967294u,
        fx_udiv64by32(((uint64_t)UINT32_MAX << 32) - 2u * (uint64_t)UINT32_MAX, UINT32_MAX));
    for (i = 0; i < 1000000; i++) {
        uint32_t d = (uint32_t)(rng() >> (32 + rng() % 32));
        uint64_t n = rng() >> (rng() % 64);
        if (d == 0u) {
            d = 1u;
        }
        if ((n >> 32) >= d) {
            TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_udiv64by32(n, d));
            n %= (uint64_t)d << 32;
        }
        TEST_ASSERT_EQUAL_UINT32((uint32_t)(n / d), fx_udiv64by32(n, d));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_muldiv_and_sqrt);
    RUN_TEST(test_dist_matches_closed_form);
    RUN_TEST(test_dist_reduced_exact_bound);
    RUN_TEST(test_reach_is_tight_lower_bound);
    RUN_TEST(test_named_cases);
    RUN_TEST(test_at_rest_follows_speeds);
    RUN_TEST(test_random_profiles_and_optimality);
    RUN_TEST(test_reach_paths_and_helpers);
    RUN_TEST(test_plan_states_chain);
    RUN_TEST(test_dist_fits_matches_dist);
    RUN_TEST(test_reach_closed_form);
    RUN_TEST(test_cruise_block_time_and_distance);
    RUN_TEST(test_udiv64by32);
    return UNITY_END();
}
