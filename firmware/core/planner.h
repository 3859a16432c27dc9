/*
 * planner.h - look-ahead planner: a ring of straight blocks, junction speeds,
 * per-block S-curve or trapezoidal profiles and their exact durations.
 *
 * Specification
 * -------------
 * Blocks are straight moves to an absolute end point (nm) at a programmed
 * path feed (nm/s), or dwells. Arcs are segmented by the host or by the drive
 * (drive.c, within DRIVE_ARC_CHORD_NM) before they reach the planner: the
 * planner has no arc blocks. The ring memory is supplied by the caller
 * (plan_init), so the depth is fixed at start-up (PLAN_DEPTH_DEFAULT = 64 on
 * the drive; the host estimator may pass more) and nothing is allocated.
 *
 * Block limits. For a block with unit direction u (u_i = delta_i / len):
 *   v_max = min(feed, min_i v_i / |u_i|, throughput cap)
 *   a_max = min_i a_i / |u_i|,   j_max = min_i j_i / |u_i|
 * so every axis stays within its own limits inside the block. Different
 * per-axis limits: the exact floor(lim_b len / |delta_b|) of the limiting
 * axis b. Equal limits on every axis (one division per block instead of
 * three; components below 2^31 nm): lim f / 2^31 with f = len / max_i
 * |delta_i| in q31 rounded down, at most the exact floor and at most
 * lim / 2^30 + 1 below it (longer components: the exact floor); the block
 * then keeps a lower bound of floor(A^2/J) (within 32 of it) for the reach
 * instead of the exact pair. Direction ratios ratio_q62[i] =
 * floor(delta_i 2^62 / len) or one less (magnitude; delta_i = +-len gives
 * +-2^62 exactly), from one reciprocal of len per block.
 *
 * Junction speed (entry speed limit of a block), profile.corner:
 *   PLAN_CORNER_JD (default)   junction deviation: with cos(t) = -u1.u2 and
 *       s = sin(t/2) = sqrt((1 - cos t)/2), v^2 = a_j * dev * s / (1 - s),
 *       a_j = min_i a_i / |e_i|, e = (u2 - u1)/|u2 - u1|, dev =
 *       profile.junction_dev_nm. Collinear: no limit; 180 degrees: stop.
 *   PLAN_CORNER_VSTEP          per-axis velocity step: v = min_i dv_i / |du_i|
 *       with du = u2 - u1 and dv_i = profile.corner_dv[i] (nm/s).
 *   PLAN_CORNER_SMOOTH         smoothed corner (imitates e.g. an iTNC530):
 *       v = min_i sqrt(a_c_i * l / |du_i|), l = (len1 + len2) / 2,
 *       a_c_i = profile.corner_acc[i] (nm/s^2). The control rounds each
 *       corner over half of each neighbouring block, so no part of a block
 *       lies outside a rounding zone: the block's speed is also capped,
 *         v_max(k) = min(v_max(k), max(vc_in(k), vc_out(k))),
 *       vc_in/vc_out the smoothed speeds v of its entry and exit junctions
 *       before the reversal/stop/v_max clamps. A junction adds no cap
 *       (+inf) when it is collinear (du = 0), an axis reversal, an exact
 *       stop, next to a dwell, the start of the job, or when its speed is 0
 *       (a_c_i = 0: a stop); so does the exit of a block with no next block
 *       yet. A queued block's cap falls when the next move is pushed; a
 *       popped block is final, so the cap uses only the blocks known when
 *       the block is popped (plan_estimate pops exactly as the drive does,
 *       so estimate == execution holds). The cap is never below either
 *       junction speed of the block, so it changes only the block's own
 *       profile, never a planned entry speed (flag PLAN_BF_CORNER).
 *   PLAN_CORNER_STOP           every junction is an exact stop.
 * In every rule: an axis whose direction component changes sign (both
 * at least PLAN_REVERSAL_MIN_Q30 = 1/16 in magnitude: a smaller sign change,
 * e.g. an arc's chords crossing a quadrant, is an ordinary corner for the
 * rule) reverses, and a reversal is a stop (junction speed 0); the
 * junction is also limited by both blocks' v_max. PLAN_MOVE_EXACT_STOP on a
 * block (G61 modal or G60/G9 per block) makes its exit speed 0; G64
 * (continuous path) is the absence of the flag.
 *
 * Arc chord joins (PLAN_MOVE_ARC_JOIN on the later move; not after an exact
 * stop): an axis reversal still stops; otherwise, in every rule but
 * PLAN_CORNER_STOP, the junction and the block's v_max are limited by the
 * arc through the two chords, R = l / |u2 - u1| with l the mean chord
 * length (exact for equal chords of a circle): v^2 <= a_n R and, for the
 * S-curve shapes, v^3 <= j_n R^2, a_n and j_n the axis limits projected on
 * u2 - u1 (the normal of the arc at the join). The corner rule would treat
 * the chord polygon's joins as corners (junction deviation: 24.5 instead
 * of 30 m/min on pi/32 chords at a 3 ms tick).
 *
 * Minimum block time (throughput limit), profile.min_block_ns = T > 0 and
 * profile.mbt_window = W (1..PLAN_WINDOW_MAX): block k never runs faster than
 *   c_k = (len_{k-W+1} + ... + len_k) / (n_k * T),  n_k = blocks in that
 * window (fewer than W at the start of a job). A run of equal blocks thus
 * takes exactly T per block, any periodic pattern whose period divides W
 * takes T per block on average, and a single short block between long ones
 * is not slowed (its window is dominated by the long ones). W = 1 is the
 * per-block cap ("mrt" model: every block takes at least T). The window
 * uses only the block and its predecessors, so the cap is fixed when the
 * block is queued and never depends on how full the queue is.
 *
 * Look-ahead. Every block stores its planned entry speed; a block's exit
 * speed is the next block's entry speed, and the newest block ends at rest.
 * plan_push() runs a reverse pass (from the newest block back: entry =
 * min(junction limit, sc_reach(exit, len))) and a forward pass (entry of
 * k+1 = min(itself, sc_reach(entry_k, len_k))) over the blocks after the
 * `planned` mark only: a block is marked planned when its entry can no longer
 * rise (it reached its junction limit, or it is limited by the maximum
 * acceleration from a planned predecessor), exactly as a new block can only
 * raise speeds. The reverse pass stops at the first entry it leaves
 * unchanged, and the forward pass starts at the block before the first
 * changed entry. The oldest block's entry speed is fixed (it is the exit of
 * the block that was popped before it, or 0). plan_set_deferred() batches
 * the passes (trapezoid and at-rest S-curve only; see below).
 *
 * S-curve reach. With the acceleration zero at both ends of a block, the
 * speed reachable within a distance is NOT monotone in the start speed
 * (dist(v, w) = (v + w) sqrt((w - v)/J) in the reduced case: from w/2 the
 * speed w needs 6 % more distance than from rest). A later block can then
 * lower the reverse limit of a block whose entry was already marked final;
 * the planner keeps the final entry (the plan stays what the estimator
 * computes and the interpolator executes, and the block's profile is
 * scaled to its length by the interpolator), so in S-curve mode the
 * incremental plan can differ from a from-scratch plan after long random
 * paths (one entry 4 % above it in 200 000 random pushes). Trapezoidal
 * reach sqrt(v^2 + 2 A d) is monotone and the incremental plan equals the
 * from-scratch plan.
 *
 * At-rest S-curve (profile.shape = SC_SHAPE_SCURVE_AT_REST, opt-in): a block
 * whose planned entry or exit speed is 0 (job start and end, exact stop,
 * reversal, dwell, a zero junction limit) gets the jerk-limited S-curve,
 * every other block the trapezoid: jerk shows at starts and stops, while
 * along a path the acceleration is not forced to 0 at every block end
 * (chains of short blocks run as with the trapezoid). The reverse pass from
 * an exit of 0 and the forward pass from an entry of 0 use the S-curve
 * reach, the others the trapezoid reach (scurve.h: the shape follows the
 * speeds inside sc_reach/sc_dist/sc_plan), and plan_pop() plans the block
 * with its final entry and exit, so the shape executed is the shape
 * estimated. This reach is monotone in the start speed (from rest the
 * S-curve reaches no further than the trapezoid from any speed), so the
 * incremental plan equals the from-scratch plan and deferred passes apply.
 *
 * Continuous S-curve (profile.shape = SC_SHAPE_SCURVE_CONTINUOUS, the
 * drive's default; planner_cont.c): jerk-limited with the path acceleration
 * continuous across block ends. A run is a chain of blocks with the same
 * v_max whose junctions do not limit it (v_junction >= v_max: no corner
 * limit, stop, reversal or dwell); a run is planned as one profile and every
 * block is its slice, so blocks join at non-zero acceleration. Junctions between runs are anchors:
 * a = 0 there, and the speed at most the anchor's bound, kept in the first
 * block's v_entry by a reverse pass over the runs in plan_pop (from the
 * queue's end at rest: bound = min(v_junction, max(reach(next bound, d),
 * reach(0, d))), d the run's length less a margin, sc_reach of the run's
 * limits with a = 0 at both ends; a bound never falls). A run's limits
 * are v_max and the smallest a and j of the axes its blocks move, less
 * 2^-12 (an axis that does not move has no acceleration or jerk; any
 * direction of the others keeps each within its own limits). A block's
 * limit class (cont_cls: the axes it moves, masks with the same limits
 * one class) changes only at an anchor: where it changes, plan_push keeps
 * the junction 1 nm/s below v_max, so a run's limits never change while
 * it grows (with equal a and j on every axis there is one class and the
 * plans are those of every axis's limits). plan_pop plans the oldest run from the
 * path state (v, a) where the last block ended: seven phases as scurve.h's
 * (R1 from (v, a) to a speed vp at a = 0, a cruise at vp, R2 down to the
 * exit speed v1 = min(vp, bound), or to rest), vp the highest speed for
 * which the realised R1 and sc_dist(vp, v1) fit the run (bisection to
 * 2^-12); the block gets the slice of that profile over its length (its
 * end the time where the profile reaches it, ns; its states evaluated on
 * the profile, so speed and acceleration carry over to the next block to
 * within the q16 rounding). The plan stays in force while the run and its
 * bound do not change; a pop after a push plans again from the state (a
 * cruise at the limit only moves R2 on, and not before a block reaches
 * R2: until then the plan in force gives the block the same cruise). If
 * no new plan fits, the one in force stays: it reaches its end within
 * limits (then the path is at rest at a block end, or at the anchor's
 * bound). So the last queued block
 * always ends at rest, the speed never goes negative and never passes a
 * block's v_max, |a| and |j| of the path stay within the run's limits
 * across block ends (test_interp: random paths, path a and j on every
 * tick). Not with PLAN_CORNER_SMOOTH (its cap lowers a queued block's v_max
 * and would cut a run under way: PLAN_E_PROFILE). The estimate pops as the
 * drive does (plan_queued_ns is exact for the run in force, an estimate
 * for runs not planned yet). Cost: a push and a pop 1 997 Cortex-M4
 * instructions on the bench's chords (bench-firmware.sh,
 * planner_block_instructions_m4; 2 802 before the cruise's slice and
 * divisions were made cheap: docs/planner.md); every run boundary in the
 * queue adds a reach.
 *
 * plan_pop() freezes the oldest block: its exit speed (the next block's
 * entry, or 0 if it is the only one) becomes final, its profile is computed
 * (sc_plan) and handed out with its geometry; the interpolator executes it
 * unchanged. Estimates therefore equal execution exactly when the queue is
 * refilled before each pop (the drive's main loop pushes before it pops;
 * plan_estimate() in estimator.h does the same).
 *
 * Units: positions nm (pos_nm_t), lengths nm, speeds nm/s, acc nm/s^2,
 * jerk nm/s^3, times ns, direction ratios q2_62 (delta_i / len * 2^62).
 *
 * Contexts: a plan_t is used from one context (main on the drive); the
 * interpolator receives popped segments through its own FIFO (interp.h).
 */
