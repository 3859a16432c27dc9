/*
 * Fixed-point math: every function against an exact reference.
 *
 * References are 128-bit integer arithmetic (GCC/Clang __int128, host only)
 * for the integer functions and double precision for sin/cos/atan2.
 * Domains: exhaustive where small (isqrt32 on [0, 2^20], every perfect-square
 * and cube boundary, sin/cos on a dense grid and around every octant
 * boundary, atan2 on [-64, 64]^2), randomized with a fixed-seed xorshift
 * generator over the full domains (random bit lengths, so small and huge
 * values are both frequent), and the extremes of every type and every
 * saturation boundary. Set FIXMATH_REPORT=1 to print the measured error
 * maxima (the figures quoted in fixmath.h).
 */
#include "fixmath.h"
#include "fixmath_test.h"
#include "unity.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

__extension__ typedef __int128 i128;
__extension__ typedef unsigned __int128 u128;

#define TWO32 4294967296.0
#define TWO30 1073741824.0

void setUp(void)
{
}

void tearDown(void)
{
}

/* ---- helpers ------------------------------------------------------------ */

static uint64_t rng_state;

static uint64_t rng(void)
{
    /* xorshift64* */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 0x2545F4914F6CDD1DULL;
}

static void rng_seed(uint64_t s)
{
    rng_state = s ? s : 1;
}

/* uniform bit length in 0..64, uniform bits below it */
static uint64_t rnd_u64(void)
{
    unsigned len = (unsigned)(rng() % 65);
    uint64_t v = rng();
    if (len < 64) {
        v &= ((uint64_t)1 << len) - 1;
        v |= (len > 0) ? (uint64_t)1 << (len - 1) : 0;
    }
    return v;
}

/* random bit length, random sign; 1 in 64 draws is an extreme value */
static int64_t rnd_i64(void)
{
    static const int64_t ext[] = {INT64_MIN, INT64_MIN + 1, INT64_MAX, INT64_MAX - 1, 0, 1, -1};
    uint64_t m;
    if (rng() % 64 == 0) {
        return ext[rng() % (sizeof ext / sizeof ext[0])];
    }
    m = rnd_u64() >> 1;
    return (rng() & 1) ? -(int64_t)m - (int64_t)(rng() & 1) : (int64_t)m;
}

static int32_t rnd_i32(void)
{
    static const int32_t ext[] = {INT32_MIN, INT32_MIN + 1, INT32_MAX, INT32_MAX - 1, 0, 1, -1};
    uint64_t m;
    if (rng() % 64 == 0) {
        return ext[rng() % (sizeof ext / sizeof ext[0])];
    }
    m = rnd_u64() >> 33;
    return (rng() & 1) ? -(int32_t)m - (int32_t)(rng() & 1) : (int32_t)m;
}

static int report_on;

static void report(const char *name, double v, const char *unit)
{
    if (report_on) {
        printf("%s: %.4f %s\n", name, v, unit);
    }
}

static char msg[200];

#define EXPECT_I64(exp, got, ...)                                                                  \
    do {                                                                                           \
        int64_t e_ = (exp), g_ = (got);                                                            \
        if (e_ != g_) {                                                                            \
            snprintf(msg, sizeof msg, __VA_ARGS__);                                                \
            TEST_ASSERT_EQUAL_INT64_MESSAGE(e_, g_, msg);                                          \
        }                                                                                          \
    } while (0)

static int64_t sat64(i128 v)
{
    if (v > INT64_MAX) {
        return INT64_MAX;
    }
    if (v < INT64_MIN) {
        return INT64_MIN;
    }
    return (int64_t)v;
}

static int32_t sat32(i128 v)
{
    if (v > INT32_MAX) {
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)v;
}

/* round(v / 2^s), ties toward +inf: floor(v / 2^s + 1/2); |v| <= 2^126 */
static i128 ref_shift(i128 v, unsigned s)
{
    if (s == 0) {
        return v;
    }
    if (s >= 128) {
        return 0;
    }
    return (v >> s) + ((v >> (s - 1)) & 1);
}

/* round(n / d), ties away from zero, of magnitudes; d != 0 */
static u128 ref_udiv_round(u128 n, u128 d)
{
    u128 q = n / d, r = n % d;
    return (r >= d - r) ? q + 1 : q;
}

/* round(n / d) ties away from zero, saturated; n = +-nm, d = +-dm */
static int64_t ref_div_sat(u128 nm, bool nneg, u128 dm, bool dneg)
{
    u128 q;
    if (dm == 0) {
        return nm == 0 ? 0 : nneg ? INT64_MIN : INT64_MAX;
    }
    q = ref_udiv_round(nm, dm);
    if (nneg != dneg) {
        return (q > ((u128)1 << 63)) ? INT64_MIN : (int64_t)(0 - (i128)q);
    }
    return (q > (u128)INT64_MAX) ? INT64_MAX : (int64_t)q;
}

static u128 uabs(i128 v)
{
    return (u128)(v < 0 ? -v : v);
}

static unsigned bitlen(u128 v)
{
    unsigned n = 0;
    while (v != 0) {
        v >>= 1;
        n++;
    }
    return n;
}

static u128 ref_isqrt128(u128 n)
{
    u128 r = (u128)sqrtl((long double)n);
    while (r * r > n) {
        r--;
    }
    while ((r + 1) * (r + 1) <= n) {
        r++;
    }
    return r;
}

/* signed binary-angle error of got against the real angle ref (in turns*2^32) */
static double angle_err(fx_angle_t got, double ref)
{
    double d = (double)got - ref;
    while (d > TWO32 / 2) {
        d -= TWO32;
    }
    while (d < -TWO32 / 2) {
        d += TWO32;
    }
    return d;
}

static double ref_atan2_turns(int64_t y, int64_t x)
{
    return atan2((double)y, (double)x) / (2.0 * M_PI) * TWO32;
}

/* ---- saturation and clamping ------------------------------------------ */

static const int32_t edge32[] = {
    INT32_MIN, INT32_MIN + 1, INT32_MIN / 2, -65536,        -2,       -1, 0, 1, 2,
    65536,     1073741824,    INT32_MAX / 2, INT32_MAX - 1, INT32_MAX};
#define N_EDGE32 (sizeof edge32 / sizeof edge32[0])

static const int64_t edge64[] = {INT64_MIN,
                                 INT64_MIN + 1,
                                 INT64_MIN / 2,
                                 (int64_t)INT32_MIN - 1,
                                 INT32_MIN,
                                 -4294967296LL,
                                 -2,
                                 -1,
                                 0,
                                 1,
                                 2,
                                 INT32_MAX,
                                 (int64_t)INT32_MAX + 1,
                                 4294967296LL,
                                 INT64_MAX / 2,
                                 INT64_MAX - 1,
                                 INT64_MAX};
#define N_EDGE64 (sizeof edge64 / sizeof edge64[0])

static void test_sat32_boundaries(void)
{
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat32(INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat32((int64_t)INT32_MAX + 1));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat32(INT64_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat32(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat32((int64_t)INT32_MIN - 1));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat32(INT64_MIN));
    TEST_ASSERT_EQUAL_INT32(0, fx_sat32(0));
    TEST_ASSERT_EQUAL_INT32(-1, fx_sat32(-1));
}

