/*
 * Quadrature decoder: loop-back through the generator (x4/x2/x1, forward,
 * reverse, dither, up to the rated speed), illegal transitions and the fault
 * window, counter extension, index latch, velocity error bounds, glitch
 * filter, scaling and configuration checks.
 */
#include "qdec.h"
#include "qgen.h"
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TS_NS 100000u /* 10 kHz control tick */

void setUp(void)
{
}

void tearDown(void)
{
}

/* ---- harness ---------------------------------------------------------------------- */

typedef struct {
    qdec_t *dec[4];
    unsigned n;
} fan_t;

static void fan_emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    fan_t *f = ctx;
    unsigned i;
    for (i = 0; i < f->n; i++) {
        qdec_edge(f->dec[i], lines, t_ns);
    }
}

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;

static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 16);
}

static int64_t floor_div(int64_t a, int64_t b)
{
    int64_t q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

static qdec_config_t edge_cfg(qdec_mode_t mode)
{
    qdec_config_t c;
    qdec_config_default(&c);
    c.mode = mode;
    return c;
}

/* ---- loop-back ------------------------------------------------------------------------ */

typedef struct {
    qgen_t g;
    qdec_t d4, d2, d1;
    fan_t fan;
    uint64_t t;
    int64_t c0;
    uint64_t samples;
} loop_t;

static void loop_init(loop_t *l, qgen_pos_t x0)
{
    qdec_config_t c4 = edge_cfg(QDEC_X4), c2 = edge_cfg(QDEC_X2), c1 = edge_cfg(QDEC_X1);
    l->t = 1000; /* any start; the 32-bit timestamps wrap every 4.3 s */
    l->fan.dec[0] = &l->d4;
    l->fan.dec[1] = &l->d2;
    l->fan.dec[2] = &l->d1;
    l->fan.n = 3;
    qgen_init(&l->g, x0, l->t, fan_emit, &l->fan);
    TEST_ASSERT_TRUE(qdec_init(&l->d4, &c4, qgen_lines(&l->g), (uint32_t)l->t));
    TEST_ASSERT_TRUE(qdec_init(&l->d2, &c2, qgen_lines(&l->g), (uint32_t)l->t));
    TEST_ASSERT_TRUE(qdec_init(&l->d1, &c1, qgen_lines(&l->g), (uint32_t)l->t));
    l->c0 = l->g.count;
    l->samples = 0;
}

static void loop_check(loop_t *l)
{
    int64_t c = l->g.count;
    qdec_sample(&l->d4, (uint32_t)l->t);
    qdec_sample(&l->d2, (uint32_t)l->t);
    qdec_sample(&l->d1, (uint32_t)l->t);
    l->samples++;
    TEST_ASSERT_EQUAL_INT64(c - l->c0, l->d4.out.pos);
    TEST_ASSERT_EQUAL_INT64(floor_div(c + 1, 2) - floor_div(l->c0 + 1, 2), l->d2.out.pos);
    TEST_ASSERT_EQUAL_INT64(floor_div(c + 3, 4) - floor_div(l->c0 + 3, 4), l->d1.out.pos);
    TEST_ASSERT_EQUAL_UINT32(l->g.illegal, l->d4.out.illegal);
    TEST_ASSERT_EQUAL_UINT32(0, l->d4.out.faults);
}

/* One tick of constant velocity v (counts per tick, q24) then a sample. */
static void loop_tick(loop_t *l, qgen_pos_t step)
{
    l->t += TS_NS;
    qgen_move_to(&l->g, l->g.x + step, l->t);
    loop_check(l);
}

static void test_loopback_million_edges(void)
{
    static loop_t l;
    /* counts per tick: slow to the rated speed (10^7 counts/s = 1000/tick) */
    static const int32_t speeds[] = {1, 7, 33, 150, 499, 1000};
    unsigned i, k, r;

    loop_init(&l, QGEN_COUNTS(-123456789) + QGEN_ONE / 2);
    while (l.g.edges < 1200000u) {
        /* forward and reverse at each speed, fractional speeds too */
        for (i = 0; i < sizeof(speeds) / sizeof(speeds[0]); i++) {
            qgen_pos_t step = QGEN_COUNTS(speeds[i]) + (qgen_pos_t)(rnd() % QGEN_ONE);
            for (k = 0; k < 40; k++) {
                loop_tick(&l, step);
            }
            for (k = 0; k < 40; k++) {
                loop_tick(&l, -step);
            }
        }
        /* at exactly the rated speed, both directions */
        for (k = 0; k < 50; k++) {
            loop_tick(&l, QGEN_COUNTS(QDEC_RATED_CPS / 10000));
        }
        for (k = 0; k < 50; k++) {
            loop_tick(&l, -QGEN_COUNTS(QDEC_RATED_CPS / 10000));
        }
        /* dither across one edge: 10 crossings per tick, 10 us apart */
        {
            qgen_pos_t b = QGEN_COUNTS(l.g.count + 1);
            qgen_move_to(&l.g, b - QGEN_ONE / 4, l.t + TS_NS / 2);
            l.t += TS_NS;
            qgen_move_to(&l.g, b - QGEN_ONE / 4, l.t);
            loop_check(&l);
            for (k = 0; k < 200; k++) {
                for (r = 0; r < 10; r++) {
                    qgen_pos_t amp = (qgen_pos_t)(rnd() % (QGEN_ONE / 2)) + 1;
                    qgen_move_to(&l.g, (r & 1) ? b - amp : b + amp, l.t + (r + 1) * 10000u);
                }
                l.t += TS_NS;
                loop_check(&l);
            }
        }
        /* random accelerating moves */
        for (k = 0; k < 200; k++) {
            int32_t v = (int32_t)(rnd() % 2001u) - 1000;
            loop_tick(&l, QGEN_COUNTS(v) + (qgen_pos_t)(rnd() % QGEN_ONE));
        }
    }
    TEST_ASSERT_TRUE(l.g.edges >= 1000000u);
    TEST_ASSERT_EQUAL_UINT32(0, l.d4.out.illegal);
    TEST_ASSERT_EQUAL_UINT32(0, l.d2.out.illegal);
    TEST_ASSERT_EQUAL_UINT32(0, l.d1.out.illegal);
}

static void test_loopback_injected_illegal(void)
{
    static loop_t l;
    unsigned k;

    loop_init(&l, QGEN_ONE / 3);
    for (k = 0; k < 20000u; k++) {
        int32_t v = (int32_t)((k / 500u) % 7u) - 3; /* -3..3 counts per tick */
        loop_tick(&l, QGEN_COUNTS(v) + QGEN_ONE / 7);
        if (rnd() % 4u == 0u) {
            /* right after the tick's last edge, as a burst of noise would */
            qgen_illegal(&l.g, l.t, 1u + rnd() % 50u);
        }
    }
    l.t += TS_NS;
    loop_check(&l);
    TEST_ASSERT_TRUE(l.g.illegal > 5000u);
    TEST_ASSERT_EQUAL_UINT32(l.g.illegal, l.d4.out.illegal);
    TEST_ASSERT_EQUAL_UINT32(l.g.illegal, l.d2.out.illegal);
    TEST_ASSERT_EQUAL_UINT32(l.g.illegal, l.d1.out.illegal);
}

static void test_illegal_never_counts_a_step(void)
{
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    static const uint32_t seq[4] = {0, 1, 3, 2};
    unsigned i;

    for (i = 0; i < 4; i++) {
        TEST_ASSERT_TRUE(qdec_init(&d, &c, seq[i], 0));
        qdec_edge(&d, seq[(i + 2) & 3], 10); /* both channels change */
        qdec_sample(&d, 100);
        TEST_ASSERT_EQUAL_INT64(0, d.out.pos);
        TEST_ASSERT_EQUAL_UINT32(1, d.out.illegal);
        /* decoding resumes from the new state */
        qdec_edge(&d, seq[(i + 3) & 3], 20);
        qdec_sample(&d, 200);
        TEST_ASSERT_EQUAL_INT64(1, d.out.pos);
        qdec_edge(&d, seq[(i + 3) & 3] | QDEC_LINE_Z, 30); /* Z only: nothing */
        qdec_sample(&d, 300);
        TEST_ASSERT_EQUAL_INT64(1, d.out.pos);
        TEST_ASSERT_EQUAL_UINT32(1, d.out.illegal);
    }
}

static void test_illegal_fault_window(void)
{
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint32_t t = 0;
    unsigned k;

    c.illegal_limit = 5;
    c.illegal_window_ns = 1000000; /* 5 within 1 ms */
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, t));
    /* one illegal every 300 us: 4 per window at most -> no fault */
    for (k = 0; k < 400; k++) {
        t += TS_NS;
        if (k % 3 == 0) {
            qdec_edge(&d, (k & 1) ? 0u : 3u, t - 10);
        }
        qdec_sample(&d, t);
    }
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    TEST_ASSERT_EQUAL_UINT32(134, d.out.illegal);
    /* after a pause, one every 200 us: the 5th within 1 ms raises it */
    t += 20 * TS_NS;
    qdec_sample(&d, t);
    for (k = 0; k < 4; k++) {
        t += 2 * TS_NS;
        qdec_edge(&d, (d.e.ab == 0) ? 3u : 0u, t - 10);
        qdec_sample(&d, t);
        TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    }
    t += 2 * TS_NS;
    qdec_edge(&d, (d.e.ab == 0) ? 3u : 0u, t - 10);
    qdec_sample(&d, t);
    TEST_ASSERT_EQUAL_UINT32(QDEC_FAULT_ILLEGAL, d.out.faults);
    /* latched until cleared; clearing forgets the history */
    t += 100 * TS_NS;
    qdec_sample(&d, t);
    TEST_ASSERT_EQUAL_UINT32(QDEC_FAULT_ILLEGAL, d.out.faults);
    qdec_clear_faults(&d);
    qdec_edge(&d, (d.e.ab == 0) ? 3u : 0u, t + 5);
    qdec_sample(&d, t + TS_NS);
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    /* a burst of 5 in one tick */
    for (k = 0; k < 5; k++) {
        qdec_edge(&d, (d.e.ab == 0) ? 3u : 0u, t + TS_NS + 10 + k);
    }
    qdec_sample(&d, t + 2 * TS_NS);
    TEST_ASSERT_EQUAL_UINT32(QDEC_FAULT_ILLEGAL, d.out.faults);
}

