/*
 * fixmath's inline fast paths of the arc reference and the drive, each
 * against the general function it stands for, on edge values and a
 * pseudo-random sweep of the full argument range:
 *   - fx_mul32_q30(a, b)     == fx_mul32_shift(a, b, 30);
 *   - fx_mul64x32_q30(a, b)  == fx_mul64x32_shift(a, b, 30);
 *   - fx_mul64_sat(a, b)     == fx_mul64_shift(a, b, 0);
 * and the two helpers moved out of the drive against their definitions:
 *   - fx_ratio_q30: the stated shift-then-divide rule, and within
 *     2^30 / den_shifted + 1/2 of the exact quotient;
 *   - fx_sin_1mcos_small_q62: sin d and 1 - cos d within 2e-11 (the
 *     series' remainder plus rounding) of long double values over the
 *     domain, odd and even in d, and 0 outside it.
 */
#include <math.h>

#include "fixmath.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

static uint64_t rng = 0x9E3779B97F4A7C15ull;

static uint64_t next(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

/* A value of random bit length (so small and large magnitudes both come). */
static int64_t rand64(void)
{
    uint64_t v = next() >> 1; /* < 2^63 */
    unsigned len = (unsigned)(next() % 63u);
    return (int64_t)(v >> len) * ((next() & 1u) ? -1 : 1);
}

static const int64_t edges[] = {0,
                                1,
                                -1,
                                2,
                                (int64_t)1 << 29,
                                -((int64_t)1 << 29),
                                INT32_MAX,
                                INT32_MIN,
                                (int64_t)INT32_MAX + 1,
                                (int64_t)INT32_MIN - 1,
                                (int64_t)1 << 62,
                                -((int64_t)1 << 62),
                                INT64_MAX,
                                INT64_MIN,
                                INT64_MIN + 1};
#define N_EDGES (sizeof edges / sizeof edges[0])

static void test_inline_products_equal_the_general_functions(void)
{
    unsigned i, j, k;
    for (i = 0; i < N_EDGES; i++) {
        for (j = 0; j < N_EDGES; j++) {
            int64_t a = edges[i], b = edges[j];
            int32_t b32 = (int32_t)b;
            TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, b32, 30), fx_mul64x32_q30(a, b32));
            TEST_ASSERT_EQUAL_INT64(fx_mul64_shift(a, b, 0), fx_mul64_sat(a, b));
            TEST_ASSERT_EQUAL_INT64(fx_mul32_shift((int32_t)a, b32, 30),
                                    fx_mul32_q30((int32_t)a, b32));
        }
    }
    for (k = 0; k < 2000000u; k++) {
        int64_t a = rand64(), b = rand64();
        int32_t a32 = (int32_t)next(), b32 = (int32_t)next();
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a, b32, 30), fx_mul64x32_q30(a, b32));
        TEST_ASSERT_EQUAL_INT64(fx_mul64_shift(a, b, 0), fx_mul64_sat(a, b));
        TEST_ASSERT_EQUAL_INT64(fx_mul32_shift(a32, b32, 30), fx_mul32_q30(a32, b32));
        /* the fast branches: operands within int32 */
        TEST_ASSERT_EQUAL_INT64(fx_mul64x32_shift(a32, b32, 30), fx_mul64x32_q30(a32, b32));
        TEST_ASSERT_EQUAL_INT64(fx_mul64_shift(a32, b32, 0), fx_mul64_sat(a32, b32));
    }
}

static void test_ratio_q30_follows_its_rule(void)
{
    unsigned k;
    TEST_ASSERT_EQUAL_INT64(0, fx_ratio_q30(0, 5));
    TEST_ASSERT_EQUAL_INT64(0, fx_ratio_q30(-3, 5));
    TEST_ASSERT_EQUAL_INT64(0, fx_ratio_q30(3, 0));
    TEST_ASSERT_EQUAL_INT64(0, fx_ratio_q30(3, -5));
    TEST_ASSERT_EQUAL_INT64(FX_ONE_Q30, fx_ratio_q30(5, 5));
    TEST_ASSERT_EQUAL_INT64(FX_ONE_Q30, fx_ratio_q30(INT64_MAX, 7));
    TEST_ASSERT_EQUAL_INT64((int64_t)1 << 29, fx_ratio_q30(1, 2));
    TEST_ASSERT_EQUAL_INT64(357913941, fx_ratio_q30(1, 3)); /* round(2^30 / 3) */
    TEST_ASSERT_EQUAL_INT64(715827883, fx_ratio_q30(2, 3));
    for (k = 0; k < 1000000u; k++) {
        int64_t den = (int64_t)(next() >> (1u + (unsigned)(next() % 62u)));
        int64_t num = den > 0 ? (int64_t)(next() % (uint64_t)den) : 0;
        int64_t n = num, d = den, want, got = fx_ratio_q30(num, den);
        long double exact;
        if (den <= 0 || num <= 0) {
            TEST_ASSERT_EQUAL_INT64(0, got);
            continue;
        }
        while (d >= ((int64_t)1 << 32)) {
            n >>= 1;
            d >>= 1;
        }
        want = fx_div_round64(n << 30, d);
        TEST_ASSERT_EQUAL_INT64(want, got);
        exact = (long double)num * 1073741824.0L / (long double)den;
        TEST_ASSERT_TRUE(fabsl((long double)got - exact) <= 1073741824.0L / (long double)d + 0.5L);
    }
}

static void test_sin_1mcos_small_q62_within_its_bound(void)
{
    const long double q62 = 4611686018427387904.0L;   /* 2^62 */
    const long double turn = 18446744073709551616.0L; /* 2^64 */
    const int64_t dmax = (int64_t)1 << 58;
    int64_t s, e, s2, e2;
    unsigned k;
    long double worst = 0;
    for (k = 0; k <= 200000u; k++) {
        int64_t d = k == 0 ? 0 : (k == 1 ? dmax : (int64_t)(next() % (uint64_t)dmax));
        long double a = (long double)d * 6.28318530717958647692528676655900577L / turn;
        long double es, ee;
        fx_sin_1mcos_small_q62(d, &s, &e);
        fx_sin_1mcos_small_q62(-d, &s2, &e2);
        TEST_ASSERT_EQUAL_INT64(-s, s2); /* sin odd */
        TEST_ASSERT_EQUAL_INT64(e, e2);  /* 1 - cos even */
        TEST_ASSERT_TRUE(s >= 0 && e >= 0);
        es = fabsl((long double)s / q62 - sinl(a));
        ee = fabsl((long double)e / q62 - (1.0L - cosl(a)));
        worst = es > worst ? es : worst;
        worst = ee > worst ? ee : worst;
    }
    /* the sine's series remainder |d|^7 / 5040 is 1.7e-11 at pi/32 */
    TEST_ASSERT_TRUE(worst < 2e-11L);
    fx_sin_1mcos_small_q62(dmax + 1, &s, &e);
    TEST_ASSERT_EQUAL_INT64(0, s);
    TEST_ASSERT_EQUAL_INT64(0, e);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_inline_products_equal_the_general_functions);
    RUN_TEST(test_ratio_q30_follows_its_rule);
    RUN_TEST(test_sin_1mcos_small_q62_within_its_bound);
    return UNITY_END();
}
