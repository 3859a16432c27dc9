/*
 * Compensation store (comp_store.h) on small pages (the simulated drive:
 * 2 KiB) and on STM32F4 sectors (128 KiB, 4-byte write unit): bank
 * placement, log appends, compaction carrying every axis's current table
 * over, alternating banks, and simulated power cuts at every step of an
 * append and of a compaction (erase or program interrupted), after which
 * every axis holds its previous or (the written axis only) its new table,
 * and the next write succeeds.
 */
#include "comp.h"
#include "comp_store.h"
#include "hal.h"
#include "hal_flash_sim.h"
#include "unity.h"

#include <string.h>

/* STM32F4 HAL region (docs/ports.md): sectors 5..11 at 0x08020000. */
#define F4_BASE   0x08020000u
#define F4_SIZE   (7u * 131072u)
#define F4_SECTOR 131072u

static comp_table_t T, U; /* 2 KiB each: static, not on the stack */
static uint32_t ver[CORE_AXES];
static int32_t seed[CORE_AXES];
static uint8_t snap[2u * F4_SECTOR];

static void small_pages(void)
{
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
}

static void f4_sectors(void)
{
    TEST_ASSERT_TRUE(flash_sim_configure(F4_BASE, F4_SIZE, F4_SECTOR, 4u));
}

void setUp(void)
{
    small_pages();
    memset(ver, 0, sizeof ver);
    memset(seed, 0, sizeof seed);
}

void tearDown(void)
{
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
}

/* A table of n points for axis a whose content depends on s. */
static void make(comp_table_t *t, unsigned a, int32_t s, uint16_t n)
{
    uint16_t i;
    memset(t, 0, sizeof *t);
    t->axis = (uint8_t)a;
    t->n = n;
    t->ramp_us = 20000u;
    for (i = 0; i < n; i++) {
        t->pos[i] = (pos_nm_t)i * 1000000 - 50000000;
        t->fwd[i] = (s + i) % 900000;
        t->rev[i] = -((s + 3 * i) % 900000);
    }
    TEST_ASSERT_EQUAL_INT(COMP_OK, comp_table_check(t));
}

/* Write a full table for axis a with a new seed; track the version. */
static unsigned put(unsigned a, int32_t s)
{
    uint32_t v = 0;
    unsigned bank = 9;
    make(&T, a, s, COMP_POINTS_MAX);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(a, &T, &v, &bank));
    TEST_ASSERT_EQUAL_UINT32(ver[a] + 1u, v);
    ver[a] = v;
    seed[a] = s;
    return bank;
}

/* Axis a's current table is version v with seed s. */
static void expect(unsigned a, uint32_t v, int32_t s)
{
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(a, &U, NULL));
    TEST_ASSERT_EQUAL_UINT32(v, U.version);
    make(&T, a, s, COMP_POINTS_MAX);
    TEST_ASSERT_EQUAL_UINT16(T.n, U.n);
    TEST_ASSERT_EQUAL_MEMORY(T.pos, U.pos, sizeof T.pos);
    TEST_ASSERT_EQUAL_MEMORY(T.fwd, U.fwd, sizeof T.fwd);
    TEST_ASSERT_EQUAL_MEMORY(T.rev, U.rev, sizeof T.rev);
    TEST_ASSERT_NULL(U.dir_src);
}

static void expect_all(void)
{
    unsigned a;
    for (a = 0; a < CORE_AXES; a++) {
        expect(a, ver[a], seed[a]);
    }
}

static void test_f4_layout_is_sectors_10_and_11(void)
{
    comp_store_layout_t lay;
    f4_sectors();
    TEST_ASSERT_TRUE(comp_store_layout(&lay));
    TEST_ASSERT_EQUAL_UINT32(F4_SECTOR, lay.bank_bytes);
    TEST_ASSERT_EQUAL_UINT32(0x080C0000u, lay.base);                /* sector 10 */
    TEST_ASSERT_EQUAL_UINT32(0x080E0000u, comp_store_bank_addr(1)); /* sector 11 */
    TEST_ASSERT_EQUAL_UINT32(2u * F4_SECTOR, comp_store_bytes());
    /* the application slot of the port (sectors 5..9) ends where it starts */
    TEST_ASSERT_EQUAL_UINT32(F4_BASE + 5u * F4_SECTOR, lay.base);
    /* simulated drive: the top 32 KiB, two banks of 8 pages */
    small_pages();
    TEST_ASSERT_TRUE(comp_store_layout(&lay));
    TEST_ASSERT_EQUAL_UINT32(FLASH_SIM_DEFAULT_BASE + FLASH_SIM_DEFAULT_SIZE - 32768u, lay.base);
    TEST_ASSERT_EQUAL_UINT32(16384u, lay.bank_bytes);
    /* write unit that does not divide the header cell: refused */
    TEST_ASSERT_TRUE(flash_sim_configure(F4_BASE, F4_SIZE, F4_SECTOR, 128u));
    TEST_ASSERT_FALSE(comp_store_layout(&lay));
}

