/* Quadrature generator: edge times, levels, index window, injections. */
#include "qgen.h"
#include "unity.h"

#include <string.h>

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

/* The fast path (ideal edges, no index: the loop that writes the state back
 * at the end) against the crossing-time formula of the spec in 128-bit
 * arithmetic, event by event, and the state after each move: random moves
 * of 0..300 counts either way, steps of 0..200 us, around 64-bit wrap of
 * the 32-bit time and at both ends of the fast path's position range. */
static uint64_t rnd_state = 0x1234567u;
static uint64_t rnd64(void)
{
    rnd_state = rnd_state * 6364136223846793005ull + 1442695040888963407ull;
    return rnd_state >> 11;
}

static int64_t count_of(qgen_pos_t x) /* floor(x / QGEN_ONE) */
{
    return x >= 0 ? x / QGEN_ONE : -((-x + QGEN_ONE - 1) / QGEN_ONE);
}

static void fast_path_case(qgen_pos_t x0, uint64_t t0)
{
    __extension__ typedef __int128 i128;
    qgen_t g;
    unsigned m;
    uint64_t edges = 0;

    qgen_init(&g, x0, t0, rec_emit, &rec);
    for (m = 0; m < 400; m++) {
        qgen_pos_t xa = g.x, dx = (qgen_pos_t)(rnd64() % (300u * (uint64_t)QGEN_ONE));
        uint64_t ta = g.t, dt = (m % 7 == 3) ? 0u : rnd64() % 200000u;
        qgen_pos_t x1 = (rnd64() & 1u) ? xa + dx : xa - dx;
        int64_t c0, c1;

        if (m % 5 == 2 || m % 5 == 3) {
            /* onto whole counts, then whole counts in 1 us: crossings at
             * exact ns (remainder == divisor) */
            int64_t j = (int64_t)(rnd64() % 40u) + 2;
            x1 = m % 5 == 2 ? QGEN_COUNTS(count_of(xa) + j) : xa - QGEN_COUNTS(j);
            dt = 1000u;
        }
        c0 = count_of(xa);
        c1 = count_of(x1);
        uint64_t n = (uint64_t)(c1 > c0 ? c1 - c0 : c0 - c1), k;

        if (m % 11 == 5) {
            x1 = xa; /* no motion */
            c1 = c0;
            n = 0;
        }
        rec.n = 0;
        TEST_ASSERT_EQUAL_UINT64(n, qgen_move_to(&g, x1, ta + dt));
        TEST_ASSERT_EQUAL_UINT32(n, rec.n);
        for (k = 0; k < n; k++) {
            int64_t c = x1 > xa ? c0 + 1 + (int64_t)k : c0 - (int64_t)k;
            i128 b = (i128)c * QGEN_ONE;
            i128 d = x1 > xa ? b - xa : xa - b;
            uint64_t t = ta + (uint64_t)(d * (i128)dt / (i128)(x1 > xa ? x1 - xa : xa - x1));
            int64_t now = x1 > xa ? c : c - 1;
            TEST_ASSERT_EQUAL_UINT32((uint32_t)t, rec.t[k]);
            TEST_ASSERT_EQUAL_UINT32(qgen_lines_at(&g, now), rec.lines[k]);
            if (k + 1 == n) {
                TEST_ASSERT_EQUAL_UINT64(t, g.last_edge_t);
            }
        }
        edges += n;
        TEST_ASSERT_EQUAL_INT64(c1, g.count);
        TEST_ASSERT_EQUAL_UINT32(qgen_lines_at(&g, c1), qgen_lines(&g));
        TEST_ASSERT_EQUAL_UINT64(edges, g.edges);
        TEST_ASSERT_EQUAL_UINT64(ta + dt, g.t);
        TEST_ASSERT_EQUAL_INT64(x1, g.x);
    }
}

static void test_fast_path_matches_formula(void)
{
    const qgen_pos_t lim = (qgen_pos_t)1 << 61;
    fast_path_case(QGEN_ONE / 3, 1000);
    fast_path_case(-QGEN_COUNTS(123457) - 77, 0xFFFF0000ull);
    fast_path_case(lim - QGEN_COUNTS(200000), 5);
    fast_path_case(-lim + QGEN_COUNTS(200000) + 1, 5);
}

/* Runs (qgen_set_run) against the events of the same moves: a run stands
 * for exactly the events the reference generator emits (steps = +-their
 * number, t_last = the last one's time, no event emitted), the moves with
 * an index event and those the callback refuses come as the same events,
 * and the state after every move is the reference's. */
typedef struct {
    int32_t steps;
    uint32_t t_last;
    unsigned calls, taken;
} run_rec_t;

static rec_t rec_b;
static run_rec_t runs;

static void rec_b_emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    (void)ctx;
    TEST_ASSERT_TRUE(rec_b.n < MAXEV);
    rec_b.lines[rec_b.n] = lines;
    rec_b.t[rec_b.n] = t_ns;
    rec_b.n++;
}

static bool run_take(void *ctx, int32_t steps, uint32_t t_last_ns)
{
    (void)ctx;
    runs.calls++;
    runs.steps = steps;
    runs.t_last = t_last_ns;
    if (runs.calls % 7u == 0u) {
        return false; /* refused: the events follow one by one */
    }
    runs.taken++;
    return true;
}

