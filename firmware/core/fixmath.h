/*
 * fixmath.h - fixed-point arithmetic for the whole firmware core.
 *
 * Specification
 * -------------
 * Every quantity in the core is an integer with a named format. The names
 * below are the only Q formats the core uses; a new one is added here first.
 *
 *   pos_nm_t    int64_t   position in nanometres (machine units). 2^63 nm is
 *                         9.2e6 km: no travel overflows, nothing drifts.
 *   q16_16_t    int32_t   general signed value, 16 integer + 16 fraction bits,
 *                         range [-32768, 32768), resolution 1.5e-5.
 *   q1_30_t     int32_t   ratio, unit-vector component, sin/cos: range [-2, 2),
 *                         resolution 9.3e-10. FX_ONE_Q30 is 1.0.
 *   q32_32_t    int64_t   wide signed value for accumulators and gains.
 *   fx_angle_t  uint32_t  binary angle: a full turn is 2^32, so angle
 *                         arithmetic wraps exactly (0x40000000 = 90 degrees).
 *                         One LSB is 2^-32 turn = 1.46e-9 rad.
 *
 * Rounding (every function states which rule it follows):
 *   shift     round to nearest, ties toward +inf (add half an LSB, then
 *             arithmetic shift): fx_round_shift64, fx_mul32_shift,
 *             fx_sat_mul32, fx_mul64x32_shift, fx_mul64_shift,
 *             fx_pos_scale_q16/q30 and the fx_qX_from_qY / fx_qX_to_int
 *             conversions that drop bits. Example: 1.5 -> 2, -1.5 -> -1.
 *   division  round to nearest, ties away from zero (sign-symmetric):
 *             fx_div_round64, fx_div_shift64, fx_div_sat32, fx_muldiv64,
 *             fx_recip_q16. Example: 3/2 -> 2, -3/2 -> -2.
 *   floor     fx_isqrt32/64, fx_icbrt64, fx_hypot2/3 (exact floor).
 * Saturating functions clamp to the format's range instead of wrapping; the
 * plain ones are documented as exact. No function has undefined behaviour
 * for any argument value: out-of-range shift counts and zero divisors give
 * the documented result.
 *
 * Error bounds (asserted by tests/unit/test_fixmath.c, exhaustively over small
 * domains and against a double / 128-bit reference over the full domains):
 *   fx_isqrt32/64, fx_icbrt64   exact floor.
 *   fx_hypot2, fx_hypot3        exact floor of the true length for every
 *                               input, saturated to INT64_MAX.
 *   fx_sin, fx_cos, fx_sincos   |error| < 1 LSB of q1_30 (9.3e-10): the
 *                               result is one of the two q1_30 neighbours of
 *                               the exact value (max 0.960 LSB, measured over
 *                               every angle); exact 0 and +/-1 at multiples
 *                               of 90 degrees, |result| <= FX_ONE_Q30, sin
 *                               odd, cos even, cos(a) == sin(90deg - a), sin
 *                               non-decreasing on [-90, 90] degrees.
 *   fx_atan2                    |error| <= 0.6 LSB of fx_angle_t (2^-32 turn,
 *                               8.8e-10 rad) for every input (analysis: 0.5
 *                               rounding + 0.08 CORDIC residual; max 0.58
 *                               measured); exact on the axes and diagonals.
 *   all the others              exact (after the stated rounding and
 *                               saturation).
 *
 * Cost: no 64-bit division anywhere on 32-bit targets (Cortex-M4 has only a
 * 32/32 divider and a 32 x 32 -> 64 multiplier, and the compiler's 64-bit
 * division helper is a shift-subtract loop). Divisions (fx_div*, fx_muldiv64,
 * fx_udiv128, fx_udivmod64) are long divisions with 32-bit digits, each digit
 * estimated with the hardware divider and corrected (Knuth's algorithm D);
 * hosts with a 64-bit divider (compilers with __int128) use it instead, with
 * identical results. Roots are Newton iterations from above seeded from a
 * table (square root) or a power of two (cube root), exact by construction.
 * Instructions per call on the Cortex-M4 (QEMU -icount, docs/ports.md,
 * operands typical of the planner): fx_isqrt64 ~120 (40 below 2^32),
 * fx_icbrt64 ~240, fx_mul64_shift ~60 (35 when both operands fit 32 bits),
 * fx_mul64x32_shift ~100 (60), fx_div_round64 ~100, a 128/64 division by
 * 10^9 ~75 (a precomputed reciprocal), by another 32-bit divisor ~110.
 *
 * Contexts: all functions are pure and reentrant (callable from any context,
 * interrupts included). No floating point, no heap, no libc.
 */
#ifndef FIXMATH_H
#define FIXMATH_H

#include <stdbool.h>
#include <stdint.h>

typedef int64_t pos_nm_t;
typedef int32_t q16_16_t;
typedef int32_t q1_30_t;
typedef int64_t q32_32_t;
typedef uint32_t fx_angle_t;

