/*
 * fixmath.c - see fixmath.h for the specification and error bounds.
 *
 * Right shifts of negative values are arithmetic (GCC and Clang define this;
 * every target of the project uses one of them). Left shifts of values that
 * may be negative are written as multiplications to stay defined in C99.
 */
#include "fixmath.h"

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

int64_t fx_round_shift64(int64_t v, unsigned s)
{
    if (s == 0) {
        return v;
    }
    /* floor(v / 2^s) plus the first dropped bit: round half up, no overflow */
    return (v >> s) + ((v >> (s - 1)) & 1);
}

int64_t fx_mul32_shift(int32_t a, int32_t b, unsigned s)
{
    return fx_round_shift64((int64_t)a * b, s);
}

int32_t fx_sat_mul32(int32_t a, int32_t b, unsigned s)
{
    return fx_sat32(fx_mul32_shift(a, b, s));
}

/* ---- 128-bit helpers (two's complement, hi:lo) ---------------------------- */

typedef struct {
    uint64_t hi;
    uint64_t lo;
} fx_u128_t;

static fx_u128_t fx_umul64(uint64_t a, uint64_t b)
{
    uint64_t a_lo = a & 0xFFFFFFFFu, a_hi = a >> 32;
    uint64_t b_lo = b & 0xFFFFFFFFu, b_hi = b >> 32;
    uint64_t ll = a_lo * b_lo;
    uint64_t lh = a_lo * b_hi;
    uint64_t hl = a_hi * b_lo;
    uint64_t hh = a_hi * b_hi;
    uint64_t mid = (ll >> 32) + (lh & 0xFFFFFFFFu) + (hl & 0xFFFFFFFFu);
    fx_u128_t r;

    r.lo = (mid << 32) | (ll & 0xFFFFFFFFu);
    r.hi = hh + (lh >> 32) + (hl >> 32) + (mid >> 32);
    return r;
}

static fx_u128_t fx_neg128(fx_u128_t v)
{
    fx_u128_t r;

    r.lo = ~v.lo + 1u;
    r.hi = ~v.hi + (r.lo == 0 ? 1u : 0u);
    return r;
}

static uint64_t fx_uabs64(int64_t v)
{
    return (v < 0) ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
}

/* round(v / 2^s) of a signed 128-bit value, saturated to int64. */
static int64_t fx_round_shift128_sat(fx_u128_t v, unsigned s)
{
    int64_t hi;
    uint64_t lo;

    if (s > 0) {
        /* add half an LSB, carrying into hi */
        fx_u128_t half = {0u, 0u};
        if (s - 1 < 64) {
            half.lo = (uint64_t)1 << (s - 1);
        } else {
            half.hi = (uint64_t)1 << (s - 1 - 64);
        }
        lo = v.lo + half.lo;
        v.hi = v.hi + half.hi + (lo < v.lo ? 1u : 0u);
        v.lo = lo;
    }
    hi = (int64_t)v.hi;
    if (s == 0) {
        lo = v.lo;
    } else if (s < 64) {
        lo = (v.lo >> s) | (v.hi << (64 - s));
        hi = hi >> s;
    } else {
        lo = (uint64_t)(hi >> (s - 64));
        hi = hi >> 63;
    }
    /* fits in int64 when hi is the sign extension of lo */
    if (hi != (((int64_t)lo < 0) ? -1 : 0)) {
        return (hi < 0) ? INT64_MIN : INT64_MAX;
    }
    return (int64_t)lo;
}

int64_t fx_mul64_shift(int64_t a, int64_t b, unsigned s)
{
    fx_u128_t p = fx_umul64(fx_uabs64(a), fx_uabs64(b));

    if ((a < 0) != (b < 0)) {
        p = fx_neg128(p);
    }
    return fx_round_shift128_sat(p, s);
}

int64_t fx_mul64x32_shift(int64_t a, int32_t b, unsigned s)
{
    return fx_mul64_shift(a, (int64_t)b, s);
}

/* ---- division ---------------------------------------------------------------- */

