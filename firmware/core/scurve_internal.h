/*
 * scurve_internal.h - what scurve.c (wide arithmetic, distances, one block)
 * and scurve_reach.c (the reach) share; not part of the interface
 * (scurve.h). Main context, like the rest of scurve.
 */
#ifndef SCURVE_INTERNAL_H
#define SCURVE_INTERNAL_H

#include "fixmath.h"
#include "scurve.h"

#define NS ((uint64_t)1000000000u)
/* floor(sqrt(INT64_MAX)): squares up to it fit int64 */
#define SC_SQRT_INT64_MAX ((int64_t)3037000499)
/* 2^72 / 1e9 rounded: ns -> seconds * 2^40 with one multiply (>> 32) */
#define SC_NS_TO_Q40 ((int64_t)4722366482870)

/* a * b; factors below 2^32 take one 32 x 32 -> 64 multiply */
static inline fx_u128_t sc_mul(uint64_t a, uint64_t b)
{
    fx_u128_t r;

    if (((a | b) >> 32) == 0) {
        r.hi = 0;
        r.lo = a * b;
        return r;
    }
    return fx_umul64(a, b);
}

/* The limits to use for a profile whose lowest speed involved is `lo`: for
 * SC_SHAPE_SCURVE_AT_REST a copy in *tmp with the S-curve (lo <= 0) or the
 * trapezoid; the other shapes unchanged. */
static inline const sc_limits_t *sc_resolve(const sc_limits_t *lim, int64_t lo, sc_limits_t *tmp)
{
    if (lim->shape != SC_SHAPE_SCURVE_AT_REST) {
        return lim;
    }
    *tmp = *lim;
    tmp->shape = (uint8_t)((lo <= 0) ? SC_SHAPE_SCURVE : SC_SHAPE_TRAPEZOID);
    return tmp;
}

/* floor(A^2/J) and ceil(A^2/J) from one division */
void sc_aaj(int64_t a, int64_t j, int64_t *qf, int64_t *qc);
/* sc_dist with qc = ceil(A^2/J) supplied (< 0: computed here) */
int64_t sc_dist_q(int64_t va, int64_t vb, const sc_limits_t *lim, int64_t qc);
/* ceil(sqrt(x)) of a 128-bit value */
uint64_t sc_isqrt128_ceil(fx_u128_t x);
/* The reach in nm/s * 2^16 for a distance dq in nm * 2^16 (scurve_reach.c). */
int64_t sc_reach_q16(int64_t v, int64_t dq, const sc_limits_t *lim, int64_t q, int64_t qc,
                     bool closed);

#endif /* SCURVE_INTERNAL_H */
