/*
 * planner_test.h - test hooks of the planner (internal: only the unit tests
 * include it). Each exposes one private step of planner.c, or switches a
 * fast path off, so that a test can compare the fast path with the full
 * computation.
 */
#ifndef PLANNER_TEST_H
#define PLANNER_TEST_H

#include "planner.h"

/* The junction-deviation early exit of planner p (on after plan_init; off:
 * the full computation always runs; the junction speeds are identical).
 * Only p changes: other planners (the host estimator's) keep theirs. */
void plan_test_jd_fast(plan_t *p, bool on);

/* Test hooks: the block limits' multiply-divide (sc_muldiv with one 64/64
 * division when the product fits 64 bits) and the direction ratio
 * floor(a 2^62 / len) (one 128/64 division); both equal sc_muldiv. */
int64_t plan_test_muldiv(int64_t a, int64_t b, int64_t c);
int64_t plan_test_ratio(int64_t a, int64_t len);
/* Test hook: the direction ratio from the block's reciprocal (what
 * plan_push uses): floor(a 2^62 / len) or one less, 0 <= a <= len <= 2^40. */
int64_t plan_test_ratio_rec(int64_t a, int64_t len);
/* Test hook: the equal-limits factor f = floor(l 2^31 / d) (l = len, d = dm
 * when dm < 2^31; else both cut to 31 bits, l down and d up), 0 < dm <= len
 * <= 2 dm, len <= 2^41. */
uint32_t plan_test_len_factor(int64_t len, int64_t dm);

/* Test hook: the continuous S-curve's cruise time and distance
 * (planner_cont.c; recip: with W's reciprocal, else divided): for v_q16 =
 * W 2^16 (0 < W < 2^32) and 0 < dq < 2^42, true with *tau =
 * sc_muldiv_ceil(dq, 1e9, v_q16) and *ds = sc_muldiv(v_q16, *tau, 1e9);
 * false (nothing set) otherwise. */
bool plan_test_cont_cruise_time(int64_t v_q16, int64_t dq, bool recip, int64_t *tau, int64_t *ds);

#endif /* PLANNER_TEST_H */
