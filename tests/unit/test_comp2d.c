/*
 * 2-D compensation map (comp2d.h): bilinear interpolation against values
 * computed by hand, the direction terms, edges held, the shift, and every
 * refusal of comp2d_check.
 */
#include "comp2d.h"
#include "unity.h"

#include <string.h>

static comp2d_map_t M;
static const pos_nm_t LO[2] = {-100000000, -100000000};
static const pos_nm_t HI[2] = {100000000, 100000000};

void setUp(void)
{
    memset(&M, 0, sizeof M);
    M.version = COMP2D_VERSION;
    M.nx = 2;
    M.ny = 2;
    M.x0 = 0;
    M.y0 = 0;
    M.dx = 1000000; /* 1 mm */
    M.dy = 2000000; /* 2 mm */
    /* X's mean correction at (0,0) (1,0) (0,1) (1,1) */
    M.g[0][COMP2D_MID][0] = 100;
    M.g[0][COMP2D_MID][1] = 300;
    M.g[0][COMP2D_MID][2] = -200;
    M.g[0][COMP2D_MID][3] = 500;
}

void tearDown(void)
{
}

static void correct(pos_nm_t x, pos_nm_t y, q1_30_t wx, q1_30_t wy, pos_nm_t out[2])
{
    const pos_nm_t raw[2] = {x, y};
    const q1_30_t w[2] = {wx, wy};
    TEST_ASSERT_EQUAL_INT(COMP2D_OK, comp2d_check(&M, LO, HI));
    comp2d_prepare(&M);
    comp2d_correct(&M, raw, w, out);
}

static void test_bilinear_hand_value(void)
{
    pos_nm_t out[2];
    /* (0.25 mm, 1.5 mm): fx = 0.25, fy = 0.75; along x 150 and -25, along
     * y 150 + 0.75 * (-175) = 18.75 nm -> 19 */
    correct(250000, 1500000, 0, 0, out);
    TEST_ASSERT_EQUAL_INT64(250000 + 19, out[0]);
    TEST_ASSERT_EQUAL_INT64(1500000, out[1]);
    /* on a node: exact */
    correct(1000000, 2000000, 0, 0, out);
    TEST_ASSERT_EQUAL_INT64(1000000 + 500, out[0]);
    /* (0.6, 0.4): 100 + 0.6 * 200 = 220, -200 + 0.6 * 700 = 220; 220 */
    correct(600000, 400000, 0, 0, out);
    TEST_ASSERT_EQUAL_INT64(600000 + 220, out[0]);
}

static void test_direction_terms(void)
{
    pos_nm_t out[2];
    unsigned i;
    for (i = 0; i < 4; i++) {
        M.g[1][COMP2D_HX][i] = 40;
        M.g[1][COMP2D_HY][i] = (int16_t)(-10 * (int)i); /* 0 -10 -20 -30 */
    }
    /* Y at (0.5, 1.0): hy = bilinear = -15; +x, +y: 40 - 15 */
    correct(500000, 1000000, FX_ONE_Q30, FX_ONE_Q30, out);
    TEST_ASSERT_EQUAL_INT64(1000000 + 25, out[1]);
    correct(500000, 1000000, -FX_ONE_Q30, FX_ONE_Q30, out);
    TEST_ASSERT_EQUAL_INT64(1000000 - 55, out[1]);
    correct(500000, 1000000, 0, -FX_ONE_Q30, out);
    TEST_ASSERT_EQUAL_INT64(1000000 + 15, out[1]);
    correct(500000, 1000000, FX_ONE_Q30 / 2, 0, out); /* halfway through a ramp */
    TEST_ASSERT_EQUAL_INT64(1000000 + 20, out[1]);
}

static void test_edges_held_and_shift(void)
{
    pos_nm_t out[2];
    correct(-5000000, 9000000, 0, 0, out); /* beyond (0, 1): -200 */
    TEST_ASSERT_EQUAL_INT64(-5000000 - 200, out[0]);
    correct(7000000, -1, 0, 0, out); /* beyond (1, 0): 300 */
    TEST_ASSERT_EQUAL_INT64(7000000 + 300, out[0]);
    M.shift = 2; /* units of 4 nm */
    correct(250000, 1500000, 0, 0, out);
    TEST_ASSERT_EQUAL_INT64(250000 + 75, out[0]);
    M.g[0][COMP2D_MID][3] = 32767;
    M.shift = COMP2D_SHIFT_MAX;
    correct(1000000, 2000000, 0, 0, out);
    TEST_ASSERT_EQUAL_INT64(1000000 + 32767 * 256, out[0]);
}

static void test_null_map_is_identity(void)
{
    const pos_nm_t raw[2] = {123, -456};
    const q1_30_t w[2] = {0, 0};
    pos_nm_t out[2];
    comp2d_correct(NULL, raw, w, out);
    TEST_ASSERT_EQUAL_INT64(123, out[0]);
    TEST_ASSERT_EQUAL_INT64(-456, out[1]);
}

static void test_refusals(void)
{
    static const pos_nm_t small_hi[2] = {999999, 100000000};
    M.version = 2;
    TEST_ASSERT_EQUAL_INT(COMP2D_E_VERSION, comp2d_check(&M, LO, HI));
    M.version = COMP2D_VERSION;
    M.nx = 13;
    M.ny = 12; /* 156 > 144 nodes */
    TEST_ASSERT_EQUAL_INT(COMP2D_E_MEMORY, comp2d_check(&M, LO, HI));
    M.nx = 12;
    TEST_ASSERT_EQUAL_INT(COMP2D_OK, comp2d_check(&M, LO, HI)); /* 144 nodes: fits */
    M.nx = 1;
    M.ny = 2;
    TEST_ASSERT_EQUAL_INT(COMP2D_E_MEMORY, comp2d_check(&M, LO, HI));
    M.nx = 2;
    M.dx = COMP2D_STEP_MIN_NM;
    TEST_ASSERT_EQUAL_INT(COMP2D_E_STEP, comp2d_check(&M, LO, HI));
    M.dx = 1000000;
    M.shift = COMP2D_SHIFT_MAX + 1;
    TEST_ASSERT_EQUAL_INT(COMP2D_E_STEP, comp2d_check(&M, LO, HI));
    M.shift = 0;
    /* the grid ends at x = 1 mm, the field at 0.999999 mm */
    TEST_ASSERT_EQUAL_INT(COMP2D_E_FIELD, comp2d_check(&M, LO, small_hi));
    M.x0 = -100000001;
    TEST_ASSERT_EQUAL_INT(COMP2D_E_FIELD, comp2d_check(&M, LO, HI));
    M.x0 = 0;
    TEST_ASSERT_EQUAL_INT(COMP2D_OK, comp2d_check(&M, LO, HI));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_bilinear_hand_value);
    RUN_TEST(test_direction_terms);
    RUN_TEST(test_edges_held_and_shift);
    RUN_TEST(test_null_map_is_identity);
    RUN_TEST(test_refusals);
    return UNITY_END();
}
