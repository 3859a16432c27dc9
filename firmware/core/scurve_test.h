/*
 * scurve_test.h - test hooks of the closed-form profiles (internal: only the
 * unit tests include it). The switches are file-static (scurve has no
 * state object): they change every profile computed while they are off, so
 * a test turns them back on before it returns. Not reentrant.
 */
#ifndef SCURVE_TEST_H
#define SCURVE_TEST_H

#include "scurve.h"

/* sc_muldiv through the 32-bit-digit division (what targets without a
 * 64-bit divider run) on every host. */
int64_t sc_muldiv_portable(int64_t a, int64_t b, int64_t c);
/* sc_reach without the estimate-and-check path (the bracketing
 * Newton steps and chord it falls back to). Not reentrant. */
int64_t sc_reach_bracket(int64_t v, int64_t d, const sc_limits_t *lim);
/* the reach's exact one-comparison distance checks in the
 * reduced S-curve case (on by default; off: sc_dist decides every check;
 * the results are identical). */
void sc_test_dist_fits(bool on);
/* the reduced S-curve reach's closed form (on by default; off:
 * the estimate-and-check path decides; both are lower bounds). */
void sc_test_reach_closed(bool on);
/* the closed form alone (S-curve limits, exact A^2/J): its
 * result, or -1 where it does not apply or its check fails. */
int64_t sc_test_reach_closed_only(int64_t v, int64_t d, const sc_limits_t *lim);

#endif /* SCURVE_TEST_H */