#ifndef PLANNER_H
#define PLANNER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core_config.h"
#include "fixmath.h"
#include "scurve.h"

#define PLAN_DEPTH_DEFAULT 64
#define PLAN_WINDOW_MAX    64
/* Smallest direction component (q1_30) on both sides of a sign change that
 * counts as an axis reversal (a stop): 1/16. */
#define PLAN_REVERSAL_MIN_Q30 ((int64_t)1 << 26)

typedef enum {
    PLAN_OK = 0,
    PLAN_SKIPPED = 1,    /* zero-length move: nothing queued (not an error) */
    PLAN_E_FULL = -1,    /* ring full: pop first                            */
    PLAN_E_EMPTY = -2,   /* nothing to pop                                  */
    PLAN_E_FEED = -3,    /* feed <= 0 or above SC_V_LIMIT                   */
    PLAN_E_RANGE = -4,   /* block too long (> SC_LEN_MAX) or target absurd  */
    PLAN_E_PROFILE = -5, /* invalid profile value (plan_init)               */
    PLAN_E_ARG = -6      /* NULL pointer, depth 0, bad dwell                */
} plan_result_t;

typedef enum {
    PLAN_CORNER_JD = 0,     /* junction deviation (the drive's default) */
    PLAN_CORNER_VSTEP = 1,  /* per-axis velocity step                   */
    PLAN_CORNER_SMOOTH = 2, /* smoothed corner, per-axis corner acc.    */
    PLAN_CORNER_STOP = 3    /* exact stop at every junction             */
} plan_corner_t;