/* ---- counter extension ---------------------------------------------------------------- */

static void run_counter(uint8_t bits, int64_t step, unsigned samples, bool expect_fault,
                        uint32_t max_delta)
{
    qdec_t d;
    qdec_config_t c;
    uint64_t mask = (bits == 32) ? 0xFFFFFFFFull : ((1ull << bits) - 1u);
    uint64_t raw0 = 0x9E3779B9u & mask;
    int64_t truth = 0;
    uint32_t t = 0xFFFF0000u; /* the time stamps wrap during the run too */
    unsigned k;

    qdec_config_default(&c);
    c.input = QDEC_INPUT_COUNTER;
    c.counter_bits = bits;
    c.max_delta = max_delta;
    TEST_ASSERT_TRUE(qdec_init(&d, &c, (uint32_t)raw0, t));
    for (k = 0; k < samples; k++) {
        truth += step;
        t += TS_NS;
        qdec_sample_counter(&d, (uint32_t)((raw0 + (uint64_t)truth) & mask), t);
        TEST_ASSERT_EQUAL_INT64(truth, d.out.pos);
    }
    TEST_ASSERT_EQUAL_UINT32(expect_fault ? QDEC_FAULT_OVERSPEED : 0u, d.out.faults);
    TEST_ASSERT_EQUAL_INT8(step > 0 ? 1 : -1, d.out.dir);
}

/* The overspeed test's one-compare form against |delta| > max_delta over
 * its whole range: every limit the decoder can hold (0 .. 2^31 - 1), the
 * deltas around +-limit and the ends of int32, and random pairs. */
static void test_overspeed_compare(void)
{
    static const uint32_t lims[] = {
        0u, 1u, 63u, 16383u, 32767u, (1u << 30) - 1u, 1u << 30, 0x7FFFFFFEu, 0x7FFFFFFFu};
    unsigned i, j, k;

    for (i = 0; i < sizeof lims / sizeof lims[0]; i++) {
        uint32_t m = lims[i];
        int64_t ds[] = {INT32_MIN,
                        INT32_MIN + 1,
                        -(int64_t)m - 1,
                        -(int64_t)m,
                        -(int64_t)m + 1,
                        -1,
                        0,
                        1,
                        (int64_t)m - 1,
                        m,
                        (int64_t)m + 1,
                        INT32_MAX - 1,
                        INT32_MAX};

        for (j = 0; j < sizeof ds / sizeof ds[0]; j++) {
            int64_t d = ds[j];
            if (d < INT32_MIN || d > INT32_MAX) {
                continue;
            }
            TEST_ASSERT_EQUAL_INT((d < 0 ? -d : d) > (int64_t)m, qdec_overspeed((int32_t)d, m));
        }
    }
    for (k = 0; k < 200000u; k++) {
        uint32_t m = rnd() & 0x7FFFFFFFu;
        int32_t d = (int32_t)rnd();

        if (k & 1u) {
            m >>= rnd() % 31u;
        }
        TEST_ASSERT_EQUAL_INT((d < 0 ? -(int64_t)d : (int64_t)d) > (int64_t)m,
                              qdec_overspeed(d, m));
    }
}

static void test_counter_extension_max_delta(void)
{
    /* 16 bit: +-32767 per sample, 2 samples per wrap, 5000 wraps each way */
    run_counter(16, QDEC_MAX_DELTA(16), 10000, false, QDEC_MAX_DELTA(16));
    run_counter(16, -(int64_t)QDEC_MAX_DELTA(16), 10000, false, QDEC_MAX_DELTA(16));
    /* with the default limit (16383) the same moves count exactly and fault */
    run_counter(16, QDEC_MAX_DELTA(16), 100, true, 0);
    run_counter(16, 16383, 20000, false, 0);
    run_counter(16, -16383, 20000, false, 0);
    /* 32 bit: +-(2^31 - 1), 5000 wraps each way */
    run_counter(32, QDEC_MAX_DELTA(32), 10000, false, QDEC_MAX_DELTA(32));
    run_counter(32, -(int64_t)QDEC_MAX_DELTA(32), 10000, false, QDEC_MAX_DELTA(32));
    run_counter(12, -2047, 9000, false, QDEC_MAX_DELTA(12));
}

static void test_counter_random_and_overspeed(void)
{
    qdec_t d;
    qdec_config_t c;
    int64_t truth = 0;
    uint16_t raw = 0;
    unsigned k;

    qdec_config_default(&c);
    c.input = QDEC_INPUT_COUNTER;
    c.counter_bits = 16;
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
    for (k = 0; k < 50000; k++) {
        int32_t step = (int32_t)(rnd() % 32767u) - 16383;
        truth += step;
        raw = (uint16_t)(raw + (uint16_t)step);
        qdec_sample_counter(&d, raw, (k + 1) * TS_NS);
        TEST_ASSERT_EQUAL_INT64(truth, d.out.pos);
    }
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    /* a true change of 40000 (beyond 32767) looks like -25536: it cannot be
     * counted, but it is never hidden */
    raw = (uint16_t)(raw + 40000u);
    qdec_sample_counter(&d, raw, 50001u * TS_NS);
    TEST_ASSERT_EQUAL_UINT32(QDEC_FAULT_OVERSPEED, d.out.faults);
}

/* ---- index ------------------------------------------------------------------------------- */

static void test_index_qualified_same_both_directions(void)
{
    qgen_t g;
    qdec_t d;
    fan_t fan = {{&d}, 1};
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint64_t t = 5000;
    uint32_t ev;
    unsigned rev;
    const int64_t I = 1000, P = 4000; /* index every 4000 counts */

    qgen_init(&g, QGEN_COUNTS(0) + QGEN_ONE / 2, t, fan_emit, &fan);
    qgen_set_index(&g, I, P, 1, 2); /* Z 4 counts wide, ungated it straddles */
    c.index_qual = (uint8_t)(qgen_lines_at(&g, I) & 3u);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, qgen_lines(&g), (uint32_t)t));
    ev = d.out.index_events;
    for (rev = 0; rev < 3; rev++) {
        t += 2000000;
        qgen_move_to(&g, QGEN_COUNTS(I + rev * P + 50), t);
        qdec_sample(&d, (uint32_t)t);
        TEST_ASSERT_EQUAL_UINT32(ev + 1, d.out.index_events);
        TEST_ASSERT_EQUAL_INT64(I + (int64_t)rev * P, d.out.index_pos);
        TEST_ASSERT_EQUAL_INT8(1, d.out.index_dir);
        ev = d.out.index_events;
        /* back over it: the same count, direction -1 */
        t += 100000;
        qgen_move_to(&g, QGEN_COUNTS(I + rev * P - 50), t);
        qdec_sample(&d, (uint32_t)t);
        TEST_ASSERT_EQUAL_UINT32(ev + 1, d.out.index_events);
        TEST_ASSERT_EQUAL_INT64(I + (int64_t)rev * P, d.out.index_pos);
        TEST_ASSERT_EQUAL_INT8(-1, d.out.index_dir);
        ev = d.out.index_events;
        t += 100000;
        qgen_move_to(&g, QGEN_COUNTS(I + rev * P + 60), t);
        qdec_sample(&d, (uint32_t)t);
        ev = d.out.index_events;
    }
    /* a long move latches the last index passed */
    t += 10000000;
    qgen_move_to(&g, QGEN_COUNTS(I + 10 * P + 3), t);
    qdec_sample(&d, (uint32_t)t);
    TEST_ASSERT_EQUAL_INT64(I + 10 * P, d.out.index_pos);
}

