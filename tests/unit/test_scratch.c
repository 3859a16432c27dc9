/*
 * The main-context scratch area (scratch.h): one holder at a time, a nested
 * claim fails by name instead of sharing the bytes silently, and every user
 * on the simulated drive (calib_init's table load, comp_store_clear, the
 * servo probe, param_store's save and load) gives it back.
 */
#include "calib.h"
#include "comp.h"
#include "comp_store.h"
#include "drive.h"
#include "hal_flash_sim.h"
#include "param_store.h"
#include "scratch.h"
#include "sim.h"
#include "unity.h"

static void boot(void)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
}

void setUp(void)
{
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
    boot();
}

void tearDown(void)
{
}

static void test_claim_is_exclusive(void)
{
    uint32_t c = scratch_collisions();
    void *p = scratch_claim(SCRATCH_TEST, 16);
    TEST_ASSERT_NOT_NULL(p);
    TEST_ASSERT_EQUAL_INT(SCRATCH_TEST, scratch_owner());
    TEST_ASSERT_NULL(scratch_claim(SCRATCH_CALIB, 16));
    TEST_ASSERT_EQUAL_UINT32(c + 1u, scratch_collisions());
    scratch_release(SCRATCH_CALIB); /* not the holder: counted, ignored */
    TEST_ASSERT_EQUAL_INT(SCRATCH_TEST, scratch_owner());
    TEST_ASSERT_EQUAL_UINT32(c + 2u, scratch_collisions());
    scratch_release(SCRATCH_TEST);
    TEST_ASSERT_EQUAL_INT(SCRATCH_FREE, scratch_owner());
    TEST_ASSERT_NULL(scratch_claim(SCRATCH_TEST, scratch_bytes() + 1u));
    TEST_ASSERT_EQUAL_PTR(p, scratch_claim(SCRATCH_TEST, scratch_bytes()));
    scratch_release(SCRATCH_TEST);
    TEST_ASSERT_TRUE(scratch_bytes() >= sizeof(comp_table_t));
    TEST_ASSERT_TRUE(scratch_bytes() >= sizeof(servo_t));
}

/* A user called while the area is held fails with its own error. */
static void test_nested_users_refuse(void)
{
    servo_params_t p = drive_config()->servo;
    uint32_t detail = 0;
    TEST_ASSERT_NOT_NULL(scratch_claim(SCRATCH_TEST, 16));
    TEST_ASSERT_EQUAL_INT(COMP_STORE_E_BUSY, comp_store_clear(0, NULL));
    TEST_ASSERT_EQUAL_INT(DRIVE_E_INVALID, drive_set_servo_params(&p));
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_E_FLASH, param_store_save(NULL, &detail));
    TEST_ASSERT_EQUAL_UINT32(COMP_STORE_E_BUSY, detail);
    scratch_release(SCRATCH_TEST);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_clear(0, NULL));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_set_servo_params(&p));
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
}

/* Every user on the drive claims and releases: no collision, area free. */
static void test_every_user_gives_it_back(void)
{
    static comp_table_t t;
    uint32_t c = scratch_collisions();
    int64_t kp = 0;
    unsigned i;
    t.axis = 1;
    t.n = 3;
    for (i = 0; i < 3u; i++) {
        t.pos[i] = (pos_nm_t)i * 1000000;
        t.fwd[i] = (int32_t)i * 100;
        t.rev[i] = -(int32_t)i * 100;
    }
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_write(1, &t, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_get(DRIVE_PARAM_KP, 0, &kp));
    TEST_ASSERT_EQUAL_INT(DRIVE_OK, drive_param_set(DRIVE_PARAM_KP, 0, kp + 1)); /* probe */
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_OK, param_store_save(NULL, NULL));
    boot(); /* calib_init loads the table, param_store loads the blob */
    TEST_ASSERT_EQUAL_INT(PARAM_STORE_LOADED, param_store_status());
    TEST_ASSERT_NOT_NULL(calib_comp_active(1));
    TEST_ASSERT_EQUAL_UINT16(3, calib_comp_active(1)->n);
    TEST_ASSERT_EQUAL_INT(COMP_STORE_OK, comp_store_clear(1, NULL));
    TEST_ASSERT_EQUAL_INT(SCRATCH_FREE, scratch_owner());
    TEST_ASSERT_EQUAL_UINT32(c, scratch_collisions());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_claim_is_exclusive);
    RUN_TEST(test_nested_users_refuse);
    RUN_TEST(test_every_user_gives_it_back);
    return UNITY_END();
}