static void test_sat_arith32_edges_and_random(void)
{
    unsigned i, j;
    for (i = 0; i < N_EDGE32; i++) {
        int32_t a = edge32[i];
        EXPECT_I64(sat32(-(i128)a), fx_sat_neg32(a), "neg %d", a);
        EXPECT_I64(sat32(a < 0 ? -(i128)a : a), fx_sat_abs32(a), "abs %d", a);
        for (j = 0; j < N_EDGE32; j++) {
            int32_t b = edge32[j];
            EXPECT_I64(sat32((i128)a + b), fx_sat_add32(a, b), "add %d %d", a, b);
            EXPECT_I64(sat32((i128)a - b), fx_sat_sub32(a, b), "sub %d %d", a, b);
        }
    }
    /* exact boundaries */
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_add32(INT32_MAX - 1, 1));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_add32(INT32_MAX, 1));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_add32(INT32_MIN + 1, -1));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_add32(INT32_MIN, -1));
    TEST_ASSERT_EQUAL_INT32(-1, fx_sat_add32(INT32_MAX, INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_sub32(0, INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_sub32(-1, INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_sub32(-2, INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_sub32(-1, INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN + 1, fx_sat_sub32(0, INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_neg32(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_abs32(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_abs32(INT32_MIN + 1));
    rng_seed(32);
    for (i = 0; i < 100000; i++) {
        int32_t a = rnd_i32(), b = rnd_i32();
        EXPECT_I64(sat32((i128)a + b), fx_sat_add32(a, b), "add %d %d", a, b);
        EXPECT_I64(sat32((i128)a - b), fx_sat_sub32(a, b), "sub %d %d", a, b);
    }
}

static void test_sat_arith64_edges_and_random(void)
{
    unsigned i, j;
    for (i = 0; i < N_EDGE64; i++) {
        int64_t a = edge64[i];
        EXPECT_I64(sat64(-(i128)a), fx_sat_neg64(a), "neg %" PRId64, a);
        EXPECT_I64(sat64(a < 0 ? -(i128)a : a), fx_sat_abs64(a), "abs %" PRId64, a);
        for (j = 0; j < N_EDGE64; j++) {
            int64_t b = edge64[j];
            EXPECT_I64(sat64((i128)a + b), fx_sat_add64(a, b), "add %" PRId64 " %" PRId64, a, b);
            EXPECT_I64(sat64((i128)a - b), fx_sat_sub64(a, b), "sub %" PRId64 " %" PRId64, a, b);
        }
    }
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_add64(INT64_MAX - 1, 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_add64(INT64_MAX, 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_sat_add64(INT64_MIN, -1));
    TEST_ASSERT_EQUAL_INT64(-1, fx_sat_add64(INT64_MAX, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_sub64(-1, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_sub64(0, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_sat_sub64(-2, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_sat_sub64(-1, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN + 1, fx_sat_sub64(0, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_neg64(INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_abs64(INT64_MIN));
    rng_seed(64);
    for (i = 0; i < 100000; i++) {
        int64_t a = rnd_i64(), b = rnd_i64();
        EXPECT_I64(sat64((i128)a + b), fx_sat_add64(a, b), "add %" PRId64 " %" PRId64, a, b);
        EXPECT_I64(sat64((i128)a - b), fx_sat_sub64(a, b), "sub %" PRId64 " %" PRId64, a, b);
    }
}

/* fx_sat_diff32 (the servo's following error) against the exact difference
 * saturated to int32: the edges (int64 overflow of a - b both ways, the
 * int32 limits) and random pairs, near each other and far apart. */
static i128 clamp_i32(i128 v)
{
    return v > INT32_MAX ? INT32_MAX : v < INT32_MIN ? INT32_MIN : v;
}

static void test_sat_diff32_exact(void)
{
    unsigned i, j;
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            int64_t a = edge64[i], b = edge64[j];
            EXPECT_I64((int64_t)clamp_i32((i128)a - b), fx_sat_diff32(a, b),
                       "diff %" PRId64 " %" PRId64, a, b);
        }
    }
    rng_seed(32);
    for (i = 0; i < 100000; i++) {
        int64_t a = rnd_i64(), b = rnd_i64();
        i128 near = (i128)a + (int32_t)rnd_i64(); /* within +-2^31 of a */
        int64_t c = (int64_t)near;
        EXPECT_I64((int64_t)clamp_i32((i128)a - b), fx_sat_diff32(a, b),
                   "diff %" PRId64 " %" PRId64, a, b);
        if (near == c) {
            EXPECT_I64((int64_t)clamp_i32((i128)c - a), fx_sat_diff32(c, a),
                       "near %" PRId64 " %" PRId64, c, a);
        }
    }
}

/* The host form of fx_sat_diff32 (FX_SUB_OVERFLOW: the subtraction's
 * overflow flag) against the wrapped form the Cortex-M4 compiles, bit for
 * bit, and both against the exact difference. */
static void test_sat_diff32_host_equals_wrap(void)
{
    unsigned i, j;
    TEST_ASSERT_EQUAL_INT(1, FX_SUB_OVERFLOW); /* the host form is the one in use */
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            int64_t a = edge64[i], b = edge64[j];
            EXPECT_I64((int64_t)fx_sat_diff32_wrap(a, b), fx_sat_diff32(a, b),
                       "diff %" PRId64 " %" PRId64, a, b);
            EXPECT_I64((int64_t)clamp_i32((i128)a - b), fx_sat_diff32_wrap(a, b),
                       "wrap %" PRId64 " %" PRId64, a, b);
        }
    }
    rng_seed(33);
    for (i = 0; i < 1000000u; i++) {
        int64_t a = rnd_i64() >> (rng() % 64u), b;
        i128 near = (i128)a + ((int32_t)rnd_i64() >> (rng() % 32u));
        b = (i % 2u) ? (int64_t)near : rnd_i64() >> (rng() % 64u);
        if ((i128)b != near && (i % 2u)) {
            b = a; /* near left int64: the difference 0 */
        }
        EXPECT_I64((int64_t)fx_sat_diff32_wrap(a, b), fx_sat_diff32(a, b),
                   "diff %" PRId64 " %" PRId64, a, b);
        EXPECT_I64((int64_t)clamp_i32((i128)a - b), fx_sat_diff32(a, b),
                   "exact %" PRId64 " %" PRId64, a, b);
    }
}

/* The host form of fx_round_shift64 (FX_ROUND_INC: floor((floor(v /
 * 2^(s-1)) + 1) / 2)) against the dropped-bit form the Cortex-M4 compiles,
 * bit for bit, and both against round half up of v / 2^s, every shift. */
static void test_round_shift64_host_equals_bit(void)
{
    unsigned i, s;
    TEST_ASSERT_EQUAL_INT(1, FX_ROUND_INC); /* the host form is the one in use */
    for (s = 1; s < 64; s++) {
        for (i = 0; i < N_EDGE64 + 20000u; i++) {
            int64_t v = (i < N_EDGE64) ? edge64[i] : rnd_i64() >> (rng() % 64u);
            i128 exact = ((i128)v + ((i128)1 << (s - 1))) >> s;

            EXPECT_I64(fx_round_shift64_bit(v, s), fx_round_shift64(v, s), "host %" PRId64 " >> %u",
                       v, s);
            EXPECT_I64((int64_t)exact, fx_round_shift64_bit(v, s), "bit %" PRId64 " >> %u", v, s);
        }
    }
}

static void test_clamp(void)
{
    TEST_ASSERT_EQUAL_INT32(5, fx_clamp32(5, 0, 10));
    TEST_ASSERT_EQUAL_INT32(0, fx_clamp32(-5, 0, 10));
    TEST_ASSERT_EQUAL_INT32(10, fx_clamp32(15, 0, 10));
    TEST_ASSERT_EQUAL_INT32(0, fx_clamp32(0, 0, 10));
    TEST_ASSERT_EQUAL_INT32(10, fx_clamp32(10, 0, 10));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_clamp32(INT32_MIN, INT32_MIN, INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_clamp32(INT32_MAX, INT32_MIN, INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(-3, fx_clamp32(INT32_MIN, -3, -3));
    TEST_ASSERT_EQUAL_INT32(-3, fx_clamp32(INT32_MAX, -3, -3));
    /* inverted limits: the upper one wins */
    TEST_ASSERT_EQUAL_INT32(0, fx_clamp32(5, 10, 0));
    TEST_ASSERT_EQUAL_INT32(0, fx_clamp32(-5, 10, 0));
    TEST_ASSERT_EQUAL_INT64(7, fx_clamp64(7, -10, 10));
    TEST_ASSERT_EQUAL_INT64(-10, fx_clamp64(INT64_MIN, -10, 10));
    TEST_ASSERT_EQUAL_INT64(10, fx_clamp64(INT64_MAX, -10, 10));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_clamp64(INT64_MIN, INT64_MIN, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_clamp64(INT64_MAX, INT64_MIN, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(0, fx_clamp64(5, 10, 0));
}

/* ---- shifts and multiplications ----------------------------------------- */

static void test_round_shift64_ties_toward_plus_inf(void)
{
    unsigned s;
    TEST_ASSERT_EQUAL_INT64(2, fx_round_shift64(3, 1));   /*  1.5  ->  2 */
    TEST_ASSERT_EQUAL_INT64(-1, fx_round_shift64(-3, 1)); /* -1.5  -> -1 */
    TEST_ASSERT_EQUAL_INT64(1, fx_round_shift64(1, 1));   /*  0.5  ->  1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_round_shift64(-1, 1));  /* -0.5  ->  0 */
    TEST_ASSERT_EQUAL_INT64(-1, fx_round_shift64(-5, 2)); /* -1.25 -> -1 */
    TEST_ASSERT_EQUAL_INT64(-2, fx_round_shift64(-7, 2)); /* -1.75 -> -2 */
    for (s = 1; s < 63; s++) {
        int64_t half = (int64_t)1 << (s - 1);
        EXPECT_I64(1, fx_round_shift64(half, s), "+half s=%u", s);
        EXPECT_I64(0, fx_round_shift64(-half, s), "-half s=%u", s);
        EXPECT_I64(0, fx_round_shift64(half - 1, s), "below half s=%u", s);
        EXPECT_I64(-1, fx_round_shift64(-half - 1, s), "below -half s=%u", s);
        EXPECT_I64(2, fx_round_shift64(3 * half, s), "1.5 s=%u", s);
        EXPECT_I64(-1, fx_round_shift64(-3 * half, s), "-1.5 s=%u", s);
    }
}

static void test_round_shift64_extremes_and_random(void)
{
    unsigned s, i, k;
    for (s = 0; s < 70; s++) {
        for (k = 0; k < N_EDGE64; k++) {
            int64_t v = edge64[k];
            EXPECT_I64((int64_t)ref_shift(v, s), fx_round_shift64(v, s), "v=%" PRId64 " s=%u", v,
                       s);
        }
    }
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_round_shift64(INT64_MAX, 0));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, fx_round_shift64(INT64_MAX, 1));
    TEST_ASSERT_EQUAL_INT64(1, fx_round_shift64(INT64_MAX, 63));
    TEST_ASSERT_EQUAL_INT64(-1, fx_round_shift64(INT64_MIN, 63));
    TEST_ASSERT_EQUAL_INT64(0, fx_round_shift64(INT64_MIN, 64));
    TEST_ASSERT_EQUAL_INT64(0, fx_round_shift64(INT64_MAX, 64));
    TEST_ASSERT_EQUAL_INT64(0, fx_round_shift64(INT64_MIN, 1000));
    rng_seed(1);
    for (i = 0; i < 100000; i++) {
        int64_t v = rnd_i64();
        s = (unsigned)(rng() % 66);
        EXPECT_I64((int64_t)ref_shift(v, s), fx_round_shift64(v, s), "v=%" PRId64 " s=%u", v, s);
    }
}

static void test_mul32_shift_and_sat_mul32(void)
{
    unsigned i, j, s;
    /* extremes: the product itself never overflows */
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, fx_mul32_shift(INT32_MIN, INT32_MIN, 0));
    TEST_ASSERT_EQUAL_INT64(-((int64_t)1 << 31) * INT32_MAX,
                            fx_mul32_shift(INT32_MIN, INT32_MAX, 0));
    TEST_ASSERT_EQUAL_INT64(1, fx_mul32_shift(INT32_MIN, INT32_MIN, 62));
    TEST_ASSERT_EQUAL_INT64(1, fx_mul32_shift(INT32_MIN, INT32_MIN, 63)); /* 0.5 -> 1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_mul32_shift(INT32_MIN, INT32_MIN, 64));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul32_shift(INT32_MIN, INT32_MAX, 64));
    /* q16 * q16: 1.5 * -2.5 = -3.75 exactly; 3 LSB * 0.5 = 1.5 LSB -> 2 */
    TEST_ASSERT_EQUAL_INT32(-245760, fx_sat_mul32(98304, -163840, 16));
    TEST_ASSERT_EQUAL_INT32(2, fx_sat_mul32(3, 32768, 16));
    TEST_ASSERT_EQUAL_INT32(-1, fx_sat_mul32(-3, 32768, 16));
    /* saturation boundary: 65535 * 65537 = 2^32 - 1 */
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(65535, 32769, 0));
    TEST_ASSERT_EQUAL_INT32(2147385345, fx_sat_mul32(65535, 32767, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(65535, 65537, 1));   /* 2^31 - 0.5 -> 2^31 */
    TEST_ASSERT_EQUAL_INT32(-INT32_MAX, fx_sat_mul32(-65535, 65537, 1)); /* tie up */
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(INT32_MAX, 1, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_mul32(INT32_MIN, 1, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(INT32_MIN, -1, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(INT32_MIN, INT32_MIN, 31));
    TEST_ASSERT_EQUAL_INT32(1 << 30, fx_sat_mul32(INT32_MIN, INT32_MIN, 32));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_mul32(INT32_MIN, 65536, 16));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_sat_mul32(INT32_MIN, -65536, 16));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_mul32(65536, -32768 * 65536, 16));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_sat_mul32(65536 * 2, -32768 * 65536, 16));
    for (i = 0; i < N_EDGE32; i++) {
        for (j = 0; j < N_EDGE32; j++) {
            for (s = 0; s < 66; s += 5) {
                int32_t a = edge32[i], b = edge32[j];
                i128 r = ref_shift((i128)a * b, s);
                EXPECT_I64((int64_t)r, fx_mul32_shift(a, b, s), "%d*%d>>%u", a, b, s);
                EXPECT_I64(sat32(r), fx_sat_mul32(a, b, s), "sat %d*%d>>%u", a, b, s);
            }
        }
    }
    rng_seed(2);
    for (i = 0; i < 200000; i++) {
        int32_t a = rnd_i32(), b = rnd_i32();
        i128 r;
        s = (unsigned)(rng() % 64);
        r = ref_shift((i128)a * b, s);
        EXPECT_I64((int64_t)r, fx_mul32_shift(a, b, s), "%d*%d>>%u", a, b, s);
        EXPECT_I64(sat32(r), fx_sat_mul32(a, b, s), "sat %d*%d>>%u", a, b, s);
    }
}

static void test_mul64_shift_extremes(void)
{
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MIN, INT64_MIN, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MIN, INT64_MIN, 63));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, fx_mul64_shift(INT64_MIN, INT64_MIN, 64));
    TEST_ASSERT_EQUAL_INT64(1, fx_mul64_shift(INT64_MIN, INT64_MIN, 126));
    TEST_ASSERT_EQUAL_INT64(1, fx_mul64_shift(INT64_MIN, INT64_MIN, 127)); /* 0.5 -> 1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64_shift(INT64_MIN, INT64_MIN, 128));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64_shift(INT64_MIN, INT64_MAX, 127)); /* -0.49.. */
    TEST_ASSERT_EQUAL_INT64(-1, fx_mul64_shift(INT64_MIN, INT64_MAX, 126));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64_shift(INT64_MIN, INT64_MIN, 4000));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_mul64_shift(INT64_MIN, 1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MIN, -1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_mul64_shift(INT64_MIN, 2, 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MAX, 1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MAX, 2, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_mul64_shift(INT64_MAX, -2, 0));
    /* boundary: (2^63 - 1/2) rounds up and saturates; -(2^63 - 1/2) rounds to -(2^63-1) */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64_shift(INT64_MAX, 2, 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN + 1, fx_mul64_shift(-INT64_MAX, 2, 1));
    TEST_ASSERT_EQUAL_INT64((int64_t)3 << 61, fx_mul64_shift((int64_t)1 << 62, 3, 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_mul64_shift((int64_t)1 << 62, -4, 1));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64_shift(0, INT64_MIN, 0));
    /* ties of negative products go toward +inf */
    TEST_ASSERT_EQUAL_INT64(-1, fx_mul64_shift(-3, 1, 1));
    TEST_ASSERT_EQUAL_INT64(2, fx_mul64_shift(3, 1, 1));
    TEST_ASSERT_EQUAL_INT64(-1, fx_mul64_shift(-3, (int64_t)1 << 40, 41));
    TEST_ASSERT_EQUAL_INT64(-1, fx_mul64x32_shift(-3, 1, 1));
    TEST_ASSERT_EQUAL_INT64(-1, fx_mul64x32_shift(-((int64_t)3 << 40), 1 << 20, 61));
    TEST_ASSERT_EQUAL_INT64(2, fx_mul64x32_shift((int64_t)3 << 40, 1 << 20, 61));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64x32_shift(INT64_MIN, INT32_MIN, 31));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, fx_mul64x32_shift(INT64_MIN, INT32_MIN, 32));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_mul64x32_shift(INT64_MIN, 1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_mul64x32_shift(INT64_MIN, -1, 0));
    TEST_ASSERT_EQUAL_INT64(1, fx_mul64x32_shift(INT64_MIN, INT32_MIN, 94)); /* 2^94 / 2^94 */
    TEST_ASSERT_EQUAL_INT64(1, fx_mul64x32_shift(INT64_MIN, INT32_MIN, 95)); /* 0.5 -> 1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64x32_shift(INT64_MIN, INT32_MIN, 96));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64x32_shift(INT64_MIN, INT32_MAX, 95));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul64x32_shift(INT64_MAX, INT32_MAX, 200));
}

static void test_mul64_shift_random(void)
{
    unsigned i, j, s;
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            for (s = 0; s < 132; s += 3) {
                int64_t a = edge64[i], b = edge64[j];
                EXPECT_I64(sat64(ref_shift((i128)a * b, s)), fx_mul64_shift(a, b, s),
                           "%" PRId64 "*%" PRId64 ">>%u", a, b, s);
            }
        }
    }
    rng_seed(3);
    for (i = 0; i < 200000; i++) {
        int64_t a = rnd_i64(), b = rnd_i64();
        int32_t c = rnd_i32();
        s = (unsigned)(rng() % 130);
        EXPECT_I64(sat64(ref_shift((i128)a * b, s)), fx_mul64_shift(a, b, s),
                   "%" PRId64 "*%" PRId64 ">>%u", a, b, s);
        EXPECT_I64(sat64(ref_shift((i128)a * c, s)), fx_mul64x32_shift(a, c, s),
                   "%" PRId64 "*%d>>%u", a, c, s);
        if (s < 64) {
            /* sign symmetry away from ties: -(a*b) rounds like a*b unless it
             * is exactly half-way */
            i128 p = (i128)a * b;
            bool tie = s > 0 && (uabs(p) & (((u128)1 << s) - 1)) == ((u128)1 << (s - 1));
            if (!tie && a != INT64_MIN) {
                int64_t pos = fx_mul64_shift(a, b, s), neg = fx_mul64_shift(-a, b, s);
                TEST_ASSERT_TRUE(pos == INT64_MIN || neg == INT64_MIN || neg == -pos);
            }
        }
    }
}

static void test_pos_scale(void)
{
    unsigned i;
    /* 1 m scaled by 1.5 (q16) and by -0.25 (q30) */
    TEST_ASSERT_EQUAL_INT64(1500000000LL, fx_pos_scale_q16(1000000000LL, 3 << 15));
    TEST_ASSERT_EQUAL_INT64(-250000000LL, fx_pos_scale_q30(1000000000LL, -(1 << 28)));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_pos_scale_q16(INT64_MAX, 2 << 16));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_pos_scale_q16(INT64_MAX, -(2 << 16)));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_pos_scale_q30(INT64_MIN, INT32_MIN)); /* * -2 */
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_pos_scale_q30(INT64_MIN, FX_ONE_Q30));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_pos_scale_q30(INT64_MAX, FX_ONE_Q30));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_pos_scale_q16(INT64_MIN, -FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT64(1, fx_pos_scale_q16(1, 32768));   /* 0.5 -> 1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_pos_scale_q16(-1, 32768));  /* -0.5 -> 0 */
    TEST_ASSERT_EQUAL_INT64(-1, fx_pos_scale_q16(-1, 32769)); /* -0.50002 -> -1 */
    rng_seed(4);
    for (i = 0; i < 100000; i++) {
        int64_t p = rnd_i64();
        int32_t r = rnd_i32();
        EXPECT_I64(sat64(ref_shift((i128)p * r, 16)), fx_pos_scale_q16(p, r), "%" PRId64 "*%d", p,
                   r);
        EXPECT_I64(sat64(ref_shift((i128)p * r, 30)), fx_pos_scale_q30(p, r), "%" PRId64 "*%d", p,
                   r);
    }
}