#define FX_ONE_Q16 ((q16_16_t)1 << 16)
#define FX_ONE_Q30 ((q1_30_t)1 << 30)
#define FX_ONE_Q32 ((q32_32_t)1 << 32)

#define FX_ANGLE_45  ((fx_angle_t)0x20000000u)
#define FX_ANGLE_90  ((fx_angle_t)0x40000000u)
#define FX_ANGLE_180 ((fx_angle_t)0x80000000u)
#define FX_ANGLE_270 ((fx_angle_t)0xC0000000u)

/* Integer (or format-preserving) conversions for constants; n must be in
 * range (|n| < 32768). Use fx_q16_from_int for run-time values. */
#define FX_INT_TO_Q16(n) ((q16_16_t)((int32_t)(n)*65536))

/* ---- saturation and saturating arithmetic ------------------------------- */

int32_t fx_sat32(int64_t v); /* v clamped to [INT32_MIN, INT32_MAX] */
int32_t fx_sat_add32(int32_t a, int32_t b);
int32_t fx_sat_sub32(int32_t a, int32_t b);
int32_t fx_sat_neg32(int32_t a); /* -INT32_MIN gives INT32_MAX */
int32_t fx_sat_abs32(int32_t a); /* |INT32_MIN| gives INT32_MAX */
int64_t fx_sat_add64(int64_t a, int64_t b);
int64_t fx_sat_sub64(int64_t a, int64_t b);

/* -a and |a|; -INT64_MIN and |INT64_MIN| give INT64_MAX. Inline (the tick's
 * estimators use them). */
static inline int64_t fx_sat_neg64(int64_t a)
{
    return (a == INT64_MIN) ? INT64_MAX : -a;
}

static inline int64_t fx_sat_abs64(int64_t a)
{
    return (a < 0) ? fx_sat_neg64(a) : a;
}

/* Inline forms for the per-tick loops (pid.c, cec.c, servo.c).
 * fx_sat32_fast(v) == fx_sat32(v); fx_sat_diff32(a, b) == fx_sat32(a - b)
 * computed without overflowing the int64 subtraction (equal to
 * fx_sat32(fx_sat_sub64(a, b))). */
static inline int32_t fx_sat32_fast(int64_t v)
{
    return (v > INT32_MAX) ? INT32_MAX : (v < INT32_MIN) ? INT32_MIN : (int32_t)v;
}

/* fx_sat_diff32 as the 32-bit targets compile it (the host form's oracle,
 * test_fixmath.c: test_sat_diff32_host_equals_wrap). */
static inline int32_t fx_sat_diff32_wrap(int64_t a, int64_t b)
{
    /* the wrapped difference; it overflowed when a and b differ in sign and
     * d's sign is not a's (then the exact value lies beyond a's side) */
    int64_t d = (int64_t)((uint64_t)a - (uint64_t)b);

    if (((a ^ b) & (a ^ d)) < 0) {
        return (a < 0) ? INT32_MIN : INT32_MAX;
    }
    if (d == (int64_t)(int32_t)d) {
        return (int32_t)d;
    }
    return (d < 0) ? INT32_MIN : INT32_MAX;
}

/* 64-bit GCC hosts test the subtraction's own overflow flag (x86 JO: 5
 * instructions fewer per call, 33 per simulated tick of the HIL bench);
 * the Cortex-M4 keeps the wrapped form (its SBCS + BVS costs the control
 * tick 16 instructions more). FX_SUB_OVERFLOW=0 selects the wrapped form. */
#if !defined(FX_SUB_OVERFLOW) && defined(__GNUC__) && UINTPTR_MAX > 0xFFFFFFFFu
#define FX_SUB_OVERFLOW 1
#elif !defined(FX_SUB_OVERFLOW)
#define FX_SUB_OVERFLOW 0
#endif

static inline int32_t fx_sat_diff32(int64_t a, int64_t b)
{
#if FX_SUB_OVERFLOW
    int64_t d;

    if (__builtin_sub_overflow(a, b, &d)) {
        return (a < 0) ? INT32_MIN : INT32_MAX;
    }
    if (d == (int64_t)(int32_t)d) {
        return (int32_t)d;
    }
    return (d < 0) ? INT32_MIN : INT32_MAX;
#else
    return fx_sat_diff32_wrap(a, b);
#endif
}

/* the smaller and the larger of a and b */
static inline int64_t fx_min64(int64_t a, int64_t b)
{
    return (a < b) ? a : b;
}

static inline int64_t fx_max64(int64_t a, int64_t b)
{
    return (a > b) ? a : b;
}

/* v limited to [-lim, lim] for lim >= 0 (== fx_clamp64(v, -lim, lim)),
 * inline for the tick. */
static inline int64_t fx_clamp_sym64(int64_t v, int64_t lim)
{
    return (v > lim) ? lim : (v < -lim) ? -lim : v;
}

