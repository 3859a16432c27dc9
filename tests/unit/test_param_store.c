/*
 * Saved drive parameters (param_store.h) on the simulated drive's flash:
 * save while disabled only, load at start-up (sim_start -> app_init) all or
 * nothing, a damaged record, another format or parameter count, another axis
 * count and a refused value each leave the defaults and say why; the blob
 * and the compensation tables carry each other over a compaction; a power
 * cut at any byte of a save leaves the old or the new set, whole.
 */
#include <string.h>

#include "comp.h"
#include "comp_store.h"
#include "drive.h"
#include "hal.h"
#include "hal_flash_sim.h"
#include "param_store.h"
#include "sim.h"
#include "unity.h"

static uint8_t buf[COMP_STORE_BLOB_MAX];
static comp_table_t T;

static void boot(unsigned axes)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, (int)axes));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
}

void setUp(void)
{
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
    boot(3);
}

void tearDown(void)
{
    flash_sim_power_cut_after(-1);
    flash_sim_power_on();
}

static int64_t get(drive_param_t id, unsigned axis)
{
    int64_t v = 0;
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(id, axis, &v));
    return v;
}

/* A set of changes that differ from every default (the exact-stop corner
 * rule: the smoothed one is refused with the continuous S-curve). */
static void change(int64_t k)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_V_MAX, 1, 250000000 + k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_KP, 2, ((int64_t)700 << 32) + k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_FERR_LIMIT, 0, 123456 + k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SOFT_MIN, 0, -5000000 - k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_SOFT_MAX, 0, 7000000 + k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_IN_POS, 2, 2500 + k));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_CORNER, 0, 3));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK,
                          drive_param_set(DRIVE_PARAM_CEC_KP, 0, ((int64_t)30 << 32) + k));
}

static bool changed(int64_t k)
{
    return get(DRIVE_PARAM_V_MAX, 1) == 250000000 + k &&
           get(DRIVE_PARAM_KP, 2) == ((int64_t)700 << 32) + k &&
           get(DRIVE_PARAM_FERR_LIMIT, 0) == 123456 + k &&
           get(DRIVE_PARAM_SOFT_MIN, 0) == -5000000 - k &&
           get(DRIVE_PARAM_SOFT_MAX, 0) == 7000000 + k && get(DRIVE_PARAM_IN_POS, 2) == 2500 + k &&
           get(DRIVE_PARAM_CORNER, 0) == 3 && get(DRIVE_PARAM_CEC_KP, 0) == ((int64_t)30 << 32) + k;
}

/* Nothing of the saved set in use: the defaults of a fresh start. */
static bool defaults(void)
{
    return get(DRIVE_PARAM_V_MAX, 1) != 250000000 && get(DRIVE_PARAM_FERR_LIMIT, 0) != 123456 &&
           get(DRIVE_PARAM_SOFT_MAX, 0) == 0 && get(DRIVE_PARAM_IN_POS, 0) == DRIVE_IN_POS_NM &&
           get(DRIVE_PARAM_CORNER, 0) == 0;
}

/* The CEC's gains are servo parameters of the path (one set): they reach
 * the servo configuration, the CEC mode stays, an axis index is refused. */
static void test_cec_gains_are_servo_parameters(void)
{
    const drive_config_t *c = drive_config();
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_cec_mode(DRIVE_CEC_TANGENT));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_CEC_KP, 0, (int64_t)24 << 32));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_CEC_KI, 0, 0));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_CEC_KD, 0, (int64_t)1 << 30));
    TEST_ASSERT_TRUE(c->servo.cec.pid.kp == (int64_t)24 << 32);
    TEST_ASSERT_TRUE(c->servo.cec.pid.ki == 0);
    TEST_ASSERT_TRUE(c->servo.cec.pid.kd == (int64_t)1 << 30);
    TEST_ASSERT_TRUE(get(DRIVE_PARAM_CEC_KP, 0) == (int64_t)24 << 32);
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_CEC_KP, 1, 0));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_param_set(DRIVE_PARAM_CEC_KP, 0, -1));
}

static void test_saved_parameters_survive_a_restart(void)
{
    uint32_t v = 0;
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_NONE, param_store_status());
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(&v, NULL));
    TEST_ASSERT_EQUAL_UINT32(1, v);
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
    TEST_ASSERT_TRUE(changed(0));
    /* the servo copy in use too (the gains request) */
    TEST_ASSERT_EQUAL_INT64(((int64_t)700 << 32), drive_config()->servo.axis[2].kp);
    TEST_ASSERT_EQUAL_INT32(123456, drive_config()->servo.ferr_limit_nm[0]);
}

/* CANopen 0x1011 "load": a record without parameters, so the next start
 * keeps the defaults; refused while enabled like a save. */
static void test_saved_defaults_give_the_defaults_at_the_next_start(void)
{
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    change(1);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save_defaults(NULL, NULL));
    TEST_ASSERT_TRUE(changed(1)); /* in use until the next start */
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
    TEST_ASSERT_TRUE(defaults());
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_E_STATE, param_store_save_defaults(NULL, NULL));
}

static void test_save_only_while_disabled(void)
{
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_enable(true));
    TEST_ASSERT_TRUE(sim_run(10, NULL, 0, 0) >= 0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_E_STATE, param_store_save(NULL, NULL));
    TEST_ASSERT_EQUAL_UINT32(0, comp_store_bank_addr(0) != 0 ? 0 : 1);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_EMPTY,
                          comp_store_blob_load(buf, sizeof buf, &(uint16_t){0}, NULL));
}