static void test_index_ungated_has_hysteresis(void)
{
    qgen_t g;
    qdec_t d;
    fan_t fan = {{&d}, 1};
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint64_t t = 0;

    qgen_init(&g, QGEN_COUNTS(-100), t, fan_emit, &fan);
    qgen_set_index(&g, 0, 0, 1, 2);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, qgen_lines(&g), (uint32_t)t));
    t += 1000000;
    qgen_move_to(&g, QGEN_COUNTS(100), t);
    qdec_sample(&d, (uint32_t)t);
    TEST_ASSERT_EQUAL_INT64(100 - 1, d.out.index_pos); /* count -1 relative to start -100 */
    t += 1000000;
    qgen_move_to(&g, QGEN_COUNTS(-100), t);
    qdec_sample(&d, (uint32_t)t);
    TEST_ASSERT_EQUAL_INT64(100 + 2, d.out.index_pos);
    TEST_ASSERT_EQUAL_UINT32(2, d.out.index_events);
}

static void test_index_capture_counter_mode(void)
{
    qdec_t d;
    qdec_config_t c;

    qdec_config_default(&c);
    c.input = QDEC_INPUT_COUNTER;
    c.counter_bits = 16;
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 65000, 0));
    qdec_sample_counter(&d, 65500, TS_NS);
    qdec_index_capture(&d, 200, TS_NS + 50000); /* after a wrap: +736 counts */
    qdec_sample_counter(&d, 900, 2 * TS_NS);
    TEST_ASSERT_EQUAL_UINT32(1, d.out.index_events);
    TEST_ASSERT_EQUAL_INT64(736, d.out.index_pos);
    TEST_ASSERT_EQUAL_INT64(1436, d.out.pos);
    TEST_ASSERT_EQUAL_INT8(1, d.out.index_dir);
    TEST_ASSERT_EQUAL_UINT32(TS_NS + 50000, d.out.index_t_ns);
}

/* ---- velocity ------------------------------------------------------------------------------ */

typedef struct {
    double worst_rel;
    double worst_abs;
} verr_t;

/* Constant velocity v (counts/s) from rest position 0.5; returns the worst
 * error after the start-up (two edges plus the window). Asserts the bound. */
static verr_t run_velocity(double v, bool counter, uint64_t window_ns, const qgen_pos_t *off)
{
    qgen_t g;
    qdec_t d;
    fan_t fan = {{&d}, counter ? 0u : 1u};
    qdec_config_t c = edge_cfg(QDEC_X4);
    double av = fabs(v), ts = TS_NS * 1e-9, wc = (double)window_ns * 1e-9;
    double dur = fmax(4.0 / av, 0.05), start = 1.5 / av + wc + 2 * ts;
    uint64_t t0 = 4294000000ull, t = t0; /* near a 32-bit wrap */
    qgen_pos_t x0 = QGEN_ONE / 2;
    verr_t r = {0, 0};
    uint64_t k, n = (uint64_t)(dur / ts);

    if (counter) {
        c.input = QDEC_INPUT_COUNTER;
        c.counter_bits = 16;
    }
    c.vel_window_ns = window_ns;
    c.vel_cycle = (off != NULL);
    qgen_init(&g, x0, t, fan_emit, &fan);
    if (off != NULL) {
        TEST_ASSERT_TRUE(qgen_set_edge_offsets(&g, off));
        start += 6.0 / av;
    }
    TEST_ASSERT_TRUE(qdec_init(&d, &c, counter ? (uint32_t)g.count : qgen_lines(&g), (uint32_t)t));
    for (k = 1; k <= n; k++) {
        double tt = (double)k * ts, est, err, bound;
        t = t0 + k * TS_NS;
        qgen_move_to(&g, x0 + (qgen_pos_t)llround(v * tt * (double)QGEN_ONE), t);
        if (counter) {
            qdec_sample_counter(&d, (uint32_t)(g.count & 0xFFFF), (uint32_t)t);
        } else {
            qdec_sample(&d, (uint32_t)t);
        }
        if (tt < start) {
            continue;
        }
        est = (double)qdec_velocity(&d) / 4294967296.0;
        err = fabs(est - v);
        if (counter) {
            /* counts exact at sample times: < min(1, |v| Ts) / W, W the window */
            double w = fmax(fmax(wc, 2 * ts) - ts, 1.0 / av - ts);
            bound = fmin(1.0, av * ts) / w + 1e-6;
        } else {
            /* edge times rounded to 1 ns: < |v| 2 ns / W, W >= one edge interval
             * and >= one sample less one edge interval */
            double cyc = (off != NULL) ? 4.0 : 1.0; /* counts per recorded edge */
            double w = fmax(cyc / av, ts - cyc / av);
            bound = av * 2e-9 / w + 1e-6;
        }
        if (err > bound) {
            printf("v %g counter %d t %g est %.9g err %g bound %g\n", v, counter, tt, est, err,
                   bound);
        }
        TEST_ASSERT_TRUE(err <= bound);
        TEST_ASSERT_FALSE(d.out.stopped);
        if (err / av > r.worst_rel) {
            r.worst_rel = err / av;
        }
        if (err > r.worst_abs) {
            r.worst_abs = err;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    return r;
}

static const double vel_list[] = {0.1,    0.37,   1.0,    4.1,    10.0,  33.3,
                                  100.0,  271.0,  1000.0, 3333.3, 9999., 10001.,
                                  15000., 33333., 1.0e5,  3.7e5,  1.0e6};

static void test_velocity_edge_mode_bound(void)
{
    unsigned i;
    for (i = 0; i < sizeof(vel_list) / sizeof(vel_list[0]); i++) {
        verr_t a = run_velocity(vel_list[i], false, 0, NULL);
        verr_t b = run_velocity(-vel_list[i], false, 0, NULL);
        TEST_ASSERT_TRUE(a.worst_rel < 5e-5 && b.worst_rel < 5e-5);
    }
}

static void test_velocity_counter_mode_bound(void)
{
    unsigned i;
    for (i = 0; i < sizeof(vel_list) / sizeof(vel_list[0]); i++) {
        run_velocity(vel_list[i], true, 0, NULL);
        run_velocity(-vel_list[i], true, 1000000, NULL);
    }
}

/* Edge placement errors of +-0.2 count: whole-cycle windows cancel them. */
static void test_velocity_cycle_mode_with_phase_error(void)
{
    const qgen_pos_t off[4] = {0, QGEN_ONE / 5, -QGEN_ONE / 8, QGEN_ONE / 10};
    unsigned i;
    for (i = 0; i < sizeof(vel_list) / sizeof(vel_list[0]); i++) {
        if (vel_list[i] >= 1.0) {
            verr_t a = run_velocity(vel_list[i], false, 0, off);
            verr_t b = run_velocity(-vel_list[i], false, 0, off);
            TEST_ASSERT_TRUE(a.worst_rel < 5e-5 && b.worst_rel < 5e-5);
        }
    }
}

/* Windows longer than 2^31 ns with many counts (the division's long path). */
static void test_velocity_long_interval(void)
{
    qdec_t d;
    qdec_config_t c;
    uint32_t t = 0;
    unsigned k;

    qdec_config_default(&c);
    c.input = QDEC_INPUT_COUNTER;
    c.counter_bits = 16;
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, t));
    t += TS_NS;
    qdec_sample_counter(&d, 1, t);
    for (k = 0; k < 70; k++) { /* 7 s without a count */
        t += 100000000u;
        qdec_sample_counter(&d, 1, t);
    }
    qdec_sample_counter(&d, 1001, t + TS_NS);
    /* 1000 counts in 7.0001 s */
    TEST_ASSERT_INT64_WITHIN(1 << 20, (int64_t)(1000.0 / 7.0001 * 4294967296.0), qdec_velocity(&d));
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
}

