/*
 * path_check.h - random-path check of planner + interpolator, shared by
 * tests/unit/test_interp.c (sanitized, coarse tick) and bench/bench_planner.c
 * (unsanitized, 10 kHz). See test_interp.c for what is checked.
 */
#ifndef PATH_CHECK_H
#define PATH_CHECK_H

#include <stdbool.h>
#include <stdint.h>

#include "planner.h"

typedef struct {
    uint32_t blocks;           /* blocks completed by the interpolator       */
    uint32_t limit_violations; /* ticks where a differenced limit was broken */
    uint32_t time_violations;  /* block ends off the estimate by >= 1 tick   */
    uint32_t underruns;
    bool final_exact;         /* last reference == last target, every axis  */
    bool total_ticks_ok;      /* ticks == ceil(sum of estimates / tick)     */
    int64_t max_block_err_ns; /* max |block end - cumulative estimate|      */
    uint64_t ticks;
    int64_t est_total_ns;   /* sum of the estimated block times           */
    double max_v_ratio;     /* max |dp| / (v_i h) over axes and ticks     */
    double max_a_ratio;     /* max |d2p| / (a_i h^2) inside blocks        */
    double max_j_ratio;     /* max |d acc_ff| / (j_i h) inside blocks     */
    uint32_t corner_capped; /* blocks whose v_max is the smoothed-corner cap */
    uint64_t jerk_checks;   /* axis-ticks checked against the jerk limit
                             * (S-curve blocks; at-rest shape: blocks whose
                             * estimated entry or exit speed is 0)       */
    /* Path level (interp_t s/v/a, every busy tick, block ends included:
     * the continuous S-curve joins blocks at non-zero acceleration) */
    double max_path_a_ratio;         /* max |a| / the smallest a_i of the axes the
                                      * block moves (of the two blocks of a tick) */
    double max_path_j_ratio;         /* max |a(t+h) - a(t)| / (j h), j the same   */
    double max_path_a_min_ratio;     /* max |a| / min_i a_i over every axis:
                                      * above 1 where a run does not move
                                      * the axis with the smallest a      */
    uint32_t joins_accel;            /* block ends passed at |a| >= min_i a_i / 10 */
    uint32_t stalls;                 /* times the feed stopped (pc_stall_every)     */
    uint32_t cont_kept, cont_forced; /* planner's counters at the end    */
} pc_result_t;

/* Withhold pushes every this many blocks until the interpolator is idle
 * (0: never): the drive must stop at the end of what it has queued. */
extern uint32_t pc_stall_every;

/* Random paths of CAM output instead (0.002..0.3 mm chords, gentle
 * turns, the feed changing every hundred blocks or so). */
extern bool pc_smooth_paths;

/* Every other stretch of 200 blocks in the XZ plane (Y still): runs that
 * do not move the slow Y take X and Z's limits. */
extern bool pc_planar_xz;

/* The test machine: X, Z 500 mm/s, 2 m/s^2, 50 m/s^3; Y 300 mm/s, 1 m/s^2,
 * 20 m/s^3; junction deviation 0.01 mm; minimum block time 0.5 ms (W = 4). */
plan_profile_t pc_profile(uint8_t shape);

/* Run n random blocks at tick_ns with the given seed and shape. */
void pc_run(uint32_t n, int64_t tick_ns, uint32_t seed, uint8_t shape, pc_result_t *r);

/* The same with any profile (its shape selects the jerk check). */
void pc_run_profile(uint32_t n, int64_t tick_ns, uint32_t seed, const plan_profile_t *prof,
                    pc_result_t *r);

void pc_print(const char *prefix, const pc_result_t *r);

#endif /* PATH_CHECK_H */