typedef struct {
    int64_t v_max[CORE_AXES];      /* nm/s, 1 .. SC_V_LIMIT                 */
    int64_t a_max[CORE_AXES];      /* nm/s^2, SC_A_MIN .. SC_A_LIMIT        */
    int64_t j_max[CORE_AXES];      /* nm/s^3, SC_J_MIN .. SC_J_LIMIT        */
    int64_t corner_dv[CORE_AXES];  /* VSTEP: allowed velocity step, nm/s    */
    int64_t corner_acc[CORE_AXES]; /* SMOOTH: corner acceleration, nm/s^2   */
    int64_t junction_dev_nm;       /* JD: junction deviation, nm (>= 0)     */
    int64_t min_block_ns;          /* throughput limit T, ns (0: off)       */
    uint16_t mbt_window;           /* W, blocks, 1..PLAN_WINDOW_MAX         */
    uint8_t corner;                /* plan_corner_t                         */
    uint8_t shape;                 /* sc_shape_t                            */
} plan_profile_t;

#define PLAN_MOVE_EXACT_STOP 0x01u /* stop at the end of this block (G61/G60/G9) */
/* This move and the previous one are consecutive chords of one arc (the
 * drive's arc_seg, or a host that knows its chords): their join is limited
 * by the arc's centripetal limits instead of the corner rule, and so is the
 * block's speed (see "Arc chord joins" above). */