/* v saturated to the unsigned ranges of the wire formats: [0, 2^32 - 1]
 * and [0, 2^16 - 1]. */
static inline uint32_t fx_sat_u32(int64_t v)
{
    return (v < 0) ? 0u : (v > (int64_t)UINT32_MAX) ? UINT32_MAX : (uint32_t)v;
}

static inline uint16_t fx_sat_u16(uint32_t v)
{
    return (v > 0xFFFFu) ? (uint16_t)0xFFFFu : (uint16_t)v;
}

/* |v| as uint64_t, exact for every v (|INT64_MIN| is 2^63). */
static inline uint64_t fx_uabs64(int64_t v)
{
    return (v < 0) ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
}

/* The int64 of magnitude m and sign neg (negative when neg), saturated to
 * [INT64_MIN, INT64_MAX]; ok == false means the magnitude exceeded 64 bits
 * (saturates too). */
static inline int64_t fx_signed_sat(bool ok, uint64_t m, bool neg)
{
    if (neg) {
        if (!ok || m > (uint64_t)INT64_MAX + 1u) {
            return INT64_MIN;
        }
        return (int64_t)((uint64_t)0 - m);
    }
    if (!ok || m > (uint64_t)INT64_MAX) {
        return INT64_MAX;
    }
    return (int64_t)m;
}

/* min(max(v, lo), hi): v limited to [lo, hi]. lo <= hi is expected; if
 * lo > hi the result is hi (the upper limit wins). */
int32_t fx_clamp32(int32_t v, int32_t lo, int32_t hi);
int64_t fx_clamp64(int64_t v, int64_t lo, int64_t hi);

/* ---- shifts and multiplications (rounding: shift rule) ------------------- */

/* 64-bit hosts round a shift by floor((floor(v / 2^(s-1)) + 1) / 2) for
 * s >= 2 (three x86 instructions with a constant s instead of five: the
 * HIL tick 2960 -> 2934 instructions); the same value as the dropped-bit
 * form, which the Cortex-M4 keeps (test_fixmath.c:
 * test_round_shift64_host_equals_bit). FX_ROUND_INC=0 selects the
 * dropped-bit form. */
#if !defined(FX_ROUND_INC) && UINTPTR_MAX > 0xFFFFFFFFu
#define FX_ROUND_INC 1
#elif !defined(FX_ROUND_INC)
#define FX_ROUND_INC 0
#endif

/* fx_round_shift64's dropped-bit form for s in 1..63: floor(v / 2^s) plus
 * the first dropped bit (round half up, no overflow). */
static inline int64_t fx_round_shift64_bit(int64_t v, unsigned s)
{
    return (v >> s) + ((v >> (s - 1)) & 1);
}

/* round(v / 2^s). Exact for s = 0; any s >= 64 gives 0. Never overflows.
 * Inline: with a constant s (the tick's use) it is two instructions. */
static inline int64_t fx_round_shift64(int64_t v, unsigned s)
{
    if (s == 0) {
        return v;
    }
    if (s >= 64) {
        return 0; /* |v / 2^s| <= 1/2, and -1/2 rounds up to 0 */
    }
#if FX_ROUND_INC
    if (s >= 2) {
        /* |v / 2^(s-1)| <= 2^62: the increment does not overflow */
        return ((v >> (s - 1)) + 1) >> 1;
    }
#endif
    return fx_round_shift64_bit(v, s);
}

/* round(a * b / 2^s) from the exact 64-bit product. Never overflows; s >= 64
 * gives 0 (s = 0..62 is the useful range). Inline (one SMULL and the shift
 * for a constant s). */
static inline int64_t fx_mul32_shift(int32_t a, int32_t b, unsigned s)
{
    return fx_round_shift64((int64_t)a * b, s);
}

/* round(a * b / 2^s), saturated to int32 (e.g. q16 * q16 with s = 16). */
int32_t fx_sat_mul32(int32_t a, int32_t b, unsigned s);

/* round(a * b / 2^s) with a 96-bit intermediate, saturated to int64: scales
 * a 64-bit position by a 32-bit ratio (e.g. pos_nm by q1_30, s = 30). Any s is
 * accepted (s >= 96 gives 0). */
int64_t fx_mul64x32_shift(int64_t a, int32_t b, unsigned s);

/* round(a * b / 2^s) for two int64 values, exact 128-bit intermediate,
 * saturated to int64. Any s is accepted; s >= 128 gives 0. */
int64_t fx_mul64_shift(int64_t a, int64_t b, unsigned s);

/* fx_mul32_shift(a, b, 30) as one SMLAL of the product and half an LSB and
 * a shift (|a * b| <= 2^62: the sum cannot overflow); fx_mul32_shift's
 * overflow-free rounding of any int64 costs the arc reference's cruise
 * tick 11 more instructions on the M4 (tests/unit/test_fixmath_fast.c). */