static void test_velocity_decay_and_timeout(void)
{
    qgen_t g;
    qdec_t d;
    fan_t fan = {{&d}, 1};
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint64_t t = 0, stop;
    unsigned k;

    c.zero_timeout_ns = 50000000; /* 50 ms */
    qgen_init(&g, QGEN_ONE / 2, t, fan_emit, &fan);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, qgen_lines(&g), 0));
    for (k = 0; k < 100; k++) { /* 1000 counts/s, reverse */
        t += TS_NS;
        qgen_move_to(&g, g.x - QGEN_ONE / 10, t);
        qdec_sample(&d, (uint32_t)t);
    }
    TEST_ASSERT_INT64_WITHIN(1ll << 22, -(1000ll << 32), qdec_velocity(&d));
    TEST_ASSERT_EQUAL_INT8(-1, d.out.dir);
    stop = g.last_edge_t;
    /* stopped: the estimate is bounded by 1 count / time since the edge */
    for (k = 0; k < 1000; k++) {
        double since, bound;
        t += TS_NS;
        qgen_move_to(&g, g.x, t);
        qdec_sample(&d, (uint32_t)t);
        since = (double)(t - stop) * 1e-9;
        if (since < 0.05) {
            bound = 1.0 / since;
            TEST_ASSERT_TRUE((double)-qdec_velocity(&d) / 4294967296.0 <=
                             fmin(bound, 1000.0) * 1.0001);
            TEST_ASSERT_TRUE(qdec_velocity(&d) < 0);
            TEST_ASSERT_FALSE(d.out.stopped);
        } else {
            TEST_ASSERT_EQUAL_INT64(0, qdec_velocity(&d));
            TEST_ASSERT_TRUE(d.out.stopped);
        }
    }
    TEST_ASSERT_EQUAL_INT8(-1, d.out.dir); /* the direction of approach stays */
    /* dithering across one edge, 10 crossings per tick: the net count per
     * tick is 0, so is the estimate (not the edge rate) */
    {
        int64_t b = g.count + 1;
        unsigned r;
        for (k = 0; k < 100; k++) {
            for (r = 0; r < 10; r++) {
                qgen_move_to(&g, QGEN_COUNTS(b) + ((r & 1) ? -QGEN_ONE / 8 : QGEN_ONE / 8),
                             t + (r + 1) * 9000u);
            }
            t += TS_NS;
            qdec_sample(&d, (uint32_t)t);
            if (k > 0) {
                TEST_ASSERT_EQUAL_INT64(0, qdec_velocity(&d));
            }
            TEST_ASSERT_FALSE(d.out.stopped);
        }
    }
}

/* The velocity is evaluated on demand (qdec_velocity): asking at every
 * sample or only now and then gives the same value, whatever happened in
 * between (new estimates, the bound between edges, undefined estimates,
 * the zero-speed timeout), for edge and counter input and any window. */
static void test_velocity_on_demand_equals_every_sample(void)
{
    static const uint64_t windows[3] = {0, 350000, 2000000};
    unsigned w, cyc, counter;

    for (counter = 0; counter < 2; counter++) {
        for (cyc = 0; cyc < 2; cyc++) {
            for (w = 0; w < 3; w++) {
                qgen_t g;
                qdec_t a, b;
                fan_t fan = {{&a, &b}, 2};
                qdec_config_t c = edge_cfg(QDEC_X4);
                uint64_t t = 0;
                uint32_t lcg = 12345u;
                unsigned k, asked = 0, next = 0, stops = 0;
                qgen_pos_t step = 0;

                if (counter && cyc) {
                    continue; /* vel_cycle is edge input only */
                }
                c.input = counter ? QDEC_INPUT_COUNTER : QDEC_INPUT_EDGES;
                c.vel_cycle = cyc != 0;
                c.vel_window_ns = windows[w];
                c.zero_timeout_ns = 30000000; /* 30 ms */
                qgen_init(&g, QGEN_ONE / 2, t, counter ? NULL : fan_emit, &fan);
                TEST_ASSERT_TRUE(qdec_init(&a, &c, counter ? 0u : qgen_lines(&g), 0));
                TEST_ASSERT_TRUE(qdec_init(&b, &c, counter ? 0u : qgen_lines(&g), 0));
                for (k = 0; k < 6000; k++) {
                    /* segments of 20 or 400 ticks (40 ms: longer than the
                     * timeout), 0..+-30 counts per tick, a third of them
                     * standing still */
                    if (k == next) {
                        lcg = lcg * 1664525u + 1013904223u;
                        step =
                            (qgen_pos_t)((int32_t)(lcg >> 16) % 60001 - 30000) * (QGEN_ONE / 1000);
                        if ((lcg >> 8) % 3u == 0u) {
                            step = 0;
                        }
                        next += ((lcg >> 4) & 1u) ? 400u : 20u;
                    }
                    t += TS_NS;
                    qgen_move_to(&g, g.x + step, t);
                    if (counter) {
                        qdec_sample_counter(&a, (uint32_t)g.count, (uint32_t)t);
                        qdec_sample_counter(&b, (uint32_t)g.count, (uint32_t)t);
                    } else {
                        qdec_sample(&a, (uint32_t)t);
                        qdec_sample(&b, (uint32_t)t);
                    }
                    (void)qdec_velocity(&a);
                    stops += a.out.stopped ? 1u : 0u;
                    lcg = lcg * 1664525u + 1013904223u;
                    /* asked now and then, with pauses of 50 ms (longer
                     * than the timeout) without any question */
                    if ((k / 500u) % 2u == 0u && (lcg >> 20) % 9u == 0u) {
                        asked++;
                        TEST_ASSERT_EQUAL_INT64(a.out.vel, qdec_velocity(&b));
                        TEST_ASSERT_EQUAL_INT64(a.out.vel_nm_s, b.out.vel_nm_s);
                        TEST_ASSERT_EQUAL(a.out.stopped, b.out.stopped);
                    }
                }
                TEST_ASSERT_TRUE(stops > 100); /* the timeout was reached */
                TEST_ASSERT_TRUE(asked > 150);
                TEST_ASSERT_EQUAL_INT64(a.out.pos, b.out.pos);
            }
        }
    }
}

/* ---- glitch filter ------------------------------------------------------------------------------
 */

typedef struct {
    qdec_t raw, filt;
    qgen_t g;
    fan_t fan;
    uint64_t t;
    int64_t c0;
} gl_t;

static void test_glitch_filter(void)
{
    static gl_t s;
    qdec_config_t c = edge_cfg(QDEC_X4);
    const uint32_t glitch = 500;
    const double rated = 2e9 / glitch; /* 4e6 counts/s */
    unsigned k, r, injected = 0, dither_drops = 0;
    int64_t lag_max = 0;

    s.t = 77;
    s.fan.dec[0] = &s.raw;
    s.fan.dec[1] = &s.filt;
    s.fan.n = 2;
    qgen_init(&s.g, QGEN_ONE / 2, s.t, fan_emit, &s.fan);
    TEST_ASSERT_TRUE(qdec_init(&s.raw, &c, qgen_lines(&s.g), (uint32_t)s.t));
    c.glitch_ns = glitch;
    TEST_ASSERT_TRUE(qdec_init(&s.filt, &c, qgen_lines(&s.g), (uint32_t)s.t));
    s.c0 = s.g.count;

    for (k = 0; k < 30000; k++) {
        unsigned phase = (k / 1000u) % 6u;
        qgen_pos_t step;
        int64_t truth, lag;
        switch (phase) {
        case 0: /* 0.99 x rated speed, forward */
            step = (qgen_pos_t)(rated * 0.99 * TS_NS * 1e-9 * QGEN_ONE);
            break;
        case 1:
            step = -(qgen_pos_t)(rated * 0.99 * TS_NS * 1e-9 * QGEN_ONE);
            break;
        case 2: /* slow, with glitches between the edges */
        case 3:
            step = (phase == 2 ? 1 : -1) * (QGEN_ONE / 3);
            break;
        default: /* dither across one edge (below) */
            step = 0;
            break;
        }
        if (k % 1000u == 0u) {
            step = 0; /* rest a tick between phases: no reversal pulse */
        }
        if (phase == 4 || phase == 5) {
            /* 20 crossings of one edge; even ticks 100..200 ns apart (all
             * dropped in pairs: 10 pulses), odd ticks 600..700 ns (all real) */
            qgen_pos_t b = QGEN_COUNTS(s.g.count + 1);
            uint64_t tt = s.t + 1000u;
            qgen_move_to(&s.g, b - QGEN_ONE / 8, tt);
            for (r = 0; r < 20; r++) {
                tt += ((k & 1) ? 600u : 100u) + rnd() % 101u;
                qgen_move_to(&s.g, (r & 1) ? b - QGEN_ONE / 8 : b + QGEN_ONE / 8, tt);
            }
            if ((k & 1) == 0) {
                dither_drops += 10;
            }
            s.t += TS_NS;
            qgen_move_to(&s.g, s.g.x, s.t);
        } else {
            if (phase >= 2 && (k & 1) == 0) {
                /* a pulse early in the tick, the motion continues after it */
                uint32_t line = (rnd() & 1u) ? QDEC_LINE_A : QDEC_LINE_B;
                qgen_glitch(&s.g, line, s.t + 1000u + rnd() % 1000u, 1u + rnd() % (glitch - 1));
                injected++;
            }
            s.t += TS_NS;
            qgen_move_to(&s.g, s.g.x + step, s.t);
        }
        qdec_sample(&s.raw, (uint32_t)s.t);
        qdec_sample(&s.filt, (uint32_t)s.t);
        truth = s.g.count - s.c0;
        TEST_ASSERT_EQUAL_INT64(truth, s.raw.out.pos);
        lag = truth - s.filt.out.pos;
        if (lag < 0) {
            lag = -lag;
        }
        if (lag > lag_max) {
            lag_max = lag;
        }
        /* at most the edges younger than glitch_ns are pending */
        if (lag > 2) {
            printf("k %u phase %u truth %lld filt %lld glitches %u\n", k, phase, (long long)truth,
                   (long long)s.filt.out.pos, (unsigned)s.filt.out.glitches);
        }
        TEST_ASSERT_TRUE(lag <= 2);
        if (s.t - s.g.last_edge_t >= glitch && truth != s.filt.out.pos) {
            printf("k %u phase %u truth %lld filt %lld\n", k, phase, (long long)truth,
                   (long long)s.filt.out.pos);
        }
        if (s.t - s.g.last_edge_t >= glitch) {
            TEST_ASSERT_EQUAL_INT64(truth, s.filt.out.pos);
        }
        TEST_ASSERT_EQUAL_UINT32(0, s.filt.out.illegal);
    }
    /* every injected pulse dropped; dither reversals shorter than glitch_ns too */
    TEST_ASSERT_EQUAL_UINT32(injected + dither_drops, s.filt.out.glitches);
    TEST_ASSERT_TRUE(injected >= 5000u);
    TEST_ASSERT_EQUAL_UINT32(0, s.raw.out.glitches);
    s.t += TS_NS;
    qgen_move_to(&s.g, s.g.x, s.t);
    qdec_sample(&s.filt, (uint32_t)s.t);
    TEST_ASSERT_EQUAL_INT64(s.g.count - s.c0, s.filt.out.pos);
    printf("glitch filter: %u pulses injected, %u dropped, worst lag %d counts\n", injected,
           (unsigned)s.filt.out.glitches, (int)lag_max);
}

