/* CRCs: the standard check values, incremental use, and single-bit sensitivity. */
#include "crc.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

static const uint8_t check[] = "123456789";

static void test_crc32_check_value(void)
{
    TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, crc32_update(CRC32_INIT, check, 9));
    TEST_ASSERT_EQUAL_HEX32(0x00000000u, crc32_update(CRC32_INIT, check, 0));
}

static void test_crc32_incremental_equals_whole(void)
{
    uint32_t c = crc32_update(CRC32_INIT, check, 4);
    TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, crc32_update(c, check + 4, 5));
}

static void test_crc16_check_value(void)
{
    uint16_t c = crc16_update(CRC16_INIT, check, 3);
    TEST_ASSERT_EQUAL_HEX16(0x29B1u, crc16_update(CRC16_INIT, check, 9));
    TEST_ASSERT_EQUAL_HEX16(0x29B1u, crc16_update(c, check + 3, 6));
}

static void test_every_single_bit_flip_is_detected(void)
{
    uint8_t buf[64];
    unsigned i, bit;
    uint32_t ref32;
    uint16_t ref16;
    for (i = 0; i < sizeof buf; i++) {
        buf[i] = (uint8_t)(i * 37u + 11u);
    }
    ref32 = crc32_update(CRC32_INIT, buf, sizeof buf);
    ref16 = crc16_update(CRC16_INIT, buf, sizeof buf);
    for (bit = 0; bit < 8 * sizeof buf; bit++) {
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        TEST_ASSERT_NOT_EQUAL(ref32, crc32_update(CRC32_INIT, buf, sizeof buf));
        TEST_ASSERT_NOT_EQUAL(ref16, crc16_update(CRC16_INIT, buf, sizeof buf));
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_crc32_check_value);
    RUN_TEST(test_crc32_incremental_equals_whole);
    RUN_TEST(test_crc16_check_value);
    RUN_TEST(test_every_single_bit_flip_is_detected);
    return UNITY_END();
}