static void runs_case(qgen_pos_t x0, uint64_t t0, bool index)
{
    qgen_t a, b;
    unsigned m, z_moves = 0, taken_before;
    uint64_t run_edges = 0;

    qgen_init(&a, x0, t0, rec_emit, &rec);
    qgen_init(&b, x0, t0, rec_b_emit, NULL);
    qgen_set_run(&b, run_take);
    if (index) {
        qgen_set_index(&a, count_of(x0) + 150, 397, 1, 2);
        qgen_set_index(&b, count_of(x0) + 150, 397, 1, 2);
    }
    memset(&runs, 0, sizeof runs);
    for (m = 0; m < 3000; m++) {
        qgen_pos_t dx = (qgen_pos_t)(rnd64() % (120u * (uint64_t)QGEN_ONE));
        uint64_t dt = (m % 13 == 4) ? 0u : rnd64() % 200000u;
        qgen_pos_t xa = a.x, x1 = (rnd64() % 3u == 0u) ? xa - dx : xa + dx;
        uint64_t n;
        unsigned k, z = 0;

        if (m % 17 == 6) {
            x1 = QGEN_COUNTS(count_of(xa) + 5); /* onto a whole count */
            dt = 1000u;
        }
        if (m % 29 == 3) { /* distance * dt past 2^64: the 128-bit quotient */
            dt = ((uint64_t)1 << 37) + rnd64() % 1000u;
        }
        if (index && (m % 23 == 9 || m % 23 == 10 || m % 23 == 11 || m % 23 == 12)) {
            /* onto the edges of the index windows (counts ip - 1 .. ip + 2
             * around ip = index + j * 397) and the counts just outside */
            int64_t ip = count_of(x0) + 150, c = count_of(xa) - ip;
            int64_t j = (c >= 0 ? c : c - 396) / 397;
            int64_t lo_top = ip + j * 397 + 2, hi_first = ip + (j + 1) * 397 - 1;
            int64_t to = (m % 23 == 9)    ? lo_top
                         : (m % 23 == 10) ? hi_first
                         : (m % 23 == 11) ? lo_top + 1
                                          : hi_first - 1;
            x1 = QGEN_COUNTS(to) + QGEN_ONE / 2;
        }
        rec.n = 0;
        rec_b.n = 0;
        taken_before = runs.taken;
        n = qgen_move_to(&a, x1, a.t + dt);
        TEST_ASSERT_EQUAL_UINT64(n, qgen_move_to(&b, x1, b.t + dt));
        for (k = 0; k < rec.n; k++) {
            /* the levels of the count entered, from the spec's formula */
            int64_t c = count_of(xa) + (x1 > xa ? (int64_t)k + 1 : -(int64_t)k - 1);
            TEST_ASSERT_EQUAL_UINT32(qgen_lines_at(&a, c), rec.lines[k]);
            z |= rec.lines[k] & QDEC_LINE_Z;
        }
        if (runs.taken != taken_before) {
            TEST_ASSERT_TRUE(n > 0u);
            TEST_ASSERT_EQUAL_UINT32(0, z);
            TEST_ASSERT_EQUAL_UINT32(0, rec_b.n);
            TEST_ASSERT_EQUAL_INT32(x1 > xa ? (int32_t)n : -(int32_t)n, runs.steps);
            TEST_ASSERT_EQUAL_UINT32(rec.t[rec.n - 1u], runs.t_last);
        } else {
            z_moves += z ? 1u : 0u;
            TEST_ASSERT_EQUAL_UINT32(rec.n, rec_b.n);
            TEST_ASSERT_EQUAL_INT(0, memcmp(rec.t, rec_b.t, sizeof(uint32_t) * rec.n));
            TEST_ASSERT_EQUAL_INT(0, memcmp(rec.lines, rec_b.lines, sizeof(uint32_t) * rec.n));
        }
        TEST_ASSERT_EQUAL_INT64(a.count, b.count);
        TEST_ASSERT_EQUAL_UINT32(a.lines, b.lines);
        TEST_ASSERT_EQUAL_UINT64(a.edges, b.edges);
        TEST_ASSERT_EQUAL_UINT64(a.last_edge_t, b.last_edge_t);
        TEST_ASSERT_EQUAL_UINT64(a.t, b.t);
        TEST_ASSERT_EQUAL_INT64(a.x, b.x);
        run_edges += runs.taken != taken_before ? n : 0u;
        TEST_ASSERT_EQUAL_UINT64(run_edges, b.run_edges);
    }
    TEST_ASSERT_TRUE(runs.taken > 1000u);
    TEST_ASSERT_TRUE(runs.calls > runs.taken); /* some refused */
    if (index) {
        TEST_ASSERT_TRUE(z_moves > 50u); /* moves through the index window */
    }
}

static void test_runs_match_events(void)
{
    runs_case(QGEN_ONE / 3, 1000, false);
    runs_case(QGEN_ONE / 3, 1000, true);
    runs_case(-QGEN_COUNTS(123457) - 77, 0xFFFF0000ull, true);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_constant_velocity_edge_times);
    RUN_TEST(test_timestamps_wrap_and_stay_ordered);
    RUN_TEST(test_index_window);
    RUN_TEST(test_injections);
    RUN_TEST(test_edge_offsets);
    RUN_TEST(test_fast_path_matches_formula);
    RUN_TEST(test_runs_match_events);
    return UNITY_END();
}
