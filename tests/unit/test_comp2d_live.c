/*
 * The 2-D map in the tick (comp2d_live.h): main publishes the map's
 * linearisation, the tick adds k + gx dx + gy dy.
 *   - at the anchor (at rest) it is the full bilinear map (comp2d_correct)
 *     within 2 nm, for every direction of approach;
 *   - the directions follow the command and ramp over 20 ms;
 *   - moving at 20 mm/s over a field steeper than the thesis's, with
 *     reversals, main polling once a tick: within 50 nm of the full map
 *     (with the weights main published) at every tick;
 *   - the tick preempting the publish between any two of its statements
 *     sees the old anchor or the new one, never a mix;
 *   - no map: nothing added; clearing stops at once.
 */
#include <string.h>

#include "comp2d.h"
#include "comp2d_live.h"
#include "preempt.h"
#include "unity.h"

static comp2d_map_t M;
static uint32_t now_us;
static int64_t vel[2]; /* the commanded velocity main sees */
static const pos_nm_t LO[2] = {-100000000, -100000000};
static const pos_nm_t HI[2] = {100000000, 100000000};

static uint32_t rnd_state;
static int32_t rnd(int32_t span)
{
    rnd_state = rnd_state * 1103515245u + 12345u;
    return (int32_t)((rnd_state >> 8) % (2u * (uint32_t)span + 1u)) - span;
}

/* 11 x 11 nodes every 15 mm from -75 mm, shift 2: mean +-40 um, direction
 * terms +-6 um (the thesis field: about 160 um over 120 mm, 11 um of
 * hysteresis; this one is steeper and more twisted) */
void setUp(void)
{
    unsigned a, i;
    memset(&M, 0, sizeof M);
    M.version = COMP2D_VERSION;
    M.nx = 11;
    M.ny = 11;
    M.x0 = -75000000;
    M.y0 = -75000000;
    M.dx = 15000000;
    M.dy = 15000000;
    M.shift = 2;
    rnd_state = 7u;
    for (a = 0; a < 2u; a++) {
        for (i = 0; i < 121u; i++) {
            M.g[a][COMP2D_MID][i] = (int16_t)rnd(10000);
            M.g[a][COMP2D_HX][i] = (int16_t)rnd(1500);
            M.g[a][COMP2D_HY][i] = (int16_t)rnd(1500);
        }
    }
    TEST_ASSERT_EQUAL_INT(COMP2D_OK, comp2d_check(&M, LO, HI));
    comp2d_prepare(&M);
    comp2d_live_init();
    now_us = 0u;
    vel[0] = vel[1] = 0;
    preempt_hook = 0;
}

void tearDown(void)
{
    preempt_hook = 0;
}

/* the tick's result at p: what the decoders and the feedback get */
static void tick_at(const pos_nm_t p[2], pos_nm_t out[2])
{
    pos_nm_t x = p[0], y = p[1];
    comp2d_live_apply(&x, &y, &out[0], &out[1]);
}

/* the full map at p with the weights of the published anchor */
static void full_at(const pos_nm_t p[2], pos_nm_t out[2])
{
    const q1_30_t w[2] = {comp2d_live_pub->wx, comp2d_live_pub->wy};
    comp2d_correct(&M, p, w, out);
}

/* main's poll, 100 us (one tick) later */
static void poll(const pos_nm_t p[2])
{
    now_us += 100u;
    comp2d_live_poll(p, vel, now_us);
}

/* bring the axes to p having moved to it along (sx, sy), settled */
static void arrive(const pos_nm_t p[2], int sx, int sy)
{
    pos_nm_t q[2];
    unsigned k;
    q[0] = p[0] - sx * 10000;
    q[1] = p[1] - sy * 10000;
    poll(q);
    vel[0] = sx;
    vel[1] = sy;
    poll(p); /* commanded towards p */
    vel[0] = vel[1] = 0;
    for (k = 0; k < 300u; k++) {
        poll(p);
    }
}

