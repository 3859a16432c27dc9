/*
 * fixmath.c - see fixmath.h for the specification and error bounds.
 *
 * Right shifts of negative values are arithmetic (GCC and Clang define this;
 * every target of the project uses one of them). Left shifts of values that
 * may be negative are written as multiplications to stay defined in C99.
 * Magnitudes are handled as uint64_t so that INT64_MIN needs no special case.
 */
#include "fixmath.h"

/* ---- saturation ----------------------------------------------------------- */

int32_t fx_sat32(int64_t v)
{
    if (v > INT32_MAX) {
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)v;
}

int32_t fx_sat_add32(int32_t a, int32_t b)
{
    return fx_sat32((int64_t)a + b);
}

int32_t fx_sat_sub32(int32_t a, int32_t b)
{
    return fx_sat32((int64_t)a - b);
}

int32_t fx_sat_neg32(int32_t a)
{
    return (a == INT32_MIN) ? INT32_MAX : -a;
}

int32_t fx_sat_abs32(int32_t a)
{
    return (a < 0) ? fx_sat_neg32(a) : a;
}

int64_t fx_sat_add64(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) {
        return INT64_MAX;
    }
    if (b < 0 && a < INT64_MIN - b) {
        return INT64_MIN;
    }
    return a + b;
}

int64_t fx_sat_sub64(int64_t a, int64_t b)
{
    if (b < 0 && a > INT64_MAX + b) {
        return INT64_MAX;
    }
    if (b > 0 && a < INT64_MIN + b) {
        return INT64_MIN;
    }
    return a - b;
}

int32_t fx_clamp32(int32_t v, int32_t lo, int32_t hi)
{
    if (v < lo) {
        v = lo;
    }
    return (v > hi) ? hi : v;
}

uint64_t fx_gcd64(uint64_t a, uint64_t b)
{
    while (b != 0u) {
        uint64_t t = a % b;
        a = b;
        b = t;
    }
    return a;
}

int64_t fx_clamp64(int64_t v, int64_t lo, int64_t hi)
{
    if (v < lo) {
        v = lo;
    }
    return (v > hi) ? hi : v;
}

/* ---- shifts and multiplications -------------------------------------------- */

int32_t fx_sat_mul32(int32_t a, int32_t b, unsigned s)
{
    return fx_sat32(fx_mul32_shift(a, b, s));
}

/* ---- 128-bit helpers (two's complement, hi:lo) ------------------------------ */

/* round(v / 2^s) by the shift rule (ties toward +inf) for v = +m or -m
 * (neg), saturated to int64. m <= 2^126 (a product of two int64 magnitudes).
 * Rounding half up on the signed value is floor((m + 2^(s-1)) / 2^s) for
 * v >= 0 and floor((m - 1 + 2^(s-1)) / 2^s) for v < 0 (a tie of the
 * magnitude goes down), and floor((x + 2^(s-1)) / 2^s) = floor((t + 1) / 2)
 * with t = floor(x / 2^(s-1)): one 128-bit shift, no mask of the dropped
 * bits. */
static inline int64_t fx_round_shift128_sat(fx_u128_t m, bool neg, unsigned s)
{
    uint64_t t, lo = m.lo, hi = m.hi;
    unsigned r;
    bool ok = true;

    if (s == 0) {
        return fx_signed_sat(hi == 0, lo, neg);
    }
    if (s >= 128) {
        return 0; /* |v| <= 2^126 < 2^(s-1) */
    }
    if (neg) {
        if (lo == 0) {
            if (hi == 0) {
                return 0;
            }
            hi--;
        }
        lo--;
    }
    r = s - 1;
    if (r >= 64) {
        t = hi >> (r - 64);
    } else if (hi == 0) {
        t = lo >> r;
    } else if (r == 0) {
        t = lo;
        ok = false;
    } else {
        t = (lo >> r) | (hi << (64 - r));
        ok = (hi >> r) == 0;
    }
    /* floor((t + 1) / 2) <= 2^63; !ok: the quotient is at least 2^63 */
    return fx_signed_sat(ok, (t >> 1) + (t & 1u), neg);
}

int64_t fx_mul64_shift(int64_t a, int64_t b, unsigned s)
{
    uint64_t ua = fx_uabs64(a), ub = fx_uabs64(b);
    fx_u128_t p;

    if (((ua | ub) >> 32) == 0) { /* one 32 x 32 -> 64 multiply */
        p.hi = 0;
        p.lo = ua * ub;
    } else {
        p = fx_umul64(ua, ub);
    }
    return fx_round_shift128_sat(p, (a < 0) != (b < 0), s);
}

