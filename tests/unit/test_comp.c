/*
 * Compensation table (comp.h) and its flash store (comp_store.h):
 * interpolation against a reference, ends held, direction blend and the
 * reversal ramp (bounded change per tick), limits, the decoder hook, the
 * record codec (every corrupted byte refused), and the store (log in two
 * banks): versions, previous table kept until the new one is verified,
 * power cuts during a write, corrupted records. More store tests (sector
 * flash, compaction, power cuts at every step): test_comp_store.c.
 */
#include "comp.h"
#include "comp_store.h"
#include "crc.h"
#include "hal.h"
#include "hal_flash_sim.h"
#include "qdec.h"
#include "unity.h"

#include <math.h>
#include <string.h>

static comp_table_t T; /* 2 KiB: static, not on the stack */

void setUp(void)
{
    memset(&T, 0, sizeof T);
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
}

void tearDown(void)
{
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
}

static uint64_t rng = 0x9E3779B97F4A7C15ull;
static uint64_t next_rand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

/* The Table 5.7 shape: 11 points, -75..75 mm, corrections in nm. */
static void table57(comp_table_t *t)
{
    static const int32_t fwd[11] = {27000, 15000, 11000, 12000, 10000, 9000,
                                    8000,  6000,  5000,  5000,  6000};
    static const int32_t rev[11] = {27000, 25000, 19000, 17000, 14000, 9000,
                                    8000,  8000,  8000,  7000,  4000};
    unsigned i;
    memset(t, 0, sizeof *t);
    t->n = 11;
    t->axis = 1;
    t->ramp_us = 20000;
    for (i = 0; i < 11; i++) {
        t->pos[i] = (pos_nm_t)(-75000000 + 15000000 * (int64_t)i);
        t->fwd[i] = fwd[i];
        t->rev[i] = rev[i];
    }
}

/* Reference: linear search and double arithmetic. */
static double ref_corr(const comp_table_t *t, pos_nm_t x, double w)
{
    double cf, cr;
    unsigned i;
    if (t->n == 0) {
        return 0.0;
    }
    if (x <= t->pos[0]) {
        cf = t->fwd[0];
        cr = t->rev[0];
    } else if (x >= t->pos[t->n - 1]) {
        cf = t->fwd[t->n - 1];
        cr = t->rev[t->n - 1];
    } else {
        for (i = 0; i + 1 < t->n && !(x >= t->pos[i] && x <= t->pos[i + 1]); i++) {
        }
        {
            double f = (double)(x - t->pos[i]) / (double)(t->pos[i + 1] - t->pos[i]);
            cf = t->fwd[i] + f * (t->fwd[i + 1] - t->fwd[i]);
            cr = t->rev[i] + f * (t->rev[i + 1] - t->rev[i]);
        }
    }
    return cr + (cf - cr) * (w + 1.0) / 2.0;
}

/* ---- correction ------------------------------------------------------------ */

static void test_null_and_empty_are_identity(void)
{
    TEST_ASSERT_EQUAL_INT64(123456789, comp_correct(NULL, 123456789, COMP_DIR_POS));
    TEST_ASSERT_EQUAL_INT64(INT64_MIN, comp_correct(NULL, INT64_MIN, COMP_DIR_NEG));
    T.n = 0;
    TEST_ASSERT_EQUAL_INT64(-42, comp_correct(&T, -42, COMP_DIR_NONE));
    TEST_ASSERT_EQUAL_INT64(7, comp_correct_w(&T, 7, COMP_W_ONE));
}