static inline int64_t fx_mul32_q30(int32_t a, int32_t b)
{
    return ((int64_t)a * b + ((int64_t)1 << 29)) >> 30;
}

/* Inline forms for the tick, with a one-multiply path when the operands fit
 * 32 bits: fx_mul64_sat(a, b) == fx_mul64_shift(a, b, 0) (a * b saturated
 * to int64), fx_mul64x32_shift30(a, b) == fx_mul64x32_shift(a, b, 30). */
static inline int64_t fx_mul64_sat(int64_t a, int64_t b)
{
    if (a == (int32_t)a && b == (int32_t)b) {
        return (int64_t)(int32_t)a * (int32_t)b;
    }
    return fx_mul64_shift(a, b, 0);
}

static inline int64_t fx_mul64x32_shift30(int64_t a, int32_t b)
{
    if (a == (int32_t)a) { /* |a * b| <= 2^62: exact in int64 */
        return fx_mul32_q30((int32_t)a, b);
    }
    return fx_mul64x32_shift(a, b, 30);
}

/* Position times a ratio, rounded and saturated to int64:
 * round(p * r / 2^16) and round(p * r / 2^30). */
pos_nm_t fx_pos_scale_q16(pos_nm_t p, q16_16_t r);
pos_nm_t fx_pos_scale_q30(pos_nm_t p, q1_30_t r);

/* ---- 128-bit products and bit lengths (inline, exact) ----------------------
 * The only 64 x 64 -> 128 product of the firmware: four 32 x 32 -> 64
 * multiplies on every target (the host tests run the code the Cortex-M4
 * runs). fx_umulhi64 is its high word (inlined, the compiler drops the low
 * word's carries it does not need). */
typedef struct {
    uint64_t hi;
    uint64_t lo;
} fx_u128_t;

/* The product in 32 x 32 -> 64 pieces (the form of targets without a
 * 128-bit type: the Cortex-M4). */
static inline fx_u128_t fx_umul64_pieces(uint64_t a, uint64_t b)
{
    uint64_t a_lo = (uint32_t)a, a_hi = a >> 32;
    uint64_t b_lo = (uint32_t)b, b_hi = b >> 32;
    uint64_t ll = a_lo * b_lo;
    uint64_t lh = a_lo * b_hi;
    uint64_t hl = a_hi * b_lo;
    uint64_t mid = (ll >> 32) + (uint32_t)lh + (uint32_t)hl;
    fx_u128_t r;

    r.lo = (mid << 32) | (uint32_t)ll;
    r.hi = a_hi * b_hi + (lh >> 32) + (hl >> 32) + (mid >> 32);
    return r;
}

/* Host-only form (docs/fast-paths.md): a 64-bit host with a 128-bit type
 * (GCC, Clang: __SIZEOF_INT128__; not the 32-bit M4) takes the product in
 * one multiply; the same 128 bits (test_fixmath.c:
 * test_umul64_host_equals_pieces). FX_MUL_PIECES=1 keeps the pieces. */
#if !defined(FX_MUL_PIECES) && defined(__SIZEOF_INT128__)
#define FX_MUL_PIECES 0
#elif !defined(FX_MUL_PIECES)
#define FX_MUL_PIECES 1
#endif

#if FX_MUL_PIECES
static inline fx_u128_t fx_umul64(uint64_t a, uint64_t b)
{
    return fx_umul64_pieces(a, b);
}
#else
__extension__ typedef unsigned __int128 fx_host_u128;

static inline fx_u128_t fx_umul64(uint64_t a, uint64_t b)
{
    fx_host_u128 p = (fx_host_u128)a * b;
    fx_u128_t r;

    r.lo = (uint64_t)p;
    r.hi = (uint64_t)(p >> 64);
    return r;
}
#endif

/* floor(a * b / 2^64) */
static inline uint64_t fx_umulhi64(uint64_t a, uint64_t b)
{
    return fx_umul64(a, b).hi;
}

/* a * b for b < 2^32 (a 96-bit product) from two 32 x 32 -> 64 multiplies
 * (the pieces form; a host with a 128-bit type: one multiply, as
 * fx_umul64) */
static inline fx_u128_t fx_umul64x32_pieces(uint64_t a, uint32_t b)
{
    uint64_t lo = (uint64_t)(uint32_t)a * b;
    uint64_t hi = (a >> 32) * b + (lo >> 32); /* < 2^64: one UMLAL */
    fx_u128_t r;

    r.lo = (hi << 32) | (uint32_t)lo;
    r.hi = hi >> 32;
    return r;
}

static inline fx_u128_t fx_umul64x32(uint64_t a, uint32_t b)
{
#if FX_MUL_PIECES
    return fx_umul64x32_pieces(a, b);
#else
    return fx_umul64(a, b);
#endif
}

/* a + b mod 2^128 */
static inline fx_u128_t fx_add128(fx_u128_t a, fx_u128_t b)
{
    fx_u128_t r;

    r.lo = a.lo + b.lo;
    r.hi = a.hi + b.hi + (r.lo < a.lo ? 1u : 0u);
    return r;
}