int64_t fx_mul64x32_shift(int64_t a, int32_t b, unsigned s)
{
    uint64_t ua = fx_uabs64(a);
    uint32_t ub = (uint32_t)fx_uabs64(b);
    fx_u128_t p;

    if ((ua >> 32) == 0) { /* one 32 x 32 -> 64 multiply */
        p.hi = 0;
        p.lo = ua * ub;
    } else {
        p = fx_umul64x32(ua, ub);
    }

    return fx_round_shift128_sat(p, (a < 0) != (b < 0), s);
}

pos_nm_t fx_pos_scale_q16(pos_nm_t p, q16_16_t r)
{
    return fx_mul64x32_shift(p, r, 16);
}

pos_nm_t fx_pos_scale_q30(pos_nm_t p, q1_30_t r)
{
    return fx_mul64x32_shift(p, r, 30);
}

/* ---- conversions -------------------------------------------------------------- */

q16_16_t fx_q16_from_int(int32_t n)
{
    return fx_sat32((int64_t)n * 65536);
}

int32_t fx_q16_to_int(q16_16_t v)
{
    return (int32_t)fx_round_shift64(v, 16);
}

q1_30_t fx_q30_from_q16(q16_16_t v)
{
    return fx_sat32((int64_t)v * 16384);
}

q16_16_t fx_q16_from_q30(q1_30_t v)
{
    return (q16_16_t)fx_round_shift64(v, 14);
}

q32_32_t fx_q32_from_int(int64_t n)
{
    if (n > INT32_MAX) {
        return INT64_MAX;
    }
    if (n < INT32_MIN) {
        return INT64_MIN;
    }
    return n * FX_ONE_Q32;
}

int64_t fx_q32_to_int(q32_32_t v)
{
    return fx_round_shift64(v, 32);
}

q32_32_t fx_q32_from_q16(q16_16_t v)
{
    return (q32_32_t)v * 65536;
}

q16_16_t fx_q16_from_q32(q32_32_t v)
{
    return fx_sat32(fx_round_shift64(v, 16));
}

q32_32_t fx_q32_from_q30(q1_30_t v)
{
    return (q32_32_t)v * 4;
}

q1_30_t fx_q30_from_q32(q32_32_t v)
{
    return fx_sat32(fx_round_shift64(v, 2));
}

/* ---- trigonometry ------------------------------------------------------------- */

/*
 * The angle is folded into [0, 45] degrees; there sin and cos are Taylor
 * series evaluated in unsigned Q0.32 (x < pi/4 < 1), every product rounded,
 * every bracket of the Horner form positive. Truncation after x^11 (sin) and
 * x^12 (cos) is below 1.2e-10 on [0, pi/4], an eighth of a q1_30 LSB.
 */
#define FX_2PI_Q29 3373259426u /* 2 pi * 2^29: quadrant fraction (2^30) to rad Q0.32 */

/* 1/n! in Q0.32, rounded */
#define FX_INV_FACT2  2147483648u
#define FX_INV_FACT3  715827883u
#define FX_INV_FACT4  178956971u
#define FX_INV_FACT5  35791394u
#define FX_INV_FACT6  5965232u
#define FX_INV_FACT7  852176u
#define FX_INV_FACT8  106522u
#define FX_INV_FACT9  11836u
#define FX_INV_FACT10 1184u
#define FX_INV_FACT11 108u
#define FX_INV_FACT12 9u

/* round(a * b / 2^32): one 32 x 32 -> 64 multiply */
static uint32_t fx_mulhi32(uint32_t a, uint32_t b)
{
    return (uint32_t)(((uint64_t)a * b + 0x80000000u) >> 32);
}

/* sin(x) in q1_30 for x in Q0.32, 0 <= x <= pi/4, z = x^2 */
static q1_30_t fx_sin_poly(uint32_t x, uint32_t z)
{
    uint32_t t = FX_INV_FACT11;

    t = FX_INV_FACT9 - fx_mulhi32(z, t);
    t = FX_INV_FACT7 - fx_mulhi32(z, t);
    t = FX_INV_FACT5 - fx_mulhi32(z, t);
    t = FX_INV_FACT3 - fx_mulhi32(z, t);
    t = x - fx_mulhi32(fx_mulhi32(z, x), t); /* x - x^3 (1/3! - ...) */
    return (q1_30_t)((t + 2u) >> 2);
}