static void test_glitch_filter_counts_exact_pulses(void)
{
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);

    c.glitch_ns = 100;
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
    /* A pulse of 99 ns: dropped, even across a sample */
    qdec_edge(&d, QDEC_LINE_A, 1000);
    qdec_sample(&d, 1050);
    TEST_ASSERT_EQUAL_INT64(0, d.out.pos);
    qdec_edge(&d, 0, 1099);
    qdec_sample(&d, 2000);
    TEST_ASSERT_EQUAL_INT64(0, d.out.pos);
    TEST_ASSERT_EQUAL_UINT32(1, d.out.glitches);
    /* a pulse of 100 ns passes: +1 then -1, each at its own time */
    qdec_edge(&d, QDEC_LINE_A, 3000);
    qdec_edge(&d, 0, 3100);
    qdec_sample(&d, 3150);
    TEST_ASSERT_EQUAL_INT64(1, d.out.pos); /* the falling edge is still pending */
    qdec_sample(&d, 3200);
    TEST_ASSERT_EQUAL_INT64(0, d.out.pos);
    TEST_ASSERT_EQUAL_UINT32(1, d.out.glitches);
    /* a spike on A around a real B edge is removed; B counts (-1) */
    qdec_edge(&d, QDEC_LINE_A, 5000);
    qdec_edge(&d, QDEC_LINE_A | QDEC_LINE_B, 5010);
    qdec_edge(&d, QDEC_LINE_B, 5020);
    qdec_sample(&d, 6000);
    TEST_ASSERT_EQUAL_INT64(-1, d.out.pos);
    TEST_ASSERT_EQUAL_UINT32(0, d.out.illegal);
    /* A and B changing in one event stay illegal */
    qdec_edge(&d, QDEC_LINE_A, 7000);
    qdec_sample(&d, 8000);
    TEST_ASSERT_EQUAL_UINT32(1, d.out.illegal);
    TEST_ASSERT_EQUAL_INT64(-1, d.out.pos);
}

/* ---- scaling, compensation hook, configuration ----------------------------------------------- */

__extension__ typedef __int128 i128;

/* The inline 32-bit scaling (den 1, |counts| < 2^31, |offset| < 2^62)
 * equals the general form and the exact saturated value over its whole
 * range, and its edges fall back to the general form. */
/* ---- runs (qdec_edge_run) ------------------------------------------------------------- */

static unsigned runs_taken;

static void run_dec_emit(void *ctx, uint32_t lines, uint32_t t_ns)
{
    qdec_edge(ctx, lines, t_ns);
}

static bool run_dec_run(void *ctx, int32_t steps, uint32_t t_last_ns)
{
    bool ok = qdec_edge_run(ctx, steps, t_last_ns);
    runs_taken += ok ? 1u : 0u;
    return ok;
}

static void check_same_decoders(qdec_t *a, qdec_t *b)
{
    TEST_ASSERT_EQUAL_UINT32(a->e.count, b->e.count);
    TEST_ASSERT_EQUAL_UINT32(a->e.nedge, b->e.nedge);
    TEST_ASSERT_EQUAL_UINT32(a->e.t_last, b->e.t_last);
    TEST_ASSERT_EQUAL_INT8(a->e.dir, b->e.dir);
    TEST_ASSERT_EQUAL_UINT8(a->e.ab, b->e.ab);
    TEST_ASSERT_EQUAL_UINT8(a->e.z, b->e.z);
    TEST_ASSERT_EQUAL_INT64(a->out.pos, b->out.pos);
    TEST_ASSERT_EQUAL_INT64(a->out.pos_nm, b->out.pos_nm);
    TEST_ASSERT_EQUAL_INT8(a->out.dir, b->out.dir);
    TEST_ASSERT_EQUAL(a->out.stopped, b->out.stopped);
    TEST_ASSERT_EQUAL_UINT32(a->out.faults, b->out.faults);
    TEST_ASSERT_EQUAL_UINT32(a->out.index_events, b->out.index_events);
    TEST_ASSERT_EQUAL_INT64(a->out.index_pos, b->out.index_pos);
    TEST_ASSERT_EQUAL_UINT32(a->out.index_t_ns, b->out.index_t_ns);
    TEST_ASSERT_EQUAL_INT8(a->out.index_dir, b->out.index_dir);
    TEST_ASSERT_EQUAL_INT64(qdec_velocity(a), qdec_velocity(b));
}

/* The decoder fed runs (the simulator's fast encoder) against the same
 * decoder fed every edge of the same trajectory: speeds from standstill to
 * 2e6 counts/s, reversals inside a tick, an index every 1000 counts (the
 * ticks through its window go edge by edge): every output and the edge
 * state equal after every sample. */
static void test_edge_run_equals_edges(void)
{
    qgen_t ga, gb;
    qdec_t da, db;
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint64_t t = 5000, k;
    double v = 0.0;
    qgen_pos_t x = QGEN_ONE / 2;

    c.nm_per_count_num = 1250;
    c.index_qual = 0;
    qgen_init(&ga, x, t, run_dec_emit, &da);
    qgen_init(&gb, x, t, run_dec_emit, &db);
    qgen_set_index(&ga, 300, 1000, 0, 0);
    qgen_set_index(&gb, 300, 1000, 0, 0);
    qgen_set_run(&gb, run_dec_run);
    TEST_ASSERT_TRUE(qdec_init(&da, &c, qgen_lines(&ga), (uint32_t)t));
    TEST_ASSERT_TRUE(qdec_init(&db, &c, qgen_lines(&gb), (uint32_t)t));
    runs_taken = 0;
    for (k = 0; k < 60000; k++) {
        unsigned s;
        if (k % 500 == 0) {
            /* a new speed, counts per tick: +-200 (2e6 counts/s), some stops */
            v = (k % 3500 == 0) ? 0.0 : ((double)(rnd() % 40001u) - 20000.0) / 100.0;
        }
        for (s = 1; s <= 4; s++) {
            /* four substeps, one of them sometimes against the motion */
            double dv = (s == 3 && (k % 7 == 0)) ? -0.6 * v : 0.25 * v;
            x += (qgen_pos_t)(dv * (double)QGEN_ONE);
            qgen_move_to(&ga, x, t + 25000u * s);
            qgen_move_to(&gb, x, t + 25000u * s);
        }
        t += TS_NS;
        qdec_sample(&da, (uint32_t)t);
        qdec_sample(&db, (uint32_t)t);
        check_same_decoders(&da, &db);
    }
    TEST_ASSERT_TRUE(runs_taken > 100000u);
    TEST_ASSERT_TRUE(da.out.index_events > 100u);
    TEST_ASSERT_EQUAL_UINT64(ga.edges, gb.edges);
}