static void test_points_directions_and_ends(void)
{
    unsigned i;
    table57(&T);
    for (i = 0; i < 11; i++) {
        TEST_ASSERT_EQUAL_INT64(T.pos[i] + T.fwd[i], comp_correct(&T, T.pos[i], COMP_DIR_POS));
        TEST_ASSERT_EQUAL_INT64(T.pos[i] + T.rev[i], comp_correct(&T, T.pos[i], COMP_DIR_NEG));
        /* NONE: the mean of both directions (rounded half up) */
        TEST_ASSERT_EQUAL_INT64(T.pos[i] + (T.fwd[i] + T.rev[i] + 1) / 2,
                                comp_correct(&T, T.pos[i], COMP_DIR_NONE));
    }
    /* beyond the ends the end correction is held */
    TEST_ASSERT_EQUAL_INT64(-90000000 + 27000, comp_correct(&T, -90000000, COMP_DIR_POS));
    TEST_ASSERT_EQUAL_INT64(80000000 + 4000, comp_correct(&T, 80000000, COMP_DIR_NEG));
    /* midway between -60 and -45 mm: (15000 + 11000) / 2 forward */
    TEST_ASSERT_EQUAL_INT64(-52500000 + 13000, comp_correct(&T, -52500000, COMP_DIR_POS));
    TEST_ASSERT_EQUAL_INT64(-52500000 + 22000, comp_correct(&T, -52500000, COMP_DIR_NEG));
    /* saturation at the type's edges instead of overflow */
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, comp_correct(&T, INT64_MAX - 10, COMP_DIR_POS));
}

static void test_interpolation_matches_reference(void)
{
    unsigned trial, i, k;
    for (trial = 0; trial < 40; trial++) {
        pos_nm_t p = -(pos_nm_t)(next_rand() % 1000000000000ull);
        memset(&T, 0, sizeof T);
        T.n = (uint16_t)(1 + next_rand() % COMP_POINTS_MAX);
        for (i = 0; i < T.n; i++) {
            p += 1 + (pos_nm_t)(next_rand() % (trial % 4 == 0 ? 1000u : 30000000000ull));
            T.pos[i] = p;
            T.fwd[i] = (int32_t)(next_rand() % (2u * COMP_CORR_MAX_NM + 1u)) - COMP_CORR_MAX_NM;
            T.rev[i] = (int32_t)(next_rand() % (2u * COMP_CORR_MAX_NM + 1u)) - COMP_CORR_MAX_NM;
        }
        TEST_ASSERT_EQUAL_INT(COMP_OK, comp_table_check(&T));
        for (k = 0; k < 2000; k++) {
            pos_nm_t lo = T.pos[0] - 1000, hi = T.pos[T.n - 1] + 1000;
            pos_nm_t x = lo + (pos_nm_t)(next_rand() % (uint64_t)(hi - lo + 1));
            int32_t w = (int32_t)(next_rand() % (2u * COMP_W_ONE + 1u)) - COMP_W_ONE;
            double want = ref_corr(&T, x, (double)w / COMP_W_ONE);
            double got = (double)comp_correction(&T, x, w);
            /* two roundings (column, blend): within one nm of the exact value */
            TEST_ASSERT_TRUE_MESSAGE(fabs(got - want) <= 1.0 + 1e-6 * fabs(want),
                                     "interpolated correction off by more than 1 nm");
        }
    }
}

static void test_check_limits(void)
{
    table57(&T);
    TEST_ASSERT_EQUAL_INT(COMP_OK, comp_table_check(&T));
    T.pos[5] = T.pos[4];
    TEST_ASSERT_EQUAL_INT(COMP_E_ORDER, comp_table_check(&T));
    table57(&T);
    T.fwd[3] = COMP_CORR_MAX_NM + 1;
    TEST_ASSERT_EQUAL_INT(COMP_E_RANGE, comp_table_check(&T));
    table57(&T);
    T.rev[3] = -COMP_CORR_MAX_NM - 1;
    TEST_ASSERT_EQUAL_INT(COMP_E_RANGE, comp_table_check(&T));
    table57(&T);
    T.pos[0] = -COMP_POS_LIMIT_NM - 1;
    TEST_ASSERT_EQUAL_INT(COMP_E_RANGE, comp_table_check(&T));
    table57(&T);
    T.pos[10] = T.pos[9] + COMP_SPAN_MAX_NM + 1;
    TEST_ASSERT_EQUAL_INT(COMP_E_ORDER, comp_table_check(&T));
    table57(&T);
    T.ramp_us = COMP_RAMP_MAX_US + 1u;
    TEST_ASSERT_EQUAL_INT(COMP_E_RANGE, comp_table_check(&T));
    table57(&T);
    T.n = COMP_POINTS_MAX + 1;
    TEST_ASSERT_EQUAL_INT(COMP_E_COUNT, comp_table_check(&T));
    TEST_ASSERT_EQUAL_INT(COMP_E_ARG, comp_table_check(NULL));
}