static void test_exact_at_the_anchor(void)
{
    pos_nm_t p[2], t[2], f[2];
    q1_30_t w[2];
    unsigned k;
    comp2d_live_set(&M);
    for (k = 0; k < 200u; k++) {
        int sx = (k & 1u) ? 1 : -1, sy = (k & 2u) ? 1 : -1;
        p[0] = (pos_nm_t)rnd(90000000);
        p[1] = (pos_nm_t)rnd(90000000);
        arrive(p, sx, sy);
        /* settled: the weights are the directions of approach */
        TEST_ASSERT_EQUAL_INT32(sx * COMP_W_ONE, comp2d_live_pub->wx);
        TEST_ASSERT_EQUAL_INT32(sy * COMP_W_ONE, comp2d_live_pub->wy);
        tick_at(p, t);
        w[0] = sx * COMP_W_ONE;
        w[1] = sy * COMP_W_ONE;
        comp2d_correct(&M, p, w, f);
        TEST_ASSERT_INT64_WITHIN(2, f[0], t[0]);
        TEST_ASSERT_INT64_WITHIN(2, f[1], t[1]);
    }
}

static void test_directions_follow_the_command_and_ramp(void)
{
    pos_nm_t p[2] = {0, 0};
    int32_t w[2];
    unsigned k;
    comp2d_live_set(&M);
    poll(p);
    comp2d_live_weights(w);
    TEST_ASSERT_EQUAL_INT32(0, w[0]); /* no command yet: the mean */
    p[0] += 5000;                     /* moved, not commanded: no direction */
    poll(p);
    comp2d_live_weights(w);
    TEST_ASSERT_EQUAL_INT32(0, w[0]);
    vel[0] = 1; /* commanded +x: ramps to +1 in 20 ms (200 polls of 100 us) */
    poll(p);
    comp2d_live_weights(w);
    TEST_ASSERT_INT32_WITHIN(COMP_W_ONE / 1000, COMP_W_ONE / 100, w[0]);
    vel[0] = 0; /* held at rest */
    for (k = 0; k < 200u; k++) {
        poll(p);
    }
    comp2d_live_weights(w);
    TEST_ASSERT_EQUAL_INT32(COMP_W_ONE, w[0]);
    TEST_ASSERT_EQUAL_INT32(0, w[1]);
    vel[0] = -3; /* a reversal: 1/100 of the swing a tick */
    poll(p);
    comp2d_live_weights(w);
    TEST_ASSERT_INT32_WITHIN(COMP_W_ONE / 1000, COMP_W_ONE - COMP_W_ONE / 100, w[0]);
    for (k = 0; k < 200u; k++) {
        poll(p);
    }
    comp2d_live_weights(w);
    TEST_ASSERT_EQUAL_INT32(-COMP_W_ONE, w[0]);
}

/* A path at 20 mm/s (2 um a tick): circles of radius 40 mm and 70 mm around
 * (5, -3) mm (every cell edge crossed at every angle, reversals of X and Y)
 * and a diagonal line beyond the grid and back. The tick runs, then main
 * polls, as app_tick / app_poll do; returns the largest difference, nm. */
