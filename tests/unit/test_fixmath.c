/* Fixed-point math: exactness of roots, bounds of trig, saturation. */
#include "fixmath.h"
#include "unity.h"

#include <math.h>

void setUp(void)
{
}

void tearDown(void)
{
}

static void test_isqrt32_exhaustive_small(void)
{
    uint32_t v;
    for (v = 0; v < 1000000u; v++) {
        uint32_t r = fx_isqrt32(v);
        TEST_ASSERT_TRUE((uint64_t)r * r <= v);
        TEST_ASSERT_TRUE((uint64_t)(r + 1) * (r + 1) > v);
    }
    TEST_ASSERT_EQUAL_UINT32(65535u, fx_isqrt32(UINT32_MAX));
}

static void test_sin_error_bound(void)
{
    double worst = 0.0;
    uint32_t i;
    for (i = 0; i < 200000u; i++) {
        fx_angle_t a = i * 21475u + (i >> 3);
        double ref = sin((double)a / 4294967296.0 * 2.0 * M_PI);
        double err = fabs((double)fx_sin(a) / 1073741824.0 - ref);
        if (err > worst) {
            worst = err;
        }
    }
    TEST_ASSERT_TRUE(worst <= 4e-9);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_isqrt32_exhaustive_small);
    RUN_TEST(test_sin_error_bound);
    return UNITY_END();
}