static void test_extreme_table_no_overflow(void)
{
    /* widest span and largest opposite corrections: products near 2^61 */
    memset(&T, 0, sizeof T);
    T.n = 2;
    T.pos[0] = -COMP_SPAN_MAX_NM / 2;
    T.pos[1] = COMP_SPAN_MAX_NM / 2;
    T.fwd[0] = -COMP_CORR_MAX_NM;
    T.fwd[1] = COMP_CORR_MAX_NM;
    T.rev[0] = COMP_CORR_MAX_NM;
    T.rev[1] = -COMP_CORR_MAX_NM;
    TEST_ASSERT_EQUAL_INT(COMP_OK, comp_table_check(&T));
    TEST_ASSERT_EQUAL_INT64(0, comp_correction(&T, 0, COMP_W_ONE));
    TEST_ASSERT_EQUAL_INT64(COMP_CORR_MAX_NM / 2,
                            comp_correction(&T, COMP_SPAN_MAX_NM / 4, COMP_W_ONE));
    TEST_ASSERT_EQUAL_INT64(-COMP_CORR_MAX_NM / 2,
                            comp_correction(&T, COMP_SPAN_MAX_NM / 4, -COMP_W_ONE));
    TEST_ASSERT_EQUAL_INT64(0, comp_correction(&T, COMP_SPAN_MAX_NM / 4, 0));
    /* w beyond +-1 is clamped */
    TEST_ASSERT_EQUAL_INT64(COMP_CORR_MAX_NM, comp_correction(&T, COMP_SPAN_MAX_NM, INT32_MAX));
}

/* ---- direction ramp --------------------------------------------------------- */

static void test_ramp_follows_commanded_direction(void)
{
    comp_ramp_t r;
    unsigned k;
    int32_t prev;
    comp_ramp_init(&r, 20000u, 10000u); /* 200 ticks for a full swing */
    TEST_ASSERT_EQUAL_INT32(0, r.w_q30);
    comp_ramp_step(&r, 0); /* no motion yet: stays at the mean */
    TEST_ASSERT_EQUAL_INT32(0, r.w_q30);
    for (k = 0; k < 99; k++) {
        comp_ramp_step(&r, 1000);
    }
    TEST_ASSERT_TRUE(r.w_q30 < COMP_W_ONE);
    comp_ramp_step(&r, 1000);
    TEST_ASSERT_EQUAL_INT32(COMP_W_ONE, r.w_q30);
    /* at rest the direction of approach is held */
    for (k = 0; k < 1000; k++) {
        comp_ramp_step(&r, 0);
    }
    TEST_ASSERT_EQUAL_INT32(COMP_W_ONE, r.w_q30);
    /* reversal: linear, monotonic, exactly 200 ticks */
    prev = r.w_q30;
    for (k = 0; k < 200; k++) {
        comp_ramp_step(&r, -5);
        TEST_ASSERT_TRUE(r.w_q30 < prev);
        TEST_ASSERT_TRUE((int64_t)prev - r.w_q30 <= (int64_t)r.step_q30);
        prev = r.w_q30;
    }
    TEST_ASSERT_EQUAL_INT32(-COMP_W_ONE, r.w_q30);
    /* a short reversal back and forth only moves part way */
    for (k = 0; k < 50; k++) {
        comp_ramp_step(&r, 7);
    }
    TEST_ASSERT_TRUE(r.w_q30 > -COMP_W_ONE && r.w_q30 < 0);
    /* ramp 0: switches in one tick */
    comp_ramp_set_time(&r, 0u, 10000u);
    comp_ramp_step(&r, -1);
    TEST_ASSERT_EQUAL_INT32(-COMP_W_ONE, r.w_q30);
    comp_ramp_step(&r, 1);
    TEST_ASSERT_EQUAL_INT32(COMP_W_ONE, r.w_q30);
}