#define PLAN_MOVE_ARC_JOIN 0x02u

typedef struct {
    pos_nm_t target[CORE_AXES]; /* absolute end point, nm (ignored for a dwell) */
    int64_t feed;               /* programmed path feed, nm/s (moves)           */
    int64_t dwell_ns;           /* > 0: a dwell (G4) of this time; no motion    */
    uint32_t tag;               /* caller's id (e.g. line number), echoed       */
    uint8_t flags;              /* PLAN_MOVE_*                                  */
} plan_move_t;

/* Block flags (plan_block_t.flags, plan_seg_t.flags). */
#define PLAN_BF_EXACT_STOP 0x01u /* exit speed forced to 0                     */
#define PLAN_BF_DWELL      0x02u /* dwell block                                */
#define PLAN_BF_MBT        0x04u /* v_max set by the minimum block time        */
#define PLAN_BF_PLANNED    0x08u /* entry final (look-ahead bookkeeping)       */
#define PLAN_BF_CORNER     0x10u /* v_max set by the smoothed-corner block cap */

/* One ring entry (opaque to users; sized for the caller's storage array). */
typedef struct {
    pos_nm_t start[CORE_AXES];
    pos_nm_t end[CORE_AXES];
    int64_t ratio_q62[CORE_AXES]; /* delta_i / len * 2^62                    */
    int64_t len;                  /* nm (0 for a dwell)                      */
    int64_t dwell_ns;
    sc_limits_t lim;     /* block limits (v_max includes the cap);
                          * continuous S-curve, axes with different
                          * limits: a and j of the block's class
                          * (cont_a, cont_j), what its run takes    */
    int64_t v_junction;  /* entry speed limit, nm/s                 */
    int64_t v_entry;     /* planned entry speed, nm/s               */
    int64_t v_corner_in; /* smoothed-corner speed of the entry
                          * junction (block cap), INT64_MAX: none   */
    sc_reach_k_t rk;     /* the reach's constants for the block's
                          * length (sc_reach_k_init): q, qc floor
                          * and ceil of a_max^2 / j_max (nm/s); or
                          * qc -1 and q a lower bound of the floor
                          * (equal axis limits); -1 for a dwell;
                          * not set for the continuous S-curve
                          * (its passes reach over runs)         */
    uint32_t tag;
    uint8_t flags;
    uint8_t cont_cls; /* continuous S-curve: the limit class of the
                       * axes the block moves (plan_t cont_cls) */
} plan_block_t;