/* Constant velocity through runs alone: at every sample the position is
 * floor(x(t_k)) - floor(x0) and the last edge's time the crossing of that
 * count, t0 + floor((c ONE - x0) T / S) with S the q24 step per tick T. */
static void test_edge_run_constant_velocity_closed_form(void)
{
    static const int64_t steps[] = {(int64_t)(37.3 * 16777216.0), -(int64_t)(0.71 * 16777216.0),
                                    (int64_t)(1999.9 * 16777216.0), QGEN_ONE + 1};
    qgen_t g;
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    unsigned j;

    for (j = 0; j < 4; j++) {
        int64_t S = steps[j];
        qgen_pos_t x0 = -QGEN_COUNTS(777) + 12345;
        uint64_t t0 = 0xFFF00000ull, k; /* across the 32-bit wrap */
        int64_t c0 = floor_div(x0, QGEN_ONE);

        qgen_init(&g, x0, t0, NULL, &d); /* no edge callback: runs only */
        qgen_set_run(&g, run_dec_run);
        TEST_ASSERT_TRUE(qdec_init(&d, &c, qgen_lines(&g), (uint32_t)t0));
        runs_taken = 0;
        for (k = 1; k <= 3000; k++) {
            int64_t ck = floor_div(x0 + (int64_t)k * S, QGEN_ONE);
            qgen_move_to(&g, x0 + (int64_t)k * S, t0 + k * TS_NS);
            qdec_sample(&d, (uint32_t)(t0 + k * TS_NS));
            TEST_ASSERT_EQUAL_INT64(ck - c0, d.out.pos);
            if (ck != c0) {
                /* the boundary last crossed: ck (forward) or ck + 1 */
                int64_t b = (S > 0) ? ck : ck + 1;
                __extension__ __int128 dist = (__int128)b * QGEN_ONE - x0;
                uint64_t tl = t0 + (uint64_t)(dist * TS_NS / S);
                TEST_ASSERT_EQUAL_UINT32((uint32_t)tl, d.e.t_last);
            }
        }
        TEST_ASSERT_TRUE(runs_taken > 0u);
    }
}

/* qdec_edge_run refuses (returns false, changes nothing) what it cannot
 * stand for: no steps, x2/x1, the glitch filter, vel_cycle, Z high. */
static void test_edge_run_refusals(void)
{
    qdec_t d, before;
    qdec_config_t c;
    unsigned k;

    for (k = 0; k < 6; k++) {
        c = edge_cfg(k == 1 ? QDEC_X2 : k == 2 ? QDEC_X1 : QDEC_X4);
        c.glitch_ns = (k == 3) ? 500u : 0u;
        c.vel_cycle = (k == 4);
        TEST_ASSERT_TRUE(qdec_init(&d, &c, (k == 5) ? QDEC_LINE_Z : 0u, 0));
        before = d;
        TEST_ASSERT_FALSE(qdec_edge_run(&d, (k == 0) ? 0 : 5, 1000));
        TEST_ASSERT_EQUAL_INT(0, memcmp(&before, &d, sizeof d));
    }
    /* and takes the others: 5 forward from 00 ends in A (0, A, AB, B, 0, A) */
    c = edge_cfg(QDEC_X4);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0u, 0));
    TEST_ASSERT_TRUE(qdec_edge_run(&d, 5, 1000));
    TEST_ASSERT_EQUAL_UINT8(QDEC_LINE_A, d.e.ab);
    TEST_ASSERT_TRUE(qdec_edge_run(&d, -7, 2000)); /* -2 from 00: AB */
    TEST_ASSERT_EQUAL_UINT8(QDEC_LINE_A | QDEC_LINE_B, d.e.ab);
    TEST_ASSERT_EQUAL_UINT32(12, d.e.nedge);
    TEST_ASSERT_EQUAL_INT8(-1, d.e.dir);
    TEST_ASSERT_EQUAL_UINT32(4, d.e.seq);
}

static void test_scaling_fast_path(void)
{
    static const int32_t nums[] = {1, 1250, -1250, INT32_MAX, INT32_MIN};
    static const int64_t offs[] = {0,
                                   -12345,
                                   ((int64_t)1 << 62) - 1,
                                   -((int64_t)1 << 62) + 1,
                                   (int64_t)1 << 62,
                                   -((int64_t)1 << 62),
                                   INT64_MAX,
                                   INT64_MIN};
    static const int64_t fixed[] = {
        0, 1, -1, INT32_MAX, INT32_MIN, (int64_t)INT32_MAX + 1, (int64_t)INT32_MIN - 1};
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    unsigned k, o, j;

    for (k = 0; k < 5; k++) {
        for (o = 0; o < 8; o++) {
            c.nm_per_count_num = nums[k];
            c.nm_per_count_den = 1;
            c.offset_nm = offs[o];
            TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
            for (j = 0; j < 2000; j++) {
                /* second half: the offset set by qdec_set_offset_nm (it keeps
                 * the short path's condition up to date) */
                int64_t off = (j < 1000) ? offs[o] : offs[7 - o];
                int64_t counts =
                    (j % 1000 < 7) ? fixed[j % 1000] : (int64_t)(int32_t)(rnd() ^ (rnd() << 16));
                i128 ref = (i128)counts * nums[k] + off;
                if (j == 1000) {
                    qdec_set_offset_nm(&d, off);
                }
                if (ref > INT64_MAX) {
                    ref = INT64_MAX;
                } else if (ref < INT64_MIN) {
                    ref = INT64_MIN;
                }
                TEST_ASSERT_EQUAL_INT64((int64_t)ref, qdec_counts_to_nm(&d, counts));
                TEST_ASSERT_EQUAL_INT64((int64_t)ref, qdec_counts_to_nm_any(&d, counts));
            }
        }
    }
}

static void test_scaling_exact(void)
{
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    unsigned k;
    static const int32_t nums[] = {5000000, 1, -250, 2147483647, 7};
    static const int32_t dens[] = {4096, 1, 1, 3, 2147483647};

    for (k = 0; k < 5; k++) {
        unsigned j;
        c.nm_per_count_num = nums[k];
        c.nm_per_count_den = dens[k];
        c.offset_nm = -12345;
        TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
        /* counts whose scaled value stays within +-2^62 */
        i128 lim = ((i128)1 << 62) * dens[k] / (nums[k] < 0 ? -nums[k] : nums[k]);
        if (lim > INT64_MAX) {
            lim = INT64_MAX;
        }
        for (j = 0; j < 20000; j++) {
            int64_t counts = (int64_t)((((i128)rnd() << 32) ^ ((i128)rnd() << 16) ^ rnd()) % lim);
            if (rnd() & 1u) {
                counts = -counts;
            }
            i128 p = (i128)counts * nums[k];
            i128 qq = p / dens[k], rr = p % dens[k];
            int64_t ref;
            if (2 * (rr < 0 ? -rr : rr) >= dens[k]) {
                qq += (p < 0) ? -1 : 1;
            }
            if (j < 3) {
                counts = (j == 0) ? 0 : (j == 1) ? -1 : 1;
                p = (i128)counts * nums[k];
                qq = p / dens[k];
                rr = p % dens[k];
                if (2 * (rr < 0 ? -rr : rr) >= dens[k]) {
                    qq += (p < 0) ? -1 : 1;
                }
            }
            ref = (int64_t)qq - 12345;
            TEST_ASSERT_EQUAL_INT64(ref, qdec_counts_to_nm(&d, counts));
        }
        /* saturation instead of wrap */
        if (nums[k] > 1000) {
            TEST_ASSERT_EQUAL_INT64(INT64_MAX, qdec_counts_to_nm(&d, INT64_MAX));
            TEST_ASSERT_EQUAL_INT64(INT64_MIN, qdec_counts_to_nm(&d, INT64_MIN + 1));
        }
    }
}

/* den != 1 with |counts| < 2^31 (the counter-input sample's usual case):
 * round(counts * num / den) + offset, half away from zero, saturated, at
 * offsets on both sides of +-2^62 (where the short path stops). */
