/*
 * cec_test.h - test hooks of cec (internal: the unit tests include it, the
 * firmware's callers do not).
 */
#ifndef CEC_TEST_H
#define CEC_TEST_H

#include "cec.h"

/* The exact arc distance's root, floor(sqrt(v)), from the first-order step
 * about the radius r with inv ~ 2^30 / r (any inv: exact), falling back to
 * fx_isqrt64_near from *hint (which it updates). */
uint32_t cec_arc_root_test(uint64_t v, pos_nm_t r, pid_coef_t inv, uint32_t *hint);

/* The normalisation's division: fx_div_sat32(num, den, 30), by one 64-bit
 * division where it fits. */
int32_t cec_div_q30_test(int64_t num, int32_t den);

/* cec_step by its general path alone (the oracle of its usual exact arc
 * tick). */
void cec_step_general_test(cec_t *c, const motion_ref_t *ref, const pos_nm_t meas[CORE_AXES]);

#endif /* CEC_TEST_H */
