/*
 * fixmath's fx_mul32_q30 (the arc reference's tick form) against the general
 * function it stands for, fx_mul32_shift(a, b, 30), on edge values and 2e6
 * pseudo-random pairs, and fx_ratio_q30 (moved out of the drive) against its definition: the
 * stated shift-then-divide rule, and within 2^30 / den_shifted + 1/2 of the
 * exact quotient. (fx_mul64_sat, fx_mul64x32_shift30 and
 * fx_sin_vers_small are checked in test_fixmath.c.)
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
            TEST_ASSERT_EQUAL_INT64(fx_mul32_shift((int32_t)a, b32, 30),
                                    fx_mul32_q30((int32_t)a, b32));
        }
    }
    for (k = 0; k < 2000000u; k++) {
        int32_t a32 = (int32_t)next(), b32 = (int32_t)next();
        TEST_ASSERT_EQUAL_INT64(fx_mul32_shift(a32, b32, 30), fx_mul32_q30(a32, b32));
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

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_inline_products_equal_the_general_functions);
    RUN_TEST(test_ratio_q30_follows_its_rule);
    return UNITY_END();
}