int64_t fx_div_round64(int64_t num, int64_t den)
{
    uint64_t un, ud, q, r;
    bool neg;

    if (den == 0) {
        return (num > 0) ? INT64_MAX : (num < 0) ? INT64_MIN : 0;
    }
    un = fx_uabs64(num);
    ud = fx_uabs64(den);
    neg = (num < 0) != (den < 0);
    q = un / ud;
    r = un % ud;
    if (r >= ud - r) {
        q++; /* ties away from zero */
    }
    if (neg) {
        return (q > (uint64_t)INT64_MAX + 1u) ? INT64_MIN : (int64_t)((uint64_t)0 - q);
    }
    return (q > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)q;
}

int32_t fx_div_sat32(int64_t num, int32_t den, unsigned s)
{
    return fx_sat32(fx_div_round64(num * ((int64_t)1 << s), den));
}

q16_16_t fx_recip_q16(q16_16_t x)
{
    return fx_div_sat32(FX_ONE_Q16, x, 16);
}

/* ---- roots ------------------------------------------------------------------ */

uint32_t fx_isqrt32(uint32_t v)
{
    uint32_t r = 0, bit = (uint32_t)1 << 30;

    while (bit > v) {
        bit >>= 2;
    }
    while (bit != 0) {
        if (v >= r + bit) {
            v -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r;
}

uint32_t fx_isqrt64(uint64_t v)
{
    uint64_t r = 0, bit = (uint64_t)1 << 62;

    if (v <= UINT32_MAX) {
        return fx_isqrt32((uint32_t)v);
    }
    while (bit > v) {
        bit >>= 2;
    }
    while (bit != 0) {
        if (v >= r + bit) {
            v -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return (uint32_t)r;
}

uint32_t fx_icbrt64(uint64_t v)
{
    uint64_t y = 0;
    int s;

    for (s = 63; s >= 0; s -= 3) {
        uint64_t b;
        y *= 2;
        b = 3 * y * (y + 1) + 1;
        if ((v >> s) >= b) {
            v -= b << s;
            y++;
        }
    }
    return (uint32_t)y;
}

/* ---- trigonometry ----------------------------------------------------------- */

/* Taylor coefficients in q1_30; truncation below 2e-10 on [0, pi/4]. */
#define FX_PI_2_Q30 1686629713 /* (pi/2) * 2^30: binary-angle quadrant to rad */

static int32_t fx_mul_q30(int32_t a, int32_t b)
{
    return (int32_t)fx_mul32_shift(a, b, 30);
}

/* x in rad, q1_30, 0 <= x <= pi/4 */
static q1_30_t fx_sin_poly(int32_t x)
{
    int32_t x2 = fx_mul_q30(x, x);
    int32_t acc = -27;                      /* -1/11! */
    acc = 2959 + fx_mul_q30(x2, acc);       /*  1/9!  */
    acc = -213044 + fx_mul_q30(x2, acc);    /* -1/7!  */
    acc = 8947849 + fx_mul_q30(x2, acc);    /*  1/5!  */
    acc = -178956971 + fx_mul_q30(x2, acc); /* -1/3!  */
    acc = FX_ONE_Q30 + fx_mul_q30(x2, acc);
    return fx_mul_q30(x, acc);
}

static q1_30_t fx_cos_poly(int32_t x)
{
    int32_t x2 = fx_mul_q30(x, x);
    int32_t acc = -296;                     /* -1/10! */
    acc = 26631 + fx_mul_q30(x2, acc);      /*  1/8!  */
    acc = -1491308 + fx_mul_q30(x2, acc);   /* -1/6!  */
    acc = 44739243 + fx_mul_q30(x2, acc);   /*  1/4!  */
    acc = -536870912 + fx_mul_q30(x2, acc); /* -1/2!  */
    return FX_ONE_Q30 + fx_mul_q30(x2, acc);
}

/* sin and cos of an angle in the first quadrant, t in [0, 2^30) */
static void fx_sincos_q1(uint32_t t, q1_30_t *s, q1_30_t *c)
{
    if (t <= ((uint32_t)1 << 29)) {
        int32_t x = (int32_t)fx_round_shift64((int64_t)t * FX_PI_2_Q30, 30);
        *s = fx_sin_poly(x);
        *c = fx_cos_poly(x);
    } else {
        int32_t x = (int32_t)fx_round_shift64((int64_t)(((uint32_t)1 << 30) - t) * FX_PI_2_Q30, 30);
        *s = fx_cos_poly(x);
        *c = fx_sin_poly(x);
    }
}

q1_30_t fx_sin(fx_angle_t a)
{
    q1_30_t s, c;

    fx_sincos_q1(a & 0x3FFFFFFFu, &s, &c);
    switch (a >> 30) {
    case 0:
        return s;
    case 1:
        return c;
    case 2:
        return -s;
    default:
        return -c;
    }
}

q1_30_t fx_cos(fx_angle_t a)
{
    return fx_sin(a + FX_ANGLE_90);
}

/* atan(2^-i) as binary angle (2^32 per turn) */
static const uint32_t fx_cordic_atan[32] = {
    536870912u, 316933406u, 167458907u, 85004756u, 42667331u, 21354465u, 10679838u, 5340245u,
    2670163u,   1335087u,   667544u,    333772u,   166886u,   83443u,    41722u,    20861u,
    10430u,     5215u,      2608u,      1304u,     652u,      326u,      163u,      81u,
    41u,        20u,        10u,        5u,        3u,        1u,        1u,        0u};

fx_angle_t fx_atan2(int64_t y, int64_t x)
{
    uint32_t angle = 0;
    uint64_t m;
    int i;

    if (x == 0 && y == 0) {
        return 0;
    }
    /* scale so that max(|x|,|y|) lies in [2^58, 2^59): headroom for CORDIC
     * growth (x1.65) and the additions, full precision for small inputs */
    m = fx_uabs64(x) > fx_uabs64(y) ? fx_uabs64(x) : fx_uabs64(y);
    while (m >= ((uint64_t)1 << 59)) {
        x >>= 1;
        y >>= 1;
        m >>= 1;
    }
    while (m < ((uint64_t)1 << 58)) {
        x *= 2;
        y *= 2;
        m <<= 1;
    }
    if (x < 0) {
        angle = FX_ANGLE_180;
        x = -x;
        y = -y;
    }
    for (i = 0; i < 32; i++) {
        int64_t xs = x >> i, ys = y >> i;
        if (y > 0) {
            x += ys;
            y -= xs;
            angle += fx_cordic_atan[i];
        } else {
            x -= ys;
            y += xs;
            angle -= fx_cordic_atan[i];
        }
    }
    return angle;
}

static uint64_t fx_sq(uint64_t v)
{
    return v * v;
}

int64_t fx_hypot2(int64_t x, int64_t y)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y);
    unsigned k = 0;
    uint64_t r;

    while ((ax | ay) >= ((uint64_t)1 << 31)) {
        ax >>= 1;
        ay >>= 1;
        k++;
    }
    r = (uint64_t)fx_isqrt64(fx_sq(ax) + fx_sq(ay));
    if (k > 0 && r > ((uint64_t)INT64_MAX >> k)) {
        return INT64_MAX;
    }
    return (int64_t)(r << k);
}

int64_t fx_hypot3(int64_t x, int64_t y, int64_t z)
{
    uint64_t ax = fx_uabs64(x), ay = fx_uabs64(y), az = fx_uabs64(z);
    unsigned k = 0;
    uint64_t r;

    while ((ax | ay | az) >= ((uint64_t)1 << 31)) {
        ax >>= 1;
        ay >>= 1;
        az >>= 1;
        k++;
    }
    r = (uint64_t)fx_isqrt64(fx_sq(ax) + fx_sq(ay) + fx_sq(az));
    if (k > 0 && r > ((uint64_t)INT64_MAX >> k)) {
        return INT64_MAX;
    }
    return (int64_t)(r << k);
}
