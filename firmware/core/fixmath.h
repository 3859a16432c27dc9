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
 *
 * Rounding: every shift that drops bits rounds to nearest, ties toward +inf
 * (add half an LSB, then arithmetic shift). Saturating functions clamp to the
 * format's range instead of wrapping; the plain ones are documented as exact.
 *
 * Error bounds (asserted by tests/unit/test_fixmath.c):
 *   fx_isqrt32/64, fx_icbrt64   exact floor.
 *   fx_sin/fx_cos               |error| <= 4e-9 (4 LSB of q1_30).
 *   fx_atan2                    |error| <= 2^-26 turn (9.4e-8 rad)
 *                               for inputs with max(|x|,|y|) >= 2^8.
 *   fx_hypot2                   exact floor for |x|,|y| < 2^31; otherwise
 *                               relative error < 2^-29.
 *   fx_hypot3                   exact floor for |x|,|y|,|z| < 2^31.
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

#define FX_ANGLE_90  ((fx_angle_t)0x40000000u)
#define FX_ANGLE_180 ((fx_angle_t)0x80000000u)

/* Integer (or format-preserving) conversions; n must be in range. */
#define FX_INT_TO_Q16(n) ((q16_16_t)((int32_t)(n)*65536))

/* ---- saturation and 32-bit saturating arithmetic ------------------------ */

int32_t fx_sat32(int64_t v);
int32_t fx_sat_add32(int32_t a, int32_t b);
int32_t fx_sat_sub32(int32_t a, int32_t b);
int32_t fx_sat_neg32(int32_t a);
int32_t fx_sat_abs32(int32_t a);
int64_t fx_sat_add64(int64_t a, int64_t b);

/* Arithmetic shift right by s (0..62) with rounding to nearest. */
int64_t fx_round_shift64(int64_t v, unsigned s);

/* (a * b) >> s, rounded; exact 64-bit product, s in 0..62. Never overflows. */
int64_t fx_mul32_shift(int32_t a, int32_t b, unsigned s);

/* (a * b) >> s, rounded, saturated to int32 (e.g. q16 * q16 with s = 16). */
int32_t fx_sat_mul32(int32_t a, int32_t b, unsigned s);

/* (a * b) >> s, rounded, saturated to int64, with a 96-bit intermediate:
 * scales a 64-bit position by a 32-bit ratio (e.g. pos_nm by q1_30, s = 30). */
int64_t fx_mul64x32_shift(int64_t a, int32_t b, unsigned s);

/* (a * b) >> s for two int64 values, 128-bit intermediate, rounded and
 * saturated to int64; s in 0..126. */
int64_t fx_mul64_shift(int64_t a, int64_t b, unsigned s);

/* ---- division ------------------------------------------------------------- */

/* round((num << s) / den), saturated to int32; den == 0 saturates toward the
 * sign of num (0 / 0 gives 0). s in 0..31; |num| < 2^(63-s) is required. */
int32_t fx_div_sat32(int64_t num, int32_t den, unsigned s);

/* round(num / den) for int64, den != 0 (den == 0 saturates like above). */
int64_t fx_div_round64(int64_t num, int64_t den);

/* Reciprocal 1/x in q16_16 of a q16_16 value, saturated. */
q16_16_t fx_recip_q16(q16_16_t x);

/* ---- roots ---------------------------------------------------------------- */

uint32_t fx_isqrt32(uint32_t v); /* floor(sqrt(v)), exact  */
uint32_t fx_isqrt64(uint64_t v); /* floor(sqrt(v)), exact  */
uint32_t fx_icbrt64(uint64_t v); /* floor(cbrt(v)), exact  */

/* ---- trigonometry and vector length ---------------------------------------- */

q1_30_t fx_sin(fx_angle_t a);
q1_30_t fx_cos(fx_angle_t a);
/* Angle of the vector (x, y); (0, 0) gives 0. */
fx_angle_t fx_atan2(int64_t y, int64_t x);
/* floor(sqrt(x^2 + y^2)) and the three-axis form, saturated to int64. */
int64_t fx_hypot2(int64_t x, int64_t y);
int64_t fx_hypot3(int64_t x, int64_t y, int64_t z);

#endif /* FIXMATH_H */