static void test_reversal_correction_has_no_step(void)
{
    comp_ramp_t r;
    unsigned k;
    pos_nm_t x = -60000000; /* hysteresis 10 um there */
    int64_t prev, c, max_step = 0;
    table57(&T);
    comp_ramp_init(&r, T.ramp_us, 10000u);
    T.dir_src = &r;
    comp_ramp_step(&r, 100);
    for (k = 0; k < 300; k++) {
        comp_ramp_step(&r, 100);
    }
    prev = comp_correct(&T, x, COMP_DIR_NEG) - x; /* dir ignored: the source wins */
    TEST_ASSERT_EQUAL_INT64(T.fwd[1], prev);
    for (k = 0; k < 400; k++) {
        comp_ramp_step(&r, -100);
        c = comp_correct(&T, x, COMP_DIR_POS) - x;
        if (c - prev > max_step) {
            max_step = c - prev;
        }
        if (prev - c > max_step) {
            max_step = prev - c;
        }
        prev = c;
    }
    TEST_ASSERT_EQUAL_INT64(T.rev[1], prev);
    /* 10000 nm over 200 ticks: at most 50 nm (+1 rounding) per tick */
    TEST_ASSERT_TRUE(max_step <= 51);
    TEST_ASSERT_TRUE(max_step >= 49);
}

static void test_decoder_applies_table(void)
{
    static qdec_t q;
    qdec_config_t cfg;
    comp_ramp_t r;
    table57(&T);
    comp_ramp_init(&r, 0u, 10000u);
    T.dir_src = &r;
    qdec_config_default(&cfg);
    cfg.input = QDEC_INPUT_COUNTER;
    cfg.counter_bits = 32;
    cfg.nm_per_count_num = 1250;
    cfg.nm_per_count_den = 1;
    TEST_ASSERT_TRUE(qdec_init(&q, &cfg, 0u, 0u));
    qdec_set_comp(&q, &T);
    comp_ramp_step(&r, -1);
    /* -60 mm = -48000 counts, reached counting down */
    qdec_sample_counter(&q, (uint32_t)-48000, 100000u);
    TEST_ASSERT_EQUAL_INT64(-60000000, q.out.pos_nm_raw);
    TEST_ASSERT_EQUAL_INT64(-60000000 + 25000, q.out.pos_nm);
    comp_ramp_step(&r, 1);
    qdec_sample_counter(&q, (uint32_t)-48000, 200000u);
    TEST_ASSERT_EQUAL_INT64(-60000000 + 15000, q.out.pos_nm);
    qdec_set_comp(&q, NULL);
    qdec_sample_counter(&q, (uint32_t)-48000, 300000u);
    TEST_ASSERT_EQUAL_INT64(-60000000, q.out.pos_nm);
}

/* ---- record codec ------------------------------------------------------------ */

static uint8_t buf[COMP_RECORD_MAX + 16];
static comp_table_t U;

static void test_record_round_trip(void)
{
    size_t len;
    unsigned i;
    table57(&T);
    T.version = 7;
    len = comp_record_encode(&T, buf, sizeof buf);
    TEST_ASSERT_EQUAL_size_t(COMP_RECORD_HDR + 11 * COMP_POINT_BYTES, len);
    TEST_ASSERT_EQUAL_INT(COMP_OK, comp_record_decode(buf, len, &U));
    TEST_ASSERT_EQUAL_UINT16(11, U.n);
    TEST_ASSERT_EQUAL_UINT32(7, U.version);
    TEST_ASSERT_EQUAL_UINT32(20000, U.ramp_us);
    TEST_ASSERT_EQUAL_UINT8(1, U.axis);
    TEST_ASSERT_NULL(U.dir_src);
    TEST_ASSERT_EQUAL_UINT32(crc32_update(CRC32_INIT, buf + 32, len - 32), U.data_crc);
    for (i = 0; i < 11; i++) {
        TEST_ASSERT_EQUAL_INT64(T.pos[i], U.pos[i]);
        TEST_ASSERT_EQUAL_INT32(T.fwd[i], U.fwd[i]);
        TEST_ASSERT_EQUAL_INT32(T.rev[i], U.rev[i]);
    }
    /* a full table is exactly one record of COMP_RECORD_MAX bytes */
    memset(&T, 0, sizeof T);
    T.n = COMP_POINTS_MAX;
    for (i = 0; i < COMP_POINTS_MAX; i++) {
        T.pos[i] = (pos_nm_t)i * 1000;
    }
    TEST_ASSERT_EQUAL_size_t(COMP_RECORD_MAX, comp_record_encode(&T, buf, sizeof buf));
    TEST_ASSERT_EQUAL_size_t(0, comp_record_encode(&T, buf, COMP_RECORD_MAX - 1));
    T.pos[3] = T.pos[2];
    TEST_ASSERT_EQUAL_size_t(0, comp_record_encode(&T, buf, sizeof buf)); /* invalid */
}

