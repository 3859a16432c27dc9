/*
 * planner_cont.h - the continuous S-curve of the planner
 * (SC_SHAPE_SCURVE_CONTINUOUS; planner.h, "Continuous S-curve"): what
 * planner.c calls. Internal to the planner. Main context.
 */
#ifndef PLANNER_CONT_H
#define PLANNER_CONT_H

#include "planner.h"

/* The run limits' table of the profile p->prof (plan_t cont_cls, cont_a,
 * cont_j); returns the smallest axis a (nm/s^2). plan_init and
 * plan_set_profile. */
int64_t plan_cont_derive(plan_t *p);

/* Axes with different limits (not same_limits), this shape: the limit
 * class of the block just queued (b, its v_junction, lim.v_max and
 * cont_cls set: plan_push) gives its lim a and j and,
 * where the class changes, its junction 1 nm/s below v_max (an anchor).
 * plan_push. */
void plan_cont_class(plan_t *p, plan_block_t *b);

/* The profile keeps a run's candidate distances (pc_r1) in q16:
 * 3 v^2 / (2 a) <= 2^44 nm with the largest axis v and the smallest a.
 * plan_check_profile. */
bool plan_cont_profile_ok(const plan_profile_t *prof);

/* Forget the run's plan and the counters: at rest (plan_reset). */
void plan_cont_reset(plan_t *p);

/* plan_pop of a move block (count >= 1, the oldest block not a dwell):
 * fills out->prof and out->total_ns. */
void plan_cont_pop(plan_t *p, plan_seg_t *out);

/* plan_queued_ns for this shape. */
int64_t plan_cont_queued_ns(const plan_t *p);

#endif /* PLANNER_CONT_H */