/* ---- conversions ---------------------------------------------------------- */

static void test_conversions(void)
{
    unsigned i;
    TEST_ASSERT_EQUAL_INT32(3 * 65536, fx_q16_from_int(3));
    TEST_ASSERT_EQUAL_INT32(-32768 * 65536, fx_q16_from_int(-32768));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q16_from_int(-32769));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q16_from_int(32768));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q16_from_int(INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q16_from_int(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(FX_INT_TO_Q16(-7), fx_q16_from_int(-7));
    TEST_ASSERT_EQUAL_INT32(2, fx_q16_to_int(98304));   /*  1.5 ->  2 */
    TEST_ASSERT_EQUAL_INT32(-1, fx_q16_to_int(-98304)); /* -1.5 -> -1 */
    TEST_ASSERT_EQUAL_INT32(-2, fx_q16_to_int(-98305));
    TEST_ASSERT_EQUAL_INT32(32768, fx_q16_to_int(INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(-32768, fx_q16_to_int(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q30, fx_q30_from_q16(FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q30_from_q16(-2 * FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q30_from_q16(2 * FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX - 16383, fx_q30_from_q16(2 * FX_ONE_Q16 - 1));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q30_from_q16(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q16, fx_q16_from_q30(FX_ONE_Q30));
    TEST_ASSERT_EQUAL_INT32(1, fx_q16_from_q30(8192));  /*  0.5 LSB ->  1 */
    TEST_ASSERT_EQUAL_INT32(0, fx_q16_from_q30(-8192)); /* -0.5 LSB ->  0 */
    TEST_ASSERT_EQUAL_INT32(2 * FX_ONE_Q16, fx_q16_from_q30(INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(-2 * FX_ONE_Q16, fx_q16_from_q30(INT32_MIN));
    TEST_ASSERT_EQUAL_INT64(-5 * FX_ONE_Q32, fx_q32_from_int(-5));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_q32_from_int(INT32_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX - 0xFFFFFFFFLL, fx_q32_from_int(INT32_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_q32_from_int((int64_t)INT32_MAX + 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_q32_from_int((int64_t)INT32_MIN - 1));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_q32_from_int(INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_q32_from_int(INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(3, fx_q32_to_int(5 * (FX_ONE_Q32 / 2)));     /* 2.5 -> 3 */
    TEST_ASSERT_EQUAL_INT64(-2, fx_q32_to_int(-5 * (FX_ONE_Q32 / 2)));   /* -2.5 -> -2 */
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 31, fx_q32_to_int(INT64_MAX)); /* 2^31 - tiny */
    TEST_ASSERT_EQUAL_INT64(INT32_MIN, fx_q32_to_int(INT64_MIN));
    TEST_ASSERT_EQUAL_INT64((int64_t)INT32_MIN * FX_ONE_Q16, fx_q32_from_q16(INT32_MIN));
    TEST_ASSERT_EQUAL_INT64((int64_t)INT32_MAX * 4, fx_q32_from_q30(INT32_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q16_from_q32(INT64_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q16_from_q32(INT64_MIN));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q16_from_q32((int64_t)INT32_MIN * 65536 - 32768));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q16_from_q32((int64_t)INT32_MIN * 65536 - 32769));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q16_from_q32((int64_t)INT32_MAX * 65536 + 32767));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q16_from_q32((int64_t)INT32_MAX * 65536 + 32768));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_q30_from_q32(INT64_MAX));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_q30_from_q32(INT64_MIN));
    TEST_ASSERT_EQUAL_INT32(1, fx_q30_from_q32(2));   /*  0.5 ->  1 */
    TEST_ASSERT_EQUAL_INT32(0, fx_q30_from_q32(-2));  /* -0.5 ->  0 */
    TEST_ASSERT_EQUAL_INT32(-1, fx_q30_from_q32(-3)); /* -0.75 -> -1 */
    rng_seed(5);
    for (i = 0; i < 100000; i++) {
        int32_t a = rnd_i32();
        int64_t b = rnd_i64();
        EXPECT_I64(sat32((i128)a * 65536), fx_q16_from_int(a), "q16_from_int %d", a);
        EXPECT_I64((int64_t)ref_shift(a, 16), fx_q16_to_int(a), "q16_to_int %d", a);
        EXPECT_I64(sat32((i128)a * 16384), fx_q30_from_q16(a), "q30_from_q16 %d", a);
        EXPECT_I64((int64_t)ref_shift(a, 14), fx_q16_from_q30(a), "q16_from_q30 %d", a);
        EXPECT_I64((int64_t)a * 65536, fx_q32_from_q16(a), "q32_from_q16 %d", a);
        EXPECT_I64((int64_t)a * 4, fx_q32_from_q30(a), "q32_from_q30 %d", a);
        EXPECT_I64(sat64((i128)b * ((i128)1 << 32)), fx_q32_from_int(b), "%" PRId64, b);
        EXPECT_I64((int64_t)ref_shift(b, 32), fx_q32_to_int(b), "%" PRId64, b);
        EXPECT_I64(sat32(ref_shift(b, 16)), fx_q16_from_q32(b), "%" PRId64, b);
        EXPECT_I64(sat32(ref_shift(b, 2)), fx_q30_from_q32(b), "%" PRId64, b);
        /* round trips through a wider format are exact */
        EXPECT_I64(a, fx_q16_from_q32(fx_q32_from_q16(a)), "q16 rt %d", a);
        EXPECT_I64(a, fx_q30_from_q32(fx_q32_from_q30(a)), "q30 rt %d", a);
    }
}

/* ---- division --------------------------------------------------------------- */

static void test_div_round64(void)
{
    unsigned i, j;
    TEST_ASSERT_EQUAL_INT64(4, fx_div_round64(7, 2));   /*  3.5 ->  4 */
    TEST_ASSERT_EQUAL_INT64(-4, fx_div_round64(-7, 2)); /* -3.5 -> -4 */
    TEST_ASSERT_EQUAL_INT64(-4, fx_div_round64(7, -2)); /* -3.5 -> -4 */
    TEST_ASSERT_EQUAL_INT64(4, fx_div_round64(-7, -2)); /*  3.5 ->  4 */
    TEST_ASSERT_EQUAL_INT64(2, fx_div_round64(5, 3));   /*  1.67 -> 2 */
    TEST_ASSERT_EQUAL_INT64(-1, fx_div_round64(-4, 3)); /* -1.33 -> -1 */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_round64(1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_round64(-1, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_div_round64(0, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_round64(INT64_MIN, -1));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_round64(INT64_MIN, 1));
    TEST_ASSERT_EQUAL_INT64(1, fx_div_round64(INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(-1, fx_div_round64(INT64_MAX, INT64_MIN));    /* -0.99.. */
    TEST_ASSERT_EQUAL_INT64(-1, fx_div_round64(INT64_MIN, INT64_MAX));    /* -1.00.. */
    TEST_ASSERT_EQUAL_INT64(1, fx_div_round64(INT64_MIN / 2, INT64_MIN)); /* 0.5 -> 1 */
    TEST_ASSERT_EQUAL_INT64(0, fx_div_round64(INT64_MIN / 2 + 1, INT64_MIN));
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            int64_t n = edge64[i], d = edge64[j];
            EXPECT_I64(ref_div_sat(uabs(n), n < 0, uabs(d), d < 0), fx_div_round64(n, d),
                       "%" PRId64 "/%" PRId64, n, d);
        }
    }
    rng_seed(6);
    for (i = 0; i < 100000; i++) {
        int64_t n = rnd_i64(), d = rnd_i64();
        int64_t q = fx_div_round64(n, d);
        EXPECT_I64(ref_div_sat(uabs(n), n < 0, uabs(d), d < 0), q, "%" PRId64 "/%" PRId64, n, d);
        /* sign symmetry: ties away from zero */
        if (n != INT64_MIN && d != 0 && q != INT64_MIN) {
            EXPECT_I64(-q, fx_div_round64(-n, d), "sym %" PRId64 "/%" PRId64, n, d);
        }
    }
}

static void test_div_shift64_and_sat32(void)
{
    unsigned i, s;
    /* the quotient is exact even when num * 2^s overflows 64 bits: a q1_30
     * unit-vector component dx / len of a 2^62 nm move */
    TEST_ASSERT_EQUAL_INT64(FX_ONE_Q30 / 2, fx_div_shift64((int64_t)1 << 61, (int64_t)1 << 62, 30));
    TEST_ASSERT_EQUAL_INT64(-759250125,
                            fx_div_shift64(-3260954456333195553LL, 4611686018427387904LL, 30));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_div_sat32(INT64_MIN / 2, INT32_MIN, 30));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_div_sat32(-((int64_t)1 << 31) * INT32_MAX, INT32_MAX, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_div_sat32(-(int64_t)INT32_MAX, INT32_MAX, 31));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_div_sat32(INT32_MAX, INT32_MAX, 31));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_div_sat32(INT64_MAX, INT32_MAX, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_div_sat32(INT64_MIN, INT32_MAX, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_div_sat32(INT64_MIN, INT32_MIN, 0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_div_sat32(1, 0, 16));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_div_sat32(-1, 0, 16));
    TEST_ASSERT_EQUAL_INT32(0, fx_div_sat32(0, 0, 16));
    TEST_ASSERT_EQUAL_INT32(0, fx_div_sat32(0, 5, 200));
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_div_sat32(1, INT32_MIN, 200));
    TEST_ASSERT_EQUAL_INT32(3, fx_div_sat32(5, 2, 0));   /*  2.5 ->  3 */
    TEST_ASSERT_EQUAL_INT32(-3, fx_div_sat32(-5, 2, 0)); /* -2.5 -> -3 */
    TEST_ASSERT_EQUAL_INT32(98304, fx_div_sat32(3, 2, 16));
    TEST_ASSERT_EQUAL_INT64(-1, fx_div_shift64(1, INT64_MIN, 63));
    TEST_ASSERT_EQUAL_INT64(-2, fx_div_shift64(1, INT64_MIN, 64));
    TEST_ASSERT_EQUAL_INT64(-128, fx_div_shift64(1, INT64_MIN, 70));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_shift64(1, INT64_MIN, 126));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_shift64(1, INT64_MIN, 127));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_shift64(1, INT64_MIN, 128));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_shift64(-1, INT64_MIN, 126));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_shift64(INT64_MIN, INT64_MIN, 63));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_shift64(INT64_MAX, INT64_MAX, 63));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_shift64(INT64_MAX, -INT64_MAX, 63));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 62, fx_div_shift64(INT64_MAX, INT64_MAX, 62));
    TEST_ASSERT_EQUAL_INT64(0, fx_div_shift64(0, 0, 3));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_div_shift64(5, 0, 3));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_div_shift64(-5, 0, 3));
    rng_seed(7);
    for (i = 0; i < 100000; i++) {
        int64_t n = rnd_i64(), d = rnd_i64();
        int32_t d32 = rnd_i32();
        int64_t ref;
        s = (unsigned)(rng() % 65);
        ref = ref_div_sat(uabs(n) << s, n < 0, uabs(d), d < 0);
        EXPECT_I64(ref, fx_div_shift64(n, d, s), "%" PRId64 "<<%u/%" PRId64, n, s, d);
        /* large shifts: |num| * 2^s may exceed 128 bits (then it saturates) */
        s = 60 + (unsigned)(rng() % 72);
        if (n == 0) {
            ref = 0;
        } else if (128 - bitlen(uabs(n)) <= s) {
            ref = (n < 0) != (d < 0) ? INT64_MIN : INT64_MAX;
        } else {
            ref = ref_div_sat(uabs(n) << s, n < 0, uabs(d), d < 0);
        }
        if (d == 0) {
            ref = n == 0 ? 0 : n < 0 ? INT64_MIN : INT64_MAX;
        }
        EXPECT_I64(ref, fx_div_shift64(n, d, s), "%" PRId64 "<<%u/%" PRId64, n, s, d);
        s = s % 40;
        ref = ref_div_sat(uabs(n) << s, n < 0, uabs(d32), d32 < 0);
        EXPECT_I64(sat32(ref), fx_div_sat32(n, d32, s), "%" PRId64 "<<%u/%d", n, s, d32);
    }
}

