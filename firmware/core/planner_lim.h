/*
 * planner_lim.h - the planner's block limits by axis and the join of two
 * chords of one arc: what planner.c calls (planner_lim.c). Internal to the
 * planner. Main context.
 */
#ifndef PLANNER_LIM_H
#define PLANNER_LIM_H

#include "planner.h"

/* floor(a b / c) as sc_muldiv: 0 for a <= 0 or b <= 0, INT64_MAX for
 * c <= 0, saturated; cheaper when a b fits 64 bits. */
int64_t plan_lim_muldiv(int64_t a, int64_t b, int64_t c);

/* min over the axes with d_i != 0 of floor(lim_i len / |d_i|), INT64_MAX
 * when no axis moves; lim_i > 0, |d_i| < 2^63, len >= 0. */
int64_t plan_axis_limit(const int64_t *lim, const int64_t *d, int64_t len);

/* plan_push's exact block limits of a move d (len > 0 its length):
 * returns min(feed, the axes' v limit projected on d); lim[0], lim[1] the
 * projected a and j (at most SC_A_LIMIT, SC_J_LIMIT), or 0 and -1 for the
 * continuous S-curve with axes of different limits, which reads neither:
 * then b->cont_cls is set (the class of the axes d moves) and
 * plan_cont_class gives b its class's a and j. */
int64_t plan_limits_exact(const plan_t *p, plan_block_t *b, const int64_t *d, int64_t len,
                          int64_t feed, int64_t *lim);

/* Junction speed of a PLAN_MOVE_ARC_JOIN move (new direction w2 in q30,
 * d its move, len2 its length, jt its j_max or -1: then from d) after the
 * last queued one: 0 at an axis reversal or with PLAN_CORNER_STOP, else
 * the arc's centripetal limits at the radius of the join (nm/s,
 * INT64_MAX: none). */
int64_t plan_arc_corner(const plan_t *p, const int32_t *w2, const int64_t *d, int64_t len2,
                        int64_t jt);

#endif
