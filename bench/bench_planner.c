/*
 * Planner figures (host build, -O2, no sanitizers).
 *   bench_planner push N     N pushes on a full depth-64 ring (callgrind
 *                            counts bench_push: plan_push + its re-planning)
 *   bench_planner estimate N [trapezoid]
 *                            plan_estimate over N random blocks (S-curve, or
 *                            trapezoid: deferred passes), prints
 *                            estimator_blocks_per_second[_trapezoid]
 *   bench_planner check N HZ the random-path interpolator check of
 *                            tests/unit/test_interp.c at HZ, unsanitized
 *   bench_planner collinear N [DEPTH]
 *                            plan_estimate over N collinear 0.1 mm X blocks
 *                            at F15000 (trapezoid, a = 386 mm/s^2, minimum
 *                            block time 0.4486 ms, window 16; the job-time
 *                            estimator's iTNC530 case), depth 1024 by default:
 *                            prints estimator_collinear_us_per_block
 */
#include "estimator.h"
#include "path_check.h"
#include "planner.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static plan_block_t store[PLAN_DEPTH_DEFAULT];
static plan_t pl;
static const pos_nm_t origin[CORE_AXES] = {0, 0, 0};

static uint64_t rs = 0x243F6A8885A308D3ull;
static uint64_t rnd(void)
{
    rs ^= rs << 13;
    rs ^= rs >> 7;
    rs ^= rs << 17;
    return rs;
}

/* a wandering path of 0.01-1 mm blocks, occasionally sharp corners */
static void make_move(plan_move_t *m, pos_nm_t *pos)
{
    int i;
    int64_t step = 10000 + (int64_t)(rnd() % 990000);
    memset(m, 0, sizeof(*m));
    for (i = 0; i < CORE_AXES; i++) {
        int64_t d = (int64_t)(rnd() % 2001) - 1000;
        if (i == 0) {
            d = 1000 + (int64_t)(rnd() % 1000); /* mostly +X */
        }
        pos[i] += d * step / 2000;
        m->target[i] = pos[i];
    }
    m->feed = 50000000 + (int64_t)(rnd() % 200000000);
}

__attribute__((noinline)) static void bench_push(const plan_move_t *m)
{
    if (plan_push(&pl, m) != PLAN_OK) {
        abort();
    }
}

int main(int argc, char **argv)
{
    const char *mode = argc > 1 ? argv[1] : "push";
    long n = argc > 2 ? atol(argv[2]) : 10000, k;
    plan_profile_t prof = pc_profile(SC_SHAPE_SCURVE);
    pos_nm_t pos[CORE_AXES] = {0, 0, 0};

    prof.min_block_ns = 450000;
    prof.mbt_window = 16;
    if (!strcmp(mode, "push")) {
        plan_move_t m;
        plan_seg_t seg;
        plan_init(&pl, store, PLAN_DEPTH_DEFAULT, &prof, origin);
        for (k = 0; k < PLAN_DEPTH_DEFAULT; k++) {
            make_move(&m, pos);
            bench_push(&m);
        }
        for (k = 0; k < n; k++) {
            make_move(&m, pos);
            plan_pop(&pl, &seg);
            bench_push(&m);
        }
        return 0;
    }
    if (!strcmp(mode, "estimate") && argc > 3 && !strcmp(argv[3], "trapezoid")) {
        prof.shape = SC_SHAPE_TRAPEZOID;
    }
    if (!strcmp(mode, "estimate")) {
        plan_move_t *mv = malloc(sizeof(*mv) * (size_t)n);
        plan_est_t *out = malloc(sizeof(*out) * (size_t)n);
        static plan_block_t ring[PLAN_DEPTH_DEFAULT];
        struct timespec t0, t1;
        uint32_t bad;
        double best = 1e30;
        int rep;
        if (mv == NULL || out == NULL) {
            return 1;
        }
        for (k = 0; k < n; k++) {
            make_move(&mv[k], pos);
        }
        for (rep = 0; rep < 3; rep++) {
            double dt;
            clock_gettime(CLOCK_MONOTONIC, &t0);
            if (plan_estimate(&prof, origin, mv, (uint32_t)n, ring, PLAN_DEPTH_DEFAULT, out,
                              &bad) != PLAN_OK) {
                return 1;
            }
            clock_gettime(CLOCK_MONOTONIC, &t1);
            dt = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
            if (dt < best) {
                best = dt;
            }
        }
        printf("estimator_blocks_per_second%s: %.0f blocks/s\n",
               prof.shape == SC_SHAPE_TRAPEZOID ? "_trapezoid" : "", (double)n / best);
        free(mv);
        free(out);
        return 0;
    }
    if (!strcmp(mode, "check")) {
        pc_result_t r;
        long hz = argc > 3 ? atol(argv[3]) : 10000;
        char prefix[64];
        snprintf(prefix, sizeof(prefix), "interp_random_path_%ldhz", hz);
        pc_run((uint32_t)n, 1000000000 / hz, 12345u, SC_SHAPE_SCURVE, &r);
        pc_print(prefix, &r);
        return (r.limit_violations || r.time_violations || !r.final_exact || !r.total_ticks_ok) ? 1
                                                                                                : 0;
    }
    if (!strcmp(mode, "collinear")) {
        long depth = argc > 3 ? atol(argv[3]) : 1024;
        plan_move_t *mv = malloc(sizeof(*mv) * (size_t)n);
        plan_est_t *out = malloc(sizeof(*out) * (size_t)n);
        plan_block_t *ring = malloc(sizeof(*ring) * (size_t)depth);
        plan_profile_t cp = prof;
        struct timespec t0, t1;
        uint32_t bad;
        double best = 1e30;
        int rep, i;
        if (mv == NULL || out == NULL || ring == NULL || depth < 1 || depth > 65535) {
            return 1;
        }
        for (i = 0; i < CORE_AXES; i++) {
            cp.v_max[i] = 500000000;
            cp.a_max[i] = (i == 1) ? 302000000 : 386000000;
            cp.j_max[i] = 3000000000000;
        }
        cp.shape = SC_SHAPE_TRAPEZOID;
        cp.min_block_ns = 448600;
        cp.mbt_window = 16;
        memset(mv, 0, sizeof(*mv) * (size_t)n);
        for (k = 0; k < n; k++) {
            mv[k].target[0] = (k + 1) * 100000;
            mv[k].feed = 250000000;
        }
        for (rep = 0; rep < 3; rep++) {
            double dt;
            clock_gettime(CLOCK_MONOTONIC, &t0);
            if (plan_estimate(&cp, origin, mv, (uint32_t)n, ring, (uint16_t)depth, out, &bad) !=
                PLAN_OK) {
                return 1;
            }
            clock_gettime(CLOCK_MONOTONIC, &t1);
            dt = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
            if (dt < best) {
                best = dt;
            }
        }
        printf("estimator_collinear_us_per_block: %.3f us\n", 1e6 * best / (double)n);
        free(mv);
        free(out);
        free(ring);
        return 0;
    }
    return 2;
}