static void test_muldiv64(void)
{
    unsigned i;
    /* a * b = 3e27 overflows 64 bits, the quotient does not */
    TEST_ASSERT_EQUAL_INT64(3000000000000000000LL / 7,
                            fx_muldiv64(3000000000000000000LL, 1000000000LL, 7000000000LL));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_muldiv64(INT64_MAX, INT64_MAX, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_muldiv64(INT64_MIN, INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_muldiv64(INT64_MIN, INT64_MAX, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_muldiv64(INT64_MIN, INT64_MIN, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_muldiv64(INT64_MIN, 1, -1));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_muldiv64(3, 4, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_muldiv64(-3, 4, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_muldiv64(0, 4, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_muldiv64(INT64_MIN, 0, 0));
    TEST_ASSERT_EQUAL_INT64(2, fx_muldiv64(3, 1, 2));   /*  1.5 ->  2 */
    TEST_ASSERT_EQUAL_INT64(-2, fx_muldiv64(-3, 1, 2)); /* -1.5 -> -2 */
    TEST_ASSERT_EQUAL_INT64(-2, fx_muldiv64(3, -1, 2));
    TEST_ASSERT_EQUAL_INT64(2, fx_muldiv64(3, -1, -2));
    rng_seed(8);
    for (i = 0; i < 100000; i++) {
        int64_t a = rnd_i64(), b = rnd_i64(), c = rnd_i64();
        i128 p = (i128)a * b;
        EXPECT_I64(ref_div_sat(uabs(p), p < 0, uabs(c), c < 0), fx_muldiv64(a, b, c),
                   "%" PRId64 "*%" PRId64 "/%" PRId64, a, b, c);
    }
}

static void test_recip_q16(void)
{
    int32_t x;
    unsigned i;
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q16, fx_recip_q16(FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT32(-FX_ONE_Q16 / 4, fx_recip_q16(-4 * FX_ONE_Q16));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_recip_q16(0));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_recip_q16(1));
    TEST_ASSERT_EQUAL_INT32(INT32_MAX, fx_recip_q16(2));  /* 2^31 */
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_recip_q16(-2)); /* -2^31 exactly */
    TEST_ASSERT_EQUAL_INT32(INT32_MIN, fx_recip_q16(-1));
    TEST_ASSERT_EQUAL_INT32(1431655765, fx_recip_q16(3));
    TEST_ASSERT_EQUAL_INT32(-2, fx_recip_q16(INT32_MIN));
    TEST_ASSERT_EQUAL_INT32(2, fx_recip_q16(INT32_MAX));
    /* every small value and its reciprocal, exact to the rounding rule */
    for (x = -(1 << 18); x <= (1 << 18); x++) {
        EXPECT_I64(sat32(ref_div_sat((u128)1 << 32, false, uabs(x), x < 0)), fx_recip_q16(x),
                   "recip %d", x);
    }
    rng_seed(9);
    for (i = 0; i < 100000; i++) {
        x = rnd_i32();
        EXPECT_I64(sat32(ref_div_sat((u128)1 << 32, false, uabs(x), x < 0)), fx_recip_q16(x),
                   "recip %d", x);
    }
}

/* The digit division (what 32-bit targets run: fx_udiv128_digits,
 * fx_udivmod64_digits) against the host's 128-bit division, and the public
 * fx_udiv128 / fx_udivmod64 against it: random operands of random lengths,
 * the divisor 10^9 (its own reciprocal path), one-digit divisors, numerators
 * just below the overflow limit (hi = d - 1) and the correction-step
 * boundaries (remainders 0 and d - 1). */
static void check_udiv128(uint64_t hi, uint64_t lo, uint64_t d)
{
    uint64_t r1, r2, q1, q2;
    u128 n = ((u128)hi << 64) | lo;

    q1 = fx_udiv128_digits(hi, lo, d, &r1);
    q2 = fx_udiv128(hi, lo, d, &r2);
    if (hi >= d) {
        if (q1 != UINT64_MAX || r1 != 0 || q2 != UINT64_MAX || r2 != 0) {
            snprintf(msg, sizeof msg, "udiv128 overflow %" PRIx64 ":%" PRIx64 " / %" PRIx64, hi, lo,
                     d);
            TEST_FAIL_MESSAGE(msg);
        }
        return;
    }
    if (q1 != (uint64_t)(n / d) || r1 != (uint64_t)(n % d) || q2 != q1 || r2 != r1) {
        snprintf(msg, sizeof msg, "udiv128 %" PRIx64 ":%" PRIx64 " / %" PRIx64, hi, lo, d);
        TEST_FAIL_MESSAGE(msg);
    }
    if (hi == 0) {
        q1 = fx_udivmod64_digits(lo, d, &r1);
        q2 = fx_udivmod64(lo, d, &r2);
        if (q1 != lo / d || r1 != lo % d || q2 != q1 || r2 != r1) {
            snprintf(msg, sizeof msg, "udivmod64 %" PRIx64 " / %" PRIx64, lo, d);
            TEST_FAIL_MESSAGE(msg);
        }
    }
}

static void test_udiv_digits_against_native(void)
{
    static const uint64_t fixed_d[] = {
        1, 3, 1000, 1000000000, 999999999, 0x80000000u, 0xFFFFFFFFu, 0x100000000ull, 0x100000001ull,
        0xFFFFFFFF00000000ull, UINT64_MAX, (uint64_t)1 << 63,
        /* digits that make the estimates need corrections */
        0x8000FFFFu, 0x80010000u - 1u, 0xFFFF0001u, 0x80000000FFFFFFFFull, 0x800000007FFFFFFFull,
        0xFFFFFFFF00000001ull, 0x0000FFFF0000FFFFull};
    uint64_t r;
    unsigned i, k;

    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_udivmod64_digits(5, 0, &r));
    TEST_ASSERT_EQUAL_UINT64(0, r);
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_udivmod64(5, 0, &r));
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_udiv128_digits(0, 5, 0, &r));
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_udiv128(7, 0, 7, &r));
    TEST_ASSERT_EQUAL_UINT64(0, r);
    rng_seed(13);
    for (i = 0; i < 300000; i++) {
        uint64_t d = rnd_u64(), hi = rnd_u64(), lo = rnd_u64();
        switch (i % 6) {
        case 0:
            d = fixed_d[rng() % (sizeof fixed_d / sizeof fixed_d[0])];
            break;
        case 1:
            d = 1000000000; /* the reciprocal path */
            break;
        case 2:
            d = rnd_u64() >> 32; /* one digit */
            break;
        case 3:
            hi = 0;
            break;
        default:
            break;
        }
        if (d == 0) {
            d = 1;
        }
        if (i % 4 != 0) {
            hi %= d; /* mostly in range; a quarter overflow-checks */
        }
        check_udiv128(hi, lo, d);
        /* the largest numerators and the remainder boundaries */
        check_udiv128(d - 1, UINT64_MAX, d);
        if (hi < d && lo >= 1) {
            check_udiv128(hi, lo - 1, d);
        }
    }
    for (k = 0; k < sizeof fixed_d / sizeof fixed_d[0]; k++) {
        uint64_t d = fixed_d[k];
        for (i = 0; i < 20000; i++) {
            /* n = q * d + {0, d - 1}: remainders at both ends */
            u128 n = (u128)rnd_u64() * d + ((i & 1) ? d - 1 : 0);
            if ((n >> 64) < d) {
                check_udiv128((uint64_t)(n >> 64), (uint64_t)n, d);
            }
        }
    }
}

/* ---- roots ------------------------------------------------------------------- */

static void check_isqrt64(uint64_t v)
{
    u128 r = fx_isqrt64(v);
    if (!(r * r <= v && (r + 1) * (r + 1) > v)) {
        snprintf(msg, sizeof msg, "isqrt64(%" PRIu64 ") = %" PRIu64, v, (uint64_t)r);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_isqrt32_exhaustive_and_boundaries(void)
{
    uint32_t v, r;
    for (v = 0; v <= (1u << 20); v++) {
        r = fx_isqrt32(v);
        if (!((uint64_t)r * r <= v && (uint64_t)(r + 1) * (r + 1) > v)) {
            snprintf(msg, sizeof msg, "isqrt32(%u) = %u", v, r);
            TEST_FAIL_MESSAGE(msg);
        }
    }
    /* every perfect square: r*r - 1, r*r, r*r + 1 */
    for (r = 1; r <= 65535; r++) {
        uint32_t sq = r * r;
        EXPECT_I64(r - 1, fx_isqrt32(sq - 1), "isqrt32(%u^2-1)", r);
        EXPECT_I64(r, fx_isqrt32(sq), "isqrt32(%u^2)", r);
        EXPECT_I64(r, fx_isqrt32(sq + 1), "isqrt32(%u^2+1)", r);
    }
    TEST_ASSERT_EQUAL_UINT32(65535u, fx_isqrt32(UINT32_MAX));
    TEST_ASSERT_EQUAL_UINT32(0, fx_isqrt32(0));
    TEST_ASSERT_EQUAL_UINT32(1, fx_isqrt32(1));
    TEST_ASSERT_EQUAL_UINT32(1, fx_isqrt32(3));
    TEST_ASSERT_EQUAL_UINT32(2, fx_isqrt32(4));
}

/* fx_udiv64by32: floor(n / d) when it fits 32 bits, else (and for d == 0)
 * UINT32_MAX; numerators with a high word (the 64/32 step) and without,
 * quotients at both ends of the 32-bit range. */
static void test_udiv64by32_exact(void)
{
    unsigned i;
    rng_seed(11);
    for (i = 0; i < 200000; i++) {
        uint32_t d = (uint32_t)(rng() >> (32 + (i % 32)));
        uint64_t n = rnd_u64() >> (i % 64);
        uint64_t q;
        if (i % 5 == 0 && d != 0u) {
            /* quotient just below 2^32 and just above */
            n = (uint64_t)d * (0xFFFFFFFFull - (i % 3)) + (rng() % d);
            if (i % 10 == 0) {
                n += d;
            }
        }
        q = d == 0u ? UINT32_MAX : n / d;
        if (q > UINT32_MAX) {
            q = UINT32_MAX;
        }
        TEST_ASSERT_EQUAL_UINT32((uint32_t)q, fx_udiv64by32(n, d));
    }
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_udiv64by32(5, 0));
    TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFFu, fx_udiv64by32(0xFFFFFFFEFFFFFFFFull, 0xFFFFFFFFu));
    TEST_ASSERT_EQUAL_UINT32(2u, fx_udiv64by32(0x100000000ull, 0x80000000u));
}