static int64_t run_path(unsigned poll_every)
{
    int64_t worst = 0;
    pos_nm_t p[2], prev[2] = {45000000, -3000000}, t[2], f[2];
    unsigned k, c;
    comp2d_live_set(&M);
    poll(prev);
    for (k = 0; k < 3u * 157080u + 240000u; k++) {
        if (k < 3u * 157080u) {
            /* circle: 2 um / tick; r = 40, 70, 40 mm (index k / 157080) */
            double r = (k / 157080u) % 2u ? 70e6 : 40e6;
            double th = (double)(k % 157080u) * 2e3 / r * (r == 40e6 ? 1.75 : 1.0);
            p[0] = 5000000 + (pos_nm_t)(r * __builtin_cos(th));
            p[1] = -3000000 + (pos_nm_t)(r * __builtin_sin(th));
        } else {
            int64_t j = (int64_t)(k - 3u * 157080u);
            int64_t s = j < 120000 ? j : 240000 - j; /* out and back */
            p[0] = -85000000 + s * 1414;
            p[1] = -85000000 + s * 1414;
        }
        if (p[0] - prev[0] > 100000 || prev[0] - p[0] > 100000) {
            poll(p); /* the path jumps to its next part: not motion */
        }
        tick_at(p, t);
        full_at(p, f);
        for (c = 0; c < 2u; c++) {
            int64_t e = t[c] - f[c];
            e = e < 0 ? -e : e;
            worst = e > worst ? e : worst;
        }
        vel[0] = p[0] - prev[0]; /* the path is the command */
        vel[1] = p[1] - prev[1];
        if (k % poll_every == 0u) {
            poll(p);
        }
        prev[0] = p[0];
        prev[1] = p[1];
    }
    return worst;
}

static void test_moving_within_50_nm_of_the_full_map(void)
{
    int64_t worst = run_path(1u);
    TEST_ASSERT_TRUE(comp2d_live_anchors() > 1000u);
    TEST_ASSERT_TRUE_MESSAGE(worst < 50, "tick vs comp2d_correct over 50 nm");
}

/* ---- the tick preempting the publish ---------------------------------- */

static pos_nm_t probe[2], seen[64][2];
static unsigned fired;

static void hook(const char *file, int line)
{
    (void)file;
    (void)line;
    if (fired < 64u) {
        tick_at(probe, seen[fired]);
    }
    fired++;
}

static void test_tick_preempting_the_publish_sees_one_anchor(void)
{
    pos_nm_t a[2] = {-20000000, 10000000}, b[2] = {33000000, -41000000};
    pos_nm_t r_old[2], r_new[2];
    unsigned k, i;
    comp2d_live_set(&M);
    for (k = 0; k < 40u; k++) {
        /* the anchor at a, then (the hook running the tick at every
         * statement of the publish) at b, another cell */
        poll(a);
        probe[0] = a[0] + rnd(3000000);
        probe[1] = a[1] + rnd(3000000);
        tick_at(probe, r_old);
        fired = 0u;
        preempt_hook = hook;
        poll(b);
        preempt_hook = 0;
        tick_at(probe, r_new);
        TEST_ASSERT_TRUE(r_old[0] != r_new[0] || r_old[1] != r_new[1]);
        TEST_ASSERT_TRUE(fired >= 5u && fired <= 64u);
        for (i = 0; i < fired; i++) {
            bool is_old = seen[i][0] == r_old[0] && seen[i][1] == r_old[1];
            bool is_new = seen[i][0] == r_new[0] && seen[i][1] == r_new[1];
            TEST_ASSERT_TRUE_MESSAGE(is_old || is_new, "the tick saw a half-written anchor");
        }
        a[0] += 1000000;
        b[1] -= 1000000;
    }
}

static void test_no_map_adds_nothing_and_clear_is_immediate(void)
{
    pos_nm_t p[2] = {1234567, -7654321}, t[2] = {0, 0};
    tick_at(p, t);
    TEST_ASSERT_EQUAL_INT64(0, t[0]); /* untouched: no map */
    comp2d_live_set(&M);
    poll(p);
    tick_at(p, t);
    TEST_ASSERT_TRUE(t[0] != p[0]);
    comp2d_live_set(0);
    t[0] = 0;
    tick_at(p, t);
    TEST_ASSERT_EQUAL_INT64(0, t[0]);
    TEST_ASSERT_NULL(comp2d_live_map());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_exact_at_the_anchor);
    RUN_TEST(test_directions_follow_the_command_and_ramp);
    RUN_TEST(test_moving_within_50_nm_of_the_full_map);
    RUN_TEST(test_tick_preempting_the_publish_sees_one_anchor);
    RUN_TEST(test_no_map_adds_nothing_and_clear_is_immediate);
    return UNITY_END();
}
