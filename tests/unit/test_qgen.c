/* Quadrature generator: edge times, levels, index window, injections. */
#include "qgen.h"
#include "unity.h"

#define MAXEV 4096

typedef struct {
    uint32_t lines[MAXEV];
    uint32_t t[MAXEV];
    unsigned n;
} rec_t;

static void rec_emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    rec_t *r = ctx;
    TEST_ASSERT_TRUE(r->n < MAXEV);
    r->lines[r->n] = lines;
    r->t[r->n] = t_ns;
    r->n++;
}

static rec_t rec;

void setUp(void)
{
    rec.n = 0;
}

void tearDown(void)
{
}

static void test_constant_velocity_edge_times(void)
{
    qgen_t g;
    unsigned i;

    /* 10 counts in 10 us from the middle of count 0: edges at 0.5, 1.5 ... us */
    qgen_init(&g, QGEN_ONE / 2, 1000, rec_emit, &rec);
    TEST_ASSERT_EQUAL_UINT32(0, qgen_lines(&g));
    TEST_ASSERT_EQUAL_UINT64(10, qgen_move_to(&g, QGEN_COUNTS(10) + QGEN_ONE / 2, 11000));
    for (i = 0; i < 10; i++) {
        static const uint32_t ab[4] = {0, 1, 3, 2};
        TEST_ASSERT_EQUAL_UINT32(1500 + 1000 * i, rec.t[i]);
        TEST_ASSERT_EQUAL_UINT32(ab[(i + 1) & 3], rec.lines[i]);
    }
    TEST_ASSERT_EQUAL_INT64(10, g.count);
    /* back to -3 in 13 us: edges at 0.5 us, 1.5 us ... after the start */
    rec.n = 0;
    TEST_ASSERT_EQUAL_UINT64(13, qgen_move_to(&g, QGEN_COUNTS(-3) + QGEN_ONE / 2, 24000));
    TEST_ASSERT_EQUAL_UINT32(11500, rec.t[0]);
    TEST_ASSERT_EQUAL_UINT32(23500, rec.t[12]);
    TEST_ASSERT_EQUAL_INT64(-3, g.count);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_A, rec.lines[12]); /* -3 mod 4 = 1 */
    /* no motion, or time standing still: no edges / all at once */
    rec.n = 0;
    TEST_ASSERT_EQUAL_UINT64(0, qgen_move_to(&g, g.x, 30000));
    TEST_ASSERT_EQUAL_UINT64(5, qgen_move_to(&g, g.x + QGEN_COUNTS(5), 30000));
    TEST_ASSERT_EQUAL_UINT32(30000, rec.t[4]);
}

static void test_timestamps_wrap_and_stay_ordered(void)
{
    qgen_t g;
    unsigned i;

    qgen_init(&g, 0, 0xFFFFF000ull, rec_emit, &rec);
    qgen_move_to(&g, QGEN_COUNTS(2000) + 12345, 0xFFFFF000ull + 100000ull);
    TEST_ASSERT_EQUAL_UINT32(2000, rec.n);
    for (i = 1; i < rec.n; i++) {
        TEST_ASSERT_TRUE((int32_t)(rec.t[i] - rec.t[i - 1]) >= 49);
        TEST_ASSERT_TRUE((int32_t)(rec.t[i] - rec.t[i - 1]) <= 50);
    }
}