/* -1, 0 or 1 as a <, == or > b */
static inline int fx_cmp128(fx_u128_t a, fx_u128_t b)
{
    if (a.hi != b.hi) {
        return (a.hi < b.hi) ? -1 : 1;
    }
    if (a.lo != b.lo) {
        return (a.lo < b.lo) ? -1 : 1;
    }
    return 0;
}

/* round(+-ua * ub / 2^(64 + t)) (shift rule; negative when neg) for
 * magnitudes ua, ub <= 2^63 and 1 <= t <= 63: fx_mul64_shift(+-ua, ub,
 * 64 + t) in inline form from the product's high word (the low word only
 * decides ties of negative values). For callers that keep a magnitude and a
 * sign per axis (the interpolator's q62 direction ratios, t = 14). */
static inline int64_t fx_umul_shift_hi(uint64_t ua, uint64_t ub, bool neg, unsigned t)
{
    fx_u128_t p = fx_umul64(ua, ub);
    uint64_t half = (uint64_t)1 << (t - 1u);

    if (neg) { /* -floor((|p| + 2^(63 + t) - 1) / 2^(64 + t)) */
        return -(int64_t)((p.hi + half - (p.lo == 0u ? 1u : 0u)) >> t);
    }
    return (int64_t)((p.hi + half) >> t);
}

/* round(a * b / 2^32) (shift rule) == fx_mul64x32_shift(a, b, 32) for every
 * int64 a and int32 b (|a * b| <= 2^94: never saturates), inline: two
 * 32 x 32 -> 64 products. */
static inline int64_t fx_mul64x32_shift32_pieces(int64_t a, int32_t b)
{
    fx_u128_t p = fx_umul64x32(fx_uabs64(a), (uint32_t)fx_uabs64(b));
    uint64_t hi = (p.hi << 32) | (p.lo >> 32); /* |a * b| >> 32 */
    uint32_t l32 = (uint32_t)p.lo;

    if ((a < 0) != (b < 0)) { /* -floor((|p| + 2^31 - 1) / 2^32) */
        return -(int64_t)(hi + (((uint64_t)l32 + 0x7FFFFFFFu) >> 32));
    }
    return (int64_t)(hi + (((uint64_t)l32 + 0x80000000u) >> 32));
}

/* The same value: floor((a b + 2^31) / 2^32) from the signed 128-bit
 * product on hosts with one (FX_MUL_PIECES 0: no magnitudes and sign
 * fix-up; the interpolator's cruise correction, test_fixmath.c:
 * test_mul_q30_host_equals_pieces), the magnitudes' form elsewhere. */
static inline int64_t fx_mul64x32_shift32(int64_t a, int32_t b)
{
#if FX_MUL_PIECES
    return fx_mul64x32_shift32_pieces(a, b);
#else
    __extension__ typedef __int128 fx_host_i128;
    return (int64_t)(((fx_host_i128)a * b + ((fx_host_i128)1 << 31)) >> 32);
#endif
}

/* Number of leading zero bits of v != 0 (32-bit CLZ only: Cortex-M4 has no
 * 64-bit one). fx_bitlen64(v) is the bit length, 0 for v == 0. */
static inline unsigned fx_clz32(uint32_t v)
{
#if defined(__GNUC__)
    return (unsigned)__builtin_clz(v);
#else
    unsigned n = 0;

    while (!(v & 0x80000000u)) {
        v <<= 1;
        n++;
    }
    return n;
#endif
}

static inline unsigned fx_clz64(uint64_t v)
{
    uint32_t hi = (uint32_t)(v >> 32);

    return (hi != 0u) ? fx_clz32(hi) : 32u + fx_clz32((uint32_t)v);
}

static inline unsigned fx_bitlen64(uint64_t v)
{
    return (v == 0u) ? 0u : 64u - fx_clz64(v);
}

/* An int32 the compiler must keep as a plain 32-bit register (so that a
 * widening product stays one SMULL/SMLAL instead of a 64 x 64 multiply); no
 * effect on the value. */
static inline int32_t fx_opaque32(int32_t v)
{
#if defined(__GNUC__)
    __asm__("" : "+r"(v));
#endif
    return v;
}

/* round(a * b / 2^30) (shift rule) == fx_mul64x32_shift(a, b, 30) for
 * |a| <= 2^61 and 0 <= b <= 2^30, without a 96-bit product: a = ah * 2^32 +
 * al with al unsigned; a * b = ah * b * 2^32 + al * b (one SMULL, one
 * UMULL). The PID's filter and back-calculation gains. */