static void test_record_every_corruption_refused(void)
{
    size_t len, i;
    unsigned bit;
    table57(&T);
    len = comp_record_encode(&T, buf, sizeof buf);
    for (i = 0; i < len; i++) {
        for (bit = 0; bit < 8; bit += 3) {
            buf[i] ^= (uint8_t)(1u << bit);
            memset(&U, 0x5A, sizeof U);
            TEST_ASSERT_NOT_EQUAL(COMP_OK, comp_record_decode(buf, len, &U));
            TEST_ASSERT_EQUAL_UINT8(0x5A, ((uint8_t *)&U)[0]); /* untouched */
            buf[i] ^= (uint8_t)(1u << bit);
        }
    }
    for (i = 0; i < len; i++) {
        TEST_ASSERT_NOT_EQUAL(COMP_OK, comp_record_decode(buf, i, &U)); /* truncated */
    }
    TEST_ASSERT_EQUAL_INT(COMP_OK, comp_record_decode(buf, len, &U));
    TEST_ASSERT_NOT_EQUAL(COMP_OK, comp_record_decode(buf, len + 1, &U));
}

/* ---- flash store -------------------------------------------------------------- */

static void test_store_layout(void)
{
    comp_store_layout_t lay;
    const hal_flash_layout_t *l = hal_flash_layout();
    TEST_ASSERT_TRUE(comp_store_layout(&lay));
    /* two banks of 16 KiB (8 pages) at the top 32 KiB (never the
     * bootloader's slot) */
    TEST_ASSERT_EQUAL_UINT32(16384, lay.bank_bytes);
    TEST_ASSERT_EQUAL_UINT32(l->base + l->size - 2u * 16384u, lay.base);
    TEST_ASSERT_EQUAL_UINT32(COMP_STORE_REGION_BYTES, comp_store_bytes());
    TEST_ASSERT_TRUE(lay.base >= l->base + l->size - COMP_STORE_REGION_BYTES);
    TEST_ASSERT_EQUAL_UINT32(lay.base, comp_store_bank_addr(0));
    TEST_ASSERT_EQUAL_UINT32(lay.base + 16384u, comp_store_bank_addr(1));
    TEST_ASSERT_EQUAL_UINT32(0, comp_store_bank_addr(2));
    TEST_ASSERT_EQUAL_UINT32(0, comp_store_record_addr(CORE_AXES));
    TEST_ASSERT_EQUAL_UINT32(0, comp_store_record_addr(0)); /* none yet */
    /* pages too large for the region (two banks > half of it): no layout,
     * writes refused */
    TEST_ASSERT_TRUE(flash_sim_configure(0x08000000u, 512u * 1024u, 262144u, 8u));
    TEST_ASSERT_FALSE(comp_store_layout(&lay));
    TEST_ASSERT_EQUAL_UINT32(0, comp_store_bytes());
    table57(&T);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_LAYOUT, comp_store_write(1, &T, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_LAYOUT, comp_store_load(1, &U, NULL));
}