static void test_index_window(void)
{
    qgen_t g;
    unsigned i, z = 0;

    qgen_init(&g, QGEN_COUNTS(-10), 0, rec_emit, &rec);
    qgen_set_index(&g, 0, 100, 1, 2);
    TEST_ASSERT_EQUAL_UINT32(0, qgen_lines_at(&g, -2) & QDEC_LINE_Z);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_Z, qgen_lines_at(&g, -1) & QDEC_LINE_Z);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_Z, qgen_lines_at(&g, 2) & QDEC_LINE_Z);
    TEST_ASSERT_EQUAL_UINT32(0, qgen_lines_at(&g, 3) & QDEC_LINE_Z);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_Z, qgen_lines_at(&g, 299) & QDEC_LINE_Z);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_Z, qgen_lines_at(&g, -98) & QDEC_LINE_Z);
    qgen_move_to(&g, QGEN_COUNTS(290), 1000000);
    for (i = 0; i < rec.n; i++) {
        z += (rec.lines[i] & QDEC_LINE_Z) ? 1u : 0u;
    }
    TEST_ASSERT_EQUAL_UINT32(12, z); /* 4 counts at each of 0, 100, 200 */
}

static void test_injections(void)
{
    qgen_t g;

    qgen_init(&g, QGEN_COUNTS(2), 0, rec_emit, &rec); /* lines A|B */
    qgen_illegal(&g, 100, 7);
    TEST_ASSERT_EQUAL_UINT32(2, rec.n);
    TEST_ASSERT_EQUAL_UINT32(0, rec.lines[0]);
    TEST_ASSERT_EQUAL_UINT32(3, rec.lines[1]);
    TEST_ASSERT_EQUAL_UINT32(107, rec.t[1]);
    TEST_ASSERT_EQUAL_UINT64(2, g.illegal);
    qgen_glitch(&g, QDEC_LINE_B, 200, 3);
    TEST_ASSERT_EQUAL_UINT32(QDEC_LINE_A, rec.lines[2]);
    TEST_ASSERT_EQUAL_UINT32(3, rec.lines[3]);
    TEST_ASSERT_EQUAL_UINT32(203, rec.t[3]);
    TEST_ASSERT_EQUAL_UINT64(1, g.glitches);
    TEST_ASSERT_EQUAL_UINT64(0, g.edges);
    TEST_ASSERT_EQUAL_UINT64(203, g.t);
}

static void test_edge_offsets(void)
{
    qgen_t g;
    const qgen_pos_t off[4] = {0, QGEN_ONE / 8, -QGEN_ONE / 8, QGEN_ONE / 4};
    const qgen_pos_t bad[4] = {0, QGEN_ONE / 2, 0, 0};

    qgen_init(&g, QGEN_ONE / 2, 0, rec_emit, &rec);
    TEST_ASSERT_FALSE(qgen_set_edge_offsets(&g, bad));
    TEST_ASSERT_TRUE(qgen_set_edge_offsets(&g, off));
    /* 1 count per us: boundaries into counts 1..4 at 1.125, 1.875, 3.25, 4 */
    qgen_move_to(&g, QGEN_COUNTS(4) + QGEN_ONE / 2, 4000);
    TEST_ASSERT_EQUAL_UINT32(4, rec.n);
    TEST_ASSERT_EQUAL_UINT32(625, rec.t[0]);
    TEST_ASSERT_EQUAL_UINT32(1375, rec.t[1]);
    TEST_ASSERT_EQUAL_UINT32(2750, rec.t[2]);
    TEST_ASSERT_EQUAL_UINT32(3500, rec.t[3]);
    /* crossing back happens at the same places */
    rec.n = 0;
    qgen_move_to(&g, QGEN_COUNTS(3) + QGEN_ONE * 3 / 10, 5000);
    TEST_ASSERT_EQUAL_UINT32(1, rec.n);
    TEST_ASSERT_EQUAL_INT64(3, g.count);
    qgen_move_to(&g, QGEN_COUNTS(3) + QGEN_ONE / 5, 6000);
    TEST_ASSERT_EQUAL_UINT32(2, rec.n);
    TEST_ASSERT_EQUAL_INT64(2, g.count);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_constant_velocity_edge_times);
    RUN_TEST(test_timestamps_wrap_and_stay_ordered);
    RUN_TEST(test_index_window);
    RUN_TEST(test_injections);
    RUN_TEST(test_edge_offsets);
    return UNITY_END();
}
