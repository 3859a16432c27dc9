/* ISO-TP: two instances talk to each other through a captured frame list
 * (the drive's and, mirrored, a host's); segmentation, flow control, block
 * size, STmin and every error path counted without wedging. */
#include <string.h>

#include "proto_isotp.h"
#include "unity.h"

void setUp(void)
{
}

void tearDown(void)
{
}

#define REQ 0x081u
#define RSP 0x0C1u

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t d[8];
} frame_t;

static frame_t q[600];
static unsigned qn;
static bool refuse_tx;

static bool cap_tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    if (refuse_tx || qn >= 600) {
        return false;
    }
    q[qn].id = id;
    q[qn].len = len;
    memcpy(q[qn].d, data, len);
    qn++;
    return true;
}

static proto_isotp_t drive, host;
static uint8_t got[PROTO_ISOTP_MAX];
static size_t got_len;
static unsigned got_n;

/* Deliver every queued frame to the instance listening on its id. */
static void pump(uint32_t now)
{
    unsigned guard;

    for (guard = 0; guard < 100; guard++) {
        unsigned i, n;

        proto_isotp_poll(&drive, now, cap_tx, NULL);
        proto_isotp_poll(&host, now, cap_tx, NULL);
        if (qn == 0) {
            return;
        }
        n = qn;
        for (i = 0; i < n; i++) {
            proto_isotp_t *to = q[i].id == REQ ? &drive : &host;
            const uint8_t *m;
            size_t len;

            if (proto_isotp_rx(to, q[i].d, q[i].len, now, &m, &len)) {
                memcpy(got, m, len);
                got_len = len;
                got_n++;
            }
        }
        memmove(q, q + n, (qn - n) * sizeof q[0]);
        qn -= n;
    }
}

static void reset(void)
{
    proto_isotp_init(&drive, REQ, RSP);
    proto_isotp_init(&host, RSP, REQ);
    qn = 0;
    got_n = 0;
    refuse_tx = false;
}

static void test_every_length_both_ways(void)
{
    uint8_t msg[PROTO_ISOTP_MAX];
    size_t len, i;

    reset();
    for (len = 1; len <= PROTO_ISOTP_MAX; len++) {
        for (i = 0; i < len; i++) {
            msg[i] = (uint8_t)(i * 7u + len);
        }
        got_n = 0;
        TEST_ASSERT_TRUE(proto_isotp_send(&host, msg, len, 0));
        pump(0);
        TEST_ASSERT_EQUAL_UINT(1, got_n);
        TEST_ASSERT_EQUAL_size_t(len, got_len);
        TEST_ASSERT_EQUAL_MEMORY(msg, got, len);
        got_n = 0;
        TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, len, 0));
        pump(0);
        TEST_ASSERT_EQUAL_UINT(1, got_n);
        TEST_ASSERT_EQUAL_MEMORY(msg, got, len);
    }
    TEST_ASSERT_EQUAL_UINT32(0, drive.stats.rx_errors + host.stats.rx_errors);
    TEST_ASSERT_FALSE(proto_isotp_send(&drive, msg, 0, 0));
    TEST_ASSERT_FALSE(proto_isotp_send(&drive, msg, PROTO_ISOTP_MAX + 1, 0));
}

static void test_frame_layout_single_and_first(void)
{
    uint8_t msg[20] = {1, 2, 3};

    reset();
    TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, 3, 0));
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn);
    TEST_ASSERT_EQUAL_HEX32(RSP, q[0].id);
    TEST_ASSERT_EQUAL_UINT8(4, q[0].len);
    TEST_ASSERT_EQUAL_HEX8(0x03, q[0].d[0]);
    qn = 0;
    TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, 20, 0));
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn); /* first frame, then waits for flow control */
    TEST_ASSERT_EQUAL_HEX8(0x10, q[0].d[0]);
    TEST_ASSERT_EQUAL_HEX8(20, q[0].d[1]);
    TEST_ASSERT_TRUE(proto_isotp_busy(&drive));
}