/* cos(x) in q1_30 for x in Q0.32, 0 <= x <= pi/4, z = x^2 */
static q1_30_t fx_cos_poly(uint32_t z)
{
    uint32_t t = FX_INV_FACT12;

    t = FX_INV_FACT10 - fx_mulhi32(z, t);
    t = FX_INV_FACT8 - fx_mulhi32(z, t);
    t = FX_INV_FACT6 - fx_mulhi32(z, t);
    t = FX_INV_FACT4 - fx_mulhi32(z, t);
    t = FX_INV_FACT2 - fx_mulhi32(z, t);
    t = fx_mulhi32(z, t); /* 1 - cos(x) in Q0.32 */
    /* round((2^32 - t) / 4), ties up */
    return (q1_30_t)(((uint32_t)1 << 30) - ((t + 1u) >> 2));
}

/* x = t * (pi/2) / 2^30 rad in Q0.32, for t in [0, 2^29] */
static uint32_t fx_quad_to_rad(uint32_t t)
{
    return (uint32_t)(((uint64_t)t * FX_2PI_Q29 + ((uint32_t)1 << 28)) >> 29);
}

/* sin of t / 2^30 quarter turns, t in [0, 2^30]. cos is sin(2^30 - t), which
 * makes the two exactly symmetric about 45 degrees. */
static q1_30_t fx_sin_quad(uint32_t t)
{
    uint32_t x;

    if (t <= ((uint32_t)1 << 29)) {
        x = fx_quad_to_rad(t);
        return fx_sin_poly(x, fx_mulhi32(x, x));
    }
    x = fx_quad_to_rad(((uint32_t)1 << 30) - t);
    return fx_cos_poly(fx_mulhi32(x, x));
}

/* *s = fx_sin_quad(t), *c = fx_sin_quad(2^30 - t), sharing x and x^2 */
static void fx_sincos_quad(uint32_t t, q1_30_t *s, q1_30_t *c)
{
    uint32_t u = (t <= ((uint32_t)1 << 29)) ? t : ((uint32_t)1 << 30) - t;
    uint32_t x = fx_quad_to_rad(u), z = fx_mulhi32(x, x);
    q1_30_t sn = fx_sin_poly(x, z);
    q1_30_t cs = (u == ((uint32_t)1 << 29)) ? sn : fx_cos_poly(z);

    if (u == t) {
        *s = sn;
        *c = cs;
    } else {
        *s = cs;
        *c = sn;
    }
}

q1_30_t fx_sin(fx_angle_t a)
{
    uint32_t t = a & 0x3FFFFFFFu;

    switch (a >> 30) {
    case 0:
        return fx_sin_quad(t);
    case 1:
        return fx_sin_quad(((uint32_t)1 << 30) - t);
    case 2:
        return -fx_sin_quad(t);
    default:
        return -fx_sin_quad(((uint32_t)1 << 30) - t);
    }
}

q1_30_t fx_cos(fx_angle_t a)
{
    return fx_sin(a + FX_ANGLE_90);
}

void fx_sincos(fx_angle_t a, q1_30_t *s, q1_30_t *c)
{
    q1_30_t sq, cq; /* sin and cos of the angle within its quadrant */

    fx_sincos_quad(a & 0x3FFFFFFFu, &sq, &cq);
    switch (a >> 30) {
    case 0:
        *s = sq;
        *c = cq;
        break;
    case 1:
        *s = cq;
        *c = -sq;
        break;
    case 2:
        *s = -sq;
        *c = -cq;
        break;
    default:
        *s = -cq;
        *c = sq;
        break;
    }
}

/* atan(2^-i) in units of 2^-56 turn (binary angle with 24 extra bits),
 * i = 1..33, rounded from a 70-digit evaluation. */
#define FX_ATAN_FRAC  24
#define FX_ATAN_STEPS 33
static const int64_t fx_cordic_atan[FX_ATAN_STEPS + 1] = {
    0, /* i = 0 is not used: the input is already within 45 degrees */
    5317260203651848,
    2809494260081567,
    1426143154396570,
    715839029270683,
    358268477703266,
    179177955010598,
    89594445026371,
    44797906047171,
    22399038468267,
    11199529914810,
    5599766292493,
    2799883313132,
    1399941677427,
    699970841321,
    349985420986,
    174992710534,
    87496355272,
    43748177637,
    21874088818,
    10937044409,
    5468522205,
    2734261102,
    1367130551,
    683565276,
    341782638,
    170891319,
    85445659,
    42722830,
    21361415,
    10680707,
    5340354,
    2670177,
    1335088};

/* atan(v / u) as a binary angle, 0 < v < u: CORDIC vectoring with the
 * vector scaled to [2^60, 2^61) (growth 1.17 and sqrt(2) stay below 2^63).
 * After step i the residual angle is below atan(2^-i); 33 steps leave
 * 0.08 LSB, the final rounding 0.5 LSB. */