static inline int64_t fx_mul_q30_pos_pieces(int64_t a, q1_30_t b)
{
    int32_t ah = fx_opaque32((int32_t)(a >> 32)); /* |ah| <= 2^29 */
    uint32_t al = (uint32_t)a;
    int64_t h = (int64_t)ah * b;              /* |h| <= 2^59 */
    uint64_t lo = (uint64_t)al * (uint32_t)b; /* < 2^62 */
    return (int64_t)((uint64_t)h << 2) + (int64_t)((lo + ((uint64_t)1 << 29)) >> 30);
}

/* The same value, floor((a b + 2^29) / 2^30), from the signed 128-bit
 * product on hosts with one (FX_MUL_PIECES 0; the PID's D filter and
 * back-calculation; test_fixmath.c: test_mul_q30_host_equals_pieces), the
 * two 32-bit pieces elsewhere. */
static inline int64_t fx_mul_q30_pos(int64_t a, q1_30_t b)
{
#if FX_MUL_PIECES
    return fx_mul_q30_pos_pieces(a, b);
#else
    __extension__ typedef __int128 fx_host_i128;
    return (int64_t)(((fx_host_i128)a * b + ((fx_host_i128)1 << 29)) >> 30);
#endif
}

/* |v| <= max for max <= 2^31 - 1, with one add and one unsigned compare:
 * v + max (mod 2^32) lies in [0, 2 max] exactly when |v| <= max (above:
 * v + max <= 2^31 - 1 + max < 2^32; below: v + max >= 2^31 + max > 2 max
 * mod 2^32). */
static inline bool fx_in_range32(int32_t v, uint32_t max)
{
    return (uint32_t)v + max <= 2u * max;
}

/* round(x * m / 2^sh) for sh in 1..31 with rnd = 2^(sh - 1) preloaded (the
 * caller keeps it with m and sh): one multiply-accumulate and a funnel
 * shift. fx_mul_rsh32 for a result known to fit 32 bits, fx_mul_rsh64 for
 * any (== fx_mul32_shift(x, m, sh)). The PID's fast-path products. The
 * _pieces forms shift in 32-bit halves (the Cortex-M4 has no 64-bit
 * shift); 64-bit hosts shift the sum in one instruction, the same value
 * (|x m| <= 2^62: the signed sum does not overflow; test_fixmath.c:
 * test_mul_rsh_and_mul_q30_pos compares both forms). FX_RSH_PIECES=1 keeps
 * the pieces. */
#if !defined(FX_RSH_PIECES) && UINTPTR_MAX > 0xFFFFFFFFu
#define FX_RSH_PIECES 0
#elif !defined(FX_RSH_PIECES)
#define FX_RSH_PIECES 1
#endif

static inline int32_t fx_mul_rsh32_pieces(int32_t x, int32_t m, unsigned sh, uint32_t rnd)
{
    uint64_t u = (uint64_t)rnd + (uint64_t)((int64_t)x * m);

    return (int32_t)(((uint32_t)u >> sh) | ((uint32_t)(u >> 32) << (32u - sh)));
}

static inline int64_t fx_mul_rsh64_pieces(int32_t x, int32_t m, unsigned sh, uint32_t rnd)
{
    uint64_t u = (uint64_t)rnd + (uint64_t)((int64_t)x * m);
    uint32_t lo = (uint32_t)u, hi = (uint32_t)(u >> 32);
    uint32_t rlo = (lo >> sh) | (hi << (32u - sh));
    uint32_t rhi = (uint32_t)((int32_t)hi >> sh);

    return (int64_t)(((uint64_t)rhi << 32) | rlo);
}

static inline int64_t fx_mul_rsh64(int32_t x, int32_t m, unsigned sh, uint32_t rnd)
{
#if FX_RSH_PIECES
    return fx_mul_rsh64_pieces(x, m, sh, rnd);
#else
    return ((int64_t)x * m + (int64_t)rnd) >> sh;
#endif
}

static inline int32_t fx_mul_rsh32(int32_t x, int32_t m, unsigned sh, uint32_t rnd)
{
#if FX_RSH_PIECES
    return fx_mul_rsh32_pieces(x, m, sh, rnd);
#else
    return (int32_t)fx_mul_rsh64(x, m, sh, rnd);
#endif
}

/* ---- conversions between the named formats -------------------------------- */

/* Widening conversions are exact; narrowing ones round (shift rule) and
 * saturate to the destination's range. */
q16_16_t fx_q16_from_int(int32_t n);  /* n * 2^16, saturated          */
int32_t fx_q16_to_int(q16_16_t v);    /* round(v / 2^16)               */
q1_30_t fx_q30_from_q16(q16_16_t v);  /* v * 2^14, saturated to [-2, 2) */
q16_16_t fx_q16_from_q30(q1_30_t v);  /* round(v / 2^14)               */
q32_32_t fx_q32_from_int(int64_t n);  /* n * 2^32, saturated           */
int64_t fx_q32_to_int(q32_32_t v);    /* round(v / 2^32)               */
q32_32_t fx_q32_from_q16(q16_16_t v); /* v * 2^16, exact              */
q16_16_t fx_q16_from_q32(q32_32_t v); /* round(v / 2^16), saturated   */
q32_32_t fx_q32_from_q30(q1_30_t v);  /* v * 2^2, exact               */
q1_30_t fx_q30_from_q32(q32_32_t v);  /* round(v / 2^2), saturated    */