static void test_isqrt64_boundaries_and_random(void)
{
    uint64_t r;
    unsigned i;
    /* the 64-bit path agrees with the 32-bit one on the 32-bit range */
    for (r = 0; r < (1u << 16); r++) {
        uint32_t v = (uint32_t)(r * 65537u);
        EXPECT_I64(fx_isqrt32(v), fx_isqrt64(v), "isqrt64(%u)", v);
    }
    /* square boundaries: small roots, roots around 2^32 and 2^16, random roots */
    for (r = 1; r < (1u << 17); r++) {
        EXPECT_I64((int64_t)r - 1, fx_isqrt64(r * r - 1), "isqrt64(%" PRIu64 "^2-1)", r);
        EXPECT_I64((int64_t)r, fx_isqrt64(r * r), "isqrt64(%" PRIu64 "^2)", r);
    }
    for (r = 0xFFFFFFFFu; r > 0xFFFFFFFFu - (1u << 17); r--) {
        EXPECT_I64((int64_t)r - 1, fx_isqrt64(r * r - 1), "isqrt64(%" PRIu64 "^2-1)", r);
        EXPECT_I64((int64_t)r, fx_isqrt64(r * r), "isqrt64(%" PRIu64 "^2)", r);
        EXPECT_I64((int64_t)r, fx_isqrt64(r * r + 1), "isqrt64(%" PRIu64 "^2+1)", r);
    }
    TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFFu, fx_isqrt64(UINT64_MAX));
    TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFEu, fx_isqrt64(0xFFFFFFFE00000000ULL));
    TEST_ASSERT_EQUAL_UINT32(65536u, fx_isqrt64(4294967296ULL));
    TEST_ASSERT_EQUAL_UINT32(65535u, fx_isqrt64(4294967295ULL));
    rng_seed(10);
    for (i = 0; i < 100000; i++) {
        uint64_t v = rnd_u64();
        r = rng() >> 32 | 1;
        check_isqrt64(v);
        EXPECT_I64((int64_t)r, fx_isqrt64(r * r), "isqrt64(%" PRIu64 "^2)", r);
        EXPECT_I64((int64_t)r - 1, fx_isqrt64(r * r - 1), "isqrt64(%" PRIu64 "^2-1)", r);
    }
    for (i = 0; i < 64; i++) {
        check_isqrt64((uint64_t)1 << i);
        check_isqrt64(((uint64_t)1 << i) - 1);
        check_isqrt64(((uint64_t)1 << i) + 1);
    }
}

/* fx_isqrt64_near(v, h) == fx_isqrt64(v) for every hint: the root itself,
 * one or two off (the square and remainder checks and the Newton step's
 * r and r - 1), far off (the fallback), 0 and UINT32_MAX; v at and around
 * the squares (the boundaries of each branch), random v, both ends. */
static void check_isqrt64_near(uint64_t v, uint32_t h)
{
    uint32_t want = fx_isqrt64(v), got = fx_isqrt64_near(v, h);
    if (got != want) {
        snprintf(msg, sizeof msg, "isqrt64_near(%" PRIu64 ", %u) = %u, isqrt64 %u", v, h, got,
                 want);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_isqrt64_near(void)
{
    static const int32_t offs[] = {0, 1, -1, 2, -2, 3, -3, 1000, -1000, 1 << 20, -(1 << 20)};
    uint64_t r, v;
    unsigned i, k;
    rng_seed(41);
    for (i = 0; i < 300000; i++) {
        r = (i & 1) ? (rng() >> 32) : (rng() >> (32 + rng() % 32));
        switch (i % 4) {
        case 0:
            v = r * r;
            break;
        case 1:
            v = r * r + 2 * r; /* (r + 1)^2 - 1 */
            break;
        case 2:
            v = r * r - (r > 0);
            break;
        default:
            v = rnd_u64();
            r = fx_isqrt64(v);
            break;
        }
        for (k = 0; k < sizeof offs / sizeof offs[0]; k++) {
            int64_t h = (int64_t)r + offs[k];
            if (h >= 0 && h <= (int64_t)UINT32_MAX) {
                check_isqrt64_near(v, (uint32_t)h);
            }
        }
        check_isqrt64_near(v, (uint32_t)rng());
        check_isqrt64_near(v, 0);
        check_isqrt64_near(v, UINT32_MAX);
    }
    for (k = 0; k < 8; k++) {
        static const uint64_t ends[] = {
            0, 1, 2, 3, 4, UINT64_MAX, UINT64_MAX - 1, 0xFFFFFFFE00000001ULL};
        check_isqrt64_near(ends[k], 0);
        check_isqrt64_near(ends[k], 1);
        check_isqrt64_near(ends[k], 2);
        check_isqrt64_near(ends[k], UINT32_MAX);
        check_isqrt64_near(ends[k], UINT32_MAX - 1);
    }
}

static void check_icbrt(uint64_t v)
{
    u128 r = fx_icbrt64(v);
    if (!(r * r * r <= v && (r + 1) * (r + 1) * (r + 1) > v)) {
        snprintf(msg, sizeof msg, "icbrt64(%" PRIu64 ") = %" PRIu64, v, (uint64_t)r);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_icbrt64_every_cube_boundary(void)
{
    uint64_t r, v;
    unsigned i;
    for (v = 0; v < (1u << 16); v++) {
        check_icbrt(v);
    }
    /* every cube below 2^64: floor(cbrt(2^64 - 1)) = 2642245 */
    for (r = 1; r <= 2642245u; r++) {
        uint64_t c = r * r * r;
        if (fx_icbrt64(c) != r || fx_icbrt64(c - 1) != r - 1) {
            snprintf(msg, sizeof msg, "icbrt64 at %" PRIu64 "^3", r);
            TEST_FAIL_MESSAGE(msg);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(2642245u, fx_icbrt64(UINT64_MAX));
    TEST_ASSERT_EQUAL_UINT32(2642245u, fx_icbrt64(18446724184312856125ULL));
    TEST_ASSERT_EQUAL_UINT32(2642244u, fx_icbrt64(18446724184312856124ULL));
    TEST_ASSERT_EQUAL_UINT32(0, fx_icbrt64(0));
    TEST_ASSERT_EQUAL_UINT32(1, fx_icbrt64(7));
    TEST_ASSERT_EQUAL_UINT32(2, fx_icbrt64(8));
    rng_seed(11);
    for (i = 0; i < 100000; i++) {
        check_icbrt(rnd_u64());
    }
    for (i = 0; i < 64; i++) {
        check_icbrt((uint64_t)1 << i);
        check_icbrt(((uint64_t)1 << i) - 1);
    }
}

/* ---- trigonometry -------------------------------------------------------------- */

#define SIN_BOUND_LSB  1.0
#define ATAN_BOUND_LSB 0.6

static double sin_err_max, cos_err_max;

static void check_sincos(fx_angle_t a)
{
    double turn = (double)a / TWO32 * 2.0 * M_PI;
    q1_30_t s = fx_sin(a), c = fx_cos(a), s2, c2;
    double es = fabs((double)s - sin(turn) * TWO30);
    double ec = fabs((double)c - cos(turn) * TWO30);
    if (es > sin_err_max) {
        sin_err_max = es;
    }
    if (ec > cos_err_max) {
        cos_err_max = ec;
    }
    if (es > SIN_BOUND_LSB || ec > SIN_BOUND_LSB) {
        snprintf(msg, sizeof msg, "angle 0x%08x: sin err %.3f cos err %.3f LSB", a, es, ec);
        TEST_FAIL_MESSAGE(msg);
    }
    fx_sincos(a, &s2, &c2);
    if (s2 != s || c2 != c) {
        snprintf(msg, sizeof msg, "fx_sincos(0x%08x) differs from fx_sin/fx_cos", a);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_sin_cos_exact_points(void)
{
    unsigned k;
    TEST_ASSERT_EQUAL_INT32(0, fx_sin(0));
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q30, fx_sin(FX_ANGLE_90));
    TEST_ASSERT_EQUAL_INT32(0, fx_sin(FX_ANGLE_180));
    TEST_ASSERT_EQUAL_INT32(-FX_ONE_Q30, fx_sin(FX_ANGLE_270));
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q30, fx_cos(0));
    TEST_ASSERT_EQUAL_INT32(0, fx_cos(FX_ANGLE_90));
    TEST_ASSERT_EQUAL_INT32(-FX_ONE_Q30, fx_cos(FX_ANGLE_180));
    TEST_ASSERT_EQUAL_INT32(0, fx_cos(FX_ANGLE_270));
    /* sin 45 = cos 45 = round(2^30 / sqrt 2) = 759250125 (within 1 LSB) */
    for (k = 0; k < 8; k++) {
        fx_angle_t a = FX_ANGLE_45 + k * FX_ANGLE_90;
        q1_30_t s = fx_sin(a), c = fx_cos(a);
        TEST_ASSERT_INT32_WITHIN(1, 759250125, s < 0 ? -s : s);
        TEST_ASSERT_EQUAL_INT32(s < 0 ? -s : s, c < 0 ? -c : c);
    }
    /* sin 30 = 1/2, cos 60 = 1/2 (binary angle of 30 degrees is not exact:
     * 2^32 / 12 = 357913941.33) */
    TEST_ASSERT_INT32_WITHIN(1, 1 << 29, fx_sin(357913941u));
    TEST_ASSERT_INT32_WITHIN(1, 1 << 29, fx_cos(715827883u));
    /* smallest angle: sin(2 pi / 2^32) * 2^30 = 1.57 -> 2 (or 1) */
    TEST_ASSERT_INT32_WITHIN(1, 2, fx_sin(1));
    TEST_ASSERT_INT32_WITHIN(1, -2, fx_sin(0xFFFFFFFFu));
    TEST_ASSERT_EQUAL_INT32(FX_ONE_Q30, fx_cos(1));
}

static void test_sin_cos_dense_grid_and_octants(void)
{
    uint32_t k;
    int32_t d;
    sin_err_max = cos_err_max = 0.0;
    /* 2^20 points over the whole turn, with an odd offset so the low bits vary */
    for (k = 0; k < (1u << 20); k++) {
        check_sincos(k * 4096u + (k * 2654435761u >> 20));
    }
    /* every angle within 2^13 LSB of each octant boundary (the fold points) */
    for (k = 0; k < 8; k++) {
        for (d = -(1 << 13); d <= (1 << 13); d++) {
            check_sincos(k * FX_ANGLE_45 + (uint32_t)d);
        }
    }
    rng_seed(12);
    for (k = 0; k < 200000; k++) {
        check_sincos((fx_angle_t)rng());
    }
    /* the worst angle of an exhaustive offline sweep of [0, 90] degrees (all
     * others are exact reflections): 0.960 LSB, and its reflections */
    for (k = 0; k < 4; k++) {
        check_sincos(0x200d5eedu + k * FX_ANGLE_90);
        check_sincos(k * FX_ANGLE_90 - 0x200d5eedu);
    }
    report("fixmath_sin_max_error", sin_err_max, "lsb_q30");
    report("fixmath_cos_max_error", cos_err_max, "lsb_q30");
    TEST_ASSERT_TRUE(sin_err_max <= SIN_BOUND_LSB);
    TEST_ASSERT_TRUE(cos_err_max <= SIN_BOUND_LSB);
}

static void test_sin_cos_symmetry_and_range(void)
{
    uint32_t k;
    rng_seed(13);
    for (k = 0; k < 300000; k++) {
        fx_angle_t a = (k < 100000) ? k : (fx_angle_t)rng();
        q1_30_t s = fx_sin(a), c = fx_cos(a);
        if (s != -fx_sin((fx_angle_t)0 - a) || c != fx_cos((fx_angle_t)0 - a) ||
            s != -fx_sin(a + FX_ANGLE_180) || c != -fx_cos(a + FX_ANGLE_180) ||
            c != fx_sin(FX_ANGLE_90 - a) || s != fx_cos(FX_ANGLE_90 - a) || s > FX_ONE_Q30 ||
            s < -FX_ONE_Q30) {
            snprintf(msg, sizeof msg, "symmetry broken at 0x%08x", a);
            TEST_FAIL_MESSAGE(msg);
        }
    }
}

static void test_sin_monotonic_first_quadrant(void)
{
    /* sin never decreases on [0, 90] degrees (no 1-LSB dips at the fold) */
    uint32_t a;
    q1_30_t prev = fx_sin(0);
    for (a = 1; a <= FX_ANGLE_90;
         a += (a > FX_ANGLE_45 - 100000 && a < FX_ANGLE_45 + 100000) ? 1 : 997) {
        q1_30_t s = fx_sin(a);
        if (s < prev) {
            snprintf(msg, sizeof msg, "sin decreases at 0x%08x", a);
            TEST_FAIL_MESSAGE(msg);
        }
        prev = s;
    }
}

static double atan_err_max;

static void check_atan2(int64_t y, int64_t x)
{
    double e = fabs(angle_err(fx_atan2(y, x), ref_atan2_turns(y, x)));
    if (e > atan_err_max) {
        atan_err_max = e;
    }
    if (e > ATAN_BOUND_LSB) {
        snprintf(msg, sizeof msg, "atan2(%" PRId64 ", %" PRId64 ") = %u: err %.3f LSB", y, x,
                 fx_atan2(y, x), e);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_atan2_axes_and_diagonals(void)
{
    static const int64_t mags[] = {1, 2, 3, 1000, (int64_t)1 << 40, INT64_MAX - 1, INT64_MAX};
    unsigned i;
    TEST_ASSERT_EQUAL_UINT32(0, fx_atan2(0, 0));
    for (i = 0; i < sizeof mags / sizeof mags[0]; i++) {
        int64_t m = mags[i];
        TEST_ASSERT_EQUAL_UINT32(0, fx_atan2(0, m));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_90, fx_atan2(m, 0));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180, fx_atan2(0, -m));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_270, fx_atan2(-m, 0));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_45, fx_atan2(m, m));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_90 + FX_ANGLE_45, fx_atan2(m, -m));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180 + FX_ANGLE_45, fx_atan2(-m, -m));
        TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_270 + FX_ANGLE_45, fx_atan2(-m, m));
    }
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180, fx_atan2(0, INT64_MIN));
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_270, fx_atan2(INT64_MIN, 0));
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180 + FX_ANGLE_45, fx_atan2(INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_90 + FX_ANGLE_45, fx_atan2(INT64_MAX, -INT64_MAX));
    /* one quadrant at a time, 30 and 60 degrees: (sqrt 3, 1) */
    TEST_ASSERT_UINT32_WITHIN(1, 357913941u, fx_atan2(1000000000, 1732050808));
    TEST_ASSERT_UINT32_WITHIN(1, 4294967296u - 357913941u, fx_atan2(-1000000000, 1732050808));
    TEST_ASSERT_UINT32_WITHIN(1, 2147483648u - 357913941u, fx_atan2(1000000000, -1732050808));
    TEST_ASSERT_UINT32_WITHIN(1, 2147483648u + 357913941u, fx_atan2(-1000000000, -1732050808));
}