/* A popped, frozen block: what the interpolator executes. */
typedef struct {
    pos_nm_t start[CORE_AXES];
    pos_nm_t end[CORE_AXES];
    int64_t ratio_q62[CORE_AXES];
    int64_t len;       /* nm                                  */
    int64_t dwell_ns;  /* dwell time (profile empty), ns      */
    int64_t total_ns;  /* duration of the block, ns           */
    sc_profile_t prof; /* velocity profile (moves)            */
    uint32_t tag;
    uint8_t flags; /* PLAN_BF_*                           */
} plan_seg_t;

typedef struct {
    plan_profile_t prof;
    plan_block_t *ring;
    uint16_t depth;
    uint16_t tail;                     /* oldest block                              */
    uint16_t count;                    /* blocks queued                             */
    uint16_t planned;                  /* blocks from the tail whose entry is final */
    uint16_t fresh;                    /* blocks planned by the last pass (the
                                        * rest were queued after it)             */
    bool deferred;                     /* passes deferred to plan_pop/update   */
    bool defer_passes;                 /* plan_push leaves the passes (the
                                        * request and the shape: pl_pass_mode) */
    uint8_t blk_shape;                 /* the blocks' sc_limits_t shape        */
    pos_nm_t pos[CORE_AXES];           /* end point of the last queued block */
    int64_t last_ratio_q62[CORE_AXES]; /* direction of the last move   */
    int32_t last_q30[CORE_AXES];       /* the same in q1_30 (truncated)  */
    int64_t last_len;                  /* length of the last move (0: none)  */
    int64_t last_vmax;                 /* v_max of the last move            */
    bool last_stop;                    /* last block ends in an exact stop  */
    uint8_t last_cls;                  /* limit class of the last move (cont) */
    int64_t next_entry;                /* fixed entry speed for a new tail  */
    /* throughput window: lengths of the last W moves */
    int64_t win_len[PLAN_WINDOW_MAX];
    uint16_t win_pos, win_n;
    int64_t win_sum;
    bool same_limits;    /* every axis has the same v, a and j limits      */
    bool v_same;         /* every axis has the same v limit                */
    int64_t aaj0;        /* floor(a^2 / j) of axis 0's limits (plan_init)  */
    int64_t jd_amin_dev; /* min_i a_i * junction_dev_nm, saturated (init) */
    int64_t cruise_v;    /* speed of the last cruise-only block popped    */
    uint64_t cruise_rec; /* its sc_cruise_recip                           */
    bool jd_fast_off;    /* tests only (planner_test.h): false after
                          * plan_init; true skips this planner's
                          * junction-deviation early exit              */
    /* continuous S-curve (planner_cont.c): the plan of the current run
     * from the next block's start on, and the path state there */
    sc_profile_t cont_prof; /* the run's remaining profile              */
    int64_t cont_t_ns;      /* time into cont_prof of the next block    */
    int64_t cont_rem;       /* distance cont_prof still covers, nm (0:
                             * none: the next pop plans from the state) */
    int64_t cont_x;         /* exit bound cont_prof was planned for     */
    sc_state_t cont_st;     /* path state at the next block's start: s on
                             * cont_prof at cont_t_ns, v, a (q16)       */
    uint16_t cont_scan;     /* blocks the last pop's pass saw, and the  */
    uint16_t cont_run_n;    /* blocks of its oldest run (the queue's  */
    int64_t cont_run_len;   /* first blocks), its length (nm)           */
    uint32_t cont_kept;     /* pops that kept cont_prof because no new
                             * plan fitted (tests: rare)                */
    uint32_t cont_forced;   /* pops with no feasible plan (tests: 0)    */
    /* run limits by the axes a block moves (plan_init): mask (bit i: axis
     * i moves; 0: all) -> class, the smallest mask with the same limits;
     * a class's smallest a and j of those axes less 2^-12 */
    uint8_t cont_cls[1u << CORE_AXES];
    int64_t cont_a[1u << CORE_AXES];
    int64_t cont_j[1u << CORE_AXES];
} plan_t;

