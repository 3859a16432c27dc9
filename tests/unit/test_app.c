/*
 * test_app.c - the composition root (app.h) as every target uses it: the
 * simulator builds the application through app_init, and the one handler
 * chain answers the dispatcher's, the calibration's and the bootloader's
 * ids over the serial link with no handler registered by anyone else.
 */
#include <string.h>

#include "app.h"
#include "boot_sim.h"
#include "hal_sim.h"
#include "proto_frame.h"
#include "proto_msgs.h"
#include "sim.h"
#include "unity.h"

static uint8_t seq;

void setUp(void)
{
    TEST_ASSERT_EQUAL_INT(0, sim_setup(10000.0, 3));
}

void tearDown(void)
{
}

static void start(int boot)
{
    TEST_ASSERT_EQUAL_INT(0, sim_set_link(4u, 1, 0, 0u, 0x010203u, 0xCAFEu, boot));
    TEST_ASSERT_EQUAL_INT(0, sim_start());
}

/* Send one request over the simulated UART, run the drive 2 ms, return the
 * first reply message (its length; 0 if none). */
static size_t request(uint8_t id, const uint8_t *payload, size_t n, uint8_t *reply)
{
    uint8_t m[PROTO_MSG_MAX], f[2 * PROTO_MSG_MAX + 8], rx[4096];
    proto_frame_rx_t fr;
    size_t flen, got, i;

    m[0] = id;
    m[1] = ++seq;
    if (n > 0u) {
        memcpy(m + 2, payload, n);
    }
    flen = proto_frame_encode(m, n + 2u, f, sizeof f);
    TEST_ASSERT_TRUE(flen > 0u);
    TEST_ASSERT_EQUAL_size_t(flen, hal_sim_uart_inject(f, flen));
    TEST_ASSERT_TRUE(sim_run(20, NULL, 0, 0) >= 0);
    got = hal_sim_uart_drain(rx, sizeof rx);
    proto_frame_rx_init(&fr);
    for (i = 0; i < got; i++) {
        const uint8_t *msg;
        size_t len;

        if (proto_frame_rx_byte(&fr, rx[i], &msg, &len) && len >= 2u && msg[1] == seq) {
            memcpy(reply, msg, len);
            return len;
        }
    }
    return 0;
}

static void test_identify_reports_the_board_through_app_init(void)
{
    uint8_t r[PROTO_MSG_MAX];
    proto_identify_reply_t id;
    size_t n;

    start(0);
    n = request(PROTO_MSG_IDENTIFY, NULL, 0, r);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_IDENTIFY_REPLY, r[0]);
    TEST_ASSERT_TRUE(proto_identify_reply_decode(r + 2, n - 2, &id));
    TEST_ASSERT_EQUAL_UINT8(4, id.node_id);
    TEST_ASSERT_EQUAL_UINT8(3, id.axes);
    TEST_ASSERT_EQUAL_HEX32(0x010203u, id.fw_version);
    TEST_ASSERT_EQUAL_HEX32(0xCAFEu, id.build_id);
    TEST_ASSERT_TRUE((id.capabilities & (1u << PROTO_CAPABILITY_CALIBRATION)) != 0u);
    TEST_ASSERT_TRUE((id.capabilities & (1u << PROTO_CAPABILITY_SIMULATED)) != 0u);
    TEST_ASSERT_FALSE((id.capabilities & (1u << PROTO_CAPABILITY_BOOTLOADER)) != 0u);
}

/* Calibration is reachable on every target: the chain is app_init's. */
static void test_calibration_ids_are_answered_by_the_calibration(void)
{
    uint8_t r[PROTO_MSG_MAX];

    start(0);
    TEST_ASSERT_TRUE(request(PROTO_MSG_CALIB_STATUS, NULL, 0, r) > 0u);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_CALIB_STATE, r[0]);
}

static void test_boot_enter_without_bootloader_and_unknown_ids_are_refused(void)
{
    uint8_t r[PROTO_MSG_MAX];
    proto_error_t e;
    size_t n;

    start(0);
    n = request(PROTO_MSG_BOOT_ENTER, (const uint8_t *)"\0\0\0\0", PROTO_BOOT_ENTER_LEN, r);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, r[0]);
    TEST_ASSERT_TRUE(proto_error_decode(r + 2, n - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_BOOT, e.code);
    TEST_ASSERT_FALSE(hal_sim_take_reset_request());
    n = request(0xC5u, NULL, 0, r);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ERROR, r[0]);
    TEST_ASSERT_TRUE(proto_error_decode(r + 2, n - 2, &e));
    TEST_ASSERT_EQUAL_UINT8(PROTO_ERROR_CODE_UNKNOWN_MESSAGE, e.code);
}

/* With the bootloader's slot: boot_enter acks, sets the request word and
 * resets once the ack has left the UART. */
static void test_boot_enter_acks_then_resets(void)
{
    uint8_t r[PROTO_MSG_MAX];

    TEST_ASSERT_TRUE(boot_sim_init(NULL, 4u, 0u));
    start(1);
    TEST_ASSERT_TRUE(
        request(PROTO_MSG_BOOT_ENTER, (const uint8_t *)"\0\0\0\0", PROTO_BOOT_ENTER_LEN, r) > 0u);
    TEST_ASSERT_EQUAL_HEX8(PROTO_MSG_ACK, r[0]);
    TEST_ASSERT_TRUE(sim_run(2, NULL, 0, 0) >= 0); /* the ack has left: reset */
    TEST_ASSERT_TRUE(hal_sim_take_reset_request());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_identify_reports_the_board_through_app_init);
    RUN_TEST(test_calibration_ids_are_answered_by_the_calibration);
    RUN_TEST(test_boot_enter_without_bootloader_and_unknown_ids_are_refused);
    RUN_TEST(test_boot_enter_acks_then_resets);
    return UNITY_END();
}
