/*
 * fixmath_test.h - test hooks of fixmath (internal: the unit tests and the
 * portable-path hooks of other modules include it, the firmware's callers
 * do not).
 */
#ifndef FIXMATH_TEST_H
#define FIXMATH_TEST_H

#include "fixmath.h"

/* fx_udivmod64 and fx_udiv128 through the 32-bit-digit code that 32-bit
 * targets run (hosts with a 64-bit divider use it in those two), callable
 * on every host so that the tests compare the two. */
uint64_t fx_udivmod64_digits(uint64_t n, uint64_t d, uint64_t *rem);
uint64_t fx_udiv128_digits(uint64_t hi, uint64_t lo, uint64_t d, uint64_t *rem);

#endif /* FIXMATH_TEST_H */