static void test_block_size_and_stmin_are_honoured(void)
{
    uint8_t msg[100];
    const uint8_t fc[3] = {0x30, 2, 5}; /* BS 2, STmin 5 ms */
    const uint8_t *m;
    size_t len;

    memset(msg, 0xAB, sizeof msg);
    reset();
    TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, sizeof msg, 0));
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    qn = 0;
    proto_isotp_rx(&drive, fc, 3, 0, &m, &len);
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn); /* one CF, next after STmin */
    proto_isotp_poll(&drive, 4000, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn);
    proto_isotp_poll(&drive, 5000, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(2, qn);
    TEST_ASSERT_EQUAL_HEX8(0x22, q[1].d[0]);
    proto_isotp_poll(&drive, 20000, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(2, qn); /* block of 2 done: waits for the next FC */
}

static void test_overflow_and_wrong_sequence_are_refused(void)
{
    const uint8_t ff_big[8] = {0x1F, 0xFF, 1, 2, 3, 4, 5, 6};
    const uint8_t ff[8] = {0x10, 20, 1, 2, 3, 4, 5, 6};
    const uint8_t cf_bad[8] = {0x23, 1, 1, 1, 1, 1, 1, 1};
    const uint8_t cf_lone[8] = {0x21, 1, 1, 1, 1, 1, 1, 1};
    const uint8_t *m;
    size_t len;

    reset();
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, ff_big, 8, 0, &m, &len));
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn);
    TEST_ASSERT_EQUAL_HEX8(0x32, q[0].d[0]); /* flow control: overflow */
    TEST_ASSERT_EQUAL_UINT32(1, drive.stats.rx_errors);
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, ff, 8, 0, &m, &len));
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, cf_bad, 8, 0, &m, &len));
    TEST_ASSERT_EQUAL_UINT32(2, drive.stats.rx_errors);
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, cf_lone, 8, 0, &m, &len));
    TEST_ASSERT_EQUAL_UINT32(3, drive.stats.rx_errors);
}

static void test_malformed_frames_are_counted(void)
{
    const uint8_t sf0[2] = {0x00, 1};
    const uint8_t sf_long[3] = {0x05, 1, 2}; /* claims 5 bytes, has 2 */
    const uint8_t ff_short[5] = {0x10, 20, 1, 2, 3};
    const uint8_t bad_pci[2] = {0x70, 0};
    const uint8_t *m;
    size_t len;

    reset();
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, sf0, 2, 0, &m, &len));
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, sf_long, 3, 0, &m, &len));
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, ff_short, 5, 0, &m, &len));
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, bad_pci, 2, 0, &m, &len));
    TEST_ASSERT_FALSE(proto_isotp_rx(&drive, bad_pci, 0, 0, &m, &len));
    TEST_ASSERT_EQUAL_UINT32(5, drive.stats.rx_errors);
}

static void test_timeouts_release_both_directions(void)
{
    const uint8_t ff[8] = {0x10, 20, 1, 2, 3, 4, 5, 6};
    uint8_t msg[30] = {0};
    const uint8_t *m;
    size_t len;

    reset();
    proto_isotp_rx(&drive, ff, 8, 100, &m, &len);
    TEST_ASSERT_TRUE(drive.rx_active);
    proto_isotp_poll(&drive, 100 + PROTO_ISOTP_TIMEOUT_US + 1, cap_tx, NULL);
    TEST_ASSERT_FALSE(drive.rx_active);
    TEST_ASSERT_EQUAL_UINT32(1, drive.stats.rx_timeouts);
    TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, sizeof msg, 0));
    proto_isotp_poll(&drive, 0, cap_tx, NULL); /* FF sent, no FC ever comes */
    proto_isotp_poll(&drive, PROTO_ISOTP_TIMEOUT_US + 1, cap_tx, NULL);
    TEST_ASSERT_FALSE(proto_isotp_busy(&drive));
    TEST_ASSERT_EQUAL_UINT32(1, drive.stats.tx_aborts);
}

static void test_full_mailbox_retries_same_frame(void)
{
    uint8_t msg[3] = {9, 8, 7};

    reset();
    TEST_ASSERT_TRUE(proto_isotp_send(&drive, msg, 3, 0));
    refuse_tx = true;
    proto_isotp_poll(&drive, 0, cap_tx, NULL);
    TEST_ASSERT_TRUE(proto_isotp_busy(&drive));
    refuse_tx = false;
    proto_isotp_poll(&drive, 10, cap_tx, NULL);
    TEST_ASSERT_EQUAL_UINT(1, qn);
    TEST_ASSERT_FALSE(proto_isotp_busy(&drive));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_every_length_both_ways);
    RUN_TEST(test_frame_layout_single_and_first);
    RUN_TEST(test_block_size_and_stmin_are_honoured);
    RUN_TEST(test_overflow_and_wrong_sequence_are_refused);
    RUN_TEST(test_malformed_frames_are_counted);
    RUN_TEST(test_timeouts_release_both_directions);
    RUN_TEST(test_full_mailbox_retries_same_frame);
    return UNITY_END();
}