static void test_scaling_den_short_path(void)
{
    static const int32_t nums[] = {5000000, -5000000, 1, -3, INT32_MAX, INT32_MIN};
    static const int32_t dens[] = {4096, 2, 3, 7, 1000, INT32_MAX};
    static const int64_t offs[] = {0,
                                   -12345,
                                   ((int64_t)1 << 62) - 1,
                                   -((int64_t)1 << 62) + 1,
                                   (int64_t)1 << 62,
                                   -((int64_t)1 << 62),
                                   INT64_MAX,
                                   INT64_MIN};
    static const int64_t fixed[] = {0, 1, -1, 2, -2, INT32_MAX, INT32_MIN, 2048, -2048};
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);
    unsigned k, m, o, j;

    for (k = 0; k < 6; k++) {
        for (m = 0; m < 6; m++) {
            for (o = 0; o < 8; o++) {
                c.nm_per_count_num = nums[k];
                c.nm_per_count_den = dens[m];
                c.offset_nm = offs[o];
                TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
                for (j = 0; j < 300; j++) {
                    int64_t counts = (j < 9) ? fixed[j] : (int64_t)(int32_t)(rnd() ^ (rnd() << 16));
                    i128 p = (i128)counts * nums[k];
                    i128 qq = p / dens[m], rr = p % dens[m];
                    if (2 * (rr < 0 ? -rr : rr) >= dens[m]) {
                        qq += (p < 0) ? -1 : 1;
                    }
                    qq += offs[o];
                    if (qq > INT64_MAX) {
                        qq = INT64_MAX;
                    } else if (qq < INT64_MIN) {
                        qq = INT64_MIN;
                    }
                    TEST_ASSERT_EQUAL_INT64((int64_t)qq, qdec_counts_to_nm_any(&d, counts));
                    TEST_ASSERT_EQUAL_INT64((int64_t)qq, qdec_counts_to_nm(&d, counts));
                }
            }
        }
    }
}

static void test_nm_outputs_and_identity_comp(void)
{
    qgen_t g;
    qdec_t d;
    fan_t fan = {{&d}, 1};
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint64_t t = 0;
    unsigned k;

    c.nm_per_count_num = 5000000; /* 5 mm per 4096 counts */
    c.nm_per_count_den = 4096;
    c.offset_nm = 1000000;
    qgen_init(&g, QGEN_ONE / 2, t, fan_emit, &fan);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, qgen_lines(&g), 0));
    TEST_ASSERT_EQUAL_INT64(1000000, d.out.pos_nm);
    for (k = 0; k < 1000; k++) {
        t += TS_NS;
        qgen_move_to(&g, g.x + QGEN_COUNTS(40), t); /* 400000 counts/s */
        qdec_sample(&d, (uint32_t)t);
    }
    TEST_ASSERT_EQUAL_INT64(40000, d.out.pos);
    TEST_ASSERT_EQUAL_INT64(1000000 + 48828125, d.out.pos_nm_raw);
    TEST_ASSERT_EQUAL_INT64(d.out.pos_nm_raw, d.out.pos_nm);
    (void)qdec_velocity(&d);
    TEST_ASSERT_INT64_WITHIN(2, 488281250, d.out.vel_nm_s);
    TEST_ASSERT_EQUAL_INT64(123, comp_correct(NULL, 123, COMP_DIR_POS));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, comp_correct(NULL, INT64_MIN, COMP_DIR_NEG));
    qdec_set_offset_nm(&d, 0);
    qdec_sample(&d, (uint32_t)(t + TS_NS));
    TEST_ASSERT_EQUAL_INT64(48828125, d.out.pos_nm);
}

static void test_config_rejected(void)
{
    qdec_t d;
    qdec_config_t c;
    qdec_config_t bad[12];
    unsigned i;

    for (i = 0; i < 12; i++) {
        qdec_config_default(&bad[i]);
    }
    bad[0].mode = (qdec_mode_t)3;
    bad[1].input = (qdec_input_t)2;
    bad[2].input = QDEC_INPUT_COUNTER;
    bad[2].counter_bits = 7;
    bad[3].input = QDEC_INPUT_COUNTER;
    bad[3].counter_bits = 33;
    bad[4].illegal_limit = QDEC_ILLEGAL_MAX + 1;
    bad[5].index_qual = 4;
    bad[6].nm_per_count_num = 0;
    bad[7].nm_per_count_den = 0;
    bad[8].nm_per_count_den = -3;
    bad[9].input = QDEC_INPUT_COUNTER;
    bad[9].glitch_ns = 10;
    bad[10].input = QDEC_INPUT_COUNTER;
    bad[10].counter_bits = 16;
    bad[10].max_delta = 32768;
    bad[11].glitch_ns = 0x80000000u;
    for (i = 0; i < 12; i++) {
        d.out.pos = 4242;
        TEST_ASSERT_FALSE(qdec_init(&d, &bad[i], 0, 0));
        TEST_ASSERT_EQUAL_INT64(4242, d.out.pos); /* untouched */
    }
    qdec_config_default(&c);
    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 0));
}

/* ---- qdec_sample's short path against the reference path --------------------------------------
 */

static void assert_same_out(const qdec_t *a, const qdec_t *b)
{
    TEST_ASSERT_EQUAL_INT64(b->out.pos, a->out.pos);
    TEST_ASSERT_EQUAL_INT64(b->out.pos_nm_raw, a->out.pos_nm_raw);
    TEST_ASSERT_EQUAL_INT64(b->out.pos_nm, a->out.pos_nm);
    TEST_ASSERT_EQUAL_INT(b->out.dir, a->out.dir);
    TEST_ASSERT_EQUAL(b->out.stopped, a->out.stopped);
    TEST_ASSERT_EQUAL_UINT32(b->out.faults, a->out.faults);
    TEST_ASSERT_EQUAL_UINT32(b->out.illegal, a->out.illegal);
    TEST_ASSERT_EQUAL_UINT32(b->out.glitches, a->out.glitches);
    TEST_ASSERT_EQUAL_UINT32(b->out.index_events, a->out.index_events);
    TEST_ASSERT_EQUAL_INT64(b->out.index_pos, a->out.index_pos);
    TEST_ASSERT_EQUAL_UINT32(b->out.index_t_ns, a->out.index_t_ns);
    TEST_ASSERT_EQUAL_INT(b->out.index_dir, a->out.index_dir);
}

/* Random edge streams (legal steps both ways, illegal transitions, Z with a
 * gated index), edge times before and after the sample, sample periods from
 * 1 ns to 2^31 - 1 ns and backwards (time fault), count jumps of any 32-bit
 * size (overspeed, positions beyond 2^31), scale, offset and compensation
 * table: the short path (q->fast) and the reference path (fast cleared)
 * give the same outputs and the same velocity at every sample. */
static void test_sample_fast_equals_reference(void)
{
    static const uint8_t seq4[4] = {0, 1, 3, 2};
    static const uint64_t windows[2] = {0, 350000};
    static comp_table_t tab;
    unsigned cfgi, k, fast_used = 0, ref_used = 0;

    tab.n = 3;
    tab.pos[0] = -1000000;
    tab.pos[1] = 0;
    tab.pos[2] = 1000000;
    tab.fwd[0] = 5;
    tab.fwd[1] = -7;
    tab.fwd[2] = 11;
    tab.rev[0] = -3;
    tab.rev[1] = 2;
    tab.rev[2] = 9;
    TEST_ASSERT_EQUAL(COMP_OK, comp_table_check(&tab));
    for (cfgi = 0; cfgi < 8; cfgi++) {
        qdec_t a, b;
        qdec_config_t c = edge_cfg((qdec_mode_t)(cfgi % 3u));
        uint32_t t = 0xFFFF0000u, lines = 0; /* the clock wraps early */
        unsigned ph = 0;

        c.vel_window_ns = windows[cfgi & 1u];
        c.nm_per_count_num = (cfgi & 2u) ? -3 : 250;
        c.nm_per_count_den = (cfgi == 6u) ? 7 : 1;
        c.offset_nm = (cfgi & 4u) ? -123456789 : 0;
        c.comp = (cfgi == 5u) ? &tab : NULL;
        c.illegal_limit = 3;
        c.illegal_window_ns = 5000000;
        c.index_qual = (cfgi & 1u) ? 3u : QDEC_INDEX_UNGATED;
        c.zero_timeout_ns = 20000000;
        TEST_ASSERT_TRUE(qdec_init(&a, &c, lines, t));
        TEST_ASSERT_TRUE(qdec_init(&b, &c, lines, t));
        TEST_ASSERT_TRUE(a.fast);
        b.fast = false;
        for (k = 0; k < 20000; k++) {
            uint32_t r = rnd(), n = r % 8u, j, ts;
            int32_t dt;
            bool fast_before;

            for (j = 0; j < n; j++) {
                uint32_t rr = rnd();
                if (rr % 401u == 0u) {
                    lines ^= 3u; /* illegal: both channels at once */
                    ph = (ph + 2u) % 4u;
                } else if (rr % 211u == 0u) {
                    lines |= QDEC_LINE_Z; /* an index pulse until the next step */
                } else {
                    /* either way, or mostly forward in half of the stretches */
                    bool fwd = ((k / 700u) % 2u == 0u) ? (rr & 448u) != 0u : (rr & 64u) != 0u;
                    ph = fwd ? (ph + 1u) % 4u : (ph + 3u) % 4u;
                    lines = seq4[ph];
                }
                ts = t + (uint32_t)((int32_t)(rnd() % 300000u) - 100000);
                qdec_edge(&a, lines, ts);
                qdec_edge(&b, lines, ts);
            }
            if (r % 97u == 0u) { /* a count jump of any 32-bit size, or at the overspeed limit */
                static const uint32_t edge_jumps[4] = {(1u << 30) - 1u, 1u << 30,
                                                       0u - ((1u << 30) - 1u), 0u - (1u << 30)};
                uint32_t jump = (r & 0x300u) ? rnd() * 65599u : edge_jumps[(r >> 12) & 3u];
                a.e.count += jump;
                b.e.count += jump;
                a.e.nedge++;
                b.e.nedge++;
            }
            switch ((r >> 8) % 50u) {
            case 0:
                dt = -(int32_t)(rnd() % 1000u); /* backwards or the same time */
                break;
            case 1:
                dt = (int32_t)(0x7FFFFFFFu - rnd() % 1000u); /* the longest period */
                break;
            case 2:
                dt = (int32_t)(rnd() % 30000000u); /* up to 30 ms: timeouts */
                break;
            case 3:
                dt = 1;
                break;
            default:
                dt = 100000;
                break;
            }
            t += (uint32_t)dt;
            fast_before =
                a.last_illegal == a.e.illegal && a.last_idx_events == a.e.idx_events && dt > 0;
            /* the short path's one check (e.rare) stands for both counters */
            TEST_ASSERT_EQUAL_INT(a.last_illegal == a.e.illegal &&
                                      a.last_idx_events == a.e.idx_events,
                                  a.last_rare == a.e.rare);
            fast_used += fast_before ? 1u : 0u;
            ref_used += fast_before ? 0u : 1u;
            qdec_sample(&a, t);
            qdec_sample(&b, t);
            assert_same_out(&a, &b);
            if ((r >> 16) % 3u == 0u) {
                TEST_ASSERT_EQUAL_INT64(qdec_velocity(&b), qdec_velocity(&a));
                TEST_ASSERT_EQUAL_INT64(b.out.vel_nm_s, a.out.vel_nm_s);
            }
            if ((r >> 20) % 500u == 0u) {
                qdec_clear_faults(&a);
                qdec_clear_faults(&b);
            }
        }
        TEST_ASSERT_EQUAL_INT64(qdec_velocity(&b), qdec_velocity(&a));
    }
    printf("sample paths: %u short, %u reference\n", fast_used, ref_used);
    TEST_ASSERT_TRUE(fast_used > 100000u);
    TEST_ASSERT_TRUE(ref_used > 5000u);
}