static void test_atan2_exhaustive_small_and_extremes(void)
{
    int64_t x, y;
    unsigned i, j;
    atan_err_max = 0.0;
    for (y = -64; y <= 64; y++) {
        for (x = -64; x <= 64; x++) {
            check_atan2(y, x);
        }
    }
    for (i = 0; i < N_EDGE64; i++) {
        for (j = 0; j < N_EDGE64; j++) {
            check_atan2(edge64[i], edge64[j]);
        }
    }
    /* tiny against huge, and nearly equal huge components */
    check_atan2(1, INT64_MAX);
    check_atan2(1, INT64_MIN);
    check_atan2(-1, INT64_MIN);
    check_atan2(INT64_MAX, 1);
    check_atan2(INT64_MAX, INT64_MAX - 1);
    check_atan2(INT64_MIN + 1, INT64_MIN);
    check_atan2((int64_t)1 << 40, ((int64_t)1 << 40) + 1);
    TEST_ASSERT_EQUAL_UINT32(0, fx_atan2(1, INT64_MAX));
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180, fx_atan2(1, INT64_MIN)); /* 180 - 7e-11 LSB */
    TEST_ASSERT_EQUAL_UINT32(FX_ANGLE_180, fx_atan2(-1, INT64_MIN));
    /* one LSB of angle is 1.46e-9 rad: y/x = 1e-9 is 0.68 LSB -> 1 */
    TEST_ASSERT_EQUAL_UINT32(1, fx_atan2(1000, 1000000000000LL));
    TEST_ASSERT_EQUAL_UINT32(0xFFFFFFFFu, fx_atan2(-1000, 1000000000000LL));
}

static void test_atan2_random_full_domain(void)
{
    unsigned i;
    rng_seed(14);
    for (i = 0; i < 200000; i++) {
        int64_t y = rnd_i64(), x = rnd_i64();
        fx_angle_t a = fx_atan2(y, x);
        check_atan2(y, x);
        /* exact symmetries */
        if (y != INT64_MIN && x != INT64_MIN && (x | y) != 0) {
            if (fx_atan2(-y, x) != (fx_angle_t)0 - a || fx_atan2(y, -x) != FX_ANGLE_180 - a) {
                snprintf(msg, sizeof msg, "atan2 symmetry at (%" PRId64 ", %" PRId64 ")", y, x);
                TEST_FAIL_MESSAGE(msg);
            }
            if (x >= 0 && y >= 0 && fx_atan2(x, y) != FX_ANGLE_90 - a) {
                snprintf(msg, sizeof msg, "atan2 swap at (%" PRId64 ", %" PRId64 ")", y, x);
                TEST_FAIL_MESSAGE(msg);
            }
        }
    }
    /* near-axis, near-diagonal and scaled copies: same angle at every scale */
    for (i = 0; i < 20000; i++) {
        int64_t x = (int64_t)(rng() >> 2), y = x + (int64_t)(rng() % 1000) - 500;
        int64_t small = (int64_t)(rng() >> 34) + 1;
        check_atan2(y, x);
        check_atan2(small, x);
        check_atan2(y / 4096, x / 4096);
        TEST_ASSERT_EQUAL_UINT32(fx_atan2(small, small * 3), fx_atan2(small * 1024, small * 3072));
    }
    report("fixmath_atan2_max_error", atan_err_max, "lsb_angle");
    TEST_ASSERT_TRUE(atan_err_max <= ATAN_BOUND_LSB);
}

static void test_atan2_of_sincos_round_trip(void)
{
    unsigned i;
    double worst = 0.0;
    rng_seed(15);
    for (i = 0; i < 100000; i++) {
        fx_angle_t a = (fx_angle_t)rng();
        double e = fabs(angle_err(fx_atan2(fx_sin(a), fx_cos(a)), (double)a));
        if (e > worst) {
            worst = e;
        }
    }
    report("fixmath_atan2_sincos_roundtrip_max_error", worst, "lsb_angle");
    /* sin/cos errors of 1 LSB q30 move the angle by up to 0.9 LSB */
    TEST_ASSERT_TRUE(worst <= 2.0);
}

/* ---- vector length --------------------------------------------------------------- */

static void test_hypot_exact_small_and_extremes(void)
{
    int64_t x, y;
    for (y = -70; y <= 70; y++) {
        for (x = -70; x <= 70; x++) {
            int64_t z = (x * 7 + y) % 50;
            EXPECT_I64((int64_t)ref_isqrt128((u128)(x * x + y * y)), fx_hypot2(x, y),
                       "hypot2(%" PRId64 ", %" PRId64 ")", x, y);
            EXPECT_I64((int64_t)ref_isqrt128((u128)(x * x + y * y + z * z)), fx_hypot3(x, y, z),
                       "hypot3(%" PRId64 ", %" PRId64 ", %" PRId64 ")", x, y, z);
        }
    }
    TEST_ASSERT_EQUAL_INT64(5, fx_hypot2(3, 4));
    TEST_ASSERT_EQUAL_INT64(5, fx_hypot2(-3, -4));
    TEST_ASSERT_EQUAL_INT64(13, fx_hypot3(3, 4, 12));
    TEST_ASSERT_EQUAL_INT64(0, fx_hypot2(0, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_hypot3(0, 0, 0));
    /* one component: exactly |x|, at every scale */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MAX, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(0, -INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX - 1, fx_hypot3(0, INT64_MAX - 1, 0));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 31, fx_hypot2((int64_t)1 << 31, 0));
    TEST_ASSERT_EQUAL_INT64(((int64_t)1 << 31) - 1, fx_hypot2(((int64_t)1 << 31) - 1, 0));
    TEST_ASSERT_EQUAL_INT64(123456789012345LL, fx_hypot3(0, 0, -123456789012345LL));
    /* saturation */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MIN, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot3(INT64_MIN, INT64_MIN, INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MAX, 1)); /* exact, not saturated */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX - 1, fx_hypot2(INT64_MAX - 1, 1 << 30)); /* + 1/16 */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MAX, 1 << 30));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_hypot2(INT64_MAX, (int64_t)1 << 32)); /* sat */
    /* a Pythagorean triple scaled to the top of the range: 3-4-5 times 2^60 */
    TEST_ASSERT_EQUAL_INT64((int64_t)5 << 60, fx_hypot2((int64_t)3 << 60, -((int64_t)4 << 60)));
    TEST_ASSERT_EQUAL_INT64((int64_t)13 << 59,
                            fx_hypot3((int64_t)3 << 59, (int64_t)4 << 59, (int64_t)12 << 59));
    /* just under and over a triple: floor is exact */
    TEST_ASSERT_EQUAL_INT64(((int64_t)5 << 60) - 1,
                            fx_hypot2((int64_t)3 << 60, ((int64_t)4 << 60) - 1));
}

static void test_hypot_random_full_domain(void)
{
    unsigned i;
    rng_seed(16);
    for (i = 0; i < 100000; i++) {
        int64_t x = rnd_i64(), y = rnd_i64(), z = rnd_i64();
        u128 n2 = uabs(x) * uabs(x) + uabs(y) * uabs(y);
        u128 n3 = n2 + uabs(z) * uabs(z);
        int64_t ref2 = sat64((i128)ref_isqrt128(n2)), ref3 = sat64((i128)ref_isqrt128(n3));
        int64_t h2 = fx_hypot2(x, y);
        EXPECT_I64(ref2, h2, "hypot2(%" PRId64 ", %" PRId64 ")", x, y);
        EXPECT_I64(ref3, fx_hypot3(x, y, z), "hypot3(%" PRId64 ", %" PRId64 ", %" PRId64 ")", x, y,
                   z);
        /* symmetric in sign and order */
        if (x != INT64_MIN && y != INT64_MIN) {
            EXPECT_I64(h2, fx_hypot2(-y, x), "hypot2 sym (%" PRId64 ", %" PRId64 ")", x, y);
        }
    }
    /* both sides of the 2^31 fast-path boundary */
    for (i = 0; i < 20000; i++) {
        int64_t x = ((int64_t)1 << 31) - 1000 + (int64_t)(rng() % 2000);
        int64_t y = (int64_t)(rng() >> 33) - ((int64_t)1 << 30);
        int64_t z = (int64_t)(rng() % 4096) - 2048;
        u128 n3 = uabs(x) * uabs(x) + uabs(y) * uabs(y) + uabs(z) * uabs(z);
        EXPECT_I64((int64_t)ref_isqrt128(uabs(x) * uabs(x) + uabs(y) * uabs(y)), fx_hypot2(x, y),
                   "hypot2(%" PRId64 ", %" PRId64 ")", x, y);
        EXPECT_I64((int64_t)ref_isqrt128(n3), fx_hypot3(y, z, x),
                   "hypot3(%" PRId64 ", %" PRId64 ", %" PRId64 ")", y, z, x);
    }
}

/* ---- inline helpers shared by the tick and the planner -------------------- */

static void test_clamp_sym_uabs_signed_sat(void)
{
    static const int64_t v[] = {INT64_MIN, INT64_MIN + 1, -5,       -1, 0, 1,
                                5,         INT64_MAX - 1, INT64_MAX};
    static const int64_t lim[] = {0, 1, 4, 5, 6, INT64_MAX};
    unsigned i, j;

    for (i = 0; i < sizeof v / sizeof v[0]; i++) {
        for (j = 0; j < sizeof lim / sizeof lim[0]; j++) {
            TEST_ASSERT_EQUAL_INT64(fx_clamp64(v[i], -lim[j], lim[j]),
                                    fx_clamp_sym64(v[i], lim[j]));
        }
        TEST_ASSERT_EQUAL_UINT64((uint64_t)(v[i] < 0 ? -(i128)v[i] : (i128)v[i]), fx_uabs64(v[i]));
    }
    TEST_ASSERT_EQUAL_UINT64((uint64_t)1 << 63, fx_uabs64(INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_signed_sat(true, (uint64_t)1 << 63, true));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_signed_sat(true, ((uint64_t)1 << 63) + 1u, true));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_signed_sat(true, (uint64_t)1 << 63, false));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_signed_sat(true, (uint64_t)INT64_MAX, false));
    TEST_ASSERT_EQUAL_INT64(-INT64_MAX, fx_signed_sat(true, (uint64_t)INT64_MAX, true));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_signed_sat(false, 0, false));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_signed_sat(false, 0, true));
    TEST_ASSERT_EQUAL_INT64(0, fx_signed_sat(true, 0, true));
    TEST_ASSERT_EQUAL_INT64(-7, fx_signed_sat(true, 7, true));
}

static void check_umul(uint64_t a, uint64_t b)
{
    u128 p = (u128)a * b;
    fx_u128_t r = fx_umul64(a, b);

    TEST_ASSERT_EQUAL_UINT64((uint64_t)(p >> 64), r.hi);
    TEST_ASSERT_EQUAL_UINT64((uint64_t)p, r.lo);
    TEST_ASSERT_EQUAL_UINT64((uint64_t)(p >> 64), fx_umulhi64(a, b));
    p = (u128)a * (uint32_t)b;
    r = fx_umul64x32(a, (uint32_t)b);
    TEST_ASSERT_EQUAL_UINT64((uint64_t)(p >> 64), r.hi);
    TEST_ASSERT_EQUAL_UINT64((uint64_t)p, r.lo);
}