static void test_store_versions_and_slots(void)
{
    uint32_t ver = 0;
    unsigned slot = 9;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_EMPTY, comp_store_load(1, &U, &slot));
    table57(&T);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &T, &ver, &slot));
    TEST_ASSERT_EQUAL_UINT32(1, ver);
    TEST_ASSERT_EQUAL_UINT(0, slot);
    T.fwd[0] = 1234;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &T, &ver, &slot));
    TEST_ASSERT_EQUAL_UINT32(2, ver);
    TEST_ASSERT_EQUAL_UINT(0, slot); /* appended to the log of bank 0 */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(1, &U, &slot));
    TEST_ASSERT_EQUAL_UINT32(2, U.version);
    TEST_ASSERT_EQUAL_INT32(1234, U.fwd[0]);
    TEST_ASSERT_EQUAL_UINT(0, slot);
    /* the third write goes to the same bank; the second stays as the previous */
    T.fwd[0] = 999;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &T, &ver, &slot));
    TEST_ASSERT_EQUAL_UINT(0, slot);
    TEST_ASSERT_EQUAL_UINT32(3, ver);
    /* other axes are independent */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_EMPTY, comp_store_load(0, &U, NULL));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_ARG, comp_store_write(0, &T, NULL, NULL)); /* axis 1 table */
    T.axis = 0;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(0, &T, &ver, NULL));
    TEST_ASSERT_EQUAL_UINT32(1, ver);
    /* clear: a valid empty table as the next version */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_clear(1, &ver));
    TEST_ASSERT_EQUAL_UINT32(4, ver);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(1, &U, NULL));
    TEST_ASSERT_EQUAL_UINT16(0, U.n);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_ARG, comp_store_load(CORE_AXES, &U, NULL));
}

static void test_store_corrupt_new_slot_falls_back(void)
{
    uint32_t ver;
    unsigned slot;
    table57(&T);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_ARG, comp_store_write(2, &T, NULL, NULL)); /* axis 1's */
    T.axis = 2;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(2, &T, &ver, &slot));
    T.rev[4] = -5;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(2, &T, &ver, &slot));
    TEST_ASSERT_EQUAL_UINT32(2, ver);
    /* a bit flips in the new record's data: the previous one is current */
    TEST_ASSERT_TRUE(flash_sim_poke(comp_store_record_addr(2) + 100u, 0x00));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(2, &U, &slot));
    TEST_ASSERT_EQUAL_UINT32(1, U.version);
    TEST_ASSERT_EQUAL_INT32(14000, U.rev[4]);
    /* and the next write is version 2 again, after the broken one; the good
     * one stays */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(2, &T, &ver, &slot));
    TEST_ASSERT_EQUAL_UINT32(2, ver);
    TEST_ASSERT_EQUAL_UINT(0, slot);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(2, &U, NULL));
    TEST_ASSERT_EQUAL_UINT32(2, U.version);
    TEST_ASSERT_EQUAL_INT32(-5, U.rev[4]);
}

static void test_store_power_cut_anywhere(void)
{
    /* cut the power after n flash bytes for every n over the whole write:
     * afterwards the store holds either the old table or the new one */
    long n;
    unsigned olds = 0, news = 0;
    for (n = 0; n < 2048 + 32 + 11 * 16 + 64; n += 7) {
        uint32_t ver;
        setUp();
        table57(&T);
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &T, &ver, NULL));
        T.fwd[2] = -777;
        flash_sim_power_cut_after(n);
        (void)comp_store_write(1, &T, &ver, NULL);
        flash_sim_power_cut_after(-1);
        flash_sim_power_on();
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(1, &U, NULL));
        if (U.version == 2) {
            TEST_ASSERT_EQUAL_INT32(-777, U.fwd[2]);
            news++;
        } else {
            TEST_ASSERT_EQUAL_UINT32(1, U.version);
            TEST_ASSERT_EQUAL_INT32(11000, U.fwd[2]);
            olds++;
        }
    }
    TEST_ASSERT_TRUE(olds > 0);
    TEST_ASSERT_TRUE(news > 0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_null_and_empty_are_identity);
    RUN_TEST(test_points_directions_and_ends);
    RUN_TEST(test_interpolation_matches_reference);
    RUN_TEST(test_check_limits);
    RUN_TEST(test_extreme_table_no_overflow);
    RUN_TEST(test_ramp_follows_commanded_direction);
    RUN_TEST(test_reversal_correction_has_no_step);
    RUN_TEST(test_decoder_applies_table);
    RUN_TEST(test_record_round_trip);
    RUN_TEST(test_record_every_corruption_refused);
    RUN_TEST(test_store_layout);
    RUN_TEST(test_store_versions_and_slots);
    RUN_TEST(test_store_corrupt_new_slot_falls_back);
    RUN_TEST(test_store_power_cut_anywhere);
    return UNITY_END();
}