/* Steady motion keeps the velocity record on its short path (the ring
 * rising: vel_fast) once the ring is full, and the folded bookkeeping is
 * what the record count says. */
static void test_velocity_short_record_stays(void)
{
    static const uint8_t seq4[4] = {0, 1, 3, 2};
    qdec_t q;
    qdec_config_t c = edge_cfg(QDEC_X4);
    uint32_t t = 1000;
    unsigned k;

    TEST_ASSERT_TRUE(qdec_init(&q, &c, 0, t));
    for (k = 1; k <= 40; k++) {
        qdec_edge(&q, seq4[k % 4u], t + 50000u);
        t += 100000u;
        qdec_sample(&q, t);
        if (k >= 2u) {
            TEST_ASSERT_TRUE(q.vel_fast);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(40, q.rec);
    TEST_ASSERT_TRUE(q.rec - q.rec_norm <= QDEC_VEL_RING);
    TEST_ASSERT_EQUAL_INT64(10000ll << 32, qdec_velocity(&q)); /* 1 count per 100 us */
    TEST_ASSERT_EQUAL_UINT32(q.rec, q.rec_norm);
    TEST_ASSERT_EQUAL_UINT8(QDEC_VEL_RING, q.ring_n);
    TEST_ASSERT_EQUAL_UINT8(QDEC_VEL_RING - 1u, q.ring_mono);
}

static void test_time_fault(void)
{
    qdec_t d;
    qdec_config_t c = edge_cfg(QDEC_X4);

    TEST_ASSERT_TRUE(qdec_init(&d, &c, 0, 1000));
    qdec_sample(&d, 2000);
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
    qdec_sample(&d, 2000);
    TEST_ASSERT_EQUAL_UINT32(QDEC_FAULT_TIME, d.out.faults);
    /* an edge stamped just after the sample's clock read is fine */
    qdec_clear_faults(&d);
    qdec_edge(&d, QDEC_LINE_A, 3010);
    qdec_sample(&d, 3000);
    TEST_ASSERT_EQUAL_INT64(1, d.out.pos);
    TEST_ASSERT_EQUAL_UINT32(0, d.out.faults);
}

/* Samples without a counted edge keep the position and skip the scaling
 * (qdec.h): an offset set between them (qdec_set_offset_nm), a compensation
 * table installed or removed, or a table whose values change, all show in
 * pos_nm at the next sample without an edge, exactly as on the reference
 * path (a twin decoder with fast cleared). */
static void test_idle_sample_follows_offset_and_comp(void)
{
    static const uint8_t seq4[4] = {0, 1, 3, 2};
    static comp_table_t tab;
    qdec_config_t c = edge_cfg(QDEC_X4);
    qdec_t a, b;
    uint32_t t = 1000;
    unsigned k;

    tab.n = 2;
    tab.pos[0] = 0;
    tab.pos[1] = 1000000;
    tab.fwd[0] = 40;
    tab.fwd[1] = 80;
    tab.rev[0] = -10;
    tab.rev[1] = -20;
    TEST_ASSERT_EQUAL(COMP_OK, comp_table_check(&tab));
    c.nm_per_count_num = 250;
    TEST_ASSERT_TRUE(qdec_init(&a, &c, 0, t));
    TEST_ASSERT_TRUE(qdec_init(&b, &c, 0, t));
    b.fast = false;
    for (k = 1; k <= 9; k++) { /* 9 counts forward, then samples without edges */
        t += 1000;
        qdec_edge(&a, seq4[k % 4u], t);
        qdec_edge(&b, seq4[k % 4u], t);
    }
    t += 100000;
    qdec_sample(&a, t);
    qdec_sample(&b, t);
    assert_same_out(&a, &b);
    TEST_ASSERT_EQUAL_INT64(2250, a.out.pos_nm);
    for (k = 0; k < 6; k++) {
        t += 100000;
        switch (k) {
        case 1:
            qdec_set_offset_nm(&a, 5000);
            qdec_set_offset_nm(&b, 5000);
            break;
        case 2:
            qdec_set_comp(&a, &tab);
            qdec_set_comp(&b, &tab);
            break;
        case 3:
            tab.fwd[0] = 400; /* the table changes under the decoder */
            break;
        case 4:
            qdec_set_comp(&a, NULL);
            qdec_set_comp(&b, NULL);
            break;
        default:
            break;
        }
        qdec_sample(&a, t);
        qdec_sample(&b, t);
        assert_same_out(&a, &b);
    }
    TEST_ASSERT_EQUAL_INT64(7250, a.out.pos_nm); /* offset kept, table removed */
    TEST_ASSERT_EQUAL_INT64(9, a.out.pos);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_loopback_million_edges);
    RUN_TEST(test_loopback_injected_illegal);
    RUN_TEST(test_illegal_never_counts_a_step);
    RUN_TEST(test_illegal_fault_window);
    RUN_TEST(test_counter_extension_max_delta);
    RUN_TEST(test_overspeed_compare);
    RUN_TEST(test_counter_random_and_overspeed);
    RUN_TEST(test_index_qualified_same_both_directions);
    RUN_TEST(test_index_ungated_has_hysteresis);
    RUN_TEST(test_index_capture_counter_mode);
    RUN_TEST(test_velocity_edge_mode_bound);
    RUN_TEST(test_velocity_counter_mode_bound);
    RUN_TEST(test_velocity_cycle_mode_with_phase_error);
    RUN_TEST(test_velocity_long_interval);
    RUN_TEST(test_velocity_decay_and_timeout);
    RUN_TEST(test_glitch_filter);
    RUN_TEST(test_glitch_filter_counts_exact_pulses);
    RUN_TEST(test_velocity_on_demand_equals_every_sample);
    RUN_TEST(test_scaling_fast_path);
    RUN_TEST(test_scaling_exact);
    RUN_TEST(test_scaling_den_short_path);
    RUN_TEST(test_nm_outputs_and_identity_comp);
    RUN_TEST(test_config_rejected);
    RUN_TEST(test_time_fault);
    RUN_TEST(test_sample_fast_equals_reference);
    RUN_TEST(test_idle_sample_follows_offset_and_comp);
    RUN_TEST(test_velocity_short_record_stays);
    RUN_TEST(test_edge_run_equals_edges);
    RUN_TEST(test_edge_run_constant_velocity_closed_form);
    RUN_TEST(test_edge_run_refusals);
    return UNITY_END();
}