static void test_umul64_extremes_and_random(void)
{
    static const uint64_t e[] = {0,
                                 1,
                                 2,
                                 0xFFFFFFFFu,
                                 (uint64_t)1 << 32,
                                 ((uint64_t)1 << 32) + 1u,
                                 (uint64_t)1 << 63,
                                 UINT64_MAX - 1u,
                                 UINT64_MAX};
    unsigned i, j;

    for (i = 0; i < sizeof e / sizeof e[0]; i++) {
        for (j = 0; j < sizeof e / sizeof e[0]; j++) {
            check_umul(e[i], e[j]);
        }
    }
    rng_seed(0x128);
    for (i = 0; i < 200000; i++) {
        check_umul(rnd_u64(), rnd_u64());
    }
}

static fx_u128_t mk128(u128 v)
{
    fx_u128_t r;

    r.hi = (uint64_t)(v >> 64);
    r.lo = (uint64_t)v;
    return r;
}

static void test_add_cmp128_and_bit_lengths(void)
{
    static const u128 e[] = {0,
                             1,
                             ((u128)1 << 64) - 1u,
                             (u128)1 << 64,
                             ((u128)1 << 64) + 1u,
                             (u128)UINT64_MAX << 64,
                             ~(u128)0};
    unsigned i, j;
    fx_u128_t s;

    for (i = 0; i < sizeof e / sizeof e[0]; i++) {
        for (j = 0; j < sizeof e / sizeof e[0]; j++) {
            s = fx_add128(mk128(e[i]), mk128(e[j]));
            TEST_ASSERT_TRUE(s.hi == (uint64_t)((e[i] + e[j]) >> 64) &&
                             s.lo == (uint64_t)(e[i] + e[j]));
            TEST_ASSERT_EQUAL_INT((e[i] > e[j]) - (e[i] < e[j]),
                                  fx_cmp128(mk128(e[i]), mk128(e[j])));
        }
    }
    TEST_ASSERT_EQUAL_UINT(0, fx_bitlen64(0));
    for (i = 0; i < 64; i++) {
        uint64_t p = (uint64_t)1 << i;
        TEST_ASSERT_EQUAL_UINT(i + 1u, fx_bitlen64(p));
        TEST_ASSERT_EQUAL_UINT(i + 1u, fx_bitlen64(p | (p - 1u)));
        TEST_ASSERT_EQUAL_UINT(63u - i, fx_clz64(p));
        if (i < 32) {
            TEST_ASSERT_EQUAL_UINT(31u - i, fx_clz32((uint32_t)p));
        }
    }
}

static void check_isqrt128(u128 n)
{
    uint64_t r = fx_isqrt128(mk128(n));

    TEST_ASSERT_TRUE((u128)r * r <= n);
    TEST_ASSERT_TRUE(r == UINT64_MAX || (u128)(r + 1u) * (r + 1u) > n);
}

static void test_isqrt128_boundaries_and_random(void)
{
    unsigned b, i;

    check_isqrt128(0);
    check_isqrt128(~(u128)0);
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_isqrt128(mk128(~(u128)0)));
    for (b = 32; b < 64; b++) { /* roots around every power of two, both paths */
        uint64_t r = (uint64_t)1 << b;
        uint64_t rs[] = {r - 1u, r, r + 1u, r | (r - 1u)};
        for (i = 0; i < 4; i++) {
            u128 sq = (u128)rs[i] * rs[i];
            check_isqrt128(sq - 1u);
            check_isqrt128(sq);
            check_isqrt128(sq + 1u);
            TEST_ASSERT_EQUAL_UINT64(rs[i], fx_isqrt128(mk128(sq)));
            TEST_ASSERT_EQUAL_UINT64(rs[i] - 1u, fx_isqrt128(mk128(sq - 1u)));
        }
    }
    check_isqrt128(((u128)1 << 126) - 1u); /* last value of the Newton path */
    check_isqrt128((u128)1 << 126);
    rng_seed(0x5127);
    for (i = 0; i < 100000; i++) {
        check_isqrt128(((u128)rnd_u64() << 64) | rng());
    }
}

static void test_in_range_min_max(void)
{
    static const uint32_t mx[] = {0, 1, 2, 1000, 0x3FFFFFFFu, 0x7FFFFFFEu, 0x7FFFFFFFu};
    static const int32_t v[] = {
        INT32_MIN, INT32_MIN + 1, -0x7FFFFFFE, -1001,      -1000,    -2, -1, 0, 1,
        2,         1000,          1001,        0x7FFFFFFE, INT32_MAX};
    unsigned i, j;

    for (i = 0; i < sizeof mx / sizeof mx[0]; i++) {
        for (j = 0; j < sizeof v / sizeof v[0]; j++) {
            int64_t a = (v[j] < 0) ? -(int64_t)v[j] : v[j];
            TEST_ASSERT_EQUAL_INT(a <= (int64_t)mx[i], fx_in_range32(v[j], mx[i]));
        }
    }
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, fx_min64(INT64_MIN, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_max64(INT64_MIN, INT64_MAX));
    TEST_ASSERT_EQUAL_INT64(-1, fx_min64(-1, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_max64(-1, 0));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, fx_sat_neg64(INT64_MIN));
    TEST_ASSERT_EQUAL_INT64(-INT64_MAX, fx_sat_neg64(INT64_MAX));
}

/* the PID's preloaded-rounding products against fx_mul32_shift, at every
 * shift and the operand extremes */
static void test_mul_rsh_and_mul_q30_pos(void)
{
    static const int32_t x[] = {INT32_MIN, INT32_MIN + 1, -65536,   -3, -1, 0, 1,
                                3,         65535,         INT32_MAX};
    unsigned sh, i, j;

    for (sh = 1; sh < 32; sh++) {
        uint32_t rnd = (uint32_t)1 << (sh - 1);
        for (i = 0; i < sizeof x / sizeof x[0]; i++) {
            for (j = 0; j < sizeof x / sizeof x[0]; j++) {
                int64_t ref = fx_mul32_shift(x[i], x[j], sh);
                TEST_ASSERT_EQUAL_INT64(ref, fx_mul_rsh64(x[i], x[j], sh, rnd));
                TEST_ASSERT_EQUAL_INT64(ref, fx_mul_rsh64_pieces(x[i], x[j], sh, rnd));
                if (ref == (int32_t)ref) {
                    TEST_ASSERT_EQUAL_INT32((int32_t)ref, fx_mul_rsh32(x[i], x[j], sh, rnd));
                    TEST_ASSERT_EQUAL_INT32((int32_t)ref, fx_mul_rsh32_pieces(x[i], x[j], sh, rnd));
                }
            }
        }
    }
    /* the host form (FX_RSH_PIECES 0) against the M4's pieces, bit for bit
     * (fx_mul_rsh32: the low word, whatever the value) */
    TEST_ASSERT_EQUAL_INT(0, FX_RSH_PIECES);
    rng_seed(0x31);
    for (i = 0; i < 1000000u; i++) {
        int32_t a = (int32_t)rng() >> (rng() % 32u), m = (int32_t)rng() >> (rng() % 32u);
        unsigned s = 1u + (unsigned)(rng() % 31u);
        uint32_t rnd = (uint32_t)1 << (s - 1u);
        TEST_ASSERT_EQUAL_INT64(fx_mul_rsh64_pieces(a, m, s, rnd), fx_mul_rsh64(a, m, s, rnd));
        TEST_ASSERT_EQUAL_INT64(fx_mul32_shift(a, m, s), fx_mul_rsh64(a, m, s, rnd));
        TEST_ASSERT_EQUAL_INT32(fx_mul_rsh32_pieces(a, m, s, rnd), fx_mul_rsh32(a, m, s, rnd));
    }
    rng_seed(0x30);
    for (i = 0; i < 200000; i++) {
        int64_t a = (int64_t)(rng() >> 2) - ((int64_t)1 << 61); /* |a| <= 2^61 */
        q1_30_t b = (q1_30_t)(rng() % ((uint64_t)FX_ONE_Q30 + 1u));
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, b, 30), fx_mul_q30_pos(a, b));
    }
    TEST_ASSERT_EQUAL_INT64(((int64_t)1 << 61), fx_mul_q30_pos((int64_t)1 << 61, FX_ONE_Q30));
    TEST_ASSERT_EQUAL_INT64(-((int64_t)1 << 61), fx_mul_q30_pos(-((int64_t)1 << 61), FX_ONE_Q30));
    TEST_ASSERT_EQUAL_INT64(0, fx_mul_q30_pos(-((int64_t)1 << 61), 0));
}

/* The host forms of fx_mul_q30_pos and fx_mul64x32_shift32 (FX_MUL_PIECES
 * 0: the signed 128-bit product) against the pieces the M4 compiles, bit
 * for bit: the operands' edges pairwise and random operands of every
 * magnitude, over each function's whole domain (|a| <= 2^61 and 0 <= b <=
 * 2^30; every int64 a and int32 b). */
static void test_mul_q30_host_equals_pieces(void)
{
    static const int64_t ea[] = {0,
                                 1,
                                 -1,
                                 2,
                                 -2,
                                 0x7FFFFFFF,
                                 -0x80000000LL,
                                 0xFFFFFFFFLL,
                                 0x100000000LL,
                                 -0x100000001LL,
                                 ((int64_t)1 << 61) - 1,
                                 (int64_t)1 << 61,
                                 -((int64_t)1 << 61),
                                 INT64_MAX,
                                 INT64_MIN,
                                 INT64_MIN + 1};
    static const int32_t eb[] = {0,          1,          -1,           2,
                                 0x1FFFFFFF, 0x20000000, 0x3FFFFFFF,   FX_ONE_Q30,
                                 INT32_MAX,  INT32_MIN,  INT32_MIN + 1};
    const unsigned na = sizeof ea / sizeof ea[0], nb = sizeof eb / sizeof eb[0];
    unsigned i, j;

    TEST_ASSERT_EQUAL_INT(0, FX_MUL_PIECES); /* the host form is the one in use */
    for (i = 0; i < na; i++) {
        for (j = 0; j < nb; j++) {
            int64_t a = ea[i];
            int32_t b = eb[j];
            TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift32_pieces(a, b), fx_mul64x32_shift32(a, b));
            if (a >= -((int64_t)1 << 61) && a <= ((int64_t)1 << 61) && b >= 0 && b <= FX_ONE_Q30) {
                TEST_ASSERT_EQUAL_INT64(fx_mul_q30_pos_pieces(a, b), fx_mul_q30_pos(a, b));
            }
        }
    }
    rng_seed(0x51);
    for (i = 0; i < 2000000u; i++) {
        int64_t a = (int64_t)rnd_u64() >> (rng() % 64u);
        int32_t b = (int32_t)rng() >> (rng() % 32u);
        int64_t a61 = a >> 2; /* |a61| <= 2^61 */
        q1_30_t b30 = (q1_30_t)((uint32_t)b % ((uint32_t)FX_ONE_Q30 + 1u));
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift32_pieces(a, b), fx_mul64x32_shift32(a, b));
        TEST_ASSERT_EQUAL_INT64(fx_mul_q30_pos_pieces(a61, b30), fx_mul_q30_pos(a61, b30));
    }
}

/* the inline high-word products against fx_mul64_shift at every shift,
 * the extremes (2^63 magnitudes, ties of both signs) and random operands */
static void check_umul_shift_hi(uint64_t ua, uint64_t ub, unsigned t)
{
    i128 x = (i128)((u128)ua * ub); /* <= 2^126 */
    i128 half = (i128)1 << (63 + t);

    /* shift rule: floor((x + 2^(s-1)) / 2^s), arithmetic shift of i128 */
    TEST_ASSERT_EQUAL_INT64((int64_t)(((u128)x + (u128)half) >> (64 + t)),
                            fx_umul_shift_hi(ua, ub, false, t));
    TEST_ASSERT_EQUAL_INT64((int64_t)((-x + half) >> (64 + t)), fx_umul_shift_hi(ua, ub, true, t));
}

static void test_umul_shift_hi_and_mul64x32_shift32(void)
{
    static const uint64_t e[] = {0,
                                 1,
                                 3,
                                 0xFFFFFFFFu,
                                 (uint64_t)1 << 32,
                                 (uint64_t)1 << 62,
                                 ((uint64_t)1 << 63) - 1u,
                                 (uint64_t)1 << 63};
    static const int64_t a64[] = {
        INT64_MIN,        INT64_MIN + 1, -((int64_t)1 << 32), -3, -1, 0, 1, 3,
        (int64_t)1 << 32, INT64_MAX};
    static const int32_t b32[] = {INT32_MIN, INT32_MIN + 1, -65536,   -2, -1, 0, 1,
                                  2,         65536,         INT32_MAX};
    unsigned t, i, j;

    for (t = 1; t < 64; t++) {
        for (i = 0; i < sizeof e / sizeof e[0]; i++) {
            for (j = 0; j < sizeof e / sizeof e[0]; j++) {
                check_umul_shift_hi(e[i], e[j], t);
            }
        }
        if (t <= 61) { /* a tie of both signs: |p| = 3 * 2^(63 + t) */
            check_umul_shift_hi((uint64_t)3 << t, (uint64_t)1 << 63, t);
        }
        check_umul_shift_hi(5, (uint64_t)1 << 62, t);
    }
    rng_seed(0x64);
    for (i = 0; i < 200000; i++) {
        check_umul_shift_hi(rng() >> 1, rng() >> 1, 1u + (unsigned)(rng() % 63));
        check_umul_shift_hi(rnd_u64() >> 1, rnd_u64() >> 1, 14);
    }
    for (i = 0; i < sizeof a64 / sizeof a64[0]; i++) {
        for (j = 0; j < sizeof b32 / sizeof b32[0]; j++) {
            TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a64[i], b32[j], 32),
                                    fx_mul64x32_shift32(a64[i], b32[j]));
        }
    }
    for (i = 0; i < 200000; i++) {
        int64_t a = (int64_t)rnd_u64();
        int32_t b = (int32_t)rng();
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, b, 32), fx_mul64x32_shift32(a, b));
        a = (int64_t)(rng() & ~(uint64_t)0xFFFFFFFFu) | 0x80000000u; /* ties */
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, 1, 32), fx_mul64x32_shift32(a, 1));
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, -1, 32), fx_mul64x32_shift32(a, -1));
    }
}