static void test_damaged_record_is_ignored_and_reported(void)
{
    uint16_t len = 0;
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_load(buf, sizeof buf, &len, NULL));
    /* flip one data byte of the record (after the 64-byte bank header and
     * the 32-byte record header) */
    TEST_ASSERT_TRUE(flash_sim_poke(comp_store_bank_addr(0) + 64u + 32u + 20u, 0x5A));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_CORRUPT, param_store_status());
    TEST_ASSERT_TRUE(defaults());
}

static void test_damaged_newest_falls_back_to_the_previous_save(void)
{
    uint32_t a2;
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    change(10);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    /* the second record follows the first: damage its data */
    a2 = comp_store_bank_addr(0) + 64u;
    a2 +=
        (32u + (uint32_t)((param_store_encode(buf, sizeof buf) + 15u) / 16u) * 16u + 7u) / 8u * 8u;
    TEST_ASSERT_TRUE(hal_flash_read(a2 + 32u + 40u, buf, 1));
    TEST_ASSERT_TRUE(flash_sim_poke(a2 + 32u + 40u, (uint8_t)~buf[0]));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
    TEST_ASSERT_TRUE(changed(0));
}

static void test_other_format_axes_or_value_leave_the_defaults(void)
{
    uint16_t len;
    change(0);
    len = param_store_encode(buf, sizeof buf);
    TEST_ASSERT_TRUE(len > 12u);

    buf[4] = PARAM_STORE_FORMAT + 1u; /* a later format */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_write(buf, len, NULL));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_VERSION, param_store_status());
    TEST_ASSERT_TRUE(defaults());

    buf[4] = PARAM_STORE_FORMAT;
    buf[7] = (uint8_t)(DRIVE_PARAM_COUNT - 1); /* a firmware with fewer parameters */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_write(buf, len, NULL));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_VERSION, param_store_status());
    TEST_ASSERT_TRUE(defaults());

    buf[7] = (uint8_t)DRIVE_PARAM_COUNT;
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_write(buf, len, NULL));
    boot(2);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_AXES, param_store_status());
    TEST_ASSERT_TRUE(defaults());

    /* the last entry (ffl_rate) -1, out of range: nothing of the set is
     * applied */
    memset(buf + len - 8u, 0xff, 8u);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_write(buf, len, NULL));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_REFUSED, param_store_status());
    TEST_ASSERT_TRUE(defaults());

    /* a length that does not match the entry count */
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_blob_write(buf, (uint16_t)(len - 3u), NULL));
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_CORRUPT, param_store_status());
    TEST_ASSERT_TRUE(defaults());
}

/* A compensation table of n points for axis a. */
static void table(unsigned a, int32_t s)
{
    uint16_t i;
    memset(&T, 0, sizeof T);
    T.axis = (uint8_t)a;
    T.n = COMP_POINTS_MAX;
    for (i = 0; i < T.n; i++) {
        T.pos[i] = (pos_nm_t)i * 1000000 - 50000000;
        T.fwd[i] = (s + i) % 900000;
        T.rev[i] = -((s + 3 * i) % 900000);
    }
}

static void test_compaction_carries_blob_and_tables(void)
{
    uint32_t v = 0;
    unsigned bank = 9, k;
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    /* comp tables until the log moves to bank 1 */
    for (k = 0; k < 12u && bank != 1u; k++) {
        table(k % 3u, (int32_t)k);
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(k % 3u, &T, &v, &bank));
    }
    TEST_ASSERT_EQUAL_UINT(1, bank);
    boot(3);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
    TEST_ASSERT_TRUE(changed(0));
    /* saves until the log moves back to bank 0: the tables stay */
    for (k = 0; k < 40u && comp_store_record_addr(0) >= comp_store_bank_addr(1); k++) {
        change((int64_t)k + 1);
        TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    }
    TEST_ASSERT_TRUE(comp_store_record_addr(0) < comp_store_bank_addr(1));
    boot(3);
    TEST_ASSERT_TRUE(changed((int64_t)k));
    for (bank = 0; bank < 3u; bank++) {
        TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_load(bank, &T, NULL));
        TEST_ASSERT_EQUAL_UINT16(COMP_POINTS_MAX, T.n);
    }
}

static void test_power_cut_during_save_keeps_one_whole_set(void)
{
    long n, total;
    unsigned olds = 0, news = 0;
    change(0);
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    change(5);
    flash_sim_stats_reset();
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    total = (long)flash_sim_stats()->bytes;
    TEST_ASSERT_EQUAL_UINT32(0, flash_sim_stats()->erases); /* an append */
    for (n = 0; n < total; n++) {
        TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                             FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
        boot(3);
        change(0);
        TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
        change(5);
        flash_sim_power_cut_after(n);
        TEST_ASSERT_NOT_EQUAL(PARAM_STORE_OK, param_store_save(NULL, NULL));
        flash_sim_power_cut_after(-1);
        flash_sim_power_on();
        boot(3);
        TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
        if (changed(5)) {
            news++;
        } else {
            TEST_ASSERT_TRUE(changed(0));
            olds++;
        }
    }
    TEST_ASSERT_TRUE(olds > 0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cec_gains_are_servo_parameters);
    RUN_TEST(test_saved_parameters_survive_a_restart);
    RUN_TEST(test_saved_defaults_give_the_defaults_at_the_next_start);
    RUN_TEST(test_save_only_while_disabled);
    RUN_TEST(test_damaged_record_is_ignored_and_reported);
    RUN_TEST(test_damaged_newest_falls_back_to_the_previous_save);
    RUN_TEST(test_other_format_axes_or_value_leave_the_defaults);
    RUN_TEST(test_compaction_carries_blob_and_tables);
    RUN_TEST(test_power_cut_during_save_keeps_one_whole_set);
    return UNITY_END();
}