/* Validate the profile and initialise an empty planner at `start` (nm).
 * storage must hold `depth` blocks (1..65535). Main. */
plan_result_t plan_init(plan_t *p, plan_block_t *storage, uint16_t depth,
                        const plan_profile_t *prof, const pos_nm_t start[CORE_AXES]);

/* Replace the profile of an initialised planner and forget every queued
 * block (plan_reset at the current position). Also recomputes what
 * plan_init derives from the limits (equal-limits fast path, A^2/J bound,
 * the junction-deviation bound): assigning p->prof directly leaves those
 * stale (a pure-Y block then planned with X's limits). On an invalid
 * profile nothing changes. Main. */
plan_result_t plan_set_profile(plan_t *p, const plan_profile_t *prof);

/* Check a profile without initialising anything. */
plan_result_t plan_check_profile(const plan_profile_t *prof);

/* Queue a move or dwell and re-plan. PLAN_SKIPPED for a zero-length move
 * (the position is unchanged; nothing queued). On any error nothing changes.
 * Main. */
plan_result_t plan_push(plan_t *p, const plan_move_t *m);

/* Freeze and remove the oldest block into *out. Main. */
plan_result_t plan_pop(plan_t *p, plan_seg_t *out);

/* Deferred passes (off after plan_init; plan_estimate turns it on). Only
 * with SC_SHAPE_TRAPEZOID or SC_SHAPE_SCURVE_AT_REST (an S-curve profile
 * ignores it: see "S-curve reach" above; the continuous S-curve always
 * plans in plan_pop). When on,
 * plan_push only queues the block and computes its limits; the reverse and
 * forward passes run in plan_pop when the oldest block's exit is not final
 * yet (planned < 2), or in plan_update, once for all blocks queued since the
 * last pass. Popped segments are identical to those of the immediate mode
 * (a final entry never changes; otherwise the passes run first), but the
 * stored entries, `planned` and plan_queued_ns() are only up to date after
 * plan_update(). Turning it off runs the pending passes. Main. */
void plan_set_deferred(plan_t *p, bool on);

/* Run the pending passes (deferred mode); nothing to do otherwise. Main. */
void plan_update(plan_t *p);

/* Forget every queued block (after a stop); the position becomes `pos`. */
void plan_reset(plan_t *p, const pos_nm_t pos[CORE_AXES]);

uint16_t plan_count(const plan_t *p);
uint16_t plan_free_slots(const plan_t *p);

/* Planned time of all queued blocks under the current plan, ns (the host
 * streams by time with it). O(count) closed-form profiles. Main. */
int64_t plan_queued_ns(const plan_t *p);

/* Read access for tests and the estimator: i-th queued block from the oldest. */
const plan_block_t *plan_peek(const plan_t *p, uint16_t i);

#endif /* PLANNER_H */