/* Writes append into one bank until it is full, then all axes move to the
 * other bank (compaction), alternately, with every table kept. */
static void run_compactions(uint32_t bank_bytes)
{
    unsigned a, bank, last = 0, switches = 0, in_bank = 0;
    uint32_t erases0;
    int32_t s = 1;
    const uint32_t per_bank = (bank_bytes - 64u) / COMP_RECORD_MAX;
    for (a = 0; a < CORE_AXES; a++) {
        TEST_ASSERT_EQUAL_INT(COMP_STORE_EMPTY, comp_store_load(a, &U, NULL));
        TEST_ASSERT_EQUAL_UINT(0, put(a, s++));
    }
    in_bank = CORE_AXES;
    flash_sim_stats_reset();
    erases0 = 0;
    while (switches < 3) {
        bank = put(1, s++);
        if (bank != last) {
            /* a full bank: exactly when no further full record fits */
            TEST_ASSERT_EQUAL_UINT32(per_bank, in_bank);
            TEST_ASSERT_EQUAL_UINT32(erases0 + bank_bytes / hal_flash_layout()->page_size,
                                     flash_sim_stats()->erases);
            erases0 = flash_sim_stats()->erases;
            switches++;
            in_bank = CORE_AXES; /* the new one + the other axes' copies */
            last = bank;
            expect_all();
        } else {
            in_bank++;
            TEST_ASSERT_EQUAL_UINT32(erases0,
                                     flash_sim_stats()->erases); /* appends erase nothing */
        }
    }
    expect_all();
    /* clear one axis: an empty table is its current one, the others stay */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_clear(0, &ver[0]));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(0, &U, NULL));
    TEST_ASSERT_EQUAL_UINT16(0, U.n);
    expect(2, ver[2], seed[2]);
}

static void test_compaction_small_pages(void)
{
    run_compactions(16384u);
}

static void test_compaction_f4_sectors(void)
{
    f4_sectors();
    run_compactions(F4_SECTOR);
}

/* Snapshot / restore of the whole store region through the HAL. */
static void snapshot(void)
{
    TEST_ASSERT_TRUE(hal_flash_read(comp_store_bank_addr(0), snap, comp_store_bytes()));
}

static void restore(void)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint32_t base = comp_store_bank_addr(0), n = comp_store_bytes(), off, i;
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
    for (off = 0; off < n; off += l->page_size) {
        TEST_ASSERT_TRUE(hal_flash_erase_page(base + off));
    }
    for (off = 0; off < n; off += l->write_size) {
        for (i = 0; i < l->write_size && snap[off + i] == 0xFFu; i++) {
        }
        if (i < l->write_size) {
            TEST_ASSERT_TRUE(hal_flash_write(base + off, snap + off, l->write_size));
        }
    }
}

/* Cut the power after n flash byte operations of the next write of axis 1,
 * for n over the whole write (stride `erase_step` inside the erase, every
 * `prog_step`-th byte while programming, every byte of the last 80), then
 * check every axis and that the store still takes a write. */
static void cut_everywhere(long erase_step, long prog_step)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint32_t v0[CORE_AXES];
    int32_t s0[CORE_AXES];
    long total, erase_ops, n;
    unsigned a, olds = 0, news = 0;
    uint32_t v;
    snapshot();
    memcpy(v0, ver, sizeof v0);
    memcpy(s0, seed, sizeof s0);
    /* the uninterrupted write: how many byte operations it takes */
    flash_sim_stats_reset();
    (void)put(1, 777);
    erase_ops = (long)flash_sim_stats()->erases * (long)l->page_size;
    total = erase_ops + (long)flash_sim_stats()->bytes;
    for (n = 0; n < total; n += (n < erase_ops ? erase_step : (n >= total - 80 ? 1 : prog_step))) {
        restore();
        flash_sim_power_cut_after(n);
        make(&T, 1, 777, COMP_POINTS_MAX);
        TEST_ASSERT_NOT_EQUAL(COMP_STORE_OK, comp_store_write(1, &T, &v, NULL));
        flash_sim_power_cut_after(-1);
        flash_sim_power_on();
        for (a = 0; a < CORE_AXES; a++) {
            if (a != 1) {
                expect(a, v0[a], s0[a]);
            }
        }
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(1, &U, NULL));
        if (U.version == v0[1] + 1u) {
            expect(1, v0[1] + 1u, 777);
            news++;
        } else {
            expect(1, v0[1], s0[1]);
            olds++;
        }
        /* after the reset the store takes the next table */
        make(&T, 1, 4242, COMP_POINTS_MAX);
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &T, &v, NULL));
        TEST_ASSERT_TRUE(v == v0[1] + 1u || v == v0[1] + 2u);
        expect(1, v, 4242);
        for (a = 0; a < CORE_AXES; a++) {
            if (a != 1) {
                expect(a, v0[a], s0[a]);
            }
        }
    }
    TEST_ASSERT_TRUE(olds > 0);
    TEST_ASSERT_TRUE(news > 0 || erase_ops > 0); /* a compaction commits with its last byte */
}