/* ---- division (rounding: division rule, ties away from zero) -------------- */

/* round(num * 2^s / den), exact 128-bit numerator, saturated to int64. Any s
 * is accepted. den == 0 saturates toward the sign of num (0 / 0 gives 0). */
int64_t fx_div_shift64(int64_t num, int64_t den, unsigned s);

/* round(num * 2^s / den), saturated to int32; den == 0 saturates toward the
 * sign of num (0 / 0 gives 0). Defined for every num and s (no longer limited
 * to |num| < 2^(63-s): larger values saturate, as the true quotient does).
 * For a 64-bit divisor, e.g. a q1_30 unit-vector component dx / len of a long
 * move, use fx_sat32(fx_div_shift64(dx, len, 30)). */
int32_t fx_div_sat32(int64_t num, int32_t den, unsigned s);

/* round(num / den) for int64; den == 0 saturates like above, and
 * INT64_MIN / -1 gives INT64_MAX. */
int64_t fx_div_round64(int64_t num, int64_t den);

/* round(a * b / c) with an exact 128-bit product, saturated to int64; c == 0
 * saturates toward the sign of a * b (0 if a * b == 0). For the planner:
 * distance * time / length and the like without intermediate overflow. */
int64_t fx_muldiv64(int64_t a, int64_t b, int64_t c);

/* Unsigned division, exact: floor(n / d) with *rem = n mod d. d == 0 gives
 * UINT64_MAX and *rem = 0. */
uint64_t fx_udivmod64(uint64_t n, uint64_t d, uint64_t *rem);

/* floor((hi * 2^64 + lo) / d) with *rem the remainder, for hi < d (the
 * quotient fits 64 bits); hi >= d (d == 0 included) gives UINT64_MAX and
 * *rem = 0. */
uint64_t fx_udiv128(uint64_t hi, uint64_t lo, uint64_t d, uint64_t *rem);

/* Reciprocal 1/x in q16_16 of a q16_16 value: round(2^32 / x), saturated
 * to int32 (x = 0, 1, 2 give INT32_MAX, x = -1 gives INT32_MIN; x = -2 gives
 * INT32_MIN exactly). */
q16_16_t fx_recip_q16(q16_16_t x);

/* ---- roots (floor, exact) --------------------------------------------------- */

uint32_t fx_isqrt32(uint32_t v); /* floor(sqrt(v)) */
uint32_t fx_isqrt64(uint64_t v); /* floor(sqrt(v)) */
/* Greatest common divisor (fx_gcd64(0, 0) == 0); for reducing scale ratios. */
uint64_t fx_gcd64(uint64_t a, uint64_t b);
uint32_t fx_icbrt64(uint64_t v);   /* floor(cbrt(v)) */
uint64_t fx_isqrt128(fx_u128_t v); /* floor(sqrt(v)), every 128-bit v */

/* ---- trigonometry and vector length ---------------------------------------- */

/* sin and cos of a binary angle in q1_30, |error| < 1 LSB (see above).
 * fx_sincos gives both at once, bit-identical to fx_sin and fx_cos. */
q1_30_t fx_sin(fx_angle_t a);
q1_30_t fx_cos(fx_angle_t a);
void fx_sincos(fx_angle_t a, q1_30_t *s, q1_30_t *c);

/* sin(x) and 1 - cos(x) in q62 (2^62 = 1.0) of a small angle, for rotation
 * recurrences that advance an angle by a constant step: a = |angle| as a
 * 64-bit binary angle (a full turn is 2^64, an fx_angle_t times 2^32),
 * a <= FX_SMALL_ANGLE_MAX (1/64 turn, pi/32 rad; larger values are
 * clamped). Taylor series to x^5 and x^6: |error| <= x^7 / 5040 (sine) and
 * x^8 / 40320 (versine) plus 2^-59, i.e. below 2e-11 and 2^-58 at pi/32
 * (tests/unit/test_fixmath.c checks both against long double). */
#define FX_SMALL_ANGLE_MAX ((uint64_t)1 << 58)
void fx_sin_vers_small(uint64_t a, uint64_t *sn, uint64_t *vs);

/* Angle of the vector (x, y), counter-clockwise from +x, in [0, 2^32): so
 * (0, -1) gives FX_ANGLE_270. (0, 0) gives 0. Any int64 inputs, including
 * INT64_MIN. Symmetric: atan2(-y, x) == -atan2(y, x) (mod 2^32),
 * atan2(y, -x) == FX_ANGLE_180 - atan2(y, x), atan2(x, y) == FX_ANGLE_90 -
 * atan2(y, x) for x, y >= 0. */