/* small-angle sine and versine (q62) against long double (64-bit mantissa:
 * absolute error below 2^-66 here) within the stated series bounds */
static void check_sin_vers_small(uint64_t a)
{
    long double pi = 3.14159265358979323846264338327950288L;
    long double x = (long double)a * (2.0L * pi) / 18446744073709551616.0L; /* rad */
    long double two62 = 4611686018427387904.0L;
    long double s_ref = sinl(x) * two62, v_ref = 2.0L * sinl(x / 2.0L) * sinl(x / 2.0L) * two62;
    long double x2 = x * x, x7 = x2 * x2 * x2 * x, x8 = x7 * x;
    long double s_tol = x7 / 5040.0L * two62 + 8.0L, v_tol = x8 / 40320.0L * two62 + 8.0L;
    uint64_t sn, vs;

    fx_sin_vers_small(a, &sn, &vs);
    TEST_ASSERT_TRUE(fabsl((long double)sn - s_ref) <= s_tol);
    TEST_ASSERT_TRUE(fabsl((long double)vs - v_ref) <= v_tol);
}

static void test_sin_vers_small(void)
{
    unsigned i;
    uint64_t sn, vs, sn2, vs2;

    fx_sin_vers_small(0, &sn, &vs);
    TEST_ASSERT_EQUAL_UINT64(0, sn);
    TEST_ASSERT_EQUAL_UINT64(0, vs);
    check_sin_vers_small(1);
    check_sin_vers_small((uint64_t)1 << 32); /* one fx_angle_t LSB */
    check_sin_vers_small(FX_SMALL_ANGLE_MAX);
    for (i = 0; i < 58; i++) {
        check_sin_vers_small((uint64_t)1 << i);
        check_sin_vers_small(((uint64_t)1 << i) * 3u / 2u);
    }
    rng_seed(0x5199);
    for (i = 0; i < 100000; i++) {
        check_sin_vers_small(rng() >> 6); /* [0, 2^58) */
    }
    /* clamped above the maximum */
    fx_sin_vers_small(FX_SMALL_ANGLE_MAX, &sn, &vs);
    fx_sin_vers_small(UINT64_MAX, &sn2, &vs2);
    TEST_ASSERT_EQUAL_UINT64(sn, sn2);
    TEST_ASSERT_EQUAL_UINT64(vs, vs2);
}

/* the inline one-multiply forms against the general functions */
static void test_mul64_sat_and_shift30_inline(void)
{
    static const int64_t e[] = {INT64_MIN,
                                INT64_MIN + 1,
                                -((int64_t)1 << 32),
                                (int64_t)INT32_MIN - 1,
                                INT32_MIN,
                                -3,
                                -1,
                                0,
                                1,
                                3,
                                INT32_MAX,
                                (int64_t)INT32_MAX + 1,
                                (int64_t)1 << 32,
                                INT64_MAX};
    static const int32_t b32[] = {INT32_MIN, -65536, -1, 0, 1, 65536, (int32_t)1 << 29, INT32_MAX};
    unsigned i, j;

    for (i = 0; i < sizeof e / sizeof e[0]; i++) {
        for (j = 0; j < sizeof e / sizeof e[0]; j++) {
            TEST_ASSERT_EQUAL_INT64(fx_mul64_shift(e[i], e[j], 0), fx_mul64_sat(e[i], e[j]));
        }
        for (j = 0; j < sizeof b32 / sizeof b32[0]; j++) {
            TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(e[i], b32[j], 30),
                                    fx_mul64x32_shift30(e[i], b32[j]));
        }
    }
    rng_seed(0x3030);
    for (i = 0; i < 200000; i++) {
        int64_t a = (int64_t)rnd_u64(), b = (int64_t)rnd_u64();
        TEST_ASSERT_EQUAL_INT64(fx_mul64_shift(a, b, 0), fx_mul64_sat(a, b));
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, (int32_t)b, 30),
                                fx_mul64x32_shift30(a, (int32_t)b));
        a = (int64_t)(int32_t)rng(); /* the one-multiply path, ties included */
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, (int32_t)1 << 29, 30),
                                fx_mul64x32_shift30(a, (int32_t)1 << 29));
    }
}

/* The wire formats' unsigned saturations, at both ends. */
static void test_sat_u32_u16_at_the_extremes(void)
{
    TEST_ASSERT_EQUAL_UINT32(0u, fx_sat_u32(INT64_MIN));
    TEST_ASSERT_EQUAL_UINT32(0u, fx_sat_u32(-1));
    TEST_ASSERT_EQUAL_UINT32(0u, fx_sat_u32(0));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX - 1u, fx_sat_u32((int64_t)UINT32_MAX - 1));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_sat_u32((int64_t)UINT32_MAX));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_sat_u32((int64_t)UINT32_MAX + 1));
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, fx_sat_u32(INT64_MAX));
    TEST_ASSERT_EQUAL_UINT16(0u, fx_sat_u16(0u));
    TEST_ASSERT_EQUAL_UINT16(0xFFFEu, fx_sat_u16(0xFFFEu));
    TEST_ASSERT_EQUAL_UINT16(0xFFFFu, fx_sat_u16(0xFFFFu));
    TEST_ASSERT_EQUAL_UINT16(0xFFFFu, fx_sat_u16(0x10000u));
    TEST_ASSERT_EQUAL_UINT16(0xFFFFu, fx_sat_u16(UINT32_MAX));
}

static void test_gcd64(void)
{
    TEST_ASSERT_EQUAL_UINT64(0u, fx_gcd64(0u, 0u));
    TEST_ASSERT_EQUAL_UINT64(7u, fx_gcd64(7u, 0u));
    TEST_ASSERT_EQUAL_UINT64(7u, fx_gcd64(0u, 7u));
    TEST_ASSERT_EQUAL_UINT64(4000000u,
                             fx_gcd64(5000000000u, 4000u * 1000u)); /* 5 mm lead, 4000 counts */
    TEST_ASSERT_EQUAL_UINT64(1u, fx_gcd64(UINT64_MAX, UINT64_MAX - 1u));
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, fx_gcd64(UINT64_MAX, UINT64_MAX));
    TEST_ASSERT_EQUAL_UINT64(1u << 20, fx_gcd64((uint64_t)3 << 20, (uint64_t)5 << 20));
}

/* The host form of the 64 x 64 -> 128 product (fixmath.h, FX_MUL_PIECES
 * 0: one multiply on a 128-bit type) and of the 64 x 32 one against the
 * 32-bit pieces the Cortex-M4 runs and against the test's own 128-bit
 * product: operand edges (0, 1, 2^31, 2^32 - 1, 2^32, 2^63, 2^64 - 1 and
 * neighbours) pairwise and 2 million random pairs of random widths. */
static void test_umul64_host_equals_pieces(void)
{
    static const uint64_t edge[] = {0u,
                                    1u,
                                    2u,
                                    0x7FFFFFFFu,
                                    0x80000000u,
                                    0xFFFFFFFFu,
                                    0x100000000u,
                                    0x100000001u,
                                    0x7FFFFFFFFFFFFFFFu,
                                    0x8000000000000000u,
                                    0xFFFFFFFF00000000u,
                                    0xFFFFFFFFFFFFFFFEu,
                                    0xFFFFFFFFFFFFFFFFu};
    unsigned i;
    TEST_ASSERT_EQUAL_INT(0, FX_MUL_PIECES); /* the host form is the one in use */
    rng_seed(43);
    for (i = 0; i < 2000000u + 169u; i++) {
        uint64_t a, b;
        if (i < 169u) {
            a = edge[i / 13u];
            b = edge[i % 13u];
        } else {
            a = rnd_u64() >> (rng() % 64u);
            b = rnd_u64() >> (rng() % 64u);
        }
        {
            u128 p = (u128)a * b, p32 = (u128)a * (uint32_t)b;
            fx_u128_t h = fx_umul64(a, b), q = fx_umul64_pieces(a, b);
            fx_u128_t h32 = fx_umul64x32(a, (uint32_t)b), q32 = fx_umul64x32_pieces(a, (uint32_t)b);
            TEST_ASSERT_EQUAL_UINT64((uint64_t)p, h.lo);
            TEST_ASSERT_EQUAL_UINT64((uint64_t)(p >> 64), h.hi);
            TEST_ASSERT_EQUAL_UINT64(h.lo, q.lo);
            TEST_ASSERT_EQUAL_UINT64(h.hi, q.hi);
            TEST_ASSERT_EQUAL_UINT64((uint64_t)p32, h32.lo);
            TEST_ASSERT_EQUAL_UINT64((uint64_t)(p32 >> 64), h32.hi);
            TEST_ASSERT_EQUAL_UINT64(h32.lo, q32.lo);
            TEST_ASSERT_EQUAL_UINT64(h32.hi, q32.hi);
            TEST_ASSERT_EQUAL_UINT64(h.hi, fx_umulhi64(a, b));
        }
    }
}

int main(void)
{
    report_on = getenv("FIXMATH_REPORT") != NULL;
    UNITY_BEGIN();
    RUN_TEST(test_gcd64);
    RUN_TEST(test_sat_u32_u16_at_the_extremes);
    RUN_TEST(test_sat32_boundaries);
    RUN_TEST(test_sat_arith32_edges_and_random);
    RUN_TEST(test_sat_arith64_edges_and_random);
    RUN_TEST(test_sat_diff32_exact);
    RUN_TEST(test_sat_diff32_host_equals_wrap);
    RUN_TEST(test_round_shift64_host_equals_bit);
    RUN_TEST(test_clamp);
    RUN_TEST(test_round_shift64_ties_toward_plus_inf);
    RUN_TEST(test_round_shift64_extremes_and_random);
    RUN_TEST(test_mul32_shift_and_sat_mul32);
    RUN_TEST(test_mul64_shift_extremes);
    RUN_TEST(test_mul64_shift_random);
    RUN_TEST(test_pos_scale);
    RUN_TEST(test_conversions);
    RUN_TEST(test_div_round64);
    RUN_TEST(test_div_shift64_and_sat32);
    RUN_TEST(test_muldiv64);
    RUN_TEST(test_recip_q16);
    RUN_TEST(test_udiv_digits_against_native);
    RUN_TEST(test_udiv64by32_exact);
    RUN_TEST(test_isqrt32_exhaustive_and_boundaries);
    RUN_TEST(test_isqrt64_boundaries_and_random);
    RUN_TEST(test_isqrt64_near);
    RUN_TEST(test_umul64_host_equals_pieces);
    RUN_TEST(test_mul_q30_host_equals_pieces);
    RUN_TEST(test_icbrt64_every_cube_boundary);
    RUN_TEST(test_sin_cos_exact_points);
    RUN_TEST(test_sin_cos_dense_grid_and_octants);
    RUN_TEST(test_sin_cos_symmetry_and_range);
    RUN_TEST(test_sin_monotonic_first_quadrant);
    RUN_TEST(test_atan2_axes_and_diagonals);
    RUN_TEST(test_atan2_exhaustive_small_and_extremes);
    RUN_TEST(test_atan2_random_full_domain);
    RUN_TEST(test_atan2_of_sincos_round_trip);
    RUN_TEST(test_hypot_exact_small_and_extremes);
    RUN_TEST(test_hypot_random_full_domain);
    RUN_TEST(test_clamp_sym_uabs_signed_sat);
    RUN_TEST(test_umul64_extremes_and_random);
    RUN_TEST(test_add_cmp128_and_bit_lengths);
    RUN_TEST(test_isqrt128_boundaries_and_random);
    RUN_TEST(test_in_range_min_max);
    RUN_TEST(test_mul_rsh_and_mul_q30_pos);
    RUN_TEST(test_umul_shift_hi_and_mul64x32_shift32);
    RUN_TEST(test_sin_vers_small);
    RUN_TEST(test_mul64_sat_and_shift30_inline);
    return UNITY_END();
}