static uint32_t fx_atan_octant(uint64_t u, uint64_t v)
{
    unsigned lz = fx_clz64(u);
    int64_t x, y, z = 0;
    int i;

    if (lz > 3) {
        u <<= lz - 3;
        v <<= lz - 3;
    } else {
        u >>= 3 - lz;
        v >>= 3 - lz;
    }
    x = (int64_t)u;
    y = (int64_t)v;
    for (i = 1; i <= FX_ATAN_STEPS && y != 0; i++) {
        int64_t xs = x >> i, ys = y >> i;
        if (y > 0) {
            x += ys;
            y -= xs;
            z += fx_cordic_atan[i];
        } else {
            x -= ys;
            y += xs;
            z -= fx_cordic_atan[i];
        }
    }
    return (uint32_t)((z + ((int64_t)1 << (FX_ATAN_FRAC - 1))) >> FX_ATAN_FRAC);
}

fx_angle_t fx_atan2(int64_t y, int64_t x)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);
    fx_angle_t a; /* angle of (|x|, |y|), in [0, 90] degrees */

    if (ay == 0) {
        a = 0; /* also (0, 0) */
    } else if (ax == 0) {
        a = FX_ANGLE_90;
    } else if (ax == ay) {
        a = FX_ANGLE_45;
    } else if (ay < ax) {
        a = fx_atan_octant(ax, ay);
    } else {
        a = FX_ANGLE_90 - fx_atan_octant(ay, ax);
    }
    if (x < 0) {
        a = FX_ANGLE_180 - a;
    }
    if (y < 0) {
        a = (fx_angle_t)0 - a;
    }
    return a;
}

/* Small-angle sine and versine in q62 (see fixmath.h): the angle in rad
 * q64, then the Taylor series to x^5 and x^6 in q64 by high products (each
 * within 2 units of q64 of the exact floor). */
#define FX_PI_HALF_Q61  3622009729038561421ll  /* round(pi / 2 * 2^61) */
#define FX_RECIP6_Q64   3074457345618258602ull /* floor(2^64 / 6) */
#define FX_RECIP24_Q64  768614336404564650ull  /* floor(2^64 / 24) */
#define FX_RECIP120_Q64 153722867280912930ull  /* floor(2^64 / 120) */
#define FX_RECIP720_Q64 25620477880152155ull   /* floor(2^64 / 720) */

void fx_sin_vers_small(uint64_t a, uint64_t *sn, uint64_t *vs)
{
    uint64_t x, x2, x3, x4;

    if (a > FX_SMALL_ANGLE_MAX) {
        a = FX_SMALL_ANGLE_MAX;
    }
    x = (uint64_t)fx_mul64_shift((int64_t)a, FX_PI_HALF_Q61, 61) << 2; /* rad, q64 */
    x2 = fx_umulhi64(x, x);
    x3 = fx_umulhi64(x2, x);
    x4 = fx_umulhi64(x2, x2);
    *sn = (x - fx_umulhi64(x3, FX_RECIP6_Q64) + fx_umulhi64(fx_umulhi64(x4, x), FX_RECIP120_Q64)) >>
          2;
    *vs = ((x2 >> 1) - fx_umulhi64(x4, FX_RECIP24_Q64) +
           fx_umulhi64(fx_umulhi64(x4, x2), FX_RECIP720_Q64)) >>
          2;
}

/* ---- vector length -------------------------------------------------------------- */

static int64_t fx_sat_u64(uint64_t v)
{
    return (v > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)v;
}

int64_t fx_hypot2(int64_t x, int64_t y)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);

    if ((ax | ay) < ((uint64_t)1 << 31)) {
        return (int64_t)fx_isqrt64(ax * ax + ay * ay);
    }
    return fx_sat_u64(fx_isqrt128(fx_add128(fx_umul64(ax, ax), fx_umul64(ay, ay))));
}

int64_t fx_hypot3(int64_t x, int64_t y, int64_t z)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y), az = fx_uabs64(z);
    fx_u128_t n;

    if ((ax | ay | az) < ((uint64_t)1 << 31)) {
        return (int64_t)fx_isqrt64(ax * ax + ay * ay + az * az);
    }
    n = fx_add128(fx_umul64(ax, ax), fx_umul64(ay, ay));
    return fx_sat_u64(fx_isqrt128(fx_add128(n, fx_umul64(az, az))));
}

int64_t fx_ratio_q30(int64_t num, int64_t den)
{
    if (den <= 0 || num <= 0) {
        return 0;
    }
    if (num >= den) {
        return FX_ONE_Q30;
    }
    while (den >= ((int64_t)1 << 32)) {
        num >>= 1;
        den >>= 1;
    }
    if (den == 0) {
        return 0;
    }
    return fx_div_round64(num << 30, den);
}