fx_angle_t fx_atan2(int64_t y, int64_t x);

/* floor(sqrt(x^2 + y^2)) and floor(sqrt(x^2 + y^2 + z^2)), exact for every
 * input (128-bit sum of squares), saturated to INT64_MAX. Components below
 * 2^31 in magnitude (2.1 m in nm) take the fast path (one 64-bit root);
 * larger ones a 128-bit root about 6x slower (see bench/bench-fixmath.sh). */
int64_t fx_hypot2(int64_t x, int64_t y);
int64_t fx_hypot3(int64_t x, int64_t y, int64_t z);

/* ---- division by a constant with its reciprocal ---------------------------- */

/* round(num * 2^30 / den) (division rule) for 0 < num < den, after num and
 * den are shifted right together until den < 2^32 (the quotient of the
 * shifted values: within 2^30 / den_shifted of the exact one); 0 when num
 * <= 0 or den <= 0 (or den shifts to 0), 2^30 when num >= den. A chord
 * fraction or a speed ratio in q30. */
int64_t fx_ratio_q30(int64_t num, int64_t den);

/* floor(2^62 / d) for 1 <= d < 2^32 (d == 0 gives 0): the reciprocal that
 * fx_div_q30_rec uses, computed once per divisor (a 64-bit division). */
uint64_t fx_recip62(uint32_t d);

/* round(n * 2^30 / d), ties away from zero (== fx_div_round64(n << 30, d)),
 * for 0 <= n <= d, 1 <= d < 2^32, rec = fx_recip62(d); result in [0, 2^30].
 * Two 32 x 32 -> 64 products and an exact remainder correction instead of a
 * 64-bit division: q = floor(n * rec / 2^32) is floor(n * 2^30 / d) or one
 * less (n * (2^62 / d - rec) / 2^32 < 1). */
static inline uint32_t fx_div_q30_rec(uint32_t n, uint32_t d, uint64_t rec)
{
    uint64_t q = (rec >> 32) * n + (((uint64_t)(uint32_t)rec * n) >> 32);
    uint64_t rem = ((uint64_t)n << 30) - q * d; /* in [0, 2d) */

    if (rem >= d) {
        q++;
        rem -= d;
    }
    if (2u * rem >= d) {
        q++;
    }
    return (uint32_t)q;
}

/* floor(n / d) when the quotient fits 32 bits (n / 2^32 < d); UINT32_MAX
 * otherwise (also for d == 0). One normalised two-digit long division (two
 * 32-bit UDIV), no 64-bit division helper. */
uint32_t fx_udiv64by32(uint64_t n, uint32_t d);

/* floor(sqrt(v)) as fx_isqrt64, for a root that moves little between calls,
 * from h (any value: only the cost depends on it): h itself when h^2 <= v
 * and v - h^2 <= 2h, h + 1, h - 1 or h - 2 when v - h^2 says so (no
 * division: the squares of h's neighbours from h^2 and 2h); else one Newton step r = floor((h +
 * floor(v / h)) / 2), which is never below the root (AM-GM) and within one of it when h is within
 * about 2^-15 r of it, taken when r^2 or (r - 1)^2 is at most v; otherwise fx_isqrt64. fx_isqrt64's
 * Newton iteration is a chain of four or five dependent divisions; a root near last tick's root
 * (the CEC's normalisation and exact arc distance) takes at most one. Exactness:
 * tests/unit/test_fixmath.c, test_isqrt64_near. */
static inline uint32_t fx_isqrt64_near(uint64_t v, uint32_t h)
{
    uint64_t sq = (uint64_t)h * h, h2 = 2u * (uint64_t)h, r;
    if (sq <= v) {
        uint64_t d = v - sq;
        if (d <= h2) { /* v < (h + 1)^2 = h^2 + 2h + 1 */
            return h;
        }
        if (d - h2 - 1u <= h2 + 2u) { /* (h + 1)^2 <= v < (h + 2)^2 = h^2 + 4h + 4 */
            return h + 1u;            /* h < UINT32_MAX: v - h^2 <= 2h there */
        }
    } else {
        uint64_t d = sq - v; /* > 0, so h >= 1 */
        if (d < h2) {        /* (h - 1)^2 = h^2 - 2h + 1 <= v */
            return h - 1u;
        }
        if (d <= 2u * h2 - 4u) { /* (h - 2)^2 <= v (h >= 2: h = 1 gives d <= 0) */
            return h - 2u;
        }
    }
    if ((v >> 32) < h) {                              /* v / h < 2^32 (h > 0) */
        r = ((uint64_t)h + fx_udiv64by32(v, h)) >> 1; /* < 2^32, >= floor(sqrt(v)) */
        if (r * r <= v) {
            return (uint32_t)r;
        }
        if ((r - 1u) * (r - 1u) <= v) {
            return (uint32_t)r - 1u;
        }
    }
    return fx_isqrt64(v);
}

#endif /* FIXMATH_H */