/* Fill the active bank so that the next full-size write compacts. */
static void fill_to_compaction(uint32_t bank_bytes)
{
    unsigned a, n;
    int32_t s = 100;
    for (a = 0; a < CORE_AXES; a++) {
        (void)put(a, s++);
    }
    for (n = CORE_AXES; n < (bank_bytes - 64u) / COMP_RECORD_MAX; n++) {
        TEST_ASSERT_EQUAL_UINT(0, put(2, s++));
    }
}

static void test_power_cut_during_compaction_small_pages(void)
{
    fill_to_compaction(16384u);
    cut_everywhere(61, 3);
}

static void test_power_cut_during_compaction_f4_sectors(void)
{
    f4_sectors();
    fill_to_compaction(F4_SECTOR);
    cut_everywhere(4093, 11);
}

static void test_power_cut_during_append_f4_sectors(void)
{
    unsigned a;
    f4_sectors();
    for (a = 0; a < CORE_AXES; a++) {
        (void)put(a, 10 + (int32_t)a);
    }
    cut_everywhere(1, 1);
}

static void test_power_cut_during_first_write(void)
{
    /* empty flash: the first write creates bank 0; a cut leaves nothing or
     * the new table, never an error other than EMPTY */
    long n;
    uint32_t v;
    for (n = 0; n < 16384 + 2048 + 64; n += 37) {
        small_pages();
        flash_sim_power_cut_after(n);
        make(&T, 0, 5, COMP_POINTS_MAX);
        (void)comp_store_write(0, &T, &v, NULL);
        flash_sim_power_cut_after(-1);
        flash_sim_power_on();
        if (comp_store_load(0, &U, NULL) != COMP_STORE_EMPTY) {
            expect(0, 1, 5);
        }
        TEST_ASSERT_EQUAL_INT(COMP_STORE_EMPTY, comp_store_load(1, &U, NULL));
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(0, &T, &v, NULL));
        expect(0, v, 5);
    }
}

static void test_dirty_log_end_compacts(void)
{
    /* garbage at the end of the log (a half-programmed record header): the
     * next write does not program over it but moves to the other bank */
    unsigned a;
    uint32_t end;
    for (a = 0; a < CORE_AXES; a++) {
        (void)put(a, 20 + (int32_t)a);
    }
    end = comp_store_record_addr(2) + COMP_RECORD_MAX;
    TEST_ASSERT_TRUE(flash_sim_poke(end + 3u, 0x12));
    flash_sim_stats_reset();
    TEST_ASSERT_EQUAL_UINT(1, put(0, 30));
    TEST_ASSERT_EQUAL_UINT32(0, flash_sim_stats()->violations);
    expect_all();
    TEST_ASSERT_EQUAL_UINT32(comp_store_bank_addr(1) + 64u, comp_store_record_addr(0));
}

static void test_programmed_bytes_past_log_end_compact(void)
{
    /* the log ends cleanly (an erased header cell) but a byte further on is
     * programmed (e.g. an erase that did not complete on real flash): the
     * append is not attempted over it, the write moves to the other bank */
    unsigned a;
    uint32_t end;
    for (a = 0; a < CORE_AXES; a++) {
        (void)put(a, 40 + (int32_t)a);
    }
    end = comp_store_record_addr(2) + COMP_RECORD_MAX;
    TEST_ASSERT_TRUE(flash_sim_poke(end + 1000u, 0x00));
    flash_sim_stats_reset();
    TEST_ASSERT_EQUAL_UINT(1, put(1, 50));
    TEST_ASSERT_EQUAL_UINT32(0, flash_sim_stats()->violations);
    expect_all();
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_f4_layout_is_sectors_10_and_11);
    RUN_TEST(test_compaction_small_pages);
    RUN_TEST(test_compaction_f4_sectors);
    RUN_TEST(test_power_cut_during_compaction_small_pages);
    RUN_TEST(test_power_cut_during_compaction_f4_sectors);
    RUN_TEST(test_power_cut_during_append_f4_sectors);
    RUN_TEST(test_power_cut_during_first_write);
    RUN_TEST(test_dirty_log_end_compacts);
    RUN_TEST(test_programmed_bytes_past_log_end_compact);
    return UNITY_END();
}
